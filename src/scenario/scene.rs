//! The scenes of the generator: what each shows (a person walking up, a shelf reached over, the
//! approach and back, a work table, a forearm hidden in the arm's shadow), the arm's joint
//! trajectory along `s` ∈ [0, 1] and the shapes of the environment at `s` in the robot's root
//! frame (m), which the renderer casts its rays against and the truth of a hidden obstacle is
//! taken to; and the two backgrounds a bag may add, the floor (the plane z = 0 of the root, not
//! an obstacle) and the side wall behind the arm as the second camera sees it (an obstacle).

use nalgebra::{Isometry3, Point3, Vector3};
use parry3d::math::Vector;
use parry3d::query::Ray;
use parry3d::shape::{Capsule, Cuboid, Shape};

use crate::choice::Choice;

/// The scenes the generator knows, each described by its [`Choice::about`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SceneKind {
    Person,
    Shelf,
    Approach,
    Table,
    Shadow,
}

impl Choice for SceneKind {
    const ALL: &'static [Self] = &[
        SceneKind::Person,
        SceneKind::Shelf,
        SceneKind::Approach,
        SceneKind::Table,
        SceneKind::Shadow,
    ];
    fn name(self) -> &'static str {
        match self {
            SceneKind::Person => "person",
            SceneKind::Shelf => "shelf",
            SceneKind::Approach => "approach",
            SceneKind::Table => "table",
            SceneKind::Shadow => "shadow",
        }
    }

    /// What the scene shows (`generate --help` lists them).
    fn about(self) -> &'static str {
        match self {
            SceneKind::Person => {
                "A person-sized capsule walks up to the arm while it swings toward them"
            }
            SceneKind::Shelf => "The arm reaches over a box standing in front of it",
            SceneKind::Approach => {
                "The person walks up to the arm while it swings toward them, and both go back: \
                 the approach and the recovery of the speed and separation monitor"
            }
            SceneKind::Table => {
                "The person scene with a 0.5 m work table beside the arm, which the gripper \
                 passes above: a fixture for exclusion volumes"
            }
            SceneKind::Shadow => {
                "A person's forearm (a capsule of radius 0.04 m) reaches in along the camera's \
                 line of sight behind the arm's upper link, hidden in the arm's shadow as the \
                 camera sees it, up to 3 cm from it: the robot's own shadow (the truth is the \
                 distance to the whole forearm)"
            }
        }
    }
}

/// Where the camera's ray through the upper arm of [`SceneKind::Shadow`] starts (the camera's
/// optical centre, from the URDF's `camera_joint`) and the point of the upper arm's axis it
/// passes through, in the root frame (m): the hidden forearm lies along it.
const SHADOW_EYE: [f64; 3] = [1.2, 0.0, 0.8];
const SHADOW_THROUGH: [f64; 3] = [0.0, 0.0, 0.45];
/// The hidden forearm: radius and length of its axis (m), and how far behind the upper arm's
/// axis, along the ray, its near end starts and ends (m; the truth then falls from about
/// 0.8 m to about 0.03 m: the axes' horizontal offset less both radii).
const FOREARM_RADIUS: f64 = 0.04;
const FOREARM_LENGTH: f64 = 0.35;
const FOREARM_BEHIND: (f64, f64) = (0.93, 0.125);

/// The table of [`SceneKind::Table`]: its centre in the root frame and its edge lengths, m.
pub const TABLE_CENTER: [f64; 3] = [0.35, 0.45, 0.275];
pub const TABLE_SIZE: [f64; 3] = [0.5, 0.5, 0.55];

