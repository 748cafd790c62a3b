//! The ros2 bridge against Eclipse Cyclone DDS (PyPI `cyclonedds`, scripts/ros2_peer.py)
//! playing a ROS 2 robot: 1081-beam LaserScans at 40 Hz in, every located scan's robot pose out
//! on /gema2/pose, and Nav2 seeded on /initialpose.
//!
//! No packet leaves the machine: every DDS participant runs in a network namespace the test
//! creates (`unshare --net`), with only `lo`, multicast on, and 224.0.0.0/4 routed to it.

mod common;

use std::path::Path;
use std::process::Command;

fn exe() -> &'static str {
    env!("CARGO_BIN_EXE_gema2")
}

/// Runs `gema2 args...`, which must succeed.
fn gema2_ok(args: &[&str]) {
    let out = Command::new(exe()).args(args).output().unwrap();
    assert!(out.status.success(), "gema2 {}: {}", args.join(" "), String::from_utf8_lossy(&out.stderr));
}

/// A simulated UST-10LX's scans in the office (1081 beams over 270 degrees, to 10 m): `scans`
/// of them, drawn with `seed`, as a log in `d`.
fn office_ust_log(d: &Path, scans: usize, seed: u32) -> std::path::PathBuf {
    let log = d.join("ust.log");
    let (scans, seed) = (scans.to_string(), seed.to_string());
    let fov = ["--beams", "1081", "--fov", "270", "--range-max", "10"];
    gema2_ok(
        &[&["sim", "--map", "office"][..], &fov, &["--scans", &scans, "--seed", &seed, "--out", log.to_str().unwrap()]]
            .concat(),
    );
    log
}

/// Whether this machine lets the test make a network namespace.
fn namespaces_work() -> bool {
    Command::new("unshare").args(["--net", "--map-root-user", "true"]).status().is_ok_and(|s| s.success())
}

/// The pipeline file with the ros2 stage as its source.
const ROS2_PIPELINE: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/pipelines/ros2.toml");

/// A scratch directory for `test`, which runs DDS in a network namespace; none, and the test
/// recorded as skipped, where this machine cannot make one.
fn namespaced(test: &str) -> Option<tempfile::TempDir> {
    if !namespaces_work() {
        common::skipped(test, "no network namespace (unshare --net)");
        return None;
    }
    Some(tempfile::tempdir().unwrap())
}

/// Runs `script` (bash) in a new network namespace with loopback multicast.
fn in_namespace(script: &str) -> std::process::Output {
    let setup = "set -e; ip link set lo up; ip link set lo multicast on; ip route add 224.0.0.0/4 dev lo; set +e\n";
    Command::new("unshare")
        .args(["--net", "--map-root-user", "bash", "-c"])
        .arg(format!("{setup}{script}"))
        .output()
        .expect("unshare runs")
}

/// The CSV rows of `path`, split.
fn rows(path: &Path) -> Vec<Vec<String>> {
    std::fs::read_to_string(path)
        .unwrap_or_default()
        .lines()
        .map(|l| l.split(',').map(str::to_owned).collect())
        .collect()
}

/// Runs, in a new network namespace and in `d`, the pipeline file `pipeline` on the office for
/// `scans` poses (or, with 0, until `--timeout 40`; else 90) beside the Cyclone peer sending
/// `log` (with `peer_args`), and checks that both ended well. Returns what the run and the peer
/// said, for the checks that follow.
fn office_beside_the_peer(d: &Path, pipeline: &Path, name: &str, scans: usize, log: &Path, peer_args: &str) -> String {
    let python = common::python();
    let peer = concat!(env!("CARGO_MANIFEST_DIR"), "/scripts/ros2_peer.py");
    let prefix = format!("{name}_{}", std::process::id());
    let script = format!(
        "cd {dir}\n\
         GEMA2_MAP=office {exe} run --pipeline {pipeline} --prefix {prefix} --scans {scans} --timeout {timeout} --out online.csv \
           > run.out 2> run.err &\n\
         run=$!\n\
         {python} {peer} {log} {peer_args} > peer.out 2> peer.err\n\
         echo peer $?\n\
         wait $run\n\
         echo run $?\n",
        dir = d.display(),
        exe = exe(),
        pipeline = pipeline.display(),
        python = python.display(),
        log = log.display(),
        timeout = if scans == 0 { 40 } else { 90 },
    );
    let out = in_namespace(&script);
    let said = String::from_utf8_lossy(&out.stdout);
    let logs = |f: &str| std::fs::read_to_string(d.join(f)).unwrap_or_default();
    let context = format!("{said}\nrun: {}\npeer: {}", logs("run.err"), logs("peer.err"));
    assert!(said.contains("peer 0") && said.contains("run 0"), "{context}");
    context
}

