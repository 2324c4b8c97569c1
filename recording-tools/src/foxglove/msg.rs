//! The Foxglove messages we write, as serde structs that serialise to the
//! JSON the official schemas (`recording-tools/assets/foxglove/`) describe. Every field
//! the schemas list as required is always written (empty arrays included):
//! Foxglove's JSON reader does not fill in defaults.

use super::geometry::Ellipsoid;
use nalgebra::{UnitQuaternion, Vector3 as V3};
use serde::Serialize;

/// The official JSON schema of `foxglove.SceneUpdate` (text as published).
pub const SCENE_UPDATE_SCHEMA: &str = include_str!("../../assets/foxglove/SceneUpdate.json");
/// The official JSON schema of `foxglove.Log`.
pub const LOG_SCHEMA: &str = include_str!("../../assets/foxglove/Log.json");
pub const SCENE_UPDATE: &str = "foxglove.SceneUpdate";
pub const LOG: &str = "foxglove.Log";
/// The one frame every entity is drawn in (the scenario's coordinates).
pub const FRAME: &str = "world";

#[derive(Debug, Clone, Copy, Serialize, PartialEq)]
pub struct Time {
    pub sec: u64,
    pub nsec: u32,
}

impl Time {
    /// A recording's `log_time` (ns since the Unix epoch).
    pub fn from_ns(ns: u64) -> Self {
        Self {
            sec: ns / 1_000_000_000,
            nsec: (ns % 1_000_000_000) as u32,
        }
    }
}

#[derive(Debug, Clone, Copy, Serialize)]
pub struct Duration {
    pub sec: i64,
    pub nsec: u32,
}

/// Zero lifetime: "remain visible until replaced or deleted".
pub const FOREVER: Duration = Duration { sec: 0, nsec: 0 };

#[derive(Debug, Clone, Copy, Serialize)]
pub struct Vector3 {
    pub x: f64,
    pub y: f64,
    pub z: f64,
}

impl From<V3<f64>> for Vector3 {
    fn from(v: V3<f64>) -> Self {
        Self {
            x: v.x,
            y: v.y,
            z: v.z,
        }
    }
}

#[derive(Debug, Clone, Copy, Serialize)]
pub struct Quaternion {
    pub x: f64,
    pub y: f64,
    pub z: f64,
    pub w: f64,
}

impl From<UnitQuaternion<f64>> for Quaternion {
    fn from(q: UnitQuaternion<f64>) -> Self {
        Self {
            x: q.i,
            y: q.j,
            z: q.k,
            w: q.w,
        }
    }
}

#[derive(Debug, Clone, Copy, Serialize)]
pub struct Pose {
    pub position: Vector3,
    pub orientation: Quaternion,
}

impl Pose {
    pub fn at(p: V3<f64>) -> Self {
        Self {
            position: p.into(),
            orientation: UnitQuaternion::identity().into(),
        }
    }
}

#[derive(Debug, Clone, Copy, Serialize, PartialEq)]
pub struct Color {
    pub r: f64,
    pub g: f64,
    pub b: f64,
    pub a: f64,
}

pub const fn rgba(r: f64, g: f64, b: f64, a: f64) -> Color {
    Color { r, g, b, a }
}

#[derive(Debug, Clone, Serialize)]
pub struct KeyValuePair {
    pub key: String,
    pub value: String,
}

pub fn kv(key: &str, value: impl ToString) -> KeyValuePair {
    KeyValuePair {
        key: key.into(),
        value: value.to_string(),
    }
}

#[derive(Debug, Clone, Copy, Serialize)]
pub struct CubePrimitive {
    pub pose: Pose,
    pub size: Vector3,
    pub color: Color,
}

#[derive(Debug, Clone, Copy, Serialize)]
pub struct SpherePrimitive {
    pub pose: Pose,
    pub size: Vector3,
    pub color: Color,
}

impl SpherePrimitive {
    /// A round marker of diameter `d`.
    pub fn ball(p: V3<f64>, d: f64, color: Color) -> Self {
        Self {
            pose: Pose::at(p),
            size: V3::repeat(d).into(),
            color,
        }
    }

