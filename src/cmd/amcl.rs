//! `gema2 amcl`: Nav2's AMCL and gema2's sequential localizer side by side, from a global
//! start, on the same scans, the same odometry and the same map (rasterized as `gema2 map
//! export-ros` draws it). Each is judged alike: how many located scans, metres driven and
//! seconds of its own computing until its pose is right (within [`SUCCESS_POSITION`] m and
//! [`SUCCESS_HEADING_DEG`] degrees) and stays right for [`HOLD`] scans.
//!
//! AMCL runs in a Python worker (`scripts/amcl_worker.py`, PyPI `amcl`: nav2_amcl's particle
//! filter, beam model and differential motion model) that this command feeds one scan at a
//! time; the worker and its environment are the project's own (`scripts/python-env`).

use super::evaluate::{carmen_logs, log_stem, odd_scans_and_even_map};
use super::Malformed;
use crate::report::{quantile, Outcome, SUCCESS_HEADING_DEG, SUCCESS_POSITION};
use crate::sequential::{odometry_noise, Odometry, SeqRun};
use acquire::{CarmenReader, FlaserLayout, LogScan};
use anyhow::{bail, Context, Result};
use clap::Args;
use laser::Pose;
use localize::{Gema2Config, MapModel};
use map::WallMap;
use std::io::{BufRead, BufReader, BufWriter, Write};
use std::path::{Path, PathBuf};
use std::process::{ChildStdin, ChildStdout, Command, Stdio};
use std::sync::Arc;

/// Scans a right pose must hold, the first included, to count as settled.
pub const HOLD: usize = 10;

/// The worker, carried in the binary so that `--python` may name any Python with `amcl`.
const WORKER: &str = include_str!("../../scripts/amcl_worker.py");

#[derive(Args)]
pub struct AmclArgs {
    /// A folder of SLAM-corrected CARMEN logs (e.g. ../shared/datasets/carmen), or one such
    /// log: each log's odd scans against a map built from its even ones, as `gema2 evaluate
    /// --carmen` locates them.
    #[arg(long, conflicts_with_all = ["log", "map"])]
    pub carmen: Option<PathBuf>,
    /// One log (CARMEN text, e.g. `gema2 sim --trajectory`), every scan, against --map.
    #[arg(long, requires = "map")]
    pub log: Option<PathBuf>,
    /// The map of --log: a bundled map's name or a map file.
    #[arg(long, requires = "log")]
    pub map: Option<String>,
    /// Global starts a log, spread evenly over its located scans.
    #[arg(long, default_value_t = 4, value_parser = super::positive_count)]
    pub starts: usize,
    /// Located scans a start runs at most before it counts as never settled.
    #[arg(long, default_value_t = 200, value_parser = super::positive_count)]
    pub max_scans: usize,
    /// AMCL's most particles (its global start draws this many).
    #[arg(long, default_value_t = 5000, value_parser = super::positive_count)]
    pub particles: usize,
    /// AMCL's fewest particles once it has converged (KLD sampling; Nav2's default).
    #[arg(long, default_value_t = 500, value_parser = super::positive_count)]
    pub min_particles: usize,
    /// Replace the log's odometry, for both, with odometry drawn from its true motion with
    /// these alphas (AMCL's alpha1..alpha4), as `gema2 evaluate --sequential` does.
    #[arg(long, value_name = "A1,A2,A3,A4", value_delimiter = ',')]
    pub odom_noise: Option<Vec<f64>>,
    /// The seed of --odom-noise.
    #[arg(long, default_value_t = 1)]
    pub odom_seed: u64,
    /// Start AMCL at each start's true pose (0.1 m, 0.05 rad), as a user's click in RViz
    /// would, instead of globally: a check that it reads the map, scans and odometry right.
    #[arg(long)]
    pub seeded: bool,
    /// Metres a cell of the grid AMCL gets.
    #[arg(long, default_value_t = 0.05)]
    pub resolution: f64,
    /// The Python that runs AMCL; by default the project's environment (scripts/python-env,
    /// made on first use with the pinned `amcl` package).
    #[arg(long)]
    pub python: Option<PathBuf>,
    /// Override a localizer or segmenter parameter of gema2, KEY=VALUE (repeatable).
    #[arg(long = "set", value_name = "KEY=VALUE")]
    pub set: Vec<String>,
    /// Also write the tables into this markdown file (its `amcl` section, the rest kept).
    #[arg(long, value_name = "FILE")]
    pub markdown: Option<PathBuf>,
}