/// The floor (`ScenarioParams::floor`): a box of these edge lengths (m) whose top face is the
/// plane z = 0 of the robot's root, centred under the root.
pub const FLOOR_SIZE: [f64; 3] = [8.0, 8.0, 0.1];
/// The side wall behind the arm as the second camera sees it (`ScenarioParams::second_camera`):
/// its centre in the root frame and its edge lengths, m (x from −1.4 to 1.4, y from 1.55 to
/// 1.65, z from 0 to 2.4). More than 1.4 m from the arm, so the truth near the arm is the same
/// with it or without it.
pub const SIDE_WALL_CENTER: [f64; 3] = [0.0, 1.6, 1.2];
pub const SIDE_WALL_SIZE: [f64; 3] = [2.8, 0.1, 2.4];

impl SceneKind {
    /// Where along the walk-up the scene is at `s` ∈ [0, 1]: the approach scene goes out and
    /// back.
    fn progress(self, s: f64) -> f64 {
        match self {
            SceneKind::Approach => 1.0 - (2.0 * s - 1.0).abs(),
            _ => s,
        }
    }
}

/// The joint trajectory of a scene at `s` ∈ [0, 1] (eased), as `name = value` pairs.
pub(super) fn joints_at(scene: SceneKind, s: f64) -> Vec<(String, f64)> {
    let ease = 0.5 - 0.5 * (std::f64::consts::PI * scene.progress(s)).cos();
    let (from, to): ([f64; 7], [f64; 7]) = match scene {
        // pan, lift, elbow, wrist_1, wrist_2, wrist_3, finger
        SceneKind::Person | SceneKind::Approach | SceneKind::Table => (
            [0.9, 0.2, 1.1, 0.6, 0.0, 0.0, 0.015],
            [-0.95, 0.55, 0.95, 0.5, 0.8, 0.3, 0.005],
        ),
        SceneKind::Shelf => (
            [0.3, -0.2, 1.6, 0.9, 0.0, 0.0, 0.02],
            [0.05, 0.56, 0.92, 0.95, 0.4, 0.0, 0.01],
        ),
        // The upper arm stands still and upright (its shadow does not move); the forearm
        // and the wrist swing above and towards the camera, out of the shadow.
        SceneKind::Shadow => (
            [0.0, 0.0, 1.2, 0.3, 0.0, 0.0, 0.015],
            [0.0, 0.0, 0.9, 0.5, 0.6, 0.3, 0.005],
        ),
    };
    let names = [
        "shoulder_pan",
        "shoulder_lift",
        "elbow",
        "wrist_1",
        "wrist_2",
        "wrist_3",
        "finger_left_joint",
    ];
    names
        .iter()
        .zip(from.iter().zip(&to))
        .map(|(n, (a, b))| (n.to_string(), a + ease * (b - a)))
        .collect()
}

/// The environment of a scene: shapes with their world poses at `s` ∈ [0, 1], with the side
/// wall last where `side_wall` (a bag with a second camera). The obstacle is index 1 (the
/// renderer's `Hit::Scene(1)`), the table index 2.
/// The top of the person's shape (the scenes with one), m: its hair begins below it.
pub(super) fn person_top_m(scene: SceneKind) -> Option<f64> {
    matches!(
        scene,
        SceneKind::Person | SceneKind::Approach | SceneKind::Table
    )
    .then_some(0.85 + 0.67 + 0.18)
}

