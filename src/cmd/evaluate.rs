//! `gema2 evaluate`: the accuracy figures the README reports, from one command. A suite of
//! simulated logs (the bundled maps and generated ones never tuned on, each scenario), and
//! optionally real logs located against maps built from their other half.
//!
//! Each simulated log goes through the ROBOTLASER1 text that `gema2 sim` writes and is read
//! back as `gema2 locate` reads it, so a log's line here equals `gema2 sim` then `gema2 locate`
//! on the same map, scenario and seeds.

use super::build_map::{self, BuildArgs};
use super::Malformed;
use crate::report::{Outcome, Summary};
use crate::sequential::{SeqOutcome, SeqSummary};
use acquire::{write_robotlaser1, CarmenReader, FlaserLayout, LogScan, Scenario, SensorModel, Simulator};
use anyhow::{bail, Context, Result};
use clap::Args;
use laser::LaserScan;
use localize::{Gema2, Gema2Config, MapModel, Status, Step, CASCADE};
use map::WallMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

#[derive(Args)]
pub struct EvaluateArgs {
    /// Scans per simulated log.
    #[arg(long, default_value_t = 300)]
    pub scans: usize,
    /// The simulator's seed for every log.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Seeds of the generated apartment (a flat of another plan), office, radial and warehouse
    /// maps located besides the bundled four (`--map-seeds` alone: the bundled maps only).
    #[arg(long, value_delimiter = ',', num_args = 0.., default_value = "2,3,4")]
    pub map_seeds: Vec<u64>,
    /// Leave out the simulated suite.
    #[arg(long)]
    pub no_sim: bool,
    /// A folder of SLAM-corrected CARMEN logs (`*.log`, `*.log.gz`, e.g.
    /// ../shared/datasets/carmen), or one such log: each is located twice, its odd scans
    /// against a map built from its even ones (`gema2 map build` defaults) and the other way
    /// round.
    #[arg(long)]
    pub carmen: Option<PathBuf>,
    /// With --carmen: also locate each half through the occupancy grid of the other half
    /// (`gema2 map build --grid` defaults), made into walls as `--map GRID.yaml` does.
    #[arg(long)]
    pub grids: bool,
    /// Override a localizer or segmenter parameter, KEY=VALUE (repeatable), as `gema2 locate`.
    #[arg(long = "set", value_name = "KEY=VALUE")]
    pub set: Vec<String>,
    /// Also write the tables into this markdown file (its `evaluate` section, the rest kept):
    /// `--markdown docs/results.md` regenerates that page's accuracy tables.
    #[arg(long, value_name = "FILE")]
    pub markdown: Option<PathBuf>,
    /// Locate with the sequential localizer instead: simulated walks (each map and scenario
    /// of the suite, 0.2 and 0.8 m a scan, --odom-noise drawn as `gema2 sim --trajectory`
    /// draws it) and, with --carmen, each log's odd scans against the map of its even ones;
    /// per log how soon each start is sure, how often `ok` is wrong, and what tracking costs
    /// (--odom-noise, --odom-seed, --restart-every as `gema2 locate --sequential`).
    #[command(flatten)]
    pub seq: crate::sequential::SequentialArgs,
    /// With --sequential: also kidnap the robot this many times a log: 20 located scans of one
    /// stretch, then 20 of a stretch at least 10 m away, with no odometry across the cut.
    #[arg(long, default_value_t = 0)]
    pub kidnaps: usize,
}

/// One located log's figures.
struct Row {
    name: String,
    scans: usize,
    successes: usize,
    ok: usize,
    wrong_ok: usize,
    /// Of `wrong_ok`, those at a truth the scan disputes.
    disputed: usize,
    ambiguous: usize,
    failed: usize,
    median_us: f64,
    p99_us: f64,
    /// The share of scans each step of the search cascade ran on ([`localize::CASCADE`]).
    ran: [f64; Step::COUNT],
}

impl Row {
    fn of(name: String, summary: &Summary) -> Row {
        let (median_us, p99_us) = summary.time_quantiles();
        let mut ran = [0.0; Step::COUNT];
        for (share, spec) in ran.iter_mut().zip(CASCADE) {
            *share = summary.ran_share(spec.step);
        }
        Row {
            name,
            scans: summary.scans(),
            successes: summary.successes(),
            ok: summary.count(Status::Ok),
            wrong_ok: summary.wrong_ok(),
            disputed: summary.disputed_wrong_ok(),
            ambiguous: summary.count(Status::Ambiguous),
            failed: summary.count(Status::Failed),
            median_us,
            p99_us,
            ran,
        }
    }

