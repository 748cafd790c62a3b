//! Pose hypotheses from one scan line laid along a map wall: the fallback for scans in which no
//! scan corner is a map corner.
//!
//! With furniture in view, the corners a scan shows are often where a box meets a wall or
//! another box: they exist in no map, while the real corners hide behind the boxes (on the
//! simulated furnished offices, about half the scans the corner search missed showed no
//! corner that matches the map at the truth). A long scan line is usually still a wall. Laying
//! it onto a map wall fixes the heading (two ways round) and the offset across the wall; the
//! position along the wall is left, and is sampled in steps no longer than the success radius
//! needs, from the line's start at the wall's start to its end at the wall's end. The cost
//! function then decides, as it does between corner matches.
//!
//! This is not in the paper, whose section 5 matches corners only; it keeps the paper's
//! structure (hypotheses, then eq. 7) and only adds hypotheses when corners gave no pose the
//! scan confirms.

use laser::Pose;
use map::runs::RunChain;
use map::Wall;
use nalgebra::{Isometry2, Point2, UnitComplex, Vector2};
use segment::Line;

/// What the slide search needs of a scan line: its visible extent and how well its direction
/// is known. The pipeline's localizer gets exactly these numbers over the wire, so both paths
/// compute the same poses.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SlideLine {
    /// Visible extent, sensor frame.
    pub start: Point2<f64>,
    pub end: Point2<f64>,
    /// Standard deviation of the direction, radians.
    pub direction_sigma: f64,
}

impl SlideLine {
    pub fn length(&self) -> f64 {
        (self.end - self.start).norm()
    }

    /// Unit vector from `start` to `end`.
    pub fn direction(&self) -> Vector2<f64> {
        (self.end - self.start) / self.length().max(1e-12)
    }
}

impl From<&Line> for SlideLine {
    fn from(l: &Line) -> Self {
        SlideLine { start: l.start, end: l.end, direction_sigma: l.direction_sigma }
    }
}

/// [`crate::Hypothesis::scan_corner`] of a pose the slide search made: no scan corner.
pub const FROM_SLIDE: u16 = u16::MAX;

/// Which scan lines are laid along which walls, and how finely.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SlideConfig {
    /// How many of the scan's longest lines are used; 0 turns the slide search off.
    ///
    /// In a furnished scan the longest lines are often box faces (up to 1.6 m in the simulator),
    /// which slide along walls a box's depth off the truth, while the walls behind show only in
    /// short pieces. With eq. 7 telling furniture from open floor
    /// ([`crate::CostConfig::clutter_share`]), the extra wrong poses that more and shorter lines
    /// bring are ranked below the truth: 6 lines down to 0.3 m, 1024 screened, took the
    /// furnished warehouse from 77.3 to 82.0 % (with eq. 7's earlier nearest-wall form) and
    /// the CARMEN logs both ways from 1054 to 1065 successes (2 lines down to 1 m, 384
    /// screened, before), for a median 5.5 -> 8.3 ms a CARMEN scan; the scans the first look
    /// settles do not run it. Scans of few beams rarely settle there and pay it: 68-beam clean
    /// office scans 2.0 -> 3.1 ms.
    pub lines: usize,
    /// Shortest line used, metres.
    pub min_length: f64,
    /// Shortest wall a longer line is laid over (see `shorter_walls`), metres: the pieces a plan
    /// breaks a wall into at its doorways, not every short face a scan line could span.
    pub min_wall: f64,
    /// Largest direction uncertainty of a line used, radians.
    pub max_direction_sigma: f64,
    /// Largest direction uncertainty of a line the loose slide uses ([`loose_slide_lines`]),
    /// radians; at most `max_direction_sigma` turns the loose slide off.
    pub loose_direction_sigma: f64,
    /// How many lines the loose slide uses (see [`loose_slide_lines`]).
    pub loose_lines: usize,
    /// Distance between the positions tried along a wall, metres. Refinement then pulls a
    /// pose onto the walls; along a wall with nothing else in view, a pose is at most half a
    /// step off, well inside the 0.3 m success radius.
    pub step: f64,
    /// How far a line may reach past a wall's ends (line-end noise, a door frame), metres.
    pub slack: f64,
    /// A wall shorter than the line is laid within the line's extent when it is at least this
    /// fraction of the line's length (see `placements`).
    pub shorter_walls: f64,
    /// Candidates kept by the screen for the coarse cost (the corner search's `screened`).
    pub screened: usize,
    /// The same for the loose slide. Measured in alternating runs, 512 gave the CARMEN logs both
    /// ways the very successes, `ok` and wrong `ok` of 1024 (7966, 3771, 10) for a mean of
    /// the medians 8 % lower (14.5 to 13.4 ms) and p99 10-15 % lower (freiburg-079 47 to 42
    /// ms); the simulated suite lost one scan (13849 to 13848, wrong `ok` 27 either way). At
    /// 384 CARMEN lost a success, at 256 three, neither faster. Keeping 512 in the (sure) slide
    /// as well lost two successes, one of them on infinite-corridor's odd scans.
    pub loose_screened: usize,
    /// Most poses made per scan (see [`slide_step`]).
    pub max_poses: usize,
    /// Fewest beams agreeing with the map (a fraction) for a pose to be `ok` once this search
    /// has run. It tries hundreds of poses along the walls where a corner search tries a few,
    /// so a wrong pose that happens to agree with part of the scan is far likelier, most of all
    /// against a map that misses much of what the sensor sees: on the SLAM-built CARMEN maps,
    /// 24 of the 33 poses it marked `ok` with fewer than half their beams agreeing were wrong.
    /// Below this the pose is still the answer, `ambiguous` instead of `ok`.
    pub min_inliers_ok: f64,
}

