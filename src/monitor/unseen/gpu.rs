//! The GPU's part of the pass: for a depth image measured on the GPU, the request that the
//! query's submission also judge the lattice's cells in this frame's view
//! (`query::gpu::cell`, `shaders/cell.wgsl`: the image uploaded once serves both), and the
//! verdicts it returns, kept with the view for the search (`unseen::cell`), which then scans a
//! footprint on the CPU only where it needs a cause.
//!
//! The request is made after the view is prepared and before the query, with the lattice placed
//! as the pass will place it at the same stamp; the verdicts count only for a pass whose lattice
//! is that one (a volume on a moving frame, placed again, is judged on the CPU).

use crate::query::layout::CellParams;
use crate::query::Engine;
use crate::unseen::{BallSize, Lattice, ROUNDING_M};

use super::pass::At;
use super::space::{GpuCells, UnseenSpace};

impl UnseenSpace {
    /// Asks `engine`'s next query (source `source`'s depth image, its view just observed) to
    /// judge the cells on the GPU; nothing where there is no GPU, no view, or the volume cannot
    /// be placed (the pass then says why).
    pub fn request_cells(&mut self, source: usize, at: &At, engine: &mut Engine) {
        self.gpu_cells[source] = GpuCells::default();
        let request = if engine.gpu().is_some() {
            self.cells_params(source, at, engine)
        } else {
            None
        };
        if let Some((lattice, params)) = request {
            self.gpu_cells[source].lattice = Some(lattice);
            engine.request_cells(Some(params));
        } else {
            engine.request_cells(None);
        }
    }

    /// Source `source`'s latest view's cells as the GPU judged them: the lattice and one word a
    /// cell (`unseen::cell`), if it did.
    pub fn gpu_cells(&self, source: usize) -> Option<(&Lattice, &[u32])> {
        let cells = self.gpu_cells.get(source)?;
        let lattice = cells.lattice.as_ref()?;
        Some((lattice, cells.verdicts_on(lattice)?))
    }

    /// The verdicts of the query just run for source `source` (none where it ran on the CPU).
    pub fn take_cells(&mut self, source: usize, engine: &mut Engine) {
        let verdicts = engine.take_cells();
        engine.request_cells(None);
        let cells = &mut self.gpu_cells[source];
        cells.verdicts = verdicts.filter(|_| cells.lattice.is_some());
    }

    fn cells_params(
        &mut self,
        source: usize,
        at: &At,
        engine: &Engine,
    ) -> Option<(Lattice, CellParams)> {
        let lattice = self.place_volume(at, engine.links()).ok()?;
        let ball = BallSize::new(&lattice, self.settings.detection_capability_m).ok()?;
        let view = self.view(source)?;
        let o = view.optics();
        let (origin, steps) = lattice.in_frame(view.camera_from_root());
        let [n0, n1, n2] = lattice.dims().map(|n| u32::try_from(n).ok());
        let (cos_k, sin_k) = o.pixel_cos_sin();
        let v4 = |v: [f32; 3]| [v[0], v[1], v[2], 0.0];
        let params = CellParams {
            width: u32::try_from(o.width).ok()?,
            height: u32::try_from(o.height).ok()?,
            n0: n0?,
            n1: n1?,
            n2: n2?,
            cells: u32::try_from(lattice.len()).ok()?,
            pad0: 0,
            pad1: 0,
            fx: o.fx,
            fy: o.fy,
            cx: o.cx,
            cy: o.cy,
            min_range: o.min_range_m,
            // A uniform holds no infinity on every driver: the largest finite f32 compares alike.
            max_range: o.max_range_m.min(f32::MAX),
            noise: view.range_noise_m(),
            rounding: ROUNDING_M,
            cos_k,
            sin_k,
            ball: ball.radius_m,
            sub_ball: ball.sub_radius_m,
            origin: v4(origin),
            step0: v4(steps[0]),
            step1: v4(steps[1]),
            step2: v4(steps[2]),
        };
        Some((lattice, params))
    }
}
