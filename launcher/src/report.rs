//! The run report: table or JSON.

use super::RunRequest;
use super::prepare::Plan;
use super::supervise::Supervised;
use crate::error::Result;
use etp_runtime::wire::traffic::LinkTraffic;
use etp_shared::stats::verdict::{Measured, Outcomes};
use serde_json::{Value, json};

/// The run's outcomes (`etp_shared::stats`; `etp replay` of its recording
/// counts the same episodes the same way: the same numbers).
fn estimates(s: &Supervised) -> Outcomes {
    let r = &s.report;
    let energies: Vec<f64> = r.episode_results.iter().map(|e| e.energy).collect();
    Outcomes::count(r.target, r.collision, r.episodes, &energies)
}

fn free(s: &Supervised) -> Measured {
    Measured::Proportion {
        k: s.report.free,
        n: s.report.episodes,
    }
}

/// Per sensor, what its link carried (derived from the run's counts: legs,
/// handovers, slots, delivered measurements; `wire::traffic`).
fn expected_traffic(s: &Supervised) -> Vec<LinkTraffic> {
    let r = &s.report;
    (0..r.sensors.len())
        .map(|i| {
            let (mut legs, mut handovers, mut slots, mut sent) = (0u64, 0u64, 0u64, 0u64);
            for l in r
                .episode_results
                .iter()
                .flat_map(|e| &e.legs)
                .filter(|l| l.sensor as usize == i)
            {
                legs += 1;
                // A leg whose sensor was alive at its start got a handover.
                handovers += u64::from(l.transmitted.is_some());
                slots += u64::from(l.slots.unwrap_or(0));
                sent += u64::from(l.delivered.or(l.transmitted).unwrap_or(0));
            }
            LinkTraffic::expected(legs, handovers, slots, sent)
        })
        .collect()
}

/// The downlink of the estimator replica (one handover per leg) against the
/// per-step prior it replaced.
fn downlink(s: &Supervised, traffic: &[LinkTraffic]) -> Value {
    let slots: u64 = s.report.sensors.iter().map(|t| t.slots).sum();
    let handover: u64 = traffic.iter().map(|t| t.down_radio.bytes).sum();
    let per_step = LinkTraffic::per_step_prior(slots).bytes;
    json!({"handover_bytes": handover, "per_step_prior_bytes": per_step,
           "saved_fraction": if per_step > 0 { 1.0 - handover as f64 / per_step as f64 } else { 0.0 }})
}

/// The run's measurements against the strategy's prediction.
fn prediction_check(e: &Outcomes, r: &etp_runtime::report::RunReport) -> Value {
    etp_recording_tools::vocab::prediction_check(
        r.predicted.as_ref(),
        r.predicted_ci95.as_ref(),
        e,
        &[],
    )
}

/// The `--json` object (keys of issue 5, plus details).
pub fn json(a: &RunRequest, plan: &Plan, s: &Supervised) -> Value {
    let r = &s.report;
    let e = estimates(s);
    let traffic = expected_traffic(s);
    let sensors: Vec<Value> = r
        .sensors
        .iter()
        .zip(&plan.sensor_energy_per_episode)
        .zip(&traffic)
        .map(|((t, per_ep), link)| {
            let mut v = json!({"name": t.name, "transmissions": t.transmitted,
                   "delivered": t.delivered, "lost": t.lost, "triggers": t.triggers,
                   "received": t.received,
                   "received_without_ledger": t.received_without_ledger,
                   "predicted_energy": etp_recording_tools::vocab::round_energy(per_ep * r.episodes as f64),
                   "energy": t.energy, "slots": t.slots, "missing_ledgers": t.missing_ledgers,
                   "traffic": link});
            if let Some(carried) = s.link.as_ref().and_then(|l| l.traffic.get(&t.name))
                && let Some(m) = v.as_object_mut()
            {
                m.insert("remote".into(), json!(true));
                m.insert("traffic_carried".into(), json!(carried));
            }
            v
        })
        .collect();
    let mut v = json!({
        "run_id": r.run_id,
        "scenario": r.scenario,
        "strategy": r.strategy_label,
        "delta": plan.delta,
        "seed": r.seed,
        "episodes": r.episodes,
        "requested_episodes": r.requested_episodes,
        "predicted": etp_recording_tools::vocab::prediction(r.predicted.as_ref()),
        "predicted_ci95": r.predicted_ci95.map(|c| json!({"p_target": c.p_target,
            "p_collision": c.p_collision, "energy_mean": c.energy_mean})),
        "prediction_check": prediction_check(&e, r),
        "transmissions": r.sensors.iter().map(|t| t.transmitted).sum::<u64>(),
        "delivered": r.sensors.iter().map(|t| t.delivered).sum::<u64>(),
        "lost": r.sensors.iter().map(|t| t.lost).sum::<u64>(),
        "received": r.sensors.iter().map(|t| t.received).sum::<u64>(),
        "radio": plan.scenario.radio.describe(&sensor_names(plan)),
        "sensors": sensors,
        "predicted_energy_from": super::record::prediction_source(plan),
        "processes": s.processes.len(),
        "process_exits": s.processes,
        "degraded": r.degraded,
        "faults": r.faults,
        "steps": r.steps,
        "seconds": r.seconds,
        "steps_per_second": if r.seconds > 0.0 { r.steps as f64 / r.seconds } else { 0.0 },
        "wall_seconds": s.wall_seconds,
        "aborted": r.aborted,
        "drift_monitor": json!({"false_alarm": plan.drift.false_alarm,
            "on_drift": plan.drift.on_drift.name()}),
        "drift": r.drift,
        "downlink": downlink(s, &traffic),
    });
    if let Some(m) = v.as_object_mut() {
        m.extend(etp_recording_tools::vocab::outcome_fields(
            &e,
            Some(free(s)),
        ));
    }
    if let Some(own) = &plan.radio_synthesized
        && let Some(m) = v.as_object_mut()
    {
        m.insert(
            "radio_synthesized".into(),
            json!(own.describe(&sensor_names(plan))),
        );
    }
    if let Some(link) = &s.link
        && let Some(m) = v.as_object_mut()
    {
        m.insert("link".into(), json!(link));
    }
    if !plan.channel_schedule.is_empty()
        && let Some(m) = v.as_object_mut()
    {
        let names = sensor_names(plan);
        m.insert(
            "channel_schedule".into(),
            json!(
                plan.channel_schedule
                    .changes
                    .iter()
                    .map(|c| json!({
                        "sensor": names.get(c.sensor),
                        "episode": c.episode,
                        "loss": c.link.loss,
                        "retries": c.link.retries,
                        "burst": c.link.burst,
                    }))
                    .collect::<Vec<_>>()
            ),
        );
    }
    if let Some(rec) = &s.recording
        && let Some(m) = v.as_object_mut()
    {
        m.insert("recording".into(), json!(rec));
    }
    if a.episode_details
        && let Some(m) = v.as_object_mut()
    {
        m.insert("episode_results".into(), json!(r.episode_results));
    }
    v
}

