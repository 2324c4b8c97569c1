//! From the raw TOML shape to a [`Scenario`] the maths can trust.
//!
//! Every check names the field (`sensor[1] "s1".R`, `leg[3].sensor`, ...) and the
//! reason, so a user can fix the file without reading code.

use super::fields::{matrix, positive, spd, vector};
use super::raw::{RawBox, RawController, RawObstacle, RawRadio, RawScenario, RawSensor};
use super::{ControllerParams, Leg, MAX_DIM, Obstacle, Plant, Scenario, ScenarioError, Sensor};
use super::{workable, workspace_gain};
use crate::geometry::Aabb;
use crate::radio::{Estimator, Link, LinkFields, Radio};
use crate::trigger::TriggerFamily;
use nalgebra::{DMatrix, DVector};
use sha2::{Digest, Sha256};
use std::collections::HashMap;

type Result<T> = std::result::Result<T, ScenarioError>;

/// Parses a workspace point (d entries) of a named field.
type WorkspacePoint<'a> = dyn Fn(&str, &[f64]) -> Result<DVector<f64>> + 'a;

pub(crate) fn validate(mut raw: RawScenario) -> Result<Scenario> {
    let trigger = match raw.triggering.family.as_deref() {
        None => TriggerFamily::Box,
        Some(name) => TriggerFamily::parse(name)
            .map_err(|e| ScenarioError::invalid("triggering.family", e.to_string()))?,
    };
    if trigger == TriggerFamily::Box {
        // `family = "box"` is the default said aloud: the same scenario.
        raw.triggering.family = None;
    }
    let content_hash = content_hash(&raw);
    let n = raw.dim;
    if n == 0 || n > MAX_DIM {
        return Err(ScenarioError::invalid(
            "dim",
            format!("must be between 1 and {MAX_DIM}, got {n}"),
        ));
    }
    check_name(&raw.name)?;

    let m = &raw.model;
    // G is n×p (MODEL.md §7): its first row fixes p, 1 ≤ p ≤ n.
    let p = m.g.first().map_or(0, Vec::len);
    if p == 0 || p > n {
        return Err(ScenarioError::invalid(
            "model.G",
            format!("must be n×p with n = dim = {n} and 1 <= p <= n, got {p} columns"),
        ));
    }
    let plant = Plant {
        f: matrix("model.F", &m.f, Some(n), n)?,
        g: matrix("model.G", &m.g, Some(n), p)?,
        q: spd("model.Q", &m.q, n)?,
        x0: vector("model.x0", &m.x0, n)?,
        p0: spd("model.P0", &m.p0, n)?,
    };
    let workspace = match &m.c {
        Some(c) => Some(workspace_gain::workspace_map(c, n)?),
        None => None,
    };
    let d = workspace.as_ref().map_or(n, DMatrix::nrows);
    let gain = workspace_gain::feedback_gain(&raw.controller, &plant)?;
    // Workspace points (legs, sensor positions, boxes) have d entries.
    let point = |field: &str, raw: &[f64]| -> Result<DVector<f64>> {
        if workspace.is_some() && raw.len() != d {
            return Err(ScenarioError::invalid(
                field,
                format!(
                    "a workspace point must have d = {d} entries (the rows of model.C), got {}",
                    raw.len()
                ),
            ));
        }
        vector(field, raw, d)
    };
    let route_start = match &workspace {
        Some(c) => c * &plant.x0,
        None => plant.x0.clone(),
    };

    let controller = controller(&raw.controller)?;

    let (sensors, by_name) = sensors(&raw.sensors, n, &point)?;

    let obstacles = obstacles(&raw.obstacles, &point)?;

    if let Some((j, o)) = obstacle_at(&obstacles, &route_start) {
        return Err(ScenarioError::invalid(
            "model.x0",
            format!("the start lies inside obstacle[{j}] \"{}\"", o.name),
        ));
    }

    let legs = legs(&raw, &by_name, &point, &obstacles)?;

    let target = aabb("target", &raw.target, &point)?;

    let deltas = deltas(&raw.triggering.deltas)?;

    let radio = radio(raw.radio.as_ref(), &raw.sensors)?;

    let mut warnings = workable::check(
        &plant,
        workspace.as_ref(),
        &controller,
        &sensors,
        &legs,
        &route_start,
    )?;
    if let Some(c) = &workspace {
        warnings.extend(workspace_gain::rest_point_warnings(c, &plant.f, &legs));
    }

    Ok(Scenario {
        name: raw.name,
        description: raw.description,
        dim: n,
        plant,
        controller,
        sensors,
        legs,
        target,
        obstacles,
        deltas,
        content_hash,
        workspace,
        gain,
        route_start,
        warnings,
        radio,
        trigger,
    })
}

