//! `etp export-prism DIR OUTDIR`: the MDP of `DIR/mdp.bin` as PRISM explicit
//! files (`model.tra`, `.sta`, `.lab`, `.trew`, plus `model.props`), loadable
//! with `prism -importmodel OUTDIR/model.all -mdp`.

use anyhow::{Context, Result};
use etp_synthesis::mdp::{CostModel, Mdp};
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
        path.join("mdp.bin")
    } else {
        path.to_path_buf()
    };
    let bytes = std::fs::read(&file).with_context(|| format!("reading {}", file.display()))?;
    Mdp::decode(&bytes).with_context(|| format!("loading {}", file.display()))
}

pub fn run(a: Args) -> Result<()> {
    let mdp = load_mdp(&a.dir)?;
    let files = prism::export(
        &mdp,
        match a.cost {
            CostArg::Counted => CostModel::Counted,
            CostArg::Paper => CostModel::Paper,
        },
    );
    let targets: Vec<(PathBuf, &str)> = files
        .files()
        .iter()
        .map(|(name, text)| (a.outdir.join(name), *text))
        .collect();
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
