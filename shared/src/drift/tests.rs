use super::*;
use crate::radio::{Link, LinkChannel};
use crate::rng::stream_rng;
use rand::RngExt;

/// The binomial upper 99.9 % bound (normal approximation, +1 for small
/// counts) on alarms in `runs` runs at rate `alpha`.
fn most_alarms(runs: u64, alpha: f64) -> f64 {
    let n = runs as f64;
    n * alpha + 3.1 * (n * alpha * (1.0 - alpha)).sqrt() + 1.0
}

#[test]
fn the_cusum_is_the_largest_sum_over_every_start() {
    let mut rng = stream_rng(11, 0, 0);
    let llrs: Vec<f64> = (0..300).map(|_| rng.random::<f64>() - 0.55).collect();
    let mut c = Cusum::new();
    for n in 0..llrs.len() {
        let s = c.push(llrs[n]);
        let best = (0..=n)
            .map(|k| llrs[k..=n].iter().sum::<f64>())
            .fold(0.0_f64, f64::max);
        assert!((s - best).abs() < 1e-9, "n {n}: {s} against {best}");
        // The onset is the start of that sum.
        let k = n + 1 - c.since_onset() as usize;
        if c.since_onset() > 0 {
            assert!((llrs[k..=n].iter().sum::<f64>() - s).abs() < 1e-9);
        }
    }
}

#[test]
fn the_threshold_is_the_log_of_starts_times_tests_over_alpha() {
    let b = Budget {
        false_alarm: 0.01,
        horizon: 1000,
        tests: 3,
    };
    assert!((b.threshold() - (3.0e5_f64).ln()).abs() < 1e-12);
    assert!((bernoulli_kl(0.5, 0.5)).abs() < 1e-15);
    let kl = 0.6 * (0.6_f64 / 0.3).ln() + 0.4 * (0.4_f64 / 0.7).ln();
    assert!((bernoulli_kl(0.6, 0.3) - kl).abs() < 1e-15);
}

#[test]
fn a_lost_attempt_on_an_ideal_link_alarms_at_once_and_delivery_never_does() {
    let mut t = DeliveryTest::new(Link::IDEAL, 20.0);
    let ok = Transmission {
        attempts: 1,
        delivered: true,
    };
    for step in 0..10_000 {
        assert_eq!(t.observe(step, ok), None);
    }
    let lost = Transmission {
        attempts: 1,
        delivered: false,
    };
    let a = t.observe(10_000, lost).expect("an alarm");
    assert!(a.statistic.is_infinite());
    // More attempts than the link allows is as impossible.
    let mut t = DeliveryTest::new(
        Link {
            loss: 0.2,
            retries: 1,
            burst: None,
        },
        20.0,
    );
    let three = Transmission {
        attempts: 3,
        delivered: true,
    };
    assert!(t.observe(0, three).is_some());
}

/// Runs of at most `triggers` triggers on `link`, drawn by the run's own
/// sampler ([`LinkChannel`]) in episodes of 200 steps with a trigger at each
/// step with probability 0.3; from episode `change` on the channel is
/// `drifted`. Per run, the trigger index of the first alarm (if any) and the
/// index of the first trigger on the drifted channel.
fn first_alarms(
    link: Link,
    drifted: Link,
    change: u64,
    runs: u64,
    triggers: u64,
    alpha: f64,
) -> Vec<(Option<u64>, Option<u64>)> {
    let h = Budget {
        false_alarm: alpha,
        horizon: triggers,
        tests: ALTERNATIVES.len() as u64,
    }
    .threshold();
    (0..runs)
        .map(|run| {
            let mut test = DeliveryTest::new(link, h);
            let mut steps = stream_rng(5, 1, run);
            let (mut n, mut changed) = (0, None);
            for episode in 0.. {
                test.start_episode();
                let sampler = if episode >= change {
                    changed.get_or_insert(n);
                    drifted
                } else {
                    link
                };
                let mut ch = LinkChannel::new(sampler, stream_rng(5, 2, run * 100_000 + episode));
                for step in 0..200 {
                    if steps.random::<f64>() >= 0.3 {
                        continue;
                    }
                    ch.advance_to(step);
                    let t = ch.transmit();
                    if test.observe(step, t).is_some() {
                        return (Some(n), changed);
                    }
                    n += 1;
                    if n == triggers {
                        return (None, changed);
                    }
                }
            }
            (None, changed)
        })
        .collect()
}

