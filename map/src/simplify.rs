//! Douglas-Peucker simplification of a chain of points: which points a polyline keeps so that
//! every point it drops lies within a tolerance of the segment that replaces it. Used on the
//! chains of wall ends that make straight runs ([`crate::runs`]) and on the outlines traced from
//! an occupancy grid (`mapio::trace`).

use crate::wall::Wall;
use nalgebra::Point2;

/// The indices of `points` kept when each span `(first, last)` (`last` taken modulo the point
/// count, so a span may close a ring) is split at its point farthest from its chord while that
/// is beyond `tolerance`. Span ends and split points are kept; the indices come in order.
pub fn douglas_peucker(points: &[Point2<f64>], mut spans: Vec<(usize, usize)>, tolerance: f64) -> Vec<usize> {
    let n = points.len();
    if n == 0 {
        return Vec::new();
    }
    let mut keep = vec![false; n];
    for &(first, last) in &spans {
        keep[first % n] = true;
        keep[last % n] = true;
    }
    while let Some((first, last)) = spans.pop() {
        let chord = Wall { a: points[first % n], b: points[last % n] };
        let farthest =
            (first + 1..last).map(|k| (k, chord.closest(points[k % n]).0)).max_by(|x, y| x.1.total_cmp(&y.1));
        if let Some((k, _)) = farthest.filter(|&(_, d)| d > tolerance) {
            keep[k % n] = true;
            spans.push((first, k));
            spans.push((k, last));
        }
    }
    (0..n).filter(|&k| keep[k]).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_chain_keeps_its_corners_and_drops_what_lies_on_its_segments() {
        let p = |x: f64, y: f64| Point2::new(x, y);
        // an L with a point mid-leg and a bump within tolerance
        let chain = [p(0.0, 0.0), p(1.0, 0.01), p(2.0, 0.0), p(2.0, 1.0), p(2.0, 2.0)];
        assert_eq!(douglas_peucker(&chain, vec![(0, 4)], 0.05), vec![0, 2, 4]);
        assert_eq!(douglas_peucker(&chain, vec![(0, 4)], 0.001), vec![0, 1, 2, 4]);
        // a square as a ring: the span (2, 4) closes it at index 4 = 0
        let square = [p(0.0, 0.0), p(1.0, 0.0), p(1.0, 1.0), p(0.0, 1.0)];
        assert_eq!(douglas_peucker(&square, vec![(0, 2), (2, 4)], 0.1), vec![0, 1, 2, 3]);
        assert!(douglas_peucker(&[], vec![], 0.1).is_empty());
    }
}
