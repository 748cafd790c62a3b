//! Screening (step 2 of the stage): scan points placed at a candidate pose cost their squared
//! distance to the nearest wall, read from the distance field, so that thousands of candidates
//! can be ranked before eq. 7 casts a single ray. Also the helpers that choose and order those
//! points, and that keep the best distinct candidates.

use super::Candidate;
use super::LocalizerConfig;
use crate::cost::CostConfig;
use crate::lowest::Lowest;
use crate::model::{MapModel, WallFrame, FIELD_CAP};
use crate::slide::SlideLine;
use laser::{angle_diff, pose_theta, Pose};
use map::{DistanceField, FieldCell, OpenFloor};
use nalgebra::Point2;
use segment::Segmentation;

/// The screen's first pass over one in `prescreen_step` points. It keeps the `keep` best sums:
/// a pose is dropped as soon as its partial sum reaches the `keep`-th best so far (sums only
/// grow), which leaves the kept set as it was and stops most wrong poses after a few points; a
/// pose that puts every point far from the walls is never worth more work.
pub(super) struct FirstPass<'a> {
    screen: Screen<'a>,
    /// How many points each pose is screened over.
    points: usize,
    keep: usize,
    limit: f64,
    /// The best sums so far.
    best: &'a mut Lowest,
}

impl<'a> FirstPass<'a> {
    pub(super) fn new(screen: Screen<'a>, points: usize, keep: usize, best: &'a mut Lowest) -> Self {
        best.clear();
        let limit = screen.cap * screen.cap * 0.95 * points.max(1) as f64;
        FirstPass { screen, points, keep, limit, best }
    }

    /// The pass letting through no pose whose sum over its points exceeds `limit`.
    pub(super) fn capped(mut self, limit: f64) -> Self {
        self.limit = self.limit.min(limit);
        self
    }

    /// The pose's mean screen cost over `points` (the pass's points, in any order), or `None`
    /// when it cannot be among the `keep` best. The kept set does not depend on the order;
    /// the time does: the sooner a wrong pose's large misses come, the sooner it is dropped.
    pub(super) fn score(&mut self, pose: &Pose, points: &[ScreenPoint]) -> Option<f64> {
        debug_assert_eq!(points.len(), self.points);
        let sum = self.screen.sum(pose, points, self.limit)?;
        self.best.offer(sum, self.keep);
        self.limit = self.limit.min(self.best.kth(self.keep));
        Some(sum / self.points.max(1) as f64)
    }
}

/// A scan point the screen places at candidate poses, and whether it lies on a long scan line.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct ScreenPoint {
    /// Sensor frame.
    pub at: Point2<f64>,
    pub on_long_line: bool,
}

/// Whether `pose` places the sensor within `r` of `p`.
pub(super) fn within(pose: &Pose, p: Point2<f64>, r: f64) -> bool {
    (Point2::from(pose.translation.vector) - p).norm() <= r
}

/// Eq. 7's cheap stand-in for screening: scan points placed at a pose cost their squared
/// distance to the nearest wall, capped at `cap`.
#[derive(Clone, Copy)]
pub(super) struct Screen<'a> {
    field: &'a DistanceField,
    /// With [`MapModel::closed_sides`]: each wall's frame and closed sides.
    sides: Option<(&'a [WallFrame], &'a [[bool; 2]])>,
    cap: f64,
    /// The squared cap's factors for a point seen through a wall and one on a long line in
    /// open floor ([`LocalizerConfig::screen_behind`], [`LocalizerConfig::screen_open`]).
    behind: f64,
    open: f64,
    floor: &'a OpenFloor,
    cost: CostConfig,
    /// Whether [`sum`](Self::sum) with a limit first sums the field's lower bounds.
    bounds: bool,
}

impl<'a> Screen<'a> {
    pub(super) fn new(model: &'a MapModel, cfg: &LocalizerConfig) -> Self {
        let sides = model.closed_sides.as_deref().map(|closed| (&model.frames[..], closed));
        Screen {
            field: &model.field,
            sides,
            cap: cfg.screen_cap.min(FIELD_CAP),
            behind: cfg.screen_behind.max(1.0),
            open: cfg.screen_open.max(1.0),
            floor: &model.open_floor,
            cost: cfg.cost,
            bounds: true,
        }
    }

