use super::*;
use etp_shared::strategy::{Prediction, Strategy};

const TAG: u64 = 0xabc;

fn scenario() -> Scenario {
    Scenario::builtin("winding-2d").expect("built-in")
}

fn constant(s: &Scenario, index: usize) -> Strategy {
    let p = Prediction {
        p_target: 1.0,
        p_collision: 0.0,
        p_free: 0.0,
        energy_mean: 0.0,
    };
    Strategy::constant(s, index, Some(p))
}

fn header(episode: u64, leg: u32, step: u32) -> Header {
    Header {
        run: TAG,
        episode,
        step,
        leg,
        sender: SENDER_AGENT,
        seq: 0,
    }
}

fn waypoint(episode: u64, leg: u32, prev_steps: u32, prev_received: u32) -> Waypoint {
    let mut w = Waypoint {
        header: header(episode, leg, 0),
        dim: 2,
        prev_steps,
        prev_received,
        ..Waypoint::default()
    };
    w.cov[0][0] = 1e-3;
    w.cov[1][1] = 1e-3;
    w
}

fn outcome(episode: u64, leg: u32, code: u32, last_steps: u32, last_received: u32) -> Outcome {
    Outcome {
        header: header(episode, leg, 0),
        outcome: code,
        steps: 40,
        last_steps,
        last_received,
        dead_sensor: u32::MAX,
        ..Outcome::default()
    }
}

fn ledger(episode: u64, leg: u32, transmissions: u32, energy: f64) -> Ledger {
    Ledger {
        header: Header {
            run: TAG,
            episode,
            leg,
            ..Header::default()
        },
        slots: 10,
        triggers: transmissions,
        transmissions,
        delivered: transmissions,
        energy,
        ..Ledger::default()
    }
}

/// Run one episode of `legs` decision points through the core.
fn episode(core: &mut CoordinatorCore<'_>, e: u64, legs: u32) -> Vec<Opening> {
    core.start_episode(e);
    let openings = (0..legs)
        .map(|leg| {
            core.on_waypoint(&waypoint(e, leg, 7, 2))
                .expect("valid")
                .expect("current")
        })
        .collect();
    let last = core
        .end_episode(&outcome(e, legs - 1, Outcome::TARGET, 5, 1))
        .expect("valid");
    assert_eq!(last.leg, legs - 1);
    openings
}

#[test]
fn each_waypoint_closes_the_previous_leg_and_opens_its_own_at_the_strategys_delta() {
    let s = scenario();
    let st = constant(&s, 2);
    let mut core = CoordinatorCore::new(&s, &st.policy, 1, TAG);
    let legs = s.legs.len() as u32;
    let openings = episode(&mut core, 0, legs);
    for (leg, o) in openings.iter().enumerate() {
        assert_eq!(o.open.leg, leg as u32);
        assert_eq!(o.open.sensor, s.legs[leg].sensor as u32);
        assert_eq!((o.delta_index, o.delta), (2, s.deltas[2]));
        let close = leg.checked_sub(1).map(|p| LegAt {
            episode: 0,
            leg: p as u32,
            sensor: s.legs[p].sensor as u32,
        });
        assert_eq!(o.close, close);
    }
}

/// δ is drawn from ω with the coordinator's own stream: a mixed strategy
/// draws the same δ for the same seed and episode.
#[test]
fn the_draw_is_the_strategys_with_the_coordinators_stream() {
    let s = scenario();
    let mut st = constant(&s, 0);
    for state in &mut st.policy.states {
        state.omega = vec![0.2; s.deltas.len()];
    }
    let draws = |seed: u64| {
        let mut core = CoordinatorCore::new(&s, &st.policy, seed, TAG);
        (0..20)
            .flat_map(|e| episode(&mut core, e, 2))
            .map(|o| o.delta_index)
            .collect::<Vec<_>>()
    };
    let a = draws(3);
    assert_eq!(a, draws(3));
    let mut rng = stream_rng(3, streams::COORDINATOR, 0);
    let cov = DMatrix::from_fn(2, 2, |r, c| if r == c { 1e-3 } else { 0.0 });
    let u: f64 = rng.random();
    assert_eq!(a[0] as usize, st.policy.draw(0, &cov, u));
    assert!(a.iter().any(|&i| i != a[0]), "a mixed ω draws several δ");
}

#[test]
fn messages_of_other_runs_or_episodes_are_ignored() {
    let s = scenario();
    let st = constant(&s, 1);
    let mut core = CoordinatorCore::new(&s, &st.policy, 1, TAG);
    core.start_episode(4);
    let mut other_run = waypoint(4, 0, 0, 0);
    other_run.header.run = TAG + 1;
    assert_eq!(core.on_waypoint(&other_run).expect("valid"), None);
    assert_eq!(
        core.on_waypoint(&waypoint(3, 0, 0, 0)).expect("valid"),
        None
    );
    assert!(core.is_current(&header(4, 0, 0)));
    assert!(!core.is_current(&header(5, 0, 0)));
    let mut l = ledger(4, 0, 1, 1.0);
    l.header.run = TAG + 1;
    core.on_ledger(l);
    assert!(
        core.on_waypoint(&waypoint(4, 0, 0, 0))
            .expect("valid")
            .is_some()
    );
    core.end_episode(&outcome(4, 0, Outcome::FREE, 3, 0))
        .expect("valid");
    assert_eq!(core.missing_ledgers(), vec![s.legs[0].sensor as u32]);
}