#[test]
fn without_drift_independent_losses_alarm_less_often_than_the_budget_says() {
    let link = Link {
        loss: 0.3,
        retries: 1,
        burst: None,
    };
    let (runs, alpha) = (400, 0.2);
    let alarms = first_alarms(link, link, u64::MAX, runs, 2_000, alpha);
    let n = alarms.iter().filter(|a| a.0.is_some()).count();
    assert!(
        (n as f64) <= most_alarms(runs, alpha),
        "{n} of {runs} runs alarmed at α = {alpha}"
    );
}

#[test]
fn without_drift_bursts_alarm_less_often_than_the_budget_says() {
    let link = Link {
        loss: 0.2,
        retries: 2,
        burst: Some(4.0),
    };
    let (runs, alpha) = (400, 0.2);
    let alarms = first_alarms(link, link, u64::MAX, runs, 2_000, alpha);
    let n = alarms.iter().filter(|a| a.0.is_some()).count();
    assert!(
        (n as f64) <= most_alarms(runs, alpha),
        "{n} of {runs} runs alarmed at α = {alpha}"
    );
    // Read as independent losses, the same bursts look like drift: the
    // predictive law of the hidden state is what keeps the rate.
    let independent = Link {
        burst: None,
        ..link
    };
    let wrong = first_alarms(independent, link, 0, 100, 2_000, alpha);
    let n = wrong.iter().filter(|a| a.0.is_some()).count();
    assert!(n >= 50, "only {n} of 100 runs alarmed with the wrong model");
}

#[test]
fn more_loss_is_detected_after_the_change_within_walds_delay() {
    let link = Link {
        loss: 0.1,
        retries: 0,
        burst: None,
    };
    let drifted = Link { loss: 0.3, ..link };
    let (change, alpha, triggers) = (5, 0.01, 5_000);
    let alarms = first_alarms(link, drifted, change, 60, triggers, alpha);
    let h = Budget {
        false_alarm: alpha,
        horizon: triggers,
        tests: 3,
    }
    .threshold();
    // Against the alternative nearest the new loss (0.1 + 0.25 × 0.9), the
    // mean drift of ℓ per trigger under loss 0.3, so Wald's delay h / drift.
    let (p0, p1, q) = (0.1_f64, 0.325_f64, 0.3_f64);
    let drift = q * (p1 / p0).ln() + (1.0 - q) * ((1.0 - p1) / (1.0 - p0)).ln();
    let wald = h / drift;
    let mut delays: Vec<u64> = alarms
        .iter()
        .map(|&(alarm, changed)| {
            let (a, c) = (alarm.expect("every run alarms"), changed.expect("changed"));
            assert!(
                a >= c,
                "a false alarm at trigger {a}, before the change at {c}"
            );
            a - c
        })
        .collect();
    delays.sort_unstable();
    let median = delays[delays.len() / 2] as f64;
    assert!(
        median <= 1.5 * wald,
        "median delay {median} triggers against Wald's {wald:.0}"
    );
}

