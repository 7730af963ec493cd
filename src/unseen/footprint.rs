//! Step 2, the footprint test: whether one view rules out a ball of the detection capability
//! at a lattice centre, and if not, why not.
//!
//! **The rule.** A solid body that holds the ball `B = B(x, r)` stops every pixel ray that
//! meets `B` at or before the point where the ray enters `B`: the camera returns that surface,
//! or nothing (a dark body), or something in front of it. So `B` is ruled out as soon as **one**
//! ray through it returned beyond its entry point: the ray passed through free space where the
//! body would have been. Every ray whose whole pixel lies inside `B`'s silhouette is tested, so
//! a 70 mm body 1.2 m from a 320 × 240 camera is judged by some 50 pixels, not by the 4 around
//! its centre, and a few dropped pixels do not keep it.
//!
//! **In numbers** (camera frame, `p` the ball's centre at distance `l = |p|`, a pixel's unit
//! ray `d` with `proj = d·p`, `perp² = l² − proj²`):
//! - the pixel is in the **footprint** when the angle between `d` and `p` is at most
//!   `asin(r/l) − κ/f` (`κ = √½`, the half diagonal of a pixel, `f` the smaller focal length:
//!   the pixel's whole area lies in the ball's cone, so a pixel half on the ball and half on a
//!   far background, which may return the background, is left out). Then `proj ≥ l·cos α`;
//! - the ray enters `B` at `t_in = proj − √(r² − perp²)`, and `t_in ≥ l − r` on every ray
//!   through `B` (its least value, on the ray through the centre);
//! - the pixel's **free distance** `g` is its depth less the range noise, along the ray
//!   (`(z − noise)·|d̃|`, `d̃ = ((u − cx)/fx, (v − cy)/fy, 1)`), less [`ROUNDING_M`]; no return is
//!   `−1`;
//! - the ball is ruled out by the pixel when `g > t_in`: `g ≥ proj`, or `(proj − g)² < r² −
//!   perp²`, no square root.
//!
//! **Why it stays hidden.** A ray that does not rule the ball out met, before the ball, the
//! robot (its padded spheres, rendered into the view: `prepared`), or returned a surface in front
//! (another body's shadow), or returned nothing. A ball is in the **robot's shadow** in a view
//! when more than half its footprint's rays met the robot first, so that pixels the arm's own
//! shiny surfaces or its outline drop do not take the shadow apart; otherwise its cause is the
//! larger of the other two. A ball whose centre's pixel lies outside the image, behind the
//! camera, nearer than the minimum range or beyond the maximum range, or too far for a whole
//! pixel to lie inside it, is **outside** the view.
//!
//! **The order of the tests**, each a shortcut that never changes the verdict of the full scan:
//! the pixel nearest the centre's projection (one read, its ray computed: it rules out most
//! free space); then, with the view's pyramids and where that pixel lies in the footprint (a
//! footprint that holds no pixel's ray is outside the view), the window's largest free
//! distance against `l − r` (a ball behind a surface is hidden whatever the pixels, with
//! [`ROUNDING_M`] to spare for the f32 sums) and the robot's; then the scan of the window,
//! every pixel tested exactly, which stops at the first ray that rules the ball out. Where only
//! the verdict is asked (the search, the shadow counted), the scan goes by **tiles**
//! (`tiles`), the free pyramid's texels about a quarter of the window's side: a tile whose
//! largest free distance is at most `l − r` is skipped whole, and
//! one wholly inside the footprint (its corners' rays in the cone: the cone's trace on the
//! image is convex) whose largest free distance reaches `l` rules the ball out at once (that
//! pixel passes `l ≥ d·p`); only the other tiles' pixels are tested
//! (`the_shortcuts_agree_with_the_scan`: every need, with and without the pyramids).
//!
//! The window is the footprint's bounding box, and each of its rows is scanned only over the
//! columns the footprint's cone meets (`camera`).
//!
//! Cost: one read for free space; for a ball at a surface, a few dozen texel reads and the
//! pixels of the tiles a surface crosses (the Kinect frame's search: 3.1–3.3 → 2.4–2.5 ms,
//! docs/unobserved.md); `O(footprint)` reads where the cause is asked.
//! `shaders/unseen.wgsl` runs the same scan per lattice centre on the GPU.

