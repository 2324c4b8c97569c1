//! Files on disk: refusing to overwrite, reading the synthesis directory.

use anyhow::{Context, Result, bail};
use etp_synthesis::mdp::Mdp;
use etp_synthesis::pareto::{ParetoFront, compute_front};
use std::path::Path;

/// THE overwrite rule of every command: an existing `path` is replaced only
/// with `--force`.
pub fn refuse_existing(path: &Path, force: bool) -> Result<()> {
    if path.exists() && !force {
        bail!(
            "{} already exists (use --force to overwrite)",
            path.display()
        );
    }
    Ok(())
}

/// Produce `path` through `write(tmp)` on a temporary sibling that is then
/// renamed into place (and removed if `write` fails), so an interrupted or
/// failed write never leaves a half-written file under the final name.
pub fn write_via_temp<T>(path: &Path, write: impl FnOnce(&Path) -> Result<T>) -> Result<T> {
    if let Some(parent) = path.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(parent)
            .with_context(|| format!("creating {}", parent.display()))?;
    }
    let tmp = path.with_extension("tmp-etp");
    match write(&tmp) {
        Ok(v) => {
            std::fs::rename(&tmp, path)
                .with_context(|| format!("moving {} into place", path.display()))?;
            Ok(v)
        }
        Err(e) => {
            let _ = std::fs::remove_file(&tmp);
            Err(e)
        }
    }
}

/// Write `bytes` to `path`, refusing to replace an existing file unless `force`.
pub fn write_new(path: &Path, bytes: &[u8], force: bool) -> Result<()> {
    refuse_existing(path, force)?;
    write_via_temp(path, |tmp| {
        std::fs::write(tmp, bytes).with_context(|| format!("writing {}", tmp.display()))
    })
}

/// `DIR/mdp.bin` and, if present, the scenario text `DIR/scenario.toml`.
pub fn read_mdp(dir: &Path) -> Result<(Mdp, Option<String>)> {
    let path = dir.join("mdp.bin");
    let bytes = std::fs::read(&path)
        .with_context(|| format!("reading {} (run `etp synthesize` first?)", path.display()))?;
    let mdp = Mdp::decode(&bytes).with_context(|| format!("loading {}", path.display()))?;
    let scenario_path = dir.join("scenario.toml");
    let text = match std::fs::read_to_string(&scenario_path) {
        Ok(t) => Some(t),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => None,
        Err(e) => return Err(e).with_context(|| format!("reading {}", scenario_path.display())),
    };
    if let Some(t) = &text {
        let s = etp_shared::scenario::Scenario::from_toml(t)
            .with_context(|| format!("scenario {}", scenario_path.display()))?;
        if s.content_hash != mdp.scenario_hash {
            bail!(
                "{} does not belong to {} (scenario hash {:.12}… vs {:.12}…)",
                scenario_path.display(),
                path.display(),
                s.content_hash,
                mdp.scenario_hash
            );
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
                .map_err(anyhow::Error::msg)
                .with_context(|| format!("loading {}", path.display()))?;
            if f.scenario_hash != mdp.scenario_hash || f.mdp_states != mdp.states.len() {
                bail!(
                    "{} was not computed from {}/mdp.bin",
                    path.display(),
                    dir.display()
                );
            }
            Ok(f)
        }
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            compute_front(mdp, Default::default()).context("computing the Pareto front")
        }
        Err(e) => Err(e).with_context(|| format!("reading {}", path.display())),
    }
}
