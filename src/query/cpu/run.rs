//! Steps 2 and 3 on the CPU, run in order for one query: the pass's state over the bounds
//! that `Bounds::prepare` filled (step 1), the seeds (`seed.rs`), the main pass over the
//! groups of blocks in parallel (`pass.rs`), the work counts stored; then the shared
//! refinement and assembly (`finish.rs`).

use std::sync::atomic::Ordering::Relaxed;

use rayon::prelude::*;

use super::blocks::GROUP;
use super::pass::{with_scratch, LinkRoots, Pass};
use super::seed;
use crate::query::bounds::Bounds;
use crate::query::finish;
use crate::query::input::Input;
use crate::query::layout::{RobotBox, Tiling};
use crate::query::link::QueryLink;
use crate::query::options::Backend;
use crate::query::result::{QueryResult, StageCounts};
use crate::query::self_grid::SelfGrid;
use crate::query::work::{self, Tally};

/// A query on the CPU, once `bounds` holds the posed links (`Bounds::prepare`, which gave
/// `robot_box`): seeds, the blocks' bounds, the main pass, then the shared refinement and
/// assembly.
pub(in crate::query) fn run(
    links: &[QueryLink],
    grids: &[SelfGrid],
    bounds: &mut Bounds,
    input: Input,
    robot_box: RobotBox,
) -> QueryResult {
    let Input {
        points, options, ..
    } = input;
    let tiling = Tiling::new(points.len(), input.width);
    let pass = Pass {
        links,
        tiling,
        posed: &bounds.posed,
        best: &bounds.best,
        global: &bounds.global,
        global_lower: &bounds.global_lower,
        candidates: &bounds.candidates,
        self_filtered: &bounds.self_filtered,
        points,
        mode: options.mode,
        per_link: options.per_link,
        per_link_range: bounds.posed.iter().map(|p| p.range).fold(0.0, f32::max),
        max_gap: bounds.posed.iter().map(|p| p.gap).fold(0.0, f32::max),
        padding: options.self_filter_padding_m.unwrap_or(f32::NEG_INFINITY),
        grids,
        robot_box,
        roots: LinkRoots::new(&bounds.posed),
    };

    // 2. Seeds.
    let seeded = seed::seeds(&pass, options.per_link);

    // 3. Main pass, one sweep over the cloud in groups of `GROUP` blocks (parallel over the
    // groups): each block is bounded, then culled or descended; within a group the last point
    // measured is carried from block to block, so that a point repeated over many blocks is
    // measured once per group.
    let groups = tiling.blocks().div_ceil(GROUP);
    let (counts, swept) = (0..groups)
        .into_par_iter()
        .map(|g| work::counted(|| with_scratch(links.len(), |f, s| pass.group(g, f, s))))
        .reduce(
            || (StageCounts::default(), Tally::default()),
            |a, b| (a.0 + b.0, work::sum(a.1, b.1)),
        );
    for (a, n) in bounds.work.iter().zip(work::sum(seeded, swept)) {
        a.store(n, Relaxed);
    }

    finish::finish(links, bounds, input, counts, Backend::Cpu)
}
