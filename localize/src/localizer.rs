//! The localization stage (section 5): scan corners x similar map corners -> pose hypotheses
//! (eqs. 5-6) -> ranked by the cost function (eq. 7).
//!
//! Robustness over the paper's single best corner (LESSONS.md): the `corners_tried` best scan
//! corners are all matched, so a spurious best corner (a person's legs, a box) does not sink
//! the scan. Hypotheses then pass through stages of increasing cost and decreasing number:
//!
//! 1. matches whose arms cannot fit the map corner's are dropped ([`arms_fit`]);
//! 2. a distance-field screen keeps the `screened` best;
//! 3. a coarse one-sided eq. 7 over a subset of beams (first a sparser one when many pass the
//!    screen), with a noise floor that tolerates an unrefined pose, keeps the `refined` best
//!    (unmapped objects in front of walls cost little here, unlike in the screen);
//! 4. those are refined against the walls and ranked by the full one-sided eq. 7.
//!
//! All this runs first for the single best corner with few hypotheses (the [`FirstLook`]),
//! and for the `corners_tried` best only when that look's best pose is not confirmed. When
//! that is not confirmed either, the scan's longest lines are laid along the map's walls
//! ([`crate::slide`]) and those poses go through the same steps, ranked with the others.

use crate::cost::{cost, cost_below, Cost, CostConfig};
use crate::lowest::Lowest;
use crate::matching::{arms_fit, pose_from_corners};
use crate::model::{MapModel, WallFrame, FIELD_CAP};
use crate::refine::{refine, RefineConfig};
use crate::slide::{chord_poses, slide_lines, slide_poses, slide_step, SlideConfig, SlideLine, FROM_SLIDE};
use laser::{angle_diff, pose_theta, Pose, ScanView};
use mapserver::runs::RunChain;
use mapserver::{DistanceField, RayScratch, Wall};
use nalgebra::Point2;
use segment::{ErrorModel, Segmentation};
use std::sync::Arc;
use std::time::{Duration, Instant};

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
    /// Hypotheses kept by the screen, and costed coarsely.
    pub screened: usize,
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
    /// ([`mapserver::WallMap::is_approximate`], as maps built from scans do); 1 sets no limit,
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
    /// The best pose is at most `ambiguous` when more than this fraction of its beams see
    /// through mapped walls. A drawn map has no walls that are not there, so 5 % holds every
    /// right pose on the simulated logs; a map built from a log has walls of doors and things
    /// that have since moved, and right poses against the CARMEN maps see through 5-19 %: of
    /// the 154 scans there that a 5 % limit failed and this one does not, 84 were right (with
    /// the through-wall cost at 25, when this was measured). Such a pose is an answer, but not
    /// one to trust. On the simulated logs 18 scans moved, all wrong, all now `ambiguous`.
    pub max_through_ok: f64,
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
    /// ([`mapserver::Outside`]), or where the survey that built the map saw no free space
    /// ([`mapserver::SeenFree`]). Beyond the outline the map predicts "no return" in every
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
    /// Keep every candidate pose of a scan in [`Localization::all_candidates`] (diagnostics).
    pub record_candidates: bool,
    /// A cheaper search tried first; see [`FirstLook`].
    pub first_look: FirstLook,
    /// Hypotheses from scan lines laid along map walls, tried when neither look's best pose is
    /// confirmed; see [`crate::slide`].
    pub slide: SlideConfig,
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
            screened: 384,
            coarse_beams: 64,
            coarse_sigma: 0.08,
            sparse_beams: 32,
            sparse_kept: 64,
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
            cornerless_tie: 10.0,
            min_inliers: 0.3,
            max_through: 0.2,
            max_through_approximate: 1.0,
            front_cap_approximate: 8.0,
            max_through_ok: 0.05,
            surface_dropouts: 1,
            inside_only: true,
            max_hypotheses: 32,
            record_candidates: false,
            first_look: FirstLook::default(),
            slide: SlideConfig::default(),
            track_radius: None,
        }
    }
}

impl LocalizerConfig {
    /// The inner angle tolerance of matching scan corner `c`: three standard deviations of its
    /// angle, clamped to [`min_angle_tolerance`, `max_angle_tolerance`].
    ///
    /// [`min_angle_tolerance`]: Self::min_angle_tolerance
    /// [`max_angle_tolerance`]: Self::max_angle_tolerance
    pub fn angle_tolerance(&self, c: &segment::Corner) -> f64 {
        (3.0 * c.inner_angle_sigma()).clamp(self.min_angle_tolerance, self.max_angle_tolerance)
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
/// best corner is a box or a person: its pose sees through walls and is not confirmed. A
/// settled scan's ambiguity is judged among the first look's hypotheses only, so a twin pose
/// that only another scan corner would find goes unseen.
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
}

impl Default for FirstLook {
    fn default() -> Self {
        FirstLook { corners: 1, prescreened: 32, screened: 8, refined: 2, min_inliers: 0.6, max_through: 0.01 }
    }
}

impl FirstLook {
    /// Whether `best` settles the scan.
    fn confirms(&self, status: Status, best: Option<&Hypothesis>) -> bool {
        status != Status::Failed
            && best.is_some_and(|h| h.cost.inliers >= self.min_inliers && h.cost.through <= self.max_through)
    }
}

/// The outcome of one scan.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Status {
    /// One pose clearly explains the scan best.
    Ok,
    /// Two distinct poses explain it about equally well.
    Ambiguous,
    /// No corner, no candidate, or no pose that explains the scan; or, in a scan with no
    /// corner, several poses that explain it equally well.
    Failed,
}

