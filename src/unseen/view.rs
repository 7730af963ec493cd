//! What one source saw, as the unseen-space pass reads it: a [`RangeView`] is the source's pinhole
//! pixel grid, its pose `root_from_camera` (the optical frame: z forward, x right, y down; f64),
//! per pixel the measured depth along z (f32 m; NaN for no return), and the source's range
//! noise and limits.
//!
//! A pixel has no return (NaN) when its depth is 0, NaN or infinite, or when its point lies
//! outside the source's range limits (`RangeLimits`, as the monitor drops such points): such a
//! pixel sees nothing along its whole ray. A return at depth `r` says the ray is free up to
//! `r − range_noise_m`, whether it hit the scene or the robot (`prepared` renders the robot to
//! tell why a ray stopped). A ball nearer than the minimum range is not judged by the view: the
//! limits travel with every view, an organized cloud's too.
//!
//! Three ways in: [`RangeView::new`] from depths the caller has (the tests' renderer);
//! [`RangeView::from_depth`] from a depth image, through `cloud::depth::DepthView` (the same
//! decoding and range limits as the points the query measures); [`RangeView::from_organized_cloud`]
//! from an organized cloud in its own optical frame, with the intrinsics fitted from its points
//! (`fit`). An unorganized cloud (height 1: a lidar's points without its scan pattern), or an
//! organized one that no pinhole camera fits, gives an error: such a source observes nothing
//! free, and the caller leaves it out of the views. One parallel pass over the pixels.

use nalgebra::Isometry3;
use rayon::prelude::*;
use wide::{f32x8, CmpGe, CmpGt, CmpLe, CmpLt};

use crate::cloud::depth::{DepthView, PinholeCamera};
use crate::cloud::RangeLimits;

use super::error::UnseenError;
use super::fit::{fit_pinhole, FitCheck, RowFit};

/// Default range noise (m): a return at `r` is taken to show free space up to `r − 0.02`.
/// A Kinect-class structured-light camera's depth noise is about 1.5 cm (1σ) at 3 m and grows
/// with the square of the range (Khoshelham & Elberink 2012); ToF cameras do better. 2 cm keeps
/// the cell at a surface unclaimed; it only ever moves a surface's own cells to unseen, and a
/// surface that returned is measured by the distance to the points anyway.
pub const DEFAULT_RANGE_NOISE_M: f64 = 0.02;

/// What one source saw: its pixel grid, pose, depths, range noise and limits.
#[derive(Debug, Clone, PartialEq)]
pub struct RangeView {
    camera: PinholeCamera,
    root_from_camera: Isometry3<f64>,
    ranges: Vec<f32>,
    min_range2: f32,
    max_range_m: f32,
    range_noise_m: f32,
}

impl RangeView {
    /// The view of `camera` at `root_from_camera` that measured `depths` (row-major, m along z;
    /// 0, NaN, ±∞ or outside `range`: no return).
    pub fn new(
        camera: PinholeCamera,
        root_from_camera: Isometry3<f64>,
        depths: &[f32],
        range: Option<RangeLimits>,
        range_noise_m: f64,
    ) -> Result<Self, UnseenError> {
        let w = camera.width as usize;
        check_count("depths", depths.len(), &camera)?;
        let (kx, ky) = (1.0 / camera.fx as f32, 1.0 / camera.fy as f32);
        let bounds = squared(range);
        let (cx, cy) = (camera.cx as f32, camera.cy as f32);
        let ranges = depths
            .par_iter()
            .enumerate()
            .map(|(i, &z)| {
                let p = [
                    ((i % w) as f32 - cx) * kx * z,
                    ((i / w) as f32 - cy) * ky * z,
                    z,
                ];
                keep(p, bounds)
            })
            .collect();
        Self::with_ranges(camera, root_from_camera, ranges, range, range_noise_m)
    }