/// `[controller]`: u_max and eps_x positive, k_max a whole number of steps.
fn controller(c: &RawController) -> Result<ControllerParams> {
    positive("controller.u_max", c.u_max)?;
    positive("controller.eps_x", c.eps_x)?;
    if c.k_max < 1 || c.k_max > i64::from(u32::MAX) {
        return Err(ScenarioError::invalid(
            "controller.k_max",
            format!("must be a whole number of steps >= 1, got {}", c.k_max),
        ));
    }
    Ok(ControllerParams {
        u_max: c.u_max,
        eps_x: c.eps_x,
        k_max: c.k_max as u32,
    })
}

/// The `[[sensor]]`s: named once each, m ≤ n rows of H, R positive
/// definite, cost ≥ 0; and the index of each name.
fn sensors(
    raw: &[RawSensor],
    n: usize,
    point: &WorkspacePoint<'_>,
) -> Result<(Vec<Sensor>, HashMap<String, usize>)> {
    if raw.is_empty() {
        return Err(ScenarioError::invalid(
            "sensor",
            "no sensors: at least one [[sensor]] is needed",
        ));
    }
    let mut sensors = Vec::with_capacity(raw.len());
    let mut by_name = HashMap::new();
    for (i, s) in raw.iter().enumerate() {
        let at = format!("sensor[{i}] \"{}\"", s.name);
        if s.name.trim().is_empty() {
            return Err(ScenarioError::invalid(
                format!("sensor[{i}].name"),
                "must not be empty",
            ));
        }
        if let Some(first) = by_name.insert(s.name.clone(), i) {
            return Err(ScenarioError::invalid(
                format!("{at}.name"),
                format!("duplicate sensor name (also sensor[{first}])"),
            ));
        }
        let rows = s.h.len();
        if rows == 0 || rows > n {
            return Err(ScenarioError::invalid(
                format!("{at}.H"),
                format!(
                    "must have between 1 and dim = {n} rows (measurement dimension m <= n), got {rows}"
                ),
            ));
        }
        let cost = s.cost + 0.0; // −0 as +0 (see the thresholds below)
        if !cost.is_finite() || cost < 0.0 {
            return Err(ScenarioError::invalid(
                format!("{at}.cost"),
                format!("must be a finite number >= 0, got {cost}"),
            ));
        }
        sensors.push(Sensor {
            name: s.name.clone(),
            position: point(&format!("{at}.position"), &s.position)?,
            h: matrix(&format!("{at}.H"), &s.h, Some(rows), n)?,
            r: spd(&format!("{at}.R"), &s.r, rows)?,
            cost,
        });
    }
    Ok((sensors, by_name))
}

/// The `[[obstacle]]`s, each a box of workspace points.
fn obstacles(raw: &[RawObstacle], point: &WorkspacePoint<'_>) -> Result<Vec<Obstacle>> {
    raw.iter()
        .enumerate()
        .map(|(i, o)| {
            let name = o.name.clone().unwrap_or_else(|| format!("obstacle{i}"));
            let at = format!("obstacle[{i}] \"{name}\"");
            let bounds = aabb(
                &at,
                &RawBox {
                    min: o.min.clone(),
                    max: o.max.clone(),
                },
                point,
            )?;
            Ok(Obstacle { name, bounds })
        })
        .collect::<Result<Vec<_>>>()
}

