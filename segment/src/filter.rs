//! Line filtering (section 4.3): lines of fewer than k samples are sensor interferences and go,
//! with their samples; then consecutive lines deviating less than alpha are merged and refitted
//! with all their samples.
//!
//! The paper merges on angle alone. Two parallel walls one behind the other (a recess, a door
//! frame) are also "consecutive lines with small angular deviation", so a merge here also needs
//! each line's near end to lie on the other line, within `merge_offset` or twice the sensor's
//! error at that range, whichever is larger.

use crate::line::Line;
use crate::sample::{ErrorModel, Sample};
use serde::{Deserialize, Serialize};

/// Parameters of section 4.3.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct FilterConfig {
    /// k: lines with fewer samples are discarded (the paper found 4-6 good; 5 by default).
    pub min_samples: u32,
    /// alpha: consecutive lines whose directions differ less than this merge (radians).
    pub merge_angle: f64,
    /// Largest offset between the lines of a merge, metres (see the module docs).
    pub merge_offset: f64,
}

impl Default for FilterConfig {
    fn default() -> Self {
        FilterConfig { min_samples: 5, merge_angle: 5f64.to_radians(), merge_offset: 0.06 }
    }
}

/// Filters `lines` (in scan order) into `out` (cleared first).
pub fn filter_lines(lines: &[Line], samples: &[Sample], error: &ErrorModel, cfg: &FilterConfig, out: &mut Vec<Line>) {
    out.clear();
    for line in lines.iter().filter(|l| l.samples >= cfg.min_samples) {
        if let Some(last) = out.last_mut() {
            if mergeable(last, line, error, cfg) {
                let mut m = last.moments;
                m += line.moments;
                if let Some(merged) =
                    Line::from_moments(samples, last.first_sample as usize, line.last_sample as usize, m, error)
                {
                    *last = merged;
                    continue;
                }
            }
        }
        out.push(*line);
    }
}

fn mergeable(a: &Line, b: &Line, error: &ErrorModel, cfg: &FilterConfig) -> bool {
    let cos = a.direction.dot(&b.direction).abs().min(1.0);
    if cos.acos() >= cfg.merge_angle {
        return false;
    }
    let tolerance = |p: nalgebra::Point2<f64>| cfg.merge_offset.max(2.0 * error.at(p.coords.norm()));
    a.distance_to(b.start) <= tolerance(b.start) && b.distance_to(a.end) <= tolerance(a.end)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fit::Moments;
    use nalgebra::Point2;

    /// Samples along a segment from `a` to `b`, `n` of them, as if seen from the origin.
    fn samples_on(a: Point2<f64>, b: Point2<f64>, n: usize, gap_before: bool) -> Vec<Sample> {
        (0..n)
            .map(|k| {
                let p = a + (b - a) * (k as f64 / (n - 1) as f64);
                let d = p.coords.norm();
                Sample {
                    beam: 0,
                    dir: p.coords / d,
                    d,
                    near: d - 0.02,
                    far: d + 0.02,
                    gap_before: gap_before && k == 0,
                }
            })
            .collect()
    }

    fn line_of(samples: &[Sample], first: usize, n: usize) -> Line {
        let mut m = Moments::default();
        for s in &samples[first..first + n] {
            m.add(s.point());
        }
        Line::from_moments(samples, first, first + n - 1, m, &ErrorModel::PAPER).unwrap()
    }

    #[test]
    fn short_lines_go_and_collinear_neighbours_merge() {
        let mut s = samples_on(Point2::new(2.0, -2.0), Point2::new(2.0, -0.5), 20, true);
        s.extend(samples_on(Point2::new(1.0, -0.4), Point2::new(1.0, -0.35), 3, true)); // a leg
        s.extend(samples_on(Point2::new(2.0, -0.2), Point2::new(2.0, 1.5), 20, true));
        let lines = vec![line_of(&s, 0, 20), line_of(&s, 20, 3), line_of(&s, 23, 20)];
        let mut out = Vec::new();
        filter_lines(&lines, &s, &ErrorModel::PAPER, &FilterConfig::default(), &mut out);
        assert_eq!(out.len(), 1);
        assert_eq!(out[0].samples, 40);
        assert!((out[0].start - Point2::new(2.0, -2.0)).norm() < 1e-9);
        assert!((out[0].end - Point2::new(2.0, 1.5)).norm() < 1e-9);
    }

    #[test]
    fn parallel_walls_at_different_depths_do_not_merge() {
        let mut s = samples_on(Point2::new(2.0, -2.0), Point2::new(2.0, -0.5), 20, true);
        s.extend(samples_on(Point2::new(2.3, -0.5), Point2::new(2.3, 1.0), 20, true));
        let lines = vec![line_of(&s, 0, 20), line_of(&s, 20, 20)];
        let mut out = Vec::new();
        filter_lines(&lines, &s, &ErrorModel::PAPER, &FilterConfig::default(), &mut out);
        assert_eq!(out.len(), 2);
    }
}