impl Default for SlideConfig {
    fn default() -> Self {
        SlideConfig {
            lines: 6,
            min_length: 0.3,
            min_wall: 1.0,
            max_direction_sigma: 1.5f64.to_radians(),
            loose_direction_sigma: 4f64.to_radians(),
            loose_lines: 4,
            step: 0.15,
            slack: 0.2,
            shorter_walls: 0.25,
            screened: 1024,
            loose_screened: 512,
            max_poses: 8192,
            min_inliers_ok: 0.5,
        }
    }
}

/// The indices of the lines the slide search uses: the `cfg.lines` longest usable ones,
/// longest first, in `out` (cleared first).
///
/// A line is used only when the scan shows another line, however short: a scan of one wall
/// alone says nothing of where along it the sensor is. Parallel walls alone can (where their
/// visible parts end), and do on the simulated warehouse's aisles: requiring a line across the
/// slid one in scans with no corner cost 6 of 300 clean scans there. So can a pillar's face a
/// few tenths of a metre wide beside a wall: requiring the other line to be 0.3 m long left 2
/// of those 300 scans without a pose; slid, one is right and the other `ambiguous`, its twin
/// one pillar spacing along the wall (over the 39 simulated logs, 7 more successes and no more
/// wrong `ok`). Where the scan cannot tell (a corridor whose ends are out of range, a person's
/// legs beside one wall), every position along the wall explains it equally well and the scan
/// ends `ambiguous` or `failed`, never `ok`.
pub fn slide_lines(lines: &[SlideLine], cfg: &SlideConfig, out: &mut Vec<usize>) {
    longest_lines(lines, cfg, f64::NEG_INFINITY, cfg.max_direction_sigma, cfg.lines, out);
}

