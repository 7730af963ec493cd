//! A view made ready for the footprint test, once per frame of its source: each pixel's unit
//! ray (kept while the camera model stays), its free distance along the ray, the distance along
//! it to the robot's padded body at the frame's poses, and the min/max pyramids of both.
//!
//! Inputs: a [`RangeView`] (depths along z, pose, range noise and limits) and the robot's
//! padded spheres in the root frame at the view's own stamp (each inner sphere grown by the
//! self-filter padding and its link's h: a return on the link's surface lies inside them).
//! Frames: rays in the camera's optical frame; distances in metres along the ray.
//!
//! The robot is rendered, not read off the returns: a ray that met the arm's shiny surface and
//! returned nothing still met the arm, and it is the arm, not a dark body, that hides what lies
//! behind it. Per sphere, the pixels of its window (`footprint::window`) are tested exactly
//! (ray–sphere entry), the nearest kept per pixel (an atomic minimum on the f32's bits, which
//! order as u32 for non-negative values).
//!
//! **Only what the scene needs** ([`RobotImage`]): the search asks of the robot's image only
//! where the robot's shadow is reported apart (`unobserved_self_shadow: apart`); otherwise it
//! needs each ray's free distance alone, and the robot's image is rendered afterwards only in
//! the windows the causes of what was found read (per band of rows, the span of columns they
//! cover: [`PreparedView::render_robot_for`]), its pyramid rebuilt only over those bands: on the
//! Kinect frame, the render was half the view's cost, and whole bands for the 256 markers 0.7
//! ms where their windows take 0.3; a place outside the view (`footprint::in_view`: behind,
//! out of range, projecting outside the image), judged without its pixels, asks for none (the
//! causes 0.48 -> 0.41 ms there, 0.52 -> 0.29 ms on the 2 m cube).
//!
//! Cost: one pass over the pixels for the free distances and their 2 × 2 maxima (bands of rows,
//! each reading the row below it again), the two pyramids built side by side (4/3 of a pass
//! each; the maxima's pyramid for its minima alone), and per sphere its image's pixels (all of
//! them, or those of the rows asked for), in parallel (rayon); the robot's image blanked again
//! where the last frame rendered it (the whole image where that was a quarter of it or more).

use nalgebra::{Isometry3, Point3};
use rayon::prelude::*;

use crate::cloud::depth::PinholeCamera;

use super::camera::{cone_row, unit_ray, window, Cone, Optics, Rect};
use super::footprint::{in_view, InView, Pixels, ROUNDING_M};
use super::pyramid::Pyramids;
use super::robot::{PaddedSphere, Rigid32};
use super::view::RangeView;

/// Image rows per task of the robot's rendering.
const BAND: usize = 8;

/// How much of the robot's image [`PreparedView::prepare`] renders.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RobotImage {
    /// Every pixel, and its pyramid: the search asks of the robot's shadow.
    Whole,
    /// None yet (every pixel ∞, no pyramid): the search asks only whether a ball is ruled out,
    /// and the causes of what it found render the rows they read
    /// ([`PreparedView::render_robot_for`]).
    Deferred,
}

/// One view, ready for the footprint test (see the module doc).
#[derive(Debug, Default)]
pub struct PreparedView {
    camera: Option<PinholeCamera>,
    optics: Option<Optics>,
    camera_from_root: Isometry3<f64>,
    /// The range noise its free distances were taken short by (m).
    range_noise_m: f32,
    rays: Vec<[f32; 3]>,
    /// Each pixel's `|d̃| = 1 / d_z` (its unit ray `d`), apart, for the free distances' pass.
    ray_length: Vec<f32>,
    /// The free distances and the robot's image, each the base of its pyramid.
    pyramids: Pyramids,
    /// The padded spheres' silhouettes, front to back, and per band of `BAND` rows of the
    /// robot's image the columns rendered in it (`None`: none).
    shapes: Vec<Silhouette>,
    rendered: Vec<Columns>,
}

/// A span of columns `(first, last)` of a band of rows, or none.
type Columns = Option<(usize, usize)>;

