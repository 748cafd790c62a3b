//! The `gema2` command line, run as a user runs it.

mod common;

use std::path::Path;
use std::process::{Command, Output};

fn gema2(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_gema2")).args(args).output().expect("gema2 runs")
}

fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

#[test]
fn sim_then_locate_writes_the_design_csv_and_reports_accuracy() {
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("a.log");
    let csv = dir.path().join("a.csv");
    let log_s = log.to_str().unwrap();
    let out =
        gema2(&["sim", "--map", "apartment", "--scenario", "people", "--scans", "30", "--seed", "4", "--out", log_s]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let out = gema2(&["locate", "--map", "apartment", "--log", log_s, "--out", csv.to_str().unwrap()]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    // results on stdout, diagnostics on stderr
    let summary = text(&out.stdout);
    assert!(summary.contains("scans 30") && summary.contains("success") && summary.contains("median"), "{summary}");
    assert!(summary.contains("of the log's poses, taken as ground truth"), "{summary}");
    let rows: Vec<String> = std::fs::read_to_string(&csv).unwrap().lines().map(str::to_owned).collect();
    assert!(rows[0].starts_with("scan,x,y,theta,score,status,micros"), "{}", rows[0]);
    assert_eq!(rows.len(), 31);
    for (k, row) in rows[1..].iter().enumerate() {
        let cols: Vec<&str> = row.split(',').collect();
        assert_eq!(cols[0], k.to_string());
        assert!(["ok", "ambiguous", "failed"].contains(&cols[5]), "{row}");
        if cols[5] != "failed" {
            assert!(cols[1].parse::<f64>().is_ok() && cols[3].parse::<f64>().is_ok(), "{row}");
        }
    }
    // --every 3 --offset 1: scans 1, 4, 7, ...
    let out = gema2(&[
        "locate",
        "--map",
        "apartment",
        "--log",
        log_s,
        "--every",
        "3",
        "--offset",
        "1",
        "--out",
        csv.to_str().unwrap(),
    ]);
    assert!(out.status.success());
    let scans: Vec<String> = std::fs::read_to_string(&csv)
        .unwrap()
        .lines()
        .skip(1)
        .map(|l| l.split(',').next().unwrap().to_owned())
        .collect();
    assert_eq!(scans, (0..10).map(|k| (1 + 3 * k).to_string()).collect::<Vec<_>>());
    // --dump-scan makes its folder and writes that scan's segmentation and map as JSON
    let dump = dir.path().join("dumps").join("apartment");
    let out = gema2(&["locate", "--map", "apartment", "--log", log_s, "--dump-scan", "2", dump.to_str().unwrap()]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let json = std::fs::read_to_string(dump.join("scan2.json")).expect("scan 2 dumped");
    for key in ["\"points\"", "\"lines\"", "\"corners\"", "\"walls\""] {
        assert!(json.contains(key), "{key} missing");
    }
}

#[test]
fn a_malformed_map_is_rejected_naming_file_and_element() {
    let dir = tempfile::tempdir().unwrap();
    let map = dir.path().join("bad.json");
    std::fs::write(&map, r#"{"walls": [[0, 0, 1, 0], [1, 0, 1]]}"#).unwrap();
    let out = gema2(&["locate", "--map", map.to_str().unwrap(), "--log", "/dev/null"]);
    assert!(!out.status.success());
    let err = text(&out.stderr);
    assert!(err.contains("bad.json") && err.contains("walls[1]"), "{err}");
}

#[test]
fn a_malformed_log_line_is_rejected_naming_file_and_line() {
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("bad.log");
    let good = "FLASER 3 1.0 1.0 1.0 0 0 0 0 0 0 1 h 1\n";
    std::fs::write(&log, format!("PARAM a b\n{good}FLASER 3 1.0 x 1.0 0 0 0 0 0 0 1 h 1\n{good}")).unwrap();
    let csv = dir.path().join("bad.csv");
    let out = gema2(&["locate", "--map", "apartment", "--log", log.to_str().unwrap(), "--out", csv.to_str().unwrap()]);
    // the run fails, naming the line...
    assert!(!out.status.success());
    let err = text(&out.stderr);
    assert!(err.contains("skipped") && err.contains("bad.log:3") && err.contains("\"x\""), "{err}");
    assert!(err.contains("1 malformed laser line skipped"), "{err}");
    // ...but loses only that line's scan: the scans before and after it are located, written
    // and summed up, and the CSV keeps one row per laser line, the bad one `failed`
    assert!(text(&out.stdout).contains("scans 2 "), "{}", text(&out.stdout));
    let rows: Vec<String> = std::fs::read_to_string(&csv).unwrap().lines().skip(1).map(str::to_owned).collect();
    assert_eq!(rows.len(), 3, "{rows:?}");
    assert!(rows[0].starts_with("0,") && rows[2].starts_with("2,"), "{rows:?}");
    assert!(rows[1].starts_with("1,,,,,failed,"), "{rows:?}");
    // `lines` segments the scans around it the same way
    let out = gema2(&["lines", "--log", log.to_str().unwrap()]);
    assert!(!out.status.success());
    assert!(text(&out.stdout).contains("2 scans segmented") && text(&out.stderr).contains("bad.log:3"));
    // a bad line `--every` leaves out is no concern of the run
    let out = gema2(&["locate", "--map", "apartment", "--log", log.to_str().unwrap(), "--every", "2"]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    assert!(!text(&out.stderr).contains("malformed"), "{}", text(&out.stderr));
}

/// A log that cannot be read to its end (a gzip file cut short) ends the run there, with the
/// scans before it located and summed up.
#[test]
fn a_log_cut_short_ends_the_run_after_the_scans_before_it() {
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("cut.log");
    let out = gema2(&["sim", "--map", "apartment", "--scans", "40", "--out", log.to_str().unwrap()]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let mut gz = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::default());
    std::io::Write::write_all(&mut gz, &std::fs::read(&log).unwrap()).unwrap();
    let bytes = gz.finish().unwrap();
    let cut = dir.path().join("cut.log.gz");
    std::fs::write(&cut, &bytes[..bytes.len() / 2]).unwrap();
    let out = gema2(&["locate", "--map", "apartment", "--log", cut.to_str().unwrap()]);
    assert!(!out.status.success());
    let err = text(&out.stderr);
    assert!(err.contains("cut.log.gz") && err.contains("stopped there"), "{err}");
    assert!(text(&out.stdout).starts_with("scans "), "{}", text(&out.stdout));
}

#[test]
fn unknown_maps_and_missing_logs_are_clear_errors() {
    let out = gema2(&["locate", "--map", "no-such-map", "--log", "/dev/null"]);
    assert!(!out.status.success());
    assert!(text(&out.stderr).contains("no-such-map"));
    // a missing file is said once, not again under "Caused by"
    for (args, file) in [
        (&["locate", "--map", "office", "--log", "/no/such.log"][..], "/no/such.log"),
        (&["locate", "--map", "/no/map.json", "--log", "/dev/null"], "/no/map.json"),
        (&["locate", "--map", "/no/map.yaml", "--log", "/dev/null"], "/no/map.yaml"),
    ] {
        let out = Command::new(env!("CARGO_BIN_EXE_gema2")).args(args).env("RUST_BACKTRACE", "0").output().unwrap();
        let err = text(&out.stderr);
        assert!(!out.status.success() && err.contains(file), "{err}");
        assert_eq!(err.matches("No such file").count(), 1, "{err}");
    }
}

/// `map info` takes what `locate` takes: a bundled map's name or a file.
#[test]
fn map_info_reads_a_bundled_map_or_a_file() {
    let out = gema2(&["map", "info", "apartment"]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let walls = map::bundled("apartment").unwrap().unwrap().walls.len();
    assert!(text(&out.stdout).starts_with(&format!("apartment: {walls} walls, ")), "{}", text(&out.stdout));
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("radial.json");
    let out = gema2(&["map", "generate", "radial", "--out", file.to_str().unwrap()]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let out = gema2(&["map", "info", file.to_str().unwrap()]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    assert!(text(&out.stdout).contains("corners"), "{}", text(&out.stdout));
    let out = gema2(&["map", "info", "apartmnt"]);
    assert!(!out.status.success());
    assert!(
        text(&out.stderr).contains("\"apartmnt\"") && text(&out.stderr).contains("apartment"),
        "{}",
        text(&out.stderr)
    );
}

/// `map generate office-N` makes an office of about N walls; an N it cannot come near is said,
/// and a count that is no count is refused.
#[test]
fn an_office_of_n_walls_says_when_it_cannot_come_near_n() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("o.json");
    let f = file.to_str().unwrap();
    let out = gema2(&["map", "generate", "office-50", "--out", f]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    assert!(!text(&out.stderr).contains("asked"), "{}", text(&out.stderr));
    let out = gema2(&["map", "generate", "office-3", "--out", f]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let walls = mapio::load_map(f).unwrap().walls.len();
    assert!(walls > 3);
    assert!(text(&out.stderr).contains(&format!("3 asked: the nearest office the generator makes has {walls}")));
    for bad in ["office-0", "office-many", "office--5"] {
        let out = gema2(&["map", "generate", bad, "--out", f]);
        assert!(!out.status.success(), "{bad}");
        assert!(text(&out.stderr).contains("wall count"), "{bad}: {}", text(&out.stderr));
    }
}

/// `--set` is one vocabulary for `locate` and the pipeline's stages; a typo or a bad value is
/// refused before any work, naming the setting (and, for a typo, the known ones).
#[test]
fn bad_settings_are_refused_by_locate_and_the_stages() {
    for args in [
        &["locate", "--map", "office", "--log", "/dev/null", "--set", "screend=5"][..],
        &["stage", "localize", "--set", "screend=5"],
        &["stage", "segment", "--set", "screend=5"],
    ] {
        let out = gema2(args);
        assert!(!out.status.success(), "{args:?}");
        let err = text(&out.stderr);
        assert!(err.contains("unknown setting \"screend\"") && err.contains("gema2 settings"), "{args:?}: {err}");
        // the nearest key of the stage's own: the segment stage has no `screened`
        let segment = args[0] == "stage" && args[1] == "segment";
        assert_eq!(err.contains("(did you mean \"screened\"?)"), !segment, "{args:?}: {err}");
    }
    // a localization setting is not the segment stage's
    let out = gema2(&["stage", "segment", "--set", "screened=5"]);
    assert!(text(&out.stderr).contains("unknown setting \"screened\""), "{}", text(&out.stderr));
    let out = gema2(&["stage", "localize", "--set", "refined=-1"]);
    assert!(!out.status.success());
    assert!(text(&out.stderr).contains("refined: -1 is not a whole number"), "{}", text(&out.stderr));
}

/// Success compares with the log's poses and says so, and `--no-truth` turns the comparison
/// off: a user's odometry log once read 0.0 % success, exit 0, unexplained. Nothing in a CARMEN
/// log tells raw odometry from corrected poses (corrected logs overwrite the odometry too), so
/// `map build` says what its map rests on.
#[test]
fn success_says_what_it_compares_with_and_no_truth_turns_it_off() {
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("s.log");
    let out = gema2(&["sim", "--map", "apartment", "--scans", "12", "--seed", "3", "--out", log.to_str().unwrap()]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let locate = |extra: &[&str]| {
        let out = gema2(&[&["locate", "--map", "apartment", "--log", log.to_str().unwrap()][..], extra].concat());
        assert!(out.status.success(), "{}", text(&out.stderr));
        // progress is drawn on a terminal only: none of it in a pipe
        assert!(!text(&out.stderr).contains('\r') && !text(&out.stderr).contains('\u{1b}'), "{}", text(&out.stderr));
        text(&out.stdout)
    };
    let summary = locate(&[]);
    assert!(summary.contains("of the log's poses, taken as ground truth"), "{summary}");
    let summary = locate(&["--no-truth"]);
    assert!(summary.contains("scans 12") && !summary.contains("success"), "{summary}");
    let built = dir.path().join("built.json");
    let out = gema2(&["map", "build", "--log", log.to_str().unwrap(), "--out", built.to_str().unwrap()]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    assert!(text(&out.stderr).contains("taken as ground truth: the map is only as good"), "{}", text(&out.stderr));
}

/// A FLASER log of a sensor other than a SICK LMS (541 beams over 270 degrees, 30 m) is
/// located once the command line gives its layout, as well as the same scans in ROBOTLASER1;
/// read as the default 180 degrees, it is not.
#[test]
fn a_flaser_log_of_another_sensor_is_read_with_its_layout() {
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("wide.log");
    let args = ["sim", "--map", "apartment", "--scans", "12", "--beams", "541", "--fov", "270", "--range-max", "30"];
    let out = gema2(&[&args[..], &["--out", log.to_str().unwrap()]].concat());
    assert!(out.status.success(), "{}", text(&out.stderr));
    // the same scans as FLASER lines: n, ranges, the laser's pose twice, a timestamp
    let mut flaser = String::new();
    for line in std::fs::read_to_string(&log).unwrap().lines().filter(|l| l.starts_with("ROBOTLASER1")) {
        let f: Vec<&str> = line.split_whitespace().collect();
        let n: usize = f[8].parse().unwrap();
        let m: usize = f[9 + n].parse().unwrap();
        let pose = f[10 + n + m..13 + n + m].join(" ");
        flaser += &format!("FLASER {n} {} {pose} {pose} 0.0 h 0.0\n", f[9..9 + n].join(" "));
    }
    let flaser_log = dir.path().join("wide-flaser.log");
    std::fs::write(&flaser_log, flaser).unwrap();
    let success = |log: &Path, extra: &[&str]| {
        let out = gema2(&[&["locate", "--map", "apartment", "--log", log.to_str().unwrap()][..], extra].concat());
        assert!(out.status.success(), "{}", text(&out.stderr));
        number_after(&text(&out.stdout), "success ")
    };
    let layout = ["--flaser-fov", "270", "--flaser-range-max", "30"];
    assert_eq!(success(&flaser_log, &layout), success(&log, &[]));
    assert!(success(&flaser_log, &layout) >= 90.0);
    assert!(success(&flaser_log, &[]) < 50.0);
    let out = gema2(&["locate", "--map", "apartment", "--log", flaser_log.to_str().unwrap(), "--flaser-fov", "400"]);
    assert!(!out.status.success() && text(&out.stderr).contains("--flaser-fov 400"), "{}", text(&out.stderr));
}

/// Selections of no scan are errors naming the log, not empty reports that exit 0.
#[test]
fn a_selection_of_no_scan_is_an_error() {
    // a log of no scans, or an offset past its last, is no answer: an error naming the log
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("s.log");
    let out = gema2(&["sim", "--map", "office", "--scans", "3", "--out", log.to_str().unwrap()]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    for (file, offset) in [("/dev/null", "0"), (log.to_str().unwrap(), "3")] {
        let out = gema2(&["locate", "--map", "office", "--log", file, "--offset", offset]);
        assert!(!out.status.success(), "{file} --offset {offset}");
        let err = text(&out.stderr);
        assert!(err.contains(&format!("{file}: no laser scan located")), "{err}");
    }
    let out = gema2(&["lines", "--log", "/dev/null"]);
    assert!(!out.status.success() && text(&out.stderr).contains("/dev/null: no laser scan"), "{}", text(&out.stderr));
    let out = gema2(&["locate", "--map", "office", "--log", log.to_str().unwrap(), "--offset", "2"]);
    assert!(out.status.success() && text(&out.stdout).starts_with("scans 1 "), "{}", text(&out.stderr));
    // every 0th scan selects nothing: refused, not reported as an empty log
    for args in [
        &["locate", "--map", "office", "--log", "/dev/null", "--every", "0"][..],
        &["map", "build", "--log", "/dev/null", "--out", "/dev/null", "--every", "0"],
    ] {
        let out = gema2(args);
        assert!(!out.status.success(), "{args:?}");
        assert!(text(&out.stderr).contains("--every <EVERY>': must be at least 1"), "{}", text(&out.stderr));
    }
    let out = gema2(&["sim", "--map", "office", "--scans", "0", "--out", log.to_str().unwrap()]);
    assert!(!out.status.success() && text(&out.stderr).contains("must be at least 1"), "{}", text(&out.stderr));
    // measurements of nothing: bench and demo printed tables of NaN and exited 0
    for (args, why) in [
        (&["bench", "--scans", "0"][..], "must be at least 1"),
        (&["bench", "--rounds", "0"], "must be at least 1"),
        (&["bench", "--beams", "68,1"], "a scan needs at least 2 beams"),
        (&["bench", "--pipeline", "--seconds", "0"], "must be a number of seconds above 0"),
        (&["demo", "--scans", "0"], "must be at least 1"),
    ] {
        let out = gema2(args);
        assert!(!out.status.success() && text(&out.stderr).contains(why), "{args:?}: {}", text(&out.stderr));
    }
}

/// `gema2 bench` times every stage of the office scans in rounds, lists each round's median total
/// and shows the quietest round stage by stage.
#[test]
fn bench_lists_its_rounds_and_times_every_stage() {
    let out = gema2(&["bench", "--stages-only", "--scans", "4", "--rounds", "2"]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let table = text(&out.stdout);
    let rounds = table.lines().find(|l| l.contains("median total of each of 2 rounds")).expect("the rounds line");
    let totals: Vec<f64> = rounds
        .split(':')
        .nth(1)
        .and_then(|r| r.split(" us").next())
        .map(|r| r.split(" / ").filter_map(|t| t.trim().parse().ok()).collect())
        .unwrap_or_default();
    assert_eq!(totals.len(), 2, "{rounds}");
    let shown = table
        .lines()
        .find(|l| l.trim_start().starts_with("total") && l.contains("median"))
        .and_then(|l| l.split_whitespace().nth(2))
        .and_then(|t| t.parse::<f64>().ok())
        .expect("the total line");
    assert_eq!(shown, totals.iter().copied().fold(f64::INFINITY, f64::min), "{table}");
    for stage in ["line inference", "matching", "cost function"] {
        assert!(table.contains(stage), "{stage}: {table}");
    }
}

/// Options that cannot apply to the log are errors, after the scans are located and summed up:
/// `--dump-scan` of a scan not located wrote nothing and said nothing, `--diagnose` of a log
/// without truth printed no diagnosis and said nothing, and `--track 0` failed every scan after
/// the first `ok` one.
#[test]
fn locate_options_that_cannot_apply_are_errors() {
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("s.log");
    let log_s = log.to_str().unwrap();
    let out = gema2(&["sim", "--map", "office", "--scans", "6", "--out", log_s]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let dumps = dir.path().join("dumps");
    let dumps_s = dumps.to_str().unwrap();
    let out = gema2(&["locate", "--map", "office", "--log", log_s, "--every", "2", "--dump-scan", "4", dumps_s]);
    assert!(out.status.success() && dumps.join("scan4.json").is_file(), "{}", text(&out.stderr));
    for (n, why) in [("3", "--dump-scan 3: no such scan among the 3 located"), ("x", "N is a scan's index")] {
        let out = gema2(&["locate", "--map", "office", "--log", log_s, "--every", "2", "--dump-scan", n, dumps_s]);
        assert!(!out.status.success() && text(&out.stderr).contains(why), "{n}: {}", text(&out.stderr));
    }
    let out = gema2(&["locate", "--map", "office", "--log", log_s, "--track", "0"]);
    assert!(!out.status.success() && text(&out.stderr).contains("a radius in metres above 0"));
    let untrue = dir.path().join("untrue.log");
    let body = std::fs::read_to_string(&log).unwrap();
    std::fs::write(&untrue, format!("{}\n{body}", acquire::NO_TRUTH_MARKER)).unwrap();
    let out = gema2(&["locate", "--map", "office", "--log", untrue.to_str().unwrap(), "--diagnose"]);
    let err = text(&out.stderr);
    assert!(!out.status.success() && err.contains("holds no true pose, so there is nothing to diagnose"), "{err}");
    assert!(text(&out.stdout).starts_with("scans 6 "), "the summary is kept: {}", text(&out.stdout));
    // as --show of a scan past the log's end, which showed nothing and said nothing
    let out = gema2(&["lines", "--log", log_s, "--show", "6"]);
    let err = text(&out.stderr);
    assert!(!out.status.success() && err.contains("--show 6: the log holds 6 scans (0 to 5)"), "{err}");
    let out = gema2(&["lines", "--log", log_s, "--show", "5"]);
    assert!(out.status.success() && text(&out.stdout).contains("scan 5: "), "{}", text(&out.stderr));
}

/// A sensor other than the URG-04LX: a SICK-like 180-degree, 361-beam, 30 m scanner. The log
/// says so (ROBOTLASER1's start angle, field of view, resolution and maximum range), and
/// `locate` reads that layout back and localizes with it.
#[test]
fn sim_simulates_another_field_of_view_and_reach() {
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("sick.log");
    let log_s = log.to_str().unwrap();
    let args = ["sim", "--map", "apartment", "--scans", "30", "--seed", "2", "--beams", "361", "--fov", "180"];
    let out = gema2(&[&args[..], &["--range-max", "30", "--noise-proportional", "0", "--out", log_s]].concat());
    assert!(out.status.success(), "{}", text(&out.stderr));
    let body = std::fs::read_to_string(&log).unwrap();
    let line = body.lines().find(|l| l.starts_with("ROBOTLASER1")).expect("a laser line");
    let f: Vec<f64> = line.split_whitespace().skip(2).take(7).map(|t| t.parse().unwrap()).collect();
    let (start, fov, resolution, max_range, readings) = (f[0], f[1], f[2], f[3], f[6]);
    assert!((start + std::f64::consts::FRAC_PI_2).abs() < 1e-6, "{line}");
    assert!((fov - std::f64::consts::PI).abs() < 1e-6 && (resolution - 0.5f64.to_radians()).abs() < 1e-9);
    assert_eq!((max_range, readings), (30.0, 361.0));
    let out = gema2(&["locate", "--map", "apartment", "--log", log_s]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let err = text(&out.stdout);
    let success: f64 = err.split("success ").nth(1).and_then(|s| s.split(' ').next()).unwrap().parse().unwrap();
    assert!(success >= 80.0, "{err}");

    for (flag, value) in [("--fov", "0"), ("--fov", "400"), ("--range-max", "nan"), ("--beams", "1")] {
        let out = gema2(&["sim", "--map", "apartment", "--scans", "1", flag, value, "--out", log_s]);
        assert!(!out.status.success() && text(&out.stderr).contains(flag), "{flag} {value}: {}", text(&out.stderr));
    }
}

/// `map build` keeps the free space its scans saw beside the walls: every pose it was built
/// from lies in it, the space beyond the building's walls does not, and `locate` reads it.
#[test]
fn a_built_map_keeps_the_free_space_its_scans_saw() {
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("survey.log");
    let built = dir.path().join("built.json");
    let log_s = log.to_str().unwrap();
    let out = gema2(&["sim", "--map", "apartment", "--scans", "60", "--seed", "3", "--out", log_s]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let out = gema2(&["map", "build", "--log", log_s, "--every", "1", "--out", built.to_str().unwrap()]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let map = map::WallMap::load(&built).expect("the built map loads");
    let seen = map.seen_free.as_ref().expect("a built map says where its scans saw free space");
    let reader = acquire::CarmenReader::open(&log, acquire::FlaserLayout::default()).unwrap();
    for item in reader {
        let truth = item.unwrap().scan.truth.expect("simulated logs hold the truth");
        assert!(seen.contains(nalgebra::Point2::from(truth.translation.vector)), "{truth:?}");
    }
    let (lo, hi) = map::bundled("apartment").unwrap().unwrap().bounds();
    for q in [lo - nalgebra::Vector2::new(0.5, 0.5), hi + nalgebra::Vector2::new(0.5, 0.5)] {
        assert!(!seen.contains(q), "{q} lies beyond the building's walls");
    }
    let out = gema2(&["locate", "--map", built.to_str().unwrap(), "--log", log_s]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    assert!(text(&out.stdout).contains("success"), "{}", text(&out.stdout));
    let out = gema2(&["map", "build", "--log", log_s, "--seen-cell", "0", "--out", built.to_str().unwrap()]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    assert!(map::WallMap::load(&built).unwrap().seen_free.is_none());
}

/// A malformed laser line in a survey is left out of the map, not the end of it: the map is
/// built from the other scans and written, as it would be without that line, and the run
/// fails naming the line. With `--grid` too, and in `evaluate --carmen`.
#[test]
fn a_survey_with_a_malformed_line_builds_its_map_from_the_other_scans() {
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("survey.log");
    let log_s = log.to_str().unwrap();
    let out = gema2(&["sim", "--map", "apartment", "--scans", "40", "--seed", "5", "--out", log_s]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let whole = std::fs::read_to_string(&log).unwrap();
    let lines: Vec<&str> = whole.lines().collect();
    let tenth = lines.iter().enumerate().filter(|(_, l)| l.starts_with("ROBOTLASER1")).nth(9).unwrap().0;
    // the same survey without that scan, and with it garbled
    let without: Vec<&str> = lines.iter().enumerate().filter(|&(k, _)| k != tenth).map(|(_, l)| *l).collect();
    let mut garbled = lines.clone();
    garbled[tenth] = "ROBOTLASER1 0 -2.0 nonsense";
    let (clean, bad) = (dir.path().join("without.log"), dir.path().join("garbled.log"));
    std::fs::write(&clean, without.join("\n") + "\n").unwrap();
    std::fs::write(&bad, garbled.join("\n") + "\n").unwrap();
    let (from_clean, from_bad) = (dir.path().join("a.json"), dir.path().join("b.json"));
    let grid = dir.path().join("b.yaml");
    let build = |log: &std::path::Path, out: &std::path::Path, extra: &[&str]| {
        let mut args =
            vec!["map", "build", "--log", log.to_str().unwrap(), "--every", "1", "--out", out.to_str().unwrap()];
        args.extend_from_slice(extra);
        gema2(&args)
    };
    let out = build(&clean, &from_clean, &[]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let out = build(&bad, &from_bad, &["--grid", grid.to_str().unwrap()]);
    assert!(!out.status.success());
    let err = text(&out.stderr);
    assert!(err.contains(&format!("garbled.log:{}:", tenth + 1)) && err.contains("1 malformed laser line"), "{err}");
    assert_eq!(
        std::fs::read_to_string(&from_clean).unwrap(),
        std::fs::read_to_string(&from_bad).unwrap(),
        "the map of the survey without the line"
    );
    assert!(grid.exists(), "{err}");
    // `evaluate --carmen` reads the log, then builds each half's map from it again: the line
    // is reported once, and the table is printed before the run fails
    let carmen = dir.path().join("carmen");
    std::fs::create_dir(&carmen).unwrap();
    std::fs::copy(&bad, carmen.join("garbled.log")).unwrap();
    let out = gema2(&["evaluate", "--no-sim", "--carmen", carmen.to_str().unwrap()]);
    assert!(!out.status.success());
    let err = text(&out.stderr);
    assert_eq!(
        err.matches(&format!("garbled.log:{}:", tenth + 1)).count(),
        2,
        "named when met, and in the error: {err}"
    );
    assert!(err.contains("1 malformed laser line skipped"), "{err}");
    assert!(text(&out.stdout).contains("garbled odd") && text(&out.stdout).contains("garbled even"));
}

/// The share of `walls`' length (sampled every 5 cm) lying within 0.1 m of one of `others`.
fn share_within(walls: &[map::Wall], others: &[map::Wall]) -> f64 {
    let (mut near, mut all) = (0, 0);
    for w in walls {
        let steps = (w.length() / 0.05).ceil().max(1.0) as usize;
        for k in 0..=steps {
            let p = w.a + (w.b - w.a) * (k as f64 / steps as f64);
            all += 1;
            near += others.iter().any(|o| o.closest(p).0 < 0.1) as usize;
        }
    }
    near as f64 / all as f64
}

/// `map build` from a survey with people walking about: the people, seen through by the
/// scans before and after, leave nothing in the map, while the walls seen by a single scan
/// (door jambs, the ends of rooms) stay. The line-clustering builder alone (`--occupancy-cell
/// 0`, walls seen twice) drew 96.9 % of its walls on the plan and 84.0 % of the plan.
#[test]
fn a_map_built_among_people_draws_the_walls_and_not_the_people() {
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("survey.log");
    let built = dir.path().join("built.json");
    let log_s = log.to_str().unwrap();
    let out =
        gema2(&["sim", "--map", "apartment", "--scenario", "people", "--scans", "60", "--seed", "3", "--out", log_s]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let plan = map::bundled("apartment").unwrap().unwrap().walls;
    let mut shares = Vec::new();
    for cell in ["0.05", "0"] {
        let out = gema2(&[
            "map",
            "build",
            "--log",
            log_s,
            "--every",
            "1",
            "--occupancy-cell",
            cell,
            "--out",
            built.to_str().unwrap(),
        ]);
        assert!(out.status.success(), "{}", text(&out.stderr));
        let walls = map::WallMap::load(&built).unwrap().walls;
        shares.push((share_within(&walls, &plan), share_within(&plan, &walls)));
    }
    let [(on_plan, of_plan), (old_on_plan, old_of_plan)] = shares[..] else { unreachable!() };
    assert!(
        on_plan > 0.98 && of_plan > 0.86,
        "{:.3} of the map on the plan, {:.3} of the plan drawn",
        on_plan,
        of_plan
    );
    assert!(on_plan > old_on_plan && of_plan > old_of_plan, "{shares:?}");
    for (flag, value) in [("--occupancy-cell", "nan"), ("--occupancy-cell", "-1"), ("--min-length", "-0.1")] {
        let out =
            gema2(&["map", "build", "--log", log_s, &format!("{flag}={value}"), "--out", built.to_str().unwrap()]);
        assert!(!out.status.success() && text(&out.stderr).contains(flag), "{flag} {value}: {}", text(&out.stderr));
    }
}

/// The first number after `label` in `text`.
fn number_after(text: &str, label: &str) -> f64 {
    let rest = &text[text.find(label).unwrap_or_else(|| panic!("no {label:?} in {text}")) + label.len()..];
    rest.split_whitespace()
        .next()
        .and_then(|w| w.trim_end_matches(',').parse().ok())
        .unwrap_or_else(|| panic!("no number after {label:?}"))
}

#[test]
fn evaluate_gives_what_sim_then_locate_gives() {
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("a.log");
    let log_s = log.to_str().unwrap();
    // furnished warehouse: the hardest log, where a difference would show
    let sim = ["sim", "--map", "warehouse", "--scenario", "furniture", "--scans", "20", "--seed", "4", "--out", log_s];
    let out = gema2(&sim);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let out = gema2(&["locate", "--map", "warehouse", "--log", log_s]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let located = text(&out.stdout);
    let out = gema2(&["evaluate", "--scans", "20", "--seed", "4", "--map-seeds"]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let table = text(&out.stdout);
    // four bundled maps, three scenarios each
    assert!(table.contains("total: 12 logs, 240 scans"), "{table}");
    let row: Vec<&str> =
        table.lines().find(|l| l.starts_with("warehouse furniture")).unwrap().split_whitespace().collect();
    assert_eq!(row[2], "20", "{row:?}");
    assert_eq!(row[3].parse::<f64>().ok(), Some(number_after(&located, "success")), "{row:?} {located}");
    assert_eq!(row[5].parse::<f64>().ok(), Some(number_after(&located, "status: ok")), "{row:?} {located}");
}

#[test]
fn evaluate_locates_each_half_of_a_real_log_against_a_map_of_the_other() {
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("hall.log");
    let out = gema2(&["sim", "--map", "radial", "--scans", "40", "--seed", "2", "--out", log.to_str().unwrap()]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let out = gema2(&["evaluate", "--no-sim", "--carmen", dir.path().to_str().unwrap()]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let table = text(&out.stdout);
    assert!(table.contains("hall odd") && table.contains("hall even"), "{table}");
    assert!(table.contains("total: 2 logs, 40 scans"), "{table}");
    // 20 scans of a room map well enough to find most of the other 20 in it
    assert!(number_after(&table, "successes (") >= 50.0, "{table}");
    // the log itself in place of its folder: the same rows
    let out = gema2(&["evaluate", "--no-sim", "--carmen", log.to_str().unwrap()]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    // the counts, not the times
    let total =
        |t: &str| t.lines().find(|l| l.starts_with("total:")).and_then(|l| l.split(", mean").next()).map(str::to_owned);
    assert_eq!(total(&text(&out.stdout)), total(&table), "{}", text(&out.stdout));
    let notes = dir.path().join("notes.txt");
    std::fs::write(&notes, "not a log").unwrap();
    for (path, said) in
        [(notes, "neither a folder nor a CARMEN log"), (dir.path().join("gone.log"), "no such folder or log")]
    {
        let out = gema2(&["evaluate", "--no-sim", "--carmen", path.to_str().unwrap()]);
        assert!(!out.status.success() && text(&out.stderr).contains(said), "{}", text(&out.stderr));
    }
    // and through the grids of the same halves
    let out = gema2(&["evaluate", "--no-sim", "--grids", "--carmen", dir.path().to_str().unwrap()]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let table = text(&out.stdout);
    assert!(table.contains("hall odd grid") && table.contains("total: 4 logs, 80 scans"), "{table}");
    let out = gema2(&["evaluate", "--grids"]);
    assert!(!out.status.success() && text(&out.stderr).contains("give --carmen too"), "{}", text(&out.stderr));

    let empty = tempfile::tempdir().unwrap();
    let out = gema2(&["evaluate", "--no-sim", "--carmen", empty.path().to_str().unwrap()]);
    assert!(!out.status.success());
    assert!(text(&out.stderr).contains("no CARMEN log"), "{}", text(&out.stderr));
    let out = gema2(&["evaluate", "--no-sim"]);
    assert!(!out.status.success());
    assert!(text(&out.stderr).contains("nothing to evaluate"), "{}", text(&out.stderr));
    let out = gema2(&["evaluate", "--scans", "0"]);
    assert!(!out.status.success());
    assert!(text(&out.stderr).contains("--scans must be at least 1"), "{}", text(&out.stderr));
}

#[test]
fn a_ros_map_of_a_plan_localizes_its_scans() {
    let dir = tempfile::tempdir().unwrap();
    let p = |name: &str| dir.path().join(name).to_str().unwrap().to_owned();
    // the apartment with walls 12 cm thick, as a grid of 5 cm cells: faces where the laser sees them
    let out = gema2(&["map", "thicken", "apartment", "--out", &p("thick.json")]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let out = gema2(&["map", "export-ros", "--map", &p("thick.json"), "--out", &p("grid.yaml")]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    assert!(std::fs::read(p("grid.pgm")).unwrap().starts_with(b"P5"));
    let sim = [
        "sim",
        "--map",
        &p("thick.json"),
        "--scenario",
        "people",
        "--scans",
        "40",
        "--seed",
        "2",
        "--out",
        &p("a.log"),
    ];
    let out = gema2(&sim);
    assert!(out.status.success(), "{}", text(&out.stderr));
    // --map takes the YAML file as it is: a plan drawn into a grid is not rough
    let out = gema2(&["locate", "--map", &p("grid.yaml"), "--log", &p("a.log")]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    assert!(!text(&out.stderr).contains("rough grid"), "{}", text(&out.stderr));
    let err = text(&out.stdout);
    assert!(number_after(&err, "success") >= 85.0, "{err}");
    // import-ros writes the same walls as a JSON map, with the free space the grid shows
    let out = gema2(&["map", "import-ros", &p("grid.yaml"), "--out", &p("grid.json")]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let said = text(&out.stderr);
    assert!(said.contains("pieces under 10 cells") && !said.contains("--sigma 0.1"), "{said}");
    // the same grid cluttered with blobs of 3 x 3 cells, as a SLAM map's noise: rough, and
    // both commands say what makes it approximate
    let mut grid = mapio::OccupancyGrid::load(Path::new(&p("grid.yaml"))).unwrap();
    let (w, h) = (grid.width, grid.height);
    for r in (10..h.saturating_sub(10)).step_by(15) {
        for c in (10..w.saturating_sub(10)).step_by(15) {
            for k in 0..9 {
                grid.cells[(r + k / 3) * w + c + k % 3] = mapio::ros::Cell::Occupied;
            }
        }
    }
    grid.save(Path::new(&p("rough.yaml"))).unwrap();
    // a rough grid's walls are built from a virtual laser's scans, approximate as a built
    // map's; both commands say so
    let out = gema2(&["map", "import-ros", &p("rough.yaml"), "--out", &p("rough.json")]);
    let said = text(&out.stderr);
    assert!(
        out.status.success() && said.contains("scans of a virtual laser") && said.contains("accuracy 0.1 m"),
        "{said}"
    );
    let out = gema2(&["locate", "--map", &p("rough.yaml"), "--log", &p("a.log"), "--every", "10"]);
    let said = text(&out.stderr);
    assert!(out.status.success() && said.contains("is a rough grid") && said.contains("virtual laser"), "{said}");
    // traced instead, it is taken as exact, and --sigma is suggested
    let out = gema2(&["map", "import-ros", &p("rough.yaml"), "--trace", "--out", &p("rough.json")]);
    assert!(out.status.success() && text(&out.stderr).contains("--sigma 0.1"), "{}", text(&out.stderr));
    let trace = ["map", "import-ros", &p("rough.yaml"), "--trace", "--sigma", "0.1", "--out", &p("rough.json")];
    let out = gema2(&trace);
    assert!(out.status.success() && !text(&out.stderr).contains("--sigma 0.1"), "{}", text(&out.stderr));
    let out = gema2(&["locate", "--map", &p("rough.json"), "--log", &p("a.log"), "--every", "10"]);
    assert!(out.status.success() && !text(&out.stderr).contains("rough grid"), "{}", text(&out.stderr));
    // --trace and --survey are either-or
    let both = ["map", "import-ros", &p("rough.yaml"), "--trace", "--survey", "--out", &p("x.json")];
    assert!(!gema2(&both).status.success());
    let out = gema2(&["map", "info", &p("grid.json")]);
    let info = text(&out.stdout);
    assert!(info.contains("accuracy (sigma) 0.025 m") && info.contains("free space seen"), "{info}");
    // a broken YAML file is refused naming the file and the line
    std::fs::write(p("bad.yaml"), "image: grid.pgm\nresolution: 0.05\norigin: [0, 0]\n").unwrap();
    let out = gema2(&["locate", "--map", &p("bad.yaml"), "--log", &p("a.log")]);
    let err = text(&out.stderr);
    assert!(!out.status.success() && err.contains("bad.yaml: line 3: origin must be [x, y, yaw]"), "{err}");
}

#[test]
fn a_survey_grid_of_a_log_locates_the_scans_it_was_not_built_from() {
    let dir = tempfile::tempdir().unwrap();
    let p = |name: &str| dir.path().join(name).to_str().unwrap().to_owned();
    let out = gema2(&["sim", "--map", "apartment", "--scans", "80", "--seed", "5", "--out", &p("survey.log")]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    // even scans into a grid (and a wall map), odd scans located on the grid
    let build = ["map", "build", "--log", &p("survey.log"), "--grid", &p("grid.yaml"), "--out", &p("built.json")];
    let out = gema2(&build);
    assert!(out.status.success() && text(&out.stderr).contains("grid.yaml: a "), "{}", text(&out.stderr));
    let grid = mapio::OccupancyGrid::load(Path::new(&p("grid.yaml"))).unwrap();
    assert!(grid.cells.contains(&mapio::ros::Cell::Occupied) && grid.cells.contains(&mapio::ros::Cell::Free));
    let out = gema2(&["locate", "--map", &p("grid.yaml"), "--log", &p("survey.log"), "--every", "2", "--offset", "1"]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let err = text(&out.stdout);
    assert!(number_after(&err, "success") >= 80.0, "{err}");
    let out = gema2(&[
        "map",
        "build",
        "--log",
        &p("survey.log"),
        "--grid",
        &p("g.yaml"),
        "--grid-cell",
        "0",
        "--out",
        &p("b.json"),
    ]);
    assert!(!out.status.success() && text(&out.stderr).contains("--grid-cell"), "{}", text(&out.stderr));
}

#[test]
fn a_closed_stdout_ends_a_command_quietly() {
    // as `gema2 map info office | head -0` does: the reader is gone before the first line
    let mut child = Command::new(env!("CARGO_BIN_EXE_gema2"))
        .args(["map", "info", "office"])
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("gema2 runs");
    drop(child.stdout.take());
    let out = child.wait_with_output().unwrap();
    let err = text(&out.stderr);
    assert!(!err.contains("panicked") && out.status.code() != Some(101), "{:?} {err}", out.status);
}

/// `docs/results.md` is written by the commands that measure it: `evaluate --markdown` and
/// `bench --markdown` each replace their own section, name the command that made it, and keep
/// the other's.
#[test]
fn evaluate_and_bench_write_their_own_sections_of_the_results_page() {
    let dir = tempfile::tempdir().unwrap();
    let page = dir.path().join("results.md");
    let page_s = page.to_str().unwrap();
    let out = gema2(&["evaluate", "--scans", "4", "--map-seeds", "--markdown", page_s]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let first = std::fs::read_to_string(&page).unwrap();
    assert!(first.starts_with("# Measured results"), "{first}");
    assert!(first.contains("<!-- BEGIN evaluate -->\n`gema2 evaluate --scans 4 --map-seeds --markdown"), "{first}");
    assert!(first.contains("| apartment clean | 4 |") && first.contains("| warehouse furniture | 4 |"), "{first}");
    assert!(first.contains("total: 12 logs, 48 scans"), "{first}");
    // the console table says the same, with the searches each log ran
    assert!(text(&out.stdout).contains("ok prec") && text(&out.stdout).contains("searches"));
    let out = gema2(&["bench", "--stages-only", "--scans", "3", "--rounds", "1", "--markdown", page_s]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let both = std::fs::read_to_string(&page).unwrap();
    assert!(both.contains("<!-- BEGIN bench -->\n`gema2 bench --stages-only"), "{both}");
    assert!(both.contains("line inference (Codes 1-2)"), "{both}");
    let evaluate_section =
        |t: &str| t[t.find("<!-- BEGIN evaluate").unwrap()..t.find("<!-- END evaluate").unwrap()].to_owned();
    assert_eq!(evaluate_section(&first), evaluate_section(&both));
    // again: the section is replaced, not added
    let out = gema2(&["bench", "--stages-only", "--scans", "3", "--rounds", "1", "--markdown", page_s]);
    assert!(out.status.success());
    assert_eq!(std::fs::read_to_string(&page).unwrap().matches("<!-- BEGIN bench -->").count(), 1);
}

/// CI's floor on real data: freiburg-101 from `../shared/datasets/carmen` (read in place,
/// through a link), each half located against a map built from the other, as `gema2 evaluate
/// --carmen` does. Today both ways give 100 % success with 75-78 `ok`, all right; a change that
/// costs more than a few scans, or makes the localizer answer `ok` wrongly or less often, fails
/// the build; so does one that makes the sequential localizer slower to be sure or wrong.
/// Without the shared data the test says it was skipped (`.ci/run` lists it).
#[test]
fn a_real_log_keeps_its_success_and_ok_precision() {
    let Some(dir) = shared_carmen_log("a_real_log_keeps_its_success_and_ok_precision", "freiburg-101-corrected") else {
        return;
    };
    let out = gema2(&["evaluate", "--no-sim", "--carmen", dir.path().to_str().unwrap()]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let table = text(&out.stdout);
    for way in ["odd", "even"] {
        holds_floor(&table, &format!("freiburg-101-corrected {way}"), 146, 97.0, 60.0);
    }
    // the sequential localizer on its odd scans, odometry drawn as issue 48 draws it: today
    // every start fixed within 3 scans (the median on its first), no wrong ok, 98.6 % right
    // after the first fix
    let row = sequential_row(dir.path(), "freiburg-101-corrected");
    assert_eq!(row[3], "1", "the median start is not sure on its first scan: {row:?}");
    assert!(percent(&row[4], &row) >= 80.0, "fewer starts fixed within 3 scans: {row:?}");
    assert!(row[5].starts_with("0 "), "a wrong ok: {row:?}");
    assert!(percent(&row[6], &row) >= 97.0, "fewer right poses after the first fix: {row:?}");
}

/// CI's floor through a SLAM-like grid: edmonton from `../shared/datasets/carmen`, each half
/// located through the occupancy grid `map build --grid` draws of the other (`gema2 evaluate
/// --grids`). Its grid is rough (88 % of the traced wall length in short pieces), so its walls
/// are built from a virtual survey; today 92.4 / 91.2 % success and 87 `ok` each way, all
/// right. Traced face by face the same grids gave 30 / 29 %: a change that loses the survey,
/// or costs more than a few scans, or answers `ok` wrongly, fails the build.
#[test]
fn a_real_slam_grid_keeps_its_success_and_ok_precision() {
    let Some(dir) = shared_carmen_log("a_real_slam_grid_keeps_its_success_and_ok_precision", "edmonton-corrected")
    else {
        return;
    };
    let out = gema2(&["evaluate", "--no-sim", "--grids", "--carmen", dir.path().to_str().unwrap()]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let table = text(&out.stdout);
    for way in ["odd", "even"] {
        holds_floor(&table, &format!("edmonton-corrected {way} grid"), 170, 85.0, 70.0);
    }
}

/// The row of `evaluate`'s `table` named `label` (its first words) has `scans` scans, at least
/// `success` % of them right, at least `ok` answered `ok`, and 99 % of those right.
fn holds_floor(table: &str, label: &str, scans: usize, success: f64, ok: f64) {
    let words = label.split_whitespace().count();
    let row: Vec<&str> = table
        .lines()
        .find(|l| l.starts_with(&format!("{label} ")))
        .unwrap_or_else(|| panic!("no {label:?} in {table}"))
        .split_whitespace()
        .skip(words)
        .collect();
    // scans success % ok wrong ...
    let number = |v: &str| v.parse::<f64>().unwrap_or_else(|_| panic!("{v:?} in {row:?} of {label}"));
    assert_eq!(row[0], scans.to_string(), "{label}: {row:?}");
    assert!(number(row[1]) >= success, "{label}: success fell: {row:?}");
    assert!(number(row[3]) >= ok, "{label}: fewer scans are ok: {row:?}");
    assert!(number(row[4]) <= 0.01 * number(row[3]), "{label}: ok precision fell below 99 %: {row:?}");
}

/// A folder linking `name.log.gz` from `../shared/datasets/carmen` (read in place, never
/// copied), or none, with the test `test` said to be skipped, when the shared data is not there.
fn shared_carmen_log(test: &str, name: &str) -> Option<tempfile::TempDir> {
    let file = format!("{name}.log.gz");
    let log = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/datasets/carmen").join(&file);
    if !log.is_file() {
        common::skipped(test, &format!("{} is not there", log.display()));
        return None;
    }
    let dir = tempfile::tempdir().unwrap();
    std::os::unix::fs::symlink(&log, dir.path().join(file)).unwrap();
    Some(dir)
}

/// A table cell such as `97.8 %`, or `97.8 % (...)`, as a number.
fn percent(cell: &str, row: &[String]) -> f64 {
    let number = cell.split(" %").next().unwrap_or(cell);
    number.parse().unwrap_or_else(|_| panic!("{cell:?} in {row:?}"))
}

/// `gema2 evaluate --sequential`'s row for `log` in `dir`: odometry drawn as issue 48 draws it
/// (noise 0.05, 0.01, 0.05, 0.01, seed 1), a cold start every 25 located scans. The columns:
/// log | scans | starts | median to fix | fixed within 3 | wrong ok | right after fix | ...
fn sequential_row(dir: &Path, log: &str) -> Vec<String> {
    let out = gema2(&[
        "evaluate",
        "--no-sim",
        "--carmen",
        dir.to_str().unwrap(),
        "--sequential",
        "--odom-noise",
        "0.05,0.01,0.05,0.01",
        "--restart-every",
        "25",
    ]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let table = text(&out.stdout);
    let label = format!("{log} |");
    table
        .lines()
        .find(|l| l.starts_with(&label))
        .unwrap_or_else(|| panic!("no sequential row for {log} in {table}"))
        .split('|')
        .map(|c| c.trim().to_string())
        .collect()
}

/// The sequential localizer on edmonton (`../shared/datasets/carmen`, read in place through a
/// link), map from the even scans. Its drawn odometry is often off by more than the window
/// about the prediction spans: the second look about where the first refined to keeps the
/// track right (98.7 % of the poses after the first fix today; 93.6 % without it, the first
/// look stopping 0.4-0.8 m short). Without the shared data the test says it was skipped.
#[test]
fn a_track_whose_odometry_is_off_past_the_window_stays_right_on_a_real_log() {
    let test = "a_track_whose_odometry_is_off_past_the_window_stays_right_on_a_real_log";
    let Some(dir) = shared_carmen_log(test, "edmonton-corrected") else { return };
    let row = sequential_row(dir.path(), "edmonton-corrected");
    assert!(row[5].starts_with("0 "), "a wrong ok: {row:?}");
    assert!(percent(&row[6], &row) >= 97.0, "fewer right poses after the first fix: {row:?}");
}

/// `evaluate --sequential` walks a robot through each map of the suite, every scenario, 0.2
/// and 0.8 m a scan, and gives each walk the row a CARMEN log gets; a walk's row equals `gema2
/// sim --trajectory` then `gema2 locate --sequential` on the same map and seeds.
#[test]
fn evaluate_sequential_walks_the_simulated_maps() {
    let dir = tempfile::tempdir().unwrap();
    let page = dir.path().join("results.md");
    let noise = "0.05,0.01,0.05,0.01";
    let args = ["evaluate", "--sequential", "--scans", "30", "--map-seeds", "--odom-noise", noise, "--seed", "2"];
    let out = gema2(&args.iter().copied().chain(["--markdown", page.to_str().unwrap()]).collect::<Vec<_>>());
    assert!(out.status.success(), "{}", text(&out.stderr));
    let table = text(&out.stdout);
    let rows: Vec<&str> = table.lines().filter(|l| l.contains(" m | 30 |")).collect();
    assert_eq!(rows.len(), 24, "{table}");
    let row = |name: &str| -> Vec<String> {
        let label = format!("{name} | 30 |");
        let line = rows.iter().find(|l| l.starts_with(&label)).unwrap_or_else(|| panic!("no {name} in {table}"));
        line.split('|').map(|c| c.trim().to_string()).collect()
    };
    let furnished = row("office furniture 0.8 m");
    let log = dir.path().join("walk.log");
    let sim = ["sim", "--map", "office", "--scenario", "furniture", "--trajectory", "--step", "0.8"];
    let rest = ["--odom-noise", noise, "--seed", "2", "--scans", "30", "--out", log.to_str().unwrap()];
    let out = gema2(&sim.iter().chain(&rest).copied().collect::<Vec<_>>());
    assert!(out.status.success(), "{}", text(&out.stderr));
    let out =
        gema2(&["locate", "--map", "office", "--log", log.to_str().unwrap(), "--sequential", "--out", "/dev/null"]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let said = text(&out.stdout);
    let after = said.split("right after the first fix (within 0.3 m and 5 deg) ").nth(1).unwrap_or_default();
    let percent_of_locate: f64 = after.split(" %").next().unwrap_or_default().parse().unwrap_or(f64::NAN);
    assert!((percent(&furnished[6], &furnished) - percent_of_locate).abs() < 0.06, "{furnished:?}\n{said}");
    let page = std::fs::read_to_string(&page).unwrap();
    assert!(
        page.contains("### simulated walks of 30 scans") && page.contains("| apartment clean 0.2 m | 30 |"),
        "{page}"
    );
}

/// Where a track's window misses a turn, the near look and the look along can both refine to
/// the right pose; the near look's word that no rival lies within the gate then stands, and
/// the track takes that pose on that scan. Walking the clean apartment 0.8 m a scan (seed 1),
/// the look along found the near look's pose a hair cheaper on the 25th scan, unsure, and the
/// track kept a pose 0.6 m off for that scan.
#[test]
fn two_looks_on_one_pose_keep_the_near_look_s_word() {
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("walk.log");
    let log_s = log.to_str().unwrap();
    let walk = ["--trajectory", "--step", "0.8", "--odom-noise", "0.05,0.01,0.05,0.01", "--seed", "1"];
    let sim = ["sim", "--map", "apartment", "--scans", "40", "--out", log_s];
    let out = gema2(&sim.iter().chain(&walk).copied().collect::<Vec<_>>());
    assert!(out.status.success(), "{}", text(&out.stderr));
    let out = gema2(&["locate", "--map", "apartment", "--log", log_s, "--sequential", "--out", "/dev/null"]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let said = text(&out.stdout);
    let after = said
        .split("right after the first fix (within 0.3 m and 5 deg) ")
        .nth(1)
        .unwrap_or_else(|| panic!("no right after the first fix in {said}"));
    assert!(after.starts_with("100.00 %"), "{said}");
}

/// `evaluate --sequential --kidnaps N` splices stretches of a walked log from places 10 m
/// apart, and names each splice that missed a bar (an `ok` on the old place after the second
/// scan, or no right `ok` within 5) on a line of its own under the log's row: as many lines
/// as the kidnap column's counts leave out.
#[test]
fn kidnaps_are_counted_and_each_missed_splice_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("walk.log");
    let log_s = log.to_str().unwrap();
    // furniture the map lacks: today 1 of 4 splices finds a right `ok` within 5 scans
    let sim = [
        "sim",
        "--map",
        "warehouse",
        "--scenario",
        "furniture",
        "--seed",
        "3",
        "--trajectory",
        "--step",
        "0.5",
        "--scans",
        "160",
    ];
    let out = gema2(&sim.iter().copied().chain(["--out", log_s]).collect::<Vec<_>>());
    assert!(out.status.success(), "{}", text(&out.stderr));
    let out = gema2(&["evaluate", "--no-sim", "--carmen", log_s, "--sequential", "--kidnaps", "4"]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let table = text(&out.stdout);
    let row = table.lines().find(|l| l.starts_with("walk |")).unwrap_or_else(|| panic!("no row: {table}"));
    // "last ok on the old place / wrong ok after the cut / right ok within 5"
    let cell = row.rsplit('|').next().unwrap_or_default().trim().to_string();
    let words: Vec<&str> = cell.split_whitespace().collect();
    assert!(words.len() >= 7 && words[1] == "/" && words[words.len() - 2] == "of", "{cell}");
    let (found, tried): (usize, usize) =
        (words[words.len() - 3].parse().unwrap(), words[words.len() - 1].parse().unwrap());
    assert!(tried >= 1 && found <= tried, "{cell}");
    let named: Vec<&str> = table.lines().filter(|l| l.starts_with("  kidnap ")).collect();
    for line in &named {
        assert!(line.contains("then of lines") && line.contains("first right ok"), "{line}");
    }
    // each splice without a right ok within 5 is named; a named one may also have missed the
    // other bar
    assert!(named.len() >= tried - found && named.len() <= tried, "{cell}\n{}", named.join("\n"));
}

/// `gema2 odometry` fits the alphas a walked log's odometry was drawn with, and prints the
/// settings the sequential localizer takes; a log without odometry errors say so.
#[test]
fn odometry_fits_the_alphas_a_log_was_drawn_with() {
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("walk.log");
    let log_s = log.to_str().unwrap();
    let walk = ["--trajectory", "--step", "0.5", "--odom-noise", "0.05,0.01,0.05,0.01", "--scans", "1200"];
    let args =
        ["sim", "--map", "warehouse", "--seed", "4", "--out", log_s].iter().chain(&walk).copied().collect::<Vec<_>>();
    let out = gema2(&args);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let out = gema2(&["odometry", "--log", log_s]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let said = text(&out.stdout);
    let alphas: Vec<f64> = said
        .lines()
        .find_map(|l| l.strip_prefix("alphas (AMCL's): "))
        .unwrap_or_else(|| panic!("no alphas in {said}"))
        .split_whitespace()
        .skip(1)
        .step_by(2)
        .map(|v| v.parse().unwrap())
        .collect();
    for (k, (&got, want)) in alphas.iter().zip([0.05, 0.01, 0.05, 0.01]).enumerate() {
        assert!(got > want * 0.6 && got < want * 1.5, "alpha{}: {got} against {want} in {said}", k + 1);
    }
    assert!(said.contains("--set odom_alpha1=") && said.contains("--set odom_alpha4="), "{said}");
    // without odometry drawn, ROBOTLASER1's robot pose is the truth: alphas of 0
    let exact = dir.path().join("exact.log");
    let exact_s = exact.to_str().unwrap();
    let out = gema2(&["sim", "--map", "warehouse", "--trajectory", "--scans", "40", "--out", exact_s]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let said = text(&gema2(&["odometry", "--log", exact_s]).stdout);
    assert!(said.contains("a1 0.0000  a2 0.0000  a3 0.0000  a4 0.0000"), "{said}");
    let out = gema2(&["odometry", "--log", log_s, "--every", "700"]);
    assert!(!out.status.success() && text(&out.stderr).contains("too few to fit"), "{}", text(&out.stderr));
}