#[test]
fn bad_outcomes_and_legs_are_protocol_errors() {
    let s = scenario();
    let st = constant(&s, 1);
    let mut core = CoordinatorCore::new(&s, &st.policy, 1, TAG);
    core.start_episode(0);
    let beyond = s.legs.len() as u32;
    assert!(core.on_waypoint(&waypoint(0, beyond, 0, 0)).is_err());
    assert!(core.end_episode(&outcome(0, 0, 99, 1, 0)).is_err());
    assert!(
        core.end_episode(&outcome(0, beyond, Outcome::TARGET, 1, 0))
            .is_err()
    );
}

/// The report joins each leg to its ledger; a leg without one is priced at
/// what the agent received and degrades its episode; a dead link is a fault.
#[test]
fn the_report_joins_ledgers_and_prices_missing_ones_at_the_received() {
    let s = scenario();
    let st = constant(&s, 1);
    let mut core = CoordinatorCore::new(&s, &st.policy, 1, TAG);
    episode(&mut core, 0, 2);
    core.start_episode(1);
    core.on_waypoint(&waypoint(1, 0, 0, 0)).expect("valid");
    let mut dead = outcome(1, 0, Outcome::COLLISION, 4, 3);
    dead.dead_sensor = s.legs[0].sensor as u32;
    dead.degraded = 1;
    dead.detect_us = 1500;
    dead.dead_slots = 2;
    core.end_episode(&dead).expect("valid");
    core.on_ledger(ledger(0, 0, 3, 0.3));
    core.on_ledger(ledger(0, 1, 4, 0.4));
    assert_eq!(core.missing_ledgers(), vec![s.legs[0].sensor as u32]);
    let r = core.report("run".into(), 5, 1.0, None);
    assert_eq!((r.requested_episodes, r.episodes), (5, 2));
    assert_eq!((r.target, r.collision, r.free), (1, 1, 0));
    assert_eq!(r.steps, 80);
    let e0 = &r.episode_results[0];
    assert!(!e0.degraded);
    assert!((e0.energy - 0.7).abs() < 1e-12);
    assert_eq!(e0.legs[0].steps, 7);
    assert_eq!(e0.legs[0].received, 2);
    assert_eq!(e0.legs[1].steps, 5);
    assert_eq!(e0.legs[1].transmitted, Some(4));
    let e1 = &r.episode_results[1];
    assert!(e1.degraded);
    assert_eq!(e1.legs[0].transmitted, None);
    let cost = s.sensors[s.legs[0].sensor].cost;
    assert_eq!(e1.energy, 3.0 * cost);
    assert_eq!(r.degraded, 1);
    assert_eq!(r.faults.len(), 1);
    assert_eq!(r.faults[0].detect_ms, 1.5);
    assert_eq!(r.faults[0].dead_slots, 2);
    let missing: u64 = r.sensors.iter().map(|t| t.missing_ledgers).sum();
    assert_eq!(missing, 1);
}

#[test]
fn the_roll_call_names_who_is_missing() {
    let s = scenario();
    let mut roll = RollCall::new(TAG, s.sensors.len());
    assert_eq!(roll.missing(&s).len(), s.sensors.len() + 1);
    roll.on_hello(&header(0, 0, 0));
    for i in 0..s.sensors.len() as u32 {
        let mut h = header(0, 0, 0);
        h.sender = i;
        if i == 1 {
            h.run = TAG + 1;
        }
        roll.on_hello(&h);
    }
    assert!(!roll.all_present());
    assert_eq!(roll.missing(&s), vec![s.sensors[1].name.clone()]);
    let mut h = header(0, 0, 0);
    h.sender = 1;
    roll.on_hello(&h);
    assert!(roll.all_present());
}

/// The sends of every decision point: each `threshold` is followed by its
/// sensor's wake-up, and the agent is woken last. Without the wake-up after
/// the OPEN a sensor that took the leg's first truth before the OPEN
/// reached its queue waited for a wake-up that never came, and the agent
/// for its slot (the run hung).
#[test]
fn every_threshold_is_followed_by_its_sensors_wake_up_and_the_agent_is_woken_last() {
    let s = scenario();
    let st = constant(&s, 1);
    let mut core = CoordinatorCore::new(&s, &st.policy, 1, TAG);
    let legs = s.legs.len() as u32;
    for o in episode(&mut core, 0, legs) {
        let sends = o.sends();
        assert_eq!(sends.last(), Some(&Send::WakeAgent), "{sends:?}");
        for (i, send) in sends.iter().enumerate() {
            let sensor = match send {
                Send::Close(at) | Send::Open(at) => at.sensor,
                _ => continue,
            };
            assert_eq!(
                sends.get(i + 1),
                Some(&Send::WakeSensor(sensor)),
                "{send:?} not followed by its sensor's wake-up: {sends:?}"
            );
        }
        let opens: Vec<_> = sends
            .iter()
            .filter_map(|x| match x {
                Send::Open(at) => Some(*at),
                _ => None,
            })
            .collect();
        assert_eq!(opens, vec![o.open]);
        assert_eq!(
            sends.contains(&Send::Close(o.close.unwrap_or(o.open))),
            o.close.is_some()
        );
    }
}
