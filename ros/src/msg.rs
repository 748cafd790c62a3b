//! The ROS 2 messages gema2 reads and writes, field for field as their `.msg` files define
//! them, with their CDR encoding ([`Decode`] / `encode`, for bags; [`Decode::decode_as`] also
//! reads a ROS 1 bag's serialization of the same message). Names are ROS's. Each also
//! derives serde in field order, which is how a serde CDR encoder (a DDS client's) lays out the
//! same bytes: fixed arrays as tuples, vectors and strings with their lengths.

use crate::cdr::{CdrError, CdrReader, CdrWriter, Encoding};
use serde::{Deserialize, Serialize};

/// `builtin_interfaces/msg/Time`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Time {
    pub sec: i32,
    pub nanosec: u32,
}

impl Time {
    pub fn seconds(&self) -> f64 {
        self.sec as f64 + self.nanosec as f64 * 1e-9
    }

    /// The time of `ns` nanoseconds since the epoch.
    pub fn from_nanos(ns: u64) -> Self {
        Time { sec: (ns / 1_000_000_000) as i32, nanosec: (ns % 1_000_000_000) as u32 }
    }

    pub fn nanos(&self) -> i64 {
        self.sec as i64 * 1_000_000_000 + self.nanosec as i64
    }

    fn decode(r: &mut CdrReader) -> Result<Self, CdrError> {
        Ok(Time { sec: r.i32()?, nanosec: r.u32()? })
    }

    fn encode(&self, w: &mut CdrWriter) {
        w.i32(self.sec);
        w.u32(self.nanosec);
    }
}

/// `std_msgs/msg/Header`.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Header {
    pub stamp: Time,
    pub frame_id: String,
}

impl Header {
    fn decode(r: &mut CdrReader) -> Result<Self, CdrError> {
        if r.is_ros1() {
            // ROS 1's header opens with a sequence number ROS 2 dropped
            r.u32()?;
        }
        Ok(Header { stamp: Time::decode(r)?, frame_id: r.string()? })
    }

    fn encode(&self, w: &mut CdrWriter) {
        self.stamp.encode(w);
        w.string(&self.frame_id);
    }
}

/// `sensor_msgs/msg/LaserScan`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct LaserScan {
    pub header: Header,
    pub angle_min: f32,
    pub angle_max: f32,
    pub angle_increment: f32,
    pub time_increment: f32,
    pub scan_time: f32,
    pub range_min: f32,
    pub range_max: f32,
    pub ranges: Vec<f32>,
    pub intensities: Vec<f32>,
}

impl LaserScan {
    pub const TYPE: &'static str = "sensor_msgs/msg/LaserScan";

    pub fn encode(&self) -> Vec<u8> {
        let mut w = CdrWriter::new();
        self.header.encode(&mut w);
        for v in [
            self.angle_min,
            self.angle_max,
            self.angle_increment,
            self.time_increment,
            self.scan_time,
            self.range_min,
            self.range_max,
        ] {
            w.f32(v);
        }
        w.f32_seq(&self.ranges);
        w.f32_seq(&self.intensities);
        w.finish()
    }
}

/// `geometry_msgs/msg/Pose`: a position and an orientation quaternion (x, y, z, w).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Pose {
    pub position: [f64; 3],
    pub orientation: [f64; 4],
}

impl Default for Pose {
    fn default() -> Self {
        Pose { position: [0.0; 3], orientation: [0.0, 0.0, 0.0, 1.0] }
    }
}

impl Pose {
    /// The planar pose x, y, yaw (the rotation about z).
    pub fn planar(&self) -> (f64, f64, f64) {
        let [qx, qy, qz, qw] = self.orientation;
        let yaw = (2.0 * (qw * qz + qx * qy)).atan2(1.0 - 2.0 * (qy * qy + qz * qz));
        (self.position[0], self.position[1], yaw)
    }

    /// The pose at x, y turned by `yaw` about z.
    pub fn from_planar(x: f64, y: f64, yaw: f64) -> Self {
        let (s, c) = (yaw / 2.0).sin_cos();
        Pose { position: [x, y, 0.0], orientation: [0.0, 0.0, s, c] }
    }

    fn decode(r: &mut CdrReader) -> Result<Self, CdrError> {
        Ok(Pose { position: r.f64_array()?, orientation: r.f64_array()? })
    }

    fn encode(&self, w: &mut CdrWriter) {
        self.position.iter().chain(&self.orientation).for_each(|&v| w.f64(v));
    }
}

/// `geometry_msgs/msg/PoseStamped`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct PoseStamped {
    pub header: Header,
    pub pose: Pose,
}

impl PoseStamped {
    pub const TYPE: &'static str = "geometry_msgs/msg/PoseStamped";

    pub fn encode(&self) -> Vec<u8> {
        let mut w = CdrWriter::new();
        self.header.encode(&mut w);
        self.pose.encode(&mut w);
        w.finish()
    }
}

/// A 6x6 covariance, row-major over x, y, z and the rotations about x, y and z: 36 numbers
/// with no length before them (serde's derive stops at arrays of 32).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Covariance(pub [f64; 36]);

