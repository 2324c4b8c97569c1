//! What is drawn: the scenario's map, the agent at one step, the true path
//! of one episode. Coordinates are the scenario's own in frame `world`; a
//! 2-D scenario lies in the plane z = 0 with its boxes drawn as thin slabs.

use super::geometry::{Ellipsoid, ellipsoid};
use super::msg::{
    Color, CubePrimitive, LinePrimitive, Pose, SceneEntity, SceneUpdate, SpherePrimitive,
    TextPrimitive, Time, Vector3, kv, rgba,
};
use etp_runtime::wire::agent_to_coordinator::Outcome;
use etp_shared::geometry::Aabb;
use etp_shared::scenario::Scenario;
use nalgebra::{Matrix3, Vector3 as V3};

/// Ellipses and ellipsoids are drawn at this many standard deviations.
pub const SIGMA: f64 = 3.0;
/// Height of a 2-D box, and thickness of a 2-D ellipse disc: thin enough to
/// read as the plane, thick enough to be seen from above at an angle.
const SLAB: f64 = 0.1;
const DISC: f64 = 0.01;

const OBSTACLE: Color = rgba(0.55, 0.45, 0.38, 0.9);
const TARGET: Color = rgba(0.1, 0.8, 0.25, 0.45);
const ROUTE: Color = rgba(0.35, 0.55, 0.95, 0.8);
const SENSOR: Color = rgba(0.65, 0.35, 0.85, 1.0);
const LABEL: Color = rgba(1.0, 1.0, 1.0, 1.0);
/// The agent in a slot where its sensor transmitted / stayed silent / the
/// slot's closing message is not in the file.
const SENT: Color = rgba(1.0, 0.55, 0.0, 1.0);
const SILENT: Color = rgba(0.2, 0.55, 1.0, 1.0);
const UNKNOWN: Color = rgba(0.6, 0.6, 0.6, 1.0);

fn faded(c: Color, a: f64) -> Color {
    Color { a, ..c }
}

/// The colour of an episode's path: target green, collision red, free
/// (step limit) grey.
pub fn outcome_color(outcome: u32) -> Color {
    match outcome {
        Outcome::TARGET => rgba(0.1, 0.8, 0.25, 0.9),
        Outcome::COLLISION => rgba(0.9, 0.12, 0.1, 0.9),
        Outcome::FREE => rgba(0.6, 0.6, 0.6, 0.9),
        _ => rgba(0.95, 0.85, 0.1, 0.9),
    }
}

pub fn outcome_name(outcome: u32) -> &'static str {
    match outcome {
        Outcome::TARGET => "TARGET",
        Outcome::COLLISION => "COLLISION",
        Outcome::FREE => "FREE",
        _ => "UNKNOWN",
    }
}

/// A scenario point (2 or 3 coordinates) in 3-D.
fn p3(v: &[f64]) -> V3<f64> {
    V3::from_fn(|i, _| v.get(i).copied().unwrap_or(0.0))
}

fn cube(b: &Aabb, dim: usize, color: Color) -> CubePrimitive {
    let (lo, hi) = (p3(&b.min), p3(&b.max));
    let mut size = hi - lo;
    if dim < 3 {
        size.z = SLAB;
    }
    CubePrimitive {
        pose: Pose::at((lo + hi) / 2.0),
        size: size.into(),
        color,
    }
}

/// The map: obstacles, target, the route through the waypoints (start
/// white), the sensors with their names. Stable ids, so publishing it again
/// replaces it.
pub fn scene(s: &Scenario, t: Time) -> SceneUpdate {
    let mut obstacles = SceneEntity::new(t, "obstacles");
    for o in &s.obstacles {
        obstacles.cubes.push(cube(&o.bounds, s.dim, OBSTACLE));
    }
    obstacles.metadata = s
        .obstacles
        .iter()
        .enumerate()
        .map(|(i, o)| kv(&format!("obstacle {i}"), &o.name))
        .collect();
    let mut target = SceneEntity::new(t, "target");
    target.cubes.push(cube(&s.target, s.dim, TARGET));
    let mut route = SceneEntity::new(t, "route");
    let mut points = vec![p3(s.plant.x0.as_slice())];
    points.extend(s.legs.iter().map(|l| p3(l.to.as_slice())));
    route.spheres = points
        .iter()
        .enumerate()
        .map(|(i, p)| SpherePrimitive::ball(*p, 0.08, if i == 0 { LABEL } else { ROUTE }))
        .collect();
    route.lines.push(LinePrimitive::strip(
        points.iter().map(|p| Vector3::from(*p)).collect(),
        1.5,
        faded(ROUTE, 0.5),
    ));
    route.metadata = s
        .legs
        .iter()
        .enumerate()
        .map(|(i, l)| {
            let sensor = s.sensors.get(l.sensor).map_or("?", |x| x.name.as_str());
            kv(&format!("leg {i}"), format!("served by {sensor}"))
        })
        .collect();
    let mut sensors = SceneEntity::new(t, "sensors");
    for x in &s.sensors {
        let p = p3(x.position.as_slice());
        sensors.spheres.push(SpherePrimitive::ball(p, 0.15, SENSOR));
        sensors.texts.push(TextPrimitive::label(
            p + V3::new(0.0, 0.0, 0.25),
            14.0,
            SENSOR,
            x.name.clone(),
        ));
    }
    SceneUpdate::of(vec![obstacles, target, route, sensors])
}

