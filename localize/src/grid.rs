//! The search's last resort: poses on a grid over the map's free space, at the headings that
//! lay the scan's longest lines parallel to the map's main wall directions.
//!
//! Corners and slid lines need the scan to show a map corner or a stretch of wall long enough
//! to fit. In a furnished room the boxes in front of the walls can hide both, leaving the walls
//! in pieces of a few decimetres. The scan's lines, box faces included, still run parallel to
//! the walls, as furniture stands square to them, so they tell the heading up to the map's
//! symmetries; the position is then searched on a grid by the screen, and the best poses go
//! through the coarse cost, refinement and eq. 7 as every other search's do. It runs only for a
//! scan whose answer still sees through walls after every other search
//! ([`crate::LocalizerConfig::escalate_through`]).

use crate::slide::SlideLine;
use laser::{angle_diff, wrap_angle};
pub use map::model::wall_directions;
use nalgebra::Point2;
use std::f64::consts::PI;

/// [`crate::Hypothesis::scan_corner`] of a pose the grid search made (its `map_corner` is
/// `u32::MAX`: no run).
pub const FROM_GRID: u16 = u16::MAX - 1;

/// How the grid search lays out its poses and how many it carries on.
///
/// Measured over the 48 simulated logs of `gema2 evaluate`, after the wider slide (13818
/// successes without the grid): at these defaults 13843, for a largest p99 of a log of 50 ms.
/// With the longest line's heading for its votes (not their precision-weighted mean) and only
/// the four most voted headings, 13839; with those, a 0.1 m step, 10 000 kept by either pass,
/// 13841 at 163 ms; a 0.15 m step, 13836-13842; the first pass keeping 2000 against 10 000, one
/// or two scans fewer at a third less time.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GridConfig {
    /// Most headings tried ([`grid_headings`]); 0 turns the grid search off.
    pub headings: usize,
    /// Distance between grid positions, metres; coarsened when the grid would hold more than
    /// `max_poses` poses. Half the diagonal of a 0.2 m cell is 0.14 m, about what the screen and
    /// refinement pull in from.
    pub step: f64,
    pub max_poses: usize,
    /// Candidates kept by the screen's first pass, and by its full pass for the coarse cost.
    pub prescreened: usize,
    pub screened: usize,
}

impl Default for GridConfig {
    fn default() -> Self {
        GridConfig { headings: 8, step: 0.2, max_poses: 150_000, prescreened: 2000, screened: 1024 }
    }
}

/// Scan lines that vote for headings: the longest ones, at least this long (metres)...
const VOTING_LINES: usize = 6;
const VOTING_MIN_LENGTH: f64 = 0.3;
/// ...whose direction is known to this (radians: the loose slide's lines too).
const VOTING_MAX_SIGMA: f64 = 4.0 * PI / 180.0;
/// Votes for headings closer than this (radians) count as one heading.
const SAME_HEADING: f64 = 3.0 * PI / 180.0;
/// Headings voted less than this share of the most voted one are not tried.
const MIN_VOTE_SHARE: f64 = 0.5;
/// A line's direction is taken as no surer than this (radians) when it votes: the fit's own
/// figure for a long line in a clean scan is far smaller than the walls are straight.
const MIN_SIGMA: f64 = 0.25 * PI / 180.0;

/// Up to `count` sensor headings that lay the scan's longest lines along the map's wall
/// `directions`, the most voted first, and only those voted at least `MIN_VOTE_SHARE` of the
/// most voted. Each line votes for the four headings that turn it onto each direction either
/// way, with its length over its direction's uncertainty (a long, sure line counts most); votes
/// within `SAME_HEADING` are one heading, at their mean weighted by the lines' precision
/// (1 / sigma^2), so that one uncertain line does not set it. In a map whose walls run two ways,
/// lines that agree give the four quarter turns of one heading; lines that disagree (a line
/// along a grazing beam, fitted a few degrees off) give a second four, searched too when they
/// weigh as much.
pub fn grid_headings(lines: &[SlideLine], directions: &[f64], count: usize) -> Vec<f64> {
    let mut voting: Vec<&SlideLine> =
        lines.iter().filter(|l| l.length() >= VOTING_MIN_LENGTH && l.direction_sigma <= VOTING_MAX_SIGMA).collect();
    voting.sort_by(|a, b| b.length().total_cmp(&a.length()));
    voting.truncate(VOTING_LINES);
    // (first heading voted, precision-weighted sum of the votes' offsets from it, sum of the
    // precisions, votes)
    let mut votes: Vec<(f64, f64, f64, f64)> = Vec::new();
    for l in voting {
        let d = l.direction();
        let along = d.y.atan2(d.x);
        let sigma = l.direction_sigma.max(MIN_SIGMA);
        let (precision, vote) = (1.0 / (sigma * sigma), l.length() / sigma);
        for &wall in directions {
            for turn in [0.0, PI] {
                let heading = wrap_angle(wall + turn - along);
                match votes.iter_mut().find(|v| angle_diff(heading, v.0).abs() < SAME_HEADING) {
                    Some(v) => {
                        v.1 += precision * angle_diff(heading, v.0);
                        v.2 += precision;
                        v.3 += vote;
                    }
                    None => votes.push((heading, 0.0, precision, vote)),
                }
            }
        }
    }
    votes.sort_by(|a, b| b.3.total_cmp(&a.3));
    let top = votes.first().map_or(0.0, |v| v.3);
    votes
        .into_iter()
        .take_while(|v| v.3 >= MIN_VOTE_SHARE * top)
        .take(count)
        .map(|(first, offsets, precision, _)| wrap_angle(first + offsets / precision))
        .collect()
}

