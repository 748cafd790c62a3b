//! `--sequential` of `gema2 locate` and `gema2 evaluate`: the sequential localizer
//! ([`localize::sequential`]) over a log, with the log's odometry or odometry drawn from its
//! true motion, cold starts every N scans, and the figures of a run: how soon each start is
//! sure, how often it is wrong, and what tracking costs.

use crate::report::{quantile, Outcome, SUCCESS_HEADING_DEG, SUCCESS_POSITION};
use anyhow::{bail, Result};
use clap::Args;
use laser::motion::{DriftingOdometry, OdometryNoise};
use laser::{LaserScan, Pose};
use localize::{Gema2, Gema2Config, MapModel, Sequential, SequentialAnswer, Status};
use segment::Segmenter;
use std::sync::Arc;
use std::time::Instant;

/// The odometry and restarts of a sequential run.
#[derive(Args, Clone, Debug, Default)]
pub struct SequentialArgs {
    /// Locate with the sequential localizer: hypotheses carried from scan to scan by odometry
    /// (the log's, or drawn with --odom-noise), `ok` once one leads on the evidence so far.
    #[arg(long)]
    pub sequential: bool,
    /// For evaluation: replace the log's odometry with odometry drawn from its true motion by
    /// the odometry motion model with these alphas (AMCL's alpha1..alpha4), so that it drifts.
    #[arg(long, value_name = "A1,A2,A3,A4", value_delimiter = ',')]
    pub odom_noise: Option<Vec<f64>>,
    /// The seed of --odom-noise.
    #[arg(long, default_value_t = 1)]
    pub odom_seed: u64,
    /// Forget every hypothesis each N located scans: N scans a cold start.
    #[arg(long, value_name = "N")]
    pub restart_every: Option<usize>,
}

impl SequentialArgs {
    /// The drawn odometry's noise, checked.
    pub fn noise(&self) -> Result<Option<OdometryNoise>> {
        self.odom_noise.as_deref().map(odometry_noise).transpose()
    }

    /// Whether any sequential option was given without `--sequential`.
    pub fn check(&self) -> Result<()> {
        if !self.sequential && (self.odom_noise.is_some() || self.restart_every.is_some()) {
            bail!("--odom-noise and --restart-every go with --sequential");
        }
        if self.restart_every == Some(0) {
            bail!("--restart-every must be at least 1");
        }
        Ok(())
    }
}

/// `--odom-noise A1,A2,A3,A4` (of `locate`, `evaluate` and `sim`), checked.
pub fn odometry_noise(alphas: &[f64]) -> Result<OdometryNoise> {
    OdometryNoise::from_alphas(alphas).map_err(|e| anyhow::anyhow!("--odom-noise: {e}"))
}

/// Where each located scan's odometry comes from: the log's, or drawn from the true motion.
pub struct Odometry {
    drawn: Option<DriftingOdometry>,
}

impl Odometry {
    pub fn new(noise: Option<OdometryNoise>, seed: u64) -> Self {
        Odometry { drawn: noise.map(|n| DriftingOdometry::new(n, seed)) }
    }

    /// The odometry of the next located scan: `logged` as the log gives it, or drawn from the
    /// motion between the last scan's truth and `truth`. A cut (`cut`: the robot was carried
    /// elsewhere) is no motion to the odometry.
    pub fn next(&mut self, logged: Option<Pose>, truth: Option<&Pose>, cut: bool) -> Result<Option<Pose>> {
        let Some(drawn) = self.drawn.as_mut() else { return Ok(logged) };
        let Some(truth) = truth else {
            bail!("--odom-noise draws odometry from the log's true poses, and a scan has none");
        };
        Ok(Some(drawn.next(truth, cut)))
    }
}

/// One located scan of a sequential run.
#[derive(Clone, Copy, Debug)]
pub struct SeqOutcome {
    pub outcome: Outcome,
    /// The located scan's place in its start, from 1.
    pub in_start: usize,
    pub answer: SequentialAnswer,
}

impl SeqOutcome {
    /// An `ok` answer the truth shows wrong.
    pub fn wrong_ok(&self) -> bool {
        self.answer.status == Status::Ok && self.outcome.has_truth && !self.outcome.success()
    }
}

/// A sequential run over scans, with its restarts.
pub struct SeqRun {
    segmenter: Box<dyn Segmenter>,
    pub sequential: Sequential,
    restart_every: Option<usize>,
    located: usize,
    pub outcomes: Vec<SeqOutcome>,
}

