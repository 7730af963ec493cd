//! A query on the GPU, the host's steps in order ([`HOST_STEPS`](super::HOST_STEPS)): the inputs (the buffers
//! grown, the query's parameters, posed links, counters, minima and last winners written), the
//! upload of the points or of a depth image's bytes, the passes encoded (`passes.rs`) with the
//! readback's copies, the submission, the wait for the readback to be mapped, and the result:
//! the GPU's minima, bounds and counts written into the CPU's [`Bounds`], then the shared
//! refinement and assembly (`finish.rs`), as the CPU's `run` ends.

use std::sync::atomic::Ordering;
use std::time::Instant;

use bytemuck::Zeroable;

use super::engine::GpuEngine;
use super::error::GpuError;
use super::passes::{encode, groups, steps, Step, STAMP_BYTES};
use super::unproject;
use crate::query::bounds::{pack_minimum, threshold, Bounds, EMPTY};
use crate::query::finish;
use crate::query::input::Input;
use crate::query::layout::{
    self, Candidate, CellParams, Counters, DepthParams, Minima, QueryParams, RobotBox, Stage,
    Tiling, GPU_CANDIDATES, MAX_LINKS, SEED_STRIDE,
};
use crate::query::link::QueryLink;
use crate::query::options::{Backend, Mode, QueryOptions};
use crate::query::result::{QueryResult, StageCounts};
use crate::query::self_grid::SelfGrid;

/// A depth image as it crosses: the unprojection's constants and the image's bytes.
type Depth<'a> = (DepthParams, &'a [u8]);

/// Where the parts of one query's readback lie (bytes), and what the timestamps stamped.
struct Readback {
    state_size: u64,
    minima_size: u64,
    stamps_at: u64,
    /// The index of the last timestamp.
    last_stamp: u32,
    /// The dispatches, in order (their times with `profile`).
    passes: Vec<&'static str>,
}

/// What a query reads back: the counters, each link's minimum (as the GPU keeps them) and the
/// exact-mode candidates.
type ReadBack = (Counters, Vec<u64>, Vec<Candidate>);

impl GpuEngine {
    /// The query on the GPU; `bounds` must hold the posed links (`Bounds::prepare`).
    /// Returns `Ok(None)` when the exact candidates or the work items overflowed, or an arg-min
    /// was not found again (the caller runs the CPU).
    /// `grids`: the self-filter's grids for the padding of `input`'s options (none when it is
    /// off).
    pub(in crate::query) fn query(
        &mut self,
        links: &[QueryLink],
        bounds: &mut Bounds,
        robot_box: &RobotBox,
        input: Input,
        grids: &[SelfGrid],
    ) -> Result<Option<QueryResult>, GpuError> {
        let started = Instant::now();
        let (params, depth) = self.inputs(bounds, robot_box, input, grids)?;
        let uploading = Instant::now();
        let upload = match depth {
            Some((params, data)) => {
                let uniform = bytemuck::bytes_of(&params);
                self.queue.write_buffer(&self.unproject.params, 0, uniform);
                self.upload(data)?
            }
            None => self.upload(bytemuck::cast_slice(input.points))?,
        };
        let uploaded = Instant::now();
        // The unseen space's cells, where asked for and the image has pixels: their bind group
        // over the points `unproject` writes, and how many.
        let cells = match (&depth, self.cells.request, self.sized.as_ref()) {
            (Some(_), Some(request), Some(sized)) if params.n_points > 0 => {
                let group =
                    (self.cells).prepare(&self.device, &self.queue, &sized.points, &request);
                Some((group, request.cells))
            }
            _ => None,
        };
        let cell_step = cells.as_ref().map(|(group, n)| (group, *n));
        let (commands, readback) = self.encode(
            &params,
            depth.is_some(),
            upload,
            input.options.mode,
            cell_step,
        )?;
        // The small writes (queue.write_buffer) go first in this submission, then the points'
        // copy, then the passes.
        let written = Instant::now();
        let submission = self.queue.submit([commands]);
        for scope in [self.device.pop_error_scope(), self.device.pop_error_scope()] {
            if let Some(e) = pollster::block_on(scope) {
                return Err(GpuError::Device(e.to_string()));
            }
        }
        let submitted = Instant::now();
        // The staging buffer's map for the next query's points, asked for now: it is done when
        // this submission is (the copy out of it is its first command), in the same poll that
        // maps the readback, so that the next upload finds it mapped instead of waiting on the
        // device once more.
        self.remap_staging();
        self.read_back(submission)?;
        if let Some((_, n)) = cell_step {
            // The query's answer stands without them: the CPU then judges the cells.
            self.cells.last = (self.cells.read(&self.device, n))
                .map_err(|e| log::warn!("the unseen cells' verdicts were lost ({e}): CPU"))
                .ok();
        }
        let mapped = Instant::now();
        let read = self.read(&readback, input.options.mode);
        let Some(counts) = self.write_bounds(read, &params, bounds, input.options) else {
            return Ok(None);
        };
        let result = finish::finish(links, bounds, input, counts, Backend::Gpu);
        self.last_host_s = [
            (uploading - started).as_secs_f64(),
            (uploaded - uploading).as_secs_f64(),
            (written - uploaded).as_secs_f64(),
            (submitted - written).as_secs_f64(),
            (mapped - submitted).as_secs_f64(),
            mapped.elapsed().as_secs_f64(),
        ];
        Ok(Some(result))
    }

