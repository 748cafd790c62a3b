//! Mutation fuzzing of every parser that reads what a user or a device hands gema2: CARMEN logs,
//! URG logs, wall-map JSON, ROS map YAML and PGM images (through to the traced wall map), the
//! SCIP 2.0 byte stream of a serial laser, the ROS 2 messages a DDS peer sends (CDR, through to
//! the scan a LaserScan becomes), and rosbag2 bags in MCAP and sqlite3 storage (through to the
//! scans, truth and odometry read from them).
//!
//! Each parser starts from valid seeds and is fed mutants of them (bit flips, cut and repeated
//! spans, spliced seeds, and the numbers that break arithmetic: `u64::MAX`, `-1`, `nan`,
//! `1e308`). It may refuse an input with an error; it must never panic. Each parser gets a time
//! budget, `GEMA2_FUZZ_SECONDS` (default 4 s), so CI runs a bounded fuzz on every build and a
//! longer one is `GEMA2_FUZZ_SECONDS=600 cargo test --release --test fuzz`. The random stream
//! is seeded from `GEMA2_FUZZ_SEED` (default: the clock, printed on a failure), and an input
//! that panics is written to `target/fuzz-failures/` to be replayed. An input a parser is still
//! on after `GEMA2_FUZZ_HANG_SECONDS` (default 60 s) is a hang: it is written there too, and the
//! test process exits with a failure instead of spinning until CI's time runs out.

use std::io::Cursor;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

/// xorshift64*: a small, seedable random stream.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }

    fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }
}

/// Tokens that break arithmetic and parsing where a number or a separator is expected.
const NASTY: &[&[u8]] = &[
    b"18446744073709551615",
    b"9223372036854775807",
    b"4294967296",
    b"-1",
    b"0",
    b"nan",
    b"-inf",
    b"1e308",
    b"-0",
    b"99999999",
    b" ",
    b"\n",
    b"\r\n",
    b"#",
    b":",
    b"\xff\xfe",
    b"\0",
];

/// One to eight mutations of `seed`, with `others` to splice from.
fn mutate(rng: &mut Rng, seed: &[u8], others: &[Vec<u8>]) -> Vec<u8> {
    let mut v = seed.to_vec();
    for _ in 0..1 + rng.below(8) {
        let at = rng.below(v.len() + 1);
        match rng.below(7) {
            0 if !v.is_empty() => {
                let k = rng.below(v.len());
                v[k] ^= 1 << rng.below(8);
            }
            1 if !v.is_empty() => {
                let k = rng.below(v.len());
                v[k] = b"0123456789-.e \n"[rng.below(15)];
            }
            2 => {
                let end = (at + rng.below(64)).min(v.len());
                v.drain(at..end);
            }
            3 => {
                let end = (at + rng.below(64)).min(v.len());
                let span = v[at..end].to_vec();
                v.splice(at..at, span.iter().copied().cycle().take(span.len() * (1 + rng.below(4))));
            }
            4 => {
                let token = NASTY[rng.below(NASTY.len())];
                // replace the number or word under `at` with the token
                let is_word = |b: &u8| !b.is_ascii_whitespace();
                let start = v[..at].iter().rposition(|b| !is_word(b)).map_or(0, |p| p + 1);
                let end = v[at..].iter().position(|b| !is_word(b)).map_or(v.len(), |p| at + p);
                v.splice(start..end, token.iter().copied());
            }
            5 if !others.is_empty() => {
                let other = &others[rng.below(others.len())];
                let from = rng.below(other.len() + 1);
                let end = (from + rng.below(256)).min(other.len());
                v.splice(at..at, other[from..end].iter().copied());
            }
            _ => v.truncate(at),
        }
    }
    v
}

fn budget() -> Duration {
    let seconds = std::env::var("GEMA2_FUZZ_SECONDS").ok().and_then(|s| s.parse::<f64>().ok()).unwrap_or(4.0);
    Duration::from_secs_f64(seconds.max(0.0))
}

