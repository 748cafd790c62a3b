//! Corner extraction (section 4.4, eq. 4).
//!
//! Every pair of lines is intersected; an intersection is kept when it lies close enough to
//! both lines' visible parts. A corner has a position, an inner angle beta measured through the
//! free space the sensor looks from, and an orientation theta: the direction of its *right*
//! arm, the one from which beta is swept counter-clockwise to the *left* arm. Map corners
//! (crate `mapserver`) use the same convention, so matching is arm to arm.
//!
//! Which side is free is read from the lines' visible faces: the region between two arms is
//! free only when each line's visible face looks into it. When an intersection falls inside a
//! line (a T-junction where one wall runs on), that line offers an arm on each side.

use crate::line::Line;
use nalgebra::{Point2, Vector2};
use serde::{Deserialize, Serialize};
use std::f64::consts::TAU;

/// One side of a corner: the visible part of a line, seen from the corner.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Arm {
    /// Unit vector from the corner along the line, towards its visible part.
    pub direction: Vector2<f64>,
    /// Distance from the corner to the first visible point of the arm (0 when the line
    /// reaches the corner).
    pub gap: f64,
    /// Visible length of the arm beyond the gap, metres.
    pub length: f64,
    /// Samples supporting the arm (|l| of eq. 5, pro rata when a line offers two arms).
    pub samples: f64,
    /// Standard deviation of the arm's direction, radians.
    pub direction_sigma: f64,
    /// Index of the line in the segmentation's line list.
    pub line: u16,
}

/// A corner c: intersection of two lines (section 4.4).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Corner {
    /// Intersection point, sensor frame.
    pub position: Point2<f64>,
    /// beta, in (0, 2 pi): the angle swept counter-clockwise from the right arm to the left
    /// arm through free space (< pi for a room's inside corner, > pi for a protruding one).
    pub inner_angle: f64,
    /// theta: direction of the right arm, radians, sensor frame.
    pub orientation: f64,
    /// |c| of eq. 4 under the chosen [`CornerRanking`].
    pub quality: f64,
    /// Right then left arm.
    pub arms: [Arm; 2],
}

impl Corner {
    /// Standard deviation of the inner angle, radians.
    pub fn inner_angle_sigma(&self) -> f64 {
        self.arms[0].direction_sigma.hypot(self.arms[1].direction_sigma)
    }
}

/// How eq. 4's quality |c| is measured.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum CornerRanking {
    /// The paper's: the smaller sample count of the two lines. Favours close walls, where
    /// samples are dense but directions are poor.
    Samples,
    /// The smaller visible arm length in metres, discounted by the arms' direction
    /// uncertainty: long, well-determined arms rank first.
    Length,
}

/// Parameters of corner extraction.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct CornerConfig {
    /// Lines closer to parallel than this make no corner (radians).
    pub min_angle: f64,
    /// How far the intersection may lie beyond a line's visible end, metres.
    pub reach: f64,
    /// The reach between two long lines (both at least `long_line` metres): the extensions of
    /// two long walls meeting is a corner even when furniture or a door hides the junction.
    pub long_reach: f64,
    pub long_line: f64,
    /// Shortest visible arm, metres.
    pub min_arm_length: f64,
    /// Largest direction uncertainty of an arm, radians (also the scale of the uncertainty
    /// penalty in the `Length` ranking). Short arms far away, such as a rack's end seen at
    /// 3-4 m, have 3-5 degrees; the inner angle tolerance of matching widens with the
    /// uncertainty, so they are usable: raising this from 2.5 to 6 degrees took the clean
    /// warehouse log from 84.7 to 89.7 % success and changed no other simulated log by more than
    /// a point.
    pub max_direction_sigma: f64,
    pub ranking: CornerRanking,
}

impl Default for CornerConfig {
    fn default() -> Self {
        CornerConfig {
            min_angle: 25f64.to_radians(),
            reach: 1.0,
            long_reach: 5.0,
            long_line: 0.6,
            min_arm_length: 0.25,
            max_direction_sigma: 6f64.to_radians(),
            ranking: CornerRanking::Length,
        }
    }
}

/// Extracts the corners of `lines` into `out` (cleared first), best quality first.
pub fn extract_corners(lines: &[Line], cfg: &CornerConfig, out: &mut Vec<Corner>) {
    out.clear();
    for i in 0..lines.len() {
        if !usable(&lines[i], cfg) {
            continue;
        }
        for j in i + 1..lines.len() {
            if usable(&lines[j], cfg) {
                corners_of_pair(lines, i, j, cfg, out);
            }
        }
    }
    out.sort_by(|a, b| b.quality.total_cmp(&a.quality));
}

