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
//!    frame of its source, its free distance and the robot's padded body along every ray (the
//!    robot only where the search or the causes read it: [`RobotImage`]), and their min/max
//!    pyramids;
//! 2. the footprint test (`footprint`), per view and ball; the cell's verdict over the views
//!    (`cell`);
//! 3. the search (`search`): blocks of centres in the order of their bound from the robot
//!    (`robot`), only those that can be nearer than the best distance found (`needs`: the
//!    links and covers that may bring a block's centres within a best still open, once a
//!    block), a block that one view sees wholly free skipped; the caller's certified distance
//!    over the hidden centres,
//!    wave by wave ([`Measure`]: the pairs of centre and link best first, a link's tree
//!    descended only where its cheaper bounds say it may matter);
//! 4. the causes of the nearest hidden place and of those kept for markers
//!    ([`Search::name_causes`]);
//! 5. [`BallSize::distance`]: that distance less `R + d/2` (the hidden ball's nearest point is
//!    `R` from its centre, which is within `d/2` of the lattice centre), floored at 0.
//!
//! The GPU judges the cells of a depth image's view in the query's submission where the query
//! runs there (`shaders/cell.wgsl`, the rule of `footprint` without its shortcuts); a
//! [`PlacedView`] carrying its verdicts answers from them (`cell`).
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
//! Files: `error`, `lattice`, `ball`, `view` and `fit`, `camera`, `prepared` and `pyramid`,
//! `robot`, `footprint` and `tiles`, `cell`, `search` and `needs`, `measure`, `least` (the
//! best-first heaps' entry).

mod ball;
mod camera;
mod cell;
mod error;
mod fit;
mod footprint;
mod lattice;
mod least;
mod measure;
mod needs;
mod prepared;
mod pyramid;
mod robot;
mod search;
mod tiles;
mod view;

pub use ball::{BallSize, DEFAULT_DETECTION_CAPABILITY_M};
pub use camera::{Cone, Optics, Rect};
pub use cell::{in_shadow, judge_cell, CellSeen, PlacedView};
pub use error::UnseenError;
pub use fit::{fit_pinhole, MAX_RESIDUAL_PX, MIN_FIT_POINTS};
pub use footprint::{judge, Cause, Need, Pixels, Seen, Why, ROUNDING_M};
pub use lattice::{centre_at, Lattice, DEFAULT_RESOLUTION_M, MAX_CELLS};
pub use measure::{Batch, Measure};
pub use prepared::{unit_rays, PreparedView, RobotImage};
pub use pyramid::{Pyramid, Pyramids};
pub use robot::{link_bounds, padded_spheres, place, LinkBound, PaddedSphere, RobotBody};
pub use search::{fused_cause, Counts, Found, Search, Spot, BLOCK};
pub use view::{RangeView, DEFAULT_RANGE_NOISE_M};