/// How a start settled: the located scans up to and with the first of [`HOLD`] right poses in
/// a row, the metres the robot drove from the start to it, and the seconds computed till then.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Settled {
    pub scans: usize,
    pub metres: f64,
    pub seconds: f64,
}

/// What one localizer did from one start, up to where it settled.
#[derive(Clone, Copy, Debug, Default)]
struct Track {
    /// The scans located, metres driven and seconds computed so far.
    so_far: Settled,
    /// The right poses in a row up to the last scan, and where that run began.
    run: usize,
    run_start: Settled,
    settled: Option<Settled>,
}

impl Track {
    /// Adds a located scan: whether its pose is right, the metres driven since the last scan
    /// and the seconds it took. Says whether the start has settled.
    fn add(&mut self, right: bool, metres: f64, seconds: f64) -> bool {
        let s = &mut self.so_far;
        (s.scans, s.metres, s.seconds) = (s.scans + 1, s.metres + metres, s.seconds + seconds);
        if !right {
            self.run = 0;
        } else {
            if self.run == 0 {
                self.run_start = self.so_far;
            }
            self.run += 1;
            if self.run >= HOLD && self.settled.is_none() {
                self.settled = Some(self.run_start);
            }
        }
        self.settled.is_some()
    }
}

/// The AMCL worker process.
struct Worker {
    /// Killed first when the worker is dropped, then its pipes close.
    _child: super::KilledOnDrop,
    input: BufWriter<ChildStdin>,
    output: BufReader<ChildStdout>,
}

impl Worker {
    fn spawn(python: &Path, script: &Path, a: &AmclArgs) -> Result<Self> {
        let mut child = Command::new(python)
            .arg(script)
            .args(["--max-particles", &a.particles.to_string(), "--min-particles", &a.min_particles.to_string()])
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .spawn()
            .with_context(|| format!("starting {} {}", python.display(), script.display()))?;
        let (Some(input), Some(output)) = (child.stdin.take(), child.stdout.take()) else {
            bail!("the AMCL worker has no pipes");
        };
        Ok(Worker { _child: super::KilledOnDrop(child), input: BufWriter::new(input), output: BufReader::new(output) })
    }

    /// Sends one request and reads its reply, which must begin with `expect`; the reply's
    /// remaining fields.
    fn ask(&mut self, request: &str, expect: &str) -> Result<Vec<String>> {
        writeln!(self.input, "{request}").and_then(|_| self.input.flush()).context("writing to the AMCL worker")?;
        let mut line = String::new();
        if self.output.read_line(&mut line).context("reading the AMCL worker")? == 0 {
            bail!("the AMCL worker ended (its error is above)");
        }
        let mut fields = line.split_whitespace().map(str::to_owned);
        match fields.next().as_deref() {
            Some(word) if word == expect => Ok(fields.collect()),
            Some("error") => bail!("AMCL worker: {}", line.trim_start_matches("error").trim()),
            _ => bail!("the AMCL worker answered {:?} to a {expect} request", line.trim()),
        }
    }

    /// The filter's pose after `scan` with odometry `odom`, and its seconds.
    fn update(&mut self, item: &LogScan, odom: &Pose) -> Result<(Pose, f64)> {
        use std::fmt::Write as _;
        let g = item.scan.geometry;
        let mut request = format!(
            "scan {} {} {} {} {} {} {} {}",
            odom.translation.x,
            odom.translation.y,
            odom.rotation.angle(),
            g.angle_min,
            g.angle_increment,
            g.range_min,
            g.range_max,
            item.scan.ranges.len()
        );
        for r in &item.scan.ranges {
            let _ = write!(request, " {r}");
        }
        let f = self.ask(&request, "pose")?;
        let num = |i: usize| -> Result<f64> {
            f.get(i).and_then(|s| s.parse().ok()).with_context(|| format!("the AMCL worker's pose {f:?}"))
        };
        Ok((Pose::new(nalgebra::Vector2::new(num(0)?, num(1)?), num(2)?), num(3)?))
    }
}