/// Whether `l` passes a corner arm's limits: long enough, and its direction well enough known.
pub(crate) fn usable(l: &Line, cfg: &CornerConfig) -> bool {
    l.direction_sigma <= cfg.max_direction_sigma && l.length() >= cfg.min_arm_length
}

fn corners_of_pair(lines: &[Line], i: usize, j: usize, cfg: &CornerConfig, out: &mut Vec<Corner>) {
    let (a, b) = (&lines[i], &lines[j]);
    let sin = a.direction.perp(&b.direction).abs();
    if sin < cfg.min_angle.sin() {
        return;
    }
    let Some(x) = intersect(a, b) else { return };
    let reach = if a.length().min(b.length()) >= cfg.long_line { cfg.long_reach } else { cfg.reach };
    let mut arms_a = [None; 2];
    let mut arms_b = [None; 2];
    arms_of(a, i, x, reach, cfg, &mut arms_a);
    arms_of(b, j, x, reach, cfg, &mut arms_b);
    for arm_a in arms_a.iter().flatten() {
        for arm_b in arms_b.iter().flatten() {
            if let Some(c) = corner_of_arms(a, b, arm_a, arm_b, x, cfg) {
                out.push(c);
            }
        }
    }
}

/// Intersection of the two fitted lines.
fn intersect(a: &Line, b: &Line) -> Option<Point2<f64>> {
    let den = a.direction.perp(&b.direction);
    if den.abs() < 1e-12 {
        return None;
    }
    let t = (b.fit.centroid - a.fit.centroid).perp(&b.direction) / den;
    let x = a.fit.centroid + a.direction * t;
    x.coords.iter().all(|v| v.is_finite()).then_some(x)
}

/// The arms line `l` offers a corner at `x`: towards its visible part on either side.
fn arms_of(l: &Line, index: usize, x: Point2<f64>, reach: f64, cfg: &CornerConfig, out: &mut [Option<Arm>; 2]) {
    let len = l.length();
    let t = (x - l.start).dot(&l.direction);
    let sides = [
        // forward: visible part [max(t, 0), len]
        (l.direction, (-t).max(0.0), len - t.max(0.0)),
        // backward: visible part [0, min(t, len)]
        (-l.direction, (t - len).max(0.0), t.min(len)),
    ];
    for (k, (direction, gap, length)) in sides.into_iter().enumerate() {
        if gap <= reach && length >= cfg.min_arm_length {
            out[k] = Some(Arm {
                direction,
                gap,
                length,
                samples: l.samples as f64 * (length / len.max(1e-9)).min(1.0),
                direction_sigma: l.direction_sigma,
                line: index as u16,
            });
        }
    }
}

