//! `gema2 bench`: per-stage time per scan (the paper's Figure 9 breakdown) and how the whole
//! locate scales with beams and map walls. Figures, not pass/fail: this machine is shared and
//! noisy, so every figure is a median over many scans.

use crate::report::quantile;
use acquire::{Scenario, SensorModel, Simulator};
use anyhow::Result;
use clap::Args;
use localize::{Gema2, LocalizerConfig, MapModel};
use map::{MapCornerConfig, WallMap};
use segment::SegmenterConfig;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Instant;

#[derive(Args)]
pub struct BenchArgs {
    /// Scans per measurement.
    #[arg(long, default_value_t = 200, value_parser = super::positive_count)]
    pub scans: usize,
    /// Rounds of the per-stage measurement, each over the same scans: the round with the lowest
    /// median total is shown stage by stage, and every round's median total is listed.
    #[arg(long, default_value_t = 3, value_parser = super::positive_count)]
    pub rounds: usize,
    /// Skip the scaling table.
    #[arg(long)]
    pub stages_only: bool,
    /// Beam counts of the scaling table.
    #[arg(long, value_delimiter = ',', default_value = "68,170,341,682,1364", value_parser = super::beam_count)]
    pub beams: Vec<usize>,
    /// Wall counts of the scaling table.
    #[arg(long, value_delimiter = ',', default_value = "50,200,1000,5000")]
    pub walls: Vec<usize>,
    /// Measure the process pipeline instead: latency at 10 Hz with every hop across cores and
    /// with all stages on one core, each with default and with real-time scheduling, and
    /// throughput at --rate max.
    #[arg(long)]
    pub pipeline: bool,
    /// Seconds of each pipeline measurement.
    #[arg(long, default_value_t = 10.0, value_parser = super::positive_seconds)]
    pub seconds: f64,
    /// The source's warm-up lead at 10 Hz (acquire's --warm-up-us; 0: none), to compare.
    #[arg(long, default_value_t = acquire::node::DEFAULT_WARM_UP_US)]
    pub warm_up_us: u64,
    /// Measure what a second localizer adds to the machine's memory instead: a pipeline on
    /// --map, scans from --log (or simulated in --map) at --rate, a second localize stage
    /// beside it, its own memory read once a second for --seconds after it is ready.
    #[arg(long, conflicts_with = "pipeline")]
    pub memory: bool,
    /// With --memory: the map served (a bundled map's name, a JSON wall map, a ROS .yaml).
    #[arg(long, default_value = "office", requires = "memory")]
    pub map: String,
    /// With --memory: a CARMEN log to replay (default: simulate in --map).
    #[arg(long, requires = "memory")]
    pub log: Option<PathBuf>,
    /// With --memory: each CARMEN log of this folder (or this one log) in turn, on the map of
    /// its even scans, built as `gema2 map build --every 2 --offset 0` builds it: a table.
    #[arg(long, requires = "memory", conflicts_with_all = ["map", "log"])]
    pub carmen: Option<PathBuf>,
    /// With --memory: scans per second.
    #[arg(long, default_value = "20", requires = "memory", value_parser = acquire::node::rate_arg)]
    pub rate: String,
    /// Also write the per-stage and scaling tables (or, with --memory, its figures) into this
    /// markdown file (its `bench` or `bench-memory` section, the rest kept):
    /// `--markdown docs/results.md`.
    #[arg(long, value_name = "FILE", conflicts_with = "pipeline")]
    pub markdown: Option<PathBuf>,
}

/// Prints a line and keeps it in `$out` (a `String`, or a `&mut String`).
macro_rules! say {
    ($out:expr, $($arg:tt)*) => {{
        let line = format!($($arg)*);
        println!("{line}");
        $out.push_str(&line);
        $out.push('\n');
    }};
}

/// [`say!`] without the line's end.
macro_rules! say_part {
    ($out:expr, $($arg:tt)*) => {{
        let part = format!($($arg)*);
        print!("{part}");
        $out.push_str(&part);
    }};
}

/// Where the stages of a benchmark pipeline run.
struct Layout {
    /// Cores of acquire, segment, localize and the supervisor (the pose consumer).
    cores: [usize; 4],
    /// SCHED_FIFO priorities rising downstream, and idle cores kept awake (PM QoS 0 us).
    realtime: bool,
}

