//! Recording hand-made messages and reading the file back with rerun's decoder: every entity is
//! where `entities` says, with the counts that were sent.

use messages::*;
use viewer::entities::*;
use viewer::{Inspection, Output, OutputSpec, Recorder};

fn zeroed<T: Zeroable>() -> Box<T> {
    messages::zeroed_box()
}

fn header(seq: u64) -> Header {
    let mut h = Header::new(seq, 1_000_000_000 + seq * 100_000_000);
    h.stages[0] = StageSpan { enter_ns: h.stamp_ns, leave_ns: h.stamp_ns + 20_000 };
    h.stages[1] = StageSpan { enter_ns: h.stamp_ns + 60_000, leave_ns: h.stamp_ns + 160_000 };
    h.stages[2] = StageSpan { enter_ns: h.stamp_ns + 200_000, leave_ns: h.stamp_ns + 1_200_000 };
    h.set_producer("test");
    h
}

fn scan(seq: u64, valid: usize) -> Box<ScanMsg> {
    let mut s = zeroed::<ScanMsg>();
    s.header = header(seq);
    s.angle_min = -2.0;
    s.angle_increment = 0.01;
    s.range_min = 0.02;
    s.range_max = 5.6;
    s.count = 400;
    for (i, r) in s.ranges[..400].iter_mut().enumerate() {
        *r = if i < valid { 2.0 } else { f32::NAN };
    }
    s.has_truth = 1;
    s.truth = PoseMsgXyt { x: 1.0, y: 2.0, theta: 0.5 };
    s
}

fn lines(seq: u64, n: usize) -> Box<LinesMsg> {
    let mut l = zeroed::<LinesMsg>();
    l.header = header(seq);
    l.count = n as u32;
    for (k, line) in l.lines[..n].iter_mut().enumerate() {
        *line = LineMsg {
            start: [k as f64, 0.0],
            end: [k as f64, 1.0],
            direction_sigma: 0.01,
            samples: 10 + k as u32,
            _pad: 0,
        };
    }
    l
}

fn corners(seq: u64, n: usize) -> Box<CornersMsg> {
    let mut c = zeroed::<CornersMsg>();
    c.scan = *scan(seq, 10);
    c.count = n as u32;
    for (k, corner) in c.corners[..n].iter_mut().enumerate() {
        corner.position = [k as f64, 1.0];
        corner.inner_angle = std::f64::consts::FRAC_PI_2;
    }
    c
}

fn pose(seq: u64, n: usize, status: u32, x: f64) -> Box<PoseMsg> {
    let mut p = zeroed::<PoseMsg>();
    p.header = header(seq);
    p.status = status;
    p.count = n as u32;
    p.has_truth = 1;
    p.truth = PoseMsgXyt { x: 1.0, y: 2.0, theta: 0.5 };
    for (k, h) in p.hypotheses[..n].iter_mut().enumerate() {
        h.pose = PoseMsgXyt { x: x + k as f64, y: 2.0, theta: 0.5 };
        h.cost = 0.01 * (k + 1) as f64;
        h.scan_corner = 1;
    }
    p
}

fn map() -> Box<MapMsg> {
    let mut m = zeroed::<MapMsg>();
    let walls = [[0.0, 0.0, 4.0, 0.0], [4.0, 0.0, 4.0, 3.0], [4.0, 3.0, 0.0, 3.0], [0.0, 3.0, 0.0, 0.0]];
    m.version = 1;
    m.count = walls.len() as u32;
    m.walls[..4].copy_from_slice(&walls);
    m
}

/// A map that keeps its survey's free space (as a map built from a log does) is drawn with it,
/// cell for cell; a later version without it clears it.
#[test]
fn a_map_with_seen_free_space_is_drawn_with_it() {
    use map::SeenFree;
    use mapserver::wire::map_to_msg;
    use nalgebra::Point2;
    let mut walls = mapserver::wire::map_from_msg(&map()).unwrap();
    let mut seen = SeenFree::covering(Point2::new(0.0, 0.0), Point2::new(4.0, 3.0), 0.5).unwrap();
    seen.mark_ray(Point2::new(0.25, 0.25), Point2::new(3.75, 0.25)); // the bottom row of 8 cells
    seen.mark_ray(Point2::new(0.25, 0.75), Point2::new(0.25, 2.75)); // and 5 more up the left
    let cells = seen.seen_cells();
    assert_eq!(cells, 13);
    walls.seen_free = Some(seen);
    let mut with_seen = map();
    map_to_msg(&walls, 1, &mut with_seen).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("seen.rrd");
    let output = Output::open(OutputSpec { file: Some(file.clone()), ..Default::default() }).unwrap();
    let mut r = Recorder::new(output);
    r.map(&with_seen).unwrap();
    let (_, parts) = r.finish().unwrap();
    let got = Inspection::read(&parts).unwrap();
    assert_eq!((got.map_walls, got.map_seen_free), (4, cells));
    assert!(got.render().contains("13 cells of seen free space"), "{}", got.render());

    let file = dir.path().join("replaced.rrd");
    let output = Output::open(OutputSpec { file: Some(file.clone()), ..Default::default() }).unwrap();
    let mut r = Recorder::new(output);
    r.map(&with_seen).unwrap();
    let mut plain = map();
    plain.version = 2;
    r.map(&plain).unwrap();
    let (_, parts) = r.finish().unwrap();
    assert_eq!(Inspection::read(&parts).unwrap().map_seen_free, 0);
}

