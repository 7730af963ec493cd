//! The unseen-space stage's error: which parameter or which input is wrong, and what would be
//! right. The caller (the config, the monitor) adds the source's name where one is concerned.

#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum UnseenError {
    /// A length parameter that must be finite and positive (resolution, half extents,
    /// detection capability) or finite and non-negative (range noise).
    #[error("parameter {parameter}: {value} m is not a finite {expected}")]
    Length {
        parameter: &'static str,
        value: f64,
        expected: &'static str,
    },
    /// The monitored volume at this resolution holds more cells than the stage allows.
    #[error(
        "parameter resolution: {resolution_m} m over the monitored volume ({dims:?} cells) makes \
         {cells} cells, more than {max}; coarsen the resolution or shrink the volume"
    )]
    TooManyCells {
        resolution_m: f64,
        dims: [f64; 3],
        cells: f64,
        max: usize,
    },
    /// A ball of the detection capability's diameter may hold no lattice ball at all: the
    /// lattice cannot certify bodies that small.
    #[error(
        "parameter detection_capability: {detection_capability_m} m is finer than a lattice of \
         resolution {resolution_m} m resolves (it must exceed the cell diagonal, {needed_m:.4} \
         m); refine unobserved_resolution or raise the capability"
    )]
    CapabilityBelowResolution {
        detection_capability_m: f64,
        resolution_m: f64,
        needed_m: f64,
    },
    /// A per-pixel array whose length is not the camera's pixel count.
    #[error("{what}: {got} values for a {width}×{height} pixel grid")]
    PixelCount {
        what: &'static str,
        got: usize,
        width: u32,
        height: u32,
    },
    /// An unorganized cloud (height 1) has no pixel grid: it observes nothing free.
    #[error("an unorganized cloud ({width}×{height}) has no pixel grid: it observes nothing free")]
    Unorganized { width: u32, height: u32 },
    /// An organized cloud whose points are not a pinhole camera's in its own frame (too few
    /// valid points, or the fitted intrinsics do not put each point back on its pixel).
    #[error("organized cloud {width}×{height}: no pinhole camera fits its points ({reason}): it observes nothing free")]
    NotPinhole {
        width: u32,
        height: u32,
        reason: String,
    },
}
