//! Accuracy and timing summaries of a run.

use laser::{angle_diff, pose_theta, Pose};
use localize::{Status, Step};

/// Success: position within this of the truth, metres...
pub const SUCCESS_POSITION: f64 = 0.30;
/// ...and heading within this, degrees.
pub const SUCCESS_HEADING_DEG: f64 = 5.0;

/// How much worse than a wrong answer, by eq. 7 per beam over every beam, the log's true pose
/// must explain the scan for the scan to dispute the truth ([`Outcome::disputed`]). A right
/// pose costs about 1-2 a beam on a map built from a log; a whole unit more is a clear
/// difference, where twins along a corridor differ by tenths.
pub const DISPUTE_MARGIN: f64 = 1.0;

/// The header of the pose CSV (docs/design.md's six columns, then more).
pub const CSV_HEADER: &str = "scan,x,y,theta,score,status,micros,hypotheses,candidates,inliers,through,scans";

/// One CSV row; `best` is (x, y, theta, cost, inliers, through) of the reported pose, and
/// `scans` how many scans the answer rests on (1 for a single-scan answer, 0 with none).
pub fn csv_row(
    scan: usize,
    best: Option<(f64, f64, f64, f64, f64, f64)>,
    status: &str,
    micros: f64,
    hypotheses: usize,
    candidates: usize,
    scans: u32,
) -> String {
    // a pose with no cost of its own (where odometry put a track that missed the scan) leaves
    // the cost's fields empty, whatever the others hold (a pipeline sends the track's last)
    let known = |v: f64, decimals: usize| {
        if v.is_finite() && best.is_some_and(|b| b.3.is_finite()) {
            format!("{v:.decimals$}")
        } else {
            String::new()
        }
    };
    match best {
        Some((x, y, t, c, i, th)) => format!(
            "{scan},{x:.4},{y:.4},{t:.5},{},{status},{micros:.1},{hypotheses},{candidates},{},{},{scans}",
            known(c, 4),
            known(i, 3),
            known(th, 3)
        ),
        None => format!("{scan},,,,,failed,{micros:.1},{hypotheses},{candidates},,,0"),
    }
}

/// One scan's result.
#[derive(Clone, Copy, Debug)]
pub struct Outcome {
    pub status: Status,
    /// Position and heading error of the reported pose, when both it and the truth exist.
    pub error: Option<(f64, f64)>,
    pub has_truth: bool,
    pub micros: f64,
    /// Per-step microseconds: samples, line inference, filtering + corners, matching +
    /// screening, coarse cost, refinement, cost.
    pub steps: [f64; 7],
    /// The steps of the search cascade that ran.
    pub ran: localize::Ran,
    /// Microseconds of each search of the cascade, by [`localize::Step::index`] (0 when it
    /// did not run).
    pub searches: [f64; localize::Step::COUNT],
    /// A wrong answer (`ok` or `ambiguous`) that the scan itself disputes: on this map, eq. 7
    /// rates the log's true pose more than [`DISPUTE_MARGIN`] a beam worse than the answer.
    /// The log's pose may be out of step with its scan (a fast turn), or the map wrong there;
    /// either way the scan favours the answer. Said beside the counts of wrong answers, never
    /// taken from them.
    pub disputed: bool,
}

impl Outcome {
    pub fn of(status: Status, pose: Option<Pose>, truth: Option<Pose>, micros: f64) -> Self {
        let error = match (pose, truth) {
            (Some(p), Some(t)) => Some((
                (p.translation.vector - t.translation.vector).norm(),
                angle_diff(pose_theta(&p), pose_theta(&t)).abs().to_degrees(),
            )),
            _ => None,
        };
        Outcome {
            status,
            error,
            has_truth: truth.is_some(),
            micros,
            steps: [0.0; 7],
            ran: localize::Ran::default(),
            searches: [0.0; localize::Step::COUNT],
            disputed: false,
        }
    }

    /// Judges a wrong answer at `pose` against the `truth` by the scan ([`Self::disputed`]): eq.
    /// 7 over every beam at each, by `localizer`, which last located `scan`. A right answer, or
    /// one without a pose or a truth, is not judged.
    pub fn weigh_truth(
        mut self,
        localizer: &mut localize::Localizer,
        scan: &laser::ScanView<'_>,
        pose: Option<&Pose>,
        truth: Option<&Pose>,
    ) -> Self {
        if let (false, Some(pose), Some(truth)) = (self.success(), pose, truth) {
            let beams = scan.len();
            let at_answer = localizer.final_cost_below(scan, pose, f64::INFINITY, beams).value;
            let at_truth = localizer.final_cost_below(scan, truth, f64::INFINITY, beams).value;
            // an answer eq. 7 cannot cost disputes nothing; a truth it cannot cost is disputed
            self.disputed = at_answer.is_finite() && (at_truth.is_nan() || at_truth > at_answer + DISPUTE_MARGIN);
        }
        self
    }

