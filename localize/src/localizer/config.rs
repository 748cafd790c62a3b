//! What the localization stage is told: how many corners, candidates and beams each step
//! takes, the cost function's form, and when an answer is `ok` ([`LocalizerConfig`]), and the
//! cheaper [`FirstLook`] that runs before the full search.

use super::{Hypothesis, Status};
use crate::cost::CostConfig;
use crate::grid::GridConfig;
use crate::refine::RefineConfig;
use crate::slide::SlideConfig;
use segment::ErrorModel;

/// The localization stage's parameters; [`LocalizerConfig::set`] sets them by name.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LocalizerConfig {
    /// How many of the best scan corners (eq. 4 order) are matched. Corners of a kind the map
    /// has none of (within the angle tolerance) are passed over and do not count: a wall end,
    /// where the map lists none, as a map built from scans does not.
    pub corners_tried: usize,
    /// Inner angle tolerance of a match: three standard deviations of the scan corner's angle,
    /// clamped to [min, max] radians.
    pub min_angle_tolerance: f64,
    pub max_angle_tolerance: f64,
    /// Slack of the arm fit test, metres.
    pub arm_slack: f64,
    /// Scan points used to screen hypotheses with the distance field: a first pass over every
    /// candidate uses one in `prescreen_step` of them and keeps the `prescreened` best. With
    /// furniture in view its few points often land on boxes, so the right pose can rank low
    /// here: keeping 512 instead of 256 took the furnished office log from 82.7 to 83.7 %, and
    /// 1024 instead of 512 won 28 scans over the 13 furnished simulated logs (3900 scans) and
    /// 29 over all 42 (12600). Reading 20 points instead (a step of 2) won as many, but took
    /// the matching on a 5000-wall map from 1.1 to 1.5-1.7 ms a scan, where keeping more did
    /// not move it: the same instructions, but each pose's extra points are distance-field
    /// lookups that miss the cache once the field outgrows it.
    pub screen_points: usize,
    pub prescreen_step: usize,
    pub prescreened: usize,
    /// Distance from the walls beyond which a screened point counts as unexplained (metres, at
    /// most the field's cap). The screen is two-sided, so a point on a box half a metre in front
    /// of a wall must cost no more than one that misses by a little more than an unrefined
    /// pose's error: with a 0.5 m cap, furnished scans lost their right pose here 38 times in
    /// 300, with 0.12 m 19 times.
    pub screen_cap: f64,
    /// A screened point beyond the cap from every wall, outside the main free space while its
    /// sensor is in it (inside a closed rack or pillar, around a closed outline:
    /// [`crate::MapModel::open_floor`]), costs this many times the cap squared: its beam went
    /// through a wall, which the distance alone cannot tell from a box in front of one.
    pub screen_behind: f64,
    /// A screened point on a scan line at least `screen_long_line` metres long that stands in
    /// open floor, beyond the cost's furniture reach from every wall
    /// ([`CostConfig::clutter_share`]), costs up to this many times the cap squared: a long
    /// straight surface out in the open is a wall the pose misplaces, more often than furniture.
    /// Points off long lines keep the cap: people and chairs do stand in the open (applied to
    /// every point, the furnished warehouse gained 7 points and the warehouse with people lost
    /// 10).
    pub screen_open: f64,
    pub screen_long_line: f64,
    /// Hypotheses kept by the screen, and costed coarsely.
    pub screened: usize,
    /// On a map that declares itself approximate ([`map::WallMap::is_approximate`], as maps
    /// built from scans do), the most hypotheses any search of the cascade keeps for the coarse
    /// cost: at most this many of [`screened`](Self::screened) and the slides'
    /// [`SlideConfig::screened`] and [`SlideConfig::loose_screened`]. The screen reads a built
    /// map's walls to within their spread, so the hypotheses it ranks past the first few
    /// hundred are seldom the truth, and the coarse cost of 1024 slid poses is most of a real
    /// scan's time. On the seven CARMEN logs both ways, 256 instead of 1024 / 512 / 384 took
    /// the mean of the medians 25-29 % lower (two pairs of runs side by side) for 4 successes
    /// fewer of 9071 (8052 to 8048), `ok` 3846 to 3838 and wrong `ok` 8 to 6; 128 took it 36 %
    /// lower for 14 fewer. On drawn maps the same cut had added wrong `ok` answers on the
    /// simulated suite, so they keep the budgets. 0 sets no cap.
    pub screened_approximate: usize,
    /// Beams of the coarse cost, and its noise floor (metres).
    pub coarse_beams: usize,
    pub coarse_sigma: f64,
    /// When more than `sparse_kept` hypotheses pass the screen, a coarse cost over only
    /// `sparse_beams` beams keeps the `sparse_kept` best first. The ray-cast cost tells an object
    /// in front of a wall from a beam through one, which the distance-field screen cannot, so
    /// handing it more candidates rescues furnished scans whose right pose screens poorly: with
    /// 384 screened (was 128) and 32 beams, the furnished office log went from 83.7 to 85.7 %
    /// and no clean or people log lost a scan, for about 1.4 times the instructions per
    /// furnished scan.
    pub sparse_beams: usize,
    pub sparse_kept: usize,
    /// Hypotheses kept by the coarse cost, refined and costed in full.
    pub refined: usize,
    /// Scan points used by refinement.
    pub refine_points: usize,
    /// When a hypothesis distinct from the best costs less than `polish_margin` more (per beam, as
    /// [`ambiguity_margin`](Self::ambiguity_margin)), every hypothesis that close is refined again
    /// over `polish_points` scan points, `polish_iterations` steps from the final gate, and keeps
    /// the pose that costs less. Refined over 160 points, the true pose of a clean simulated scan
    /// costs a median 0.01-0.02 more than the truth, and 0.05 more in 7-15 % of scans: enough to
    /// rank near-equal poses wrongly or call the right one `ambiguous`. Over the 39 simulated logs
    /// this took successes from 10913 to 10924, `ok` from 9247 to 9266 and wrong `ok` from 70 to 67
    /// (aces: ok precision 91.0 to 92.1 %), for 8 % more instructions on the clean office log (164
    /// hypotheses polished in its 300 scans). Polishing without a contest costs about 95 us a scan
    /// more for no more successes; 341 points gave fewer successes than none; 3 steps no more than
    /// 2. 0 points: no polish.
    pub polish_margin: f64,
    pub polish_points: usize,
    pub polish_iterations: usize,
    pub refine: RefineConfig,
    pub cost: CostConfig,
    /// The sensor's e(d), which sets the noise scale of the cost.
    pub error: ErrorModel,
    /// Two poses are distinct when their positions differ by more than this (metres) or their
    /// headings by more than `distinct_heading` (radians).
    pub distinct_position: f64,
    pub distinct_heading: f64,
    /// The best pose is `ambiguous` when a distinct hypothesis costs less than this much more.
    pub ambiguity_margin: f64,
    /// ...or, once the scan's last search is ranked, less than this share of the best's own
    /// cost more: a rival is told apart by a gap the size of the best pose's misfit, not only a
    /// fixed one. On a map built from a log the right pose's cost is noisy in proportion to
    /// how badly the map's walls fit the scan (per beam 1-4 where a drawn map gives 0.1-0.5),
    /// and twins in a repetitive building then win by more than the fixed margin: on the
    /// seven CARMEN logs' odd scans, 42 `ok` answers of 1825 in five logs were wrong, 33 of
    /// them by a gap under half the best cost, against 9 % of the right ones. Applied after
    /// the search, so it changes which answers are `ok`, never the search or its answer.
    pub ambiguity_ratio: f64,
    /// [`ambiguity_margin`](Self::ambiguity_margin) for a map that declares itself approximate
    /// ([`map::WallMap::is_approximate`], as maps built from scans do). A built map knows its
    /// walls only to their spread, and each rival's cost per beam carries that misfit too: a
    /// wrong pose can lead the right one by a third of a unit where the map is poorer at the
    /// right place. On the seven CARMEN logs both ways, 0.4 instead of 0.3 made 3 of the 10
    /// wrong `ok` answers `ambiguous` (infinite-corridor, 8-23 m off) against 32 of the 3761
    /// right ones, and no other answer changed. Drawn maps are exact: there the same 0.4 took
    /// 49 right `ok` answers of the simulated suite's 10169 and no wrong one.
    pub ambiguity_margin_approximate: f64,
    /// In a scan with no corner, a slid pose along the best one's wall explains the scan as
    /// well as the best when their costs, summed over the beams (squared standard deviations,
    /// twice the log-likelihood ratio), differ by less than this; the scan then does not say
    /// where along the wall the sensor is, and is `failed`. A corridor whose ends are out of
    /// range gives differences of 0.00 per beam. The ambiguity margin (0.3 per beam, 200 over a
    /// URG scan) made this rule fail scans whose cost rose by 0.04-0.2 per beam within half a
    /// metre along the wall, 6 of 300 clean warehouse scans, all of them right.
    pub cornerless_tie: f64,
    /// The best pose is `failed` when fewer of its beams than this fraction agree with the map...
    pub min_inliers: f64,
    /// ...or when more than this fraction see through mapped walls: at the true pose only
    /// noise, mixed pixels and map errors do, whatever the map lacks.
    pub max_through: f64,
    /// [`max_through`](Self::max_through) for a map that declares itself approximate
    /// ([`map::WallMap::is_approximate`], as maps built from scans do); 1 sets no limit,
    /// the default. Such a map's errors (doors drawn shut, things since moved, gaps between its
    /// walls) are what right poses see through: 21-38 % of the beams of 28 CARMEN scans whose
    /// best pose was failed at 20 %, 23 of them right. Seeing through walls still makes a pose
    /// `ambiguous` beyond `max_through_ok`, and too few agreeing beams still fail it. On the
    /// simulated logs, whose maps are exact, nothing changes.
    pub max_through_approximate: f64,
    /// [`CostConfig::front_cap`] for a map that declares itself approximate (as
    /// [`max_through_approximate`](Self::max_through_approximate)). The one-sided cost caps a
    /// reading short of the map low because a drawn plan lacks the furniture the sensor sees;
    /// a map built from scans keeps what stayed in the survey, so there a short reading at the
    /// right pose is rarer and says more against a wrong one. Twice the drawn map's cap (8
    /// against 4): CARMEN both ways 90.4 -> 92.6 % (`ok` 691 -> 718, wrong `ok` 4 -> 4); maps
    /// built from 200 simulated scans among people or boxes (apartment, office, warehouse;
    /// locating the other 200) 61.2 -> 62.8 %, wrong `ok` 99 -> 97 of 1104 -> 1141. Between 6
    /// and 10 the figures barely move; at 12, the through-wall cap, the furnished built
    /// apartment fell from 87 to 67 %. Drawn maps keep `cost.front_cap`.
    pub front_cap_approximate: f64,
    /// [`CostConfig::clutter_share`] for a map that declares itself approximate. 1 (off): a
    /// map built from scans already holds the furniture that stood still while it was built,
    /// so what reads short of it is mostly people and things moved, which stand anywhere; and
    /// its walls are drawn only to within its sigma. On the CARMEN logs both ways, a share of
    /// 0.5 took 1065 successes to 1058 (`ok` 715 -> 690, wrong `ok` 3 -> 4); judged by the
    /// nearest wall rather than along the beam it had taken 1068 to 1045, and 0.25 to 1009.
    pub clutter_share_approximate: f64,
    /// The best pose is at most `ambiguous` when more than this fraction of its beams see
    /// through mapped walls. A drawn map has no walls that are not there, so 5 % holds every
    /// right pose on the simulated logs; a map built from a log has walls of doors and things
    /// that have since moved, and right poses against the CARMEN maps see through 5-19 %: of
    /// the 154 scans there that a 5 % limit failed and this one does not, 84 were right (with
    /// the through-wall cost at 25, when this was measured). Such a pose is an answer, but not
    /// one to trust. On the simulated logs 18 scans moved, all wrong, all now `ambiguous`.
    pub max_through_ok: f64,
    /// On a map that declares itself approximate, the best pose is `ambiguous` unless the scan
    /// pins its position down along every direction by at least this many points' worth of
    /// wall normal among refinement's [`refine_points`](Self::refine_points) scan points
    /// ([`crate::refine::weakest_direction`]); 0 sets no floor. A built map knows
    /// its walls only to their spread, so a corridor pose held along its length by a door
    /// jamb's one or two points fits a twin a few doors on as well: on the seven CARMEN logs
    /// both ways, 4 of the 14 wrong `ok` answers (infinite-corridor, 1.7-139 m off) had under
    /// 2 points' worth, against 5 of the 3751 right ones. Drawn maps are exact, and there the
    /// same floor cost 100 right `ok` answers of the simulated suite's 10169 for 2 wrong ones.
    pub min_constraint_ok_approximate: f64,
    /// The probes an `ok` answer must withstand ([`Localizer::withstands_probes`](super::Localizer::withstands_probes)),
    /// as the sequential localizer's `ok` must: the pose moved along the direction the scan
    /// pins down least and turned, each costing clearly more. A pose half a metre down a
    /// furnished warehouse's aisle can cost least and have no distinct rival within its misfit,
    /// yet explain the scan about as well half a metre either way. On the simulated suite
    /// (`gema2 evaluate`, 48 logs) they made 8 of the 14 wrong `ok` and 233 of the 9919 right
    /// ones `ambiguous` (the heading probes alone 2 wrong and 14 right); on the seven CARMEN
    /// logs both ways 1 of 6 wrong and 55 of 3838 right. Success is the same: the answers are.
    pub ok_probes: Probes,
    /// A scan with at least this many returns lost on surfaces it sees on both sides
    /// ([`crate::cost::surface_dropouts`]) comes from a sensor that reads "no return" where a
    /// wall is: its missing returns are skipped by the cost as unknown readings are
    /// ([`CostConfig::skip_no_returns`]). 0 never skips them. The simulated URG reports lost
    /// returns as error codes and "no return" only beyond its range, so no default simulated
    /// log has such a scan; the CARMEN logs' SICK reads 81.91 m for both, and 27 / 127 / 130
    /// scans of aces / csail / freiburg-101 show it. There, a right pose paid the through-wall
    /// cost for dozens of beams whose walls 3-20 m away returned nothing, and lost to poses
    /// outside the building: freiburg-101 went from 63.0 to 76.7 % and csail from 58.1 to
    /// 62.6 % (aces unchanged at 56.8 %). Costing those beams as unexplained (`front_cap`)
    /// instead gave 75.3 and 62.1 %; only runs between two readings that agree with the map,
    /// 69.9 and 58.6 %.
    pub surface_dropouts: usize,
    /// Never answer with a pose outside a building whose walls close it off
    /// ([`map::Outside`]), or where the survey that built the map saw no free space
    /// ([`map::SeenFree`]). Beyond the outline the map predicts "no return" in every
    /// direction away from it, which a scan's open side matches as well as the building does:
    /// wrong poses out there beat the right one when furniture hides the walls the scan would
    /// need (39 of the furnished warehouse's 96 wrong answers, 9 of the furnished radial map's
    /// 19). Such poses are still searched and costed: one that explains the scan about as well
    /// as the answer makes the answer `ambiguous`, since the scan then does not single it out.
    /// A map with an open outline and no seen free space rules nothing out. Maps built from
    /// the CARMEN logs are open, but keep their scans' free space: there 34 / 13 / 4 of the
    /// csail / freiburg-101 / aces wrong answers lay where no beam had been.
    pub inside_only: bool,
    /// Largest number of hypotheses reported.
    pub max_hypotheses: usize,
    /// Keep every candidate pose of a scan in [`crate::Localization::all_candidates`] (diagnostics).
    pub record_candidates: bool,
    /// A cheaper search tried first; see [`FirstLook`].
    pub first_look: FirstLook,
    /// Hypotheses from scan lines laid along map walls, tried when neither look's best pose is
    /// confirmed; see [`crate::slide`].
    pub slide: SlideConfig,
    /// When the best pose after the slide searches is `failed`, or sees through walls with more
    /// than this fraction of its beams (as no confirmed pose may: [`FirstLook::max_through`]),
    /// the slide search runs once more with the wider budgets of
    /// [`escalated`](Self::escalated), and its poses are ranked with the others; when the best
    /// pose then still does, so does the grid search ([`crate::grid`], [`Self::grid`]). Only on
    /// a map that states no error (`sigma` 0, as a drawn plan): right poses see through the
    /// errors of the others. 1: never.
    ///
    /// At the right pose only noise and mixed pixels see through a drawn map's walls, so such an
    /// answer is most likely wrong and the time is spent where it can change the answer: 0.3-7 %
    /// of the simulated scans go round, and 4-5 % of the furnished warehouse's go on to the
    /// grid. Over the 48 simulated logs of `gema2 evaluate`: successes 13798 -> 13818 with the
    /// wider slide alone and 13843 with the grid, `ok` 11591 -> 11586 -> 11593, wrong `ok` 62 ->
    /// 55 -> 53, no log lost a success; the furnished warehouse 82.3 -> 83.0 -> 85.0 % (its
    /// other simulator seeds 82.3 / 78.7 / 82.0 -> 84.7 / 79.7 / 84.7 %). The medians do not
    /// move; the p99 does, where scans are sent round: the furnished warehouse's from 7-11 to
    /// 23-27 ms, the largest of a log (an office) from 16 to 50 ms. On the 4994-wall office
    /// (343 x 112 m) a scan sent round takes 100-120 ms more for the wider slide and 50-80 ms
    /// for the grid, and its furnished log's success does not move (64 %). The office drawn
    /// 12 cm thick and exported as a 5 cm grid (`sigma` half a cell) sent 10.5 % of its
    /// furnished scans round, 9 % on to the grid, for no success gained and a p99 of 171 ms
    /// against 63 ms (on a busy machine): such maps are left out, as maps built from scans
    /// are. A limit above the first look's costs successes and lets wrong answers stand, for a
    /// shorter tail: right poses among many depth jumps see through 1-1.3 % of the beams at
    /// walls' edges, and go round for nothing (4 of the bundled office's 300 scans with people,
    /// p99 6 -> 47 ms). At 1.5 % the 48 logs gave 13838 successes and 55 wrong `ok` (against
    /// 13843 and 53), the largest p99 28 ms; at 2 %, 13834 and 57. Measured with an
    /// earlier form of this rule (judged after the
    /// cornerless scan's rule, within one success of this one): a wider corner search as well
    /// found 4 scans alone and none beyond the wider slide's; the loose slide once more, 1 more
    /// scan for a p99 of 50 ms; a limit of 0.5 % of the beams, 20 more scans and 11 fewer wrong
    /// `ok`, but furnished logs' medians up to four times as long. On the CARMEN maps
    /// (approximate, so left out) it took the median from 11.5 to 41.6 ms a scan for 2 more
    /// successes.
    pub escalate_through: f64,
    /// ...and with at least this many beams: at the right pose a few beams see through walls at
    /// their edges in a scan of any density, which in a sparse scan is a large fraction. With
    /// the fraction alone, 68-beam scans of the `gema2 bench` scaling table went round for
    /// nothing: 3.5 -> 16.4 ms a scan at 54 walls, 5.5 -> 34.5 ms at 216, 9.6 -> 52.5 ms at 993,
    /// for no more successes; with 7 beams 3.6 / 5.6 / 8.9 ms. 7 is 1 % of a URG-04LX scan:
    /// nothing changes on the 48 simulated logs (682 beams) nor on SICK-like 361-beam ones.
    pub escalate_min_beams: usize,
    /// The grid search that follows the wider slide when its answer still sees through walls
    /// ([`crate::grid`]).
    pub grid: GridConfig,
    /// Tracking (section 5.1): after an `ok` scan, only poses within this many metres of it
    /// are made, the most the robot moves between two located scans. A map corner is matched
    /// only within this plus the scan corner's own range of the last pose, and only walls
    /// within this plus the slid lines' reach are slid along. Any other outcome returns to
    /// global search. `None`: always global.
    pub track_radius: Option<f64>,
}

