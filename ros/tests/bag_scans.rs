//! Bags as drivers in the wild leave them, written here with the `mcap` crate's writer (zstd
//! chunks, as rosbag2's MCAP plugin writes by default): a message that does not decode costs
//! its own scan only; two LaserScan topics need choosing; REP 117's readings and clockwise
//! beams arrive as the stages expect them.

use mcap::records::MessageHeader;
use ros::msg::{self, Header, Time};
use ros::{Bag, BagScanError, BagScans, ScanTopics};
use std::collections::BTreeMap;
use std::path::Path;

/// Message k's stamp: 100 s, then 0.4 s apart.
fn at(k: u32) -> Time {
    Time::from_nanos(100_000_000_000 + k as u64 * 400_000_000)
}

fn scan(k: u32, increment: f32) -> msg::LaserScan {
    msg::LaserScan {
        header: Header { stamp: at(k), frame_id: "laser".into() },
        angle_min: -increment * 2.0,
        angle_max: increment * 2.0,
        angle_increment: increment,
        range_min: 0.05,
        range_max: 10.0,
        ranges: vec![1.0 + k as f32, f32::INFINITY, f32::NAN, 20.0, 0.01],
        intensities: if k.is_multiple_of(2) { vec![] } else { vec![100.0; 5] },
        ..Default::default()
    }
}

/// Writes `messages` (topic, type, CDR bytes) as one MCAP file.
fn write_bag(path: &Path, messages: &[(&str, &str, Vec<u8>)]) {
    let mut w = mcap::WriteOptions::new()
        .compression(Some(mcap::Compression::Zstd))
        .chunk_size(Some(256))
        .create(std::io::BufWriter::new(std::fs::File::create(path).unwrap()))
        .unwrap();
    let mut channels = BTreeMap::new();
    for (k, (topic, ros_type, data)) in messages.iter().enumerate() {
        let id = *channels.entry(*topic).or_insert_with(|| {
            let schema = w.add_schema(ros_type, "ros2msg", b"").unwrap();
            w.add_channel(schema, topic, "cdr", &BTreeMap::new()).unwrap()
        });
        let header = MessageHeader { channel_id: id, sequence: k as u32, log_time: k as u64, publish_time: k as u64 };
        w.write_to_known_channel(&header, data).unwrap();
    }
    w.finish().unwrap();
}

#[test]
fn a_message_that_does_not_decode_costs_its_own_scan_only() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("scans.mcap");
    let good = |k| (("/scan"), msg::LaserScan::TYPE, scan(k, 0.1).encode());
    let mut cut = scan(1, 0.1).encode();
    cut.truncate(cut.len() - 9);
    let mut messages = vec![good(0), ("/scan", msg::LaserScan::TYPE, cut), good(2)];
    // an unusable layout, and a message of another topic between
    let mut bad_layout = scan(3, 0.1);
    bad_layout.range_max = -1.0;
    messages.push(("/scan", msg::LaserScan::TYPE, bad_layout.encode()));
    messages.push(("/other", msg::PoseStamped::TYPE, msg::PoseStamped::default().encode()));
    messages.push(good(4));
    write_bag(&path, &messages);
    let bag = Bag::open(&path).unwrap();
    let got: Vec<Result<usize, String>> = BagScans::open(&bag, &ScanTopics::default())
        .unwrap()
        .map(|r| {
            r.map(|s| s.index).map_err(|e| {
                assert!(e.is_one_message(), "{e}");
                e.to_string()
            })
        })
        .collect();
    assert_eq!(got.len(), 5);
    assert_eq!(got[0], Ok(0));
    assert!(got[1].as_ref().is_err_and(|e| e.contains("/scan message 1")), "{got:?}");
    assert_eq!(got[2], Ok(2));
    assert!(got[3].as_ref().is_err_and(|e| e.contains("layout")), "{got:?}");
    assert_eq!(got[4], Ok(4));
}

#[test]
fn readings_and_clockwise_beams_arrive_as_the_stages_expect_them() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("scans.mcap");
    write_bag(&path, &[("/scan", msg::LaserScan::TYPE, scan(0, -0.1).encode())]);
    let s = BagScans::open(&Bag::open(&path).unwrap(), &ScanTopics::default()).unwrap().next().unwrap().unwrap().scan;
    assert_eq!(s.stamp, 100.0);
    assert!((s.geometry.angle(0) - 0.2).abs() < 1e-6 && (s.geometry.angle(4) + 0.2).abs() < 1e-6, "clockwise");
    let kinds: Vec<laser::Reading> = s.ranges.iter().map(|&r| s.geometry.classify(r as f64)).collect();
    use laser::Reading::*;
    assert_eq!(kinds, vec![Valid(1.0), NoReturn, Unknown, Unknown, Unknown]);
}

