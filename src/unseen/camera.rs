//! A view's camera and pixel grid as the unseen-space tests read them, in f32: the pinhole
//! ([`Optics`]: intrinsics, range limits, the angle a pixel spans), a cone's half angle
//! ([`Cone`], by its sine and cosine), pixel rectangles ([`Rect`]), and where a cone about a
//! direction meets the image: its bounding window ([`window`]) and, row by row, its columns
//! ([`cone_row`], [`cone_span`]).
//!
//! **The window.** A direction within `α` of `p̂` lies on the image plane within
//! `α / cos²(φ + α)` of `p̂`'s point (`φ` the angle of `p` from the optical axis: the gnomonic
//! projection stretches by at most `1/cos²`), bounded above by `tan α`, widened by a pixel for
//! the rounding. **The rows.** The cone `(d̃·p)² ≥ k·|d̃|²` (`d̃ = (x, y, 1)`, `x = (u − cx)/fx`)
//! on one row is a quadratic in `x`: its roots bound the row's columns. Both are only bounds:
//! every pixel they give is still tested exactly.

/// The pixel's half diagonal, in pixels: a pixel is in a footprint when its whole area is.
const HALF_PIXEL: f32 = std::f32::consts::FRAC_1_SQRT_2;

/// A view's camera in f32, as the test reads it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Optics {
    pub width: usize,
    pub height: usize,
    pub fx: f32,
    pub fy: f32,
    pub cx: f32,
    pub cy: f32,
    /// Range limits (m, Euclidean): a ball nearer than `min_range_m` or beyond `max_range_m` is
    /// outside the view.
    pub min_range_m: f32,
    pub max_range_m: f32,
    /// The angle (rad) a pixel's half diagonal spans at most: `κ = √½ / min(fx, fy)`.
    pub pixel_angle: f32,
    /// `cos κ`, `sin κ`.
    cos_k: f32,
    sin_k: f32,
    /// The intrinsics in f64, for [`unit_ray`].
    camera: crate::cloud::depth::PinholeCamera,
}

/// A cone's half angle `α` as the tests use it: its sine and cosine; `tan α` bounds `α` from
/// above (a window from it is never too small).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Cone {
    pub sin: f32,
    pub cos: f32,
}

impl Cone {
    /// The cone of a sphere of radius `rho` seen from distance `l > rho`.
    #[inline]
    pub fn of_sphere(rho: f32, l: f32) -> Self {
        let s = (rho / l).min(1.0);
        Self {
            sin: s,
            cos: (1.0 - s * s).max(0.0).sqrt(),
        }
    }

    #[inline]
    pub fn tan(&self) -> f32 {
        self.sin / self.cos
    }
}

impl Optics {
    pub fn new(
        camera: &crate::cloud::depth::PinholeCamera,
        min_range_m: f32,
        max_range_m: f32,
    ) -> Self {
        let f = camera.fx.min(camera.fy) as f32;
        Self {
            width: camera.width as usize,
            height: camera.height as usize,
            fx: camera.fx as f32,
            fy: camera.fy as f32,
            cx: camera.cx as f32,
            cy: camera.cy as f32,
            min_range_m,
            max_range_m,
            pixel_angle: HALF_PIXEL / f,
            cos_k: (HALF_PIXEL / f).cos(),
            sin_k: (HALF_PIXEL / f).sin(),
            camera: *camera,
        }
    }

    /// Pixel `(u, v)`'s unit ray, as [`unit_ray`] gives it: the value the view's ray array holds
    /// there, computed instead of read (a read far from the last one misses the caches).
    #[inline]
    pub fn ray(&self, u: usize, v: usize) -> [f32; 3] {
        unit_ray(&self.camera, u, v)
    }

    /// `(cos κ, sin κ)`, as the GPU's copy of the test takes them (`shaders/cell.wgsl`).
    pub fn pixel_cos_sin(&self) -> (f32, f32) {
        (self.cos_k, self.sin_k)
    }

    /// The image point of camera-frame `p` (z > 0).
    #[inline]
    pub fn project(&self, p: [f32; 3]) -> (f32, f32) {
        (
            self.fx * p[0] / p[2] + self.cx,
            self.fy * p[1] / p[2] + self.cy,
        )
    }

    /// The footprint's half angle `asin(r/l) − κ` for a ball of radius `r` at distance `l`,
    /// `None` when no whole pixel fits in it (by the angle-difference formulas, no trigonometry).
    #[inline]
    pub fn footprint(&self, r: f32, l: f32) -> Option<Cone> {
        let ball = Cone::of_sphere(r, l);
        let sin = ball.sin * self.cos_k - ball.cos * self.sin_k;
        (sin > 0.0).then_some(Cone {
            sin,
            cos: ball.cos * self.cos_k + ball.sin * self.sin_k,
        })
    }
}

/// The unit ray through the centre of pixel `(u, v)` of `camera`, camera frame: computed in f64,
/// rounded once.
#[inline]
pub fn unit_ray(camera: &crate::cloud::depth::PinholeCamera, u: usize, v: usize) -> [f32; 3] {
    let x = (u as f64 - camera.cx) / camera.fx;
    let y = (v as f64 - camera.cy) / camera.fy;
    let n = (x * x + y * y + 1.0).sqrt();
    [(x / n) as f32, (y / n) as f32, (1.0 / n) as f32]
}

