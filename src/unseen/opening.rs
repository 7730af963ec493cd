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
//! 2. **Dilation** of the survivors: every centre within `R` of `c` lies within `ρ_d = R + d/2`
//!    of `x`. [`open`] dilates by the enclosing box instead of that ball: the cells within
//!    `m = ⌊ρ_d/h⌋` cells of a survivor along each axis (`morphology`), which holds every
//!    offset `k` with `|k|·h ≤ ρ_d` (each `|kᵢ| ≤ |k|`). A superset of the ball's dilation
//!    stays certified: more opened cells can only lower the reported distance. What it costs in
//!    conservatism: the box's corners, at most `√3·m·h` from a survivor where the ball reaches
//!    `ρ_d` (at the defaults `m = 2`: 69 mm against 52 mm), so unseen cells up to about 17 mm
//!    beyond the ball's reach may open, and only where they are unseen and beside a survivor.
//! 3. **Intersection** with the unseen set: the opened cells are unseen cells, and they hold
//!    every centre within `R − ε` of the hidden ball's centre.
//!
//! The distance (`distance`) then subtracts `margin_m = d + ε`: the hidden ball's point nearest
//! the robot, `p`, has a centre within `R − ε` of `c` no farther than `d + ε` from it (the ball
//! of radius `d/2` about `p` moved `d/2 + ε` inwards holds a centre and lies within `R − ε`).
//!
//! Cells beyond the lattice are not unseen for the erosion: the guarantee is for a ball that
//! fits inside the monitored volume. Were they unseen, the unseen skin along a face (the cells
//! within the range noise of a floor the volume stands on, the rim where the arm leaves the
//! volume) would survive the erosion beside the robot and hold the distance at zero; a body
//! larger than the capability that reaches into the volume by more than it still counts.
//!
//! **The passes.** The erosion tests the stencil of integer offsets `|k|² < ρₑ²/h²` on every
//! unseen cell, stopping at its first seen neighbour (`morphology::erode`; at the defaults the
//! six face neighbours); past 256 offsets (`ρₑ` above 4 cells) it reads the exact squared
//! distance transform of the cells that are not unseen instead (`edt`), whose cost does not
//! grow with the radius. Both give the same survivors (unit test). The dilation is three 1-D
//! sliding-window passes. [`open_exact`] keeps the former form, two distance transforms and the
//! ball itself, as the reference the property test compares with (every cell it opens, [`open`]
//! opens, and only unseen cells).
//!
//! Cost: O(unseen cells · stencil) for the erosion (most candidates stop at a face neighbour),
//! O(cells) for the dilation, in parallel (rayon). Measured by the test `kinect_scene_runs`
//! (10⁶ cells, 17 % unseen, the Kinect scene), release build, 2-core VM under another build's
//! load, 2026-11-27, five runs: 7.3–11.9 ms, against 117–194 ms for [`open_exact`] in the same
//! runs (52.7–69.3 ms on the quiet machine); see `mod.rs`.

use rayon::prelude::*;

use super::edt::squared_distance_transform;
use super::error::UnseenError;
use super::lattice::{positive, Lattice};
use super::morphology::{dilate_by_box, erode, stencil};

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
    /// The survivors were dilated by this (m): for [`open`], the half-width `m·h` of the box of
    /// cells, along each of the lattice's axes (`m = ⌊ρ_d/h⌋`, so the box holds the ball of
    /// `ρ_d` and its corners reach `√3` times this); for [`open_exact`], the ball's radius `ρ_d`.
    pub dilation_radius_m: f64,
    /// What the distance to the opened cells' centres must lose to stay a lower bound of the
    /// distance to a hidden body: a cell diagonal plus the pixel slack (m).
    pub margin_m: f64,
}

