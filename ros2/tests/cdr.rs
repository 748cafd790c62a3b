//! The bytes the DDS client writes for a message (serde, through `cdr-encoding`, as RustDDS
//! does) are the bytes the bag reader's hand-written CDR writes: one layout, two encoders that
//! agree, and each reads what the other wrote.

use byteorder::LittleEndian;
use ros::msg::*;

fn header() -> Header {
    Header { stamp: Time { sec: 7, nanosec: 25_000_000 }, frame_id: "laser".into() }
}

fn agree<T>(m: &T, hand: Vec<u8>)
where
    T: serde::Serialize + serde::de::DeserializeOwned + PartialEq + std::fmt::Debug,
{
    let serde_bytes = cdr_encoding::to_vec::<T, LittleEndian>(m).unwrap();
    assert_eq!(serde_bytes, hand[4..], "{m:?}");
    let (back, _) = cdr_encoding::from_bytes::<T, LittleEndian>(&hand[4..]).unwrap();
    assert_eq!(&back, m);
}

#[test]
fn serde_and_the_hand_written_encoder_lay_out_the_same_bytes() {
    let scan = LaserScan {
        header: header(),
        angle_min: -2.35,
        angle_max: 2.35,
        angle_increment: 0.0043,
        range_min: 0.02,
        range_max: 10.0,
        ranges: vec![1.0, 2.5, f32::INFINITY],
        intensities: vec![],
        ..Default::default()
    };
    agree(&scan, scan.encode());
    let mut c = [0.0; 36];
    c[0] = 0.0025;
    c[35] = 0.0004;
    let pose = PoseWithCovarianceStamped {
        header: Header { frame_id: "map".into(), ..header() },
        pose: PoseWithCovariance { pose: Pose::from_planar(1.0, 2.0, 0.3), covariance: Covariance(c) },
    };
    agree(&pose, pose.encode());
    let stamped = PoseStamped { header: header(), pose: Pose::from_planar(-1.0, 0.5, 2.0) };
    agree(&stamped, stamped.encode());
}
