//! What crosses between the host and the GPU: the points (or a depth image), through a staging buffer that stays
//! allocated and is mapped again for writing after each query (filled in parallel); the small
//! readback, by spinning on the device for a short while before the thread parks; and the
//! host-to-device bandwidth that `bench gpu` gives each cloud's upload floor by.

use std::num::NonZeroU64;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

use rayon::prelude::*;

use super::engine::GpuEngine;
use super::error::GpuError;

/// The states of the points' staging buffer.
pub(super) const UNMAPPED: u8 = 0;
pub(super) const MAPPING: u8 = 1;
pub(super) const MAPPED: u8 = 2;

impl GpuEngine {
    /// Writes `bytes` (the points, or a depth image) into the staging buffer, mapped since the
    /// last query's readback (or since its creation), in parallel: one thread's copy of a
    /// 5 M-point cloud took 11.5 ms, and a staging buffer allocated per query (the queue's
    /// `write_buffer`) cost more than the copy at 307 k points. Returns the bytes to copy out of
    /// it: `bytes`' length rounded up to whole words (what follows them there is not read).
    pub(super) fn upload(&self, bytes: &[u8]) -> Result<u64, GpuError> {
        let Some(sized) = &self.sized else {
            return Err(GpuError::Device("no point buffers".into()));
        };
        if bytes.is_empty() {
            return Ok(0);
        }
        let words = bytes.len().next_multiple_of(4);
        // The map asked for after the last readback (done by now, as the GPU is idle), or
        // asked for now after a query that ended early.
        self.remap_staging();
        loop {
            match sized.staging_state.load(Ordering::Acquire) {
                MAPPED => break,
                UNMAPPED => return Err(GpuError::Device("the points' staging map failed".into())),
                _ => {
                    self.device
                        .poll(wgpu::PollType::Wait)
                        .map_err(|e| GpuError::Readback(e.to_string()))?;
                }
            }
        }
        {
            let slice = sized.staging.slice(..words as u64);
            let mut view = slice.get_mapped_range_mut();
            let target: &mut [u8] = &mut view[..bytes.len()];
            let chunk = copy_chunk(bytes.len(), rayon::current_num_threads());
            target
                .par_chunks_mut(chunk)
                .zip(bytes.par_chunks(chunk))
                .for_each(|(to, from)| to.copy_from_slice(from));
        }
        sized.staging.unmap();
        sized.staging_state.store(UNMAPPED, Ordering::Release);
        Ok(words as u64)
    }