    fn success(&self) -> f64 {
        100.0 * self.successes as f64 / self.scans.max(1) as f64
    }

    /// Right `ok` answers of all `ok` answers, %; `None` with no `ok` answer.
    fn ok_precision(&self) -> Option<f64> {
        (self.ok > 0).then(|| 100.0 * (self.ok - self.wrong_ok) as f64 / self.ok as f64)
    }

    /// The share of scans that ran each step after the first look, as "full/slide/loose/wider/grid".
    fn searches(&self) -> String {
        let pct: Vec<String> = self.ran[1..].iter().map(|v| format!("{:.0}", 100.0 * v)).collect();
        pct.join("/")
    }

    /// The row's cells after its name, in [`COLUMNS`]' order, as both tables show them.
    fn cells(&self) -> [String; 10] {
        [
            self.scans.to_string(),
            format!("{:.1} %", self.success()),
            self.ok.to_string(),
            crate::report::wrong_cell(self.wrong_ok, self.disputed),
            self.ok_precision().map_or("-".to_owned(), |p| format!("{p:.1} %")),
            self.ambiguous.to_string(),
            self.failed.to_string(),
            format!("{:.0}", self.median_us),
            format!("{:.0}", self.p99_us),
            self.searches(),
        ]
    }

    fn print(&self) {
        print_row(&self.name, &self.cells());
    }

    fn markdown(&self) -> String {
        format!("| {} | {} |\n", self.name, self.cells().join(" | "))
    }
}

/// The console table's and the markdown table's columns after the log's name, with their
/// console widths (the last, the searches, is left unpadded).
const COLUMNS: [(&str, &str, usize); 10] = [
    ("scans", "scans", 6),
    ("success", "success", 9),
    ("ok", "ok", 6),
    ("wrong", "wrong ok", 6),
    ("ok prec", "ok precision", 8),
    ("ambig", "ambiguous", 6),
    ("failed", "failed", 6),
    ("median us", "median us", 10),
    ("p99 us", "p99 us", 10),
    ("searches", "searches", 0),
];

/// One line of the console table: the name, then each cell right-aligned to its column.
fn print_row(name: &str, cells: &[String]) {
    let mut line = format!("{name:<NAME_WIDTH$}");
    for (cell, (_, _, width)) in cells.iter().zip(COLUMNS) {
        if width == 0 {
            line += &format!("  {cell}");
        } else {
            line += &format!(" {cell:>width$}");
        }
    }
    println!("{line}");
}

/// Width of the log column: "freiburg-101-corrected even grid" fits.
const NAME_WIDTH: usize = 32;

/// What the "searches" column lists.
const SEARCHES: &str = "% of scans that ran the full search / slide / loose slide / wider slide / grid";

fn header(title: &str) {
    println!("\n{title}");
    let mut names: Vec<String> = COLUMNS.iter().map(|(console, _, _)| console.to_string()).collect();
    if let Some(last) = names.last_mut() {
        *last = format!("searches ({SEARCHES})");
    }
    print_row("log", &names);
}

/// A markdown table of `rows` under `title`, with their total.
fn markdown_table(title: &str, rows: &[Row]) -> String {
    let mut s = format!("### {title}\n\n");
    let names: Vec<&str> = COLUMNS.iter().map(|(_, markdown, _)| *markdown).collect();
    s += &format!("| log | {} |\n|---|{}\n", names.join(" | "), "---|".repeat(COLUMNS.len()));
    for r in rows {
        s += &r.markdown();
    }
    s + &format!("\n{}\n\nsearches: {SEARCHES}.\n\n", total_line(rows))
}

/// The sums over `rows`; the time is the mean of the logs' medians.
fn total_line(rows: &[Row]) -> String {
    let sum = |f: fn(&Row) -> usize| rows.iter().map(f).sum::<usize>();
    let (scans, successes) = (sum(|r| r.scans), sum(|r| r.successes));
    format!(
        "total: {} logs, {scans} scans, {successes} successes ({:.1} %), ok {}, wrong ok {} ({}), mean of the medians {:.0} us",
        rows.len(),
        100.0 * successes as f64 / scans.max(1) as f64,
        sum(|r| r.ok),
        sum(|r| r.wrong_ok),
        crate::report::disputed_phrase(sum(|r| r.disputed)),
        rows.iter().map(|r| r.median_us).sum::<f64>() / rows.len().max(1) as f64
    )
}

