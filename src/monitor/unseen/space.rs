//! [`UnseenSpace`]: the cell's unseen space as the monitor keeps it (see the folder's doc): its
//! config slice, its sources' views, its latest pass, and what the separation stage and the
//! latency budget read of it.

use nalgebra::Isometry3;

use crate::cloud::exclusion::ExclusionVolume;
use crate::cloud::RangeLimits;
use crate::config::{Config, Unobserved};
use crate::query::{Mode, QueryLink, QueryOptions};
use crate::unseen::{padded_spheres, Lattice, PaddedSphere, PreparedView, RangeView, RobotImage};

use super::error::UnseenFault;
use super::facts::Unseen;

/// What each source gives the pass.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct SourceSlice {
    pub(super) name: String,
    pub(super) enabled: bool,
    pub(super) range_noise_m: f64,
    pub(super) limits: Option<RangeLimits>,
}

/// The cell's unseen space: its settings, its views and its latest pass (see the module doc).
pub struct UnseenSpace {
    pub(super) settings: Unobserved,
    pub(super) sources: Vec<SourceSlice>,
    /// The exclusion volumes that apply to every source.
    pub(super) volumes: Vec<ExclusionVolume>,
    /// The query over the hidden places: certified at least, no self-filter.
    pub(super) query: QueryOptions,
    pub(super) padding_m: f32,
    pub(super) tf_tolerance_s: f64,
    /// Per source: its latest frame's view, or why it observes nothing free.
    pub(super) views: Vec<Option<Result<PreparedView, String>>>,
    /// Per source: its latest view's cells as the GPU judged them, if it did.
    pub(super) gpu_cells: Vec<GpuCells>,
    /// The robot's reach from its root (m), once computed for the default volume.
    pub(super) reach_m: Option<Option<f64>>,
    /// The time the frame being measured spent on its view (made and prepared), s.
    pub(super) view_s: f64,
    /// The robot's padded spheres its view was prepared with, and the poses they were placed
    /// at: handed to the same frame's pass (`take_spheres`), which places them only where
    /// there are none.
    pub(super) spheres: Option<(Vec<Isometry3<f64>>, Vec<PaddedSphere>)>,
    /// Whether anyone reads the markers (`~/closest_points`) by discovery; `None` where the
    /// caller cannot tell (`replay`, the benches): then they are made as configured.
    pub(super) markers_read: Option<bool>,
    pub(super) last: Option<Unseen>,
}

impl UnseenSpace {
    pub fn new(config: &Config) -> Self {
        let mut space = Self {
            settings: config.unobserved.clone(),
            sources: Vec::new(),
            volumes: Vec::new(),
            query: config.query.clone(),
            padding_m: 0.0,
            tf_tolerance_s: config.tf_tolerance_s,
            views: (0..config.sources.len()).map(|_| None).collect(),
            gpu_cells: vec![GpuCells::default(); config.sources.len()],
            reach_m: None,
            view_s: 0.0,
            spheres: None,
            markers_read: None,
            last: None,
        };
        space.reconfigure(config);
        space
    }

    /// Takes the slice of `config` (a run-time change: sources enabled or disabled, exclusion
    /// volumes); a source whose enabled flag changed forgets its view.
    pub fn reconfigure(&mut self, config: &Config) {
        let sources: Vec<SourceSlice> = (config.sources.iter())
            .map(|s| SourceSlice {
                name: s.name.clone(),
                enabled: s.enabled,
                range_noise_m: s.range_noise_m,
                limits: RangeLimits::new(s.min_range_m, s.max_range_m),
            })
            .collect();
        for (k, s) in sources.iter().enumerate() {
            if self
                .sources
                .get(k)
                .is_some_and(|old| old.enabled != s.enabled)
            {
                self.views[k] = None;
                self.gpu_cells[k] = GpuCells::default();
            }
        }
        self.sources = sources;
        self.settings = config.unobserved.clone();
        self.volumes = (config.exclusion_volumes.iter())
            .filter(|v| v.sources.is_empty())
            .cloned()
            .collect();
        let mut query = config.query.clone();
        if query.mode == Mode::Fast {
            query.mode = Mode::Certified;
        }
        self.padding_m = query.self_filter_padding_m.unwrap_or(0.0);
        query.self_filter_padding_m = None;
        self.query = query;
        self.tf_tolerance_s = config.tf_tolerance_s;
    }

