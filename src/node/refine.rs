//! The fine trees of a first start: where the monitor started on coarse trees (a fixed budget
//! of `start_spheres`, `Monitor::with_model_first`), the thread that made it builds the trees of
//! the config's packing options and sends them here; the serving loop swaps them in with
//! `Monitor::swap_trees`, which keeps inputs, sources and levels, so monitoring never stops.

use crate::ist::{IstError, LinkTree};
use crate::monitor::{Monitor, Refinement};

/// Nice value of the threads that build the fine trees: the queries of the running monitor come
/// first.
const REFINE_NICE: i32 = 10;

/// Builds the refinement's trees on a pool of its own (a thread per core, each at nice
/// `REFINE_NICE`), so that the monitor's queries, which run on rayon's global pool, never wait
/// in a queue behind the packing, and the scheduler gives them the cores first; the packing
/// takes what they leave. On the global pool if that pool cannot be made.
pub(super) fn build(refinement: &Refinement) -> Result<Vec<LinkTree>, IstError> {
    let pool = rayon::ThreadPoolBuilder::new()
        .thread_name(|i| format!("trees refine {i}"))
        .start_handler(|_| lower_priority())
        .build();
    match pool {
        Ok(pool) => pool.install(|| refinement.build(&|_| {})),
        Err(e) => {
            log::warn!("no thread pool of its own for the fine trees ({e}): built on rayon's");
            refinement.build(&|_| {})
        }
    }
}

/// Lowers the calling thread's priority (Linux: `setpriority` with `who` 0 sets the calling
/// thread's nice value); a failure leaves it as it was.
fn lower_priority() {
    #[cfg(target_os = "linux")]
    // SAFETY: setpriority takes plain integers and touches no memory of ours.
    unsafe {
        libc::setpriority(libc::PRIO_PROCESS, 0, REFINE_NICE);
    }
}

/// The trees of the config's options and the attached objects they are for, from the thread
/// that started the monitor on coarse trees (nothing arrives where it did not).
pub(super) type Refined = std::sync::mpsc::Receiver<(
    Result<Vec<crate::ist::LinkTree>, crate::ist::IstError>,
    Vec<crate::robot::AttachedObject>,
)>;

/// Swaps in the trees of the config's options once they are built, where the monitor
/// started on coarse ones: monitoring goes on throughout (inputs, levels and sources stay).
/// If they cannot be built, or the attached objects changed meanwhile, the coarse trees
/// stay, certified as they are.
pub(super) fn swap_in(slot: &mut Option<Refined>, monitor: &mut Monitor) {
    let Some(refined) = slot.as_ref() else {
        return;
    };
    let (trees, attached) = match refined.try_recv() {
        Ok(r) => r,
        Err(std::sync::mpsc::TryRecvError::Empty) => return,
        Err(std::sync::mpsc::TryRecvError::Disconnected) => {
            *slot = None;
            return;
        }
    };
    *slot = None;
    let largest = |gaps: Vec<(String, f64)>| gaps.into_iter().map(|(_, h)| h).fold(0.0, f64::max);
    let before = largest(monitor.link_gaps());
    match trees.map_err(|e| e.to_string()).and_then(|trees| {
        monitor
            .swap_trees(&trees, &attached)
            .map_err(|e| e.to_string())
    }) {
        Ok(()) => log::info!(
            "monitoring on the trees of the config's packing options: h up to {:.3} mm (the \
             coarse trees': {:.3} mm)",
            largest(monitor.link_gaps()) * 1e3,
            before * 1e3
        ),
        Err(e) => log::warn!(
            "the trees of the config's packing options are not used ({e}): monitoring goes \
             on with the coarse trees, h up to {:.3} mm",
            before * 1e3
        ),
    }
}
