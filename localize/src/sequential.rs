//! The sequential localizer: eq. 7 accumulated over the scans of a moving robot.
//!
//! One scan in a symmetric place cannot be told from its twin; a robot that moves a metre
//! sees the difference, and its wheel odometry says how it moved. This localizer keeps the
//! hypotheses ([`Track`]s) of an unsure scan instead of discarding them, moves them by the
//! odometry between two scans, searches for each across the motion's spread and costs it again
//! by eq. 7 ([`Localizer::search_around`]). The costs add up: a track is `behind` the best by
//! the sum, over the scans it lived through, of its per-beam cost less the best's. It says `ok`
//! when one track is ahead of every distinct rival by [`SequentialConfig::margin`] on that sum,
//! and the scan tells its pose from poses at the edge of what `ok` promises
//! ([`Sequential::withstands_probes`]); on a drawn map, as for a single scan, not while the
//! pose sees through more of its walls than
//! [`max_through_ok`](crate::LocalizerConfig::max_through_ok) allows
//! ([`Localizer::sees_through_drawn_walls`]). A scan the single-scan search is `ok` on is `ok`
//! at that held track with the same probes, though a twin leads on the sum: the lead was earned
//! where the two could not be told apart. A scan that is not `ok` answers, `ambiguous`, on the
//! track the last `ok` was on while it holds and no track leads it by the margin
//! ([`SequentialConfig::keep_to_the_last_ok`]).
//!
//! While no track is sure, every scan also runs the global search of [`Localizer::locate`] and
//! its hypotheses join the tracks (a global pose that lands on a track refreshes it). Once
//! sure, a scan costs that search per track: it tracks. A track whose pose leaves the
//! odometry's spread ([`OdometryNoise::spread`]), or whose pose the scan no longer explains,
//! misses the scan; the best missing one is searched for within the spread
//! ([`Localizer::locate_near`]), and when it is not found there the robot was moved or is lost,
//! and the global search runs again on that very scan. Where odometry's spread is wider than
//! the search's window about the prediction, the best track's search looks again about where
//! its first look refined to ([`SequentialConfig::second_look_sides`]). A track that misses
//! [`SequentialConfig::lost_after`] scans in a row is dropped. Along the direction a scan pins
//! down least (an aisle's length), a held track's pose weighs the search against odometry by
//! their information ([`fuse_along`]) while odometry's spread is finer than the search's grid.
//!
//! Without odometry between two scans nothing can be carried over: the tracks are dropped and
//! the scan is located from scratch.

use crate::cost::Cost;
use crate::localizer::{same_pose, Localizer, Probes, Status};
use crate::slide::SlideLine;
use laser::motion::{motion, OdometryNoise};
use laser::{angle_diff, pose_theta, Pose, ScanView};
use segment::Segmentation;

/// The sequential localizer's settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SequentialConfig {
    /// How far the odometry's motion may be off: the motion model's alphas. Larger than the
    /// robot's own is safe (a wider gate); smaller loses the track on a slip.
    pub motion: OdometryNoise,
    /// The lead, in eq. 7 cost per beam summed over the scans, that the best track needs over
    /// every distinct rival to be `ok` (the single-scan ambiguity margin, accumulated).
    pub margin: f64,
    /// A track first seen while others are tracked starts this far behind the best: it has
    /// not been through their scans.
    pub birth: f64,
    /// A track this far behind the best is dropped.
    pub drop: f64,
    /// What a missed scan adds to a track's lag.
    pub miss: f64,
    /// A track that misses this many scans in a row is dropped.
    pub lost_after: u32,
    /// Most tracks kept.
    pub max_tracks: usize,
    /// Until the best track has lived through this many scans, the global search runs on every
    /// scan and its hypotheses join the tracks.
    pub settle_scans: u32,
    /// The gate about a predicted pose: this floor plus `gate_sigmas` of the motion's spread
    /// (metres; the heading's floor is `gate_heading`, radians).
    pub gate_position: f64,
    pub gate_heading: f64,
    pub gate_sigmas: f64,
    /// The fewest beams agreeing with the map for an `ok` answer.
    pub min_inliers_ok: f64,
    /// The fewest beams agreeing with the map for a track to hold on a scan.
    pub min_inliers_held: f64,
    /// The poses screened about a predicted one: headings this far apart (radians), at most
    /// this many either side, and positions this far apart (metres), at most this many either
    /// side along x and y, over `gate_sigmas` of the motion's spread.
    pub start_step: f64,
    pub max_start_sides: i32,
    pub position_step: f64,
    pub max_position_sides: i32,
    /// The screened poses refined per track.
    pub refined: usize,
    /// The least constraint across [`crate::refine::weakest_direction`] of an `ok` answer, in
    /// points' worth of refinement's: below it the scan leaves a direction free (a corridor),
    /// along which only drifting odometry says where the robot is.
    pub min_constraint: f64,
    /// The probes an `ok` answer must withstand ([`Sequential::withstands_probes`]), a single
    /// scan's as well ([`LocalizerConfig::ok_probes`](crate::LocalizerConfig::ok_probes)).
    pub probes: Probes,
    /// A cold start's first scan is `ok` as the single-scan search judged it, or, where that
    /// search said `ambiguous`, when no distinct hypothesis of its comes within this much eq. 7
    /// cost per beam of the best. On a map built from a log a right pose sees through more of
    /// the imperfect walls than an `ok` single scan may, though no rival comes near; the probes
    /// and the `ok` limits still apply.
    pub lone_gap: f64,
    /// Along the direction the scan pins down least, a tracked pose weighs refinement's pose
    /// against odometry's prediction by their information ([`fuse_along`]): the scan's
    /// constraint (points' worth of wall normal) over this spread squared (metres), against
    /// one over odometry's spread squared. Only while odometry's spread is finer than the
    /// search's `position_step`: then which of the grid's starts refines best along an aisle or
    /// corridor says less than odometry does.
    pub along_sigma: f64,
    /// The second look (`Sequential::look_again`): when the best track's window could not
    /// span the motion's spread and its best pose refined to beyond the window, its search
    /// runs again about that pose, this many steps (`start_step`, `position_step`) either way
    /// in heading, x and y, and refines the best start. A pose the second look moved further
    /// than `second_look_jump` (metres) or `second_look_turn` (radians) from the first is not
    /// `ok` on that scan: the scan placed it twice, differently. Negative sides: no second look.
    pub second_look_sides: i32,
    pub second_look_jump: f64,
    pub second_look_turn: f64,
    /// The look along (`Sequential::look_along`): when the best track's pose explains the scan
    /// worse by more than `along_look_jump` per beam than the track explained its last one, or
    /// its window could not span the motion's spread and the pose leaves a direction free
    /// (under `min_constraint`), poses along the direction the scan pins down least are
    /// screened across the gate (`position_step` apart, at most `along_look_most` either way,
    /// 3 headings) and the best refined. A pose that costs `along_look_margin` per beam less by
    /// eq. 7 (in a corridor with nothing along it, eq. 7 is flat and odometry's pose is as good
    /// as any) is kept as the track's `shadow`; found so again on the next scan, within
    /// `gate_position` and one spread of where odometry moved the shadow, it replaces the
    /// window's pose. Negative margin: no look along.
    pub along_look_margin: f64,
    pub along_look_jump: f64,
    pub along_look_most: i32,
    /// The near look (`Sequential::look_near`): when the best track's pose explains the scan
    /// worse by more than this per beam than the track explained its last one, the
    /// single-scan cascade searches the gate about the prediction. What it finds is taken at
    /// once where the cascade is sure of it (`ok` within the gate), where the window's pose
    /// was (within `second_look_jump` and `second_look_turn`), or where it is far cheaper than
    /// the window's (`near_look_lead`); else it is weighed as the look
    /// along's pose is, kept as the track's `shadow` to be found so again on the next scan
    /// (on the maps built from aces and infinite-corridor, 28 of 62 poses the cascade was
    /// unsure of, taken at once, were twins along a corridor that replaced right poses,
    /// against 1 of 49 it was sure of). Negative: no near look.
    pub near_look_jump: f64,
    /// A pose the near look or the look along found is taken at once, sure or not, when it
    /// costs this much less per beam by eq. 7 than the window's. The window's pose is then far
    /// off: where drawn odometry made up a turn on a spin, 44 degrees off on freiburg-079, the
    /// window refined to 6 degrees off at 4.2 per beam, and the near look found the truth at
    /// 1.1 but not sure of it, so the track answered the wrong pose for a scan. A corridor's
    /// twin does not explain a scan a whole per beam better than a right pose does. Infinite:
    /// never.
    pub near_look_lead: f64,
    /// A pose a look found and kept as the track's `shadow` (not taken) is this scan's answer,
    /// `ambiguous`, when it costs at least `look_answer_lead` per beam less than the window's
    /// pose by eq. 7 and lies within `look_answer_sigmas` of odometry's spreads of the
    /// prediction. The track keeps its own pose until the next scan agrees: on a built map one
    /// scan can favour a wrong place by that much. But a window left short of the truth by
    /// drifting odometry (a corridor, where eq. 7 is flat along it) is wrong on that scan,
    /// and the look's pose, which the scan fits much better about where odometry puts the
    /// robot, is right more often: on the CARMEN logs with drawn odometry, the poses right
    /// after the first fix rose on four of seven logs (csail 97.4 to 99.0 %, infinite-corridor
    /// by about a point, seeds 1-3) and fell on none; with the logs' own odometry they were
    /// as many (odd scans), or 3 fewer of 2600 (even scans: a pose 1.9 m along an aces
    /// corridor explains its scan 0.7 a beam better than the truth). Infinite lead: never.
    pub look_answer_lead: f64,
    pub look_answer_sigmas: f64,
    /// An `ambiguous` answer stays on the track the last `ok` answer was on, while that track
    /// holds on the scan and no other leads it by `margin`, rather than moving to whichever
    /// track leads by less: where the evidence cannot tell the tracks apart, the one the
    /// localizer was sure of and has followed since is the likelier, and a robot's answer
    /// does not jump to a twin and back. On infinite-corridor a cold start's track, `ok` on
    /// its first scan, fell a little behind a twin 81 m away on its third, and the answer
    /// followed the twin for nine scans. Only `ambiguous` answers move: no status changes.
    pub keep_to_the_last_ok: bool,
}

