//! The robot in the lattice: which cells its padded body takes (the caller drops them from the
//! unseen set: the robot is no hidden body, and its inside is never seen), and which pixels of a
//! view returned a point on it (the observation's `self_shadow` comes from them).
//!
//! Input: the robot's inner spheres placed in the root frame, each with its own padding (the
//! monitor gives the self-filter padding plus the link's certified surface gap h, so that every
//! point of the link's mesh, which lies within h of its spheres, is within the padding), and
//! the lattice. A cell is the robot's when its centre lies within `radius + padding + d/2` of a
//! sphere's centre (`d` the cell diagonal): every cell that meets the padded spheres. A pixel
//! is a robot pixel when its return (root frame) falls in a robot cell: a return on the mesh
//! surface does whenever the range noise is within the padding (as for the self-filter).
//!
//! Cost: per sphere the cells of its bounding box, in parallel over the spheres (an atomic flag
//! per cell); per view one pass over its pixels.

use std::sync::atomic::{AtomicBool, Ordering};

use nalgebra::{Isometry3, Point3};
use rayon::prelude::*;

use super::error::UnseenError;
use super::lattice::Lattice;
use super::view::RangeView;

/// One inner sphere in the root frame with the padding its cells take.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PaddedSphere {
    pub centre: [f32; 3],
    pub radius: f32,
    pub padding: f32,
}

/// The lattice's frame in f32: a root-frame point to fractional cell coordinates.
struct ToCells {
    rotation: [[f32; 3]; 3],
    translation: [f32; 3],
    inv_h: f32,
    half: [f32; 3],
}

impl ToCells {
    fn new(lattice: &Lattice) -> Self {
        let box_from_root = lattice.root_from_box().inverse();
        let m = box_from_root.rotation.to_rotation_matrix();
        let t = box_from_root.translation.vector;
        Self {
            rotation: std::array::from_fn(|r| std::array::from_fn(|c| m[(r, c)] as f32)),
            translation: [t.x as f32, t.y as f32, t.z as f32],
            inv_h: (1.0 / lattice.resolution_m()) as f32,
            half: lattice.dims().map(|n| 0.5 * n as f32),
        }
    }

    /// Cell coordinates of a root-frame point: cell `i` spans `[i, i + 1)`.
    #[inline]
    fn at(&self, p: [f32; 3]) -> [f32; 3] {
        std::array::from_fn(|r| {
            let q = (0..3).map(|c| self.rotation[r][c] * p[c]).sum::<f32>() + self.translation[r];
            q * self.inv_h + self.half[r]
        })
    }
}

/// The cells of `lattice` that the padded spheres take (see the module doc).
pub fn robot_cells(lattice: &Lattice, spheres: &[PaddedSphere]) -> Vec<bool> {
    let to = ToCells::new(lattice);
    let dims = lattice.dims();
    let half_diagonal = 0.5 * lattice.cell_diagonal_m() as f32;
    let cells: Vec<AtomicBool> = (0..lattice.len()).map(|_| AtomicBool::new(false)).collect();
    spheres.par_iter().for_each(|s| {
        let reach = (s.radius + s.padding + half_diagonal) * to.inv_h;
        let c = to.at(s.centre);
        let lo = c.map(|x| (x - reach).floor().max(0.0) as usize);
        let hi: [usize; 3] = std::array::from_fn(|a| {
            let top = (c[a] + reach).ceil();
            if top < 0.0 {
                0
            } else {
                (top as usize).min(dims[a])
            }
        });
        let reach2 = reach * reach;
        for k in lo[2]..hi[2] {
            let dz = k as f32 + 0.5 - c[2];
            for j in lo[1]..hi[1] {
                let dy = j as f32 + 0.5 - c[1];
                for i in lo[0]..hi[0] {
                    let dx = i as f32 + 0.5 - c[0];
                    if dx * dx + dy * dy + dz * dz <= reach2 {
                        cells[lattice.index([i, j, k])].store(true, Ordering::Relaxed);
                    }
                }
            }
        }
    });
    cells.into_iter().map(AtomicBool::into_inner).collect()
}

