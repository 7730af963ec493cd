//! What a query is asked: its mode, where it runs ([`Backend`]) and the options of the stages
//! that leave points out ([`QueryOptions`]), checked before any point is measured. Distances in
//! metres, crossovers in points or pixels.

use serde::{Deserialize, Serialize};

use super::error::QueryError;
use super::layout;
use crate::choice::Choice;

/// Default crossover of `Backend::Auto` for a cloud, in points: where `ist_monitor bench gpu`
/// puts it on the machine it runs on (docs/gpu.md has the figures of the runs so far). Large
/// clouds only: below it the cloud's upload can cost the GPU more than its kernel saves, and
/// the crossover moves with the CPU beside the GPU. Run the bench on the machine and set
/// `gpu_min_points` from its figure.
pub const DEFAULT_GPU_MIN_POINTS: usize = 5_000_000;

/// Default crossover of `Backend::Auto` for a depth image that the GPU unprojects itself, in
/// pixels: only the image's bytes cross to the device (a sixth of its points'), and the CPU must
/// also make the points, so the GPU wins from far fewer pixels than points (docs/gpu.md;
/// `ist_monitor bench gpu --depth`).
pub const DEFAULT_GPU_MIN_DEPTH_PIXELS: usize = 99_840;

/// What the query computes (each mode's meaning: its [`Choice::about`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Mode {
    Fast,
    Certified,
    Exact,
}

impl Mode {
    /// The mode's code in the shared layout (`layout::MODE_*`, the shader's `params.mode`).
    pub fn code(self) -> u32 {
        match self {
            Mode::Fast => layout::MODE_FAST,
            Mode::Certified => layout::MODE_CERTIFIED,
            Mode::Exact => layout::MODE_EXACT,
        }
    }
}

/// Options of one query.
#[derive(Debug, Clone, PartialEq)]
pub struct QueryOptions {
    pub mode: Mode,
    /// Points farther than this from the robot's bounding box are dropped; a result beyond it is
    /// reported as "nothing within max_distance". Infinity keeps everything.
    pub max_distance_m: f32,
    /// Points within this inner-sphere distance of the robot are the robot itself; `None`
    /// switches the self-filter off.
    pub self_filter_padding_m: Option<f32>,
    /// Per-link minima (one bound per link); off leaves one shared bound, which prunes more.
    pub per_link: bool,
    /// With per-link minima: a link's minimum is measured up to this distance (and always for
    /// the nearest link); a link farther away is reported as farther than a certified bound
    /// ([`crate::query::LinkDistance::farther_than_m`]), which costs far less. Infinity measures every link.
    pub per_link_range_m: f32,
    /// Per link (the engine's order), a range of its own, taken where below
    /// `per_link_range_m` (empty: `per_link_range_m` for every link): a caller that needs only
    /// some links' minima, each below its own bound, asks for no more (both backends read it
    /// from the posed link, `layout::PosedLink::range`).
    pub link_ranges_m: Vec<f32>,
    pub backend: Backend,
    /// `Backend::Auto` uses the GPU for a cloud from this many points on.
    pub gpu_min_points: usize,
    /// `Backend::Auto` uses the GPU for a depth image it can unproject itself (no working frame)
    /// from this many pixels on.
    pub gpu_min_depth_pixels: usize,
}

/// Where a query runs (`auto`'s rule: its [`Choice::about`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Backend {
    Cpu,
    Gpu,
    Auto,
}

impl QueryOptions {
    /// Whether a cloud of `points` points asks for the GPU: always with `gpu`, from
    /// `gpu_min_points` on with `auto` (which still stays on the CPU on a software adapter).
    pub fn wants_gpu(&self, points: usize) -> bool {
        self.wants_gpu_from(points, self.gpu_min_points)
    }

    /// Whether a depth image of `pixels` pixels asks for the GPU: as [`Self::wants_gpu`], from
    /// `gpu_min_depth_pixels` on with `auto`.
    pub fn wants_gpu_for_depth(&self, pixels: usize) -> bool {
        self.wants_gpu_from(pixels, self.gpu_min_depth_pixels)
    }

