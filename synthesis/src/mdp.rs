//! The finite, acyclic MDP of the belief abstraction (docs/MODEL.md §4) and its file
//! format `mdp.bin`.
//!
//! Layout invariant (checked by [`Mdp::check`]): states are sorted by decision
//! point; every transition from a state at decision point i goes to a state at
//! decision point i + 1 or to a terminal. Backward induction is therefore one
//! pass over the states in reverse order.
//!
//! File (format version [`MDP_FORMAT_VERSION`]): the 8-byte magic `ETPMDP\0\n`, a little-endian
//! `u32` format version, the bincode 2.0.1 (serde, standard config) encoding
//! of [`Mdp`], then the SHA-256 of everything before it (32 bytes), so a
//! flipped bit or a cut file is refused before anything is decoded (version 1
//! had no checksum: 4 of 8 random bit flips decoded into another valid MDP).

use etp_shared::discretization::{Discretization, Region, RegionSplit};
use serde::{Deserialize, Serialize};

/// Version of the `mdp.bin` layout (2: a SHA-256 of the content at the end;
/// 3: decision-point bins carry the optional workspace-marginal descriptor;
/// 4: per choice the energy's second moment and range (certified bounds) and
/// the held-out sample set (cross-fitting), docs/MODEL.md §4.1;
/// 5: the workspace descriptor's lookahead and range rule in the build settings;
/// 6: the lumping level; 7: the regions split by `--split-budget`).
pub const MDP_FORMAT_VERSION: u32 = 7;

/// The file name of a synthesis's MDP inside its output folder (`etp
/// synthesize` writes it there; `strategy`, `export` and `demo` read it).
pub const MDP_FILE: &str = "mdp.bin";
const MAGIC: &[u8; 8] = b"ETPMDP\0\n";
/// Magic and version.
const HEADER_LEN: usize = 12;
/// The SHA-256 at the end of the file.
const CHECKSUM_LEN: usize = 32;

/// Why an MDP file was refused.
#[derive(Debug, thiserror::Error)]
pub enum MdpError {
    #[error("not an etp MDP file (bad magic; is it truncated or another file?)")]
    Magic,
    #[error("MDP format version {found} is not supported (this etp reads version {expected})")]
    Version { found: u32, expected: u32 },
    #[error(
        "mdp.bin is corrupted: checksum mismatch (SHA-256 of its content {computed:.12}…, \
         recorded {stored:.12}…): the file was truncated or changed; rerun `etp synthesize`"
    )]
    Checksum { stored: String, computed: String },
    #[error("MDP file is truncated or corrupted: {0}")]
    Decode(String),
    #[error("MDP is inconsistent: {0}")]
    Invalid(String),
}

/// Which abstraction built the MDP.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Method {
    /// Method 2: discretized covariance regions (the paper's contribution).
    Discretized,
    /// Method 1: enforced KF convergence near each waypoint (one state per decision point).
    KfConvergence,
}

/// Where a transition leads.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub enum Next {
    State(u32),
    Collision,
    Target,
    Free,
}

/// One estimated transition with its sample count and 95 % interval.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Transition {
    pub next: Next,
    /// Segments (of [`Choice::samples`]) that ended here.
    pub count: u32,
    pub probability: f64,
    /// Wilson 95 % interval on the probability.
    pub ci_low: f64,
    pub ci_high: f64,
}

/// Which energy cost to optimise.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub enum CostModel {
    /// Mean of the transmissions counted in the simulated segments × c_m (default).
    #[default]
    Counted,
    /// The paper's `k̄(s, δ) γ̄(δ) c_m`.
    Paper,
}

