//! Work counters of a query's traversal, kept alike by both backends (`WorkCounts`): the
//! blocks, those culled whole, the (block, link) items measured, the tree descents begun and the
//! tree nodes expanded. The GPU counts in workgroup atomics (`shaders/traverse.wgsl`); the CPU
//! counts per thread, here, with one thread-local add per block or descent and none per node,
//! and each rayon task hands its counts over when it ends ([`counted`]).

use std::cell::Cell;
use std::sync::atomic::{AtomicU64, Ordering::Relaxed};

use serde::Serialize;

use super::layout::{Work, WORK_COUNTERS};

/// Counts per [`Work`].
pub(super) type Tally = [u64; WORK_COUNTERS];

thread_local! {
    /// What this thread counted since it last handed its counts over.
    static TALLY: Cell<Tally> = const { Cell::new([0; WORK_COUNTERS]) };
}

/// Adds `n` to counter `w` of this thread.
#[inline(always)]
pub(super) fn add(w: Work, n: u64) {
    TALLY.with(|t| {
        let mut v = t.get();
        v[w as usize] += n;
        t.set(v);
    });
}

/// One descent that expanded `nodes` nodes (per point).
#[inline(always)]
pub(super) fn descended(descents: u64, nodes: u64) {
    TALLY.with(|t| {
        let mut v = t.get();
        v[Work::Descents as usize] += descents;
        v[Work::Nodes as usize] += nodes;
        t.set(v);
    });
}

/// Runs `f` and returns what it counted on this thread (what the thread counted before, outside
/// any traversal — a result's closest-point descent, a self-filter grid — is left out).
pub(super) fn counted<R>(f: impl FnOnce() -> R) -> (R, Tally) {
    TALLY.with(|t| t.set([0; WORK_COUNTERS]));
    let r = f();
    (r, TALLY.with(|t| t.replace([0; WORK_COUNTERS])))
}

/// The sum of two tallies.
pub(super) fn sum(a: Tally, b: Tally) -> Tally {
    std::array::from_fn(|k| a[k] + b[k])
}

/// The work of the last query's traversal, counted alike on both backends so that the GPU's
/// pruning can be compared with the CPU's on any machine (`Engine::last_work`).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct WorkCounts {
    /// Blocks of `layout::BLOCK` points.
    pub blocks: u64,
    /// Blocks dropped whole by their box: no valid point, outside the region of interest, or
    /// beyond every link's reach.
    pub blocks_culled: u64,
    /// (Block, link) pairs whose points were measured against the link.
    pub items: u64,
    /// Tree descents begun (a point against a link's tree, self-filter ones included).
    pub descents: u64,
    /// Tree nodes expanded, per point (a packet's node counts once for each point in it).
    pub nodes: u64,
}

impl From<&[AtomicU64; WORK_COUNTERS]> for WorkCounts {
    /// The counters as `Bounds::work` keeps them, one per [`Work`].
    fn from(c: &[AtomicU64; WORK_COUNTERS]) -> Self {
        let w = |k: Work| c[k as usize].load(Relaxed);
        Self {
            blocks: w(Work::Blocks),
            blocks_culled: w(Work::Culled),
            items: w(Work::Items),
            descents: w(Work::Descents),
            nodes: w(Work::Nodes),
        }
    }
}
