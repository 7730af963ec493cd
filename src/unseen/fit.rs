//! The pinhole intrinsics of an organized cloud, fitted from its own points: an organized
//! cloud (a depth camera's PointCloud2, `depth_image_proc`'s output) carries its pixel grid
//! but not its CameraInfo, and the free-space pass needs to know which pixel a cell falls on.
//!
//! Each valid point `(x, y, z)` (finite, `z > 0`) of pixel `(u, v)` satisfies, for a pinhole
//! camera in the cloud's optical frame, `u = fx·x/z + cx` and `v = fy·y/z + cy`: two
//! independent straight-line least-squares fits (`u` on `x/z`, `v` on `y/z`), in f64 with
//! centred sums. The fit is taken only when it is a camera: at least [`MIN_FIT_POINTS`]
//! valid points, positive finite focal lengths, and every valid point re-projected within
//! [`MAX_RESIDUAL_PX`] of its own pixel (a cloud moved into another frame, or one from a
//! lidar's rings, fails that and observes nothing free). Two passes over the points; a camera
//! fitted before is checked (`FitCheck`) in the view's own pass.

use wide::{f32x8, CmpGt, CmpLe, CmpLt};

use crate::cloud::depth::PinholeCamera;

use super::error::UnseenError;

/// The fewest valid points a fit is made from.
pub const MIN_FIT_POINTS: usize = 16;
/// The largest distance (pixels) between a valid point's projection and its own pixel: half a
/// pixel, so that the fitted camera puts every point on the pixel that measured it.
pub const MAX_RESIDUAL_PX: f64 = 0.5;

/// The pinhole camera whose pixel grid `width × height` the organized cloud `points`
/// (row-major, the cloud's own frame: z forward) was measured on.
pub fn fit_pinhole(
    points: &[[f32; 3]],
    width: u32,
    height: u32,
) -> Result<PinholeCamera, UnseenError> {
    let fail = |reason: String| UnseenError::NotPinhole {
        width,
        height,
        reason,
    };
    let w = width as usize;
    // (u, v, x/z, y/z) of every valid point.
    let samples = || {
        points.iter().enumerate().filter_map(move |(i, p)| {
            let valid = p.iter().all(|c| c.is_finite()) && p[2] > 0.0;
            valid.then(|| {
                let [x, y, z] = p.map(f64::from);
                ((i % w) as f64, (i / w) as f64, x / z, y / z)
            })
        })
    };
    let (mut n, mut sum) = (0usize, [0.0f64; 4]);
    for (u, v, a, b) in samples() {
        n += 1;
        for (s, x) in sum.iter_mut().zip([u, v, a, b]) {
            *s += x;
        }
    }
    if n < MIN_FIT_POINTS {
        return Err(fail(format!(
            "{n} valid points, fewer than {MIN_FIT_POINTS}"
        )));
    }
    let mean = sum.map(|s| s / n as f64);
    // Centred second moments: var(a), cov(a, u), var(b), cov(b, v).
    let mut m = [0.0f64; 4];
    for (u, v, a, b) in samples() {
        let (du, dv, da, db) = (u - mean[0], v - mean[1], a - mean[2], b - mean[3]);
        m[0] += da * da;
        m[1] += da * du;
        m[2] += db * db;
        m[3] += db * dv;
    }
    let fx = m[1] / m[0];
    let fy = m[3] / m[2];
    if !(fx.is_finite() && fx > 0.0 && fy.is_finite() && fy > 0.0) {
        return Err(fail(format!(
            "focal lengths {fx:.4} and {fy:.4} px (the points span one row or column, or are \
             not in an optical frame with z forward)"
        )));
    }
    let cx = mean[0] - fx * mean[2];
    let cy = mean[1] - fy * mean[3];
    let worst = samples()
        .map(|(u, v, a, b)| (fx * a + cx - u).abs().max((fy * b + cy - v).abs()))
        .fold(0.0f64, f64::max);
    if worst > MAX_RESIDUAL_PX {
        return Err(fail(format!(
            "a point re-projects {worst:.2} px from its pixel (at most {MAX_RESIDUAL_PX})"
        )));
    }
    Ok(PinholeCamera {
        width,
        height,
        fx,
        fy,
        cx,
        cy,
    })
}

/// Whether a camera puts every valid point of an organized cloud (row-major, the camera's pixel
/// grid) within [`MAX_RESIDUAL_PX`] of its own pixel: the check that lets a source keep the
/// intrinsics fitted from an earlier frame, no fit, made a row at a time in the view's own pass
/// over the points. f32 is exact to 1e-4 px here; the half-pixel test has room for it.
#[derive(Debug, Clone, Copy)]
pub struct FitCheck {
    camera: PinholeCamera,
    fx: f32,
    fy: f32,
    cx: f32,
    cy: f32,
}