#[test]
fn two_laser_topics_need_choosing_and_truth_comes_by_stamp() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("scans.mcap");
    let truth = |k: u32, x: f64| msg::PoseStamped {
        header: Header { stamp: at(k), frame_id: "map".into() },
        pose: msg::Pose::from_planar(x, 0.0, 0.0),
    };
    let odom = |k: u32, x: f64| msg::Odometry {
        header: truth(k, x).header,
        child_frame_id: "base_link".into(),
        pose: msg::PoseWithCovariance { pose: msg::Pose::from_planar(x, 1.0, 0.0), ..Default::default() },
        twist: Default::default(),
    };
    write_bag(
        &path,
        &[
            ("/front", msg::LaserScan::TYPE, scan(0, 0.1).encode()),
            ("/rear", msg::LaserScan::TYPE, scan(0, 0.1).encode()),
            ("/truth", msg::PoseStamped::TYPE, truth(0, 1.0).encode()),
            ("/odom", msg::Odometry::TYPE, odom(0, 1.0).encode()),
            ("/front", msg::LaserScan::TYPE, scan(1, 0.1).encode()),
            ("/truth", msg::PoseStamped::TYPE, truth(2, 3.0).encode()),
            ("/odom", msg::Odometry::TYPE, odom(2, 3.0).encode()),
        ],
    );
    let bag = Bag::open(&path).unwrap();
    match BagScans::open(&bag, &ScanTopics::default()) {
        Err(BagScanError::Topic { message: e, .. }) => {
            assert!(e.contains("/front, /rear") && e.contains("--scan-topic"), "{e}")
        }
        other => panic!("{:?}", other.map(|_| ())),
    }
    for (topic, y) in [("/truth", 0.0), ("/odom", 1.0)] {
        let topics = ScanTopics {
            scan: Some("/front".into()),
            truth: Some(topic.into()),
            laser_pose: Some((0.5, 0.0, 0.0)),
            odometry: None,
            odom_frame: None,
            base_frame: None,
        };
        let scans: Vec<_> = BagScans::open(&bag, &topics).unwrap().map(|s| s.unwrap().scan.truth.unwrap()).collect();
        // at its own stamp, and halfway between two; the laser half a metre ahead of the robot
        assert_eq!(scans.len(), 2);
        assert!((scans[0].translation.x - 1.5).abs() < 1e-9 && (scans[0].translation.y - y).abs() < 1e-9);
        assert!((scans[1].translation.x - 2.5).abs() < 1e-9, "{:?}", scans[1]);
    }
    // odometry by stamp as the truth is, without the laser's mounting: the robot's own
    let topics = ScanTopics { scan: Some("/front".into()), odometry: Some("/odom".into()), ..Default::default() };
    let odometry: Vec<_> = BagScans::open(&bag, &topics).unwrap().map(|s| s.unwrap().odometry.unwrap()).collect();
    assert!((odometry[0].translation.x - 1.0).abs() < 1e-9 && (odometry[0].translation.y - 1.0).abs() < 1e-9);
    assert!((odometry[1].translation.x - 2.0).abs() < 1e-9);
    let wrong = ScanTopics { scan: Some("/front".into()), odometry: Some("/rear".into()), ..Default::default() };
    match BagScans::open(&bag, &wrong) {
        Err(BagScanError::Topic { message: e, .. }) => assert!(e.contains("odometry topic /rear holds"), "{e}"),
        other => panic!("{:?}", other.map(|_| ())),
    }
}