/// The indices of the lines the loose slide uses, as [`slide_lines`]: the `cfg.loose_lines` longest
/// of those the slide search passed over for their direction alone, uncertain by more than
/// `cfg.max_direction_sigma` but at most `cfg.loose_direction_sigma`.
///
/// With furniture in view the pieces of wall a scan shows between boxes are often short, and
/// their direction uncertain by a few degrees. Such a line puts a slid pose's heading as far
/// off, and laid along every wall it makes many more wrong poses than a sure one: slid with the
/// sure ones (a limit of 2.5 degrees), the furnished warehouse gained 3 points but three of the
/// four furnished office logs lost a scan or two. So these lines are slid only when the sure
/// ones gave no confirmed pose (as the first look confirms one), the `cfg.loose_lines` longest
/// up to 4 degrees. Over the 48 simulated logs of `gema2 evaluate`, two lines: 13775 -> 13798
/// successes, `ok` and wrong `ok` unchanged, no log lost a success; the four furnished
/// warehouses 80.3 / 78.7 / 87.7 / 78.7 -> 82.3 / 79.3 / 88.0 / 79.7 %. On CARMEN both ways,
/// 1065 -> 1073 successes, but a median 8.0 -> 12.5 ms a scan, as most of its scans are never
/// confirmed. Turning each line by one standard deviation either way as well (three poses for
/// one) placed no more furnished warehouse scans (979 against 976 of 1200), and fewer clean
/// office scans whose lines were all fitted 2 degrees off.
///
/// On a SICK's scans at 1 degree (the CARMEN logs) few lines are sure within 1.5 degrees, and
/// the loose slide does most of the slide's work. There the two longest are often far walls
/// of a few points each that no run of a built map is long enough to carry, while a nearer
/// line of many points lies along runs of its own length (acapulco's scan 549: no sure line;
/// 10.6 and 7.8 m lines 20-28 m away, and a 2.1 m line 4 m away along 1.7-1.9 m runs). Four
/// lines instead of two: CARMEN both ways 7941 -> 7966 successes at the same time a scan
/// (the slide's pose budget holds), wrong `ok` 10 either way; the 48 simulated logs 13847 ->
/// 13849, wrong `ok` 28 -> 27, no log a point lower. Six: 7973 successes, 5 % slower a scan;
/// the four surest instead of the four longest: 7969, 4 % slower.
pub fn loose_slide_lines(lines: &[SlideLine], cfg: &SlideConfig, out: &mut Vec<usize>) {
    out.clear();
    if cfg.loose_direction_sigma > cfg.max_direction_sigma {
        longest_lines(lines, cfg, cfg.max_direction_sigma, cfg.loose_direction_sigma, cfg.loose_lines, out);
    }
}

/// The `count` longest lines at least `cfg.min_length` long whose direction is uncertain by
/// more than `above` and at most `up_to`, longest first, in `out` (cleared first); none when the
/// scan has only one line.
fn longest_lines(lines: &[SlideLine], cfg: &SlideConfig, above: f64, up_to: f64, count: usize, out: &mut Vec<usize>) {
    out.clear();
    let usable =
        |l: &SlideLine| l.length() >= cfg.min_length && l.direction_sigma > above && l.direction_sigma <= up_to;
    if lines.len() >= 2 {
        out.extend((0..lines.len()).filter(|&i| usable(&lines[i])));
    }
    out.sort_by(|&a, &b| lines[b].length().total_cmp(&lines[a].length()));
    out.truncate(count);
}

/// The step along walls for laying `lines[chosen]` along `walls`: `cfg.step`, or longer where
/// that would make more than `cfg.max_poses` poses. The slide search is otherwise linear in the
/// map's wall length; the budget keeps it bounded on large maps (at a coarser step, refinement
/// has more to pull).
///
/// `bends` are the lengths of the chains the lines are also laid along as chords
/// ([`chord_poses`]): at most 2 (length / s + 1) poses each.
pub fn slide_step<'a>(
    lines: &[SlideLine],
    chosen: &[usize],
    walls: impl Iterator<Item = &'a Wall> + Clone,
    bends: impl Iterator<Item = f64> + Clone,
    cfg: &SlideConfig,
) -> f64 {
    // poses at step s: 2 (floor(room / s) + 1) for each pair with room >= 0
    let (mut room, mut pairs) = (0.0, 0usize);
    for &i in chosen {
        let length = lines[i].length();
        for w in walls.clone() {
            if let Some((_, r)) = placements(length, w.length(), cfg) {
                room += r;
                pairs += 1;
            }
        }
        for bend in bends.clone() {
            room += bend;
            pairs += 1;
        }
    }
    let budget = cfg.max_poses as f64 / 2.0 - pairs as f64;
    if budget <= 0.0 {
        return f64::INFINITY; // one position per wall and way round
    }
    cfg.step.max(room / budget)
}

