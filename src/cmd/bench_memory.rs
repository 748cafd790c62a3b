//! `gema2 bench --memory`: what a second localizer adds to the machine's memory.
//!
//! The map server builds the map model once and every localizer reads it in place from shared
//! memory; what each localizer adds is its own memory. This runs a pipeline (the map server,
//! acquire replaying a log or simulating, segment, localize), starts a second localize stage
//! beside it, and reads the second one's Private_Clean + Private_Dirty from
//! `/proc/PID/smaps_rollup` once a second while the pipeline runs: its figure 10 s after it is
//! ready, and the most over the run, against a tenth of the model's size. Readings stop when
//! the pipeline ends: then the others have unmapped the model and the binary, and their pages
//! would count as this process's own.

use super::bench::BenchArgs;
use super::KilledOnDrop;
use anyhow::{bail, Context, Result};
use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Command, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

/// How long the pipeline gets to have its map model served and its localizer ready before the
/// second localizer starts.
const PIPELINE_LEAD: Duration = Duration::from_secs(4);

/// How long the second localizer gets to read the model.
const READY_PATIENCE: Duration = Duration::from_secs(30);

/// A TOML basic string holding `s`.
fn toml_string(s: &str) -> String {
    toml::Value::String(s.to_owned()).to_string()
}

/// The pipeline file: the map server on `map`, acquire replaying `log` at `rate` or, without
/// one, simulating in `map`.
fn pipeline_file(map: &str, log: Option<&Path>, rate: &str) -> String {
    let source = match log {
        Some(log) => format!("\"--log\", {}", toml_string(&log.to_string_lossy())),
        None => format!("\"--map\", {}", toml_string(map)),
    };
    format!(
        "[[stage]]\nname = \"mapserver\"\nkind = \"mapserver\"\nargs = [\"--map\", {map}]\n\n\
         [[stage]]\nname = \"localize\"\nkind = \"localize\"\n\n\
         [[stage]]\nname = \"segment\"\nkind = \"segment\"\n\n\
         [[stage]]\nname = \"acquire\"\nkind = \"acquire\"\nargs = [{source}, \"--rate\", {rate}]\nrestart = \"never\"\n",
        map = toml_string(map),
        rate = toml_string(rate),
    )
}

/// Memory of the process `pid` of its own (not shared with another process), kB; `None` once
/// it is gone.
pub fn private_kb(pid: u32) -> Option<u64> {
    let text = std::fs::read_to_string(format!("/proc/{pid}/smaps_rollup")).ok()?;
    Some(
        text.lines()
            .filter(|l| l.starts_with("Private_Clean:") || l.starts_with("Private_Dirty:"))
            .filter_map(|l| l.split_whitespace().nth(1)?.parse::<u64>().ok())
            .sum(),
    )
}

/// The model's megabytes from a localizer's "map version N (...): X MB read in place" line.
pub fn model_mb(line: &str) -> Option<f64> {
    let (before, _) = line.split_once(" MB read in place")?;
    before.rsplit(' ').next()?.parse().ok().filter(|mb: &f64| mb.is_finite() && *mb > 0.0)
}

/// What the second localizer said that the benchmark waits for.
enum Said {
    Model(f64),
    FirstPose,
    /// Anything else it said.
    Other(String),
}

/// The last `n` lines of what stages said, without backtraces (RUST_BACKTRACE).
fn last_said(said: &str, n: usize) -> String {
    let last: Vec<&str> = said
        .lines()
        .filter(|l| !l.starts_with(' ') && !l.is_empty() && *l != "Stack backtrace:")
        .rev()
        .take(n)
        .collect();
    last.into_iter().rev().collect::<Vec<_>>().join("\n")
}