/// The smallest span holding both.
fn union(a: Columns, b: Columns) -> Columns {
    match (a, b) {
        (Some(a), Some(b)) => Some((a.0.min(b.0), a.1.max(b.1))),
        (a, None) => a,
        (None, b) => b,
    }
}

/// A padded sphere in the camera frame with the pixels its silhouette may cover.
#[derive(Debug)]
struct Silhouette {
    c: [f32; 3],
    l2: f32,
    rho2: f32,
    /// The least distance from the camera to the sphere (0 inside it).
    nearest: f32,
    rect: Rect,
}

impl PreparedView {
    /// `view` made ready with the robot's padded spheres at its stamp (root frame), reusing
    /// this one's buffers; the robot's image rendered as `image` says.
    pub fn prepare(&mut self, view: &RangeView, robot: &[PaddedSphere], image: RobotImage) {
        let camera = *view.camera();
        let optics = Optics::new(&camera, view.min_range2().sqrt(), view.max_range_m());
        if self.camera != Some(camera) {
            self.rays = unit_rays(&camera);
            self.ray_length = self.rays.iter().map(|d| 1.0 / d[2]).collect();
            self.camera = Some(camera);
        }
        self.optics = Some(optics);
        self.camera_from_root = view.root_from_camera().inverse();
        let noise = view.range_noise_m();
        self.range_noise_m = noise;
        let (w, h) = (optics.width, optics.height);
        let (ranges, length) = (view.ranges(), &self.ray_length[..]);
        // The free distances, and the largest of each 2 × 2 pixels (by the top-left one,
        // clipped at the edges), in one pass: bands of rows, each with the row below it.
        let Pyramids { free, pairs, .. } = &mut self.pyramids;
        let (free, pairs) = (free.base_mut(w, h), pairs.base_mut(w, h));
        free.par_chunks_mut(BAND * w)
            .zip(pairs.par_chunks_mut(BAND * w))
            .enumerate()
            .for_each(|(band, (f, p))| {
                let (start, n) = (band * BAND * w, f.len());
                let end = start + n;
                free_distances(f, &ranges[start..end], &length[start..end], noise);
                let below = if end < w * h {
                    let mut row = vec![0.0; w];
                    free_distances(
                        &mut row,
                        &ranges[end..end + w],
                        &length[end..end + w],
                        noise,
                    );
                    row
                } else {
                    f[n - w..].to_vec()
                };
                for (r, out) in p.chunks_exact_mut(w).enumerate() {
                    let next = match f.get((r + 1) * w..(r + 2) * w) {
                        Some(next) => next,
                        None => &below[..],
                    };
                    largest_of_pairs(&f[r * w..(r + 1) * w], next, out);
                }
            });
        self.place_robot(&optics, robot);
        let Pyramids { free, pairs, .. } = &mut self.pyramids;
        // The pairs' maxima are read at the image alone (`footprint`), their minima over blocks
        // (`search`).
        rayon::join(|| free.build(), || pairs.build_minima());
        if image == RobotImage::Whole {
            self.render_whole();
        }
    }

    /// Renders the pixels of the robot's image that the test of a ball of radius `r` at each of
    /// `centres` (root frame) reads (its window; none for a ball outside the view), where not
    /// rendered yet, and its pyramid.
    pub fn render_robot_for(&mut self, centres: &[[f32; 3]], r: f32) {
        let Some(o) = self.optics else { return };
        let mut wanted: Vec<Columns> = vec![None; self.rendered.len()];
        for c in centres {
            let q = self.camera_from_root * Point3::from(c.map(f64::from));
            let p = [q.x as f32, q.y as f32, q.z as f32];
            // A ball outside the view is judged without its pixels.
            let Some(InView { l, alpha, u, v, .. }) = in_view(&o, p, r) else {
                continue;
            };
            // Where no window bounds the footprint, `window` gives the whole image.
            if let Some(rect) = window(&o, u, v, p[2] / l, alpha) {
                let span = Some((rect.u0, rect.u1));
                (wanted[rect.v0 / BAND..=rect.v1 / BAND].iter_mut())
                    .for_each(|b| *b = union(*b, span));
            }
        }
        self.render_bands(&wanted);
    }

