//! Who wrote a message, and who speaks for an input: one voice per source topic, per joint and
//! per TF frame (issue 46).
//!
//! A ROS 2 topic takes every writer that matches it. The monitor keeps one latest result per
//! source, one history per joint and one per frame, so two writers on one input take turns
//! deciding: a second camera driver launched without its namespace, a second
//! `joint_state_publisher`, a node that anyone on the network started. Each message therefore
//! carries its writer's GID ([`Writer`]: the DDS writer GUID, or the GID in rmw_zenoh's
//! attachment), and each input keeps the newest stamp heard from each writer ([`Voices`]).
//! At a stamp `t`, the writers **heard** are those whose newest stamp is at or after
//! `t − window` (a writer stamping ahead of the clock stays heard); two or more heard is a
//! conflict, which the monitor turns into the fault `second_publisher`, naming the writers, until
//! only one has been heard for `window`. Stamps, not arrival times, decide, so a replay judges a
//! bag as the node judged it live, and a message held back by the network counts at its own time.
//! Messages with no writer (a bag, a config) carry [`Writer::UNKNOWN`], one voice.
//!
//! Cost: a linear scan of the writers kept (at most [`MAX_WRITERS`], the oldest forgotten
//! first), per message and per lookup.

use std::fmt;

/// Writers remembered per input; past this, the one heard longest ago is forgotten.
pub const MAX_WRITERS: usize = 16;

/// A message's writer: its 16-byte GID (DDS: the writer's GUID; zenoh: rmw_zenoh's GID).
#[derive(Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct Writer(pub [u8; 16]);

impl Writer {
    /// No writer known (a bag's message, a config's value): every such message is one voice.
    pub const UNKNOWN: Writer = Writer([0; 16]);

    /// `writers` for a message: GIDs joined by ", ".
    pub fn list(writers: &[Writer]) -> String {
        let names: Vec<String> = writers.iter().map(Writer::to_string).collect();
        names.join(", ")
    }
}

impl fmt::Display for Writer {
    /// As ROS 2's tools print a GID: hex bytes joined by dots.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for (i, b) in self.0.iter().enumerate() {
            if i > 0 {
                f.write_str(".")?;
            }
            write!(f, "{b:02x}")?;
        }
        Ok(())
    }
}

impl fmt::Debug for Writer {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fmt::Display::fmt(self, f)
    }
}

/// The writers heard on one input, each with the newest stamp it gave (ns).
#[derive(Debug, Clone, Default)]
pub struct Voices {
    heard: Vec<(Writer, i64)>,
}

impl Voices {
    /// `writer` gave a message stamped `stamp_ns`.
    pub fn hear(&mut self, writer: Writer, stamp_ns: i64) {
        if let Some(h) = self.heard.iter_mut().find(|(w, _)| *w == writer) {
            h.1 = h.1.max(stamp_ns);
            return;
        }
        if self.heard.len() >= MAX_WRITERS {
            if let Some(oldest) = (0..self.heard.len()).min_by_key(|&i| self.heard[i].1) {
                self.heard.swap_remove(oldest);
            }
        }
        self.heard.push((writer, stamp_ns));
    }

    /// The writers heard at `stamp_ns` (newest stamp at or after `stamp_ns − window_ns`), or
    /// remembered and still `matched` by discovery (a writer whose messages are all lost still
    /// speaks for the input while the graph has it), when there are two or more: the conflict,
    /// sorted by GID so that a report is stable.
    pub fn conflict(
        &self,
        stamp_ns: i64,
        window_ns: i64,
        matched: &[Writer],
    ) -> Option<Vec<Writer>> {
        let since = stamp_ns.saturating_sub(window_ns);
        let mut heard: Vec<Writer> = (self.heard.iter())
            .filter(|(w, newest)| *newest >= since || matched.contains(w))
            .map(|(w, _)| *w)
            .collect();
        (heard.len() > 1).then(|| {
            heard.sort_by_key(|w| w.0);
            heard
        })
    }

    /// Every writer remembered.
    pub fn writers(&self) -> impl Iterator<Item = Writer> + '_ {
        self.heard.iter().map(|(w, _)| *w)
    }

    /// Forgets every writer (the clock went back: their stamps are from another time line).
    pub fn forget(&mut self) {
        self.heard.clear();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn w(b: u8) -> Writer {
        Writer([b; 16])
    }

    #[test]
    fn two_writers_within_the_window_conflict_until_one_falls_silent() {
        let mut v = Voices::default();
        let s = 1_000_000_000;
        v.hear(w(1), s);
        assert_eq!(v.conflict(s, 500, &[]), None, "one writer is one voice");
        v.hear(w(2), s + 50);
        assert_eq!(v.conflict(s + 50, 1_000, &[]), Some(vec![w(1), w(2)]));
        // Writer 2 falls silent; writer 1 goes on: heard alone once 2's newest is older than
        // the window.
        v.hear(w(1), s + 900);
        assert!(v.conflict(s + 900, 1_000, &[]).is_some());
        v.hear(w(1), s + 1_051);
        assert_eq!(v.conflict(s + 1_051, 1_000, &[]), None);
        // A writer stamping ahead of the clock stays heard.
        v.hear(w(3), s + 10_000_000);
        assert_eq!(v.conflict(s + 1_100, 1_000, &[]), Some(vec![w(1), w(3)]));
        v.forget();
        assert_eq!(v.conflict(s, 1_000, &[]), None);
    }

    #[test]
    fn a_writer_still_matched_by_discovery_is_heard_however_old_its_stamp() {
        let mut v = Voices::default();
        let s = 1_000_000_000;
        v.hear(w(1), s);
        v.hear(w(2), s + 5_000);
        // Writer 1's newest is 4 windows old: alone by the messages, not while it is matched.
        assert_eq!(v.conflict(s + 5_000, 1_000, &[]), None);
        assert_eq!(
            v.conflict(s + 5_000, 1_000, &[w(1), w(2)]),
            Some(vec![w(1), w(2)])
        );
        // Matched but never heard on this input (another joint's writer): no voice of it.
        assert_eq!(v.conflict(s + 5_000, 1_000, &[w(2), w(3)]), None);
    }

    #[test]
    fn many_writers_keep_the_newest_and_the_gid_prints_as_ros_does() {
        let mut v = Voices::default();
        for b in 0..40u8 {
            v.hear(w(b), i64::from(b));
        }
        assert_eq!(v.heard.len(), MAX_WRITERS);
        let c = v.conflict(39, 1, &[]).unwrap();
        assert_eq!(c, vec![w(38), w(39)]);
        assert_eq!(w(171).to_string(), ["ab"; 16].join("."));
    }
}