pub fn run(a: EvaluateArgs) -> Result<()> {
    let mut config = Gema2Config::default();
    config.apply(&a.set).context("--set")?;
    if a.no_sim && a.carmen.is_none() {
        bail!("nothing to evaluate: --no-sim without --carmen");
    }
    if a.grids && a.carmen.is_none() {
        bail!("--grids locates CARMEN logs through grids: give --carmen too");
    }
    if a.scans == 0 && !a.no_sim {
        bail!("--scans must be at least 1");
    }
    a.seq.check()?;
    if a.seq.sequential {
        return sequential_suite(&a, &config);
    }
    let mut page = String::new();
    if !a.no_sim {
        let title = format!("simulated URG-04LX, {} scans a log, seed {}", a.scans, a.seed);
        header(&title);
        let mut rows = Vec::new();
        for (name, map) in suite_maps(&a.map_seeds)? {
            for scenario in [Scenario::Clean, Scenario::People, Scenario::Furniture] {
                let scans = simulated_log(&map, scenario, a.seed, a.scans)?;
                let log = format!("{name} {scenario}");
                let row = Row::of(log.clone(), &locate_all(&log, &map, &config, &scans));
                row.print();
                rows.push(row);
            }
        }
        println!("{}", total_line(&rows));
        page += &markdown_table(&title, &rows);
    }
    let mut malformed = Malformed::default();
    if let Some(dir) = &a.carmen {
        let title = format!("{}: odd scans against a map of the even ones, and the other way round", dir.display());
        header(&title);
        let mut rows = Vec::new();
        for log in carmen_logs(dir)? {
            // a malformed line keeps its place, so the halves stay the ones `map build` and
            // `locate --every 2` take; it is located in neither
            let mut scans: Vec<Option<LaserScan>> = Vec::new();
            for item in CarmenReader::open(&log, FlaserLayout::default())? {
                scans.push(malformed.take(item)?.map(|i| i.scan));
            }
            let stem = log_stem(&log);
            for (built_from, located) in [(0, 1), (1, 0)] {
                let half: Vec<LaserScan> = scans.iter().skip(located).step_by(2).flatten().cloned().collect();
                let name = format!("{stem} {}", if built_from == 0 { "odd" } else { "even" });
                let mut maps = vec![(name.clone(), built_map(&log, built_from)?)];
                if a.grids {
                    maps.push((format!("{name} grid"), grid_map(&log, built_from)?));
                }
                for (name, map) in maps {
                    let row = Row::of(name.clone(), &locate_all(&name, &map, &config, &half));
                    row.print();
                    rows.push(row);
                }
            }
        }
        println!("{}", total_line(&rows));
        page += &markdown_table(&title, &rows);
    }
    page += &format!("{}\n", crate::report::disputed_meaning());
    if let Some(path) = &a.markdown {
        let command: Vec<String> = std::env::args().skip(1).filter(|s| !s.is_empty()).collect();
        crate::results::write_section(path, "evaluate", &format!("gema2 {}", command.join(" ")), &page)?;
    }
    malformed.into_result("skipped")?;
    Ok(())
}

/// The bundled maps, then each generated kind at each seed, as `gema2 map generate` writes
/// them (through JSON, so coordinates are as a map file holds them).
fn suite_maps(seeds: &[u64]) -> Result<Vec<(String, WallMap)>> {
    let mut maps = Vec::new();
    for name in ["apartment", "radial", "office", "warehouse"] {
        maps.push((name.to_string(), mapio::load_map(name)?));
    }
    for kind in ["apartment", "office", "radial", "warehouse"] {
        for &seed in seeds {
            let map = worlds::by_name_seeded(kind, seed).with_context(|| format!("no generated {kind}"))?;
            let name = format!("{kind} seed {seed}");
            maps.push((name.clone(), WallMap::parse(&map.to_json(kind), Path::new(&name))?));
        }
    }
    Ok(maps)
}