/// One step of the agent as the file has it.
#[derive(Debug, Clone, Default)]
pub struct AgentView {
    pub episode: u64,
    pub step: u32,
    pub leg: u32,
    pub dim: usize,
    /// The serving sensor's name, and the threshold δ of the leg if known.
    pub sensor: Option<String>,
    pub delta: Option<f64>,
    pub truth: Option<V3<f64>>,
    /// The prior x̂⁻_k, P⁻_k (position block) sent to the sensor for slot k.
    pub prior: Option<(V3<f64>, Matrix3<f64>)>,
    pub transmitted: Option<bool>,
}

fn finite(v: &V3<f64>) -> bool {
    v.iter().all(|x| x.is_finite())
}

/// The agent at one step: the true position (coloured by the slot: orange
/// transmitted, blue silent), the belief mean (white) and its 3σ ellipse.
/// One id, so each step replaces the previous one.
pub fn agent(a: &AgentView, t: Time) -> SceneUpdate {
    let color = match a.transmitted {
        Some(true) => SENT,
        Some(false) => SILENT,
        None => UNKNOWN,
    };
    let mut e = SceneEntity::new(t, "agent");
    e.metadata = vec![
        kv("episode", a.episode),
        kv("step", a.step),
        kv("leg", a.leg),
    ];
    let mut anchor = None;
    if let Some((mean, cov)) = a.prior.as_ref().filter(|(m, _)| finite(m)) {
        if let Some(el) = ellipsoid(cov, a.dim.min(3), SIGMA, DISC) {
            e.spheres
                .push(SpherePrimitive::ellipsoid(*mean, &el, faded(color, 0.3)));
            e.metadata.push(kv("ellipse", ellipse_note(&el)));
        }
        e.spheres.push(SpherePrimitive::ball(*mean, 0.05, LABEL));
        anchor = Some(*mean);
    }
    if let Some(x) = a.truth.filter(finite) {
        e.spheres.push(SpherePrimitive::ball(x, 0.1, color));
        anchor = Some(x);
    }
    if let Some(p) = anchor {
        let slot = match a.transmitted {
            Some(true) => "sent",
            Some(false) => "silent",
            None => "slot ?",
        };
        let mut text = format!("ep {} · k {} · leg {}", a.episode, a.step, a.leg);
        if let Some(s) = &a.sensor {
            text += &format!(" · {s}");
        }
        if let Some(d) = a.delta {
            text += &format!(" δ={d}");
        }
        text += &format!(" · {slot}");
        e.texts.push(TextPrimitive::label(
            p + V3::new(0.0, 0.0, 0.3),
            13.0,
            LABEL,
            text,
        ));
    }
    SceneUpdate::of(vec![e])
}

fn ellipse_note(e: &Ellipsoid) -> String {
    format!(
        "{SIGMA}σ of the prior covariance; diameters {:.4} {:.4} {:.4}",
        e.size[0], e.size[1], e.size[2]
    )
}

/// The id of episode `e`'s path: one per episode, so the paths accumulate.
pub fn trajectory_id(episode: u64) -> String {
    format!("episode-{episode}")
}

/// The true path of an episode, coloured by its outcome.
pub fn trajectory(episode: u64, points: &[V3<f64>], outcome: u32, t: Time) -> SceneUpdate {
    let mut e = SceneEntity::new(t, trajectory_id(episode));
    e.metadata = vec![
        kv("episode", episode),
        kv("outcome", outcome_name(outcome)),
        kv("steps", points.len()),
    ];
    e.lines.push(LinePrimitive::strip(
        points
            .iter()
            .filter(|p| finite(p))
            .map(|p| Vector3::from(*p))
            .collect(),
        2.0,
        outcome_color(outcome),
    ));
    SceneUpdate::of(vec![e])
}