/// The grid's positions, the centres of cells `step` wide over `bounds`, where `may_stand`.
pub fn grid_positions(
    bounds: (Point2<f64>, Point2<f64>),
    step: f64,
    may_stand: &impl Fn(Point2<f64>) -> bool,
    out: &mut Vec<Point2<f64>>,
) {
    out.clear();
    out.extend(cells(bounds, step).filter(|&p| may_stand(p)));
}

/// Most cells of the bounds a grid visits, whatever the free space: a map kilometres wide
/// with little free space in it is not walked at the step of a room.
const MAX_CELLS: f64 = map::limits::SEARCH_GRID_CELLS as f64;

/// The grid's positions where the sensor `may_stand`, in `out`, and their step: `step`, or as
/// much wider as keeps them within `max_poses` poses at `headings` a position (the positions
/// at `step` are counted first, then spread as evenly over the same space), and the bounds
/// within `MAX_CELLS` cells.
pub fn grid_within(
    bounds: (Point2<f64>, Point2<f64>),
    step: f64,
    headings: usize,
    max_poses: usize,
    may_stand: impl Fn(Point2<f64>) -> bool,
    out: &mut Vec<Point2<f64>>,
) -> f64 {
    let (lo, hi) = bounds;
    let area = (hi.x - lo.x) * (hi.y - lo.y);
    let mut step = if area.is_finite() && area > 0.0 { step.max((area / MAX_CELLS).sqrt()) } else { step };
    grid_positions(bounds, step, &may_stand, out);
    let poses = out.len() * headings;
    if poses > max_poses {
        step *= (poses as f64 / max_poses.max(1) as f64).sqrt();
        grid_positions(bounds, step, &may_stand, out);
    }
    step
}