impl SeqRun {
    /// The segmenter and sequential localizer of `config` on `model`, as `gema2 locate` makes
    /// its [`Gema2`], with a cold start every `restart_every` located scans.
    pub fn new(model: Arc<MapModel>, config: &Gema2Config, restart_every: Option<usize>) -> Self {
        let Gema2 { segmenter, localizer } = Gema2::new(model, config.segmenter, config.localizer);
        let sequential = Sequential::new(localizer, config.sequential);
        SeqRun { segmenter, sequential, restart_every, located: 0, outcomes: Vec::new() }
    }

    /// Segments and locates `scan`, whose odometry is `odometry`; a cold start first when one
    /// is due.
    pub fn locate(&mut self, scan: &LaserScan, odometry: Option<Pose>) -> SeqOutcome {
        if self.restart_every.is_some_and(|n| self.located.is_multiple_of(n)) {
            self.sequential.reset();
        }
        self.located += 1;
        let in_start = self.restart_every.map_or(self.located, |n| (self.located - 1) % n + 1);
        let start = Instant::now();
        let view = scan.view();
        let seg = self.segmenter.segment(&view);
        let answer = self.sequential.locate(&view, seg, odometry);
        let micros = start.elapsed().as_secs_f64() * 1e6;
        let pose = answer.pose.filter(|_| answer.status != Status::Failed);
        let outcome = Outcome::of(answer.status, pose, scan.truth, micros).weigh_truth(
            &mut self.sequential.localizer,
            &view,
            pose.as_ref(),
            scan.truth.as_ref(),
        );
        let o = SeqOutcome { outcome, in_start, answer };
        self.outcomes.push(o);
        o
    }

    pub fn summary(&self) -> SeqSummary {
        SeqSummary::of(&self.outcomes)
    }
}

/// The figures of a sequential run.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SeqSummary {
    pub scans: usize,
    pub starts: usize,
    /// Per start: the located scans to its first right `ok` (none within the start: `None`).
    pub to_first_fix: Vec<Option<usize>>,
    pub wrong_ok: usize,
    /// Of `wrong_ok`, those at a truth the scan disputes ([`Outcome::disputed`]).
    pub disputed: usize,
    pub ok: usize,
    /// Scans after a start's first right `ok`, those of them whose pose is right, and those
    /// whose pose is wrong at a truth the scan disputes.
    pub after_fix: usize,
    pub right_after_fix: usize,
    pub disputed_after_fix: usize,
    /// Microseconds of the scans that tracked (no global search).
    pub tracking_micros: Vec<f64>,
    pub all_micros: Vec<f64>,
    pub has_truth: bool,
}

impl SeqSummary {
    pub fn of(outcomes: &[SeqOutcome]) -> Self {
        let mut s = SeqSummary { scans: outcomes.len(), ..Default::default() };
        let mut fixed = false;
        for o in outcomes {
            if o.in_start == 1 {
                s.starts += 1;
                s.to_first_fix.push(None);
                fixed = false;
            }
            let right = o.outcome.success();
            let ok = o.answer.status == Status::Ok;
            s.has_truth |= o.outcome.has_truth;
            s.ok += usize::from(ok);
            s.wrong_ok += usize::from(o.wrong_ok());
            s.disputed += usize::from(o.outcome.disputed_ok());
            if fixed {
                s.after_fix += 1;
                s.right_after_fix += usize::from(right);
                s.disputed_after_fix += usize::from(o.outcome.disputed);
            } else if ok && right {
                fixed = true;
                if let Some(last) = s.to_first_fix.last_mut() {
                    *last = Some(o.in_start);
                }
            }
            if !o.answer.global {
                s.tracking_micros.push(o.outcome.micros);
            }
            s.all_micros.push(o.outcome.micros);
        }
        s
    }

    /// The median located scans to a start's first right `ok` (a start with none counts as
    /// never), as printed: a count, `never`, or `-` with no start.
    pub fn median_to_fix(&self) -> String {
        let mut v: Vec<f64> = self.to_first_fix.iter().map(|f| f.map_or(f64::INFINITY, |n| n as f64)).collect();
        match (!v.is_empty()).then(|| quantile(&mut v, 0.5)) {
            None => "-".into(),
            Some(m) if m.is_finite() => format!("{m:.0}"),
            Some(_) => "never".into(),
        }
    }

    /// The median time a scan, microseconds (0 with none).
    pub fn median_micros(&self) -> f64 {
        let mut all = self.all_micros.clone();
        if all.is_empty() {
            0.0
        } else {
            quantile(&mut all, 0.5)
        }
    }

