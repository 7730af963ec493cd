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
//! is unseen and, in some view, a pixel of its block returned in front of it (or within the
//! range noise) a point the self-filter took as the robot: the robot's body stood between that
//! camera and the cell. One robot pixel in the block is enough, so that a pixel dropped inside
//! the robot's image does not cut holes in its shadow; the price is that a hidden body's cells
//! within a pixel of the robot's outline, behind it, count as shadow too.
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
    /// Per cell: unseen, and behind the robot's own body in some view (a subset of `unseen`).
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

    /// The unseen cells outside the robot's shadow: opened on their own (`open`), they give the
    /// distance to unseen space that another camera, not the robot, should have seen (a cell
    /// dropped next to the shadow then no longer opens with the shadow's bulk).
    pub fn beyond_self_shadow(&self) -> Vec<bool> {
        self.unseen
            .par_iter()
            .zip(&self.self_shadow)
            .map(|(&u, &s)| u && !s)
            .collect()
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
        if volumes.is_empty() {
            return Vec::new();
        }
        let indices: Vec<usize> = (0..self.unseen.len()).filter(|&i| self.unseen[i]).collect();
        let (origin, steps) = lattice.in_frame(&nalgebra::Isometry3::identity());
        let mut centres: Vec<[f32; 3]> = (indices.par_iter())
            .map(|&i| centre_at(origin, &steps, lattice.ijk(i)))
            .collect();
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
    /// Not free, and a pixel of the block returned the robot in front of the cell.
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
        let (mut free, mut robot) = (true, false);
        for i in [
            v0 * self.width + u0,
            v0 * self.width + u1,
            v1 * self.width + u0,
            v1 * self.width + u1,
        ] {
            if self.ranges[i] > beyond {
                continue;
            }
            free = false;
            // A robot pixel has a return, here one in front of the cell (or within the noise).
            robot |= self.robot[i];
        }
        match (free, robot) {
            (true, _) => Verdict::Free,
            (false, true) => Verdict::RobotInFront,
            (false, false) => Verdict::Unseen,
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cloud::depth::PinholeCamera;
    use crate::cloud::exclusion::VolumeShape;
    use crate::cloud::RangeLimits;
    use crate::geometry::Primitive;
    use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};

    const W: u32 = 64;
    const H: u32 = 48;

    fn camera() -> PinholeCamera {
        PinholeCamera {
            width: W,
            height: H,
            fx: 40.0,
            fy: 40.0,
            cx: 31.5,
            cy: 23.5,
        }
    }

    /// A lattice about (0, 0, 1) in the root frame, 0.4 m wide at 5 cm.
    fn lattice() -> Lattice {
        Lattice::new(Isometry3::translation(0.0, 0.0, 1.0), [0.2; 3], 0.05).unwrap()
    }

    /// A view from `root_from_camera` of depth `depth(u, v)` at each pixel.
    fn view(
        root_from_camera: Isometry3<f64>,
        range: Option<RangeLimits>,
        depth: impl Fn(u32, u32) -> f32,
    ) -> RangeView {
        let depths: Vec<f32> = (0..W * H).map(|i| depth(i % W, i / W)).collect();
        RangeView::new(camera(), root_from_camera, &depths, range, 0.02).unwrap()
    }

    fn depth_of(l: &Lattice, i: usize) -> f32 {
        l.centre(i)[2]
    }

    #[test]
    fn a_wall_shows_the_space_before_it_free() {
        let l = lattice();
        let far = view(Isometry3::identity(), None, |_, _| 2.0);
        let o = observe(&l, &[&far]);
        assert_eq!(o.unseen_count(), 0);
        assert_eq!(o.observed_fraction, 1.0);
        assert_eq!(o.observed_fraction_per_view, vec![1.0]);
        assert!(
            (o.pixel_pitch_m - 1.175 / 40.0).abs() < 1e-6,
            "{}",
            o.pixel_pitch_m
        );
        // A wall at 1 m: the cells from 1 − noise on are behind it or at it.
        let near = view(Isometry3::identity(), None, |_, _| 1.0);
        let o = observe(&l, &[&near]);
        for i in 0..l.len() {
            assert_eq!(o.unseen[i], depth_of(&l, i) >= 0.98, "cell {:?}", l.ijk(i));
            assert!(!o.self_shadow[i]);
        }
        // Nearer than the minimum range: not seen.
        let limited = view(
            Isometry3::identity(),
            RangeLimits::new(1.05, None),
            |_, _| 2.0,
        );
        let o = observe(&l, &[&limited]);
        for i in 0..l.len() {
            let c = l.centre(i);
            let r = (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt();
            assert_eq!(o.unseen[i], r < 1.05, "cell {:?}", l.ijk(i));
        }
    }

    #[test]
    fn dark_pixels_and_the_image_border_see_nothing() {
        let l = lattice();
        // The left half of the image returns nothing.
        let half = view(Isometry3::identity(), None, |u, _| {
            if u < 32 {
                f32::NAN
            } else {
                2.0
            }
        });
        let o = observe(&l, &[&half]);
        for i in 0..l.len() {
            let c = l.centre(i);
            let u = 40.0 * c[0] / c[2] + 31.5;
            // The 2 × 2 block reaches pixel 31 from u < 32.
            assert_eq!(o.unseen[i], u < 32.0, "cell {:?} at u = {u}", l.ijk(i));
        }
        // A narrow camera sees only the middle of the lattice.
        let narrow = RangeView::new(
            PinholeCamera {
                fx: 400.0,
                fy: 400.0,
                ..camera()
            },
            Isometry3::identity(),
            &vec![2.0; (W * H) as usize],
            None,
            0.02,
        )
        .unwrap();
        let o = observe(&l, &[&narrow]);
        assert!(o.observed_fraction > 0.0 && o.observed_fraction < 0.2);
    }

    #[test]
    fn the_robots_shadow_is_told_apart_and_a_second_camera_closes_it() {
        let l = lattice();
        // The robot stands at 0.7 m in the middle of the image, the wall at 2 m elsewhere.
        let robot = |u: u32, v: u32| (24..40).contains(&u) && (16..32).contains(&v);
        let mut front = view(Isometry3::identity(), None, |u, v| {
            if robot(u, v) {
                0.7
            } else {
                2.0
            }
        });
        let flags: Vec<bool> = (0..W * H).map(|i| robot(i % W, i / W)).collect();
        front.set_robot_pixels(&flags).unwrap();
        let o = observe(&l, &[&front]);
        let shadowed = o.self_shadow.iter().filter(|&&s| s).count();
        assert!(shadowed > 0);
        assert_eq!(
            shadowed,
            o.unseen_count(),
            "every unseen cell is behind the robot"
        );
        // Unflagged, the same pixels hide the cells, but not as the robot's shadow.
        let plain = view(Isometry3::identity(), None, |u, v| {
            if robot(u, v) {
                0.7
            } else {
                2.0
            }
        });
        let o2 = observe(&l, &[&plain]);
        assert_eq!(o2.unseen, o.unseen);
        assert!(o2.self_shadow.iter().all(|&s| !s));
        // A camera from the side (at x = 2 m looking along −x) sees into the shadow.
        let side_pose = Isometry3::from_parts(
            Translation3::new(2.0, 0.0, 1.0),
            UnitQuaternion::face_towards(&-Vector3::x(), &Vector3::y()),
        );
        let side = view(side_pose, None, |_, _| 4.0);
        let o = observe(&l, &[&front, &side]);
        assert_eq!(o.unseen_count(), 0);
        assert_eq!(o.observed_fraction_per_view[1], 1.0);
        assert!(o.observed_fraction_per_view[0] < 1.0);
    }

    #[test]
    fn dropped_cells_are_forgotten() {
        let l = lattice();
        let dark = view(Isometry3::identity(), None, |_, _| f32::NAN);
        let mut o = observe(&l, &[&dark]);
        assert_eq!(o.unseen_count(), l.len());
        let dropped = o.drop_where(&l, |_, c| c[0] < 0.0);
        assert_eq!(dropped, l.len() / 2);
        let ball = Placed::new(
            &VolumeShape::Primitive(Primitive::Sphere { radius: 0.1 }),
            &Isometry3::translation(0.1, 0.0, 1.0),
        );
        let counts = o.drop_excluded(&l, &[ball]);
        assert!(counts[0] > 0);
        for i in 0..l.len() {
            let c = l.centre(i);
            let inside = (c[0] - 0.1).powi(2) + c[1].powi(2) + (c[2] - 1.0).powi(2) <= 0.01;
            assert_eq!(o.unseen[i], c[0] >= 0.0 && !inside, "cell {:?}", l.ijk(i));
        }
    }
}