    /// A covariance ellipsoid centred on `p`.
    pub fn ellipsoid(p: V3<f64>, e: &Ellipsoid, color: Color) -> Self {
        Self {
            pose: Pose {
                position: p.into(),
                orientation: e.orientation.into(),
            },
            size: V3::from(e.size).into(),
            color,
        }
    }
}

/// `foxglove.LineType` LINE_STRIP.
pub const LINE_STRIP: u8 = 0;

#[derive(Debug, Clone, Serialize)]
pub struct LinePrimitive {
    #[serde(rename = "type")]
    pub kind: u8,
    pub pose: Pose,
    pub thickness: f64,
    pub scale_invariant: bool,
    pub points: Vec<Vector3>,
    pub color: Color,
    pub colors: Vec<Color>,
    pub indices: Vec<u32>,
}

impl LinePrimitive {
    /// A line strip `thickness` pixels wide whatever the zoom.
    pub fn strip(points: Vec<Vector3>, thickness: f64, color: Color) -> Self {
        Self {
            kind: LINE_STRIP,
            pose: Pose::at(V3::zeros()),
            thickness,
            scale_invariant: true,
            points,
            color,
            colors: Vec::new(),
            indices: Vec::new(),
        }
    }
}

#[derive(Debug, Clone, Serialize)]
pub struct TextPrimitive {
    pub pose: Pose,
    pub billboard: bool,
    pub font_size: f64,
    pub scale_invariant: bool,
    pub color: Color,
    pub text: String,
}

impl TextPrimitive {
    /// A label that faces the camera, `px` pixels high.
    pub fn label(p: V3<f64>, px: f64, color: Color, text: String) -> Self {
        Self {
            pose: Pose::at(p),
            billboard: true,
            font_size: px,
            scale_invariant: true,
            color,
            text,
        }
    }
}

/// A list we never fill (arrows, cylinders, triangles, models, deletions):
/// serialises as `[]`, which the schema requires to be present.
#[derive(Debug, Clone, Copy, Default)]
pub struct Unused;

impl Serialize for Unused {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeSeq;
        s.serialize_seq(Some(0))?.end()
    }
}

#[derive(Debug, Clone, Serialize)]
pub struct SceneEntity {
    pub timestamp: Time,
    pub frame_id: &'static str,
    pub id: String,
    pub lifetime: Duration,
    pub frame_locked: bool,
    pub metadata: Vec<KeyValuePair>,
    pub arrows: Unused,
    pub cubes: Vec<CubePrimitive>,
    pub spheres: Vec<SpherePrimitive>,
    pub cylinders: Unused,
    pub lines: Vec<LinePrimitive>,
    pub triangles: Unused,
    pub texts: Vec<TextPrimitive>,
    pub models: Unused,
}

impl SceneEntity {
    /// An empty entity in [`FRAME`] that stays until replaced.
    pub fn new(timestamp: Time, id: impl Into<String>) -> Self {
        Self {
            timestamp,
            frame_id: FRAME,
            id: id.into(),
            lifetime: FOREVER,
            frame_locked: false,
            metadata: Vec::new(),
            arrows: Unused,
            cubes: Vec::new(),
            spheres: Vec::new(),
            cylinders: Unused,
            lines: Vec::new(),
            triangles: Unused,
            texts: Vec::new(),
            models: Unused,
        }
    }
}

/// Entities are only ever replaced (same id), never deleted: `deletions`
/// is always the empty list.
#[derive(Debug, Clone, Serialize)]
pub struct SceneUpdate {
    pub deletions: Unused,
    pub entities: Vec<SceneEntity>,
}

impl SceneUpdate {
    pub fn of(entities: Vec<SceneEntity>) -> Self {
        Self {
            deletions: Unused,
            entities,
        }
    }
}

/// `foxglove.LogLevel` values.
pub const INFO: u8 = 2;
pub const WARNING: u8 = 3;
pub const ERROR: u8 = 4;

#[derive(Debug, Clone, Serialize)]
pub struct Log {
    pub timestamp: Time,
    pub level: u8,
    pub message: String,
    /// Shown as the source in Foxglove's Log panel: the sensor's name, or
    /// `agent` for outcomes.
    pub name: String,
    pub file: &'static str,
    pub line: u32,
}