impl Default for LocalizerConfig {
    fn default() -> Self {
        LocalizerConfig {
            corners_tried: 12,
            min_angle_tolerance: 2f64.to_radians(),
            max_angle_tolerance: 8f64.to_radians(),
            arm_slack: 0.3,
            screen_points: 40,
            prescreen_step: 4,
            prescreened: 1024,
            screen_cap: 0.12,
            screen_behind: 3.0,
            screen_open: 3.0,
            screen_long_line: 0.6,
            screened: 384,
            coarse_beams: 64,
            coarse_sigma: 0.08,
            sparse_beams: 32,
            sparse_kept: 64,
            screened_approximate: 256,
            refined: 6,
            refine_points: 160,
            polish_margin: 0.6,
            polish_points: 682,
            polish_iterations: 2,
            refine: RefineConfig::default(),
            cost: CostConfig::default(),
            error: ErrorModel::default(),
            distinct_position: 0.3,
            distinct_heading: 5f64.to_radians(),
            ambiguity_margin: 0.3,
            ambiguity_ratio: 0.5,
            ambiguity_margin_approximate: 0.4,
            cornerless_tie: 10.0,
            min_inliers: 0.3,
            max_through: 0.2,
            max_through_approximate: 1.0,
            front_cap_approximate: 8.0,
            clutter_share_approximate: 1.0,
            max_through_ok: 0.05,
            min_constraint_ok_approximate: 2.0,
            ok_probes: Probes::default(),
            surface_dropouts: 1,
            inside_only: true,
            max_hypotheses: 32,
            record_candidates: false,
            first_look: FirstLook::default(),
            slide: SlideConfig::default(),
            escalate_through: 0.01,
            escalate_min_beams: 7,
            grid: GridConfig::default(),
            track_radius: None,
        }
    }
}

