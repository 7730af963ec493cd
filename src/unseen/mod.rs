//! Unseen space: what no source has seen free inside the monitored volume, and a certified
//! lower bound of the distance from the robot to a body of the detection capability hidden
//! there (issue 45). A pixel that returns nothing (dark fabric, glare, beyond range) and the
//! space behind every surface, the robot's own body included, are not free: the distance to the
//! points received says nothing about them.
//!
//! Stage: after `query` and `cloud` (it uses `cloud::depth` and `cloud::exclusion`, and the
//! caller's query for the distance); it knows nothing of the config, the monitor or the node,
//! which wire it in. Frames: the lattice and every result are in the robot's root frame; each
//! source is a pinhole camera (`cloud::depth::PinholeCamera`) placed by `root_from_camera`
//! (optical frame: z forward). Units: metres. Poses f64, converted once per frame; f32 in the
//! per-cell loops.
//!
//! The steps, in the order a frame runs them:
//! 1. [`Lattice`] (`lattice`): the monitored volume, a box in the root frame, as cells of
//!    `resolution_m`; [`RangeView`] (`view`, `fit`): per source its pixel grid, pose, depths and
//!    the pixels its self-filter took as the robot, from a depth image or an organized cloud;
//! 2. [`observe`] (`observe`): a cell is seen free when, in some view, the 2 × 2 pixels around
//!    its centre's projection all returned beyond it (less the range noise); the rest is
//!    unseen, and `self_shadow` where only the robot's body stood in front. The caller then
//!    drops the cells of the robot's padded volume, of the exclusion volumes and of attached
//!    objects ([`Observation::drop_where`], [`Observation::drop_excluded`]);
//! 3. [`open`] (`opening`, on `morphology`'s stencil erosion and box dilation, `edt`'s exact
//!    distance transform past 256 offsets): the unseen cells that could hold a ball of the
//!    detection capability's diameter, so that isolated dropped pixels do not count and a dark
//!    torso does (the dilation by the box that encloses the ball: a superset, still certified);
//! 4. [`unseen_distance`] (`distance`): the caller's certified lower bound over the opened
//!    cells' centres less a cell diagonal and the pixel slack; `None` (NaN) when none is left.
//!    The same over `self_shadow` tells the robot's own shadow apart.
//!
//! **What is guaranteed.** Take a ball of diameter `D` (the detection capability) inside the
//! lattice and outside what the caller dropped, such that every pixel whose centre ray meets it
//! returns nothing (a dark body). Then [`unseen_distance`] over the opened cells, and already
//! over the opened cells inside that ball, is no more than the distance from the robot to the
//! ball (property test in `tests/unseen.rs`: random camera poses, intrinsics, dropout masks,
//! capabilities and resolutions, against a brute-force distance to a box robot; with no margin,
//! or with a wider erosion, it fails). A body behind a nearer surface is unseen by the same
//! rule (its block's pixels return in front of it); the generator's "person in the shadow"
//! should check that end to end. A body some pixel does see is measured by the distance to the
//! points. If the ball also keeps a pixel clear of the robot's image (no robot in front of it
//! within a pixel of its outline), the same holds for the opening of
//! [`Observation::beyond_self_shadow`] alone.
//!
//! **The robot's own shadow.** With one camera the space behind the arm is unseen and touches
//! it, so the distance over every opened cell is about zero. `self_shadow` marks it; what the
//! monitor does there is its policy (e.g. count the shadow only where no other camera sees it,
//! which the fusion over views already does, and report the shadow's distance apart).
//!
//! **Not here yet.** The GPU path (the lattice projected in the query's submission) is not
//! written: this is the CPU pass (rayon). Lidars without an organized scan observe nothing
//! free ([`RangeView::from_organized_cloud`] refuses them).
//!
//! Cost: O(cells × views) for the observation, O(cells) for each opening. Measured by the test
//! `kinect_scene_runs` (a 2 × 2 × 2 m volume at 2 cm, 10⁶ cells, one 640 × 480 view), release
//! build, 2-core VM, 2026-11-27. Quiet machine, three runs, before the opening's stencil and box:
//! observe 12.6–15.2 ms, open 52.7–69.3 ms (two distance transforms), the distance 2.1–3.2 ms.
//! With them, five runs while another build loaded the machine (load 3.4–3.6; observe took
//! 26.6–71.1 ms there): open 7.3–11.9 ms, against 117–194 ms for the former opening
//! ([`open_exact`], the two transforms) in the same runs, 15–21 times less; the opening and
//! distance beyond the robot's shadow 9.6–14.5 ms. Both openings of a frame then stay within a
//! fraction of the observation's cost.

//! Files: `error`, `lattice`, `view` and `fit`, `observe`, `morphology`, `edt`, `opening`,
//! `distance`.

mod distance;
mod edt;
mod error;
mod fit;
mod lattice;
mod morphology;
mod observe;
mod opening;
mod robot;
mod view;

pub use distance::unseen_distance;
pub use error::UnseenError;
pub use fit::{fit_pinhole, MAX_RESIDUAL_PX, MIN_FIT_POINTS};
pub use lattice::{Lattice, DEFAULT_RESOLUTION_M, MAX_CELLS};
pub use observe::{observe, Observation};
#[doc(hidden)]
pub use opening::open_exact;
pub use opening::{open, Opened, DEFAULT_DETECTION_CAPABILITY_M};
pub use robot::{flag_robot_pixels, place, robot_cells, robot_lattice, PaddedSphere, RobotCells};
pub use view::{RangeView, DEFAULT_RANGE_NOISE_M};
