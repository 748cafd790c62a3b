//! ROS 2 interop without a ROS installation: the messages gema2 reads and writes, in the CDR
//! encoding ROS 2 puts on the wire and in bags ([`cdr`], [`msg`]); a `sensor_msgs/LaserScan` as
//! the scan every stage sees, read as REP 117 says ([`scan`]); and rosbag2 bags in MCAP and
//! sqlite3 storage ([`bag`], [`db3`]), and ROS 1 bags, whose ROS 1 serialization the same
//! decoders read ([`ros1_bag`]).
//!
//! One job: ROS 2 bytes in and out. Depends on `laser` (what a scan and a pose are) and the
//! `mcap` crate; nothing here knows the algorithm or the pipeline.

pub mod bag;
pub mod bag_scans;
pub mod cdr;
pub mod db3;
pub mod frames;
pub mod mcap_file;
pub mod msg;
pub mod ros1_bag;
pub mod scan;
pub mod stored;

pub use bag::{Bag, BagError, BagMessage};
pub use bag_scans::{BagScan, BagScanError, BagScans, ScanTopics};
pub use cdr::CdrError;
pub use scan::{laser_scan, ScanError};

/// A planar pose given on a command line, `x,y,yaw` (metres, radians): a laser's place on the
/// robot.
pub fn planar_pose_arg(s: &str) -> Result<(f64, f64, f64), String> {
    let v: Vec<f64> =
        s.split(',').map(|t| t.trim().parse::<f64>()).collect::<Result<_, _>>().map_err(|e| format!("{s}: {e}"))?;
    match v.as_slice() {
        &[x, y, yaw] if v.iter().all(|c| c.is_finite()) => Ok((x, y, yaw)),
        _ => Err(format!("{s}: three finite numbers x,y,yaw (metres, radians)")),
    }
}

/// The DDS domain to join: `given` (a `--domain`), else `$ROS_DOMAIN_ID` as every ROS 2 node
/// reads it, else 0.
pub fn domain_id(given: Option<u16>) -> Result<u16, String> {
    match (given, std::env::var("ROS_DOMAIN_ID")) {
        (Some(d), _) => Ok(d),
        (None, Ok(d)) => d.trim().parse().map_err(|_| format!("ROS_DOMAIN_ID={d}: not a domain number")),
        (None, Err(_)) => Ok(0),
    }
}