/// A pipeline file for the simulator in the office laid out as `layout`.
fn pipeline_file(layout: &Layout, warm_up_us: u64) -> String {
    let [acquire, segment, localize, supervisor] = layout.cores;
    let priority = |p: u8| if layout.realtime { format!("priority = {p}\n") } else { String::new() };
    let wake = if layout.realtime { "wake_latency_us = 0\n" } else { "" };
    format!(
        "[supervisor]\ncpu = {supervisor}\n{}{wake}\n\
         [[stage]]\nname = \"mapserver\"\nkind = \"mapserver\"\nargs = [\"--map\", \"office\"]\n\n\
         [[stage]]\nname = \"localize\"\nkind = \"localize\"\ncpu = {localize}\n{}\n\
         [[stage]]\nname = \"segment\"\nkind = \"segment\"\ncpu = {segment}\n{}\n\
         [[stage]]\nname = \"acquire\"\nkind = \"acquire\"\n\
         args = [\"--map\", \"office\", \"--warm-up-us\", \"{warm_up_us}\"]\ncpu = {acquire}\n{}\
         restart = \"never\"\n",
        priority(40),
        priority(30),
        priority(20),
        priority(10),
    )
}

fn bench_pipeline(a: &BenchArgs) -> Result<()> {
    let scratch = super::ScratchDir::new("bench")?;
    let dir = scratch.path();
    let cores = std::thread::available_parallelism().map(|n| n.get()).unwrap_or(1);
    let other = 1.min(cores - 1);
    let recorder = crate::supervisor::child::viewer_binary();
    // latency: every hop crosses cores (neighbours on different cores), or none does; with the
    // system's default scheduling, then real-time. Throughput: the heaviest stage alone.
    let apart = [0, other, 0, other];
    let runs: [(&str, Layout, &str, f64, bool); 6] = [
        ("every hop across cores, 10 Hz", Layout { cores: apart, realtime: false }, "10", 10.0, false),
        ("all on one core, 10 Hz", Layout { cores: [0; 4], realtime: false }, "10", 10.0, false),
        ("every hop across cores, real-time, 10 Hz", Layout { cores: apart, realtime: true }, "10", 10.0, false),
        ("all on one core, real-time, 10 Hz", Layout { cores: [0; 4], realtime: true }, "10", 10.0, false),
        (
            "localize alone on a core, --rate max",
            Layout { cores: [0, 0, other, 0], realtime: false },
            "max",
            2000.0,
            false,
        ),
        (
            "localize alone on a core, --rate max, recorded by the viewer",
            Layout { cores: [0, 0, other, 0], realtime: false },
            "max",
            2000.0,
            true,
        ),
    ];
    for (k, (title, layout, rate, hz, record)) in runs.iter().enumerate() {
        let file = dir.join(format!("p{k}.toml"));
        std::fs::write(&file, pipeline_file(layout, a.warm_up_us))?;
        let [ac, sc, lc, pc] = layout.cores;
        println!("== {title} (acquire, segment, localize, consumer on cores {ac}, {sc}, {lc}, {pc})");
        if layout.realtime {
            println!("(SCHED_FIFO priorities 10, 20, 30, 40 downstream; idle cores held to 0 us wake-up by PM QoS)");
        }
        if *record {
            if let Err(e) = &recorder {
                println!("skipped: {e:#}");
                continue;
            }
            println!("(the viewer's own counts, recorded and missed per topic, are on stderr)");
        }
        let scans = ((hz * a.seconds).round() as u64).max(1);
        let outcome = crate::supervisor::run(crate::supervisor::RunArgs {
            pipeline: Some(file),
            scans: Some(scans),
            rate: Some((*rate).into()),
            prefix: format!("bench{}_{k}", std::process::id()),
            out: None,
            timeout: Some(a.seconds * 6.0 + 30.0),
            record: record.then(|| dir.join("bench.rrd")),
            max_size: None,
        });
        match outcome {
            // real-time scheduling is the system's to grant: without it, say so and go on
            Err(e) if layout.realtime => println!("skipped: {e:#}"),
            other => other?,
        }
        if *record {
            let size = std::fs::metadata(dir.join("bench.rrd")).map(|m| m.len()).unwrap_or(0);
            println!("recording: {:.1} MB", size as f64 / 1e6);
        }
    }
    Ok(())
}

struct Run {
    /// Per scan: samples, inference, filter+corners, matching+screen, coarse, refine, cost,
    /// total (microseconds).
    steps: Vec<[f64; 8]>,
    /// Per scan: whether the localizer's full search ran.
    full_search: Vec<bool>,
    success: f64,
}

fn run(map: &WallMap, sensor: SensorModel, scans: usize) -> Run {
    let model = Arc::new(MapModel::new(map.clone(), &MapCornerConfig::default()));
    let mut sim = Simulator::new(map, sensor, Scenario::Clean, 7);
    let data: Vec<_> = (0..scans).map(|_| sim.next_scan()).collect();
    let mut gema2 = Gema2::new(model, SegmenterConfig::default(), LocalizerConfig::default());
    let mut steps = Vec::with_capacity(scans);
    let mut full_search = Vec::with_capacity(scans);
    let mut right = 0;
    for scan in &data {
        let start = Instant::now();
        let (seg, loc) = gema2.process(&scan.view());
        let total = start.elapsed();
        let us = |d: std::time::Duration| d.as_secs_f64() * 1e6;
        let (s, l) = (&seg.times, &loc.times);
        steps.push([
            us(s.samples),
            us(s.inference),
            us(s.corners),
            us(l.matching),
            us(l.coarse),
            us(l.refine),
            us(l.cost),
            us(total),
        ]);
        full_search.push(l.full_search());
        let truth = scan.truth.expect("simulated scans carry truth");
        if loc.best().is_some_and(|h| localize::same_pose(&h.pose, &truth, 0.3, 5f64.to_radians())) {
            right += 1;
        }
    }
    Run { steps, full_search, success: right as f64 / scans.max(1) as f64 }
}

