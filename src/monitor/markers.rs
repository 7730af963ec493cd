//! The markers of `~/closest_points`, as RViz draws them: each source's nearest point (a line
//! from the robot to it and its distance as text, coloured by the fused level), and the known
//! shapes — exclusion volumes (grey) and attached objects (blue) — each in its own frame.
//! Positions in m, in the frame each marker names; a marker lives 1 s unless renewed.

use nalgebra::Isometry3;

use super::level::Level;
use crate::config::Config;
use crate::geometry::{Primitive, Shape};
use crate::msg::{ColorRgba, Duration, Header, Marker, Point, Pose, Quaternion, Time, Vector3};
use crate::query::Nearest;

/// How long a marker stays unless the next frame renews it.
const LIFETIME: Duration = Duration { sec: 1, nanosec: 0 };

fn color(level: Level) -> ColorRgba {
    let (r, g, b) = match level {
        Level::Ok => (0.1, 0.8, 0.2),
        Level::Warn => (1.0, 0.7, 0.0),
        Level::Error => (0.9, 0.1, 0.1),
    };
    ColorRgba { r, g, b, a: 1.0 }
}

fn point(p: [f64; 3]) -> Point {
    Point {
        x: p[0],
        y: p[1],
        z: p[2],
    }
}

/// The markers of a source's nearest point: a line from the robot to it and the distance as
/// text, coloured by `level`, under the namespace `<source>/closest`.
pub fn closest_markers(
    header: &Header,
    source: &str,
    nearest: &Nearest,
    d: f64,
    level: Level,
) -> Vec<Marker<'static>> {
    let base = Marker {
        header: header.clone(),
        ns: format!("{source}/closest"),
        action: Marker::ADD,
        pose: Pose::default(),
        color: color(level),
        lifetime: LIFETIME,
        ..Marker::default()
    };
    let n = nearest;
    let mid = [0, 1, 2].map(|k| 0.5 * (n.point_root[k] + n.robot_point_root[k]));
    vec![
        Marker {
            id: 0,
            r#type: Marker::LINE_LIST,
            scale: Vector3 {
                x: 0.005,
                ..Vector3::default()
            },
            points: vec![point(n.robot_point_root), point(n.point_root)],
            ..base.clone()
        },
        Marker {
            id: 1,
            r#type: Marker::TEXT_VIEW_FACING,
            pose: Pose {
                position: point(mid),
                ..Pose::default()
            },
            scale: Vector3 {
                z: 0.04,
                ..Vector3::default()
            },
            text: format!("{} {d:.3} m", n.link),
            ..base
        },
    ]
}

/// A known shape to draw: an exclusion volume or an attached object.
struct Known<'a> {
    /// The marker namespace of its kind, and the kind's colour.
    ns: &'static str,
    color: ColorRgba,
    /// Its index in its list.
    id: usize,
    name: &'a str,
    /// The frame it is fixed in (a TF frame, or a robot link) and its pose there.
    frame: &'a str,
    pose: &'a Isometry3<f64>,
}

const VOLUME_COLOR: ColorRgba = ColorRgba {
    r: 0.5,
    g: 0.5,
    b: 0.5,
    a: 0.3,
};
const OBJECT_COLOR: ColorRgba = ColorRgba {
    r: 0.2,
    g: 0.4,
    b: 0.9,
    a: 0.6,
};

/// The exclusion volumes (grey) and attached objects (blue) as RViz shapes, each in its own
/// frame (a volume's TF frame, an object's link) at `stamp`.
pub fn shape_markers(config: &Config, stamp: Time) -> Vec<Marker<'static>> {
    let volumes = config.exclusion_volumes.iter().enumerate().map(|(id, v)| {
        let known = Known {
            ns: "exclusion_volumes",
            color: VOLUME_COLOR,
            id,
            name: &v.name,
            frame: &v.frame,
            pose: &v.frame_from_volume,
        };
        shape_marker(known, &v.shape.shape(), stamp)
    });
    let objects = config.attached_objects.iter().enumerate().map(|(id, o)| {
        let known = Known {
            ns: "attached_objects",
            color: OBJECT_COLOR,
            id,
            name: &o.name,
            frame: &o.link,
            pose: &o.link_from_object,
        };
        shape_marker(known, &o.shape, stamp)
    });
    volumes.chain(objects).collect()
}

/// One known shape's marker, locked to its frame.
fn shape_marker(known: Known, shape: &Shape, stamp: Time) -> Marker<'static> {
    let mut mesh_resource = String::new();
    let (r#type, scale) = match shape {
        Shape::Primitive(Primitive::Box { size }) => (Marker::CUBE, *size),
        Shape::Primitive(Primitive::Sphere { radius }) => (Marker::SPHERE, [2.0 * radius; 3]),
        Shape::Primitive(Primitive::Cylinder { radius, length }) => {
            (Marker::CYLINDER, [2.0 * radius, 2.0 * radius, *length])
        }
        // RViz loads the file itself (on the machine it runs on).
        Shape::Mesh { file, scale } => {
            let file = std::fs::canonicalize(file).unwrap_or_else(|_| file.clone());
            mesh_resource = format!("file://{}", file.display());
            (Marker::MESH_RESOURCE, *scale)
        }
    };
    let t = known.pose.translation.vector;
    Marker {
        header: Header {
            stamp,
            frame_id: known.frame.to_owned(),
        },
        ns: known.ns.to_owned(),
        id: known.id as i32,
        r#type,
        action: Marker::ADD,
        pose: Pose {
            position: point([t.x, t.y, t.z]),
            orientation: Quaternion::from_unit(&known.pose.rotation),
        },
        scale: Vector3 {
            x: scale[0],
            y: scale[1],
            z: scale[2],
        },
        color: known.color,
        lifetime: LIFETIME,
        frame_locked: true,
        mesh_resource,
        text: known.name.to_owned(),
        ..Marker::default()
    }
}
