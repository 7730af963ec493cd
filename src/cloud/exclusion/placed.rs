//! A volume placed in a cloud's sensor frame for one cloud: `volume_from_sensor` in f32, the
//! volume's box and its sensor-frame bounding box, and the tests the point loop runs (a point
//! inside, a block's box that may reach it).

use std::sync::Arc;

use nalgebra::Isometry3;

use super::mesh::MeshGrid;
use super::volume::VolumeShape;
use crate::geometry::Primitive;

/// A volume placed in a cloud's sensor frame, in f32 for the point loop.
#[derive(Debug, Clone)]
pub struct Placed {
    /// `volume_from_sensor`, then less the centre of the volume's box: rows of the rotation,
    /// and the translation (a point comes out relative to the box's centre).
    rotation: [[f32; 3]; 3],
    translation: [f32; 3],
    /// Half extents of the volume's bounding box in its frame, and its centre there (zero for
    /// a primitive).
    half: [f32; 3],
    center: [f32; 3],
    /// The bounding box of that box in the sensor frame.
    pub(super) lo: [f32; 3],
    pub(super) hi: [f32; 3],
    shape: Shape,
}

#[derive(Debug, Clone)]
enum Shape {
    Box,
    Sphere { r2: f32 },
    Cylinder { r2: f32 },
    Mesh(Arc<MeshGrid>),
}

impl Placed {
    /// `shape` placed by `sensor_from_volume`.
    pub fn new(shape: &VolumeShape, sensor_from_volume: &Isometry3<f64>) -> Self {
        let volume_from_sensor = sensor_from_volume.inverse();
        let r = volume_from_sensor.rotation.to_rotation_matrix();
        let m = r.matrix();
        let (half, center) = match shape {
            VolumeShape::Primitive(p) => (p.half_extents(), [0.0; 3]),
            VolumeShape::Mesh(g) => {
                let (lo, hi) = g.bounds();
                (
                    std::array::from_fn(|k| 0.5 * (hi[k] - lo[k])),
                    std::array::from_fn(|k| 0.5 * (hi[k] + lo[k])),
                )
            }
        };
        let t = volume_from_sensor.translation.vector - nalgebra::Vector3::from(center);
        // The volume's box seen from the sensor: centre and half extents |R| h, a little wider
        // for rounding.
        let s = sensor_from_volume.rotation.to_rotation_matrix();
        let c = sensor_from_volume * nalgebra::Point3::from(center);
        let reach: [f64; 3] = std::array::from_fn(|i| {
            (0..3).map(|j| s[(i, j)].abs() * half[j]).sum::<f64>() * (1.0 + 1e-6) + 1e-6
        });
        Self {
            lo: std::array::from_fn(|i| (c[i] - reach[i]) as f32),
            hi: std::array::from_fn(|i| (c[i] + reach[i]) as f32),
            rotation: std::array::from_fn(|i| std::array::from_fn(|j| m[(i, j)] as f32)),
            translation: [t.x as f32, t.y as f32, t.z as f32],
            half: half.map(|h| h as f32),
            center: center.map(|x| x as f32),
            shape: match shape {
                VolumeShape::Primitive(Primitive::Box { .. }) => Shape::Box,
                VolumeShape::Primitive(Primitive::Sphere { radius }) => Shape::Sphere {
                    r2: (radius * radius) as f32,
                },
                VolumeShape::Primitive(Primitive::Cylinder { radius, .. }) => Shape::Cylinder {
                    r2: (radius * radius) as f32,
                },
                VolumeShape::Mesh(g) => Shape::Mesh(g.clone()),
            },
        }
    }

    #[inline]
    fn in_volume_frame(&self, p: [f32; 3]) -> [f32; 3] {
        let r = &self.rotation;
        std::array::from_fn(|i| {
            r[i][0] * p[0] + r[i][1] * p[1] + r[i][2] * p[2] + self.translation[i]
        })
    }

    /// Whether sensor-frame point `p` lies inside (NaN does not).
    #[inline]
    pub fn contains(&self, p: [f32; 3]) -> bool {
        let q = self.in_volume_frame(p);
        let in_box = |a: usize| q[a].abs() <= self.half[a];
        match self.shape {
            Shape::Box => in_box(0) && in_box(1) && in_box(2),
            Shape::Sphere { r2 } => q[0] * q[0] + q[1] * q[1] + q[2] * q[2] <= r2,
            Shape::Cylinder { r2 } => q[0] * q[0] + q[1] * q[1] <= r2 && in_box(2),
            Shape::Mesh(ref g) => g.contains(std::array::from_fn(|k| q[k] + self.center[k])),
        }
    }

    /// Whether the sensor-frame box `lo`..`hi` may reach the volume: it meets the volume's
    /// sensor-frame box, and the volume's own box.
    #[inline]
    pub(super) fn may_touch(&self, lo: [f32; 3], hi: [f32; 3]) -> bool {
        if (0..3).any(|a| lo[a] > self.hi[a] || hi[a] < self.lo[a]) {
            return false;
        }
        let c: [f32; 3] = std::array::from_fn(|a| 0.5 * (lo[a] + hi[a]));
        let h: [f32; 3] = std::array::from_fn(|a| 0.5 * (hi[a] - lo[a]));
        let q = self.in_volume_frame(c);
        let r = &self.rotation;
        (0..3).all(|i| {
            let reach = r[i][0].abs() * h[0] + r[i][1].abs() * h[1] + r[i][2].abs() * h[2];
            // A little slack for the rounding of the box's corners.
            q[i].abs() <= self.half[i] + reach + 1e-5 * (1.0 + q[i].abs())
        })
    }
}