impl LocalizerConfig {
    /// This search with every budget widened, for when time is no object: a first global fix,
    /// a robot that lost itself, a log located offline. It changes no threshold and no cost,
    /// only how many poses are made and carried to eq. 7: the 12 longest lines down to 0.3 m
    /// are slid (up to 100 000 poses), the screen's first pass keeps 100 000 poses instead of
    /// 1024, every slid pose it keeps reaches the 32-beam coarse cost, which keeps 2000 instead
    /// of 64, and 40 poses instead of 6 are refined.
    ///
    /// Measured with `gema2 evaluate --set thorough=1` (48 simulated logs, 14 400 scans, against
    /// the default search): successes 13 596 -> 13 694 (94.4 -> 95.1 %), wrong `ok` 73 -> 61,
    /// `ok` 11 536 -> 11 489; no log lost a success. The furnished logs gain most: the bundled
    /// warehouse 70.3 -> 75.0 %, the office 90.7 -> 93.0 %. Scans the first look settles cost
    /// the same; the rest cost up to a hundred times more: p99 about 80 ms on the furnished warehouse,
    /// 0.43 s on the furnished office (one core here), against 3-4 and 4-8 ms.
    ///
    /// It is better per log, not per scan: a wider search also finds wrong poses that eq. 7
    /// rates above the truth. On 200 other furnished warehouse scans (simulator seeds 5-9, 40
    /// each) it turned 5 misses into successes and 4 successes into misses.
    pub fn thorough(self) -> Self {
        LocalizerConfig {
            prescreened: 100_000,
            screened_approximate: 0,
            sparse_kept: 2000,
            refined: 40,
            slide: SlideConfig {
                lines: 12,
                min_length: 0.3,
                min_wall: 0.3,
                max_poses: 100_000,
                screened: 100_000,
                loose_screened: 100_000,
                ..self.slide
            },
            ..self
        }
    }

