//! Wall ends: where a line stops because the wall does (a door jamb, the end of a rack), not
//! because something in front of it hides the rest.
//!
//! The paper locates from corners only, so a scan with no corner in view (a corridor, an aisle
//! between racks) cannot be located at all. A visible wall end pins the pose just as well: its
//! position gives the translation and the wall's direction the rotation, which is eqs. 5-6 with
//! both arms on one wall. A wall end is therefore carried as a [`Corner`] whose inner angle is
//! 2 pi (free space sweeps all the way round the end of a wall) and whose two arms are the same
//! arm, into the visible wall. Map wall ends (crate `mapserver`) are built the same way, so
//! matching, the arm test and the cost function treat both alike.
//!
//! A line's end is a wall end when, within a few beams past it, the sensor sees beyond the end
//! (a range clearly farther, or no return at all) before it sees anything nearer: a nearer
//! reading is an occluder, a reading at about the same range is the next wall of a corner.
//!
//! The line must pass the limits of a corner's arm ([`CornerConfig::min_arm_length`] and
//! [`CornerConfig::max_direction_sigma`]), since it is both arms. An earlier, separate 0.6 m
//! minimum left out the faces of pillars and short rack ends; on the simulated logs (300 scans
//! each, seed 1) the corner's 0.25 m took the clean warehouse from 96.7 to 97.0 % success, its
//! people log from 94.3 to 94.7 % and its furnished one from 63.3 to 67.3 %, and lost no scan
//! on the other maps (the furnished office drawn with thick walls lost 1).

use crate::corner::{usable, Arm, Corner, CornerConfig};
use crate::line::Line;
use crate::sample::Sample;
use crate::visibility::hit;
use laser::{Reading, ScanView};
use serde::{Deserialize, Serialize};
use std::f64::consts::TAU;

/// Parameters of wall end detection.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct EndConfig {
    /// Look for wall ends at all.
    pub enabled: bool,
    /// How much farther than the line's end a reading past it must be to see beyond the end,
    /// metres (mixed pixels fall in between and are skipped).
    pub jump: f64,
    /// A "no return" past the end shows the wall ends only if the end lies this far inside the
    /// sensor's range, metres.
    pub range_margin: f64,
    /// Beams past the end that are examined.
    pub look: usize,
    /// A farther reading within this distance of the line's extension is the same wall seen at
    /// a grazing angle (ranges along it jump apart), not something beyond its end, metres.
    pub continuation: f64,
}

impl Default for EndConfig {
    fn default() -> Self {
        EndConfig { enabled: true, jump: 0.3, range_margin: 0.3, look: 3, continuation: 0.15 }
    }
}

/// What the beams past a line's end show.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Past {
    /// The sensor sees beyond the end: the wall ends here.
    Beyond,
    /// Something nearer hides the rest, or nothing decides: not a wall end.
    Hidden,
}

/// Adds the wall ends of `lines` to the corners in `out` and ranks them all together by eq. 4's
/// quality (a wall end's is its line's length, discounted as a corner's arms are): a long
/// wall's end is a better feature than the corner of a small box. Ranking ends after every
/// corner instead lost 1.3 points of furnished-scan success in the apartment and radial maps
/// and gained 1.3 in the warehouse. `beams_per_sample` is the sample averaging factor.
pub fn extract_wall_ends(
    scan: &ScanView<'_>,
    samples: &[Sample],
    lines: &[Line],
    beams_per_sample: usize,
    corner: &CornerConfig,
    cfg: &EndConfig,
    out: &mut Vec<Corner>,
) {
    if !cfg.enabled {
        return;
    }
    let first_new = out.len();
    for (index, line) in lines.iter().enumerate() {
        // a wall end is a corner whose two arms are this line: it takes a corner arm's limits
        if !usable(line, corner) {
            continue;
        }
        let (Some(first), Some(last)) =
            (samples.get(line.first_sample as usize), samples.get(line.last_sample as usize))
        else {
            continue;
        };
        let after = last.beam as usize + beams_per_sample.max(1);
        // the end side: beams after the last sample; the start side: beams before the first
        let sides = [
            (line.end, -line.direction, Some(after)),
            (line.start, line.direction, (first.beam as usize).checked_sub(1)),
        ];
        for (k, (point, into, beam)) in sides.into_iter().enumerate() {
            let Some(beam) = beam else { continue };
            if past(scan, line, point.coords.norm(), beam, k == 0, cfg) != Past::Beyond {
                continue;
            }
            let arm = Arm {
                direction: into,
                gap: 0.0,
                length: line.length(),
                samples: line.samples as f64,
                direction_sigma: line.direction_sigma,
                line: index as u16,
            };
            out.push(Corner {
                position: point,
                inner_angle: TAU,
                orientation: into.y.atan2(into.x),
                quality: line.length() / (1.0 + line.direction_sigma / corner.max_direction_sigma),
                arms: [arm, arm],
            });
        }
    }
    if out.len() > first_new {
        out.sort_by(|a, b| b.quality.total_cmp(&a.quality));
    }
}

