//! The localization stage (section 5): scan corners x similar map corners -> pose hypotheses
//! (eqs. 5-6) -> ranked by the cost function (eq. 7).
//!
//! Robustness over the paper's single best corner (docs/how-it-works.md, "Where the paper falls short"): the `corners_tried` best scan
//! corners are all matched, so a spurious best corner (a person's legs, a box) does not sink
//! the scan. Hypotheses then pass through stages of increasing cost and decreasing number:
//!
//! 1. matches whose arms cannot fit the map corner's are dropped ([`crate::matching::arms_fit`]);
//! 2. a distance-field screen keeps the `screened` best;
//! 3. a coarse one-sided eq. 7 over a subset of beams (first a sparser one when many pass the
//!    screen), with a noise floor that tolerates an unrefined pose, keeps the `refined` best
//!    (unmapped objects in front of walls cost little here, unlike in the screen);
//! 4. those are refined against the walls and ranked by the full one-sided eq. 7.
//!
//! All this runs first for the single best corner with few hypotheses (the [`FirstLook`]),
//! and for the `corners_tried` best only when that look's best pose is not confirmed. When
//! that is not confirmed either, the scan's longest lines are laid along the map's walls
//! ([`crate::slide`]) and those poses go through the same steps, ranked with the others; and
//! when that is not confirmed either, so are the lines too uncertain in direction for it
//! ([`crate::slide::loose_slide_lines`]). A best pose that still sees through walls sends the
//! slide search round once more with wider budgets ([`LocalizerConfig::escalated`]), and when
//! that does not help either, the grid search ([`crate::grid`]).

mod candidates;
mod cascade;
mod config;
mod ranking;
mod screen;

pub use cascade::{Ran, Step, StepSpec, When, CASCADE};
pub use config::{FirstLook, LocalizerConfig, Probes, TwinLook};
pub use screen::same_pose;

use crate::cost::{cost, cost_below, Cost, CostConfig};
use crate::lowest::Lowest;
use crate::model::MapModel;
use crate::refine::{refine, RefineConfig};
use crate::slide::{loose_slide_lines, SlideLine};
use laser::{Pose, ScanView};
use map::RayScratch;
use nalgebra::Point2;
use screen::{keep_distinct, screen_points, sort_by_score, subsample, Screen, ScreenPoint};
use segment::{ErrorModel, Segmentation};
use std::sync::Arc;
use std::time::{Duration, Instant};

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
    /// search, [`crate::slide::FROM_SLIDE`] and the index of the straight run ([`MapModel::runs`]).
    pub scan_corner: u16,
    pub map_corner: u32,
}

impl LocateTimes {
    /// Whether the full search ran: the [`FirstLook`] did not settle the scan.
    pub fn full_search(&self) -> bool {
        self.ran.contains(Step::FullSearch)
    }

    /// Whether the slide search ran: the full search's best pose was not confirmed either.
    pub fn slide_search(&self) -> bool {
        self.ran.contains(Step::Slide)
    }

    /// Whether the loose slide ran: the answer after the slide search was not `ok`, and the scan
    /// had lines of uncertain direction to lay.
    pub fn loose_slide(&self) -> bool {
        self.ran.contains(Step::LooseSlide)
    }

    /// Whether the slide search ran again with wider budgets: the best pose after the slide
    /// searches saw through walls ([`LocalizerConfig::escalate_through`]).
    pub fn escalated(&self) -> bool {
        self.ran.contains(Step::WiderSlide)
    }

    /// Whether the grid search ran ([`crate::grid`]): the best pose after the wider slide still
    /// saw through walls.
    pub fn grid_search(&self) -> bool {
        self.ran.contains(Step::Grid)
    }
}