fn seed_of_run() -> u64 {
    std::env::var("GEMA2_FUZZ_SEED").ok().and_then(|s| s.parse().ok()).unwrap_or_else(|| {
        std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map_or(1, |d| d.as_nanos() as u64) | 1
    })
}

/// Where a panicking input is kept.
fn failures() -> PathBuf {
    Path::new(env!("CARGO_TARGET_TMPDIR")).join("fuzz-failures")
}

/// Keeps `input` as `file` in [`failures`] to be replayed, and says where, with the seed that
/// makes it again and its first bytes.
fn kept(file: &str, seed: u64, input: &[u8]) -> String {
    let _ = std::fs::create_dir_all(failures());
    let file = failures().join(file);
    let _ = std::fs::write(&file, input);
    format!(
        "kept as {} (GEMA2_FUZZ_SEED={seed}): {:?}",
        file.display(),
        String::from_utf8_lossy(&input[..input.len().min(400)])
    )
}

/// How long one input may take before it is a hang.
fn hang_limit() -> Duration {
    let seconds = std::env::var("GEMA2_FUZZ_HANG_SECONDS").ok().and_then(|s| s.parse::<f64>().ok()).unwrap_or(60.0);
    Duration::from_secs_f64(seconds.max(1.0))
}

/// The run's inputs in order: the seeds, then mutants drawn from `rng`. The stream depends on
/// the seed alone, so input `k` can be made again.
fn next_input(rng: &mut Rng, seeds: &[Vec<u8>], k: usize) -> Vec<u8> {
    match seeds.get(k) {
        Some(s) => s.clone(),
        None => {
            let parent = rng.below(seeds.len());
            mutate(rng, &seeds[parent], seeds)
        }
    }
}

/// Watches a fuzz run from its own thread: when the input in hand (`in_hand`, counted from 1)
/// has not changed for [`hang_limit`], makes that input again from the seed, keeps it, and
/// ends the test process with a failure, since a spinning parser cannot be stopped from here.
fn watch_for_hangs(name: &str, seed: u64, seeds: &[Vec<u8>], in_hand: Arc<AtomicUsize>, done: Arc<AtomicBool>) {
    let (name, seeds) = (name.to_owned(), seeds.to_vec());
    std::thread::spawn(move || {
        let (mut last, mut since) = (0, Instant::now());
        while !done.load(Ordering::Relaxed) {
            std::thread::sleep(Duration::from_millis(250));
            let now = in_hand.load(Ordering::Relaxed);
            if now != last {
                (last, since) = (now, Instant::now());
                continue;
            }
            if now == 0 || since.elapsed() < hang_limit() || done.load(Ordering::Relaxed) {
                continue;
            }
            let mut rng = Rng(seed);
            let input = (0..now).map(|k| next_input(&mut rng, &seeds, k)).last().unwrap_or_default();
            let kept = kept(&format!("{name}-{seed}-hang.bin"), seed, &input);
            use std::io::Write;
            let _ = writeln!(
                std::io::stderr(),
                "{name}: input {now} has run for {:.0} s, a hang; {kept}",
                since.elapsed().as_secs_f64()
            );
            std::process::exit(101);
        }
    });
}