pub fn bench_memory(a: &BenchArgs) -> Result<()> {
    if !Path::new("/proc/self/smaps_rollup").exists() {
        bail!("--memory reads /proc/PID/smaps_rollup (Linux 4.14 and later), which this system lacks");
    }
    let scratch = super::ScratchDir::new("bench-memory")?;
    let mut out = String::new();
    let mut say = |line: String| {
        println!("{line}");
        out.push_str(&line);
        out.push('\n');
    };
    match &a.carmen {
        None => {
            let m = measure(&scratch, &a.map, a.log.as_deref(), &a.rate, a.seconds)?;
            let source = a.log.as_ref().map_or_else(|| format!("simulated in {}", a.map), |l| l.display().to_string());
            say(format!(
                "second localizer beside a running pipeline: map {}, scans {source} at {} a second",
                a.map, a.rate
            ));
            say(format!("  map model: {:.1} MB, shared; a tenth of it: {:.0} kB", m.model_mb, m.tenth_kb()));
            let at_10 = m.at_10.map(|kb| format!("{kb} kB 10 s after ready, ")).unwrap_or_default();
            say(format!(
                "  its own memory (Private_Clean + Private_Dirty): {at_10}{} kB at {:.0} s, at most {} kB over {} readings: {} a tenth of the model",
                m.last.1,
                m.last.0,
                m.most,
                m.readings,
                m.verdict()
            ));
        }
        Some(dir) => {
            let logs = super::evaluate::carmen_logs(dir)?;
            say("### a second localizer's own memory, on each log's map".into());
            say(String::new());
            say(format!(
                "A second localizer beside a running pipeline on the map of each log's even scans (`gema2 map build --every 2 --offset 0`), the log replayed at {} scans a second; its own memory (Private_Clean + Private_Dirty) over {} s after it is ready, against a tenth of the shared model.",
                a.rate, a.seconds
            ));
            say(String::new());
            say("| log | model, MB | a tenth, kB | 10 s after ready, kB | at most, kB | |".into());
            say("|---|---|---|---|---|---|".into());
            let (mut within, mut rows) = (0, 0);
            for log in &logs {
                let stem = super::evaluate::log_stem(log);
                let map = scratch.path().join(format!("{stem}-even.json"));
                // the file `gema2 map build` writes of the even scans
                let every_other = super::build_map::BuildArgs::every_other(log, 0)?;
                let built = super::build_map::build(&every_other, &mut super::Malformed::silent())?.map;
                std::fs::write(&map, built.to_json("built")).with_context(|| format!("writing {}", map.display()))?;
                let m = measure(&scratch, &map.to_string_lossy(), Some(log), &a.rate, a.seconds)
                    .with_context(|| format!("{}", log.display()))?;
                rows += 1;
                within += usize::from(m.within());
                let at_10 = m.at_10.map_or_else(|| "-".to_owned(), |kb| kb.to_string());
                say(format!(
                    "| {stem} | {:.1} | {:.0} | {at_10} | {} | {} |",
                    m.model_mb,
                    m.tenth_kb(),
                    m.most,
                    m.verdict()
                ));
            }
            say(String::new());
            say(format!("Within a tenth of the model on {within} of {rows} logs."));
        }
    }
    if let Some(path) = &a.markdown {
        let command: Vec<String> = std::env::args().skip(1).collect();
        // the table per log and the one long run keep their own sections
        let (section, body) = if a.carmen.is_some() {
            ("bench-memory-carmen", out)
        } else {
            ("bench-memory", format!("```\n{out}```\n"))
        };
        crate::results::write_section(path, section, &format!("gema2 {}", command.join(" ")), &body)?;
    }
    Ok(())
}

/// What [`measure`] read of the second localizer.
struct Measured {
    /// The shared model's size, as the localizer said it.
    model_mb: f64,
    /// Its own memory 10 s after it was ready, kB, when the readings lasted that long.
    at_10: Option<u64>,
    /// The last reading: seconds after ready, kB.
    last: (f64, u64),
    /// The most it had over the readings, kB.
    most: u64,
    readings: usize,
}

impl Measured {
    fn tenth_kb(&self) -> f64 {
        self.model_mb * 1e3 / 10.0
    }

    /// Whether the most it had is within a tenth of the model.
    fn within(&self) -> bool {
        (self.most as f64) <= self.tenth_kb()
    }

    fn verdict(&self) -> &'static str {
        if self.within() {
            "within"
        } else {
            "over"
        }
    }
}