impl Default for Covariance {
    fn default() -> Self {
        Covariance([0.0; 36])
    }
}

impl Serialize for Covariance {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeTuple;
        let mut t = s.serialize_tuple(36)?;
        for v in &self.0 {
            t.serialize_element(v)?;
        }
        t.end()
    }
}

impl<'de> Deserialize<'de> for Covariance {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct Visit;
        impl<'de> serde::de::Visitor<'de> for Visit {
            type Value = Covariance;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("36 numbers")
            }
            fn visit_seq<A: serde::de::SeqAccess<'de>>(self, mut seq: A) -> Result<Covariance, A::Error> {
                let mut c = [0.0; 36];
                for (k, v) in c.iter_mut().enumerate() {
                    *v = seq.next_element()?.ok_or_else(|| serde::de::Error::invalid_length(k, &self))?;
                }
                Ok(Covariance(c))
            }
        }
        d.deserialize_tuple(36, Visit)
    }
}

/// `geometry_msgs/msg/PoseWithCovariance`.
#[derive(Clone, Copy, Default, Debug, PartialEq, Serialize, Deserialize)]
pub struct PoseWithCovariance {
    pub pose: Pose,
    pub covariance: Covariance,
}

impl PoseWithCovariance {
    fn decode(r: &mut CdrReader) -> Result<Self, CdrError> {
        Ok(PoseWithCovariance { pose: Pose::decode(r)?, covariance: Covariance(r.f64_array()?) })
    }

    fn encode(&self, w: &mut CdrWriter) {
        self.pose.encode(w);
        self.covariance.0.iter().for_each(|&v| w.f64(v));
    }
}

/// `geometry_msgs/msg/PoseWithCovarianceStamped`: what gema2 publishes, and what Nav2's AMCL
/// takes on `/initialpose`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct PoseWithCovarianceStamped {
    pub header: Header,
    pub pose: PoseWithCovariance,
}

impl PoseWithCovarianceStamped {
    pub const TYPE: &'static str = "geometry_msgs/msg/PoseWithCovarianceStamped";

    pub fn encode(&self) -> Vec<u8> {
        let mut w = CdrWriter::new();
        self.header.encode(&mut w);
        self.pose.encode(&mut w);
        w.finish()
    }
}

/// `geometry_msgs/msg/Twist`: linear and angular velocity.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Twist {
    pub linear: [f64; 3],
    pub angular: [f64; 3],
}

/// `geometry_msgs/msg/TwistWithCovariance`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct TwistWithCovariance {
    pub twist: Twist,
    pub covariance: Covariance,
}

/// `nav_msgs/msg/Odometry` (the bag reader reads past its twist).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Odometry {
    pub header: Header,
    pub child_frame_id: String,
    pub pose: PoseWithCovariance,
    pub twist: TwistWithCovariance,
}

impl Odometry {
    pub const TYPE: &'static str = "nav_msgs/msg/Odometry";

    /// The twist is written as zero.
    pub fn encode(&self) -> Vec<u8> {
        let mut w = CdrWriter::new();
        self.header.encode(&mut w);
        w.string(&self.child_frame_id);
        self.pose.encode(&mut w);
        (0..6 + 36).for_each(|_| w.f64(0.0));
        w.finish()
    }
}

/// `nav_msgs/msg/MapMetaData`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct MapMetaData {
    pub map_load_time: Time,
    /// Metres a cell.
    pub resolution: f32,
    pub width: u32,
    pub height: u32,
    /// The pose of cell (0, 0)'s corner in the map frame.
    pub origin: Pose,
}

/// `nav_msgs/msg/OccupancyGrid`: row-major from cell (0, 0), each -1 (unknown) or 0-100
/// (occupancy, percent), as a ROS map_server publishes `/map`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct OccupancyGrid {
    pub header: Header,
    pub info: MapMetaData,
    pub data: Vec<i8>,
}

/// `geometry_msgs/msg/Transform`: a translation and a rotation quaternion (x, y, z, w).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Transform {
    pub translation: [f64; 3],
    pub rotation: [f64; 4],
}

/// `geometry_msgs/msg/TransformStamped`: `child_frame_id`'s pose in `header.frame_id`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TransformStamped {
    pub header: Header,
    pub child_frame_id: String,
    pub transform: Transform,
}

/// `tf2_msgs/msg/TFMessage`, as on `/tf_static`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct TfMessage {
    pub transforms: Vec<TransformStamped>,
}

impl TfMessage {
    pub const TYPE: &'static str = "tf2_msgs/msg/TFMessage";

    pub fn encode(&self) -> Vec<u8> {
        let mut w = CdrWriter::new();
        w.u32(self.transforms.len() as u32);
        for t in &self.transforms {
            t.header.encode(&mut w);
            w.string(&t.child_frame_id);
            t.transform.translation.iter().chain(&t.transform.rotation).for_each(|&v| w.f64(v));
        }
        w.finish()
    }
}

/// A whole message, read field by field from CDR or from ROS 1's serialization (the reader
/// knows which: its `std_msgs/Header` reads the `seq` only ROS 1 has).
pub trait Decode: Sized {
    /// The message's fields, from `r`.
    fn read(r: &mut CdrReader) -> Result<Self, CdrError>;