    /// The slide search's budgets for a scan whose answer sees through walls
    /// ([`escalate_through`](Self::escalate_through)): the 12 longest lines are slid along every
    /// run down to 0.3 m (up to 30 000 poses), the screen's first pass keeps 10 000 of them
    /// instead of 1024 and its full pass 4000, the 32-beam coarse cost keeps 500 instead of 64,
    /// and 20 poses instead of 6 are refined (so are the grid search's). Budgets already wider
    /// stay as they are. With the grid search after it, the full pass keeping 10 000 gave one
    /// scan fewer over the 48 simulated logs, for a largest p99 of 53 ms against 47. Measured
    /// with the earlier form of the rule (see [`escalate_through`](Self::escalate_through)),
    /// which gained 23 scans with these budgets: with [`thorough`](Self::thorough)'s (100 000
    /// poses, 2000 kept, 40 refined) the 48 simulated logs gained the same 23, for a p99 of up to
    /// 102 ms; with 16 000 poses, 4000 kept, 256 and 12, 19 at up to 22 ms.
    pub fn escalated(self) -> Self {
        LocalizerConfig {
            prescreened: self.prescreened.max(10_000),
            sparse_kept: self.sparse_kept.max(500),
            refined: self.refined.max(20),
            slide: SlideConfig {
                lines: self.slide.lines.max(12),
                min_wall: self.slide.min_wall.min(0.3),
                max_poses: self.slide.max_poses.max(30_000),
                screened: self.slide.screened.max(4_000),
                ..self.slide
            },
            ..self
        }
    }