    /// The screen without the field's lower bounds, for poses about a prediction: there nearly
    /// every point lies within a pooled block of a wall, whose bound is 0, and the bounds
    /// dropped a quarter of a tracked window's starts for a look-up of every point of nearly
    /// all of them (acapulco's 625 starts a scan). The sums are the same.
    pub(super) fn without_bounds(self) -> Self {
        Screen { bounds: false, ..self }
    }

    /// The sum over `points` (sensor frame) placed at `pose`; `None` as soon as the partial sum
    /// reaches `limit`.
    ///
    /// A point whose nearest wall turns its closed side to the sensor is unexplained (the cap):
    /// its beam would have crossed a wall's body to reach that face. A pose a wall's thickness
    /// off the truth puts its points there, on the far face of the walls it sees, where the
    /// distance alone finds them as near a wall as the truth's.
    #[inline]
    pub(super) fn sum(&self, pose: &Pose, points: &[ScreenPoint], limit: f64) -> Option<f64> {
        // with a limit, first the field's lower bounds, from a table that stays in cache: most
        // wrong poses pass the limit on them alone, without reading the field itself
        if self.bounds && limit < f64::INFINITY {
            let mut bound = 0.0;
            for q in points {
                let d = self.field.lower_bound(pose * q.at).min(self.cap);
                bound += d * d;
                if bound >= limit {
                    return None;
                }
            }
        }
        let sensor = Point2::from(pose.translation.vector);
        // whether the sensor stands in the main free space, looked up once a point away from
        // every wall needs it (most poses screened are dropped before any does)
        let mut inside: Option<bool> = None;
        let mut sum = 0.0;
        for q in points {
            let p = pose * q.at;
            let cell = self.field.cell_of(p);
            let mut d = self.field.distance_of(cell).min(self.cap);
            if d < self.cap && cell.is_some_and(|cell| self.seen_from_a_closed_side(cell, sensor)) {
                d = self.cap;
            }
            let c = if d < self.cap {
                d * d
            } else {
                let inside = *inside.get_or_insert_with(|| !self.floor.at(sensor).1);
                d * d * self.unexplained(p, q.on_long_line, inside)
            };
            sum += c;
            if sum >= limit {
                return None;
            }
        }
        Some(sum)
    }

    /// The factor on the squared cap of a point `p` (map frame) beyond the cap from every wall:
    /// seen through a wall when it lies outside the main free space and the sensor does not
    /// (`inside`), a wall misplaced when it lies on a long line in open floor, else 1. One
    /// lookup answers both.
    #[inline]
    fn unexplained(&self, p: Point2<f64>, on_long_line: bool, inside: bool) -> f64 {
        let (from_wall, away) = self.floor.at(p);
        if inside && away {
            self.behind
        } else if on_long_line {
            1.0 + (self.open - 1.0) * self.cost.openness(from_wall)
        } else {
            1.0
        }
    }

    /// Whether `sensor` lies on the closed side of the wall nearest to the point in `cell` (never when the map
    /// has no closed sides).
    #[inline]
    fn seen_from_a_closed_side(&self, cell: FieldCell, sensor: Point2<f64>) -> bool {
        let Some((frames, closed)) = self.sides else {
            return false;
        };
        // only a nearest wall with a closed side is looked up (few are)
        let Some(k) = self.field.marked_nearest_wall_of(cell) else {
            return false;
        };
        let (Some(f), Some(sides)) = (frames.get(k as usize), closed.get(k as usize)) else {
            return false;
        };
        let left = f.normal.dot(&(sensor - f.a)) > 0.0;
        sides[usize::from(!left)]
    }
}

/// Sorts `candidates` by score, ties in the order they come: a stable sort's order, in place.
/// The standard stable sort takes a buffer as large as the slice from the heap on every call
/// (49 kB for a search's thousand candidates), a tenth of a localizer's peak heap on a built
/// map; the candidates are numbered instead (see [`Candidate::order`]) and sorted unstably by
/// score, then number.
pub(super) fn sort_by_score(candidates: &mut [Candidate]) {
    if candidates.len() > usize::from(u16::MAX) + 1 {
        // more than the order numbers (only a search told to keep that many makes them)
        candidates.sort_by(|a, b| a.score.total_cmp(&b.score));
        return;
    }
    for (k, c) in candidates.iter_mut().enumerate() {
        c.order = k as u16;
    }
    candidates.sort_unstable_by(|a, b| a.score.total_cmp(&b.score).then(a.order.cmp(&b.order)));
}

