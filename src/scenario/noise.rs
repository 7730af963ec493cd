//! The generator's random streams: SplitMix64, with uniform draws in (0, 1] and Box–Muller
//! Gaussians. One stream per camera for the noise and holes (`renderer`), one of its own for the
//! camera-like dropouts (`dropouts`), so that turning one on leaves the other's draws as they were.

/// SplitMix64 with Box–Muller: a fixed, reproducible stream.
pub(super) struct Noise(pub(super) u64);

impl Noise {
    fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    /// Uniform in (0, 1].
    pub(super) fn uniform(&mut self) -> f64 {
        ((self.next_u64() >> 11) + 1) as f64 / (1u64 << 53) as f64
    }
    pub(super) fn gaussian(&mut self) -> f64 {
        let (u, v) = (self.uniform(), self.uniform());
        (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
    }
}