/// Compute time of the localization steps of one scan.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct LocateTimes {
    /// Corner matching (eqs. 5-6), arm test and screening.
    pub matching: Duration,
    /// Coarse eq. 7 over the screened hypotheses.
    pub coarse: Duration,
    pub refine: Duration,
    /// Full eq. 7 over the refined hypotheses, and over the probes of an `ok` one
    /// ([`LocalizerConfig::ok_probes`]).
    pub cost: Duration,
    /// The steps of the cascade that ran ([`CASCADE`]). Each step's time above is the sum
    /// over all the steps that ran.
    pub ran: Ran,
    /// Each step's time, search and ranking, by [`Step::index`].
    pub steps: [Duration; Step::COUNT],
}

#[derive(Clone, Debug)]
pub struct Localization {
    /// Ranked hypotheses, best first.
    pub hypotheses: Vec<Hypothesis>,
    pub status: Status,
    /// Poses produced by corner matching (after the arm test, before screening), in the last
    /// search; after the first look, in its own (not its twin look's).
    pub candidates: usize,
    pub times: LocateTimes,
    /// With `record_candidates`: every candidate (pose, screening score, scan corner index) of
    /// the last search, in screening order; after the first look, its own, then its twin
    /// look's.
    pub all_candidates: Vec<(Pose, f64, u16)>,
    /// The distance between poses along a wall that the slide search used, when it ran.
    pub slide_step: Option<f64>,
}

impl Localization {
    /// No answer yet: no hypothesis, `failed`.
    pub fn none() -> Self {
        Localization {
            hypotheses: Vec::new(),
            status: Status::Failed,
            candidates: 0,
            times: LocateTimes::default(),
            all_candidates: Vec::new(),
            slide_step: None,
        }
    }

    pub fn best(&self) -> Option<&Hypothesis> {
        match self.status {
            Status::Failed => None,
            _ => self.hypotheses.first(),
        }
    }

    /// How much more per beam the nearest rival of the first hypothesis costs
    /// ([`rival_gap`]).
    pub fn rival_gap(&self, position: f64, heading: f64) -> f64 {
        rival_gap(&self.hypotheses, position, heading)
    }
}

/// How much more per beam than the first of `hyps` the cheapest of the others not within
/// `position` metres and `heading` radians of it costs: +inf with none.
pub fn rival_gap(hyps: &[Hypothesis], position: f64, heading: f64) -> f64 {
    let Some((best, rest)) = hyps.split_first() else { return f64::INFINITY };
    rest.iter()
        .filter(|h| !same_pose(&h.pose, &best.pose, position, heading))
        .map(|h| h.cost.value - best.cost.value)
        .fold(f64::INFINITY, f64::min)
}

#[derive(Clone, Copy, Debug)]
struct Candidate {
    pose: Pose,
    score: f64,
    scan_corner: u16,
    map_corner: u32,
    /// Its place in the buffer when last sorted ([`screen::sort_by_score`]): what ties keep.
    /// It lies in the padding after `scan_corner`, so a candidate stays 48 bytes.
    order: u16,
}

// a search holds up to 1536 candidates (74 kB, its largest buffer): the order costs none
const _: () = assert!(std::mem::size_of::<Candidate>() == 48);

/// The localization stage: one scan's segmentation in, ranked pose hypotheses and a status
/// out ([`Localizer::locate`]). Its buffers are kept from scan to scan.
pub struct Localizer {
    /// Where the last `ok` scan put the sensor, while tracking.
    prior: Option<Point2<f64>>,
    model: Arc<MapModel>,
    pub config: LocalizerConfig,
    screen_pts: Vec<ScreenPoint>,
    /// One in `prescreen_step` screening points: the first screening pass.
    screen_few: Vec<ScreenPoint>,
    /// `screen_few` in the order the first pass reads them for one scan corner or slid line.
    screen_order: Vec<ScreenPoint>,
    /// The first screening pass's best sums.
    best_sums: Lowest,
    /// The lowest coarse costs so far ([`Localizer::coarse_cost`]).
    coarse_lowest: Lowest,
    refine_pts: Vec<Point2<f64>>,
    polish_pts: Vec<Point2<f64>>,
    candidates: Vec<Candidate>,
    /// [`Self::keep_best`]'s kept candidates as (x, position), sorted by x.
    kept_by_x: Vec<(f64, usize)>,
    /// The grid search's positions.
    grid: Vec<Point2<f64>>,
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
            grid: Vec::new(),
            lines: Vec::new(),
            slide_lines: Vec::new(),
            scratch: RayScratch::default(),
            expected: Vec::new(),
            error: config.error,
            cost: config.cost,
            out: Localization::none(),
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