impl SequentialConfig {
    /// The poses of a search's grid about `centre` into `out`: step (k, i, j) is `centre`
    /// turned k `start_step`s and moved (i, j) `position_step`s along x and y.
    fn grid_starts(&self, steps: impl Iterator<Item = (i32, i32, i32)>, centre: &Pose, out: &mut Vec<Pose>) {
        let (c, heading) = (centre.translation.vector, pose_theta(centre));
        out.clear();
        out.extend(steps.map(|(k, i, j)| {
            let at = c + nalgebra::Vector2::new(f64::from(i), f64::from(j)) * self.position_step;
            nalgebra::Isometry2::new(at, heading + f64::from(k) * self.start_step)
        }));
    }
}

impl Default for SequentialConfig {
    fn default() -> Self {
        SequentialConfig {
            motion: OdometryNoise::new([0.1, 0.02, 0.1, 0.02]),
            margin: 0.3,
            birth: 0.3,
            drop: 3.0,
            miss: 0.15,
            lost_after: 3,
            max_tracks: 24,
            settle_scans: 3,
            gate_position: 0.3,
            gate_heading: 5f64.to_radians(),
            gate_sigmas: 3.0,
            min_inliers_ok: 0.65,
            min_inliers_held: 0.5,
            start_step: 3f64.to_radians(),
            max_start_sides: 12,
            position_step: 0.2,
            max_position_sides: 2,
            refined: 3,
            min_constraint: 12.0,
            probes: Probes::default(),
            lone_gap: 2.0,
            along_sigma: 0.2,
            second_look_sides: 1,
            second_look_jump: 0.15,
            second_look_turn: 5f64.to_radians(),
            along_look_margin: 0.15,
            along_look_jump: 0.5,
            along_look_most: 10,
            near_look_jump: 1.0,
            near_look_lead: 1.0,
            look_answer_lead: 0.5,
            look_answer_sigmas: 2.0,
            keep_to_the_last_ok: true,
        }
    }
}

/// One hypothesis the localizer carries from scan to scan.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Track {
    pub pose: Pose,
    /// Its eq. 7 cost on the last scan it explained.
    pub cost: Cost,
    /// How far behind the best track it is: per-beam cost summed over the scans.
    pub behind: f64,
    /// The scans it has explained.
    pub scans: u32,
    /// The scans it has missed in a row.
    pub misses: u32,
    /// Whether it was first seen while other tracks were held (not on a cold start).
    pub late: bool,
    /// Whether this scan's second look moved it ([`SequentialConfig::second_look_jump`]).
    pub relooked: bool,
    /// A pose the look along or the near look found for it on the last scan
    /// (`Sequential::look_along`, `Sequential::look_near`), to be weighed against it again
    /// on this one.
    pub shadow: Option<Pose>,
    /// A look's pose and cost that answer this scan in the track's place when it is the best
    /// and not `ok` ([`SequentialConfig::look_answer_lead`]). Kept on the track the look was
    /// about, so that another track that the global search puts first never answers with it.
    pub look_answer: Option<(Pose, Cost)>,
    /// Which track it is: one number a track keeps while it lives, never given to another.
    pub id: u64,
}

/// One scan's answer.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SequentialAnswer {
    pub status: Status,
    /// The answering track's pose and cost (see `track`), or, when `ambiguous`, a look's that
    /// the scan fits much better ([`SequentialConfig::look_answer_lead`]); none when `failed`.
    pub pose: Option<Pose>,
    pub cost: Option<Cost>,
    /// How many scans the answer rests on (the answering track's).
    pub scans: u32,
    /// Whether the global search ran on this scan (else it tracked).
    pub global: bool,
    /// Tracks held after the scan.
    pub tracks: usize,
    /// Which of [`Sequential::tracks`] the answer is: the best, a younger one the scan's own
    /// search was `ok` on, or, when `ambiguous`, the one the last `ok` was on
    /// ([`SequentialConfig::keep_to_the_last_ok`]); none when `failed`.
    pub track: Option<usize>,
}

