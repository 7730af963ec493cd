//! A source: one configured camera or lidar and everything the monitor keeps of it — its
//! latest frame (stamp, result or fault, report), its own level, the camera model of a depth
//! image source, and how the node watches it (heard from yet, silent since when, its silence
//! last reported when). Times on the watch are the node's monotonic clock, ns; stamps are the
//! clock of the frames (ns since the epoch).
//!
//! A source is **in fault** (its [`Part`] in the fused picture) when its latest frame was a
//! fault, when nothing was received from it yet, or when its latest result is older than its
//! `source_timeout` by the clock of the frame being fused. A silent source is reported as a
//! fault every half `source_timeout` while its silence lasts (`Source::silence`).
//!
//! A source has **one voice**: the writers of its topic, each with the newest stamp it gave
//! ([`Voices`]). A frame stamped within `second_publisher_window` of a second writer's newest
//! stamp is the fault `second_publisher` naming both (`Source::one_voice`), whichever of them sent
//! it: the fused rule keeps one latest result per source, so two writers would otherwise take
//! turns deciding the stop. The same holds for a depth image source's CameraInfo.
//!
//! Messages alone cannot hear a writer whose messages are lost: a camera whose clouds all drop
//! for longer than the window leaves a second writer alone by the rule above, and its frame
//! would be measured. So the node also tells a source which writers **discovery** matches on its
//! topic now (DDS SEDP, rmw_zenoh's liveliness tokens: `Source::set_matched`); two or more
//! matched is the fault `second_publisher` for as long as they are matched, whatever reaches the
//! node (`Source::matched_conflict`); the same on a depth image source's CameraInfo topic
//! (`Source::matched_camera_conflict`). A replay has no discovery (`None`): its messages decide.

use crate::cloud::depth::PinholeCamera;
use crate::config::{Config, SourceConfig};
use crate::msg::{DiagnosticStatus, Voices, Writer};
use crate::query::QueryResult;

use super::level::LevelTracker;
use super::report::{FrameFacts, SourceReport};

/// One configured source (see the module doc).
#[derive(Debug, Clone)]
pub struct Source {
    /// Its latest frame (`None`: nothing since it was enabled, or since the clock went back).
    latest: Option<Latest>,
    /// Its own level, for its own status.
    tracker: LevelTracker,
    /// The camera model of its last CameraInfo, or why that one was refused (depth image
    /// sources; `None` until one arrives).
    camera: Option<Result<PinholeCamera, String>>,
    watch: Watch,
    /// Who wrote its messages.
    voices: Voices,
    /// Who wrote its CameraInfo (depth image sources).
    camera_voices: Voices,
    /// The writers discovery matches on its topic now, by name (`None`: no discovery).
    matched: Option<Vec<String>>,
    /// The same on a depth image source's CameraInfo topic.
    matched_camera: Option<Vec<String>>,
}

/// A source's latest frame.
#[derive(Debug, Clone)]
pub struct Latest {
    pub stamp_ns: i64,
    /// The result, or the fault's kind and reason.
    pub result: Result<QueryResult, (&'static str, String)>,
    pub report: SourceReport,
}

/// A source's part in the fused picture at one instant.
pub enum Part<'a> {
    /// In fault: the kind and the reason, and the source's own status where its latest frame
    /// was the fault.
    Fault {
        kind: &'static str,
        reason: String,
        status: Option<&'a DiagnosticStatus>,
    },
    Measured(&'a Latest),
}

/// How the node watches a source's messages (the node's monotonic clock, ns).
#[derive(Debug, Clone, Default)]
struct Watch {
    /// A message came since the source was enabled.
    heard: bool,
    /// Its silence was reported (and not yet ended by a message).
    silent_logged: bool,
    /// Since when its silence counts: when it was enabled, or the node's clock last restarted.
    since_ns: i64,
    /// When its silence was last reported as a fault.
    last_report_ns: Option<i64>,
}

/// What a message of a source ends, for the node's log.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Heard {
    /// The first since the source was enabled.
    First,
    /// The first after a silence that was reported.
    Again,
}

