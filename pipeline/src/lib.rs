//! etpareto's pipeline as a library: the steps `etp synthesize`, `etp
//! strategy`, `etp validate` and `etp study` run, callable without the command line —
//! by the `etp` binary's subcommands (which add arguments and printing) and
//! by the Python package `etpareto` (`python/`).
//!
//! A tour, in the order a user meets them:
//! * [`synthesize`] — a whole synthesis from a typed [`synthesize::SynthesisRequest`]:
//!   * [`mdp_build`] — the belief-space MDP by layered Monte Carlo, written
//!     as `DIR/mdp.bin` ([`mdp_build::split`]: adaptive splitting);
//!   * [`front`] — the Pareto front, `front.json`, its figure, `scenario.toml`;
//!   * [`aggregation`] — the aggregation check of the MDP's regions.
//! * [`synthesis_dir`] — a synthesis folder loaded for selection
//!   ([`synthesis_dir::Synthesis`]): the request loop (`meet`), predictions
//!   from on-policy rebuilds.
//! * [`selection`] — the strategy a request's loop stands by, as its file.
//! * [`predictions`] — a strategy file's predictions as reports show them,
//!   the aggregation check, the checks against a simulation.
//! * [`validation`] — a strategy simulated and checked against its
//!   predictions ([`validation::validate`] from a typed
//!   [`validation::ValidationRequest`]): `etp validate`, `etp demo`, a
//!   study's cases and `etpareto.validate`; the JSON and the failed checks.
//! * [`study`] — `etp study`: a SPEC's cases (synthesis, strategy,
//!   validation), resumable, shared out over the executor's ranks; its
//!   tables ([`study::run`] from a typed [`study::StudyRequest`]).
//! * [`output`] — files written beside and renamed, never over one unasked.
//! * [`progress`] — the steps' bars, through the [`progress::Progress`]
//!   value each step is handed, and the bar under way for a caller that
//!   draws progress itself.
//!
//! Every step runs its Monte Carlo on the executor it is handed
//! (`etp_synthesis::exec::Executor`: a thread pool and, under `etp`'s MPI
//! feature, the ranks of a job), held by its typed request ([`mdp_build::MdpRequest`],
//! [`synthesis_dir::Synthesis`]) or passed in; rank 0 alone writes files
//! and draws progress. No step keeps an executor in a global.
//!
//! The maths is in `etp-shared` and `etp-synthesis` (pure: no I/O, no
//! clock); this crate adds files and progress. Errors are
//! [`error::Error`], one variant per kind of failure (a study's:
//! [`error::StudyError`], its SPEC's [`error::SpecError`]); with its causes
//! joined by `: ` its text is what `etp` prints after `error:`.

pub mod aggregation;
pub mod error;
pub mod front;
pub mod mdp_build;
pub mod output;
pub mod predicted_front;
pub mod predictions;
pub mod progress;
pub mod selection;
pub mod study;
pub mod synthesis_dir;
pub mod synthesize;
pub mod validation;
