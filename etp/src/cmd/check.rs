//! `etp check SCENARIO`: validate and describe a scenario.

use anyhow::Result;
use etp_runtime::load_scenario;
use etp_shared::gaussian::expected_rate;
use etp_shared::scenario::Scenario;
use serde_json::json;

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Built-in name (winding-2d, open-2d, superg-3d, inertia-2d, inertia-3d) or path to a scenario TOML.
    pub scenario: String,
    /// Print one JSON object instead of tables.
    #[arg(long)]
    pub json: bool,
}

pub fn run(a: Args) -> Result<()> {
    let s = load_scenario(&a.scenario)?;
    if a.json {
        println!("{}", serde_json::to_string_pretty(&describe_json(&s))?);
    } else {
        print!("{}", describe(&s));
    }
    Ok(())
}

fn fmt_vec(v: &[f64]) -> String {
    let parts: Vec<String> = v.iter().map(|x| format!("{x:.3}")).collect();
    format!("({})", parts.join(", "))
}

fn measurement_dims(s: &Scenario) -> Vec<usize> {
    let mut ms: Vec<usize> = s.sensors.iter().map(|x| x.dim()).collect();
    ms.sort_unstable();
    ms.dedup();
    ms
}

fn describe_json(s: &Scenario) -> serde_json::Value {
    let legs: Vec<_> = (0..s.num_legs())
        .map(|i| {
            let from = s.leg_start(i);
            let to = &s.legs[i].to;
            json!({"from": from.as_slice(), "to": to.as_slice(), "length": (to - from).norm(),
                   "sensor": s.leg_sensor(i).name})
        })
        .collect();
    let sensors: Vec<_> = s
        .sensors
        .iter()
        .map(|x| json!({"name": x.name, "position": x.position.as_slice(), "m": x.dim(), "cost": x.cost}))
        .collect();
    let obstacles: Vec<_> = s
        .obstacles
        .iter()
        .map(|o| json!({"name": o.name, "min": o.bounds.min, "max": o.bounds.max}))
        .collect();
    let thresholds: Vec<_> = s
        .deltas
        .iter()
        .map(|&d| {
            let rates: serde_json::Map<String, serde_json::Value> = measurement_dims(s)
                .into_iter()
                .map(|m| (format!("m{m}"), json!(expected_rate(d, m))))
                .collect();
            json!({"delta": d, "expected_rate": rates})
        })
        .collect();
    json!({"name": s.name, "description": s.description, "dim": s.dim, "content_hash": s.content_hash,
           "legs": legs, "sensors": sensors, "obstacles": obstacles,
           "target": {"min": s.target.min, "max": s.target.max}, "thresholds": thresholds,
           "controller": {"u_max": s.controller.u_max, "eps_x": s.controller.eps_x, "k_max": s.controller.k_max,
                          "K": s.gain.as_ref().map(rows)},
           "workspace_dim": s.workspace_dim(), "input_dim": s.input_dim(),
           "C": s.workspace.as_ref().map(rows), "warnings": s.warnings})
}

fn rows(m: &nalgebra::DMatrix<f64>) -> Vec<Vec<f64>> {
    m.row_iter().map(|r| r.iter().copied().collect()).collect()
}

/// The human-readable description printed by `etp check`.
pub fn describe(s: &Scenario) -> String {
    use std::fmt::Write;
    let mut o = String::new();
    if s.workspace.is_some() || s.gain.is_some() {
        let _ = writeln!(
            o,
            "scenario {} (n = {}, workspace d = {}, input p = {}) — ok",
            s.name,
            s.dim,
            s.workspace_dim(),
            s.input_dim()
        );
    } else {
        let _ = writeln!(o, "scenario {} ({}-D) — ok", s.name, s.dim);
    }
    for w in &s.warnings {
        let _ = writeln!(o, "  warning: {w}");
    }
    if !s.description.is_empty() {
        let _ = writeln!(o, "  {}", s.description);
    }
    let _ = writeln!(o, "  content hash {}", &s.content_hash[..16]);
    let _ = writeln!(
        o,
        "  controller: u_max {}, eps_x {}, k_max {}",
        s.controller.u_max, s.controller.eps_x, s.controller.k_max
    );
    if let Some(k) = &s.gain {
        let _ = writeln!(o, "  feedback gain K ({}×{}):", k.nrows(), k.ncols());
        for r in k.row_iter() {
            let v: Vec<f64> = r.iter().copied().collect();
            let _ = writeln!(o, "    {}", fmt_vec(&v));
        }
    }
    let _ = writeln!(o, "\nlegs ({}):", s.num_legs());
    let _ = writeln!(
        o,
        "  {:>3}  {:<24} {:<24} {:>7}  sensor",
        "#", "from", "to", "length"
    );
    for i in 0..s.num_legs() {
        let from = s.leg_start(i);
        let to = &s.legs[i].to;
        let _ = writeln!(
            o,
            "  {:>3}  {:<24} {:<24} {:>7.3}  {}",
            i,
            fmt_vec(from.as_slice()),
            fmt_vec(to.as_slice()),
            (to - from).norm(),
            s.leg_sensor(i).name
        );
    }
    let _ = writeln!(o, "\nsensors ({}):", s.sensors.len());
    for x in &s.sensors {
        let legs: Vec<String> = (0..s.num_legs())
            .filter(|&i| s.leg_sensor(i).name == x.name)
            .map(|i| i.to_string())
            .collect();
        let _ = writeln!(
            o,
            "  {:<8} at {:<24} m = {}  cost {}  legs [{}]",
            x.name,
            fmt_vec(x.position.as_slice()),
            x.dim(),
            x.cost,
            legs.join(", ")
        );
    }
    let _ = writeln!(o, "\nobstacles ({}):", s.obstacles.len());
    for ob in &s.obstacles {
        let _ = writeln!(
            o,
            "  {:<8} {} – {}",
            ob.name,
            fmt_vec(&ob.bounds.min),
            fmt_vec(&ob.bounds.max)
        );
    }
    let _ = writeln!(
        o,
        "\ntarget {} – {}",
        fmt_vec(&s.target.min),
        fmt_vec(&s.target.max)
    );
    let ms = measurement_dims(s);
    let header: Vec<String> = ms.iter().map(|m| format!("γ̄(δ), m={m}")).collect();
    let _ = writeln!(
        o,
        "\nthresholds ({}):   δ   {}",
        s.deltas.len(),
        header.join("  ")
    );
    for &d in &s.deltas {
        let rates: Vec<String> = ms
            .iter()
            .map(|&m| format!("{:>12.4}", expected_rate(d, m)))
            .collect();
        let _ = writeln!(o, "  {:>20.4}  {}", d, rates.join("  "));
    }
    o
}
