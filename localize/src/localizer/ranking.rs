//! Ranking (step 4 of the stage): hypotheses sorted by eq. 7, those that converged to one pose
//! merged, and the scan's status decided: `ok` when one pose explains the scan clearly best,
//! `ambiguous` when a distinct pose explains it about as well or the best sees through too
//! many walls to be trusted, `failed` when no pose explains it.

use super::{rival_gap, same_pose, Localizer, Probes, Status};
use crate::cost::Cost;
use crate::model::MapModel;
use crate::slide::FROM_SLIDE;
use laser::{angle_diff, pose_theta, Pose, ScanView};
use nalgebra::{Point2, Vector2};

impl Localizer {
    /// Whether a distinct hypothesis as good as the best (within [`LocalizerConfig::cornerless_tie`])
    /// has its heading and lies along the wall the best was slid on.
    pub(super) fn slides_along_a_wall(&self) -> bool {
        let cfg = &self.config;
        let hyps = &self.out.hypotheses;
        let Some(best) = hyps.first().filter(|h| h.scan_corner == FROM_SLIDE) else {
            return false;
        };
        let Some(wall) = self.model.runs.get(best.map_corner as usize) else {
            return false;
        };
        let along = (wall.b - wall.a).normalize();
        hyps[1..].iter().any(|h| {
            let d = h.pose.translation.vector - best.pose.translation.vector;
            (h.cost.value - best.cost.value) * f64::from(best.cost.beams) < cfg.cornerless_tie
                && !same_pose(&h.pose, &best.pose, cfg.distinct_position, cfg.distinct_heading)
                && angle_diff(pose_theta(&h.pose), pose_theta(&best.pose)).abs() <= cfg.distinct_heading
                && along.perp(&d).abs() <= 0.5 * cfg.distinct_position
        })
    }

    /// Whether the best hypothesis, found with the slide search's help, explains fewer of the
    /// scan's beams than a slid `ok` pose must ([`SlideConfig::min_inliers_ok`](crate::slide::SlideConfig)).
    pub(super) fn short_of_the_slides_bar(&self) -> bool {
        self.out.hypotheses.first().is_some_and(|h| h.cost.inliers < self.config.slide.min_inliers_ok)
    }

    /// Whether an `ok` answer is still too weak to stand: a rival within its misfit, or a
    /// position the scan pins down too little ([`Self::rival_within_misfit`],
    /// [`Self::pinned_down_too_little`]).
    pub(super) fn too_weak_for_ok(&self) -> bool {
        self.rival_within_misfit() || self.pinned_down_too_little()
    }

    /// Whether, after the slide search, the answer so far is `ok` and stays so through the
    /// checks [`Localizer::locate`] makes once the cascade ends.
    pub(super) fn ok_after_the_slide(&self) -> bool {
        self.out.status == Status::Ok && !self.short_of_the_slides_bar() && !self.too_weak_for_ok()
    }

    /// Whether the best hypothesis withstands [`LocalizerConfig::ok_probes`] (true with none).
    pub(super) fn best_withstands_probes(&mut self, scan: &ScanView<'_>) -> bool {
        let Some(pose) = self.out.hypotheses.first().map(|h| h.pose) else { return true };
        let probes = self.config.ok_probes;
        if probes.probes_nothing() {
            return true;
        }
        let (_, along) = self.weakest_direction(&pose);
        self.withstands_probes(scan, &pose, along, &probes)
    }