impl SequentialAnswer {
    /// The answer at track `k` of [`Sequential::tracks`], `track`: its pose, cost and scans.
    fn rest_on(&mut self, k: usize, track: &Track) {
        (self.pose, self.cost, self.scans, self.track) = (Some(track.pose), Some(track.cost), track.scans, Some(k));
    }
}

/// The sequential localizer over a single-scan [`Localizer`].
pub struct Sequential {
    pub localizer: Localizer,
    pub config: SequentialConfig,
    tracks: Vec<Track>,
    /// The odometry of the last scan located.
    last_odometry: Option<Pose>,
    /// [`Localizer::search_around`]'s answer for one track, and for its second look.
    scored: Vec<(Pose, Cost)>,
    relook: Vec<(Pose, Cost)>,
    /// This scan's gate about a predicted pose (position, heading).
    gate: (f64, f64),
    /// The steps of the last window searched about a track.
    window: Window,
    /// The [`Track::id`] of the track the last `ok` answer was on, while it lives and no
    /// answer since was `failed` ([`SequentialConfig::keep_to_the_last_ok`]).
    last_ok: Option<u64>,
    /// The [`Track::id`] the next new track gets.
    next_id: u64,
}

/// The steps (k, i, j) of the grid a track is searched over ([`SequentialConfig::grid_starts`]),
/// nearest the prediction first: the screen then knows a good sum early and gives up on most
/// far starts part way through their points. Kept from scan to scan: the window's size changes
/// only with odometry's spread, and ordering its hundreds of steps anew was 3-4 % of a tracked
/// scan.
#[derive(Debug, Default)]
struct Window {
    /// The sides (turns, shifts) the steps are for.
    sides: Option<(i32, i32)>,
    steps: Vec<(i32, i32, i32)>,
}

impl Window {
    /// The steps of the window `turns` headings and `shifts` positions either way, to be given
    /// back ([`give_back`](Self::give_back)) once searched.
    fn take(&mut self, turns: i32, shifts: i32) -> Vec<(i32, i32, i32)> {
        // a window is never empty: an empty one was taken and not given back
        if self.sides != Some((turns, shifts)) || self.steps.is_empty() {
            self.steps.clear();
            for k in -turns..=turns {
                for i in -shifts..=shifts {
                    for j in -shifts..=shifts {
                        self.steps.push((k, i, j));
                    }
                }
            }
            self.steps.sort_by_key(|&(k, i, j)| k * k + i * i + j * j);
            self.sides = Some((turns, shifts));
        }
        std::mem::take(&mut self.steps)
    }

    fn give_back(&mut self, steps: Vec<(i32, i32, i32)>) {
        self.steps = steps;
    }
}

impl Sequential {
    pub fn new(localizer: Localizer, config: SequentialConfig) -> Self {
        Sequential {
            localizer,
            config,
            tracks: Vec::new(),
            last_odometry: None,
            scored: Vec::new(),
            relook: Vec::new(),
            gate: (0.0, 0.0),
            window: Window::default(),
            last_ok: None,
            next_id: 0,
        }
    }

    /// Switches to another map (from the next scan on): the tracks lie in the old one.
    pub fn set_model(&mut self, model: std::sync::Arc<crate::model::MapModel>) {
        self.localizer.set_model(model);
        self.reset();
    }

    /// Forgets every track: the next scan starts cold.
    pub fn reset(&mut self) {
        self.tracks.clear();
        self.last_odometry = None;
        self.last_ok = None;
    }

    pub fn tracks(&self) -> &[Track] {
        &self.tracks
    }

