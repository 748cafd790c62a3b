//! Where a command reads its scans: a CARMEN log (`--log`) or a ROS 2 bag (`--bag`, MCAP
//! storage, CDR), each scan numbered as it comes, malformed ones skipped and counted.

use acquire::{CarmenReader, FlaserArgs, LogScan};
use anyhow::{Context, Result};
use clap::Args;
use std::path::{Path, PathBuf};

/// A ROS 2 bag as the source of scans.
#[derive(Args, Clone, Debug, Default)]
pub struct BagArgs {
    /// A ROS 2 bag instead of a log: its directory (with metadata.yaml) or one .mcap file.
    /// Scans are numbered by LaserScan message in bag order.
    #[arg(long, conflicts_with = "log")]
    pub bag: Option<PathBuf>,
    /// The bag's sensor_msgs/LaserScan topic (default: its only one).
    #[arg(long, requires = "bag")]
    pub scan_topic: Option<String>,
    /// A geometry_msgs/PoseStamped or nav_msgs/Odometry topic of the bag holding the true pose
    /// (in the map's frame), matched to each scan by stamp; without it the bag has no truth.
    #[arg(long, requires = "bag")]
    pub truth_topic: Option<String>,
    /// The laser's place on the robot, `x,y,yaw` (metres, radians), when the truth topic gives
    /// the robot's pose rather than the laser's.
    #[arg(long, requires = "truth_topic", value_parser = ros::planar_pose_arg, allow_hyphen_values = true)]
    pub laser_pose: Option<(f64, f64, f64)>,
    /// A nav_msgs/Odometry (or PoseStamped) topic of the bag holding the robot's odometry,
    /// matched to each scan by stamp: what `--sequential` moves its hypotheses by. Or `/tf`:
    /// the transforms from the odometry frame (--odom-frame) to the robot.
    #[arg(long, requires = "bag")]
    pub odom_topic: Option<String>,
    /// The odometry frame, when --odom-topic is a tf2_msgs/TFMessage topic such as /tf.
    #[arg(long, requires = "odom_topic", default_value = "odom")]
    pub odom_frame: String,
}

/// The scans a command reads: a log's or a bag's, every K-th from an offset.
#[derive(Args, Clone, Debug)]
pub struct ScanArgs {
    /// CARMEN log (ROBOTLASER1, FLASER or RAWLASER1; .gz is fine).
    #[arg(long, required_unless_present = "bag")]
    pub log: Option<PathBuf>,
    #[command(flatten)]
    pub flaser: acquire::FlaserArgs,
    #[command(flatten)]
    pub bag: BagArgs,
    /// Every K-th laser line (or LaserScan message)...
    #[arg(long, default_value_t = 1, value_parser = super::positive_count)]
    pub every: usize,
    /// ...starting at this one.
    #[arg(long, default_value_t = 0)]
    pub offset: usize,
}

impl ScanArgs {
    /// The log or bag these arguments name.
    pub fn open(&self) -> Result<Source> {
        Source::open(self.log.as_deref(), &self.bag, &self.flaser)
    }

    /// Whether the scan at `index` is one of those taken.
    pub fn takes(&self, index: usize) -> bool {
        super::selected(index, self.every, self.offset)
    }
}

/// Why a scan was not read.
#[derive(Debug)]
pub enum SourceError {
    /// This one scan: the ones after it can still be read.
    Skip(String),
    /// The source cannot be read on.
    Stop(anyhow::Error),
}

/// What a bag's `/tf_static` says of its laser, and what is done with it.
fn mount_said(
    frame: &str,
    mount: &ros::frames::Mount,
    truth: &Option<String>,
    laser_pose: Option<(f64, f64, f64)>,
) -> String {
    let p = &mount.pose;
    let mut said = format!(
        "/tf_static places {frame:?} at {:.3}, {:.3}, {:.1} deg on base_link",
        p.translation.x,
        p.translation.y,
        laser::pose_theta(p).to_degrees()
    );
    if mount.upside_down {
        said += ", upside down: its scans are read mirrored";
    }
    if let (Some(truth), None) = (truth, laser_pose) {
        said += &format!(
            "; the truth ({truth}) is taken as the robot's pose when it is an Odometry of base_link, else as the laser's (--laser-pose says otherwise)"
        );
    }
    said
}

/// The scans of a log or a bag.
pub struct Source {
    /// The log or bag, for messages.
    pub path: PathBuf,
    /// What the scans are called in messages: "laser line", "LaserScan message".
    pub unit: &'static str,
    /// How many scans it holds, when known beforehand.
    pub total: Option<u64>,
    pub scans: Box<dyn Iterator<Item = Result<LogScan, SourceError>>>,
}

impl Source {
    /// The scans of `log` or of `bag.bag`.
    pub fn open(log: Option<&Path>, bag: &BagArgs, flaser: &FlaserArgs) -> Result<Source> {
        if let Some(path) = &bag.bag {
            let opened = ros::Bag::open(path)?;
            let topics = ros::ScanTopics {
                scan: bag.scan_topic.clone(),
                truth: bag.truth_topic.clone(),
                laser_pose: bag.laser_pose,
                odometry: bag.odom_topic.clone(),
                odom_frame: Some(bag.odom_frame.clone()),
                base_frame: None,
            };
            let scans = ros::BagScans::open(&opened, &topics)?;
            if let Some((frame, mount)) = scans.mount() {
                eprintln!("{}: {}", path.display(), mount_said(frame, mount, &bag.truth_topic, bag.laser_pose));
            }
            if let Some(said) = scans.odometry_said() {
                eprintln!("{}: {said}", path.display());
            }
            if scans.bad_truth > 0 {
                eprintln!(
                    "{}: {} messages of the truth, odometry, /tf and /tf_static topics did not decode",
                    path.display(),
                    scans.bad_truth
                );
            }
            let total = scans.total;
            let items = scans.map(|item| match item {
                Ok(s) => Ok(LogScan { line: s.index, scan: s.scan, odometry: s.odometry }),
                Err(e) if e.is_one_message() => Err(SourceError::Skip(e.to_string())),
                Err(e) => Err(SourceError::Stop(e.into())),
            });
            return Ok(Source { path: path.clone(), unit: "LaserScan message", total, scans: Box::new(items) });
        }
        let path = log.context("no scans to read: give --log or --bag")?;
        let reader = CarmenReader::open(path, flaser.layout()?)?;
        let items = reader.map(|item| match item {
            Ok(s) => Ok(s),
            Err(e @ acquire::LogError::Line { .. }) => Err(SourceError::Skip(e.to_string())),
            Err(e) => Err(SourceError::Stop(e.into())),
        });
        Ok(Source { path: path.to_owned(), unit: "laser line", total: None, scans: Box::new(items) })
    }
}