/// Action `action` (index into [`Mdp::deltas`]) in a state.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Choice {
    pub action: u16,
    /// Simulated segments behind the estimates.
    pub samples: u32,
    /// Mean counted energy of a segment.
    pub cost_counted: f64,
    /// The paper's model `k̄ γ̄(δ) c_m`.
    pub cost_model: f64,
    /// Mean steps of a segment (k̄).
    pub mean_steps: f64,
    /// Sorted by `next`; probabilities sum to 1 (over the matched segments).
    pub transitions: Vec<Transition>,
    /// Segments (of `samples`) that arrived in a region without a state: only
    /// extra segments of sample allocation (`certify::refine`), which must not
    /// change the state space. The probabilities are over the others; the
    /// certified bounds count these as the worst outcome.
    pub unmatched: u32,
    /// Mean of the squared counted energy of a segment (its second moment).
    pub cost_sq_counted: f64,
    /// Mean of the squared paper-model energy of a segment.
    pub cost_sq_model: f64,
    /// A-priori bound on one segment's energy (`k_max · c_m`): every segment's
    /// cost lies in `[0, cost_range]` (the certified energy bound needs it).
    pub cost_range: f64,
    /// The held-out estimate of this choice from segments independent of
    /// those above (cross-fitting, docs/MODEL.md §4.1); `None` when the MDP was
    /// built without a held-out set.
    pub holdout: Option<Holdout>,
}

/// A choice re-estimated on held-out segments (stream `HOLDOUT`), over the
/// same states: used only to evaluate a strategy chosen on the main sample.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Holdout {
    pub samples: u32,
    pub cost_counted: f64,
    pub cost_model: f64,
    /// Segment counts per outcome, sorted by `next`.
    pub counts: Vec<(Next, u32)>,
    /// Segments that arrived in a region no state of the main sample occupies.
    pub unmatched: u32,
}

impl Holdout {
    pub fn cost(&self, model: CostModel) -> f64 {
        match model {
            CostModel::Counted => self.cost_counted,
            CostModel::Paper => self.cost_model,
        }
    }
}

impl Choice {
    pub fn cost(&self, model: CostModel) -> f64 {
        match model {
            CostModel::Counted => self.cost_counted,
            CostModel::Paper => self.cost_model,
        }
    }

    /// Mean of the squared segment energy under `model`.
    pub fn cost_sq(&self, model: CostModel) -> f64 {
        match model {
            CostModel::Counted => self.cost_sq_counted,
            CostModel::Paper => self.cost_sq_model,
        }
    }
}

/// An abstract state: a decision point and the covariance region of the belief.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct State {
    pub decision_point: u32,
    pub region: Region,
    /// Further regions lumped into this state (`etp synthesize --merge`,
    /// [`crate::abstraction::merge_equivalent`]); empty unless merged.
    pub merged: Vec<Region>,
    /// Available actions (at least one).
    pub choices: Vec<Choice>,
}

/// Parameters of Method 1, stored for reproduction and the runtime.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct KfConvergenceParams {
    pub eps_kf: f64,
    pub eps_p: f64,
}

/// Settings of the abstraction not otherwise stored in the MDP.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct BuildSettings {
    pub magnitude_bins: u16,
    pub angle_bins: u16,
    pub pool_per_region: u32,
    /// 0 auto, 1 per-axis, 2 workspace marginal.
    pub descriptor: u8,
    pub rest_bins: u16,
    /// Lookahead steps of the workspace descriptor.
    pub lookahead: u32,
    /// The workspace descriptor's magnitude range: 0 propagation, 1 arrivals.
    pub range: u8,
    /// Level α at which statistically equivalent states were lumped
    /// (`--merge`); 0: not merged.
    pub merge_alpha: f64,
}

/// The abstraction.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Mdp {
    pub scenario_name: String,
    pub scenario_hash: String,
    pub method: Method,
    /// The actions Δ.
    pub deltas: Vec<f64>,
    /// Method 2's bins (None for Method 1).
    pub discretization: Option<Discretization>,
    /// Method 1's parameters (None for Method 2).
    pub kf_convergence: Option<KfConvergenceParams>,
    pub states: Vec<State>,
    pub initial: u32,
    /// Monte Carlo settings and totals.
    pub samples_per_choice: u32,
    /// Held-out segments per (state, action) (0: none; docs/MODEL.md §4.1).
    pub holdout_samples: u32,
    /// How many sample sizes per choice the union bound of the certified
    /// bounds must cover: 1, or 1 + the rounds of sample allocation (each
    /// round may double a choice's samples; docs/MODEL.md §4.1).
    pub looks: u32,
    /// The remaining settings of the build, so it can be repeated (sample
    /// allocation re-runs it with extra segments).
    pub build: BuildSettings,
    pub seed: u64,
    pub total_segments: u64,
    pub total_steps: u64,
    /// Regions split by the adaptive splitting of docs/MODEL.md §7.3 (empty:
    /// the descriptor's regions as binned). A state's region is its base
    /// region refined by these ([`Discretization::classify_split`]).
    pub splits: Vec<RegionSplit>,
}