/// Sorts `candidates` by score and keeps the `count` best that are not within 0.1 m and 2
/// degrees of a better kept one. `by_x` is scratch space.
pub(super) fn keep_distinct(candidates: &mut Vec<Candidate>, count: usize, by_x: &mut Vec<(f64, usize)>) {
    const POSITION: f64 = 0.1;
    sort_by_score(candidates);
    // a candidate is compared only with the kept ones whose x lies within POSITION of its own
    // (hundreds are kept from hundreds more: comparing with all of them was quadratic)
    by_x.clear();
    let window = POSITION * (1.0 + 1e-9);
    let mut kept = 0;
    for k in 0..candidates.len() {
        if kept == count {
            break;
        }
        let p = candidates[k].pose;
        let x = p.translation.x;
        let from = by_x.partition_point(|&(qx, _)| qx < x - window);
        let duplicate = by_x[from..]
            .iter()
            .take_while(|&&(qx, _)| qx <= x + window)
            .any(|&(_, i)| same_pose(&p, &candidates[i].pose, POSITION, 2f64.to_radians()));
        if !duplicate {
            // positions below `kept` hold kept candidates and never move again
            candidates.swap(kept, k);
            by_x.insert(by_x.partition_point(|&(qx, _)| qx < x), (x, kept));
            kept += 1;
        }
    }
    candidates.truncate(kept);
}

/// Whether two poses are within `position` metres and `heading` radians.
pub fn same_pose(a: &Pose, b: &Pose, position: f64, heading: f64) -> bool {
    (a.translation.vector - b.translation.vector).norm() <= position
        && angle_diff(pose_theta(a), pose_theta(b)).abs() <= heading
}

/// `points` into `out`, those that tell poses apart first: by `telling` (how far a point lies
/// from where every candidate of one match puts it on a wall), largest first.
pub(super) fn order_by_telling(
    points: &[ScreenPoint],
    out: &mut Vec<ScreenPoint>,
    telling: impl Fn(Point2<f64>) -> f64,
) {
    out.clear();
    out.extend_from_slice(points);
    out.sort_by(|a, b| telling(b.at).total_cmp(&telling(a.at)));
}

/// Up to `count` sample points spread evenly over the scan, as [`subsample`] picks them, each
/// marked whether it lies on one of `lines` at least `long` metres long: within
/// [`ON_LINE`] of its visible extent. Judged by position, so the pipeline's localizer (which
/// gets the lines' extents, not their samples) marks the same points as `gema2 locate`.
pub(super) fn screen_points(
    seg: &Segmentation,
    lines: &[SlideLine],
    count: usize,
    long: f64,
    out: &mut Vec<ScreenPoint>,
) {
    out.clear();
    let long_lines = || lines.iter().filter(|l| l.length() >= long);
    out.extend(spread(seg, count).map(|at| ScreenPoint { at, on_long_line: long_lines().any(|l| on_line(l, at)) }));
}

/// How far from a line's visible extent a sample may lie and count as on it, metres: e(d) at
/// the URG-04LX's far range, so a line's own samples always do.
pub(super) const ON_LINE: f64 = 0.1;

fn on_line(l: &SlideLine, q: Point2<f64>) -> bool {
    let along = (q - l.start).dot(&l.direction());
    (-ON_LINE..=l.length() + ON_LINE).contains(&along) && l.direction().perp(&(q - l.start)).abs() <= ON_LINE
}

/// Up to `count` sample points spread evenly over the scan.
pub(super) fn subsample(seg: &Segmentation, count: usize, out: &mut Vec<Point2<f64>>) {
    out.clear();
    out.extend(spread(seg, count));
}

