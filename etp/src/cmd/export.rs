//! `etp export DIR OUTDIR --format prism|jani|drn`: the MDP of `DIR/mdp.bin`
//! for another model checker, with queries whose thresholds come from the
//! front (`DIR/front.json`, refused if it belongs to another MDP; computed
//! when absent):
//! * `prism` — PRISM explicit files (`model.tra`, `.sta`, `.lab`, `.trew`)
//!   and `model.props`: `prism -importmodel OUTDIR/model.all -mdp`;
//! * `jani` — `model.jani`, the queries inside: `storm --jani
//!   OUTDIR/model.jani --janiproperty`;
//! * `drn` — Storm's `model.drn` and `model.props`: `storm --explicit-drn
//!   OUTDIR/model.drn --prop OUTDIR/model.props`.

use anyhow::{Context, Result};
use etp_pipeline::output::{read_front, read_mdp};
use etp_synthesis::export::{self, drn, jani, prism};
use etp_synthesis::mdp::MDP_FILE;
use etp_synthesis::mdp::{CostModel, Mdp};
use etp_synthesis::pareto::compute_front;
use std::path::{Path, PathBuf};

/// Which cost becomes the `energy` reward.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum CostArg {
    /// Mean counted transmissions × c_m (default).
    Counted,
    /// The paper's k̄ γ̄(δ) c_m.
    Paper,
}

/// Which model checker's format.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Format {
    /// PRISM explicit files (model.tra/.sta/.lab/.trew) and model.props.
    Prism,
    /// JANI (QComp interchange; Storm, Modest), properties included: model.jani.
    Jani,
    /// Storm's explicit DRN format: model.drn and model.props.
    Drn,
}

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Directory holding mdp.bin (written by `etp synthesize`), or the file itself.
    pub dir: PathBuf,
    /// Output directory for the model files.
    pub outdir: PathBuf,
    /// The format: jani (default: the interchange format Storm and the
    /// Modest Toolset read, queries included), drn (Storm) or prism.
    #[arg(long, value_enum, default_value_t = Format::Jani)]
    pub format: Format,
    /// Cost model of the energy reward.
    #[arg(long, value_enum, default_value_t = CostArg::Counted)]
    pub cost: CostArg,
    /// Overwrite existing model files in OUTDIR.
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
    let queries = export::queries(&mdp, &front, cost);
    let files: Vec<(&str, String)> = match a.format {
        Format::Prism => {
            let files = prism::export(&mdp, cost, export::properties_file(&mdp, &queries));
            files
                .files()
                .iter()
                .map(|(name, text)| (*name, (*text).to_string()))
                .collect()
        }
        Format::Jani => vec![("model.jani", jani::export(&mdp, cost, &queries))],
        Format::Drn => vec![
            ("model.drn", drn::export(&mdp, cost)),
            ("model.props", export::properties_file(&mdp, &queries)),
        ],
    };
    let targets: Vec<(PathBuf, &str)> = files
        .iter()
        .map(|(name, text)| (a.outdir.join(name), text.as_str()))
        .collect();
    etp_files::write::output_folder(&a.outdir)?;
    // All refused before any is written: no half-updated set of files.
    for (p, _) in &targets {
        etp_files::write::refuse_existing(p, a.force)?;
    }
    for (p, text) in &targets {
        etp_files::write::write_new(p, text.as_bytes(), true)?;
    }
    let out = |name: &str| a.outdir.join(name).display().to_string();
    let load = match a.format {
        Format::Prism => format!(
            "prism -importmodel {} -mdp {}",
            out("model.all"),
            out("model.props")
        ),
        Format::Jani => format!("storm --jani {} --janiproperty", out("model.jani")),
        Format::Drn => format!(
            "storm --explicit-drn {} --prop {}",
            out("model.drn"),
            out("model.props")
        ),
    };
    println!(
        "{} states (+3 terminal), {} transitions → {}\n  load: {load}",
        mdp.states.len(),
        mdp.num_transitions(),
        a.outdir.display(),
    );
    Ok(())
}
