//! MODEL.md §7: a double integrator (n = 4, p = 2, d = 2, position-only
//! sensors, LQR gain) against a hand-written loop in plain dynamic matrices.

use super::*;
use crate::radio::EpisodeChannels;
use crate::rng::{stream_rng, streams};
use crate::scenario::Scenario;
use nalgebra::{DMatrix, DVector};
use rand::RngExt;
use rand_distr::StandardNormal;

const TEXT: &str = include_str!("../testdata/double-integrator.toml");

fn normals<R: Rng + ?Sized>(rng: &mut R, n: usize) -> DVector<f64> {
    DVector::from_fn(n, |_, _| rng.sample(StandardNormal))
}

fn chol(m: &DMatrix<f64>) -> DMatrix<f64> {
    nalgebra::Cholesky::new(m.clone()).expect("SPD").l()
}

/// What the hand-written loop reports.
#[derive(Debug, PartialEq)]
struct Hand {
    outcome: Outcome,
    steps: u32,
    transmissions: u32,
    x: DVector<f64>,
    mean: DVector<f64>,
}

/// MODEL.md §7 written out once more, full KF (δ = 0), no shared code but the
/// scenario's validated matrices and the random stream.
fn hand_written_episode(s: &Scenario, seed: u64) -> Hand {
    let mut rng = stream_rng(seed, streams::SIMULATE, 0);
    let p = &s.plant;
    let c = s.workspace.as_ref().expect("C");
    let k = s.gain.as_ref().expect("K");
    let c_pinv = c.transpose() * (c * c.transpose()).try_inverse().expect("full rank");
    let mut mean = p.x0.clone();
    let mut cov = p.p0.clone();
    let mut x = &mean + chol(&cov) * normals(&mut rng, 4);
    let (mut steps, mut sent) = (0, 0);
    let contains = |b: &crate::geometry::Aabb, q: &DVector<f64>| b.contains(q.as_slice());
    for leg in &s.legs {
        let sensor = &s.sensors[leg.sensor];
        let r = &c_pinv * &leg.to;
        let mut k_i = 0;
        loop {
            let mut u = k * (&r - &mean);
            if u.norm() > s.controller.u_max {
                u *= s.controller.u_max / u.norm();
            }
            x = &p.f * &x + &p.g * &u + chol(&p.q) * normals(&mut rng, 4);
            steps += 1;
            k_i += 1;
            if s.obstacles.iter().any(|o| contains(&o.bounds, &(c * &x))) {
                return Hand {
                    outcome: Outcome::Collision,
                    steps,
                    transmissions: sent,
                    x,
                    mean,
                };
            }
            let y = &sensor.h * &x + chol(&sensor.r) * normals(&mut rng, 2);
            let prior_mean = &p.f * &mean + &p.g * &u;
            let prior_cov = &p.f * &cov * p.f.transpose() + &p.q;
            let z = &sensor.h * &prior_cov * sensor.h.transpose() + &sensor.r;
            let gain = &prior_cov * sensor.h.transpose() * z.try_inverse().expect("SPD");
            mean = &prior_mean + &gain * (&y - &sensor.h * &prior_mean);
            let ikh = DMatrix::identity(4, 4) - &gain * &sensor.h;
            cov = &ikh * &prior_cov * ikh.transpose() + &gain * &sensor.r * gain.transpose();
            cov = (&cov + cov.transpose()) * 0.5;
            sent += 1;
            if (c * &mean - &leg.to).norm() <= s.controller.eps_x || k_i >= s.controller.k_max {
                break;
            }
        }
    }
    let outcome = if contains(&s.target, &(c * &x)) {
        Outcome::Target
    } else {
        Outcome::Free
    };
    Hand {
        outcome,
        steps,
        transmissions: sent,
        x,
        mean,
    }
}