fn median(run: &Run, k: usize) -> f64 {
    let mut v: Vec<f64> = run.steps.iter().map(|s| s[k]).collect();
    quantile(&mut v, 0.5)
}

pub fn run_bench(a: BenchArgs) -> Result<()> {
    if a.pipeline {
        return bench_pipeline(&a);
    }
    if a.memory {
        return super::bench_memory::bench_memory(&a);
    }
    let office = mapio::load_map("office")?;
    // what is printed, kept for --markdown
    let mut out = String::new();
    say!(
        out,
        "GEMA2 per-stage time per scan: bundled office ({} walls), URG-04LX 682 beams, clean, {} scans",
        office.walls.len(),
        a.scans
    );
    // a shared machine's load only ever adds time: the quietest round is the nearest to what
    // the code takes, and the others show how far the load moved it
    let rounds: Vec<Run> = (0..a.rounds).map(|_| run(&office, SensorModel::urg04lx(), a.scans)).collect();
    let totals: Vec<f64> = rounds.iter().map(|r| median(r, 7)).collect();
    let quietest = (0..rounds.len()).min_by(|&i, &j| totals[i].total_cmp(&totals[j])).unwrap_or(0);
    let r = &rounds[quietest];
    if rounds.len() > 1 {
        let listed: Vec<String> = totals.iter().map(|t| format!("{t:.1}")).collect();
        say!(
            out,
            "  median total of each of {} rounds: {} us; below, round {} (the quietest), stage by stage",
            rounds.len(),
            listed.join(" / "),
            quietest + 1
        );
    }
    let names = [
        "acquisition (samples, eqs. 1-2)",
        "line inference (Codes 1-2)",
        "filtering + corners (eq. 4)",
        "matching (eqs. 5-6) + screening",
        "coarse cost (eq. 7, 64 beams)",
        "refinement",
        "cost function (eq. 7, all beams)",
        "total",
    ];
    let total = median(r, 7);
    for (k, name) in names.iter().enumerate() {
        let m = median(r, k);
        say!(out, "  {name:34} median {m:8.1} us  ({:4.1} %)", 100.0 * m / total);
    }
    let mut t: Vec<f64> = r.steps.iter().map(|s| s[7]).collect();
    say!(out, "  {:34} p99    {:8.1} us   success {:.1} %", "total", quantile(&mut t, 0.99), 100.0 * r.success);
    let (mut first, mut full): (Vec<f64>, Vec<f64>) = (Vec::new(), Vec::new());
    for (s, &f) in r.steps.iter().zip(&r.full_search) {
        if f { &mut full } else { &mut first }.push(s[7]);
    }
    say!(
        out,
        "  the first look settled {:.1} % of scans (median total {:.1} us); the full search ran on {:.1} % ({:.1} us)",
        100.0 * first.len() as f64 / r.steps.len().max(1) as f64,
        quantile(&mut first, 0.5),
        100.0 * full.len() as f64 / r.steps.len().max(1) as f64,
        quantile(&mut full, 0.5)
    );
    if !a.stages_only {
        scaling(&a, &mut out);
    }
    if let Some(path) = &a.markdown {
        let command: Vec<String> = std::env::args().skip(1).collect();
        let body = format!("```\n{}```\n", out);
        crate::results::write_section(path, "bench", &format!("gema2 {}", command.join(" ")), &body)?;
    }
    Ok(())
}

/// The scaling table: how the whole locate's time grows with beams and map walls.
fn scaling(a: &BenchArgs, out: &mut String) {
    say!(
        out,
        "\nScaling: median total locate time per scan (us) [success %], office maps of about W walls, {} scans each",
        a.scans
    );
    let maps: Vec<WallMap> = a.walls.iter().map(|&w| worlds::office_with_walls(3, w)).collect();
    say_part!(out, "{:>8}", "beams");
    for m in &maps {
        say_part!(out, "  {:>16}", format!("{} walls", m.walls.len()));
    }
    say!(out, "");
    for &b in &a.beams {
        say_part!(out, "{b:>8}");
        for m in &maps {
            let r = run(m, SensorModel::urg04lx_with_beams(b), a.scans);
            say_part!(out, "  {:>9.0} [{:4.1}]", median(&r, 7), 100.0 * r.success);
        }
        say!(out, "");
    }
}