    /// The tracks as hypotheses, `answer`'s first (it need not be the best track: see
    /// [`SequentialAnswer::track`]), then the rest best first: what a pipeline publishes, whose
    /// readers take the first hypothesis as the answer. A track that missed the scan stands
    /// where odometry put it, at an infinite cost.
    pub fn hypotheses<'a>(&'a self, answer: &SequentialAnswer) -> impl Iterator<Item = crate::Hypothesis> + 'a {
        let first = answer.track.filter(|&k| k < self.tracks.len());
        let rest = (0..self.tracks.len()).filter(move |&k| Some(k) != first);
        // the answer's pose may be a look's rather than its track's (`look_answer_lead`)
        let answered = answer.pose.zip(answer.cost);
        first.into_iter().chain(rest).map(move |k| {
            let own = (self.tracks[k].pose, self.tracks[k].cost);
            let (pose, cost) = if Some(k) == first { answered.unwrap_or(own) } else { own };
            crate::Hypothesis { pose, cost, scan_corner: 0, map_corner: 0 }
        })
    }

    /// Locates one scan, whose odometry pose (any frame, the robot's or the sensor's: only the
    /// motion between two scans is read) is `odometry` when known.
    pub fn locate(&mut self, scan: &ScanView<'_>, seg: &Segmentation, odometry: Option<Pose>) -> SequentialAnswer {
        self.localizer.set_lines(seg.lines.iter().map(SlideLine::from));
        self.locate_set_lines(scan, seg, odometry)
    }

    /// [`locate`](Self::locate) for a segmentation whose lines arrive separately (the
    /// pipeline's localizer; `seg.lines` is ignored).
    pub fn locate_with_lines(
        &mut self,
        scan: &ScanView<'_>,
        seg: &Segmentation,
        lines: impl IntoIterator<Item = SlideLine>,
        odometry: Option<Pose>,
    ) -> SequentialAnswer {
        self.localizer.set_lines(lines);
        self.locate_set_lines(scan, seg, odometry)
    }

    fn locate_set_lines(
        &mut self,
        scan: &ScanView<'_>,
        seg: &Segmentation,
        odometry: Option<Pose>,
    ) -> SequentialAnswer {
        // a reading that is not a number is no reading
        let odometry =
            odometry.filter(|p| p.translation.vector.iter().all(|v| v.is_finite()) && p.rotation.angle().is_finite());
        let moved = match (self.last_odometry, odometry) {
            (Some(a), Some(b)) => Some((motion(&a, &b), a, b)),
            _ => None,
        };
        self.last_odometry = odometry;
        if moved.is_none() {
            self.tracks.clear();
        }
        self.gate = (0.0, 0.0);
        let mut missed_best = false;
        if let Some((delta, a, b)) = moved {
            missed_best = self.follow(scan, seg, &delta, &a, &b);
        }
        let global = self.tracks.is_empty() || missed_best || !self.settled();
        let mut single = None;
        if global {
            single = self.search(scan, seg);
        }
        self.settle_lags();
        let mut answer = self.answer(scan, single);
        self.remember_the_last_ok(&answer);
        answer.global = global;
        answer
    }

    /// Whether the scan tells `pose` from the poses at the edge of what `ok` promises
    /// ([`Localizer::withstands_probes`] with [`SequentialConfig::probes`]). A track can sit
    /// off the truth, held there by odometry, where eq. 7 is flat (an aisle's length, a
    /// heading among clutter): then a pose that would be wrong explains the scan as well, and
    /// the answer is `ambiguous`.
    ///
    /// Reads the localizer's state for `scan`: call it after locating the scan.
    pub fn withstands_probes(&mut self, scan: &ScanView<'_>, pose: &Pose) -> bool {
        let (_, along) = self.localizer.weakest_direction(pose);
        self.localizer.withstands_probes(scan, pose, along, &self.config.probes)
    }

    /// Moves every track by the odometry's motion, searches for it across the motion's spread
    /// and costs it; returns whether the best track (the first) missed the scan.
    fn follow(&mut self, scan: &ScanView<'_>, seg: &Segmentation, delta: &Pose, a: &Pose, b: &Pose) -> bool {
        let cfg = self.config;
        let (spread, turn) = cfg.motion.spread(a, b);
        let gate = cfg.gate_position + cfg.gate_sigmas * spread;
        let gate_heading = cfg.gate_heading + cfg.gate_sigmas * turn;
        // odometry's motion is off by its spread, and refinement reaches a few decimetres and
        // degrees: each track is screened at headings and positions across the spread about
        // where odometry puts it, and the few best refined
        let sides =
            |spread: f64, step: f64, most: i32| ((cfg.gate_sigmas * spread / step).ceil() as i32).clamp(0, most);
        let turns = sides(turn, cfg.start_step, cfg.max_start_sides);
        let shifts = sides((spread - cfg.position_step).max(0.0), cfg.position_step, i32::MAX);
        // the window spans the spread only up to its most sides; beyond, the truth may lie outside
        let window_short = shifts > cfg.max_position_sides;
        let shifts = shifts.min(cfg.max_position_sides);
        let steps = self.window.take(turns, shifts);
        let mut starts = Vec::with_capacity(steps.len());
        // per track: where odometry puts it, and the best pose found about there
        let mut found = Vec::with_capacity(self.tracks.len());
        let mut shadow = None;
        let mut look_answer = None;
        // the near look's cascade about the best track's prediction, when it ran
        let mut cascade = None;
        for n in 0..self.tracks.len() {
            let mut predicted = self.tracks[n].pose * delta;
            let c = predicted.translation.vector;
            cfg.grid_starts(steps.iter().copied(), &predicted, &mut starts);
            self.localizer.search_around(scan, seg, &starts, (cfg.refined, f64::INFINITY), &mut self.scored);
            let edge = f64::from(shifts) * cfg.position_step;
            let mut relooked = n == 0 && window_short && self.look_again(scan, seg, &steps, (c, edge), &mut starts);
            if n == 0 {
                let track = &self.tracks[0];
                let (before, earlier) = (track.cost.value, track.shadow.map(|p| p * delta));
                let pending = earlier.is_some();
                let near = self.look_near(scan, seg, (&predicted, gate, gate_heading), before, pending);
                cascade = near.map(|(found, _)| found);
                let near = near.and_then(|(_, cheaper)| cheaper);
                let along = if cfg.along_look_margin >= 0.0 {
                    self.look_along(scan, seg, gate, (before, window_short, pending), &mut starts)
                } else {
                    None
                };
                let along = along.map(|(pose, cost)| (pose, cost, false));
                let elsewhere = match (near, along) {
                    (Some(a), Some(b)) => {
                        let cheaper = if b.1.value < a.1.value { b } else { a };
                        // both looks refined to one pose: the near look's word that no rival
                        // lies within the gate holds for it
                        let one = a.2 && one_pose(&a.0, &b.0);
                        Some((cheaper.0, cheaper.1, cheaper.2 || one))
                    }
                    (a, b) => a.or(b),
                };
                if let Some((pose, cost, sure)) = elsewhere {
                    // the last scan's look found it too, about where odometry moved it since
                    // (within the gate's floor and one spread: the whole gate spans corridor
                    // twins, 2.2 m apart on csail): two scans agree on it, where one alone may
                    // see an imperfect map's flaw
                    let agrees =
                        earlier.is_some_and(|p| same_pose(&p, &pose, cfg.gate_position + spread, gate_heading));
                    let first = self.scored[0].0;
                    let moved = !same_pose(&pose, &first, cfg.second_look_jump, cfg.second_look_turn);
                    // far cheaper than the window's: the window's pose was far off
                    let lead = cost.value < self.scored[0].1.value - cfg.near_look_lead;
                    // on an exact plan, a window's pose that sees through the walls (a local
                    // minimum after a sharp turn, half a metre off) is no pose to hold against a
                    // cheaper one that does not
                    let sees_through = self.localizer.sees_through_exact_walls(&self.scored[0].1)
                        && !self.localizer.sees_through_exact_walls(&cost);
                    if agrees || !moved || sure || lead || sees_through {
                        self.scored.clear();
                        self.scored.push((pose, cost));
                        relooked |= moved;
                        // two scans agree on a pose odometry's prediction no longer reaches
                        // (the track slipped on the last): it is held from where the last
                        // scan's look put the robot
                        if let Some(p) = earlier.filter(|_| agrees && !same_pose(&pose, &predicted, gate, gate_heading))
                        {
                            predicted = p;
                        }
                    } else if cost.value < self.scored[0].1.value - cfg.along_look_margin {
                        shadow = Some(pose);
                        let near = (pose.translation.vector - predicted.translation.vector).norm()
                            <= cfg.look_answer_sigmas * spread;
                        if near && cost.value < self.scored[0].1.value - cfg.look_answer_lead {
                            look_answer = Some((pose, cost));
                        }
                    }
                }
            }
            let fallback = (predicted, Cost { value: f64::INFINITY, inliers: 0.0, through: 1.0, beams: 0 });
            found.push((predicted, self.scored.first().copied().unwrap_or(fallback), relooked));
        }
        self.window.give_back(steps);
        let min_inliers = self.config.min_inliers_held;
        for (track, &(predicted, (refined, cost), relooked)) in self.tracks.iter_mut().zip(&found) {
            track.relooked = false;
            track.shadow = None;
            track.look_answer = None;
            let held = same_pose(&refined, &predicted, gate, gate_heading)
                && cost.value.is_finite()
                && cost.inliers >= min_inliers;
            if held {
                let mut pose = refined;
                if spread < cfg.position_step {
                    let (constraint, along) = self.localizer.weakest_direction(&refined);
                    pose = fuse_along(&refined, &predicted, constraint / cfg.along_sigma.powi(2), along, spread);
                }
                (track.pose, track.cost) = (pose, cost);
                track.scans += 1;
                track.misses = 0;
                track.relooked = relooked;
            } else {
                // where odometry says it went: the global search may still find it there
                track.pose = predicted;
                track.cost.value = f64::INFINITY;
                track.misses += 1;
            }
        }
        if let Some(best) = self.tracks.first_mut() {
            best.look_answer = look_answer;
            best.shadow = shadow.filter(|_| best.misses == 0);
        }
        // the best track (the first: the tracks are sorted by lag) lost by its search: look
        // for it within the odometry's spread with the cascade, before taking it for lost
        let Some((best, &(predicted, _, _))) = self.tracks.first_mut().zip(found.first()) else {
            return false;
        };
        if best.misses > 0 {
            let found = cascade
                .unwrap_or_else(|| cascade_near(&mut self.localizer, scan, seg, &predicted, (gate, gate_heading)));
            // only a pose with no rival within the spread: a twin there is no track
            if let Some((pose, cost, _)) = found.filter(|&(_, cost, sure)| sure && cost.inliers >= min_inliers) {
                (best.pose, best.cost) = (pose, cost);
                best.scans += 1;
                best.misses = 0;
            }
        }
        self.gate = (gate, gate_heading);
        best.misses > 0
    }

    /// The second look for the best track ([`SequentialConfig::second_look_sides`]): when its
    /// search's best pose (in `self.scored`) refined to `edge` or further from the window's
    /// `centre`, the screen and refinement run again about that pose. With odometry off by
    /// more than the window spans, the first look's starts all lie short of the truth and
    /// refinement stops in a local minimum on the way (0.4-0.8 m off on the CARMEN logs with
    /// drawn odometry); about where it stopped, a start lies near the truth. The better of the
    /// two looks is kept in `self.scored`. Returns whether the second look won and moved the
    /// pose further than `second_look_jump` or `second_look_turn`.
    fn look_again(
        &mut self,
        scan: &ScanView<'_>,
        seg: &Segmentation,
        steps: &[(i32, i32, i32)],
        (centre, edge): (nalgebra::Vector2<f64>, f64),
        starts: &mut Vec<Pose>,
    ) -> bool {
        let cfg = self.config;
        let Some(&(first, first_cost)) = self.scored.first() else { return false };
        if (first.translation.vector - centre).norm() < edge.max(cfg.position_step) {
            return false;
        }
        let near = cfg.second_look_sides;
        let steps = steps.iter().copied().filter(|(k, i, j)| k.abs() <= near && i.abs() <= near && j.abs() <= near);
        cfg.grid_starts(steps, &first, starts);
        // only a pose cheaper than the first look's is wanted
        self.localizer.search_around(scan, seg, starts, (1, first_cost.value), &mut self.relook);
        let Some(&(second, second_cost)) = self.relook.first() else { return false };
        if second_cost.value >= first_cost.value {
            return false;
        }
        std::mem::swap(&mut self.scored, &mut self.relook);
        !same_pose(&second, &first, cfg.second_look_jump, cfg.second_look_turn)
    }

    /// The near look for the best track ([`SequentialConfig::near_look_jump`]), after its
    /// window (and second look) left the best pose in `self.scored`: the single-scan cascade
    /// kept to the gate about the `predicted` pose. `before` is what the track cost on its last
    /// scan, `pending` whether the last scan's looks left a shadow to weigh again (then it
    /// looks whatever the jump).
    ///
    /// The window screens its starts by the distance field, which unmapped things fool: in a
    /// furnished warehouse a pose 47 degrees off, where people's legs and shelves line up with
    /// other shelves, screened best after the robot spun, and the right pose's start was not
    /// among those refined (eq. 7: 3.46 per beam against the truth's 0.60). Corner matching
    /// does not go by the screen, and costs a track only when its window's pose explains the
    /// scan much worse than the track explained its last, or, on an exact plan, sees through
    /// its walls ([`Localizer::sees_through_exact_walls`]: the single scan's escalation).
    ///
    /// Returns, when it looked, what the cascade found ([`cascade_near`]), and that pose again
    /// when it costs less than the window's; `self.scored` is left as it was.
    fn look_near(
        &mut self,
        scan: &ScanView<'_>,
        seg: &Segmentation,
        (predicted, gate, gate_heading): (&Pose, f64, f64),
        before: f64,
        pending: bool,
    ) -> Option<(Found, Found)> {
        let cfg = self.config;
        let &(_, first_cost) = self.scored.first()?;
        if cfg.near_look_jump < 0.0
            || (first_cost.value <= before + cfg.near_look_jump
                && !pending
                && !self.localizer.sees_through_exact_walls(&first_cost))
        {
            return None;
        }
        let found = cascade_near(&mut self.localizer, scan, seg, predicted, (gate, gate_heading));
        Some((found, found.filter(|(_, cost, _)| cost.value < first_cost.value)))
    }

    /// The look along for the best track ([`SequentialConfig::along_look_margin`]), after its
    /// window (and second look) left the best pose in `self.scored`. `before` is what the track
    /// cost on its last scan, `window_short` whether the window could not span the spread, and
    /// `pending` whether the last scan's look left a shadow to weigh again (then it looks
    /// whatever the triggers say).
    ///
    /// In a corridor a window's starts all lie on the flat of eq. 7 along it when odometry's
    /// drive is off by more than the window spans: refinement has no slope to follow, so the
    /// pose stays where odometry put it, short of or past the truth (0.6-3.8 m off after a few
    /// scans on aces with drawn odometry, the truth costing 0.5-1.5 per beam less), until the
    /// track is lost. The scan often sees where along the corridor it is (a door, a corner, its
    /// end) further off than the window reaches; starts along the weakest direction across the
    /// whole gate find it. A pose that explains this scan much worse than the track did its
    /// last one was likely left behind the same way, window short or not.
    ///
    /// Returns the pose found and its cost when it costs `along_look_margin` less than the
    /// window's; `self.scored` is left as it was.
    fn look_along(
        &mut self,
        scan: &ScanView<'_>,
        seg: &Segmentation,
        gate: f64,
        (before, window_short, pending): (f64, bool, bool),
        starts: &mut Vec<Pose>,
    ) -> Option<(Pose, Cost)> {
        let cfg = self.config;
        let &(first, first_cost) = self.scored.first()?;
        // explaining the scan about as well as the last, and either the window spanned the
        // spread or the pose is pinned down in every direction: the window's pose stands,
        // unless the last scan's look found another to weigh again
        let jumped = first_cost.value > before + cfg.along_look_jump;
        if !window_short && !jumped && !pending {
            return None;
        }
        let (constraint, along) = self.localizer.weakest_direction(&first);
        if constraint >= cfg.min_constraint && !jumped && !pending {
            return None;
        }
        let sides = ((gate / cfg.position_step).ceil() as i32).min(cfg.along_look_most);
        let (t, heading) = (first.translation.vector, pose_theta(&first));
        starts.clear();
        // within a step of the pose, refinement already looked
        for i in (-sides..=sides).filter(|i| i.abs() > 1) {
            for k in -1..=1 {
                starts.push(nalgebra::Isometry2::new(
                    t + along * (f64::from(i) * cfg.position_step),
                    heading + f64::from(k) * cfg.start_step,
                ));
            }
        }
        let wanted = first_cost.value - cfg.along_look_margin;
        self.localizer.search_around(scan, seg, starts, (1, wanted), &mut self.relook);
        let &(second, second_cost) = self.relook.first()?;
        (second_cost.value < wanted).then_some((second, second_cost))
    }

    /// The global search; its hypotheses join the tracks. Returns the single-scan status, best
    /// pose, and how much more per beam its nearest distinct rival costs (infinite with none).
    fn search(&mut self, scan: &ScanView<'_>, seg: &Segmentation) -> Option<(Status, Pose, f64)> {
        let (position, heading) = (self.localizer.config.distinct_position, self.localizer.config.distinct_heading);
        let min_inliers = self.localizer.config.min_inliers;
        let loc = self.localizer.locate_set_lines(scan, seg);
        if loc.status == Status::Failed {
            return None;
        }
        let single = loc.hypotheses.first().map(|b| (loc.status, b.pose, loc.rival_gap(position, heading)));
        let had_tracks = self.tracks.iter().any(|t| t.scans > 0);
        let hyps: Vec<_> = loc.hypotheses.iter().filter(|h| h.cost.inliers >= min_inliers).copied().collect();
        for h in hyps {
            let gate = self.gate;
            let lands_on = |t: &Track| {
                if t.misses > 0 {
                    // a missed track is where odometry put it, give or take the motion's spread
                    same_pose(&t.pose, &h.pose, gate.0.max(position), gate.1.max(heading))
                } else {
                    same_pose(&t.pose, &h.pose, position, heading)
                }
            };
            match self.tracks.iter_mut().find(|t| lands_on(t)) {
                Some(t) => {
                    // a global pose on a track: the better of the two, and a missed track found
                    if h.cost.value < t.cost.value {
                        if t.misses > 0 {
                            t.scans += 1;
                            t.misses = 0;
                        }
                        (t.pose, t.cost) = (h.pose, h.cost);
                        t.relooked = false;
                    }
                }
                None => {
                    self.next_id += 1;
                    self.tracks.push(Track {
                        pose: h.pose,
                        cost: h.cost,
                        // lagging until the lags are settled: it missed every scan the others saw
                        behind: if had_tracks { f64::NAN } else { 0.0 },
                        scans: 1,
                        misses: 0,
                        late: had_tracks,
                        relooked: false,
                        shadow: None,
                        look_answer: None,
                        id: self.next_id,
                    });
                }
            }
        }
        single
    }

    /// Adds this scan's costs to the tracks' lags, starts the new tracks behind the best,
    /// drops the tracks too far behind or lost, and keeps the best `max_tracks`.
    fn settle_lags(&mut self) {
        let cfg = self.config;
        let best_cost =
            self.tracks.iter().filter(|t| t.misses == 0).map(|t| t.cost.value).fold(f64::INFINITY, f64::min);
        for t in self.tracks.iter_mut().filter(|t| !t.behind.is_nan()) {
            t.behind += if t.misses > 0 { cfg.miss } else { t.cost.value - best_cost };
        }
        let leader = self.tracks.iter().filter(|t| !t.behind.is_nan()).map(|t| t.behind).fold(f64::INFINITY, f64::min);
        let leader = if leader.is_finite() { leader } else { 0.0 };
        for t in self.tracks.iter_mut().filter(|t| t.behind.is_nan()) {
            t.behind = leader + cfg.birth + (t.cost.value - best_cost);
        }
        let lowest = self.tracks.iter().map(|t| t.behind).fold(f64::INFINITY, f64::min);
        for t in self.tracks.iter_mut() {
            t.behind -= lowest;
        }
        self.tracks.retain(|t| t.behind <= cfg.drop && t.misses < cfg.lost_after);
        self.tracks.sort_by(|a, b| a.behind.total_cmp(&b.behind));
        // tracks that converged to one pose are one: the one ahead stays
        let mut kept = 0;
        for k in 0..self.tracks.len() {
            let t = self.tracks[k];
            match self.tracks[..kept].iter().find(|q| one_pose(&q.pose, &t.pose)) {
                // one pose: the last `ok` was on it, whichever track stays
                Some(q) if self.last_ok == Some(t.id) => self.last_ok = Some(q.id),
                Some(_) => {}
                None => {
                    self.tracks[kept] = t;
                    kept += 1;
                }
            }
        }
        self.tracks.truncate(kept.min(cfg.max_tracks));
    }

    /// Whether the best track is sure and old enough to stop the global search.
    fn settled(&self) -> bool {
        self.tracks.first().is_some_and(|t| t.scans >= self.config.settle_scans) && self.lead() >= self.config.margin
    }

    /// How far the best track is ahead of its nearest distinct rival (infinite with none).
    fn lead(&self) -> f64 {
        let Some(best) = self.tracks.first() else { return 0.0 };
        let (position, heading) = (self.localizer.config.distinct_position, self.localizer.config.distinct_heading);
        self.tracks[1..]
            .iter()
            .filter(|t| !same_pose(&t.pose, &best.pose, position, heading))
            .map(|t| t.behind - best.behind)
            .fold(f64::INFINITY, f64::min)
    }

    /// The scan's answer. A best track seen on this scan alone is `ok` only as the single-scan
    /// search judged it, or with no rival within [`SequentialConfig::lone_gap`]; an older one
    /// when it leads by the margin and explains the scan. Either must pin the position down,
    /// withstand the probes, and not have been moved far by this scan's second look.
    ///
    /// When the best track is not `ok` on those terms, or missed the scan, the held track at the
    /// pose the scan's own search was `ok` on is the answer ([`Self::answer_single_ok`]): `ok`
    /// when it passes the same bar ([`Self::meets_ok_bar`]), though it is younger than its
    /// rivals (a twin the robot drove along, or the old place of a kidnapped robot, kept the
    /// lead while the scan now tells them apart). Else an answer that is not `ok` is
    /// `ambiguous`: at the held track the scan's own search was `ok` on when the best missed
    /// the scan, else at the track the last `ok` was on ([`Self::on_the_last_ok`]), else at the
    /// best (where odometry put it, when it missed).
    fn answer(&mut self, scan: &ScanView<'_>, single: Option<(Status, Pose, f64)>) -> SequentialAnswer {
        let mut a = SequentialAnswer {
            status: Status::Failed,
            pose: None,
            cost: None,
            scans: 0,
            global: false,
            tracks: self.tracks.len(),
            track: None,
        };
        let cfg = self.localizer.config;
        let Some(&best) = self.tracks.first().filter(|t| t.misses == 0) else {
            // the best track missed the scan (a kidnapped robot's old place, while its track
            // lives out its misses)
            let Some(first) = self.tracks.first() else { return a };
            (a.status, a.pose, a.scans, a.track) = (Status::Ambiguous, Some(first.pose), first.scans, Some(0));
            self.answer_single_ok(scan, single, &mut a);
            // no place the scan is sure of: the track the last `ok` was on, if it holds, before
            // where odometry put the best
            if a.cost.is_none() {
                self.on_the_last_ok(&mut a);
            }
            return a;
        };
        a.rest_on(0, &best);
        let leads = self.lead() >= self.config.margin;
        // a track that turned up while others were held has not been through their scans: it
        // must outlive them for a while; one of a cold start, as its own search judged it, or
        // with no rival near
        let vouched = if best.late {
            best.scans >= self.config.settle_scans
        } else {
            best.scans > 1
                || single.is_some_and(|(s, p, gap)| {
                    (s == Status::Ok || s == Status::Ambiguous && gap >= self.config.lone_gap)
                        && same_pose(&p, &best.pose, cfg.distinct_position, cfg.distinct_heading)
                })
        };
        let sure = leads && vouched && !best.relooked && self.meets_ok_bar(scan, &best);
        a.status = if sure { Status::Ok } else { Status::Ambiguous };
        if let Some((pose, cost)) = best.look_answer.filter(|_| !sure) {
            (a.pose, a.cost) = (Some(pose), Some(cost));
        }
        if !sure {
            self.on_the_last_ok(&mut a);
            self.answer_single_ok(scan, single, &mut a);
        }
        a
    }

    /// Makes an `ambiguous` answer the track the last `ok` answer was on, while that track
    /// holds on the scan and no track leads it by the margin
    /// ([`SequentialConfig::keep_to_the_last_ok`]).
    fn on_the_last_ok(&self, a: &mut SequentialAnswer) {
        if !self.config.keep_to_the_last_ok || a.status != Status::Ambiguous {
            return;
        }
        let margin = self.config.margin;
        let held = self
            .last_ok
            .and_then(|id| self.tracks.iter().position(|t| t.id == id && t.misses == 0 && t.behind < margin));
        if let Some(k) = held.filter(|&k| a.track != Some(k)) {
            a.rest_on(k, &self.tracks[k]);
        }
    }

    /// Remembers which track the scan's answer is on when it is `ok`; forgets it on a `failed`
    /// one, or once that track is gone.
    fn remember_the_last_ok(&mut self, a: &SequentialAnswer) {
        self.last_ok = match a.status {
            Status::Ok => a.track.and_then(|k| self.tracks.get(k)).map(|t| t.id),
            Status::Ambiguous => self.last_ok.filter(|&id| self.tracks.iter().any(|t| t.id == id)),
            Status::Failed => None,
        };
    }

    /// Whether `track` passes what every `ok` must of the scan: the beams agreeing, on a drawn
    /// map few beams through its walls, a place the robot can be, the position's constraint
    /// across the direction the scan pins down least, and the probes along it (the last two
    /// cost most, so they run last).
    fn meets_ok_bar(&mut self, scan: &ScanView<'_>, track: &Track) -> bool {
        if track.cost.inliers < self.config.min_inliers_ok
            || self.localizer.sees_through_drawn_walls(&track.cost)
            || self.localizer.off_limits(&track.pose)
        {
            return false;
        }
        let (constraint, along) = self.localizer.weakest_direction(&track.pose);
        constraint >= self.config.min_constraint
            && self.localizer.withstands_probes(scan, &track.pose, along, &self.config.probes)
    }

    /// Makes `a` the held track at the pose this scan's single-scan search was `ok` on, if there
    /// is one: `ok` when it [`meets_ok_bar`](Self::meets_ok_bar), else still `ambiguous`, and
    /// at that pose only when the best track missed the scan.
    fn answer_single_ok(&mut self, scan: &ScanView<'_>, single: Option<(Status, Pose, f64)>, a: &mut SequentialAnswer) {
        let Some((Status::Ok, p, _)) = single else { return };
        let cfg = self.localizer.config;
        let Some(k) = self
            .tracks
            .iter()
            .position(|t| t.misses == 0 && same_pose(&t.pose, &p, cfg.distinct_position, cfg.distinct_heading))
        else {
            return;
        };
        let t = self.tracks[k];
        if self.meets_ok_bar(scan, &t) {
            a.rest_on(k, &t);
            a.status = Status::Ok;
        } else if a.cost.is_none() {
            // the best track missed: the place the scan is sure of, rather than where odometry
            // put the best
            a.rest_on(k, &t);
        }
    }
}