/// `scans` simulated scans of `map`, written as `gema2 sim` writes them and read back.
fn simulated_log(map: &WallMap, scenario: Scenario, seed: u64, scans: usize) -> Result<Vec<LaserScan>> {
    let mut sim = Simulator::new(map, SensorModel::urg04lx(), scenario, seed);
    let mut text = Vec::new();
    for _ in 0..scans {
        write_robotlaser1(&mut text, &sim.next_scan())?;
    }
    let reader = CarmenReader::from_reader(
        Box::new(std::io::Cursor::new(text)),
        Path::new("simulated"),
        FlaserLayout::default(),
    );
    Ok(reader.map(|item| item.map(|i| i.scan)).collect::<Result<_, _>>()?)
}

/// Every scan of `scans` located in `map`, judged as `gema2 locate` judges it; progress
/// under `name` on a terminal.
fn locate_all(name: &str, map: &WallMap, config: &Gema2Config, scans: &[LaserScan]) -> Summary {
    let model = Arc::new(MapModel::new(map.clone(), &config.map_corners));
    let mut gema2 = Gema2::new(model, config.segmenter, config.localizer);
    let mut summary = Summary::default();
    let mut progress = crate::progress::Progress::scans(name, Some(scans.len() as u64));
    for scan in scans {
        let outcome = Outcome::located(&mut gema2, scan);
        progress.add(&outcome);
        summary.add(outcome);
    }
    summary
}

/// Whether `path` is named as a CARMEN log: `*.log` or `*.log.gz`.
fn is_carmen_log(path: &Path) -> bool {
    let name = path.file_name().and_then(|n| n.to_str()).unwrap_or("");
    name.ends_with(".log") || name.ends_with(".log.gz")
}

/// The CARMEN logs `--carmen` names: the logs in the folder `dir`, by name, or `dir` itself
/// when it is one log.
pub(crate) fn carmen_logs(dir: &Path) -> Result<Vec<PathBuf>> {
    if !dir.is_dir() {
        if !dir.exists() {
            bail!("{}: no such folder or log", dir.display());
        }
        if !is_carmen_log(dir) {
            bail!("{}: neither a folder nor a CARMEN log (*.log, *.log.gz)", dir.display());
        }
        return Ok(vec![dir.to_owned()]);
    }
    let mut logs: Vec<PathBuf> = std::fs::read_dir(dir)
        .with_context(|| format!("reading {}", dir.display()))?
        .map(|e| e.map(|e| e.path()))
        .collect::<Result<_, _>>()
        .with_context(|| format!("reading {}", dir.display()))?;
    logs.retain(|p| is_carmen_log(p));
    logs.sort();
    if logs.is_empty() {
        bail!("{}: no CARMEN log (*.log, *.log.gz)", dir.display());
    }
    Ok(logs)
}

pub(crate) fn log_stem(log: &Path) -> String {
    let name = log.file_name().and_then(|n| n.to_str()).unwrap_or("log");
    name.trim_end_matches(".gz").trim_end_matches(".log").to_string()
}

/// The occupancy grid `gema2 map build --grid` draws of every other scan of `log` from
/// `offset`, made into walls as `--map GRID.yaml` makes them ([`mapio::grid_walls`]).
fn grid_map(log: &Path, offset: usize) -> Result<WallMap> {
    let grid = build_map::survey_grid(&BuildArgs::every_other(log, offset)?)?;
    mapio::grid_walls(&grid)
        .map(|(map, _)| map)
        .map_err(|e| anyhow::anyhow!("{}: the grid of every other scan from {offset}: {e}", log.display()))
}

/// The map `gema2 map build` makes of every other scan of `log` from `offset`, as its file
/// reads back. The log's malformed lines are left out unreported: [`run`] reported them when
/// it read the log.
pub(crate) fn built_map(log: &Path, offset: usize) -> Result<WallMap> {
    let map = build_map::build(&BuildArgs::every_other(log, offset)?, &mut Malformed::silent())?.map;
    Ok(WallMap::parse(&map.to_json("built"), log)?)
}

