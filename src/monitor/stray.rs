//! The stray-point filter (`stray_filter`, off by default): one point decides the distance, so a
//! single mixed pixel beside the arm can stop the cell. While a source's nearest point has fewer
//! than `min_points` obstacle points (itself included) within `cluster_radius` — neighbours
//! that the self-filter takes as the robot do not count, so the arm's own fringe is not a
//! cluster — it is made invalid and the query repeated, at most `max_rejected` times; after
//! that the nearest point counts, whatever its neighbours. A real obstacle of `min_points`
//! points within `cluster_radius` of each other is never rejected, so the distance is never
//! above that of any such cluster.
//!
//! Cost per frame with nothing rejected: one scan of the cloud for the nearest point's
//! neighbours (an f32 test with a margin, the exact one in f64 on the few it keeps) and a
//! self-filter check of them in small batches (`ist_monitor bench monitor`).

use nalgebra::Isometry3;

use crate::config::StrayFilter;
use crate::query::{Backend, Engine, Mode, QueryError, QueryOptions, QueryResult};

/// The query the filter repeats: the cloud (rejected points are made NaN in it) and where it is.
pub struct Input<'a> {
    pub points: &'a mut [[f32; 3]],
    /// Points per row of an organized cloud.
    pub width: Option<usize>,
    pub root_from_sensor: &'a Isometry3<f64>,
    pub poses: &'a [Isometry3<f64>],
    pub options: &'a QueryOptions,
}

/// `result` (the query of `input`) after the filter; `stray_rejected` counts the points made
/// invalid.
pub fn reject_strays(
    engine: &mut Engine,
    stray: &StrayFilter,
    input: Input<'_>,
    mut result: QueryResult,
) -> Result<QueryResult, QueryError> {
    let Input {
        points,
        width,
        root_from_sensor,
        poses,
        options,
    } = input;
    // Only the self-filter matters for the neighbours.
    let self_filter_only = QueryOptions {
        mode: Mode::Fast,
        per_link: false,
        backend: Backend::Cpu,
        ..options.clone()
    };
    let needed = u64::from(stray.min_points) - 1;
    let mut neighbours = Vec::new();
    let mut rejected = 0;
    while rejected < stray.max_rejected {
        let Some(i) = result.nearest.as_ref().map(|n| n.point_index as usize) else {
            break;
        };
        within(points, i, stray.cluster_radius_m, &mut neighbours);
        // Asked in batches: most neighbours of a real obstacle are obstacle points.
        let mut obstacle = 0;
        for batch in neighbours.chunks(8 * stray.min_points as usize) {
            let n = engine.query(batch, root_from_sensor, poses, &self_filter_only)?;
            obstacle += n.counts.total - n.counts.invalid - n.counts.self_filtered;
            if obstacle >= needed {
                break;
            }
        }
        if obstacle >= needed {
            break;
        }
        points[i] = [f32::NAN; 3];
        rejected += 1;
        result = engine.query_image(points, width, root_from_sensor, poses, options)?;
    }
    result.stray_rejected = u64::from(rejected);
    Ok(result)
}

/// The points other than `i` within `radius` of point `i`, into `out`: an f32 test with a margin
/// over every point, then the exact one in f64 on the few it keeps (NaN points fail both).
fn within(points: &[[f32; 3]], i: usize, radius: f64, out: &mut Vec<[f32; 3]>) {
    let r2 = radius * radius;
    let r2_f32 = (r2 * (1.0 + 1e-4)) as f32;
    let p = points[i];
    out.clear();
    for (j, q) in points.iter().enumerate() {
        let (dx, dy, dz) = (q[0] - p[0], q[1] - p[1], q[2] - p[2]);
        if dx * dx + dy * dy + dz * dz <= r2_f32 && j != i {
            let d2: f64 = (0..3)
                .map(|k| (f64::from(q[k]) - f64::from(p[k])).powi(2))
                .sum();
            if d2 <= r2 {
                out.push(*q);
            }
        }
    }
}