use super::camera::{cone_row, window, Cone, Optics, Rect};
use super::pyramid::{Pyramid, Pyramids};
use super::tiles::Tiles;

/// What the f32 sums may lose (m): a free distance is taken this much shorter, and the
/// shortcuts keep this much to spare, so that they agree with the full scan.
pub const ROUNDING_M: f32 = 1e-4;

/// A footprint of at least this many pixel angles (`sin α ≥ PAIR·κ`, `α ≥ 2.12 κ = 1.5/f`)
/// holds, with each whole, the 2 × 2 pixels whose centres surround a projection within it.
pub const PAIR: f32 = 2.12;

/// Why a view did not rule a ball out.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Cause {
    /// Its centre projects outside the image, lies behind the camera, nearer than its minimum
    /// range or beyond its maximum, or too far for a whole pixel to fit in the ball.
    OutsideView,
    /// More than half its footprint's rays met the robot first.
    RobotShadow,
    /// Its footprint's rays returned a surface in front of it: another body's shadow.
    Occluded,
    /// Its footprint's rays returned nothing (dark, glare, dropped pixels).
    NoReturn,
}

impl Cause {
    pub const ALL: [Cause; 4] = [
        Cause::OutsideView,
        Cause::RobotShadow,
        Cause::Occluded,
        Cause::NoReturn,
    ];

    /// The name in diagnostics and docs.
    pub fn name(self) -> &'static str {
        match self {
            Cause::OutsideView => "outside_every_view",
            Cause::RobotShadow => "robot_shadow",
            Cause::Occluded => "another_body_shadow",
            Cause::NoReturn => "no_return",
        }
    }
}

/// How much of "why" a caller needs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Need {
    /// Free or not (a hidden ball's cause may stay [`Why::Unknown`], `OutsideView` excepted).
    Verdict,
    /// Also whether it is the robot's shadow ([`Why::NotShadow`] where it is not).
    Shadow,
    /// The cause itself.
    Cause,
}

/// What a hidden ball's view says of it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Why {
    Known(Cause),
    /// Hidden, not the robot's shadow: occluded or no return, not told apart.
    NotShadow,
    /// Hidden, not classified (`Need::Verdict`).
    Unknown,
}

/// A view's verdict on one ball.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Seen {
    Free,
    Hidden(Why),
}

/// One view's pixels as the test reads them (row-major, `width × height`).
#[derive(Clone, Copy)]
pub struct Pixels<'a> {
    /// Each pixel's unit ray (camera frame).
    pub rays: &'a [[f32; 3]],
    /// Each pixel's free distance along its ray (m; −1: no return).
    pub free: &'a [f32],
    /// The distance along each ray to the padded robot (m; ∞: the ray misses it).
    pub robot: &'a [f32],
}

/// A ball of radius `r` at camera-frame `p`, as one view tests it.
pub struct Ball {
    pub p: [f32; 3],
    pub r: f32,
    l2: f32,
    l: f32,
    min_proj: f32,
    s2_max: f32,
}

/// One pixel's word on a ball.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Ray {
    Outside,
    Free,
    Robot,
    Returned,
    Dark,
}

impl Ball {
    #[inline]
    fn ray(&self, px: &Pixels, q: usize) -> Ray {
        self.ray_along(px, q, px.rays[q])
    }

    /// Whether pixel `q`'s ray rules the ball out: [`Ball::ray`] is `Ray::Free`, without asking
    /// why not where it is not.
    #[inline]
    fn rules_out(&self, px: &Pixels, q: usize) -> bool {
        self.through(px.rays[q])
            .is_some_and(|(proj, s2)| passes(proj, s2, px.free[q]))
    }