/// Runs the pipeline on `map` with scans from `log` (simulated in `map` without) at `rate`,
/// starts a second localizer beside it once the pipeline is under way, and reads the second
/// one's own memory once a second for `seconds` after it has read the model and located a
/// scan, or until the pipeline ends.
fn measure(scratch: &super::ScratchDir, map: &str, log: Option<&Path>, rate: &str, seconds: f64) -> Result<Measured> {
    let exe = std::env::current_exe().context("locating the gema2 binary")?;
    let file = scratch.path().join("memory.toml");
    std::fs::write(&file, pipeline_file(map, log, rate))?;
    let prefix = format!("benchmem{}", std::process::id());
    // the pipeline outlasts the readings, unless its log ends first
    let timeout = seconds + PIPELINE_LEAD.as_secs_f64() + READY_PATIENCE.as_secs_f64() + 30.0;
    let mut run = Command::new(&exe);
    run.arg("run").arg("--pipeline").arg(&file).args(["--prefix", &prefix, "--scans", "0"]);
    let said_path = scratch.path().join("pipeline.err");
    let said = std::fs::File::create(&said_path).context("creating the pipeline's log")?;
    run.args(["--timeout", &format!("{timeout}")]).stdout(Stdio::null()).stderr(said);
    let mut pipeline = KilledOnDrop(run.spawn().context("starting the pipeline")?);
    std::thread::sleep(PIPELINE_LEAD);
    let pipeline_said = || last_said(&std::fs::read_to_string(&said_path).unwrap_or_default(), 4);
    if let Some(status) = pipeline.0.try_wait()? {
        bail!("the pipeline ended before the second localizer started ({status}):\n{}", pipeline_said());
    }
    let mut second = KilledOnDrop(
        Command::new(&exe)
            .args(["stage", "localize", "--prefix", &prefix])
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .context("starting the second localizer")?,
    );
    let pid = second.0.id();
    let stderr = second.0.stderr.take().context("the second localizer's stderr")?;
    let (tx, rx) = mpsc::channel();
    // reads all it says, so it never blocks on a full pipe
    std::thread::spawn(move || {
        for line in BufReader::new(stderr).lines().map_while(Result::ok) {
            let said = match model_mb(&line) {
                Some(mb) => Said::Model(mb),
                None if line.contains("first pose") => Said::FirstPose,
                None => Said::Other(line),
            };
            if tx.send(said).is_err() {
                break;
            }
        }
    });
    let started = Instant::now();
    let (mut mb, mut posed, mut other) = (None, false, String::new());
    while mb.is_none() || !posed {
        let left = READY_PATIENCE.checked_sub(started.elapsed()).unwrap_or_default();
        match rx.recv_timeout(left) {
            Ok(Said::Model(m)) => mb = Some(m),
            Ok(Said::FirstPose) => posed = true,
            Ok(Said::Other(line)) => {
                other.push_str(&line);
                other.push('\n');
            }
            Err(_) => {
                let (what, running) =
                    (if mb.is_none() { "read no model" } else { "located no scan" }, pipeline.0.try_wait()?);
                let running = running.map_or_else(|| "running".to_owned(), |s| format!("ended ({s})"));
                bail!(
                    "the second localizer {what} within {READY_PATIENCE:?}; it said:\n{}\nthe pipeline, {running}, said last:\n{}",
                    Some(last_said(&other, 4)).filter(|s| !s.is_empty()).unwrap_or_else(|| "(nothing)".into()),
                    pipeline_said()
                );
            }
        }
    }
    let model_mb = mb.unwrap_or_default();
    let ready = Instant::now();
    let mut readings: Vec<(f64, u64)> = Vec::new();
    while ready.elapsed().as_secs_f64() < seconds {
        std::thread::sleep(Duration::from_secs(1));
        if pipeline.0.try_wait()?.is_some() {
            break;
        }
        match private_kb(pid) {
            Some(kb) => readings.push((ready.elapsed().as_secs_f64(), kb)),
            None => bail!("the second localizer ended during the readings"),
        }
    }
    let Some(&last) = readings.last() else {
        bail!("the pipeline ended before a reading; a longer log or the simulator gives more");
    };
    let most = readings.iter().map(|r| r.1).max().unwrap_or_default();
    let at_10 = readings.iter().find(|r| r.0 >= 10.0).map(|r| r.1);
    drop(second);
    drop(pipeline);
    Ok(Measured { model_mb, at_10, last, most, readings: readings.len() })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_the_model_size_from_the_localizers_line() {
        let line = "localize: map version 1 (3552 walls, 59728 corners): 9.3 MB read in place, 7 KB copied, in 1.8 ms; ready 1.9 ms after the stage started";
        assert_eq!(model_mb(line), Some(9.3));
        assert_eq!(model_mb("localize: first pose 65.1 ms after the stage started"), None);
        assert_eq!(model_mb("localize: x: NaN MB read in place"), None);
    }

    #[test]
    fn the_pipeline_file_parses_and_quotes_paths() {
        let text = pipeline_file("my \"odd\" map.json", Some(Path::new("/data/a b.log")), "20");
        let value: toml::Value = toml::from_str(&text).expect("valid TOML");
        let stages = value.get("stage").and_then(|s| s.as_array()).expect("stages");
        assert_eq!(stages.len(), 4);
        let args = |k: usize| stages[k].get("args").and_then(|a| a.as_array()).cloned().unwrap_or_default();
        assert_eq!(args(0)[1].as_str(), Some("my \"odd\" map.json"));
        assert_eq!(args(3)[1].as_str(), Some("/data/a b.log"));
        let simulated = pipeline_file("office", None, "max");
        assert!(toml::from_str::<toml::Value>(&simulated).is_ok());
    }

    #[test]
    fn reads_this_process_memory() {
        assert!(private_kb(std::process::id()).is_some_and(|kb| kb > 0));
        assert_eq!(private_kb(u32::MAX), None);
    }
}
