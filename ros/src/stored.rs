//! What a bag holds, whatever its storage: its topics, its messages, and why one cannot be
//! read. Shared by the bag ([`crate::bag`]) and the readers of each storage
//! ([`crate::mcap_file`], [`crate::db3`], [`crate::ros1_bag`]).

pub use crate::cdr::Encoding;
use std::path::PathBuf;
use std::sync::Arc;
use thiserror::Error;

/// Largest record or chunk a bag reader takes in, bytes, whatever the storage: a chunk holds
/// about a megabyte of messages (rosbag closes one at 768 KB), or one message larger than that
/// (a camera frame, a point cloud); a larger declared size is a corrupt or hostile file,
/// refused rather than allocated.
pub const MAX_RECORD_BYTES: usize = 1 << 30;

#[derive(Debug, Error)]
pub enum BagError {
    // the cause in the message, not chained too: it would print twice
    #[error("{path}: {cause}")]
    Io { path: PathBuf, cause: std::io::Error },
    #[error("{path}: not a readable MCAP file: {cause}")]
    Mcap { path: PathBuf, cause: String },
    #[error("{path}: not a readable sqlite3 bag file: {cause}")]
    Sqlite { path: PathBuf, cause: String },
    #[error(
        "{path}: a bag in {storage} storage; gema2 reads MCAP and sqlite3 bags, uncompressed: convert it with \
         `ros2 bag convert` or `rosbags-convert --dst-storage mcap`"
    )]
    Storage { path: PathBuf, storage: String },
    #[error("{path}: not a readable ROS 1 bag: {cause}")]
    Ros1 { path: PathBuf, cause: String },
    #[error("{path}: not a bag: neither a directory with metadata.yaml, nor an .mcap, .db3 or ROS 1 .bag file")]
    NotABag { path: PathBuf },
    #[error("{path}: the bag's metadata.yaml names no data file")]
    NoFiles { path: PathBuf },
}

/// A topic of a bag.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct TopicInfo {
    pub name: String,
    /// The ROS type, e.g. `sensor_msgs/msg/LaserScan`.
    pub ros_type: String,
    /// Messages on it, when the files' summaries say.
    pub messages: Option<u64>,
}

/// One message of a bag.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct BagMessage {
    pub topic: Arc<str>,
    pub ros_type: Arc<str>,
    /// When the recorder received it, ns since the epoch.
    pub log_time: u64,
    /// The message, laid out as `encoding` says: CDR in a rosbag2 bag, ROS 1's serialization
    /// in a ROS 1 bag.
    pub data: Vec<u8>,
    pub encoding: Encoding,
}