/// Where a line's end nearer the wall's start may lie along a wall, in metres from that start:
/// from the first number, over the second. `None` when the line is not laid along that wall.
///
/// A line no longer than the wall (give or take `cfg.slack` at each end) lies within it. A
/// wall shorter than that, but at least `cfg.shorter_walls` of the line and `cfg.min_wall`,
/// lies within the line instead: a map drawn from a plan or built from scans breaks a wall at
/// every doorway, and a scan sees it whole where the doors are shut. On the map built from the
/// CARMEN log aces (even scans), a corridor line of 15.8 m had no run longer than 4.7 m to lie
/// along, so no pose near the truth was made at all, and the corridor's twin won.
fn placements(line_length: f64, wall_length: f64, cfg: &SlideConfig) -> Option<(f64, f64)> {
    let within_wall = wall_length - line_length + 2.0 * cfg.slack;
    if within_wall >= 0.0 {
        return Some((-cfg.slack, within_wall));
    }
    (wall_length >= cfg.shorter_walls * line_length && wall_length >= cfg.min_wall)
        .then_some((wall_length - line_length - cfg.slack, line_length - wall_length + 2.0 * cfg.slack))
}

/// Calls `offer` with every pose that lays `line` (sensor frame) onto `wall`: both ways round,
/// at positions along the wall `step` apart (one, centred, for an infinite step), the line
/// within the wall's extent give or take `cfg.slack`. Nothing when the line is longer than the
/// wall allows.
pub fn slide_poses(line: &SlideLine, wall: &Wall, step: f64, cfg: &SlideConfig, mut offer: impl FnMut(Pose)) {
    let span = wall.b - wall.a;
    let wall_length = span.norm();
    let Some((lowest, room)) = placements(line.length(), wall_length, cfg) else {
        return;
    };
    if wall_length < 1e-9 || step <= 0.0 || step.is_nan() {
        return;
    }
    let w = span / wall_length;
    // positions of the line's first end along the wall, centred in the room there is
    let steps = if step.is_finite() { (room / step).floor() as usize } else { 0 };
    let step = if steps == 0 { 0.0 } else { step };
    let first = lowest + 0.5 * (room - steps as f64 * step);
    for forward in [true, false] {
        // the rotation that turns the line's direction onto the wall's, or against it; the
        // line end that lands nearer the wall's start is then `start` or `end`
        let (target, near_end) = if forward { (w, line.start) } else { (-w, line.end) };
        let rotation = turning(line, target);
        let turned = rotation * near_end.coords;
        for k in 0..=steps {
            let along = first + k as f64 * step;
            let t: Vector2<f64> = wall.a.coords + w * along - turned;
            offer(Isometry2::from_parts(t.into(), rotation));
        }
    }
}

/// Calls `offer` with every pose that lays `line` (sensor frame) as a chord of `chain`, a
/// curved or bent wall: the line's start on the chain at positions `step` apart along it, its
/// end where the chain first comes the line's length away, both ways round. A line lying along
/// one run is [`slide_poses`]'s, so only chords that span a bend are offered.
///
/// A wall drawn as a polygon of short runs (a round hall, a curved facade) has no corners a
/// scan's lines meet at, and every run is shorter than the line a scan fits along several of
/// them, so neither corners nor [`slide_poses`] give a pose there. The fitted line lies within
/// e(d) of the wall, as the chord does, so refinement pulls the pose from the chord the rest
/// of the way.
pub fn chord_poses(line: &SlideLine, chain: &RunChain, step: f64, mut offer: impl FnMut(Pose)) {
    let length = line.length();
    if !(step.is_finite() && step > 0.0) || length < 1e-9 {
        return;
    }
    let runs: Vec<Wall> = chain.runs().collect();
    if runs.len() < 2 {
        return;
    }
    // positions continue from run to run `step` apart
    let mut along = 0.0;
    for (i, run) in runs.iter().enumerate() {
        let run_length = run.length();
        let w = (run.b - run.a) / run_length;
        while along < run_length {
            let p = run.a + w * along;
            if let Some(q) = chord_end(&runs, i, p, length, chain.closed) {
                offer(lay(line, p, q));
                offer(lay(line, q, p));
            }
            along += step;
        }
        along -= run_length;
    }
}