impl Status {
    pub fn as_str(&self) -> &'static str {
        match self {
            Status::Ok => "ok",
            Status::Ambiguous => "ambiguous",
            Status::Failed => "failed",
        }
    }
}

/// One pose hypothesis.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hypothesis {
    /// Sensor pose in the map frame (refined).
    pub pose: Pose,
    pub cost: Cost,
    /// Index of the scan corner (in the segmentation's corner list) and of the map corner (in
    /// the map's inner-angle-sorted corner list) that produced it; for a pose of the slide
    /// search, [`FROM_SLIDE`] and the index of the straight run ([`MapModel::runs`]).
    pub scan_corner: u16,
    pub map_corner: u32,
}

/// Compute time of the localization steps of one scan.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct LocateTimes {
    /// Corner matching (eqs. 5-6), arm test and screening.
    pub matching: Duration,
    /// Coarse eq. 7 over the screened hypotheses.
    pub coarse: Duration,
    pub refine: Duration,
    /// Full eq. 7 over the refined hypotheses.
    pub cost: Duration,
    /// Whether the full search ran: the [`FirstLook`] did not settle the scan. Each step's
    /// time above is the sum over all searches.
    pub full_search: bool,
    /// Whether the slide search ran: the full search's best pose was not confirmed either.
    pub slide_search: bool,
}

#[derive(Clone, Debug)]
pub struct Localization {
    /// Ranked hypotheses, best first.
    pub hypotheses: Vec<Hypothesis>,
    pub status: Status,
    /// Poses produced by corner matching (after the arm test, before screening).
    pub candidates: usize,
    pub times: LocateTimes,
    /// With `record_candidates`: every candidate (pose, screening score, scan corner index),
    /// in screening order.
    pub all_candidates: Vec<(Pose, f64, u16)>,
    /// The distance between poses along a wall that the slide search used, when it ran.
    pub slide_step: Option<f64>,
}

impl Localization {
    pub fn best(&self) -> Option<&Hypothesis> {
        match self.status {
            Status::Failed => None,
            _ => self.hypotheses.first(),
        }
    }
}

#[derive(Clone, Copy, Debug)]
struct Candidate {
    pose: Pose,
    score: f64,
    scan_corner: u16,
    map_corner: u32,
}

pub struct Localizer {
    /// Where the last `ok` scan put the sensor, while tracking.
    prior: Option<Point2<f64>>,
    model: Arc<MapModel>,
    pub config: LocalizerConfig,
    screen_pts: Vec<Point2<f64>>,
    /// One in `prescreen_step` screening points: the first screening pass.
    screen_few: Vec<Point2<f64>>,
    /// `screen_few` in the order the first pass reads them for one scan corner or slid line.
    screen_order: Vec<Point2<f64>>,
    /// The first screening pass's best sums.
    best_sums: Lowest,
    /// The lowest coarse costs so far ([`Localizer::coarse_cost`]).
    coarse_lowest: Lowest,
    refine_pts: Vec<Point2<f64>>,
    polish_pts: Vec<Point2<f64>>,
    candidates: Vec<Candidate>,
    /// [`Self::keep_best`]'s kept candidates as (x, position), sorted by x.
    kept_by_x: Vec<(f64, usize)>,
    /// The scan's lines as the slide search reads them, and those it lays along walls.
    lines: Vec<SlideLine>,
    slide_lines: Vec<usize>,
    scratch: RayScratch,
    expected: Vec<f64>,
    /// The cost's e(d) for the scan being located: the configured one widened as the
    /// segmentation widened its own ([`Segmentation::noise_scale`]).
    error: ErrorModel,
    /// The cost for the scan being located: the configured one, skipping missing returns when
    /// the scan shows its sensor losing returns on surfaces.
    cost: CostConfig,
    out: Localization,
}

impl Localizer {
    pub fn new(model: Arc<MapModel>, config: LocalizerConfig) -> Self {
        Localizer {
            prior: None,
            model,
            config,
            screen_pts: Vec::new(),
            screen_few: Vec::new(),
            screen_order: Vec::new(),
            best_sums: Lowest::default(),
            coarse_lowest: Lowest::default(),
            refine_pts: Vec::new(),
            polish_pts: Vec::new(),
            candidates: Vec::new(),
            kept_by_x: Vec::new(),
            lines: Vec::new(),
            slide_lines: Vec::new(),
            scratch: RayScratch::default(),
            expected: Vec::new(),
            error: config.error,
            cost: config.cost,
            out: Localization {
                hypotheses: Vec::new(),
                status: Status::Failed,
                candidates: 0,
                times: LocateTimes::default(),
                all_candidates: Vec::new(),
                slide_step: None,
            },
        }
    }