    /// Whether the scan tells `pose` from the poses at the edge of what `ok` promises
    /// ([`Probes`]): moved either way along `along` (the direction the scan pins down least,
    /// [`weakest_direction`](Self::weakest_direction)) and turned either way, each must cost
    /// at least the margin more than `pose`. Where eq. 7 is flat (an aisle's length, a
    /// heading among clutter) a pose that would be wrong explains the scan as well: an answer
    /// there is `ambiguous`. Every pose withstands probes that probe nothing (a `position` of
    /// 0). Reads the state of the scan last located: call it after.
    pub fn withstands_probes(
        &mut self,
        scan: &ScanView<'_>,
        pose: &Pose,
        along: Vector2<f64>,
        probes: &Probes,
    ) -> bool {
        if probes.probes_nothing() {
            return true;
        }
        let (t, heading) = (pose.translation.vector, pose_theta(pose));
        let moved = [
            Pose::new(t + along * probes.position, heading),
            Pose::new(t - along * probes.position, heading),
            Pose::new(t, heading + probes.heading),
            Pose::new(t, heading - probes.heading),
        ];
        let base = self.final_cost_below(scan, pose, f64::INFINITY, probes.beams).value;
        let bar = base + probes.margin;
        moved.iter().all(|p| self.final_cost_below(scan, p, bar, probes.beams).value >= bar)
    }

    /// Whether a distinct hypothesis costs less than [`LocalizerConfig::ambiguity_ratio`] of
    /// the best one's cost more than it: a rival within the best pose's own misfit.
    pub(super) fn rival_within_misfit(&self) -> bool {
        let cfg = &self.config;
        let Some(best) = self.out.hypotheses.first() else { return false };
        self.out.rival_gap(cfg.distinct_position, cfg.distinct_heading) < cfg.ambiguity_ratio * best.cost.value
    }

    /// Whether, on a map that declares itself approximate, the scan pins the best pose's
    /// position down along some direction by fewer points' worth than
    /// [`LocalizerConfig::min_constraint_ok_approximate`].
    pub(super) fn pinned_down_too_little(&self) -> bool {
        let min = self.config.min_constraint_ok_approximate;
        min > 0.0
            && self.model.map.is_approximate()
            && self.out.hypotheses.first().is_some_and(|h| self.weakest_direction(&h.pose).0 < min)
    }

    /// Whether the best hypothesis sees through more of a drawn map's walls than an `ok` pose
    /// may ([`LocalizerConfig::max_through_ok`]); never for a map that declares itself
    /// approximate, whose right poses see through walls that are no longer there.
    pub(super) fn sees_through_walls(&self) -> bool {
        self.out.hypotheses.first().is_some_and(|h| self.sees_through_drawn_walls(&h.cost))
    }

    /// Whether a pose of `cost` sees through more of a drawn map's walls than an `ok` pose may
    /// ([`max_through_ok`](crate::LocalizerConfig::max_through_ok)): a drawn map has no walls
    /// that are not there, so a right pose sees through none of them but for noise. Never on a
    /// map that declares itself approximate, whose right poses see through walls that are no
    /// longer there.
    pub fn sees_through_drawn_walls(&self, cost: &Cost) -> bool {
        !self.model.map.is_approximate() && cost.through > self.config.max_through_ok
    }

    /// Whether a pose of `cost` sees through more walls of a map that states no error (an
    /// exact plan, `sigma` 0) than [`escalate_through`](crate::LocalizerConfig::escalate_through)
    /// and [`escalate_min_beams`](crate::LocalizerConfig::escalate_min_beams) allow: what makes
    /// a single scan's search look wider, and a track's look near its prediction
    /// ([`crate::Sequential`]). On a map that states an error, right poses see through it.
    pub fn sees_through_exact_walls(&self, cost: &Cost) -> bool {
        let beams_through = (cost.through * cost.beams as f64).round() as usize;
        self.model.map.sigma <= 0.0
            && cost.through > self.config.escalate_through
            && beams_through >= self.config.escalate_min_beams
    }