/// A log to run: its name, map and the scans to locate with their odometry.
struct Case {
    name: String,
    map: WallMap,
    items: Vec<LogScan>,
    odometry: Vec<Pose>,
}

/// Both localizers' outcome of one start.
struct StartRow {
    log: String,
    /// The located scan it starts at, from 0.
    start: usize,
    amcl: Option<Settled>,
    gema2: Option<Settled>,
    /// Located scans the start had (at most --max-scans).
    ran: usize,
    /// Metres the robot drove over them.
    metres: f64,
}

pub fn run(a: AmclArgs) -> Result<()> {
    let mut config = Gema2Config::default();
    config.apply(&a.set).context("--set")?;
    if !(a.resolution.is_finite() && a.resolution > 0.0) {
        bail!("--resolution must be a number of metres above 0");
    }
    if a.min_particles > a.particles {
        bail!("--min-particles ({}) is more than --particles ({})", a.min_particles, a.particles);
    }
    let noise = a.odom_noise.as_deref().map(odometry_noise).transpose()?;
    let python = match &a.python {
        Some(p) => p.clone(),
        None => project_python()?,
    };
    let scratch = super::ScratchDir::new("amcl")?;
    let dir = scratch.path();
    let script = dir.join("amcl_worker.py");
    std::fs::write(&script, WORKER).with_context(|| format!("writing {}", script.display()))?;

    let mut malformed = Malformed::default();
    let logs: Vec<PathBuf> = match (&a.carmen, &a.log) {
        (Some(d), _) => carmen_logs(d)?,
        (None, Some(l)) => vec![l.clone()],
        (None, None) => bail!("give --carmen DIR, or --log LOG with --map MAP"),
    };
    let odometry_said = noise.map_or("the log's".to_string(), |n| format!("drawn with noise {:?}", n.alphas));
    let title = format!(
        "from {}: located scans, metres and seconds until the pose is within {SUCCESS_POSITION} m and {SUCCESS_HEADING_DEG} deg and stays there {HOLD} scans; AMCL {}..{} particles; odometry {odometry_said}; {} starts a log, each at most {} scans",
        if a.seeded { "AMCL started at the true pose" } else { "a global start" },
        a.min_particles, a.particles, a.starts, a.max_scans
    );
    println!("{title}\n");
    println!("{:<28} {:>6}  {:<26} {:<26}", "log", "start", "AMCL scans / m / s", "gema2 scans / m / s");
    let mut rows = Vec::new();
    for log in &logs {
        let case = load_case(log, a.map.as_deref(), noise, a.odom_seed, &mut malformed)?;
        let yaml = dir.join("map.yaml");
        let grid = mapio::OccupancyGrid::from_walls(&case.map, a.resolution, 0.0).map_err(anyhow::Error::msg)?;
        grid.save(&yaml)?;
        let mut worker = Worker::spawn(&python, &script, &a)?;
        worker.ask(&format!("map {}", yaml.display()), "map")?;
        let model = Arc::new(MapModel::new(case.map.clone(), &config.map_corners));
        let n = case.items.len();
        for k in 0..a.starts {
            let start = k * n / a.starts;
            let row = run_start(&case, start, &a, &mut worker, &model, &config)?;
            println!("{:<28} {:>6}  {:<26} {:<26}", row.log, row.start, said(&row.amcl, &row), said(&row.gema2, &row));
            rows.push(row);
        }
    }
    let table = markdown(&title, &rows);
    println!("\n{}", summary_lines(&rows).join("\n"));
    if let Some(path) = &a.markdown {
        let command: Vec<String> = std::env::args().skip(1).filter(|s| !s.is_empty()).collect();
        crate::results::write_section(path, "amcl", &format!("gema2 {}", command.join(" ")), &table)?;
    }
    malformed.into_result("skipped")
}

