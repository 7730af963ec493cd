//! Fusion across sources: the cell has one level, one stop and one distance, over every enabled
//! source. [`fuse`] decides the picture ([`Fused`]); `outputs` renders it into messages.
//!
//! Each source keeps its latest result (`source`: its stamp, its distance or its fault, its
//! diagnostic status). Every frame of any source publishes the fused picture:
//!
//! - A source counts only if it is enabled. A disabled source never counts. With none enabled
//!   nothing watches the cell: that is a fault (ERROR, no distance), not a clean state.
//! - An enabled source **in fault** holds the fused level at ERROR with no distance until it
//!   recovers (its next good frame) or is disabled. In fault means: its latest frame was a fault
//!   (any kind: decode, stamp, transform, joints, no valid points, its `source_timeout` in the
//!   node), nothing received from it yet, or its latest result is older than its
//!   `source_timeout` by the clock of the frame being fused (stale). A blinded camera is never
//!   cleared by a healthy one.
//! - Otherwise the fused distance is the minimum of the sources' conservative distances, and the
//!   fused level follows it with the hysteresis of `LevelTracker`: one camera's far wall cannot
//!   release the stop another camera's near obstacle raised. A source whose valid points were
//!   all self-filtered contributes no distance and holds the fused level at WARN at least (it
//!   never lowers it).
//! - Per-link distances are each link's minimum over the sources; the closest-point markers are
//!   each source's nearest; the header stamp is the oldest stamp among the fused results (the
//!   age of the picture is that of its oldest part).
//! - `/diagnostics` carries one status per enabled source (its own level with its own
//!   hysteresis, as before) and one for the fused result, last, named `<node>: all sources`.
//!
//! The speed-scaling factor is fused by `separation::SpeedScaler` (the minimum over sources),
//! and is 0 while any source is in fault.
//!
//! **Unseen space** (`unseen`): the latest pass over every source's view rides along for the
//! outputs. With `unobserved: protect` the level (and so the stop) follows the smaller of the
//! seen and the unseen distance, the unseen one alone where no seen distance is known (every
//! valid point self-filtered), a pass that failed or came later than the latency budget is a
//! fault of the cell (ERROR, no distance: what no camera sees is not known free), and the
//! speed-scaling factor is 0 while the unseen distance holds the level at ERROR (between the
//! thresholds the separation stage holds each link to its unseen distance: `measure`). Under
//! `protect` no pass yet is a fault too. A frame's seen outputs, which go before its pass, are
//! fused with `Step::Raise` (the level may rise, never fall), its last word with `Step::Whole`
//! (`measure`).

use crate::config::Config;
use crate::query::{Nearest, Outcome, QueryResult};

use super::level::{Level, LevelTracker};
use super::source::{Latest, Part, Source};
use super::unseen::Unseen;

/// How a picture may move the cell's level.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Step {
    /// A frame's last word: the level follows the distance (raised at once, lowered after
    /// `release_frames` such steps).
    Whole,
    /// A frame's seen outputs, before its unseen pass under `protect`: the level may rise, never
    /// fall (the latest pass is the previous frame's: a release waits for this frame's).
    Raise,
    /// No new distance (a heartbeat; a frame's unseen outputs under `report`): the level stays
    /// as the results left it, faults aside.
    Keep,
}

/// What the fused picture is made for: a frame of `source` stamped `stamp_ns`, or a
/// heartbeat (`Step::Keep`; `stamp_ns` is the clock).
pub struct Moment {
    pub source: usize,
    pub stamp_ns: i64,
    /// The clock the sources' results are aged by.
    pub now_ns: i64,
    /// The frame took longer than `latency_budget`.
    pub over_budget: bool,
    /// The speed scaler's factor (`None` with the separation monitor off).
    pub factor: Option<f64>,
    pub step: Step,
}

/// The cell's picture at one instant, as fusion decided it (see the module doc).
pub struct Fused<'a> {
    pub level: Level,
    /// The fused conservative distance, m (`None`: a source in fault, or every measured
    /// source's valid points self-filtered).
    pub distance: Option<f64>,
    /// The source of that distance.
    pub nearest: Option<NearestSource<'a>>,
    /// Each link's minimum over the sources the picture rests on.
    pub per_link: PerLink,
    /// Why the cell is not watched whole: one line per enabled source in fault, or that none
    /// is enabled. Empty when the picture rests on every enabled source.
    pub faults: Vec<String>,
    /// The oldest stamp among the results the picture rests on (the moment's where none).
    pub stamp_ns: i64,
    /// What `~/speed_scaling` carries: the scaler's factor, 0 while a source is in fault
    /// (`None` with the separation monitor off).
    pub speed_factor: Option<f64>,
    /// Every enabled source's part, in the config's order.
    pub parts: Vec<(usize, Part<'a>)>,
    /// The moment's source: its closest-point markers are cleared when no source has any.
    pub source: usize,
    /// The latest pass over the unobserved space (`None` with `unobserved: ignore`).
    pub unseen: Option<&'a Unseen>,
    /// `protect`, and the unseen distance is below the seen one: the level follows it.
    pub unseen_limits: bool,
}

/// The source whose conservative distance is the smallest.
pub struct NearestSource<'a> {
    pub source: usize,
    pub distance_m: f64,
    /// Its nearest obstacle point, where it saw one (not for "nothing within").
    pub seen: Option<&'a Nearest>,
}

/// Each link's conservative distance, m, in the engine's link order.
#[derive(Default)]
pub struct PerLink {
    pub links: Vec<String>,
    pub distances_m: Vec<f64>,
}