fn sensor_names(plan: &Plan) -> Vec<String> {
    plan.scenario
        .sensors
        .iter()
        .map(|x| x.name.clone())
        .collect()
}

pub fn print(a: &RunRequest, plan: &Plan, s: &Supervised) -> Result<()> {
    if a.json {
        println!("{}", serde_json::to_string_pretty(&json(a, plan, s))?);
        return Ok(());
    }
    print_outcomes(plan, s);
    print_drift(plan, s);
    print_sensors(plan, s);
    print_traffic(s);
    print_faults(s);
    Ok(())
}

/// The channel monitor's line, and one line per flag.
fn print_drift(plan: &Plan, s: &Supervised) {
    let r = &s.report;
    let head = format!(
        "  channel monitor (false alarm ≤ {} per run, --on-drift {})",
        plan.drift.false_alarm,
        plan.drift.on_drift.name()
    );
    if r.drift.is_empty() {
        println!("{head}: no drift flagged");
        return;
    }
    println!("{head}: DRIFT flagged {} time(s)", r.drift.len());
    for d in &r.drift {
        println!("    {}", d.describe());
    }
}

/// The run line, the channel and the outcomes against the prediction.
fn print_outcomes(plan: &Plan, s: &Supervised) {
    let r = &s.report;
    let e = estimates(s);
    println!(
        "run {} · {} · {} · {} episodes · seed {} · {} processes · {:.2} s ({:.0} steps/s)",
        r.run_id,
        r.scenario,
        r.strategy_label,
        r.episodes,
        r.seed,
        s.processes.len(),
        r.seconds,
        if r.seconds > 0.0 {
            r.steps as f64 / r.seconds
        } else {
            0.0
        }
    );
    let names = sensor_names(plan);
    println!(
        "  {}",
        match &plan.radio_synthesized {
            Some(own) =>
                etp_recording_tools::vocab::channels_text(own, &plan.scenario.radio, &names),
            None => format!("radio: {}", plan.scenario.radio.describe(&names)),
        }
    );
    if !plan.channel_schedule.is_empty() {
        println!(
            "  channel schedule (the sensors' links; the prediction is the strategy's channel's): {}",
            plan.channel_schedule.describe(&names)
        );
    }
    println!(
        "  {:<12} {:>10} {:<20}   {:>10}",
        "", "measured", "(95 % interval)", "predicted"
    );
    let p = r.predicted.unwrap_or(etp_shared::strategy::Prediction {
        p_target: f64::NAN,
        p_collision: f64::NAN,
        p_free: f64::NAN,
        energy_mean: f64::NAN,
    });
    // Probabilities with their Wilson interval, which stays in [0, 1]
    // (value ± half-width would not: 0.98 ± 0.085 on 30 episodes).
    for (k, count, pr) in [
        ("P_target", r.target, p.p_target),
        ("P_collision", r.collision, p.p_collision),
        ("P_free", r.free, p.p_free),
    ] {
        let m = Measured::Proportion {
            k: count,
            n: r.episodes,
        };
        let (lo, hi) = m.interval(etp_shared::stats::Z95);
        println!(
            "  {k:<12} {:>10.4} {:<20}   {pr:>10.4}",
            m.value(),
            format!("[{lo:.4}, {hi:.4}]")
        );
    }
    let energy = e.energy.map(|m| m.estimate());
    println!(
        "  {:<12} {:>10.4} {:<20}   {:>10.4}",
        "energy",
        energy.map_or(f64::NAN, |x| x.value),
        format!("± {:.4}", energy.map_or(f64::NAN, |x| x.ci95)),
        p.energy_mean
    );
    if r.episodes > 0 {
        print!(
            "{}",
            etp_recording_tools::vocab::prediction_check_text(&prediction_check(&e, r))
        );
    }
}

