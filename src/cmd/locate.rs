//! `gema2 locate`: the whole algorithm over a log, offline (no IPC). Writes the CSV of
//! docs/design.md and prints timing and, when the log holds truth, accuracy.

use super::scans::{ScanArgs, SourceError};
use super::Malformed;
use crate::report::{Outcome, Summary};
use anyhow::{Context, Result};
use clap::Args;
use localize::{Gema2, Gema2Config, Hypothesis, Localization, MapModel, Status};
use std::io::{BufWriter, Write};
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Instant;

#[derive(Args)]
pub struct LocateArgs {
    /// The map: a bundled one's name (office, apartment, warehouse, radial), a JSON wall map, or a
    /// ROS map_server map's .yaml (the PGM beside it is read and made into walls: docs/maps.md).
    #[arg(long, default_value = "office")]
    pub map: String,
    /// The scans located.
    #[command(flatten)]
    pub scans: ScanArgs,
    /// CSV output (default: none).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Scan corners matched per scan (1 = the paper's single best corner).
    #[arg(long)]
    pub corners: Option<usize>,
    /// Use the paper's plain eq. 7 instead of the one-sided cost.
    #[arg(long)]
    pub paper_cost: bool,
    /// Use the paper's e(d) = 2 cm instead of 3 cm + 1.5 % of range.
    #[arg(long)]
    pub paper_error: bool,
    /// Track: after an ok scan, make only poses within this radius (metres) of it: the most the
    /// robot moves between two located scans.
    #[arg(long, value_parser = localize::node::track_radius)]
    pub track: Option<f64>,
    /// With truth in the log: print at which stage each scan's right pose was lost.
    #[arg(long)]
    pub diagnose: bool,
    /// The log's poses are not ground truth (raw odometry, another frame): report no success.
    /// A log can say so itself with the line `# gema2: poses are not ground truth`.
    #[arg(long)]
    pub no_truth: bool,
    /// Override a parameter, KEY=VALUE (repeatable); `gema2 settings` lists every key with its
    /// default, range and meaning. The pipeline's `segment` and `localize` stages take the same.
    #[arg(long = "set", value_name = "KEY=VALUE")]
    pub set: Vec<String>,
    /// Write scan N's samples, lines, corners and (true-pose) map as JSON to this folder
    /// (created if missing).
    #[arg(long, num_args = 2, value_names = ["N", "DIR"])]
    pub dump_scan: Vec<String>,
    #[command(flatten)]
    pub seq: crate::sequential::SequentialArgs,
}

/// `--dump-scan N DIR`, read: the scan's index and the folder.
fn dump_request(a: &LocateArgs) -> Result<Option<(usize, PathBuf)>> {
    match a.dump_scan.as_slice() {
        [n, dir] => {
            let n = n.parse().map_err(|_| anyhow::anyhow!("--dump-scan {n}: N is a scan's index, from 0"))?;
            Ok(Some((n, PathBuf::from(dir))))
        }
        _ => Ok(None),
    }
}

/// The segmenter, localizer and map-corner settings of `a`.
pub fn configs(a: &LocateArgs) -> Result<Gema2Config> {
    let mut c = Gema2Config::default();
    if let Some(k) = a.corners {
        c.localizer.corners_tried = k.max(1);
    }
    if a.paper_cost {
        c.localizer.cost.kind = localize::CostKind::Paper;
    }
    if a.paper_error {
        c.segmenter.error = segment::ErrorModel::PAPER;
        c.localizer.error = segment::ErrorModel::PAPER;
    }
    c.localizer.record_candidates = a.diagnose;
    c.localizer.track_radius = a.track;
    c.apply(&a.set).context("--set")?;
    Ok(c)
}