/// Where the chain of `runs` first comes `length` away from `p` on run `i`, going on along it
/// (round it when `closed`); `None` when that is on run `i` itself or nowhere.
fn chord_end(runs: &[Wall], i: usize, p: Point2<f64>, length: f64, closed: bool) -> Option<Point2<f64>> {
    if (runs[i].b - p).norm() >= length {
        return None; // along one run
    }
    let later = if closed { runs.len() - 1 } else { runs.len() - 1 - i };
    (1..=later).map(|k| &runs[(i + k) % runs.len()]).find_map(|run| {
        let (a, d) = (run.a - p, run.b - run.a);
        if (run.b - p).norm() < length {
            return None;
        }
        // |a + t d| = length, the larger root: the distance is below it at t = 0
        let (qa, qb, qc) = (d.norm_squared(), d.dot(&a), a.norm_squared() - length * length);
        let t = (-qb + (qb * qb - qa * qc).max(0.0).sqrt()) / qa;
        Some(run.a + d * t.clamp(0.0, 1.0))
    })
}

/// The pose that puts `line`'s start on `from` and its direction towards `to`.
fn lay(line: &SlideLine, from: Point2<f64>, to: Point2<f64>) -> Pose {
    let rotation = turning(line, (to - from).normalize());
    Isometry2::from_parts((from.coords - rotation * line.start.coords).into(), rotation)
}

/// The rotation that turns `line`'s direction onto the unit vector `target`.
fn turning(line: &SlideLine, target: Vector2<f64>) -> UnitComplex<f64> {
    let d = line.direction();
    UnitComplex::from_cos_sin_unchecked(target.x * d.x + target.y * d.y, target.y * d.x - target.x * d.y)
}

#[cfg(test)]
mod tests {
    use super::*;
    use laser::{pose, pose_theta};
    use proptest::prelude::*;
    use segment::{fit::Moments, ErrorModel, Sample};

    /// A line fitted through 20 points from `a` to `b` (sensor frame).
    fn line(a: Point2<f64>, b: Point2<f64>) -> SlideLine {
        let points: Vec<Point2<f64>> = (0..20).map(|i| a + (b - a) * (i as f64 / 19.0)).collect();
        fitted(&points)
    }

    proptest! {
        /// A wall seen from a known pose, laid back onto the wall, gives a pose within half a
        /// step of the truth along the wall and exact across it.
        #[test]
        fn a_wall_seen_from_a_pose_gives_back_that_pose(
            x in -10.0f64..10.0, y in -10.0f64..10.0, th in -3.1f64..3.1,
            wx in -10.0f64..10.0, wy in -10.0f64..10.0, wa in -3.1f64..3.1, wl in 1.5f64..8.0,
            from in 0.0f64..0.4, to in 0.6f64..1.0,
        ) {
            let truth = pose(x, y, th);
            let wall = Wall { a: Point2::new(wx, wy), b: Point2::new(wx + wl * wa.cos(), wy + wl * wa.sin()) };
            let inv = truth.inverse();
            let (a, b) = (inv * (wall.a + (wall.b - wall.a) * from), inv * (wall.a + (wall.b - wall.a) * to));
            // the sensor must not stand on the wall's line
            prop_assume!(((b - a).perp(&(-a.coords))).abs() / (b - a).norm() > 0.3);
            let l = line(a, b);
            let cfg = SlideConfig::default();
            let mut best = f64::INFINITY;
            let mut best_heading = f64::INFINITY;
            slide_poses(&l, &wall, cfg.step, &cfg, |p| {
                let e = (p.translation.vector - truth.translation.vector).norm();
                let h = laser::angle_diff(pose_theta(&p), th).abs();
                if h < 1e-6 && e < best {
                    best = e;
                    best_heading = h;
                }
            });
            prop_assert!(best_heading < 1e-6);
            prop_assert!(best <= 0.5 * cfg.step + 1e-6, "{}", best);
        }
    }

