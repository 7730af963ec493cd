//! What the live node asks of the monitor between frames: the faults that are not a frame of
//! their own. A source silent for longer than its `source_timeout` is a fault, reported every
//! half `source_timeout` while the silence lasts; a clock that cannot be trusted (with
//! `use_sim_time`, `/clock` silent or not heard yet) is a fault of every enabled source; and a
//! node whose monitor is being rebuilt reports "not monitoring" (ERROR, the safety stop, no
//! distance). Silence is counted on the node's monotonic clock (`watch_ns`, ns); the faults
//! are stamped with the node's clock (`now_ns`, ns since the epoch).

use std::time::Instant;

use super::fault::Fault;
use super::outputs::Outputs;
use super::pipeline::{Frame, Monitor};
use super::source::{Heard, Silence};

impl Monitor {
    /// Every source's silence counts from `watch_ns` (the node starts serving, or its clock
    /// ticks again).
    pub fn watch_from(&mut self, watch_ns: i64) {
        self.sources.iter_mut().for_each(|s| s.watch_from(watch_ns));
    }

    /// Source `source` was enabled at `watch_ns`: not heard from yet, its silence counted from
    /// then.
    pub fn enable_source(&mut self, source: usize, watch_ns: i64) {
        self.sources[source].enable(watch_ns);
    }

    /// A message of source `source` arrived: what it ends, where the node says so.
    pub fn hear(&mut self, source: usize) -> Option<Heard> {
        self.sources[source].hear()
    }

    /// Source `source` has no new message at `watch_ns` (its last at `last_ns`, `None` since it
    /// was enabled): a silence due to be reported, with its fault's frame at `now_ns`.
    pub fn silence(
        &mut self,
        source: usize,
        last_ns: Option<i64>,
        watch_ns: i64,
        now_ns: i64,
    ) -> Option<(Silence, Frame)> {
        let s = &self.config.sources[source];
        let timeout_s = s.source_timeout_s;
        let silence = self.sources[source].silence(timeout_s, last_ns, watch_ns)?;
        let fault = Fault::SourceTimeout {
            source_name: s.name.clone(),
            what: if silence.never {
                "no cloud received yet"
            } else {
                "no cloud"
            },
            silent_s: silence.silent_s,
            timeout_s,
        };
        Some((silence, self.on_source_fault(source, fault, now_ns)))
    }

    /// The clock cannot be trusted (`reason`) at `now_ns`: a fault of every enabled source; the
    /// fused outputs after the last of them (the heartbeat's with none enabled).
    pub fn clock_fault(&mut self, reason: &str, now_ns: i64) -> Outputs {
        let enabled = (self.config.sources.iter().enumerate())
            .filter(|(_, s)| s.enabled)
            .map(|(k, _)| k)
            .collect::<Vec<_>>();
        let mut last = None;
        for k in enabled {
            let fault = Fault::Clock(reason.to_owned());
            last = Some(self.on_source_fault(k, fault, now_ns).outputs);
        }
        last.unwrap_or_else(|| self.heartbeat(now_ns))
    }

    /// The outputs of a node that is not monitoring (`reason`) at `now_ns`: its monitor is
    /// being rebuilt, or its rebuild failed.
    pub fn not_monitoring(&self, reason: &str, now_ns: i64) -> Outputs {
        Outputs::not_monitoring(&self.config, reason, now_ns)
    }

    /// The outputs of a fault of source `source` that is not a frame of its own (a silent
    /// source, an unusable clock) at `now_ns` by the node's clock.
    fn on_source_fault(&mut self, source: usize, fault: Fault, now_ns: i64) -> Frame {
        let process = |_: &mut Self| Err(fault);
        self.finish_frame(
            source,
            Instant::now(),
            now_ns,
            Some(now_ns),
            process,
            &mut |_| {},
        )
    }
}