/// A bag's /tf_static: a laser rolled 180 degrees has its scans read mirrored, and an Odometry
/// truth of base_link is composed with the mount; a PoseStamped truth is taken as the laser's.
#[test]
fn a_bag_s_static_transforms_mount_the_laser() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("flipped.mcap");
    // rolled 180 degrees (quaternion x = 1), 0.2 m ahead of base_link, 0.3 m up
    let tf = msg::TfMessage {
        transforms: vec![msg::TransformStamped {
            header: Header { stamp: at(0), frame_id: "base_link".into() },
            child_frame_id: "laser".into(),
            transform: msg::Transform { translation: [0.2, 0.0, 0.3], rotation: [1.0, 0.0, 0.0, 0.0] },
        }],
    };
    let robot = |k: u32| msg::Odometry {
        header: Header { stamp: at(k), frame_id: "map".into() },
        child_frame_id: "base_link".into(),
        pose: msg::PoseWithCovariance { pose: msg::Pose::from_planar(1.0 + k as f64, 0.0, 0.0), ..Default::default() },
        ..Default::default()
    };
    let stamped = |k: u32| msg::PoseStamped {
        header: Header { stamp: at(k), frame_id: "map".into() },
        pose: msg::Pose::from_planar(1.0 + k as f64, 0.0, 0.0),
    };
    write_bag(
        &path,
        &[
            ("/tf_static", msg::TfMessage::TYPE, tf.encode()),
            ("/truth", msg::Odometry::TYPE, robot(0).encode()),
            ("/posed", msg::PoseStamped::TYPE, stamped(0).encode()),
            ("/scan", msg::LaserScan::TYPE, scan(0, 0.1).encode()),
            ("/truth", msg::Odometry::TYPE, robot(1).encode()),
            ("/posed", msg::PoseStamped::TYPE, stamped(1).encode()),
            ("/scan", msg::LaserScan::TYPE, scan(1, 0.1).encode()),
        ],
    );
    let bag = Bag::open(&path).unwrap();
    let topics = ScanTopics { truth: Some("/truth".into()), ..Default::default() };
    let scans = BagScans::open(&bag, &topics).unwrap();
    let (frame, mount) = scans.mount().cloned().unwrap();
    assert!(frame == "laser" && mount.upside_down && (mount.pose.translation.x - 0.2).abs() < 1e-12);
    let read: Vec<_> = scans.map(|s| s.unwrap().scan).collect();
    // the beams turn clockwise: the first at +0.2 rad, the last at -0.2
    let g = &read[0].geometry;
    assert!((g.angle(0) - 0.2).abs() < 1e-6 && (g.angle(4) + 0.2).abs() < 1e-6, "{g:?}");
    // the robot's pose composed with the mount
    let truth = read[1].truth.unwrap();
    assert!((truth.translation.x - 2.2).abs() < 1e-9, "{truth:?}");
    // a PoseStamped's truth is the laser's own unless --laser-pose says
    let posed = ScanTopics { truth: Some("/posed".into()), ..Default::default() };
    let truth = BagScans::open(&bag, &posed).unwrap().nth(1).unwrap().unwrap().scan.truth.unwrap();
    assert!((truth.translation.x - 2.0).abs() < 1e-9, "{truth:?}");
}

/// A transform of `child` in `parent` at stamp `k`: at `x, y`, turned by `yaw`, `z` up.
fn transform(k: u32, parent: &str, child: &str, (x, y, z): (f64, f64, f64), yaw: f64) -> msg::TransformStamped {
    let (s, c) = (yaw / 2.0).sin_cos();
    msg::TransformStamped {
        header: Header { stamp: at(k), frame_id: parent.into() },
        child_frame_id: child.into(),
        transform: msg::Transform { translation: [x, y, z], rotation: [0.0, 0.0, s, c] },
    }
}

