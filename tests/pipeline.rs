//! The pipeline as real processes over shared memory. Every test uses its own service prefix,
//! so tests can run in parallel.

mod common;

use std::collections::BTreeSet;
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};
use std::time::{Duration, Instant};

fn exe() -> &'static str {
    env!("CARGO_BIN_EXE_gema2")
}

fn prefix(test: &str) -> String {
    format!("t{}_{}", test, std::process::id())
}

fn gema2(args: &[&str]) -> Output {
    Command::new(exe()).args(args).output().expect("gema2 runs")
}

/// A simulated log of `scans` scans in the office, and a pipeline file replaying it.
fn setup(dir: &Path, scans: usize, rate: &str) -> (PathBuf, PathBuf) {
    setup_with(dir, scans, rate, &[])
}

/// [`setup`] with more `gema2 sim` arguments.
fn setup_with(dir: &Path, scans: usize, rate: &str, sim_args: &[&str]) -> (PathBuf, PathBuf) {
    let log = dir.join("scans.log");
    let scans = scans.to_string();
    let mut args = vec!["sim", "--map", "office", "--scenario", "people", "--scans", &scans, "--seed", "11", "--out"];
    args.push(log.to_str().unwrap());
    args.extend_from_slice(sim_args);
    let out = gema2(&args);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let pipeline =
        common::write_pipeline(dir, "pipeline.toml", "office", &["--log", log.to_str().unwrap(), "--rate", rate]);
    (log, pipeline)
}

/// `gema2 run` of `pipeline` under `prefix` for `scans` scans, its poses written to `csv`;
/// checked to succeed.
fn run_to_csv(pipeline: &Path, prefix: &str, scans: usize, csv: &Path) -> Output {
    let scans = scans.to_string();
    let (pipeline, csv) = (pipeline.to_str().unwrap(), csv.to_str().unwrap());
    let args = ["run", "--pipeline", pipeline, "--prefix", prefix, "--scans", &scans, "--timeout", "120", "--out", csv];
    let out = gema2(&args);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    out
}

/// The run's CSV holds a pose for each of scans 0..n, each once.
fn assert_every_pose_once(csv: &Path, n: u64) {
    let seqs: Vec<u64> = rows(csv).iter().map(|r| r[0].parse().unwrap()).collect();
    let distinct: BTreeSet<u64> = seqs.iter().copied().collect();
    let missing: Vec<u64> = (0..n).filter(|s| !distinct.contains(s)).collect();
    let repeated = seqs.len() - distinct.len();
    assert!(missing.is_empty() && repeated == 0 && distinct.len() as u64 == n, "lost {missing:?}, {repeated} repeated");
}

fn rows(csv: &Path) -> Vec<Vec<String>> {
    std::fs::read_to_string(csv).unwrap().lines().skip(1).map(|l| l.split(',').map(str::to_owned).collect()).collect()
}

/// Processes whose command line holds `stage <kind>` and `--prefix <prefix>`.
fn stage_pids(kind: &str, prefix: &str) -> Vec<u32> {
    let mut pids = Vec::new();
    for entry in std::fs::read_dir("/proc").unwrap().flatten() {
        let Ok(pid) = entry.file_name().to_string_lossy().parse::<u32>() else { continue };
        let Ok(cmd) = std::fs::read(entry.path().join("cmdline")) else { continue };
        let args: Vec<String> = cmd.split(|&b| b == 0).map(|a| String::from_utf8_lossy(a).into_owned()).collect();
        let has = |w: &[&str]| args.windows(w.len()).any(|x| x.iter().zip(w).all(|(a, b)| a == b));
        if has(&["stage", kind]) && has(&["--prefix", prefix]) {
            pids.push(pid);
        }
    }
    pids
}

fn wait_for(what: &str, limit: Duration, mut ok: impl FnMut() -> bool) {
    let start = Instant::now();
    while !ok() {
        assert!(start.elapsed() < limit, "timed out waiting for {what}");
        std::thread::sleep(Duration::from_millis(50));
    }
}

fn run_in_background(pipeline: &Path, prefix: &str, scans: usize, csv: &Path) -> Child {
    Command::new(exe())
        .args([
            "run",
            "--pipeline",
            pipeline.to_str().unwrap(),
            "--prefix",
            prefix,
            "--scans",
            &scans.to_string(),
            "--timeout",
            "120",
        ])
        .args(["--out", csv.to_str().unwrap()])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap()
}

/// A pipeline replaying `scans` simulated scans at `rate`, run in the background under its own
/// prefix, returned once every stage is up and `settle` has passed.
struct Running {
    _dir: tempfile::TempDir,
    csv: PathBuf,
    prefix: String,
    run: Child,
}

fn start_running(test: &str, scans: usize, rate: &str, settle: Duration) -> Running {
    let dir = tempfile::tempdir().unwrap();
    let (_, pipeline) = setup(dir.path(), scans, rate);
    let csv = dir.path().join("poses.csv");
    let p = prefix(test);
    let run = run_in_background(&pipeline, &p, scans, &csv);
    wait_for("all stages", Duration::from_secs(30), || !stage_pids("acquire", &p).is_empty());
    std::thread::sleep(settle);
    Running { _dir: dir, csv, prefix: p, run }
}

#[test]
fn the_pipeline_publishes_exactly_what_locate_computes_offline() {
    let dir = tempfile::tempdir().unwrap();
    // noise 1.5 times what e(d) is calibrated for: most scans are segmented and costed with
    // e(d) widened to their measured noise (the corners message carries the factor), some not
    let noise = ["--noise", "0.015", "--noise-proportional", "0.0075"];
    let (log, pipeline) = setup_with(dir.path(), 300, "max", &noise);
    let (online, offline) = (dir.path().join("online.csv"), dir.path().join("offline.csv"));
    let p = prefix("equal");
    let out = run_to_csv(&pipeline, &p, 300, &online);
    let report = String::from_utf8_lossy(&out.stdout);
    assert!(report.contains("poses received 300 of 300"), "{report}\n{}", String::from_utf8_lossy(&out.stderr));
    let out = gema2(&["locate", "--map", "office", "--log", log.to_str().unwrap(), "--out", offline.to_str().unwrap()]);
    assert!(out.status.success());
    let (a, b) = (rows(&online), rows(&offline));
    assert_eq!(a.len(), 300);
    assert_eq!(b.len(), 300);
    for (x, y) in a.iter().zip(&b) {
        // every column but the compute time
        let same = x.iter().zip(y).enumerate().all(|(k, (u, v))| k == 6 || u == v);
        assert!(same, "pipeline {x:?}\noffline  {y:?}");
    }
    assert!(stage_pids("segment", &p).is_empty(), "stages left running");
}