#[test]
fn cyclone_dds_scans_in_and_poses_out_with_none_lost() {
    let Some(dir) = namespaced("cyclone_dds_scans_in_and_poses_out_with_none_lost") else { return };
    let d = dir.path();
    let log = office_ust_log(d, 200, 2);
    let context =
        office_beside_the_peer(d, Path::new(ROS2_PIPELINE), "tros2", 200, &log, "--rate 40 --laser-pose 0.2,0.05,0.1");
    let logs = |f: &str| std::fs::read_to_string(d.join(f)).unwrap_or_default();
    // every scan located by the pipeline reached ROS, as the robot's pose of that scan
    let online = rows(&d.join("online.csv"));
    let located: Vec<&Vec<String>> = online.iter().skip(1).filter(|r| r[5] != "failed").collect();
    assert!(located.len() >= 190, "{} of 200 located: {context}", located.len());
    let poses: Vec<Vec<String>> = rows(&d.join("peer.out")).into_iter().filter(|r| r[0] == "gema2/pose").collect();
    assert_eq!(poses.len(), located.len(), "no pose lost: {context}");
    let (mx, my, mt) = (0.2f64, 0.05f64, 0.1f64);
    for (p, r) in poses.iter().zip(&located) {
        assert_eq!(p[1], r[0], "the scan's stamp comes back with its pose");
        let num = |s: &String| s.parse::<f64>().unwrap();
        let (lx, ly, lt) = (num(&r[1]), num(&r[2]), num(&r[3]));
        // robot = laser o mount^-1
        let t = lt - mt;
        let (x, y) = (lx - (t.cos() * mx - t.sin() * my), ly - (t.sin() * mx + t.cos() * my));
        assert!((num(&p[2]) - x).abs() < 1e-3 && (num(&p[3]) - y).abs() < 1e-3, "{p:?} vs {r:?}");
        let turn = (num(&p[4]) - t + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU) - std::f64::consts::PI;
        assert!(turn.abs() < 1e-3, "{p:?} vs {r:?}");
        assert_eq!(p[9], "map");
        // an ok pose carries the ok spread; an ambiguous one more
        let var = num(&p[5]);
        assert!(if r[5] == "ok" { (var - 0.0025).abs() < 1e-9 } else { var >= 0.0025 }, "{p:?} {r:?}");
    }
    // Nav2 seeded with ok poses, at most once per 10 s: 200 scans at 40 Hz take 5 s
    let seeds: Vec<Vec<String>> = rows(&d.join("peer.out")).into_iter().filter(|r| r[0] == "initialpose").collect();
    assert_eq!(seeds.len(), 1, "{seeds:?}");
    let latency = logs("peer.err");
    assert!(latency.contains("latency p50"), "{latency}");
    eprintln!("{}", latency.trim());
}

/// Damaged LaserScans over DDS cost only themselves. The Cyclone peer sends every fifth of 200
/// scans damaged, in turn: a layout of NaN, zero or infinite numbers, readings all NaN,
/// infinite or huge, none, 200 000 of them, bounds the wrong way round, a stray intensities
/// array (`ros2_peer.py --hostile`). The bridge drops what describes no usable scan and says
/// so, and the pipeline locates the good scans around them as it would without them.
#[test]
fn damaged_laser_scans_over_dds_cost_only_themselves() {
    let Some(dir) = namespaced("damaged_laser_scans_over_dds_cost_only_themselves") else { return };
    let d = dir.path();
    // with no pose back for the dropped scans the run ends at its timeout
    let (log, peer) = (office_ust_log(d, 200, 4), "--rate 40 --hostile 5");
    let context = office_beside_the_peer(d, Path::new(ROS2_PIPELINE), "thostile", 0, &log, peer);
    let answered: std::collections::BTreeSet<usize> = rows(&d.join("peer.out"))
        .into_iter()
        .filter(|r| r[0] == "gema2/pose")
        .filter_map(|r| r[1].parse().ok())
        .collect();
    let good: Vec<usize> = (0..200).filter(|k| k % 5 != 4).collect();
    let lost: Vec<&usize> = good.iter().filter(|k| !answered.contains(k)).collect();
    assert!(lost.len() <= good.len() / 20, "{} good scans of {} lost ({lost:?}): {context}", lost.len(), good.len());
    assert!(context.contains("dropped a LaserScan"), "no word of the dropped scans: {context}");
}