/// Feeds `parse` the seeds, then mutants of them until the budget is spent; panics naming the
/// input file of the first input that made `parse` panic, and ends the process naming the one
/// that hung it ([`watch_for_hangs`]). Returns how many inputs it ran.
fn fuzz(name: &str, seeds: &[Vec<u8>], parse: impl Fn(&[u8])) -> usize {
    let seed = seed_of_run();
    let mut rng = Rng(seed);
    let (in_hand, done) = (Arc::new(AtomicUsize::new(0)), Arc::new(AtomicBool::new(false)));
    watch_for_hangs(name, seed, seeds, Arc::clone(&in_hand), Arc::clone(&done));
    let started = Instant::now();
    let mut runs = 0;
    let mut failed = None;
    while failed.is_none() && (runs < seeds.len() || started.elapsed() < budget()) {
        let input = next_input(&mut rng, seeds, runs);
        runs += 1;
        in_hand.store(runs, Ordering::Relaxed);
        if let Err(panic) = catch_unwind(AssertUnwindSafe(|| parse(&input))) {
            let why = panic
                .downcast_ref::<String>()
                .cloned()
                .or_else(|| panic.downcast_ref::<&str>().map(|s| s.to_string()))
                .unwrap_or_default();
            failed = Some((input, why));
        }
    }
    done.store(true, Ordering::Relaxed);
    if let Some((input, why)) = failed {
        panic!("{name}: an input panicked the parser ({why}); {}", kept(&format!("{name}-{seed}.bin"), seed, &input));
    }
    assert!(runs > seeds.len() || budget().is_zero(), "{name}: no mutant ran");
    // straight to the terminal, past the harness's capture: how much fuzzing CI did
    use std::io::Write;
    let _ = writeln!(std::io::stderr(), "fuzz {name}: {runs} inputs in {:.1} s", started.elapsed().as_secs_f64());
    runs
}

fn carmen_seeds() -> Vec<Vec<u8>> {
    let ranges = |n: usize| (0..n).map(|k| format!("{:.3}", 1.0 + k as f64 * 0.01)).collect::<Vec<_>>().join(" ");
    vec![
        format!(
            "# a log\nODOM 1 2 0.5 0 0 0 1.0 host 1.0\nROBOTLASER1 0 -1.5708 3.1416 0.0175 81.9 0.01 0 181 {} 0 \
             1.0 2.0 0.5 1.0 2.0 0.5 0 0 0 0 0 1.5 host 1.5\n",
            ranges(181)
        ),
        format!("FLASER 180 {} 1.0 2.0 0.5 1.1 2.1 0.6 2.0 host 2.0\n", ranges(180)),
        format!(
            "# gema2: poses are not ground truth\nROBOTLASER1 -1.5708 3.1416 0 81.9 0.01 0 4 1 2 3 4 2 7 8 1 1 0 1 \
             1 0 0 0 0 0 0 3 h 3\nFLASER 3 1 2 3 0 0 0 0 0 0 4 h 4\n"
        ),
    ]
    .into_iter()
    .map(String::into_bytes)
    .collect()
}

#[test]
fn carmen_logs_never_panic_the_reader() {
    let layouts = [
        acquire::carmen::FlaserLayout::default(),
        acquire::carmen::FlaserLayout { field_of_view: Some(4.0), start_angle: -2.0, ..Default::default() },
    ];
    fuzz("carmen", &carmen_seeds(), |bytes| {
        for layout in layouts {
            let reader = Box::new(Cursor::new(bytes.to_vec()));
            for scan in
                acquire::carmen::CarmenReader::from_reader(reader, Path::new("fuzz.log"), layout).take(64).flatten()
            {
                assert!(scan.scan.geometry.is_well_formed(), "an unusable layout was accepted");
            }
        }
    });
}

#[test]
fn urg_logs_never_panic_the_reader() {
    let mut line = vec!["1500000".to_owned()];
    line.extend((1..acquire::urg_log::FIRST_READING).map(|k| k.to_string()));
    line.extend((0..acquire::urg_log::READINGS).map(|k| ((k * 37) % 4000).to_string()));
    let line = line.join(" ");
    let seeds = vec![format!("{line}\n{line}\n").into_bytes(), format!("\n{line}").into_bytes()];
    fuzz("urg", &seeds, |bytes| {
        let reader = Box::new(Cursor::new(bytes.to_vec()));
        for scan in acquire::urg_log::UrgLogReader::from_reader(reader, Path::new("fuzz.dat")).take(8).flatten() {
            assert!(scan.ranges.iter().all(|r| r.is_finite()), "a non-finite range was accepted");
        }
    });
}