    /// The inner angle tolerance of matching scan corner `c`: three standard deviations of its
    /// angle, clamped to [`min_angle_tolerance`, `max_angle_tolerance`].
    ///
    /// [`min_angle_tolerance`]: Self::min_angle_tolerance
    /// [`max_angle_tolerance`]: Self::max_angle_tolerance
    pub fn angle_tolerance(&self, c: &segment::Corner) -> f64 {
        (3.0 * c.inner_angle_sigma()).clamp(self.min_angle_tolerance, self.max_angle_tolerance)
    }
}

/// Probes of a pose ([`Localizer::withstands_probes`](super::Localizer::withstands_probes)):
/// the pose moved `position` metres either way along the direction the scan pins down least,
/// and turned `heading` radians either way, each costing at least `margin` more per beam by
/// eq. 7 over about `beams` beams. `ok` promises 0.3 m and 5 degrees: the turn is probed at
/// the promise, the move at twice it (at 0.3 m and 0.45 m, right answers in corridors of
/// freiburg-101 and a furnished warehouse failed it; wrong ones as few failed it at 0.6 m).
/// 32 beams: at 64 the probes cost twice as much and caught fewer wrong answers. A `position`
/// of 0 probes nothing: every pose withstands.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Probes {
    pub position: f64,
    pub heading: f64,
    pub margin: f64,
    pub beams: usize,
}

