//! What a bag holds, whatever its storage: its topics, its messages, and why one cannot be
//! read. Shared by the bag ([`crate::bag`]) and the readers of each storage
//! ([`crate::mcap_file`], [`crate::db3`]).

use std::path::PathBuf;
use std::sync::Arc;
use thiserror::Error;

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
    #[error("{path}: not a bag: neither a directory with metadata.yaml nor an .mcap file")]
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
    /// The message, CDR.
    pub data: Vec<u8>,
}
