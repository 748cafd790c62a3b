//! Candidate poses (step 1 of the stage): scan corners matched with the map's corners of a
//! similar inner angle (eqs. 5-6), or the scan's longest lines laid along the map's walls
//! ([`crate::slide`]). Each pose is screened as it is made ([`FirstPass`]), so that only the
//! best few thousand are ever kept.

use super::ranking::is_outside;
use super::screen::{order_by_telling, within, FirstPass, Screen, ScreenPoint};
use super::{Candidate, Localizer, LocalizerConfig, Source};
use crate::grid::{grid_headings, grid_within, FROM_GRID};
use crate::matching::{arms_fit, pose_from_corners};
use crate::model::MapModel;
use crate::slide::{chord_poses, slide_lines, slide_poses, slide_step, SlideLine, FROM_SLIDE};
use laser::Pose;
use map::runs::RunChain;
use map::Wall;
use nalgebra::Point2;
use segment::Segmentation;
use std::f64::consts::TAU;
use std::sync::Arc;

impl Localizer {
    /// The candidate poses of `source`, each screened by the distance field; the `keep` best
    /// are kept.
    pub(super) fn make_candidates(&mut self, seg: &Segmentation, source: Source, keep: usize) {
        self.candidates.clear();
        // the buffer holds at most `held(keep)` candidates (see `Offers::offer`); one a wide
        // search grew is given back, so a localizer does not keep the largest it ever needed
        let held = held(keep);
        if self.candidates.capacity() > 2 * held {
            self.candidates.shrink_to(held);
        }
        self.candidates.reserve_exact(held);
        let cfg = self.config;
        let model = Arc::clone(&self.model);
        // screening in two passes: one in `prescreen_step` points (`screen_few`) for all
        // poses, then every point for the `keep` best
        let screen = Screen::new(&model, &cfg);
        let below = match source {
            Source::Twins { below, .. } => below,
            _ => f64::INFINITY,
        };
        let mut offers = Offers {
            pass: FirstPass::new(screen, self.screen_few.len(), keep, &mut self.best_sums).capped(below),
            few: &self.screen_few,
            order: &mut self.screen_order,
            candidates: &mut self.candidates,
            keep,
            held,
        };
        // tracking: the robot is within r of its last pose
        let prior = self.prior.zip(cfg.track_radius);
        match source {
            Source::Corners(corners) | Source::Twins { corners, .. } => {
                corner_candidates(&mut offers, seg, &model, &cfg, prior, corners)
            }
            Source::Slides => {
                slide_lines(&self.lines, &cfg.slide, &mut self.slide_lines);
                let step = slide_candidates(&mut offers, &self.lines, &self.slide_lines, &model, &cfg, prior);
                self.out.slide_step = Some(step);
            }
            Source::Grid => grid_candidates(&mut offers, &self.lines, &model, &cfg, prior, &mut self.grid),
            Source::LooseSlides => {
                // the lines `locate_lines_given` chose: it runs this search only when there are some
                slide_candidates(&mut offers, &self.lines, &self.slide_lines, &model, &cfg, prior);
            }
        }
        if self.candidates.len() > keep {
            self.candidates.select_nth_unstable_by(keep, |a, b| a.score.total_cmp(&b.score));
            self.candidates.truncate(keep);
        }
        let n = self.screen_pts.len().max(1) as f64;
        for c in self.candidates.iter_mut() {
            c.score = screen.sum(&c.pose, &self.screen_pts, f64::INFINITY).unwrap_or(f64::INFINITY) / n;
        }
    }
}

/// Where the poses of one search go: each is scored by the screen's first pass, reading its
/// points in the order that best tells apart the poses of the current match, and kept when
/// it may be among the best.
struct Offers<'a> {
    pass: FirstPass<'a>,
    /// The first pass's points, as subsampled.
    few: &'a [ScreenPoint],
    /// `few` in the order the current match's poses read them.
    order: &'a mut Vec<ScreenPoint>,
    candidates: &'a mut Vec<Candidate>,
    /// How many the search keeps.
    keep: usize,
    /// How many `candidates` holds before it is cut back to the `keep` best.
    held: usize,
}

