//! Poses outside Rust: examples/pose_listener.py reads `gema2/pose` from shared memory with the
//! PyPI `iceoryx2` package and a ctypes mirror of the payload, while a pipeline runs.

mod common;

use std::io::{BufRead, BufReader};
use std::process::{Command, Stdio};

fn exe() -> &'static str {
    env!("CARGO_BIN_EXE_gema2")
}

#[test]
fn the_python_example_prints_the_poses_the_pipeline_publishes() {
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("scans.log");
    let out = Command::new(exe())
        .args(["sim", "--map", "office", "--scans", "40", "--seed", "3", "--out", log.to_str().unwrap()])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let prefix = format!("tpy_{}", std::process::id());
    // the listener first: it waits for the pipeline's services, and stops when the replay is over
    let example = concat!(env!("CARGO_MANIFEST_DIR"), "/examples/pose_listener.py");
    let mut listener = Command::new(common::python())
        .args([example, "--prefix", &prefix, "--idle", "3", "--timeout", "90"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let pipeline =
        common::write_pipeline(dir.path(), "p.toml", "office", &["--log", log.to_str().unwrap(), "--rate", "20"]);
    let csv = dir.path().join("poses.csv");
    let run = Command::new(exe())
        .args(["run", "--pipeline", pipeline.to_str().unwrap(), "--prefix", &prefix, "--scans", "40"])
        .args(["--timeout", "90", "--out", csv.to_str().unwrap()])
        .output()
        .unwrap();
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
    let printed: Vec<String> = BufReader::new(listener.stdout.take().unwrap()).lines().map_while(Result::ok).collect();
    let status = listener.wait().unwrap();
    let mut err = String::new();
    std::io::Read::read_to_string(&mut listener.stderr.take().unwrap(), &mut err).unwrap();
    assert!(status.success(), "pose_listener.py: {err}\n{printed:?}");
    assert_eq!(printed[0], "seq,status,x,y,theta,cost,hypotheses,map_version");
    let poses = &printed[1..];
    // the pose topic keeps no history: a pose published before the listener's subscriber
    // existed is not its to see; every one after is
    assert!(poses.len() >= 35, "{} poses: {printed:?}", poses.len());
    let last: Vec<&str> = poses[poses.len() - 1].split(',').collect();
    assert_eq!(last[0], "39", "the last pose is the last scan's");
    let seqs: Vec<u64> = poses.iter().map(|l| l.split(',').next().unwrap().parse().unwrap()).collect();
    assert!(seqs.windows(2).all(|w| w[1] == w[0] + 1), "none lost once listening: {seqs:?}");
    // the poses are those the pipeline wrote: same scan, status and pose
    let rows: Vec<Vec<String>> = std::fs::read_to_string(&csv)
        .unwrap()
        .lines()
        .skip(1)
        .map(|l| l.split(',').map(str::to_owned).collect())
        .collect();
    for line in poses {
        let f: Vec<&str> = line.split(',').collect();
        let row = rows.iter().find(|r| r[0] == f[0]).unwrap_or_else(|| panic!("{line}: no such scan in the run"));
        assert_eq!((f[0], f[1]), (row[0].as_str(), row[5].as_str()), "{line} vs {row:?}");
        if f[1] != "failed" {
            for (k, c) in [(2, 1), (3, 2)] {
                let (a, b): (f64, f64) = (f[k].parse().unwrap(), row[c].parse().unwrap());
                assert!((a - b).abs() < 1e-3, "{line} vs {row:?}");
            }
        }
    }
}