    /// Renders the robot's image whole (to draw it), where not yet.
    pub fn render_robot_whole(&mut self) {
        self.render_whole();
    }

    /// Every band's every column.
    fn render_whole(&mut self) {
        let Some(o) = self.optics else { return };
        self.render_bands(&vec![Some((0, o.width - 1)); self.rendered.len()]);
    }

    /// The view's camera, f32.
    pub fn optics(&self) -> &Optics {
        self.optics
            .as_ref()
            .expect("a prepared view has its optics")
    }

    /// The view's camera model (`None` before the first frame).
    pub fn camera(&self) -> Option<&PinholeCamera> {
        self.camera.as_ref()
    }

    pub fn camera_from_root(&self) -> &Isometry3<f64> {
        &self.camera_from_root
    }

    /// The range noise its free distances were taken short by (m).
    pub fn range_noise_m(&self) -> f32 {
        self.range_noise_m
    }

    pub fn pixels(&self) -> Pixels<'_> {
        Pixels {
            rays: &self.rays,
            free: self.pyramids.free.base(),
            robot: self.pyramids.robot.base(),
        }
    }

    pub fn pyramids(&self) -> &Pyramids {
        &self.pyramids
    }

    /// The padded `spheres` (root frame) placed in the camera frame, front to back, each with
    /// the window its silhouette may cover; the robot's image blank (∞), no band rendered.
    fn place_robot(&mut self, o: &Optics, spheres: &[PaddedSphere]) {
        let camera_from_root = Rigid32::of(&self.camera_from_root);
        self.shapes = spheres
            .par_iter()
            .filter_map(|s| {
                let c = camera_from_root.apply(s.centre);
                let rho = s.radius + s.padding;
                if c[2] + rho <= 0.0 {
                    return None;
                }
                let l2 = c[0] * c[0] + c[1] * c[1] + c[2] * c[2];
                let l = l2.sqrt();
                let rect = if l <= rho || c[2] <= rho {
                    Rect::whole(o)
                } else {
                    let (u, v) = o.project(c);
                    window(o, u, v, c[2] / l, Cone::of_sphere(rho, l))
                }?;
                Some(Silhouette {
                    c,
                    l2,
                    rho2: rho * rho,
                    // From `rho2`'s root, as the entries `render` takes from `rho2`.
                    nearest: (l - (rho * rho).sqrt()).max(0.0),
                    rect,
                })
            })
            .collect();
        // Front to back: a pixel that a nearer sphere already took skips the others' roots.
        self.shapes.sort_by(|a, b| a.nearest.total_cmp(&b.nearest));
        self.blank_robot(o);
    }

    /// The robot's image blank (∞), its pyramid with it, no band rendered: rendering bands then
    /// rebuilds only the texels over them. Where the last frame's image had the same size and
    /// rendered less than a quarter of it (the causes' windows), only what it rendered is
    /// blanked again, the texels over those rows rebuilt: the rest is ∞ still (on the Kinect
    /// frame 0.04 ms, where blanking the whole image and its pyramid takes 0.07–0.09).
    fn blank_robot(&mut self, o: &Optics) {
        let (w, h) = (o.width, o.height);
        let bands = h.div_ceil(BAND);
        let robot = &mut self.pyramids.robot;
        let rendered: usize = (self.rendered.iter().flatten())
            .map(|(c0, c1)| (c1 + 1 - c0) * BAND)
            .sum();
        let same = robot.width() == w && robot.height() == h && self.rendered.len() == bands;
        if !same || 4 * rendered > w * h {
            robot.fill(w, h, f32::INFINITY);
        } else if rendered > 0 {
            let base = robot.base_mut(w, h);
            for (band, span) in self.rendered.iter().enumerate() {
                let Some((c0, c1)) = *span else { continue };
                for v in band * BAND..((band + 1) * BAND).min(h) {
                    base[v * w + c0..=v * w + c1].fill(f32::INFINITY);
                }
            }
            robot.build_rows(&band_rows(&self.rendered, h));
        }
        self.rendered = vec![None; bands];
    }

    /// Renders the columns `wanted` of each band where not rendered yet (the span of those
    /// rendered and wanted, again: a pixel rendered twice is the same), then the robot's
    /// pyramid over the bands rendered.
    fn render_bands(&mut self, wanted: &[Columns]) {
        let Some(o) = self.optics else { return };
        // Where the span wanted lies within the one rendered, their union is the latter.
        let todo: Vec<Columns> = (wanted.iter().zip(&self.rendered))
            .map(|(&w, &r)| Some(union(w, r)).filter(|&u| u != r).flatten())
            .collect();
        if todo.iter().all(Option::is_none) {
            return;
        }
        let robot = self.pyramids.robot.base_mut(o.width, o.height);
        render(&o, &self.rays, &self.shapes, robot, &todo);
        (self.rendered.iter_mut().zip(&todo)).for_each(|(r, t)| *r = union(*r, *t));
        self.pyramids.robot.build_rows(&band_rows(&todo, o.height));
    }
}

