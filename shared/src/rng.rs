//! Reproducible random streams: every episode (or Monte Carlo sample) gets its
//! own generator derived from `(seed, stream, index)`, so results do not depend on
//! thread count or scheduling.

use rand::SeedableRng;
pub use rand_xoshiro::Xoshiro256PlusPlus as SimRng;

/// SplitMix64 finaliser: a bijective mixer with good avalanche.
pub const fn mix64(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// A uniform number on [0, 1) from the top 53 bits of a hash (exact: a
/// power-of-two scale), for draws that come from a key rather than a stream.
#[inline]
pub fn unit_f64(h: u64) -> f64 {
    (h >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
}

/// The generator for item `index` of stream `stream` under `seed`.
///
/// Streams separate independent uses of one seed (e.g. simulation vs. a
/// validation run) so they never share random numbers.
pub fn stream_rng(seed: u64, stream: u64, index: u64) -> SimRng {
    SimRng::seed_from_u64(mix64(mix64(seed ^ mix64(stream)) ^ index))
}

/// The generator of radio link `link` in episode `index` of stream `stream`
/// under `seed` (docs/MODEL.md §8): every (episode, link) pair has its own
/// stream, disjoint from the episode's own [`stream_rng`], so packet fates
/// never shift the plant's or the sensors' random numbers.
pub fn link_rng(seed: u64, stream: u64, index: u64, link: u64) -> SimRng {
    stream_rng(
        seed,
        streams::RADIO,
        mix64(mix64(mix64(stream) ^ index) ^ link),
    )
}

/// The generator of the trigger draws of sensor `sensor` in episode `index`
/// of stream `stream` under `seed` (the stochastic family, docs/MODEL.md §9):
/// disjoint from the episode's own [`stream_rng`] and from every
/// [`link_rng`], so a family that draws shifts no other random number.
pub fn trigger_rng(seed: u64, stream: u64, index: u64, sensor: u64) -> SimRng {
    stream_rng(
        seed,
        streams::TRIGGER,
        mix64(mix64(mix64(stream) ^ index) ^ sensor),
    )
}

/// Named streams used across the project.
pub mod streams {
    /// `etp simulate` episodes.
    pub const SIMULATE: u64 = 1;
    /// `etp validate` episodes.
    pub const VALIDATE: u64 = 2;
    /// Monte Carlo abstraction samples.
    pub const SYNTHESIS: u64 = 3;
    /// Multi-process runtime: agent plant and initial state.
    pub const AGENT: u64 = 4;
    /// Multi-process runtime: sensor measurement noise.
    pub const SENSOR: u64 = 5;
    /// Coordinator threshold draws.
    pub const COORDINATOR: u64 = 6;
    /// Held-out abstraction samples (cross-fitting, docs/MODEL.md §4.1): the
    /// same segment indices as [`SYNTHESIS`] under another stream, so the two
    /// sample sets share no random numbers.
    pub const HOLDOUT: u64 = 7;
    /// Radio packet fates, one generator per (stream, episode, link): see
    /// [`super::link_rng`].
    pub const RADIO: u64 = 8;
    /// Trigger draws of the stochastic family, one generator per (stream,
    /// episode, sensor): see [`super::trigger_rng`].
    pub const TRIGGER: u64 = 9;
}