/// What a check found over some rows: whether every valid point fits, and how many are valid.
#[derive(Debug, Clone, Copy)]
pub struct RowFit {
    ok: bool,
    valid: usize,
}

impl Default for RowFit {
    fn default() -> Self {
        Self { ok: true, valid: 0 }
    }
}

impl RowFit {
    /// Both together.
    pub fn and(self, other: Self) -> Self {
        Self {
            ok: self.ok && other.ok,
            valid: self.valid + other.valid,
        }
    }
}

impl FitCheck {
    /// The check of `camera` over a cloud of `width × height` points (`None` when that is not
    /// its pixel grid).
    pub fn new(camera: &PinholeCamera, width: u32, height: u32) -> Option<Self> {
        (camera.width > 0 && (camera.width, camera.height) == (width, height)).then_some(Self {
            camera: *camera,
            fx: camera.fx as f32,
            fy: camera.fy as f32,
            cx: camera.cx as f32,
            cy: camera.cy as f32,
        })
    }

    /// Row `v`'s points, eight at a time ([`FitCheck::eight`]); the last eight filled with
    /// points that did not return.
    #[inline]
    pub fn row(&self, v: usize, row: &[[f32; 3]]) -> RowFit {
        let (mut bad, mut valid) = (0u32, 0u32);
        let mut chunks = row.chunks_exact(8);
        for (k, c) in (&mut chunks).enumerate() {
            let (b, n) = self.eight(8 * k, v, c.try_into().expect("eight points"));
            (bad, valid) = (bad + b, valid + n);
        }
        let tail = chunks.remainder();
        if !tail.is_empty() {
            let c = std::array::from_fn(|i| tail.get(i).copied().unwrap_or([f32::NAN; 3]));
            let (b, n) = self.eight(row.len() - tail.len(), v, &c);
            (bad, valid) = (bad + b, valid + n);
        }
        RowFit {
            ok: bad == 0,
            valid: valid as usize,
        }
    }

    /// Pixels `u..u + 8` of row `v` (SIMD, no division: for `z > 0`, `|fx·x/z + cx − u| ≤ L`
    /// is `|fx·x + (cx − u)·z| ≤ L·z`): how many returned and do not fit, how many returned.
    #[inline(always)]
    fn eight(&self, u: usize, v: usize, c: &[[f32; 3]; 8]) -> (u32, u32) {
        let limit = f32x8::splat(MAX_RESIDUAL_PX as f32);
        let (zero, inf) = (f32x8::ZERO, f32x8::splat(f32::INFINITY));
        let lanes = f32x8::from([0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0]);
        let lane = |a: usize| f32x8::from(std::array::from_fn::<f32, 8, _>(|i| c[i][a]));
        let (x, y, z) = (lane(0), lane(1), lane(2));
        let dx = f32x8::splat(self.cx - u as f32) - lanes;
        let dy = f32x8::splat(self.cy - v as f32);
        // Finite: |·| < ∞ (false for NaN and ±∞).
        let returned = x.abs().cmp_lt(inf) & y.abs().cmp_lt(inf) & z.cmp_lt(inf) & z.cmp_gt(zero);
        let within = limit * z;
        let fits = (f32x8::splat(self.fx) * x + dx * z).abs().cmp_le(within)
            & (f32x8::splat(self.fy) * y + dy * z).abs().cmp_le(within);
        let bad = (returned & !fits).move_mask().count_ones();
        (bad, returned.move_mask().count_ones())
    }

