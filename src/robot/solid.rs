//! A collision solid for point queries: distances to a closed mesh's surface and inside or
//! outside, in f32 through parry3d's BVH (the one boundary to parry3d's glam types). A closed
//! mesh's inside comes from its orientation (pseudo-normals); a filled solid's (`fill`) from its
//! flood fill, with distances to the triangles that face the outside. Used by the intake (to
//! check shells and find the nested ones), the packing, the exact query and the generator.

use std::sync::Arc;

use parry3d::math::{Pose, Vector};
use parry3d::query::{intersection_test, PointQuery, Ray, RayCast};
use parry3d::shape::{TriMesh, TriMeshFlags, Triangle};

use super::fill::Fill;
use super::mesh::{ClosedMesh, MeshError};

#[inline]
fn distance(a: [f32; 3], b: [f32; 3]) -> f32 {
    Vector::new(a[0], a[1], a[2]).distance(Vector::new(b[0], b[1], b[2]))
}

/// A closed mesh as a solid for point queries (the one boundary to parry3d's glam types). For
/// a filled solid (`robot::fill`) inside and outside come from the fill and distances from the
/// triangles that face the outside.
pub struct Solid {
    trimesh: TriMesh,
    fill: Option<Arc<Fill>>,
}

impl Solid {
    /// The solid of a mesh the intake made (`robot::intake` checked it with [`Solid::try_new`]).
    pub fn new(mesh: &ClosedMesh) -> Self {
        Self::try_new(mesh).unwrap_or_else(|e| panic!("{e}"))
    }

    /// The solid of `mesh`: parry3d's oriented mesh for a closed mesh, its plain mesh for the
    /// outward-facing triangles of a filled one; an error when parry3d refuses it.
    pub fn try_new(mesh: &ClosedMesh) -> Result<Self, MeshError> {
        let vertices = mesh
            .vertices
            .iter()
            .map(|v| Vector::new(v[0], v[1], v[2]))
            .collect();
        let trimesh = match mesh.fill {
            Some(_) => TriMesh::new(vertices, mesh.triangles.clone()),
            None => TriMesh::with_flags(vertices, mesh.triangles.clone(), TriMeshFlags::ORIENTED),
        }
        .map_err(|e| MeshError::Load(format!("a mesh parry3d refuses: {e:?}")))?;
        Ok(Self {
            trimesh,
            fill: mesh.fill.clone(),
        })
    }

    /// Whether the triangle `t` meets the surface (parry3d's intersection test; a test it
    /// cannot make counts as meeting).
    pub fn meets_triangle(&self, t: [[f32; 3]; 3]) -> bool {
        let [a, b, c] = t.map(|v| Vector::new(v[0], v[1], v[2]));
        let triangle = Triangle::new(a, b, c);
        !intersection_test(&Pose::IDENTITY, &self.trimesh, &Pose::IDENTITY, &triangle)
            .is_ok_and(|i| !i.intersecting)
    }

    /// Whether `p` is inside, given parry's answer for a closed mesh; for a filled solid, the
    /// fill's, with `ambiguous` where it cannot tell (a point among triangles closer together
    /// than its voxel).
    #[inline]
    fn inside(&self, p: [f32; 3], parry_inside: bool, ambiguous: bool) -> bool {
        match &self.fill {
            Some(fill) => fill.contains(p.map(f64::from), ambiguous),
            None => parry_inside,
        }
    }

    /// Signed distance to the surface (positive inside) and the closest surface point; a point
    /// a filled solid cannot place counts as outside (no sphere is grown from it).
    /// A point outside the mesh's bounding box is outside, whatever the pseudo-normal of its
    /// nearest feature says (a sliver's f32 normal can turn it), so no prototype climbs away
    /// from the link.
    #[inline]
    pub fn signed_distance(&self, p: [f32; 3]) -> (f32, [f32; 3]) {
        let projection = self
            .trimesh
            .project_local_point(Vector::new(p[0], p[1], p[2]), false);
        let q = [projection.point.x, projection.point.y, projection.point.z];
        let d = distance(p, q);
        let aabb = self.trimesh.local_aabb();
        let in_box = (0..3).all(|k| aabb.mins[k] <= p[k] && p[k] <= aabb.maxs[k]);
        (
            if in_box && self.inside(p, projection.is_inside, false) {
                d
            } else {
                -d
            },
            q,
        )
    }

    /// Axis-aligned bounds of the mesh.
    pub fn bounds(&self) -> ([f32; 3], [f32; 3]) {
        let aabb = self.trimesh.local_aabb();
        (
            [aabb.mins.x, aabb.mins.y, aabb.mins.z],
            [aabb.maxs.x, aabb.maxs.y, aabb.maxs.z],
        )
    }

    /// Distance to the solid (0 inside) and the closest point (the point itself inside); a
    /// point a filled solid cannot place counts as inside (distance 0, never too far).
    #[inline]
    pub fn distance(&self, p: [f32; 3]) -> (f32, [f32; 3]) {
        let projection = self
            .trimesh
            .project_local_point(Vector::new(p[0], p[1], p[2]), false);
        if self.inside(p, projection.is_inside, true) {
            return (0.0, p);
        }
        let q = [projection.point.x, projection.point.y, projection.point.z];
        (distance(p, q), q)
    }

    /// Distance along the ray `origin + t·dir` (unit `dir`) to the first surface hit within
    /// `max`, or 0 from inside.
    pub fn cast_ray(&self, origin: [f32; 3], dir: [f32; 3], max: f32) -> Option<f32> {
        let ray = Ray::new(
            Vector::new(origin[0], origin[1], origin[2]),
            Vector::new(dir[0], dir[1], dir[2]),
        );
        self.trimesh.cast_local_ray(&ray, max, true)
    }

    /// How far the surface lies from the surface point `p` along the unit `inward` direction
    /// (the solid's thickness there, where `inward` is the inward normal), at most `max`: the
    /// first triangle the ray meets past a tiny offset from `p`'s own.
    pub fn thickness(&self, p: [f32; 3], inward: [f32; 3], max: f32) -> f32 {
        let offset = 1e-6 * max.max(f32::MIN_POSITIVE);
        let ray = Ray::new(
            Vector::new(
                p[0] + inward[0] * offset,
                p[1] + inward[1] * offset,
                p[2] + inward[2] * offset,
            ),
            Vector::new(inward[0], inward[1], inward[2]),
        );
        self.trimesh
            .cast_local_ray(&ray, max, false)
            .map_or(max, |t| t + offset)
    }

    /// [`Self::distance`] when it is at most `max`, for a point known to be outside: the BVH
    /// descent stops at `max`, so a point inside but deeper than `max` would read as `None`.
    #[inline]
    pub fn distance_within(&self, p: [f32; 3], max: f32) -> Option<(f32, [f32; 3])> {
        let projection = self.trimesh.project_local_point_with_max_dist(
            Vector::new(p[0], p[1], p[2]),
            false,
            max,
        )?;
        if self.inside(p, projection.is_inside, true) {
            return Some((0.0, p));
        }
        let q = [projection.point.x, projection.point.y, projection.point.z];
        Some((distance(p, q), q))
    }
}
