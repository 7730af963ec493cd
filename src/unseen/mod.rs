//! Unseen space: a certified lower bound of the distance from the robot to a body of the
//! detection capability that no source has seen (issues 45 and 55). A pixel that returns
//! nothing (dark fabric, glare, beyond range) and the space behind every surface, the robot's
//! own body included, are not seen free: the distance to the points received says nothing about
//! them.
//!
//! Stage: after `query` and `cloud` (it uses `cloud::depth`, and the caller's query for the
//! distance); it knows nothing of the config, the monitor or the node, which wire it in
//! (`monitor::unseen`). Frames: the lattice and every result are in the robot's root frame;
//! each source is a pinhole camera (`cloud::depth::PinholeCamera`) placed by
//! `root_from_camera` (optical frame: z forward). Units: metres. Poses f64, converted once per
//! view; f32 in the per-pixel and per-centre loops.
//!
//! **The question, per place.** A body of the detection capability `D` holds a ball of radius
//! `R = D/2`. The monitored volume is sampled by a [`Lattice`] of centres `h` apart; a hidden
//! ball centred anywhere holds the ball of radius `r = R − d/2` about its nearest centre (`d`
//! the cell diagonal), so each centre asks whether a ball of radius `r` there ([`BallSize`]) can
//! be hidden. A view rules it out as soon as one pixel ray through it returned beyond the point
//! where the ray enters it (`footprint`: every pixel of its whole footprint is asked, not the
//! four around its centre); where none does, the cell's eight sub-cubes are asked with balls
//! of `R − d/4` (`cell`). A cell no view rules out is hidden, and says why: the robot's shadow,
//! another body's shadow, pixels without return, outside every view.
//!
//! The steps, in the order a frame runs them:
//! 1. [`RangeView`] (`view`, `fit`): per source its pixel grid, pose, depths and range limits,
//!    from a depth image or an organized cloud; [`PreparedView`] (`prepared`, `pyramid`): per
//!    frame of its source, its free distance and the robot's padded body along every ray, and
//!    their min/max pyramids;
//! 2. the footprint test (`footprint`), per view and ball; the cell's verdict over the views
//!    (`cell`);
//! 3. the search (`search`): blocks of centres in the order of their bound from the robot
//!    (`robot`), only those that can be nearer than the best distance found, a block that one
//!    view sees wholly free skipped; the caller's certified distance over the hidden centres,
//!    wave by wave;
//! 4. [`BallSize::distance`]: that distance less `R + d/2` (the hidden ball's nearest point is
//!    `R` from its centre, which is within `d/2` of the lattice centre), floored at 0.
//!
//! **What is guaranteed.** Take a ball of diameter `D` inside the monitored volume and outside
//! the robot and the exclusion volumes, such that every pixel whose area meets it returns
//! nothing or a surface in front of it (a dark body, or one behind another). Then the
//! unseen distance is no more than the distance from the robot to that ball (the property test
//! in `tests/unseen.rs`: random camera poses, intrinsics up to wide angles, dropout masks,
//! capabilities down to 40 mm and resolutions, balls beside the robot, against a brute-force
//! distance; the search against the test of every centre). A body some pixel does see is
//! measured by the distance to the points. With the robot's shadow apart, the same holds for a
//! ball that more than half of its footprint's rays do not meet the robot in front of it in
//! some view that can see it.
//!
//! Cost: per view one pass over the pixels and the robot's spheres' images; then per block
//! examined a few pyramid reads, per centre judged one read for free space and a footprint's
//! pixels at a surface; measured by `ist_monitor bench monitor` (docs/unobserved.md).
//!
//! Files: `error`, `lattice`, `view` and `fit`, `prepared` and `pyramid`, `robot`,
//! `footprint`, `cell`, `search`.

mod cell;
mod error;
mod fit;
mod footprint;
mod lattice;
mod prepared;
mod pyramid;
mod robot;
mod search;
mod view;

pub use cell::{in_shadow, judge_cell, CellSeen, PlacedView};
pub use error::UnseenError;
pub use fit::{fit_pinhole, MAX_RESIDUAL_PX, MIN_FIT_POINTS};
pub use footprint::{judge, Cause, Cone, Need, Optics, Pixels, Seen, Why, ROUNDING_M};
pub use lattice::{centre_at, Lattice, DEFAULT_RESOLUTION_M, MAX_CELLS};
pub use prepared::{unit_rays, PreparedView};
pub use pyramid::{Pyramid, Pyramids};
pub use robot::{link_bounds, padded_spheres, place, LinkBound, PaddedSphere, RobotBody};
pub use search::{fused_cause, Batch, Counts, Found, Search, Spot, BLOCK};
pub use view::{RangeView, DEFAULT_RANGE_NOISE_M};

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
        let half = lattice::positive("detection_capability", detection_capability_m)? / 2.0;
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
