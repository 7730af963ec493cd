//! Step 2, the opening: the unseen cells that could hold a body of the detection capability.
//!
//! A safety sensor's **detection capability** `D` is the diameter of the smallest object it is
//! guaranteed to detect. An unseen region that cannot hold a ball of diameter `D` cannot hide
//! such an object, so it does not count: the morphological opening of the unseen set by that
//! ball, so that isolated dropped pixels (thin rays of unseen cells) vanish and a dark torso,
//! or a person in a shadow, does not. With centre sampling the opening must never lose a
//! hidden ball, which fixes its two radii. Let `R = D/2`, `h` the resolution, `d = √3·h` the
//! cell diagonal, and `ε = pitch² / (2R)` the **pixel slack**: the depth of the sliver at the
//! rim of the ball's image that a 2 × 2 pixel block can miss (a chord of at most √2 pixels
//! across a rim of radius at least `R·f/z · cos 60°`), with `pitch` the largest pixel pitch of
//! any view where it can see a cell free (`Observation::pixel_pitch_m`). Every cell centre
//! within `R − ε` of a hidden ball's centre `c` is unseen (`observe`).
//!
//! 1. **Erosion.** Take `x`, the cell centre nearest `c` (`c` lies in `x`'s cube). The centre
//!    `x + k·h` (`k` an integer offset) lies within `R − ε` of `c` wherever `c` is in that cube
//!    when `h·|(|k₁|+½, |k₂|+½, |k₃|+½)| ≤ R − ε`; call that set of offsets `K`. `x` survives
//!    an erosion by any element inside `K`. The erosion here is by the largest Euclidean ball
//!    inside `K`: a cell survives when every cell centre nearer than `ρₑ = h·min{|k| : k ∉ K}`
//!    is unseen, read off the exact squared distance transform of the cells that are not
//!    unseen (`edt`). (The plain triangle-inequality bound, a ball of `R − ε − d/2`, is
//!    smaller; at the defaults, 70 mm at 2 cm, it is below one cell and erodes nothing, where
//!    `K` holds the six face neighbours and removes every isolated cell.) When even `k = 0` is
//!    not in `K` (`d/2 > R − ε`), a ball may hold no centre at all: the capability is finer
//!    than the lattice resolves, and [`open`] refuses it.
//! 2. **Dilation** of the survivors by `ρ_d = R + d/2`: every centre within `R` of `c` lies
//!    within `R + d/2` of `x`. Read off the distance transform of the survivors.
//! 3. **Intersection** with the unseen set: the opened cells are unseen cells, and they hold
//!    every centre within `R − ε` of the hidden ball's centre.
//!
//! The distance (`distance`) then subtracts `margin_m = d + ε`: the hidden ball's point nearest
//! the robot, `p`, has a centre within `R − ε` of `c` no farther than `d + ε` from it (the ball
//! of radius `d/2` about `p` moved `d/2 + ε` inwards holds a centre and lies within `R − ε`).
//!
//! Cells beyond the lattice are taken as unseen for the erosion (a body reaching out of the
//! monitored volume still counts). Cost: two distance transforms, O(cells), in parallel.

use rayon::prelude::*;

use super::edt::squared_distance_transform;
use super::error::UnseenError;
use super::lattice::{positive, Lattice};

/// Default detection capability (m): 70 mm, arm-level. ISO 13855 (with IEC 61496's ESPE
/// classes) takes a detection capability above 40 mm and up to 70 mm as detecting an arm, and
/// adds the reach of an arm (C = 850 mm) to the safety distance; 14 mm (finger) and 30–40 mm
/// (hand) need the full `8·(d − 14)` intrusion allowance. A 2 cm lattice resolves 70 mm with
/// its opening intact (`R − ε ≥ 1.66·h`, so isolated dropped pixels vanish) to about 5 m from a
/// 525 px camera; hand level (40 mm) would need a 1.2 cm lattice for that (at 2 cm it is
/// accepted, `R ≥ d/2`, but the opening then removes nothing). Choose 40 mm with a finer
/// lattice where a person's hand must be caught behind a dropout.
pub const DEFAULT_DETECTION_CAPABILITY_M: f64 = 0.07;