    /// Switches to another map (from the next scan on).
    pub fn set_model(&mut self, model: Arc<MapModel>) {
        self.prior = None;
        self.model = model;
    }

    pub fn model(&self) -> &Arc<MapModel> {
        &self.model
    }

    /// Localizes one scan from its segmentation.
    pub fn locate(&mut self, scan: &ScanView<'_>, seg: &Segmentation) -> &Localization {
        self.lines.clear();
        self.lines.extend(seg.lines.iter().map(SlideLine::from));
        self.locate_lines_given(scan, seg)
    }

    /// [`locate`](Self::locate) for a segmentation whose lines arrive separately (the
    /// pipeline's localizer gets samples, corners and line extents; `seg.lines` is ignored).
    pub fn locate_with_lines(
        &mut self,
        scan: &ScanView<'_>,
        seg: &Segmentation,
        lines: impl IntoIterator<Item = SlideLine>,
    ) -> &Localization {
        self.lines.clear();
        self.lines.extend(lines);
        self.locate_lines_given(scan, seg)
    }

    /// For diagnosis, after [`locate`](Self::locate) of `scan`: how the search would have
    /// judged `pose` at each step.
    pub fn judge(&mut self, scan: &ScanView<'_>, pose: &Pose) -> Judgement {
        let model = Arc::clone(&self.model);
        let cfg = self.config;
        let screen = Screen::new(&model, cfg.screen_cap);
        let mean = |points: &[Point2<f64>]| {
            screen.sum(pose, points, f64::INFINITY).unwrap_or(f64::INFINITY) / points.len().max(1) as f64
        };
        let (prescreen, screen) = (mean(&self.screen_few), mean(&self.screen_pts));
        let final_cfg = self.final_cost_config();
        let cost_at = cost(scan, pose, &model.caster, &self.error, &final_cfg, &mut self.scratch, &mut self.expected);
        let refined = refine(&model, &self.refine_pts, pose, &cfg.refine).0;
        let refined_cost =
            cost(scan, &refined, &model.caster, &self.error, &final_cfg, &mut self.scratch, &mut self.expected);
        Judgement { prescreen, screen, cost: cost_at, refined, refined_cost }
    }

    /// Eq. 7's form for this map, before a scan adjusts it: an approximate map's own cap on
    /// readings short of it ([`LocalizerConfig::front_cap_approximate`]).
    fn scan_cost_config(&self) -> CostConfig {
        let mut c = self.config.cost;
        if self.model.map.is_approximate() {
            c.front_cap = self.config.front_cap_approximate;
        }
        c
    }

    /// The cost configuration of a hypothesis's final eq. 7: never expect the scan to agree
    /// with the map better than the map is accurate.
    fn final_cost_config(&self) -> CostConfig {
        CostConfig { sigma_floor: self.cost.sigma_floor.max(self.model.map.sigma), ..self.cost }
    }

    fn locate_lines_given(&mut self, scan: &ScanView<'_>, seg: &Segmentation) -> &Localization {
        self.out.hypotheses.clear();
        self.out.status = Status::Failed;
        self.out.times = LocateTimes::default();
        self.out.slide_step = None;
        // a scan noisier than the configured e(d) would count the right pose's beams as seeing
        // through walls
        self.error = self.config.error.scaled(segment::noise::usable_scale(seg.noise_scale));
        self.cost = self.scan_cost_config();
        let drops = self.config.surface_dropouts;
        self.cost.skip_no_returns = drops > 0 && crate::cost::surface_dropouts(scan, &self.error) >= drops;
        subsample(seg, self.config.screen_points, &mut self.screen_pts);
        subsample(seg, self.config.refine_points, &mut self.refine_pts);
        let first = self.config.first_look;
        let mut settled = false;
        if first.corners > 0 && first.corners < self.config.corners_tried {
            self.search(scan, seg, Source::Corners(first.corners), first.prescreened, first.screened, first.refined);
            self.rank();
            settled = first.confirms(self.out.status, self.out.hypotheses.first());
        }
        let cfg = self.config;
        if !settled {
            self.out.times.full_search = true;
            self.search(scan, seg, Source::Corners(cfg.corners_tried), cfg.prescreened, cfg.screened, cfg.refined);
            self.rank();
            settled = first.confirms(self.out.status, self.out.hypotheses.first());
        }
        if !settled && cfg.slide.lines > 0 {
            self.out.times.slide_search = true;
            self.search(scan, seg, Source::Slides, cfg.prescreened, cfg.slide.screened, cfg.refined);
            self.rank();
            if self.out.status == Status::Ok
                && self.out.hypotheses.first().is_some_and(|h| h.cost.inliers < cfg.slide.min_inliers_ok)
            {
                self.out.status = Status::Ambiguous;
            }
            // with no corner in view, an equally good pose further along the same wall means the
            // scan does not say where along it the sensor is (a corridor whose ends are out of
            // range): that is no answer, as the paper's cornerless scan. Twins elsewhere (two
            // identical aisles) stay `ambiguous`: the scan does fix each of them.
            if seg.corners.is_empty() && self.out.status == Status::Ambiguous && self.slides_along_a_wall() {
                self.out.status = Status::Failed;
            }
        }
        self.report();
        self.prior = match (self.config.track_radius, self.out.status, self.out.hypotheses.first()) {
            (Some(_), Status::Ok, Some(h)) => Some(Point2::from(h.pose.translation.vector)),
            _ => None,
        };
        &self.out
    }