    fn wants_gpu_from(&self, n: usize, crossover: usize) -> bool {
        match self.backend {
            Backend::Cpu => false,
            Backend::Gpu => true,
            Backend::Auto => n >= crossover,
        }
    }

    /// Link `l`'s range: its own where given and below `per_link_range_m`.
    #[inline]
    pub fn link_range(&self, l: usize) -> f32 {
        (self.link_ranges_m.get(l)).map_or(self.per_link_range_m, |r| r.min(self.per_link_range_m))
    }

    /// Refuses a NaN or negative `max_distance_m`, range or link range, and a negative or
    /// non-finite padding.
    pub fn validate(&self) -> Result<(), QueryError> {
        if self.max_distance_m.is_nan() || self.max_distance_m < 0.0 {
            return Err(QueryError::BadOption(
                "max_distance_m must be ≥ 0 (infinity allowed)",
            ));
        }
        if self.per_link_range_m.is_nan() || self.per_link_range_m < 0.0 {
            return Err(QueryError::BadOption(
                "per_link_range_m must be ≥ 0 (infinity allowed)",
            ));
        }
        if self.link_ranges_m.iter().any(|r| r.is_nan() || *r < 0.0) {
            return Err(QueryError::BadOption(
                "link_ranges_m must each be ≥ 0 (infinity allowed)",
            ));
        }
        if self
            .self_filter_padding_m
            .is_some_and(|p| !(p.is_finite() && p >= 0.0))
        {
            return Err(QueryError::BadOption(
                "self_filter_padding_m must be finite and ≥ 0",
            ));
        }
        Ok(())
    }
}

/// The defaults of the node parameters of the same names (`config::PARAMETERS`; a test there
/// checks that the two agree).
impl Default for QueryOptions {
    fn default() -> Self {
        Self {
            mode: Mode::Certified,
            max_distance_m: 2.0,
            self_filter_padding_m: Some(0.01),
            per_link: true,
            // The node's warn_distance + hysteresis (0.3 + 0.02 m).
            per_link_range_m: 0.32,
            link_ranges_m: Vec::new(),
            backend: Backend::Auto,
            gpu_min_points: DEFAULT_GPU_MIN_POINTS,
            gpu_min_depth_pixels: DEFAULT_GPU_MIN_DEPTH_PIXELS,
        }
    }
}

impl Choice for Mode {
    const ALL: &'static [Self] = &[Mode::Fast, Mode::Certified, Mode::Exact];

    fn name(self) -> &'static str {
        match self {
            Mode::Fast => "fast",
            Mode::Certified => "certified",
            Mode::Exact => "exact",
        }
    }

    fn about(self) -> &'static str {
        match self {
            Mode::Fast => "Distance to the inner spheres: an upper bound",
            Mode::Certified => "Upper bound and certified lower bound `max(0, d − h)`",
            Mode::Exact => "Exact distance to the collision meshes",
        }
    }
}

impl Choice for Backend {
    const ALL: &'static [Self] = &[Backend::Cpu, Backend::Gpu, Backend::Auto];

    fn name(self) -> &'static str {
        match self {
            Backend::Cpu => "cpu",
            Backend::Gpu => "gpu",
            Backend::Auto => "auto",
        }
    }

    fn about(self) -> &'static str {
        match self {
            Backend::Cpu | Backend::Gpu => "",
            Backend::Auto => {
                "The GPU for clouds of at least `gpu_min_points` and depth images of at least \
                 `gpu_min_depth_pixels` on a hardware GPU, else the CPU"
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Each name parses back to its value, in the order the errors list them.
    #[test]
    fn choices_are_named_as_the_parameters_name_them() {
        for m in Mode::ALL {
            assert_eq!(Mode::parse(m.name()), Some(*m));
        }
        assert_eq!(Mode::parse("certified"), Some(Mode::Certified));
        assert_eq!(Mode::names(), "fast, certified or exact");
        assert_eq!(Backend::names(), "cpu, gpu or auto");
    }
}