/// The sequential localizer in the pipeline (`implementation = "sequential"`): the odometry
/// each scan carries reaches it through the segment stage, and it answers as `gema2 locate
/// --sequential` does, its `scans` column included.
#[test]
fn the_sequential_localizer_in_the_pipeline_answers_as_offline() {
    let dir = tempfile::tempdir().unwrap();
    let (log, pipeline) = setup(dir.path(), 60, "max");
    let text = std::fs::read_to_string(&pipeline).unwrap();
    std::fs::write(&pipeline, common::with_stage_lines(&text, "localize", "implementation = \"sequential\"")).unwrap();
    let (online, offline) = (dir.path().join("online.csv"), dir.path().join("offline.csv"));
    run_to_csv(&pipeline, &prefix("sequential"), 60, &online);
    let log = log.to_str().unwrap();
    let out = gema2(&["locate", "--map", "office", "--log", log, "--sequential", "--out", offline.to_str().unwrap()]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let (a, b) = (rows(&online), rows(&offline));
    assert_eq!((a.len(), b.len()), (60, 60));
    for (x, y) in a.iter().zip(&b) {
        let same = x.iter().zip(y).enumerate().all(|(k, (u, v))| k == 6 || u == v);
        assert!(same, "pipeline {x:?}\noffline  {y:?}");
    }
    // with the simulator's exact odometry the answers come to rest on several scans
    assert!(a.iter().any(|r| r[11].parse::<u32>().unwrap() > 3), "{a:?}");
}

/// Where the best track misses a scan, the answer is where odometry put it, with no cost of its
/// own: the pipeline's row says so as `gema2 locate --sequential`'s does (a furnished warehouse
/// walked 0.8 m a scan with drifting odometry, replayed).
#[test]
fn a_missed_track_s_answer_reads_the_same_from_the_pipeline_as_offline() {
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("walk.log");
    let log = log.to_str().unwrap();
    let walk = ["--map", "warehouse", "--scenario", "furniture", "--seed", "2", "--trajectory", "--step", "0.8"];
    let rest = ["--odom-noise", "0.05,0.01,0.05,0.01", "--scans", "60", "--out", log];
    let out = gema2(&["sim"].iter().chain(&walk).chain(&rest).copied().collect::<Vec<_>>());
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let text = std::fs::read_to_string(common::write_pipeline(
        dir.path(),
        "p.toml",
        "warehouse",
        &["--log", log, "--rate", "max"],
    ))
    .unwrap();
    let pipeline = dir.path().join("seq.toml");
    std::fs::write(&pipeline, common::with_stage_lines(&text, "localize", "implementation = \"sequential\"")).unwrap();
    let (online, offline) = (dir.path().join("on.csv"), dir.path().join("off.csv"));
    run_to_csv(&pipeline, &prefix("missed"), 60, &online);
    let out =
        gema2(&["locate", "--map", "warehouse", "--log", log, "--sequential", "--out", offline.to_str().unwrap()]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let (a, b) = (rows(&online), rows(&offline));
    assert_eq!((a.len(), b.len()), (60, 60));
    for (x, y) in a.iter().zip(&b) {
        assert!(x.iter().zip(y).enumerate().all(|(k, (u, v))| k == 6 || u == v), "pipeline {x:?}\noffline  {y:?}");
    }
    let missed = |r: &Vec<String>| r[5] == "ambiguous" && !r[1].is_empty() && r[4].is_empty() && r[9].is_empty();
    assert!(a.iter().any(missed), "no answer of a missed track in {a:?}");
}

/// The pipeline's simulator walking a robot with drifting odometry (`--step`, `--odom-noise`)
/// gives the sequential localizer what `gema2 sim --trajectory` gives it offline: the same
/// poses, and answers resting on many scans.
#[test]
fn the_pipeline_s_walking_simulator_drives_the_sequential_localizer_as_a_walked_log_does() {
    let dir = tempfile::tempdir().unwrap();
    let walk = ["--map", "office", "--scenario", "people", "--seed", "3", "--step", "0.2"];
    let noise = ["--odom-noise", "0.05,0.01,0.05,0.01"];
    let acquire: Vec<&str> = walk.iter().chain(&noise).chain(&["--rate", "max"]).copied().collect();
    let text = std::fs::read_to_string(common::write_pipeline(dir.path(), "p.toml", "office", &acquire)).unwrap();
    let pipeline = dir.path().join("walk.toml");
    std::fs::write(&pipeline, common::with_stage_lines(&text, "localize", "implementation = \"sequential\"")).unwrap();
    let (online, offline, log) = (dir.path().join("on.csv"), dir.path().join("off.csv"), dir.path().join("walk.log"));
    run_to_csv(&pipeline, &prefix("walk"), 40, &online);
    let log = log.to_str().unwrap();
    let sim: Vec<&str> = ["sim"]
        .iter()
        .chain(&walk)
        .chain(&noise)
        .chain(&["--trajectory", "--scans", "40", "--out", log])
        .copied()
        .collect();
    let out = gema2(&sim);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let out = gema2(&["locate", "--map", "office", "--log", log, "--sequential", "--out", offline.to_str().unwrap()]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let (a, b) = (rows(&online), rows(&offline));
    assert_eq!((a.len(), b.len()), (40, 40));
    for (x, y) in a.iter().zip(&b) {
        // the log rounds each range to 0.1 mm: the pose and cost may differ in their last digit
        let same = [0, 5, 11].iter().all(|&k| x[k] == y[k]);
        let close = |k: usize| (x[k].parse::<f64>().unwrap() - y[k].parse::<f64>().unwrap()).abs() < 1e-3;
        assert!(same && [1, 2, 3, 4].into_iter().all(close), "pipeline {x:?}\noffline  {y:?}");
    }
    assert!(a.iter().any(|r| r[11].parse::<u32>().unwrap() > 10), "{a:?}");
}

/// The README's main job: `gema2` with no arguments runs the pipeline of processes on the
/// embedded default and reports each stage's and hop's latency, the success rate, and where to
/// go next. The only test that uses the default prefix.
#[test]
fn the_main_job_runs_the_pipeline_and_reports_hops_and_success() {
    let out = Command::new(exe()).output().expect("gema2 runs");
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{text}\n{}", String::from_utf8_lossy(&out.stderr));
    for want in ["hop acquire -> segment", "hop segment -> localize", "localize stage", "of 300 scans published"] {
        assert!(text.contains(want), "no {want:?} in:\n{text}");
    }
    let success = text
        .lines()
        .find_map(|l| l.strip_prefix("success "))
        .and_then(|l| l.split(' ').next())
        .and_then(|v| v.parse::<f64>().ok())
        .unwrap_or_else(|| panic!("no success rate in:\n{text}"));
    assert!(success > 90.0, "{success} % in:\n{text}");
    assert!(text.contains("next:") && text.contains("gema2 locate"), "{text}");
}

/// A pipeline of 240 scans at 40 Hz under a prefix of `test`, whose `victim` stage (segment,
/// localize or mapserver, one of each running) is SIGKILLed a second in. Checked: the supervisor
/// starts a new one and no other of the three, the run succeeds, and its report counts the
/// restart. Returns the run's directory (kept while it lives) and its poses' CSV.
fn run_with_a_stage_killed(test: &str, victim: &str) -> (tempfile::TempDir, PathBuf) {
    let Running { _dir, csv, prefix: p, run } = start_running(test, 240, "40", Duration::from_secs(1));
    let kinds = ["segment", "localize", "mapserver"];
    let before: Vec<Vec<u32>> = kinds.iter().map(|k| stage_pids(k, &p)).collect();
    assert!(before.iter().all(|pids| pids.len() == 1), "{kinds:?}: {before:?}");
    let Some(k) = kinds.iter().position(|&k| k == victim) else { panic!("no stage kind {victim}") };
    let old = before[k][0];
    // SAFETY: kill(2) on a process this test started (through the supervisor).
    unsafe { libc::kill(old as i32, libc::SIGKILL) };
    wait_for(&format!("a new {victim}"), Duration::from_secs(10), || stage_pids(victim, &p).iter().any(|&q| q != old));
    for (kind, pids) in kinds.iter().zip(&before).filter(|(&kind, _)| kind != victim) {
        assert_eq!(&stage_pids(kind, &p), pids, "{kind} was restarted");
    }
    let out = run.wait_with_output().unwrap();
    let report = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(report.contains(&format!("stage {victim} restarted 1 times")), "{report}");
    (_dir, csv)
}

#[test]
fn a_killed_stage_is_restarted_and_nothing_else_restarts() {
    let (_dir, csv) = run_with_a_stage_killed("kill", "segment");
    // poses kept coming after the restart, up to the end of the log
    let seqs: Vec<u64> = rows(&csv).iter().map(|r| r[0].parse().unwrap()).collect();
    assert!(seqs.iter().max().copied().unwrap_or(0) >= 230, "{seqs:?}");
    assert!(seqs.len() >= 150, "only {} poses", seqs.len());
}

/// The map server killed outright (SIGKILL) while scans flow: the localizer goes on reading the
/// model it holds (the shared memory outlives its dead publisher, and the supervisor's clean-up
/// of the dead node takes nothing from under it), the supervisor starts a new map server, and
/// no scan is lost.
#[test]
fn a_killed_map_server_costs_no_scan() {
    let (_dir, csv) = run_with_a_stage_killed("mapkill", "mapserver");
    assert_every_pose_once(&csv, 240);
}

/// A stage that dies and may not restart (`restart = "never"`) fails the run, after its report:
/// the run went on to the log's end and exited 0, with 38 poses of 100, as though all was well.
#[test]
fn a_stage_that_dies_unrestarted_fails_the_run() {
    let dir = tempfile::tempdir().unwrap();
    let (_, pipeline) = setup(dir.path(), 120, "40");
    let text = std::fs::read_to_string(&pipeline).unwrap();
    std::fs::write(&pipeline, common::with_stage_lines(&text, "segment", "restart = \"never\"")).unwrap();
    let (csv, p) = (dir.path().join("poses.csv"), prefix("never"));
    let run = run_in_background(&pipeline, &p, 120, &csv);
    wait_for("all stages", Duration::from_secs(30), || !stage_pids("acquire", &p).is_empty());
    std::thread::sleep(Duration::from_millis(500));
    let segment = stage_pids("segment", &p);
    assert_eq!(segment.len(), 1);
    // SAFETY: kill(2) on a process this test started (through the supervisor).
    unsafe { libc::kill(segment[0] as i32, libc::SIGKILL) };
    let out = run.wait_with_output().unwrap();
    let (report, err) = (String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
    assert!(!out.status.success(), "{err}");
    assert!(err.contains("stage segment ended (signal: 9") && err.contains("was not restarted"), "{err}");
    // the report and the poses that did come back are kept
    assert!(report.contains("poses received "), "{report}");
    assert!(!rows(&csv).is_empty());
}

/// Ctrl-Z then `fg`, a debugger attaching, any signal that is not SIGINT or SIGTERM: a wait cut
/// short that way must wait again, not end the stage as if it had been asked to stop.
#[test]
fn stages_paused_and_resumed_carry_on() {
    let Running { _dir, csv, prefix: p, run } = start_running("pause", 160, "40", Duration::from_millis(500));
    let mut pids: Vec<u32> =
        ["acquire", "segment", "localize", "mapserver"].iter().flat_map(|k| stage_pids(k, &p)).collect();
    assert_eq!(pids.len(), 4);
    pids.push(run.id());
    for &pid in &pids {
        // SAFETY: kill(2) on processes this test started (directly or through the supervisor).
        unsafe { libc::kill(pid as i32, libc::SIGSTOP) };
        std::thread::sleep(Duration::from_millis(100));
        unsafe { libc::kill(pid as i32, libc::SIGCONT) };
        std::thread::sleep(Duration::from_millis(100));
    }
    for k in ["acquire", "segment", "localize", "mapserver"] {
        assert_eq!(stage_pids(k, &p).len(), 1, "{k} is gone");
        assert!(pids.contains(&stage_pids(k, &p)[0]), "{k} was restarted");
    }
    let out = run.wait_with_output().unwrap();
    let report = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(report.contains("poses received 160 of 160"), "{report}\n{}", String::from_utf8_lossy(&out.stderr));
    assert!(!report.contains("restarted"), "{report}");
    assert_eq!(rows(&csv).len(), 160);
}

/// A supervisor killed outright (SIGKILL, the OOM killer, a crash) cannot stop its stages
/// itself: they must not live on as orphans, still publishing under the prefix a next run uses.
#[test]
fn stages_stop_when_the_supervisor_is_killed() {
    let Running { _dir, prefix: p, mut run, .. } = start_running("orphan", 400, "20", Duration::from_millis(500));
    let kinds = ["acquire", "segment", "localize", "mapserver"];
    let ours: Vec<u32> = kinds.iter().flat_map(|k| stage_pids(k, &p)).collect();
    assert_eq!(ours.len(), 4);
    run.kill().unwrap();
    let _ = run.wait();
    wait_for("the orphaned stages to stop", Duration::from_secs(10), || {
        kinds.iter().all(|k| stage_pids(k, &p).is_empty())
    });
    // they stopped cleanly, removing their own iceoryx2 nodes
    let left: Vec<u32> = messages::dead_node_pids().into_iter().filter(|pid| ours.contains(pid)).collect();
    assert!(left.is_empty(), "stages {left:?} left dead nodes behind");
}

/// Two runs under one prefix would publish into each other's topics and count each other's
/// poses: the second must refuse to start, and the first must not notice.
#[test]
fn a_second_run_under_a_prefix_in_use_refuses_to_start() {
    let Running { _dir, prefix: p, run, .. } = start_running("twice", 80, "40", Duration::from_millis(200));
    let second = gema2(&["run", "--prefix", &p, "--scans", "10", "--timeout", "30"]);
    let err = String::from_utf8_lossy(&second.stderr);
    assert!(!second.status.success() && err.contains("in use") && err.contains("--prefix"), "{err}");
    let out = run.wait_with_output().unwrap();
    let report = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(report.contains("poses received 80 of 80"), "{report}");
    assert!(!report.contains("restarted"), "{report}");
    // once it is over, the prefix is free again
    let again = gema2(&["run", "--prefix", &p, "--scans", "5", "--rate", "max", "--timeout", "60"]);
    assert!(again.status.success(), "{}", String::from_utf8_lossy(&again.stderr));
}

/// A source that ends at once (three scans as fast as it can) keeps its port up until they
/// are taken: iceoryx2 drops what a publisher sent once the publisher is gone, and before the
/// source lingered, 5 of 6 such runs received no pose at all.
#[test]
fn a_short_burst_reaches_the_end_of_the_pipeline() {
    for k in 0..3 {
        let p = prefix(&format!("burst{k}"));
        let out = gema2(&["run", "--prefix", &p, "--scans", "3", "--rate", "max", "--timeout", "30"]);
        let report = String::from_utf8_lossy(&out.stdout);
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        assert!(report.contains("poses received 3 of 3"), "run {k}: {report}");
    }
}

/// The stages start in the order the pipeline needs, whatever the file's: a file listing the
/// localizer before the map server once waited 30 s for a map that was never started and failed.
/// The run also prints no iceoryx2 warning about its missing config file.
#[test]
fn a_pipeline_file_in_any_stage_order_runs() {
    let dir = tempfile::tempdir().unwrap();
    let written = common::write_pipeline(dir.path(), "p.toml", "office", &["--rate", "max"]);
    let text = std::fs::read_to_string(&written).unwrap();
    let mut stages: Vec<&str> = text.split("[[stage]]").skip(1).collect();
    assert!(stages.len() >= 4, "{text}");
    stages.reverse();
    let reversed = stages.iter().map(|s| format!("[[stage]]{s}")).collect::<String>();
    std::fs::write(&written, &reversed).unwrap();
    let p = prefix("order");
    let start = Instant::now();
    let out =
        gema2(&["run", "--pipeline", written.to_str().unwrap(), "--prefix", &p, "--scans", "3", "--timeout", "30"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{reversed}\n{err}");
    assert!(String::from_utf8_lossy(&out.stdout).contains("poses received 3 of 3"), "{err}");
    assert!(start.elapsed() < Duration::from_secs(20), "{:?}", start.elapsed());
    assert!(!err.contains("No config file"), "{err}");
}

/// `run --scans 0` runs until the sources end or the timeout, as `acquire --scans 0` does: it
/// used to stop at once, with "poses received 0 of 0" though a scan had gone out. A rate or a
/// timeout that is none is refused before anything starts.
#[test]
fn run_with_no_scan_limit_goes_on_until_the_timeout() {
    let p = prefix("nolimit");
    let out = gema2(&["run", "--prefix", &p, "--scans", "0", "--rate", "20", "--timeout", "2"]);
    let (stdout, stderr) = (String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
    assert!(out.status.success(), "{stderr}");
    assert!(stderr.contains("timed out after"), "{stderr}");
    let line = stdout.lines().find(|l| l.starts_with("poses received ")).unwrap_or_else(|| panic!("{stdout}"));
    let received: u64 = line["poses received ".len()..].split([' ', ',']).next().unwrap().parse().unwrap();
    assert!(received >= 10 && !line.contains(" of "), "{line}");
    for (args, why) in [
        (&["--rate", "fast"][..], "a positive number of scans per second, max, or recorded"),
        (&["--rate", "0"], "a positive number of scans per second, max, or recorded"),
        (&["--timeout", "0"], "must be a number of seconds above 0"),
    ] {
        let out = gema2(&[&["run", "--prefix", &p][..], args].concat());
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success() && err.contains(why) && !err.contains("supervisor:"), "{args:?}: {err}");
    }
}

/// A run that gets no pose back (here a pipeline without its segment stage) fails, saying so,
/// instead of printing a report of nothing and exiting 0.
#[test]
fn a_run_with_no_pose_back_is_an_error() {
    let dir = tempfile::tempdir().unwrap();
    let written = common::write_pipeline(dir.path(), "p.toml", "office", &["--rate", "max"]);
    let text = std::fs::read_to_string(&written).unwrap();
    let without_segment =
        text.replace("[[stage]]\nname = \"segment\"\nkind = \"segment\"\nimplementation = \"line-visibility\"\n\n", "");
    assert_ne!(without_segment, text);
    std::fs::write(&written, without_segment).unwrap();
    let p = prefix("nopose");
    let out =
        gema2(&["run", "--pipeline", written.to_str().unwrap(), "--prefix", &p, "--scans", "3", "--timeout", "30"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{err}");
    assert!(err.contains("no pose came back of the 3 scans asked for"), "{err}");
}

/// A source waiting for a serial port that is not there stops on SIGTERM, as the supervisor
/// stops it. Before, iceoryx2's node replaced the source's own handler, and the wait went on
/// until the supervisor's SIGKILL.
#[test]
fn a_source_waiting_for_its_serial_port_stops_on_sigterm() {
    let p = prefix("noport");
    let mut child = Command::new(exe())
        .args(["stage", "acquire", "--serial", "/dev/gema2-no-such-port", "--prefix", &p])
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // let it fail to open the port a few times
    std::thread::sleep(Duration::from_millis(1500));
    unsafe { libc::kill(child.id() as i32, libc::SIGTERM) };
    let asked = Instant::now();
    let status = loop {
        if let Some(status) = child.try_wait().unwrap() {
            break Some(status);
        }
        if asked.elapsed() > Duration::from_secs(3) {
            unsafe { libc::kill(child.id() as i32, libc::SIGKILL) };
            let _ = child.wait();
            break None;
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    let mut err = String::new();
    std::io::Read::read_to_string(child.stderr.as_mut().unwrap(), &mut err).unwrap();
    assert!(err.contains("retrying"), "{err}");
    let status = status.unwrap_or_else(|| panic!("still waiting 3 s after SIGTERM: {err}"));
    assert!(status.success(), "{status}: {err}");
}

/// An output that cannot be written is refused before the run, not after it: the poses of a
/// finished run were lost when the CSV could not be created at its end.
#[test]
fn an_unwritable_output_is_refused_before_the_run() {
    let p = prefix("noout");
    let out = gema2(&["run", "--prefix", &p, "--scans", "5", "--out", "/nonexistent-dir/poses.csv"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{err}");
    assert!(err.contains("creating /nonexistent-dir/poses.csv"), "{err}");
    assert!(!err.contains("stages running"), "{err}");
}

/// A pipeline pinning a stage to a core this machine does not have (written for a larger
/// one) is refused before anything starts, naming the stage and the cores there are. Before,
/// a source restarted on failure was restarted for ever, and another stage ended the run with
/// the kernel's "Invalid argument".
#[test]
fn a_stage_pinned_to_a_missing_core_is_refused_before_anything_starts() {
    let dir = tempfile::tempdir().unwrap();
    let written = common::write_pipeline(dir.path(), "p.toml", "office", &["--scans", "5"]);
    let text = std::fs::read_to_string(&written).unwrap().replace("restart = \"never\"", "restart = \"on-failure\"");
    for stage in ["segment", "acquire"] {
        let pinned = text.replace(&format!("name = \"{stage}\"\n"), &format!("name = \"{stage}\"\ncpu = 1023\n"));
        let pipeline = dir.path().join(format!("{stage}.toml"));
        std::fs::write(&pipeline, pinned).unwrap();
        let p = prefix(&format!("nocore_{stage}"));
        let start = Instant::now();
        let out = gema2(&["run", "--pipeline", pipeline.to_str().unwrap(), "--prefix", &p, "--timeout", "20"]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{stage}: {err}");
        let why = format!("stage \"{stage}\": cpu 1023 is not one this machine lets the pipeline use");
        assert!(err.contains(&why), "{stage}: {err}");
        assert!(!err.contains("restarting"), "{stage}: {err}");
        assert!(start.elapsed() < Duration::from_secs(15), "{stage}: {:?}", start.elapsed());
        assert!(stage_pids("segment", &p).is_empty() && stage_pids("mapserver", &p).is_empty());
    }
}

/// A corrupt line in a replayed log costs that scan only: the source names the line, skips
/// it and publishes the rest.
#[test]
fn a_replayed_log_with_a_corrupt_line_loses_only_that_scan() {
    let dir = tempfile::tempdir().unwrap();
    let (log, _) = setup(dir.path(), 30, "max");
    let text = std::fs::read_to_string(&log).unwrap();
    let mut lines: Vec<&str> = text.lines().collect();
    let tenth = lines.iter().enumerate().filter(|(_, l)| l.starts_with("ROBOTLASER1")).nth(9).unwrap().0;
    lines[tenth] = "ROBOTLASER1 0 -2.0 nonsense";
    std::fs::write(&log, lines.join("\n") + "\n").unwrap();
    let p = prefix("corrupt");
    let out = gema2(&["stage", "acquire", "--log", log.to_str().unwrap(), "--rate", "max", "--prefix", &p]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert!(err.contains(&format!("scans.log:{}:", tenth + 1)), "{err}");
    assert!(err.contains("published 29 scans") && err.contains("skipped 1 malformed"), "{err}");
}

/// SIGHUP asks the map server to reload its map; the signal interrupts its wait, which must
/// not be taken for a stop request.
#[test]
fn sighup_reloads_the_map_and_the_map_server_carries_on() {
    let dir = tempfile::tempdir().unwrap();
    let map = dir.path().join("map.json");
    std::fs::write(&map, include_str!("../maps/apartment.json")).unwrap();
    let p = prefix("hup");
    let mut server = StageChild::stage(&["mapserver", "--map", map.to_str().unwrap()], &p, Stdio::piped());
    let mut lines = BufReader::new(server.child().stderr.take().unwrap()).lines();
    assert!(lines.next().and_then(Result::ok).unwrap_or_default().contains("as version 1"));
    for version in [2, 3] {
        // SAFETY: kill(2) on a child of this test.
        unsafe { libc::kill(server.child().id() as i32, libc::SIGHUP) };
        let got = lines.next().and_then(Result::ok).unwrap_or_default();
        assert!(got.contains(&format!("as version {version}")), "{got}");
    }
    // a changed file (replaced whole, as an editor saves) is read again by itself, once
    std::thread::sleep(Duration::from_millis(50));
    let new = dir.path().join("new.json");
    std::fs::write(&new, include_str!("../maps/office.json")).unwrap();
    std::fs::rename(&new, &map).unwrap();
    let got = lines.next().and_then(Result::ok).unwrap_or_default();
    assert!(got.contains("reloaded") && got.contains("as version 4"), "{got}");
    std::thread::sleep(Duration::from_secs(1));
    server.stop();
    let rest: Vec<String> = lines.map_while(Result::ok).collect();
    assert!(rest.iter().all(|l| !l.contains("as version 5")), "the unchanged file was read again: {rest:?}");
}

/// A reader that dies (kill -9, so nothing of its own cleans up) must not take its publisher with
/// it: a dead localize once made segment exit with "send: InternalError", and a publisher that
/// waits for room waited on the dead reader's full buffer for ever. The stages run here without
/// a supervisor, so nobody else removes the dead nodes. The source publishes as fast as the
/// chain takes scans (it waits for room), so its log growing shows the whole chain upstream of
/// the dead stage still moving.
#[test]
fn a_killed_reader_leaves_every_stage_upstream_running() {
    let dir = tempfile::tempdir().unwrap();
    let p = prefix("deadreader");
    let stage = |kind: &str, args: &[&str]| {
        StageChild::spawn(
            Command::new(exe())
                .args(["stage", kind, "--prefix", &p])
                .args(args)
                .stdout(Stdio::null())
                .stderr(Stdio::piped()),
        )
    };
    let mut mapserver = stage("mapserver", &["--map", "office"]);
    let first = BufReader::new(mapserver.child().stderr.take().unwrap()).lines().next();
    assert!(first.and_then(Result::ok).unwrap_or_default().contains("as version 1"));
    let mut localize = stage("localize", &[]);
    let mut segment = stage("segment", &[]);
    std::thread::sleep(Duration::from_secs(1));
    let log = dir.path().join("published.log");
    let mut acquire = stage("acquire", &["--rate", "max", "--carmen-out", log.to_str().unwrap()]);
    let lines = || std::fs::read_to_string(&log).map(|t| t.lines().count()).unwrap_or(0);
    let still_publishing = |what: &str| {
        let before = lines();
        wait_for(&format!("the source to publish after {what}"), Duration::from_secs(20), || lines() > before + 200);
    };
    still_publishing("its start");
    let kill = |victim: &mut StageChild| {
        // SAFETY: kill(2) on a child of this test.
        unsafe { libc::kill(victim.child().id() as i32, libc::SIGKILL) };
        let _ = victim.child().wait();
        // long enough for the dead reader's 64-message buffer to fill many times over
        std::thread::sleep(Duration::from_secs(1));
    };
    kill(&mut localize);
    still_publishing("localize died");
    assert!(segment.child().try_wait().unwrap().is_none(), "segment exited when localize died");
    kill(&mut segment);
    still_publishing("segment died");
    assert!(acquire.child().try_wait().unwrap().is_none(), "acquire exited when segment died");
    let out = acquire.stop();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("published"), "{err}");
    mapserver.stop();
}

/// The map server's corner queries have a client: `gema2 map corners` asks the running server
/// and prints what it holds, near an angle and a place.
#[test]
fn map_corners_asks_the_running_map_server() {
    let p = prefix("corners");
    let mut server = StageChild::stage(&["mapserver", "--map", "office"], &p, Stdio::piped());
    let first = BufReader::new(server.child().stderr.take().unwrap()).lines().next();
    assert!(first.and_then(Result::ok).unwrap_or_default().contains("as version 1"));
    let ask = |extra: &[&str]| gema2(&[&["map", "corners", "--prefix", &p][..], extra].concat());
    let out = ask(&["--angle", "90", "--tolerance", "3"]);
    let text = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let head = text.lines().next().unwrap_or_default();
    assert!(head.starts_with("# map version 1: "), "{text}");
    let rows: Vec<Vec<f64>> =
        text.lines().skip(2).map(|l| l.split('\t').map(|v| v.parse().unwrap()).collect()).collect();
    assert!(!rows.is_empty(), "{text}");
    assert!(rows.iter().all(|r| (87.0..=93.0).contains(&r[2])), "{text}");
    // a place far from the building holds none
    let out = ask(&["--angle", "90", "--near", "5000", "5000", "1"]);
    assert!(String::from_utf8_lossy(&out.stdout).starts_with("# map version 1: 0 corners match"));
    server.stop();
    // with no map server, it says so
    let out = gema2(&["map", "corners", "--prefix", &prefix("nocorners"), "--angle", "90"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("no map server is serving"), "{err}");
}

/// A stage process this test started, killed if the test fails before stopping it: an orphan
/// would hold the test harness's output pipe open and hang the run.
struct StageChild(Option<Child>);

impl StageChild {
    fn spawn(cmd: &mut Command) -> Self {
        StageChild(Some(cmd.spawn().unwrap()))
    }

    /// `gema2 stage` with `args` (the stage's kind first) under `prefix`, its stderr to `stderr`.
    fn stage(args: &[&str], prefix: &str, stderr: Stdio) -> Self {
        Self::spawn(Command::new(exe()).arg("stage").args(args).args(["--prefix", prefix]).stderr(stderr))
    }

    fn child(&mut self) -> &mut Child {
        self.0.as_mut().unwrap()
    }

    /// SIGTERM, then what the stage printed, however it ended.
    fn terminated(mut self) -> Output {
        let child = self.0.take().unwrap();
        // SAFETY: kill(2) on a child of this test.
        unsafe { libc::kill(child.id() as i32, libc::SIGTERM) };
        child.wait_with_output().unwrap()
    }

    /// SIGTERM, then what the stage printed; asserts that it stopped cleanly.
    fn stop(mut self) -> Output {
        let child = self.0.take().unwrap();
        // SAFETY: kill(2) on a child of this test.
        unsafe { libc::kill(child.id() as i32, libc::SIGTERM) };
        let out = child.wait_with_output().unwrap();
        assert!(out.status.success(), "a stage did not stop cleanly on SIGTERM: {}", out.status);
        out
    }
}

impl Drop for StageChild {
    fn drop(&mut self) {
        if let Some(c) = self.0.as_mut() {
            let _ = c.kill();
            let _ = c.wait();
        }
    }
}

#[test]
fn a_hot_swap_of_segment_then_localize_loses_at_most_two_scans() {
    let Running { _dir, csv, prefix: p, run } = start_running("swap", 240, "40", Duration::from_secs(1));
    let old = stage_pids("segment", &p);
    let swap = gema2(&["swap", "segment", "--impl", "split-and-merge", "--prefix", &p]);
    assert!(swap.status.success(), "{}", String::from_utf8_lossy(&swap.stderr));
    assert!(String::from_utf8_lossy(&swap.stdout).contains("swapped segment to split-and-merge"));
    let now = stage_pids("segment", &p);
    assert_eq!(now.len(), 1);
    assert_ne!(now, old);
    let bad = gema2(&["swap", "segment", "--impl", "no-such", "--prefix", &p]);
    assert!(!bad.status.success() && String::from_utf8_lossy(&bad.stderr).contains("no-such"));
    let other = gema2(&["swap", "localize", "--impl", "split-and-merge", "--prefix", &p]);
    let why = String::from_utf8_lossy(&other.stderr);
    assert!(!other.status.success() && why.contains("no implementation \"split-and-merge\""), "{why}");
    let source = gema2(&["swap", "acquire", "--impl", "x", "--prefix", &p]);
    assert!(String::from_utf8_lossy(&source.stderr).contains("no implementations"));
    let server = gema2(&["swap", "mapserver", "--prefix", &p, "--set", "map_reach=3"]);
    assert!(String::from_utf8_lossy(&server.stderr).contains("every localizer's too"));
    // a fresh localizer reads the map server's model in place, and takes over
    let old = stage_pids("localize", &p);
    let swap = gema2(&["swap", "localize", "--impl", "gema2", "--prefix", &p]);
    assert!(swap.status.success(), "{}", String::from_utf8_lossy(&swap.stderr));
    let now = stage_pids("localize", &p);
    assert_eq!(now.len(), 1);
    assert_ne!(now, old);
    let out = run.wait_with_output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let seqs: BTreeSet<u64> = rows(&csv).iter().map(|r| r[0].parse().unwrap()).collect();
    let missing: Vec<u64> = (0..240).filter(|s| !seqs.contains(s)).collect();
    assert!(missing.len() <= 2, "lost scans {missing:?}");
}

#[test]
fn a_localizer_started_late_receives_the_map() {
    let p = prefix("late");
    let map = StageChild::stage(&["mapserver", "--map", "apartment"], &p, Stdio::null());
    std::thread::sleep(Duration::from_millis(1500));
    let mut loc = StageChild::stage(&["localize"], &p, Stdio::piped());
    let mut lines = BufReader::new(loc.child().stderr.take().unwrap()).lines();
    let got = lines.next().and_then(Result::ok).unwrap_or_default();
    assert!(got.contains("map version 1 (38 walls,") && got.contains("read in place"), "{got}");
    loc.stop();
    map.stop();
}

/// A new map version reaches a localizer that is locating: it switches between two scans, and
/// no scan is lost or located twice on the way. Version 2 is the same map again (SIGHUP);
/// version 3, the file rewritten with a building beside the office, has a larger model than
/// the map server's chunks hold, so it comes from a new publisher while the localizer still
/// holds version 2's block from the old one.
#[test]
fn a_new_map_version_is_taken_up_between_two_scans_and_loses_none() {
    let dir = tempfile::tempdir().unwrap();
    let map = dir.path().join("office.json");
    std::fs::write(&map, include_str!("../maps/office.json")).unwrap();
    let log = dir.path().join("scans.log");
    let made = gema2(&["sim", "--map", "office", "--scans", "200", "--seed", "5", "--out", log.to_str().unwrap()]);
    assert!(made.status.success());
    let pipeline = common::write_pipeline(
        dir.path(),
        "pipeline.toml",
        map.to_str().unwrap(),
        &["--log", log.to_str().unwrap(), "--rate", "40"],
    );
    let (p, csv) = (prefix("version"), dir.path().join("poses.csv"));
    let run = run_in_background(&pipeline, &p, 200, &csv);
    wait_for("the source", Duration::from_secs(30), || !stage_pids("acquire", &p).is_empty());
    std::thread::sleep(Duration::from_millis(1500));
    for pid in stage_pids("mapserver", &p) {
        // SAFETY: kill(2) on a stage of this test's pipeline.
        unsafe { libc::kill(pid as i32, libc::SIGHUP) };
    }
    std::thread::sleep(Duration::from_millis(1000));
    // a second building 100 m east, 40 m by 40, with a wall every 2 m: many more walls and
    // cells than the office alone
    let office = include_str!("../maps/office.json");
    let mut extra = String::new();
    for k in 0..20 {
        let y = 2.0 * f64::from(k);
        extra +=
            &format!("    [100.0, {y:.1}, 140.0, {y:.1}],\n    [{:.1}, 0.0, {:.1}, 40.0],\n", 100.0 + y, 100.0 + y);
    }
    let larger = office.replacen("\"walls\": [\n", &format!("\"walls\": [\n{extra}"), 1);
    assert_ne!(larger, office);
    let next = dir.path().join("office.json.new");
    std::fs::write(&next, larger).unwrap();
    std::fs::rename(&next, &map).unwrap();
    let out = run.wait_with_output().unwrap();
    let said = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{said}");
    assert!(said.contains("localize: map version 2 ("), "the localizer never took version 2: {said}");
    let block_mb = |version: u32| {
        said.lines()
            .find(|l| l.contains(&format!("localize: map version {version} (")))
            .and_then(|l| l.split("): ").nth(1)?.split(" MB").next()?.parse::<f64>().ok())
    };
    let (two, three) = (block_mb(2), block_mb(3));
    assert!(three.is_some(), "the localizer never took the larger version 3: {said}");
    assert!(three > two, "version 3's model ({three:?} MB) is not larger than version 2's ({two:?} MB)");
    assert_every_pose_once(&csv, 200);
}

/// Memory of the process `pid` of its own (not shared), kB: what it adds to the machine.
fn private_kb(pid: u32) -> u64 {
    let text = std::fs::read_to_string(format!("/proc/{pid}/smaps_rollup")).unwrap_or_default();
    text.lines()
        .filter(|l| l.starts_with("Private_Clean:") || l.starts_with("Private_Dirty:"))
        .filter_map(|l| l.split_whitespace().nth(1)?.parse::<u64>().ok())
        .sum()
}

/// Starts a localize stage under `prefix` and returns it once it has read the map model, with
/// the megabytes of the model it reported.
fn localizer_with_model(prefix: &str, set: &[&str]) -> (StageChild, f64) {
    let mut cmd = Command::new(exe());
    cmd.args(["stage", "localize", "--prefix", prefix]).stderr(Stdio::piped());
    for kv in set {
        cmd.args(["--set", kv]);
    }
    let mut loc = StageChild::spawn(&mut cmd);
    let mut lines = BufReader::new(loc.child().stderr.take().unwrap()).lines();
    let got = lines.next().and_then(Result::ok).unwrap_or_default();
    let mb = got
        .split(": ")
        .nth(2)
        .and_then(|t| t.split(" MB read in place").next())
        .and_then(|n| n.parse::<f64>().ok())
        .unwrap_or_else(|| panic!("no model read: {got}"));
    // keep reading what it says, so it never blocks on a full pipe
    std::thread::spawn(move || lines.map_while(Result::ok).for_each(drop));
    (loc, mb)
}

/// The map server builds the model once and every localizer reads it in place: a second
/// localizer of a large map adds to the machine's memory at most a tenth of the model's size
/// over what a localizer of a map a hundredth that size takes.
#[test]
fn a_second_localizer_reads_the_model_in_place_and_adds_no_copy_of_it() {
    let dir = tempfile::tempdir().unwrap();
    let big = dir.path().join("big.json");
    let made = gema2(&["map", "generate", "office-1500", "--seed", "3", "--out", big.to_str().unwrap()]);
    assert!(made.status.success());
    let (p, small_p) = (prefix("inplace"), prefix("inplace-small"));
    let mut server = StageChild::stage(&["mapserver", "--map", big.to_str().unwrap()], &p, Stdio::piped());
    let said = BufReader::new(server.child().stderr.take().unwrap()).lines().next().and_then(Result::ok);
    assert!(said.unwrap_or_default().contains("as version 1"));
    let small_server = StageChild::stage(&["mapserver", "--map", "apartment"], &small_p, Stdio::null());
    std::thread::sleep(Duration::from_millis(500));
    let (first, mb) = localizer_with_model(&p, &[]);
    let (mut second, mb_again) = localizer_with_model(&p, &[]);
    let (mut small, small_mb) = localizer_with_model(&small_p, &[]);
    assert_eq!(mb, mb_again);
    assert!(mb > 10.0 && small_mb * 20.0 < mb, "a model of {mb} MB and one of {small_mb} MB");
    let (added, baseline) = (private_kb(second.child().id()), private_kb(small.child().id()));
    assert!(baseline > 0, "no memory figures for the localizers");
    let limit = baseline as f64 + mb * 1e3 / 10.0;
    assert!(
        (added as f64) <= limit,
        "the second localizer holds {added} kB of its own, over {limit:.0} kB: a model of {mb} MB"
    );
    drop((first, second, small, small_server));
    server.stop();
}

/// A localizer whose corner settings differ from those the model was built with refuses it,
/// naming the setting; with the same settings on both it locates.
#[test]
fn a_model_built_for_other_corner_settings_is_refused() {
    let p = prefix("refuse");
    let server = StageChild::spawn(
        Command::new(exe())
            .args(["stage", "mapserver", "--map", "apartment", "--prefix", &p, "--set", "map_reach=2"])
            .stderr(Stdio::null()),
    );
    std::thread::sleep(Duration::from_millis(1000));
    let out = Command::new(exe()).args(["stage", "localize", "--prefix", &p]).stdin(Stdio::null()).output().unwrap();
    let why = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{why}");
    assert!(why.contains("map_reach = 2 there, 5 here") && why.contains("same --set"), "{why}");
    let (agreeing, _) = localizer_with_model(&p, &["map_reach=2"]);
    drop(agreeing);
    server.stop();
}

#[test]
fn a_payload_type_mismatch_across_processes_names_the_service() {
    let p = prefix("types");
    let map = StageChild::stage(&["mapserver", "--map", "apartment"], &p, Stdio::null());
    std::thread::sleep(Duration::from_millis(1500));
    let node = messages::create_node("typetest").unwrap();
    let err = messages::open_pubsub::<messages::ScanMsg>(&node, &format!("{p}/map"), messages::Topic::Map.settings())
        .err()
        .unwrap()
        .to_string();
    assert!(err.contains(&format!("{p}/map")) && err.contains("IncompatibleTypes"), "{err}");
    assert!(err.contains("built from the same sources"), "the likely cause is named: {err}");
    map.stop();
}

#[test]
fn ctrl_c_stops_every_stage_and_leaves_no_dead_resources() {
    let Running { _dir, prefix: p, run, .. } = start_running("sigint", 100, "20", Duration::from_millis(500));
    let mut ours: Vec<u32> =
        ["acquire", "segment", "localize", "mapserver"].iter().flat_map(|k| stage_pids(k, &p)).collect();
    ours.push(run.id());
    // SAFETY: kill(2) on a child of this test.
    unsafe { libc::kill(run.id() as i32, libc::SIGINT) };
    let start = Instant::now();
    let out = run.wait_with_output().unwrap();
    assert!(start.elapsed() < Duration::from_secs(10));
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    for kind in ["acquire", "segment", "localize", "mapserver"] {
        assert!(stage_pids(kind, &p).is_empty(), "{kind} still running");
    }
    // only our own processes: tests running alongside kill stages on purpose
    let left: Vec<u32> = messages::dead_node_pids().into_iter().filter(|pid| ours.contains(pid)).collect();
    assert!(left.is_empty(), "dead iceoryx2 nodes of processes {left:?} were left behind (ours: {ours:?})");
}

/// Runs the shipped pipeline file `file` on the emulated sensor `emu` (its place in the
/// variable `sensor`), for `scans` scans recorded to `recorded`; stops the emulator, checks that
/// every scan was located, and returns the recording.
fn run_on_sensor(mut emu: Child, file: &str, sensor: (&str, &str), scans: usize, recorded: &Path) -> String {
    let pipeline = format!("{}/pipelines/{file}", env!("CARGO_MANIFEST_DIR"));
    let p = prefix(file.trim_end_matches(".toml"));
    let out = Command::new(exe())
        .args(["run", "--pipeline", &pipeline, "--prefix", &p, "--scans", &scans.to_string(), "--timeout", "60"])
        .env("GEMA2_MAP", "office")
        .env(sensor.0, sensor.1)
        .env("GEMA2_RECORD", recorded)
        .output()
        .unwrap();
    // SAFETY: kill(2) on a child of this test.
    unsafe { libc::kill(emu.id() as i32, libc::SIGTERM) };
    let _ = emu.wait();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let report = String::from_utf8_lossy(&out.stdout);
    assert!(report.contains(&format!("poses received {scans} of {scans}")), "{report}");
    std::fs::read_to_string(recorded).unwrap()
}

#[test]
fn the_whole_pipeline_runs_on_an_emulated_urg04lx() {
    let dir = tempfile::tempdir().unwrap();
    let link = dir.path().join("urg");
    let recorded = dir.path().join("recorded.log");
    let emu = Command::new(exe())
        .args(["emulate-urg", "--map", "office", "--period-ms", "25", "--link", link.to_str().unwrap()])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    wait_for("the emulator's pty", Duration::from_secs(10), || link.exists());
    // the shipped example, as its comment says to run it
    let text = run_on_sensor(emu, "urg-serial.toml", ("GEMA2_SERIAL", link.to_str().unwrap()), 20, &recorded);
    assert!(text.starts_with("# gema2: poses are not ground truth"));
    assert!(text.lines().filter(|l| l.starts_with("ROBOTLASER1")).count() >= 20);
}

/// `pipelines/ust-tcp.toml` against an emulated UST-10LX on TCP: 1081-beam scans at 40 Hz, the
/// sensor's own geometry, every scan located.
#[test]
fn the_whole_pipeline_runs_on_an_emulated_ust_10lx_over_tcp() {
    let dir = tempfile::tempdir().unwrap();
    let recorded = dir.path().join("recorded.log");
    let mut emu = Command::new(exe())
        .args(["emulate-urg", "--map", "office", "--model", "ust-10lx", "--tcp", "127.0.0.1:0"])
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let mut address = String::new();
    std::io::BufRead::read_line(&mut std::io::BufReader::new(emu.stdout.take().unwrap()), &mut address).unwrap();
    let text = run_on_sensor(emu, "ust-tcp.toml", ("GEMA2_LIDAR", address.trim()), 40, &recorded);
    let beams: Vec<usize> = text
        .lines()
        .filter(|l| l.starts_with("ROBOTLASER1"))
        .map(|l| l.split_whitespace().nth(8).and_then(|n| n.parse().ok()).unwrap_or(0))
        .collect();
    assert!(beams.len() >= 40 && beams.iter().all(|&n| n == 1081), "{:?}", &beams[..beams.len().min(5)]);
}

/// `pipelines/replay.toml`, run as its comment says: a CARMEN log through every stage against
/// a map, every scan located, the run ending with the log.
#[test]
fn the_replay_example_locates_every_scan_of_a_log() {
    let dir = tempfile::tempdir().unwrap();
    let (log, _) = setup(dir.path(), 40, "max");
    let csv = dir.path().join("poses.csv");
    let pipeline = concat!(env!("CARGO_MANIFEST_DIR"), "/pipelines/replay.toml");
    let p = prefix("replay");
    let out = Command::new(exe())
        .args(["run", "--pipeline", pipeline, "--prefix", &p, "--timeout", "60", "--out", csv.to_str().unwrap()])
        .env("GEMA2_MAP", "office")
        .env("GEMA2_LOG", &log)
        .env("GEMA2_RATE", "40")
        .output()
        .unwrap();
    let report = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{report}\n{}", String::from_utf8_lossy(&out.stderr));
    assert!(report.contains("poses received 40,"), "{report}");
    assert_eq!(rows(&csv).len(), 40);
    // without the log's variable the file is refused, naming it
    let out = Command::new(exe())
        .args(["run", "--pipeline", pipeline, "--prefix", &p])
        .env("GEMA2_MAP", "office")
        .env_remove("GEMA2_LOG")
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("GEMA2_LOG"), "{err}");
}

/// A test's own scan source under `prefix`: it drops a scan rather than wait for a full reader.
fn scan_outlet(
    node: &messages::iceoryx2::prelude::Node<messages::iceoryx2::prelude::ipc::Service>,
    prefix: &str,
) -> messages::Outlet<messages::ScanMsg> {
    let drop_when_full = messages::iceoryx2::prelude::BackpressureStrategy::DiscardData;
    messages::Outlet::open(node, prefix, messages::Topic::Scan, drop_when_full).unwrap()
}

/// Writes scan `seq`, stamped now: 400 beams 0.01 rad apart, each 2 m.
fn flat_scan(seq: u64) -> impl Fn(&mut messages::ScanMsg) + Copy {
    move |m: &mut messages::ScanMsg| {
        m.header = messages::Header::new(seq, messages::monotonic_ns());
        (m.angle_min, m.angle_increment, m.range_min, m.range_max) = (-2.0, 0.01, 0.02, 5.6);
        m.count = 400;
        m.ranges[..400].fill(2.0);
    }
}

/// iceoryx2 can lose a wake-up under load (`messages::MISSED_WAKEUP_POLL`): a scan whose
/// notification never came must still be segmented, not wait forever in the queue.
#[test]
fn a_stage_finds_a_scan_that_came_without_a_wake_up() {
    let p = prefix("nowake");
    let seg = StageChild::stage(&["segment"], &p, Stdio::piped());
    let node = messages::create_node("nowaketest").unwrap();
    let scans = messages::open_topic::<messages::ScanMsg>(&node, &p, messages::Topic::Scan).unwrap();
    let corners = messages::open_topic::<messages::CornersMsg>(&node, &p, messages::Topic::Corners).unwrap();
    let corners_in = corners.data.subscriber_builder().create().unwrap();
    let publisher = scans.data.publisher_builder().create().unwrap();
    // a notifier on a service nobody listens to: the scan goes out with no wake-up
    let unheard = messages::service_name(&p, "unheard");
    let unheard = node.service_builder(&unheard.as_str().try_into().unwrap()).event().open_or_create().unwrap();
    let silent = unheard.notifier_builder().create().unwrap();
    let fill = flat_scan(7);
    let mut delivered = 0;
    wait_for("the segment stage's subscriber", Duration::from_secs(30), || {
        delivered = messages::publish(&publisher, &silent, fill).unwrap();
        delivered > 0
    });
    let mut got = None;
    wait_for("the scan's corners", Duration::from_secs(5), || {
        got = corners_in.receive().unwrap().map(|c| c.scan.header.seq);
        got.is_some()
    });
    assert_eq!(got, Some(7));
    let out = seg.stop();
    assert!(
        String::from_utf8_lossy(&out.stderr).contains("found by the poll"),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// A localizer that starts after the last scan still locates it: the corners topic keeps the
/// latest scan's message, and the segment stage hands it over once the localizer is ready,
/// so a restarted or swapped-in localizer answers at once instead of at the next scan.
#[test]
fn a_localizer_started_after_the_last_scan_locates_that_scan() {
    let p = prefix("history");
    let map = StageChild::stage(&["mapserver", "--map", "apartment"], &p, Stdio::null());
    let seg = StageChild::stage(&["segment"], &p, Stdio::null());
    let node = messages::create_node("historytest").unwrap();
    let mut scans = scan_outlet(&node, &p);
    let corners = messages::open_topic::<messages::CornersMsg>(&node, &p, messages::Topic::Corners).unwrap();
    let corners_in = corners.data.subscriber_builder().create().unwrap();
    let fill = flat_scan(7);
    wait_for("the segment stage's subscriber", Duration::from_secs(30), || scans.send(fill).unwrap() > 0);
    wait_for("the scan's corners", Duration::from_secs(5), || corners_in.receive().unwrap().is_some());
    // no scan comes after this one
    let poses = messages::open_topic::<messages::PoseMsg>(&node, &p, messages::Topic::Pose).unwrap();
    let pose_in = poses.data.subscriber_builder().create().unwrap();
    let loc = StageChild::stage(&["localize"], &p, Stdio::piped());
    let mut seq = None;
    wait_for("the pose of the scan before the localizer started", Duration::from_secs(30), || {
        seq = pose_in.receive().unwrap().map(|m| m.header.seq);
        seq.is_some()
    });
    assert_eq!(seq, Some(7));
    let out = loc.stop();
    let said = String::from_utf8_lossy(&out.stderr);
    assert!(said.contains("first pose") && said.contains("(scan 7,"), "{said}");
    seg.stop();
    map.stop();
}

/// The hand-over of the latest scan is a convenience: a segment stage that cannot listen for
/// other stages' readiness (every listener slot of `<prefix>/ready` taken) says so and
/// segments as ever.
#[test]
fn a_segment_stage_that_cannot_listen_for_readiness_still_segments() {
    let p = prefix("noready");
    let node = messages::create_node("noreadytest").unwrap();
    let taken: Vec<_> = std::iter::from_fn(|| messages::ready_listener(&node, &p).ok()).take(64).collect();
    assert!(taken.len() < 64, "the readiness event has no limit on listeners");
    let seg = StageChild::stage(&["segment"], &p, Stdio::piped());
    let mut scans = scan_outlet(&node, &p);
    let corners = messages::open_topic::<messages::CornersMsg>(&node, &p, messages::Topic::Corners).unwrap();
    let corners_in = corners.data.subscriber_builder().create().unwrap();
    wait_for("the segment stage's subscriber", Duration::from_secs(30), || scans.send(flat_scan(3)).unwrap() > 0);
    wait_for("the scan's corners", Duration::from_secs(5), || corners_in.receive().unwrap().is_some());
    let out = seg.stop();
    let said = String::from_utf8_lossy(&out.stderr);
    assert!(said.contains("a new localizer will wait for the next scan"), "{said}");
    drop(taken);
}

/// A warm-up sent on the scan topic passes through segment and localize to the pose topic's
/// readers, and publishes nothing on its way.
#[test]
fn a_warm_up_passes_down_the_pipeline_without_a_message() {
    let p = prefix("warm");
    let seg = StageChild::stage(&["segment"], &p, Stdio::null());
    let loc = StageChild::stage(&["localize"], &p, Stdio::null());
    let node = messages::create_node("warmtest").unwrap();
    let scans = scan_outlet(&node, &p);
    let poses = messages::open_topic::<messages::PoseMsg>(&node, &p, messages::Topic::Pose).unwrap();
    let pose_in = poses.data.subscriber_builder().create().unwrap();
    let pose_wake = poses.event.listener_builder().create().unwrap();
    // a warm-up sent before a stage listens is lost: send one every 100 ms until one arrives
    let mut arrived = false;
    wait_for("a warm-up at the pose topic", Duration::from_secs(30), || {
        scans.warm_up().unwrap();
        pose_wake.timed_wait(|e| arrived |= e.id == messages::WARM_UP, Duration::from_millis(100)).unwrap();
        arrived
    });
    assert!(pose_in.receive().unwrap().is_none(), "a warm-up made a pose");
    seg.stop();
    loc.stop();
}

/// The scheduling policy, priority and allowed cores of a running process.
fn scheduling_of(pid: u32) -> (i32, i32, Vec<usize>) {
    let pid = pid as libc::pid_t;
    // SAFETY: plain queries of another process's scheduling into structs we own.
    unsafe {
        let policy = libc::sched_getscheduler(pid) & !libc::SCHED_RESET_ON_FORK;
        let mut param = libc::sched_param { sched_priority: 0 };
        libc::sched_getparam(pid, &mut param);
        let mut set: libc::cpu_set_t = std::mem::zeroed();
        libc::sched_getaffinity(pid, std::mem::size_of::<libc::cpu_set_t>(), &mut set);
        let cores = (0..libc::CPU_SETSIZE as usize).filter(|&c| libc::CPU_ISSET(c, &set)).collect();
        (policy, param.sched_priority, cores)
    }
}

#[test]
fn a_realtime_pipeline_runs_each_stage_where_and_how_its_file_says() {
    let dir = tempfile::tempdir().unwrap();
    let (_, plain) = setup(dir.path(), 60, "20");
    // the plain pipeline with every stage placed, the supervisor pinned and holding PM QoS
    let text = std::fs::read_to_string(&plain).unwrap();
    let placed = format!("[supervisor]\ncpu = 0\npriority = 40\nwake_latency_us = 0\n\n{text}");
    let placed = common::with_stage_lines(&placed, "localize", "cpu = 0\npriority = 30");
    let placed = common::with_stage_lines(&placed, "segment", "cpu = 0\npriority = 20");
    let placed = common::with_stage_lines(&placed, "acquire", "cpu = 0\npriority = 10");
    let pipeline = dir.path().join("realtime.toml");
    std::fs::write(&pipeline, placed).unwrap();
    let csv = dir.path().join("poses.csv");
    let p = prefix("realtime");
    let mut run = run_in_background(&pipeline, &p, 60, &csv);
    let started = Instant::now();
    while stage_pids("acquire", &p).is_empty() {
        if let Ok(Some(_)) = run.try_wait() {
            // the system refused real-time scheduling: the error must say what is missing
            let out = run.wait_with_output().unwrap();
            let err = String::from_utf8_lossy(&out.stderr);
            assert!(!out.status.success(), "ended before its stages started: {err}");
            assert!(err.contains("CAP_SYS_NICE") || err.contains("/dev/cpu_dma_latency"), "{err}");
            common::skipped(
                "a_realtime_pipeline_runs_each_stage_where_and_how_its_file_says",
                "the system refuses \
                     real-time scheduling (no CAP_SYS_NICE or RLIMIT_RTPRIO): only the refusal's message was checked",
            );
            return;
        }
        assert!(started.elapsed() < Duration::from_secs(30), "timed out waiting for the stages");
        std::thread::sleep(Duration::from_millis(50));
    }
    let cores = std::thread::available_parallelism().map(|n| n.get()).unwrap();
    for (kind, priority) in [("acquire", 10), ("segment", 20), ("localize", 30)] {
        // a stage places itself first thing in its main, moments after its process appears
        let want = (libc::SCHED_FIFO, priority, vec![0]);
        let mut seen = Vec::new();
        wait_for(&format!("stage {kind} at priority {priority} on core 0"), Duration::from_secs(10), || {
            seen = stage_pids(kind, &p).into_iter().map(scheduling_of).collect();
            // (acquire publishes for 3 s: it is still there when checked)
            !seen.is_empty() && seen.iter().all(|s| *s == want)
        });
    }
    // no cpu of its own: not confined to the supervisor's core, and not real-time either
    for pid in stage_pids("mapserver", &p) {
        let (policy, _, allowed) = scheduling_of(pid);
        assert_eq!(policy, libc::SCHED_OTHER, "the supervisor's priority leaked into the map server");
        assert_eq!(allowed.len(), cores, "the map server runs on {allowed:?}");
    }
    let out = run.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert!(err.contains("idle cores wake within 0 us"), "{err}");
    assert_eq!(rows(&csv).len(), 60);
}

/// Writes an executable shell script `name` in `dir` and returns its path.
fn script(dir: &Path, name: &str, body: &str) -> PathBuf {
    use std::os::unix::fs::PermissionsExt;
    let path = dir.join(name);
    std::fs::write(&path, format!("#!/bin/sh\n{body}\n")).unwrap();
    std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o755)).unwrap();
    path
}

/// In a 10 Hz run, localize is swapped to a separately built program with other settings, and
/// then swaps that cannot work are refused while the running localizer goes on: no pose is
/// lost or repeated at the consumer.
#[test]
fn localize_swaps_to_another_program_with_other_settings_and_refuses_what_cannot_run() {
    let Running { _dir, csv, prefix: p, run } = start_running("swapbin", 120, "10", Duration::from_secs(2));
    let d = _dir.path();
    // another program of the localize kind: here a wrapper that says it ran, then is one
    let marker = d.join("ran");
    let wrapper = script(
        d,
        "my-localize",
        &format!(
            "[ \"$1\" = --wire-version ] || echo ran >> {}\nexec {} stage localize \"$@\"",
            marker.display(),
            exe()
        ),
    );
    // the listing says what each stage runs and can become
    let list = gema2(&["swap", "--prefix", &p]);
    let listed = String::from_utf8_lossy(&list.stdout);
    assert!(list.status.success(), "{}", String::from_utf8_lossy(&list.stderr));
    assert!(listed.contains("localize (localize): gema2 stage localize") && listed.contains("--binary"), "{listed}");
    assert!(listed.contains("acquire (acquire):") && listed.contains("scan boundary"), "{listed}");
    assert!(listed.contains("mapserver (mapserver):") && listed.contains("new map version"), "{listed}");
    let old = stage_pids("localize", &p);
    let swap =
        gema2(&["swap", "localize", "--binary", wrapper.to_str().unwrap(), "--set", "thorough=1", "--prefix", &p]);
    assert!(swap.status.success(), "{}", String::from_utf8_lossy(&swap.stderr));
    let now = stage_pids("localize", &p);
    assert_eq!(now.len(), 1);
    assert_ne!(now, old);
    assert!(std::fs::read_to_string(&marker).is_ok_and(|t| t.contains("ran")), "the new program ran");
    let cmdline = std::fs::read(format!("/proc/{}/cmdline", now[0])).unwrap_or_default();
    assert!(String::from_utf8_lossy(&cmdline).contains("thorough=1"), "with the new settings");
    // a program that is not there, one of another wire version, one that dies at start, and a
    // setting the map server owns: each refused, the running localizer untouched
    let other_version = script(d, "old-localize", "[ \"$1\" = --wire-version ] && echo 1 && exit 0\nexit 3");
    let dies = script(
        d,
        "broken-localize",
        &format!("[ \"$1\" = --wire-version ] && echo {} && exit 0\nexit 7", messages::WIRE_VERSION),
    );
    let cases: [(&[&str], &str); 4] = [
        (&["--binary", "/no/such/localize"], "cannot be started"),
        (&["--binary", other_version.to_str().unwrap()], "speaks wire version 1"),
        (&["--binary", dies.to_str().unwrap()], "exited before it was ready"),
        (&["--set", "map_reach=3"], "map_reach shapes the map model"),
    ];
    for (args, why) in cases {
        let mut all = vec!["swap", "localize", "--prefix", &p];
        all.extend_from_slice(args);
        let out = gema2(&all);
        let said = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success() && said.contains(why), "{args:?}: {said}");
        assert_eq!(stage_pids("localize", &p), now, "{args:?}: the running localizer was touched");
    }
    let out = run.wait_with_output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert_every_pose_once(&csv, 120);
}

/// In a 10 Hz run the source is swapped for another (here a replay of another log): the new one
/// takes over at a scan boundary, numbering on from the old one's last scan, so the consumer
/// sees every number once.
#[test]
fn the_source_is_handed_over_at_a_scan_boundary_with_no_pose_lost_or_repeated() {
    let Running { _dir, csv, prefix: p, run } = start_running("swapsrc", 100, "10", Duration::from_secs(2));
    let other = _dir.path().join("other.log");
    let made = gema2(&["sim", "--map", "office", "--scans", "100", "--seed", "8", "--out", other.to_str().unwrap()]);
    assert!(made.status.success());
    let old = stage_pids("acquire", &p);
    // --args takes the rest of the line: the prefix goes before it
    let swap = gema2(&[
        "swap",
        "acquire",
        "--prefix",
        &p,
        "--args",
        "--log",
        other.to_str().unwrap(),
        "--rate",
        "10",
        "--scans",
        "100",
    ]);
    assert!(swap.status.success(), "{}", String::from_utf8_lossy(&swap.stderr));
    let now = stage_pids("acquire", &p);
    assert_eq!(now.len(), 1);
    assert_ne!(now, old);
    let out = run.wait_with_output().unwrap();
    let said = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{said}");
    assert!(said.contains("acquire: took over from the source it replaces at scan "), "{said}");
    assert_every_pose_once(&csv, 100);
}

/// In a 10 Hz run the map server is swapped for one serving another map file: it publishes the
/// version after the running one's, the localizer takes it up between two scans, and no pose is
/// lost or repeated.
#[test]
fn the_map_server_is_swapped_to_another_map_as_a_new_version() {
    let Running { _dir, csv, prefix: p, run } = start_running("swapmap", 100, "10", Duration::from_secs(2));
    let map = _dir.path().join("office-copy.json");
    std::fs::write(&map, include_str!("../maps/office.json")).unwrap();
    let old = stage_pids("mapserver", &p);
    let swap = gema2(&["swap", "mapserver", "--prefix", &p, "--args", "--map", map.to_str().unwrap()]);
    assert!(swap.status.success(), "{}", String::from_utf8_lossy(&swap.stderr));
    let now = stage_pids("mapserver", &p);
    assert_eq!(now.len(), 1);
    assert_ne!(now, old);
    let out = run.wait_with_output().unwrap();
    let said = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{said}");
    assert!(said.contains("office-copy.json (210 walls") && said.contains("as version 2"), "{said}");
    assert!(said.contains("localize: map version 2 ("), "the localizer never took version 2: {said}");
    assert_every_pose_once(&csv, 100);
}

/// The whole case: in one 10 Hz run each of the four stage kinds is swapped in turn
/// (segment to another implementation, localize to a separately built program with other
/// settings, the source to another log, the map server to another map file), and the consumer
/// gets every pose once.
#[test]
fn every_stage_kind_is_swapped_in_turn_in_one_run_with_every_pose_once() {
    let Running { _dir, csv, prefix: p, run } = start_running("swapall", 200, "10", Duration::from_secs(2));
    let d = _dir.path();
    let wrapper = script(d, "my-localize", &format!("exec {} stage localize \"$@\"", exe()));
    let other = d.join("other.log");
    let made = gema2(&["sim", "--map", "office", "--scans", "200", "--seed", "9", "--out", other.to_str().unwrap()]);
    assert!(made.status.success());
    let map = d.join("office-copy.json");
    std::fs::write(&map, include_str!("../maps/office.json")).unwrap();
    let swaps: [Vec<&str>; 4] = [
        vec!["segment", "--prefix", &p, "--impl", "split-and-merge"],
        vec!["localize", "--prefix", &p, "--binary", wrapper.to_str().unwrap(), "--set", "thorough=1"],
        vec!["acquire", "--prefix", &p, "--args", "--log", other.to_str().unwrap(), "--rate", "10", "--scans", "200"],
        vec!["mapserver", "--prefix", &p, "--args", "--map", map.to_str().unwrap()],
    ];
    for args in swaps {
        let old = stage_pids(args[0], &p);
        let out = gema2(&[&["swap"][..], &args].concat());
        assert!(out.status.success(), "{args:?}: {}", String::from_utf8_lossy(&out.stderr));
        let now = stage_pids(args[0], &p);
        assert!(now.len() == 1 && now != old, "{args:?}: {old:?} -> {now:?}");
        std::thread::sleep(Duration::from_millis(1500));
    }
    let out = run.wait_with_output().unwrap();
    let said = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{said}");
    assert_every_pose_once(&csv, 200);
}

/// A pipeline file names alternatives per stage; `gema2 swap` lists them and `--to` takes one.
#[test]
fn a_stage_is_swapped_to_an_alternative_its_pipeline_file_names() {
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("scans.log");
    let made = gema2(&["sim", "--map", "office", "--scans", "60", "--seed", "4", "--out", log.to_str().unwrap()]);
    assert!(made.status.success());
    let text = format!(
        "[[stage]]\nname = \"mapserver\"\nkind = \"mapserver\"\nargs = [\"--map\", \"office\"]\n\n\
         [[stage]]\nname = \"localize\"\nkind = \"localize\"\n\n\
         [[stage]]\nname = \"segment\"\nkind = \"segment\"\n\
         [[stage.alternative]]\nname = \"sm\"\nimplementation = \"split-and-merge\"\n\n\
         [[stage]]\nname = \"acquire\"\nkind = \"acquire\"\nargs = [\"--log\", {log:?}, \"--rate\", \"10\"]\nrestart = \"never\"\n",
        log = log.to_str().unwrap()
    );
    let pipeline = dir.path().join("alternatives.toml");
    std::fs::write(&pipeline, text).unwrap();
    let (p, csv) = (prefix("alt"), dir.path().join("poses.csv"));
    let run = run_in_background(&pipeline, &p, 60, &csv);
    wait_for("the source", Duration::from_secs(30), || !stage_pids("acquire", &p).is_empty());
    let list = gema2(&["swap", "--prefix", &p]);
    let listed = String::from_utf8_lossy(&list.stdout);
    assert!(listed.contains("--to sm: --impl split-and-merge"), "{listed}");
    let nope = gema2(&["swap", "segment", "--to", "nope", "--prefix", &p]);
    let why = String::from_utf8_lossy(&nope.stderr);
    assert!(!nope.status.success() && why.contains("names no alternative \"nope\""), "{why}");
    let swap = gema2(&["swap", "segment", "--to", "sm", "--prefix", &p]);
    assert!(swap.status.success(), "{}", String::from_utf8_lossy(&swap.stderr));
    assert!(String::from_utf8_lossy(&swap.stdout).contains("swapped segment to split-and-merge"));
    let out = run.wait_with_output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let seqs: BTreeSet<u64> = rows(&csv).iter().map(|r| r[0].parse().unwrap()).collect();
    assert_eq!(seqs.len(), 60);
}

/// `gema2 bench --memory` runs a pipeline, starts a second localizer beside it and reads its
/// own memory while the pipeline runs, against a tenth of the model it reported; a pipeline
/// that cannot start is an error that says why.
#[test]
fn bench_memory_reads_a_second_localizers_own_memory() {
    let out = gema2(&["bench", "--memory", "--seconds", "2"]);
    let said = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(out.status.success(), "{said}{}", String::from_utf8_lossy(&out.stderr));
    let after =
        |line: &str, key: &str| -> Option<f64> { line.split(key).nth(1)?.split_whitespace().next()?.parse().ok() };
    let mb = said.lines().find_map(|l| after(l, "map model: ")).expect("the model's size");
    let most = said.lines().find_map(|l| after(l, "at most ")).expect("the most memory read");
    let readings = said.lines().find_map(|l| after(l, " kB over ")).expect("the readings");
    assert!(mb > 0.0 && most > 0.0 && readings >= 1.0, "{said}");
    assert!(said.contains(" a tenth of the model"), "{said}");

    let out = gema2(&["bench", "--memory", "--log", "/nonexistent/gema2.log", "--seconds", "2"]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("cannot read the log"), "{err}");
}

/// `gema2 bench --memory --carmen DIR` measures a second localizer on the map of each log's
/// even scans, a row a log, and writes the table into its own section of a results page,
/// beside the single run's.
#[test]
fn bench_memory_measures_each_log_of_a_folder_on_its_own_map() {
    let dir = tempfile::tempdir().unwrap();
    let logs = dir.path().join("logs");
    std::fs::create_dir(&logs).unwrap();
    let log = logs.join("walk.log");
    // 15 s of scans at 20 a second: the pipeline outlasts its 4 s lead and the readings
    let out = gema2(&["sim", "--map", "office", "--scans", "300", "--seed", "5", "--out", log.to_str().unwrap()]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let page = dir.path().join("results.md");
    std::fs::write(&page, "# results\n\n<!-- BEGIN bench-memory -->\nthe long run\n<!-- END bench-memory -->\n")
        .unwrap();
    let (logs_s, page_s) = (logs.to_str().unwrap(), page.to_str().unwrap());
    let out = gema2(&["bench", "--memory", "--carmen", logs_s, "--seconds", "2", "--markdown", page_s]);
    let said = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(out.status.success(), "{said}{}", String::from_utf8_lossy(&out.stderr));
    let row = said.lines().find(|l| l.starts_with("| walk |")).unwrap_or_else(|| panic!("no row for the log: {said}"));
    let cells: Vec<&str> = row.split('|').map(str::trim).collect();
    let (mb, tenth, most): (f64, f64, f64) =
        (cells[2].parse().unwrap(), cells[3].parse().unwrap(), cells[5].parse().unwrap());
    assert!(mb > 0.0 && (tenth - mb * 100.0).abs() <= 5.5 && most > 0.0, "{row}");
    assert_eq!(cells[6], if most <= tenth { "within" } else { "over" }, "{row}");
    assert!(said.contains("of 1 logs"), "{said}");
    let written = std::fs::read_to_string(&page).unwrap();
    assert!(written.contains("the long run") && written.contains("<!-- BEGIN bench-memory-carmen -->"), "{written}");
    assert!(written.contains(row), "{written}");

    let out = gema2(&["bench", "--memory", "--carmen", dir.path().join("none").to_str().unwrap()]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("no such folder or log"));
}

/// What a test reads off the pose topic: every scan answered so far, by number.
struct Answers {
    poses: messages::iceoryx2::port::subscriber::Subscriber<
        messages::iceoryx2::prelude::ipc::Service,
        messages::PoseMsg,
        (),
    >,
    seen: std::collections::BTreeSet<u64>,
}

impl Answers {
    fn open(node: &messages::iceoryx2::prelude::Node<messages::iceoryx2::prelude::ipc::Service>, prefix: &str) -> Self {
        let topic = messages::open_topic::<messages::PoseMsg>(node, prefix, messages::Topic::Pose).unwrap();
        Answers { poses: topic.data.subscriber_builder().create().unwrap(), seen: Default::default() }
    }

    /// Whether scan `seq` has been answered.
    fn has(&mut self, seq: u64) -> bool {
        while let Some(m) = self.poses.receive().unwrap() {
            self.seen.insert(m.header.seq);
        }
        self.seen.contains(&seq)
    }
}

/// Overwrites `m` with bytes of the xorshift stream `state`.
///
/// # Safety
/// `T` must be integers and floats alone, as the wire's payloads are (`repr(C)`, their padding
/// spelled out as fields), so that any bytes make one.
unsafe fn fill_random<T>(m: &mut T, state: &std::cell::Cell<u64>) {
    // SAFETY: the caller's promise; the slice covers `m` alone.
    let bytes = unsafe { std::slice::from_raw_parts_mut(m as *mut T as *mut u8, std::mem::size_of::<T>()) };
    let mut s = state.get();
    for b in bytes.iter_mut() {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        *b = s as u8;
    }
    state.set(s);
}

/// A damage done to a good message.
type Damage<'a, T> = Box<dyn Fn(&mut T) + 'a>;

/// Sends `out` each damaged message (`good(100 + k)`, then the `k`th damage), and after each a
/// good one (`good(1000 + k)`) until it is answered; returns how many bad messages a good one
/// was answered after, within 30 s each.
fn bad_then_good<T: std::fmt::Debug + messages::iceoryx2::prelude::ZeroCopySend + messages::Zeroable + 'static>(
    out: &mut messages::Outlet<T>,
    answers: &mut Answers,
    good: impl Fn(u64, &mut T),
    damages: &[Damage<'_, T>],
) -> usize {
    let start = Instant::now();
    for (k, damage) in damages.iter().enumerate() {
        out.send(|m| {
            good(100 + k as u64, m);
            damage(m);
        })
        .unwrap();
        std::thread::sleep(Duration::from_millis(20));
        let (seq, since) = (1000 + k as u64, Instant::now());
        while !answers.has(seq) {
            if since.elapsed() > Duration::from_secs(30) {
                return k;
            }
            out.send(|m| good(seq, m)).unwrap();
            std::thread::sleep(Duration::from_millis(50));
        }
    }
    eprintln!(
        "{} bad messages, each followed by a good one answered, in {:.1} s",
        damages.len(),
        start.elapsed().as_secs_f64()
    );
    damages.len()
}

/// Hostile scans on the wire cost those scans only. A publisher that is not gema2's (a driver
/// with a bug, a process writing garbage) sends scans with a count past the array, layouts of
/// NaN, zero or infinite numbers, readings that are all NaN, infinite or huge, NaN odometry
/// and truth, stamps at the ends of time, and frames of random bytes. Segment and localize
/// take or drop each without dying, and after each a good scan is located.
#[test]
fn hostile_scans_cost_only_themselves() {
    use messages::ScanMsg;
    let p = prefix("hostile");
    let map = StageChild::stage(&["mapserver", "--map", "apartment"], &p, Stdio::null());
    let mut seg = StageChild::stage(&["segment"], &p, Stdio::piped());
    let mut loc = StageChild::stage(&["localize"], &p, Stdio::piped());
    let node = messages::create_node("hostiletest").unwrap();
    let mut scans = scan_outlet(&node, &p);
    let mut answers = Answers::open(&node, &p);
    let good = |seq: u64, m: &mut ScanMsg| flat_scan(seq)(m);
    wait_for("a pose for a good scan", Duration::from_secs(60), || {
        scans.send(|m| good(1, m)).unwrap();
        answers.has(1)
    });
    let state = std::cell::Cell::new(0x9E37_79B9_7F4A_7C15u64);
    let mut damages: Vec<Damage<'_, ScanMsg>> = vec![
        Box::new(|m| m.count = u32::MAX),
        Box::new(|m| m.count = messages::MAX_BEAMS as u32 + 1),
        Box::new(|m| m.angle_increment = f64::NAN),
        Box::new(|m| m.angle_increment = 0.0),
        Box::new(|m| (m.angle_min, m.angle_increment) = (f64::INFINITY, 1e-300)),
        Box::new(|m| m.range_max = f64::INFINITY),
        Box::new(|m| {
            m.range_min = f64::NEG_INFINITY;
            m.ranges.fill(f32::NEG_INFINITY);
        }),
        Box::new(|m| m.ranges.fill(f32::NAN)),
        Box::new(|m| m.ranges.fill(f32::INFINITY)),
        Box::new(|m| m.ranges.iter_mut().enumerate().for_each(|(k, r)| *r = if k % 2 == 0 { 1e30 } else { -1e30 })),
        Box::new(|m| {
            m.has_odometry = 1;
            m.odometry = messages::PoseMsgXyt { x: f64::NAN, y: f64::INFINITY, theta: -f64::INFINITY };
        }),
        Box::new(|m| {
            m.has_truth = 1;
            m.truth = messages::PoseMsgXyt { x: f64::NAN, y: 1e308, theta: f64::NAN };
        }),
        Box::new(|m| m.header.stamp_ns = u64::MAX),
        Box::new(|m| m.header.stamp_ns = 0),
    ];
    for _ in 0..20 {
        // SAFETY: a ScanMsg is integers and floats alone.
        damages.push(Box::new(|m| unsafe { fill_random(m, &state) }));
    }
    let after = bad_then_good(&mut scans, &mut answers, good, &damages);
    let alive = [seg.child().try_wait().unwrap().is_none(), loc.child().try_wait().unwrap().is_none()];
    let [seg_said, loc_said] = [seg, loc].map(|s| String::from_utf8_lossy(&s.terminated().stderr).into_owned());
    let said = format!("segment said:\n{seg_said}\nlocalize said:\n{loc_said}");
    assert!(alive == [true, true], "a stage died (segment, localize alive: {alive:?}); {said}");
    assert_eq!(after, damages.len(), "no good scan was located after bad scan {after}; {said}");
    assert!(seg_said.contains("dropped scan"), "the segment stage did not say what it dropped; {said}");
    assert!(
        seg_said.contains("ahead of this machine's monotonic clock"),
        "no word of the scan from the future; {said}"
    );
    map.stop();
}

/// A map server on the apartment and a localize stage under a prefix of a test's name, fed
/// segmentations by the test itself in place of a segment stage: the stages, the test's node,
/// its outlet on the corners topic and its reader of the poses.
struct CornersRig {
    prefix: String,
    map: StageChild,
    loc: StageChild,
    _node: messages::iceoryx2::prelude::Node<messages::iceoryx2::prelude::ipc::Service>,
    out: messages::Outlet<messages::CornersMsg>,
    answers: Answers,
}

impl CornersRig {
    fn start(test: &str) -> Self {
        let p = prefix(test);
        let map = StageChild::stage(&["mapserver", "--map", "apartment"], &p, Stdio::null());
        let loc = StageChild::stage(&["localize"], &p, Stdio::piped());
        let node = messages::create_node(&format!("{test}test")).unwrap();
        let drop_when_full = messages::iceoryx2::prelude::BackpressureStrategy::DiscardData;
        let out = messages::Outlet::open(&node, &p, messages::Topic::Corners, drop_when_full).unwrap();
        let answers = Answers::open(&node, &p);
        CornersRig { prefix: p, map, loc, _node: node, out, answers }
    }
}

/// A good segmentation of scan `seq`: the flat scan, no corners, no lines.
fn good_segmentation(seq: u64, m: &mut messages::CornersMsg) {
    flat_scan(seq)(&mut m.scan);
    (m.count, m.line_count, m.noise_scale) = (0, 0, 1.0);
}

/// Hostile segmentations on the wire cost those scans only. A publisher on the corners topic
/// that is not gema2's segment stage sends corner and line counts past their arrays, corners
/// and lines of NaN or of huge numbers, noise scales of any value, and frames of random bytes,
/// half of them around a good scan. The localizer answers each bad one that has a usable
/// scan, after each a good one, and lives.
#[test]
fn hostile_segmentations_cost_only_themselves() {
    use messages::CornersMsg;
    let CornersRig { map, mut loc, _node, mut out, mut answers, .. } = CornersRig::start("hostileseg");
    let good = good_segmentation;
    wait_for("a pose for a good segmentation", Duration::from_secs(60), || {
        out.send(|m| good(1, m)).unwrap();
        answers.has(1)
    });
    let corner = |v: f64| messages::CornerMsg {
        position: [v, v],
        inner_angle: v,
        orientation: v,
        quality: v,
        arms: [messages::ArmMsg {
            direction: [v, v],
            gap: v,
            length: v,
            samples: v,
            direction_sigma: v,
            line: u32::MAX,
            _pad: 0,
        }; 2],
    };
    let line = |a: f64, b: f64| messages::LineMsg {
        start: [a, a],
        end: [b, -b],
        direction_sigma: 0.01,
        samples: u32::MAX,
        _pad: 0,
    };
    let state = std::cell::Cell::new(0x2545_F491_4F6C_DD1Du64);
    let mut damages: Vec<Damage<'_, CornersMsg>> = vec![
        Box::new(|m| m.count = u32::MAX),
        Box::new(|m| m.line_count = u32::MAX),
        Box::new(|m| m.noise_scale = f64::NAN),
        Box::new(|m| m.noise_scale = 1e300),
        Box::new(|m| m.noise_scale = -5.0),
    ];
    for v in [f64::NAN, f64::INFINITY, 1e300, -1e300, 0.0] {
        damages.push(Box::new(move |m| {
            m.count = messages::MAX_CORNERS as u32;
            m.corners.fill(corner(v));
        }));
    }
    for (a, b) in [(f64::NAN, 1.0), (-1e300, 1e300), (-1e6, 1e6), (0.0, 0.0), (1.0, f64::INFINITY)] {
        damages.push(Box::new(move |m| {
            m.line_count = messages::MAX_LINES as u32;
            m.lines.fill(line(a, b));
        }));
    }
    for k in 0..20 {
        let (state, seq) = (&state, 100 + damages.len() as u64);
        damages.push(Box::new(move |m| {
            // SAFETY: a CornersMsg is integers and floats alone.
            unsafe { fill_random(m, state) };
            if k % 2 == 0 {
                flat_scan(seq)(&mut m.scan);
            }
        }));
    }
    let after = bad_then_good(&mut out, &mut answers, good, &damages);
    let alive = loc.child().try_wait().unwrap().is_none();
    let said = String::from_utf8_lossy(&loc.terminated().stderr).into_owned();
    assert!(alive, "the localize stage died; it said:\n{said}");
    assert_eq!(after, damages.len(), "no good scan was located after bad segmentation {after}; it said:\n{said}");
    // the bad ones around a good scan were located, not skipped: the test tried them
    let tried = (0..damages.len() as u64).filter(|k| answers.has(100 + k)).count();
    assert!(tried >= 25, "only {tried} bad segmentations around a good scan were answered");
    map.stop();
}

/// Hostile model blocks on the wire cost no scan. A publisher on the model topic that is not
/// gema2's map server sends, as new map versions, a block of another layout, a block of this
/// layout that is random bytes, the served block cut to half, and an empty block. The localizer
/// refuses each and says why, locates a good scan with the model it holds after each, and then
/// takes a good block sent as the next version. A localizer that starts with no model to go
/// on with, the newest block a bad one, waits for a good one.
#[test]
fn hostile_model_blocks_are_refused_and_the_held_model_kept() {
    let CornersRig { prefix: p, map, mut loc, _node: node, out: mut corners, mut answers } =
        CornersRig::start("hostilemodel");
    let mut located = |seq: u64| {
        let since = Instant::now();
        while !answers.has(seq) {
            if since.elapsed() > Duration::from_secs(60) {
                return false;
            }
            corners.send(|m| good_segmentation(seq, m)).unwrap();
            std::thread::sleep(Duration::from_millis(50));
        }
        true
    };
    assert!(located(1), "no pose for the first scan");
    let ports = messages::open_model_topic(&node, &p).unwrap();
    let served = {
        let reader = ports.subscriber().unwrap();
        let since = Instant::now();
        loop {
            if let Some(s) = reader.receive().unwrap() {
                break s.payload().to_vec();
            }
            assert!(since.elapsed() < Duration::from_secs(10), "the served model never came");
            std::thread::sleep(Duration::from_millis(20));
        }
    };
    let notifier = ports.event.notifier_builder().create().unwrap();
    let mut outlet = messages::ModelOutlet::new(&ports, served.len()).unwrap();
    let layout = map::model::MODEL_LAYOUT;
    let mut state = 0x2545_F491_4F6C_DD1Du64;
    let random: Vec<u8> = (0..served.len())
        .map(|_| {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state as u8
        })
        .collect();
    let bad: [(u32, u64, &[u8]); 4] = [
        (100, layout + 1, &served),
        (101, layout, &random),
        (102, layout, &served[..served.len() / 2]),
        (103, layout, &[]),
    ];
    for (k, &(version, layout, block)) in bad.iter().enumerate() {
        outlet.publish(&ports, &notifier, version, layout, block).unwrap();
        assert!(located(10 + k as u64), "no good scan was located after model version {version}");
    }
    outlet.publish(&ports, &notifier, 104, layout, &served).unwrap();
    assert!(located(20), "no good scan was located after the good model version 104");
    let alive = loc.child().try_wait().unwrap().is_none();
    let said = String::from_utf8_lossy(&loc.terminated().stderr).into_owned();
    assert!(alive, "the localizer died; it said:\n{said}");
    for (version, ..) in bad {
        assert!(said.contains(&format!("refused version {version}:")), "version {version} not refused:\n{said}");
    }
    assert!(said.contains("localize: map version 104 ("), "the good version 104 was not taken:\n{said}");
    // a localizer that starts while the newest block on the topic is random bytes, and none
    // other is there (the map server gone): it waits, and takes the next good one
    map.stop();
    outlet.publish(&ports, &notifier, 105, layout, &random).unwrap();
    let mut late = StageChild::stage(&["localize"], &p, Stdio::piped());
    let lines = BufReader::new(late.child().stderr.take().unwrap()).lines();
    let (tx, said) = std::sync::mpsc::channel();
    std::thread::spawn(move || lines.map_while(Result::ok).try_for_each(|l| tx.send(l)));
    let mut heard = String::new();
    let mut hear = |what: &str, mut meanwhile: Box<dyn FnMut() + '_>| {
        let since = Instant::now();
        while !heard.contains(what) {
            assert!(since.elapsed() < Duration::from_secs(30), "the late localizer never said {what:?}:\n{heard}");
            meanwhile();
            while let Ok(line) = said.recv_timeout(Duration::from_millis(20)) {
                heard += &line;
                heard.push('\n');
            }
        }
    };
    // the newest block (the history) goes to a reader that joined when the publisher updates
    // its connections
    hear("no map yet: refused version 105:", Box::new(|| outlet.update_connections(&ports).unwrap()));
    outlet.publish(&ports, &notifier, 106, layout, &served).unwrap();
    hear("localize: map version 106 (", Box::new(|| ()));
    assert!(located(30), "no scan was located by the localizer that started on a bad block");
    assert!(late.child().try_wait().unwrap().is_none(), "the localizer that started on a bad block died");
}