    /// Makes the candidates of `source`, keeps the `screened` best by the screen (its first
    /// pass keeps `prescreened`) and the `refined` best of those by the coarse cost, refines
    /// them and adds them to the hypotheses with their full eq. 7 cost (unranked). Adds each
    /// step's time.
    fn search(
        &mut self,
        scan: &ScanView<'_>,
        seg: &Segmentation,
        source: Source,
        prescreened: usize,
        screened: usize,
        refined: usize,
    ) {
        let t0 = Instant::now();
        self.out.all_candidates.clear();
        self.make_candidates(seg, source, prescreened.max(screened));
        self.out.candidates = self.candidates.len();
        if self.config.record_candidates {
            self.candidates.sort_by(|a, b| a.score.total_cmp(&b.score));
            self.out.all_candidates.extend(self.candidates.iter().map(|c| (c.pose, c.score, c.scan_corner)));
        }
        self.keep_best(screened);
        let t1 = Instant::now();
        // with no more screened than refined there is nothing for the coarse cost to choose
        if screened > refined {
            let cfg = self.config;
            if self.candidates.len() > cfg.sparse_kept.max(refined) {
                self.coarse_cost(scan, cfg.sparse_beams, cfg.sparse_kept);
                self.keep_best(cfg.sparse_kept);
            }
            self.coarse_cost(scan, cfg.coarse_beams, refined);
            self.keep_best(refined);
        }
        let t2 = Instant::now();
        let model = Arc::clone(&self.model);
        for c in self.candidates.iter_mut() {
            c.pose = refine(&model, &self.refine_pts, &c.pose, &self.config.refine).0;
        }
        let t3 = Instant::now();
        let final_cfg = self.final_cost_config();
        for c in &self.candidates {
            let cost =
                cost(scan, &c.pose, &model.caster, &self.error, &final_cfg, &mut self.scratch, &mut self.expected);
            if cost.value.is_finite() {
                self.out.hypotheses.push(Hypothesis {
                    pose: c.pose,
                    cost,
                    scan_corner: c.scan_corner,
                    map_corner: c.map_corner,
                });
            }
        }
        let t4 = Instant::now();
        self.polish(scan, seg);
        let t5 = Instant::now();
        let times = &mut self.out.times;
        times.matching += t1 - t0;
        times.coarse += t2 - t1;
        times.refine += (t3 - t2) + (t5 - t4);
        times.cost += t4 - t3;
    }