#[test]
fn wall_maps_never_panic_the_parser() {
    let seeds: Vec<Vec<u8>> = map::bundled::BUNDLED.iter().map(|(_, text)| text.as_bytes().to_vec()).collect();
    fuzz("map-json", &seeds, |bytes| {
        let text = String::from_utf8_lossy(bytes);
        if let Ok(m) = map::WallMap::parse(&text, Path::new("fuzz.json")) {
            // what the parser accepts, the wire accepts too
            assert!(map::map::check_walls(&m.walls).is_ok(), "a map the wall check refuses was accepted");
        }
    });
}

#[test]
fn ros_maps_never_panic_the_parser_or_the_tracer() {
    use mapio::image::Channels;
    use mapio::ros::{MapMeta, OccupancyGrid};
    let yaml = b"image: map.pgm\nresolution: 0.05\norigin: [-1.0, -2.0, 0.0]\nnegate: 0\noccupied_thresh: 0.65\n\
                 free_thresh: 0.196\nmode: trinary\n"
        .to_vec();
    // a room: a wall ring round free floor, 24 x 16 cells, as P5 and as P2
    let (w, h) = (24usize, 16usize);
    let shade = |x: usize, y: usize| if x == 0 || y == 0 || x == w - 1 || y == h - 1 { 0u8 } else { 254 };
    let mut p5 = format!("P5\n# room\n{w} {h}\n255\n").into_bytes();
    p5.extend((0..h).flat_map(|y| (0..w).map(move |x| shade(x, y))));
    let p2 = format!(
        "P2\n{w} {h}\n255\n{}\n",
        (0..h)
            .map(|y| (0..w).map(|x| shade(x, y).to_string()).collect::<Vec<_>>().join(" "))
            .collect::<Vec<_>>()
            .join("\n")
    )
    .into_bytes();
    // and as a grey-with-alpha PNG
    let mut png = Vec::new();
    {
        let mut e = png::Encoder::new(&mut png, w as u32, h as u32);
        e.set_color(png::ColorType::GrayscaleAlpha);
        let mut writer = e.write_header().unwrap();
        let data: Vec<u8> = (0..h).flat_map(|y| (0..w).flat_map(move |x| [shade(x, y), 255])).collect();
        writer.write_image_data(&data).unwrap();
    }
    // one input holds both files: the YAML, a NUL, the image
    let seeds: Vec<Vec<u8>> =
        [&p5, &p2, &png].iter().map(|img| [yaml.as_slice(), b"\0", img.as_slice()].concat()).collect();
    let trace = mapio::trace::TraceConfig::default();
    fuzz("ros-map", &seeds, |bytes| {
        let (text, image) = match bytes.iter().position(|&b| b == 0) {
            Some(k) => (&bytes[..k], &bytes[k + 1..]),
            None => (bytes, &[][..]),
        };
        let meta = MapMeta::parse(&String::from_utf8_lossy(text), Path::new("fuzz.yaml"));
        let channels = meta.as_ref().map_or(Channels::WithAlpha, MapMeta::channels);
        let pgm = mapio::image::read(image, Path::new("fuzz.pgm"), channels);
        if let (Ok(meta), Ok(pgm)) = (meta, pgm) {
            // traced only while small, and surveyed (a rough grid's walls) while smaller, as a
            // fuzz input must stay cheap to run
            let cells = pgm.width * pgm.height;
            if cells <= 4096 {
                if let Some(grid) = OccupancyGrid::from_image(&meta, &pgm) {
                    if cells <= 1024 {
                        let _ = mapio::grid_walls(&grid);
                    } else {
                        let _ = grid.to_wall_map(&trace, None);
                    }
                }
            }
        }
    });
}

/// Reads canned bytes; writes vanish.
struct Canned(Cursor<Vec<u8>>);

impl std::io::Read for Canned {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        self.0.read(buf)
    }
}

