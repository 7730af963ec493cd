//! The dispatches of one GPU query ([`Step`]) and how they are recorded: in three compute passes
//! (the ones before `plan`, `plan`, the ones after: the dispatch buffer `plan` writes is read as
//! indirect arguments after it), after a fourth for a depth image's `unproject` (its own bind
//! group, which writes the points the others read) and, where the unseen space asks, a fifth
//! for its `cells` (`cell.rs`; its own bind group too), with a timestamp at each end; or, to profile, each dispatch in a
//! pass of its own with its own timestamps (`bench gpu --passes`).

use super::engine::Pipelines;
use crate::query::layout::{SEED_STRIDE, WORKGROUP};

/// Most dispatches in one query.
pub(super) const MAX_STEPS: usize = 11;
/// Room for the timestamps in the readback.
pub(super) const STAMP_BYTES: u64 = 16 * MAX_STEPS as u64;

/// How many workgroups a dispatch runs.
pub(super) enum Size {
    Groups(u32),
    /// Read from the dispatch buffer at this offset (written by `plan`).
    Indirect(u64),
}

/// One dispatch of a query.
pub(super) struct Step<'a> {
    pub(super) name: &'static str,
    pub(super) pipeline: &'a wgpu::ComputePipeline,
    pub(super) size: Size,
    /// Binds the dispatch buffer for writing (`plan`): in a pass apart from its readers.
    pub(super) writes_dispatch: bool,
    /// Its own bind group, instead of the traversal's (`unproject`): in a pass of its own.
    pub(super) group: Option<&'a wgpu::BindGroup>,
}

impl<'a> Step<'a> {
    pub(super) fn direct(
        name: &'static str,
        pipeline: &'a wgpu::ComputePipeline,
        groups: u32,
    ) -> Self {
        Self {
            name,
            pipeline,
            size: Size::Groups(groups),
            writes_dispatch: false,
            group: None,
        }
    }

    pub(super) fn indirect(
        name: &'static str,
        pipeline: &'a wgpu::ComputePipeline,
        offset: u64,
    ) -> Self {
        Self {
            name,
            pipeline,
            size: Size::Indirect(offset),
            writes_dispatch: false,
            group: None,
        }
    }
}

/// Records `steps` into `encoder`: in compute passes (the unprojection's, the ones before `plan`,
/// `plan`, the ones after it) with
/// a timestamp at the start of the first and the end of the last; or, with `profile`, each in a
/// pass of its own with a timestamp at each end. Returns the index of the last timestamp.
pub(super) fn encode(
    encoder: &mut wgpu::CommandEncoder,
    steps: &[Step],
    group: &wgpu::BindGroup,
    dispatch_group: &wgpu::BindGroup,
    dispatch: &wgpu::Buffer,
    stamps: Option<&wgpu::QuerySet>,
    profile: bool,
) -> u32 {
    // The passes: runs of steps, cut around the one that writes the dispatch buffer and those
    // with a bind group of their own.
    let mut passes: Vec<&[Step]> = Vec::new();
    if profile {
        passes.extend(steps.chunks(1));
    } else {
        let mut start = 0;
        for (k, step) in steps.iter().enumerate() {
            if step.writes_dispatch || step.group.is_some() {
                passes.extend([&steps[start..k], &steps[k..k + 1]]);
                start = k + 1;
            }
        }
        passes.push(&steps[start..]);
        passes.retain(|p| !p.is_empty());
    }
    let last = passes.len().saturating_sub(1);
    let end = if profile { 2 * last as u32 + 1 } else { 1 };
    for (k, run) in passes.iter().enumerate() {
        let timestamp_writes = stamps.and_then(|set| {
            let (begin, end) = if profile {
                (Some(2 * k as u32), Some(2 * k as u32 + 1))
            } else {
                ((k == 0).then_some(0), (k == last).then_some(1))
            };
            (begin.is_some() || end.is_some()).then_some(wgpu::ComputePassTimestampWrites {
                query_set: set,
                beginning_of_pass_write_index: begin,
                end_of_pass_write_index: end,
            })
        });
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some(run[0].name),
            timestamp_writes,
        });
        pass.set_bind_group(0, run[0].group.unwrap_or(group), &[]);
        for step in *run {
            pass.set_pipeline(step.pipeline);
            if step.writes_dispatch {
                pass.set_bind_group(1, dispatch_group, &[]);
            }
            match step.size {
                Size::Groups(0) => {}
                Size::Groups(n) => pass.dispatch_workgroups(n, 1, 1),
                Size::Indirect(offset) => pass.dispatch_workgroups_indirect(dispatch, offset),
            }
        }
    }
    end
}

/// Workgroups of a dispatch over `n` units of work, each workgroup looping over the rest
/// (the passes stride by the number of workgroups).
pub(super) fn groups(n: usize) -> u32 {
    n.min(65_535) as u32
}

/// The dispatches of a query of `n` points in `n_blocks` blocks, `l` links and `n_winners` seeds
/// from the last query, in order (the shader's header says what each does).
pub(super) fn steps(
    p: &Pipelines,
    n: usize,
    n_blocks: usize,
    l: usize,
    n_winners: u32,
) -> Vec<Step<'_>> {
    let mut steps = Vec::new();
    if n > 0 {
        let samples = (n as u32).div_ceil(SEED_STRIDE).div_ceil(WORKGROUP);
        steps.push(Step::direct("seed_scan", &p.seed_scan, samples));
        if let Some(pick) = &p.seed_pick {
            steps.push(Step::direct("seed_pick", pick, samples));
        }
        let pairs = (l as u32 + n_winners) * l as u32;
        steps.push(Step::direct("seed", &p.seed, pairs.div_ceil(WORKGROUP)));
        let cull = n_blocks.div_ceil(WORKGROUP as usize);
        steps.push(Step::direct("cull", &p.cull, groups(cull)));
        // The kept blocks are a few percent: as many workgroups as could be resident at
        // once on a large GPU, each taking block after block.
        steps.push(Step::direct(
            "blocks",
            &p.blocks,
            groups(n_blocks.min(4096)),
        ));
    }
    steps.push(Step {
        name: "plan",
        pipeline: &p.plan,
        size: Size::Groups(1),
        writes_dispatch: true,
        group: None,
    });
    steps.push(Step::indirect("measure", &p.measure, 0));
    steps.push(Step::indirect("tally", &p.tally, 12));
    if let Some(argmin) = &p.argmin {
        steps.push(Step::indirect("argmin", argmin, 0));
    }
    steps
}
