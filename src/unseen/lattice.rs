//! The monitored volume as a voxel lattice: a box fixed in the robot's root frame
//! (`root_from_box`, half extents in metres) cut into cubic cells of `resolution_m`.
//!
//! Cells are indexed `i + n0·(j + n1·k)` (`i` along the box's x, fastest). Along each axis the
//! lattice has `n = ceil(2·half / resolution)` cells (at least one), centred on the box: cell
//! `i`'s centre lies at `(i + ½ − n/2)·resolution` in the box frame, so the lattice covers the
//! box (a little more where the extent is not a multiple of the resolution, never less).
//!
//! Centres are computed, not stored: the root-frame centre of cell 0 and the root-frame step
//! along each index, in f32, from the f64 pose converted once; the centre of `(i, j, k)` is
//! `origin + i·step_x + j·step_y + k·step_z` (f32; a 2 m lattice is exact to a few µm).
//! [`Lattice::in_frame`] gives the same origin and steps in another frame (a camera's), so the
//! observation pass walks cells with three additions and no pose per cell.

use nalgebra::{Isometry3, Point3, Vector3};

use super::error::UnseenError;

/// Default lattice resolution (m): 2 cm, the 2–4 cm range at its fine end. A 2 × 2 × 2 m
/// volume is then 10⁶ cells, which the search prunes to the few hundred blocks that can be
/// nearer than what it finds (5 ms on the Kinect frame on 2 cores, docs/unobserved.md); it
/// certifies an arm-level detection capability (70 mm: a base ball of 17.7 mm about each centre,
/// `cell`), where 4 cm would not.
pub const DEFAULT_RESOLUTION_M: f64 = 0.02;

/// The most cells a lattice may hold: 16 M (a 5 m cube at 2 cm); beyond, the per-frame pass
/// and its buffers (about 20 bytes a cell) leave a frame budget behind.
pub const MAX_CELLS: usize = 1 << 24;

/// The monitored volume as a lattice of cubic cells.
#[derive(Debug, Clone, PartialEq)]
pub struct Lattice {
    root_from_box: Isometry3<f64>,
    half_extents_m: [f64; 3],
    resolution_m: f64,
    dims: [usize; 3],
}

impl Lattice {
    /// The lattice of the box `root_from_box` with `half_extents_m` at `resolution_m`; refused
    /// when a length is not finite and positive or when it would hold more than [`MAX_CELLS`].
    pub fn new(
        root_from_box: Isometry3<f64>,
        half_extents_m: [f64; 3],
        resolution_m: f64,
    ) -> Result<Self, UnseenError> {
        positive("resolution", resolution_m)?;
        for h in half_extents_m {
            positive("monitored_volume half extent", h)?;
        }
        let dims_f = half_extents_m.map(|h| (2.0 * h / resolution_m).ceil().max(1.0));
        let cells = dims_f.iter().product::<f64>();
        if cells > MAX_CELLS as f64 {
            return Err(UnseenError::TooManyCells {
                resolution_m,
                dims: dims_f,
                cells,
                max: MAX_CELLS,
            });
        }
        Ok(Self {
            root_from_box,
            half_extents_m,
            resolution_m,
            dims: dims_f.map(|n| n as usize),
        })
    }

    /// Cells along the box's x, y and z.
    pub fn dims(&self) -> [usize; 3] {
        self.dims
    }

    /// Cells in all.
    pub fn len(&self) -> usize {
        self.dims[0] * self.dims[1] * self.dims[2]
    }

    /// Never true for a lattice made by [`Lattice::new`] (at least one cell).
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    pub fn resolution_m(&self) -> f64 {
        self.resolution_m
    }

    /// The length of a cell's diagonal, `√3 · resolution` (m).
    pub fn cell_diagonal_m(&self) -> f64 {
        3f64.sqrt() * self.resolution_m
    }

    pub fn root_from_box(&self) -> &Isometry3<f64> {
        &self.root_from_box
    }

    pub fn half_extents_m(&self) -> [f64; 3] {
        self.half_extents_m
    }

    /// The index of cell `(i, j, k)`.
    #[inline]
    pub fn index(&self, ijk: [usize; 3]) -> usize {
        ijk[0] + self.dims[0] * (ijk[1] + self.dims[1] * ijk[2])
    }

