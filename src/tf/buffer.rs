//! The TF buffer: the frame tree with a short history of `parent_from_child` (f64) per edge,
//! static edges holding one value for all time, and the lookup of `target_from_source` at a
//! stamp (each edge interpolated, or its nearest sample within the tolerance). Input: `/tf`,
//! `/tf_static` and the config's static transforms; output: poses or a [`TfError`] naming the
//! edge.
//!
//! **One authority per frame.** Each edge keeps who wrote it ([`Voices`], by the messages'
//! stamps): two writers of one dynamic frame within the voice window of a lookup's stamp, a
//! static frame given two different values by two writers, or a frame one writer calls static
//! and another dynamic, is [`TfError::SecondPublisher`] on every lookup through that edge — the
//! dynamic conflict until one writer has been alone for the window, the static one for as long as
//! the buffer lives (a static value, once contested, cannot be trusted again without a restart).
//! A static frame restated with the same value by a new writer (a restarted
//! robot_state_publisher) is no conflict. Where the node's discovery gives the writers of `/tf`
//! and `/tf_static` by GID (DDS: [`TfBuffer::set_matched`]), a dynamic frame's writer stays its
//! voice for as long as it is matched, however long its messages are lost.

use std::collections::HashMap;

use nalgebra::{Isometry3, Translation3};

use super::history::{History, Miss};
use crate::msg::{TransformStamped, Voices, Writer};

/// Longest chain of frames walked; deeper is taken for a loop.
const MAX_DEPTH: usize = 64;

#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum TfError {
    #[error("transform {parent} → {child}: quaternion is zero or not finite")]
    BadQuaternion { parent: String, child: String },
    #[error("transform {parent} → {child}: translation is not finite")]
    NonFinite { parent: String, child: String },
    #[error("transform with an empty frame id or a frame that is its own parent ('{0}')")]
    BadFrames(String),
    #[error("no transform path between frames {target} and {from}")]
    NoPath { target: String, from: String },
    #[error("frame {0}: loop or chain deeper than {MAX_DEPTH} frames")]
    Loop(String),
    #[error(
        "transform {parent} → {child} is stale: newest at {newest_s:.3} s, needed at {stamp_s:.3} s (tolerance {tolerance_s} s)"
    )]
    Stale {
        parent: String,
        child: String,
        newest_s: f64,
        stamp_s: f64,
        tolerance_s: f64,
    },
    #[error(
        "transform {parent} → {child}: needed at {stamp_s:.3} s, before the oldest sample kept ({oldest_s:.3} s)"
    )]
    TooOld {
        parent: String,
        child: String,
        oldest_s: f64,
        stamp_s: f64,
    },
    #[error("frame {child} has more than one authority: {what} by writers {writers}")]
    SecondPublisher {
        child: String,
        what: &'static str,
        writers: String,
    },
}

#[derive(Debug, Clone)]
struct Edge {
    parent: String,
    is_static: bool,
    /// `parent_from_child` over time.
    samples: History<Isometry3<f64>>,
    /// Who wrote it dynamically (`/tf`), by stamp.
    voices: Voices,
    /// Who wrote it statically, with the value each gave.
    statics: Vec<(Writer, Isometry3<f64>)>,
    /// A conflict that holds for the buffer's life: what it was, and the writers.
    contested: Option<(&'static str, Vec<Writer>)>,
}

/// A TF buffer: the frame tree with a history per edge.
#[derive(Debug, Clone)]
pub struct TfBuffer {
    edges: HashMap<String, Edge>,
    cache_ns: i64,
    /// Two writers of one dynamic frame within this of a lookup's stamp are a conflict.
    voice_window_ns: i64,
    /// The writers discovery matches on `/tf` and `/tf_static` now (empty: none known).
    matched: Vec<Writer>,
}

/// The default voice window, s (the config's `second_publisher_window`).
pub const VOICE_WINDOW_S: f64 = 1.0;

pub(super) fn strip(frame: &str) -> &str {
    frame.strip_prefix('/').unwrap_or(frame)
}

fn seconds(ns: i64) -> f64 {
    ns as f64 * 1e-9
}

/// The pose a fraction `s` of the way from `a` to `b`: translation linear, rotation slerp.
pub fn interpolate(a: &Isometry3<f64>, b: &Isometry3<f64>, s: f64) -> Isometry3<f64> {
    let translation = a.translation.vector.lerp(&b.translation.vector, s);
    Isometry3::from_parts(
        Translation3::from(translation),
        a.rotation.slerp(&b.rotation, s),
    )
}

impl Edge {
    /// Notes `writer`'s statement (see the module doc for what contests an edge).
    fn hear(&mut self, writer: Writer, stamp_ns: i64, is_static: bool, pose: &Isometry3<f64>) {
        if self.contested.is_some() {
            return;
        }
        let other = |w: &Writer| *w != writer;
        if is_static {
            let differs = |p: &Isometry3<f64>| {
                (p.translation.vector - pose.translation.vector).norm() > 1e-9
                    || p.rotation.angle_to(&pose.rotation) > 1e-9
            };
            let by = (self.statics.iter()).find(|(w, p)| other(w) && differs(p));
            if let Some((w, _)) = by {
                self.contested = Some(("two static values", vec![*w, writer]));
            } else if let Some(w) = self.voices.writers().find(other) {
                self.contested = Some(("static and dynamic", vec![w, writer]));
            }
            self.statics.retain(|(w, _)| other(w));
            self.statics.push((writer, *pose));
        } else {
            if let Some((w, _)) = self.statics.iter().find(|(w, _)| other(w)) {
                self.contested = Some(("static and dynamic", vec![*w, writer]));
            }
            self.voices.hear(writer, stamp_ns);
        }
    }

