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

use nalgebra::{Isometry3, Point3};

use super::layout::{PosedLink, RobotBox};
use super::{QueryLink, QueryOptions};

/// Widening of the robot box, m: far above the f32 rounding of a transformed point (~1e-6 m).
const BOX_MARGIN: f32 = 1e-4;

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
