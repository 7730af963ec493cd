//! The point loop: every point inside a placed volume made invalid (NaN) and counted for the
//! first volume it lies in, blocks of [`BLOCK`] consecutive points culled by their bounding box
//! before any point is tested, tasks in parallel.

use rayon::prelude::*;

use super::placed::Placed;

/// Points per block of the overlap test.
pub const BLOCK: usize = 32;
/// Points per parallel task.
const TASK: usize = 8192;

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
    use crate::cloud::exclusion::volume::VolumeShape;
    use crate::geometry::Primitive;
    use nalgebra::Isometry3;
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