impl Probes {
    /// Whether these probes test nothing: a `position` of 0 (or less), which every pose
    /// withstands.
    pub fn probes_nothing(&self) -> bool {
        self.position <= 0.0
    }
}

impl Default for Probes {
    fn default() -> Self {
        Probes { position: 0.6, heading: 5f64.to_radians(), margin: 0.3, beams: 32 }
    }
}

/// A first, cheaper search, as the paper's: the best scan corner (or few best) the map has
/// corners like, fewer hypotheses screened and refined.
///
/// When its best pose is *confirmed* (at least `min_inliers` of the beams agree with the map
/// and at most `max_through` see through its walls) the scan ends there, `ok` or `ambiguous`;
/// otherwise the full search runs and its hypotheses are ranked together with the first
/// look's. An ambiguous scan whose best pose is confirmed is a symmetric place (two identical
/// rooms): the full search would find the same twins. On the clean office log this changed
/// no scan's status, and on the other simulated logs success by at most one scan.
///
/// Seeing through walls is what tells a wrong pose: people and furniture only shorten beams,
/// so a right pose in a furnished room has fewer inliers but still almost no beam through a
/// wall. On the simulated logs, lowering `min_inliers` from 0.9 to 0.6 settled 2 % -> 50 % of
/// furnished office scans and changed no scan's success. The full search exists for scans whose
/// best corner is a box or a person: its pose sees through walls and is not confirmed. On a
/// map built from scans a twin does not see through walls either, so there the first look
/// does not run (see the cascade).
///
/// A confirmed pose the first look rates `ok` is only as sure as the twins it looked for: with
/// one scan corner and two refined hypotheses it passes over a twin whose match to that corner
/// screened poorly (the corner's pose a few centimetres and a degree off), or that only
/// another corner finds. So before such a scan settles, the [twin look](TwinLook) searches the
/// best few corners for poses the screen rates nearly as well, and ranks them with the first
/// look's: a twin it finds makes the scan `ambiguous`. A short-range sensor sees a small patch
/// of the map that has twins in many places: with 3.5 m of range (a 360-beam LDS-01) the
/// bundled office and warehouse gave 17 wrong `ok` in 900 scans without the twin look, 3 with
/// it; the simulated URG-04LX suite 28 and 14 (`gema2 evaluate`), for 3 % fewer `ok` and
/// 30-300 µs more on a scan the first look settles (0.7 ms on a 5000-wall office).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FirstLook {
    /// Scan corners matched; 0 turns the first look off.
    pub corners: usize,
    /// Candidates kept by the first screening pass (see [`LocalizerConfig::prescreened`]).
    pub prescreened: usize,
    pub screened: usize,
    pub refined: usize,
    pub min_inliers: f64,
    pub max_through: f64,
    pub twins: TwinLook,
}

