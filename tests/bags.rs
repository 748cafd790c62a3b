//! ROS 2 bags written by an implementation that is not ours (the PyPI `rosbags` package, through
//! scripts/carmen2bag.py): `gema2 locate --bag` gives the rows `--log` gives on the same scans.

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

const MAP: &str = "apartment";

fn exe() -> &'static str {
    env!("CARGO_BIN_EXE_gema2")
}

fn gema2(args: &[&str]) -> Output {
    Command::new(exe()).args(args).output().expect("gema2 runs")
}

fn ok(out: Output) -> String {
    assert!(out.status.success(), "{}\n{}", String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// `scripts/carmen2bag.py LOG OUT extra...`.
fn carmen2bag(log: &Path, out: &Path, extra: &[&str]) {
    let script = concat!(env!("CARGO_MANIFEST_DIR"), "/scripts/carmen2bag.py");
    let run = Command::new(common::python()).arg(script).arg(log).arg(out).args(extra).output().unwrap();
    assert!(run.status.success(), "carmen2bag.py: {}", String::from_utf8_lossy(&run.stderr));
}

/// A CSV row: status, x, y, theta, score.
type Row = (String, f64, f64, f64, f64);

/// The CSV rows of `path`.
fn rows(path: &Path) -> Vec<Row> {
    std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .skip(1)
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            let num = |k: usize| f[k].parse::<f64>().unwrap_or(f64::NAN);
            (f[5].to_owned(), num(1), num(2), num(3), num(4))
        })
        .collect()
}

/// Locates `source` (`--log L` or `--bag B ...`) on `map` and returns the CSV rows and the report.
fn locate(dir: &Path, name: &str, map: &str, source: &[&str], extra: &[&str]) -> (Vec<Row>, String) {
    let (rows, report, _) = locate_saying(dir, name, map, source, extra);
    (rows, report)
}

/// [`locate`], with what the command said on stderr as well.
fn locate_saying(dir: &Path, name: &str, map: &str, source: &[&str], extra: &[&str]) -> (Vec<Row>, String, String) {
    let csv = dir.join(format!("{name}.csv"));
    let mut args = vec!["locate", "--map", map, "--out", csv.to_str().unwrap()];
    args.extend_from_slice(source);
    args.extend_from_slice(extra);
    let run = gema2(&args);
    let said = String::from_utf8_lossy(&run.stderr).into_owned();
    let report = ok(run);
    (rows(&csv), report, said)
}

/// How many rows agree (the same status, and the same pose within 1 cm and 0.5 degrees), and
/// how many more are ties: ambiguous both ways, with the same score, the best of two equally good
/// poses told apart by the last bits of a float. A bag carries a scan's angles as float32,
/// a log as decimals, and a symmetric world's ties fall either way; so do they between a FLASER
/// and a ROBOTLASER1 line of the same scan.
fn agreeing(a: &[Row], b: &[Row]) -> (usize, usize) {
    let same = |p: &Row, q: &Row| {
        let turn = (p.3 - q.3 + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU) - std::f64::consts::PI;
        p.0 == q.0 && (p.0 == "failed" || ((p.1 - q.1).hypot(p.2 - q.2) <= 0.01 && turn.abs().to_degrees() <= 0.5))
    };
    let tie = |p: &Row, q: &Row| p.0 == "ambiguous" && q.0 == "ambiguous" && (p.4 - q.4).abs() < 1e-3;
    let agree = a.iter().zip(b).filter(|(p, q)| same(p, q)).count();
    let ties = a.iter().zip(b).filter(|(p, q)| !same(p, q) && tie(p, q)).count();
    (agree, ties)
}

/// A FLASER copy of a simulated SICK-like ROBOTLASER1 log: n readings from -90 degrees over
/// 180, the laser pose and the odometry pose, and a time written with 6 digits, as in the
/// CSAIL log: every scan has the same stamp, and the truth must still pair up.
fn as_flaser(log: &Path, out: &Path) {
    let text = std::fs::read_to_string(log).unwrap();
    let mut lines = String::new();
    for l in text.lines().filter(|l| l.starts_with("ROBOTLASER1")) {
        let t: Vec<&str> = l.split_whitespace().collect();
        let n: usize = t[8].parse().unwrap();
        let ranges = &t[9..9 + n];
        let p = 9 + n + 1; // after the remission count (0)
        let (x, y, th, stamp) = (t[p], t[p + 1], t[p + 2], "1.13486e+09");
        lines += &format!("FLASER {n} {} {x} {y} {th} {x} {y} {th} {stamp} sim {stamp}\n", ranges.join(" "));
    }
    std::fs::write(out, lines).unwrap();
}