/// The `[[leg]]`s: a non-empty route of waypoints outside every obstacle,
/// each served by a known sensor.
fn legs(
    raw: &RawScenario,
    by_name: &HashMap<String, usize>,
    point: &WorkspacePoint<'_>,
    obstacles: &[Obstacle],
) -> Result<Vec<Leg>> {
    if raw.legs.is_empty() {
        return Err(ScenarioError::invalid(
            "leg",
            "the route is empty: at least one [[leg]] is needed",
        ));
    }
    let mut legs = Vec::with_capacity(raw.legs.len());
    for (i, l) in raw.legs.iter().enumerate() {
        let to = point(&format!("leg[{i}].to"), &l.to)?;
        let sensor = *by_name.get(&l.sensor).ok_or_else(|| {
            ScenarioError::invalid(
                format!("leg[{i}].sensor"),
                format!(
                    "unknown sensor \"{}\" (known: {})",
                    l.sensor,
                    raw.sensors
                        .iter()
                        .map(|s| s.name.as_str())
                        .collect::<Vec<_>>()
                        .join(", ")
                ),
            )
        })?;
        if let Some((j, o)) = obstacle_at(obstacles, &to) {
            return Err(ScenarioError::invalid(
                format!("leg[{i}].to"),
                format!("the waypoint lies inside obstacle[{j}] \"{}\"", o.name),
            ));
        }
        legs.push(Leg { to, sensor });
    }
    Ok(legs)
}

/// The first obstacle holding the workspace point `p`, with its index.
fn obstacle_at<'a>(obstacles: &'a [Obstacle], p: &DVector<f64>) -> Option<(usize, &'a Obstacle)> {
    obstacles
        .iter()
        .enumerate()
        .find(|(_, o)| o.bounds.contains(p.as_slice()))
}

/// `[triggering] deltas`: finite, ≥ 0, each once.
fn deltas(raw: &[f64]) -> Result<Vec<f64>> {
    // `+ 0.0` turns a −0 into +0 and leaves every other value's bits: a
    // threshold or cost of −0 would otherwise reach the wire as −0, which
    // the recording's protobuf (proto3 drops zero scalars) cannot keep.
    let deltas: Vec<f64> = raw.iter().map(|d| d + 0.0).collect();
    if deltas.is_empty() {
        return Err(ScenarioError::invalid(
            "triggering.deltas",
            "at least one threshold is needed",
        ));
    }
    for (i, &d) in deltas.iter().enumerate() {
        if !d.is_finite() || d < 0.0 {
            return Err(ScenarioError::invalid(
                format!("triggering.deltas[{i}]"),
                format!("a threshold must be a finite number >= 0, got {d}"),
            ));
        }
        if let Some(j) = deltas[..i].iter().position(|&e| e == d) {
            return Err(ScenarioError::invalid(
                format!("triggering.deltas[{i}]"),
                format!("duplicate threshold {d} (also deltas[{j}])"),
            ));
        }
    }
    Ok(deltas)
}

