//! `etp run --config RUN.toml`: the launch file of a run. Its keys are the
//! long flags of `etp run` (`strategy` or `scenario` + `delta`, `episodes`,
//! `seed`, `record`, `slot_deadline`, `listen` + `remote` sensors, the radio
//! `loss`, `retries`, `burst`, `estimator`, the live view's `live` and
//! `live_wait`, …); a flag
//! given on the command line
//! wins over the file. Relative paths in the file are relative to the file.
//! The resolved configuration of every run — file or flags — is stored in the
//! recording's metadata (`etp.config`, key `toml`).
//!
//! ```toml
//! scenario = "open-2d"
//! delta = 1.0518
//! episodes = 50
//! seed = 7
//! record = "open-2d.mcap"
//! ```

use super::Args;
use anyhow::{Context, Result, bail};
use etp_runtime::scenario_arg::ScenarioSource;
use std::path::{Path, PathBuf};

/// Defaults of the flags that have one.
pub const DEFAULT_EPISODES: u64 = 100;
pub const DEFAULT_SEED: u64 = 0;
pub const DEFAULT_DEADLINE: f64 = 3600.0;
pub const DEFAULT_PREDICT_EPISODES: u64 = 2000;
pub const DEFAULT_JOIN_TIMEOUT: f64 = 60.0;

