//! The radio's closed forms and statistics, with fixed seeds and interval
//! tolerances (docs/MODEL.md §8).

use super::*;
use crate::etkf::standard_normal;
use crate::rng::stream_rng;
use rand::Rng;

const DELTAS: [f64; 6] = [0.0, 5e-5, 0.5, 1.0518, 1.4986, 2.2365];

fn link(loss: f64, retries: i64, burst: Option<f64>) -> Link {
    let f = LinkFields {
        loss: "loss",
        retries: "retries",
        burst: "burst",
    };
    Link::checked(loss, retries, burst, f).expect("valid link")
}

/// Mean and 95 % half-width of a sample.
fn mean_ci(sum: f64, sum_sq: f64, n: f64) -> (f64, f64) {
    let mean = sum / n;
    let var = (sum_sq / n - mean * mean).max(0.0);
    (mean, 1.96 * (var / n).sqrt())
}

#[test]
fn beta_lossy_is_beta_at_q_zero_and_zero_at_q_one() {
    for &d in &DELTAS {
        for m in 1..=6 {
            assert_eq!(
                beta_lossy(d, m, 0.0).to_bits(),
                gaussian::beta(d).to_bits(),
                "δ = {d}, m = {m}"
            );
            assert_eq!(beta_lossy(d, m, 1.0).to_bits(), 0.0f64.to_bits());
        }
    }
    // δ = 0 and q > 0: every step triggers, so silence is always a loss.
    for q in [1e-9, 0.1, 0.5] {
        assert_eq!(beta_lossy(0.0, 2, q), 0.0);
    }
}

#[test]
fn beta_lossy_falls_with_q_and_stays_in_zero_beta() {
    for &d in &DELTAS[2..] {
        let mut prev = gaussian::beta(d);
        for i in 1..=20 {
            let q = f64::from(i) * 0.05;
            let b = beta_lossy(d, 2, q);
            assert!((0.0..=prev).contains(&b), "δ = {d}, q = {q}: {b} > {prev}");
            prev = b;
        }
        // The quotient tends to β as q → 0.
        assert!((beta_lossy(d, 2, 1e-12) - gaussian::beta(d)).abs() < 1e-9);
    }
}

/// c = 1 − β_q is the per-axis second moment of ε given "no packet received":
/// ε ~ N(0, I₂), trigger ‖ε‖∞ > δ, the trigger's packet lost with probability q.
#[test]
fn c_is_the_variance_of_the_innovation_given_no_packet() {
    let mut rng = stream_rng(2026, 99, 0);
    for &delta in &[0.5, 1.0518, 1.4986, 2.2365] {
        for &q in &[0.1, 0.3, 0.7] {
            let (mut n, mut s, mut ss, mut cross) = (0.0, 0.0, 0.0, 0.0);
            for _ in 0..200_000 {
                let e = standard_normal::<2, _>(&mut rng);
                let triggered = e.amax() > delta;
                let lost = rng.random::<f64>() < q;
                if triggered && !lost {
                    continue;
                }
                for i in 0..2 {
                    s += e[i] * e[i];
                    ss += e[i].powi(4);
                }
                cross += e[0] * e[1];
                n += 1.0;
            }
            // Pooled over both axes (2n values; they are dependent through the
            // box, so the half-width is widened by √2).
            let (mean, ci) = mean_ci(s, ss, 2.0 * n);
            let c = 1.0 - beta_lossy(delta, 2, q);
            assert!(ci < 0.02, "δ = {delta}, q = {q}: too few samples ({n})");
            assert!(
                (mean - c).abs() < 1.5 * ci,
                "δ = {delta}, q = {q}: measured {mean} ± {ci}, formula {c}"
            );
            // The mean is unchanged and the axes stay uncorrelated.
            assert!((cross / n).abs() < 4.0 * (c / n).sqrt() + 1e-3, "{cross}");
        }
    }
}