/// The corner between two arms, if the region between them is free on both lines' visible
/// faces; `None` otherwise.
fn corner_of_arms(la: &Line, lb: &Line, a: &Arm, b: &Arm, x: Point2<f64>, cfg: &CornerConfig) -> Option<Corner> {
    let a_faces = la.normal.dot(&b.direction);
    let b_faces = lb.normal.dot(&a.direction);
    let small_free = a_faces > 0.0 && b_faces > 0.0;
    let reflex_free = a_faces < 0.0 && b_faces < 0.0;
    if !small_free && !reflex_free {
        return None;
    }
    let angle = a.direction.dot(&b.direction).clamp(-1.0, 1.0).acos();
    let b_ccw_of_a = a.direction.perp(&b.direction) > 0.0;
    // sweeping counter-clockwise from right to left through the free region
    let (right, left, beta) = match (small_free, b_ccw_of_a) {
        (true, true) => (a, b, angle),
        (true, false) => (b, a, angle),
        (false, true) => (b, a, TAU - angle),
        (false, false) => (a, b, TAU - angle),
    };
    let quality = match cfg.ranking {
        CornerRanking::Samples => right.samples.min(left.samples),
        CornerRanking::Length => {
            let sigma = right.direction_sigma.max(left.direction_sigma);
            right.length.min(left.length) / (1.0 + sigma / cfg.max_direction_sigma)
        }
    };
    Some(Corner {
        position: x,
        inner_angle: beta,
        orientation: right.direction.y.atan2(right.direction.x),
        quality,
        arms: [*right, *left],
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fit::Moments;
    use crate::sample::{ErrorModel, Sample};
    use nalgebra::Vector2;
    use std::f64::consts::{FRAC_PI_2, PI};

    fn samples_on(a: Point2<f64>, b: Point2<f64>, n: usize) -> Vec<Sample> {
        (0..n)
            .map(|k| {
                let p = a + (b - a) * (k as f64 / (n - 1) as f64);
                let d = p.coords.norm();
                Sample { beam: 0, dir: p.coords / d, d, near: d - 0.02, far: d + 0.02, gap_before: k == 0 }
            })
            .collect()
    }

    fn lines_of(segments: &[(Point2<f64>, Point2<f64>)]) -> Vec<Line> {
        let mut all = Vec::new();
        let mut lines = Vec::new();
        for (a, b) in segments {
            let first = all.len();
            all.extend(samples_on(*a, *b, 30));
            let mut m = Moments::default();
            for s in &all[first..] {
                m.add(s.point());
            }
            lines.push(Line::from_moments(&all, first, all.len() - 1, m, &ErrorModel::PAPER).unwrap());
        }
        lines
    }

    #[test]
    fn inside_corner_of_a_room() {
        // walls x = 2 (y from -2 to 1) and y = 1 (x from 2 to -1), sensor at origin
        let lines = lines_of(&[
            (Point2::new(2.0, -2.0), Point2::new(2.0, 1.0)),
            (Point2::new(2.0, 1.0), Point2::new(-1.0, 1.0)),
        ]);
        let mut out = Vec::new();
        extract_corners(&lines, &CornerConfig::default(), &mut out);
        assert_eq!(out.len(), 1);
        let c = out[0];
        assert!((c.position - Point2::new(2.0, 1.0)).norm() < 1e-9);
        assert!((c.inner_angle - FRAC_PI_2).abs() < 1e-9);
        // sweeping counter-clockwise through the room: from the y = 1 wall (towards -x) to
        // the x = 2 wall (towards -y)
        assert!((c.orientation.abs() - PI).abs() < 1e-9, "{}", c.orientation);
        assert!((c.arms[1].direction - Vector2::new(0.0, -1.0)).norm() < 1e-9);
    }

    #[test]
    fn protruding_corner_is_reflex() {
        // a block filling x >= 2, y >= 0.5, seen from the origin: its faces x = 2 (towards +y)
        // and y = 0.5 (towards +x) meet at (2, 0.5); free space wraps 270 degrees around it
        let lines =
            lines_of(&[(Point2::new(4.0, 0.5), Point2::new(2.0, 0.5)), (Point2::new(2.0, 0.5), Point2::new(2.0, 3.0))]);
        let mut out = Vec::new();
        extract_corners(&lines, &CornerConfig::default(), &mut out);
        assert_eq!(out.len(), 1);
        assert!((out[0].inner_angle - 1.5 * PI).abs() < 1e-9, "{}", out[0].inner_angle);
        // counter-clockwise through free space: from the x = 2 face (up) round to y = 0.5 (+x)
        assert!((out[0].arms[0].direction - Vector2::new(0.0, 1.0)).norm() < 1e-9);
        assert!((out[0].arms[1].direction - Vector2::new(1.0, 0.0)).norm() < 1e-9);
    }

    #[test]
    fn t_junction_gives_the_corner_on_the_visible_side_only() {
        // wall y = 2 from x = -2..2 runs on; wall x = 0.5 from y = 2 down to y = 1 meets it
        let lines = lines_of(&[
            (Point2::new(2.0, 2.0), Point2::new(0.6, 2.0)),
            (Point2::new(0.5, 1.0), Point2::new(0.5, 1.95)),
        ]);
        let mut out = Vec::new();
        extract_corners(&lines, &CornerConfig::default(), &mut out);
        // the sensor (origin, x < 0.5) sees the x = 0.5 wall's left face: the corner to the
        // left of it, between y = 2 (towards -x) and... the y = 2 line only runs to +x here,
        // so the only free region is the reflex one on the sensor's side
        assert!(out.iter().all(|c| c.inner_angle > 0.0 && c.inner_angle < TAU));
        // a far intersection yields nothing
        let far = lines_of(&[
            (Point2::new(2.0, 2.0), Point2::new(1.8, 2.0)),
            (Point2::new(-2.0, 0.0), Point2::new(-2.0, -1.0)),
        ]);
        extract_corners(&far, &CornerConfig::default(), &mut out);
        assert!(out.is_empty());
    }

    #[test]
    fn parallel_lines_make_no_corner() {
        let lines = lines_of(&[
            (Point2::new(2.0, -1.0), Point2::new(2.0, 1.0)),
            (Point2::new(3.0, 1.2), Point2::new(3.0, 2.0)),
        ]);
        let mut out = Vec::new();
        extract_corners(&lines, &CornerConfig::default(), &mut out);
        assert!(out.is_empty());
    }
}
