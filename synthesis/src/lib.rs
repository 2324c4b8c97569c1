//! `etp-synthesis`: everything etpareto computes offline.
//!
//! * [`simulate`] — the in-process Monte Carlo episode simulator (parallel over
//!   episodes with rayon, reproducible from a seed whatever the thread count):
//!   [`simulate::simulate`] runs any threshold policy, [`simulate::SimulationSummary`]
//!   holds outcome frequencies, energy, steps and trigger rates with 95 % intervals.
//!
//! Pure maths: no I/O, no clock. Progress is reported through a callback so the
//! front end can draw a bar.

pub mod abstraction;
pub mod mdp;
pub mod pareto;
pub mod prism;
pub mod simulate;