impl std::io::Write for Canned {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        Ok(buf.len())
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

#[test]
fn scip_streams_never_panic_the_driver() {
    use acquire::scip::codec::{checksum, data_lines, encode};
    let status = |s: &[u8]| {
        let mut l = s.to_vec();
        l.push(checksum(s));
        l.push(b'\n');
        l
    };
    // the reply to MD, then two scans of 682 readings
    let mut stream = b"MD0044072501000\n".to_vec();
    stream.extend(status(b"00"));
    stream.push(b'\n');
    for scan in 0..2u32 {
        stream.extend_from_slice(b"MD0044072501000\n");
        stream.extend(status(b"99"));
        let mut time = Vec::new();
        encode(1000 + scan * 100, 4, &mut time);
        stream.extend(status(&time));
        let mut data = Vec::new();
        for k in 0..682u32 {
            encode(20 + (k * 13 + scan) % 4000, 3, &mut data);
        }
        data_lines(&data, &mut stream);
        stream.push(b'\n');
    }
    fuzz("scip", &[stream], |bytes| {
        let mut urg = acquire::scip::Urg::new(Canned(Cursor::new(bytes.to_vec())), Duration::from_millis(1));
        if urg.start(acquire::scip::Encoding::Three, 44, 725, 1, 0).is_ok() {
            for _ in 0..4 {
                if urg.next_scan().is_err() {
                    break;
                }
            }
        }
    });
}

/// Messages as a ROS 2 peer would send them: a LaserScan with REP 117's odd readings, the
/// poses and odometry the sequential localizer and the evaluation read, and a TF message.
fn ros_message_seeds() -> Vec<Vec<u8>> {
    use ros::msg::{self, Header, Time};
    let header = Header { stamp: Time::from_nanos(1_700_000_000_123_456_789), frame_id: "base_laser".into() };
    let scan = msg::LaserScan {
        header: header.clone(),
        angle_min: -2.0,
        angle_max: 2.0,
        angle_increment: 0.5,
        range_min: 0.05,
        range_max: 10.0,
        ranges: vec![1.0, f32::INFINITY, f32::NAN, 20.0, 0.01, 3.5, f32::NEG_INFINITY, 2.0, 9.99],
        intensities: vec![100.0; 9],
        ..Default::default()
    };
    let pose = msg::Pose::from_planar(1.5, -2.0, 0.7);
    let odometry = msg::Odometry {
        header: header.clone(),
        child_frame_id: "base_link".into(),
        pose: msg::PoseWithCovariance { pose, ..Default::default() },
        ..Default::default()
    };
    let tf = msg::TfMessage {
        transforms: vec![msg::TransformStamped {
            header: header.clone(),
            child_frame_id: "odom".into(),
            transform: msg::Transform { translation: [1.0, 2.0, 0.0], rotation: [0.0, 0.0, 0.3, 0.95] },
        }],
    };
    vec![
        scan.encode(),
        msg::PoseStamped { header: header.clone(), pose }.encode(),
        msg::PoseWithCovarianceStamped { header, pose: msg::PoseWithCovariance { pose, ..Default::default() } }
            .encode(),
        odometry.encode(),
        tf.encode(),
    ]
}

/// A message off the network is decoded as every type a gema2 node reads; a LaserScan that
/// decodes is made into a scan, which must hold no reading the stages cannot take.
#[test]
fn ros_messages_never_panic_the_decoders() {
    use ros::msg::{self, Decode};
    fuzz("ros-message", &ros_message_seeds(), |bytes| {
        if let Ok(m) = msg::LaserScan::decode(bytes) {
            if let Ok(scan) = ros::laser_scan(&m) {
                assert!(scan.geometry.is_well_formed(), "an ill-formed layout was accepted: {:?}", scan.geometry);
                assert!(scan.ranges.iter().all(|r| r.is_nan() || r.is_finite()), "an infinite range was accepted");
            }
        }
        let _ = msg::PoseStamped::decode(bytes).map(|p| p.pose.planar());
        let _ = msg::PoseWithCovarianceStamped::decode(bytes);
        let _ = msg::Odometry::decode(bytes).map(|o| o.pose.pose.planar());
        let _ = msg::TfMessage::decode(bytes);
        // a ROS 1 peer's bytes, as a ROS 1 bag holds them
        let _ = msg::LaserScan::decode_as(ros::cdr::Encoding::Ros1, bytes).map(|m| ros::laser_scan(&m));
    });
}

/// An MCAP file of `messages` (topic, type, CDR bytes), chunked and compressed as `compression`
/// says (no chunks at all with `None`).
fn mcap_bytes(messages: &[(&str, &str, Vec<u8>)], compression: Option<mcap::Compression>) -> Vec<u8> {
    let mut out = Vec::new();
    {
        let mut w = mcap::WriteOptions::new()
            .compression(compression)
            .chunk_size(compression.map(|_| 512))
            .use_chunks(compression.is_some())
            .create(Cursor::new(&mut out))
            .expect("an MCAP writer");
        let mut channels = std::collections::BTreeMap::new();
        for (k, (topic, ros_type, data)) in messages.iter().enumerate() {
            let id = *channels.entry(*topic).or_insert_with(|| {
                let schema = w.add_schema(ros_type, "ros2msg", b"").expect("a schema");
                w.add_channel(schema, topic, "cdr", &std::collections::BTreeMap::new()).expect("a channel")
            });
            let at = 1_000_000_000 + k as u64 * 100_000_000;
            let header =
                mcap::records::MessageHeader { channel_id: id, sequence: k as u32, log_time: at, publish_time: at };
            w.write_to_known_channel(&header, data).expect("a message");
        }
        w.finish().expect("the summary");
    }
    out
}

/// The messages of the bag seeds: four scans, each with a true pose and odometry.
fn bag_messages() -> Vec<(&'static str, &'static str, Vec<u8>)> {
    use ros::msg::{self, Header, Time};
    let stamp = |k: u64| Time::from_nanos(1_000_000_000 + k * 100_000_000);
    let scan = |k: u64| {
        msg::LaserScan {
            header: Header { stamp: stamp(k), frame_id: "laser".into() },
            angle_min: -1.0,
            angle_max: 1.0,
            angle_increment: 0.5,
            range_min: 0.05,
            range_max: 10.0,
            ranges: vec![1.0 + k as f32, 2.0, f32::INFINITY, 3.0, 0.5],
            ..Default::default()
        }
        .encode()
    };
    let pose = |k: u64| msg::PoseStamped {
        header: Header { stamp: stamp(k), frame_id: "map".into() },
        pose: msg::Pose::from_planar(k as f64 * 0.1, 0.0, 0.0),
    };
    let odometry = |k: u64| msg::Odometry {
        header: pose(k).header,
        child_frame_id: "base_link".into(),
        pose: msg::PoseWithCovariance { pose: pose(k).pose, ..Default::default() },
        ..Default::default()
    };
    // odometry on /tf too, and /tf_static placing the laser on the robot
    let transform = |k: u64, parent: &str, child: &str, x: f64| msg::TransformStamped {
        header: Header { stamp: stamp(k), frame_id: parent.into() },
        child_frame_id: child.into(),
        transform: msg::Transform { translation: [x, 0.0, 0.0], rotation: [0.0, 0.0, 0.1, 0.99] },
    };
    let fixed = msg::TfMessage { transforms: vec![transform(0, "base_link", "laser", 0.3)] };
    let mut messages = vec![("/tf_static", msg::TfMessage::TYPE, fixed.encode())];
    for k in 0..4 {
        messages.push(("/scan", msg::LaserScan::TYPE, scan(k)));
        messages.push(("/truth", msg::PoseStamped::TYPE, pose(k).encode()));
        messages.push(("/odom", msg::Odometry::TYPE, odometry(k).encode()));
        let tf = msg::TfMessage {
            transforms: vec![transform(k, "map", "odom", 1.0), transform(k, "odom", "base_link", k as f64 * 0.1)],
        };
        messages.push(("/tf", msg::TfMessage::TYPE, tf.encode()));
    }
    messages
}

/// Reads the bag at `path` as `locate --bag` does: its topics, then its scans with their truth
/// and odometry, and with the default topics; what it accepts must be usable.
fn read_bag(path: &Path) {
    let Ok(bag) = ros::Bag::open(path) else { return };
    let _ = bag.topics();
    let topics = ros::ScanTopics {
        scan: Some("/scan".into()),
        truth: Some("/truth".into()),
        odometry: Some("/odom".into()),
        ..Default::default()
    };
    let off_tf = ros::ScanTopics { odometry: Some("/tf".into()), ..topics.clone() };
    for t in [&topics, &off_tf, &ros::ScanTopics::default()] {
        if let Ok(scans) = ros::BagScans::open(&bag, t) {
            for s in scans.take(16).flatten() {
                assert!(s.scan.geometry.is_well_formed(), "an ill-formed layout was accepted");
            }
        }
    }
}

/// A sqlite3 bag (ROS 2 Humble's default storage) damaged anywhere, its pages, its schema or
/// its rows, is refused or read as far as it goes; never a panic.
#[test]
fn sqlite3_bags_never_panic_the_reader() {
    let dir = tempfile::tempdir().expect("a scratch folder");
    let seed = dir.path().join("seed.db3");
    {
        let db = rusqlite::Connection::open(&seed).expect("a sqlite3 file");
        db.execute_batch(
            "CREATE TABLE topics(id INTEGER PRIMARY KEY, name TEXT NOT NULL, type TEXT NOT NULL, \
             serialization_format TEXT NOT NULL, offered_qos_profiles TEXT NOT NULL);\
             CREATE TABLE messages(id INTEGER PRIMARY KEY, topic_id INTEGER NOT NULL, \
             timestamp INTEGER NOT NULL, data BLOB NOT NULL);",
        )
        .expect("the rosbag2 tables");
        let mut ids = std::collections::BTreeMap::new();
        for (k, (topic, ros_type, data)) in bag_messages().into_iter().enumerate() {
            let next = ids.len() as i64 + 1;
            let id = *ids.entry(topic).or_insert_with(|| {
                db.execute(
                    "INSERT INTO topics VALUES (?1, ?2, ?3, 'cdr', '')",
                    rusqlite::params![next, topic, ros_type],
                )
                .expect("a topic");
                next
            });
            let at = 1_000_000_000 + k as i64 * 100_000_000;
            db.execute(
                "INSERT INTO messages(topic_id, timestamp, data) VALUES (?1, ?2, ?3)",
                rusqlite::params![id, at, data],
            )
            .expect("a message");
        }
    }
    let seeds = vec![std::fs::read(&seed).expect("the seed's bytes")];
    let path = dir.path().join("fuzz.db3");
    fuzz("db3", &seeds, |bytes| {
        std::fs::write(&path, bytes).expect("writing the scratch bag");
        read_bag(&path);
    });
}

/// A bag whose file is damaged, cut or hostile (a record claiming exabytes, a chunk that does
/// not decompress, a message before its channel) is refused or read as far as it goes; it
/// never panics or aborts the reader, whether it lists the topics or reads scans, truth and
/// odometry from them.
#[test]
fn mcap_bags_never_panic_the_reader() {
    let messages = bag_messages();
    let seeds: Vec<Vec<u8>> = [None, Some(mcap::Compression::Zstd), Some(mcap::Compression::Lz4)]
        .into_iter()
        .map(|c| mcap_bytes(&messages, c))
        .collect();
    let dir = tempfile::tempdir().expect("a scratch folder");
    let path = dir.path().join("fuzz.mcap");
    fuzz("mcap", &seeds, |bytes| {
        std::fs::write(&path, bytes).expect("writing the scratch bag");
        read_bag(&path);
    });
}