    /// Records the step times of a segmentation and localization.
    pub fn with_steps(mut self, seg: &segment::SegmentTimes, loc: &localize::LocateTimes) -> Self {
        let us = |d: std::time::Duration| d.as_secs_f64() * 1e6;
        self.steps = [
            us(seg.samples),
            us(seg.inference),
            us(seg.corners),
            us(loc.matching),
            us(loc.coarse),
            us(loc.refine),
            us(loc.cost),
        ];
        self.ran = loc.ran;
        self.searches = loc.steps.map(us);
        self
    }

    /// Locates `scan` with `gema2`, timed, and judges the answer against the scan's truth.
    pub fn located(gema2: &mut localize::Gema2, scan: &laser::LaserScan) -> Self {
        let start = std::time::Instant::now();
        let (seg, loc) = gema2.process(&scan.view());
        let micros = start.elapsed().as_secs_f64() * 1e6;
        let pose = loc.best().map(|h| h.pose);
        let outcome = Outcome::of(loc.status, pose, scan.truth, micros).with_steps(&seg.times, &loc.times);
        outcome.weigh_truth(&mut gema2.localizer, &scan.view(), pose.as_ref(), scan.truth.as_ref())
    }

    pub fn success(&self) -> bool {
        self.error.is_some_and(|(d, a)| d <= SUCCESS_POSITION && a <= SUCCESS_HEADING_DEG)
    }

    /// A wrong `ok` at a truth the scan disputes ([`Self::disputed`]).
    pub fn disputed_ok(&self) -> bool {
        self.status == Status::Ok && self.disputed
    }
}

#[derive(Default)]
pub struct Summary {
    pub outcomes: Vec<Outcome>,
}

/// The q-quantile of `v` (sorted in place).
pub fn quantile(v: &mut [f64], q: f64) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(f64::total_cmp);
    v[((v.len() - 1) as f64 * q).round() as usize]
}

impl Summary {
    pub fn add(&mut self, o: Outcome) {
        self.outcomes.push(o);
    }

    pub fn scans(&self) -> usize {
        self.outcomes.len()
    }

    /// Scans whose reported pose is right.
    pub fn successes(&self) -> usize {
        self.outcomes.iter().filter(|o| o.success()).count()
    }

    /// Fraction of scans whose reported pose is right.
    pub fn success_rate(&self) -> f64 {
        self.successes() as f64 / self.scans().max(1) as f64
    }

    /// Scans marked ok whose pose is wrong.
    pub fn wrong_ok(&self) -> usize {
        self.outcomes.iter().filter(|o| o.status == Status::Ok && !o.success()).count()
    }

    /// Wrong `ok` answers the scan disputes the truth of ([`Outcome::disputed`]).
    pub fn disputed_wrong_ok(&self) -> usize {
        self.outcomes.iter().filter(|o| o.disputed_ok()).count()
    }

    /// Median and p99 compute time per scan, microseconds (NaN without a scan).
    pub fn time_quantiles(&self) -> (f64, f64) {
        let mut t: Vec<f64> = self.outcomes.iter().map(|o| o.micros).collect();
        (quantile(&mut t, 0.5), quantile(&mut t, 0.99))
    }

    /// Mean position error of the successes, metres; `None` without a success.
    pub fn mean_error(&self) -> Option<f64> {
        let e: Vec<f64> = self.outcomes.iter().filter(|o| o.success()).filter_map(|o| o.error.map(|e| e.0)).collect();
        (!e.is_empty()).then(|| e.iter().sum::<f64>() / e.len() as f64)
    }

    pub fn count(&self, s: Status) -> usize {
        self.outcomes.iter().filter(|o| o.status == s).count()
    }

    /// The fraction of scans that ran `step` of the search cascade.
    pub fn ran_share(&self, step: Step) -> f64 {
        let ran = self.outcomes.iter().filter(|o| o.ran.contains(step)).count();
        ran as f64 / self.scans().max(1) as f64
    }

    /// Of the scans marked ok, the fraction that are right; `None` when none is ok.
    pub fn ok_precision(&self) -> Option<f64> {
        let ok = self.count(Status::Ok);
        (ok > 0).then(|| (ok - self.wrong_ok()) as f64 / ok as f64)
    }