/// The opened unseen set: the cells that may belong to a hidden body of the capability.
#[derive(Debug, Clone, PartialEq)]
pub struct Opened {
    /// Per cell (lattice index).
    pub cells: Vec<bool>,
    /// Cells set in `cells`.
    pub count: usize,
    /// A cell survived the erosion when every cell centre nearer than this was unseen (m).
    pub erosion_radius_m: f64,
    /// The survivors were dilated by this (m).
    pub dilation_radius_m: f64,
    /// What the distance to the opened cells' centres must lose to stay a lower bound of the
    /// distance to a hidden body: a cell diagonal plus the pixel slack (m).
    pub margin_m: f64,
}

/// The opening of `unseen` (one flag per cell of `lattice`) by a ball of diameter
/// `detection_capability_m`, made conservative for centre sampling and for the views'
/// `pixel_pitch_m` (see the module doc).
pub fn open(
    lattice: &Lattice,
    unseen: &[bool],
    pixel_pitch_m: f64,
    detection_capability_m: f64,
) -> Result<Opened, UnseenError> {
    let radius = positive("detection_capability", detection_capability_m)? / 2.0;
    if unseen.len() != lattice.len() {
        return Err(UnseenError::PixelCount {
            what: "unseen cell flags (one per lattice cell)",
            got: unseen.len(),
            width: lattice.len() as u32,
            height: 1,
        });
    }
    let h = lattice.resolution_m();
    let slack = pixel_pitch_m.max(0.0).powi(2) / (2.0 * radius);
    let Some(erosion2) = erosion_offset2((radius - slack) / h) else {
        return Err(UnseenError::CapabilityBelowResolution {
            detection_capability_m,
            resolution_m: h,
            needed_m: lattice.cell_diagonal_m() + 2.0 * slack,
        });
    };
    let dims = lattice.dims();
    // 1. Erosion: distance to the nearest cell that is not unseen.
    let mut grid: Vec<f64> = unseen
        .par_iter()
        .map(|&u| if u { f64::INFINITY } else { 0.0 })
        .collect();
    squared_distance_transform(&mut grid, dims);
    // Squared distances are integers: compare half a unit below.
    let survives = erosion2 as f64 - 0.5;
    let any = grid.par_iter().any(|&d2| d2 >= survives);
    let dilation = radius + 0.5 * lattice.cell_diagonal_m();
    let opened = Opened {
        cells: Vec::new(),
        count: 0,
        erosion_radius_m: (erosion2 as f64).sqrt() * h,
        dilation_radius_m: dilation,
        margin_m: lattice.cell_diagonal_m() + slack,
    };
    if !any {
        return Ok(Opened {
            cells: vec![false; unseen.len()],
            ..opened
        });
    }
    // 2. Dilation: distance to the nearest survivor.
    grid.par_iter_mut().for_each(|d2| {
        *d2 = if *d2 >= survives { 0.0 } else { f64::INFINITY };
    });
    squared_distance_transform(&mut grid, dims);
    // 3. Intersection with the unseen cells.
    let reach2 = (dilation / h).powi(2) * (1.0 + 1e-12);
    let cells: Vec<bool> = grid
        .par_iter()
        .zip(unseen)
        .map(|(&d2, &u)| u && d2 <= reach2)
        .collect();
    let count = cells.par_iter().filter(|&&c| c).count();
    Ok(Opened {
        cells,
        count,
        ..opened
    })
}

