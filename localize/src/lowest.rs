//! The `keep` lowest of a stream of costs: the bound the screening and coarse passes stop a
//! pose at once it provably cannot be kept.

use std::collections::BinaryHeap;

/// The lowest values offered so far, at most `keep` of them, as a max-heap of their bit
/// patterns: costs are non-negative, and non-negative floats order as their bits do. The heap
/// is kept between scans so that its storage is reused.
#[derive(Debug, Default)]
pub(crate) struct Lowest {
    heap: BinaryHeap<u64>,
}

impl Lowest {
    pub(crate) fn clear(&mut self) {
        self.heap.clear();
    }

    /// Offers a non-negative `value`: kept while fewer than `keep` are, or in place of the
    /// highest kept when lower than it.
    #[inline]
    pub(crate) fn offer(&mut self, value: f64, keep: usize) {
        debug_assert!(value >= 0.0, "{value}");
        let bits = value.to_bits();
        if self.heap.len() < keep {
            self.heap.push(bits);
        } else if self.heap.peek().is_some_and(|&top| bits < top) {
            self.heap.pop();
            self.heap.push(bits);
        }
    }

    /// The `keep`-th lowest value offered so far; +inf until `keep` have been offered.
    #[inline]
    pub(crate) fn kth(&self, keep: usize) -> f64 {
        match self.heap.peek() {
            Some(&top) if self.heap.len() >= keep => f64::from_bits(top),
            _ => f64::INFINITY,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #[test]
        fn the_kth_is_the_kth_lowest_of_all_offered(
            values in proptest::collection::vec(0.0f64..100.0, 0..60),
            keep in 0usize..20,
        ) {
            let mut lowest = Lowest::default();
            for &v in &values {
                lowest.offer(v, keep);
            }
            let mut sorted = values.clone();
            sorted.sort_by(f64::total_cmp);
            let expected = match keep.checked_sub(1).and_then(|k| sorted.get(k)) {
                Some(&v) => v,
                None => f64::INFINITY,
            };
            prop_assert_eq!(lowest.kth(keep), expected);
        }
    }

    #[test]
    fn clearing_forgets_what_was_offered() {
        let mut lowest = Lowest::default();
        lowest.offer(1.0, 1);
        assert_eq!(lowest.kth(1), 1.0);
        lowest.clear();
        assert_eq!(lowest.kth(1), f64::INFINITY);
    }
}