    /// The candidate poses of `source`, each screened by the distance field; the `keep` best
    /// are kept.
    fn make_candidates(&mut self, seg: &Segmentation, source: Source, keep: usize) {
        self.candidates.clear();
        let cfg = self.config;
        let model = Arc::clone(&self.model);
        // screening in two passes: one in `prescreen_step` points for all poses, then every
        // point for the `keep` best
        self.screen_few.clear();
        self.screen_few.extend(self.screen_pts.iter().step_by(cfg.prescreen_step.max(1)));
        let screen = Screen::new(&model, cfg.screen_cap);
        let few = &self.screen_few;
        let order = &mut self.screen_order;
        let mut pass = FirstPass::new(screen, few.len(), keep, &mut self.best_sums);
        let candidates = &mut self.candidates;
        match source {
            Source::Corners(corners) => {
                // a corner of a kind the map has none of (a wall end, where the map lists no
                // wall ends) makes no candidate: the next best takes its place
                let matchable = seg.corners.iter().enumerate().filter_map(|(ci, c)| {
                    let range = model.corners.similar_range(c.inner_angle, cfg.angle_tolerance(c));
                    (!range.is_empty()).then_some((ci, c, range))
                });
                // tracking: the robot is within r of its last pose, so a map corner it sees lies
                // within r plus the scan corner's own range of that pose
                let track = self.prior.zip(cfg.track_radius);
                for (ci, c, range) in matchable.take(corners) {
                    // points on the corner's arms fit every match of it: they go last
                    order_by_telling(few, order, |q| {
                        c.arms.iter().map(|a| a.direction.perp(&(q - c.position)).abs()).fold(f64::INFINITY, f64::min)
                    });
                    for k in range {
                        let m = &model.corners.corners()[k];
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
                        if let Some(score) = pass.score(&pose, order) {
                            candidates.push(Candidate { pose, score, scan_corner: ci as u16, map_corner: k as u32 });
                        }
                    }
                }
            }
            Source::Slides => {
                slide_lines(&self.lines, &cfg.slide, &mut self.slide_lines);
                // tracking: only poses within r of the last one, so only the walls within r plus
                // the slid lines' reach of it, as with map corners; the step is sized for those
                // walls alone
                let prior = self.prior.zip(cfg.track_radius);
                let lines = &self.lines;
                let reach = self
                    .slide_lines
                    .iter()
                    .map(|&li| lines[li].start.coords.norm().max(lines[li].end.coords.norm()))
                    .fold(0.0, f64::max);
                let near = |w: &&Wall| prior.is_none_or(|(p, r)| w.closest(p).0 <= r + reach);
                let bent_near =
                    |c: &&RunChain| prior.is_none_or(|(p, r)| c.runs().any(|w| w.closest(p).0 <= r + reach));
                let bends = model.bends.iter().filter(bent_near);
                let step = slide_step(
                    &self.lines,
                    &self.slide_lines,
                    model.runs.iter().filter(near),
                    bends.clone().map(RunChain::length),
                    &cfg.slide,
                );
                self.out.slide_step = Some(step);
                for &li in &self.slide_lines {
                    // points on the slid line fit every pose along the wall: they go last
                    let line = &self.lines[li];
                    order_by_telling(few, order, |q| line.direction().perp(&(q - line.start)).abs());
                    let mut offer = |pose: Pose, map_corner| {
                        if prior.is_some_and(|(p, r)| !within(&pose, p, r)) {
                            return;
                        }
                        if let Some(score) = pass.score(&pose, order) {
                            candidates.push(Candidate { pose, score, scan_corner: FROM_SLIDE, map_corner });
                        }
                    };
                    for (wi, wall) in model.runs.iter().enumerate().filter(|(_, w)| near(w)) {
                        slide_poses(&self.lines[li], wall, step, &cfg.slide, |pose| offer(pose, wi as u32));
                    }
                    // a chord's pose names no run
                    for chain in bends.clone() {
                        chord_poses(&self.lines[li], chain, step, |pose| offer(pose, u32::MAX));
                    }
                }
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

    /// When the best hypothesis so far is contested (see [`LocalizerConfig::polish_margin`]),
    /// refines once more, over the polish points, every hypothesis that costs less than the
    /// margin more than the best, and costs it again (the polish's time counts as
    /// refinement). One polished by an earlier search's contest is polished again, which
    /// keeps it or lowers its cost: a contest judged between polished and unpolished poses
    /// would favour the polished.
    fn polish(&mut self, scan: &ScanView<'_>, seg: &Segmentation) {
        let cfg = self.config;
        if cfg.polish_points == 0 {
            return;
        }
        let hyps = &self.out.hypotheses;
        let Some(best) = hyps.iter().min_by(|a, b| a.cost.value.total_cmp(&b.cost.value)).copied() else {
            return;
        };
        let near = |h: &Hypothesis| h.cost.value - best.cost.value < cfg.polish_margin;
        let contested = hyps
            .iter()
            .any(|h| near(h) && !same_pose(&h.pose, &best.pose, cfg.distinct_position, cfg.distinct_heading));
        if !contested {
            return;
        }
        // only for a contested scan: an uncontested one never needs them
        subsample(seg, cfg.polish_points, &mut self.polish_pts);
        let final_cfg = self.final_cost_config();
        // it starts where refinement ended: at its final gate
        let refine_cfg =
            RefineConfig { first_gate: cfg.refine.final_gate, iterations: cfg.polish_iterations, ..cfg.refine };
        let model = Arc::clone(&self.model);
        for h in self.out.hypotheses.iter_mut().filter(|h| near(h)) {
            let pose = refine(&model, &self.polish_pts, &h.pose, &refine_cfg).0;
            let c = cost(scan, &pose, &model.caster, &self.error, &final_cfg, &mut self.scratch, &mut self.expected);
            if c.value < h.cost.value {
                (h.pose, h.cost) = (pose, c);
            }
        }
    }

    /// Sorts candidates by score and keeps the `count` best distinct ones.
    fn keep_best(&mut self, count: usize) {
        keep_distinct(&mut self.candidates, count, &mut self.kept_by_x);
    }

    /// Scores each candidate by eq. 7 over about `beams` equispaced beams, tolerant of
    /// misalignment, for [`keep_best`](Self::keep_best) to keep the `keep` best. The candidates
    /// are distinct already (this keeps the poses a keep before it made distinct), so those are
    /// the `keep` lowest costs: a candidate known to cost more than `keep` others is stopped
    /// early ([`cost_below`]) and scores +inf. The candidates come best first by the previous
    /// step's score, so the bound is tight early.
    fn coarse_cost(&mut self, scan: &ScanView<'_>, beams: usize, keep: usize) {
        let cfg = CostConfig {
            stride: (scan.len() / beams.max(1)).max(1),
            sigma_floor: self.config.coarse_sigma.max(self.model.map.sigma),
            ..self.cost
        };
        let lowest = &mut self.coarse_lowest;
        lowest.clear();
        for c in self.candidates.iter_mut() {
            let bound = lowest.kth(keep);
            c.score = cost_below(
                scan,
                &c.pose,
                &self.model.caster,
                &self.error,
                &cfg,
                bound,
                &mut self.scratch,
                &mut self.expected,
            )
            .value;
            if c.score.is_finite() {
                lowest.offer(c.score, keep);
            }
        }
    }

    /// Whether a distinct hypothesis as good as the best (within [`LocalizerConfig::cornerless_tie`])
    /// has its heading and lies along the wall the best was slid on.
    fn slides_along_a_wall(&self) -> bool {
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

    /// Sorts hypotheses, merges those that converged to the same pose, and sets the status.
    fn rank(&mut self) {
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
        let Some(at) = hyps.iter().position(|h| !is_outside(&self.model, cfg.inside_only, h)) else {
            self.out.status = Status::Failed;
            return;
        };
        hyps[..=at].rotate_right(1);
        let best = hyps[0];
        let max_through = if self.model.map.is_approximate() { cfg.max_through_approximate } else { cfg.max_through };
        self.out.status = if best.cost.inliers < cfg.min_inliers || best.cost.through > max_through {
            Status::Failed
        } else if best.cost.through > cfg.max_through_ok
            || hyps.iter().any(|h| {
                !same_pose(&h.pose, &best.pose, cfg.distinct_position, cfg.distinct_heading)
                    && h.cost.value - best.cost.value < cfg.ambiguity_margin
            })
        {
            Status::Ambiguous
        } else {
            Status::Ok
        };
    }

    /// Drops the hypotheses outside the building (see [`Self::rank`]) and all but the
    /// reported number of the others.
    fn report(&mut self) {
        let (model, inside_only) = (&self.model, self.config.inside_only);
        self.out.hypotheses.retain(|h| !is_outside(model, inside_only, h));
        self.out.hypotheses.truncate(self.config.max_hypotheses);
    }
}

/// Whether `h` lies where the robot cannot be ([`MapModel::off_limits`]), when answers are
/// kept to where it can.
fn is_outside(model: &MapModel, inside_only: bool, h: &Hypothesis) -> bool {
    inside_only && model.off_limits(Point2::from(h.pose.translation.vector))
}

/// Where a search's candidate poses come from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Source {
    /// The given number of best scan corners, matched against similar map corners (eqs. 5-6).
    Corners(usize),
    /// The longest scan lines laid along every map wall ([`crate::slide`]).
    Slides,
}

/// How the search judges one pose of a scan ([`Localizer::judge`]).
#[derive(Clone, Copy, Debug)]
pub struct Judgement {
    /// The screen's first pass and its full pass (mean per point).
    pub prescreen: f64,
    pub screen: f64,
    /// Eq. 7 at the pose, the pose refinement reaches from it, and eq. 7 there.
    pub cost: Cost,
    pub refined: Pose,
    pub refined_cost: Cost,
}

/// The screen's first pass over one in `prescreen_step` points. It keeps the `keep` best sums:
/// a pose is dropped as soon as its partial sum reaches the `keep`-th best so far (sums only
/// grow), which leaves the kept set as it was and stops most wrong poses after a few points; a
/// pose that puts every point far from the walls is never worth more work.
struct FirstPass<'a> {
    screen: Screen<'a>,
    /// How many points each pose is screened over.
    points: usize,
    keep: usize,
    limit: f64,
    /// The best sums so far.
    best: &'a mut Lowest,
}

impl<'a> FirstPass<'a> {
    fn new(screen: Screen<'a>, points: usize, keep: usize, best: &'a mut Lowest) -> Self {
        best.clear();
        let limit = screen.cap * screen.cap * 0.95 * points.max(1) as f64;
        FirstPass { screen, points, keep, limit, best }
    }

    /// The pose's mean screen cost over `points` (the pass's points, in any order), or `None`
    /// when it cannot be among the `keep` best. The kept set does not depend on the order;
    /// the time does: the sooner a wrong pose's large misses come, the sooner it is dropped.
    fn score(&mut self, pose: &Pose, points: &[Point2<f64>]) -> Option<f64> {
        debug_assert_eq!(points.len(), self.points);
        let sum = self.screen.sum(pose, points, self.limit)?;
        self.best.offer(sum, self.keep);
        self.limit = self.limit.min(self.best.kth(self.keep));
        Some(sum / self.points.max(1) as f64)
    }
}

/// Whether `pose` places the sensor within `r` of `p`.
fn within(pose: &Pose, p: Point2<f64>, r: f64) -> bool {
    (Point2::from(pose.translation.vector) - p).norm() <= r
}

/// Eq. 7's cheap stand-in for screening: scan points placed at a pose cost their squared
/// distance to the nearest wall, capped at `cap`.
#[derive(Clone, Copy)]
struct Screen<'a> {
    field: &'a DistanceField,
    /// With [`MapModel::closed_sides`]: each wall's frame and closed sides.
    sides: Option<(&'a [WallFrame], &'a [[bool; 2]])>,
    cap: f64,
}

impl<'a> Screen<'a> {
    fn new(model: &'a MapModel, cap: f64) -> Self {
        let sides = model.closed_sides.as_deref().map(|closed| (&model.frames[..], closed));
        Screen { field: &model.field, sides, cap: cap.min(FIELD_CAP) }
    }