/// The .mcap file of a bag directory.
fn mcap_in(bag: &Path) -> PathBuf {
    std::fs::read_dir(bag)
        .unwrap()
        .map(|e| e.unwrap().path())
        .find(|p| p.extension().is_some_and(|e| e == "mcap"))
        .expect("a bag holds an .mcap file")
}

/// A simulated URG log of `scans` scans in `dir` and the bag carmen2bag.py makes of it.
fn log_and_bag(dir: &Path, scans: usize) -> (PathBuf, PathBuf) {
    let log = sim(dir, "urg.log", scans, &[]);
    let bag = dir.join("bag");
    carmen2bag(&log, &bag, &[]);
    (log, bag)
}

/// A simulated log of `scans` scans in the apartment (a world with few symmetries).
fn sim(dir: &Path, name: &str, scans: usize, extra: &[&str]) -> PathBuf {
    let log = dir.join(name);
    let scans = scans.to_string();
    let mut args = vec!["sim", "--map", MAP, "--scans", &scans, "--seed", "4", "--out", log.to_str().unwrap()];
    args.extend_from_slice(extra);
    ok(gema2(&args));
    log
}

#[test]
fn a_bag_written_by_rosbags_locates_as_the_log_it_was_made_from() {
    let dir = tempfile::tempdir().unwrap();
    // a URG-04LX log (ROBOTLASER1), and a SICK-like one as FLASER lines with no-return readings
    let urg = sim(dir.path(), "urg.log", 60, &[]);
    let sick = sim(
        dir.path(),
        "sick.log",
        60,
        &["--beams", "181", "--fov", "180", "--range-max", "8", "--dropout-as-max-range"],
    );
    let flaser = dir.path().join("sick-flaser.log");
    as_flaser(&sick, &flaser);
    for (name, log, extra) in [("urg", &urg, &[][..]), ("flaser", &flaser, &["--flaser-range-max", "8"][..])] {
        let bag = dir.path().join(format!("{name}-bag"));
        carmen2bag(log, &bag, extra);
        let log_s = log.to_str().unwrap();
        let bag_s = bag.to_str().unwrap();
        for selection in [&["--every", "1"][..], &["--every", "3", "--offset", "2"][..]] {
            let (by_log, log_report) =
                locate(dir.path(), &format!("{name}-log"), MAP, &["--log", log_s], &[extra, selection].concat());
            let (by_bag, bag_report) = locate(
                dir.path(),
                &format!("{name}-bag"),
                MAP,
                &["--bag", bag_s, "--truth-topic", "/truth"],
                selection,
            );
            assert_eq!(by_log.len(), by_bag.len(), "{name} {selection:?}: one row per scan");
            assert!(by_log.len() >= 20, "{name}: {} rows", by_log.len());
            let (agree, ties) = agreeing(&by_log, &by_bag);
            assert!(agree * 100 >= by_log.len() * 99, "{name} {selection:?}: {agree} of {} rows agree", by_log.len());
            assert_eq!(agree + ties, by_log.len(), "{name} {selection:?}: rows that neither agree nor tie");
            // the truth topic gives the same success figures
            let success = |r: &str| r.lines().find(|l| l.starts_with("success")).map(str::to_owned);
            assert!(success(&log_report).is_some(), "{log_report}");
            assert_eq!(success(&log_report), success(&bag_report), "{name} {selection:?}");
        }
        // the bag's single file reads as the bag
        let file = mcap_in(&bag);
        let (by_file, _) = locate(dir.path(), &format!("{name}-file"), MAP, &["--bag", file.to_str().unwrap()], &[]);
        let (by_log, _) = locate(dir.path(), &format!("{name}-log"), MAP, &["--log", log_s], extra);
        assert!(agreeing(&by_log, &by_file).0 * 100 >= by_log.len() * 99);
    }
}