/// Decoding never allocates more than this, whatever lengths a corrupted file claims.
const DECODE_LIMIT: usize = 1 << 30;

fn bincode_config() -> bincode::config::Configuration {
    bincode::config::standard()
}

fn bincode_decode_config() -> bincode::config::Configuration<
    bincode::config::LittleEndian,
    bincode::config::Varint,
    bincode::config::Limit<DECODE_LIMIT>,
> {
    bincode::config::standard().with_limit::<DECODE_LIMIT>()
}

impl Mdp {
    /// Number of decision points (legs).
    pub fn num_decision_points(&self) -> usize {
        self.states
            .last()
            .map_or(0, |s| s.decision_point as usize + 1)
    }

    /// Total transitions over all choices.
    pub fn num_transitions(&self) -> usize {
        self.states
            .iter()
            .flat_map(|s| &s.choices)
            .map(|c| c.transitions.len())
            .sum()
    }

    /// Per state, the sampled segments that arrived in it (Σ of the
    /// transition counts into it; 0 for the initial state): how many beliefs
    /// its region's statistics and pool rest on.
    pub fn arrivals_per_state(&self) -> Vec<u64> {
        let mut v = vec![0u64; self.states.len()];
        for s in &self.states {
            for c in &s.choices {
                for t in &c.transitions {
                    if let Next::State(i) = t.next
                        && let Some(a) = v.get_mut(i as usize)
                    {
                        *a += u64::from(t.count);
                    }
                }
            }
        }
        v
    }

    /// Whether some state offers fewer than all the thresholds: a build
    /// on one strategy's own thresholds (`etp synthesize --pool-policy`
    /// without `--all-actions`). Its front is not the scenario's; what it
    /// is for is predicting that strategy (`etp strategy evaluate`).
    pub fn policy_only(&self) -> bool {
        self.states
            .iter()
            .any(|s| s.choices.len() < self.deltas.len())
    }

    /// States per decision point.
    pub fn states_per_decision_point(&self) -> Vec<usize> {
        let mut v = vec![0; self.num_decision_points()];
        for s in &self.states {
            v[s.decision_point as usize] += 1;
        }
        v
    }

    /// The file bytes.
    pub fn encode(&self) -> Vec<u8> {
        // Encoding plain data into a Vec cannot fail.
        let body = bincode::serde::encode_to_vec(self, bincode_config()).unwrap_or_default();
        Self::file_of_body(&body)
    }

    /// The file whose bincode body is `body` (header and checksum added): lets
    /// the `mdp_decode` fuzz target reach the decoder behind the checksum.
    #[doc(hidden)]
    pub fn file_of_body(body: &[u8]) -> Vec<u8> {
        use sha2::{Digest, Sha256};
        let mut out = Vec::with_capacity(HEADER_LEN + body.len() + CHECKSUM_LEN);
        out.extend_from_slice(MAGIC);
        out.extend_from_slice(&MDP_FORMAT_VERSION.to_le_bytes());
        out.extend_from_slice(body);
        let digest = Sha256::digest(&out);
        out.extend_from_slice(&digest);
        out
    }

