//! Cross-fitting's held-out sample set and sample allocation's extra segments
//! (docs/MODEL.md §4.1): disjoint random streams, and the main sample, the
//! states and the pools untouched by either.

use etp_shared::rng::{stream_rng, streams};
use etp_shared::scenario::Scenario;
use etp_synthesis::abstraction::{self, AbstractionParams, build_with_extra, params_of};
use etp_synthesis::mdp::Mdp;
use rand::RngExt;
use std::collections::HashSet;

fn build(holdout: u32) -> Mdp {
    let s = Scenario::builtin("winding-2d").expect("built-in");
    let p = AbstractionParams {
        samples: 60,
        holdout_samples: holdout,
        seed: 5,
        ..AbstractionParams::default()
    };
    abstraction::build(&s, &p, &|_: u64| {}).expect("builds")
}

/// The main sample without its held-out parts (to compare two builds).
fn main_part(m: &Mdp) -> Mdp {
    let mut m = m.clone();
    m.holdout_samples = 0;
    m.total_segments = 0;
    m.total_steps = 0;
    for s in &mut m.states {
        for c in &mut s.choices {
            c.holdout = None;
        }
    }
    m
}

#[test]
fn held_out_set_leaves_the_main_sample_unchanged_and_is_independent() {
    let plain = build(0);
    let with = build(60);
    assert_eq!(main_part(&plain), main_part(&with));
    assert_eq!(with.holdout_samples, 60);
    let mut differ = 0;
    for s in &with.states {
        for c in &s.choices {
            let h = c.holdout.as_ref().expect("held out");
            assert_eq!(h.samples, 60);
            let total: u32 = h.counts.iter().map(|x| x.1).sum::<u32>() + h.unmatched;
            assert_eq!(total, 60);
            let main: Vec<_> = c.transitions.iter().map(|t| (t.next, t.count)).collect();
            differ += usize::from(main != h.counts);
        }
    }
    assert!(differ > 0, "held-out counts repeat the main ones");
}

#[test]
fn synthesis_and_holdout_streams_share_no_generator() {
    // Fingerprint each generator by its first two outputs: over 10⁵ indices
    // (and the same indices mixed like segment ids) no generator of one
    // stream equals one of the other.
    let first = |stream: u64, i: u64| {
        let mut r = stream_rng(5, stream, i);
        (r.random::<u64>(), r.random::<u64>())
    };
    let ids: Vec<u64> = (0..50_000)
        .chain((0..50_000).map(etp_shared::rng::mix64))
        .collect();
    let main: HashSet<(u64, u64)> = ids.iter().map(|&i| first(streams::SYNTHESIS, i)).collect();
    assert_eq!(main.len(), ids.len());
    for &i in &ids {
        assert!(!main.contains(&first(streams::HOLDOUT, i)), "index {i}");
    }
}

#[test]
fn extra_segments_change_only_their_choice() {
    let s = Scenario::builtin("winding-2d").expect("built-in");
    let base = build(0);
    let mut extra: Vec<Vec<u32>> = base
        .states
        .iter()
        .map(|s| vec![0; s.choices.len()])
        .collect();
    extra[0][1] = 60;
    let more = build_with_extra(&s, &params_of(&base), &extra, &|_: u64| {}).expect("builds");
    assert_eq!(more.states.len(), base.states.len());
    for (k, (a, b)) in more.states.iter().zip(&base.states).enumerate() {
        assert_eq!(a.region, b.region);
        for (c, (x, y)) in a.choices.iter().zip(&b.choices).enumerate() {
            if (k, c) == (0, 1) {
                assert_eq!(x.samples, 120);
                assert_ne!(x.transitions, y.transitions);
            } else {
                assert_eq!(x, y, "state {k} choice {c}");
            }
        }
    }
}