impl<'a> Fused<'a> {
    /// The results the picture rests on: every measured source, or nothing while one is in
    /// fault.
    pub fn contributing(&self) -> impl Iterator<Item = (usize, &'a Latest)> + '_ {
        let whole = self.faults.is_empty();
        (self.parts.iter())
            .filter(move |_| whole)
            .filter_map(|(k, part)| match part {
                Part::Measured(l) => Some((*k, *l)),
                Part::Fault { .. } => None,
            })
    }
}

/// The fused picture of `sources` at `moment`; `fused` is the cell's level, which it updates.
pub fn fuse<'a>(
    config: &Config,
    sources: &'a [Source],
    unseen: Option<&'a Unseen>,
    fused: &mut LevelTracker,
    moment: &Moment,
) -> Fused<'a> {
    let parts: Vec<(usize, Part)> = (0..config.sources.len())
        .filter(|&k| config.sources[k].enabled)
        .map(|k| (k, sources[k].part(&config.sources[k], moment.now_ns)))
        .collect();
    let mut faults: Vec<String> = (parts.iter())
        .filter_map(|(k, part)| match part {
            Part::Fault { reason, .. } => {
                Some(format!("source {}: {reason}", config.sources[*k].name))
            }
            Part::Measured(_) => None,
        })
        .collect();
    if parts.is_empty() {
        // Nothing watches the cell (every source disabled, at start or at run time): as a
        // fault, never a clean state.
        faults.push("no source is enabled: nothing watches the cell".into());
    }
    let protect = config.unobserved.protects();
    let unseen_distance = match unseen.map(|u| &u.outcome) {
        Some(Ok(facts)) => facts.distance_m,
        Some(Err(reason)) if protect => {
            faults.push(format!("unobserved space not known: {reason}"));
            None
        }
        None if protect => {
            faults.push("unobserved space not known: no pass yet".into());
            None
        }
        _ => None,
    };
    let mut picture = Fused {
        level: Level::Error,
        distance: None,
        nearest: None,
        per_link: PerLink::default(),
        faults,
        stamp_ns: moment.stamp_ns,
        speed_factor: None,
        parts,
        source: moment.source,
        unseen,
        unseen_limits: false,
    };
    let holding = picture.contributing().any(|(_, l)| l.report.all_self);
    // The nearest source: the smallest conservative distance.
    let nearest = (picture.contributing())
        .filter_map(|(k, l)| l.report.distance.map(|d| (k, l, d)))
        .min_by(|a, b| a.2.total_cmp(&b.2));
    let nearest = nearest.map(|(source, l, distance_m)| NearestSource {
        source,
        distance_m,
        seen: (l.result.as_ref().ok())
            .filter(|r| r.outcome == Outcome::Nearest)
            .and_then(|r| r.nearest.as_ref()),
    });
    let distance = nearest.as_ref().map(|n| n.distance_m);
    // `protect`: the level follows the smaller of the two, the unseen one where no seen one is
    // known.
    let unseen_limits = protect
        && match (distance, unseen_distance) {
            (Some(d), Some(u)) => u < d,
            (None, Some(_)) => true,
            _ => false,
        };
    let level_distance = if unseen_limits {
        unseen_distance
    } else {
        distance
    };
    let whole = picture.faults.is_empty();
    let mut level = if !whole {
        fused.update(None)
    } else if moment.step == Step::Keep {
        // No new distance: the level stays as the results left it.
        fused.level()
    } else if let Some(d) = level_distance {
        let before = fused.level();
        let level = match moment.step {
            Step::Raise => fused.raise_for(d),
            _ => fused.update(Some(d)),
        };
        if holding {
            fused.hold_at_least(before.max(Level::Warn))
        } else {
            level
        }
    } else {
        // Every measured source self-filtered all its points: nothing is known, nothing
        // failed: WARN at least, the level held.
        fused.hold_at_least(Level::Warn)
    };
    if moment.over_budget {
        level = level.max(Level::Warn);
    }
    let stamp_ns = picture.contributing().map(|(_, l)| l.stamp_ns).min();
    let max_distance = f64::from(config.query.max_distance_m);
    let per_link = per_link(picture.contributing(), max_distance);
    picture.level = level;
    picture.distance = distance;
    picture.nearest = nearest;
    picture.per_link = per_link;
    picture.stamp_ns = stamp_ns.unwrap_or(moment.stamp_ns);
    // A source in fault allows no motion, whatever the scaler last had from it.
    picture.speed_factor = moment.factor.map(|f| {
        if whole && !(unseen_limits && level == Level::Error) {
            f
        } else {
            0.0
        }
    });
    picture.unseen_limits = unseen_limits;
    picture
}

/// Per link, the minimum over `contributing` (every source's links come in the engine's order).
fn per_link<'a>(
    contributing: impl Iterator<Item = (usize, &'a Latest)>,
    max_distance: f64,
) -> PerLink {
    let mut per_link = PerLink::default();
    for (_, l) in contributing {
        let Ok(r) = &l.result else { continue };
        let positions = link_positions(r, max_distance);
        if per_link.links.is_empty() {
            per_link.links = r.links.iter().map(|l| l.link.clone()).collect();
            per_link.distances_m = positions;
        } else {
            for (p, q) in per_link.distances_m.iter_mut().zip(positions) {
                *p = p.min(q);
            }
        }
    }
    per_link
}

/// Each link's conservative distance in a result, in the engine's link order (a link beyond
/// `per_link_range`: the bound it is known to exceed; `max_distance` when nothing is nearer).
pub fn link_positions(r: &QueryResult, max_distance: f64) -> Vec<f64> {
    r.links
        .iter()
        .map(|l| {
            l.exact_m
                .or(l.lower_m)
                .or(l.distance_m)
                .or(l.farther_than_m)
                .unwrap_or(max_distance)
        })
        .collect()
}