    /// The first `n` points of the point buffer as the last query left them (a depth image's
    /// points as the GPU made them): for tests and benchmarks, which compare them with the
    /// CPU's.
    pub fn read_points(&self, n: usize) -> Result<Vec<[f32; 3]>, GpuError> {
        let Some(sized) = self.sized.as_ref().filter(|s| s.points_capacity >= n) else {
            return Err(GpuError::Readback(format!("no buffer holds {n} points")));
        };
        let bytes = 12 * n as u64;
        if bytes == 0 {
            return Ok(Vec::new());
        }
        let target = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("points readback"),
            size: bytes,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let mut encoder = self
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor { label: None });
        encoder.copy_buffer_to_buffer(&sized.points, 0, &target, 0, bytes);
        let submission = self.queue.submit([encoder.finish()]);
        let failed = Arc::new(AtomicBool::new(false));
        let f = failed.clone();
        target.slice(..).map_async(wgpu::MapMode::Read, move |r| {
            f.store(r.is_err(), Ordering::Release)
        });
        self.device
            .poll(wgpu::PollType::WaitForSubmissionIndex(submission))
            .map_err(|e| GpuError::Readback(e.to_string()))?;
        self.device
            .poll(wgpu::PollType::Wait)
            .map_err(|e| GpuError::Readback(e.to_string()))?;
        if failed.load(Ordering::Acquire) {
            return Err(GpuError::Readback("the points could not be mapped".into()));
        }
        let points = bytemuck::pod_collect_to_vec(&target.slice(..).get_mapped_range());
        Ok(points)
    }

    /// Asks for the staging buffer to be mapped for the next query's points (done once this
    /// query's copy is), unless it is mapped or being mapped.
    pub(super) fn remap_staging(&self) {
        if let Some(sized) = &self.sized {
            let state = &sized.staging_state;
            if state
                .compare_exchange(UNMAPPED, MAPPING, Ordering::AcqRel, Ordering::Acquire)
                .is_ok()
            {
                let state = state.clone();
                sized
                    .staging
                    .slice(..)
                    .map_async(wgpu::MapMode::Write, move |r| {
                        state.store(if r.is_ok() { MAPPED } else { UNMAPPED }, Ordering::Release)
                    });
            }
        }
    }

    /// The host-to-device bandwidth, bytes/s: `bytes` written through the queue as the points
    /// are (into the staging memory, in parallel) and copied to a device buffer, timed to the
    /// copy's completion; the median of nine. A cloud's upload floor is its bytes over this.
    pub fn upload_bandwidth(&self, bytes: usize) -> Result<f64, GpuError> {
        let size =
            NonZeroU64::new(bytes.max(4).next_multiple_of(4) as u64).expect("at least four bytes");
        let target = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("bandwidth"),
            size: size.get(),
            usage: wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let source = vec![0x5au8; size.get() as usize];
        let mut times = Vec::new();
        for _ in 0..10 {
            let start = std::time::Instant::now();
            {
                let mut view = self
                    .queue
                    .write_buffer_with(&target, 0, size)
                    .ok_or_else(|| GpuError::Device("the bandwidth buffer's staging".into()))?;
                let to: &mut [u8] = &mut view;
                to.par_chunks_mut(1 << 18)
                    .zip(source.par_chunks(1 << 18))
                    .for_each(|(t, f)| t.copy_from_slice(f));
            }
            let submission = self.queue.submit([]);
            self.device
                .poll(wgpu::PollType::WaitForSubmissionIndex(submission))
                .map_err(|e| GpuError::Readback(e.to_string()))?;
            times.push(start.elapsed().as_secs_f64());
        }
        // The first one also maps the staging memory.
        times.remove(0);
        times.sort_by(f64::total_cmp);
        Ok(size.get() as f64 / times[times.len() / 2])
    }

    /// Maps the readback buffer once `submission` is done: spinning on the device for a short
    /// while (a query's readback is ready in tens of microseconds on a hardware GPU, and a
    /// parked thread takes longer to wake), then waiting.
    pub(super) fn read_back(&self, submission: wgpu::SubmissionIndex) -> Result<(), GpuError> {
        let mapped = Arc::new(AtomicBool::new(false));
        let failed = Arc::new(AtomicBool::new(false));
        let (m, f) = (mapped.clone(), failed.clone());
        self.readback
            .slice(..)
            .map_async(wgpu::MapMode::Read, move |r| {
                f.store(r.is_err(), Ordering::Release);
                m.store(true, Ordering::Release);
            });
        let spin_until = std::time::Instant::now() + std::time::Duration::from_micros(2000);
        while !mapped.load(Ordering::Acquire) && std::time::Instant::now() < spin_until {
            self.device
                .poll(wgpu::PollType::Poll)
                .map_err(|e| GpuError::Readback(e.to_string()))?;
            std::hint::spin_loop();
        }
        if !mapped.load(Ordering::Acquire) {
            self.device
                .poll(wgpu::PollType::WaitForSubmissionIndex(submission))
                .map_err(|e| GpuError::Readback(e.to_string()))?;
            // The map's callback runs in a poll after the submission is done.
            while !mapped.load(Ordering::Acquire) {
                self.device
                    .poll(wgpu::PollType::Wait)
                    .map_err(|e| GpuError::Readback(e.to_string()))?;
            }
        }
        if failed.load(Ordering::Acquire) {
            return Err(GpuError::Readback(
                "the readback buffer could not be mapped".into(),
            ));
        }
        Ok(())
    }
}

/// The bytes each thread copies into the staging memory: two pieces a thread, whole pages,
/// at least 32 KiB (below that a thread's wake-up costs more than its copy) and at most
/// 256 KiB. A 640 × 480 depth image (614 KB) is then 19 pieces on 16 threads, not the 3 that
/// 256 KiB pieces gave it.
fn copy_chunk(bytes: usize, threads: usize) -> usize {
    const PAGE: usize = 4096;
    (bytes / (2 * threads.max(1)))
        .next_multiple_of(PAGE)
        .clamp(32 << 10, 256 << 10)
}

#[cfg(test)]
mod tests {
    use super::copy_chunk;

    #[test]
    fn copy_chunks_spread_an_image_over_the_threads() {
        // A 640 × 480 16UC1 image on 16 threads: 20 KiB a piece would be too small.
        assert_eq!(copy_chunk(614_400, 16), 32 << 10);
        // 3.7 MB of points on 16 threads: 116 KiB pieces, 32 of them.
        let c = copy_chunk(3_686_400, 16);
        assert_eq!(c % 4096, 0);
        assert_eq!(3_686_400usize.div_ceil(c), 32);
        // 60 MB on 16 threads, or anything on one: at most 256 KiB.
        assert_eq!(copy_chunk(60_000_000, 16), 256 << 10);
        assert_eq!(copy_chunk(1_000, 0), 32 << 10);
    }
}