    /// Along unit ray `d`: its projection on the centre and `r² − perp²`, where its pixel lies
    /// in the footprint and the ray meets the ball (`None`: outside).
    #[inline]
    fn through(&self, d: [f32; 3]) -> Option<(f32, f32)> {
        let proj = d[0] * self.p[0] + d[1] * self.p[1] + d[2] * self.p[2];
        if proj < self.min_proj {
            return None;
        }
        let s2 = self.s2_max - (self.l2 - proj * proj).max(0.0);
        (s2 > 0.0).then_some((proj, s2))
    }

    /// [`Ball::ray`] with pixel `q`'s unit ray `d` given.
    #[inline]
    fn ray_along(&self, px: &Pixels, q: usize, d: [f32; 3]) -> Ray {
        let Some((proj, s2)) = self.through(d) else {
            return Ray::Outside;
        };
        let g = px.free[q];
        if passes(proj, s2, g) {
            return Ray::Free;
        }
        if px.robot[q] <= proj - s2.sqrt() {
            Ray::Robot
        } else if g >= 0.0 {
            Ray::Returned
        } else {
            Ray::Dark
        }
    }
}

/// Whether a ray with free distance `g` passes the entry `proj − √s2` into the ball: `g ≥ proj`,
/// or `(proj − g)² < s2` (no square root).
#[inline]
fn passes(proj: f32, s2: f32, g: f32) -> bool {
    let diff = proj - g;
    g >= proj || diff * diff < s2
}

/// A ball the view may see: its centre's distance (and square), its footprint's half angle,
/// its centre's projection and the pixel nearest it.
pub struct InView {
    pub l2: f32,
    pub l: f32,
    pub alpha: Cone,
    pub u: f32,
    pub v: f32,
    pub centre: usize,
    /// That pixel's column and row.
    pub pixel: (usize, usize),
}

/// The ball of radius `r` at camera-frame `p` where the view may see it; `None` where it is
/// outside the view whatever the pixels: behind the camera, nearer than the minimum range or
/// beyond the maximum, too far for a whole pixel, its centre projecting outside the image.
#[inline]
pub fn in_view(o: &Optics, p: [f32; 3], r: f32) -> Option<InView> {
    let l2 = p[0] * p[0] + p[1] * p[1] + p[2] * p[2];
    let l = l2.sqrt();
    if p[2].is_nan() || p[2] <= r || l - r < o.min_range_m || l - r > o.max_range_m {
        return None;
    }
    let alpha = o.footprint(r, l)?;
    let (u, v) = o.project(p);
    let (uc, vc) = ((u + 0.5).floor(), (v + 0.5).floor());
    if !(uc >= 0.0 && vc >= 0.0 && uc < o.width as f32 && vc < o.height as f32) {
        return None;
    }
    Some(InView {
        l2,
        l,
        alpha,
        u,
        v,
        centre: vc as usize * o.width + uc as usize,
        pixel: (uc as usize, vc as usize),
    })
}