/// Adds `c` to `candidates`, first cutting them back to the `keep` best when they are `held`
/// (more than `keep`). A candidate with `keep` better than it is not among the `keep` best, so
/// the best `keep` of all offered are the same as when every candidate is held (but which of
/// equal ones).
fn hold(candidates: &mut Vec<Candidate>, c: Candidate, keep: usize, held: usize) {
    if candidates.len() >= held {
        candidates.select_nth_unstable_by(keep, |a, b| a.score.total_cmp(&b.score));
        candidates.truncate(keep);
    }
    candidates.push(c);
}

/// The most candidates a search that keeps `keep` holds at once: the first pass lets through
/// every pose that is among the best so far, about `keep` (1 + ln(poses / keep)) of them, and a
/// few thousand poses of 48 bytes each are most of a localizer's own memory.
fn held(keep: usize) -> usize {
    keep + (keep / 2).max(16)
}

impl Offers<'_> {
    /// Orders the points for the poses offered next: by `telling`, largest first (points
    /// every pose of the match puts on a wall tell nothing and go last).
    fn order_by(&mut self, telling: impl Fn(Point2<f64>) -> f64) {
        order_by_telling(self.few, self.order, telling);
    }

    fn offer(&mut self, pose: Pose, scan_corner: u16, map_corner: u32) {
        if let Some(score) = self.pass.score(&pose, self.order) {
            hold(self.candidates, Candidate { pose, score, scan_corner, map_corner, order: 0 }, self.keep, self.held);
        }
    }
}

/// Offers the poses of the `corners` best scan corners the map has corners like, each matched
/// with every map corner of a similar inner angle whose arms it fits. With `track` (the last
/// pose and the tracking radius), only poses within the radius of it.
fn corner_candidates(
    offers: &mut Offers<'_>,
    seg: &Segmentation,
    model: &MapModel,
    cfg: &LocalizerConfig,
    track: Option<(Point2<f64>, f64)>,
    corners: usize,
) {
    // a corner of a kind the map has none of (a wall end, where the map lists no wall ends)
    // makes no candidate: the next best takes its place
    let matchable = seg.corners.iter().enumerate().filter_map(|(ci, c)| {
        let range = model.corners.similar_range(c.inner_angle, cfg.angle_tolerance(c));
        (!range.is_empty()).then_some((ci, c, range))
    });
    for (ci, c, range) in matchable.take(corners) {
        // points on the corner's arms fit every match of it: they go last
        offers.order_by(|q| {
            c.arms.iter().map(|a| a.direction.perp(&(q - c.position)).abs()).fold(f64::INFINITY, f64::min)
        });
        for k in range {
            let m = &model.corners.corners()[k];
            // a map corner the robot sees lies within r plus the scan corner's own range of
            // the last pose
            if track.is_some_and(|(p, r)| (m.position - p).norm() > r + c.position.coords.norm()) {
                continue;
            }
            if !arms_fit(c, m, cfg.arm_slack) {
                continue;
            }
            let pose = pose_from_corners(c, m);
            if track.is_some_and(|(p, r)| !within(&pose, p, r)) {
                continue;
            }
            // on a map built from scans a wall end is matched only from where its survey saw
            // free space: a pose off limits is never the answer, and its thousands of ends
            // matched from everywhere cost 10-15 % of a scan's time
            if m.inner_angle >= TAU && model.map.is_approximate() && is_outside(model, cfg.inside_only, &pose) {
                continue;
            }
            offers.offer(pose, ci as u16, k as u32);
        }
    }
}