    /// The share of starts with a right `ok` within `n` located scans.
    pub fn fixed_within(&self, n: usize) -> f64 {
        let hits = self.to_first_fix.iter().filter(|f| f.is_some_and(|k| k <= n)).count();
        hits as f64 / self.starts.max(1) as f64
    }

    pub fn wrong_ok_share(&self) -> f64 {
        self.wrong_ok as f64 / self.scans.max(1) as f64
    }

    /// The wrong `ok` count as the table and the summary say it: "2 (0.99 % of scans)", and how many
    /// of them are at a disputed truth when any is wrong.
    pub fn wrong_ok_cell(&self) -> String {
        let mut cell = format!("{} ({:.2} % of scans", self.wrong_ok, 100.0 * self.wrong_ok_share());
        if self.wrong_ok > 0 {
            cell += &format!("; {}", crate::report::disputed_phrase(self.disputed));
        }
        cell + ")"
    }

    pub fn right_after_fix_share(&self) -> Option<f64> {
        (self.after_fix > 0).then(|| self.right_after_fix as f64 / self.after_fix as f64)
    }

    /// The share right after the first fix as the table and the summary say it: "97.38 %",
    /// and how many of the wrong poses are at a disputed truth when any is wrong; `-` with no
    /// fix.
    pub fn right_after_fix_cell(&self, decimals: usize) -> String {
        let Some(share) = self.right_after_fix_share() else { return "- (no fix)".into() };
        let mut cell = format!("{:.decimals$} %", 100.0 * share);
        let wrong = self.after_fix - self.right_after_fix;
        if wrong > 0 {
            cell += &format!(" ({} of {wrong} wrong at a disputed truth)", self.disputed_after_fix);
        }
        cell
    }

    pub fn tracking(&self) -> Option<(f64, f64)> {
        let mut v = self.tracking_micros.clone();
        (!v.is_empty()).then(|| (quantile(&mut v, 0.5), quantile(&mut v, 0.99)))
    }

    /// The lines `gema2 locate --sequential` prints.
    pub fn render(&self) -> String {
        let mut s = String::new();
        s += &format!(
            "sequential: {} scans, {} starts; ok {}; median {:.0} us a scan\n",
            self.scans,
            self.starts,
            self.ok,
            self.median_micros()
        );
        match self.tracking() {
            Some((p50, p99)) => {
                s += &format!(
                    "tracking (no global search) on {} scans: median {p50:.0} us, p99 {p99:.0} us\n",
                    self.tracking_micros.len()
                )
            }
            None => s += "tracking: never (every scan ran the global search)\n",
        }
        if self.has_truth {
            let median = self.median_to_fix();
            let after = self.right_after_fix_cell(2);
            s += &format!(
                "first right ok after a median of {median} located scans; within 3 on {:.1} % of starts; wrong ok {}; right after the first fix (within {SUCCESS_POSITION} m and {SUCCESS_HEADING_DEG} deg) {after}\n",
                100.0 * self.fixed_within(3),
                self.wrong_ok_cell(),
            );
        }
        s
    }
}

/// What a run's table row leaves out, a line each, to look into: the starts with no right `ok`
/// within `within` located scans ([`SeqSummary::to_first_fix`]), by the log line of the
/// start's first scan and the located scans to its first right `ok`; and the wrong `ok`
/// answers, by log line, with how far off they were (`*`: at a disputed truth). `summary` is
/// [`SeqSummary::of`] `outcomes`, and `lines[k]` the log line of `outcomes[k]`'s scan. Nothing
/// for a run without truth.
pub fn to_look_into(summary: &SeqSummary, outcomes: &[SeqOutcome], lines: &[usize], within: usize) -> Vec<String> {
    if !summary.has_truth {
        return Vec::new();
    }
    let located = || outcomes.iter().zip(lines);
    let firsts = located().filter(|(o, _)| o.in_start == 1).map(|(_, &line)| line);
    let slow: Vec<String> = firsts
        .zip(&summary.to_first_fix)
        .filter(|(_, fix)| fix.is_none_or(|n| n > within))
        .map(|(line, fix)| format!("{line}: {}", fix.map_or("never".to_string(), |n| n.to_string())))
        .collect();
    let wrong: Vec<String> = located()
        .filter(|(o, _)| o.wrong_ok())
        .map(|(o, line)| {
            let off = o.outcome.error.map_or("no pose".to_string(), |(m, deg)| format!("{m:.2} m {deg:.1} deg"));
            format!("{line}{}: {off}", if o.outcome.disputed { "*" } else { "" })
        })
        .collect();
    let mut said = Vec::new();
    if !slow.is_empty() {
        said.push(format!(
            "starts with no right ok within {within} scans (log line of the first scan: scans to the first right ok): {}",
            slow.join(", ")
        ));
    }
    if !wrong.is_empty() {
        said.push(format!("wrong ok (log line: how far off; * at a disputed truth): {}", wrong.join(", ")));
    }
    said
}

