//! Posing, step 1 of every query and the same for both backends: the links and the robot's box
//! are composed in f64 and rounded to f32 once, into the shared layout (`layout.rs`) that the
//! CPU walks and the GPU uploads.
//!
//! - Per link: `sensor_from_link = sensor_from_root · root_from_link`, its inverse as the rows
//!   of [`PosedLink`] (`link_from_sensor`), and the root sphere of the link's tree in the sensor
//!   frame. The robot is brought into the sensor frame, where the points are small numbers; the
//!   large offsets of a map frame cancel in f64 before anything is rounded.
//! - The robot's box: the links' root spheres in the root frame, widened by `BOX_MARGIN` so
//!   that the f32 rounding of a transformed point never drops it, with `root_from_sensor` in
//!   f32, the region of interest and the self-filter padding.
//! - The working frame ([`working_origin`]): a cloud whose own frame is far from the robot (a
//!   map- or UTM-frame lidar, coordinates of 1e4–1e7 m) would still meet the robot at large
//!   numbers in the sensor frame, where an f32 transform loses centimetres to cancellation.
//!   Such a query runs in the sensor frame translated to an f32 point `o` near the robot: each
//!   point becomes `p − o`, one f32 subtraction that is exact for every point near the robot
//!   (Sterbenz: `o/2 ≤ p ≤ 2o`) and within half an ulp of `|p − o|` elsewhere, and the robot is
//!   posed relative to `o` in f64. The interval then holds for the f32 points as given, at any
//!   offset; the spacing of those f32 points where the robot is (their quantization) is
//!   reported, and beyond [`MAX_POINT_SPACING_M`] the query refuses to certify anything.

use nalgebra::{Isometry3, Point3, Translation3};
use rayon::prelude::*;

use super::layout::{PosedLink, RobotBox};
use super::link::QueryLink;
use super::options::QueryOptions;

/// Widening of the robot box, m: far above the f32 rounding of a transformed point (~1e-6 m).
const BOX_MARGIN: f32 = 1e-4;

/// The robot's place in the sensor frame beyond which the query runs in a working frame near
/// the robot, m: below it the f32 spacing of the coordinates (≤ 1.9e-6 m) is far below the
/// tolerances of the bounds, and the query is exactly the sensor-frame one.
const FAR_FROM_SENSOR_M: f64 = 16.0;

/// The coarsest spacing of the cloud's f32 coordinates at the robot that the query certifies,
/// m: a point is then known to within √3/2 of it (8.7 mm). A cloud whose frame's origin lies
/// more than 131 km from the robot is refused (publish it in a frame near the robot).
pub const MAX_POINT_SPACING_M: f32 = 0.01;

/// Where the robot is in the sensor frame (the mean of its links' root spheres) and the f32
/// spacing of coordinates there: `(Some(o), spacing)` when the robot is farther than
/// `FAR_FROM_SENSOR_M` from the sensor frame's origin, `o` being that place rounded to f32.
pub(super) fn working_origin(
    links: &[QueryLink],
    root_from_sensor: &Isometry3<f64>,
    link_poses: &[Isometry3<f64>],
) -> (Option<[f32; 3]>, f32) {
    let mut sum = nalgebra::Vector3::zeros();
    for link in links {
        let c = link.nodes[0].center;
        sum += (link_poses[link.pose_index] * Point3::new(c[0] as f64, c[1] as f64, c[2] as f64))
            .coords;
    }
    let centre = root_from_sensor.inverse() * Point3::from(sum / links.len().max(1) as f64);
    let far = centre.coords.amax();
    let o = [centre.x as f32, centre.y as f32, centre.z as f32];
    // The spacing of f32 values at the largest coordinate of the robot's place.
    let largest = o.iter().fold(0.0f32, |m, v| m.max(v.abs()));
    let spacing = f32::from_bits(largest.to_bits() + 1) - largest;
    ((far > FAR_FROM_SENSOR_M).then_some(o), spacing)
}