/// `[radio]` and the per-sensor `loss`/`retries`/`burst`, resolved to one
/// checked link per sensor; errors name the field the offending value came
/// from (the sensor's own, else `radio.*`).
fn radio(raw: Option<&RawRadio>, sensors: &[RawSensor]) -> Result<Radio> {
    let estimator = match raw.and_then(|r| r.estimator.as_deref()) {
        None => Estimator::default(),
        Some(name) => Estimator::parse(name).ok_or_else(|| {
            ScenarioError::invalid(
                "radio.estimator",
                format!("must be \"aware\" or \"naive\", got {name:?}"),
            )
        })?,
    };
    let links = sensors
        .iter()
        .enumerate()
        .map(|(i, s)| {
            let at = format!("sensor[{i}] \"{}\"", s.name);
            let own = |has: bool, name: &str| {
                if has {
                    format!("{at}.{name}")
                } else {
                    format!("radio.{name}")
                }
            };
            let (loss_f, retries_f) = (
                own(s.loss.is_some(), "loss"),
                own(s.retries.is_some(), "retries"),
            );
            // The burst bound involves loss and B: name the sensor's own field
            // when it set either.
            let burst_f = if s.burst.is_some() || s.loss.is_some() {
                format!("{at}.burst")
            } else {
                "radio.burst".to_string()
            };
            Link::checked(
                s.loss.or(raw.and_then(|r| r.loss)).unwrap_or(0.0),
                s.retries.or(raw.and_then(|r| r.retries)).unwrap_or(0),
                s.burst.or(raw.and_then(|r| r.burst)),
                LinkFields {
                    loss: &loss_f,
                    retries: &retries_f,
                    burst: &burst_f,
                },
            )
            .map_err(|e| ScenarioError::invalid(e.field, e.reason))
        })
        .collect::<Result<Vec<_>>>()?;
    Ok(Radio { estimator, links })
}

/// Longest scenario name.
const NAME_MAX: usize = 64;

/// A scenario's name becomes a folder and file name (`out/<name>/`,
/// `recordings/<name>-<run>.mcap`): one path component of
/// `[A-Za-z0-9][A-Za-z0-9._-]{0,63}`, so it can neither climb out of the
/// output folder (`..`, `/`) nor be hidden (leading `.`) or read as an option
/// (leading `-`).
fn check_name(name: &str) -> Result<()> {
    let mut chars = name.chars();
    let ok = chars.next().is_some_and(|c| c.is_ascii_alphanumeric())
        && chars.all(|c| c.is_ascii_alphanumeric() || matches!(c, '.' | '_' | '-'))
        && name.len() <= NAME_MAX;
    if ok {
        Ok(())
    } else {
        Err(ScenarioError::invalid(
            "name",
            format!(
                "must be 1 to {NAME_MAX} characters of A-Z a-z 0-9 . _ - starting with a letter \
                 or digit (it names output folders), got {name:?}"
            ),
        ))
    }
}

/// SHA-256 over the canonical (parsed, defaults filled) content, so comments and
/// formatting do not change it but any value does.
fn content_hash(raw: &RawScenario) -> String {
    // Serialising plain structs of numbers and strings cannot fail.
    let canonical = serde_json::to_vec(raw).unwrap_or_default();
    let digest = Sha256::digest(&canonical);
    digest.iter().map(|b| format!("{b:02x}")).collect()
}

fn aabb(field: &str, raw: &RawBox, point: &WorkspacePoint<'_>) -> Result<Aabb> {
    let min = point(&format!("{field}.min"), &raw.min)?;
    let max = point(&format!("{field}.max"), &raw.max)?;
    for i in 0..min.len() {
        if min[i] > max[i] {
            return Err(ScenarioError::invalid(
                field,
                format!("min > max on axis {i}: {} > {}", min[i], max[i]),
            ));
        }
    }
    Ok(Aabb {
        min: min.as_slice().to_vec(),
        max: max.as_slice().to_vec(),
    })
}

#[cfg(test)]
mod name_tests {
    use super::check_name;

    #[test]
    fn names_are_one_safe_path_component() {
        for ok in ["open-2d", "a", "Winding_2D.v2", &"x".repeat(64)] {
            assert!(check_name(ok).is_ok(), "{ok:?}");
        }
        for bad in [
            "",
            "../../escape",
            "..",
            ".hidden",
            "-rf",
            "a/b",
            "a\\b",
            "with space",
            "é",
            &"x".repeat(65),
        ] {
            let e = check_name(bad).expect_err(bad).to_string();
            assert!(e.contains("field `name`"), "{bad:?}: {e}");
        }
    }
}