pub fn run(a: LocateArgs) -> Result<()> {
    a.seq.check()?;
    if a.seq.sequential {
        return run_sequential(a);
    }
    let (map, grid) = mapio::load_map_with_grid(&a.map)?;
    super::map::note_rough_grid(&a.map, &map, grid);
    let config = configs(&a)?;
    let loc_cfg = config.localizer;
    let model = Arc::new(MapModel::new(map, &config.map_corners));
    let mut gema2 = Gema2::new(Arc::clone(&model), config.segmenter, config.localizer);
    let source = a.scans.open()?;
    let mut csv = a.out.as_deref().map(CsvOut::create).transpose()?;
    let dump = dump_request(&a)?;
    let mut run = Run {
        dumped: false,
        summary: Summary::default(),
        diagnosis: Default::default(),
        disputed: Vec::new(),
        unreadable: None,
        malformed: Malformed::of(source.unit),
        path: source.path.clone(),
    };
    let mut judge = None;
    let mut progress = crate::progress::Progress::of_log("", &source.path, source.total);
    for (index, item) in selected_items(&a, source.scans) {
        let item = match item {
            Ok(item) => item,
            Err(SourceError::Skip(e)) => {
                // one bad line loses its own scan only: the run goes on, and fails at the end.
                // Its row says `failed`, so the CSV keeps one row per laser line (docs/design.md);
                // the summary counts only the scans located.
                if let Some(w) = csv.as_mut() {
                    w.unreadable(index)?;
                }
                run.malformed.add(e);
                continue;
            }
            Err(SourceError::Stop(e)) => {
                // a log that cannot be read any further ends the run with its error, after the
                // scans before it are written and summed up: they are not lost with it
                run.unreadable = Some(e);
                break;
            }
        };
        let scan = &item.scan;
        let start = Instant::now();
        let (seg, loc) = gema2.process(&scan.view());
        let micros = start.elapsed().as_secs_f64() * 1e6;
        if let Some((_, dir)) = dump.as_ref().filter(|(n, _)| *n == index) {
            dump_scan(dir, index, scan, seg, &model)?;
            run.dumped = true;
        }
        if let (true, Some(truth)) = (a.diagnose, scan.truth.as_ref()) {
            let what = crate::diagnose::classify(seg, loc, truth, &model, &loc_cfg);
            if std::env::var_os("GEMA2_DUMP").is_some_and(|v| v.to_str().is_some_and(|v| what.starts_with(v))) {
                eprintln!("scan {index}: {what} [{}]", loc.status.as_str());
                crate::diagnose::dump(seg, loc, truth, &model);
                judge = Some(*truth);
            }
            run.diagnosis.add(what);
        }
        let best = loc.hypotheses.first().filter(|_| loc.status != Status::Failed);
        if let Some(w) = csv.as_mut() {
            w.row(index, loc, best, micros)?;
        }
        let pose = best.map(|h| h.pose);
        let outcome = Outcome::of(loc.status, pose, scan.truth, micros).with_steps(&seg.times, &loc.times).weigh_truth(
            &mut gema2.localizer,
            &scan.view(),
            pose.as_ref(),
            scan.truth.as_ref(),
        );
        progress.add(&outcome);
        if outcome.disputed_ok() {
            run.disputed.push(index);
        }
        run.summary.add(outcome);
        if let Some(truth) = judge.take() {
            crate::diagnose::dump_judgement(&gema2.localizer.judge(&scan.view(), &truth), &truth);
        }
    }
    progress.finish();
    if let Some(w) = csv {
        w.finish()?;
    }
    run.conclude(&a, dump)
}

/// The laser lines (or LaserScan messages) of `scans` that `--every` and `--offset` select,
/// each with its index among all of them (a malformed line keeps its index, so the scans after
/// it keep theirs), without truth under `--no-truth`. A line they leave out is no concern of
/// the run, malformed or not; a source that cannot be read on ends the run wherever it stops.
fn selected_items(
    a: &LocateArgs,
    scans: Box<dyn Iterator<Item = Result<acquire::LogScan, SourceError>>>,
) -> impl Iterator<Item = (usize, Result<acquire::LogScan, SourceError>)> {
    let (taken, no_truth) = (a.scans.clone(), a.no_truth);
    scans.enumerate().filter(move |(index, item)| matches!(item, Err(SourceError::Stop(_))) || taken.takes(*index)).map(
        move |(index, mut item)| {
            if let (Ok(item), true) = (item.as_mut(), no_truth) {
                item.scan.truth = None;
            }
            (index, item)
        },
    )
}

