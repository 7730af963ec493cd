//! How the GPU engine is made: 64-bit atomics, subgroup operations and packets, each where the
//! adapter has it unless an environment variable turns it off (or, for packets, on).

/// Setting this variable (to anything but `0`) keeps the GPU from using 64-bit atomics even
/// where the adapter has them: the portable path ([`Minima::Split32`](crate::query::layout::Minima::Split32)), as on adapters without.
pub const NO_INT64_ENV: &str = "IST_MONITOR_GPU_NO_INT64";

/// Setting this variable (to anything but `0`) keeps the GPU from using subgroup operations
/// even where the adapter has them: the workgroup-memory reductions ([`Reduce::Shared`](crate::query::layout::Reduce::Shared)), as on
/// adapters without.
pub const NO_SUBGROUPS_ENV: &str = "IST_MONITOR_GPU_NO_SUBGROUPS";

/// Setting this variable (to anything but `0`) makes the measure pass descend each sub-block's
/// points as a packet (the shader's `DESCEND_PACKETS`: one stack for the eight points, as the CPU's
/// `descent::nearest_packet`) instead of each point on its own. Off by default: on the GPUs
/// measured the barriers of a packet's rounds and the nodes expanded for only some of its points
/// cost more than its shared reads save (docs/gpu.md's figures; `bench gpu --packets`).
pub const PACKETS_ENV: &str = "IST_MONITOR_GPU_PACKETS";

/// How the GPU engine is made.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct GpuOptions {
    /// Use 64-bit atomics where the adapter has them ([`Minima::Packed64`](crate::query::layout::Minima::Packed64)).
    pub int64_atomics: bool,
    /// Use subgroup operations where the adapter has them ([`Reduce::Subgroups`](crate::query::layout::Reduce::Subgroups)).
    pub subgroups: bool,
    /// Descend each sub-block's points as a packet in the measure pass ([`PACKETS_ENV`]).
    pub packets: bool,
}

impl Default for GpuOptions {
    /// 64-bit atomics and subgroup operations where the adapter has them, unless
    /// [`NO_INT64_ENV`] or [`NO_SUBGROUPS_ENV`] is set; packets where [`PACKETS_ENV`] is set.
    fn default() -> Self {
        let set = |var| std::env::var(var).is_ok_and(|v| v != "0");
        Self {
            int64_atomics: !set(NO_INT64_ENV),
            subgroups: !set(NO_SUBGROUPS_ENV),
            packets: set(PACKETS_ENV),
        }
    }
}
