//! Recording a real pipeline run through the `viewer` program and reading the file back with
//! rerun's decoder (`viewer inspect`). The test subscribes to the same topics itself, so it knows
//! what the run published and compares that with what the recording holds, scan by scan.

mod common;

use messages::{open_topic, CornersMsg, LinesMsg, PoseMsg, ScanMsg, Topic};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

fn gema2() -> &'static str {
    env!("CARGO_BIN_EXE_gema2")
}

/// The viewer program, which `cargo test --workspace` builds beside gema2.
fn viewer() -> PathBuf {
    let p = Path::new(gema2()).with_file_name("viewer");
    assert!(p.is_file(), "{} is missing: run the tests with `cargo test --workspace`", p.display());
    p
}

fn prefix(test: &str) -> String {
    format!("r{}_{}", test, std::process::id())
}

fn simulate(dir: &Path, scans: usize) -> PathBuf {
    let log = dir.join("scans.log");
    let out = Command::new(gema2())
        .args(["sim", "--map", "apartment", "--scenario", "people", "--seed", "5", "--scans"])
        .arg(scans.to_string())
        .arg("--out")
        .arg(&log)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    log
}

fn pipeline(dir: &Path, log: &Path, rate: &str) -> PathBuf {
    common::write_pipeline(dir, "pipeline.toml", "apartment", &["--log", log.to_str().unwrap(), "--rate", rate])
}

/// Per scan, what the run published: valid readings, lines, corners, hypotheses, and whether a
/// pose and a chosen corner exist.
#[derive(Clone, Debug, Default, PartialEq)]
struct Published {
    readings: Option<usize>,
    lines: Option<usize>,
    corners: Option<usize>,
    hypotheses: Option<usize>,
    chosen: Option<usize>,
}

/// Subscribes to the data topics under `prefix` until `stop`, counting what each scan carried.
fn watch(prefix: String, stop: Arc<AtomicBool>) -> std::thread::JoinHandle<BTreeMap<u64, Published>> {
    let (ready_tx, ready_rx) = std::sync::mpsc::channel();
    let handle = std::thread::spawn(move || {
        let node = messages::create_node("recording-test").unwrap();
        let scan =
            open_topic::<ScanMsg>(&node, &prefix, Topic::Scan).unwrap().data.subscriber_builder().create().unwrap();
        let lines =
            open_topic::<LinesMsg>(&node, &prefix, Topic::Lines).unwrap().data.subscriber_builder().create().unwrap();
        let corners = open_topic::<CornersMsg>(&node, &prefix, Topic::Corners)
            .unwrap()
            .data
            .subscriber_builder()
            .create()
            .unwrap();
        let pose =
            open_topic::<PoseMsg>(&node, &prefix, Topic::Pose).unwrap().data.subscriber_builder().create().unwrap();
        ready_tx.send(()).unwrap();
        let mut seen: BTreeMap<u64, Published> = BTreeMap::new();
        let mut corner_counts: BTreeMap<u64, usize> = BTreeMap::new();
        // the scan corner each pose was built from; whether it is one of the scan's published
        // corners is decided at the end, since a pose can be read before its corners message
        let mut pose_corners: BTreeMap<u64, Option<usize>> = BTreeMap::new();
        while !stop.load(Ordering::Relaxed) {
            let mut any = false;
            while let Ok(Some(m)) = scan.receive() {
                let g = laser::ScanGeometry {
                    angle_min: m.angle_min,
                    angle_increment: m.angle_increment,
                    range_min: m.range_min,
                    range_max: m.range_max,
                };
                let valid = m.ranges[..m.count as usize].iter().filter(|&&r| g.is_valid(r as f64)).count();
                seen.entry(m.header.seq).or_default().readings = Some(valid);
                any = true;
            }
            while let Ok(Some(m)) = lines.receive() {
                seen.entry(m.header.seq).or_default().lines = Some(m.count as usize);
                any = true;
            }
            while let Ok(Some(m)) = corners.receive() {
                seen.entry(m.scan.header.seq).or_default().corners = Some(m.count as usize);
                corner_counts.insert(m.scan.header.seq, m.count as usize);
                any = true;
            }
            while let Ok(Some(m)) = pose.receive() {
                seen.entry(m.header.seq).or_default().hypotheses = Some(m.count as usize);
                pose_corners.insert(m.header.seq, (m.count > 0).then(|| m.hypotheses[0].scan_corner as usize));
                any = true;
            }
            if !any {
                std::thread::sleep(Duration::from_micros(300));
            }
        }
        for (seq, corner) in pose_corners {
            let n = corner_counts.get(&seq).copied().unwrap_or(0);
            seen.entry(seq).or_default().chosen = Some(usize::from(corner.is_some_and(|c| c < n)));
        }
        seen
    });
    ready_rx.recv_timeout(Duration::from_secs(20)).expect("the watcher subscribes");
    handle
}