    /// The view of a depth image: `depth` (checked against `camera` when it was made, with the
    /// source's range limits) decoded pixel by pixel as the query's points are.
    pub fn from_depth(
        depth: &DepthView,
        camera: &PinholeCamera,
        root_from_camera: Isometry3<f64>,
        range_noise_m: f64,
    ) -> Result<Self, UnseenError> {
        check_count("depth image pixels", depth.len(), camera)?;
        // `point` is NaN for no return and outside the limits; a 32FC1 depth of 0 is (0, 0, 0).
        let ranges = (0..depth.len())
            .into_par_iter()
            .map(|i| keep(depth.point(i), squared(None)))
            .collect();
        Self::with_ranges(
            *camera,
            root_from_camera,
            ranges,
            depth.range,
            range_noise_m,
        )
    }

    /// The view of an organized cloud: `points` (row-major `width × height`, in the cloud's
    /// optical frame, which `root_from_camera` places), the intrinsics fitted from them
    /// ([`super::fit::fit_pinhole`]), or `known` where it still fits every point
    /// ([`super::fit::FitCheck`], in the same pass as the depths: a source's camera does not
    /// change from frame to frame). An unorganized cloud, or one no pinhole camera fits, is an
    /// error: that source observes nothing free.
    pub fn from_organized_cloud(
        points: &[[f32; 3]],
        width: u32,
        height: u32,
        root_from_camera: Isometry3<f64>,
        range: Option<RangeLimits>,
        range_noise_m: f64,
        known: Option<&PinholeCamera>,
    ) -> Result<Self, UnseenError> {
        if width <= 1 || height <= 1 {
            return Err(UnseenError::Unorganized { width, height });
        }
        if points.len() as u64 != u64::from(width) * u64::from(height) {
            return Err(UnseenError::PixelCount {
                what: "cloud points",
                got: points.len(),
                width,
                height,
            });
        }
        // The depths, and where a camera is known whether it still fits, in one pass.
        let w = width as usize;
        let check = known.and_then(|c| FitCheck::new(c, width, height));
        let bounds = squared(range);
        let mut ranges = vec![0.0f32; points.len()];
        let rows = (ranges
            .par_chunks_mut(w)
            .zip(points.par_chunks(w))
            .enumerate())
        .map(|(v, (out, row))| {
            keep_row(row, bounds, out);
            check.map_or(RowFit::default(), |c| c.row(v, row))
        })
        .reduce(RowFit::default, RowFit::and);
        let camera = match check.and_then(|c| c.kept(rows)) {
            Some(kept) => kept,
            None => fit_pinhole(points, width, height)?,
        };
        Self::with_ranges(camera, root_from_camera, ranges, range, range_noise_m)
    }

    fn with_ranges(
        camera: PinholeCamera,
        root_from_camera: Isometry3<f64>,
        ranges: Vec<f32>,
        range: Option<RangeLimits>,
        range_noise_m: f64,
    ) -> Result<Self, UnseenError> {
        if !(range_noise_m.is_finite() && range_noise_m >= 0.0) {
            return Err(UnseenError::Length {
                parameter: "range_noise",
                value: range_noise_m,
                expected: "length ≥ 0",
            });
        }
        let (min2, max2) = range.map_or((0.0, f32::INFINITY), |r| r.squared());
        Ok(Self {
            camera,
            root_from_camera,
            ranges,
            min_range2: min2,
            max_range_m: max2.sqrt(),
            range_noise_m: range_noise_m as f32,
        })
    }

    pub fn camera(&self) -> &PinholeCamera {
        &self.camera
    }

    pub fn root_from_camera(&self) -> &Isometry3<f64> {
        &self.root_from_camera
    }

    /// Per pixel, the measured depth along z (m), NaN for no return.
    pub fn ranges(&self) -> &[f32] {
        &self.ranges
    }

    pub fn range_noise_m(&self) -> f32 {
        self.range_noise_m
    }

    /// The squared minimum range (m², 0 when none): a cell nearer the camera is not seen.
    pub fn min_range2(&self) -> f32 {
        self.min_range2
    }

