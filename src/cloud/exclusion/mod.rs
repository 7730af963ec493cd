//! Exclusion volumes: known parts of the cell (a table, a fixture, a conveyor) whose points are
//! dropped before the query, so that they neither stop the cell nor hide anything else.
//!
//! A volume is a primitive (`geometry::Primitive`: box, sphere, cylinder) or a mesh file's
//! solid dilated by a padding (`mesh`: a grid of signed distances) fixed in a TF frame
//! — the world, a fixture's frame, or a link of the robot — and applies to every source or to
//! those it names. Per cloud, the monitor places each volume in the cloud's sensor frame
//! (`sensor_from_volume`, looked up at the cloud's stamp as the sensor itself is) and
//! [`exclude`] makes every point inside one invalid (NaN), counting the points of each volume.
//! A point inside two volumes counts for the first in the list.
//!
//! The cost is kept off the points that cannot be inside: the cloud is cut into blocks of
//! [`BLOCK`] consecutive points (neighbours in an organized cloud), each block's bounding box
//! is tested against the box of every volume's sensor-frame box, then against each volume's
//! sensor-frame box, then against the volume's own box (the block's box turned into the
//! volume's frame: centre `R c + t`, half extents `|R| h`), and only the points of a block that
//! passes are tested one by one, in f32 in the volume's frame. Blocks run in parallel.
//!
//! What this costs in safety is what it says: a person inside an exclusion volume is not seen.
//! Volumes are shown in RViz (`outputs`) and their counts are in the diagnostics.

use std::sync::Arc;

use nalgebra::Isometry3;
use rayon::prelude::*;

use crate::geometry::Primitive;

pub mod mesh;
pub use mesh::MeshGrid;

/// Points per block of the overlap test.
pub const BLOCK: usize = 32;
/// Points per parallel task.
const TASK: usize = 8192;

/// What an exclusion volume is: a primitive, or a mesh's dilated solid.
#[derive(Debug, Clone, PartialEq)]
pub enum VolumeShape {
    Primitive(Primitive),
    Mesh(Arc<MeshGrid>),
}

impl VolumeShape {
    /// The shape as configured (a mesh by its file and scale).
    pub fn shape(&self) -> crate::geometry::Shape {
        match self {
            VolumeShape::Primitive(p) => (*p).into(),
            VolumeShape::Mesh(g) => crate::geometry::Shape::Mesh {
                file: g.file.clone(),
                scale: g.scale,
            },
        }
    }
}

impl PartialEq for MeshGrid {
    /// The same file, scale and padding: the same volume.
    fn eq(&self, other: &Self) -> bool {
        (&self.file, self.scale, self.padding_m) == (&other.file, other.scale, other.padding_m)
    }
}

/// An exclusion volume as configured.
#[derive(Debug, Clone, PartialEq)]
pub struct ExclusionVolume {
    pub name: String,
    pub shape: VolumeShape,
    /// The TF frame (or robot link) it is fixed in.
    pub frame: String,
    pub frame_from_volume: Isometry3<f64>,
    /// The sources it applies to (every source when empty).
    pub sources: Vec<String>,
}