    /// Parse and check a file's bytes: magic, version, checksum, then the
    /// content and its invariants.
    pub fn decode(bytes: &[u8]) -> Result<Self, MdpError> {
        use sha2::{Digest, Sha256};
        if bytes.len() < HEADER_LEN || &bytes[..8] != MAGIC {
            return Err(MdpError::Magic);
        }
        let version = u32::from_le_bytes([bytes[8], bytes[9], bytes[10], bytes[11]]);
        if version != MDP_FORMAT_VERSION {
            return Err(MdpError::Version {
                found: version,
                expected: MDP_FORMAT_VERSION,
            });
        }
        if bytes.len() < HEADER_LEN + CHECKSUM_LEN {
            return Err(MdpError::Decode(format!(
                "{} bytes: shorter than a header and a checksum",
                bytes.len()
            )));
        }
        let (content, stored) = bytes.split_at(bytes.len() - CHECKSUM_LEN);
        let computed = Sha256::digest(content);
        if computed.as_slice() != stored {
            let hex = |b: &[u8]| b.iter().map(|x| format!("{x:02x}")).collect::<String>();
            return Err(MdpError::Checksum {
                stored: hex(stored),
                computed: hex(&computed),
            });
        }
        let body = &content[HEADER_LEN..];
        let (mdp, used): (Self, usize) =
            bincode::serde::decode_from_slice(body, bincode_decode_config())
                .map_err(|e| MdpError::Decode(e.to_string()))?;
        if used != body.len() {
            return Err(MdpError::Decode(format!(
                "{} trailing bytes after the MDP",
                body.len() - used
            )));
        }
        mdp.check()?;
        Ok(mdp)
    }

