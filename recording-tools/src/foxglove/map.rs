//! The scenario's map as Foxglove draws it, built once for both encodings:
//! the JSON copy of a recording (`etp replay … --foxglove`) and the protobuf
//! messages of the live view (`etp run --live`). Each encoding implements
//! [`Draw`], the primitives the map is made of; [`scene`] decides what is
//! drawn, where and in which colour.

pub use super::msg::{Color, rgba};
use etp_shared::geometry::Aabb;
use etp_shared::scenario::Scenario;
use nalgebra::Vector3 as V3;

pub const OBSTACLE: Color = rgba(0.55, 0.45, 0.38, 0.9);
pub const TARGET: Color = rgba(0.1, 0.8, 0.25, 0.45);
pub const ROUTE: Color = rgba(0.35, 0.55, 0.95, 0.8);
pub const SENSOR: Color = rgba(0.65, 0.35, 0.85, 1.0);
/// Labels, the route's start and the belief mean.
pub const WHITE: Color = rgba(1.0, 1.0, 1.0, 1.0);
/// The agent in a slot where its sensor transmitted / stayed silent.
pub const SENT: Color = rgba(1.0, 0.55, 0.0, 1.0);
pub const SILENT: Color = rgba(0.2, 0.55, 1.0, 1.0);

/// Height of a 2-D box: thin enough to read as the plane, thick enough to
/// be seen from above at an angle.
const SLAB: f64 = 0.1;

/// The primitives of a Foxglove scene in one encoding. An entity is filled
/// by pushing primitives and key-value notes onto it.
pub trait Draw {
    type Entity;
    type Update;
    /// An empty entity with a stable id (publishing it again replaces it).
    fn entity(&self, id: &str) -> Self::Entity;
    fn cube(&self, e: &mut Self::Entity, centre: V3<f64>, size: V3<f64>, color: Color);
    /// A round marker of diameter `d`.
    fn ball(&self, e: &mut Self::Entity, p: V3<f64>, d: f64, color: Color);
    /// A line strip `thickness` pixels wide whatever the zoom.
    fn strip(&self, e: &mut Self::Entity, points: &[V3<f64>], thickness: f64, color: Color);
    /// A label that faces the camera, `px` pixels high.
    fn label(&self, e: &mut Self::Entity, p: V3<f64>, px: f64, color: Color, text: String);
    fn note(&self, e: &mut Self::Entity, key: String, value: String);
    fn update(&self, entities: Vec<Self::Entity>) -> Self::Update;
}

/// A scenario point (its first three coordinates) in 3-D.
pub fn point(v: &[f64]) -> V3<f64> {
    V3::from_fn(|i, _| v.get(i).copied().unwrap_or(0.0))
}

fn cube<D: Draw>(d: &D, e: &mut D::Entity, b: &Aabb, dim: usize, color: Color) {
    let (lo, hi) = (point(&b.min), point(&b.max));
    let mut size = hi - lo;
    if dim < 3 {
        size.z = SLAB;
    }
    d.cube(e, (lo + hi) / 2.0, size, color);
}

/// The map: obstacles, target, the route from `start` through the waypoints
/// (start white), the sensors with their names, in a drawing of dimension
/// `dim` (below 3 the boxes are thin slabs in the plane z = 0).
pub fn scene<D: Draw>(d: &D, s: &Scenario, dim: usize, start: &[f64]) -> D::Update {
    let mut obstacles = d.entity("obstacles");
    for o in &s.obstacles {
        cube(d, &mut obstacles, &o.bounds, dim, OBSTACLE);
    }
    for (i, o) in s.obstacles.iter().enumerate() {
        d.note(&mut obstacles, format!("obstacle {i}"), o.name.clone());
    }
    let mut target = d.entity("target");
    cube(d, &mut target, &s.target, dim, TARGET);
    let mut route = d.entity("route");
    let mut points = vec![point(start)];
    points.extend(s.legs.iter().map(|l| point(l.to.as_slice())));
    for (i, p) in points.iter().enumerate() {
        d.ball(&mut route, *p, 0.08, if i == 0 { WHITE } else { ROUTE });
    }
    d.strip(&mut route, &points, 1.5, Color { a: 0.5, ..ROUTE });
    for (i, l) in s.legs.iter().enumerate() {
        let sensor = s.sensors.get(l.sensor).map_or("?", |x| x.name.as_str());
        d.note(
            &mut route,
            format!("leg {i}"),
            format!("served by {sensor}"),
        );
    }
    let mut sensors = d.entity("sensors");
    for x in &s.sensors {
        let p = point(x.position.as_slice());
        d.ball(&mut sensors, p, 0.15, SENSOR);
        d.label(
            &mut sensors,
            p + V3::new(0.0, 0.0, 0.25),
            14.0,
            SENSOR,
            x.name.clone(),
        );
    }
    d.update(vec![obstacles, target, route, sensors])
}