/// `--out`: the CSV of docs/design.md with the `micros` column, one row per selected laser line.
struct CsvOut(BufWriter<std::fs::File>);

impl CsvOut {
    fn create(path: &std::path::Path) -> Result<Self> {
        let f = std::fs::File::create(path).with_context(|| format!("creating {}", path.display()))?;
        let mut w = BufWriter::new(f);
        writeln!(w, "{}", crate::report::CSV_HEADER)?;
        Ok(CsvOut(w))
    }

    /// Scan `index`'s row: `best` is its answer, none when it failed.
    fn row(&mut self, index: usize, loc: &Localization, best: Option<&Hypothesis>, micros: f64) -> Result<()> {
        let fields = best.map(|h| {
            let (p, c) = (&h.pose, &h.cost);
            (p.translation.x, p.translation.y, laser::pose_theta(p), c.value, c.inliers, c.through)
        });
        let row =
            crate::report::csv_row(index, fields, loc.status.as_str(), micros, loc.hypotheses.len(), loc.candidates, 1);
        writeln!(self.0, "{row}")?;
        Ok(())
    }

    /// Scan `index`'s row of a sequential run.
    fn sequential_row(&mut self, index: usize, o: &crate::sequential::SeqOutcome) -> Result<()> {
        let a = &o.answer;
        // a best track that missed the scan answers where odometry put it, with no cost
        let cost = a.cost.map_or((f64::NAN, f64::NAN, f64::NAN), |c| (c.value, c.inliers, c.through));
        let fields = a
            .pose
            .filter(|_| a.status != Status::Failed)
            .map(|p| (p.translation.x, p.translation.y, laser::pose_theta(&p), cost.0, cost.1, cost.2));
        let row = crate::report::csv_row(index, fields, a.status.as_str(), o.outcome.micros, a.tracks, 0, a.scans);
        writeln!(self.0, "{row}")?;
        Ok(())
    }

    /// The row of scan `index`, whose line could not be read: no answer.
    fn unreadable(&mut self, index: usize) -> Result<()> {
        writeln!(self.0, "{}", crate::report::csv_row(index, None, Status::Failed.as_str(), 0.0, 0, 0, 0))?;
        Ok(())
    }

    fn finish(mut self) -> Result<()> {
        Ok(self.0.flush()?)
    }
}

/// `--dump-scan`: scan `index`'s samples, lines, corners and true-pose map, as JSON in `dir`.
fn dump_scan(
    dir: &std::path::Path,
    index: usize,
    scan: &laser::LaserScan,
    seg: &segment::Segmentation,
    model: &MapModel,
) -> Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let path = dir.join(format!("scan{index}.json"));
    std::fs::write(&path, crate::diagnose::scan_json(scan, seg, model))
        .with_context(|| format!("writing {}", path.display()))
}

/// What a run over the log gathered, summed up once the log is read.
struct Run {
    dumped: bool,
    summary: Summary,
    diagnosis: crate::diagnose::Diagnosis,
    /// The scans whose wrong `ok` is at a truth the scan disputes.
    disputed: Vec<usize>,
    unreadable: Option<anyhow::Error>,
    malformed: Malformed,
    /// The log or bag read.
    path: PathBuf,
}

