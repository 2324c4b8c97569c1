use super::*;
use etp_shared::episode::LegReplica;
use etp_shared::etkf::Vector;
use etp_shared::scenario::Scenario;

fn winding() -> CompiledScenario<2> {
    CompiledScenario::<2>::new(&Scenario::builtin("winding-2d").expect("built-in"))
}

/// A sensor as the sensor process serves a slot: its replica's prior, the
/// trigger on y = H x + v, the replica's update with what it did.
struct FakeSensor {
    replica: Option<LegReplica<2>>,
    delta: f64,
    rng: SimRng,
}

impl FakeSensor {
    fn new(delta: f64) -> Self {
        Self {
            replica: None,
            delta,
            rng: stream_rng(9, streams::SENSOR, 0),
        }
    }

    fn hand_over(&mut self, c: &CompiledScenario<2>, dp: &DecisionPoint<2>) {
        self.replica = Some(LegReplica::handed_over(
            c,
            dp.leg as usize,
            self.delta,
            dp.belief,
            dp.step,
        ));
    }

    fn serve(
        &mut self,
        c: &CompiledScenario<2>,
        x: &Vector<2>,
        req: &SlotRequest<2>,
    ) -> SlotResult {
        let replica = self.replica.as_mut().expect("handed over");
        assert_eq!(replica.next_step(), req.step);
        let open = replica.open(c);
        let episode::SensorFilter::M2(filter) = &c.filters[req.sensor] else {
            panic!("winding-2d measures 2-D");
        };
        let y = filter.sensor.measure(x, &mut self.rng);
        let fired = filter.innovation(open.prior()).triggers(&y, self.delta);
        let digest = belief_digest(open.prior());
        let mut wire = [0.0; 6];
        wire[..2].copy_from_slice(y.as_slice());
        let outcome = if fired {
            SlotOutcome::Transmitted(&wire[..])
        } else {
            SlotOutcome::Silent
        };
        replica.close(c, open, outcome);
        SlotResult::Closed(fired.then_some(wire), digest)
    }
}

/// Run one episode, each slot served by `serve`; the decision points seen
/// and the end.
fn run(
    c: &CompiledScenario<2>,
    episode: u64,
    delta: f64,
    mut serve: impl FnMut(&mut EpisodeCore<2>, &DecisionPoint<2>, &SlotRequest<2>) -> SlotResult,
) -> (Vec<DecisionPoint<2>>, EpisodeEnd) {
    let mut core = EpisodeCore::start(c, episode, 1).expect("legs");
    let mut points = Vec::new();
    loop {
        let dp = core.decision_point();
        points.push(dp);
        let sensor = c.legs[dp.leg as usize].sensor;
        core.open_leg(c, delta, sensor).expect("the leg's sensor");
        loop {
            let request = match core.begin_step(c).expect("open leg") {
                Step::Slot(r) => r,
                Step::Ended(end) => return (points, end),
            };
            let result = serve(&mut core, &dp, &request);
            match core
                .close_slot(c, request, result, None)
                .expect("exact replica")
            {
                AfterSlot::Continue => {}
                AfterSlot::LegEnded => break,
                AfterSlot::Ended(end) => return (points, end),
            }
        }
    }
}

/// Served by a sensor's replica, every slot's digest is accepted, the
/// episode runs to an outcome and the counts add up.
#[test]
fn an_episode_served_by_a_replica_runs_to_its_outcome_and_counts_add_up() {
    let c = winding();
    for episode in 0..10 {
        let mut sensor = FakeSensor::new(1.0);
        let mut handed: Option<u32> = None;
        let (points, end) = run(&c, episode, 1.0, |core, dp, req| {
            if handed != Some(dp.leg) {
                sensor.hand_over(&c, dp);
                handed = Some(dp.leg);
            }
            let x = *core.x();
            sensor.serve(&c, &x, req)
        });
        let o = end.outcome;
        assert_eq!(points[0].step, 0);
        assert_eq!(points[0].prev, LegCounts::default());
        // Steps: the decision points' steps plus the last leg's.
        assert_eq!(o.steps, end.step);
        assert_eq!(points.last().map(|p| p.step + o.last_steps), Some(end.step));
        for w in points.windows(2) {
            assert_eq!(w[1].step - w[0].step, w[1].prev.steps);
        }
        let received: u32 = points.iter().map(|p| p.prev.received).sum();
        assert_eq!(o.received, received + o.last_received);
        assert!(o.received <= o.slots && o.slots <= o.steps);
        assert_eq!((o.degraded, o.dead_slots, o.dead_sensor), (0, 0, u32::MAX));
        assert!(OutcomeCode::try_from(o.outcome).is_ok());
        if o.outcome != OutcomeCode::Collision.code() {
            assert_eq!(end.leg as usize + 1, c.legs.len());
            assert_eq!(o.slots, o.steps);
        }
    }
}