    /// Whether the pass runs at all (`unobserved: ignore` costs nothing).
    pub fn enabled(&self) -> bool {
        self.settings.enabled()
    }

    /// Whether the level, the stop and the speed factor take the unseen distance.
    pub fn protects(&self) -> bool {
        self.settings.protects()
    }

    pub fn settings(&self) -> &Unobserved {
        &self.settings
    }

    /// Source `source` left no view (its frame was a fault, it was disabled or restarted).
    pub fn forget(&mut self, source: usize) {
        self.views[source] = None;
        self.gpu_cells[source] = GpuCells::default();
        self.spheres = None;
    }

    /// Every source's view forgotten, and the latest pass (the clock went back).
    pub fn forget_all(&mut self) {
        self.views.iter_mut().for_each(|v| *v = None);
        self.spheres = None;
        self.gpu_cells
            .iter_mut()
            .for_each(|c| *c = GpuCells::default());
        self.last = None;
    }

    /// Source `source`'s latest frame: its view, or why it observes nothing free, made in
    /// `made_s` seconds, prepared with the robot at that frame's `poses` (rendered into it with
    /// the self-filter padding and each link's h). Nothing with `unobserved: ignore`.
    pub fn observe(
        &mut self,
        source: usize,
        view: Result<RangeView, String>,
        made_s: f64,
        links: &[QueryLink],
        poses: &[Isometry3<f64>],
    ) {
        if !self.enabled() {
            return;
        }
        let start = std::time::Instant::now();
        // The robot's image is read by the search only for the shadow apart; otherwise the
        // causes of what it found render what they read (`pass`).
        let image = if self.settings.self_shadow == crate::config::SelfShadow::Apart {
            RobotImage::Whole
        } else {
            RobotImage::Deferred
        };
        let made = view.map(|view| {
            let mut prepared = match self.views[source].take() {
                Some(Ok(p)) => p,
                _ => PreparedView::default(),
            };
            let spheres = self.take_spheres(links, poses);
            prepared.prepare(&view, &spheres, image);
            self.spheres = Some((poses.to_vec(), spheres));
            prepared
        });
        self.views[source] = Some(made);
        self.gpu_cells[source] = GpuCells::default();
        self.view_s = made_s + start.elapsed().as_secs_f64();
    }

    /// Whether anyone reads the markers now (the node, by discovery): where nobody does, the
    /// pass keeps no hidden places for them and names no causes but the nearest's.
    pub fn set_markers_read(&mut self, read: Option<bool>) {
        self.markers_read = read;
    }

    /// Whether the pass runs and draws markers (`unobserved_markers` above 0).
    pub fn draws_markers(&self) -> bool {
        self.enabled() && self.settings.markers > 0
    }

    /// The hidden places kept for the markers: the configured count, or none while nobody
    /// reads them.
    pub(super) fn markers(&self) -> usize {
        match self.markers_read {
            Some(false) => 0,
            _ => self.settings.markers,
        }
    }

    /// The robot's spheres at `poses`, padded for the views (each grown by the self-filter
    /// padding and its link's h): those the frame's view was prepared with where they were
    /// placed at `poses`, else placed now. Taken: a later frame places its own.
    pub(super) fn take_spheres(
        &mut self,
        links: &[QueryLink],
        poses: &[Isometry3<f64>],
    ) -> Vec<PaddedSphere> {
        match self.spheres.take() {
            Some((at, spheres)) if at == poses => spheres,
            _ => padded_spheres(links, poses, self.padding_m, self.smallest_sphere_m()),
        }
    }

