//! Files on disk: refusing to overwrite, reading the synthesis directory.

use crate::error::{Context, Error, Result, Words};
use etp_synthesis::exec::Executor;
use etp_synthesis::mdp::{MDP_FILE, Mdp};
use etp_synthesis::pareto::{ParetoFront, compute_front};
use std::path::Path;

/// [`etp_files::write::refuse_existing`] on `exec`'s rank 0 only: in an
/// MPI job rank 0 may already have written the file another rank checks.
pub fn refuse_existing(exec: &Executor, path: &Path, force: bool) -> Result<()> {
    if !exec.is_root() {
        return Ok(());
    }
    Ok(etp_files::write::refuse_existing(path, force)?)
}

/// [`etp_files::write::write_new`] (beside, then renamed) on `exec`'s
/// rank 0 only: in an MPI job the other ranks hold the same bytes and write
/// nothing.
pub fn write_new(exec: &Executor, path: &Path, bytes: &[u8], force: bool) -> Result<()> {
    if !exec.is_root() {
        return Ok(());
    }
    Ok(etp_files::write::write_new(path, bytes, force)?)
}

/// `DIR/mdp.bin` and, if present, the scenario text `DIR/scenario.toml`.
pub fn read_mdp(dir: &Path) -> Result<(Mdp, Option<String>)> {
    let path = dir.join(MDP_FILE);
    let bytes = std::fs::read(&path).in_synthesis(format!(
        "reading {} (run `etp synthesize` first?)",
        path.display()
    ))?;
    let mdp = Mdp::decode(&bytes).in_synthesis(format!("loading {}", path.display()))?;
    let scenario_path = dir.join("scenario.toml");
    let text = match std::fs::read_to_string(&scenario_path) {
        Ok(t) => Some(t),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => None,
        Err(e) => return Err(e).in_synthesis(format!("reading {}", scenario_path.display())),
    };
    if let Some(t) = &text {
        let s = etp_shared::scenario::Scenario::from_toml(t)
            .in_scenario(format!("scenario {}", scenario_path.display()))?;
        if s.content_hash != mdp.scenario_hash {
            return Err(Error::synthesis(format!(
                "{} does not belong to {} (scenario hash {:.12}… vs {:.12}…)",
                scenario_path.display(),
                path.display(),
                s.content_hash,
                mdp.scenario_hash
            )));
        }
    }
    Ok((mdp, text))
}

/// `DIR/front.json` (computed from the MDP if absent); refused if it belongs to
/// another MDP's scenario.
pub fn read_front(dir: &Path, mdp: &Mdp) -> Result<ParetoFront> {
    let path = dir.join("front.json");
    match std::fs::read_to_string(&path) {
        Ok(text) => {
            let f = ParetoFront::from_json(&text)
                .map_err(Words)
                .in_synthesis(format!("loading {}", path.display()))?;
            if f.scenario_hash != mdp.scenario_hash || f.mdp_states != mdp.states.len() {
                return Err(Error::synthesis(format!(
                    "{} was not computed from {}/mdp.bin",
                    path.display(),
                    dir.display()
                )));
            }
            Ok(f)
        }
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            compute_front(mdp, Default::default()).computing("computing the Pareto front")
        }
        Err(e) => Err(e).in_synthesis(format!("reading {}", path.display())),
    }
}