/// Examines up to `cfg.look` beams from `beam` onwards (`forward`) or backwards, for an end
/// of `line` at `range` metres.
fn past(scan: &ScanView<'_>, line: &Line, range: f64, beam: usize, forward: bool, cfg: &EndConfig) -> Past {
    let n = scan.len();
    for step in 0..cfg.look {
        let i = if forward { beam + step } else { beam.wrapping_sub(step) };
        if i >= n {
            return Past::Hidden; // the scan's edge: nothing is known past it
        }
        match scan.reading(i) {
            Reading::Valid(d) if d > range + cfg.jump => {
                return if on_extension(scan, line, i, d, cfg) { Past::Hidden } else { Past::Beyond };
            }
            Reading::Valid(d) if d < range - cfg.jump => return Past::Hidden,
            // about the same range: a mixed pixel, or the next wall of a corner
            Reading::Valid(_) | Reading::Unknown => {}
            Reading::NoReturn => {
                if continues_past_lost_returns(scan, line, i, forward, cfg) {
                    return Past::Hidden;
                }
                // the wall may go on out of range: only if its extension would have been seen
                // well inside the range does a missing return show that it ends
                let a = scan.geometry.angle(i);
                let reach = scan.geometry.range_max - cfg.range_margin;
                let along =
                    hit(line.start, line.end, nalgebra::Vector2::new(a.cos(), a.sin())).unwrap_or(f64::INFINITY);
                return if range < reach && along < reach { Past::Beyond } else { Past::Hidden };
            }
        }
    }
    Past::Hidden
}

/// Whether the first reading after the missing returns from beam `i` on (at most
/// [`laser::MAX_LOST_RETURNS`] of them) lies on `line`'s extension: the wall went on and its
/// returns were lost, as a sensor that reports a lost return as "no return" (a SICK LMS) shows
/// them.
fn continues_past_lost_returns(scan: &ScanView<'_>, line: &Line, i: usize, forward: bool, cfg: &EndConfig) -> bool {
    (1..=laser::MAX_LOST_RETURNS)
        .map(|step| if forward { i.wrapping_add(step) } else { i.wrapping_sub(step) })
        .take_while(|&j| j < scan.len())
        .map(|j| (j, scan.reading(j)))
        .find(|(_, r)| *r != Reading::NoReturn)
        .is_some_and(|(j, r)| matches!(r, Reading::Valid(d) if on_extension(scan, line, j, d, cfg)))
}

