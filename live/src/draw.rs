//! What the live view draws, as Foxglove's own schemas (`foxglove.SceneUpdate`,
//! `foxglove.Log`): the scenario's map (built by
//! `etp_recording_tools::foxglove::map`, as for a recording's copy) and the
//! agent at one slot. Frame `world`, the scenario's workspace coordinates (a
//! 2-D scenario in the plane z = 0, its boxes as thin slabs); a state is drawn
//! through the workspace map C (position C x, covariance C P Cᵀ), like the
//! legs and obstacles.

use etp_recording_tools::foxglove::geometry::ellipsoid;
use etp_recording_tools::foxglove::map::{self, Draw, point};
use etp_runtime::live::SlotFrame;
use etp_shared::scenario::Scenario;
use foxglove::messages::{
    Color, CubePrimitive, KeyValuePair, LinePrimitive, Point3, Pose, Quaternion, SceneEntity,
    SceneUpdate, SpherePrimitive, TextPrimitive, Timestamp, Vector3,
};
use nalgebra::{DMatrix, DVector, Matrix3, Vector3 as V3};

/// The frame every entity is drawn in.
pub const FRAME: &str = "world";
/// Ellipses and ellipsoids at this many standard deviations.
pub const SIGMA: f64 = 3.0;
const DISC: f64 = 0.01;

/// A colour of the map's palette as Foxglove's protobuf message.
const fn color(c: map::Color) -> Color {
    Color {
        r: c.r,
        g: c.g,
        b: c.b,
        a: c.a,
    }
}
/// The agent in a slot where its sensor transmitted / stayed silent.
pub const SENT: Color = color(map::SENT);
pub const SILENT: Color = color(map::SILENT);
const ELLIPSE: Color = color(map::rgba(1.0, 1.0, 1.0, 0.25));

/// The scenario's geometry, for drawing states.
#[derive(Debug, Clone)]
pub struct Map {
    /// The workspace map C (d × n).
    c: DMatrix<f64>,
    /// Workspace dimension d (drawn: the first three).
    d: usize,
}

impl Map {
    pub fn new(s: &Scenario) -> Self {
        let c = s
            .workspace
            .clone()
            .unwrap_or_else(|| DMatrix::identity(s.dim, s.dim));
        let d = c.nrows();
        Self { c, d }
    }

    /// Position C x and covariance C P Cᵀ (leading 3 × 3 block) of a state
    /// of dimension n (`p` row-major n × n); `None` if the sizes disagree.
    pub fn project(&self, x: &[f64], p: Option<&[f64]>) -> Option<(V3<f64>, Option<Matrix3<f64>>)> {
        let n = self.c.ncols();
        if x.len() != n {
            return None;
        }
        let w = &self.c * DVector::from_column_slice(x);
        let pos = point(w.as_slice());
        let cov = match p {
            Some(p) if p.len() == n * n => {
                let s = &self.c * DMatrix::from_row_slice(n, n, p) * self.c.transpose();
                Some(Matrix3::from_fn(|r, c| {
                    if r < self.d && c < self.d {
                        s[(r, c)]
                    } else {
                        0.0
                    }
                }))
            }
            _ => None,
        };
        Some((pos, cov))
    }

    /// Dimension of the drawing (2 or 3).
    pub fn dim(&self) -> usize {
        self.d.min(3)
    }
}

fn v3(p: V3<f64>) -> Vector3 {
    Vector3 {
        x: p.x,
        y: p.y,
        z: p.z,
    }
}

fn pose(p: V3<f64>) -> Option<Pose> {
    Some(Pose {
        position: Some(v3(p)),
        orientation: Some(Quaternion {
            x: 0.0,
            y: 0.0,
            z: 0.0,
            w: 1.0,
        }),
    })
}

/// Foxglove's protobuf messages, as the live view sends them, stamped
/// with the time they hold.
struct ProtobufMessages(Timestamp);

impl Draw for ProtobufMessages {
    type Entity = SceneEntity;
    type Update = SceneUpdate;

    fn entity(&self, id: &str) -> SceneEntity {
        SceneEntity {
            timestamp: Some(self.0),
            frame_id: FRAME.into(),
            id: id.into(),
            ..SceneEntity::default()
        }
    }

    fn cube(&self, e: &mut SceneEntity, centre: V3<f64>, size: V3<f64>, c: map::Color) {
        e.cubes.push(CubePrimitive {
            pose: pose(centre),
            size: Some(v3(size)),
            color: Some(color(c)),
        });
    }

    fn ball(&self, e: &mut SceneEntity, p: V3<f64>, d: f64, c: map::Color) {
        e.spheres.push(SpherePrimitive {
            pose: pose(p),
            size: Some(Vector3 { x: d, y: d, z: d }),
            color: Some(color(c)),
        });
    }

    fn strip(&self, e: &mut SceneEntity, points: &[V3<f64>], thickness: f64, c: map::Color) {
        e.lines.push(LinePrimitive {
            thickness,
            scale_invariant: true,
            points: points
                .iter()
                .map(|p| Point3 {
                    x: p.x,
                    y: p.y,
                    z: p.z,
                })
                .collect(),
            color: Some(color(c)),
            ..LinePrimitive::default()
        });
    }

    fn label(&self, e: &mut SceneEntity, p: V3<f64>, px: f64, c: map::Color, text: String) {
        e.texts.push(TextPrimitive {
            pose: pose(p),
            billboard: true,
            font_size: px,
            scale_invariant: true,
            color: Some(color(c)),
            text,
        });
    }

    fn note(&self, e: &mut SceneEntity, key: String, value: String) {
        e.metadata.push(KeyValuePair { key, value });
    }

