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

use crate::error::{Context, IoContext, Result};
use etp_runtime::scenario_arg::ScenarioSource;
use std::path::{Path, PathBuf};

/// Defaults of the flags that have one.
pub const DEFAULT_EPISODES: u64 = 100;
pub const DEFAULT_SEED: u64 = 0;
pub const DEFAULT_DEADLINE: f64 = 3600.0;
pub const DEFAULT_PREDICT_EPISODES: u64 = 2000;
pub const DEFAULT_JOIN_TIMEOUT: f64 = 60.0;

/// The keys of a run file, each written once with its type. A key marked
/// `=> plain` is merged by [`merge`] as given on the command line, else from
/// the file; the others (what to run and the recording) have their own rule
/// there. A switch given on the command line is `Some(true)`, so a plain
/// switch is on when either side turns it on.
macro_rules! run_file_keys {
    ($( $(#[$attr:meta])* $key:ident : $ty:ty $(=> $plain:ident)? ,)*) => {
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

        /// Each plain key the command line left open, from the file.
        fn merge_plain(cli: &mut RunConfig, file: &mut RunConfig) {
            $($( let _ = stringify!($plain); cli.$key = cli.$key.take().or(file.$key.take()); )?)*
        }
    };
}

run_file_keys! {
    strategy: PathBuf,
    scenario: String,
    delta: f64,
    episodes: u64 => plain,
    seed: u64 => plain,
    deadline: f64 => plain,
    run_id: String => plain,
    predict_episodes: u64 => plain,
    clone_sensors: usize => plain,
    record: PathBuf,
    record_default: bool,
    allow_degraded: bool => plain,
    slot_deadline: u64 => plain,
    /// Across hosts: the Zenoh endpoint to listen on, the sensors served
    /// from other hosts, how long to wait for them (`--listen`, `--remote`,
    /// `--join-timeout`).
    listen: String => plain,
    remote: Vec<String> => plain,
    join_timeout: f64 => plain,
    /// The link's protection: the key folder (`--tls`) or plain TCP
    /// (`--insecure`).
    tls: PathBuf => plain,
    insecure: bool => plain,
    /// The radio options (`--loss`, `--retries`, `--burst`, `--estimator`,
    /// docs/MODEL.md §8), written into the run's scenario text.
    loss: f64 => plain,
    retries: i64 => plain,
    burst: f64 => plain,
    estimator: String => plain,
    /// The trigger family (`--trigger`, docs/MODEL.md §9).
    trigger: etp_shared::trigger::TriggerFamily => plain,
    /// Changes of sensors' links during the run (`--channel-schedule`,
    /// docs/MODEL.md §8.8), applied on the sensor side.
    channel_schedule: PathBuf => plain,
    /// The channel monitor (docs/MODEL.md §11): its false-alarm
    /// probability for the run (`--drift-false-alarm`) and what a flag does
    /// (`--on-drift warn|stop`).
    drift_false_alarm: f64 => plain,
    on_drift: String => plain,
    /// The live view (`--live ADDR:PORT`, `--live-wait`): how the run is
    /// watched, not what it computes, so never stored in a recording's
    /// `etp.config` (a run again from it is not served live). Read as
    /// `--live` reads it (`localhost:8765` too).
    #[serde(default, deserialize_with = "crate::live::deserialize_addr")]
    live: std::net::SocketAddr => plain,
    live_wait: bool => plain,
}

/// Read a run file (errors name the file and the key).
pub fn read(path: &Path) -> Result<RunConfig> {
    let text = std::fs::read_to_string(path)
        .doing(|| format!("reading the run file {}", path.display()))?;
    let mut c: RunConfig =
        toml::from_str(&text).in_run_file(|| format!("run file {}", path.display()))?;
    let base = path.parent().unwrap_or(Path::new(""));
    let rel = |p: &mut Option<PathBuf>| {
        if let Some(x) = p.as_mut().filter(|x| x.is_relative()) {
            *x = base.join(&*x);
        }
    };
    rel(&mut c.strategy);
    rel(&mut c.record);
    rel(&mut c.channel_schedule);
    // A scenario that is not a built-in name is a path, relative to the file.
    c.scenario = c
        .scenario
        .map(|s| ScenarioSource::parse(&s).in_folder(base).to_arg());
    Ok(c)
}

/// The command line's keys `cli` over the run file `file`: a key given on
/// the command line wins; when the command line names what to run (a
/// strategy or a scenario), the file's choice is ignored whole, and when it
/// names a recording, so is the file's.
pub fn merge(mut cli: RunConfig, mut file: RunConfig) -> RunConfig {
    if cli.strategy.is_some() || cli.scenario.is_some() {
        if file.strategy.is_some() || file.scenario.is_some() || file.delta.is_some() {
            tracing::info!("the command line's strategy/scenario overrides the run file's");
        }
    } else {
        cli.strategy = file.strategy.take();
        cli.scenario = file.scenario.take();
        cli.delta = cli.delta.or(file.delta);
    }
    if cli.record.is_none() && !cli.record_default.unwrap_or(false) {
        cli.record = file.record.take();
        cli.record_default = file.record_default;
    }
    merge_plain(&mut cli, &mut file);
    cli
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
            *x = std::path::absolute(&*x).doing(|| format!("making {} absolute", x.display()))?;
        }
        Ok(())
    };
    abs(&mut c.strategy)?;
    abs(&mut c.record)?;
    abs(&mut c.channel_schedule)?;
    if let Some(s) = c.scenario.take() {
        let source = ScenarioSource::parse(&s)
            .absolute()
            .doing(|| format!("making {s} absolute"))?;
        c.scenario = Some(source.to_arg());
    }
    toml::to_string(&c).in_run_file(|| "writing the run's configuration")
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
        use crate::request::{LiveView, RunRequest};
        let dir = std::env::temp_dir().join(format!("etp-config-live-{}", std::process::id()));
        std::fs::create_dir(&dir).expect("a fresh folder");
        let file = dir.join("run.toml");
        std::fs::write(
            &file,
            "scenario = \"open-2d\"\ndelta = 1.0\nlive = \"127.0.0.1:0\"\nlive_wait = true\n",
        )
        .expect("run file");
        let c = read(&file).expect("the run file");
        std::fs::remove_dir_all(&dir).expect("clean up");
        let r = RunRequest::from_config(merge(RunConfig::default(), c)).expect("resolved");
        assert_eq!(
            r.live,
            Some(LiveView {
                addr: std::net::SocketAddr::from(([127, 0, 0, 1], 0)),
                wait_for_client: true
            })
        );
        let text = stored(&r.to_config(None)).expect("stored");
        assert!(!text.contains("live"), "{text}");
    }

    /// The command line wins key by key; naming what to run or a recording
    /// there sets the file's choice aside whole.
    #[test]
    fn the_command_line_wins_over_the_run_file() {
        let file = RunConfig {
            strategy: Some("s.json".into()),
            episodes: Some(50),
            seed: Some(7),
            record_default: Some(true),
            allow_degraded: Some(true),
            ..RunConfig::default()
        };
        let cli = RunConfig {
            scenario: Some("open-2d".into()),
            delta: Some(1.0518),
            episodes: Some(3),
            record: Some("r.mcap".into()),
            ..RunConfig::default()
        };
        let m = merge(cli, file.clone());
        assert_eq!(m.strategy, None);
        assert_eq!(m.scenario.as_deref(), Some("open-2d"));
        assert_eq!((m.episodes, m.seed), (Some(3), Some(7)));
        assert_eq!((m.record_default, m.allow_degraded), (None, Some(true)));
        let m = merge(RunConfig::default(), file);
        assert_eq!(m.strategy, Some(PathBuf::from("s.json")));
        assert_eq!(m.record_default, Some(true));
    }
}