#[test]
fn link_checks_name_the_field() {
    let f = LinkFields {
        loss: "radio.loss",
        retries: "radio.retries",
        burst: "radio.burst",
    };
    for (loss, retries, burst, field) in [
        (1.0, 0, None, "radio.loss"),
        (-0.1, 0, None, "radio.loss"),
        (f64::NAN, 0, None, "radio.loss"),
        (0.2, -1, None, "radio.retries"),
        (0.2, 1001, None, "radio.retries"),
        (0.2, 0, Some(0.5), "radio.burst"),
        (0.2, 0, Some(f64::INFINITY), "radio.burst"),
        // B/(1 + B) = 0.6 at B = 1.5.
        (0.61, 0, Some(1.5), "radio.burst"),
    ] {
        let e = Link::checked(loss, retries, burst, f).expect_err("refused");
        assert_eq!(e.field, field, "{e}");
    }
    assert!(Link::checked(0.6, 0, Some(1.5), f).is_ok());
    assert!(Link::checked(0.0, 0, None, f).expect("ok").is_ideal());
}

#[test]
fn an_ideal_link_draws_nothing_and_always_delivers() {
    let mut ch = LinkChannel::new(Link::IDEAL, stream_rng(1, 2, 3));
    for k in 1..100 {
        ch.advance_to(k);
        assert_eq!(
            ch.transmit(),
            Transmission {
                attempts: 1,
                delivered: true
            }
        );
    }
    assert_eq!(ch.rng.next_u64(), stream_rng(1, 2, 3).next_u64());
    let mut ep = EpisodeChannels::new(&Radio::ideal(3), 1, 2, 3);
    assert!(ep.is_ideal());
    ep.start_step();
    assert!(ep.transmit(2).delivered);
}

/// attempts = delivered + lost exactly; retries' attempts per trigger and
/// residual loss match `Σ_{j=0..r} loss^j` and `loss^(1+r)`.
#[test]
fn retries_match_their_formulas_and_attempts_add_up() {
    for (loss, retries) in [(0.3, 0), (0.3, 2), (0.2, 1), (0.6, 3)] {
        let l = link(loss, retries, None);
        let mut ch = LinkChannel::new(l, stream_rng(7, 8, retries as u64));
        let n = 200_000u64;
        let (mut attempts, mut delivered, mut lost, mut sq) = (0u64, 0u64, 0u64, 0.0);
        for _ in 0..n {
            let t = ch.transmit();
            assert!(t.attempts >= 1 && t.attempts <= 1 + l.retries);
            attempts += u64::from(t.attempts);
            delivered += u64::from(t.delivered);
            lost += u64::from(t.lost());
            sq += f64::from(t.attempts).powi(2);
        }
        assert_eq!(attempts, delivered + lost);
        let (mean, ci) = mean_ci(attempts as f64, sq, n as f64);
        assert!(
            (mean - l.expected_attempts()).abs() <= ci.max(1e-12),
            "loss {loss} retries {retries}: {mean} ± {ci} vs {}",
            l.expected_attempts()
        );
        let q = l.residual_loss();
        assert_eq!(q, loss.powi(1 + retries as i32));
        let measured = (n - delivered) as f64 / n as f64;
        let ci = 2.58 * (q * (1.0 - q) / n as f64).sqrt();
        assert!((measured - q).abs() < ci, "{measured} vs {q} ± {ci}");
    }
}

/// Gilbert–Elliott: the fraction of steps in Bad is `loss` and bursts of lost
/// steps last `burst` steps on average; retries never help inside a burst.
#[test]
fn gilbert_elliott_loss_rate_and_burst_length_match() {
    for (loss, burst, retries) in [(0.3, 4.0, 0), (0.2, 5.0, 2), (0.5, 1.5, 1)] {
        let l = link(loss, retries, Some(burst));
        assert_eq!(l.residual_loss(), loss);
        let episodes = 400;
        let steps = 500u64;
        let (mut lost_steps, mut total, mut bursts, mut attempts, mut delivered) =
            (0u64, 0u64, 0u64, 0u64, 0u64);
        for e in 0..episodes {
            let mut ch = LinkChannel::new(l, stream_rng(11, 12, e));
            let mut was_lost = false;
            for k in 1..=steps {
                ch.advance_to(k);
                let t = ch.transmit();
                attempts += u64::from(t.attempts);
                delivered += u64::from(t.delivered);
                if !t.delivered {
                    assert_eq!(t.attempts, 1 + l.retries);
                    lost_steps += 1;
                    bursts += u64::from(!was_lost);
                }
                was_lost = !t.delivered;
                total += 1;
            }
        }
        let rate = lost_steps as f64 / total as f64;
        // Correlated steps: allow a generous (but tight in absolute terms) band.
        assert!((rate - loss).abs() < 0.02, "loss {loss} B {burst}: {rate}");
        let mean_burst = lost_steps as f64 / bursts as f64;
        assert!(
            (mean_burst - burst).abs() < 0.05 * burst,
            "loss {loss} B {burst}: mean burst {mean_burst}"
        );
        assert!(
            (attempts as f64 / total as f64 - l.expected_attempts()).abs() < 0.05,
            "attempts per trigger"
        );
        assert_eq!(total - delivered, lost_steps);
    }
}