/// Flags the pixels of `view` whose return falls in a cell of `robot` (one flag per cell of
/// `lattice`); a return outside the lattice is not the robot's. The count flagged.
pub fn flag_robot_pixels(view: &mut RangeView, lattice: &Lattice, robot: &[bool]) -> usize {
    let to = ToCells::new(lattice);
    let root_from_camera: Isometry3<f64> = *view.root_from_camera();
    let m = root_from_camera.rotation.to_rotation_matrix();
    let t = root_from_camera.translation.vector;
    let rot: [[f32; 3]; 3] = std::array::from_fn(|r| std::array::from_fn(|c| m[(r, c)] as f32));
    let tr = [t.x as f32, t.y as f32, t.z as f32];
    let camera = *view.camera();
    let (w, dims) = (camera.width as usize, lattice.dims());
    let (kx, ky) = (1.0 / camera.fx as f32, 1.0 / camera.fy as f32);
    let (cx, cy) = (camera.cx as f32, camera.cy as f32);
    let flags: Vec<bool> = view
        .ranges()
        .par_iter()
        .enumerate()
        .map(|(i, &z)| {
            if !z.is_finite() {
                return false;
            }
            let p = [
                ((i % w) as f32 - cx) * kx * z,
                ((i / w) as f32 - cy) * ky * z,
                z,
            ];
            let root: [f32; 3] =
                std::array::from_fn(|r| (0..3).map(|c| rot[r][c] * p[c]).sum::<f32>() + tr[r]);
            let q = to.at(root);
            if !q.iter().zip(dims).all(|(&x, n)| x >= 0.0 && x < n as f32) {
                return false;
            }
            robot[lattice.index(q.map(|x| x as usize))]
        })
        .collect();
    let count = flags.iter().filter(|&&f| f).count();
    view.robot_pixels_mut().copy_from_slice(&flags);
    count
}

/// A lattice over the padded spheres' box (root frame, axis-aligned) at `resolution_m`: the
/// robot's cells there tell the pixels that returned on the robot wherever it reaches, inside
/// the monitored volume or not ([`in_cells`]). `None` without spheres.
pub fn robot_lattice(
    spheres: &[PaddedSphere],
    resolution_m: f64,
) -> Option<Result<Lattice, UnseenError>> {
    let (mut lo, mut hi) = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);
    for s in spheres {
        let r = s.radius + s.padding;
        for a in 0..3 {
            lo[a] = lo[a].min(s.centre[a] - r);
            hi[a] = hi[a].max(s.centre[a] + r);
        }
    }
    if spheres.is_empty() {
        return None;
    }
    // One cell more on every side, so that the cells the spheres take lie inside.
    let grow = 1.5 * resolution_m;
    let centre = Isometry3::translation(
        0.5 * f64::from(lo[0] + hi[0]),
        0.5 * f64::from(lo[1] + hi[1]),
        0.5 * f64::from(lo[2] + hi[2]),
    );
    let half = std::array::from_fn(|a| 0.5 * f64::from(hi[a] - lo[a]) + grow);
    Some(Lattice::new(centre, half, resolution_m))
}

/// The cells a robot takes on its own lattice, to look root-frame points up in.
pub struct RobotCells<'a> {
    lattice: &'a Lattice,
    cells: &'a [bool],
    to: ToCells,
}

impl<'a> RobotCells<'a> {
    /// `cells`: one flag per cell of `lattice` ([`robot_cells`]).
    pub fn new(lattice: &'a Lattice, cells: &'a [bool]) -> Self {
        Self {
            lattice,
            cells,
            to: ToCells::new(lattice),
        }
    }

    /// Whether the root-frame point `p` falls in a robot cell (a point outside the lattice
    /// does not).
    pub fn contains(&self, p: [f32; 3]) -> bool {
        let q = self.to.at(p);
        let dims = self.lattice.dims();
        q.iter().zip(dims).all(|(&x, n)| x >= 0.0 && x < n as f32)
            && self.cells[self.lattice.index(q.map(|x| x as usize))]
    }
}

/// The root-frame centre of a point given in a link's frame, placed by `root_from_link`.
pub fn place(root_from_link: &Isometry3<f64>, centre: [f32; 3]) -> [f32; 3] {
    let p = root_from_link * Point3::from(centre.map(f64::from));
    [p.x as f32, p.y as f32, p.z as f32]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cloud::depth::PinholeCamera;

    #[test]
    fn a_sphere_takes_the_cells_it_meets_and_its_pixels() {
        let l = Lattice::new(Isometry3::translation(0.0, 0.0, 1.0), [0.2; 3], 0.02).unwrap();
        let s = PaddedSphere {
            centre: [0.0, 0.0, 1.0],
            radius: 0.05,
            padding: 0.01,
        };
        let cells = robot_cells(&l, &[s]);
        let reach = 0.06 + 0.5 * l.cell_diagonal_m() as f32;
        for (i, &c) in cells.iter().enumerate() {
            let p = l.centre(i);
            let d = (p[0].powi(2) + p[1].powi(2) + (p[2] - 1.0).powi(2)).sqrt();
            if (d - reach).abs() > 1e-4 {
                assert_eq!(c, d <= reach, "cell {:?} at {d}", l.ijk(i));
            }
        }
        // A camera at the origin looking along z: the centre pixel returns the sphere's front.
        let camera = PinholeCamera {
            width: 5,
            height: 5,
            fx: 10.0,
            fy: 10.0,
            cx: 2.0,
            cy: 2.0,
        };
        let mut depths = vec![3.0f32; 25];
        depths[12] = 0.95;
        depths[0] = f32::NAN;
        let mut view = RangeView::new(camera, Isometry3::identity(), &depths, None, 0.02).unwrap();
        assert_eq!(flag_robot_pixels(&mut view, &l, &cells), 1);
        assert!(view.robot_pixels()[12]);
    }
}
