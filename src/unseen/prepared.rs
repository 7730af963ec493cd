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
//! Cost: two passes over the pixels, the pyramids (4/3 of a pass), and per sphere its image's
//! pixels, in parallel (rayon).

use nalgebra::{Isometry3, Point3};
use rayon::prelude::*;

use crate::cloud::depth::PinholeCamera;

use super::footprint::{cone_row, window, Cone, Optics, Pixels, Rect, ROUNDING_M};
use super::pyramid::Pyramids;
use super::robot::PaddedSphere;
use super::view::RangeView;

/// Image rows per task of the robot's rendering.
const BAND: usize = 8;

/// One view, ready for the footprint test (see the module doc).
#[derive(Debug, Default)]
pub struct PreparedView {
    camera: Option<PinholeCamera>,
    optics: Option<Optics>,
    camera_from_root: Isometry3<f64>,
    rays: Vec<[f32; 3]>,
    /// The free distances and the robot's image, each the base of its pyramid.
    pyramids: Pyramids,
}

/// A padded sphere in the camera frame with the pixels its silhouette may cover.
struct Silhouette {
    c: [f32; 3],
    l2: f32,
    rho2: f32,
    rect: Rect,
}

impl PreparedView {
    /// `view` made ready with the robot's padded spheres at its stamp (root frame), reusing
    /// this one's buffers.
    pub fn prepare(&mut self, view: &RangeView, robot: &[PaddedSphere]) {
        let camera = *view.camera();
        let optics = Optics::new(&camera, view.min_range2().sqrt(), view.max_range_m());
        if self.camera != Some(camera) {
            self.rays = unit_rays(&camera);
            self.camera = Some(camera);
        }
        self.optics = Some(optics);
        self.camera_from_root = view.root_from_camera().inverse();
        let noise = view.range_noise_m();
        let (w, h) = (optics.width, optics.height);
        let free = self.pyramids.free.base_mut(w, h);
        free.par_iter_mut()
            .zip(view.ranges().par_iter().zip(&self.rays))
            .for_each(|(g, (&z, d))| {
                *g = if z.is_finite() {
                    // |d̃| = 1 / d_z for the unit ray d of d̃ = (x/z, y/z, 1).
                    ((z - noise) / d[2] - ROUNDING_M).max(0.0)
                } else {
                    -1.0
                };
            });
        // The largest free distance of each 2 × 2 pixels (clipped at the edges).
        let (free, pairs) = (&self.pyramids.free, &mut self.pyramids.pairs);
        let free = free.base();
        pairs
            .base_mut(w, h)
            .par_chunks_mut(w)
            .enumerate()
            .for_each(|(v, row)| {
                let below = (v + 1).min(h - 1);
                for (u, out) in row.iter_mut().enumerate() {
                    let right = (u + 1).min(w - 1);
                    *out = free[v * w + u]
                        .max(free[v * w + right])
                        .max(free[below * w + u])
                        .max(free[below * w + right]);
                }
            });
        self.render_robot(&optics, robot);
        self.pyramids.free.build();
        self.pyramids.pairs.build();
        self.pyramids.robot.build();
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

    /// Renders `spheres` (root frame) into the robot's image: per pixel a distance along its
    /// ray at which it has met one of them, or ∞ (see [`render_blocks`]).
    fn render_robot(&mut self, o: &Optics, spheres: &[PaddedSphere]) {
        let m = self.camera_from_root.rotation.to_rotation_matrix();
        let t = self.camera_from_root.translation.vector;
        let rot: [[f32; 3]; 3] = std::array::from_fn(|r| std::array::from_fn(|c| m[(r, c)] as f32));
        let tr = [t.x as f32, t.y as f32, t.z as f32];
        let mut shapes: Vec<Silhouette> = spheres
            .par_iter()
            .filter_map(|s| {
                let c: [f32; 3] = std::array::from_fn(|r| {
                    (0..3).map(|k| rot[r][k] * s.centre[k]).sum::<f32>() + tr[r]
                });
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
                    rect,
                })
            })
            .collect();
        // Front to back: a pixel that a nearer sphere already took skips the others' roots.
        shapes.sort_by(|a, b| {
            (a.l2.sqrt() - a.rho2.sqrt()).total_cmp(&(b.l2.sqrt() - b.rho2.sqrt()))
        });
        let robot = self.pyramids.robot.base_mut(o.width, o.height);
        render(o, &self.rays, &shapes, robot);
    }
}

/// The robot's image: bands of rows in parallel (no two tasks write a pixel), each over the
/// silhouettes that reach its rows, front to back; per row the silhouette's columns
/// (`cone_row`), per pixel its ray's entry into the sphere, kept where nearer (a pixel already
/// nearer skips the root). Exact per pixel ray: a pixel is given the robot only where its own
/// ray meets the padded spheres, the side the robot's shadow needs.
fn render(o: &Optics, rays: &[[f32; 3]], shapes: &[Silhouette], robot: &mut [f32]) {
    let w = o.width;
    robot
        .par_chunks_mut(BAND * w)
        .enumerate()
        .for_each(|(band, out)| {
            out.fill(f32::INFINITY);
            let (v_lo, v_hi) = (band * BAND, band * BAND + out.len() / w - 1);
            for s in shapes {
                if s.rect.v1 < v_lo || s.rect.v0 > v_hi {
                    continue;
                }
                let inside = s.l2 <= s.rho2;
                let k = s.l2 - s.rho2;
                let nearest = (s.l2.sqrt() - s.rho2.sqrt()).max(0.0);
                for v in v_lo.max(s.rect.v0)..=v_hi.min(s.rect.v1) {
                    let cols = if inside {
                        Some((s.rect.u0, s.rect.u1))
                    } else {
                        cone_row(o, s.c, k, v, s.rect)
                    };
                    let Some((u0, u1)) = cols else { continue };
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

/// Each pixel's unit ray through its centre, camera frame (row-major).
pub fn unit_rays(camera: &PinholeCamera) -> Vec<[f32; 3]> {
    let (w, h) = (camera.width as usize, camera.height as usize);
    (0..w * h)
        .into_par_iter()
        .map(|i| {
            let d = Point3::new(
                ((i % w) as f64 - camera.cx) / camera.fx,
                ((i / w) as f64 - camera.cy) / camera.fy,
                1.0,
            )
            .coords
            .normalize();
            [d.x as f32, d.y as f32, d.z as f32]
        })
        .collect()
}