/// The map `gema2 map build` makes of `log`'s even scans, and its odd scans as `gema2 locate
/// --every 2 --offset 1` takes them: what a sequential run locates (`--sequential`, `gema2
/// amcl`). A malformed line keeps its place, so the halves stay those; it is counted in
/// `malformed` and located in neither.
pub(crate) fn odd_scans_and_even_map(log: &Path, malformed: &mut Malformed) -> Result<(WallMap, Vec<LogScan>)> {
    let mut items = Vec::new();
    for item in CarmenReader::open(log, FlaserLayout::default())? {
        items.push(malformed.take(item)?);
    }
    let odd = items.into_iter().skip(1).step_by(2).flatten().collect();
    Ok((built_map(log, 0)?, odd))
}

/// The columns of `--sequential`'s tables.
const SEQ_HEAD: [&str; 11] = [
    "log",
    "scans",
    "starts",
    "median to fix",
    "fixed within 3",
    "wrong ok",
    "right after fix",
    "tracking median us",
    "tracking p99 us",
    "median us",
    "kidnaps: last ok on the old place / wrong ok after the cut / right ok within 5",
];

/// The distances walked between two scans of `--sequential`'s simulated walks, metres.
const WALK_STEPS: [f64; 2] = [0.2, 0.8];

/// The share of right poses after the first fix that the walks' total counts walks at
/// (issue 48's bar).
const STEADY: f64 = 0.995;

/// `--sequential`: the sequential localizer on simulated walks through the suite's maps (but
/// with `--no-sim`), and on each CARMEN log's odd scans against the map of its even ones;
/// a table each, one row a log.
fn sequential_suite(a: &EvaluateArgs, config: &Gema2Config) -> Result<()> {
    let noise = a.seq.noise()?;
    let restarts = a.seq.restart_every.map_or("- (never)".to_string(), |n| n.to_string());
    let mut page = String::new();
    if !a.no_sim {
        let title = format!(
            "simulated walks of {} scans, {} m a scan, seed {}, sequential, odometry {}, a cold start every {restarts} located scans",
            a.scans,
            WALK_STEPS.map(|s| s.to_string()).join(" or "),
            a.seed,
            noise.map_or("exact".to_string(), |n| format!("drawn with noise {:?}", n.alphas)),
        );
        let mut table = seq_header(&title);
        // every walk's located scans, one start after another: the total's figures
        let (mut all, mut walks, mut steady) = (Vec::new(), 0, 0);
        for (name, map) in suite_maps(&a.map_seeds)? {
            let model = Arc::new(MapModel::new(map.clone(), &config.map_corners));
            for step in WALK_STEPS {
                for scenario in [Scenario::Clean, Scenario::People, Scenario::Furniture] {
                    let walk = walked_log(&map, scenario, a.seed, a.scans, step, noise)?;
                    let name = format!("{name} {scenario} {step} m");
                    // the walk's odometry already drifts as asked: located as the log's own
                    let (row, outcomes) = seq_row(a, &name, &model, config, &walk, None)?;
                    table += &row;
                    let s = SeqSummary::of(&outcomes);
                    steady += usize::from(s.right_after_fix_share().is_some_and(|r| r >= STEADY));
                    all.extend(outcomes);
                    walks += 1;
                }
            }
        }
        let all = SeqSummary::of(&all);
        let total = format!(
            "total: {walks} walks, {} scans, {} starts; fixed within 3: {:.1} %; wrong ok {}; right after fix {}; walks at {:.1} % or more right after fix: {steady} of {walks}; tracking median {} us",
            all.scans,
            all.starts,
            100.0 * all.fixed_within(3),
            all.wrong_ok_cell(),
            all.right_after_fix_cell(2),
            100.0 * STEADY,
            all.tracking().map_or("-".to_string(), |(t50, _)| format!("{t50:.0}")),
        );
        println!("{total}");
        page += &format!("{table}\n{total}\n\n");
    }
    let mut malformed = Malformed::default();
    if let Some(dir) = &a.carmen {
        let title = format!(
            "{}: odd scans against a map of the even ones, sequential, odometry {}, a cold start every {restarts} located scans",
            dir.display(),
            noise
                .map_or("of the log".to_string(), |n| format!("drawn with noise {:?}, seed {}", n.alphas, a.seq.odom_seed)),
        );
        let mut table = seq_header(&title);
        for log in carmen_logs(dir)? {
            let (map, odd) = odd_scans_and_even_map(&log, &mut malformed)?;
            let model = Arc::new(MapModel::new(map, &config.map_corners));
            table += &seq_row(a, &log_stem(&log), &model, config, &odd, noise)?.0;
        }
        page += &table;
    }
    page += &format!("{}\n", crate::report::disputed_meaning());
    if let Some(path) = &a.markdown {
        let command: Vec<String> = std::env::args().skip(1).filter(|s| !s.is_empty()).collect();
        crate::results::write_section(path, "evaluate-sequential", &format!("gema2 {}", command.join(" ")), &page)?;
    }
    malformed.into_result("skipped")
}