pub(super) fn obstacles(
    scene_kind: SceneKind,
    s: f64,
    side_wall: bool,
) -> Vec<(Box<dyn Shape>, Isometry3<f64>)> {
    // A wall 1.4 m behind the robot, seen past it.
    let wall: Box<dyn Shape> = Box::new(Cuboid::new(Vector::new(0.05, 2.0, 1.2)));
    let wall_pose = Isometry3::translation(-1.4, 0.0, 1.2);
    let obstacle: (Box<dyn Shape>, Isometry3<f64>) = match scene_kind {
        SceneKind::Person | SceneKind::Approach | SceneKind::Table => {
            // Radius 0.18 m, 1.7 m tall, walking from 1.1 m to 0.58 m beside the base (the
            // approach scene: from 1.2 m, and back).
            let (walk, from) = match scene_kind {
                SceneKind::Approach => (scene_kind.progress(s), -1.2),
                _ => ((s * 1.2).min(1.0), -1.1),
            };
            let y = from + walk * (-from - 0.58);
            (
                Box::new(Capsule::new_z(0.67, 0.18)),
                Isometry3::translation(0.1, y, 0.85),
            )
        }
        SceneKind::Shelf => (
            Box::new(Cuboid::new(Vector::new(0.15, 0.25, 0.2))),
            Isometry3::translation(0.62, 0.05, 0.2),
        ),
        SceneKind::Shadow => hidden_forearm(s),
    };
    let mut scene = vec![(wall, wall_pose), obstacle];
    if scene_kind == SceneKind::Table {
        scene.push(centred_box(TABLE_CENTER, TABLE_SIZE));
    }
    if side_wall {
        scene.push(centred_box(SIDE_WALL_CENTER, SIDE_WALL_SIZE));
    }
    scene
}

/// The floor (`ScenarioParams::floor`): [`FLOOR_SIZE`], its top face the plane z = 0.
pub(super) fn floor() -> (Box<dyn Shape>, Isometry3<f64>) {
    centred_box([0.0, 0.0, -0.5 * FLOOR_SIZE[2]], FLOOR_SIZE)
}

/// A box of edge lengths `size` centred at `center` (root frame, m), axis-aligned.
fn centred_box(center: [f64; 3], size: [f64; 3]) -> (Box<dyn Shape>, Isometry3<f64>) {
    let [x, y, z] = size.map(|e| (0.5 * e) as f32);
    let [cx, cy, cz] = center;
    (
        Box::new(Cuboid::new(Vector::new(x, y, z))),
        Isometry3::translation(cx, cy, cz),
    )
}

/// The forearm of [`SceneKind::Shadow`] at `s`: a capsule along the camera's ray through the
/// upper arm, its near end reaching in from [`FOREARM_BEHIND`]`.0` to `.1` behind the upper
/// arm's axis (linear, there by `s` = 5/6 as the person scene's walk). Its radius is less than
/// the upper arm's (0.05 m) and it lies farther from the camera, so it stays inside the cone of
/// rays the upper arm stops.
fn hidden_forearm(s: f64) -> (Box<dyn Shape>, Isometry3<f64>) {
    let (eye, through) = (Vector3::from(SHADOW_EYE), Vector3::from(SHADOW_THROUGH));
    let d = (through - eye).normalize();
    let (from, to) = FOREARM_BEHIND;
    let behind = from + (s * 1.2).min(1.0) * (to - from);
    // Along the ray, past the upper arm's axis by `behind`, then half the axis farther.
    let centre = through + d * (behind + 0.5 * FOREARM_LENGTH);
    let axis = nalgebra::UnitQuaternion::rotation_between(&Vector3::z(), &d)
        .unwrap_or_else(nalgebra::UnitQuaternion::identity);
    (
        Box::new(Capsule::new_z(
            (0.5 * FOREARM_LENGTH) as f32,
            FOREARM_RADIUS as f32,
        )),
        Isometry3::from_parts(centre.into(), axis),
    )
}

/// Where the ray from `o` along `d` first meets `shape` at `pose`, within `max` (m).
pub(super) fn ray_hit(
    shape: &dyn Shape,
    pose: &Isometry3<f64>,
    o: &Point3<f64>,
    d: &Vector3<f64>,
    max: f64,
) -> Option<f64> {
    let lo = pose.inverse_transform_point(o);
    let ld = pose.inverse_transform_vector(d);
    let ray = Ray::new(
        Vector::new(lo.x as f32, lo.y as f32, lo.z as f32),
        Vector::new(ld.x as f32, ld.y as f32, ld.z as f32),
    );
    shape.cast_local_ray(&ray, max as f32, true).map(f64::from)
}