/// Whether the view (`o`, `px`, with its `pyramids` where given) rules out the ball of radius
/// `r` at camera-frame `p`, and why not, to the depth `need` asks (see the module doc).
pub fn judge(
    o: &Optics,
    px: &Pixels,
    pyramids: Option<&Pyramids>,
    p: [f32; 3],
    r: f32,
    need: Need,
) -> Seen {
    const OUTSIDE: Seen = Seen::Hidden(Why::Known(Cause::OutsideView));
    let Some(InView {
        l2,
        l,
        alpha,
        u,
        v,
        centre,
        pixel,
    }) = in_view(o, p, r)
    else {
        return OUTSIDE;
    };
    let ball = Ball {
        p,
        r,
        l2,
        l,
        min_proj: l * alpha.cos,
        s2_max: r * r,
    };
    // 1. The pixel nearest the centre's projection (its ray computed: the first read of a
    // centre's pixels is one far from the last centre's).
    let central = ball.ray_along(px, centre, o.ray(pixel.0, pixel.1));
    if central == Ray::Free {
        return Seen::Free;
    }
    // 1b. The 2 × 2 pixels about the projection, each within √2 pixels of it: where the
    // footprint holds them all, their largest free distance beyond the centre rules the ball
    // out (a dropped pixel among them does not keep it).
    if let Some(pyr) = pyramids {
        let (ua, va) = (u.floor(), v.floor());
        let holds = alpha.sin >= PAIR * o.pixel_angle;
        let inside = ua >= 0.0 && va >= 0.0 && ua < o.width as f32 && va < o.height as f32;
        if holds && inside && pyr.pairs.at(ua as usize, va as usize) >= ball.l + ROUNDING_M {
            return Seen::Free;
        }
    }
    let Some(rect) = window(o, u, v, p[2] / l, alpha) else {
        return OUTSIDE;
    };
    // 2. The pyramids: no ray of the window passes the ball's nearest entry. Only where the
    // footprint is known to hold a ray (the central pixel's): one that holds none is outside
    // the view, as the scan finds.
    if let Some(pyr) = pyramids.filter(|_| central != Ray::Outside) {
        let entry = ball.l - ball.r - ROUNDING_M;
        if pyr.free.max(rect) <= entry {
            if need == Need::Verdict {
                return Seen::Hidden(Why::Unknown);
            }
            if pyr.robot.max(rect) <= entry {
                return Seen::Hidden(Why::Known(Cause::RobotShadow));
            }
            if need == Need::Shadow && pyr.robot.min(rect) > ball.l + ball.r {
                return Seen::Hidden(Why::NotShadow);
            }
        }
    }
    // 3. The scan: for the verdict alone, by tiles where the pyramids are given and the
    // footprint is known to hold a ray; else pixel by pixel.
    let tiles = pyramids.filter(|_| need == Need::Verdict && central != Ray::Outside);
    if let Some(ruled_out) = tiles.and_then(|pyr| by_tiles(px, &pyr.free, &ball, rect)) {
        // The footprint holds the central pixel's ray, which does not rule the ball out.
        return if ruled_out {
            Seen::Free
        } else {
            Seen::Hidden(Why::Unknown)
        };
    }
    match scan(o, px, &ball, rect) {
        Some(counts) => hidden(counts, need),
        None => Seen::Free,
    }
}

/// A hidden ball's rays that met the robot first, returned a surface in front, returned
/// nothing.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
struct Counts {
    robot: u32,
    returned: u32,
    dark: u32,
}

impl Counts {
    fn add(&mut self, ray: Ray) {
        match ray {
            Ray::Robot => self.robot += 1,
            Ray::Returned => self.returned += 1,
            Ray::Dark => self.dark += 1,
            Ray::Outside | Ray::Free => {}
        }
    }
}

/// The verdict on a ball no ray rules out, from its footprint's `counts`.
fn hidden(counts: Counts, need: Need) -> Seen {
    let Counts {
        robot,
        returned,
        dark,
    } = counts;
    let why = if robot + returned + dark == 0 {
        // The footprint holds no pixel centre in f32 (a sliver at the image's border).
        Why::Known(Cause::OutsideView)
    } else if need == Need::Verdict {
        Why::Unknown
    } else if 2 * robot > robot + returned + dark {
        Why::Known(Cause::RobotShadow)
    } else if need == Need::Shadow {
        Why::NotShadow
    } else if dark >= returned {
        Why::Known(Cause::NoReturn)
    } else {
        Why::Known(Cause::Occluded)
    };
    Seen::Hidden(why)
}

/// Whether a ray rules the ball out, by the tiles of the `free` pyramid (`tiles`); `None`
/// where the window is too small for tiles.
fn by_tiles(px: &Pixels, free: &Pyramid, ball: &Ball, rect: Rect) -> Option<bool> {
    let inner = ball.min_proj + 1e-4 * ball.l;
    let p = ball.p;
    let tiles = Tiles {
        free,
        rect,
        entry: ball.l - ball.r - ROUNDING_M,
        beyond: ball.l + ROUNDING_M,
    };
    tiles.rule_out(
        |q| {
            let d = px.rays[q];
            d[0] * p[0] + d[1] * p[1] + d[2] * p[2] >= inner
        },
        |q| ball.rules_out(px, q),
    )
}