/// Whether two refined poses are one: within 5 cm and 1 degree, where refinement from
/// different starts ends on the same minimum (tracks that converged, two looks that agree).
fn one_pose(a: &Pose, b: &Pose) -> bool {
    same_pose(a, b, 0.05, 1f64.to_radians())
}

/// What [`cascade_near`] found: a pose, its cost, and whether the cascade was sure of it.
type Found = Option<(Pose, Cost, bool)>;

/// The single-scan cascade kept to `gate` about the `predicted` pose: its best pose within
/// `gate_heading` of the prediction, with its cost and whether the cascade was sure of it (`ok`
/// within the gate, and that pose its best: no distinct rival near it).
fn cascade_near(
    localizer: &mut Localizer,
    scan: &ScanView<'_>,
    seg: &Segmentation,
    predicted: &Pose,
    (gate, gate_heading): (f64, f64),
) -> Found {
    let centre = nalgebra::Point2::from(predicted.translation.vector);
    let heading = pose_theta(predicted);
    let loc = localizer.locate_near(scan, seg, centre, gate);
    let ok = loc.status == Status::Ok;
    loc.hypotheses
        .iter()
        .enumerate()
        .find(|(_, h)| angle_diff(pose_theta(&h.pose), heading).abs() <= gate_heading)
        .map(|(k, h)| (h.pose, h.cost, ok && k == 0))
}