#[test]
fn the_burst_states_predictive_law_is_the_chains_power() {
    let link = Link {
        loss: 0.25,
        retries: 1,
        burst: Some(3.0),
    };
    let law = LinkLaw::new(link);
    let (to_good, to_bad) = link.transitions().expect("bursts");
    // The chain's d-step matrix by repeated multiplication.
    let step = |(bb, gb): (f64, f64)| {
        (
            bb * (1.0 - to_good) + (1.0 - bb) * to_bad,
            gb * (1.0 - to_good) + (1.0 - gb) * to_bad,
        )
    };
    let mut p = (1.0, 0.0); // P(Bad | Bad d ago), P(Bad | Good d ago)
    for d in 0..40u64 {
        let from_bad = law.bad_after(Some((true, 100)), 100 + d);
        let from_good = law.bad_after(Some((false, 100)), 100 + d);
        assert!((from_bad - p.0).abs() < 1e-12, "d {d}");
        assert!((from_good - p.1).abs() < 1e-12, "d {d}");
        p = step(p);
    }
    assert!((law.bad_after(None, 7) - 0.25).abs() < 1e-15);
}

#[test]
fn triggers_at_the_model_rate_rarely_alarm_and_a_doubled_rate_is_found() {
    let (runs, slots, alpha) = (300u64, 3_000u64, 0.2);
    let h = Budget {
        false_alarm: alpha,
        horizon: slots,
        tests: 2 * ALTERNATIVES.len() as u64,
    }
    .threshold();
    let run = |run: u64, rate: f64, actual: f64| {
        let mut rng = stream_rng(9, 3, run);
        let mut t = TriggerTest::new(h);
        (0..slots).find(|_| t.observe(rate, rng.random::<f64>() < actual).is_some())
    };
    let rate = crate::gaussian::expected_rate(1.5, 2);
    let false_alarms = (0..runs).filter(|&r| run(r, rate, rate).is_some()).count();
    assert!(
        (false_alarms as f64) <= most_alarms(runs, alpha),
        "{false_alarms} of {runs}"
    );
    for r in 0..50 {
        assert!(run(r, rate, 2.0 * rate).is_some(), "a doubled rate missed");
        assert!(
            run(r, rate, 0.3 * rate).is_some(),
            "a third of the rate missed"
        );
    }
}

/// winding-2d at δ = 1.5 on every leg, every link `link`, family `family`.
fn winding_with(link: Link, family: crate::trigger::TriggerFamily) -> crate::scenario::Scenario {
    let mut s = crate::scenario::Scenario::builtin("winding-2d").expect("built-in");
    for l in &mut s.radio.links {
        *l = link;
    }
    s.trigger = family;
    s
}

/// Runs of `episodes` episodes each on `s` with a fresh monitor per run at
/// rate `alpha`: how many runs raised any flag.
fn runs_flagged(s: &crate::scenario::Scenario, runs: u64, episodes: u64, alpha: f64) -> u64 {
    use crate::episode::{CompiledScenario, LegMode};
    use crate::etkf::Threshold;
    use crate::rng::streams;
    let c = CompiledScenario::<2>::new(s);
    let config = MonitorConfig {
        false_alarm: alpha,
        episodes,
    };
    (0..runs)
        .filter(|&run| {
            let mut obs = MonitorObserver::new(s, config);
            for e in 0..episodes {
                let index = run * episodes + e;
                obs.start_episode(e);
                c.run_episode(
                    |_, _, _| LegMode::EventTriggered(Threshold::new(1.5)),
                    &mut stream_rng(41, streams::SIMULATE, index),
                    &mut c.channels(41, streams::SIMULATE, index),
                    &mut obs,
                );
            }
            !obs.flags.is_empty()
        })
        .count() as u64
}

#[test]
fn the_monitor_on_the_synthesized_channel_flags_within_its_rate() {
    use crate::trigger::TriggerFamily;
    // Loss and triggers at once: 9 tests per sensor share α.
    let lossy = Link {
        loss: 0.3,
        retries: 1,
        burst: None,
    };
    let (runs, alpha) = (1000, 0.05);
    for (link, family) in [
        (Link::default(), TriggerFamily::Box),
        (Link::default(), TriggerFamily::Stochastic),
        (lossy, TriggerFamily::Stochastic),
        (lossy, TriggerFamily::Box),
        (
            Link {
                burst: Some(3.0),
                ..lossy
            },
            TriggerFamily::Stochastic,
        ),
    ] {
        let s = winding_with(link, family);
        let flagged = runs_flagged(&s, runs, 20, alpha);
        assert!(
            (flagged as f64) <= most_alarms(runs, alpha),
            "{family:?} {link:?}: {flagged} of {runs} runs flagged at α = {alpha}"
        );
    }
}