#[test]
fn the_same_seed_gives_the_same_episode() {
    let c = winding();
    let silent = |core: &mut EpisodeCore<2>, _: &DecisionPoint<2>, req: &SlotRequest<2>| {
        let _ = core;
        SlotResult::Closed(None, belief_digest(req.open.prior()))
    };
    assert_eq!(run(&c, 3, 2.0, silent), run(&c, 3, 2.0, silent));
    assert_ne!(run(&c, 3, 2.0, silent).1, run(&c, 4, 2.0, silent).1);
}

#[test]
fn a_replica_on_another_prior_is_a_protocol_error() {
    let c = winding();
    let mut core = EpisodeCore::start(&c, 0, 1).expect("legs");
    core.open_leg(&c, 1.0, c.legs[0].sensor)
        .expect("its sensor");
    let Step::Slot(req) = core.begin_step(&c).expect("open") else {
        panic!("no collision on the first step of winding-2d");
    };
    let wrong = belief_digest(req.open.prior()) ^ 1;
    let err = core
        .close_slot(&c, req, SlotResult::Closed(None, wrong), None)
        .expect_err("diverged");
    assert!(err.to_string().contains("replica diverged"), "{err}");
}

#[test]
fn a_leg_opened_at_another_sensor_or_not_opened_is_refused() {
    let c = winding();
    let mut core = EpisodeCore::start(&c, 0, 1).expect("legs");
    assert!(core.begin_step(&c).is_err());
    let other = c.legs[0].sensor + 1;
    let err = core.open_leg(&c, 1.0, other).expect_err("wrong sensor");
    assert!(err.to_string().contains("the scenario says"), "{err}");
}

/// A dead link: prediction only (the posterior is the prior), the episode
/// degraded, the first fault reported, the leg's counts marked.
#[test]
fn a_dead_link_is_prediction_only_and_degrades_the_episode() {
    let c = winding();
    let mut core = EpisodeCore::start(&c, 0, 1).expect("legs");
    core.open_leg(&c, 1.0, c.legs[0].sensor)
        .expect("its sensor");
    let fault = |sensor| Fault {
        sensor,
        detect_us: 10,
        wait_started_unix_ns: 1,
        detected_unix_ns: 2,
    };
    let mut priors = Vec::new();
    let mut dead = 0;
    let after = loop {
        let Step::Slot(req) = core.begin_step(&c).expect("open") else {
            panic!("collided while testing a dead link");
        };
        priors.push(*req.open.prior());
        let f = (dead == 0).then(|| fault(7)).or(Some(fault(8)));
        dead += 1;
        match core
            .close_slot(&c, req, SlotResult::Dead(None), f)
            .expect("dead is no error")
        {
            AfterSlot::Continue => {}
            other => break other,
        }
    };
    match after {
        AfterSlot::LegEnded => {
            let dp = core.decision_point();
            assert!(dp.prev.degraded);
            assert_eq!(dp.prev.steps, dead);
            assert_eq!(dp.prev.received, 0);
            // Prediction only: the belief at the leg's end is the last prior.
            assert_eq!(Some(&dp.belief), priors.last());
        }
        AfterSlot::Ended(end) => assert_eq!(end.outcome.last_steps, dead),
        AfterSlot::Continue => unreachable!(),
    }
    let end = loop {
        match core.begin_step(&c) {
            Ok(Step::Ended(end)) => break end,
            Ok(Step::Slot(req)) => {
                if let Ok(AfterSlot::Ended(end)) =
                    core.close_slot(&c, req, SlotResult::Dead(None), None)
                {
                    break end;
                }
            }
            // The next leg was not opened: open it at its sensor.
            Err(_) => {
                let leg = core.decision_point().leg as usize;
                core.open_leg(&c, 1.0, c.legs[leg].sensor)
                    .expect("its sensor");
            }
        }
    };
    let o = end.outcome;
    assert_eq!(o.degraded, 1);
    assert_eq!(o.dead_sensor, 7);
    assert_eq!(o.dead_slots, o.slots);
    assert_eq!(o.received, 0);
}