impl Run {
    /// Prints the summary (and diagnosis), then fails when the log could not be read to its
    /// end or held malformed laser lines, when no scan was located, or when a `--dump-scan` or
    /// `--diagnose` asked for had nothing to work on.
    fn conclude(self, a: &LocateArgs, dump: Option<(usize, PathBuf)>) -> Result<()> {
        let located = self.summary.outcomes.len();
        // with no scan there is nothing to sum up: the error below says why
        if located > 0 {
            print!("{}", self.summary.render());
            print!("{}", crate::report::disputed_scans(&self.disputed));
        }
        if a.diagnose {
            print!("{}", self.diagnosis.render());
        }
        if let Some(e) = self.unreadable {
            anyhow::bail!("{e}; stopped there, after {located} scans");
        }
        self.malformed.into_result("skipped")?;
        if located == 0 {
            // an empty result is no answer: a script must not take it for one
            anyhow::bail!(
                "{}: no laser scan located (no ROBOTLASER1, FLASER or RAWLASER1 line, or none that --every {} --offset {} selects)",
                self.path.display(),
                a.scans.every,
                a.scans.offset
            );
        }
        if let Some((n, _)) = dump.filter(|_| !self.dumped) {
            anyhow::bail!(
                "--dump-scan {n}: no such scan among the {located} located (--every {} --offset {})",
                a.scans.every,
                a.scans.offset
            );
        }
        if a.diagnose && self.diagnosis.is_empty() {
            anyhow::bail!("--diagnose: {} holds no true pose, so there is nothing to diagnose", self.path.display());
        }
        Ok(())
    }
}

/// `--sequential`: the sequential localizer over the selected scans, each row's `scans` column
/// saying how many scans its answer rests on.
fn run_sequential(a: LocateArgs) -> Result<()> {
    use crate::sequential::{Odometry, SeqRun};
    if a.diagnose || !a.dump_scan.is_empty() {
        anyhow::bail!("--diagnose and --dump-scan locate single scans: leave out --sequential");
    }
    let (map, grid) = mapio::load_map_with_grid(&a.map)?;
    super::map::note_rough_grid(&a.map, &map, grid);
    let config = configs(&a)?;
    let model = Arc::new(MapModel::new(map, &config.map_corners));
    let mut run = SeqRun::new(model, &config, a.seq.restart_every);
    let mut odometry = Odometry::new(a.seq.noise()?, a.seq.odom_seed);
    let source = a.scans.open()?;
    let mut csv = a.out.as_deref().map(CsvOut::create).transpose()?;
    let mut malformed = Malformed::of(source.unit);
    let mut summary = Summary::default();
    let mut disputed = Vec::new();
    let mut stopped = None;
    let mut progress = crate::progress::Progress::of_log("", &source.path, source.total);
    for (index, item) in selected_items(&a, source.scans) {
        let item = match item {
            Ok(item) => item,
            Err(SourceError::Skip(e)) => {
                if let Some(w) = csv.as_mut() {
                    w.unreadable(index)?;
                }
                malformed.add(e);
                continue;
            }
            Err(SourceError::Stop(e)) => {
                stopped = Some(e);
                break;
            }
        };
        let odom = odometry.next(item.odometry, item.scan.truth.as_ref(), false)?;
        let o = run.locate(&item.scan, odom);
        if let Some(w) = csv.as_mut() {
            w.sequential_row(index, &o)?;
        }
        progress.add(&o.outcome);
        if o.outcome.disputed_ok() {
            disputed.push(index);
        }
        summary.add(o.outcome);
    }
    progress.finish();
    if let Some(w) = csv {
        w.finish()?;
    }
    if !summary.outcomes.is_empty() {
        print!("{}", summary.render());
        print!("{}", run.summary().render());
        print!("{}", crate::report::disputed_scans(&disputed));
    }
    if let Some(e) = stopped {
        anyhow::bail!("{e}; stopped there, after {} scans", summary.outcomes.len());
    }
    malformed.into_result("skipped")?;
    if summary.outcomes.is_empty() {
        anyhow::bail!("{}: no laser scan located", source.path.display());
    }
    Ok(())
}