    proptest! {
        /// A wall seen whole from a known pose, laid onto a map wall that is only a piece of it
        /// (a wall a plan breaks at a doorway), gives a pose within half a step of the truth.
        #[test]
        fn a_wall_seen_longer_than_the_map_draws_it_gives_back_the_pose(
            x in -10.0f64..10.0, y in -10.0f64..10.0, th in -3.1f64..3.1,
            wa in -3.1f64..3.1, wl in 4.0f64..10.0, from in 0.05f64..0.5, piece in 0.3f64..0.9,
        ) {
            let truth = pose(x, y, th);
            let start = Point2::new(x + 2.0, y - 1.0);
            let dir = Vector2::new(wa.cos(), wa.sin());
            let seen = Wall { a: start, b: start + dir * wl };
            // the map draws the piece from `from` of the seen length, `piece` of it long
            let (u, v) = (from * wl, (from + piece * (1.0 - from)) * wl);
            let wall = Wall { a: start + dir * u, b: start + dir * v };
            let inv = truth.inverse();
            let (a, b) = (inv * seen.a, inv * seen.b);
            prop_assume!(((b - a).perp(&(-a.coords))).abs() / (b - a).norm() > 0.3);
            let l = line(a, b);
            let cfg = SlideConfig::default();
            prop_assume!(wall.length() >= cfg.shorter_walls * l.length() && wall.length() >= cfg.min_wall);
            prop_assume!(wall.length() < l.length() - 2.0 * cfg.slack);
            let mut best = f64::INFINITY;
            slide_poses(&l, &wall, cfg.step, &cfg, |p| {
                if laser::angle_diff(pose_theta(&p), th).abs() < 1e-6 {
                    best = best.min((p.translation.vector - truth.translation.vector).norm());
                }
            });
            prop_assert!(best <= 0.5 * cfg.step + 1e-6, "{}", best);
        }
    }

    /// The least-squares line through `points` (sensor frame), as line inference fits one.
    fn fitted(points: &[Point2<f64>]) -> SlideLine {
        let samples: Vec<Sample> = points
            .iter()
            .enumerate()
            .map(|(i, p)| {
                let d = p.coords.norm();
                Sample { beam: i as u32, dir: p.coords / d, d, near: d - 0.01, far: d + 0.01, gap_before: i == 0 }
            })
            .collect();
        let mut m = Moments::default();
        for s in &samples {
            m.add(s.point());
        }
        let last = samples.len() - 1;
        SlideLine::from(&Line::from_moments(&samples, 0, last, m, &ErrorModel::default()).expect("a fit"))
    }

    proptest! {
        /// A curved wall (a circle drawn as a polygon of short runs) seen from a pose inside
        /// it: the scan's line along several runs, laid back as a chord, gives a pose near
        /// enough for refinement, where no single run is long enough to slide it along.
        #[test]
        fn a_chord_of_a_curved_wall_gives_a_pose_near_the_truth(
            x in -1.5f64..1.5, y in -1.5f64..1.5, th in -3.1f64..3.1, from in 0.0f64..6.2,
        ) {
            let (r, sides) = (5.0, 40);
            let p = |k: usize| {
                let a = std::f64::consts::TAU * k as f64 / sides as f64;
                Point2::new(r * a.cos(), r * a.sin())
            };
            let walls: Vec<Wall> = (0..sides).map(|k| Wall { a: p(k), b: p(k + 1) }).collect();
            let chains = map::runs::chains_of_runs(&walls, 0.03);
            prop_assert_eq!(chains.len(), 1);
            // the wall's points over 0.3 rad of arc (three runs), seen from the truth
            let truth = pose(x, y, th);
            let inv = truth.inverse();
            let on_wall = |a: f64| {
                let k = ((a / std::f64::consts::TAU * sides as f64).floor() as usize) % sides;
                let w = &walls[k];
                let (ray, dir) = (Point2::origin(), nalgebra::Vector2::new(a.cos(), a.sin()));
                // where the ray from the centre at angle a meets that side
                let e = w.b - w.a;
                let t = (w.a - ray).perp(&e) / dir.perp(&e);
                inv * (ray + dir * t)
            };
            let points: Vec<Point2<f64>> = (0..60).map(|i| on_wall(from + 0.3 * i as f64 / 59.0)).collect();
            let l = fitted(&points);
            prop_assume!(l.length() > 1.0);
            let cfg = SlideConfig::default();
            for wall in &walls {
                let mut n = 0;
                slide_poses(&l, wall, cfg.step, &cfg, |_| n += 1);
                prop_assert_eq!(n, 0);
            }
            let mut best = (f64::INFINITY, f64::INFINITY);
            chord_poses(&l, &chains[0], cfg.step, |q| {
                let e = (q.translation.vector - truth.translation.vector).norm();
                let h = laser::angle_diff(pose_theta(&q), th).abs();
                if e + h < best.0 + best.1 {
                    best = (e, h);
                }
            });
            prop_assert!(best.0 < 0.15 && best.1 < 3f64.to_radians(), "{:?}", best);
        }
    }