/// Every pixel of `rect` tested against `ball` (see [`judge`]): `None` at the first ray that
/// rules it out, else the footprint's counts.
fn scan(o: &Optics, px: &Pixels, ball: &Ball, rect: Rect) -> Option<Counts> {
    let mut counts = Counts::default();
    let k = ball.min_proj * ball.min_proj;
    // Rows from the centre's outward: the rays through the middle enter the ball first, and
    // rule it out first where anything does.
    let (first, last) = (rect.v0 as isize, rect.v1 as isize);
    let middle = ((ball.p[1] / ball.p[2] * o.fy + o.cy).round() as isize).clamp(first, last);
    let rows = (0..=2 * (last - first)).map(|k| {
        let step = (k + 1) / 2;
        if k % 2 == 1 {
            middle - step
        } else {
            middle + step
        }
    });
    for v in rows
        .filter(|v| (first..=last).contains(v))
        .map(|v| v as usize)
    {
        let Some((u0, u1)) = cone_row(o, ball.p, k, v, rect) else {
            continue;
        };
        let row = v * o.width;
        for u in u0..=u1 {
            match ball.ray(px, row + u) {
                Ray::Free => return None,
                ray => counts.add(ray),
            }
        }
    }
    Some(counts)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cloud::depth::PinholeCamera;

    fn optics() -> Optics {
        Optics::new(&super::super::camera::test_camera(), 0.0, f32::INFINITY)
    }

    /// A test image's unit rays, free distances and robot image, owned.
    struct Image {
        rays: Vec<[f32; 3]>,
        free: Vec<f32>,
        robot: Vec<f32>,
    }

    impl Image {
        fn px(&self) -> Pixels<'_> {
            Pixels {
                rays: &self.rays,
                free: &self.free,
                robot: &self.robot,
            }
        }
    }

    /// Unit rays, free distances for depth `z(u, v)` (NaN: no return) and a robot image.
    fn pixels(
        o: &Optics,
        z: impl Fn(usize, usize) -> f32,
        robot: impl Fn(usize, usize) -> f32,
    ) -> Image {
        let mut image = Image {
            rays: Vec::new(),
            free: Vec::new(),
            robot: Vec::new(),
        };
        for v in 0..o.height {
            for u in 0..o.width {
                // The view's rays (`prepared::unit_rays`), which the central pixel's test
                // computes again.
                let d = o.ray(u, v);
                let n = 1.0 / d[2];
                image.rays.push(d);
                let depth = z(u, v);
                image.free.push(if depth.is_nan() {
                    -1.0
                } else {
                    depth * n - ROUNDING_M
                });
                image.robot.push(robot(u, v));
            }
        }
        image
    }

    /// The image's pyramids, as `prepared` builds them.
    fn pyramids(o: &Optics, image: &Image) -> Pyramids {
        let (w, h) = (o.width, o.height);
        let mut p = Pyramids::default();
        p.free.base_mut(w, h).copy_from_slice(&image.free);
        p.robot.base_mut(w, h).copy_from_slice(&image.robot);
        let pairs = p.pairs.base_mut(w, h);
        for v in 0..h {
            for u in 0..w {
                let at = |du: usize, dv: usize| {
                    image.free[(v + dv).min(h - 1) * w + (u + du).min(w - 1)]
                };
                pairs[v * w + u] = at(0, 0).max(at(1, 0)).max(at(0, 1)).max(at(1, 1));
            }
        }
        for pyramid in [&mut p.free, &mut p.pairs, &mut p.robot] {
            pyramid.build();
        }
        p
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig { cases: 64, .. proptest::prelude::ProptestConfig::default() })]

        /// The shortcuts (the pyramids, the tiles) never change a verdict: over scenes of
        /// boxes at random depths in front of a wall, the robot in front of some, clusters of
        /// dropped pixels, and balls anywhere in view from a pixel across to a third of the
        /// image, every need gets what the scan of every pixel gives.
        #[test]
        fn the_shortcuts_agree_with_the_scan(seed in proptest::prelude::any::<u64>()) {
            let mut state = seed | 1;
            let mut next = move || {
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                (state >> 11) as f32 / (1u64 << 53) as f32
            };
            let camera = PinholeCamera {
                width: 64 + (next() * 96.0) as u32,
                height: 48 + (next() * 64.0) as u32,
                fx: f64::from(40.0 + next() * 80.0),
                fy: f64::from(40.0 + next() * 80.0),
                cx: 40.0,
                cy: 30.0,
            };
            let o = Optics::new(&camera, 0.0, f32::INFINITY);
            let wall = 1.0 + 2.0 * next();
            // Boxes: (u0, v0, u1, v1, depth, robot).
            let boxes: Vec<[f32; 6]> = (0..6)
                .map(|_| {
                    let (u, v) = (next() * o.width as f32, next() * o.height as f32);
                    let (a, b) = (4.0 + next() * 30.0, 4.0 + next() * 30.0);
                    [u, v, u + a, v + b, 0.3 + next() * wall, next()]
                })
                .collect();
            let holes: Vec<[f32; 3]> = (0..12)
                .map(|_| [next() * o.width as f32, next() * o.height as f32, 1.0 + next() * 6.0])
                .collect();
            let depth = |u: usize, v: usize| {
                let (x, y) = (u as f32, v as f32);
                if holes.iter().any(|h| (x - h[0]).powi(2) + (y - h[1]).powi(2) < h[2] * h[2]) {
                    return f32::NAN;
                }
                (boxes.iter())
                    .filter(|b| x >= b[0] && x <= b[2] && y >= b[1] && y <= b[3])
                    .map(|b| b[4])
                    .fold(wall, f32::min)
            };
            let robot = |u: usize, v: usize| {
                let (x, y) = (u as f32, v as f32);
                (boxes.iter())
                    .filter(|b| b[5] < 0.3 && x >= b[0] && x <= b[2] && y >= b[1] && y <= b[3])
                    .map(|b| b[4] - 0.01)
                    .fold(f32::INFINITY, f32::min)
            };
            let image = pixels(&o, depth, robot);
            let pyr = pyramids(&o, &image);
            let px = image.px();
            for k in 0..300 {
                let across = 0.5 + next() * 40.0;
                let (u, v, z) = if k % 2 == 0 {
                    let z = 0.2 + next() * (wall + 0.5);
                    (next() * o.width as f32, next() * o.height as f32, z)
                } else {
                    // About a box's edge, its surface through the ball.
                    let b = boxes[k % boxes.len()];
                    let (u, v) = (b[0] + (b[2] - b[0]) * (1.4 * next() - 0.2), b[1] + (b[3] - b[1]) * (1.4 * next() - 0.2));
                    let r = b[4] * across / o.fx;
                    (u, v, b[4] + (2.0 * next() - 1.0) * 1.2 * r)
                };
                let p = [(u - o.cx) / o.fx * z, (v - o.cy) / o.fy * z, z];
                let r = z * across / o.fx;
                for need in [Need::Verdict, Need::Shadow, Need::Cause] {
                    let fast = judge(&o, &px, Some(&pyr), p, r, need);
                    let full = judge(&o, &px, None, p, r, need);
                    proptest::prop_assert_eq!(fast, full, "ball {:?} r {} {:?}", p, r, need);
                }
            }
        }
    }

    #[test]
    fn a_wall_behind_rules_out_a_ball_and_one_in_front_hides_it() {
        let o = optics();
        let image = pixels(&o, |_, _| 2.0, |_, _| f32::INFINITY);
        let px = image.px();
        // A 3 cm ball at 1 m: the wall at 2 m passes through it.
        assert_eq!(
            judge(&o, &px, None, [0.0, 0.0, 1.0], 0.03, Need::Cause),
            Seen::Free
        );
        // A ball just behind the wall: hidden by another body.
        assert_eq!(
            judge(&o, &px, None, [0.0, 0.0, 2.15], 0.1, Need::Cause),
            Seen::Hidden(Why::Known(Cause::Occluded))
        );
        // A 3 cm ball there is under a pixel wide at f = 50 px: too far for this view.
        assert_eq!(
            judge(&o, &px, None, [0.0, 0.0, 2.05], 0.03, Need::Cause),
            Seen::Hidden(Why::Known(Cause::OutsideView))
        );
        // A ball touching the wall from the front: its central rays pass its entry point.
        assert_eq!(
            judge(&o, &px, None, [0.0, 0.0, 1.9], 0.1, Need::Cause),
            Seen::Free
        );
        // Behind the camera, or projecting outside the image.
        for p in [[0.0, 0.0, -1.0], [5.0, 0.0, 1.0]] {
            assert_eq!(
                judge(&o, &px, None, p, 0.03, Need::Cause),
                Seen::Hidden(Why::Known(Cause::OutsideView))
            );
        }
    }

    #[test]
    fn dropped_pixels_do_not_keep_a_ball_a_dark_disc_does() {
        let o = optics();
        // Every other pixel dropped, in a checkerboard: each footprint keeps returns.
        let image = pixels(
            &o,
            |u, v| if (u + v) % 2 == 0 { f32::NAN } else { 2.0 },
            |_, _| f32::INFINITY,
        );
        let px = image.px();
        assert_eq!(
            judge(&o, &px, None, [0.0, 0.0, 1.0], 0.05, Need::Cause),
            Seen::Free
        );
        // A disc of 12 pixels' radius about the centre returns nothing.
        let image = pixels(
            &o,
            |u, v| {
                let (du, dv) = (u as f32 - 31.5, v as f32 - 23.5);
                if du * du + dv * dv < 144.0 {
                    f32::NAN
                } else {
                    2.0
                }
            },
            |_, _| f32::INFINITY,
        );
        let px = image.px();
        assert_eq!(
            judge(&o, &px, None, [0.0, 0.0, 1.0], 0.05, Need::Cause),
            Seen::Hidden(Why::Known(Cause::NoReturn))
        );
        assert_eq!(
            judge(&o, &px, None, [0.0, 0.0, 1.0], 0.05, Need::Verdict),
            Seen::Hidden(Why::Unknown)
        );
    }

    #[test]
    fn the_robot_in_front_makes_its_shadow() {
        let o = optics();
        // The robot's padded body 0.8 m along every central ray; its surface returned at 0.8 m.
        let near = |u: usize, v: usize| (u as i32 - 32).abs() < 15 && (v as i32 - 24).abs() < 15;
        let image = pixels(
            &o,
            |u, v| if near(u, v) { 0.8 } else { 2.0 },
            |u, v| if near(u, v) { 0.8 } else { f32::INFINITY },
        );
        let px = image.px();
        let behind = [0.0, 0.0, 1.2];
        assert_eq!(
            judge(&o, &px, None, behind, 0.05, Need::Cause),
            Seen::Hidden(Why::Known(Cause::RobotShadow))
        );
        assert_eq!(
            judge(&o, &px, None, behind, 0.05, Need::Shadow),
            Seen::Hidden(Why::Known(Cause::RobotShadow))
        );
        // The same returns with no robot rendered there: another body's shadow.
        let none = pixels(&o, |_, _| 2.0, |_, _| f32::INFINITY);
        let px = Pixels {
            robot: &none.robot,
            ..image.px()
        };
        assert_eq!(
            judge(&o, &px, None, behind, 0.05, Need::Shadow),
            Seen::Hidden(Why::NotShadow)
        );
    }
}
