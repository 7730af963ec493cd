//! Step 1, the observation: which cells of the lattice some source has seen free.
//!
//! Inputs: the [`Lattice`] (root frame) and the sources' [`RangeView`]s (each its pixel grid,
//! `root_from_camera`, depths along z). Output: an [`Observation`], per cell whether it is
//! unseen and whether it is in the robot's own shadow, and the fractions seen.
//!
//! **Seen free.** A cell is seen free by a view when its centre `p` (camera frame, `z > 0`,
//! no nearer than the view's minimum range) projects to `(u, v) = (fx·x/z + cx, fy·y/z + cy)`
//! inside the image, and *each* pixel of the 2 × 2 block whose centres surround `(u, v)` has a
//! return `r` with `r − range_noise > z`: every ray next to the centre passed beyond it. The
//! block, rather than the one nearest pixel, is what keeps the pass certified: if the centre
//! lies inside a body that returns nothing (or that something nearer hides), the body's image
//! contains the centre's projection and so, unless the centre is within a sliver of the body's
//! outline (`opening`'s pixel slack, `pitch² / capability`), at least one of the block's pixel
//! centres, whose ray then does not pass. A pixel with no return sees nothing along its ray; a
//! cell outside the image (or within half a pixel of its border), behind the camera or nearer
//! than its minimum range is not seen by that view.
//!
//! **Fused.** A cell is unseen when no view sees it free. It is in the **self shadow** when it
//! is unseen and some view would have seen it but for the robot: every pixel of its block that
//! does not pass beyond it returned, in front of it, a point the self-filter took as the robot.
//!
//! **Cost.** One parallel pass over the lattice's rows (rayon); per cell and view three f32
//! additions to step the centre, one division, four depth reads. The poses are composed once
//! per view in f64 (`Lattice::in_frame`). 10⁶ cells × one 640 × 480 view: see the tests.

use rayon::prelude::*;

use crate::cloud::exclusion::{exclude, Placed};

use super::lattice::{centre_at, Lattice};
use super::view::RangeView;

/// Which cells no source has seen free, and why.
#[derive(Debug, Clone, PartialEq)]
pub struct Observation {
    /// Per cell (lattice index): seen free by no view.
    pub unseen: Vec<bool>,
    /// Per cell: unseen, and hidden from some view only by the robot's own body (a subset of
    /// `unseen`).
    pub self_shadow: Vec<bool>,
    /// Cells seen free by some view, over all cells.
    pub observed_fraction: f64,
    /// Cells seen free by each view (in the order given), over all cells.
    pub observed_fraction_per_view: Vec<f64>,
    /// The largest pixel pitch (m) of any view at the farthest depth where it can see a cell
    /// free (the lattice's farthest corner, or the view's maximum range when nearer): the
    /// opening's pixel slack comes from it. 0 without views.
    pub pixel_pitch_m: f64,
}

impl Observation {
    /// Unseen cells.
    pub fn unseen_count(&self) -> usize {
        self.unseen.iter().filter(|&&u| u).count()
    }

    /// Forgets the unseen cells for which `drop(index, root-frame centre)` holds (they become
    /// neither unseen nor shadow): what the caller removes because it cannot hold a person, the
    /// robot's own padded volume first (its self-filter), attached objects. Returns how many.
    pub fn drop_where(
        &mut self,
        lattice: &Lattice,
        drop: impl Fn(usize, [f32; 3]) -> bool + Sync,
    ) -> usize {
        let (origin, steps) = lattice.in_frame(&nalgebra::Isometry3::identity());
        self.unseen
            .par_iter_mut()
            .zip(self.self_shadow.par_iter_mut())
            .enumerate()
            .filter(|(i, (u, _))| **u && drop(*i, centre_at(origin, &steps, lattice.ijk(*i))))
            .map(|(_, (u, s))| {
                *u = false;
                *s = false;
            })
            .count()
    }

    /// Forgets the unseen cells inside the exclusion `volumes`, placed in the lattice's root
    /// frame (`Placed::new(shape, &root_from_volume)`), with `cloud::exclusion`'s own point
    /// test. Returns how many each volume took (a cell in two counts for the first).
    pub fn drop_excluded(&mut self, lattice: &Lattice, volumes: &[Placed]) -> Vec<u64> {
        let indices: Vec<usize> = (0..self.unseen.len()).filter(|&i| self.unseen[i]).collect();
        let mut centres: Vec<[f32; 3]> = indices.iter().map(|&i| lattice.centre(i)).collect();
        let counts = exclude(&mut centres, volumes);
        for (&i, c) in indices.iter().zip(&centres) {
            if c[0].is_nan() {
                self.unseen[i] = false;
                self.self_shadow[i] = false;
            }
        }
        counts
    }
}

/// A view's verdict on one cell.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Verdict {
    Free,
    /// Not free, and every pixel that stopped short of the cell was the robot.
    RobotInFront,
    Unseen,
}