/// The unit tests' camera: 64 × 48 pixels, a focal length of 50 pixels, the principal point in
/// the middle.
#[cfg(test)]
pub(super) fn test_camera() -> crate::cloud::depth::PinholeCamera {
    crate::cloud::depth::PinholeCamera {
        width: 64,
        height: 48,
        fx: 50.0,
        fy: 50.0,
        cx: 31.5,
        cy: 23.5,
    }
}

/// An inclusive pixel rectangle.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Rect {
    pub u0: usize,
    pub v0: usize,
    pub u1: usize,
    pub v1: usize,
}

impl Rect {
    /// Every pixel of the image.
    pub fn whole(o: &Optics) -> Option<Rect> {
        Rect::covering(o, 0.0, o.width as f32, 0.0, o.height as f32)
    }

    /// The pixels whose centres lie in `[u_lo, u_hi] × [v_lo, v_hi]`, clipped to the image;
    /// `None` when none does.
    pub fn covering(o: &Optics, u_lo: f32, u_hi: f32, v_lo: f32, v_hi: f32) -> Option<Rect> {
        let (w, h) = ((o.width - 1) as f32, (o.height - 1) as f32);
        let (u0, u1) = (u_lo.ceil().max(0.0), u_hi.floor().min(w));
        let (v0, v1) = (v_lo.ceil().max(0.0), v_hi.floor().min(h));
        (u0 <= u1 && v0 <= v1).then_some(Rect {
            u0: u0 as usize,
            v0: v0 as usize,
            u1: u1 as usize,
            v1: v1 as usize,
        })
    }
}

/// The window about `(u, v)` of a cone `alpha` about a direction at `cos φ` from the optical
/// axis (see the module doc); the whole image when the cone reaches the image plane's horizon.
#[inline]
pub fn window(o: &Optics, u: f32, v: f32, cos_phi: f32, alpha: Cone) -> Option<Rect> {
    let Some(half) = half_window(cos_phi, alpha) else {
        return Rect::whole(o);
    };
    let (hu, hv) = (o.fx * half + 1.0, o.fy * half + 1.0);
    Rect::covering(o, u - hu, u + hu, v - hv, v + hv)
}

/// The half side, on the image plane at unit depth, of the window of a cone `alpha` about a
/// direction at `cos φ` from the optical axis: `tan α / c²`, `c = cos(φ + α)`. `None` when the
/// cone comes within `acos 0.05` of the image plane's horizon (no window bounds it).
#[inline]
pub fn half_window(cos_phi: f32, alpha: Cone) -> Option<f32> {
    let cos_phi = cos_phi.clamp(-1.0, 1.0);
    let sin_phi = (1.0 - cos_phi * cos_phi).sqrt();
    let c = cos_phi * alpha.cos - sin_phi * alpha.sin;
    (c > 0.05).then(|| alpha.tan() / (c * c))
}

/// The columns of row `v` (within `rect`) whose rays may lie in the cone `(d̃·p)² ≥ k·|d̃|²`
/// about camera-frame `p` (`k = (|p| cos α)²` for half angle `α`; `|p|² − ρ²` for the
/// silhouette of a sphere of radius `ρ`): the roots of that quadratic in `x = (u − cx)/fx` on
/// the row, widened by a pixel for the f32 sums; `None` where the row misses it. Every pixel
/// returned is still tested exactly.
#[inline]
pub fn cone_row(o: &Optics, p: [f32; 3], k: f32, v: usize, rect: Rect) -> Option<(usize, usize)> {
    let (lo, hi) = cone_span(o, p, k, v as f32)?;
    let lo = (lo - 1.0).floor().max(rect.u0 as f32);
    let hi = (hi + 1.0).ceil().min(rect.u1 as f32);
    (lo <= hi).then_some((lo as usize, hi as usize))
}

/// The image columns `u` where the row `v` meets the cone of [`cone_row`] (unrounded; −∞..∞
/// where the cone opens past the horizon along the row), `None` where it misses.
#[inline]
pub fn cone_span(o: &Optics, p: [f32; 3], k: f32, v: f32) -> Option<(f32, f32)> {
    let y = (v - o.cy) / o.fy;
    let b = y * p[1] + p[2];
    let qa = p[0] * p[0] - k;
    if qa.is_nan() || qa >= 0.0 {
        return Some((f32::NEG_INFINITY, f32::INFINITY));
    }
    let qb = 2.0 * p[0] * b;
    let qc = b * b - k * (y * y + 1.0);
    let disc = qb * qb - 4.0 * qa * qc;
    if disc.is_nan() || disc < 0.0 {
        return None;
    }
    let s = disc.sqrt();
    // qa < 0: the first root is the smaller.
    let x1 = (-qb + s) / (2.0 * qa);
    let x2 = (-qb - s) / (2.0 * qa);
    Some((o.fx * x1 + o.cx, o.fx * x2 + o.cx))
}
