//! The truth a frame is scored against: the exact minimum distance between the robot's
//! collision meshes and the frame's obstacle points (m, pruned by each element's bounding box),
//! with the two points it is taken between (the separation monitor's truth, the approach speed
//! at the robot's point, is `Renderer::approach`, which moves that point along the trajectory).
//! Where the scene hides its obstacle (dark, or in the arm's shadow), also the exact distance
//! between the meshes and the obstacle's whole shape: parry3d's closest points of each mesh
//! (a BVH of its triangles) and the shape placed in the link's frame, f32, one query per
//! collision element.

use nalgebra::{Isometry3, Point3};
use parry3d::math::{Pose, Rotation, Vector};
use parry3d::query::{closest_points, ClosestPoints};
use parry3d::shape::{Shape, TriMesh};
use rayon::prelude::*;

use crate::packing::Solid;
use crate::robot::RobotModel;

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

/// The robot's collision meshes as parry3d triangle meshes, by link index (the kinematics'
/// order), for the distance to a hidden shape. `None` where parry3d refuses a mesh (the intake
/// has checked them, so it does not).
pub(super) fn robot_meshes(
    model: &RobotModel,
    solids: &[(usize, Vec<Solid>)],
) -> Option<Vec<(usize, Vec<TriMesh>)>> {
    model
        .links
        .iter()
        .zip(solids)
        .map(|(l, (index, _))| {
            let meshes = l.elements.iter().map(|e| {
                let vertices = (e.mesh.vertices.iter())
                    .map(|v| Vector::new(v[0], v[1], v[2]))
                    .collect();
                TriMesh::new(vertices, e.mesh.triangles.clone()).ok()
            });
            Some((*index, meshes.collect::<Option<Vec<_>>>()?))
        })
        .collect()
}

/// The exact distance between the robot's meshes and `shape` at `root_from_shape`, and where
/// (`None`: a pair parry3d cannot query). Overlapping shapes give 0 at the shape's centre.
pub(super) fn shape_truth(
    shape: &dyn Shape,
    root_from_shape: &Isometry3<f64>,
    meshes: &[(usize, Vec<TriMesh>)],
    poses: &[Isometry3<f64>],
) -> Option<(f64, Witness)> {
    let mut best: Option<(f64, Witness)> = None;
    for (link, elements) in meshes {
        let link_from_shape = poses[*link].inverse() * root_from_shape;
        let (t, q) = (
            link_from_shape.translation.vector,
            link_from_shape.rotation.coords,
        );
        let pose = Pose::from_parts(
            Vector::new(t.x as f32, t.y as f32, t.z as f32),
            Rotation::from_xyzw(q.x as f32, q.y as f32, q.z as f32, q.w as f32),
        );
        for mesh in elements {
            let margin = best.map_or(f32::MAX, |b| b.0 as f32);
            let (d, on_robot, on_shape) =
                match closest_points(&Pose::IDENTITY, mesh, &pose, shape, margin).ok()? {
                    ClosestPoints::Disjoint => continue,
                    ClosestPoints::Intersecting => (0.0, t.into(), t.into()),
                    ClosestPoints::WithinMargin(a, b) => {
                        let p = |v: Vector| Point3::new(v.x as f64, v.y as f64, v.z as f64);
                        (f64::from(a.distance(b)), p(a), p(b))
                    }
                };
            if best.is_none_or(|b| d < b.0) {
                let witness = Witness {
                    link: *link,
                    robot_in_link: on_robot,
                    obstacle_root: poses[*link] * on_shape,
                };
                best = Some((d, witness));
            }
        }
    }
    best
}