    pub fn render(&self) -> String {
        if self.outcomes.is_empty() {
            return "scans 0: the log holds no laser scan (or none that --every and --offset select)\n".into();
        }
        let (p50, p99) = self.time_quantiles();
        let mut s = format!(
            "scans {}  time per scan: median {:.0} us, p99 {:.0} us\nstatus: ok {}, ambiguous {}, failed {}\n",
            self.scans(),
            p50,
            p99,
            self.count(Status::Ok),
            self.count(Status::Ambiguous),
            self.count(Status::Failed)
        );
        let share = |f: fn(&Outcome) -> bool| {
            100.0 * self.outcomes.iter().filter(|o| f(o)).count() as f64 / self.scans().max(1) as f64
        };
        s += &format!(
            "first look settled {:.1} % of scans (the rest ran the full search); the slide search ran on {:.1} %, the loose slide on {:.1} %, the wider slide on {:.1} %, the grid on {:.1} %\n",
            share(|o| !o.ran.contains(Step::FullSearch)),
            share(|o| o.ran.contains(Step::Slide)),
            share(|o| o.ran.contains(Step::LooseSlide)),
            share(|o| o.ran.contains(Step::WiderSlide)),
            share(|o| o.ran.contains(Step::Grid))
        );
        let names = ["samples", "inference", "filter+corners", "matching", "coarse cost", "refine", "cost"];
        s += "median us per step:";
        for (k, name) in names.iter().enumerate() {
            let mut v: Vec<f64> = self.outcomes.iter().map(|o| o.steps[k]).collect();
            s += &format!(" {name} {:.1}", quantile(&mut v, 0.5));
        }
        s += "\n";
        s += "median us of a search, over the scans it ran on:";
        for step in localize::CASCADE.map(|c| c.step) {
            let mut v: Vec<f64> =
                self.outcomes.iter().filter(|o| o.ran.contains(step)).map(|o| o.searches[step.index()]).collect();
            if !v.is_empty() {
                s += &format!(" {} {:.1}", step.as_str(), quantile(&mut v, 0.5));
            }
        }
        s += "\n";
        if self.outcomes.iter().any(|o| o.has_truth) {
            let error = self.mean_error().map_or("- (no success)".into(), |e| format!("{:.2} cm", 100.0 * e));
            let mut precision = self.ok_precision().map_or("- (no scan ok)".into(), |p| format!("{:.1} %", 100.0 * p));
            if self.wrong_ok() > 0 {
                precision += &format!(" ({} wrong ok, {})", self.wrong_ok(), disputed_phrase(self.disputed_wrong_ok()));
            }
            s += &format!(
                "success {:.1} % (within {SUCCESS_POSITION} m and {SUCCESS_HEADING_DEG} deg of the log's poses, taken as ground truth)  mean error of successes {error}  ok precision {precision}\n",
                100.0 * self.success_rate(),
            );
        }
        s
    }
}

/// "N at a disputed truth", said beside a count of wrong answers.
pub fn disputed_phrase(n: usize) -> String {
    format!("{n} at a disputed truth")
}

/// A count of wrong answers as a table cell: "0", or "3 (2 disputed)" with how many of them
/// are at a disputed truth.
pub fn wrong_cell(wrong: usize, disputed: usize) -> String {
    match wrong {
        0 => "0".to_owned(),
        n => format!("{n} ({disputed} disputed)"),
    }
}

/// The line naming the scans (by index in the log) whose wrong `ok` is at a disputed truth,
/// the first 20 of them; empty with none.
pub fn disputed_scans(scans: &[usize]) -> String {
    const LISTED: usize = 20;
    if scans.is_empty() {
        return String::new();
    }
    let listed: Vec<String> = scans.iter().take(LISTED).map(|s| s.to_string()).collect();
    let more = match scans.len().saturating_sub(LISTED) {
        0 => String::new(),
        n => format!(" and {n} more"),
    };
    format!(
        "wrong ok at a disputed truth (the log's pose explains the scan more than {DISPUTE_MARGIN:.1} a beam worse): scans {}{more}\n",
        listed.join(", ")
    )
}