#[test]
fn the_monitor_flags_a_sensor_whose_link_is_not_the_model() {
    use crate::trigger::TriggerFamily;
    // The model says loss 0.1; the channel loses 0.5: the loss flag in
    // every run, naming the sensor that serves, raised once.
    let model = winding_with(
        Link {
            loss: 0.1,
            retries: 1,
            burst: None,
        },
        TriggerFamily::Stochastic,
    );
    let truth = winding_with(
        Link {
            loss: 0.5,
            retries: 1,
            burst: None,
        },
        TriggerFamily::Stochastic,
    );
    use crate::episode::{CompiledScenario, LegMode};
    use crate::etkf::Threshold;
    use crate::rng::streams;
    let c = CompiledScenario::<2>::new(&truth);
    let config = MonitorConfig {
        false_alarm: 0.01,
        episodes: 50,
    };
    for run in 0..10 {
        let mut obs = MonitorObserver::new(&model, config);
        for e in 0..50 {
            obs.start_episode(e);
            c.run_episode(
                |_, _, _| LegMode::EventTriggered(Threshold::new(1.5)),
                &mut stream_rng(43, streams::SIMULATE, run * 50 + e),
                &mut c.channels(43, streams::SIMULATE, run * 50 + e),
                &mut obs,
            );
        }
        let loss: Vec<_> = obs
            .flags
            .iter()
            .filter(|f| f.quantity == Quantity::Loss)
            .collect();
        assert!(
            !loss.is_empty(),
            "run {run}: loss 0.5 against 0.1 not flagged"
        );
        let mut sensors: Vec<_> = loss.iter().map(|f| f.sensor).collect();
        sensors.dedup();
        assert_eq!(sensors.len(), loss.len(), "a flag raised twice: {loss:?}");
        for f in &loss {
            assert!(f.statistic >= f.threshold);
            let est = f.estimate.expect("a loss flag estimates the loss");
            assert!(est > 0.2, "estimate {est} of a 0.5 loss");
        }
        assert!(
            obs.flags.iter().all(|f| f.quantity == Quantity::Loss),
            "triggers are the model's: {:?}",
            obs.flags
        );
    }
}

#[test]
fn a_loss_on_an_ideal_link_is_flagged_at_once_and_only_once() {
    let s = winding_with(Link::default(), crate::trigger::TriggerFamily::Box);
    let mut m = Monitor::new(
        &s,
        MonitorConfig {
            false_alarm: 0.01,
            episodes: 100,
        },
    );
    m.start_episode(7);
    let sent = Transmission {
        attempts: 1,
        delivered: true,
    };
    let lost = Transmission {
        attempts: 1,
        delivered: false,
    };
    assert!(m.observe(1, 3, 1.5, sent).is_empty());
    let flags = m.observe(1, 4, 1.5, lost);
    assert_eq!(flags.len(), 1, "{flags:?}");
    let f = flags[0];
    assert_eq!(
        (f.sensor, f.quantity, f.episode, f.step),
        (1, Quantity::Loss, 7, 4)
    );
    assert_eq!(f.statistic, f64::INFINITY);
    assert!(m.observe(1, 5, 1.5, lost).is_empty(), "raised once");
    assert!(m.observe(99, 5, 1.5, lost).is_empty(), "no such sensor");
    // h = ln(N K / α): N = 100 episodes × legs × k_max, K = 3 per sensor (box
    // has a model rate: 9).
    let b = m.budget();
    assert_eq!(b.tests, 9 * s.sensors.len() as u64);
    assert_eq!(
        b.horizon,
        100 * s.legs.len() as u64 * u64::from(s.controller.k_max)
    );
}