    /// The conflict that stops a lookup at `stamp_ns` (`None`: the newest sample's stamp).
    fn conflict(
        &self,
        stamp_ns: Option<i64>,
        window_ns: i64,
        matched: &[Writer],
    ) -> Option<(&'static str, Vec<Writer>)> {
        if let Some(c) = &self.contested {
            return Some(c.clone());
        }
        if self.is_static {
            return None;
        }
        let at = stamp_ns.or_else(|| self.samples.newest_stamp())?;
        (self.voices.conflict(at, window_ns, matched)).map(|w| ("two dynamic writers", w))
    }
}

impl TfBuffer {
    /// A buffer keeping `cache_s` seconds of history per dynamic edge.
    pub fn new(cache_s: f64) -> Self {
        Self {
            edges: HashMap::new(),
            cache_ns: (cache_s * 1e9) as i64,
            voice_window_ns: (VOICE_WINDOW_S * 1e9) as i64,
            matched: Vec::new(),
        }
    }

    /// Two writers of one dynamic frame within `window_s` of a stamp are a conflict.
    pub fn set_voice_window(&mut self, window_s: f64) {
        self.voice_window_ns = (window_s * 1e9) as i64;
    }

    /// The writers that discovery matches on `/tf` and `/tf_static` now (empty: no discovery):
    /// a dynamic frame's writer stays its voice while it is matched, however long its messages
    /// are lost.
    pub fn set_matched(&mut self, writers: Vec<Writer>) {
        self.matched = writers;
    }

    /// Forgets the dynamic transforms (`/tf`) and who wrote them, keeping the static ones.
    pub fn forget_dynamic(&mut self) {
        self.edges.retain(|_, e| e.is_static);
        self.edges.values_mut().for_each(|e| e.voices.forget());
    }

    /// Adds one transform (`header.frame_id` the parent, `parent_from_child`) of no known
    /// writer (a bag's, the config's).
    pub fn insert(&mut self, t: &TransformStamped, is_static: bool) -> Result<(), TfError> {
        self.insert_from(t, is_static, Writer::UNKNOWN)
    }

    /// Adds one transform written by `writer`.
    pub fn insert_from(
        &mut self,
        t: &TransformStamped,
        is_static: bool,
        writer: Writer,
    ) -> Result<(), TfError> {
        let parent = strip(&t.header.frame_id);
        let child = strip(&t.child_frame_id);
        if parent.is_empty() || child.is_empty() || parent == child {
            return Err(TfError::BadFrames(child.to_owned()));
        }
        let names = || (parent.to_owned(), child.to_owned());
        if t.transform.rotation.to_unit().is_none() {
            let (parent, child) = names();
            return Err(TfError::BadQuaternion { parent, child });
        }
        let Some(pose) = t.transform.to_isometry() else {
            let (parent, child) = names();
            return Err(TfError::NonFinite { parent, child });
        };
        let stamp = t.header.stamp.as_nanos();
        let edge = self.edges.entry(child.to_owned()).or_insert_with(|| Edge {
            parent: parent.to_owned(),
            is_static,
            samples: History::default(),
            voices: Voices::default(),
            statics: Vec::new(),
            contested: None,
        });
        edge.hear(writer, stamp, is_static, &pose);
        if edge.parent != parent || edge.is_static != is_static {
            // Re-parented, or turned static/dynamic: the new statement replaces the old.
            edge.parent = parent.to_owned();
            edge.is_static = is_static;
            edge.samples.clear();
        }
        if is_static {
            edge.samples.clear();
        }
        edge.samples.insert(stamp, pose, self.cache_ns, usize::MAX);
        Ok(())
    }