/// A laser mounted upside down (rolled 180 degrees on /tf_static), as the robot sees it: its
/// beams turn clockwise. The bridge reads its scans mirrored and locates them where the
/// upright laser's would be; unmirrored, the office would be seen in a mirror.
#[test]
fn a_laser_mounted_upside_down_is_read_mirrored() {
    let Some(dir) = namespaced("a_laser_mounted_upside_down_is_read_mirrored") else { return };
    let d = dir.path();
    let log = d.join("flip.log");
    gema2_ok(&["sim", "--map", "office", "--scans", "60", "--seed", "3", "--out", log.to_str().unwrap()]);
    let pipeline = Path::new(ROS2_PIPELINE);
    let context =
        office_beside_the_peer(d, pipeline, "tflip", 60, &log, "--rate 20 --laser-pose 0.2,0.0,0.3 --upside-down");
    assert!(context.contains("is mounted upside down"), "{context}");
    // the located laser poses against the log's own (ROBOTLASER1's laser pose)
    let truth: Vec<(f64, f64, f64)> = std::fs::read_to_string(&log)
        .unwrap()
        .lines()
        .filter(|l| l.starts_with("ROBOTLASER1"))
        .map(|l| {
            let t: Vec<f64> = l.split_whitespace().skip(1).map(|v| v.parse().unwrap_or(f64::NAN)).collect();
            let n = t[7] as usize;
            let m = t[8 + n] as usize;
            let at = 9 + n + m;
            (t[at], t[at + 1], t[at + 2])
        })
        .collect();
    let online = rows(&d.join("online.csv"));
    let right = online
        .iter()
        .skip(1)
        .filter(|r| {
            let k: usize = r[0].parse().unwrap();
            let num = |s: &String| s.parse::<f64>().unwrap_or(f64::NAN);
            let (x, y, t) = truth[k];
            let turn = (num(&r[3]) - t + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU) - std::f64::consts::PI;
            (num(&r[1]) - x).hypot(num(&r[2]) - y) <= 0.3 && turn.abs() <= 5f64.to_radians()
        })
        .count();
    assert!(right >= 54, "{right} of 60 right: {context}");
}

/// The map from a ROS 2 map_server: Cyclone DDS publishes the office drawn as a grid on /map
/// (transient local, as map_server does); the map server takes it (`--map ros2:/map`, the
/// pipeline file's default), traces it into walls and the pipeline locates the scans against
/// it; the grid published again midway is a new map version.
#[test]
fn the_map_comes_from_a_ros_2_map_server() {
    let Some(dir) = namespaced("the_map_comes_from_a_ros_2_map_server") else { return };
    let python = common::python();
    let d = dir.path();
    let grid = d.join("office.yaml");
    gema2_ok(&["map", "export-ros", "--map", "office", "--out", grid.to_str().unwrap()]);
    let log = office_ust_log(d, 80, 6);
    let pipeline = ROS2_PIPELINE;
    let peer = concat!(env!("CARGO_MANIFEST_DIR"), "/scripts/ros2_peer.py");
    let prefix = format!("tros2map_{}", std::process::id());
    // the robot (and its map_server) first; the pipeline's map server waits for the grid
    let script = format!(
        "cd {dir}\n\
         {python} {peer} {log} --rate 20 --grid {grid} --regrid-after 40 > peer.out 2> peer.err &\n\
         peer=$!\n\
         unset GEMA2_MAP\n\
         {exe} run --pipeline {pipeline} --prefix {prefix} --scans 80 --timeout 90 --out online.csv \
           > run.out 2> run.err\n\
         echo run $?\n\
         wait $peer\n\
         echo peer $?\n",
        dir = d.display(),
        exe = exe(),
        python = python.display(),
        log = log.display(),
        grid = grid.display(),
    );
    let out = in_namespace(&script);
    let said = String::from_utf8_lossy(&out.stdout);
    let logs = |f: &str| std::fs::read_to_string(d.join(f)).unwrap_or_default();
    let context = format!("{said}\nrun: {}\npeer: {}", logs("run.err"), logs("peer.err"));
    assert!(said.contains("peer 0") && said.contains("run 0"), "{context}");
    assert!(logs("run.err").contains("mapserver: serving ros2:/map ("), "{context}");
    // the grid published again is a new map version, taken up by the localizer
    assert!(
        logs("run.err").contains("mapserver: received ros2:/map (") && logs("run.err").contains("as version 2"),
        "{context}"
    );
    assert!(logs("run.err").contains("localize: map version 2 ("), "{context}");
    // the poses against the traced grid are where the simulator put the laser
    let truth: Vec<(f64, f64)> = std::fs::read_to_string(&log)
        .unwrap()
        .lines()
        .filter(|l| l.starts_with("ROBOTLASER1"))
        .map(|l| {
            let t: Vec<&str> = l.split_whitespace().collect();
            let n: usize = t[8].parse().unwrap();
            let p = 9 + n + 1;
            (t[p].parse().unwrap(), t[p + 1].parse().unwrap())
        })
        .collect();
    let poses: Vec<Vec<String>> = rows(&d.join("peer.out")).into_iter().filter(|r| r[0] == "gema2/pose").collect();
    let right = poses
        .iter()
        .filter(|p| {
            let k: usize = p[1].parse().unwrap();
            let (x, y): (f64, f64) = (p[2].parse().unwrap(), p[3].parse().unwrap());
            truth.get(k).is_some_and(|&(tx, ty)| (x - tx).hypot(y - ty) < 0.3)
        })
        .count();
    assert!(right * 10 >= truth.len() * 8, "{right} of {} scans located right: {context}", truth.len());
}