    /// The `(i, j, k)` of cell `index`.
    #[inline]
    pub fn ijk(&self, index: usize) -> [usize; 3] {
        let [n0, n1, _] = self.dims;
        [index % n0, (index / n0) % n1, index / (n0 * n1)]
    }

    /// The centre of cell 0 and the step along each index, in the frame `frame_from_root`
    /// takes the root frame to (f64 composed once, rounded to f32).
    pub fn in_frame(&self, frame_from_root: &Isometry3<f64>) -> ([f32; 3], [[f32; 3]; 3]) {
        let frame_from_box = frame_from_root * self.root_from_box;
        let h = self.resolution_m;
        let first = Point3::from(std::array::from_fn(|a| {
            (0.5 - 0.5 * self.dims[a] as f64) * h
        }));
        let origin = frame_from_box * first;
        let steps = std::array::from_fn(|a| {
            let s = frame_from_box.rotation * (Vector3::ith(a, 1.0) * h);
            [s.x as f32, s.y as f32, s.z as f32]
        });
        ([origin.x as f32, origin.y as f32, origin.z as f32], steps)
    }

    /// The root-frame centre of cell `index` (f32, m).
    pub fn centre(&self, index: usize) -> [f32; 3] {
        let (origin, steps) = self.in_frame(&Isometry3::identity());
        centre_at(origin, &steps, self.ijk(index))
    }

    /// The root-frame centres of the cells set in `cells` (one flag a cell), in index order.
    pub fn centres(&self, cells: &[bool]) -> Vec<[f32; 3]> {
        let (origin, steps) = self.in_frame(&Isometry3::identity());
        cells
            .iter()
            .enumerate()
            .filter(|(_, &c)| c)
            .map(|(i, _)| centre_at(origin, &steps, self.ijk(i)))
            .collect()
    }
}

/// `origin + i·steps[0] + j·steps[1] + k·steps[2]`.
#[inline]
pub fn centre_at(origin: [f32; 3], steps: &[[f32; 3]; 3], ijk: [usize; 3]) -> [f32; 3] {
    let [i, j, k] = ijk.map(|x| x as f32);
    std::array::from_fn(|a| origin[a] + i * steps[0][a] + j * steps[1][a] + k * steps[2][a])
}

/// `value` as a finite, positive length, or the error naming `parameter`.
pub(super) fn positive(parameter: &'static str, value: f64) -> Result<f64, UnseenError> {
    if value.is_finite() && value > 0.0 {
        Ok(value)
    } else {
        Err(UnseenError::Length {
            parameter,
            value,
            expected: "length > 0",
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Translation3, UnitQuaternion};

    #[test]
    fn cells_cover_the_box_and_index_round_trips() {
        let pose = Isometry3::from_parts(
            Translation3::new(0.3, -0.2, 0.5),
            UnitQuaternion::from_euler_angles(0.2, -0.4, 1.1),
        );
        let l = Lattice::new(pose, [0.5, 0.25, 0.31], 0.1).unwrap();
        assert_eq!(l.dims(), [10, 5, 7]);
        assert_eq!(l.len(), 350);
        for index in [0, 1, 17, 349] {
            assert_eq!(l.index(l.ijk(index)), index);
        }
        // Centres in the box frame: symmetric about the box's centre, a resolution apart.
        let local = |index: usize| {
            let c = l.centre(index).map(f64::from);
            pose.inverse_transform_point(&Point3::from(c))
        };
        let first = local(0);
        let last = local(349);
        assert!((first.x + 0.45).abs() < 1e-5 && (last.x - 0.45).abs() < 1e-5);
        assert!((first.z + 0.3).abs() < 1e-5 && (last.z - 0.3).abs() < 1e-5);
        let next = local(l.index([1, 0, 0]));
        assert!(((next - first).norm() - 0.1).abs() < 1e-5);
        let set: Vec<bool> = (0..350).map(|i| i == 17).collect();
        assert_eq!(l.centres(&set), vec![l.centre(17)]);
    }

    #[test]
    fn bad_parameters_are_named() {
        let id = Isometry3::identity();
        for (half, res, want) in [
            ([1.0; 3], 0.0, "parameter resolution"),
            ([1.0; 3], f64::NAN, "parameter resolution"),
            ([1.0, -1.0, 1.0], 0.1, "half extent"),
            ([10.0; 3], 0.005, "more than"),
        ] {
            let e = Lattice::new(id, half, res).unwrap_err().to_string();
            assert!(e.contains(want), "{e} lacks {want}");
        }
    }
}