/// Catching up the state lazily gives the states of advancing every step.
#[test]
fn lazy_advance_equals_advancing_every_step() {
    let l = link(0.3, 1, Some(4.0));
    let mut eager = LinkChannel::new(l, stream_rng(3, 4, 5));
    let mut lazy = LinkChannel::new(l, stream_rng(3, 4, 5));
    for k in 1..=2000u64 {
        eager.advance_to(k);
        if k % 7 == 0 || k % 11 == 0 {
            lazy.advance_to(k);
            assert_eq!(lazy.is_bad(), eager.is_bad(), "step {k}");
            assert_eq!(lazy.transmit(), eager.transmit());
        }
    }
}

#[test]
fn episode_links_have_their_own_streams() {
    let radio = Radio {
        estimator: Estimator::Aware,
        links: vec![link(0.5, 0, None); 2],
    };
    let fates = |ep: &mut EpisodeChannels, s: usize| -> Vec<bool> {
        (0..64)
            .map(|_| {
                ep.start_step();
                ep.transmit(s).delivered
            })
            .collect()
    };
    let mut a = EpisodeChannels::new(&radio, 1, 2, 0);
    let mut b = EpisodeChannels::new(&radio, 1, 2, 0);
    let mut c = EpisodeChannels::new(&radio, 1, 2, 1);
    let a0 = fates(&mut a, 0);
    assert_eq!(a0, fates(&mut b, 0), "same (seed, stream, episode, link)");
    assert_ne!(a0, fates(&mut a, 1), "another link");
    assert_ne!(a0, fates(&mut c, 0), "another episode");
}

#[test]
fn overrides_replace_every_link_and_are_checked() {
    let radio = Radio {
        estimator: Estimator::Naive,
        links: vec![link(0.1, 0, None), link(0.2, 3, Some(2.0))],
    };
    let o = RadioOverride {
        loss: Some(0.3),
        retries: None,
        burst: None,
        estimator: Some(Estimator::Aware),
    };
    let r = radio.overridden(&o).expect("valid");
    assert_eq!(r.estimator, Estimator::Aware);
    assert_eq!(r.links[0], link(0.3, 0, None));
    assert_eq!(r.links[1], link(0.3, 3, Some(2.0)));
    let bad = RadioOverride {
        loss: Some(0.9),
        ..RadioOverride::default()
    };
    assert_eq!(radio.overridden(&bad).expect_err("burst").field, "--burst");
    // Retries or bursts on a channel that loses nothing are refused by name.
    for (o, field) in [
        (
            RadioOverride {
                retries: Some(1000),
                ..RadioOverride::default()
            },
            "--retries",
        ),
        (
            RadioOverride {
                loss: Some(0.0),
                burst: Some(3.0),
                ..RadioOverride::default()
            },
            "--burst",
        ),
    ] {
        let e = Radio::ideal(2).overridden(&o).expect_err("does nothing");
        assert_eq!(e.field, field);
        assert!(e.reason.contains("--loss"), "{e}");
    }
    let lossy = Radio::ideal(2)
        .overridden(&RadioOverride {
            loss: Some(0.2),
            ..RadioOverride::default()
        })
        .expect("lossy");
    assert!(
        lossy
            .overridden(&RadioOverride {
                retries: Some(2),
                ..RadioOverride::default()
            })
            .is_ok(),
        "retries on the scenario's own lossy channel"
    );
    let names = ["a".to_string(), "b".to_string()];
    assert_eq!(Radio::ideal(2).describe(&names), "ideal");
    assert!(
        r.describe(&names)
            .contains("b: loss 0.3, retries 3, burst 2")
    );
    // The aware factor uses q, the naive one β.
    let q = r.link(0).residual_loss();
    assert_eq!(r.silence_beta(0, 1.4986, 2), beta_lossy(1.4986, 2, q));
    let naive = Radio {
        estimator: Estimator::Naive,
        ..r
    };
    assert_eq!(naive.silence_beta(0, 1.4986, 2), gaussian::beta(1.4986));
}