    /// `parent_from_child` of the edge above `child` at `stamp_ns` (`None`: the newest).
    fn sample(
        &self,
        child: &str,
        stamp_ns: Option<i64>,
        tolerance_ns: i64,
    ) -> Result<Isometry3<f64>, TfError> {
        let edge = &self.edges[child];
        let names = || (edge.parent.clone(), child.to_owned());
        if let Some((what, writers)) = edge.conflict(stamp_ns, self.voice_window_ns, &self.matched)
        {
            return Err(TfError::SecondPublisher {
                child: child.to_owned(),
                what,
                writers: Writer::list(&writers),
            });
        }
        let stamp_ns = stamp_ns.filter(|_| !edge.is_static);
        let sampled = edge.samples.sample(stamp_ns, tolerance_ns, interpolate);
        match sampled.expect("edges are created with a sample") {
            Ok(pose) => Ok(pose),
            Err(Miss::Stale { newest_ns }) => {
                let (parent, child) = names();
                Err(TfError::Stale {
                    parent,
                    child,
                    newest_s: seconds(newest_ns),
                    stamp_s: seconds(stamp_ns.unwrap_or_default()),
                    tolerance_s: seconds(tolerance_ns),
                })
            }
            Err(Miss::TooOld { oldest_ns }) => {
                let (parent, child) = names();
                Err(TfError::TooOld {
                    parent,
                    child,
                    oldest_s: seconds(oldest_ns),
                    stamp_s: seconds(stamp_ns.unwrap_or_default()),
                })
            }
        }
    }

    /// The frames from `start` up to the top of its tree, each with `frame_from_start`.
    pub(super) fn chain(
        &self,
        start: &str,
        stamp_ns: Option<i64>,
        tolerance_ns: i64,
    ) -> Result<Vec<(String, Isometry3<f64>)>, TfError> {
        let mut out = vec![(start.to_owned(), Isometry3::identity())];
        let mut frame = start.to_owned();
        while let Some(edge) = self.edges.get(&frame) {
            if out.len() > MAX_DEPTH {
                return Err(TfError::Loop(start.to_owned()));
            }
            let parent_from_frame = self.sample(&frame, stamp_ns, tolerance_ns)?;
            let parent_from_start = parent_from_frame * out[out.len() - 1].1;
            frame = edge.parent.clone();
            out.push((frame.clone(), parent_from_start));
        }
        Ok(out)
    }

    /// `target_from_source` at `stamp_ns` (`None`: the newest of every edge), each dynamic edge
    /// within `tolerance_s` of the stamp.
    pub fn lookup(
        &self,
        target: &str,
        source: &str,
        stamp_ns: Option<i64>,
        tolerance_s: f64,
    ) -> Result<Isometry3<f64>, TfError> {
        let (target, source) = (strip(target), strip(source));
        if target == source {
            return Ok(Isometry3::identity());
        }
        let tolerance_ns = (tolerance_s * 1e9) as i64;
        let up_source = self.chain(source, stamp_ns, tolerance_ns)?;
        let up_target = self.chain(target, stamp_ns, tolerance_ns)?;
        for (frame, frame_from_source) in &up_source {
            if let Some((_, frame_from_target)) = up_target.iter().find(|(f, _)| f == frame) {
                return Ok(frame_from_target.inverse() * frame_from_source);
            }
        }
        Err(TfError::NoPath {
            target: target.to_owned(),
            from: source.to_owned(),
        })
    }
}

#[cfg(test)]
pub(super) mod tests {
    use super::*;
    use crate::msg::{Header, Quaternion, Time, Transform, Vector3};
    use nalgebra::{UnitQuaternion, Vector3 as V3};

    pub(in crate::tf) fn ts(
        parent: &str,
        child: &str,
        t_ns: i64,
        pose: Isometry3<f64>,
    ) -> TransformStamped {
        TransformStamped {
            header: Header {
                stamp: Time::from_nanos(t_ns),
                frame_id: parent.into(),
            },
            child_frame_id: child.into(),
            transform: Transform::from_isometry(&pose),
        }
    }

