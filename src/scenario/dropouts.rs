//! A depth camera's dropped pixels as real ones drop them (issue 55, item 9), beside the
//! renderer's independent random holes: so that what the unseen-space pass meets in the tests
//! is what a ToF or structured-light camera gives (5–15 % of the pixels, in clusters).
//!
//! The model, in this order, on one random stream of its own (the renderer's noise and holes
//! keep theirs, so a bag without it is byte for byte as before):
//! 1. **Depth edges.** A pixel whose range differs from a neighbour's by more than
//!    `3 cm + 2 %` of its range, or whose neighbour returned nothing while it did, drops with
//!    probability [`EDGE`]: a structured-light camera's projector shadow beside a near edge, a
//!    ToF camera's mixed pixels filtered out.
//! 2. **Dark surfaces.** The person's hair and shoes (the top 15 cm and the bottom 8 cm of their
//!    shape) return nothing, as dark fabric and black leather do.
//! 3. **Clusters.** Discs of 1 to 3 pixels' radius at 320 pixels across (scaled with the
//!    width: the same size in the scene at every resolution), placed at random until the
//!    model has dropped its share `rate` of the pixels: glare, shiny and dark spots, the
//!    blobs the depth filters of real cameras leave.
//!
//! Cost: one pass over the pixels and the clusters' discs.

use super::noise::Noise;

/// Probability that an edge pixel drops.
pub const EDGE: f64 = 0.5;
/// The person's dark top (hair) and bottom (shoes), m.
const HAIR_M: f64 = 0.15;
const SHOES_M: f64 = 0.08;

/// The camera-like dropout model of one camera.
pub(super) struct CameraDropouts {
    rate: f64,
    noise: Noise,
}

/// What the model needs of a pixel: the range of what it hit (`None`: nothing), and where that
/// is the person, the hit's height above the floor (root z, m).
pub(super) struct Pixel {
    pub range_m: Option<f64>,
    pub person_height_m: Option<f64>,
}

impl CameraDropouts {
    /// The model dropping its share `rate` of the pixels, on the stream of `seed`.
    pub fn new(rate: f64, seed: u64) -> Self {
        Self {
            rate,
            noise: Noise(seed),
        }
    }

    /// Drops (NaN) the pixels of `points` (`width × height`, row-major) the model drops, given
    /// `pixels` (the same order); `person_top_m`: the top of the person's shape, where the scene
    /// has one. The count dropped by the model (a pixel the renderer dropped already counts
    /// where the model drops it too).
    pub fn apply(
        &mut self,
        pixels: &[Pixel],
        width: usize,
        height: usize,
        person_top_m: Option<f64>,
        points: &mut [[f32; 3]],
    ) -> usize {
        if self.rate <= 0.0 {
            return 0;
        }
        let mut dropped = vec![false; pixels.len()];
        // 1. Depth edges.
        let range = |i: usize| pixels[i].range_m;
        for (i, d) in dropped.iter_mut().enumerate() {
            let (u, v) = (i % width, i / width);
            let Some(t) = range(i) else { continue };
            let step = 0.03 + 0.02 * t;
            let edge = [
                (u + 1 < width).then(|| i + 1),
                (v + 1 < height).then(|| i + width),
            ]
            .into_iter()
            .chain([(u > 0).then(|| i - 1), (v > 0).then(|| i - width)])
            .flatten()
            .any(|j| range(j).is_none_or(|s| (s - t).abs() > step));
            let draw = self.noise.uniform();
            *d |= edge && draw < EDGE;
        }
        // 2. Dark surfaces: the person's hair and shoes.
        if let Some(top) = person_top_m {
            for (d, p) in dropped.iter_mut().zip(pixels) {
                *d |= p
                    .person_height_m
                    .is_some_and(|z| z > top - HAIR_M || z < SHOES_M);
            }
        }
        // 3. Clusters, up to the model's share.
        let scale = width as f64 / 320.0;
        let target = (self.rate * pixels.len() as f64).round() as usize;
        let mut count = dropped.iter().filter(|&&d| d).count();
        let mut guard = 0;
        while count < target && guard < 100 * target.max(1) {
            guard += 1;
            let (cu, cv) = (
                self.noise.uniform() * width as f64,
                self.noise.uniform() * height as f64,
            );
            let r = scale * (1.0 + 2.0 * self.noise.uniform());
            let (u0, u1) = (
                (cu - r).floor().max(0.0) as usize,
                ((cu + r).ceil() as usize).min(width),
            );
            let (v0, v1) = (
                (cv - r).floor().max(0.0) as usize,
                ((cv + r).ceil() as usize).min(height),
            );
            for v in v0..v1 {
                for u in u0..u1 {
                    let (du, dv) = (u as f64 + 0.5 - cu, v as f64 + 0.5 - cv);
                    let i = v * width + u;
                    if du * du + dv * dv <= r * r && !dropped[i] {
                        dropped[i] = true;
                        count += 1;
                    }
                }
            }
        }
        for (p, &d) in points.iter_mut().zip(&dropped) {
            if d {
                *p = [f32::NAN; 3];
            }
        }
        count
    }
}