impl ExclusionVolume {
    /// Whether it applies to source `name`.
    pub fn applies_to(&self, source: &str) -> bool {
        self.sources.is_empty() || self.sources.iter().any(|s| s == source)
    }
}

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
    lo: [f32; 3],
    hi: [f32; 3],
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
    fn may_touch(&self, lo: [f32; 3], hi: [f32; 3]) -> bool {
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

/// Makes every point inside one of `volumes` invalid (NaN); returns how many each took (a
/// point inside two counts for the first).
pub fn exclude(points: &mut [[f32; 3]], volumes: &[Placed]) -> Vec<u64> {
    if volumes.is_empty() {
        return Vec::new();
    }
    // Every volume's sensor-frame box in one: most blocks miss it.
    let mut all = (volumes[0].lo, volumes[0].hi);
    for v in volumes {
        for a in 0..3 {
            all.0[a] = all.0[a].min(v.lo[a]);
            all.1[a] = all.1[a].max(v.hi[a]);
        }
    }
    points
        .par_chunks_mut(TASK)
        .map(|task| {
            let mut counts = vec![0u64; volumes.len()];
            for block in task.chunks_mut(BLOCK) {
                exclude_block(block, volumes, all, &mut counts);
            }
            counts
        })
        .reduce(
            || vec![0; volumes.len()],
            |a, b| a.iter().zip(&b).map(|(x, y)| x + y).collect(),
        )
}

fn exclude_block(
    block: &mut [[f32; 3]],
    volumes: &[Placed],
    all: ([f32; 3], [f32; 3]),
    counts: &mut [u64],
) {
    // A comparison with NaN is false, so invalid coordinates drop out without a branch (one
    // `minss`/`maxss` each).
    let (mut lo, mut hi) = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);
    for p in block.iter() {
        for a in 0..3 {
            lo[a] = if p[a] < lo[a] { p[a] } else { lo[a] };
            hi[a] = if p[a] > hi[a] { p[a] } else { hi[a] };
        }
    }
    if lo.iter().zip(&hi).any(|(l, h)| l > h) {
        // No point with every coordinate a number: none can be inside.
        return;
    }
    // A box with an infinite side cannot be placed; its points are all tested.
    let bounded = lo.iter().chain(&hi).all(|x| x.is_finite());
    if bounded && (0..3).any(|a| lo[a] > all.1[a] || hi[a] < all.0[a]) {
        return;
    }
    for (v, volume) in volumes.iter().enumerate() {
        if bounded && !volume.may_touch(lo, hi) {
            continue;
        }
        for p in block.iter_mut() {
            if volume.contains(*p) {
                *p = [f32::NAN; 3];
                counts[v] += 1;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Translation3, UnitQuaternion};
    use proptest::prelude::*;

    fn shape() -> impl Strategy<Value = Primitive> {
        prop_oneof![
            prop::array::uniform3(0.05f64..1.0).prop_map(|size| Primitive::Box { size }),
            (0.05f64..0.6).prop_map(|radius| Primitive::Sphere { radius }),
            (0.05f64..0.6, 0.05f64..1.0)
                .prop_map(|(radius, length)| Primitive::Cylinder { radius, length }),
        ]
    }

    fn pose() -> impl Strategy<Value = Isometry3<f64>> {
        (
            prop::array::uniform3(-1.0f64..1.0),
            prop::array::uniform3(-3.2f64..3.2),
        )
            .prop_map(|(t, e)| {
                Isometry3::from_parts(
                    Translation3::new(t[0], t[1], t[2]),
                    UnitQuaternion::from_euler_angles(e[0], e[1], e[2]),
                )
            })
    }

    proptest! {
        /// The blocked, f32 filter takes exactly the points the f64 definition puts inside
        /// (away from the surface by more than f32 rounding), and counts them.
        #[test]
        fn exclusion_takes_exactly_the_points_inside(
            shapes in prop::collection::vec((shape(), pose()), 1..4),
            points in prop::collection::vec(prop::array::uniform3(-1.5f32..1.5), 1..3000),
            holes in prop::collection::vec(any::<bool>(), 3000),
            sorted in any::<bool>(),
        ) {
            let mut points = points;
            if sorted {
                // Neighbours in the cloud close in space, as in an organized cloud: blocks are
                // thin slabs, and most miss most volumes (the culling is exercised).
                points.sort_by(|a, b| a[0].total_cmp(&b[0]));
            }
            let mut cloud: Vec<[f32; 3]> = points.iter().zip(&holes)
                .map(|(p, h)| if *h && p[0] > 1.0 { [f32::NAN; 3] } else { *p })
                .collect();
            let before = cloud.clone();
            let placed: Vec<Placed> = shapes
                .iter()
                .map(|(s, p)| Placed::new(&VolumeShape::Primitive(*s), p))
                .collect();
            let counts = exclude(&mut cloud, &placed);
            let mut expected = vec![0u64; shapes.len()];
            for (p, after) in before.iter().zip(&cloud) {
                if p[0].is_nan() {
                    prop_assert!(after[0].is_nan());
                    continue;
                }
                let q = p.map(f64::from);
                let inside = |(s, pose): &(Primitive, Isometry3<f64>)| {
                    let l = pose.inverse_transform_point(&q.into());
                    s.contains([l.x, l.y, l.z])
                };
                // Points within 1e-5 m of a surface may go either way in f32.
                let near_surface = shapes.iter().any(|(s, pose)| {
                    let l = pose.inverse_transform_point(&q.into());
                    let l = [l.x, l.y, l.z];
                    let grow = |e: f64| match *s {
                        Primitive::Box { size } => Primitive::Box { size: size.map(|x| x + e) },
                        Primitive::Sphere { radius } => Primitive::Sphere { radius: radius + e / 2.0 },
                        Primitive::Cylinder { radius, length } =>
                            Primitive::Cylinder { radius: radius + e / 2.0, length: length + e },
                    };
                    grow(2e-5).contains(l) != grow(-2e-5).contains(l)
                });
                if near_surface {
                    continue;
                }
                match shapes.iter().position(inside) {
                    Some(v) => {
                        expected[v] += 1;
                        prop_assert!(after[0].is_nan(), "{p:?} inside volume {v} kept");
                    }
                    None => prop_assert_eq!(after, p, "a point outside every volume changed"),
                }
            }
            // Counts agree up to the points near a surface, which were skipped above.
            let near: u64 = counts.iter().sum::<u64>() - expected.iter().sum::<u64>();
            for (c, e) in counts.iter().zip(&expected) {
                prop_assert!(c >= e && c - e <= near);
            }
        }
    }
}