    /// The structural invariants: sorted, acyclic layering, distributions.
    pub fn check(&self) -> Result<(), MdpError> {
        let bad = |m: String| Err(MdpError::Invalid(m));
        if self.states.is_empty() {
            return bad("no states".into());
        }
        if !self.splits.is_empty() {
            let Some(d) = &self.discretization else {
                return bad("splits without a discretization".into());
            };
            etp_shared::discretization::check_splits(&self.splits, d).map_err(MdpError::Invalid)?;
        }
        if self.initial as usize >= self.states.len()
            || self.states[self.initial as usize].decision_point != 0
        {
            return bad("initial state missing or not at decision point 0".into());
        }
        for (i, s) in self.states.iter().enumerate() {
            if i > 0 && s.decision_point < self.states[i - 1].decision_point {
                return bad(format!("states not sorted by decision point at {i}"));
            }
            if s.choices.is_empty() {
                return bad(format!("state {i} has no action"));
            }
            for c in &s.choices {
                if c.unmatched > c.samples {
                    return bad(format!("state {i}: more unmatched segments than samples"));
                }
                if c.action as usize >= self.deltas.len() {
                    return bad(format!("state {i}: action {} out of range", c.action));
                }
                if !(c.cost_counted.is_finite() && c.cost_counted >= 0.0) {
                    return bad(format!("state {i}: cost {}", c.cost_counted));
                }
                let mut sum = 0.0;
                for t in &c.transitions {
                    if let Next::State(j) = t.next {
                        let ok = (j as usize) < self.states.len()
                            && self.states[j as usize].decision_point == s.decision_point + 1;
                        if !ok {
                            return bad(format!(
                                "state {i}: transition to {j} breaks the layering"
                            ));
                        }
                    }
                    if !(t.probability.is_finite() && (0.0..=1.0).contains(&t.probability)) {
                        return bad(format!("state {i}: probability {}", t.probability));
                    }
                    sum += t.probability;
                }
                // No transition at all only when every segment was unmatched.
                let all_unmatched = c.unmatched > 0 && c.unmatched == c.samples;
                if !(c.transitions.is_empty() && all_unmatched) && (sum - 1.0).abs() > 1e-9 {
                    return bad(format!(
                        "state {i}, action {}: probabilities sum to {sum}",
                        c.action
                    ));
                }
            }
        }
        Ok(())
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// A two-decision-point MDP with known values, for tests of the MDP users.
    pub(crate) fn toy() -> Mdp {
        let t = |next, p: f64| Transition {
            next,
            count: (p * 100.0) as u32,
            probability: p,
            ci_low: p,
            ci_high: p,
        };
        let choice = |action, cost, transitions| Choice {
            action,
            samples: 100,
            cost_counted: cost,
            cost_model: cost,
            mean_steps: 10.0,
            transitions,
            cost_sq_counted: cost * cost,
            cost_sq_model: cost * cost,
            cost_range: 20.0,
            holdout: None,
            unmatched: 0,
        };
        Mdp {
            scenario_name: "toy".into(),
            scenario_hash: "0".repeat(64),
            method: Method::Discretized,
            deltas: vec![0.0, 2.0],
            discretization: None,
            kf_convergence: None,
            states: vec![
                State {
                    decision_point: 0,
                    region: Region(vec![(0, 0)]),
                    merged: Vec::new(),
                    choices: vec![
                        choice(
                            0,
                            10.0,
                            vec![t(Next::State(1), 0.9), t(Next::Collision, 0.1)],
                        ),
                        choice(
                            1,
                            2.0,
                            vec![t(Next::State(2), 0.7), t(Next::Collision, 0.3)],
                        ),
                    ],
                },
                State {
                    decision_point: 1,
                    region: Region(vec![(0, 0)]),
                    merged: Vec::new(),
                    choices: vec![
                        choice(0, 10.0, vec![t(Next::Target, 0.95), t(Next::Free, 0.05)]),
                        choice(1, 2.0, vec![t(Next::Target, 0.6), t(Next::Collision, 0.4)]),
                    ],
                },
                State {
                    decision_point: 1,
                    region: Region(vec![(5, 0)]),
                    merged: Vec::new(),
                    choices: vec![
                        choice(0, 12.0, vec![t(Next::Target, 0.9), t(Next::Free, 0.1)]),
                        choice(1, 2.0, vec![t(Next::Target, 0.5), t(Next::Collision, 0.5)]),
                    ],
                },
            ],
            initial: 0,
            samples_per_choice: 100,
            holdout_samples: 0,
            looks: 1,
            build: BuildSettings::default(),
            seed: 0,
            total_segments: 600,
            total_steps: 6000,
            splits: Vec::new(),
        }
    }

    #[test]
    fn round_trip_and_refusals() {
        let m = toy();
        let bytes = m.encode();
        assert_eq!(Mdp::decode(&bytes).expect("round trip"), m);
        assert!(matches!(
            Mdp::decode(&bytes[..bytes.len() - 3]),
            Err(MdpError::Checksum { .. })
        ));
        assert!(matches!(
            Mdp::decode(&bytes[..20]),
            Err(MdpError::Decode(_))
        ));
        assert!(matches!(Mdp::decode(b"hello"), Err(MdpError::Magic)));
        let mut v = bytes.clone();
        // Another version (6: written before splits were stored) is refused.
        v[8] = 6;
        assert!(matches!(
            Mdp::decode(&v),
            Err(MdpError::Version { found: 6, .. })
        ));
        // The checksum passes, the content does not (a bug, not a flip).
        let mut broken = toy();
        broken.states[0].choices[0].transitions[0].next = Next::State(0);
        assert!(matches!(
            Mdp::decode(&broken.encode()),
            Err(MdpError::Invalid(_))
        ));
    }

    /// Every bit of the file, flipped alone, is refused: a header bit by the
    /// magic or version check, any other by the checksum (version 1 accepted
    /// 4 of 8 flips, one renaming the scenario).
    #[test]
    fn every_single_bit_flip_is_refused() {
        let bytes = toy().encode();
        for bit in 0..bytes.len() * 8 {
            let mut v = bytes.clone();
            v[bit / 8] ^= 1 << (bit % 8);
            match Mdp::decode(&v) {
                Err(MdpError::Magic) => assert!(bit < 64, "bit {bit}"),
                Err(MdpError::Version { .. }) => assert!((64..96).contains(&bit), "bit {bit}"),
                Err(MdpError::Checksum { .. }) => assert!(bit >= 96, "bit {bit}"),
                other => panic!("bit {bit} flipped: {other:?}"),
            }
        }
        let e = Mdp::decode(&bytes[..bytes.len() - 1])
            .expect_err("cut")
            .to_string();
        assert!(
            e.starts_with("mdp.bin is corrupted: checksum mismatch"),
            "{e}"
        );
    }
}
