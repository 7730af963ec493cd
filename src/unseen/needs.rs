//! The search's bests still open (`search`): what a block or a centre must be nearer than to be
//! worth examining, over the counted distance, the robot's shadow (apart) and each link.
//!
//! A link's need is its best so far, capped at the per-link range; a best at or below the
//! ball's margin is final (−∞: nothing is needed to lower it). A centre is wanted when some link
//! with an open need may come within it: its bounding sphere, then one of its covers, each
//! grown by the link's h ([`LinkBound::may_be_within`], on squared distances).
//!
//! **Per block.** Every centre of a block lies within `ρ` of its middle, so a cover farther than
//! its reach plus `ρ` from the middle can bring none of them within a need: [`Needs::in_block`]
//! keeps, once a block, the links and covers that may ([`Wanted`]), and each of the block's 64
//! centres is tested against those alone (on the Kinect frame a handful of the 11 × 32 covers).
//! The test per centre is the one [`LinkBound::may_be_within`] makes, on fewer covers. Where one
//! cover, and its link's bounding sphere, come within reach less `ρ` of the middle, every centre
//! is wanted and none is tested (a large need: the first waves, a scene where nothing is found
//! hidden). All on squared distances, no square root.

use super::robot::{distance2, LinkBound};

/// What the f32 sums of a block's middle may lose (m): a cover within this much more than its
/// reach plus `ρ` is kept for the block.
const SLACK_M: f32 = 1e-4;

/// The bests still open: what a centre must be nearer than to be worth examining.
#[derive(Debug, Clone)]
pub(super) struct Needs {
    pub counted: f64,
    pub shadow: f64,
    pub links: Vec<f64>,
}

/// The spheres of the links that may bring a centre of one block within a need: per link its
/// bounding sphere and a range of `covers`, each sphere as its centre and squared reach.
pub(super) struct Wanted {
    /// Every centre of the block: one cover (and its link's bounding sphere) reaches them all.
    all: bool,
    links: Vec<Reach>,
    covers: Vec<([f32; 3], f32)>,
}

/// One link's part of [`Wanted`]: its bounding sphere's centre and squared reach, and its covers
/// (`None`: the link has none, the bounding sphere decides).
struct Reach {
    centre: [f32; 3],
    reach2: f32,
    covers: Option<std::ops::Range<usize>>,
}

impl Needs {
    /// The largest need: nothing whose bound is at least this is needed.
    pub fn stop(&self) -> f64 {
        self.links
            .iter()
            .copied()
            .fold(self.counted.max(self.shadow), f64::max)
    }

    /// Whether a place `bound` from the robot, `link_bound(l)` from each link, may lower one.
    pub fn wants(&self, bound: f32, link_bound: impl Fn(usize) -> f32) -> bool {
        let b = f64::from(bound);
        b < self.counted
            || b < self.shadow
            || (self.links.iter().enumerate()).any(|(l, &n)| f64::from(link_bound(l)) < n)
    }

    /// Link `l`'s need, the counted and the shadow's included (−∞: none).
    fn of_link(&self, l: usize) -> f64 {
        let any = self.counted.max(self.shadow);
        self.links.get(l).map_or(any, |&n| n.max(any))
    }