/// The smallest `|k|²` of an integer offset outside `K = {k : |(|kᵢ| + ½)| ≤ reach}` (reach in
/// cells), `None` when `K` is empty.
fn erosion_offset2(reach: f64) -> Option<u64> {
    let reach2 = reach * reach;
    if reach2.is_nan() || reach2 < 0.75 {
        return None;
    }
    let m = reach.ceil() as u64 + 1;
    let mut best = u64::MAX;
    for a in 0..=m {
        for b in a..=m {
            for c in b..=m {
                let outside = [a, b, c]
                    .iter()
                    .map(|&k| (k as f64 + 0.5).powi(2))
                    .sum::<f64>()
                    > reach2;
                if outside {
                    best = best.min(a * a + b * b + c * c);
                }
            }
        }
    }
    Some(best)
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Isometry3;

    fn cube(n: usize, h: f64) -> Lattice {
        Lattice::new(Isometry3::identity(), [0.5 * n as f64 * h; 3], h).unwrap()
    }

    #[test]
    fn the_erosion_element_is_the_guaranteed_offsets() {
        // Too small for a centre: refused.
        assert_eq!(erosion_offset2(0.8), None);
        // A centre, no neighbour: nothing is eroded (|k|² ≥ 1 always holds for a cell).
        assert_eq!(erosion_offset2(0.9), Some(1));
        // 70 mm at 2 cm: the six face neighbours (√2.75 = 1.658 ≤ 1.75 < √4.75).
        assert_eq!(erosion_offset2(1.75), Some(2));
        assert_eq!(erosion_offset2(2.2), Some(3));
    }

    #[test]
    fn isolated_cells_vanish_and_a_ball_survives_whole() {
        let l = cube(30, 0.02);
        let mut unseen = vec![false; l.len()];
        // Scattered single cells and a one-cell-thick line.
        for ijk in [[3, 4, 5], [20, 20, 20], [10, 25, 2]] {
            unseen[l.index(ijk)] = true;
        }
        for i in 0..30 {
            unseen[l.index([i, 12, 12])] = true;
        }
        // A ball of diameter 7 cm (its centres within 3.5 cm) about cell (20, 8, 8).
        let c = l.centre(l.index([20, 8, 8]));
        let mut ball = 0;
        for (i, u) in unseen.iter_mut().enumerate() {
            let p = l.centre(i);
            if (0..3).map(|a| (p[a] - c[a]).powi(2)).sum::<f32>() <= 0.035f32.powi(2) {
                *u = true;
                ball += 1;
            }
        }
        let o = open(&l, &unseen, 0.004, DEFAULT_DETECTION_CAPABILITY_M).unwrap();
        assert_eq!(o.count, ball);
        for (i, &opened) in o.cells.iter().enumerate() {
            let p = l.centre(i);
            let inside = (0..3).map(|a| (p[a] - c[a]).powi(2)).sum::<f32>() <= 0.035f32.powi(2);
            assert_eq!(opened, inside, "cell {:?}", l.ijk(i));
        }
        assert!((o.margin_m - (0.02 * 3f64.sqrt() + 0.004f64.powi(2) / 0.07)).abs() < 1e-12);
        // Everything unseen stays unseen; nothing unseen opens to nothing.
        let all = open(&l, &vec![true; l.len()], 0.004, 0.07).unwrap();
        assert_eq!(all.count, l.len());
        let none = open(&l, &vec![false; l.len()], 0.004, 0.07).unwrap();
        assert_eq!((none.count, none.cells.len()), (0, l.len()));
    }

    #[test]
    fn capabilities_the_lattice_cannot_resolve_are_refused() {
        let l = cube(4, 0.02);
        let e = open(&l, &[true; 64], 0.0, 0.03).unwrap_err().to_string();
        assert!(
            e.contains("detection_capability") && e.contains("0.0346"),
            "{e}"
        );
        assert!(open(&l, &[true; 64], 0.0, -1.0).is_err());
        assert!(open(&l, &[true; 3], 0.0, 0.07).is_err());
    }
}
