//! What the cloud stage hands on: a [`Cloud`], its points `[f32; 3]` in the sensor frame (m) in
//! the sensor's order; the most points a file may declare; and a source's range limits, which
//! the readers apply as they make points.

/// The most points a cloud file may declare (1.2 GB as `[f32; 3]`): ten times a 12-megapixel
/// depth image, a hundred times a 64-beam lidar's sweep.
pub const MAX_POINTS: u64 = 100_000_000;

/// A source's range limits (`min_range`, `max_range`): a point whose distance from the sensor
/// lies outside them is dropped (made invalid), compared as squared f32 ranges.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RangeLimits {
    min2: f32,
    max2: f32,
}

impl RangeLimits {
    /// The limits of `min_m` and `max_m` (none: unbounded); `None` when they drop nothing.
    pub fn new(min_m: f64, max_m: Option<f64>) -> Option<Self> {
        (min_m > 0.0 || max_m.is_some()).then(|| Self {
            min2: (min_m * min_m) as f32,
            max2: max_m.map_or(f32::INFINITY, |m| (m * m) as f32),
        })
    }

    /// The squared limits `(min², max²)`, f32, as [`RangeLimits::keeps`] compares them.
    pub fn squared(&self) -> (f32, f32) {
        (self.min2, self.max2)
    }

    /// Whether `p` lies within the limits (NaN does not).
    #[inline]
    pub fn keeps(&self, p: [f32; 3]) -> bool {
        let r2 = p[0] * p[0] + p[1] * p[1] + p[2] * p[2];
        r2 >= self.min2 && r2 <= self.max2
    }
}

/// A point cloud in its sensor frame.
#[derive(Debug, Clone, PartialEq)]
pub struct Cloud {
    pub points: Vec<[f32; 3]>,
    /// Image size for organized clouds (height 1 for unorganized ones).
    pub width: u32,
    pub height: u32,
    /// The frame the points are in, when the source says (PointCloud2 header).
    pub frame_id: Option<String>,
    /// Header stamp (s, ns), when the source has one.
    pub stamp: Option<(i32, u32)>,
}