/// `refined` moved towards `predicted` along the unit direction `along` by their information
/// there: the scan's `information` (1 / metres squared) against odometry's `1 / spread^2`. The
/// pose across `along`, and its heading, stay refinement's: the scan pins those down. With no
/// information the pose along is odometry's; with much more than odometry's, refinement's.
/// The cost is left as refinement's: along the weakest direction eq. 7 hardly changes.
pub fn fuse_along(
    refined: &Pose,
    predicted: &Pose,
    information: f64,
    along: nalgebra::Vector2<f64>,
    spread: f64,
) -> Pose {
    let odometry = 1.0 / (spread * spread).max(1e-12);
    let scan = information.max(0.0);
    let w = scan / (scan + odometry);
    let offset = (predicted.translation.vector - refined.translation.vector).dot(&along);
    let mut pose = *refined;
    pose.translation.vector += along * ((1.0 - w) * offset);
    pose
}

#[cfg(test)]
mod tests {
    use super::*;
    use laser::pose;
    use proptest::prelude::*;

    proptest! {
        /// The fused pose lies between refinement's and odometry's along the direction, keeps
        /// refinement's across it and its heading, and goes to either end as the information
        /// does.
        #[test]
        fn fusing_moves_only_along_and_between(
            (rx, ry, rt) in (-20.0..20.0f64, -20.0..20.0f64, -3.0..3.0f64),
            (px, py, pt) in (-20.0..20.0f64, -20.0..20.0f64, -3.0..3.0f64),
            a in -3.2..3.2f64,
            information in 0.0..1e4f64,
            spread in 0.01..1.0f64,
        ) {
            let (refined, predicted) = (pose(rx, ry, rt), pose(px, py, pt));
            let along = nalgebra::Vector2::new(a.cos(), a.sin());
            let across = nalgebra::Vector2::new(-along.y, along.x);
            let fused = fuse_along(&refined, &predicted, information, along, spread);
            let (f, r, p) = (fused.translation.vector, refined.translation.vector, predicted.translation.vector);
            prop_assert!((f - r).dot(&across).abs() < 1e-9);
            prop_assert!(angle_diff(pose_theta(&fused), rt).abs() < 1e-12);
            let (t_f, t_r, t_p) = (f.dot(&along), r.dot(&along), p.dot(&along));
            prop_assert!(t_f >= t_r.min(t_p) - 1e-9 && t_f <= t_r.max(t_p) + 1e-9);
            let none = fuse_along(&refined, &predicted, 0.0, along, spread).translation.vector;
            prop_assert!((none.dot(&along) - t_p).abs() < 1e-9);
            let much = fuse_along(&refined, &predicted, 1e12, along, spread).translation.vector;
            prop_assert!((much.dot(&along) - t_r).abs() < 1e-3 * (t_p - t_r).abs().max(1e-9));
        }
    }