/// `viewer inspect --per-scan`: the summary and, per scan, the instances of each entity.
fn inspect(files: &[PathBuf]) -> (String, BTreeMap<u64, BTreeMap<String, usize>>) {
    let out = Command::new(viewer()).arg("inspect").arg("--per-scan").args(files).output().unwrap();
    assert!(out.status.success(), "viewer inspect: {}", String::from_utf8_lossy(&out.stderr));
    let text = String::from_utf8_lossy(&out.stdout).into_owned();
    let mut lines = text.lines().skip_while(|l| !l.starts_with("seq\t"));
    let header: Vec<String> = lines.next().expect("a per-scan table").split('\t').map(str::to_owned).collect();
    let mut table = BTreeMap::new();
    for l in lines {
        let cols: Vec<&str> = l.split('\t').collect();
        let row =
            header[1..].iter().zip(&cols[1..]).filter_map(|(h, c)| c.parse().ok().map(|n| (h.clone(), n))).collect();
        table.insert(cols[0].parse().unwrap(), row);
    }
    (text, table)
}

#[test]
fn a_recorded_run_holds_every_scan_with_the_counts_the_run_published() {
    let dir = tempfile::tempdir().unwrap();
    let log = simulate(dir.path(), 120);
    let file = dir.path().join("run.rrd");
    let p = prefix("counts");
    let stop = Arc::new(AtomicBool::new(false));
    let watcher = watch(p.clone(), stop.clone());
    let out = Command::new(gema2())
        .args(["run", "--prefix", &p, "--scans", "120", "--timeout", "120", "--pipeline"])
        .arg(pipeline(dir.path(), &log, "50"))
        .arg("--record")
        .arg(&file)
        .output()
        .unwrap();
    stop.store(true, Ordering::Relaxed);
    let published = watcher.join().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(stderr.contains("scan: 120 recorded, 0 missed"), "{stderr}");
    assert_eq!(published.len(), 120);

    let (summary, recorded) = inspect(std::slice::from_ref(&file));
    assert!(summary.contains("scans: 120 (seq 0..=119)"), "{summary}");
    // the run's report and the recording's agree on every latency figure they share: one
    // definition, from the pose's stamps, with one quantile
    let report = String::from_utf8_lossy(&out.stdout);
    let figure = |text: &str, label: &str| -> (String, String) {
        let line =
            text.lines().find(|l| l.trim_start().starts_with(label)).unwrap_or_else(|| panic!("{label}: {text}"));
        let mut numbers = line[line.find(label).unwrap() + label.len()..].split_whitespace().map(str::to_owned);
        (numbers.next().unwrap(), numbers.next().unwrap())
    };
    for f in messages::latency::FIGURES {
        assert_eq!(figure(&report, f.label), figure(&summary, f.label), "{}:\n{report}\n{summary}", f.label);
    }
    assert!(summary.contains("map: ") && !summary.contains("map: 0 walls"), "{summary}");
    assert!(summary.contains("success: "), "{summary}");
    for (seq, p) in &published {
        let r = &recorded[seq];
        let got = |e: &str| r.get(e).copied();
        assert_eq!(got("scan/readings"), p.readings, "scan {seq} readings");
        assert_eq!(got("scan/lines"), p.lines, "scan {seq} lines");
        assert_eq!(got("scan/corners"), p.corners, "scan {seq} corners");
        assert_eq!(got("world/hypotheses"), p.hypotheses, "scan {seq} hypotheses");
        assert_eq!(got("world/pose"), p.hypotheses.map(|h| h.min(1)), "scan {seq} pose");
        assert_eq!(got("scan/corners/chosen"), p.chosen, "scan {seq} chosen corner");
        assert_eq!(got("world/readings"), p.hypotheses.and_then(|h| if h > 0 { p.readings } else { Some(0) }));
        assert_eq!(got("world/truth"), Some(1), "scan {seq} truth");
        assert_eq!(got("metrics/status"), Some(1), "scan {seq} status");
    }
    // gema2 inspect hands the file to the same decoder
    let out = Command::new(gema2()).arg("inspect").arg(&file).output().unwrap();
    assert!(out.status.success() && String::from_utf8_lossy(&out.stdout).contains("scans: 120"));
    // a reader that leaves before the end (`| head -8`) ends the printing quietly: the pipe is
    // closed before inspect has read the recording, so every write meets a broken pipe
    let mut early = Command::new(gema2())
        .args(["inspect", "--per-scan"])
        .arg(&file)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    drop(early.stdout.take());
    let out = early.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{:?}: {stderr}", out.status);
    assert!(!stderr.contains("panicked") && !stderr.contains("Broken pipe"), "{stderr}");

    // a recording cut short (a recorder killed mid-write, a full disk) keeps what it holds up
    // to the cut: inspect reports it, says it is damaged, and fails
    let bytes = std::fs::read(&file).unwrap();
    let cut = dir.path().join("cut.rrd");
    std::fs::write(&cut, &bytes[..bytes.len() * 3 / 5]).unwrap();
    let out = Command::new(gema2()).arg("inspect").arg(&cut).output().unwrap();
    let (stdout, stderr) = (String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
    assert!(!out.status.success(), "{stdout}");
    assert!(stdout.contains("damaged: ") && stdout.contains("cut.rrd"), "{stdout}");
    assert!(stderr.contains("1 of 1 parts damaged") && !stderr.contains("exit status"), "{stderr}");
    let line = stdout.lines().find(|l| l.starts_with("scans: ")).unwrap_or_else(|| panic!("{stdout}"));
    let kept: usize = line["scans: ".len()..].split(' ').next().unwrap().parse().unwrap();
    assert!((20..120).contains(&kept), "{line}");
}

fn signal(pid: u32, sig: i32) {
    // SAFETY: kill(2) on a process this test started.
    unsafe { libc::kill(pid as i32, sig) };
}

/// Waits (a minute at most) until the recording `file` holds `bytes` bytes.
fn wait_for_bytes(file: &Path, bytes: u64) {
    let start = Instant::now();
    while start.elapsed() < Duration::from_secs(60) && std::fs::metadata(file).map_or(0, |m| m.len()) < bytes {
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// A recorder killed outright (kill -9: nothing of its own cleans up) reads every topic, and
/// every stage that waits for room had it among its readers: the run must go on to its end as
/// though it had never been there.
#[test]
fn a_recorder_killed_outright_costs_the_run_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let log = simulate(dir.path(), 3000);
    let file = dir.path().join("killed.rrd");
    let p = prefix("killrec");
    let mut recorder =
        Command::new(viewer()).args(["--prefix", &p, "--out"]).arg(&file).stderr(Stdio::null()).spawn().unwrap();
    let run = Command::new(gema2())
        .args(["run", "--prefix", &p, "--scans", "3000", "--timeout", "120", "--pipeline"])
        .arg(pipeline(dir.path(), &log, "max"))
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // kill it once it has had some scans, while the source still publishes as fast as it may
    wait_for_bytes(&file, 100_000);
    signal(recorder.id(), libc::SIGKILL);
    let _ = recorder.wait();
    let out = run.wait_with_output().unwrap();
    let report = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{report}\n{}", String::from_utf8_lossy(&out.stderr));
    assert!(report.contains("poses received 3000 of 3000"), "{report}");
}

#[test]
fn sigint_mid_run_leaves_a_clean_file_with_every_scan_received() {
    let dir = tempfile::tempdir().unwrap();
    let log = simulate(dir.path(), 400);
    let file = dir.path().join("stopped.rrd");
    let p = prefix("sigint");
    let recorder =
        Command::new(viewer()).args(["--prefix", &p, "--out"]).arg(&file).stderr(Stdio::piped()).spawn().unwrap();
    let mut run = Command::new(gema2())
        .args(["run", "--prefix", &p, "--scans", "400", "--timeout", "120", "--pipeline"])
        .arg(pipeline(dir.path(), &log, "40"))
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    // stop the recorder mid-run, once it has had a second or two of scans
    wait_for_bytes(&file, 200_000);
    signal(recorder.id(), libc::SIGINT);
    let out = recorder.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    signal(run.id(), libc::SIGINT);
    let _ = run.wait();
    assert!(out.status.success(), "the recorder failed: {stderr}");
    // "scan: N recorded, M missed, ..., seq A..=B"
    let line = stderr.lines().find(|l| l.starts_with("scan: ")).unwrap_or_else(|| panic!("{stderr}"));
    let number = |after: &str, upto: &str| -> u64 {
        let rest = &line[line.find(after).unwrap() + after.len()..];
        rest[..rest.find(upto).unwrap_or(rest.len())].trim().parse().unwrap()
    };
    let (recorded, first, last) = (number("scan: ", " recorded"), number("seq ", ".."), number("..=", "\n"));
    assert!(recorded > 10 && last < 399, "not stopped mid-run: {line}");
    let (_, table) = inspect(std::slice::from_ref(&file));
    let scans: Vec<u64> = table.iter().filter(|(_, e)| e.contains_key("scan/readings")).map(|(&s, _)| s).collect();
    assert_eq!(scans.len() as u64, recorded, "{line}");
    assert_eq!((scans[0], *scans.last().unwrap()), (first, last));
    // the rerun CLI, where installed, agrees that the file is sound
    if let Ok(v) = Command::new("rerun").args(["rrd", "verify"]).arg(&file).output() {
        assert!(v.status.success(), "rerun rrd verify: {}", String::from_utf8_lossy(&v.stderr));
    }
}

/// A live viewer that never answers (a mistyped `--connect` address) takes nothing from the
/// file: every scan is recorded, the recorder stops on SIGINT, and it fails saying what the
/// viewer missed. rerun's client blocks once 100 messages wait for a viewer, which stopped the
/// file at 47 of 60 scans and the recorder for good.
#[test]
fn a_live_viewer_that_never_answers_costs_the_file_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let log = simulate(dir.path(), 120);
    let file = dir.path().join("live.rrd");
    let p = prefix("deadlive");
    let closed = std::net::TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap();
    let mut recorder = Command::new(viewer())
        .args(["--prefix", &p, "--connect", &closed.to_string(), "--out"])
        .arg(&file)
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let run = Command::new(gema2())
        .args(["run", "--prefix", &p, "--scans", "120", "--timeout", "120", "--pipeline"])
        .arg(pipeline(dir.path(), &log, "100"))
        .output()
        .unwrap();
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
    // the recorder takes what is still queued once the run is over
    std::thread::sleep(Duration::from_millis(500));
    signal(recorder.id(), libc::SIGINT);
    let start = Instant::now();
    while recorder.try_wait().unwrap().is_none() {
        if start.elapsed() > Duration::from_secs(60) {
            let _ = recorder.kill();
            panic!("the recorder did not stop within 60 s of SIGINT");
        }
        std::thread::sleep(Duration::from_millis(100));
    }
    let out = recorder.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{stderr}");
    assert!(stderr.contains(&format!("no rerun viewer answers at {closed}")), "{stderr}");
    assert!(stderr.contains("scan: 120 recorded, 0 missed"), "{stderr}");
    assert!(stderr.contains("viewer: wrote") && stderr.contains("never answered"), "{stderr}");
    let (summary, _) = inspect(std::slice::from_ref(&file));
    assert!(summary.contains("scans: 120 (seq 0..=119)"), "{summary}");
}

/// Every swap is recorded: the recording's log holds the supervisor's word for it, and
/// `inspect` lists the swaps, refused ones too.
#[test]
fn swaps_are_recorded_and_inspect_lists_them() {
    let dir = tempfile::tempdir().unwrap();
    let log = simulate(dir.path(), 60);
    let file = dir.path().join("swaps.rrd");
    let p = prefix("swaprec");
    let run = Command::new(gema2())
        .args(["run", "--prefix", &p, "--scans", "60", "--timeout", "60", "--record"])
        .arg(&file)
        .arg("--pipeline")
        .arg(pipeline(dir.path(), &log, "20"))
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    wait_for_bytes(&file, 1);
    let swap = |args: &[&str]| Command::new(gema2()).args(["swap"]).args(args).args(["--prefix", &p]).output().unwrap();
    let done = swap(&["segment", "--impl", "split-and-merge"]);
    assert!(done.status.success(), "{}", String::from_utf8_lossy(&done.stderr));
    let refused = swap(&["segment", "--impl", "no-such"]);
    assert!(!refused.status.success());
    let out = run.wait_with_output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let (text, _) = inspect(&[file]);
    assert!(text.contains("swaps: 2"), "{text}");
    assert!(text.contains("  swapped segment to split-and-merge"), "{text}");
    assert!(text.contains("no implementation \"no-such\""), "{text}");
}
