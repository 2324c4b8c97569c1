//! `etp-synthesis`: everything etpareto computes offline.
//!
//! * [`simulate`] — the in-process Monte Carlo episode simulator (parallel over
//!   episodes with rayon, reproducible from a seed whatever the thread count):
//!   [`simulate::simulate`] runs any threshold policy, [`simulate::SimulationSummary`]
//!   holds outcome frequencies, energy, steps and trigger rates with 95 % intervals;
//!   [`constant`] the constant-threshold simulation of `etp simulate`,
//!   [`records`] its episodes one row each, [`report`] its `--json` object.
//!
//! * [`abstraction`] — the belief-space MDP by layered Monte Carlo (docs/MODEL.md §4,
//!   Method 2 discretized regions and Method 1 KF convergence).
//! * [`mdp`] — the [`mdp::Mdp`] type and its versioned file `mdp.bin`
//!   ([`mdp::MDP_FILE`]).
//! * [`pareto`] — every vertex and facet of the Pareto front, strategies for a
//!   requested trade-off (vertex LP, occupation measures), `front.json`.
//! * [`certify`] — predictions that hold (docs/MODEL.md §4.1): the cross-fitted
//!   value on held-out samples, the interval MDP and its robust backward
//!   induction ([`certify::robust::Certified`]), certified strategy selection,
//!   the certified front, and replicates (R rebuilds' cross-fitted values).
//! * [`predict`] — the prediction etp stands by (docs/MODEL.md §7.4): a
//!   strategy predicted on on-policy rebuilds ([`predict::rebuild`]) and the
//!   request loop that selects, rebuilds and moves the request by the
//!   measured gap ([`predict::request::meet_request`]).
//! * [`validate`] — simulating a strategy (belief → region → δ ~ ω), trajectories.
//! * [`export`] — the MDP for other model checkers: PRISM explicit files,
//!   JANI and Storm's DRN, with the queries of its front.
//! * [`synthetic`] — seeded synthetic layered MDPs for benchmarks at scale.
//! * [`exec`] — how parallel work runs: the one [`exec::Executor`] (a rayon
//!   pool and the ranks of a job), passed in, its units back in unit order.
//!
//! Pure maths: no I/O, no clock. Progress is reported through a callback so the
//! front end can draw a bar.

pub mod abstraction;
pub mod certify;
pub mod constant;
pub mod exec;
pub mod export;
pub mod mdp;
pub mod pareto;
pub mod predict;
pub mod records;
pub mod report;
pub mod simulate;
pub mod synthetic;
pub mod validate;
