//! The balls a lattice cell stands for (see the module doc of `unseen` and `cell`): a body of the
//! detection capability `D` (radius `R = D/2`) centred anywhere in a cell of diagonal `d` holds
//! the base ball `B(x, R − d/2)` about the cell's centre, and, centred in one of its eight
//! sub-cubes, that sub-cube's ball `B(x_k, R − d/4)`; its nearest point to the robot is at
//! least `R + d/2` nearer than the cell's centre is.

use super::error::UnseenError;
use super::lattice::{positive, Lattice};

/// Default detection capability (m): 70 mm, arm-level. ISO 13855 (with IEC 61496's ESPE
/// classes) takes a detection capability above 40 mm and up to 70 mm as detecting an arm, and
/// adds the reach of an arm (C = 850 mm) to the safety distance; 14 mm (finger) and 30–40 mm
/// (hand) need the full `8·(d − 14)` intrusion allowance. At a 2 cm lattice a 70 mm body is
/// judged by the ball of 17.7 mm about each centre; 40 mm leaves 2.7 mm, judged by few pixels
/// beyond a metre: choose a 1 cm lattice for a hand.
pub const DEFAULT_DETECTION_CAPABILITY_M: f64 = 0.07;

/// The balls each lattice cell stands for, and what a distance to it loses (see the module
/// doc and `cell`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BallSize {
    /// The base ball's radius `r = D/2 − d/2`, rounded down to f32 (m).
    pub radius_m: f32,
    /// The sub-balls' radius `D/2 − d/4`, rounded down to f32 (m).
    pub sub_radius_m: f32,
    /// `R = D/2` (m).
    pub capability_radius_m: f64,
    /// `d/2`, half the cell diagonal (m).
    pub half_diagonal_m: f64,
    /// `R + d/2` (m): subtracted from the distance to a hidden centre.
    pub margin_m: f64,
}

impl BallSize {
    /// The ball for `detection_capability_m` on `lattice`; refused where it would hold no
    /// point (`D` at most the cell diagonal).
    pub fn new(lattice: &Lattice, detection_capability_m: f64) -> Result<Self, UnseenError> {
        let half = positive("detection_capability", detection_capability_m)? / 2.0;
        let d = lattice.cell_diagonal_m();
        let r = half - d / 2.0;
        if r <= 0.0 {
            return Err(UnseenError::CapabilityBelowResolution {
                detection_capability_m,
                resolution_m: lattice.resolution_m(),
                needed_m: d,
            });
        }
        Ok(Self {
            radius_m: crate::geometry::f32_at_most(r),
            sub_radius_m: crate::geometry::f32_at_most(half - d / 4.0),
            capability_radius_m: half,
            half_diagonal_m: d / 2.0,
            margin_m: half + d / 2.0,
        })
    }

    /// The distance to a hidden body from the certified lower bound `lower_m` at its centre.
    pub fn distance(&self, lower_m: f64) -> f64 {
        (lower_m - self.margin_m).max(0.0)
    }
}