/// What a disputed truth is, said under a table that counts them.
pub fn disputed_meaning() -> String {
    format!(
        "disputed truth: a wrong answer where eq. 7 over every beam rates the log's own pose more than {DISPUTE_MARGIN:.1} a beam \
         worse than the answer (the log's pose out of step with its scan, or the map wrong there); counted as wrong all the same."
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A pose without a cost of its own (a track that missed the scan, where odometry put it)
    /// keeps its pose and status; only the cost's fields are empty. No answer is `failed`.
    #[test]
    fn a_row_without_a_cost_keeps_its_pose() {
        let row = csv_row(17, Some((1.5, -2.0, 0.25, f64::INFINITY, f64::NAN, f64::NAN)), "ambiguous", 8.0, 7, 0, 9);
        assert_eq!(row, "17,1.5000,-2.0000,0.25000,,ambiguous,8.0,7,0,,,9");
        let stale = csv_row(17, Some((1.5, -2.0, 0.25, f64::INFINITY, 0.8, 0.01)), "ambiguous", 8.0, 7, 0, 9);
        assert_eq!(stale, row);
        assert_eq!(row.split(',').count(), CSV_HEADER.split(',').count());
        let row = csv_row(3, Some((1.0, 2.0, 0.5, 0.75, 0.9, 0.01)), "ok", 100.0, 1, 2, 1);
        assert_eq!(row, "3,1.0000,2.0000,0.50000,0.7500,ok,100.0,1,2,0.900,0.010,1");
        assert_eq!(csv_row(4, None, "ambiguous", 1.0, 0, 0, 0), "4,,,,,failed,1.0,0,0,,,0");
    }

    /// No scan, no success, no `ok`: the summary says so instead of printing NaN or a 0 that
    /// reads as a measurement.
    #[test]
    fn a_summary_with_nothing_to_measure_says_so() {
        assert!(Summary::default().render().starts_with("scans 0: the log holds no laser scan"));
        let truth = laser::pose(1.0, 2.0, 0.3);
        let mut s = Summary::default();
        s.add(Outcome::of(Status::Failed, None, Some(truth), 10.0));
        s.add(Outcome::of(Status::Ambiguous, Some(laser::pose(5.0, 2.0, 0.3)), Some(truth), 12.0));
        let text = s.render();
        assert!(text.contains("success 0.0 %"), "{text}");
        assert!(text.contains("mean error of successes - (no success)"), "{text}");
        assert!(text.contains("ok precision - (no scan ok)"), "{text}");
        assert!(!text.contains("NaN"), "{text}");
        s.add(Outcome::of(Status::Ok, Some(laser::pose(1.02, 2.0, 0.3)), Some(truth), 11.0));
        let text = s.render();
        assert!(text.contains("mean error of successes 2.00 cm  ok precision 100.0 %"), "{text}");
    }

    #[test]
    fn the_disputed_scans_are_listed_up_to_twenty() {
        assert_eq!(disputed_scans(&[]), "");
        assert!(disputed_scans(&[397, 399]).ends_with("scans 397, 399\n"));
        let many: Vec<usize> = (0..23).collect();
        assert!(disputed_scans(&many).ends_with("18, 19 and 3 more\n"));
    }

    /// A wrong answer is disputed when the scan fits the map clearly better at it than
    /// at the log's pose, and only then: a log's pose turned 20 degrees off its scan is
    /// disputed by the right answer, and the right pose is never disputed by a wrong answer.
    #[test]
    fn a_truth_is_disputed_only_where_the_scan_favours_the_answer() {
        use acquire::{Scenario, SensorModel, Simulator};
        let walls = map::bundled("office").expect("a readable bundled map").expect("a bundled office");
        let model = std::sync::Arc::new(localize::MapModel::new(walls.clone(), &map::MapCornerConfig::default()));
        let mut gema2 = localize::Gema2::new(model, Default::default(), Default::default());
        let mut sim = Simulator::new(&walls, SensorModel::urg04lx(), Scenario::Clean, 3);
        let mut judged = 0;
        for _ in 0..20 {
            let scan = sim.next_scan();
            let Some(truth) = scan.truth else { continue };
            let (_, _) = gema2.process(&scan.view());
            let turned = truth * laser::pose(0.0, 0.0, 20f64.to_radians());
            let ok = |pose: &Pose, truth: &Pose| Outcome::of(Status::Ok, Some(*pose), Some(*truth), 1.0);
            let view = scan.view();
            // the log's pose (`turned`) is off; the answer is where the scan was taken
            let log_off = ok(&truth, &turned).weigh_truth(&mut gema2.localizer, &view, Some(&truth), Some(&turned));
            // the answer is off, the log right
            let answer_off = ok(&turned, &truth).weigh_truth(&mut gema2.localizer, &view, Some(&turned), Some(&truth));
            assert!(!answer_off.disputed, "a right log pose disputed by a turned answer");
            judged += usize::from(log_off.disputed);
            // a right answer, or one without a pose: nothing to judge
            let right = ok(&truth, &truth).weigh_truth(&mut gema2.localizer, &view, Some(&truth), Some(&truth));
            assert!(!right.disputed);
            let failed = Outcome::of(Status::Failed, None, Some(turned), 1.0).weigh_truth(
                &mut gema2.localizer,
                &view,
                None,
                Some(&turned),
            );
            assert!(!failed.disputed);
            // an ambiguous answer is judged as an `ok` one
            let unsure = Outcome::of(Status::Ambiguous, Some(truth), Some(turned), 1.0).weigh_truth(
                &mut gema2.localizer,
                &view,
                Some(&truth),
                Some(&turned),
            );
            assert_eq!(unsure.disputed, log_off.disputed);
        }
        assert!(judged >= 18, "only {judged} of 20 turned log poses disputed");
    }
}