    /// The sum over `points` (sensor frame) placed at `pose`; `None` as soon as the partial sum
    /// reaches `limit`.
    ///
    /// A point whose nearest wall turns its closed side to the sensor is unexplained (the cap):
    /// its beam would have crossed a wall's body to reach that face. A pose a wall's thickness
    /// off the truth puts its points there, on the far face of the walls it sees, where the
    /// distance alone finds them as near a wall as the truth's.
    #[inline]
    fn sum(&self, pose: &Pose, points: &[Point2<f64>], limit: f64) -> Option<f64> {
        // with a limit, first the field's lower bounds, from a table that stays in cache: most
        // wrong poses pass the limit on them alone, without reading the field itself
        if limit < f64::INFINITY {
            let mut bound = 0.0;
            for q in points {
                let d = self.field.lower_bound(pose * q).min(self.cap);
                bound += d * d;
                if bound >= limit {
                    return None;
                }
            }
        }
        let sensor = Point2::from(pose.translation.vector);
        let mut sum = 0.0;
        for q in points {
            let p = pose * q;
            let mut d = self.field.distance(p).min(self.cap);
            if d < self.cap && self.seen_from_a_closed_side(p, sensor) {
                d = self.cap;
            }
            sum += d * d;
            if sum >= limit {
                return None;
            }
        }
        Some(sum)
    }