    fn update(&self, entities: Vec<SceneEntity>) -> SceneUpdate {
        SceneUpdate {
            deletions: Vec::new(),
            entities,
        }
    }
}

/// The map (see [`map::scene`]) in the workspace's dimension, its route
/// from the route's start (the plant's initial state if it has none).
pub fn scene(s: &Scenario, map: &Map, t: Timestamp) -> SceneUpdate {
    let start = if s.route_start.is_empty() {
        s.plant.x0.as_slice()
    } else {
        s.route_start.as_slice()
    };
    map::scene(&ProtobufMessages(t), s, map.dim(), start)
}

/// The agent at one slot: the true position (orange if the serving sensor
/// transmitted in this slot, blue if silent), the prior mean (white) and
/// its 3σ ellipse (ellipsoid in 3-D), a line to the serving sensor when it
/// transmitted, and a label (episode, step, leg, sensor, δ).
pub fn agent(s: &Scenario, map: &Map, f: &SlotFrame, t: Timestamp) -> SceneUpdate {
    let draw = ProtobufMessages(t);
    let mut e = draw.entity("agent");
    let truth = map.project(&f.x, None).map(|(p, _)| p);
    let prior = map.project(&f.mean, Some(&f.cov));
    let sent = f.attempts > 0;
    let sensor = s.sensors.get(f.sensor as usize);
    if let Some(p) = truth {
        let c = if sent { map::SENT } else { map::SILENT };
        draw.ball(&mut e, p, 0.14, c);
        let name = sensor.map_or("?", |x| x.name.as_str());
        draw.label(
            &mut e,
            p + V3::new(0.0, 0.0, 0.3),
            14.0,
            map::WHITE,
            format!(
                "episode {} step {} leg {} · {name} δ={:.4}{}",
                f.episode,
                f.step,
                f.leg,
                f.delta,
                if sent { " · sent" } else { "" }
            ),
        );
        if let (true, Some(x)) = (sent, sensor) {
            let q = point(x.position.as_slice());
            draw.strip(&mut e, &[q, p], 2.0, map::SENT);
        }
    }
    if let Some((m, cov)) = prior {
        draw.ball(&mut e, m, 0.08, map::WHITE);
        if let Some(el) = cov.and_then(|c| ellipsoid(&c, map.dim(), SIGMA, DISC)) {
            let q = el.orientation.into_inner();
            e.spheres.push(SpherePrimitive {
                pose: Some(Pose {
                    position: Some(v3(m)),
                    orientation: Some(Quaternion {
                        x: q.i,
                        y: q.j,
                        z: q.k,
                        w: q.w,
                    }),
                }),
                size: Some(Vector3 {
                    x: el.size[0],
                    y: el.size[1],
                    z: el.size[2],
                }),
                color: Some(ELLIPSE),
            });
        }
    }
    draw.update(vec![e])
}

#[cfg(test)]
mod tests {
    use super::*;
    use etp_runtime::live::Totals;

    fn frame(attempts: u32) -> SlotFrame {
        SlotFrame {
            episode: 2,
            leg: 1,
            step: 17,
            sensor: 0,
            delta: 1.5,
            x: vec![1.0, 2.0],
            mean: vec![1.2, 1.8],
            cov: vec![0.04, 0.0, 0.0, 0.01],
            attempts,
            delivered: attempts > 0,
            totals: Totals::default(),
        }
    }

    #[test]
    fn the_scene_has_every_obstacle_the_target_the_route_and_the_sensors()
    -> Result<(), Box<dyn std::error::Error>> {
        let s = etp_runtime::load_scenario("winding-2d")?;
        let u = scene(&s, &Map::new(&s), Timestamp::new(0, 0));
        let ids: Vec<_> = u.entities.iter().map(|e| e.id.as_str()).collect();
        assert_eq!(ids, ["obstacles", "target", "route", "sensors"]);
        assert_eq!(u.entities[0].cubes.len(), s.obstacles.len());
        assert_eq!(u.entities[2].spheres.len(), s.legs.len() + 1);
        assert_eq!(u.entities[3].texts.len(), s.sensors.len());
        assert!(u.entities.iter().all(|e| e.frame_id == FRAME));
        Ok(())
    }

    #[test]
    fn the_agent_has_truth_prior_and_its_3_sigma_ellipse() -> Result<(), Box<dyn std::error::Error>>
    {
        let s = etp_runtime::load_scenario("winding-2d")?;
        let map = Map::new(&s);
        let silent = agent(&s, &map, &frame(0), Timestamp::new(0, 0));
        let e = &silent.entities[0];
        assert_eq!(e.spheres.len(), 3);
        assert_eq!(e.spheres[0].color, Some(SILENT));
        // σ = 0.2 and 0.1: 3σ diameters 1.2 and 0.6, a flat disc in 2-D.
        let size = e.spheres[2].size.ok_or("no size")?;
        assert!((size.x - 1.2).abs() < 1e-12 && (size.y - 0.6).abs() < 1e-12);
        assert!(e.lines.is_empty());
        let sent = agent(&s, &map, &frame(1), Timestamp::new(0, 0));
        assert_eq!(sent.entities[0].spheres[0].color, Some(SENT));
        assert_eq!(sent.entities[0].lines.len(), 1);
        // A frame of another dimension draws nothing rather than nonsense.
        let mut odd = frame(0);
        odd.x = vec![1.0; 3];
        odd.mean = vec![1.0; 3];
        assert!(
            agent(&s, &map, &odd, Timestamp::new(0, 0)).entities[0]
                .spheres
                .is_empty()
        );
        Ok(())
    }
}
