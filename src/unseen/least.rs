//! The entry of a best-first heap: an item keyed by a lower bound, the least bound first out of
//! std's max-heap. The search keeps its boxes' bounds there with an index into its own list of
//! boxes (a pop moves 8 bytes, not the box), and the measure its pairs of centre and link.

use std::cmp::Ordering;

/// `item` with its lower bound `bound` (m); ordered by the bound alone, reversed.
#[derive(Debug, Clone, Copy)]
pub(super) struct Least<T> {
    pub bound: f32,
    pub item: T,
}

impl<T> PartialEq for Least<T> {
    fn eq(&self, other: &Self) -> bool {
        self.cmp(other) == Ordering::Equal
    }
}

impl<T> Eq for Least<T> {}

impl<T> PartialOrd for Least<T> {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}

impl<T> Ord for Least<T> {
    /// The least bound first out of the (max-)heap.
    fn cmp(&self, other: &Self) -> Ordering {
        other.bound.total_cmp(&self.bound)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::BinaryHeap;

    #[test]
    fn the_least_bound_comes_out_first() {
        let mut heap: BinaryHeap<Least<u32>> = [3.0, -1.0, 2.5, f32::INFINITY, 0.0]
            .iter()
            .enumerate()
            .map(|(i, &bound)| Least {
                bound,
                item: i as u32,
            })
            .collect();
        let order: Vec<u32> = std::iter::from_fn(|| heap.pop().map(|l| l.item)).collect();
        assert_eq!(order, vec![1, 4, 2, 0, 3]);
    }
}