    pub(in crate::tf) fn pose(x: f64, yaw: f64) -> Isometry3<f64> {
        Isometry3::from_parts(
            Translation3::new(x, 0.0, 0.0),
            UnitQuaternion::from_axis_angle(&V3::z_axis(), yaw),
        )
    }

    #[test]
    fn interpolates_with_slerp_and_honours_the_tolerance() {
        let mut tf = TfBuffer::new(10.0);
        tf.insert(&ts("world", "base", 1_000_000_000, pose(0.0, 0.0)), false)
            .unwrap();
        tf.insert(&ts("world", "base", 2_000_000_000, pose(1.0, 1.0)), false)
            .unwrap();
        let mid = tf
            .lookup("world", "base", Some(1_500_000_000), 0.0)
            .unwrap();
        assert!((mid.translation.x - 0.5).abs() < 1e-12);
        assert!((mid.rotation.angle() - 0.5).abs() < 1e-12);
        // Within the tolerance past the newest: the newest; beyond it: stale.
        let late = tf
            .lookup("world", "base", Some(2_040_000_000), 0.05)
            .unwrap();
        assert!((late.translation.x - 1.0).abs() < 1e-12);
        let e = tf
            .lookup("world", "base", Some(2_100_000_000), 0.05)
            .unwrap_err();
        assert!(matches!(e, TfError::Stale { .. }), "{e}");
        let e = tf.lookup("world", "base", Some(100), 0.05).unwrap_err();
        assert!(matches!(e, TfError::TooOld { .. }), "{e}");
        // The inverse direction.
        let inv = tf
            .lookup("base", "world", Some(2_000_000_000), 0.0)
            .unwrap();
        assert!((inv * pose(1.0, 1.0)).translation.vector.norm() < 1e-12);
    }

    #[test]
    fn composes_through_the_common_ancestor() {
        let mut tf = TfBuffer::new(10.0);
        tf.insert(&ts("world", "a", 0, pose(1.0, 0.5)), true)
            .unwrap();
        tf.insert(&ts("world", "b", 0, pose(-2.0, -0.3)), true)
            .unwrap();
        tf.insert(&ts("b", "/c", 0, pose(0.25, 1.0)), true).unwrap();
        let a_from_c = tf.lookup("a", "c", Some(123), 0.0).unwrap();
        let expected = pose(1.0, 0.5).inverse() * pose(-2.0, -0.3) * pose(0.25, 1.0);
        assert!((a_from_c.to_homogeneous() - expected.to_homogeneous()).norm() < 1e-12);
        assert!(matches!(
            tf.lookup("a", "nowhere", None, 0.0),
            Err(TfError::NoPath { .. })
        ));
    }

    #[test]
    fn quaternions_are_normalized_or_refused() {
        let mut tf = TfBuffer::new(10.0);
        let mut t = ts("world", "cam", 0, pose(0.0, 0.0));
        t.transform.rotation = Quaternion {
            x: 0.0,
            y: 0.0,
            z: 0.0,
            w: 2.0,
        };
        tf.insert(&t, true).unwrap();
        let p = tf.lookup("world", "cam", None, 0.0).unwrap();
        assert!((p.rotation.quaternion().norm() - 1.0).abs() < 1e-12);
        for bad in [
            Quaternion {
                x: 0.0,
                y: 0.0,
                z: 0.0,
                w: 0.0,
            },
            Quaternion {
                x: f64::NAN,
                y: 0.0,
                z: 0.0,
                w: 1.0,
            },
        ] {
            t.transform.rotation = bad;
            assert!(matches!(
                tf.insert(&t, true),
                Err(TfError::BadQuaternion { .. })
            ));
        }
        t.transform.rotation = Quaternion::default();
        t.transform.translation = Vector3 {
            x: f64::INFINITY,
            y: 0.0,
            z: 0.0,
        };
        assert!(matches!(
            tf.insert(&t, true),
            Err(TfError::NonFinite { .. })
        ));
        t.child_frame_id = "world".into();
        assert!(matches!(tf.insert(&t, true), Err(TfError::BadFrames(_))));
    }

