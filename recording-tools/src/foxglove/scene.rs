//! What is drawn of a recording: the scenario's map (built by
//! [`super::map`]), the agent at one step, the true path of one episode.
//! Coordinates are the scenario's own in frame `world`; a 2-D scenario lies
//! in the plane z = 0 with its boxes drawn as thin slabs.

use super::geometry::{Ellipsoid, ellipsoid};
use super::map::{self, Draw, SENT, SILENT, WHITE};
use super::msg::{
    Color, CubePrimitive, LinePrimitive, Pose, SceneEntity, SceneUpdate, SpherePrimitive,
    TextPrimitive, Time, Vector3, kv, rgba,
};
use etp_runtime::wire::agent_to_coordinator::Outcome;
use etp_shared::scenario::Scenario;
use nalgebra::{Matrix3, Vector3 as V3};

/// Ellipses and ellipsoids are drawn at this many standard deviations.
pub const SIGMA: f64 = 3.0;
/// Thickness of a 2-D ellipse disc.
const DISC: f64 = 0.01;

/// The agent in a slot whose closing message is not in the file.
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

/// The JSON messages of a recording's copy, stamped with the time they hold.
struct JsonMessages(Time);

impl Draw for JsonMessages {
    type Entity = SceneEntity;
    type Update = SceneUpdate;

    fn entity(&self, id: &str) -> SceneEntity {
        SceneEntity::new(self.0, id)
    }

    fn cube(&self, e: &mut SceneEntity, centre: V3<f64>, size: V3<f64>, color: Color) {
        e.cubes.push(CubePrimitive {
            pose: Pose::at(centre),
            size: size.into(),
            color,
        });
    }

    fn ball(&self, e: &mut SceneEntity, p: V3<f64>, d: f64, color: Color) {
        e.spheres.push(SpherePrimitive::ball(p, d, color));
    }

    fn strip(&self, e: &mut SceneEntity, points: &[V3<f64>], thickness: f64, color: Color) {
        let points = points.iter().map(|p| Vector3::from(*p)).collect();
        e.lines.push(LinePrimitive::strip(points, thickness, color));
    }

    fn label(&self, e: &mut SceneEntity, p: V3<f64>, px: f64, color: Color, text: String) {
        e.texts.push(TextPrimitive::label(p, px, color, text));
    }

    fn note(&self, e: &mut SceneEntity, key: String, value: String) {
        e.metadata.push(kv(&key, value));
    }

    fn update(&self, entities: Vec<SceneEntity>) -> SceneUpdate {
        SceneUpdate::of(entities)
    }
}

/// The map (see [`map::scene`]), its route from the plant's initial state.
pub fn scene(s: &Scenario, t: Time) -> SceneUpdate {
    map::scene(&JsonMessages(t), s, s.dim, s.plant.x0.as_slice())
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
        e.spheres.push(SpherePrimitive::ball(*mean, 0.05, WHITE));
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
            WHITE,
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
