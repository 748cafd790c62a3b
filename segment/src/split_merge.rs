//! A split-and-merge segmentation baseline with the same outputs as line visibility: runs of
//! samples between gaps and depth jumps are split recursively at the sample farthest from the
//! chord until every piece lies within e(d) of it, then filtered and cornered exactly as the
//! paper's lines are. It exists so the two can be compared, and swapped, in one running
//! pipeline.

use crate::fit::Moments;
use crate::line::Line;
use crate::noise::noise_scale;
use crate::sample::{build_samples, ErrorModel, Sample};
use crate::segmenter::{finish, Segmentation, Segmenter, SegmenterConfig};
use laser::ScanView;
use std::time::Instant;

#[derive(Clone, Debug)]
pub struct SplitAndMergeSegmenter {
    pub config: SegmenterConfig,
    out: Segmentation,
    stack: Vec<(usize, usize)>,
    scratch: Vec<f64>,
}

impl SplitAndMergeSegmenter {
    pub fn new(config: SegmenterConfig) -> Self {
        SplitAndMergeSegmenter { config, out: Segmentation::default(), stack: Vec::new(), scratch: Vec::new() }
    }

    /// Splits `samples[first..=last]` into lines pushed onto `out` (in scan order).
    fn split(&mut self, first: usize, last: usize, error: &ErrorModel) {
        let samples = &self.out.samples;
        self.stack.clear();
        self.stack.push((first, last));
        let mut pieces = Vec::new();
        while let Some((a, b)) = self.stack.pop() {
            let (pa, pb) = (samples[a].point(), samples[b].point());
            let chord = pb - pa;
            let len = chord.norm();
            let mut worst = (0.0, a);
            if len > 1e-9 {
                for (k, s) in samples.iter().enumerate().take(b).skip(a + 1) {
                    let off = (s.point() - pa).perp(&chord).abs() / len;
                    let excess = off / error.at(s.d);
                    if excess > worst.0 {
                        worst = (excess, k);
                    }
                }
            }
            if worst.0 > 1.0 && worst.1 > a && worst.1 < b {
                // push the right part first so pieces come out in scan order
                self.stack.push((worst.1, b));
                self.stack.push((a, worst.1));
            } else {
                pieces.push((a, b));
            }
        }
        for (a, b) in pieces {
            if b > a {
                let mut m = Moments::default();
                for s in &samples[a..=b] {
                    m.add(s.point());
                }
                if let Some(line) = Line::from_moments(samples, a, b, m, error) {
                    self.out.raw_lines.push(line);
                }
            }
        }
    }
}

/// Whether `s` starts a new run: after invalid readings, or a jump in depth beyond the error
/// bands of both readings.
fn breaks(prev: &Sample, s: &Sample) -> bool {
    s.gap_before || (s.d - prev.d).abs() > (s.far - s.d) + (prev.far - prev.d) + 0.1 * s.d.min(prev.d)
}

impl Segmenter for SplitAndMergeSegmenter {
    fn name(&self) -> &'static str {
        "split-and-merge"
    }

    fn segment(&mut self, scan: &ScanView<'_>) -> &Segmentation {
        let c = self.config;
        let t0 = Instant::now();
        self.out.noise_scale = noise_scale(scan, &c.error, c.noise_tolerance, &mut self.scratch);
        let error = c.error.scaled(self.out.noise_scale);
        build_samples(scan, &error, c.averaging, &mut self.out.samples);
        let t1 = Instant::now();
        self.out.raw_lines.clear();
        let n = self.out.samples.len();
        let mut start = 0;
        for k in 1..=n {
            if k == n || breaks(&self.out.samples[k - 1], &self.out.samples[k]) {
                self.split(start, k - 1, &error);
                start = k;
            }
        }
        finish(scan, &c, &error, [t0, t1, Instant::now()], &mut self.out);
        &self.out
    }
}

/// A segmenter by name: `line-visibility` (the paper's) or `split-and-merge`.
pub fn segmenter_by_name(name: &str, config: SegmenterConfig) -> Option<Box<dyn Segmenter>> {
    match name {
        "line-visibility" => Some(Box::new(crate::LineVisibilitySegmenter::new(config))),
        "split-and-merge" => Some(Box::new(SplitAndMergeSegmenter::new(config))),
        _ => None,
    }
}

/// The implementations [`segmenter_by_name`] knows.
pub const SEGMENTERS: [&str; 2] = ["line-visibility", "split-and-merge"];

#[cfg(test)]
mod tests {
    use super::*;
    use crate::inference::tests_support::room_ranges;
    use laser::ScanGeometry;

    #[test]
    fn both_implementations_find_the_corners_of_a_room() {
        let g = ScanGeometry::urg04lx();
        let ranges = room_ranges(&g, 682, &[(-1.0, -1.5), (3.0, -1.5), (3.0, 2.0), (-1.0, 2.0)]);
        let scan = ScanView { geometry: g, ranges: &ranges };
        for name in SEGMENTERS {
            let mut s = segmenter_by_name(name, SegmenterConfig::default()).unwrap();
            let out = s.segment(&scan);
            assert_eq!(out.lines.len(), 4, "{name}");
            // the room's corners at (3, -1.5) and (3, 2) (and (-1, 2) in view) are found
            for (x, y) in [(3.0, -1.5), (3.0, 2.0)] {
                assert!(
                    out.corners.iter().any(|c| (c.position.x - x).abs() < 0.02 && (c.position.y - y).abs() < 0.02),
                    "{name}: ({x}, {y})"
                );
            }
        }
        assert!(segmenter_by_name("nope", SegmenterConfig::default()).is_none());
    }
}
