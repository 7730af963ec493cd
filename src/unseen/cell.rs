//! Step 2b, a lattice cell: whether a hidden body of the detection capability can be centred
//! anywhere in it, over every view.
//!
//! A body of radius `R` centred at `c*` in the cell of centre `x` (a cube of side `h`, diagonal
//! `d`) holds the **base ball** `B(x, R − d/2)`, so one ray that passes the base ball's entry
//! rules out every such body at once (`footprint`). Where no view rules out the base ball, the
//! cell is cut in eight: `c*` lies in one of the sub-cubes, of centre `x_k` at `h/4` from `x`
//! along each axis, and holds the **sub-ball** `B(x_k, R − d/4)`, larger than the base ball; the
//! cell is still free when every sub-ball is ruled out, each by some view. This recovers most of
//! what sampling the lattice costs (the base ball is half the capability's radius at 70 mm on a
//! 2 cm lattice; the sub-balls three quarters), so that a small cluster of dropped pixels no
//! wider than a hand does not keep a cell, while a place a body can hide in is kept whatever
//! the order.
//!
//! **The robot's shadow** (`Need::Shadow`): a cell is in the shadow when the robot hides its
//! base ball from every view that can see it ([`in_shadow`]); such a cell is not refined (its
//! distance is the shadow's own, reported apart, and taking it hidden only lowers that).
//!
//! **Verdicts made on the GPU** (`shaders/cell.wgsl`, by the same rule, for a depth image in the
//! query's submission): a view that carries them answers "ruled out or not" for the base ball
//! and each sub-ball by one bit; the footprint is scanned here only where a cause is needed.
//!
//! Cost: the base ball in each view (most cells end there); where it stays hidden, up to eight
//! sub-balls (each often decided by the pyramids).

use super::ball::BallSize;
use super::footprint::{judge, Cause, Need, Seen, Why};
use super::lattice::{centre_at, Lattice};
use super::prepared::PreparedView;

/// A view with the lattice placed in its camera frame.
pub struct PlacedView<'a> {
    pub view: &'a PreparedView,
    pub origin: [f32; 3],
    pub steps: [[f32; 3]; 3],
    /// The GPU's verdicts on this lattice in this view, one word a cell in the lattice's
    /// index order (bit 0: the base ball ruled out; bit `1 + k`: sub-ball `k`), if it made them.
    verdicts: Option<&'a [u32]>,
    dims: [usize; 3],
}

impl<'a> PlacedView<'a> {
    pub fn new(view: &'a PreparedView, lattice: &Lattice) -> Self {
        let (origin, steps) = lattice.in_frame(view.camera_from_root());
        Self {
            view,
            origin,
            steps,
            verdicts: None,
            dims: lattice.dims(),
        }
    }

    /// The view with the GPU's `verdicts` on the same lattice (ignored unless one a cell).
    pub fn with_verdicts(mut self, verdicts: Option<&'a [u32]>) -> Self {
        let cells = self.dims.iter().product::<usize>();
        self.verdicts = verdicts.filter(|v| v.len() == cells);
        self
    }

    /// Whether it carries the GPU's verdicts.
    pub fn has_verdicts(&self) -> bool {
        self.verdicts.is_some()
    }

    /// The GPU's word on cell `ijk`, if there is one.
    #[inline]
    fn verdict(&self, ijk: [usize; 3]) -> Option<u32> {
        let [n0, n1, _] = self.dims;
        (self.verdicts).map(|v| v[ijk[0] + n0 * (ijk[1] + n1 * ijk[2])])
    }

    /// Cell `ijk`'s centre in the camera frame.
    #[inline]
    pub fn centre(&self, ijk: [usize; 3]) -> [f32; 3] {
        centre_at(self.origin, &self.steps, ijk)
    }

    /// The centre of sub-cube `k` (bit `a` set: `+h/4` along axis `a`, else `−h/4`) of cell
    /// `ijk`, in the camera frame.
    #[inline]
    pub fn sub_centre(&self, ijk: [usize; 3], k: usize) -> [f32; 3] {
        let mut p = self.centre(ijk);
        for a in 0..3 {
            let sign = if k >> a & 1 == 1 { 0.25 } else { -0.25 };
            for (c, s) in p.iter_mut().zip(self.steps[a]) {
                *c += sign * s;
            }
        }
        p
    }

    /// The view's verdict on the ball of radius `r` at camera-frame `p`.
    #[inline]
    fn judge(&self, p: [f32; 3], r: f32, need: Need, pyramids: bool) -> Seen {
        let v = self.view;
        judge(
            v.optics(),
            &v.pixels(),
            pyramids.then(|| v.pyramids()),
            p,
            r,
            need,
        )
    }
}

/// A cell's verdict over every view.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CellSeen {
    Free,
    /// No view rules out every body that may be centred in it; `shadow` (with `Need::Shadow`):
    /// the robot hides each such ball from every view that can see it.
    Hidden {
        shadow: bool,
    },
}

/// Whether any body of `size`'s capability can be centred in cell `ijk`, over `views` (see the
/// module doc). `known[v]`: what view `v` says of the base ball and every sub-ball at once
/// (the search's block shortcuts), or `None` to judge them; `pyramids`: use the views'
/// pyramids (the per-ball shortcuts; the result is the same).
pub fn judge_cell(
    views: &[PlacedView],
    ijk: [usize; 3],
    size: &BallSize,
    need: Need,
    known: &[Option<Why>],
    pyramids: bool,
) -> CellSeen {
    let mut whys = Vec::with_capacity(views.len());
    // `bit` of the GPU's word: 0 the base ball, 1 + k sub-ball k.
    let all = |p: &dyn Fn(&PlacedView) -> [f32; 3], r: f32, bit: u32, whys: &mut Vec<Why>| {
        whys.clear();
        for (v, k) in views.iter().zip(known) {
            let seen = match (k, v.verdict(ijk)) {
                (Some(why), _) => Seen::Hidden(*why),
                (None, Some(word)) if word >> bit & 1 == 1 => Seen::Free,
                (None, Some(_)) if need == Need::Verdict => Seen::Hidden(Why::Unknown),
                (None, _) => v.judge(p(v), r, need, pyramids),
            };
            match seen {
                Seen::Free => return true,
                Seen::Hidden(why) => whys.push(why),
            }
        }
        false
    };
    if all(&|v| v.centre(ijk), size.radius_m, 0, &mut whys) {
        return CellSeen::Free;
    }
    if need == Need::Shadow && in_shadow(&whys) {
        // The robot hides the base ball from every view that can see it: the shadow, not
        // refined (its own distance is reported apart, and a smaller one is on the safe side).
        return CellSeen::Hidden { shadow: true };
    }
    for k in 0..8 {
        if !all(
            &|v| v.sub_centre(ijk, k),
            size.sub_radius_m,
            1 + k as u32,
            &mut whys,
        ) {
            return CellSeen::Hidden { shadow: false };
        }
    }
    CellSeen::Free
}

/// Whether every view's word on a hidden ball is the robot's shadow or outside the view, and
/// at least one the robot's shadow.
pub fn in_shadow(whys: &[Why]) -> bool {
    let shadow = Why::Known(Cause::RobotShadow);
    let outside = Why::Known(Cause::OutsideView);
    whys.contains(&shadow) && whys.iter().all(|w| *w == shadow || *w == outside)
}