    /// The camera, where it fits by every row's [`FitCheck::row`].
    pub fn kept(&self, rows: RowFit) -> Option<PinholeCamera> {
        (rows.ok && rows.valid >= MIN_FIT_POINTS).then_some(self.camera)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rayon::prelude::*;

    /// [`FitCheck`] over a whole cloud.
    fn fits(camera: &PinholeCamera, points: &[[f32; 3]]) -> bool {
        let pixels = camera.width as usize * camera.height as usize;
        let check = FitCheck::new(camera, camera.width, camera.height);
        let Some(check) = check.filter(|_| points.len() == pixels) else {
            return false;
        };
        let rows = (points.par_chunks(camera.width as usize).enumerate())
            .map(|(v, row)| check.row(v, row))
            .reduce(RowFit::default, RowFit::and);
        check.kept(rows).is_some()
    }

    /// The organized cloud a pinhole camera makes of a tilted plane, with holes.
    fn plane_cloud(c: &PinholeCamera) -> Vec<[f32; 3]> {
        let (w, h) = (c.width as usize, c.height as usize);
        (0..w * h)
            .map(|i| {
                let (u, v) = ((i % w) as f64, (i / w) as f64);
                if i % 7 == 3 {
                    return [f32::NAN; 3];
                }
                let z = 1.5 + 0.002 * u - 0.001 * v;
                [
                    ((u - c.cx) / c.fx * z) as f32,
                    ((v - c.cy) / c.fy * z) as f32,
                    z as f32,
                ]
            })
            .collect()
    }

    /// Row `v`'s check point by point, in f64: each returned point projected within
    /// [`MAX_RESIDUAL_PX`] of its pixel.
    fn row_by_points(c: &PinholeCamera, v: usize, row: &[[f32; 3]]) -> RowFit {
        let (mut ok, mut valid) = (true, 0);
        for (u, p) in row.iter().enumerate() {
            let [x, y, z] = p.map(f64::from);
            if !(p.iter().all(|c| c.is_finite()) && z > 0.0) {
                continue;
            }
            valid += 1;
            let du = (c.fx * x / z + c.cx - u as f64).abs();
            let dv = (c.fy * y / z + c.cy - v as f64).abs();
            ok &= du <= MAX_RESIDUAL_PX && dv <= MAX_RESIDUAL_PX;
        }
        RowFit { ok, valid }
    }

    proptest::proptest! {
        /// The row's vector form (eight points at a time, no division) counts the returned
        /// points and finds a misfit as the check point by point in f64 does, for rows of any
        /// length; points moved off their pixels by a residual of 0–1.5 px, some not returned.
        #[test]
        fn the_rows_vector_check_is_the_pointwise_one(
            seed in 1u64..,
            width in 1usize..40,
            v in 0usize..30,
        ) {
            let c = PinholeCamera { width: width as u32, height: 30, fx: 300.0, fy: 310.0, cx: 20.5, cy: 14.5 };
            let mut state = seed;
            let mut next = move || {
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                (state >> 11) as f64 / (1u64 << 53) as f64
            };
            let row: Vec<[f32; 3]> = (0..width)
                .map(|u| {
                    let z = 0.5 + 3.0 * next();
                    match (next() * 10.0) as u32 {
                        0 => [f32::NAN; 3],
                        1 => [0.0, 0.0, -z as f32],
                        2 => [f32::INFINITY, 0.0, z as f32],
                        _ => {
                            // A residual well within, or far from the border of, half a pixel.
                            let r = if next() < 0.8 { 0.4 * next() } else { 0.6 + next() };
                            let (du, dv) = if next() < 0.5 { (r, 0.0) } else { (0.0, r) };
                            [
                                ((u as f64 + du - c.cx) / c.fx * z) as f32,
                                ((v as f64 + dv - c.cy) / c.fy * z) as f32,
                                z as f32,
                            ]
                        }
                    }
                })
                .collect();
            let check = FitCheck::new(&c, c.width, c.height).unwrap();
            let got = check.row(v, &row);
            let want = row_by_points(&c, v, &row);
            proptest::prop_assert_eq!((got.ok, got.valid), (want.ok, want.valid));
        }
    }

    #[test]
    fn a_pinhole_clouds_intrinsics_are_found() {
        let c = PinholeCamera {
            width: 64,
            height: 48,
            fx: 60.0,
            fy: 61.5,
            cx: 31.7,
            cy: 24.2,
        };
        let f = fit_pinhole(&plane_cloud(&c), 64, 48).unwrap();
        assert!((f.fx - c.fx).abs() < 1e-3 && (f.fy - c.fy).abs() < 1e-3);
        assert!((f.cx - c.cx).abs() < 1e-3 && (f.cy - c.cy).abs() < 1e-3);
        // Kept for the next frame: it fits; another camera's does not.
        assert!(fits(&f, &plane_cloud(&c)));
        let wider = PinholeCamera { fx: 58.0, ..f };
        assert!(!fits(&wider, &plane_cloud(&c)));
    }

    #[test]
    fn clouds_that_are_no_camera_are_refused() {
        let c = PinholeCamera {
            width: 16,
            height: 8,
            fx: 20.0,
            fy: 20.0,
            cx: 8.0,
            cy: 4.0,
        };
        let good = plane_cloud(&c);
        // Too few valid points.
        let few: Vec<[f32; 3]> = good
            .iter()
            .enumerate()
            .map(|(i, p)| if i < 10 { *p } else { [f32::NAN; 3] })
            .collect();
        assert!(fit_pinhole(&few, 16, 8)
            .unwrap_err()
            .to_string()
            .contains("fewer than"));
        // The same points in a frame with x forward.
        let turned: Vec<[f32; 3]> = good.iter().map(|p| [p[2], -p[0], -p[1]]).collect();
        assert!(fit_pinhole(&turned, 16, 8).is_err());
        // Shuffled rows: points off their pixels.
        let mut shuffled = good.clone();
        shuffled.swap(20, 100);
        shuffled.swap(21, 60);
        let e = fit_pinhole(&shuffled, 16, 8).unwrap_err().to_string();
        assert!(e.contains("re-projects"), "{e}");
    }
}