/// The opening of `unseen` (one flag per cell of `lattice`) by a ball of diameter
/// `detection_capability_m`, made conservative for centre sampling and for the views'
/// `pixel_pitch_m`, its dilation by the enclosing box of cells (see the module doc).
pub fn open(
    lattice: &Lattice,
    unseen: &[bool],
    pixel_pitch_m: f64,
    detection_capability_m: f64,
) -> Result<Opened, UnseenError> {
    let (erosion2, mut opened) = prepare(lattice, unseen, pixel_pitch_m, detection_capability_m)?;
    let dims = lattice.dims();
    // The box that holds the ball of ρ_d (the tolerance as `open_exact`'s, so that the box
    // holds every offset the ball there takes).
    let h = lattice.resolution_m();
    let m = (opened.dilation_radius_m / h * (1.0 + 1e-12)).floor() as usize;
    opened.dilation_radius_m = m as f64 * h;
    // 1. Erosion.
    let survivors = match stencil(erosion2) {
        Some(offsets) => erode(unseen, dims, &offsets),
        None => erode_by_transform(unseen, dims, erosion2),
    };
    if !survivors.par_iter().any(|&s| s) {
        return Ok(Opened {
            cells: vec![false; unseen.len()],
            ..opened
        });
    }
    // 2. Dilation; 3. intersection.
    let cells = dilate_by_box(&survivors, dims, m);
    Ok(intersect(cells, unseen, opened))
}

/// The opening as [`open`] takes it, with the dilation by the ball of `ρ_d` itself, by two
/// exact distance transforms: a subset of [`open`]'s cells, slower (the reference of the
/// property test, and the cost the module doc compares with).
#[doc(hidden)]
pub fn open_exact(
    lattice: &Lattice,
    unseen: &[bool],
    pixel_pitch_m: f64,
    detection_capability_m: f64,
) -> Result<Opened, UnseenError> {
    let (erosion2, opened) = prepare(lattice, unseen, pixel_pitch_m, detection_capability_m)?;
    let dims = lattice.dims();
    let survivors = erode_by_transform(unseen, dims, erosion2);
    if !survivors.par_iter().any(|&s| s) {
        return Ok(Opened {
            cells: vec![false; unseen.len()],
            ..opened
        });
    }
    // Distance to the nearest survivor.
    let mut grid: Vec<f64> = survivors
        .par_iter()
        .map(|&s| if s { 0.0 } else { f64::INFINITY })
        .collect();
    squared_distance_transform(&mut grid, dims);
    let reach2 = (opened.dilation_radius_m / lattice.resolution_m()).powi(2) * (1.0 + 1e-12);
    let cells = grid.par_iter().map(|&d2| d2 <= reach2).collect();
    Ok(intersect(cells, unseen, opened))
}

/// The checked inputs: the erosion's `|k|²` (see [`erosion_offset2`]) and the opening's radii
/// and margin, with no cells yet (the dilation radius is the ball's, `ρ_d`).
fn prepare(
    lattice: &Lattice,
    unseen: &[bool],
    pixel_pitch_m: f64,
    detection_capability_m: f64,
) -> Result<(u64, Opened), UnseenError> {
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
    Ok((
        erosion2,
        Opened {
            cells: Vec::new(),
            count: 0,
            erosion_radius_m: (erosion2 as f64).sqrt() * h,
            dilation_radius_m: radius + 0.5 * lattice.cell_diagonal_m(),
            margin_m: lattice.cell_diagonal_m() + slack,
        },
    ))
}