/// Offers the poses that lay each of the `chosen` scan lines along the map's walls, and as
/// chords of its bent walls; returns the step along the walls. With `prior` (the last pose and
/// the tracking radius), only poses within the radius of it, so only the walls within the
/// radius plus the lines' reach of it, as with map corners; the step is then sized for those
/// walls alone.
fn slide_candidates(
    offers: &mut Offers<'_>,
    lines: &[SlideLine],
    chosen: &[usize],
    model: &MapModel,
    cfg: &LocalizerConfig,
    prior: Option<(Point2<f64>, f64)>,
) -> f64 {
    let reach =
        chosen.iter().map(|&li| lines[li].start.coords.norm().max(lines[li].end.coords.norm())).fold(0.0, f64::max);
    let near = |w: &&Wall| prior.is_none_or(|(p, r)| w.closest(p).0 <= r + reach);
    let bent_near = |c: &&RunChain| prior.is_none_or(|(p, r)| c.runs().any(|w| w.closest(p).0 <= r + reach));
    let bends = model.bends.iter().filter(bent_near);
    let step =
        slide_step(lines, chosen, model.runs.iter().filter(near), bends.clone().map(RunChain::length), &cfg.slide);
    for &li in chosen {
        let line = &lines[li];
        // points on the slid line fit every pose along the wall: they go last
        offers.order_by(|q| line.direction().perp(&(q - line.start)).abs());
        let mut offer = |pose: Pose, map_corner| {
            if prior.is_none_or(|(p, r)| within(&pose, p, r)) {
                offers.offer(pose, FROM_SLIDE, map_corner);
            }
        };
        for (wi, wall) in model.runs.iter().enumerate().filter(|(_, w)| near(w)) {
            slide_poses(line, wall, step, &cfg.slide, |pose| offer(pose, wi as u32));
        }
        // a chord's pose names no run
        for chain in bends.clone() {
            chord_poses(line, chain, step, |pose| offer(pose, u32::MAX));
        }
    }
    step
}

/// Offers poses on a grid over the map's free space, at the headings that lay the scan's
/// longest lines along the map's main wall directions ([`crate::grid`]): positions in the main
/// free space, at least 0.1 m from every wall, `cfg.grid.step` apart, or further apart when the
/// map is too large for `cfg.grid.max_poses` poses. With `prior` (the last pose and the tracking
/// radius), only positions within the radius of it. `positions` is scratch space.
fn grid_candidates(
    offers: &mut Offers<'_>,
    lines: &[SlideLine],
    model: &MapModel,
    cfg: &LocalizerConfig,
    prior: Option<(Point2<f64>, f64)>,
    positions: &mut Vec<Point2<f64>>,
) {
    let headings = grid_headings(lines, &model.wall_directions, cfg.grid.headings);
    if headings.is_empty() {
        return;
    }
    let may_stand = |p: Point2<f64>| {
        prior.is_none_or(|(q, r)| (p - q).norm() <= r)
            && !model.open_floor.at(p).1
            && !model.off_limits(p)
            && model.field.distance(p) >= 0.1
    };
    grid_within(model.map.bounds(), cfg.grid.step, headings.len(), cfg.grid.max_poses, may_stand, positions);
    // every point tells poses this far apart: the first pass reads them as they come
    offers.order_by(|_| 0.0);
    for heading in headings {
        for p in positions.iter() {
            offers.offer(Pose::new(p.coords, heading), FROM_GRID, u32::MAX);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn candidate(score: f64) -> Candidate {
        Candidate { pose: Pose::identity(), score, scan_corner: 0, map_corner: 0, order: 0 }
    }

    proptest! {
        /// Held a few at a time, the candidates' best `keep` are those of all of them, and the
        /// buffer never passes its bound.
        #[test]
        fn the_best_are_kept_however_few_are_held(
            scores in prop::collection::vec(0.0f64..100.0, 0..3000),
            keep in 0usize..300,
        ) {
            let held = held(keep);
            let mut bounded = Vec::new();
            for &s in &scores {
                hold(&mut bounded, candidate(s), keep, held);
                prop_assert!(bounded.len() <= held);
            }
            let best = |mut v: Vec<f64>| {
                v.sort_by(f64::total_cmp);
                v.truncate(keep);
                v
            };
            prop_assert_eq!(best(bounded.iter().map(|c| c.score).collect()), best(scores));
        }
    }
}