    /// The links and covers that may bring a centre within `rho` of root-frame `middle` within
    /// a need (see the module doc).
    pub fn in_block(&self, links: &[LinkBound], middle: [f32; 3], rho: f32) -> Wanted {
        let mut wanted = Wanted {
            all: false,
            links: Vec::new(),
            covers: Vec::new(),
        };
        for (l, link) in links.iter().enumerate() {
            let need = self.of_link(l);
            if need == f64::NEG_INFINITY {
                continue;
            }
            let need = need as f32;
            // The sphere (c, r) grown by h comes within `need` of p: |p − c| < need + r + h. It
            // may for some centre of the block where |middle − c| < reach + ρ, and does for
            // every one where |middle − c| < reach − ρ (squared; room for the f32 sums).
            let reach = |r: f32| link.reach(r, need);
            let within = |c: [f32; 3], d: f32| d > 0.0 && distance2(middle, c) < d * d;
            let near = |c: [f32; 3], r: f32| reach(r) > 0.0 && within(c, reach(r) + rho + SLACK_M);
            let whole = |c: [f32; 3], r: f32| within(c, reach(r) - rho - SLACK_M);
            if !near(link.centre, link.radius) {
                continue;
            }
            let sphere_whole = whole(link.centre, link.radius);
            let squared = |r: f32| reach(r).max(0.0).powi(2);
            let start = wanted.covers.len();
            for &(c, r) in &link.covers {
                if sphere_whole && whole(c, r) {
                    // Every centre of the block is wanted.
                    wanted.all = true;
                    return wanted;
                }
                if near(c, r) {
                    wanted.covers.push((c, squared(r)));
                }
            }
            if link.covers.is_empty() && sphere_whole {
                wanted.all = true;
                return wanted;
            }
            let covers = (!link.covers.is_empty()).then_some(start..wanted.covers.len());
            if covers.as_ref().is_some_and(|c| c.is_empty()) {
                continue;
            }
            wanted.links.push(Reach {
                centre: link.centre,
                reach2: squared(link.radius),
                covers,
            });
        }
        wanted
    }

    /// The bound of root-frame point `p` from the robot (the links' covers where they may
    /// matter): the markers' order.
    pub fn near(&self, links: &[LinkBound], p: [f32; 3]) -> f32 {
        (links.iter().enumerate())
            .map(|(l, link)| link.lower_bound_below(p, self.of_link(l) as f32))
            .fold(f32::INFINITY, f32::min)
    }
}

impl Wanted {
    /// Whether root-frame centre `p` of the block may lower a best still open: what
    /// [`LinkBound::may_be_within`] says of each link at its need, on the covers kept.
    #[inline]
    pub fn point(&self, p: [f32; 3]) -> bool {
        self.all
            || self.links.iter().any(|link| {
                distance2(p, link.centre) < link.reach2
                    && link.covers.clone().is_none_or(|range| {
                        (self.covers[range].iter()).any(|&(c, reach2)| distance2(p, c) < reach2)
                    })
            })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn point() -> impl Strategy<Value = [f32; 3]> {
        prop::array::uniform3(-1.0f32..1.0)
    }

    /// A need: open at some distance, or final.
    fn need() -> impl Strategy<Value = f64> {
        prop_oneof![3 => 0.0f64..0.4, 1 => Just(f64::NEG_INFINITY)]
    }

    fn link() -> impl Strategy<Value = LinkBound> {
        (
            point(),
            0.05f32..0.4,
            0.0f32..0.01,
            prop::collection::vec((point(), 0.01f32..0.2), 0..6),
        )
            .prop_map(|(centre, radius, gap_m, covers)| LinkBound {
                centre,
                radius,
                gap_m,
                covers: covers
                    .into_iter()
                    .map(|(c, r)| (std::array::from_fn(|k| centre[k] + 0.3 * c[k]), r))
                    .collect(),
            })
    }

    proptest! {
        /// Each centre of a block is wanted exactly where some link at its need may come within
        /// it ([`LinkBound::may_be_within`], the per-centre test of every cover).
        #[test]
        fn a_block_wants_what_every_cover_wants(
            links in prop::collection::vec(link(), 1..5),
            needs in prop::collection::vec(need(), 5),
            counted in need(),
            middle in point(),
            offsets in prop::collection::vec(prop::array::uniform3(-1.0f32..1.0), 1..20),
            rho in 0.0f32..0.2,
        ) {
            let needs = Needs {
                counted,
                shadow: f64::NEG_INFINITY,
                links: needs[..links.len()].to_vec(),
            };
            let wanted = needs.in_block(&links, middle, rho);
            for o in offsets {
                // A point within ρ of the middle.
                let n = (o.iter().map(|x| x * x).sum::<f32>()).sqrt().max(1.0);
                let p = std::array::from_fn(|k| middle[k] + rho * o[k] / n);
                let every = (links.iter().enumerate()).any(|(l, link)| {
                    let need = needs.of_link(l);
                    need > f64::NEG_INFINITY && link.may_be_within(p, need as f32)
                });
                prop_assert_eq!(wanted.point(p), every, "{:?}", p);
            }
        }
    }
}