    /// The camera of source `source`'s latest view, for its next cloud to keep where it fits.
    pub fn known_camera(&self, source: usize) -> Option<crate::cloud::depth::PinholeCamera> {
        match &self.views[source] {
            Some(Ok(p)) => p.camera().copied(),
            _ => None,
        }
    }

    /// The range limits and noise of source `source`.
    pub fn source_limits(&self, source: usize) -> (Option<RangeLimits>, f64) {
        let s = &self.sources[source];
        (s.limits, s.range_noise_m)
    }

    /// Source `source`'s latest view, as the passes judge it (`None`: none, or why not).
    pub fn view(&self, source: usize) -> Option<&PreparedView> {
        self.views.get(source)?.as_ref()?.as_ref().ok()
    }

    /// Source `source`'s latest view with the robot's image rendered whole, to draw it.
    pub fn view_whole(&mut self, source: usize) -> Option<&PreparedView> {
        let view = self.views.get_mut(source)?.as_mut()?.as_mut().ok()?;
        view.render_robot_whole();
        Some(view)
    }

    /// The latest pass (`None` before the first, and with `unobserved: ignore`).
    pub fn last(&self) -> Option<&Unseen> {
        self.last.as_ref().filter(|_| self.enabled())
    }

    /// Under `protect`, a frame whose processing with the pass (`processing_s`) exceeds the
    /// latency budget `budget_s` makes the latest pass a fault: too late to act on. The cell's
    /// fault from the latest pass under `protect` (a late one included), if any.
    pub fn check_late(&mut self, processing_s: f64, budget_s: f64) -> Option<UnseenFault> {
        if !self.protects() {
            return None;
        }
        let last = self.last.as_mut()?;
        if processing_s > budget_s {
            last.outcome = Err(UnseenFault::Late {
                elapsed_ms: processing_s * 1e3,
                budget_ms: budget_s * 1e3,
            });
        }
        last.outcome.as_ref().err().cloned()
    }

    /// The per-link unseen distances the separation stage holds each link to under `protect`
    /// (the engine's order; `None` where the pass is off, failed or found nothing hidden: then
    /// the seen distances alone apply, or a fault already stops the cell).
    pub fn protecting_links(&self, links: usize) -> Option<Vec<f64>> {
        if !self.protects() {
            return None;
        }
        let facts = self.last()?.outcome.as_ref().ok()?;
        let d = facts.distance_m?;
        if facts.per_link.len() == links {
            Some(facts.per_link.iter().map(|(_, l)| l.max(d)).collect())
        } else {
            // Per-link minima off: every link is at least as far as the nearest.
            Some(vec![d; links])
        }
    }

    /// The smallest sphere rendered into a view, and taken for the cells the robot holds: a
    /// quarter cell. The padding and the larger spheres about them cover most of the smaller
    /// ones' image, and leaving them out leaves a ray not the robot's, or a cell undropped: the
    /// conservative side.
    pub(super) fn smallest_sphere_m(&self) -> f32 {
        (0.25 * self.settings.resolution_m) as f32
    }
}

/// One source's cells judged on the GPU: the lattice asked for, and its verdicts once read.
#[derive(Debug, Clone, Default)]
pub(super) struct GpuCells {
    pub(super) lattice: Option<Lattice>,
    pub(super) verdicts: Option<Vec<u32>>,
}

impl GpuCells {
    /// The verdicts, where they were made on `lattice`.
    pub(super) fn verdicts_on(&self, lattice: &Lattice) -> Option<&[u32]> {
        match (&self.lattice, &self.verdicts) {
            (Some(l), Some(v)) if l == lattice && v.len() == l.len() => Some(v),
            _ => None,
        }
    }
}