    /// Sorts hypotheses, merges those that converged to the same pose, and sets the status.
    pub(super) fn rank(&mut self) {
        let cfg = self.config;
        let hyps = &mut self.out.hypotheses;
        hyps.sort_by(|a, b| a.cost.value.total_cmp(&b.cost.value));
        // keep the first (cheapest) of hypotheses that converged to the same pose, in place
        let mut kept = 0;
        for k in 0..hyps.len() {
            let h = hyps[k];
            if !hyps[..kept].iter().any(|q| same_pose(&q.pose, &h.pose, 0.05, 1f64.to_radians())) {
                hyps[kept] = h;
                kept += 1;
            }
        }
        hyps.truncate(kept);
        // poses outside the building are never the answer, but one that explains the scan as
        // well as the answer says the scan does not single the answer out: they stay in the
        // list, behind the answer, until the scan's last search is ranked
        let Some(at) = hyps.iter().position(|h| !is_outside(&self.model, cfg.inside_only, &h.pose)) else {
            self.out.status = Status::Failed;
            return;
        };
        hyps[..=at].rotate_right(1);
        let best = hyps[0];
        let (max_through, margin) = if self.model.map.is_approximate() {
            (cfg.max_through_approximate, cfg.ambiguity_margin_approximate)
        } else {
            (cfg.max_through, cfg.ambiguity_margin)
        };
        self.out.status = if best.cost.inliers < cfg.min_inliers || best.cost.through > max_through {
            Status::Failed
        } else if best.cost.through > cfg.max_through_ok
            || rival_gap(hyps, cfg.distinct_position, cfg.distinct_heading) < margin
        {
            Status::Ambiguous
        } else {
            Status::Ok
        };
    }

    /// Drops the hypotheses outside the building (see [`Self::rank`]) and all but the
    /// reported number of the others.
    pub(super) fn report(&mut self) {
        let (model, inside_only) = (&self.model, self.config.inside_only);
        self.out.hypotheses.retain(|h| !is_outside(model, inside_only, &h.pose));
        self.out.hypotheses.truncate(self.config.max_hypotheses);
    }
}