    #[test]
    fn a_chord_within_one_run_is_left_to_the_slide_along_it() {
        let chain = RunChain {
            points: vec![Point2::new(0.0, 0.0), Point2::new(10.0, 0.0), Point2::new(19.0, 3.0)],
            closed: false,
        };
        let l = line(Point2::new(2.0, -1.0), Point2::new(2.0, 1.0));
        let mut poses = Vec::new();
        chord_poses(&l, &chain, 0.5, |p| poses.push(p));
        // only starts within 2 m before the bend, both ways round
        assert!(!poses.is_empty());
        for q in &poses {
            let (s, e) = (q * l.start, q * l.end);
            // one end on the first run within the line's length of the bend, the other past it
            let before = |p: Point2<f64>| p.y.abs() < 1e-9 && p.x >= 10.0 - l.length() - 1e-9 && p.x <= 10.0;
            let after = |p: Point2<f64>| p.x > 10.0 && (p.y - (p.x - 10.0) / 3.0).abs() < 1e-9;
            assert!((before(s) && after(e)) || (before(e) && after(s)), "{s} {e}");
            assert!(((e - s).norm() - l.length()).abs() < 1e-9);
        }
        assert!(poses.len() <= 2 * 5, "{}", poses.len());
        // no position or an infinite step: no poses
        let mut n = 0;
        chord_poses(&l, &chain, f64::INFINITY, |_| n += 1);
        assert_eq!(n, 0);
    }

    #[test]
    fn a_line_alone_is_not_slid_but_one_beside_any_other_is() {
        let cfg = SlideConfig::default();
        let wall = line(Point2::new(2.0, -2.0), Point2::new(2.0, 2.0));
        let mut out = Vec::new();
        slide_lines(std::slice::from_ref(&wall), &cfg, &mut out);
        assert!(out.is_empty(), "{out:?}");
        // a pillar's face beside it can tell where along the wall the sensor is
        let tiny = line(Point2::new(1.0, 1.0), Point2::new(1.2, 1.0));
        slide_lines(&[wall, tiny], &cfg, &mut out);
        assert_eq!(out, vec![0]);
        let parallel = line(Point2::new(-1.0, 1.5), Point2::new(-1.0, -1.5));
        let across = line(Point2::new(-0.5, 2.5), Point2::new(1.0, 2.5));
        slide_lines(&[parallel, tiny, across, wall], &cfg, &mut out);
        // the lines long enough to slide, longest first
        assert_eq!(out, vec![3, 0, 2]);
        // ... at most `lines` of them
        slide_lines(&[parallel, tiny, across, wall], &SlideConfig { lines: 2, ..cfg }, &mut out);
        assert_eq!(out, vec![3, 0]);
    }

    #[test]
    fn the_loose_slide_takes_only_lines_the_slide_passed_over_for_their_direction() {
        let cfg = SlideConfig { loose_lines: 2, ..SlideConfig::default() };
        let with_sigma = |l: SlideLine, degrees: f64| SlideLine { direction_sigma: degrees.to_radians(), ..l };
        let a = Point2::new(2.0, -1.0);
        let sure = with_sigma(line(a, Point2::new(2.0, 2.0)), 1.0);
        let loose_short = with_sigma(line(a, Point2::new(2.5, -1.0)), 3.0);
        let loose_long = with_sigma(line(a, Point2::new(3.0, -1.0)), 2.0);
        let loose_longest = with_sigma(line(a, Point2::new(3.2, -1.0)), 3.5);
        let too_loose = with_sigma(line(a, Point2::new(5.0, -1.0)), 6.0);
        let too_short = with_sigma(line(a, Point2::new(2.2, -1.0)), 2.0);
        let all = [sure, loose_short, too_loose, loose_long, too_short, loose_longest];
        let mut out = Vec::new();
        slide_lines(&all, &cfg, &mut out);
        assert_eq!(out, vec![0]);
        // the two longest loose lines
        loose_slide_lines(&all, &cfg, &mut out);
        assert_eq!(out, vec![5, 3]);
        // a line alone says nothing of where along a wall the sensor is
        loose_slide_lines(std::slice::from_ref(&loose_long), &cfg, &mut out);
        assert!(out.is_empty());
        // no looser limit than the slide's own: no loose slide
        let off = SlideConfig { loose_direction_sigma: cfg.max_direction_sigma, ..cfg };
        loose_slide_lines(&all, &off, &mut out);
        assert!(out.is_empty());
    }