/// Per row of an image `height` rows high, whether its band of `bands` has columns.
fn band_rows(bands: &[Columns], height: usize) -> Vec<bool> {
    (0..height).map(|v| bands[v / BAND].is_some()).collect()
}

/// The robot's image over the columns `bands` gives each band of rows (the rest as it was: ∞
/// where never rendered): bands in parallel (no two tasks write a pixel), each over the
/// silhouettes that reach its rows and columns, front to back; per row the silhouette's columns
/// (`cone_row`), per pixel its ray's entry into the sphere, kept where nearer (a pixel already
/// nearer skips the root). Exact per pixel ray: a pixel is given the robot only where its own
/// ray meets the padded spheres, the side the robot's shadow needs.
fn render(
    o: &Optics,
    rays: &[[f32; 3]],
    shapes: &[Silhouette],
    robot: &mut [f32],
    bands: &[Columns],
) {
    let w = o.width;
    robot
        .par_chunks_mut(BAND * w)
        .enumerate()
        .filter_map(|(band, out)| bands[band].map(|span| (band, span, out)))
        .for_each(|(band, (c0, c1), out)| {
            let (v_lo, v_hi) = (band * BAND, band * BAND + out.len() / w - 1);
            for s in shapes {
                if s.rect.v1 < v_lo || s.rect.v0 > v_hi || s.rect.u1 < c0 || s.rect.u0 > c1 {
                    continue;
                }
                let inside = s.l2 <= s.rho2;
                let k = s.l2 - s.rho2;
                let nearest = s.nearest;
                for v in v_lo.max(s.rect.v0)..=v_hi.min(s.rect.v1) {
                    let cols = if inside {
                        Some((s.rect.u0, s.rect.u1))
                    } else {
                        cone_row(o, s.c, k, v, s.rect)
                    };
                    let Some((u0, u1)) = cols else { continue };
                    let (u0, u1) = (u0.max(c0), u1.min(c1));
                    let row = (v - v_lo) * w;
                    for u in u0..=u1 {
                        let q = &mut out[row + u];
                        if *q <= nearest {
                            continue;
                        }
                        let d = rays[v * w + u];
                        let proj = d[0] * s.c[0] + d[1] * s.c[1] + d[2] * s.c[2];
                        let perp2 = (s.l2 - proj * proj).max(0.0);
                        if (proj > 0.0 || inside) && perp2 < s.rho2 {
                            *q = q.min((proj - (s.rho2 - perp2).sqrt()).max(0.0));
                        }
                    }
                }
            }
        });
}

/// Each pixel's free distance along its ray: its depth `z` less the range `noise`, times its
/// ray's `|d̃| = 1 / d_z` (`d̃ = (x/z, y/z, 1)`, `d` its unit ray; a product, not a quotient: a
/// few ulps, far within [`ROUNDING_M`]), less [`ROUNDING_M`]; −1 for no return. Branch-free, so
/// that it runs as vectors.
#[inline]
fn free_distances(out: &mut [f32], z: &[f32], length: &[f32], noise: f32) {
    for ((g, &z), &k) in out.iter_mut().zip(z).zip(length) {
        let free = ((z - noise) * k - ROUNDING_M).max(0.0);
        *g = if z.is_finite() { free } else { -1.0 };
    }
}