/// A `--sequential` table's title and head, printed; the markdown of both returned.
fn seq_header(title: &str) -> String {
    println!("\n{title}\n\n{}", SEQ_HEAD.join(" | "));
    format!("### {title}\n\n| {} |\n|{}\n", SEQ_HEAD.join(" | "), "---|".repeat(SEQ_HEAD.len()))
}

/// One log's row of `--sequential`'s table: `scans` located in order by a sequential run on
/// `model`, with odometry drawn with `noise` (the log's own without), and `--kidnaps`
/// splices of them. Printed, with the splices that missed a bar; the markdown row and the
/// run's located scans returned.
fn seq_row(
    a: &EvaluateArgs,
    name: &str,
    model: &Arc<MapModel>,
    config: &Gema2Config,
    scans: &[LogScan],
    noise: Option<laser::motion::OdometryNoise>,
) -> Result<(String, Vec<SeqOutcome>)> {
    use crate::sequential::{Odometry, SeqRun};
    let mut run = SeqRun::new(Arc::clone(model), config, a.seq.restart_every);
    let mut odometry = Odometry::new(noise, a.seq.odom_seed);
    let scans: Vec<&LogScan> = scans.iter().collect();
    let mut progress = crate::progress::Progress::scans(name, Some(scans.len() as u64));
    for item in &scans {
        let odom = odometry.next(item.odometry, item.scan.truth.as_ref(), false)?;
        let o = run.locate(&item.scan, odom);
        progress.add(&o.outcome);
    }
    progress.finish();
    let (kidnaps, missed) = kidnap_all(&scans, a.kidnaps, model, config, noise, a.seq.odom_seed)?;
    let s = run.summary();
    let pct = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{:.1} %", 100.0 * v));
    let (t50, t99) =
        s.tracking().map_or(("-".to_string(), "-".to_string()), |(a, b)| (format!("{a:.0}"), format!("{b:.0}")));
    let cells = [
        name.to_string(),
        s.scans.to_string(),
        s.starts.to_string(),
        s.median_to_fix(),
        pct(Some(s.fixed_within(3))),
        s.wrong_ok_cell(),
        s.right_after_fix_cell(1),
        t50,
        t99,
        format!("{:.0}", s.median_micros()),
        kidnaps,
    ];
    println!("{}", cells.join(" | "));
    let lines: Vec<usize> = scans.iter().map(|item| item.line).collect();
    for m in crate::sequential::to_look_into(&s, &run.outcomes, &lines, 3).into_iter().chain(missed) {
        println!("  {m}");
    }
    Ok((format!("| {} |\n", cells.join(" | ")), run.outcomes))
}

/// A robot walking `step` metres a scan through `map` among `scenario`'s obstacles, its
/// odometry drawn with `noise` (exact without), as `gema2 sim --trajectory` writes it and
/// `gema2 locate` reads it back: a row equals `gema2 sim --trajectory --step S --odom-noise N
/// --seed S` then `gema2 locate --sequential` on the same map.
fn walked_log(
    map: &WallMap,
    scenario: Scenario,
    seed: u64,
    scans: usize,
    step: f64,
    noise: Option<laser::motion::OdometryNoise>,
) -> Result<Vec<LogScan>> {
    let sim = Simulator::new(map, SensorModel::urg04lx(), scenario, seed);
    let mut walk = acquire::Walk::new(sim, step, Some(noise.unwrap_or(laser::motion::OdometryNoise::NONE)), seed);
    let mut text = Vec::new();
    for _ in 0..scans {
        let (scan, odometry) = walk.next_scan();
        acquire::write_robotlaser1_with_odometry(&mut text, &scan, odometry.as_ref())?;
    }
    let reader =
        CarmenReader::from_reader(Box::new(std::io::Cursor::new(text)), Path::new("walked"), FlaserLayout::default());
    Ok(reader.collect::<Result<_, _>>()?)
}