#[test]
fn bags_gema2_cannot_read_are_refused_in_words() {
    let dir = tempfile::tempdir().unwrap();
    let log = sim(dir.path(), "urg.log", 30, &[]);
    // a compressed bag's files: the command that converts it
    let zstd = dir.path().join("zstd-bag");
    std::fs::create_dir(&zstd).unwrap();
    std::fs::write(
        zstd.join("metadata.yaml"),
        "  storage_identifier: mcap\n  relative_file_paths:\n  - b_0.mcap.zstd\n",
    )
    .unwrap();
    let out = gema2(&["locate", "--bag", zstd.to_str().unwrap()]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("b_0.mcap.zstd") && err.contains("ros2 bag convert"), "{err}");
    // a topic that is not there, and a truth topic that holds scans
    let bag = dir.path().join("bag");
    carmen2bag(&log, &bag, &[]);
    let b = bag.to_str().unwrap();
    let out = gema2(&["locate", "--bag", b, "--scan-topic", "/laser"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("no topic /laser") && err.contains("/scan"), "{err}");
    let out = gema2(&["locate", "--bag", b, "--truth-topic", "/scan"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("not PoseStamped or Odometry"), "{err}");
    // a .db3 file that is not sqlite
    let junk = dir.path().join("junk.db3");
    std::fs::write(&junk, b"this is not a database, whatever its name says").unwrap();
    let out = gema2(&["locate", "--bag", junk.to_str().unwrap()]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("junk.db3: not a readable sqlite3 bag file"), "{err}");
    // a directory that is no bag
    let out = gema2(&["locate", "--bag", dir.path().to_str().unwrap()]);
    assert!(String::from_utf8_lossy(&out.stderr).contains("not a bag"));
}

/// A bag in sqlite3 storage (ROS 2 Humble's default), written by rosbags, reads as the same
/// bag in MCAP storage does.
#[test]
fn a_sqlite3_bag_locates_as_its_mcap_twin() {
    let dir = tempfile::tempdir().unwrap();
    let (log, bag) = log_and_bag(dir.path(), 40);
    let db3 = dir.path().join("db3-bag");
    carmen2bag(&log, &db3, &["--storage", "sqlite3"]);
    let (b1, b2) = (bag.to_str().unwrap(), db3.to_str().unwrap());
    let (from_mcap, mcap_report) = locate(dir.path(), "mcap", MAP, &["--bag", b1, "--truth-topic", "/truth"], &[]);
    let (from_db3, db3_report) = locate(dir.path(), "db3", MAP, &["--bag", b2, "--truth-topic", "/truth"], &[]);
    assert_eq!(from_mcap.len(), 40);
    assert_eq!(from_mcap, from_db3);
    let success = |r: &str| r.lines().find(|l| l.starts_with("success")).map(str::to_owned);
    assert_eq!(success(&mcap_report), success(&db3_report));
    // its one file reads as the bag
    let file =
        std::fs::read_dir(&db3).unwrap().map(|e| e.unwrap().path()).find(|p| p.extension().is_some_and(|e| e == "db3"));
    let (from_file, _) = locate(dir.path(), "db3-file", MAP, &["--bag", file.unwrap().to_str().unwrap()], &[]);
    assert_eq!(from_file, from_mcap);
}

/// ROS 1 bags written by rosbags (ROS 1 serialization: a header with `seq`, no alignment; plain,
/// bz2 and lz4 chunks) read as the same scans in a ROS 2 bag do: the same rows, single-scan and
/// sequential on the bag's odometry.
#[test]
fn a_ros1_bag_locates_as_its_ros2_twin() {
    let dir = tempfile::tempdir().unwrap();
    let log = sim(dir.path(), "walk.log", 40, &["--trajectory"]);
    let ros2 = dir.path().join("walk-bag");
    carmen2bag(&log, &ros2, &[]);
    let topics = ["--truth-topic", "/truth", "--odom-topic", "/odom"];
    let twin = |name: &str, bag: &Path, extra: &[&str]| {
        let mut source = vec!["--bag", bag.to_str().unwrap()];
        source.extend_from_slice(&topics);
        locate(dir.path(), name, MAP, &source, extra)
    };
    let (single, single_report) = twin("ros2", &ros2, &[]);
    let (sequential, _) = twin("ros2-seq", &ros2, &["--sequential"]);
    assert_eq!(single.len(), 40);
    let success = |r: &str| r.lines().find(|l| l.starts_with("success")).map(str::to_owned);
    for compression in ["none", "bz2", "lz4"] {
        // a ROS 1 bag by its usual name, and by another
        let name = if compression == "lz4" { "walk-lz4.recording" } else { &format!("walk-{compression}.bag") };
        let bag = dir.path().join(name);
        carmen2bag(&log, &bag, &["--storage", "rosbag1", "--compression", compression]);
        let (rows, report) = twin(compression, &bag, &[]);
        assert_eq!(rows, single, "{compression}");
        assert_eq!(success(&report), success(&single_report), "{compression}");
        let (rows, _) = twin(&format!("{compression}-seq"), &bag, &["--sequential"]);
        assert_eq!(rows, sequential, "{compression}");
    }
}

#[test]
fn a_bag_cut_short_locates_the_scans_before_the_cut_and_fails() {
    let dir = tempfile::tempdir().unwrap();
    let (_, bag) = log_and_bag(dir.path(), 40);
    let file = mcap_in(&bag);
    let bytes = std::fs::read(&file).unwrap();
    let cut = dir.path().join("cut.mcap");
    std::fs::write(&cut, &bytes[..bytes.len() / 2]).unwrap();
    let csv = dir.path().join("cut.csv");
    let out = gema2(&["locate", "--bag", cut.to_str().unwrap(), "--out", csv.to_str().unwrap()]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("cut.mcap") && err.contains("stopped there"), "{err}");
    let n = rows(&csv).len();
    assert!((10..40).contains(&n), "{n} rows before the cut");
}

#[test]
fn a_map_built_from_a_bag_is_the_map_built_from_its_log() {
    let dir = tempfile::tempdir().unwrap();
    let (log, bag) = log_and_bag(dir.path(), 100);
    let built = |name: &str, source: &[&str]| {
        let out = dir.path().join(name);
        let mut args = vec!["map", "build", "--out", out.to_str().unwrap()];
        args.extend_from_slice(source);
        let run = gema2(&args);
        assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
        let text = std::fs::read_to_string(&out).unwrap();
        let walls = text.lines().filter(|l| l.trim_start().starts_with('[')).count();
        (String::from_utf8_lossy(&run.stderr).lines().next().unwrap_or("").replace(name, ""), walls)
    };
    let from_log = built("log.json", &["--log", log.to_str().unwrap()]);
    let from_bag = built("bag.json", &["--bag", bag.to_str().unwrap(), "--truth-topic", "/truth"]);
    assert!(from_log.1 > 10, "{from_log:?}");
    assert_eq!(from_log, from_bag);
    // a bag without truth builds nothing, and says why
    let out = gema2(&["map", "build", "--bag", bag.to_str().unwrap(), "--out", "/dev/null"]);
    assert!(String::from_utf8_lossy(&out.stderr).contains("--truth-topic"));
}

/// The acquire stage replays a bag into the pipeline: every scan located, with the rows
/// `locate --bag` computes offline; at `--rate recorded` at the pace of the stamps.
#[test]
fn the_pipeline_replays_a_bag_as_fast_as_it_goes_or_as_recorded() {
    let dir = tempfile::tempdir().unwrap();
    let (_, bag) = log_and_bag(dir.path(), 40);
    let bag_s = bag.to_str().unwrap();
    let (offline, _) = locate(dir.path(), "offline", MAP, &["--bag", bag_s], &[]);
    for rate in ["max", "recorded"] {
        let pipeline = common::write_pipeline(dir.path(), "p.toml", MAP, &["--bag", bag_s, "--rate", rate]);
        let online = dir.path().join(format!("online-{rate}.csv"));
        let prefix = format!("tbag{rate}_{}", std::process::id());
        let start = std::time::Instant::now();
        let out = gema2(&[
            "run",
            "--pipeline",
            pipeline.to_str().unwrap(),
            "--prefix",
            &prefix,
            "--scans",
            "40",
            "--timeout",
            "60",
            "--out",
            online.to_str().unwrap(),
        ]);
        let took = start.elapsed().as_secs_f64();
        let report = String::from_utf8_lossy(&out.stdout);
        assert!(out.status.success(), "{report}\n{}", String::from_utf8_lossy(&out.stderr));
        assert!(report.contains("poses received 40 of 40"), "{rate}: {report}");
        let online = rows(&online);
        assert_eq!(online.len(), 40);
        assert!(online.iter().zip(&offline).all(|(a, b)| a == b), "{rate}: the pipeline's rows are locate's");
        if rate == "recorded" {
            // 40 scans stamped 0.1 s apart
            assert!(took > 3.8, "{rate}: {took} s");
        }
    }
}

/// Odometry from a bag: carmen2bag.py writes each ROBOTLASER1 line's robot pose on /odom, and
/// `locate --bag --odom-topic /odom --sequential` carries its hypotheses by it as `--log
/// --sequential` does by the log's own: the same rows, and answers that rest on several scans.
/// Without the odometry topic every answer rests on its own scan.
#[test]
fn a_bag_s_odometry_carries_the_sequential_localizer_as_the_log_s_does() {
    let dir = tempfile::tempdir().unwrap();
    let log = sim(dir.path(), "walk.log", 60, &["--trajectory"]);
    let bag = dir.path().join("walk-bag");
    carmen2bag(&log, &bag, &[]);
    let seq = ["--sequential"];
    let (by_log, _) = locate(dir.path(), "walk-log", MAP, &["--log", log.to_str().unwrap()], &seq);
    let bag_s = bag.to_str().unwrap();
    let with_odom = ["--bag", bag_s, "--truth-topic", "/truth", "--odom-topic", "/odom"];
    let (by_bag, _) = locate(dir.path(), "walk-bag", MAP, &with_odom, &seq);
    assert_eq!(by_log.len(), by_bag.len());
    let (agree, ties) = agreeing(&by_log, &by_bag);
    assert!(agree * 100 >= by_log.len() * 95, "{agree} of {} rows agree ({ties} ties)", by_log.len());
    // the CSV's last column: the scans an answer rests on
    let resting = |name: &str| -> Vec<u32> {
        let text = std::fs::read_to_string(dir.path().join(format!("{name}.csv"))).unwrap();
        text.lines().skip(1).map(|l| l.rsplit(',').next().unwrap().parse().unwrap()).collect()
    };
    let (from_log, from_bag) = (resting("walk-log"), resting("walk-bag"));
    assert_eq!(from_log, from_bag);
    assert!(from_bag.iter().any(|&n| n >= 10), "{from_bag:?}");
    // no odometry topic: nothing carried from scan to scan
    let (_, _) = locate(dir.path(), "walk-bare", MAP, &["--bag", bag_s, "--truth-topic", "/truth"], &seq);
    assert!(resting("walk-bare").iter().all(|&n| n <= 1), "{:?}", resting("walk-bare"));
    // the same odometry on /tf only (odom -> base_link), in a ROS 1 bag: rows that agree
    let on_tf = dir.path().join("walk-tf.bag");
    carmen2bag(&log, &on_tf, &["--storage", "rosbag1", "--odom-on-tf"]);
    let off_tf = ["--bag", on_tf.to_str().unwrap(), "--truth-topic", "/truth", "--odom-topic", "/tf"];
    let (by_tf, _, said) = locate_saying(dir.path(), "walk-tf", MAP, &off_tf, &seq);
    assert!(said.contains("odometry from /tf: odom -> base_link"), "{said}");
    // the heading is read off a transform's quaternion by another formula than a pose's: the
    // last bits may differ, as between the log and the bag
    let (agree, ties) = agreeing(&by_bag, &by_tf);
    assert!(agree * 100 >= by_bag.len() * 95, "{agree} of {} rows agree ({ties} ties)", by_bag.len());
    assert!(resting("walk-tf").iter().any(|&n| n >= 10), "{:?}", resting("walk-tf"));
}

/// `gema2 odometry` reads a bag's truth and odometry topics as it reads a log's poses: the
/// same alphas from the bag carmen2bag.py wrote of a walked log with drifting odometry.
#[test]
fn a_bag_s_odometry_fits_the_alphas_the_log_s_does() {
    let dir = tempfile::tempdir().unwrap();
    let walk = ["--trajectory", "--step", "0.5", "--odom-noise", "0.05,0.01,0.05,0.01"];
    let log = sim(dir.path(), "drift.log", 200, &walk);
    let bag = dir.path().join("drift-bag");
    carmen2bag(&log, &bag, &[]);
    let alphas = |source: &[&str]| -> String {
        let said = ok(gema2(&["odometry"].iter().chain(source).copied().collect::<Vec<_>>()));
        said.lines().find(|l| l.starts_with("alphas")).unwrap_or_else(|| panic!("no alphas in {said}")).to_owned()
    };
    let by_log = alphas(&["--log", log.to_str().unwrap()]);
    let by_bag = alphas(&["--bag", bag.to_str().unwrap(), "--truth-topic", "/truth", "--odom-topic", "/odom"]);
    assert_eq!(by_log, by_bag);
    assert!(!by_log.contains("a1 0.0000"), "{by_log}");
}
