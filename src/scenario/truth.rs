//! The truth a frame is scored against: the exact minimum distance between the robot's
//! collision meshes and the frame's obstacle points (m, pruned by each element's bounding box),
//! with the two points it is taken between (the separation monitor's truth, the approach speed
//! at the robot's point, is `Renderer::approach`, which moves that point along the trajectory).

use nalgebra::{Isometry3, Point3};
use rayon::prelude::*;

use crate::packing::Solid;

/// The two points of a frame's exact minimum.
#[derive(Debug, Clone, Copy)]
pub struct Witness {
    /// Index of the robot link (the kinematics' order).
    pub link: usize,
    /// The closest point of its mesh, in the link's frame.
    pub robot_in_link: Point3<f64>,
    /// The obstacle point, in the root frame.
    pub obstacle_root: Point3<f64>,
}

/// The exact distance from every obstacle point (root frame) to the robot's meshes, and where
/// (`None`: no obstacle point).
pub(super) fn exact_truth(
    obstacle: &[Point3<f64>],
    solids: &[(usize, Vec<Solid>)],
    poses: &[Isometry3<f64>],
) -> (Option<f64>, Option<Witness>) {
    let none = (f64::INFINITY, None);
    let (best, witness) = obstacle
        .par_iter()
        .map(|p| {
            let mut best = none;
            for (link, elements) in solids {
                let lp = poses[*link].inverse_transform_point(p);
                let lp = [lp.x as f32, lp.y as f32, lp.z as f32];
                for e in elements {
                    let (lo, hi) = e.bounds();
                    let gap: f32 = (0..3)
                        .map(|a| (lo[a] - lp[a]).max(lp[a] - hi[a]).max(0.0).powi(2))
                        .sum::<f32>()
                        .sqrt();
                    if f64::from(gap) < best.0 {
                        let (d, q) = e.distance(lp);
                        if f64::from(d) < best.0 {
                            let q = Point3::new(q[0] as f64, q[1] as f64, q[2] as f64);
                            best = (
                                f64::from(d),
                                Some(Witness {
                                    link: *link,
                                    robot_in_link: q,
                                    obstacle_root: *p,
                                }),
                            );
                        }
                    }
                }
            }
            best
        })
        .reduce(|| none, |a, b| if b.0 < a.0 { b } else { a });
    (best.is_finite().then_some(best), witness)
}