/// The log's scans to locate, their odometry, and its map: every scan against `map` when one
/// is given, else the log's odd scans against the map of its even ones.
fn load_case(
    log: &Path,
    map: Option<&str>,
    noise: Option<laser::motion::OdometryNoise>,
    seed: u64,
    malformed: &mut Malformed,
) -> Result<Case> {
    let (map, items) = match map {
        None => odd_scans_and_even_map(log, malformed)?,
        Some(m) => {
            let mut items = Vec::new();
            for item in CarmenReader::open(log, FlaserLayout::default())? {
                items.extend(malformed.take(item)?);
            }
            (mapio::load_map(m)?, items)
        }
    };
    let mut drawn = Odometry::new(noise, seed);
    let mut odometry = Vec::with_capacity(items.len());
    for item in &items {
        if item.scan.truth.is_none() {
            bail!("{} line {}: no true pose, so neither localizer can be judged", log.display(), item.line);
        }
        let odom = drawn.next(item.odometry, item.scan.truth.as_ref(), false)?;
        let Some(odom) = odom else {
            bail!(
                "{} line {}: no odometry; give --odom-noise to draw it from the true motion",
                log.display(),
                item.line
            );
        };
        odometry.push(odom);
    }
    Ok(Case { name: log_stem(log), map, items, odometry })
}

/// Both localizers from located scan `start` of `case`, until each has settled or
/// --max-scans have gone.
fn run_start(
    case: &Case,
    start: usize,
    a: &AmclArgs,
    worker: &mut Worker,
    model: &Arc<MapModel>,
    config: &Gema2Config,
) -> Result<StartRow> {
    let request = match (a.seeded, case.items[start].scan.truth) {
        (true, Some(t)) => format!("start {} {} {}", t.translation.x, t.translation.y, t.rotation.angle()),
        _ => "start".to_string(),
    };
    worker.ask(&request, "started")?;
    let mut gema2 = SeqRun::new(Arc::clone(model), config, None);
    let (mut amcl, mut ours) = (Track::default(), Track::default());
    let end = (start + a.max_scans).min(case.items.len());
    let mut driven = 0.0;
    let mut last: Option<Pose> = None;
    let mut ran = 0;
    for (item, odom) in case.items[start..end].iter().zip(&case.odometry[start..end]) {
        let truth = item.scan.truth;
        let step = match (last, truth) {
            (Some(l), Some(t)) => (t.translation.vector - l.translation.vector).norm(),
            _ => 0.0,
        };
        last = truth;
        driven += step;
        ran += 1;
        if amcl.settled.is_none() {
            let (pose, seconds) = worker.update(item, odom)?;
            let right = Outcome::of(localize::Status::Ok, Some(pose), truth, 0.0).success();
            amcl.add(right, step, seconds);
        }
        if ours.settled.is_none() {
            let o = gema2.locate(&item.scan, Some(*odom));
            ours.add(o.outcome.success(), step, o.outcome.micros * 1e-6);
        }
        if amcl.settled.is_some() && ours.settled.is_some() {
            break;
        }
    }
    Ok(StartRow { log: case.name.clone(), start, amcl: amcl.settled, gema2: ours.settled, ran, metres: driven })
}

/// A start's cell: "scans / m / s", or that it never settled.
fn said(s: &Option<Settled>, row: &StartRow) -> String {
    match s {
        Some(s) => format!("{} / {:.1} / {:.4}", s.scans, s.metres, s.seconds),
        None => format!("not in {} scans ({:.0} m)", row.ran, row.metres),
    }
}

/// One localizer's starts of one log, in brief: settled k of n, and the medians of those that
/// settled.
fn brief(rows: &[&StartRow], pick: fn(&StartRow) -> Option<Settled>) -> String {
    let done: Vec<Settled> = rows.iter().filter_map(|r| pick(r)).collect();
    if done.is_empty() {
        return format!("0 of {}", rows.len());
    }
    let median = |f: fn(&Settled) -> f64| quantile(&mut done.iter().map(f).collect::<Vec<_>>(), 0.5);
    format!(
        "{} of {}: {:.0} scans, {:.1} m, {:.4} s",
        done.len(),
        rows.len(),
        median(|s| s.scans as f64),
        median(|s| s.metres),
        median(|s| s.seconds)
    )
}

/// The logs in the order they ran.
fn logs_of(rows: &[StartRow]) -> Vec<&str> {
    let mut logs: Vec<&str> = Vec::new();
    for r in rows {
        if logs.last() != Some(&r.log.as_str()) {
            logs.push(&r.log);
        }
    }
    logs
}

