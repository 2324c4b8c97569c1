//! `etp export-prism DIR OUTDIR`: the MDP of `DIR/mdp.bin` as PRISM explicit
//! files (`model.tra`, `.sta`, `.lab`, `.trew`), loadable with
//! `prism -importmodel OUTDIR/model.all -mdp`, plus `model.props` whose
//! thresholds come from the front (`DIR/front.json`, refused if it belongs to
//! another MDP; computed when absent).

use crate::output::{read_front, read_mdp};
use anyhow::{Context, Result};
use etp_synthesis::mdp::MDP_FILE;
use etp_synthesis::mdp::{CostModel, Mdp};
use etp_synthesis::pareto::compute_front;
use etp_synthesis::prism;
use std::path::{Path, PathBuf};

/// Which cost becomes the `energy` reward.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum CostArg {
    /// Mean counted transmissions × c_m (default).
    Counted,
    /// The paper's k̄ γ̄(δ) c_m.
    Paper,
}

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Directory holding mdp.bin (written by `etp synthesize`), or the file itself.
    pub dir: PathBuf,
    /// Output directory for the PRISM files.
    pub outdir: PathBuf,
    /// Cost model of the energy reward.
    #[arg(long, value_enum, default_value_t = CostArg::Counted)]
    pub cost: CostArg,
    /// Overwrite existing PRISM files in OUTDIR.
    #[arg(long)]
    pub force: bool,
}

/// Load an MDP from a directory (its `mdp.bin`) or a file path.
pub fn load_mdp(path: &Path) -> Result<Mdp> {
    let file = if path.is_dir() {
        path.join(MDP_FILE)
    } else {
        path.to_path_buf()
    };
    let bytes = std::fs::read(&file).with_context(|| format!("reading {}", file.display()))?;
    Mdp::decode(&bytes).with_context(|| format!("loading {}", file.display()))
}

pub fn run(a: Args) -> Result<()> {
    let cost = match a.cost {
        CostArg::Counted => CostModel::Counted,
        CostArg::Paper => CostModel::Paper,
    };
    // A directory (or its mdp.bin): the MDP, scenario.toml and front.json are
    // checked to belong together. Any other MDP file: its front is computed.
    let dir = if a.dir.is_dir() {
        Some(a.dir.clone())
    } else if a.dir.file_name().is_some_and(|n| n == MDP_FILE) {
        Some(
            a.dir
                .parent()
                .map_or_else(|| PathBuf::from("."), Path::to_path_buf),
        )
    } else {
        None
    };
    let (mdp, front) = match &dir {
        Some(d) => {
            let (mdp, _) = read_mdp(d)?;
            let front = read_front(d, &mdp)?;
            (mdp, front)
        }
        None => {
            let mdp = load_mdp(&a.dir)?;
            let front =
                compute_front(&mdp, CostModel::Counted).context("computing the Pareto front")?;
            (mdp, front)
        }
    };
    let props = prism::properties(&mdp, &front, cost);
    let files = prism::export(&mdp, cost, props);
    let targets: Vec<(PathBuf, &str)> = files
        .files()
        .iter()
        .map(|(name, text)| (a.outdir.join(name), *text))
        .collect();
    crate::output::output_folder(&a.outdir)?;
    // All refused before any is written: no half-updated set of files.
    for (p, _) in &targets {
        crate::output::refuse_existing(p, a.force)?;
    }
    for (p, text) in &targets {
        crate::output::write_new(p, text.as_bytes(), true)?;
    }
    println!(
        "{} states (+3 terminal), {} transitions → {}\n  load: prism -importmodel {} -mdp {}",
        mdp.states.len(),
        mdp.num_transitions(),
        a.outdir.display(),
        a.outdir.join("model.all").display(),
        a.outdir.join("model.props").display(),
    );
    Ok(())
}