    /// A window kept from scan to scan holds the steps one made anew would: every (k, i, j)
    /// within its sides once, nearest first; and one taken and not given back is made again.
    #[test]
    fn a_kept_window_is_the_window_its_sides_make() {
        let fresh = |turns: i32, shifts: i32| {
            let mut steps: Vec<_> = (-turns..=turns)
                .flat_map(|k| (-shifts..=shifts).flat_map(move |i| (-shifts..=shifts).map(move |j| (k, i, j))))
                .collect();
            steps.sort_by_key(|&(k, i, j)| k * k + i * i + j * j);
            steps
        };
        let mut window = Window::default();
        for (turns, shifts) in [(2, 1), (2, 1), (0, 3), (2, 1), (6, 2)] {
            let steps = window.take(turns, shifts);
            assert_eq!(steps, fresh(turns, shifts), "{turns} {shifts}");
            assert_eq!(steps.len() as i32, (2 * turns + 1) * (2 * shifts + 1).pow(2));
            assert_eq!(steps[0], (0, 0, 0), "the prediction first");
            window.give_back(steps);
        }
        let _lost = window.take(1, 1);
        assert_eq!(window.take(1, 1), fresh(1, 1));
    }

    /// Equal information either side: halfway.
    #[test]
    fn equal_information_meets_halfway() {
        let (refined, predicted) = (pose(1.0, 0.0, 0.3), pose(0.0, 0.5, 0.1));
        let fused = fuse_along(&refined, &predicted, 1.0 / 0.04, nalgebra::Vector2::new(1.0, 0.0), 0.2);
        assert!((fused.translation.vector - nalgebra::Vector2::new(0.5, 0.0)).norm() < 1e-12, "{fused:?}");
    }