/// The centres of the cells `step` wide over `bounds`, row by row (none for a step that is
/// not positive or bounds that are not).
fn cells(bounds: (Point2<f64>, Point2<f64>), step: f64) -> impl Iterator<Item = Point2<f64>> {
    let (lo, hi) = bounds;
    let count = |extent: f64| if step > 0.0 && extent >= 0.0 { (extent / step).ceil() as usize } else { 0 };
    let (cols, rows) = (count(hi.x - lo.x), count(hi.y - lo.y));
    (0..rows).flat_map(move |r| {
        (0..cols).map(move |c| Point2::new(lo.x + (c as f64 + 0.5) * step, lo.y + (r as f64 + 0.5) * step))
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use map::Wall;
    use nalgebra::Vector2;
    use proptest::prelude::*;

    proptest! {
        /// A scan of a square room seen at any heading votes for that heading, up to the room's
        /// quarter turns, which are all among the four it gives.
        #[test]
        fn the_lines_of_a_square_room_vote_for_the_sensor_heading(heading in -3.1f64..3.1) {
            let walls = Wall::rectangle(0.0, 0.0, 8.0, 8.0);
            let dirs = wall_directions(&walls, 4);
            // the room's walls as the sensor at (3, 3) with `heading` sees them
            let to_sensor = nalgebra::Isometry2::new(Vector2::new(3.0, 3.0), heading).inverse();
            let lines: Vec<SlideLine> = walls
                .iter()
                .map(|w| SlideLine { start: to_sensor * w.a, end: to_sensor * w.b, direction_sigma: 0.001 })
                .collect();
            let headings = grid_headings(&lines, &dirs, 4);
            prop_assert_eq!(headings.len(), 4);
            for k in 0..4 {
                let turned = heading + k as f64 * PI / 2.0;
                prop_assert!(headings.iter().any(|&h| angle_diff(h, turned).abs() < 1e-6), "{:?}", headings);
            }
        }
    }

    /// Two lines 5 degrees apart in a map of walls along 0 and 90 degrees: each sets a heading
    /// and its quarter turns when it weighs at least half as much as the other, and only the
    /// heavier one's when it weighs less.
    #[test]
    fn lines_that_disagree_give_both_headings_when_they_weigh_alike() {
        let dirs = [0.0, PI / 2.0];
        let line = |length: f64, degrees: f64| {
            let a = degrees.to_radians();
            SlideLine {
                start: Point2::origin(),
                end: Point2::new(length * a.cos(), length * a.sin()),
                direction_sigma: 0.01,
            }
        };
        let both = grid_headings(&[line(2.0, 10.0), line(1.5, 15.0)], &dirs, 8);
        assert_eq!(both.len(), 8, "{both:?}");
        for turned in [-10.0f64, -15.0] {
            assert!(both.iter().any(|&h| angle_diff(h, turned.to_radians()).abs() < 1e-9), "{both:?}");
        }
        let one = grid_headings(&[line(2.0, 10.0), line(0.9, 15.0)], &dirs, 8);
        assert_eq!(one.len(), 4, "{one:?}");
        // lines within the same-heading tolerance make one heading between them, nearer the surer
        let sure = SlideLine { direction_sigma: 0.005, ..line(1.0, 11.0) };
        let merged = grid_headings(&[line(2.0, 10.0), sure], &dirs, 8);
        assert_eq!(merged.len(), 4, "{merged:?}");
        let h = merged.iter().copied().find(|h| angle_diff(*h, -0.18).abs() < 0.1).expect("a heading near -10.5");
        assert!(h < (-10.5f64).to_radians() && h > (-11.0f64).to_radians(), "{}", h.to_degrees());
    }

    #[test]
    fn lines_too_short_or_too_uncertain_do_not_vote() {
        let dirs = [0.0];
        let line = |length: f64, sigma: f64| SlideLine {
            start: Point2::origin(),
            end: Point2::new(length, 0.0),
            direction_sigma: sigma,
        };
        assert!(grid_headings(&[line(0.2, 0.001)], &dirs, 4).is_empty());
        assert!(grid_headings(&[line(2.0, 0.1)], &dirs, 4).is_empty());
        assert_eq!(grid_headings(&[line(2.0, 0.001)], &dirs, 4).len(), 2);
    }

    /// The grid widens its step to keep within its budget over the free space, and walks no
    /// more than its most cells of a map kilometres wide, however little of it is free.
    #[test]
    fn the_grid_keeps_its_poses_within_the_budget() {
        let room = (Point2::new(0.0, 0.0), Point2::new(40.0, 30.0));
        let mut out = Vec::new();
        assert_eq!(grid_within(room, 0.2, 8, 1_000_000, |_| true, &mut out), 0.2);
        assert_eq!(out.len(), 200 * 150);
        let step = grid_within(room, 0.2, 8, 100_000, |_| true, &mut out);
        // about: the widened grid's cells round up at the room's edges
        assert!(out.len() * 8 <= 102_000 && out.len() * 8 > 90_000, "{step}: {}", out.len());
        // half the room free: the step for the half
        let half = grid_within(room, 0.2, 8, 100_000, |p| p.x < 20.0, &mut out);
        assert!((half - step / 2f64.sqrt()).abs() < 0.01, "{half} {step}");
        // 10 km square with a 20 m room in a corner: the cap holds
        let huge = (Point2::new(0.0, 0.0), Point2::new(10_000.0, 10_000.0));
        let wide = grid_within(huge, 0.2, 8, 150_000, |p| p.x < 20.0 && p.y < 20.0, &mut out);
        assert!(wide >= 5.0 - 1e-9 && !out.is_empty(), "{wide}: {}", out.len());
        assert_eq!(grid_within(room, 0.2, 8, 100_000, |_| false, &mut out), 0.2);
        assert!(out.is_empty());
    }

    #[test]
    fn grid_positions_are_where_the_sensor_may_stand() {
        let mut out = Vec::new();
        let bounds = (Point2::new(0.0, 0.0), Point2::new(2.0, 1.0));
        grid_positions(bounds, 0.5, &|_| true, &mut out);
        assert_eq!(out.len(), 8);
        assert_eq!(out[0], Point2::new(0.25, 0.25));
        grid_positions(bounds, 0.5, &|p: Point2<f64>| p.x < 1.0, &mut out);
        assert_eq!(out.len(), 4);
        grid_positions(bounds, 0.0, &|_| true, &mut out);
        assert!(out.is_empty());
    }
}