/// A silence due to be reported as a fault.
#[derive(Debug, Clone, Copy)]
pub struct Silence {
    /// Seconds since the last message (or since the source was enabled).
    pub silent_s: f64,
    /// Nothing was received since it was enabled.
    pub never: bool,
    /// The first report of this silence (the node says so once).
    pub first: bool,
}

impl Source {
    pub fn new(config: &Config) -> Self {
        Self {
            latest: None,
            tracker: LevelTracker::new(config),
            camera: None,
            watch: Watch::default(),
            voices: Voices::default(),
            camera_voices: Voices::default(),
            matched: None,
            matched_camera: None,
        }
    }

    /// The writers that discovery matches on its topic now (`None`: the transport has no
    /// discovery, or the node does not ask it).
    pub fn set_matched(&mut self, writers: Option<Vec<String>>) {
        self.matched = writers;
    }

    /// The writers that discovery matches on its CameraInfo topic now (a depth image source;
    /// `None` as for [`Source::set_matched`]).
    pub fn set_matched_camera(&mut self, writers: Option<Vec<String>>) {
        self.matched_camera = writers;
    }

    /// The writers discovery matches on its topic, when there are two or more (see the module
    /// doc), sorted so that a report is stable.
    pub fn matched_conflict(&self) -> Option<Vec<String>> {
        two_or_more(&self.matched)
    }

    /// The same on its CameraInfo topic: a second writer of the camera model would move every
    /// point of its images.
    pub fn matched_camera_conflict(&self) -> Option<Vec<String>> {
        two_or_more(&self.matched_camera)
    }

    /// `writer` sent a message stamped `stamp_ns` (each one received, also those the node's
    /// slot dropped for a newer one).
    pub fn hear_writer(&mut self, writer: Writer, stamp_ns: i64) {
        self.voices.hear(writer, stamp_ns);
    }

    /// The writers heard at `stamp_ns` when there are two or more (see the module doc).
    pub fn one_voice(&self, stamp_ns: i64, window_s: f64) -> Result<(), Vec<Writer>> {
        match self.voices.conflict(stamp_ns, (window_s * 1e9) as i64, &[]) {
            None => Ok(()),
            Some(writers) => Err(writers),
        }
    }

    /// The same for its CameraInfo: two writers of the camera model a depth image is
    /// unprojected with are a conflict too.
    pub fn one_camera(&self, stamp_ns: i64, window_s: f64) -> Result<(), Vec<Writer>> {
        match self
            .camera_voices
            .conflict(stamp_ns, (window_s * 1e9) as i64, &[])
        {
            None => Ok(()),
            Some(writers) => Err(writers),
        }
    }

    /// Takes a frame: its report (with the source's own level) and its result as the latest.
    /// Whether the frame was over the latency budget.
    pub fn frame(
        &mut self,
        config: &Config,
        robot: &str,
        stamp_ns: i64,
        facts: FrameFacts,
    ) -> bool {
        let report = SourceReport::new(config, robot, facts, &mut self.tracker);
        let over_budget = report.over_budget;
        self.latest = Some(Latest {
            stamp_ns,
            result: match facts.result {
                Ok(r) => Ok(r.clone()),
                Err(f) => Err((f.kind(), f.to_string())),
            },
            report,
        });
        over_budget
    }