/// A view in f32, with the lattice placed in its camera frame.
struct Placement<'a> {
    origin: [f32; 3],
    steps: [[f32; 3]; 3],
    fx: f32,
    fy: f32,
    cx: f32,
    cy: f32,
    width: usize,
    /// The largest `u` and `v` whose 2 × 2 block lies in the image.
    u_max: f32,
    v_max: f32,
    min2: f32,
    noise: f32,
    ranges: &'a [f32],
    robot: &'a [bool],
}

impl<'a> Placement<'a> {
    fn new(lattice: &Lattice, view: &'a RangeView) -> Self {
        let (origin, steps) = lattice.in_frame(&view.root_from_camera().inverse());
        let c = view.camera();
        Self {
            origin,
            steps,
            fx: c.fx as f32,
            fy: c.fy as f32,
            cx: c.cx as f32,
            cy: c.cy as f32,
            width: c.width as usize,
            u_max: (c.width - 1) as f32,
            v_max: (c.height - 1) as f32,
            min2: view.min_range2(),
            noise: view.range_noise_m(),
            ranges: view.ranges(),
            robot: view.robot_pixels(),
        }
    }

    /// The pixel pitch (m) at the farthest depth where this view may see a cell free: the
    /// lattice's farthest corner cell, or the maximum range where that is nearer (a cell seen
    /// free lies before a return).
    fn pitch(&self, lattice: &Lattice, max_range_m: f32) -> f64 {
        let dims = lattice.dims();
        let z_far = (0..8)
            .map(|corner: usize| {
                let ijk = std::array::from_fn(|a| (corner >> a & 1) * (dims[a] - 1));
                centre_at(self.origin, &self.steps, ijk)[2]
            })
            .fold(0.0f32, f32::max)
            .min(max_range_m);
        f64::from(z_far) / f64::from(self.fx.min(self.fy))
    }

    #[inline]
    fn verdict(&self, p: [f32; 3]) -> Verdict {
        let z = p[2];
        if z.is_nan() || z <= 0.0 || p[0] * p[0] + p[1] * p[1] + z * z < self.min2 {
            return Verdict::Unseen;
        }
        let u = self.fx * p[0] / z + self.cx;
        let v = self.fy * p[1] / z + self.cy;
        if !(u >= 0.0 && v >= 0.0 && u <= self.u_max && v <= self.v_max) {
            return Verdict::Unseen;
        }
        let (u0, v0) = (u as usize, v as usize);
        let u1 = (u0 + 1).min(self.u_max as usize);
        let v1 = (v0 + 1).min(self.v_max as usize);
        // Free iff r − noise > z for every pixel; a NaN range fails the comparison.
        let beyond = z + self.noise;
        let mut free = true;
        for i in [
            v0 * self.width + u0,
            v0 * self.width + u1,
            v1 * self.width + u0,
            v1 * self.width + u1,
        ] {
            let r = self.ranges[i];
            if r > beyond {
                continue;
            }
            if r.is_nan() || !self.robot[i] {
                return Verdict::Unseen;
            }
            free = false;
        }
        if free {
            Verdict::Free
        } else {
            Verdict::RobotInFront
        }
    }
}

/// Which cells of `lattice` no view in `views` has seen free (see the module doc).
pub fn observe(lattice: &Lattice, views: &[&RangeView]) -> Observation {
    let placed: Vec<Placement> = views.iter().map(|v| Placement::new(lattice, v)).collect();
    let [n0, n1, _] = lattice.dims();
    let n = lattice.len();
    let mut unseen = vec![false; n];
    let mut self_shadow = vec![false; n];
    let zero = || (vec![0u64; views.len()], 0u64);
    let (per_view, any) = unseen
        .par_chunks_mut(n0)
        .zip(self_shadow.par_chunks_mut(n0))
        .enumerate()
        .fold(zero, |(mut per_view, mut any), (row, (unseen, shadow))| {
            let jk = [0, row % n1, row / n1];
            let starts: Vec<[f32; 3]> = placed
                .iter()
                .map(|p| centre_at(p.origin, &p.steps, jk))
                .collect();
            for i in 0..n0 {
                let (mut seen, mut robot) = (false, false);
                for (v, (p, s)) in placed.iter().zip(&starts).enumerate() {
                    let c = std::array::from_fn(|a| s[a] + i as f32 * p.steps[0][a]);
                    match p.verdict(c) {
                        Verdict::Free => {
                            seen = true;
                            per_view[v] += 1;
                        }
                        Verdict::RobotInFront => robot = true,
                        Verdict::Unseen => {}
                    }
                }
                unseen[i] = !seen;
                shadow[i] = !seen && robot;
            }
            any += unseen.iter().filter(|&&u| !u).count() as u64;
            (per_view, any)
        })
        .reduce(zero, |(a, x), (b, y)| {
            (a.iter().zip(&b).map(|(p, q)| p + q).collect(), x + y)
        });
    let fraction = |count: u64| count as f64 / n as f64;
    Observation {
        unseen,
        self_shadow,
        observed_fraction: fraction(any),
        observed_fraction_per_view: per_view.into_iter().map(fraction).collect(),
        pixel_pitch_m: placed
            .iter()
            .zip(views)
            .map(|(p, v)| p.pitch(lattice, v.max_range_m()))
            .fold(0.0, f64::max),
    }
}
