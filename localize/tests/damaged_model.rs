//! A map model block damaged in shared memory (a faulty or hostile map server, a stray write)
//! that still reads as a model must be safe to locate with: any answer, never a panic or a
//! hang. `map`'s own test checks that reading a damaged block never panics; this one goes on
//! and uses what was read, because a damaged array that passes its length and index checks
//! (a distance, a wall's end, a grid cell's wall list, the corners' order) is only touched by
//! the search, the cost and the tracker.

use acquire::{Scenario, SensorModel, Simulator};
use laser::{LaserScan, Pose};
use localize::{Gema2, Localizer, LocalizerConfig, MapModel, Sequential, SequentialConfig};
use map::flat::FlatReader;
use map::MapCornerConfig;
use segment::{LineVisibilitySegmenter, Segmenter, SegmenterConfig};
use std::sync::mpsc;
use std::sync::Arc;
use std::time::Duration;

/// Damaged blocks tried; about half of the single-byte damages still read as a model.
const CASES: usize = 160;
/// Longer than any locate of a few scans on the office in a debug build, by far.
const HANG: Duration = Duration::from_secs(120);

/// The single-scan search and the sequential localizer over `scans` with `model`.
fn locate_all(model: Arc<MapModel>, scans: &[LaserScan]) {
    let mut gema2 = Gema2::new(Arc::clone(&model), SegmenterConfig::default(), LocalizerConfig::default());
    for scan in scans {
        let _ = gema2.process(&scan.view());
    }
    let localizer = Localizer::new(model, LocalizerConfig::default());
    let mut sequential = Sequential::new(localizer, SequentialConfig::default());
    let mut segmenter = LineVisibilitySegmenter::new(SegmenterConfig::default());
    for scan in scans {
        let seg = segmenter.segment(&scan.view());
        let _ = sequential.locate(&scan.view(), seg, scan.truth);
    }
}

#[test]
fn a_damaged_model_that_reads_is_located_with_without_a_panic_or_a_hang() {
    let map = map::bundled("office").and_then(Result::ok).expect("the bundled office parses");
    let block = MapModel::new(map.clone(), &MapCornerConfig::default()).to_block();
    let bytes = block.bytes().to_vec();
    // a walk: scans a few decimetres apart, so the sequential localizer tracks as well
    let mut sim = Simulator::new(&map, SensorModel::urg04lx(), Scenario::People, 5);
    let start: Pose = sim.random_pose();
    let scans: Vec<LaserScan> = (0..3)
        .map(|k| {
            let truth = start * laser::pose(0.25 * k as f64, 0.0, 0.1 * k as f64);
            sim.scan_at(&truth, &acquire::Obstacles::default())
        })
        .collect();
    let (mut state, mut read, mut failures) = (0x2545_f491_4f6c_dd1du64, 0, Vec::new());
    for case in 0..CASES {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        let mut damaged = bytes.clone();
        let at = (state % damaged.len() as u64) as usize;
        damaged[at] ^= (state >> 40) as u8 | 1;
        let Ok(model) = MapModel::from_block(&mut FlatReader::of_copy(&damaged)) else { continue };
        read += 1;
        let (done, finished) = mpsc::channel();
        let scans = scans.clone();
        std::thread::spawn(move || {
            let outcome =
                std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| locate_all(Arc::new(model), &scans)));
            let _ = done.send(outcome.is_ok());
        });
        match finished.recv_timeout(HANG) {
            Ok(true) => {}
            Ok(false) => failures.push(format!("case {case}: byte {at} damaged, a panic")),
            Err(_) => failures.push(format!("case {case}: byte {at} damaged, no answer in {HANG:?}")),
        }
    }
    assert!(read * 4 > CASES, "only {read} of {CASES} damaged blocks read: the test tries too little");
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
