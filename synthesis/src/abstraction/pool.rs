//! Bounded, deterministic particle pools.
//!
//! The pool of decision point i + 1 is a uniform sample (without replacement)
//! of the beliefs that arrived there, drawn separately per region so that every
//! region that was reached keeps at least one particle. It is a *bottom-k*
//! sample: every arrival carries a pseudo-random key (a hash of its segment id),
//! and a region keeps the `cap` arrivals with the smallest keys. The result does
//! not depend on the order in which arrivals are merged, hence not on threads.

use etp_shared::rng::mix64;

/// Salt separating reservoir keys from the segment's random stream.
const KEY_SALT: u64 = 0x5EED_0FB0_770A_1E00;

/// The reservoir key of segment `id`.
#[inline]
pub(super) fn key(id: u64) -> u64 {
    mix64(id ^ KEY_SALT)
}

/// Keep the `cap` items with the smallest keys, in key order.
pub(super) fn bottom_k<T>(mut items: Vec<(u64, T)>, cap: usize) -> Vec<T> {
    let cap = cap.max(1);
    if items.len() > cap {
        items.select_nth_unstable_by_key(cap - 1, |x| x.0);
        items.truncate(cap);
    }
    // Stable sort on the key: equal keys (practically never) keep merge order.
    items.sort_by_key(|x| x.0);
    items.into_iter().map(|x| x.1).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use etp_shared::etkf::Belief;
    use etp_shared::etkf::{Matrix, Vector};

    fn b(v: f64) -> Belief<1> {
        Belief {
            mean: Vector::<1>::new(v),
            cov: Matrix::<1, 1>::new(1.0),
        }
    }

    #[test]
    fn keeps_the_smallest_keys_whatever_the_order() {
        let items: Vec<(u64, Belief<1>)> = (0..100u64).map(|i| (key(i), b(i as f64))).collect();
        let mut reversed = items.clone();
        reversed.reverse();
        let a = bottom_k(items.clone(), 10);
        let r = bottom_k(reversed, 10);
        assert_eq!(a, r);
        assert_eq!(a.len(), 10);
        let mut keys: Vec<u64> = items.iter().map(|x| x.0).collect();
        keys.sort_unstable();
        let kept: Vec<u64> = a.iter().map(|p| key(p.mean[0] as u64)).collect();
        assert_eq!(kept, keys[..10].to_vec());
        assert_eq!(bottom_k(items[..3].to_vec(), 10).len(), 3);
    }
}
