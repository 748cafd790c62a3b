//! `gema2 amcl`: Nav2's AMCL (the pinned PyPI `amcl`, in the project's Python environment)
//! fed the scans, odometry and map that the sequential localizer gets, judged alike.

mod common;

use std::process::{Command, Output};

fn gema2(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_gema2")).args(args).output().expect("gema2 runs")
}

fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

/// The "every start" rows of the results section: (start, AMCL cell, gema2 cell).
fn starts(page: &str) -> Vec<(String, String, String)> {
    let every = page.split("Every start").nth(1).unwrap_or("");
    every
        .lines()
        .filter_map(|l| {
            let cells: Vec<&str> = l.trim_matches('|').split('|').map(str::trim).collect();
            (cells.len() == 4 && cells[1].parse::<usize>().is_ok())
                .then(|| (cells[1].to_string(), cells[2].to_string(), cells[3].to_string()))
        })
        .collect()
}

/// The located scans a cell says its localizer took to settle; `None` when it never did.
fn settled_after(cell: &str) -> Option<usize> {
    cell.split(" / ").next().and_then(|s| s.parse().ok())
}

/// AMCL started at the true pose must hold it from its first scans: this fails when the map
/// reaches it flipped or shifted, when the scan's angles or the odometry's frame are wrong, or
/// when the worker's replies are misread. The sequential localizer, from a cold start, must
/// settle as soon on the same scans.
#[test]
fn amcl_started_at_the_true_pose_holds_it_and_gema2_settles_as_soon() {
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("walk.log");
    let log = log.to_str().unwrap();
    let out = gema2(&["sim", "--map", "office", "--trajectory", "--scans", "80", "--seed", "3", "--out", log]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let page = dir.path().join("results.md");
    let python = common::python();
    let out = gema2(&[
        "amcl",
        "--log",
        log,
        "--map",
        "office",
        "--seeded",
        "--starts",
        "2",
        "--max-scans",
        "30",
        "--particles",
        "1000",
        "--min-particles",
        "200",
        "--python",
        python.to_str().unwrap(),
        "--markdown",
        page.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}\n{}", text(&out.stdout), text(&out.stderr));
    let page = std::fs::read_to_string(&page).unwrap();
    assert!(page.contains("<!-- BEGIN amcl -->"), "{page}");
    let rows = starts(&page);
    assert_eq!(rows.iter().map(|r| r.0.as_str()).collect::<Vec<_>>(), ["0", "40"], "{page}");
    for (start, amcl, ours) in &rows {
        assert!(settled_after(amcl).is_some_and(|n| n <= 3), "AMCL from {start}: {amcl}\n{page}");
        assert!(settled_after(ours).is_some_and(|n| n <= 3), "gema2 from {start}: {ours}\n{page}");
    }
}

/// A Python without the worker's packages is a clear error, not a table of nothing.
#[test]
fn a_python_that_cannot_run_amcl_is_a_clear_error() {
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("walk.log");
    let log = log.to_str().unwrap();
    let out = gema2(&["sim", "--map", "office", "--trajectory", "--scans", "12", "--out", log]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let out = gema2(&["amcl", "--log", log, "--map", "office", "--python", "/nonexistent/python3"]);
    assert!(!out.status.success());
    let err = text(&out.stderr);
    assert!(err.contains("/nonexistent/python3"), "{err}");
    let out = gema2(&["amcl", "--log", log, "--map", "office", "--python", "/bin/false"]);
    assert!(!out.status.success());
    assert!(text(&out.stderr).contains("AMCL worker"), "{}", text(&out.stderr));
}