/// The erosion survivors read off the exact squared distance transform of the cells that are
/// not unseen: those whose nearest such cell lies at `|k|² ≥ erosion2`.
fn erode_by_transform(unseen: &[bool], dims: [usize; 3], erosion2: u64) -> Vec<bool> {
    let mut grid: Vec<f64> = unseen
        .par_iter()
        .map(|&u| if u { f64::INFINITY } else { 0.0 })
        .collect();
    squared_distance_transform(&mut grid, dims);
    // Squared distances are integers: compare half a unit below.
    let survives = erosion2 as f64 - 0.5;
    // The nearest cell beyond the lattice lies along an axis, `min(i + 1, n − i)` away: it
    // fails the cell as a seen one would.
    let [n0, n1, _] = dims;
    grid.par_iter()
        .enumerate()
        .map(|(index, &d2)| {
            let ijk = [index % n0, (index / n0) % n1, index / (n0 * n1)];
            let border = (0..3)
                .map(|a| (ijk[a] + 1).min(dims[a] - ijk[a]))
                .min()
                .unwrap_or(0) as f64;
            d2 >= survives && border * border >= survives
        })
        .collect()
}

/// Step 3: `dilated` less the cells that are not unseen, counted, into `opened`.
fn intersect(mut dilated: Vec<bool>, unseen: &[bool], opened: Opened) -> Opened {
    dilated
        .par_iter_mut()
        .zip(unseen)
        .for_each(|(c, &u)| *c &= u);
    let count = dilated.par_iter().filter(|&&c| c).count();
    Opened {
        cells: dilated,
        count,
        ..opened
    }
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
    use super::super::morphology::tests::Rng;
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
        assert!(open_exact(&l, &[true; 64], 0.0, 0.03).is_err());
    }

    /// Against the exact opening (two distance transforms, the ball itself) on random unseen
    /// sets, lattices, resolutions, capabilities and pixel pitches: the same erosion survivors,
    /// and the fast opening holds every cell the exact one opens and only unseen cells.
    #[test]
    fn the_fast_opening_holds_the_exact_one() {
        let mut rng = Rng(0x0be1_1a5e);
        let (mut tried, mut fallback, mut opened) = (0, 0, 0);
        while tried < 60 {
            let h = rng.range(0.01, 0.05);
            let half = [0; 3].map(|_| rng.range(0.5, 15.0) * h);
            let l = Lattice::new(Isometry3::translation(0.1, -0.2, 0.3), half, h).unwrap();
            let capability = rng.range(1.5, 12.0) * h;
            let pitch = rng.range(0.0, 0.3) * h;
            // Unseen everywhere but for scattered seen cells, at a density that leaves some
            // survivors and some holes.
            let density = rng.range(0.6, 0.995);
            let unseen: Vec<bool> = (0..l.len()).map(|_| rng.next() < density).collect();
            let Ok(exact) = open_exact(&l, &unseen, pitch, capability) else {
                assert!(open(&l, &unseen, pitch, capability).is_err());
                continue;
            };
            tried += 1;
            let fast = open(&l, &unseen, pitch, capability).unwrap();
            let (erosion2, _) = prepare(&l, &unseen, pitch, capability).unwrap();
            let survivors = erode_by_transform(&unseen, l.dims(), erosion2);
            match stencil(erosion2) {
                Some(offsets) => assert_eq!(erode(&unseen, l.dims(), &offsets), survivors),
                None => fallback += 1,
            }
            opened += usize::from(exact.count > 0);
            for (i, (&e, &f)) in exact.cells.iter().zip(&fast.cells).enumerate() {
                assert!(!e || f, "cell {:?}", l.ijk(i));
                assert!(!f || unseen[i], "cell {:?}", l.ijk(i));
            }
            assert!(fast.count >= exact.count);
            assert_eq!(fast.cells.iter().filter(|&&c| c).count(), fast.count);
            assert_eq!(
                (fast.erosion_radius_m, fast.margin_m),
                (exact.erosion_radius_m, exact.margin_m)
            );
            // The box's half-width is ρ_d rounded down to whole cells.
            assert!(fast.dilation_radius_m <= exact.dilation_radius_m);
            assert!(fast.dilation_radius_m + h > exact.dilation_radius_m);
        }
        // Both erosion paths and non-empty openings were exercised.
        assert!(
            fallback > 0 && fallback < tried && opened > 10,
            "{fallback} {opened}"
        );
    }
}