#[test]
fn a_recording_holds_every_entity_with_the_counts_sent() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("run.rrd");
    let output = Output::open(OutputSpec { file: Some(file.clone()), ..Default::default() }).unwrap();
    let mut r = Recorder::new(output);
    r.map(&map()).unwrap();
    // scan 0: located; scan 1: failed, no hypothesis; scan 2 never arrives; scan 3: ambiguous, wrong
    r.scan(&scan(0, 300)).unwrap();
    r.lines(&lines(0, 3)).unwrap();
    r.corners(&corners(0, 2)).unwrap();
    r.pose(&pose(0, 4, STATUS_OK, 1.01)).unwrap();
    r.scan(&scan(1, 50)).unwrap();
    r.lines(&lines(1, 1)).unwrap();
    r.corners(&corners(1, 0)).unwrap();
    r.pose(&pose(1, 0, STATUS_FAILED, 0.0)).unwrap();
    r.scan(&scan(3, 120)).unwrap();
    r.lines(&lines(3, 2)).unwrap();
    r.lines(&lines(3, 2)).unwrap(); // a duplicate, as during a hot swap
    r.corners(&corners(3, 5)).unwrap();
    r.pose(&pose(3, 2, STATUS_AMBIGUOUS, 3.0)).unwrap();
    let (counts, parts) = r.finish().unwrap();
    assert_eq!(parts, vec![file.clone()]);
    assert_eq!((counts.scan.recorded, counts.scan.missed), (3, 1));
    assert_eq!(counts.lines.duplicates, 1);

    let got = Inspection::read(&parts).unwrap();
    assert_eq!(got.scans.keys().copied().collect::<Vec<_>>(), vec![0, 1, 3]);
    let count = |seq: i64, e: &str| got.scans[&seq].get(e).copied();
    assert_eq!(count(0, SCAN_READINGS), Some(300));
    assert_eq!(count(0, SCAN_LINES), Some(3));
    assert_eq!(count(0, SCAN_CORNERS), Some(2));
    assert_eq!(count(0, SCAN_CHOSEN_CORNER), Some(1));
    assert_eq!(count(0, WORLD_HYPOTHESES), Some(4));
    assert_eq!(count(0, WORLD_POSE), Some(1));
    assert_eq!(count(0, WORLD_READINGS), Some(300));
    assert_eq!(count(0, WORLD_TRUTH), Some(1));
    assert_eq!(count(1, SCAN_READINGS), Some(50));
    assert_eq!(count(1, WORLD_HYPOTHESES), Some(0));
    assert_eq!(count(1, WORLD_POSE), Some(0));
    assert_eq!(count(1, SCAN_CHOSEN_CORNER), Some(0));
    assert_eq!(count(3, SCAN_LINES), Some(2), "the duplicate is not recorded twice");
    assert_eq!(count(3, SCAN_CORNERS), Some(5));
    assert_eq!(got.scans_with_status(STATUS_FAILED), vec![1]);
    assert_eq!(got.scans_with_status(STATUS_AMBIGUOUS), vec![3]);
    assert_eq!(got.success.get(&0), Some(&true));
    assert_eq!(got.success.get(&3), Some(&false));
    assert_eq!(got.success.get(&1), Some(&false), "no pose is a miss");
    assert!(!got.position_error.contains_key(&1));
    assert_eq!((got.map_walls, got.map_corners > 0), (4, true));
    assert_eq!(got.acquired, Some((1_000_000_000, 1_300_000_000)));
    let (p50, _) = messages::latency::p50_p99(&got.latencies["localize"]);
    assert!((p50 - 1000.0).abs() < 1e-6, "{p50}");
    assert_eq!(got.latencies["hop/scan"].len(), 3);
    assert!(got.log.iter().any(|(s, t)| *s == Some(1) && t.contains("status failed")), "{:?}", got.log);
    let text = got.render();
    assert!(text.contains("scans: 3 (seq 0..=3)") && text.contains("failed: 1 scans: 1"), "{text}");
}

#[test]
fn malformed_messages_are_logged_not_recorded_and_the_file_stays_clean() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("bad.rrd");
    let mut r = Recorder::new(Output::open(OutputSpec { file: Some(file.clone()), ..Default::default() }).unwrap());
    let mut bad_map = map();
    bad_map.walls[1][2] = f64::NAN;
    r.map(&bad_map).unwrap();
    let mut s = scan(0, 10);
    s.count = 5000;
    r.scan(&s).unwrap();
    let mut s = scan(1, 10);
    s.angle_increment = f64::NAN;
    r.scan(&s).unwrap();
    let (counts, parts) = r.finish().unwrap();
    assert_eq!((counts.map.malformed, counts.scan.malformed), (1, 2));
    let got = Inspection::read(&parts).unwrap();
    assert!(got.scans.values().all(|e| !e.contains_key(SCAN_READINGS)));
    assert_eq!(got.log.len(), 3, "{:?}", got.log);
    assert!(got.log.iter().all(|(_, t)| t.contains("bad map") || t.contains("unusable")));
}