/// `root_from_work` for the working frame at `o` in the sensor frame.
pub(super) fn root_from_work(root_from_sensor: &Isometry3<f64>, o: [f32; 3]) -> Isometry3<f64> {
    root_from_sensor * Translation3::new(o[0] as f64, o[1] as f64, o[2] as f64)
}

/// The points in the working frame at `o`, into `out`: `p − o` in f32, except that a point
/// (0, 0, 0), the drivers' "no return", stays invalid (it becomes NaN, not `−o`), and a point at
/// `o` itself stays valid (1e-38 m from it, not the invalid (0, 0, 0)).
pub(super) fn to_work(points: &[[f32; 3]], o: [f32; 3], out: &mut Vec<[f32; 3]>) {
    let shift = |p: &[f32; 3]| {
        if *p == [0.0; 3] {
            return [f32::NAN; 3];
        }
        let q = [p[0] - o[0], p[1] - o[1], p[2] - o[2]];
        if q == [0.0; 3] {
            [f32::MIN_POSITIVE, 0.0, 0.0]
        } else {
            q
        }
    };
    // Kept from query to query: written over, not cleared and zeroed first.
    out.resize(points.len(), [0.0; 3]);
    // In parallel, in place: one pass over the cloud, like the floor's.
    out.par_chunks_mut(WORK_CHUNK)
        .zip(points.par_chunks(WORK_CHUNK))
        .for_each(|(out, points)| {
            for (o, p) in out.iter_mut().zip(points) {
                *o = shift(p);
            }
        });
}

/// Points per task of [`to_work`].
const WORK_CHUNK: usize = 8192;

/// Rows `[R | t]` of a rigid transform, in f32.
fn rows(m: &Isometry3<f64>) -> [[f32; 4]; 3] {
    let h = m.to_homogeneous();
    std::array::from_fn(|r| std::array::from_fn(|k| h[(r, k)] as f32))
}

/// Poses `links` into `posed` (whose `node_base` and `sphere_base` are kept).
pub(super) fn pose_links(
    links: &[QueryLink],
    posed: &mut [PosedLink],
    root_from_sensor: &Isometry3<f64>,
    link_poses: &[Isometry3<f64>],
) {
    let sensor_from_root = root_from_sensor.inverse();
    for (link, out) in links.iter().zip(posed) {
        let sensor_from_link = sensor_from_root * link_poses[link.pose_index];
        let root = link.nodes[0];
        let c = sensor_from_link
            * Point3::new(
                root.center[0] as f64,
                root.center[1] as f64,
                root.center[2] as f64,
            );
        *out = PosedLink {
            rows: rows(&sensor_from_link.inverse()),
            center: [c.x as f32, c.y as f32, c.z as f32],
            radius: root.radius,
            gap: link.gap_m,
            ..*out
        };
    }
}

/// The robot's box for one query.
pub(super) fn robot_box(
    links: &[QueryLink],
    root_from_sensor: &Isometry3<f64>,
    link_poses: &[Isometry3<f64>],
    options: &QueryOptions,
) -> RobotBox {
    let mut lo = [f32::INFINITY; 3];
    let mut hi = [f32::NEG_INFINITY; 3];
    for link in links {
        let root = link.nodes[0];
        let c = link_poses[link.pose_index]
            * Point3::new(
                root.center[0] as f64,
                root.center[1] as f64,
                root.center[2] as f64,
            );
        for k in 0..3 {
            lo[k] = lo[k].min((c[k] - root.radius as f64) as f32 - BOX_MARGIN);
            hi[k] = hi[k].max((c[k] + root.radius as f64) as f32 + BOX_MARGIN);
        }
    }
    RobotBox {
        rows: rows(root_from_sensor),
        lo,
        max_distance: options.max_distance_m,
        hi,
        padding: options.self_filter_padding_m.unwrap_or(-1.0),
    }
}

/// `root_from_sensor` from two poses in a common (map) frame, composed in f64 so that large map
/// coordinates cancel before anything is rounded.
pub fn root_from_sensor_via_map(
    map_from_root: &Isometry3<f64>,
    map_from_sensor: &Isometry3<f64>,
) -> Isometry3<f64> {
    map_from_root.inverse() * map_from_sensor
}