#[test]
fn double_integrator_episode_matches_a_hand_written_loop() {
    let s = Scenario::from_toml(TEXT).expect("valid");
    assert_eq!((s.dim, s.workspace_dim(), s.input_dim()), (4, 2, 2));
    let c = CompiledScenario::<4>::new(&s);
    let mut outcomes = std::collections::BTreeSet::new();
    for seed in 0..40 {
        let hand = hand_written_episode(&s, seed);
        struct Last(Vector<4>, Vector<4>);
        impl EpisodeObserver<4> for Last {
            fn on_step(&mut self, e: &StepEvent<'_, 4>) {
                self.0 = *e.x;
                self.1 = e.belief.mean;
            }
        }
        let mut last = Last(Vector::zeros(), Vector::zeros());
        let r = c.run_episode(
            |_, _, _| LegMode::EventTriggered(Threshold::new(0.0)),
            &mut stream_rng(seed, streams::SIMULATE, 0),
            &mut EpisodeChannels::ideal(),
            &mut last,
        );
        assert_eq!(
            (r.outcome, r.steps, r.transmissions),
            (hand.outcome, hand.steps, hand.transmissions),
            "seed {seed}"
        );
        for i in 0..4 {
            assert!((last.0[i] - hand.x[i]).abs() < 1e-9, "seed {seed} x[{i}]");
            assert!(
                (last.1[i] - hand.mean[i]).abs() < 1e-9,
                "seed {seed} x̂[{i}]"
            );
        }
        outcomes.insert(format!("{:?}", r.outcome));
    }
    // The fixture is built so that both outcomes occur: the wall beyond the
    // first waypoint catches agents that overshoot (inertia).
    assert!(outcomes.len() >= 2, "outcomes seen: {outcomes:?}");
}

#[test]
fn the_reference_is_a_rest_point_and_the_agent_settles_there() {
    let s = Scenario::from_toml(TEXT).expect("valid");
    assert!(s.warnings.is_empty(), "{:?}", s.warnings);
    let c = CompiledScenario::<4>::new(&s);
    // r = C⁺ w = (w, 0): position at the waypoint, zero velocity.
    assert_eq!(c.legs[0].reference, Vector::<4>::new(2.0, 0.0, 0.0, 0.0));
    // Noise-free closed loop from rest at the origin converges to r.
    let mut x = Vector::<4>::zeros();
    for _ in 0..400 {
        x = c.plant.f * x + c.plant.g * c.input(0, &x);
    }
    assert!((x - c.legs[0].reference).amax() < 1e-6, "{x}");
    assert!(c.input(0, &x).norm() < 1e-6);
}

/// `run_leg` takes the AVX2 build of the leg loop where the CPU has it; the
/// portable build must give the same bits (true state, belief, counts) on
/// every built-in scenario, at δ = 0 and at a large δ.
#[test]
fn the_avx2_leg_loop_is_the_portable_one_bit_for_bit() {
    for name in crate::scenario::BUILTIN_NAMES {
        let s = Scenario::builtin(name).expect("built-in");
        crate::with_dim!(s.dim, N => {
            let c = CompiledScenario::<N>::new(&s);
            for delta in [0.0, 2.2365] {
                let mode = LegMode::EventTriggered(Threshold::new(delta));
                for e in 0..40u64 {
                    let mut rng_a = stream_rng(3, streams::SIMULATE, e);
                    let mut a = c.initial_state(&mut rng_a);
                    let mut rng_b = rng_a.clone();
                    let mut b = a;
                    for leg in 0..c.legs.len() {
                        let ra = c.run_leg(leg, &mut a, &mode, &mut rng_a, &mut EpisodeChannels::ideal(), &mut ());
                        let sensor = c.legs[leg].sensor;
                        let rb = on_filter!(&c.filters[sensor], f => c.run_leg_portable(f, super::LegCall {
                            leg,
                            state: &mut b,
                            mode: &mode,
                            rng: &mut rng_b,
                            channels: &mut EpisodeChannels::ideal(),
                            observer: &mut (),
                        }));
                        assert_eq!(ra, rb, "{name} δ = {delta} episode {e} leg {leg}");
                        let bits = |st: &AgentState<N>| {
                            st.x.iter()
                                .chain(st.belief.mean.iter())
                                .chain(st.belief.cov.iter())
                                .map(|v| v.to_bits())
                                .collect::<Vec<u64>>()
                        };
                        assert_eq!(bits(&a), bits(&b), "{name} δ = {delta} episode {e} leg {leg}");
                        if matches!(ra.end, LegEnd::Collision { .. }) {
                            break;
                        }
                    }
                }
            }
        });
    }
}
