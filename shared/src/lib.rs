//! `etp-shared`: the vocabulary every etpareto process shares.
//!
//! A short tour, in the order data flows:
//!
//! * [`scenario::Scenario`] — a validated scenario (plant, sensors, route, target,
//!   obstacles, thresholds Δ), loaded from TOML or a built-in name.
//! * [`etkf::EtKalmanFilter`] — the event-triggered Kalman filter of docs/MODEL.md §2
//!   for fixed dimensions `N ≤ 6`, `M ≤ 6`: prediction, whitened innovation,
//!   ∞-norm trigger, explicit (Joseph) and implicit (β(δ)) updates.
//! * [`gaussian`] — φ, Φ, β(δ), the expected rate γ̄(δ) and its inverse.
//! * [`trigger::TriggerFamily`] — the trigger families of docs/MODEL.md §9
//!   (box, stochastic, send-on-delta, variance, periodic): each one's
//!   decision, silence update, expected rate and lossy-radio moments.
//! * [`episode::CompiledScenario`] — the scenario in fixed-size form with the
//!   episode rules of docs/MODEL.md §3 (controller, collision, leg termination,
//!   target/free classification): [`episode::CompiledScenario::run_leg`] and
//!   [`episode::CompiledScenario::run_episode`].
//! * [`radio`] — the lossy, acknowledged radio of docs/MODEL.md §8: per-link
//!   channels (independent or Gilbert–Elliott losses, retries), β_q(δ) for the
//!   aware silence update, and each attempt's fate from its own stream.
//! * [`drift`] — sequential tests (CUSUM, a false-alarm rate per run
//!   derived, not tuned) of a run's attempts and triggers against the
//!   channel and trigger it was synthesized for (docs/MODEL.md §11).
//! * [`rng`] — reproducible per-episode random streams (`Xoshiro256++`).
//! * [`stats`] — confidence intervals for means and proportions.
//! * [`episode::agent_core`] — `AgentCore`, THE step of docs/MODEL.md §3/§7
//!   written once (input, move, collision, prior, the served slot's update,
//!   the leg end): a pure state machine driven by the in-process leg loop,
//!   the agent process, `replay verify` and the sensor's replica
//!   ([`episode::replica`], which the serving sensor runs from one handover
//!   per leg); [`episode::step`] the pieces it orders and `serve_slot`, the
//!   sensor's side of a slot.
//! * [`strategy`] — `strategy.json` (format 2): a `Strategy` is its policy
//!   (scenario, Δ, discretization, ω per state, optional splits, the
//!   embedded scenario text and channel), its predictions (`predicted` first,
//!   certified bounds, the aggregation check, diagnostics) and its
//!   provenance; written through one flat layout whose key order is the
//!   file's, and sealed by a hash of its text.
//! * [`discretization`] — covariance regions (Method 2), the workspace
//!   descriptor and its lookahead map, and `RegionSplit`, the one
//!   refinement used by synthesis, validation and the coordinator.
//! * [`structured`] and [`dense`] — fast products (gathers for a selecting
//!   H, unrolled fixed-size products) that give nalgebra's results bit for
//!   bit; `linalg::deterministic_eigen` fixes the whitening basis the
//!   ∞-norm trigger depends on.
//!
//! The runtime's payloads, services and recordings live in `etp-runtime`,
//! which depends on this crate and never the other way round.
//!
//! Everything here is pure: no I/O, no clock, randomness only through the RNG
//! the caller passes in, so every result is reproducible from a seed.

pub mod controller;
pub mod dense;
pub mod discretization;
pub mod dispatch;
pub mod drift;
pub mod episode;
pub mod etkf;
pub mod gaussian;
pub mod geometry;
pub mod linalg;
pub mod lqr;
pub mod radio;
pub mod rng;
pub mod scenario;
pub mod stats;
pub mod strategy;
pub mod structured;
pub mod trigger;