/// Odometry off /tf, as robots that publish it only there leave it: the transforms from odom to
/// base_footprint, from which /tf_static hangs base_link and the laser 0.3 m ahead. The other
/// transforms on /tf (map -> odom, a wheel) are passed over, and the odometry is the laser's:
/// composed with its place, so a turn moves the laser ahead of the axle as it moved. An odometry
/// frame that /tf does not hold is an error that says what it holds.
#[test]
fn odometry_comes_off_tf_and_moves_the_laser_as_it_moved() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("tf.mcap");
    let fixed = msg::TfMessage {
        transforms: vec![
            transform(0, "base_footprint", "base_link", (0.0, 0.0, 0.1), 0.0),
            transform(0, "/base_link", "laser", (0.3, 0.0, 0.2), 0.0),
        ],
    };
    let base = |k: u32| (0.5 * k as f64, 0.0, 0.4 * k as f64);
    let mut messages = vec![("/tf_static", msg::TfMessage::TYPE, fixed.encode())];
    for k in 0..4 {
        let (x, y, yaw) = base(k);
        let tf = msg::TfMessage {
            transforms: vec![
                transform(k, "map", "odom", (7.0, -3.0, 0.0), 1.0 + k as f64),
                transform(k, "/odom", "base_footprint", (x, y, 0.0), yaw),
                transform(k, "base_link", "wheel", (0.0, 0.2, 0.0), 2.0 * k as f64),
            ],
        };
        messages.push(("/tf", msg::TfMessage::TYPE, tf.encode()));
        messages.push(("/scan", msg::LaserScan::TYPE, scan(k, 0.1).encode()));
    }
    write_bag(&path, &messages);
    let bag = Bag::open(&path).unwrap();
    let topics = ScanTopics { odometry: Some("/tf".into()), ..Default::default() };
    let scans = BagScans::open(&bag, &topics).unwrap();
    let said = scans.odometry_said().unwrap_or_default().to_owned();
    assert!(said.contains("odom -> base_footprint") && said.contains("(0.300, 0.000) m"), "{said}");
    let odometry: Vec<_> = scans.map(|s| s.unwrap().odometry.unwrap()).collect();
    assert_eq!(odometry.len(), 4);
    for (k, o) in odometry.iter().enumerate() {
        let (x, y, yaw) = base(k as u32);
        let laser = laser::pose(x, y, yaw) * laser::pose(0.3, 0.0, 0.0);
        assert!((o.translation.vector - laser.translation.vector).norm() < 1e-9, "scan {k}: {o:?}, not {laser:?}");
        assert!((o.rotation.angle() - laser.rotation.angle()).abs() < 1e-9, "scan {k}: {o:?}");
    }
    // a turn of 0.4 rad about the axle swings the laser sideways as well as forward
    let moved = odometry[0].inverse() * odometry[1];
    assert!(moved.translation.y > 0.1, "{moved:?}");
    // another odometry frame: none on /tf
    let wrong =
        ScanTopics { odometry: Some("/tf".into()), odom_frame: Some("wheel_odom".into()), ..Default::default() };
    match BagScans::open(&bag, &wrong) {
        Err(BagScanError::Topic { message: e, .. }) => {
            assert!(e.contains("no transform from wheel_odom") && e.contains("odom -> base_footprint"), "{e}");
            assert!(e.contains("--odom-frame"), "{e}");
        }
        other => panic!("{:?}", other.map(|_| ())),
    }
    // an Odometry topic of base_footprint is composed with the laser's place the same way
    let odom = |k: u32| {
        let (x, y, yaw) = base(k);
        msg::Odometry {
            header: Header { stamp: at(k), frame_id: "odom".into() },
            child_frame_id: "base_footprint".into(),
            pose: msg::PoseWithCovariance { pose: msg::Pose::from_planar(x, y, yaw), ..Default::default() },
            ..Default::default()
        }
    };
    let path = dir.path().join("odom.mcap");
    let mut messages = vec![("/tf_static", msg::TfMessage::TYPE, fixed.encode())];
    for k in 0..2 {
        messages.push(("/odom", msg::Odometry::TYPE, odom(k).encode()));
        messages.push(("/scan", msg::LaserScan::TYPE, scan(k, 0.1).encode()));
    }
    write_bag(&path, &messages);
    let bag = Bag::open(&path).unwrap();
    let topics = ScanTopics { odometry: Some("/odom".into()), ..Default::default() };
    let by_odom: Vec<_> = BagScans::open(&bag, &topics).unwrap().map(|s| s.unwrap().odometry.unwrap()).collect();
    assert!((by_odom[1].translation.vector - odometry[1].translation.vector).norm() < 1e-9, "{by_odom:?}");
}

/// A bag whose mounts come on /tf, again and again, as ROS 1 robots publish them: the laser,
/// rolled 180 degrees 0.2 m ahead of base_link, is placed as /tf_static would place it, while
/// odometry moving on /tf places nothing.
#[test]
fn a_mount_repeated_on_tf_places_the_laser_as_tf_static_would() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("ros1-like.mcap");
    let mut messages = Vec::new();
    for k in 0..3 {
        let mut mount = transform(k, "base_link", "laser", (0.2, 0.0, 0.3), 0.0);
        mount.transform.rotation = [1.0, 0.0, 0.0, 0.0];
        let tf =
            msg::TfMessage { transforms: vec![mount, transform(k, "odom", "base_link", (k as f64, 0.0, 0.0), 0.0)] };
        messages.push(("/tf", msg::TfMessage::TYPE, tf.encode()));
        messages.push(("/scan", msg::LaserScan::TYPE, scan(k, 0.1).encode()));
    }
    write_bag(&path, &messages);
    let bag = Bag::open(&path).unwrap();
    let scans = BagScans::open(&bag, &ScanTopics::default()).unwrap();
    let (frame, mount) = scans.mount().cloned().unwrap();
    assert!(frame == "laser" && mount.upside_down && (mount.pose.translation.x - 0.2).abs() < 1e-12, "{mount:?}");
    let read: Vec<_> = scans.map(|s| s.unwrap().scan).collect();
    let g = &read[0].geometry;
    assert!((g.angle(0) - 0.2).abs() < 1e-6 && (g.angle(4) + 0.2).abs() < 1e-6, "mirrored: {g:?}");
}
