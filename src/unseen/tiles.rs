//! Step 2's scan by tiles: whether any ray of a footprint rules its ball out, where only the
//! verdict is asked (the search with the robot's shadow counted), read from the free
//! pyramid's texels before any pixel (`footprint` has the rule, the ball and the other
//! shortcuts; it gives this walk the two tests it needs).
//!
//! The window is cut into the texels of the level whose side is at most a quarter of its
//! longer side. A texel whose largest free distance is at most the ball's least entry `l − r`
//! holds no ray that rules the ball out (every ray through the ball enters it at `l − r` or
//! beyond): skipped whole. A texel wholly inside the footprint whose largest free distance
//! reaches `l` holds a ray that passes the ball's centre (`g ≥ l ≥ d·p`): the ball is ruled
//! out at once. "Wholly inside" is read at the texel's corner pixels (the caller's test, with
//! room for the f32 sums): the cone's trace on the image plane is convex, so every pixel
//! between the corners is inside too. The pixels of the other texels are tested one by one
//! as the full scan tests them, so the verdict is the scan's
//! (`footprint::tests::the_shortcuts_agree_with_the_scan`).
//!
//! Cost: a few dozen texel reads, and the pixels of the texels a surface crosses, where the
//! full scan reads every pixel of a hidden ball's footprint (about 2,500 on the Kinect frame)
//! and some 570 before the free ray of one that is not: the Kinect frame's search 3.1–3.3 →
//! 2.4–2.5 ms (docs/unobserved.md).

use super::camera::Rect;
use super::pyramid::Pyramid;

/// Tiles per window side, about: the tiles are the texels of the pyramid's level whose side
/// is at most a quarter of the window's longer side.
const TILES: usize = 4;

/// Most tiles a window spans (under `2·TILES + 1` a side: 81), one bit each.
const MOST_TILES: usize = 128;

/// A footprint's window over the free pyramid, with the ball's least entry and its centre's
/// distance, each with the f32 sums' room taken (`entry = l − r − ε`, `beyond = l + ε`).
pub struct Tiles<'a> {
    pub free: &'a Pyramid,
    pub rect: Rect,
    pub entry: f32,
    pub beyond: f32,
}

impl Tiles<'_> {
    /// Whether a ray of the window rules the ball out: `inside(q)` whether pixel `q`'s ray
    /// lies in the footprint's cone with room, `free(q)` the full scan's test of pixel `q`.
    /// `None` where the window is too small for tiles (or spans more than `MOST_TILES`).
    pub fn rule_out(
        &self,
        inside: impl Fn(usize) -> bool,
        mut free: impl FnMut(usize) -> bool,
    ) -> Option<bool> {
        let rect = self.rect;
        let side = (rect.u1 - rect.u0 + 1).max(rect.v1 - rect.v0 + 1);
        let k = (usize::BITS - 1).checked_sub((side / TILES).leading_zeros())? as usize;
        if k == 0 {
            return None;
        }
        let (maxima, across_level) = self.free.maxima(k)?;
        let (width, height) = (self.free.width(), self.free.height());
        let (j0, j1) = (rect.v0 >> k, rect.v1 >> k);
        let (i0, i1) = (rect.u0 >> k, rect.u1 >> k);
        let across = i1 - i0 + 1;
        if across * (j1 - j0 + 1) > MOST_TILES {
            return None;
        }
        let mut each = 0u128;
        for j in j0..=j1 {
            for i in i0..=i1 {
                let most = maxima[j * across_level + i];
                if most <= self.entry {
                    continue;
                }
                // The pixels the texel covers.
                let (u0, v0) = (i << k, j << k);
                let (u1, v1) = (
                    (u0 + (1 << k)).min(width) - 1,
                    (v0 + (1 << k)).min(height) - 1,
                );
                let corners = [(u0, v0), (u1, v0), (u0, v1), (u1, v1)];
                if most >= self.beyond && corners.iter().all(|&(u, v)| inside(v * width + u)) {
                    return Some(true);
                }
                each |= 1 << ((j - j0) * across + (i - i0));
            }
        }
        while each != 0 {
            let t = each.trailing_zeros() as usize;
            each &= each - 1;
            let (i, j) = (i0 + t % across, j0 + t / across);
            // The tile's pixels in the window.
            let (u0, v0) = ((i << k).max(rect.u0), (j << k).max(rect.v0));
            let (u1, v1) = (
                (((i + 1) << k) - 1).min(rect.u1),
                (((j + 1) << k) - 1).min(rect.v1),
            );
            for v in v0..=v1 {
                if (u0..=u1).any(|u| free(v * width + u)) {
                    return Some(true);
                }
            }
        }
        Some(false)
    }
}