    /// A sequential localizer in an empty 8 x 4 m room.
    fn in_a_room() -> Sequential {
        let room = [(0.0, 0.0, 8.0, 0.0), (8.0, 0.0, 8.0, 4.0), (8.0, 4.0, 0.0, 4.0), (0.0, 4.0, 0.0, 0.0)];
        let walls = room.iter().map(|&(ax, ay, bx, by)| map::Wall::new(ax, ay, bx, by)).collect();
        let model = crate::model::MapModel::new(map::WallMap::new(walls), &map::MapCornerConfig::default());
        let localizer = Localizer::new(std::sync::Arc::new(model), crate::LocalizerConfig::default());
        Sequential::new(localizer, SequentialConfig::default())
    }

    fn cost(value: f64) -> Cost {
        Cost { value, inliers: 0.9, through: 0.0, beams: 100 }
    }

    /// A held track of 5 scans at (x, 2) facing along x, level with the best.
    fn track(x: f64, id: u64) -> Track {
        Track {
            pose: pose(x, 2.0, 0.0),
            cost: cost(1.0),
            behind: 0.0,
            scans: 5,
            misses: 0,
            late: false,
            relooked: false,
            shadow: None,
            look_answer: None,
            id,
        }
    }

    /// A look's pose answers for the track it was found about while that track is the best,
    /// and never for another track that the scan's global search put first.
    #[test]
    fn a_looks_answer_stays_with_its_track() {
        let mut sequential = in_a_room();
        let look = (pose(5.5, 2.0, 0.0), cost(0.2));
        // level, so neither leads and the answer is `ambiguous` without reading the scan
        let (found_for, other) = (Track { look_answer: Some(look), ..track(5.0, 1) }, track(2.0, 2));
        let ranges = [1.0f32; 8];
        let geometry = laser::ScanGeometry::urg04lx_decimated(96);
        let scan = ScanView { geometry, ranges: &ranges };
        sequential.tracks = vec![other, found_for];
        let a = sequential.answer(&scan, None);
        assert_eq!((a.status, a.pose, a.track), (Status::Ambiguous, Some(other.pose), Some(0)));
        sequential.tracks = vec![found_for, other];
        let a = sequential.answer(&scan, None);
        assert_eq!((a.status, a.pose, a.cost), (Status::Ambiguous, Some(look.0), Some(look.1)));
    }

    /// An `ambiguous` answer stays on the track the last `ok` was on while it holds and no
    /// track leads it by the margin; a `failed` answer or a cold start forgets it.
    #[test]
    fn an_ambiguous_answer_stays_on_the_track_last_ok() {
        let mut sequential = in_a_room();
        let (twin, last_ok) = (track(2.0, 1), track(5.0, 2));
        let ambiguous_on = |track: usize, pose| SequentialAnswer {
            status: Status::Ambiguous,
            pose: Some(pose),
            cost: Some(cost(1.0)),
            scans: 5,
            global: false,
            tracks: 2,
            track: Some(track),
        };
        let ok_on = |track| SequentialAnswer { status: Status::Ok, ..ambiguous_on(track, last_ok.pose) };
        let answer = |sequential: &mut Sequential, mut a: SequentialAnswer| {
            sequential.on_the_last_ok(&mut a);
            sequential.remember_the_last_ok(&a);
            (a.pose, a.track)
        };
        sequential.tracks = vec![last_ok, twin];
        answer(&mut sequential, ok_on(0));
        // the twin is ahead by less than the margin: the answer stays
        sequential.tracks = vec![Track { behind: 0.0, ..twin }, Track { behind: 0.2, ..last_ok }];
        assert_eq!(answer(&mut sequential, ambiguous_on(0, twin.pose)), (Some(last_ok.pose), Some(1)));
        // it missed the scan: the best
        sequential.tracks = vec![twin, Track { misses: 1, ..last_ok }];
        assert_eq!(answer(&mut sequential, ambiguous_on(0, twin.pose)), (Some(twin.pose), Some(0)));
        // held again, but the twin leads it by the margin: the best
        sequential.tracks = vec![twin, Track { behind: 0.3, ..last_ok }];
        assert_eq!(answer(&mut sequential, ambiguous_on(0, twin.pose)), (Some(twin.pose), Some(0)));
        // behind by less again: the answer is back on it
        sequential.tracks = vec![twin, Track { behind: 0.1, ..last_ok }];
        assert_eq!(answer(&mut sequential, ambiguous_on(0, twin.pose)), (Some(last_ok.pose), Some(1)));
        // merged into the track ahead at its pose: the last `ok` is that one
        sequential.tracks = vec![twin, Track { pose: twin.pose, behind: 0.1, ..last_ok }];
        sequential.settle_lags();
        assert_eq!((sequential.tracks.len(), sequential.last_ok), (1, Some(twin.id)));
        sequential.tracks = vec![Track { pose: last_ok.pose, ..twin }, Track { pose: twin.pose, id: 3, ..twin }];
        assert_eq!(answer(&mut sequential, ambiguous_on(1, twin.pose)), (Some(last_ok.pose), Some(0)));
        // a `failed` answer forgets it
        let mut failed = ambiguous_on(0, twin.pose);
        failed.status = Status::Failed;
        answer(&mut sequential, failed);
        assert_eq!(answer(&mut sequential, ambiguous_on(0, twin.pose)), (Some(twin.pose), Some(0)));
        // as does a cold start
        answer(&mut sequential, ok_on(1));
        sequential.reset();
        sequential.tracks = vec![twin, last_ok];
        assert_eq!(answer(&mut sequential, ambiguous_on(0, twin.pose)), (Some(twin.pose), Some(0)));
    }
}