    #[test]
    fn the_step_grows_to_keep_within_the_pose_budget() {
        let short = line(Point2::new(1.0, -0.5), Point2::new(1.0, 0.5));
        let walls: Vec<Wall> =
            (0..100).map(|k| Wall { a: Point2::new(0.0, k as f64), b: Point2::new(10.0, k as f64) }).collect();
        let count = |cfg: &SlideConfig| {
            let step = slide_step(&[short], &[0], walls.iter(), std::iter::empty(), cfg);
            let mut n = 0;
            for w in &walls {
                slide_poses(&short, w, step, cfg, |_| n += 1);
            }
            (step, n)
        };
        let roomy = SlideConfig { max_poses: 1 << 20, ..SlideConfig::default() };
        assert_eq!(count(&roomy), (roomy.step, 100 * 2 * 63));
        let tight = SlideConfig { max_poses: 4000, ..SlideConfig::default() };
        let (step, n) = count(&tight);
        assert!(step > tight.step && n <= 4000 && n > 3000, "{step} {n}");
        // fewer poses than walls allow: one per wall and way round, centred
        let tiny = SlideConfig { max_poses: 100, ..SlideConfig::default() };
        let (step, n) = count(&tiny);
        assert!(step.is_infinite() && n == 200, "{step} {n}");
        let mut centre = Vec::new();
        slide_poses(&short, &walls[0], step, &tiny, |p| centre.push(p * short.start));
        assert!(centre.iter().all(|c| (c.x - 4.5).abs() < 1e-9 || (c.x - 5.5).abs() < 1e-9), "{centre:?}");
    }

    #[test]
    fn a_line_far_longer_than_the_wall_gives_nothing_and_steps_cover_the_room() {
        let cfg = SlideConfig::default();
        let wall = Wall { a: Point2::new(0.0, 0.0), b: Point2::new(3.0, 0.0) };
        // 3 m is less than a quarter of 13 m
        let long = line(Point2::new(1.0, -6.5), Point2::new(1.0, 6.5));
        let mut n = 0;
        slide_poses(&long, &wall, cfg.step, &cfg, |_| n += 1);
        assert_eq!(n, 0);
        // 3 m is more than a quarter of 4 m: the wall lies within the line
        let longer = line(Point2::new(1.0, -2.0), Point2::new(1.0, 2.0));
        let mut ends = Vec::new();
        slide_poses(&longer, &wall, cfg.step, &cfg, |p| ends.push((p * longer.start, p * longer.end)));
        // two ways round, (4 - 3 + 0.4) / 0.15 = 9.33 -> 10 positions each
        assert_eq!(ends.len(), 20);
        for (a, b) in &ends {
            let (lo, hi) = (a.x.min(b.x), a.x.max(b.x));
            assert!(lo <= 0.2 + 1e-9 && hi >= 2.8 - 1e-9 && a.y.abs() < 1e-9, "{a} {b}");
        }
        let off = SlideConfig { shorter_walls: 0.8, ..cfg };
        n = 0;
        slide_poses(&longer, &wall, cfg.step, &off, |_| n += 1);
        assert_eq!(n, 0, "3 m is less than 0.8 of 4 m");
        let short = line(Point2::new(1.0, -1.0), Point2::new(1.0, 1.0));
        let mut starts = Vec::new();
        slide_poses(&short, &wall, cfg.step, &cfg, |p| starts.push(p * short.start));
        // two ways round, (3 - 2 + 0.4) / 0.15 = 9.33 -> 10 positions each
        assert_eq!(starts.len(), 20);
        for s in &starts {
            assert!(s.y.abs() < 1e-9, "{s}");
        }
    }
}