impl Default for FirstLook {
    fn default() -> Self {
        FirstLook {
            corners: 1,
            prescreened: 32,
            screened: 8,
            refined: 2,
            min_inliers: 0.6,
            max_through: 0.01,
            twins: TwinLook::default(),
        }
    }
}

/// The look for twins of a pose the [`FirstLook`] confirmed as `ok`: the candidates of the
/// best `corners` scan corners, the first screening pass keeping only those it rates at most
/// `bound` times the confirmed pose (over the same points), and `prescreened`, `screened`,
/// `refined` as a search's budgets. Measured on the simulated short-range office and
/// warehouse (3.5 m, 360 beams): 2 corners left 5 of the 17 wrong `ok`, 4 and 6 left 3, 12
/// left 4 at more cost; 2 refined instead of 4 left 4; a bound of 2 or 3 instead of 1.5
/// removed no more wrong `ok` but made 1-2 % more right ones `ambiguous`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TwinLook {
    /// Scan corners matched, best first; 0 turns the twin look off.
    pub corners: usize,
    /// The most a candidate's first-pass screen sum may be, as a multiple of the confirmed
    /// pose's over the same points: a twin's corner pose, a few centimetres and a degree off
    /// before refinement, screens worse than the refined pose it would rival.
    pub bound: f64,
    /// Candidates kept by the first screening pass.
    pub prescreened: usize,
    /// Candidates kept by the full screen, for the coarse cost.
    pub screened: usize,
    /// Candidates refined and costed by eq. 7, to be ranked with the first look's.
    pub refined: usize,
}

impl Default for TwinLook {
    fn default() -> Self {
        TwinLook { corners: 4, bound: 1.5, prescreened: 32, screened: 16, refined: 4 }
    }
}

impl FirstLook {
    /// Whether `best` settles the scan.
    pub(super) fn confirms(&self, status: Status, best: Option<&Hypothesis>) -> bool {
        status != Status::Failed
            && best.is_some_and(|h| h.cost.inliers >= self.min_inliers && h.cost.through <= self.max_through)
    }
}
