//! A subcommand of `etp replay` as the one [`Job`] that runs it.

use super::{Action, SelectArgs, WriteArgs};
use etp_recording_tools::{export, foxglove, select};
use std::path::PathBuf;

impl Action {
    /// The job of this tool.
    pub(super) fn job(self) -> Job {
        let sel = |j: Job, s: SelectArgs| Job { select: s, ..j };
        let on = |file: PathBuf| Job {
            file: Some(file),
            ..Job::default()
        };
        match self {
            Action::Summary { file, json, select } => sel(Job { json, ..on(file) }, select),
            Action::Info { file, json, select } => sel(
                Job {
                    json,
                    info: true,
                    ..on(file)
                },
                select,
            ),
            Action::Cat { file, json, select } => sel(
                Job {
                    json,
                    cat: true,
                    ..on(file)
                },
                select,
            ),
            Action::Export {
                file,
                dir,
                format,
                write: WriteArgs { force, json },
                select,
            } => sel(
                Job {
                    export: Some(dir),
                    format,
                    force,
                    json,
                    only: true,
                    ..on(file)
                },
                select,
            ),
            Action::Filter {
                file,
                out,
                write: WriteArgs { force, json },
                select,
            } => sel(
                Job {
                    filter: Some(out),
                    force,
                    json,
                    only: true,
                    ..on(file)
                },
                select,
            ),
            Action::Verify { file, json } => Job {
                verify: true,
                json,
                ..on(file)
            },
            Action::Repair {
                file,
                out,
                write: WriteArgs { force, json },
            } => Job {
                repair: Some(out),
                force,
                json,
                only: true,
                ..on(file)
            },
            Action::Publish {
                file,
                rate,
                run_id,
                repeat,
                json,
                select,
            } => sel(
                Job {
                    publish: true,
                    rate,
                    run_id,
                    repeat,
                    json,
                    ..on(file)
                },
                select,
            ),
            Action::Foxglove {
                file,
                out,
                clock,
                episodes,
                write: WriteArgs { force, json },
            } => Job {
                foxglove: Some(out),
                foxglove_clock: clock,
                force,
                json,
                only: true,
                select: SelectArgs {
                    episodes,
                    ..SelectArgs::default()
                },
                ..on(file)
            },
            Action::Plot {
                file,
                out,
                write: WriteArgs { force, json },
            } => Job {
                plot: true,
                plot_out: out,
                force,
                json,
                only: true,
                ..on(file)
            },
        }
    }
}

/// What `etp replay` does to a file: the summary, or one tool's job
/// (made by [`Action::job`], never parsed itself).
#[derive(Debug, Default)]
pub struct Job {
    pub file: Option<PathBuf>,
    pub json: bool,
    /// `repair FILE OUT`.
    pub repair: Option<PathBuf>,
    pub verify: bool,
    pub publish: bool,
    /// `publish --rate`.
    pub rate: f64,
    /// `publish --run-id`.
    pub run_id: Option<String>,
    /// `foxglove FILE OUT`.
    pub foxglove: Option<PathBuf>,
    pub foxglove_clock: foxglove::Clock,
    /// `publish --loop [N]`.
    pub repeat: Option<u64>,
    /// `export FILE DIR`.
    pub export: Option<PathBuf>,
    pub format: export::Format,
    pub cat: bool,
    pub info: bool,
    pub select: SelectArgs,
    pub plot: bool,
    /// `plot -o STEM`.
    pub plot_out: Option<PathBuf>,
    /// Overwrite output files that exist.
    pub force: bool,
    /// `filter FILE OUT`.
    pub filter: Option<PathBuf>,
    /// The job alone, without the summary on stdout (a subcommand's).
    pub only: bool,
}

impl Job {
    /// Nothing but the summary is asked for.
    pub(super) fn summary_alone(&self) -> bool {
        !(self.only || self.verify || self.publish || self.cat || self.info || self.plot)
            && self.repair.is_none()
            && self.foxglove.is_none()
            && self.export.is_none()
            && self.filter.is_none()
    }

    pub(super) fn selection(&self) -> select::Selection {
        select::Selection {
            topics: self.select.topics.clone(),
            exclude_topics: self.select.exclude_topics.clone(),
            episodes: self.select.episodes,
            start: self.select.start,
            end: self.select.end,
        }
    }
}
