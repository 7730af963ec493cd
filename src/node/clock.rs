//! The node's clock, as ROS 2 has it: the system clock, or with `use_sim_time` the time that
//! `/clock` publishes (`rosgraph_msgs/msg/Clock`: a simulator, `ros2 bag play --clock`). The
//! stamp checks (stale, future), the sources' timeouts, the ages of the fused results and the
//! output stamps all read it.
//!
//! Simulated time has two failure modes that the system clock has not, and both are faults here
//! rather than a frozen clean state:
//! - `/clock` silent (never heard, or nothing for `clock_timeout` of wall time: the simulator
//!   or the bag stopped): the stamps cannot be checked against anything, so every source is in
//!   fault until it ticks again.
//! - `/clock` going back (a bag played in a loop, a simulation reset): what was received lies
//!   on another time line, so the monitor forgets it (`Monitor::on_clock_jump`) and every
//!   source is in fault until its next frame; levels held stay held.
//!
//! Timeouts use [`NodeClock::monotonic_ns`]: the system's monotonic clock, or simulated time.

use std::sync::atomic::{AtomicI64, AtomicU64, Ordering};
use std::sync::Mutex;
use std::time::Instant;

use super::error::lock;
use crate::msg::Time;

/// The node's clock (see the module doc).
pub struct NodeClock {
    started: Instant,
    sim: Option<SimTime>,
}

struct SimTime {
    /// The last `/clock` time, ns; `None` before the first (`i64::MIN`).
    now_ns: AtomicI64,
    /// When `/clock` last ticked (wall).
    heard: Mutex<Option<Instant>>,
    /// How often it went back, and the last jump `(from, to)`.
    jumps: AtomicU64,
    last_jump: Mutex<(i64, i64)>,
}

impl NodeClock {
    /// The system clock.
    pub fn system() -> Self {
        Self {
            started: Instant::now(),
            sim: None,
        }
    }

    /// Simulated time from `/clock`.
    pub fn simulated() -> Self {
        Self {
            started: Instant::now(),
            sim: Some(SimTime {
                now_ns: AtomicI64::new(i64::MIN),
                heard: Mutex::new(None),
                jumps: AtomicU64::new(0),
                last_jump: Mutex::new((0, 0)),
            }),
        }
    }

    pub fn is_simulated(&self) -> bool {
        self.sim.is_some()
    }

    /// Now, ns since the epoch (simulated: the last `/clock`, 0 before the first).
    pub fn now_ns(&self) -> i64 {
        match &self.sim {
            None => Time::now_nanos(),
            Some(s) => s.now_ns.load(Ordering::Acquire).max(0),
        }
    }

    /// A clock for intervals: the system's monotonic one (ns since this clock was made), or
    /// simulated time.
    pub fn monotonic_ns(&self) -> i64 {
        match &self.sim {
            None => self.started.elapsed().as_nanos() as i64,
            Some(_) => self.now_ns(),
        }
    }

    /// Takes a `/clock` tick (simulated time; ignored otherwise).
    pub fn tick(&self, t: Time) {
        let Some(s) = &self.sim else { return };
        let t = t.as_nanos();
        let before = s.now_ns.swap(t, Ordering::AcqRel);
        if before != i64::MIN && t < before {
            *lock(&s.last_jump) = (before, t);
            s.jumps.fetch_add(1, Ordering::AcqRel);
        }
        *lock(&s.heard) = Some(Instant::now());
    }

    /// How often the clock went back so far.
    pub fn jumps(&self) -> u64 {
        self.sim
            .as_ref()
            .map_or(0, |s| s.jumps.load(Ordering::Acquire))
    }

    /// The last jump back, `(from, to)` ns.
    pub fn last_jump(&self) -> (i64, i64) {
        self.sim.as_ref().map_or((0, 0), |s| *lock(&s.last_jump))
    }

    /// Why the clock cannot be used now (`None`: it can): simulated time with `/clock` not heard
    /// yet, or silent for more than `timeout_s` of wall time.
    pub fn fault(&self, timeout_s: f64) -> Option<String> {
        let s = self.sim.as_ref()?;
        match *lock(&s.heard) {
            None => Some(
                "use_sim_time is set and nothing arrived on /clock yet (start the simulator, or \
                 `ros2 bag play --clock`)"
                    .into(),
            ),
            Some(t) if t.elapsed().as_secs_f64() > timeout_s => Some(format!(
                "use_sim_time is set and /clock is silent for {:.1} s (clock_timeout {timeout_s} \
                 s): the simulation or the bag stopped",
                t.elapsed().as_secs_f64()
            )),
            Some(_) => None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn simulated_time_follows_clock_and_reports_silence_and_jumps() {
        let c = NodeClock::simulated();
        assert!(c.fault(1.0).unwrap().contains("nothing arrived"));
        assert_eq!(c.now_ns(), 0);
        c.tick(Time {
            sec: 100,
            nanosec: 5,
        });
        assert_eq!(c.now_ns(), 100_000_000_005);
        assert_eq!(c.monotonic_ns(), c.now_ns());
        assert!(c.fault(1.0).is_none());
        std::thread::sleep(std::time::Duration::from_millis(30));
        assert!(c.fault(0.01).unwrap().contains("silent"));
        c.tick(Time {
            sec: 101,
            nanosec: 0,
        });
        assert_eq!(c.jumps(), 0);
        // A bag played again: the clock goes back.
        c.tick(Time {
            sec: 90,
            nanosec: 0,
        });
        assert_eq!(c.jumps(), 1);
        assert_eq!(c.last_jump(), (101_000_000_000, 90_000_000_000));
        // The system clock is never in fault and ignores ticks.
        let w = NodeClock::system();
        w.tick(Time { sec: 1, nanosec: 0 });
        assert!(w.fault(0.0).is_none());
        assert!(w.now_ns() > 1_000_000_000);
    }
}