/// Each sensor's counts and predicted energy.
fn print_sensors(plan: &Plan, s: &Supervised) {
    let r = &s.report;
    println!(
        "  {:<8} {:>12} {:>10} {:>8} {:>10} {:>16}",
        "sensor", "transmitted", "delivered", "lost", "received", "predicted energy"
    );
    for (t, per_ep) in r.sensors.iter().zip(&plan.sensor_energy_per_episode) {
        let flag = if t.delivered != t.received || t.missing_ledgers > 0 {
            format!(
                "  ({} ledger(s) missing; +{} received on those legs, checked against nothing)",
                t.missing_ledgers, t.received_without_ledger
            )
        } else {
            String::new()
        };
        println!(
            "  {:<8} {:>12} {:>10} {:>8} {:>10} {:>16.1}{flag}",
            t.name,
            t.transmitted,
            t.delivered,
            t.lost,
            t.received,
            per_ep * r.episodes as f64
        );
    }
    println!(
        "  predicted energy per sensor: {}",
        super::record::prediction_source(plan)
    );
}

/// What crossed each link, and what the handovers saved.
fn print_traffic(s: &Supervised) {
    let r = &s.report;
    let traffic = expected_traffic(s);
    println!(
        "  {:<8} {:>22} {:>22} {:>22} {:>22}",
        "traffic", "radio down", "radio up", "plumbing down", "plumbing up"
    );
    let cell = |c: etp_runtime::wire::traffic::Count| format!("{} msg {} B", c.messages, c.bytes);
    for (t, link) in r.sensors.iter().zip(&traffic) {
        let carried = s.link.as_ref().and_then(|l| l.traffic.get(&t.name));
        let shown = carried.unwrap_or(link);
        println!(
            "  {:<8} {:>22} {:>22} {:>22} {:>22}{}",
            t.name,
            cell(shown.down_radio),
            cell(shown.up_radio),
            cell(shown.down_plumbing),
            cell(shown.up_plumbing),
            if carried.is_some() {
                "  (remote: as carried by the link)"
            } else {
                ""
            }
        );
    }
    let d = downlink(s, &traffic);
    println!(
        "  downlink: {} B of handovers (one per leg) vs {} B of per-step priors: {:.1} % saved",
        d["handover_bytes"],
        d["per_step_prior_bytes"],
        100.0 * d["saved_fraction"].as_f64().unwrap_or(0.0)
    );
}

/// Dead links, link faults, an abort, the recording and processes that did not exit 0.
fn print_faults(s: &Supervised) {
    let r = &s.report;
    if r.degraded > 0 {
        println!(
            "  DEGRADED: {} episode(s) ran with a dead link (prediction only on its slots)",
            r.degraded
        );
        for f in &r.faults {
            println!(
                "    episode {}: sensor {} dead, detected {:.1} ms after the agent began waiting, {} slots prediction-only",
                f.episode, f.sensor, f.detect_ms, f.dead_slots
            );
        }
    }
    if let Some(why) = s.link.as_ref().and_then(|l| l.faults()) {
        println!("  LINK FAULT: {why}");
    }
    if let Some(why) = s.link.as_ref().and_then(|l| l.stalls()) {
        println!("  link stalled: {why}");
    }
    if let Some(why) = s.link.as_ref().and_then(|l| l.handshakes()) {
        println!("  link admission: {why}");
    }
    if let Some(why) = &r.aborted {
        println!("  ABORTED: {why}");
    }
    if let Some(rec) = &s.recording {
        let total: u64 = rec.counts.values().sum();
        println!(
            "  recording {} ({} bytes, {}): {total} messages",
            rec.path.display(),
            rec.bytes,
            if rec.finished {
                "finished"
            } else {
                "UNFINISHED: see etp replay repair"
            }
        );
        for (topic, n) in &rec.counts {
            println!("    {topic:<20} {n}");
        }
    }
    for p in s.processes.iter().filter(|p| p.status != "exit 0") {
        println!("  process {} (pid {}): {}", p.name, p.pid, p.status);
    }
}
