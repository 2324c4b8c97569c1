use super::*;
use etp_runtime::wire::Header;
use etp_shared::strategy::Prediction;

const TAG: u64 = 11;

fn scenario() -> Scenario {
    Scenario::builtin("winding-2d").expect("built-in")
}

fn strategy(s: &Scenario) -> Strategy {
    let p = Prediction {
        p_target: 0.9,
        p_collision: 0.05,
        p_free: 0.05,
        energy_mean: 3.0,
    };
    Strategy::constant(s, 1, p)
}

fn header(episode: u64, leg: u32, step: u32) -> Header {
    Header {
        run: TAG,
        episode,
        leg,
        step,
        ..Header::default()
    }
}

fn waypoint(episode: u64, leg: u32, prev: (u32, u32)) -> Waypoint {
    let mut w = Waypoint {
        header: header(episode, leg, 0),
        dim: 2,
        prev_steps: prev.0,
        prev_received: prev.1,
        ..Waypoint::default()
    };
    w.cov[0][0] = 1.0;
    w.cov[1][1] = 1.0;
    w
}

fn outcome(episode: u64, leg: u32, code: OutcomeCode) -> Outcome {
    Outcome {
        header: header(episode, leg, 9),
        outcome: code.code(),
        steps: 9,
        last_steps: 4,
        last_received: 2,
        dead_sensor: u32::MAX,
        ..Outcome::default()
    }
}

#[test]
fn each_waypoint_closes_the_previous_leg_and_opens_its_own() {
    let s = scenario();
    let st = strategy(&s);
    let mut c = CoordinatorCore::new(&s, &st, 3, TAG);
    c.start_episode(0);
    let a = c.on_waypoint(&waypoint(0, 0, (0, 0)));
    let sensor0 = s.legs[0].sensor as u32;
    assert!(matches!(
        a[..],
        [ThresholdAction::Open { episode: 0, leg: 0, sensor, delta_index: 1, delta }]
            if sensor == sensor0 && delta == st.deltas[1]
    ));
    let a = c.on_waypoint(&waypoint(0, 1, (5, 3)));
    assert_eq!(
        a[0],
        ThresholdAction::Close {
            episode: 0,
            leg: 0,
            sensor: sensor0
        }
    );
    assert!(matches!(a[1], ThresholdAction::Open { leg: 1, .. }));
    // Another run's or another episode's waypoint decides nothing.
    let mut other = waypoint(0, 2, (1, 1));
    other.header.run = TAG + 1;
    assert!(c.on_waypoint(&other).is_empty());
    assert!(c.on_waypoint(&waypoint(7, 2, (1, 1))).is_empty());
    let close = c
        .on_outcome(&outcome(0, 1, OutcomeCode::Target))
        .expect("known code");
    assert!(matches!(close, Some(ThresholdAction::Close { leg: 1, .. })));
    assert_eq!(c.finished(), 1);
    // Legs 0 and 1 wait for their ledgers; one arrives.
    let mut want = vec![s.legs[0].sensor as u32, s.legs[1].sensor as u32];
    want.sort_unstable();
    want.dedup();
    assert_eq!(c.missing_ledgers(), want);
    c.on_ledger(&Ledger {
        header: header(0, 0, 0),
        slots: 5,
        transmissions: 3,
        energy: 3.0 * s.sensors[s.legs[0].sensor].cost,
    });
    let r = c.report("run".into(), 1, 1.0, None);
    assert_eq!((r.episodes, r.target, r.degraded), (1, 1, 1));
    let legs = &r.episode_results[0].legs;
    assert_eq!(
        (legs[0].steps, legs[0].received, legs[0].transmitted),
        (5, 3, Some(3))
    );
    assert_eq!(
        (legs[1].steps, legs[1].received, legs[1].transmitted),
        (4, 2, None)
    );
}

#[test]
fn the_draws_are_the_coordinator_stream_of_the_episode() {
    let s = scenario();
    let st = strategy(&s);
    // The same seed and episode draw the same; the draw consumes one number
    // per waypoint (a constant strategy ignores it, so compare the streams).
    let mut a = CoordinatorCore::new(&s, &st, 3, TAG);
    let mut b = CoordinatorCore::new(&s, &st, 3, TAG);
    a.start_episode(4);
    b.start_episode(4);
    for leg in 0..3 {
        assert_eq!(
            a.on_waypoint(&waypoint(4, leg, (1, 0))),
            b.on_waypoint(&waypoint(4, leg, (1, 0)))
        );
    }
}

#[test]
fn a_dead_link_is_a_fault_and_an_unknown_code_an_error() {
    let s = scenario();
    let st = strategy(&s);
    let mut c = CoordinatorCore::new(&s, &st, 3, TAG);
    c.start_episode(2);
    c.on_waypoint(&waypoint(2, 0, (0, 0)));
    let mut bad = outcome(2, 0, OutcomeCode::Free);
    bad.outcome = 99;
    assert!(c.on_outcome(&bad).is_err());
    let mut o = outcome(2, 0, OutcomeCode::Collision);
    o.dead_sensor = 0;
    o.degraded = 1;
    o.detect_us = 2500;
    o.dead_slots = 3;
    c.on_outcome(&o).expect("known code");
    let r = c.report("run".into(), 5, 1.0, Some("interrupted".into()));
    assert_eq!((r.requested_episodes, r.episodes, r.collision), (5, 1, 1));
    assert_eq!(r.faults.len(), 1);
    assert_eq!(r.faults[0].sensor, s.sensors[0].name);
    assert_eq!((r.faults[0].detect_ms, r.faults[0].dead_slots), (2.5, 3));
    assert!(r.episode_results[0].degraded);
}