    /// Its part at `now_ns` (see the module doc); `config` is the source's own.
    pub fn part(&self, config: &SourceConfig, now_ns: i64) -> Part<'_> {
        match &self.latest {
            None => Part::Fault {
                kind: "no_message_yet",
                reason: "nothing received yet".into(),
                status: None,
            },
            Some(Latest {
                result: Err((kind, reason)),
                report,
                ..
            }) => Part::Fault {
                kind,
                reason: reason.clone(),
                status: Some(&report.status),
            },
            Some(l) => {
                let age_s = (now_ns as f64 - l.stamp_ns as f64) * 1e-9;
                if age_s > config.source_timeout_s {
                    Part::Fault {
                        kind: "stale_source",
                        reason: format!(
                            "its latest result is stamped {age_s:.3} s before now \
                             (source_timeout {} s)",
                            config.source_timeout_s
                        ),
                        status: None,
                    }
                } else {
                    Part::Measured(l)
                }
            }
        }
    }

    /// Takes the thresholds of `config` (the level held is kept); a source enabled or disabled
    /// by the change (`toggled`) starts anew: never heard from, in fault until its first frame.
    pub fn reconfigure(&mut self, config: &Config, toggled: bool) {
        self.tracker.set_thresholds(config);
        if toggled {
            self.latest = None;
            self.tracker = LevelTracker::new(config);
        }
    }

    /// Forgets its latest result (it is in fault until its next frame); its level is kept.
    pub fn forget_result(&mut self) {
        self.latest = None;
    }

    /// Takes a CameraInfo's camera model, or why it was refused; `writer` sent it, stamped
    /// `stamp_ns`.
    pub fn set_camera(
        &mut self,
        camera: Result<PinholeCamera, String>,
        writer: Writer,
        stamp_ns: i64,
    ) {
        self.camera = Some(camera);
        self.camera_voices.hear(writer, stamp_ns);
    }

    /// The camera model its depth images are made into points with, or why there is none.
    pub fn camera(&self) -> Result<PinholeCamera, String> {
        match &self.camera {
            Some(Ok(c)) => Ok(*c),
            Some(Err(e)) => Err(format!("the last CameraInfo was refused: {e}")),
            None => Err("no CameraInfo received yet".into()),
        }
    }

    /// Takes over what `old` (the same source in the monitor this one replaces) received and
    /// how the node watched it: its camera model and its silence.
    pub fn take_inputs(&mut self, old: &mut Source) {
        std::mem::swap(&mut self.camera, &mut old.camera);
        std::mem::swap(&mut self.watch, &mut old.watch);
        std::mem::swap(&mut self.voices, &mut old.voices);
        std::mem::swap(&mut self.camera_voices, &mut old.camera_voices);
        std::mem::swap(&mut self.matched, &mut old.matched);
        std::mem::swap(&mut self.matched_camera, &mut old.matched_camera);
    }

    /// Enabled at `now_ns`: not heard from yet, its silence counted from now.
    pub fn enable(&mut self, now_ns: i64) {
        self.watch = Watch {
            since_ns: now_ns,
            ..Watch::default()
        };
    }

    /// Its silence counts from `now_ns` (the node starts serving, or its clock ticks again).
    pub fn watch_from(&mut self, now_ns: i64) {
        self.watch.since_ns = now_ns;
    }

    /// The clock went back at `now_ns`: its result is forgotten and its silence counts anew.
    pub fn restart(&mut self, now_ns: i64) {
        self.latest = None;
        self.watch.since_ns = now_ns;
        self.watch.last_report_ns = None;
        self.voices.forget();
        self.camera_voices.forget();
    }

    /// A message arrived: what it ends, where the node says so (its first, or the first after
    /// a reported silence).
    pub fn hear(&mut self) -> Option<Heard> {
        let w = &mut self.watch;
        w.last_report_ns = None;
        if w.heard && !w.silent_logged {
            return None;
        }
        let heard = if w.heard { Heard::Again } else { Heard::First };
        (w.heard, w.silent_logged) = (true, false);
        Some(heard)
    }

    /// No message at `now_ns` (the last one at `last_ns`, `None` since enabled): a silence
    /// longer than `timeout_s` is due to be reported when it never was, or half `timeout_s`
    /// after it last was.
    pub fn silence(
        &mut self,
        timeout_s: f64,
        last_ns: Option<i64>,
        now_ns: i64,
    ) -> Option<Silence> {
        let w = &mut self.watch;
        let silent_s = (now_ns - last_ns.unwrap_or(w.since_ns)).max(0) as f64 * 1e-9;
        let due = (w.last_report_ns).is_none_or(|t| (now_ns - t) as f64 * 1e-9 >= timeout_s / 2.0);
        if !(silent_s > timeout_s && due) {
            return None;
        }
        let first = !w.silent_logged;
        w.silent_logged = true;
        w.last_report_ns = Some(now_ns);
        Some(Silence {
            silent_s,
            never: last_ns.is_none(),
            first,
        })
    }
}

/// `writers` sorted, when there are two or more.
fn two_or_more(writers: &Option<Vec<String>>) -> Option<Vec<String>> {
    let mut writers = writers.clone().filter(|w| w.len() > 1)?;
    writers.sort();
    Some(writers)
}