/// Whether `pose` lies where the robot cannot be ([`MapModel::off_limits`]), when answers are
/// kept to where it can.
pub(super) fn is_outside(model: &MapModel, inside_only: bool, pose: &Pose) -> bool {
    inside_only && model.off_limits(Point2::from(pose.translation.vector))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Cost, Hypothesis, LocalizerConfig};
    use laser::Pose;
    use std::sync::Arc;

    /// A slid pose further along the wall ties with the best only when the scan cannot tell
    /// them apart: their costs summed over the beams differ by less than `cornerless_tie`. A
    /// per-beam difference that is small but holds over hundreds of beams is not a tie.
    #[test]
    fn a_cornerless_tie_is_judged_on_the_whole_scan() {
        let map = map::WallMap::new(vec![map::Wall::new(0.0, 0.0, 20.0, 0.0)]);
        let model = Arc::new(MapModel::new(map, &map::MapCornerConfig::default()));
        let mut localizer = Localizer::new(model, LocalizerConfig::default());
        let slid = |x: f64, value: f64| Hypothesis {
            pose: Pose::new(nalgebra::Vector2::new(x, 1.5), 0.3),
            cost: Cost { value, inliers: 1.0, through: 0.0, beams: 680 },
            scan_corner: FROM_SLIDE,
            map_corner: 0,
        };
        // 0.02 per beam over 680 beams: 13.6 in all, above the default 10
        localizer.out.hypotheses = vec![slid(5.0, 0.5), slid(6.0, 0.52)];
        assert!(!localizer.slides_along_a_wall());
        // 0.01 per beam: 6.8 in all, a tie
        localizer.out.hypotheses = vec![slid(5.0, 0.5), slid(6.0, 0.51)];
        assert!(localizer.slides_along_a_wall());
        // the same cost off the wall's line is another place, not a tie along it
        localizer.out.hypotheses[1].pose = Pose::new(nalgebra::Vector2::new(6.0, 3.0), 0.3);
        assert!(!localizer.slides_along_a_wall());
    }

    /// A rival is judged against the best pose's own misfit: the same gap of 0.6 per beam tells
    /// a twin apart from a pose that fits well (cost 0.5), not from one that fits badly (2.0);
    /// the same pose again (within `distinct_position`) is no rival.
    #[test]
    fn a_rival_within_the_best_pose_s_misfit_is_no_clear_second() {
        let map = map::WallMap::new(vec![map::Wall::new(0.0, 0.0, 20.0, 0.0)]);
        let model = Arc::new(MapModel::new(map, &map::MapCornerConfig::default()));
        let mut localizer = Localizer::new(model, LocalizerConfig::default());
        let at = |x: f64, value: f64| Hypothesis {
            pose: Pose::new(nalgebra::Vector2::new(x, 1.5), 0.3),
            cost: Cost { value, inliers: 0.8, through: 0.0, beams: 680 },
            scan_corner: 0,
            map_corner: 0,
        };
        localizer.out.hypotheses = vec![at(5.0, 0.5), at(15.0, 1.1)];
        assert!(!localizer.rival_within_misfit());
        localizer.out.hypotheses = vec![at(5.0, 2.0), at(15.0, 2.6)];
        assert!(localizer.rival_within_misfit());
        localizer.out.hypotheses = vec![at(5.0, 2.0), at(5.01, 2.1)];
        assert!(!localizer.rival_within_misfit());
        let off = LocalizerConfig { ambiguity_ratio: 0.0, ..LocalizerConfig::default() };
        let mut localizer = Localizer::new(Arc::clone(&localizer.model), off);
        localizer.out.hypotheses = vec![at(5.0, 2.0), at(15.0, 2.6)];
        assert!(!localizer.rival_within_misfit());
    }

    /// A distinct rival between the two margins behind the best: far enough behind on a drawn
    /// map, whose walls are exact, for `ok`; not on a built one, whose walls are known only to
    /// their spread (`ambiguity_margin_approximate`).
    #[test]
    fn a_built_map_asks_a_wider_gap_of_a_rival() {
        let config = LocalizerConfig::default();
        assert!(config.ambiguity_margin < config.ambiguity_margin_approximate);
        let gap = (config.ambiguity_margin + config.ambiguity_margin_approximate) / 2.0;
        let walls = vec![map::Wall::new(0.0, 0.0, 20.0, 0.0)];
        let status_against = |map: map::WallMap| {
            let model = Arc::new(MapModel::new(map, &map::MapCornerConfig::default()));
            let mut localizer = Localizer::new(model, config);
            let at = |x: f64, value: f64| Hypothesis {
                pose: Pose::new(nalgebra::Vector2::new(x, 1.5), 0.3),
                cost: Cost { value, inliers: 0.9, through: 0.0, beams: 680 },
                scan_corner: 0,
                map_corner: 0,
            };
            localizer.out.hypotheses = vec![at(5.0, 0.4), at(15.0, 0.4 + gap)];
            localizer.rank();
            localizer.out.status
        };
        assert_eq!(status_against(map::WallMap::new(walls.clone())), Status::Ok);
        let built = map::WallMap { sigma: 0.1, ..map::WallMap::new(walls) };
        assert!(built.is_approximate());
        assert_eq!(status_against(built), Status::Ambiguous);
    }

    /// Beams through mapped walls: up to `max_through_ok` the best pose may be `ok`, up to
    /// `max_through` it is an untrusted answer (`ambiguous`), beyond that no answer.
    #[test]
    fn beams_through_walls_grade_the_status() {
        let map = map::WallMap::new(vec![map::Wall::new(0.0, 0.0, 20.0, 0.0)]);
        let model = Arc::new(MapModel::new(map, &map::MapCornerConfig::default()));
        let config = LocalizerConfig::default();
        let mut localizer = Localizer::new(model, config);
        let mut status_with = |through: f64| {
            localizer.out.hypotheses = vec![Hypothesis {
                pose: Pose::new(nalgebra::Vector2::new(5.0, 1.5), 0.3),
                cost: Cost { value: 0.5, inliers: 0.8, through, beams: 680 },
                scan_corner: 0,
                map_corner: 0,
            }];
            localizer.rank();
            localizer.out.status
        };
        assert_eq!(status_with(0.0), Status::Ok);
        assert_eq!(status_with(config.max_through_ok), Status::Ok);
        assert_eq!(status_with(config.max_through_ok + 0.01), Status::Ambiguous);
        assert_eq!(status_with(config.max_through), Status::Ambiguous);
        assert_eq!(status_with(config.max_through + 0.01), Status::Failed);
        // against a map that declares itself approximate, seeing through its walls never
        // fails a pose by default, and fails it beyond its own limit when one is set
        let approximate = map::WallMap { sigma: 0.1, ..map::WallMap::new(vec![map::Wall::new(0.0, 0.0, 20.0, 0.0)]) };
        let model = Arc::new(MapModel::new(approximate, &map::MapCornerConfig::default()));
        for (limit, status) in [(1.0, Status::Ambiguous), (0.4, Status::Failed)] {
            let mut localizer =
                Localizer::new(Arc::clone(&model), LocalizerConfig { max_through_approximate: limit, ..config });
            localizer.out.hypotheses = vec![Hypothesis {
                pose: Pose::new(nalgebra::Vector2::new(5.0, 1.5), 0.3),
                cost: Cost { value: 0.5, inliers: 0.6, through: 0.45, beams: 680 },
                scan_corner: 0,
                map_corner: 0,
            }];
            localizer.rank();
            assert_eq!(localizer.out.status, status, "limit {limit}");
        }
    }

    /// A pose outside a closed building is never the answer, and is never reported; one that
    /// explains the scan about as well as the answer makes the answer `ambiguous`. With
    /// `inside_only` off it is an answer like any other.
    #[test]
    fn poses_outside_a_closed_building_are_witnesses_never_answers() {
        let map = map::WallMap::new(map::Wall::rectangle(0.0, 0.0, 20.0, 10.0).to_vec());
        let model = Arc::new(MapModel::new(map, &map::MapCornerConfig::default()));
        let at = |x: f64, y: f64, value: f64| Hypothesis {
            pose: Pose::new(nalgebra::Vector2::new(x, y), 0.3),
            cost: Cost { value, inliers: 0.8, through: 0.0, beams: 680 },
            scan_corner: 0,
            map_corner: 0,
        };
        let run = |config: LocalizerConfig, hyps: Vec<Hypothesis>| {
            let mut localizer = Localizer::new(Arc::clone(&model), config);
            localizer.out.hypotheses = hyps;
            localizer.rank();
            let first = localizer.out.hypotheses[0].pose;
            localizer.report();
            (localizer.out.status, first, localizer.out.hypotheses.clone())
        };
        let inside = at(5.0, 5.0, 0.9);
        let far_inside = at(15.0, 5.0, 2.0);
        // an outside pose cheaper than the answer, and one 0.1 m beyond the outline
        for outside in [at(-3.0, 5.0, 0.5), at(10.0, 10.15, 0.5)] {
            let (status, first, reported) = run(LocalizerConfig::default(), vec![outside, inside, far_inside]);
            assert_eq!(first, inside.pose);
            assert_eq!(status, Status::Ambiguous);
            assert_eq!(reported, vec![inside, far_inside]);
            // far costlier than the answer: no doubt about it
            let (status, _, reported) = run(
                LocalizerConfig::default(),
                vec![inside, far_inside, Hypothesis { cost: Cost { value: 3.0, ..outside.cost }, ..outside }],
            );
            assert_eq!(status, Status::Ok);
            assert_eq!(reported, vec![inside, far_inside]);
            let off = LocalizerConfig { inside_only: false, ..LocalizerConfig::default() };
            // the outside pose answers, clear of the inside one by more than the margin
            let (status, first, reported) = run(off, vec![outside, inside, far_inside]);
            assert_eq!((status, first), (Status::Ok, outside.pose));
            assert_eq!(reported.len(), 3);
        }
        // only outside poses: no answer
        let mut localizer = Localizer::new(Arc::clone(&model), LocalizerConfig::default());
        localizer.out.hypotheses = vec![at(-3.0, 5.0, 0.5)];
        localizer.rank();
        localizer.report();
        assert_eq!(localizer.out.status, Status::Failed);
        assert!(localizer.out.hypotheses.is_empty());
    }

    /// A map built from scans says where its survey saw free space: a pose elsewhere is a
    /// witness, as one outside a closed building, never an answer.
    #[test]
    fn poses_where_the_survey_saw_no_free_space_are_never_answers() {
        let mut map = map::WallMap::new(vec![map::Wall::new(0.0, 0.0, 20.0, 0.0)]);
        let mut seen = map::SeenFree::covering(Point2::new(-1.0, -1.0), Point2::new(21.0, 6.0), 0.2).unwrap();
        // the survey looked along a corridor 2 m from the wall, up to x = 10
        seen.mark_ray(Point2::new(0.0, 2.0), Point2::new(10.0, 2.0));
        map.seen_free = Some(seen);
        let model = Arc::new(MapModel::new(map, &map::MapCornerConfig::default()));
        assert!(model.outside.is_none(), "one wall closes nothing off");
        let at = |x: f64, value: f64| Hypothesis {
            pose: Pose::new(nalgebra::Vector2::new(x, 2.0), 0.3),
            cost: Cost { value, inliers: 0.8, through: 0.0, beams: 680 },
            scan_corner: 0,
            map_corner: 0,
        };
        let mut localizer = Localizer::new(Arc::clone(&model), LocalizerConfig::default());
        localizer.out.hypotheses = vec![at(15.0, 0.5), at(5.0, 0.9)];
        localizer.rank();
        localizer.report();
        assert_eq!(localizer.out.status, Status::Ambiguous);
        assert_eq!(localizer.out.hypotheses, vec![at(5.0, 0.9)]);
        // a pose a cell beside what was seen is within the slack
        assert!(!model.off_limits(Point2::new(5.0, 2.25)));
        assert!(model.off_limits(Point2::new(5.0, 3.0)));
    }

    /// Which maps hold a pose to the walls it sees through: an exact plan (`sigma` 0) to the
    /// escalation rule (over 1 % and at least 7 beams) and to `max_through_ok`; a map that
    /// states an error under 5 cm (a ROS grid made into walls) to `max_through_ok` only; a
    /// map built from scans to neither.
    #[test]
    fn the_see_through_tests_follow_what_the_map_states_of_its_error() {
        let config = LocalizerConfig::default();
        let walls = vec![map::Wall::new(0.0, 0.0, 20.0, 0.0)];
        let tests = |sigma: f64, through: f64, beams: u32| {
            let map = map::WallMap { sigma, ..map::WallMap::new(walls.clone()) };
            let localizer = Localizer::new(Arc::new(MapModel::new(map, &map::MapCornerConfig::default())), config);
            let cost = Cost { value: 1.0, inliers: 0.8, through, beams };
            (localizer.sees_through_exact_walls(&cost), localizer.sees_through_drawn_walls(&cost))
        };
        let (some, many) = (0.02, config.max_through_ok + 0.01);
        assert_eq!(tests(0.0, some, 680), (true, false));
        assert_eq!(tests(0.0, many, 680), (true, true));
        assert_eq!(tests(0.0, config.escalate_through, 680), (false, false));
        // too few beams through to say so, though the share is over
        assert_eq!(tests(0.0, some, 100), (false, false));
        assert_eq!(tests(0.025, many, 680), (false, true));
        assert_eq!(tests(0.1, many, 680), (false, false));
    }
}