    /// The maximum range (m, ∞ when none): no return lies beyond it.
    pub fn max_range_m(&self) -> f32 {
        self.max_range_m
    }
}

/// The squared range limits `(min², max²)` (m²; `(0, ∞)` without limits).
fn squared(range: Option<RangeLimits>) -> (f32, f32) {
    range.map_or((0.0, f32::INFINITY), |r| r.squared())
}

/// The depth of camera-frame point `p` if it is a return within the squared range limits
/// `(min², max²)`, else NaN (branch-free, so that a pass over the pixels runs as vectors).
#[inline]
fn keep(p: [f32; 3], (min2, max2): (f32, f32)) -> f32 {
    let [x, y, z] = p;
    let r2 = x * x + y * y + z * z;
    let returned = x.is_finite() & y.is_finite() & z.is_finite() & (z > 0.0);
    if returned & (r2 >= min2) & (r2 <= max2) {
        z
    } else {
        f32::NAN
    }
}

/// [`keep`] over a row of points into `out`, eight at a time (SIMD).
fn keep_row(row: &[[f32; 3]], (min2, max2): (f32, f32), out: &mut [f32]) {
    let (lo, hi, inf) = (
        f32x8::splat(min2),
        f32x8::splat(max2),
        f32x8::splat(f32::INFINITY),
    );
    let nan = f32x8::splat(f32::NAN);
    let mut chunks = row.chunks_exact(8);
    let mut outs = out.chunks_exact_mut(8);
    for (c, o) in (&mut chunks).zip(&mut outs) {
        let x = f32x8::from(std::array::from_fn::<f32, 8, _>(|i| c[i][0]));
        let y = f32x8::from(std::array::from_fn::<f32, 8, _>(|i| c[i][1]));
        let z = f32x8::from(std::array::from_fn::<f32, 8, _>(|i| c[i][2]));
        let r2 = x * x + y * y + z * z;
        // Finite: |·| < ∞ (false for NaN and ±∞).
        let kept = x.abs().cmp_lt(inf)
            & y.abs().cmp_lt(inf)
            & z.cmp_lt(inf)
            & z.cmp_gt(f32x8::ZERO)
            & r2.cmp_ge(lo)
            & r2.cmp_le(hi);
        o.copy_from_slice(&kept.blend(z, nan).to_array());
    }
    for (o, &p) in outs.into_remainder().iter_mut().zip(chunks.remainder()) {
        *o = keep(p, (min2, max2));
    }
}