    /// [`locate_set_lines`](Self::locate_set_lines) with every search kept to poses within
    /// `radius` of `centre`, as tracking keeps them (`track`): the sequential localizer's
    /// search about a track whose refined pose left the odometry's spread
    /// ([`crate::sequential`]).
    pub fn locate_near(
        &mut self,
        scan: &ScanView<'_>,
        seg: &Segmentation,
        centre: Point2<f64>,
        radius: f64,
    ) -> &Localization {
        let (prior, track) = (self.prior, self.config.track_radius);
        self.prior = Some(centre);
        self.config.track_radius = Some(radius);
        self.locate_lines_given(scan, seg);
        (self.prior, self.config.track_radius) = (prior, track);
        &self.out
    }

    /// The scan's lines for [`locate_set_lines`](Self::locate_set_lines),
    /// [`locate_near`](Self::locate_near) and [`search_around`](Self::search_around), which the
    /// sequential localizer runs on one scan.
    pub fn set_lines(&mut self, lines: impl IntoIterator<Item = SlideLine>) {
        self.lines.clear();
        self.lines.extend(lines);
    }

    /// [`locate`](Self::locate) with the lines of [`set_lines`](Self::set_lines).
    pub fn locate_set_lines(&mut self, scan: &ScanView<'_>, seg: &Segmentation) -> &Localization {
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
        let screen = Screen::new(&model, &cfg);
        let mean = |points: &[ScreenPoint]| {
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
    /// readings short of it ([`LocalizerConfig::front_cap_approximate`]) and share of it for
    /// furniture ([`LocalizerConfig::clutter_share_approximate`]).
    fn scan_cost_config(&self) -> CostConfig {
        let mut c = self.config.cost;
        if self.model.map.is_approximate() {
            c.front_cap = self.config.front_cap_approximate;
            c.clutter_share = self.config.clutter_share_approximate;
            c.edge_step = 0.0;
        }
        c
    }

    /// The cost configuration of a hypothesis's final eq. 7: never expect the scan to agree
    /// with the map better than the map is accurate.
    fn final_cost_config(&self) -> CostConfig {
        CostConfig { sigma_floor: self.cost.sigma_floor.max(self.model.map.sigma), ..self.cost }
    }

    /// The per-scan state every search and [`search_around`](Self::search_around) read: eq. 7's
    /// e(d) and form for this scan, and the points refinement fits.
    fn prepare(&mut self, scan: &ScanView<'_>, seg: &Segmentation) {
        // a scan noisier than the configured e(d) would count the right pose's beams as seeing
        // through walls
        self.error = self.config.error.scaled(segment::noise::usable_scale(seg.noise_scale));
        self.cost = self.scan_cost_config();
        let drops = self.config.surface_dropouts;
        self.cost.skip_no_returns = drops > 0 && crate::cost::surface_dropouts(scan, &self.error) >= drops;
        subsample(seg, self.config.refine_points, &mut self.refine_pts);
    }

    /// The scan's screening points, and one in `prescreen_step` of them for the first pass:
    /// what every search of the scan and [`search_around`](Self::search_around) screen with.
    fn set_screen_points(&mut self, seg: &Segmentation) {
        let cfg = &self.config;
        screen_points(seg, &self.lines, cfg.screen_points, cfg.screen_long_line, &mut self.screen_pts);
        self.screen_few.clear();
        self.screen_few.extend(self.screen_pts.iter().step_by(cfg.prescreen_step.max(1)));
    }

    /// Screens each of `starts` by the distance field (with the lines of
    /// [`set_lines`](Self::set_lines)), as a search screens its candidates, then refines the
    /// `keep` best and costs them by the full eq. 7: a search over the poses
    /// a track may have reached, for the sequential localizer ([`crate::sequential`]). `out`
    /// gets (pose, cost) of the refined ones that cost less than `below` per beam, cheapest
    /// first, less those known to cost more than one refined before them (eq. 7 stopped early:
    /// [`crate::cost::cost_below`]). A caller that wants only a pose cheaper than one it holds
    /// passes that pose's cost as `below` (else infinity): where the ray caster marches beam
    /// by beam, a dearer pose then costs only the beams that show it dearer.
    pub fn search_around(
        &mut self,
        scan: &ScanView<'_>,
        seg: &Segmentation,
        starts: &[Pose],
        (keep, below): (usize, f64),
        out: &mut Vec<(Pose, Cost)>,
    ) {
        out.clear();
        self.prepare(scan, seg);
        self.set_screen_points(seg);
        let cfg = self.config;
        let model = Arc::clone(&self.model);
        let screen = Screen::new(&model, &cfg);
        // two passes, as a search screens its candidates: one in `prescreen_step` points for
        // every start, then every point for the best few of those. Tracking screens hundreds of
        // starts a track, and screening them was most of a tracked scan's time.
        let few = (keep * AROUND_PRESCREENED_PER_KEPT).max(AROUND_PRESCREENED_LEAST);
        self.best_sums.clear();
        self.candidates.clear();
        let two_passes = starts.len() > few;
        let (first_pass, first_keep) = if two_passes { (&self.screen_few, few) } else { (&self.screen_pts, keep) };
        let about_a_prediction = screen.without_bounds();
        for p in starts {
            let limit = self.best_sums.kth(first_keep);
            if let Some(sum) = about_a_prediction.sum(p, first_pass, limit) {
                self.best_sums.offer(sum, first_keep);
                self.candidates.push(Candidate { pose: *p, score: sum, scan_corner: 0, map_corner: 0, order: 0 });
            }
        }
        if two_passes {
            sort_by_score(&mut self.candidates);
            self.candidates.truncate(few);
            self.best_sums.clear();
            let mut kept = 0;
            for k in 0..self.candidates.len() {
                let pose = self.candidates[k].pose;
                let limit = self.best_sums.kth(keep);
                if let Some(sum) = screen.sum(&pose, &self.screen_pts, limit) {
                    self.best_sums.offer(sum, keep);
                    self.candidates[kept] = Candidate { pose, score: sum, scan_corner: 0, map_corner: 0, order: 0 };
                    kept += 1;
                }
            }
            self.candidates.truncate(kept);
        }
        sort_by_score(&mut self.candidates);
        self.candidates.truncate(keep);
        let final_cfg = self.final_cost_config();
        for c in &self.candidates {
            let refined = refine(&model, &self.refine_pts, &c.pose, &cfg.refine).0;
            // only the cheapest is wanted: one known to cost more than it is stopped early
            let bound = out.iter().map(|(_, c)| c.value).fold(below, f64::min);
            let cost = crate::cost::cost_below(
                scan,
                &refined,
                &model.caster,
                &self.error,
                &final_cfg,
                bound,
                &mut self.scratch,
                &mut self.expected,
            );
            if cost.value.is_finite() && cost.value < below {
                out.push((refined, cost));
            }
        }
        out.sort_by(|a, b| a.1.value.total_cmp(&b.1.value));
    }

    /// How well the last scan refined or located pins down the position at `pose`, and along
    /// which direction least ([`crate::refine::weakest_direction`], over refinement's points).
    pub fn weakest_direction(&self, pose: &Pose) -> (f64, nalgebra::Vector2<f64>) {
        crate::refine::weakest_direction(&self.model, &self.refine_pts, pose, self.config.refine.final_gate)
    }

    /// Eq. 7 of `pose` for the last scan prepared, as a hypothesis's final cost but over about
    /// `beams` equispaced beams, stopped early (+inf) once it is known to cost more than
    /// `bound` ([`cost_below`]).
    pub fn final_cost_below(&mut self, scan: &ScanView<'_>, pose: &Pose, bound: f64, beams: usize) -> Cost {
        let model = Arc::clone(&self.model);
        let mut final_cfg = self.final_cost_config();
        final_cfg.stride = (scan.len() / beams.max(1)).max(1);
        cost_below(scan, pose, &model.caster, &self.error, &final_cfg, bound, &mut self.scratch, &mut self.expected)
    }

    /// Whether `pose` lies where the robot cannot be (outside a closed building or the
    /// surveyed free space), when answers are kept to where it can.
    pub fn off_limits(&self, pose: &Pose) -> bool {
        ranking::is_outside(&self.model, self.config.inside_only, pose)
    }

    fn locate_lines_given(&mut self, scan: &ScanView<'_>, seg: &Segmentation) -> &Localization {
        self.out.hypotheses.clear();
        self.out.status = Status::Failed;
        self.out.times = LocateTimes::default();
        self.out.slide_step = None;
        self.prepare(scan, seg);
        self.set_screen_points(seg);
        let ran = self.run_cascade(scan, seg);
        if ran.contains(Step::Slide) {
            if self.out.status == Status::Ok && self.short_of_the_slides_bar() {
                self.out.status = Status::Ambiguous;
            }
            // with no corner in view, an equally good pose further along the same wall means the
            // scan does not say where along it the sensor is (a corridor whose ends are out of
            // range): that is no answer, as the paper's cornerless scan. Twins elsewhere (two
            // identical aisles) stay `ambiguous`: the scan does fix each of them. Nor is a pose
            // the scan contradicts: with no corner to anchor it, a slid pose whose beams see
            // through a drawn map's walls (more than an `ok` pose may) is only the least bad
            // place for lines the map has nowhere.
            if seg.corners.is_empty()
                && self.out.status == Status::Ambiguous
                && (self.slides_along_a_wall() || self.sees_through_walls())
            {
                self.out.status = Status::Failed;
            }
        }
        if self.out.status == Status::Ok && self.too_weak_for_ok() {
            self.out.status = Status::Ambiguous;
        }
        if self.out.status == Status::Ok {
            let probing = Instant::now();
            if !self.best_withstands_probes(scan) {
                self.out.status = Status::Ambiguous;
            }
            self.out.times.cost += probing.elapsed();
        }
        self.report();
        self.prior = match (self.config.track_radius, self.out.status, self.out.hypotheses.first()) {
            (Some(_), Status::Ok, Some(h)) => Some(Point2::from(h.pose.translation.vector)),
            _ => None,
        };
        &self.out
    }

    /// Runs the steps of [`CASCADE`] in order, each that its settings switch on, whose
    /// predecessor ran and whose condition holds on the answer so far; returns the steps that
    /// ran. Each step's time is added to [`LocateTimes::steps`].
    fn run_cascade(&mut self, scan: &ScanView<'_>, seg: &Segmentation) -> Ran {
        let mut ran = Ran::default();
        for spec in CASCADE {
            if spec.after.is_some_and(|before| !ran.contains(before))
                || !spec.step.switched_on(&self.config)
                || (spec.step == Step::FirstLook && self.model.map.is_approximate())
            {
                continue;
            }
            let due = match spec.when {
                When::Unconfirmed => !self.config.first_look.confirms(self.out.status, self.out.hypotheses.first()),
                When::NotOkAfterSlide => !self.ok_after_the_slide(),
                When::SeesThroughWalls => self.escalates(),
            };
            if due {
                let t = Instant::now();
                if self.run_step(spec.step, scan, seg) {
                    ran.insert(spec.step);
                }
                self.out.times.steps[spec.step.index()] += t.elapsed();
            }
        }
        self.out.times.ran = ran;
        ran
    }

    /// The [`TwinLook`] after a first look that confirmed an `ok` pose: the best few scan
    /// corners' candidates the screen rates nearly as well as that pose, searched and ranked
    /// with the first look's hypotheses. A twin it finds makes the scan `ambiguous` (or, were
    /// it cheaper, the answer); with none the scan settles as before.
    fn look_for_twins(&mut self, scan: &ScanView<'_>, seg: &Segmentation) {
        let twins = self.config.first_look.twins;
        if twins.corners == 0 {
            return;
        }
        let Some(best) = self.out.hypotheses.first().map(|h| h.pose) else { return };
        let model = Arc::clone(&self.model);
        let Some(sum) = Screen::new(&model, &self.config).sum(&best, &self.screen_few, f64::INFINITY) else {
            return;
        };
        // a pose that fits to the last bit would bar its own twin, which fits as well, not better
        let sum = sum.max(TWIN_SUM_FLOOR * self.screen_few.len() as f64);
        // the scan's candidates stay the first look's, those recorded gain the twin look's
        let (candidates, mut recorded) = (self.out.candidates, std::mem::take(&mut self.out.all_candidates));
        let source = Source::Twins { corners: twins.corners, below: twins.bound * sum };
        self.search(scan, seg, source, twins.prescreened, twins.screened, twins.refined);
        self.out.candidates = candidates;
        recorded.append(&mut self.out.all_candidates);
        self.out.all_candidates = recorded;
        self.rank();
    }

    /// One step of the cascade with its budgets, then [`rank`](Self::rank); false when it
    /// found nothing to search (the loose slide with no loose line).
    fn run_step(&mut self, step: Step, scan: &ScanView<'_>, seg: &Segmentation) -> bool {
        let cfg = self.config;
        let cap = self.model.map.is_approximate() && cfg.screened_approximate > 0;
        // what a search keeps for the coarse cost (LocalizerConfig::screened_approximate)
        let screened = |budget: usize| if cap { budget.min(cfg.screened_approximate) } else { budget };
        match step {
            Step::FirstLook => {
                let first = cfg.first_look;
                self.search(
                    scan,
                    seg,
                    Source::Corners(first.corners),
                    first.prescreened,
                    first.screened,
                    first.refined,
                );
                self.rank();
                if self.out.status == Status::Ok && first.confirms(self.out.status, self.out.hypotheses.first()) {
                    self.look_for_twins(scan, seg);
                }
            }
            Step::FullSearch => {
                let screened = screened(cfg.screened);
                self.search(scan, seg, Source::Corners(cfg.corners_tried), cfg.prescreened, screened, cfg.refined);
                self.rank();
            }
            Step::Slide => {
                self.search(scan, seg, Source::Slides, cfg.prescreened, screened(cfg.slide.screened), cfg.refined);
                self.rank();
            }
            Step::LooseSlide => {
                loose_slide_lines(&self.lines, &cfg.slide, &mut self.slide_lines);
                if self.slide_lines.is_empty() {
                    return false;
                }
                let screened = screened(cfg.slide.loose_screened);
                self.search(scan, seg, Source::LooseSlides, cfg.prescreened, screened, cfg.refined);
                self.rank();
            }
            Step::WiderSlide => {
                let wide = cfg.escalated();
                self.search_wider(scan, seg, Source::Slides, wide.prescreened, wide.slide.screened);
            }
            Step::Grid => {
                self.search_wider(scan, seg, Source::Grid, cfg.grid.prescreened, cfg.grid.screened);
            }
        }
        true
    }

    /// Whether the best pose after the slide searches is one the scan contradicts, so that the
    /// slide search runs again with the budgets of [`LocalizerConfig::escalated`]: it is
    /// `failed`, or more of its beams see through walls than
    /// [`LocalizerConfig::escalate_through`] and [`LocalizerConfig::escalate_min_beams`] allow,
    /// on a map that states no error (on one that does, right poses see through its errors).
    fn escalates(&self) -> bool {
        self.model.map.sigma <= 0.0
            && (self.out.status == Status::Failed
                || self.out.hypotheses.first().is_none_or(|h| self.sees_through_exact_walls(&h.cost)))
    }

    /// [`search`](Self::search) with the budgets of [`LocalizerConfig::escalated`] (the search
    /// reads them from the configuration), then [`rank`](Self::rank) as configured.
    fn search_wider(
        &mut self,
        scan: &ScanView<'_>,
        seg: &Segmentation,
        source: Source,
        prescreened: usize,
        screened: usize,
    ) {
        let cfg = self.config;
        let wide = cfg.escalated();
        self.config = wide;
        self.search(scan, seg, source, prescreened, screened, wide.refined);
        self.config = cfg;
        self.rank();
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
            sort_by_score(&mut self.candidates);
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
}

/// The least screen sum a point of the [`TwinLook`]'s bound counts, square metres: (5 mm)²,
/// below any sensor's noise, so that a confirmed pose that fits exactly still lets through a
/// twin that fits as well.
const TWIN_SUM_FLOOR: f64 = 2.5e-5;

/// Where a search's candidate poses come from.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Source {
    /// The given number of best scan corners, matched against similar map corners (eqs. 5-6).
    Corners(usize),
    /// As `Corners`, keeping only the poses whose first-pass screen sum is at most `below`:
    /// the [`TwinLook`]'s rivals of a pose the first look is sure of.
    Twins { corners: usize, below: f64 },
    /// The longest scan lines laid along every map wall ([`crate::slide`]).
    Slides,
    /// The lines `Slides` passed over for their uncertain direction
    /// ([`crate::slide::loose_slide_lines`]), once `Slides` gave no confirmed pose; the caller
    /// chooses them into `Localizer::slide_lines`.
    LooseSlides,
    /// Poses on a grid over the free space at the headings the scan's lines give
    /// ([`crate::grid`]).
    Grid,
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

/// [`Localizer::search_around`] screens every start on one in `prescreen_step` points and keeps
/// this many per pose it refines (and at least [`AROUND_PRESCREENED_LEAST`]) for the screen on
/// every point. With 3 refined: 48 of a tracked scan's 625 starts. At 8 per refined pose the
/// sequential evaluation's wrong `ok` rose on freiburg-079; at 16 and more it did not.
const AROUND_PRESCREENED_PER_KEPT: usize = 16;
const AROUND_PRESCREENED_LEAST: usize = 32;

#[cfg(test)]
mod tests {
    use super::*;

    /// Eq. 7's cap on readings short of the map is the approximate one only for a map that
    /// declares itself approximate.
    #[test]
    fn an_approximate_map_has_its_own_cap_on_short_readings() {
        let walls = vec![map::Wall::new(0.0, 0.0, 20.0, 0.0)];
        let config = LocalizerConfig { front_cap_approximate: 9.0, ..LocalizerConfig::default() };
        let cap_on = |map: map::WallMap| {
            let model = Arc::new(MapModel::new(map, &map::MapCornerConfig::default()));
            Localizer::new(model, config).scan_cost_config().front_cap
        };
        assert_eq!(cap_on(map::WallMap::new(walls.clone())), config.cost.front_cap);
        assert_eq!(cap_on(map::WallMap { sigma: 0.1, ..map::WallMap::new(walls) }), 9.0);
    }
}