    /// Decodes CDR `bytes`, their encapsulation header first.
    fn decode(bytes: &[u8]) -> Result<Self, CdrError> {
        Self::decode_as(Encoding::Cdr, bytes)
    }

    /// Decodes `bytes` laid out as `encoding` says.
    fn decode_as(encoding: Encoding, bytes: &[u8]) -> Result<Self, CdrError> {
        Self::read(&mut CdrReader::of(encoding, bytes)?)
    }
}

impl Decode for LaserScan {
    fn read(r: &mut CdrReader) -> Result<Self, CdrError> {
        Ok(LaserScan {
            header: Header::decode(r)?,
            angle_min: r.f32()?,
            angle_max: r.f32()?,
            angle_increment: r.f32()?,
            time_increment: r.f32()?,
            scan_time: r.f32()?,
            range_min: r.f32()?,
            range_max: r.f32()?,
            ranges: r.f32_seq()?,
            intensities: r.f32_seq()?,
        })
    }
}

impl Decode for PoseStamped {
    fn read(r: &mut CdrReader) -> Result<Self, CdrError> {
        Ok(PoseStamped { header: Header::decode(r)?, pose: Pose::decode(r)? })
    }
}

impl Decode for PoseWithCovarianceStamped {
    fn read(r: &mut CdrReader) -> Result<Self, CdrError> {
        Ok(PoseWithCovarianceStamped { header: Header::decode(r)?, pose: PoseWithCovariance::decode(r)? })
    }
}

impl Decode for Odometry {
    fn read(r: &mut CdrReader) -> Result<Self, CdrError> {
        Ok(Odometry {
            header: Header::decode(r)?,
            child_frame_id: r.string()?,
            pose: PoseWithCovariance::decode(r)?,
            twist: TwistWithCovariance::default(),
        })
    }
}

impl Decode for TfMessage {
    fn read(r: &mut CdrReader) -> Result<Self, CdrError> {
        // each transform takes at least 64 bytes: the length check bounds the allocation
        let n = r.len(64, "a TransformStamped[]")?;
        let transforms = (0..n)
            .map(|_| {
                Ok(TransformStamped {
                    header: Header::decode(r)?,
                    child_frame_id: r.string()?,
                    transform: Transform { translation: r.f64_array()?, rotation: r.f64_array()? },
                })
            })
            .collect::<Result<_, CdrError>>()?;
        Ok(TfMessage { transforms })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn header() -> Header {
        Header { stamp: Time { sec: 1_700_000_000, nanosec: 123_456_789 }, frame_id: "laser".into() }
    }

    #[test]
    fn every_message_reads_back_what_was_written() {
        let scan = LaserScan {
            header: header(),
            angle_min: -2.0,
            angle_max: 2.0,
            angle_increment: 0.5,
            range_min: 0.02,
            range_max: 30.0,
            ranges: vec![1.0, f32::INFINITY, 3.0, 0.0, 5.0, 6.0, 7.0, 8.0, 9.0],
            ..Default::default()
        };
        assert_eq!(LaserScan::decode(&scan.encode()).unwrap(), scan);
        let tf = TfMessage {
            transforms: vec![TransformStamped {
                header: header(),
                child_frame_id: "laser".into(),
                transform: Transform { translation: [0.1, 0.2, 0.3], rotation: [1.0, 0.0, 0.0, 0.0] },
            }],
        };
        assert_eq!(TfMessage::decode(&tf.encode()).unwrap(), tf);
        let pose = PoseStamped { header: header(), pose: Pose::from_planar(1.0, -2.0, 3.0) };
        assert_eq!(PoseStamped::decode(&pose.encode()).unwrap(), pose);
        let mut covariance = [0.0; 36];
        covariance[0] = 0.25;
        covariance[35] = 0.01;
        let with = PoseWithCovarianceStamped {
            header: header(),
            pose: PoseWithCovariance { pose: Pose::from_planar(4.0, 5.0, -1.0), covariance: Covariance(covariance) },
        };
        assert_eq!(PoseWithCovarianceStamped::decode(&with.encode()).unwrap(), with);
        let odom =
            Odometry { header: header(), child_frame_id: "base_link".into(), pose: with.pose, ..Default::default() };
        assert_eq!(Odometry::decode(&odom.encode()).unwrap(), odom);
    }

    #[test]
    fn planar_poses_keep_their_yaw() {
        for yaw in [-3.1, -1.0, 0.0, 0.5, 3.1] {
            let (x, y, t) = Pose::from_planar(1.0, 2.0, yaw).planar();
            assert_eq!((x, y), (1.0, 2.0));
            assert!((t - yaw).abs() < 1e-12);
        }
    }

    #[test]
    fn a_cut_message_is_an_error_at_every_length() {
        let scan = LaserScan { header: header(), ranges: vec![1.0; 20], range_max: 5.0, ..Default::default() };
        let bytes = scan.encode();
        for n in 0..bytes.len() {
            assert!(LaserScan::decode(&bytes[..n]).is_err(), "cut at {n}");
        }
    }
}
