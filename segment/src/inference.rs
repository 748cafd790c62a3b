//! Line inference (section 4.2, Code 1): samples in scan order are added to the current line
//! while line visibility admits them; otherwise the line is closed, fitted, and a new line
//! starts at the sample. Invalid readings (a gap) close the line too.
//!
//! Near a corner the first samples of the next wall still lie within e(d) of the previous
//! wall's extension, so line visibility admits them (the paper's case A). After Code 1,
//! samples where two adjacent lines meet therefore go to whichever line they lie closer to, and
//! then up to [`MAX_TRIM`] end samples farther than half their error band from their line are
//! dropped, so corners are not bent towards the neighbouring wall.

use crate::fit::Moments;
use crate::line::Line;
use crate::sample::{ErrorModel, Sample};
use crate::visibility::LineVisibility;

/// Infers the lines L of `samples` into `out` (cleared first). Lines of one sample are kept
/// in the count but have no fit, so they are not emitted: filtering would discard them anyway.
/// Returns the number of clusters Code 1 produced (the size of L).
pub fn infer_lines(samples: &[Sample], angle_increment: f64, error: &ErrorModel, out: &mut Vec<Line>) -> usize {
    out.clear();
    if samples.is_empty() {
        return 0;
    }
    let mut visibility = LineVisibility::new(angle_increment);
    let mut moments = Moments::default();
    let mut first = 0;
    let mut clusters = 0;
    for (j, s) in samples.iter().enumerate() {
        let bounds = visibility.crossings(s);
        if j == 0 || s.gap_before || !visibility.admits_within(s, bounds) {
            if j > 0 {
                close(samples, first, j - 1, moments, error, out);
                clusters += 1;
            }
            first = j;
            moments = Moments::default();
            visibility.restart(samples, j);
        } else {
            visibility.include_within(samples, j, bounds);
        }
        moments.add(s.point());
    }
    close(samples, first, samples.len() - 1, moments, error, out);
    reassign_boundaries(samples, error, out);
    for line in out.iter_mut() {
        trim_ends(samples, error, line);
    }
    out.retain(|l| l.samples >= 2);
    clusters + 1
}

/// Moves samples across the boundary of adjacent lines to the line they fit better.
fn reassign_boundaries(samples: &[Sample], error: &ErrorModel, lines: &mut [Line]) {
    for i in 1..lines.len() {
        let (head, tail) = lines.split_at_mut(i);
        let (a, b) = (&mut head[i - 1], &mut tail[0]);
        if b.first_sample != a.last_sample + 1 || samples[b.first_sample as usize].gap_before {
            continue;
        }
        for _ in 0..MAX_TRIM {
            if a.samples <= 3 || b.samples <= 3 {
                break;
            }
            let (ka, kb) = (a.last_sample as usize, b.first_sample as usize);
            let (pa, pb) = (samples[ka].point(), samples[kb].point());
            let moved = if b.distance_to(pa) < a.distance_to(pa) {
                shrink(samples, error, a, ka, false) && grow(samples, error, b, ka, true)
            } else if a.distance_to(pb) < b.distance_to(pb) {
                shrink(samples, error, b, kb, true) && grow(samples, error, a, kb, false)
            } else {
                false
            };
            if !moved {
                break;
            }
        }
    }
}

/// Removes sample `k` (the line's first when `at_start`, else its last) and refits.
fn shrink(samples: &[Sample], error: &ErrorModel, line: &mut Line, k: usize, at_start: bool) -> bool {
    let mut m = line.moments;
    m.remove(samples[k].point());
    let (first, last) = if at_start { (k + 1, line.last_sample as usize) } else { (line.first_sample as usize, k - 1) };
    match Line::from_moments(samples, first, last, m, error) {
        Some(l) => {
            *line = l;
            true
        }
        None => false,
    }
}