    #[test]
    fn old_samples_are_dropped() {
        let mut tf = TfBuffer::new(1.0);
        for i in 0..100 {
            tf.insert(&ts("w", "b", i * 100_000_000, pose(i as f64, 0.0)), false)
                .unwrap();
        }
        assert!(tf.edges["b"].samples.len() <= 12);
        let e = tf.lookup("w", "b", Some(0), 0.0).unwrap_err();
        assert!(matches!(e, TfError::TooOld { .. }));
    }

    #[test]
    fn one_frame_from_two_authorities_is_refused_while_both_are_heard() {
        let (a, b) = (Writer([1; 16]), Writer([2; 16]));
        let s = 1_000_000_000;
        let mut tf = TfBuffer::new(10.0);
        tf.set_voice_window(0.5);
        tf.insert_from(&ts("w", "cam", s, pose(1.0, 0.0)), false, a)
            .unwrap();
        assert!(tf.lookup("w", "cam", Some(s), 0.1).is_ok());
        // A second writer of the same frame, 3 m away: no lookup takes either value.
        tf.insert_from(&ts("w", "cam", s + 50_000_000, pose(4.0, 0.0)), false, b)
            .unwrap();
        let e = tf
            .lookup("w", "cam", Some(s + 50_000_000), 0.1)
            .unwrap_err();
        assert!(
            matches!(&e, TfError::SecondPublisher { child, .. } if child == "cam"),
            "{e}"
        );
        assert!(e.to_string().contains(&b.to_string()), "{e}");
        assert!(tf.lookup("w", "cam", None, 0.1).is_err());
        // b falls silent: once a has been alone for the window, a's transforms are taken again.
        let later = s + 700_000_000;
        tf.insert_from(&ts("w", "cam", later, pose(1.0, 0.0)), false, a)
            .unwrap();
        let p = tf.lookup("w", "cam", Some(later), 0.1).unwrap();
        assert!((p.translation.x - 1.0).abs() < 1e-12);
        // Other frames are not touched by a conflict on one.
        tf.insert_from(&ts("w", "other", s, pose(0.0, 0.0)), false, a)
            .unwrap();
        tf.insert_from(&ts("w", "other", s, pose(0.0, 0.0)), false, b)
            .unwrap();
        assert!(tf.lookup("w", "cam", Some(later), 0.1).is_ok());
        assert!(tf.lookup("w", "other", Some(s), 0.1).is_err());
    }

    #[test]
    fn a_static_frame_contested_stays_refused_and_a_restated_one_does_not() {
        let (a, b, c) = (Writer([1; 16]), Writer([2; 16]), Writer([3; 16]));
        let mut tf = TfBuffer::new(10.0);
        tf.insert_from(&ts("w", "cam", 0, pose(1.0, 0.2)), true, a)
            .unwrap();
        // The same value from a new writer (a restarted publisher): no conflict.
        tf.insert_from(&ts("w", "cam", 5, pose(1.0, 0.2)), true, b)
            .unwrap();
        assert!(tf.lookup("w", "cam", Some(0), 0.0).is_ok());
        // Another value from another writer: refused for good, whatever comes after.
        tf.insert_from(&ts("w", "cam", 9, pose(2.0, 0.2)), true, c)
            .unwrap();
        let e = tf.lookup("w", "cam", Some(0), 0.0).unwrap_err();
        assert!(
            matches!(
                e,
                TfError::SecondPublisher {
                    what: "two static values",
                    ..
                }
            ),
            "{e}"
        );
        tf.insert_from(&ts("w", "cam", 10, pose(1.0, 0.2)), true, a)
            .unwrap();
        tf.forget_dynamic();
        assert!(tf.lookup("w", "cam", Some(10_000_000_000), 0.0).is_err());
        // A frame one writer states static and another publishes on /tf.
        tf.insert_from(&ts("w", "lidar", 0, pose(0.5, 0.0)), true, a)
            .unwrap();
        tf.insert_from(&ts("w", "lidar", 1, pose(0.5, 0.0)), false, b)
            .unwrap();
        assert!(tf.lookup("w", "lidar", Some(1), 0.1).is_err());
        // The same writer changing its own static value is no conflict (a new calibration).
        tf.insert_from(&ts("w", "imu", 0, pose(0.1, 0.0)), true, a)
            .unwrap();
        tf.insert_from(&ts("w", "imu", 0, pose(0.2, 0.0)), true, a)
            .unwrap();
        let p = tf.lookup("w", "imu", None, 0.0).unwrap();
        assert!((p.translation.x - 0.2).abs() < 1e-12);
    }
}