    /// Whether `sensor` lies on the closed side of the wall nearest to `p` (never when the map
    /// has no closed sides).
    #[inline]
    fn seen_from_a_closed_side(&self, p: Point2<f64>, sensor: Point2<f64>) -> bool {
        let Some((frames, closed)) = self.sides else {
            return false;
        };
        // only a nearest wall with a closed side is looked up (few are)
        let Some(k) = self.field.marked_nearest_wall(p) else {
            return false;
        };
        let (Some(f), Some(sides)) = (frames.get(k as usize), closed.get(k as usize)) else {
            return false;
        };
        let left = f.normal.dot(&(sensor - f.a)) > 0.0;
        sides[usize::from(!left)]
    }
}

/// Sorts `candidates` by score and keeps the `count` best that are not within 0.1 m and 2
/// degrees of a better kept one. `by_x` is scratch space.
fn keep_distinct(candidates: &mut Vec<Candidate>, count: usize, by_x: &mut Vec<(f64, usize)>) {
    const POSITION: f64 = 0.1;
    candidates.sort_by(|a, b| a.score.total_cmp(&b.score));
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
fn order_by_telling(points: &[Point2<f64>], out: &mut Vec<Point2<f64>>, telling: impl Fn(Point2<f64>) -> f64) {
    out.clear();
    out.extend_from_slice(points);
    out.sort_by(|a, b| telling(*b).total_cmp(&telling(*a)));
}

/// Up to `count` sample points spread evenly over the scan.
fn subsample(seg: &Segmentation, count: usize, out: &mut Vec<Point2<f64>>) {
    out.clear();
    let n = seg.samples.len();
    if n == 0 || count == 0 {
        return;
    }
    let step = (n as f64 / count as f64).max(1.0);
    let mut k = 0.0;
    while (k as usize) < n {
        out.push(seg.samples[k as usize].point());
        k += step;
    }
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
        let mut walls = mapserver::Wall::rectangle(0.0, 0.0, 6.0, 4.0).to_vec();
        walls.push(mapserver::Wall::new(3.0, 0.0, 3.0, 4.0));
        let thick = mapserver::thick::thicken(&mapserver::WallMap::new(walls), 0.12);
        let model = MapModel::new(thick, &mapserver::MapCornerConfig::default());
        assert!(model.closed_sides.is_some());
        let truth = Pose::new(nalgebra::Vector2::new(1.5, 2.0), 0.0);
        // sensor-frame points on the face x = 2.94 at 0.5 m spacing, 2 cm behind it as noise has them
        let points: Vec<Point2<f64>> = (0..6).map(|k| Point2::new(1.44 + 0.02, -1.25 + 0.5 * k as f64)).collect();
        let off = Pose::new(nalgebra::Vector2::new(1.62, 2.0), 0.0);
        let screen = Screen::new(&model, 0.12);
        let at_truth = screen.sum(&truth, &points, f64::INFINITY).unwrap();
        let a_wall_off = screen.sum(&off, &points, f64::INFINITY).unwrap();
        assert!(at_truth < 6.0 * 0.03f64.powi(2), "{at_truth}");
        assert!(a_wall_off >= 6.0 * 0.12f64.powi(2) * 0.99, "{a_wall_off}");
        // both lie on a wall by distance alone
        for pose in [truth, off] {
            assert!(points.iter().all(|q| model.field.distance(pose * q) < 0.04));
        }
    }

    /// A slid pose further along the wall ties with the best only when the scan cannot tell
    /// them apart: their costs summed over the beams differ by less than `cornerless_tie`. A
    /// per-beam difference that is small but holds over hundreds of beams is not a tie.
    #[test]
    fn a_cornerless_tie_is_judged_on_the_whole_scan() {
        let map = mapserver::WallMap::new(vec![mapserver::Wall::new(0.0, 0.0, 20.0, 0.0)]);
        let model = Arc::new(MapModel::new(map, &mapserver::MapCornerConfig::default()));
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

    /// Beams through mapped walls: up to `max_through_ok` the best pose may be `ok`, up to
    /// `max_through` it is an untrusted answer (`ambiguous`), beyond that no answer.
    #[test]
    fn beams_through_walls_grade_the_status() {
        let map = mapserver::WallMap::new(vec![mapserver::Wall::new(0.0, 0.0, 20.0, 0.0)]);
        let model = Arc::new(MapModel::new(map, &mapserver::MapCornerConfig::default()));
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
        let approximate = mapserver::WallMap {
            sigma: 0.1,
            ..mapserver::WallMap::new(vec![mapserver::Wall::new(0.0, 0.0, 20.0, 0.0)])
        };
        let model = Arc::new(MapModel::new(approximate, &mapserver::MapCornerConfig::default()));
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

    /// Eq. 7's cap on readings short of the map is the approximate one only for a map that
    /// declares itself approximate.
    #[test]
    fn an_approximate_map_has_its_own_cap_on_short_readings() {
        let walls = vec![mapserver::Wall::new(0.0, 0.0, 20.0, 0.0)];
        let config = LocalizerConfig { front_cap_approximate: 9.0, ..LocalizerConfig::default() };
        let cap_on = |map: mapserver::WallMap| {
            let model = Arc::new(MapModel::new(map, &mapserver::MapCornerConfig::default()));
            Localizer::new(model, config).scan_cost_config().front_cap
        };
        assert_eq!(cap_on(mapserver::WallMap::new(walls.clone())), config.cost.front_cap);
        assert_eq!(cap_on(mapserver::WallMap { sigma: 0.1, ..mapserver::WallMap::new(walls) }), 9.0);
    }

    /// A pose outside a closed building is never the answer, and is never reported; one that
    /// explains the scan about as well as the answer makes the answer `ambiguous`. With
    /// `inside_only` off it is an answer like any other.
    #[test]
    fn poses_outside_a_closed_building_are_witnesses_never_answers() {
        let map = mapserver::WallMap::new(mapserver::Wall::rectangle(0.0, 0.0, 20.0, 10.0).to_vec());
        let model = Arc::new(MapModel::new(map, &mapserver::MapCornerConfig::default()));
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
        let mut map = mapserver::WallMap::new(vec![mapserver::Wall::new(0.0, 0.0, 20.0, 0.0)]);
        let mut seen = mapserver::SeenFree::covering(Point2::new(-1.0, -1.0), Point2::new(21.0, 6.0), 0.2).unwrap();
        // the survey looked along a corridor 2 m from the wall, up to x = 10
        seen.mark_ray(Point2::new(0.0, 2.0), Point2::new(10.0, 2.0));
        map.seen_free = Some(seen);
        let model = Arc::new(MapModel::new(map, &mapserver::MapCornerConfig::default()));
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

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]
        /// The first screening pass keeps the same poses, with the same sums, whatever order it
        /// reads the points in: the order only decides how soon a pose is dropped.
        #[test]
        fn the_first_pass_keeps_the_same_poses_in_any_point_order(
            poses in proptest::collection::vec((0.0f64..12.0, -1.0f64..9.0, -3.2f64..3.2), 1..120),
            points in proptest::collection::vec((-4.0f64..4.0, -4.0f64..4.0), 1..12),
            keep in 1usize..40,
        ) {
            let model = MapModel::new(mapserver::load_map("apartment").unwrap(), &mapserver::MapCornerConfig::default());
            let points: Vec<Point2<f64>> = points.iter().map(|&(x, y)| Point2::new(x, y)).collect();
            let mut reversed = points.clone();
            reversed.reverse();
            let kept = |order: &[Point2<f64>]| {
                let mut best = Lowest::default();
                let mut pass = FirstPass::new(Screen::new(&model, 0.12), order.len(), keep, &mut best);
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