/// Whether beam `i`'s reading `d` lies within [`EndConfig::continuation`] of `line`'s
/// extension: the same wall, not something beyond its end.
fn on_extension(scan: &ScanView<'_>, line: &Line, i: usize, d: f64, cfg: &EndConfig) -> bool {
    let a = scan.geometry.angle(i);
    line.distance_to(nalgebra::Point2::new(d * a.cos(), d * a.sin())) < cfg.continuation
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::segmenter::{LineVisibilitySegmenter, Segmenter, SegmenterConfig};
    use laser::ScanGeometry;

    /// Ranges of a 181-beam, 180-degree scan (beam i at i - 90 degrees, sensor frame x forward,
    /// y left) of a wall y = `y` for x in [x0, x1]; the beams that miss it read 10 m (no return).
    fn wall_scan(y: f64, x0: f64, x1: f64) -> (ScanGeometry, Vec<f32>) {
        let g = ScanGeometry::centred(181, 180f64.to_radians(), 5.6);
        let ranges = (0..181)
            .map(|i| {
                let (s, c) = g.angle(i).sin_cos();
                let x = y * c / s;
                if s > 1e-6 && x >= x0 && x <= x1 {
                    (y / s) as f32
                } else {
                    10.0
                }
            })
            .collect();
        (g, ranges)
    }

    fn ends(g: ScanGeometry, ranges: &[f32]) -> Vec<Corner> {
        lines_and_ends(SegmenterConfig::default(), g, ranges).1
    }

    /// The number of lines `config` finds in the scan, and their wall ends.
    fn lines_and_ends(config: SegmenterConfig, g: ScanGeometry, ranges: &[f32]) -> (usize, Vec<Corner>) {
        let mut seg = LineVisibilitySegmenter::new(config);
        let out = seg.segment(&ScanView { geometry: g, ranges });
        (out.lines.len(), out.corners.iter().filter(|c| c.inner_angle == TAU).copied().collect())
    }

    #[test]
    fn a_wall_with_nothing_behind_its_ends_has_two_wall_ends() {
        let (g, ranges) = wall_scan(2.0, 0.5, 2.5);
        let found = ends(g, &ranges);
        assert_eq!(found.len(), 2, "{found:?}");
        for (x, into) in [(0.5, 1.0), (2.5, -1.0)] {
            let e = found.iter().find(|c| (c.position.x - x).abs() < 0.06).expect("an end at each side");
            assert!((e.position.y - 2.0).abs() < 0.02, "{e:?}");
            assert!((e.arms[0].direction.x - into).abs() < 1e-3, "{e:?}");
            assert_eq!(e.arms[0], e.arms[1]);
        }
    }

    #[test]
    fn a_face_as_short_as_a_corners_arm_has_wall_ends() {
        // a 0.4 m pillar face with nothing behind it: long enough for a corner's arm
        let (g, ranges) = wall_scan(2.0, 1.0, 1.4);
        assert_eq!(ends(g, &ranges).len(), 2);
        // the arm limit is the corner's: raised above the face's length, the ends go too
        let mut config = SegmenterConfig::default();
        config.corner.min_arm_length = 0.5;
        let (lines, found) = lines_and_ends(config, g, &ranges);
        assert_eq!(lines, 1);
        assert!(found.is_empty(), "{found:?}");
    }

    #[test]
    fn an_end_hidden_by_something_nearer_is_not_a_wall_end() {
        let (g, mut ranges) = wall_scan(2.0, 0.5, 2.5);
        // a post at 1 m just past the wall's x = 0.5 end hides whether the wall goes on
        let last = (0..181).rev().find(|&i| ranges[i] < 5.6).unwrap();
        for r in ranges.iter_mut().skip(last + 1).take(6) {
            *r = 1.0;
        }
        let found = ends(g, &ranges);
        assert_eq!(found.len(), 1, "{found:?}");
        assert!((found[0].position.x - 2.5).abs() < 0.06, "{found:?}");
    }

    #[test]
    fn a_wall_running_out_of_range_has_no_wall_end() {
        // the wall y = 5.3 leaves the 5.6 m range on both sides: nothing says it ends
        let (g, ranges) = wall_scan(5.3, -10.0, 10.0);
        let ranges: Vec<f32> = ranges.iter().map(|&r| r.min(10.0)).collect();
        assert!(ranges.iter().filter(|&&r| r < 5.6).count() > 15);
        assert!(ends(g, &ranges).is_empty());
    }

    #[test]
    fn a_wall_seen_at_a_grazing_angle_does_not_end_where_its_ranges_jump() {
        // the wall y = 0.6 from x = 0.5 to 9: past about 4 m, neighbouring beams land more than
        // the jump apart along it, and inference may end the line there; the wall goes on
        let (g, ranges) = wall_scan(0.6, 0.5, 9.0);
        let found = ends(g, &ranges);
        assert!(found.iter().all(|c| c.position.x < 1.0), "{found:?}");
    }

    #[test]
    fn returns_lost_on_a_wall_that_goes_on_are_no_wall_end() {
        // a sensor that reports a lost return as its maximum range (a SICK LMS): one or two such
        // beams three beams short of the end of the wall y = 2, x in [0.5, 3] (beams 124-166)
        // leave too few samples past them for a line, so the long line ends at the lost returns
        for lost in [1, 2] {
            let (g, mut ranges) = wall_scan(2.0, 0.5, 3.0);
            ranges[127..127 + lost].fill(10.0);
            let found = ends(g, &ranges);
            // the wall goes on past them: only its end at x = 0.5 is seen
            assert_eq!(found.len(), 1, "{lost} lost: {found:?}");
            assert!((found[0].position.x - 0.5).abs() < 0.1, "{lost} lost: {found:?}");
        }
        // farther than the line's extension, the next reading shows the wall did end there
        let (g, mut ranges) = wall_scan(2.0, 0.5, 3.0);
        ranges[127] = 10.0;
        ranges[124..127].fill(4.0);
        assert_eq!(ends(g, &ranges).len(), 2);
    }

    #[test]
    fn the_scans_edge_is_not_a_wall_end() {
        // the wall y = 2 from x = -1 to 2.5 is cut by the field of view at x = 0 (beam +90)
        let (g, ranges) = wall_scan(2.0, -1.0, 2.5);
        let found = ends(g, &ranges);
        assert_eq!(found.len(), 1, "{found:?}");
        assert!((found[0].position.x - 2.5).abs() < 0.06, "{found:?}");
    }
}