    /// Host step "inputs": the cloud's buffers grown for `input`, the self-filter's grids and
    /// the bind group current, then the small writes: the query's parameters (returned, with a
    /// depth image's constants and bytes), the posed links, the counters, the minima and the
    /// last query's winners.
    fn inputs<'a>(
        &mut self,
        bounds: &Bounds,
        robot_box: &RobotBox,
        input: Input<'a>,
        grids: &[SelfGrid],
    ) -> Result<(QueryParams, Option<Depth<'a>>), GpuError> {
        let options = input.options;
        let n = input.len();
        let l = bounds.posed.len();
        // The CPU's blocks: runs, or tiles of an organized cloud (width 0: runs).
        let tiling = Tiling::new(n, input.width);
        let n_blocks = tiling.blocks();
        let (width, height) = tiling.image().unwrap_or((0, 0));
        // A depth image crosses as its bytes (whole words), its points made by the first pass.
        let depth = input
            .depth
            .map(|d| Ok::<_, GpuError>((unproject::params(d)?, d.data())))
            .transpose()?;
        let image_bytes = depth.map_or(0, |(_, data)| data.len().next_multiple_of(4) as u64);
        self.ensure(n, n_blocks, n_blocks * l, image_bytes)?;
        if let Some(padding) = options.self_filter_padding_m {
            self.use_grids(padding, grids)?;
        }
        self.bind();
        let Some(sized) = self.sized.as_ref() else {
            return Err(GpuError::Device("no point buffers".into()));
        };
        if sized.group.is_none() {
            return Err(GpuError::Device("no bind group".into()));
        }
        let winners: Vec<u32> = self
            .last_winners
            .iter()
            .copied()
            .filter(|&i| (i as usize) < n)
            .collect();
        let params = QueryParams {
            robot_box: *robot_box,
            n_points: n as u32,
            n_links: l as u32,
            mode: options.mode.code(),
            per_link: options.per_link as u32,
            stride: SEED_STRIDE,
            n_sample: (n as u32).div_ceil(SEED_STRIDE),
            n_winners: winners.len() as u32,
            capacity: GPU_CANDIDATES,
            pad3: 0,
            width: width as u32,
            height: height as u32,
            n_blocks: n_blocks as u32,
            item_capacity: sized.items_capacity.min(u32::MAX as usize) as u32,
            ..QueryParams::zeroed()
        };
        self.write_inputs(&params, bounds, &winners);
        Ok((params, depth))
    }

    /// The small writes of a query: `params`, the posed links, the counters, the minima (then
    /// the seeds' scan) and the last query's `winners`.
    fn write_inputs(&self, params: &QueryParams, bounds: &Bounds, winners: &[u32]) {
        let l = bounds.posed.len();
        let q = &self.queue;
        q.write_buffer(&self.params, 0, bytemuck::bytes_of(params));
        q.write_buffer(&self.links, 0, bytemuck::cast_slice(&bounds.posed));
        let state = Counters {
            global: f32::INFINITY.to_bits(),
            global_lower: f32::INFINITY.to_bits(),
            seed_key: [u32::MAX; MAX_LINKS],
            seed_point: [u32::MAX; MAX_LINKS],
            ..Counters::zeroed()
        };
        q.write_buffer(&self.state, 0, bytemuck::bytes_of(&state));
        match self.minima {
            // The minima, then the seeds' scan.
            Minima::Packed64 => q.write_buffer(
                &self.minima_buffer,
                0,
                bytemuck::cast_slice(&vec![EMPTY; 2 * l]),
            ),
            Minima::Split32 => {
                let mut minima = vec![f32::INFINITY.to_bits(); l];
                minima.extend(std::iter::repeat_n(u32::MAX, l));
                q.write_buffer(&self.minima_buffer, 0, bytemuck::cast_slice(&minima));
            }
        }
        if !winners.is_empty() {
            q.write_buffer(&self.winners, 0, bytemuck::cast_slice(winners));
        }
    }

    /// Host step "encode": the copy of the `upload` bytes out of the staging memory (into the
    /// image buffer for a `depth` image), the passes (`passes::steps`, after the unprojection
    /// for a depth image) and the copies into the readback, under error scopes that the
    /// submission pops (validation errors of this query come back as an error, on which the
    /// caller runs the CPU, not as wgpu's default panic).
    fn encode(
        &self,
        params: &QueryParams,
        depth: bool,
        upload: u64,
        mode: Mode,
        cells: Option<(&wgpu::BindGroup, u32)>,
    ) -> Result<(wgpu::CommandBuffer, Readback), GpuError> {
        let Some(sized) = self.sized.as_ref() else {
            return Err(GpuError::Device("no point buffers".into()));
        };
        let Some(group) = sized.group.as_ref() else {
            return Err(GpuError::Device("no bind group".into()));
        };
        // The query's sizes, as `inputs` wrote them (the engine checked n to fit 32 bits).
        let (n, n_blocks, l) = (
            params.n_points as usize,
            params.n_blocks as usize,
            params.n_links as usize,
        );
        self.device.push_error_scope(wgpu::ErrorFilter::Validation);
        self.device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
        let mut steps = steps(&self.pipelines, n, n_blocks, l, params.n_winners);
        if depth && n > 0 {
            let unproject = Step {
                group: Some(&sized.image_group),
                ..Step::direct(
                    "unproject",
                    &self.unproject.pipeline,
                    groups(n.div_ceil(layout::WORKGROUP as usize)),
                )
            };
            steps.insert(0, unproject);
            if let Some((group, n)) = cells {
                let judge = Step {
                    group: Some(group),
                    ..Step::direct(
                        "cells",
                        &self.cells.pipeline,
                        groups((n as usize).div_ceil(layout::WORKGROUP as usize)),
                    )
                };
                steps.insert(1, judge);
            }
        }
        let mut encoder = self
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor { label: None });
        if upload > 0 {
            let target = if depth { &sized.image } else { &sized.points };
            encoder.copy_buffer_to_buffer(&sized.staging, 0, target, 0, upload);
        }
        let last_stamp = encode(
            &mut encoder,
            &steps,
            group,
            &self.dispatch_group,
            &self.dispatch,
            self.timestamps.as_ref().map(|(set, _)| set),
            self.profile,
        );
        if let Some((_, n)) = cells {
            self.cells.copy_out(&mut encoder, n);
        }
        let state_size = std::mem::size_of::<Counters>() as u64;
        let minima_size = 8 * l as u64;
        encoder.copy_buffer_to_buffer(&self.state, 0, &self.readback, 0, state_size);
        encoder.copy_buffer_to_buffer(
            &self.minima_buffer,
            0,
            &self.readback,
            state_size,
            minima_size,
        );
        let stamps_at = state_size + minima_size;
        if let Some((set, resolve)) = &self.timestamps {
            encoder.resolve_query_set(set, 0..last_stamp + 1, resolve, 0);
            encoder.copy_buffer_to_buffer(resolve, 0, &self.readback, stamps_at, STAMP_BYTES);
        }
        if mode == Mode::Exact {
            encoder.copy_buffer_to_buffer(
                &self.candidates,
                0,
                &self.readback,
                stamps_at + STAMP_BYTES,
                (std::mem::size_of::<Candidate>() * GPU_CANDIDATES as usize) as u64,
            );
        }
        let readback = Readback {
            state_size,
            minima_size,
            stamps_at,
            last_stamp,
            passes: steps.iter().map(|s| s.name).collect(),
        };
        Ok((encoder.finish(), readback))
    }

    /// Host step "result", first: the counters, minima and candidates out of the mapped
    /// readback, and the times of the kernel and (with `profile`) of each pass.
    fn read(&mut self, at: &Readback, mode: Mode) -> ReadBack {
        let Readback {
            state_size,
            minima_size,
            stamps_at,
            last_stamp,
            ..
        } = *at;
        let slice = self.readback.slice(..);
        let read = {
            let bytes = slice.get_mapped_range();
            let state: Counters = bytemuck::pod_read_unaligned(&bytes[..state_size as usize]);
            let minima: Vec<u64> = bytemuck::pod_collect_to_vec(
                &bytes[state_size as usize..(state_size + minima_size) as usize],
            );
            let stamps: Vec<u64> = bytemuck::pod_collect_to_vec(
                &bytes[stamps_at as usize..(stamps_at + STAMP_BYTES) as usize],
            );
            let period_s = f64::from(self.queue.get_timestamp_period()) * 1e-9;
            let span = |a: usize, b: usize| stamps[b].saturating_sub(stamps[a]) as f64 * period_s;
            self.last_kernel_s = self
                .timestamps
                .as_ref()
                .map(|_| span(0, last_stamp as usize));
            self.last_passes.clear();
            if self.profile && self.timestamps.is_some() {
                for (k, &name) in at.passes.iter().enumerate() {
                    self.last_passes.push((name, span(2 * k, 2 * k + 1)));
                }
            }
            let count = (state.candidate_count.min(GPU_CANDIDATES)) as usize;
            let start = (stamps_at + STAMP_BYTES) as usize;
            let candidates: Vec<Candidate> = if mode == Mode::Exact {
                let end = start + std::mem::size_of::<Candidate>() * count;
                bytemuck::pod_collect_to_vec(&bytes[start..end])
            } else {
                Vec::new()
            };
            (state, minima, candidates)
        };
        self.readback.unmap();
        read
    }

    /// Host step "result", then: what was read back, into the CPU's layout (`bounds`) and this
    /// query's winners kept for the next one's seeds. Returns the stage counts, or `None` when
    /// the exact candidates or the work items overflowed or an arg-min was lost (the CPU
    /// answers; nothing is written then).
    fn write_bounds(
        &mut self,
        (state, minima, candidates): ReadBack,
        params: &QueryParams,
        bounds: &mut Bounds,
        options: &QueryOptions,
    ) -> Option<StageCounts> {
        if state.candidate_count > GPU_CANDIDATES {
            return None;
        }
        if state.item_count > params.item_capacity {
            log::debug!(
                "GPU: {} work items, room for {}",
                state.item_count,
                params.item_capacity
            );
            return None;
        }
        // Each link's minimum, packed as the CPU packs it.
        let packed: Vec<u64> = match self.minima {
            Minima::Packed64 => minima,
            Minima::Split32 => split_minima(&minima, &state, bounds, options)?,
        };
        // Into the CPU's layout, and on through the CPU's refinement and assembly.
        for ((best, &v), winner) in bounds.best.iter().zip(&packed).zip(&mut self.last_winners) {
            best.store(v, Ordering::Relaxed);
            *winner = if v == EMPTY { u32::MAX } else { v as u32 };
        }
        bounds.global.store(state.global, Ordering::Relaxed);
        bounds
            .global_lower
            .store(state.global_lower, Ordering::Relaxed);
        bounds.candidates_mut().extend_from_slice(&candidates);
        for (n, &s) in bounds.self_filtered.iter().zip(&state.self_filtered) {
            n.store(u64::from(s), Ordering::Relaxed);
        }
        for (n, &w) in bounds.work.iter().zip(&state.work) {
            n.store(u64::from(w), Ordering::Relaxed);
        }
        let c = |stage: Stage| u64::from(state.counts[stage as usize]);
        Some(StageCounts {
            total: u64::from(params.n_points),
            invalid: c(Stage::Invalid),
            outside_roi: c(Stage::OutsideRoi),
            self_filtered: c(Stage::SelfFiltered),
            pruned: c(Stage::Pruned),
            evaluated: c(Stage::Evaluated),
            inside: c(Stage::Inside),
            exact_refined: 0,
        })
    }
}