/// Adds sample `k` before the line's first (`at_start`) or after its last, and refits.
fn grow(samples: &[Sample], error: &ErrorModel, line: &mut Line, k: usize, at_start: bool) -> bool {
    let mut m = line.moments;
    m.add(samples[k].point());
    let (first, last) = if at_start { (k, line.last_sample as usize) } else { (line.first_sample as usize, k) };
    match Line::from_moments(samples, first, last, m, error) {
        Some(l) => {
            *line = l;
            true
        }
        None => false,
    }
}

/// Drops end samples farther than half their error band from the line.
fn trim_ends(samples: &[Sample], error: &ErrorModel, line: &mut Line) {
    // trimming needs a line long enough to tell an outlying end from a curved wall
    if (line.samples as usize) < 2 * MAX_TRIM + 3 {
        return;
    }
    for at_start in [false, true] {
        for _ in 0..MAX_TRIM {
            let k = if at_start { line.first_sample } else { line.last_sample } as usize;
            let s = &samples[k];
            if line.distance_to(s.point()) <= 0.5 * error.at(s.d) || !shrink(samples, error, line, k, at_start) {
                break;
            }
        }
    }
}

/// Most samples trimmed from each end of a line.
pub const MAX_TRIM: usize = 3;

fn close(samples: &[Sample], first: usize, last: usize, moments: Moments, error: &ErrorModel, out: &mut Vec<Line>) {
    if last > first {
        if let Some(line) = Line::from_moments(samples, first, last, moments, error) {
            out.push(line);
        }
    }
}

#[cfg(test)]
pub(crate) mod tests_support {
    use laser::ScanGeometry;
    use nalgebra::Vector2;

    /// Ranges of a convex polygonal room seen from `origin`-relative vertices (brute force).
    pub(crate) fn room_ranges(g: &ScanGeometry, n: usize, verts: &[(f64, f64)]) -> Vec<f32> {
        (0..n)
            .map(|i| {
                let a = g.angle(i);
                let dir = Vector2::new(a.cos(), a.sin());
                let mut best = f64::INFINITY;
                for k in 0..verts.len() {
                    let p = Vector2::new(verts[k].0, verts[k].1);
                    let q = Vector2::new(verts[(k + 1) % verts.len()].0, verts[(k + 1) % verts.len()].1);
                    let e = q - p;
                    let den = dir.perp(&e);
                    if den.abs() < 1e-12 {
                        continue;
                    }
                    let t = p.perp(&e) / den;
                    let s = p.perp(&dir) / den;
                    if t > 0.0 && (0.0..=1.0).contains(&s) {
                        best = best.min(t);
                    }
                }
                best.min(g.range_max) as f32
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::tests_support::room_ranges;
    use super::*;
    use crate::sample::build_samples;
    use laser::{ScanGeometry, ScanView};

    #[test]
    fn a_square_room_gives_one_line_per_visible_wall() {
        let g = ScanGeometry::urg04lx();
        let ranges = room_ranges(&g, 682, &[(-1.0, -1.5), (3.0, -1.5), (3.0, 2.0), (-1.0, 2.0)]);
        let scan = ScanView { geometry: g, ranges: &ranges };
        let e = ErrorModel::default();
        let mut samples = Vec::new();
        build_samples(&scan, &e, 1, &mut samples);
        let mut lines = Vec::new();
        let clusters = infer_lines(&samples, g.angle_increment, &e, &mut lines);
        // 240 degrees from inside the room see 4 walls
        assert_eq!(clusters, 4, "{lines:#?}");
        assert_eq!(lines.len(), 4);
        let total: u32 = lines.iter().map(|l| l.samples).sum();
        assert!(total as usize >= samples.len() - 2 * MAX_TRIM * lines.len());
        for l in &lines {
            // samples of the next wall admitted past a corner are trimmed off again
            assert!(l.fit.rms() < 1e-3, "{}", l.fit.rms());
            assert!(l.normal.dot(&l.fit.centroid.coords) < 0.0);
        }
    }
}