/// Per log: AMCL's and gema2's starts that settled, with their medians.
fn summary_lines(rows: &[StartRow]) -> Vec<String> {
    let mut lines = vec!["per log, starts settled and their medians (scans, metres, seconds):".to_string()];
    for log in logs_of(rows) {
        let of: Vec<&StartRow> = rows.iter().filter(|r| r.log == log).collect();
        lines.push(format!("{log:<28} AMCL {:<40} gema2 {}", brief(&of, |r| r.amcl), brief(&of, |r| r.gema2)));
    }
    lines
}

/// The `amcl` section of docs/results.md: per log in brief, then every start.
fn markdown(title: &str, rows: &[StartRow]) -> String {
    let mut s = format!("### {title}\n\n| log | AMCL: starts settled, median scans, m, s | gema2 sequential: the same |\n|---|---|---|\n");
    for log in logs_of(rows) {
        let of: Vec<&StartRow> = rows.iter().filter(|r| r.log == log).collect();
        s += &format!("| {log} | {} | {} |\n", brief(&of, |r| r.amcl), brief(&of, |r| r.gema2));
    }
    s += "\nEvery start (located scan it starts at; scans / metres / seconds):\n\n| log | start | AMCL | gema2 |\n|---|---|---|---|\n";
    for r in rows {
        s += &format!("| {} | {} | {} | {} |\n", r.log, r.start, said(&r.amcl, r), said(&r.gema2, r));
    }
    s
}

/// The project's Python environment, made on first use by scripts/python-env.
fn project_python() -> Result<PathBuf> {
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("scripts/python-env");
    if !script.exists() {
        bail!(
            "{} is not here (an installed gema2 away from its source): give --python, a Python with the `amcl` package",
            script.display()
        );
    }
    eprintln!("making the Python environment (once): {}", script.display());
    let out = Command::new(&script).output().with_context(|| format!("running {}", script.display()))?;
    if !out.status.success() {
        bail!("{} failed: {}", script.display(), String::from_utf8_lossy(&out.stderr).trim());
    }
    Ok(PathBuf::from(String::from_utf8_lossy(&out.stdout).trim()))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The first place in `right` where [`HOLD`] right poses begin, as [`Settled`]: `metres[i]`
    /// and `seconds[i]` are the totals up to and with scan `i`.
    pub fn settled(right: &[bool], metres: &[f64], seconds: &[f64]) -> Option<Settled> {
        let mut t = Track::default();
        let (mut m0, mut s0) = (0.0, 0.0);
        for i in 0..right.len() {
            if t.add(right[i], metres[i] - m0, seconds[i] - s0) {
                return t.settled;
            }
            (m0, s0) = (metres[i], seconds[i]);
        }
        None
    }

    fn totals(steps: &[f64]) -> Vec<f64> {
        steps
            .iter()
            .scan(0.0, |t, s| {
                *t += s;
                Some(*t)
            })
            .collect()
    }

    #[test]
    fn a_start_settles_at_the_first_of_ten_right_poses_in_a_row() {
        // wrong, then 9 right (one short), wrong, then 10 right from scan 12
        let mut right = vec![false];
        right.extend([true; 9]);
        right.push(false);
        right.extend([true; 10]);
        let metres = totals(&vec![1.0; right.len()]);
        let seconds = totals(&vec![0.5; right.len()]);
        let s = settled(&right, &metres, &seconds).expect("settles");
        assert_eq!(s.scans, 12);
        assert!((s.metres - 12.0).abs() < 1e-9 && (s.seconds - 6.0).abs() < 1e-9, "{s:?}");
    }

    #[test]
    fn nine_right_poses_at_the_end_never_settle() {
        let mut right = vec![false; 3];
        right.extend([true; HOLD - 1]);
        let ones = totals(&vec![1.0; right.len()]);
        assert_eq!(settled(&right, &ones, &ones), None);
    }

    #[test]
    fn right_from_the_first_scan_settles_at_one() {
        let right = [true; HOLD];
        let m = totals(&[0.0, 2.0, 2.0, 2.0, 2.0, 2.0, 2.0, 2.0, 2.0, 2.0]);
        let s = settled(&right, &m, &totals(&[0.1; HOLD])).expect("settles");
        assert_eq!(s.scans, 1);
        assert!(s.metres.abs() < 1e-12 && (s.seconds - 0.1).abs() < 1e-12, "{s:?}");
    }
}