/// `out[u]`: the largest of `row[u]`, `row[u + 1]`, `next[u]`, `next[u + 1]` (the last column
/// alone at the edge).
#[inline]
fn largest_of_pairs(row: &[f32], next: &[f32], out: &mut [f32]) {
    let w = out.len();
    for ((o, a), b) in out.iter_mut().zip(row.windows(2)).zip(next.windows(2)) {
        *o = a[0].max(a[1]).max(b[0]).max(b[1]);
    }
    out[w - 1] = row[w - 1].max(next[w - 1]);
}

/// Each pixel's unit ray through its centre, camera frame (row-major).
pub fn unit_rays(camera: &PinholeCamera) -> Vec<[f32; 3]> {
    let (w, h) = (camera.width as usize, camera.height as usize);
    (0..w * h)
        .into_par_iter()
        .map(|i| unit_ray(camera, i % w, i / w))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 64 × 48 camera at the origin looking along +z, a wall 3 m away.
    fn view() -> RangeView {
        let camera = super::super::camera::test_camera();
        RangeView::new(camera, Isometry3::identity(), &[3.0; 64 * 48], None, 0.02).unwrap()
    }

    fn sphere(x: f32, y: f32, z: f32, radius: f32) -> PaddedSphere {
        PaddedSphere {
            centre: [x, y, z],
            radius,
            padding: 0.01,
        }
    }

    /// The robot's image and every level of its pyramid (maxima; minima over every 4 × 4).
    fn robot_image(v: &PreparedView) -> Vec<Vec<u32>> {
        let robot = &v.pyramids().robot;
        let mut out: Vec<Vec<u32>> = (0..)
            .map_while(|k| robot.maxima(k))
            .map(|(m, _)| m.iter().map(|x| x.to_bits()).collect())
            .collect();
        let rects = (0..12).flat_map(|j| (0..16).map(move |i| (4 * i, 4 * j)));
        out.push(
            rects
                .map(|(u0, v0)| {
                    let rect = Rect {
                        u0,
                        v0,
                        u1: u0 + 3,
                        v1: v0 + 3,
                    };
                    robot.min(rect).to_bits()
                })
                .collect(),
        );
        out
    }

    /// A view prepared again for a second frame (the robot moved, other places asked for) has
    /// the robot's image of one prepared for that frame alone: the bands the first frame
    /// rendered are blanked again, the rest was never written.
    #[test]
    fn a_second_frame_blanks_what_the_first_rendered() {
        let first = [sphere(-0.3, -0.2, 1.5, 0.1), sphere(0.2, 0.1, 1.2, 0.15)];
        let second = [sphere(0.4, 0.3, 1.4, 0.12)];
        let asked_first = [[-0.3, -0.2, 1.3], [0.2, 0.1, 1.0], [0.0, 0.0, 2.0]];
        let asked_second = [[0.4, 0.3, 1.2], [-0.5, 0.0, 2.0]];
        let mut reused = PreparedView::default();
        reused.prepare(&view(), &first, RobotImage::Deferred);
        reused.render_robot_for(&asked_first, 0.02);
        assert!(
            reused.pixels().robot.iter().any(|d| d.is_finite()),
            "the first frame rendered some of the robot"
        );
        reused.prepare(&view(), &second, RobotImage::Deferred);
        reused.render_robot_for(&asked_second, 0.02);
        let mut fresh = PreparedView::default();
        fresh.prepare(&view(), &second, RobotImage::Deferred);
        fresh.render_robot_for(&asked_second, 0.02);
        assert_eq!(robot_image(&reused), robot_image(&fresh));
        // And after a whole image, a deferred one.
        reused.prepare(&view(), &first, RobotImage::Whole);
        reused.prepare(&view(), &second, RobotImage::Deferred);
        reused.render_robot_for(&asked_second, 0.02);
        assert_eq!(robot_image(&reused), robot_image(&fresh));
    }
}