/// The points of [`subsample`], in scan order.
fn spread(seg: &Segmentation, count: usize) -> impl Iterator<Item = Point2<f64>> + '_ {
    let n = seg.samples.len();
    let step = (n as f64 / count.max(1) as f64).max(1.0);
    // accumulated step by step, as the points have always been picked
    std::iter::successors(Some(0.0), move |k| Some(k + step))
        .take_while(move |&k| count > 0 && (k as usize) < n)
        .map(|k| seg.samples[k as usize].point())
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// Seen from the left, a 12 cm thick partition's left face; a pose 12 cm further right puts
    /// those points on its right face, from inside the wall. The distance field alone finds them
    /// on a wall either way; the closed sides tell the second apart.
    #[test]
    fn the_screen_tells_a_pose_a_walls_thickness_off_from_the_truth() {
        let mut walls = map::Wall::rectangle(0.0, 0.0, 6.0, 4.0).to_vec();
        walls.push(map::Wall::new(3.0, 0.0, 3.0, 4.0));
        let thick = map::thick::thicken(&map::WallMap::new(walls), 0.12);
        let model = MapModel::new(thick, &map::MapCornerConfig::default());
        assert!(model.closed_sides.is_some());
        let truth = Pose::new(nalgebra::Vector2::new(1.5, 2.0), 0.0);
        // sensor-frame points on the face x = 2.94 at 0.5 m spacing, 2 cm behind it as noise has them
        let points: Vec<ScreenPoint> = (0..6)
            .map(|k| ScreenPoint { at: Point2::new(1.44 + 0.02, -1.25 + 0.5 * k as f64), on_long_line: true })
            .collect();
        let off = Pose::new(nalgebra::Vector2::new(1.62, 2.0), 0.0);
        let screen = Screen::new(&model, &LocalizerConfig::default());
        let at_truth = screen.sum(&truth, &points, f64::INFINITY).unwrap();
        let a_wall_off = screen.sum(&off, &points, f64::INFINITY).unwrap();
        assert!(at_truth < 6.0 * 0.03f64.powi(2), "{at_truth}");
        assert!(a_wall_off >= 6.0 * 0.12f64.powi(2) * 0.99, "{a_wall_off}");
        // both lie on a wall by distance alone
        for pose in [truth, off] {
            assert!(points.iter().all(|q| model.field.distance(pose * q.at) < 0.04));
        }
    }
    /// A 12 x 8 m room with a closed 2 x 2 m pillar, the sensor at (3, 4) facing +x.
    fn room_with_a_pillar() -> MapModel {
        let mut walls = map::Wall::rectangle(0.0, 0.0, 12.0, 8.0).to_vec();
        walls.extend(map::Wall::rectangle(8.0, 3.0, 10.0, 5.0));
        MapModel::new(map::WallMap::new(walls), &map::MapCornerConfig::default())
    }

    /// One point's screen cost at the sensor pose of [`room_with_a_pillar`].
    fn one_point(model: &MapModel, at: (f64, f64), on_long_line: bool) -> f64 {
        let screen = Screen::new(model, &LocalizerConfig::default());
        let sensor = Pose::new(nalgebra::Vector2::new(3.0, 4.0), 0.0);
        let q = ScreenPoint { at: Point2::new(at.0 - 3.0, at.1 - 4.0), on_long_line };
        screen.sum(&sensor, &[q], f64::INFINITY).unwrap()
    }

    /// Away from every wall, a point costs the squared cap, times `screen_behind` inside the
    /// pillar (its beam went through a wall) and times `screen_open` on a long line in open
    /// floor; a point where furniture stands, or off any long line, just the squared cap.
    #[test]
    fn the_screen_charges_points_seen_through_walls_and_long_lines_in_open_floor() {
        let model = room_with_a_pillar();
        let cfg = LocalizerConfig::default();
        let cap_sq = cfg.screen_cap * cfg.screen_cap;
        let close = |a: f64, b: f64| (a - b).abs() < 1e-9;
        // inside the pillar, 1 m from its faces, on a line or not
        assert!(close(one_point(&model, (9.0, 4.0), false), cfg.screen_behind * cap_sq));
        assert!(close(one_point(&model, (9.0, 4.0), true), cfg.screen_behind * cap_sq));
        // open floor: 2 m from the room's top wall, 3 m from the rest
        assert!(close(one_point(&model, (3.0, 6.0), true), cfg.screen_open * cap_sq));
        assert!(close(one_point(&model, (3.0, 6.0), false), cap_sq));
        // where furniture stands: 0.5 m in front of the top wall
        assert!(close(one_point(&model, (3.0, 7.5), true), cap_sq));
        // on a wall: its own small distance, whatever it lies on
        assert!(one_point(&model, (3.0, 7.99), true) < 0.001);
        // the extra charges off: the squared cap everywhere away from the walls
        let off = LocalizerConfig { screen_behind: 1.0, screen_open: 1.0, ..cfg };
        let screen = Screen::new(&model, &off);
        let sensor = Pose::new(nalgebra::Vector2::new(3.0, 4.0), 0.0);
        for at in [(6.0, 0.0), (0.0, 2.0)] {
            let q = ScreenPoint { at: Point2::new(at.0, at.1), on_long_line: true };
            assert!(close(screen.sum(&sensor, &[q], f64::INFINITY).unwrap(), cap_sq));
        }
    }

    /// The screen's points are the scan's samples, marked when they lie on a long line's
    /// visible extent; a short line marks none.
    #[test]
    fn screen_points_mark_the_samples_on_long_lines() {
        let g = laser::ScanGeometry::centred(181, 180f64.to_radians(), 10.0);
        // a wall at x = 3 across the whole scan
        let ranges: Vec<f32> = (0..181).map(|i| (3.0 / g.angle(i).cos()).min(9.0) as f32).collect();
        let view = laser::ScanView { geometry: g, ranges: &ranges };
        let mut seg = Segmentation::default();
        segment::sample::build_samples(&view, &segment::ErrorModel::default(), 1, &mut seg.samples);
        let line = |y0: f64, y1: f64| SlideLine {
            start: Point2::new(3.0, y0),
            end: Point2::new(3.0, y1),
            direction_sigma: 0.01,
        };
        let mut out = Vec::new();
        screen_points(&seg, &[line(-1.0, 1.0), line(2.0, 2.4)], 400, 0.6, &mut out);
        assert_eq!(out.len(), seg.samples.len());
        for p in &out {
            let on = p.at.y.abs() <= 1.0 + ON_LINE;
            assert_eq!(p.on_long_line, on, "{:?}", p.at);
        }
        assert!(out.iter().any(|p| p.on_long_line) && out.iter().any(|p| !p.on_long_line));
        // no line long enough: nothing marked
        screen_points(&seg, &[line(-1.0, 1.0)], 400, 2.5, &mut out);
        assert!(out.iter().all(|p| !p.on_long_line));
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]
        /// A sum with a limit is the sum without one, or `None` where that reaches the limit:
        /// the pooled bounds and the stop part way drop only poses the whole sum drops, and
        /// leave a kept pose's sum as it is to the bit. On a thick-walled plan (closed sides)
        /// and an open one, every other point on a long line.
        #[test]
        fn a_limit_only_drops_the_poses_it_should(
            poses in proptest::collection::vec((0.0f64..12.0, -1.0f64..9.0, -3.2f64..3.2), 1..40),
            points in proptest::collection::vec((-4.0f64..4.0, -4.0f64..4.0), 1..80),
            share in 0.0f64..1.5,
            thick in any::<bool>(),
        ) {
            let walls = map::bundled("apartment").unwrap().unwrap();
            let walls = if thick { map::thick::thicken(&walls, 0.12) } else { walls };
            let model = MapModel::new(walls, &map::MapCornerConfig::default());
            let points: Vec<ScreenPoint> = points
                .iter()
                .enumerate()
                .map(|(k, &(x, y))| ScreenPoint { at: Point2::new(x, y), on_long_line: k % 2 == 0 })
                .collect();
            let cfg = LocalizerConfig::default();
            for screen in [Screen::new(&model, &cfg), Screen::new(&model, &cfg).without_bounds()] {
                for &(x, y, t) in &poses {
                    let pose = Pose::new(nalgebra::Vector2::new(x, y), t);
                    let whole = screen.sum(&pose, &points, f64::INFINITY).unwrap();
                    // limits about the whole sum, and the sum itself (reached: dropped)
                    for limit in [whole * share, whole, whole * (1.0 + 1e-12), whole + 1.0] {
                        let expected = (whole < limit).then_some(whole);
                        prop_assert_eq!(screen.sum(&pose, &points, limit).map(f64::to_bits), expected.map(f64::to_bits));
                    }
                }
            }
        }

        /// The first screening pass keeps the same poses, with the same sums, whatever order it
        /// reads the points in: the order only decides how soon a pose is dropped.
        #[test]
        fn the_first_pass_keeps_the_same_poses_in_any_point_order(
            poses in proptest::collection::vec((0.0f64..12.0, -1.0f64..9.0, -3.2f64..3.2), 1..120),
            points in proptest::collection::vec((-4.0f64..4.0, -4.0f64..4.0), 1..12),
            keep in 1usize..40,
        ) {
            let model = MapModel::new(map::bundled("apartment").unwrap().unwrap(), &map::MapCornerConfig::default());
            // every other point on a long line, so the charges for open floor count too
            let points: Vec<ScreenPoint> = points
                .iter()
                .enumerate()
                .map(|(k, &(x, y))| ScreenPoint { at: Point2::new(x, y), on_long_line: k % 2 == 0 })
                .collect();
            let mut reversed = points.clone();
            reversed.reverse();
            let kept = |order: &[ScreenPoint]| {
                let mut best = Lowest::default();
                let cfg = LocalizerConfig::default();
                let mut pass = FirstPass::new(Screen::new(&model, &cfg), order.len(), keep, &mut best);
                let mut scored: Vec<(usize, f64)> = poses
                    .iter()
                    .enumerate()
                    .filter_map(|(k, &(x, y, t))| pass.score(&Pose::new(nalgebra::Vector2::new(x, y), t), order).map(|s| (k, s)))
                    .collect();
                scored.sort_by(|a, b| a.1.total_cmp(&b.1).then(a.0.cmp(&b.0)));
                scored.truncate(keep);
                scored
            };
            let (a, b) = (kept(&points), kept(&reversed));
            prop_assert_eq!(a.len(), b.len());
            for (x, y) in a.iter().zip(&b) {
                // the same sums up to rounding; poses whose sums tie within it may swap
                prop_assert!((x.1 - y.1).abs() < 1e-12, "{:?} {:?}", x, y);
            }
        }
    }

    proptest! {
        /// Sorting by score in place orders the candidates as the standard stable sort does,
        /// ties (scores drawn from a few values) in the order they came.
        #[test]
        fn sort_by_score_is_the_stable_sort(scores in proptest::collection::vec(0u8..4, 0..3000)) {
            let candidates: Vec<Candidate> = scores
                .iter()
                .enumerate()
                .map(|(k, &s)| Candidate {
                    pose: Pose::identity(),
                    score: f64::from(s) * 0.25,
                    scan_corner: 0,
                    map_corner: k as u32,
                    order: 7,
                })
                .collect();
            let mut ours = candidates.clone();
            sort_by_score(&mut ours);
            let mut stable = candidates;
            stable.sort_by(|a, b| a.score.total_cmp(&b.score));
            let ids = |v: &[Candidate]| v.iter().map(|c| c.map_corner).collect::<Vec<_>>();
            prop_assert_eq!(ids(&ours), ids(&stable));
        }
    }

    proptest! {
        /// The windowed de-duplication keeps exactly what comparing with every kept candidate
        /// keeps.
        #[test]
        fn keep_distinct_equals_comparing_with_every_kept_one(
            poses in proptest::collection::vec((0.0f64..0.6, 0.0f64..0.6, -0.1f64..0.1, 0.0f64..1.0), 0..80),
            count in 0usize..40,
        ) {
            let candidates: Vec<Candidate> = poses
                .iter()
                .enumerate()
                .map(|(k, &(x, y, theta, score))| Candidate {
                    pose: Pose::new(nalgebra::Vector2::new(x, y), theta),
                    score,
                    scan_corner: 0,
                    map_corner: k as u32,
                    order: 0,
                })
                .collect();
            let mut fast = candidates.clone();
            keep_distinct(&mut fast, count, &mut Vec::new());
            let mut sorted = candidates;
            sorted.sort_by(|a, b| a.score.total_cmp(&b.score));
            let mut reference: Vec<Candidate> = Vec::new();
            for c in sorted {
                if reference.len() < count
                    && !reference.iter().any(|q| same_pose(&c.pose, &q.pose, 0.1, 2f64.to_radians()))
                {
                    reference.push(c);
                }
            }
            let ids = |v: &[Candidate]| v.iter().map(|c| c.map_corner).collect::<Vec<_>>();
            prop_assert_eq!(ids(&fast), ids(&reference));
        }
    }
}