/// Odometry over DDS: Cyclone DDS publishes the robot's nav_msgs/Odometry on /odom with each
/// scan, the ros2 stage gives every scan the odometry at its stamp, and the sequential localizer
/// (`implementation = "sequential"`) carries its hypotheses from scan to scan by it: its answers
/// come to rest on several scans. Without odometry every scan would rest on itself alone.
#[test]
fn odometry_over_dds_carries_the_sequential_localizer_from_scan_to_scan() {
    sequential_over_dds(
        "odometry_over_dds_carries_the_sequential_localizer_from_scan_to_scan",
        "tros2odom",
        "/odom",
        "--odom",
    );
}

/// The same with the odometry on /tf only, as many robots publish it: odom -> base_footprint
/// beside a localizer's map -> odom, base_link hung from base_footprint on /tf_static
/// (`GEMA2_ODOM_TOPIC=/tf`).
#[test]
fn odometry_off_tf_over_dds_carries_the_sequential_localizer() {
    sequential_over_dds("odometry_off_tf_over_dds_carries_the_sequential_localizer", "tros2tf", "/tf", "--odom-on-tf");
}

/// A walk of 100 scans through the office, located by the sequential localizer in the ROS 2
/// pipeline (services under `name`) reading its odometry from `odom_topic`, which the peer
/// fills (`peer_odom`).
fn sequential_over_dds(test: &str, name: &str, odom_topic: &str, peer_odom: &str) {
    let Some(dir) = namespaced(test) else { return };
    let d = dir.path();
    // a robot walking the office, its exact odometry in each line's robot pose
    let log = d.join("walk.log");
    gema2_ok(&[
        "sim",
        "--map",
        "office",
        "--trajectory",
        "--scans",
        "100",
        "--seed",
        "4",
        "--out",
        log.to_str().unwrap(),
    ]);
    let text = std::fs::read_to_string(ROS2_PIPELINE).unwrap();
    assert!(text.contains("${GEMA2_ODOM_TOPIC:-/odom}"), "the pipeline file names its odometry topic");
    let text = text.replace("${GEMA2_ODOM_TOPIC:-/odom}", odom_topic);
    let text = common::with_stage_lines(&text, "localize", "implementation = \"sequential\"");
    let pipeline = d.join("ros2-sequential.toml");
    std::fs::write(&pipeline, text).unwrap();
    let context = office_beside_the_peer(d, &pipeline, name, 100, &log, &format!("--rate 20 {peer_odom}"));
    let online = rows(&d.join("online.csv"));
    assert_eq!(online.first().map(|h| h[11].as_str()), Some("scans"), "{context}");
    let located: Vec<&Vec<String>> = online.iter().skip(1).filter(|r| r[5] != "failed").collect();
    assert!(located.len() >= 90, "{} of 100 located: {context}", located.len());
    let resting = |n: u32| located.iter().filter(|r| r[11].parse::<u32>().unwrap_or(0) >= n).count();
    assert!(resting(2) * 2 >= located.len(), "{} of {} rest on 2 scans or more: {context}", resting(2), located.len());
    assert!(resting(10) > 0, "none rests on 10 scans: {context}");
}