/// The keys of a run file, each written once: its type and, for a plain
/// key, the place of its flag in [`Args`] (`=> place`). A plain key is
/// copied to and from [`Args`] by [`of_args`] and [`resolve`] (the command
/// line wins); the others (what to run, the recording, the remote sensors
/// and the two switches) have their own rules there.
macro_rules! run_file_keys {
    ($( $(#[$attr:meta])* $key:ident : $ty:ty $(=> $($place:ident).+)? ,)*) => {
        /// The keys of a run file (every one optional; unknown keys are refused).
        #[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
        #[serde(deny_unknown_fields)]
        pub struct RunConfig {
            $(
                $(#[$attr])*
                #[serde(skip_serializing_if = "Option::is_none")]
                pub $key: Option<$ty>,
            )*
        }

        /// The plain keys of `a` (the others are left `None`).
        fn plain_of_args(a: &Args) -> RunConfig {
            let mut c = RunConfig::default();
            $($( c.$key = copied(&a.$($place).+); )?)*
            c
        }

        /// Each plain key the command line left open, from `c`.
        fn merge_plain(a: &mut Args, c: &mut RunConfig) {
            $($( a.$($place).+ = a.$($place).+.take().or(c.$key.take()); )?)*
        }
    };
}

/// `x.clone()` for any option (a copy for the numbers).
fn copied<T: Clone>(x: &Option<T>) -> Option<T> {
    x.clone()
}

run_file_keys! {
    strategy: PathBuf,
    scenario: String,
    delta: f64,
    episodes: u64 => episodes,
    seed: u64 => seed,
    deadline: f64 => deadline,
    run_id: String => run_id,
    predict_episodes: u64 => predict_episodes,
    clone_sensors: usize => clone_sensors,
    record: PathBuf,
    record_default: bool,
    allow_degraded: bool,
    slot_deadline: u64 => slot_deadline,
    /// Across hosts: the Zenoh endpoint to listen on, the sensors served
    /// from other hosts, how long to wait for them (`--listen`, `--remote`,
    /// `--join-timeout`).
    listen: String => listen,
    remote: Vec<String>,
    join_timeout: f64 => join_timeout,
    /// The link's protection: the key folder (`--tls`) or plain TCP
    /// (`--insecure`).
    tls: PathBuf => link.tls,
    insecure: bool,
    /// The radio options (`--loss`, `--retries`, `--burst`, `--estimator`,
    /// docs/MODEL.md §8), written into the run's scenario text.
    loss: f64 => radio.loss,
    retries: i64 => radio.retries,
    burst: f64 => radio.burst,
    estimator: String => radio.estimator,
    /// The trigger family (`--trigger`, docs/MODEL.md §9).
    trigger: etp_shared::trigger::TriggerFamily => trigger.trigger,
    /// The live view (`--live ADDR:PORT`, `--live-wait`): how the run is
    /// watched, not what it computes, so never stored in a recording's
    /// `etp.config` (a run again from it is not served live). Read as
    /// `--live` reads it (`localhost:8765` too).
    #[serde(default, deserialize_with = "crate::live::deserialize_addr")]
    live: std::net::SocketAddr => live,
    live_wait: bool,
}

/// Read a run file (errors name the file and the key).
pub fn read(path: &Path) -> Result<RunConfig> {
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("reading the run file {}", path.display()))?;
    let mut c: RunConfig =
        toml::from_str(&text).with_context(|| format!("run file {}", path.display()))?;
    let base = path.parent().unwrap_or(Path::new(""));
    let rel = |p: &mut Option<PathBuf>| {
        if let Some(x) = p.as_mut().filter(|x| x.is_relative()) {
            *x = base.join(&*x);
        }
    };
    rel(&mut c.strategy);
    rel(&mut c.record);
    // A scenario that is not a built-in name is a path, relative to the file.
    c.scenario = c
        .scenario
        .map(|s| ScenarioSource::parse(&s).in_folder(base).to_arg());
    Ok(c)
}

/// Fill what the command line left open from `--config`, then the defaults.
pub fn resolve(mut a: Args) -> Result<Args> {
    if let Some(path) = a.config.clone() {
        let mut c = read(&path)?;
        if a.strategy.is_some() || a.scenario.is_some() {
            // The command line names what to run: the file's choice is ignored whole.
            if c.strategy.is_some() || c.scenario.is_some() || c.delta.is_some() {
                tracing::info!("the command line's strategy/scenario overrides the run file's");
            }
        } else {
            a.strategy = c.strategy.take();
            a.scenario = c.scenario.take();
            if a.delta.is_none() {
                a.delta = c.delta;
            }
        }
        merge_plain(&mut a, &mut c);
        a.allow_degraded |= c.allow_degraded.unwrap_or(false);
        a.live_wait |= c.live_wait.unwrap_or(false);
        if a.remote.is_empty() {
            a.remote = c.remote.unwrap_or_default();
        }
        a.link.insecure |= c.insecure.unwrap_or(false);
        if a.listen.is_some() == a.remote.is_empty() {
            bail!(
                "run file {}: `listen` and `remote` go together (sensors served from other hosts)",
                path.display()
            );
        }
        if a.record.is_none() && !a.record_default {
            a.record = c.record;
            a.record_default = c.record_default.unwrap_or(false);
        }
        if a.record.is_some() && a.record_default {
            bail!(
                "run file {}: `record` and `record_default` exclude each other",
                path.display()
            );
        }
        if a.delta.is_some() && a.scenario.is_none() {
            bail!(
                "run file {}: `delta` needs `scenario` (a constant-δ run)",
                path.display()
            );
        }
    }
    a.episodes.get_or_insert(DEFAULT_EPISODES);
    a.seed.get_or_insert(DEFAULT_SEED);
    a.deadline.get_or_insert(DEFAULT_DEADLINE);
    a.predict_episodes.get_or_insert(DEFAULT_PREDICT_EPISODES);
    a.join_timeout.get_or_insert(DEFAULT_JOIN_TIMEOUT);
    Ok(a)
}

/// The text of the `etp.config` record: the resolved run as a run file that
/// runs again from any working directory — paths made absolute (they were
/// relative to where the run started), and no run id (a new run gets a new
/// one; this run's id is in the `etp.run` record).
pub fn stored(c: &RunConfig) -> Result<String> {
    let mut c = c.clone();
    c.run_id = None;
    let abs = |p: &mut Option<PathBuf>| -> Result<()> {
        if let Some(x) = p.as_mut() {
            *x = std::path::absolute(&*x)
                .with_context(|| format!("making {} absolute", x.display()))?;
        }
        Ok(())
    };
    abs(&mut c.strategy)?;
    abs(&mut c.record)?;
    if let Some(s) = c.scenario.take() {
        let source = ScenarioSource::parse(&s)
            .absolute()
            .with_context(|| format!("making {s} absolute"))?;
        c.scenario = Some(source.to_arg());
    }
    toml::to_string(&c).context("writing the run's configuration")
}

/// The resolved run as a run file (the `etp.config` record).
pub fn of_args(a: &Args, record: Option<&Path>) -> RunConfig {
    RunConfig {
        strategy: a.strategy.clone(),
        scenario: a.scenario.clone(),
        delta: a.delta,
        record: record.map(Path::to_path_buf),
        record_default: None,
        allow_degraded: Some(a.allow_degraded),
        remote: (!a.remote.is_empty()).then(|| a.remote.clone()),
        insecure: a.link.insecure.then_some(true),
        live: None,
        live_wait: None,
        ..plain_of_args(a)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_run_file_round_trips_and_refuses_unknown_keys() {
        let c = RunConfig {
            scenario: Some("open-2d".into()),
            delta: Some(1.0518),
            episodes: Some(50),
            // A lossy run keeps its channel in the stored run file.
            loss: Some(0.3),
            retries: Some(1),
            estimator: Some("aware".into()),
            ..RunConfig::default()
        };
        let text = toml::to_string(&c).expect("toml");
        assert!(text.contains("loss = 0.3"), "{text}");
        assert_eq!(toml::from_str::<RunConfig>(&text).expect("back"), c);
        let e = toml::from_str::<RunConfig>("episodez = 3").expect_err("unknown key");
        assert!(e.to_string().contains("episodez"), "{e}");
        let e = toml::from_str::<RunConfig>("episodes = \"ten\"").expect_err("bad type");
        assert!(e.to_string().contains("episodes"), "{e}");
        let c: RunConfig = toml::from_str("live = \"127.0.0.1:8765\"\nlive_wait = true")
            .expect("the live view's keys");
        assert_eq!(
            c.live,
            Some(std::net::SocketAddr::from(([127, 0, 0, 1], 8765)))
        );
        assert_eq!(c.live_wait, Some(true));
        let e = toml::from_str::<RunConfig>("live = \"localhost\"").expect_err("no port");
        assert!(e.to_string().contains("live"), "{e}");
        let c: RunConfig = toml::from_str("live = \"localhost:8765\"").expect("a host name");
        assert_eq!(
            c.live,
            Some(std::net::SocketAddr::from(([127, 0, 0, 1], 8765)))
        );
        let text = toml::to_string(&c).expect("toml");
        assert_eq!(toml::from_str::<RunConfig>(&text).expect("back"), c);
    }

    #[test]
    fn the_stored_run_file_runs_from_anywhere_under_a_new_run_id() {
        let c = RunConfig {
            strategy: Some("out/strategy.json".into()),
            scenario: Some("my/scenario.toml".into()),
            record: Some("rec.mcap".into()),
            run_id: Some("old-run".into()),
            ..RunConfig::default()
        };
        let back: RunConfig = toml::from_str(&stored(&c).expect("stored")).expect("toml");
        let cwd = std::env::current_dir().expect("cwd");
        assert_eq!(back.run_id, None);
        assert_eq!(back.strategy, Some(cwd.join("out/strategy.json")));
        assert_eq!(back.record, Some(cwd.join("rec.mcap")));
        assert_eq!(
            back.scenario,
            Some(cwd.join("my/scenario.toml").display().to_string())
        );
        let builtin = RunConfig {
            scenario: Some("winding-2d".into()),
            ..RunConfig::default()
        };
        let back: RunConfig = toml::from_str(&stored(&builtin).expect("stored")).expect("toml");
        assert_eq!(back.scenario.as_deref(), Some("winding-2d"));
    }

    /// The run file's `live`/`live_wait` serve the run live, and the stored
    /// record of the run leaves them out.
    #[test]
    fn a_run_file_serves_live_and_its_record_does_not() {
        use clap::Parser;
        #[derive(clap::Parser)]
        struct Cmd {
            #[command(flatten)]
            a: Args,
        }
        let dir = std::env::temp_dir().join(format!("etp-config-live-{}", std::process::id()));
        std::fs::create_dir(&dir).expect("a fresh folder");
        let file = dir.join("run.toml");
        std::fs::write(
            &file,
            "scenario = \"open-2d\"\ndelta = 1.0\nlive = \"127.0.0.1:0\"\nlive_wait = true\n",
        )
        .expect("run file");
        let a = Cmd::try_parse_from(["run", "--config", &file.display().to_string()])
            .expect("flags")
            .a;
        let a = resolve(a).expect("resolved");
        std::fs::remove_dir_all(&dir).expect("clean up");
        assert_eq!(
            a.live,
            Some(std::net::SocketAddr::from(([127, 0, 0, 1], 0)))
        );
        assert!(a.live_wait);
        let text = stored(&of_args(&a, None)).expect("stored");
        assert!(!text.contains("live"), "{text}");
    }
}
