//! Step 3, the distance to unseen space: a certified lower bound of the distance from the
//! robot to any body of the detection capability that no source has seen.
//!
//! Input: the [`Opened`] cells (root frame) and the caller's certified lower bound of the
//! distance from a set of root-frame points to the robot (the monitor passes the inner sphere
//! trees' query, each link's surface gap subtracted; the tests pass a brute-force distance to
//! a box). Output: that bound over the opened cells' centres less `Opened::margin_m`, floored
//! at 0, or `None` when no opened cell is left (the caller publishes NaN: the monitored volume
//! is seen, up to what cannot hide a body of the capability).
//!
//! **Why a whole cell diagonal.** The opened cells are sampled at their centres. A hidden ball
//! of the capability holds every centre within `R − ε` of its own centre (`opening`); its point
//! nearest the robot may lie up to a cell diagonal (plus the pixel slack `ε`) from the nearest
//! such centre — half a diagonal would cover only the nearest centre to a given point, which may
//! lie outside the ball and so not be unseen. Subtracting `d + ε` keeps the bound below the
//! distance to every point of the ball, and the lower bound of the query keeps it below the
//! distance to the robot's meshes.
//!
//! What the caller removes before the opening: the robot's own padded volume (its
//! self-filter: cells within the self-filter padding of a link; the robot is not a hidden body,
//! and its inside is always unseen), the exclusion volumes
//! ([`super::observe::Observation::drop_excluded`]) and attached objects
//! (`Observation::drop_where`). A hidden body is taken to lie outside all of these.
//! Cost: one pass to gather the centres, then the caller's query.

use super::lattice::Lattice;
use super::opening::Opened;

/// `lower_bound(centres) − opened.margin_m` (floored at 0) over the centres of the opened cells,
/// or of those also set in `subset` (e.g. `Observation::self_shadow`); `None` when there is no
/// such cell. `lower_bound` is called once, with the root-frame centres (f32, m).
pub fn unseen_distance<F>(
    lattice: &Lattice,
    opened: &Opened,
    subset: Option<&[bool]>,
    lower_bound: F,
) -> Option<f64>
where
    F: FnOnce(&[[f32; 3]]) -> f64,
{
    let cells: Vec<bool> = match subset {
        Some(s) => opened.cells.iter().zip(s).map(|(&o, &s)| o && s).collect(),
        None => opened.cells.clone(),
    };
    let centres = lattice.centres(&cells);
    if centres.is_empty() {
        return None;
    }
    Some((lower_bound(&centres) - opened.margin_m).max(0.0))
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Isometry3;

    #[test]
    fn the_margin_is_subtracted_and_nothing_left_is_none() {
        let l = Lattice::new(Isometry3::identity(), [0.1; 3], 0.02).unwrap();
        let mut cells = vec![false; l.len()];
        cells[l.index([9, 4, 4])] = true;
        cells[l.index([0, 0, 0])] = true;
        let opened = Opened {
            cells,
            count: 2,
            erosion_radius_m: 0.0,
            dilation_radius_m: 0.0,
            margin_m: 0.03,
        };
        // Distance from the plane x = 1 m.
        let to_plane = |c: &[[f32; 3]]| {
            c.iter()
                .map(|p| 1.0 - f64::from(p[0]))
                .fold(f64::MAX, f64::min)
        };
        let d = unseen_distance(&l, &opened, None, to_plane).unwrap();
        assert!((d - (1.0 - 0.09 - 0.03)).abs() < 1e-6, "{d}");
        // Only the far corner in the subset.
        let mut subset = vec![false; l.len()];
        subset[0] = true;
        let d = unseen_distance(&l, &opened, Some(&subset), to_plane).unwrap();
        assert!((d - (1.0 + 0.09 - 0.03)).abs() < 1e-6, "{d}");
        assert_eq!(
            unseen_distance(&l, &opened, Some(&vec![false; l.len()]), to_plane),
            None
        );
        // Floored at zero.
        assert_eq!(unseen_distance(&l, &opened, None, |_| 0.01), Some(0.0));
    }
}