fn check_count(what: &'static str, got: usize, camera: &PinholeCamera) -> Result<(), UnseenError> {
    if got as u64 == u64::from(camera.width) * u64::from(camera.height) {
        Ok(())
    } else {
        Err(UnseenError::PixelCount {
            what,
            got,
            width: camera.width,
            height: camera.height,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cloud::depth::{encode_depth, DepthEncoding};
    use crate::msg::Header;
    use proptest::prelude::*;

    /// A coordinate as clouds give them: finite, 0, NaN, ±∞, negative.
    fn coordinate() -> impl Strategy<Value = f32> {
        prop_oneof![
            6 => -3.0f32..3.0,
            1 => Just(0.0f32),
            1 => Just(f32::NAN),
            1 => Just(f32::INFINITY),
            1 => Just(f32::NEG_INFINITY),
        ]
    }

    proptest! {
        /// The row's vector form keeps what [`keep`] keeps, point by point, whatever the row's
        /// length (its tail past the last eight included).
        #[test]
        fn keep_row_is_keep(
            row in prop::collection::vec([coordinate(), coordinate(), coordinate()], 0..40),
            min in prop::sample::select(vec![0.0f32, 0.5, 1.0]),
            max in prop::sample::select(vec![2.0f32, 4.0, f32::INFINITY]),
        ) {
            let bounds = (min * min, max * max);
            let mut out = vec![0.0; row.len()];
            keep_row(&row, bounds, &mut out);
            for (p, o) in row.iter().zip(&out) {
                prop_assert_eq!(o.to_bits(), keep(*p, bounds).to_bits(), "{:?}", p);
            }
        }
    }

    fn camera() -> PinholeCamera {
        PinholeCamera {
            width: 4,
            height: 2,
            fx: 100.0,
            fy: 100.0,
            cx: 1.5,
            cy: 0.5,
        }
    }

    #[test]
    fn depth_images_decode_as_the_query_does() {
        let depths = [1.0, 0.0, f32::NAN, 2.5, 0.2, 7.0, 1.234, 3.0];
        for encoding in [DepthEncoding::Millimetres16, DepthEncoding::Metres32] {
            let image = encode_depth(Header::default(), 4, 2, &depths, encoding);
            let limits = RangeLimits::new(0.3, Some(5.0));
            let depth = DepthView::new(&image, &camera(), limits).unwrap();
            let view =
                RangeView::from_depth(&depth, &camera(), Isometry3::identity(), 0.02).unwrap();
            let r = view.ranges();
            assert!((r[0] - 1.0).abs() < 1e-6 && (r[6] - 1.234).abs() < 1e-3);
            // 0, NaN, nearer than 0.3 m and beyond 5 m: no return.
            for i in [1, 2, 4, 5] {
                assert!(r[i].is_nan(), "{encoding:?} pixel {i}: {}", r[i]);
            }
            assert!((view.min_range2() - 0.09).abs() < 1e-6 && view.max_range_m() == 5.0);
        }
    }

    #[test]
    fn bad_inputs_are_refused() {
        let id = Isometry3::identity();
        let e = RangeView::new(camera(), id, &[1.0; 7], None, 0.02).unwrap_err();
        assert!(e.to_string().contains("7 values for a 4×2"), "{e}");
        let e = RangeView::new(camera(), id, &[1.0; 8], None, -0.1).unwrap_err();
        assert!(e.to_string().contains("range_noise"), "{e}");
        let points = vec![[0.0, 0.0, 1.0]; 8];
        let e = RangeView::from_organized_cloud(&points, 8, 1, id, None, 0.02, None).unwrap_err();
        assert!(matches!(e, UnseenError::Unorganized { .. }));
    }

    #[test]
    fn organized_clouds_give_their_depths() {
        let points: Vec<[f32; 3]> = (0..200)
            .map(|i| {
                let (u, v, z) = ((i % 20) as f32, (i / 20) as f32, 2.0 + 0.01 * i as f32);
                if i == 5 {
                    [f32::NAN; 3]
                } else {
                    [(u - 9.5) / 30.0 * z, (v - 4.5) / 30.0 * z, z]
                }
            })
            .collect();
        let limits = RangeLimits::new(0.0, Some(3.5));
        let view_with = |known: Option<&PinholeCamera>| {
            RangeView::from_organized_cloud(
                &points,
                20,
                10,
                Isometry3::identity(),
                limits,
                0.02,
                known,
            )
            .unwrap()
        };
        let view = view_with(None);
        assert!((view.camera().fx - 30.0).abs() < 1e-3);
        assert!(view.ranges()[5].is_nan() && (view.ranges()[6] - 2.06).abs() < 1e-6);
        // The last rows lie beyond 3.5 m.
        assert!(view.ranges()[199].is_nan());
        // The camera of an earlier frame is kept where it fits, refitted where it does not.
        let kept = *view.camera();
        let tagged = PinholeCamera {
            cx: kept.cx + 0.2,
            ..kept
        };
        assert_eq!(
            view_with(Some(&tagged)).camera(),
            &tagged,
            "within half a pixel: kept"
        );
        let wrong = PinholeCamera { fx: 40.0, ..kept };
        let refit = view_with(Some(&wrong));
        assert!(
            (refit.camera().fx - 30.0).abs() < 1e-3,
            "{:?}",
            refit.camera()
        );
        let bits = |v: &RangeView| v.ranges().iter().map(|r| r.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&refit), bits(&view));
    }
}