/// `--kidnaps N`: N splices of two stretches of the log's `odd` scans at least 10 m apart, each
/// located by a fresh sequential localizer on `model` with no odometry across the cut.
/// Says, over the splices, the latest scan after a cut with a wrong `ok` and how many found a
/// right `ok` within 5 scans of it; and, a line each, the splices that missed either bar
/// (an `ok` on the old place after the second scan, no right `ok` within 5), to look into.
fn kidnap_all(
    odd: &[&acquire::LogScan],
    count: usize,
    model: &Arc<MapModel>,
    config: &Gema2Config,
    noise: Option<laser::motion::OdometryNoise>,
    seed: u64,
) -> Result<(String, Vec<String>)> {
    use crate::sequential::{Kidnap, Odometry, SeqRun};
    const STRETCH: usize = 20;
    if count == 0 {
        return Ok(("-".into(), Vec::new()));
    }
    let n = odd.len();
    let place = |k: usize| odd[k].scan.truth.map(|t| t.translation.vector);
    let (mut results, mut missed) = (Vec::new(), Vec::new());
    for k in 0..count {
        let i = k * n / count;
        if i + STRETCH > n {
            break;
        }
        let Some(end_a) = place(i + STRETCH - 1) else { continue };
        // the first stretch from half the log on that starts 10 m away
        let far = (0..n)
            .map(|d| (i + n / 2 + d * 7) % n)
            .take(n)
            .find(|&j| j + STRETCH <= n && place(j).is_some_and(|p| (p - end_a).norm() >= 10.0));
        let Some(j) = far else { continue };
        let mut fresh = SeqRun::new(Arc::clone(model), config, None);
        let mut odometry = Odometry::new(noise, seed + k as u64 + 1);
        let mut after = Vec::new();
        for (m, item) in odd[i..i + STRETCH].iter().chain(&odd[j..j + STRETCH]).enumerate() {
            // drawn odometry sees no motion across the cut; the log's own is moved on from
            // where it was at the cut by the second stretch's own motion
            let odom = match noise {
                Some(_) => odometry.next(None, item.scan.truth.as_ref(), m == STRETCH)?,
                None if m >= STRETCH => shifted(odd, i + STRETCH - 1, j, m - STRETCH),
                None => item.odometry,
            };
            let o = fresh.locate(&item.scan, odom);
            if m >= STRETCH {
                after.push(o);
            }
        }
        let Some(old) = odd[i + STRETCH - 1].scan.truth else { continue };
        let judged = Kidnap::judge(&after, &old);
        if judged.last_old_ok > 2 || judged.new_fix.is_none_or(|f| f > 5) {
            missed.push(format!(
                "kidnap {k}: the scans of log lines {}-{}, then of lines {}-{}: last ok on the old place {}, first right ok {}",
                odd[i].line,
                odd[i + STRETCH - 1].line,
                odd[j].line,
                odd[j + STRETCH - 1].line,
                judged.last_old_ok,
                judged.new_fix.map_or("none".to_string(), |f| format!("{f} scans after the cut")),
            ));
        }
        results.push(judged);
    }
    if results.is_empty() {
        return Ok(("- (no two stretches 10 m apart)".into(), missed));
    }
    let worst = results.iter().map(|r| r.last_old_ok).max().unwrap_or(0);
    let wrong: usize = results.iter().map(|r| r.wrong_ok).sum();
    let disputed: usize = results.iter().map(|r| r.disputed).sum();
    let wrong = crate::report::wrong_cell(wrong, disputed);
    let found = results.iter().filter(|r| r.new_fix.is_some_and(|f| f <= 5)).count();
    Ok((format!("{worst} / {wrong} / {found} of {}", results.len()), missed))
}

/// The log's odometry for the `m`-th scan after a cut from scan `a` to scan `b` of `odd`: where
/// odometry was at `a`, moved on by the motion from `b` to `b + m`.
fn shifted(odd: &[&acquire::LogScan], a: usize, b: usize, m: usize) -> Option<laser::Pose> {
    let (at_a, at_b, now) = (odd[a].odometry?, odd[b].odometry?, odd[b + m].odometry?);
    Some(at_a * laser::motion::motion(&at_b, &now))
}