/// A damaged file is not refused whole: what it holds up to the damage is read, and the damage
/// is named (`viewer inspect` then prints both and fails).
#[test]
fn a_truncated_or_foreign_file_is_damage_naming_it_and_keeps_what_it_holds() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("run.rrd");
    let mut r = Recorder::new(Output::open(OutputSpec { file: Some(file.clone()), ..Default::default() }).unwrap());
    for seq in 0..20 {
        r.scan(&scan(seq, 300)).unwrap();
    }
    r.finish().unwrap();
    let bytes = std::fs::read(&file).unwrap();
    let cut = dir.path().join("cut.rrd");
    std::fs::write(&cut, &bytes[..bytes.len() / 2]).unwrap();
    let got = Inspection::read(std::slice::from_ref(&cut)).unwrap();
    assert!(got.damage.len() == 1 && got.damage[0].contains("cut.rrd"), "{:?}", got.damage);
    let kept = got.scans.values().filter(|e| e.contains_key(SCAN_READINGS)).count();
    assert!((1..=20).contains(&kept), "{kept} of 20 scans read before the cut");
    assert!(got.render().starts_with("damaged: "), "{}", got.render());
    let foreign = dir.path().join("foreign.rrd");
    std::fs::write(&foreign, b"this is not a recording at all").unwrap();
    let got = Inspection::read(&[foreign, file]).unwrap();
    assert!(got.damage.len() == 1 && got.damage[0].contains("foreign.rrd"), "{:?}", got.damage);
    // the sound part after the foreign one is read whole
    assert_eq!(got.scans.values().filter(|e| e.contains_key(SCAN_READINGS)).count(), 20);
    let missing = dir.path().join("missing.rrd");
    assert!(Inspection::read(&[missing]).unwrap_err().to_string().contains("missing.rrd"));
}

#[test]
fn past_the_size_limit_the_recording_rolls_over_and_every_part_decodes_with_the_map() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("long.rrd");
    let spec = OutputSpec { file: Some(file.clone()), max_size: Some(64 * 1024), ..Default::default() };
    let mut r = Recorder::new(Output::open(spec).unwrap());
    r.map(&map()).unwrap();
    for seq in 0..400 {
        r.scan(&scan(seq, 400)).unwrap();
        r.pose(&pose(seq, 8, STATUS_OK, 1.0)).unwrap();
    }
    let (_, parts) = r.finish().unwrap();
    assert!(parts.len() >= 2, "{parts:?}");
    assert_eq!(parts[1], dir.path().join("long.1.rrd"));
    let mut seen = 0;
    for p in &parts {
        let part = Inspection::read(std::slice::from_ref(p)).unwrap();
        assert_eq!(part.map_walls, 4, "{} lacks the map", p.display());
        seen += part.scans.len();
    }
    let all = Inspection::read(&parts).unwrap();
    assert_eq!(all.scans.len(), 400);
    assert!(seen >= 400);
}

/// The recorder's scan counts after `scans`, in order: recorded, duplicates, missed and
/// malformed.
fn scan_counts(scans: &[Box<ScanMsg>]) -> (u64, u64, u64, u64) {
    let dir = tempfile::tempdir().unwrap();
    let output = Output::open(OutputSpec { file: Some(dir.path().join("run.rrd")), ..Default::default() }).unwrap();
    let mut r = Recorder::new(output);
    for s in scans {
        r.scan(s).unwrap();
    }
    let c = r.finish().unwrap().0.scan;
    (c.recorded, c.duplicates, c.missed, c.malformed)
}

#[test]
fn a_restarted_source_is_recorded_and_a_copy_is_not() {
    // the source restarts and numbers from 0 again, later on the same clock
    let mut again = scan(0, 300);
    again.header.stamp_ns = scan(5, 300).header.stamp_ns;
    // and skips its scan 1
    let mut next = scan(2, 300);
    next.header.stamp_ns = scan(6, 300).header.stamp_ns;
    let scans = [
        scan(0, 300),
        scan(1, 300),
        scan(1, 300), // a resend: same scan, same stamp
        again,
        scan(3, 300), // stamped before the restart: an old copy
        next,
    ];
    assert_eq!(scan_counts(&scans), (4, 2, 1, 0));
}

/// A scan stamped ahead of the machine's monotonic clock (a damaged message) is counted as
/// malformed, not as the newest: the scans after it are recorded.
#[test]
fn a_scan_stamped_ahead_of_the_clock_is_malformed_and_the_next_ones_are_recorded() {
    let mut ahead = scan(1, 300);
    ahead.header.stamp_ns = u64::MAX;
    // its number counts as missed, as a message that never came would
    assert_eq!(scan_counts(&[scan(0, 300), ahead, scan(2, 300)]), (2, 0, 1, 1));
}