/// How one kidnapping went: the robot located along one stretch, then carried elsewhere with
/// no odometry across the cut.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Kidnap {
    /// The last scan after the cut (1 = the first scan after it) still `ok` on the old place:
    /// within 3 m of the last true pose before the cut; 0 when none was.
    pub last_old_ok: usize,
    /// The wrong `ok` answers after the cut, wherever they lie.
    pub wrong_ok: usize,
    /// Of `wrong_ok`, those at a truth the scan disputes ([`Outcome::disputed`]).
    pub disputed: usize,
    /// The first scan after the cut with a right `ok` on the new place.
    pub new_fix: Option<usize>,
}

impl Kidnap {
    /// Judges the outcomes after a cut; `old` is the last true pose before it.
    pub fn judge(after: &[SeqOutcome], old: &Pose) -> Self {
        let mut k = Kidnap::default();
        for (i, o) in after.iter().enumerate() {
            if o.answer.status != Status::Ok {
                continue;
            }
            let right = o.outcome.success();
            let near_old = o.answer.pose.is_some_and(|p| (p.translation.vector - old.translation.vector).norm() < 3.0);
            if near_old && !right {
                k.last_old_ok = i + 1;
            }
            k.wrong_ok += usize::from(!right);
            k.disputed += usize::from(o.outcome.disputed_ok());
            if right && k.new_fix.is_none() {
                k.new_fix = Some(i + 1);
            }
        }
        k
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn outcome(in_start: usize, status: Status, error: Option<(f64, f64)>) -> SeqOutcome {
        let mut outcome = Outcome::of(status, None, None, 1.0);
        (outcome.error, outcome.has_truth) = (error, true);
        let answer =
            SequentialAnswer { status, pose: None, cost: None, scans: 1, global: true, tracks: 1, track: None };
        SeqOutcome { outcome, in_start, answer }
    }

    /// The starts that miss the bar and the wrong `ok` answers are named by log line; a start
    /// fixed in time and a right `ok` are not.
    #[test]
    fn what_to_look_into_names_the_slow_starts_and_the_wrong_oks() {
        let right = Some((0.05, 1.0));
        let far = Some((12.5, 90.0));
        let outcomes = [
            // fixed on its second scan
            outcome(1, Status::Ambiguous, far),
            outcome(2, Status::Ok, right),
            // a wrong ok, then fixed on the fourth scan
            outcome(1, Status::Ok, far),
            outcome(2, Status::Ambiguous, right),
            outcome(3, Status::Ambiguous, right),
            outcome(4, Status::Ok, right),
            // never fixed
            outcome(1, Status::Ambiguous, right),
        ];
        let lines = [10, 12, 14, 16, 18, 20, 22];
        let said = to_look_into(&SeqSummary::of(&outcomes), &outcomes, &lines, 3);
        assert_eq!(said.len(), 2, "{said:?}");
        assert!(said[0].ends_with("14: 4, 22: never"), "{}", said[0]);
        assert!(said[1].ends_with("14: 12.50 m 90.0 deg"), "{}", said[1]);
        assert!(to_look_into(&SeqSummary::of(&outcomes[..2]), &outcomes[..2], &lines[..2], 3).is_empty());
    }

    /// `--set`'s sequential keys (the odometry's alphas) reach the localizer a run makes.
    #[test]
    fn a_run_s_localizer_takes_the_configured_motion_model() {
        let walls = map::bundled("apartment").expect("a readable bundled map").expect("a bundled apartment");
        let model = Arc::new(MapModel::new(walls, &map::MapCornerConfig::default()));
        let mut config = Gema2Config::default();
        config.apply(&["odom_alpha1=0.3", "odom_alpha4=0.07"]).expect("known keys");
        let run = SeqRun::new(model, &config, None);
        assert_eq!(run.sequential.config, config.sequential);
        assert_eq!(run.sequential.config.motion.alphas[0], 0.3);
        assert_eq!(run.sequential.config.motion.alphas[3], 0.07);
    }
}