/// The portable path's minima (`[0, l)` f32 bits, `[l, 2 l)` their points, read back as `l`
/// words of 8 bytes) packed as the CPU packs them; `None` when a minimum within its link's
/// final threshold has no point (the CPU answers).
fn split_minima(
    minima: &[u64],
    state: &Counters,
    bounds: &Bounds,
    options: &QueryOptions,
) -> Option<Vec<u64>> {
    let l = minima.len();
    let words: &[u32] = bytemuck::cast_slice(minima);
    let (global, global_lower) = (
        f32::from_bits(state.global),
        f32::from_bits(state.global_lower),
    );
    let mut packed = Vec::with_capacity(l);
    for k in 0..l {
        let (d, p) = (words[k], words[l + k]);
        if d == f32::INFINITY.to_bits() {
            packed.push(EMPTY);
        } else if p != u32::MAX {
            packed.push(pack_minimum(f32::from_bits(d), p));
        } else {
            // No point attains the minimum bit for bit: a seed's upper bound that
            // no exact descent went below, which is only so for a link farther
            // than its final threshold (reported as farther than it, as the CPU
            // reports a link it never measured). Within its threshold, the two
            // descents rounded differently: the CPU answers.
            let t = threshold(
                options.mode,
                options.per_link,
                bounds.posed[k].range,
                global,
                global_lower,
                f32::from_bits(d),
                bounds.posed[k].gap,
            );
            if f32::from_bits(d) <= t {
                return None;
            }
            packed.push(EMPTY);
        }
    }
    Some(packed)
}

impl GpuEngine {
    /// Asks the next depth query to judge the unseen space's cells `request` (`cell.rs`, after
    /// `unproject` in the same submission); `None` takes a request back.
    pub fn request_cells(&mut self, request: Option<CellParams>) {
        self.cells.request = request;
        self.cells.last = None;
    }

    /// The verdicts of the last query that ran the cells' pass (one word a cell), taken.
    pub fn take_cells(&mut self) -> Option<Vec<u32>> {
        self.cells.last.take()
    }
}
