//! The laser scans of a bag, numbered in bag order, each with its true pose when the bag has a
//! pose topic to take it from: what `gema2 locate --bag` and `gema2 map build --bag` read.
//!
//! Truth comes from a `geometry_msgs/PoseStamped` or `nav_msgs/Odometry` topic, matched to
//! each scan by header stamp: a pose with the scan's own stamp (when several scans and poses
//! share a stamp, as in a log whose clock was written with 6 digits, the k-th scan takes the
//! k-th pose, or the one nearest in bag order when there are fewer poses), else the pose interpolated between the two around the stamp when
//! they are at most [`MAX_TRUTH_GAP_NS`] apart. A scan between poses further apart, or outside
//! them, has no truth. With the laser's place on the robot (`laser_pose`), the truth is the
//! robot's pose and the scan's is that composed with it.
//!
//! Odometry comes the same way from a second such topic (`nav_msgs/Odometry` as a robot's base
//! publishes it), or from the transforms of a `tf2_msgs/TFMessage` topic (`/tf`) from the
//! odometry frame (`odom`) to the robot, as many robots publish it only there; matched to each
//! scan by stamp. The sequential localizer reads only the motion between two scans, and the
//! motion is the laser's: where `/tf_static` places the laser on the frame odometry follows,
//! the odometry is composed with that place, so a turn moves an off-centre laser as it moved.
//!
//! A bag's `/tf_static` places the laser on the robot ([`crate::frames`]), and so does a
//! transform that `/tf` repeats unchanged through the bag, as ROS 1 robots publish their mounts
//! ([`UnchangingTf`]), where `/tf_static` says nothing of that frame: a laser mounted upside
//! down has its scans read mirrored, as the ROS 2 bridge reads them live, and the mount is told
//! ([`BagScans::mount`]) for a truth topic of the robot's pose.

use crate::bag::{Bag, BagError, Messages};
use crate::cdr::Encoding;
use crate::frames::{frame_name, Mount, StaticFrames, UnchangingTf};
use crate::msg::{self, Decode};
use laser::{interpolate, pose, LaserScan, Pose};
use thiserror::Error;

/// The widest gap between two true poses that a scan's truth is interpolated across.
pub const MAX_TRUTH_GAP_NS: i64 = 1_000_000_000;

#[derive(Debug, Error)]
pub enum BagScanError {
    /// One message that does not decode: its scan is lost, the bag reads on.
    #[error("{topic} message {index}: {cause}")]
    Message { topic: String, index: usize, cause: String },
    /// The bag cannot be read on.
    #[error(transparent)]
    Bag(#[from] BagError),
    /// The topics asked for are not in the bag (named by its path), or not of a type that can
    /// be read.
    #[error("{bag}: {message}")]
    Topic { bag: std::path::PathBuf, message: String },
}

impl BagScanError {
    /// Whether the scans after it can still be read.
    pub fn is_one_message(&self) -> bool {
        matches!(self, BagScanError::Message { .. })
    }
}

/// Which topics to read, and where the laser sits on the robot.
#[derive(Clone, Debug, Default)]
pub struct ScanTopics {
    /// The LaserScan topic; `None`: the bag's only one.
    pub scan: Option<String>,
    /// A PoseStamped or Odometry topic holding the true pose.
    pub truth: Option<String>,
    /// The laser's pose in the frame of the truth's pose (x, y, yaw), when they differ.
    pub laser_pose: Option<(f64, f64, f64)>,
    /// An Odometry or PoseStamped topic holding the robot's odometry, or a TFMessage topic
    /// (`/tf`) holding it as the transforms from `odom_frame` to the robot.
    pub odometry: Option<String>,
    /// The frame odometry is kept in, on a TFMessage odometry topic; `None`: `odom`.
    pub odom_frame: Option<String>,
    /// The robot's frame on `/tf_static`; `None`: `base_link`.
    pub base_frame: Option<String>,
}

/// The static transforms' topic.
pub const TF_STATIC: &str = "/tf_static";

/// The transforms' topic, where a ROS 1 bag keeps its mounts too ([`UnchangingTf`]).
pub const TF: &str = "/tf";

/// One scan of the bag.
#[derive(Clone, Debug)]
pub struct BagScan {
    /// Its number among the bag's LaserScan messages on its topic, from 0.
    pub index: usize,
    pub scan: LaserScan,
    /// The odometry pose at the scan's stamp, with an odometry topic.
    pub odometry: Option<Pose>,
}

/// True poses by stamp.
struct Truth {
    /// (stamp ns, order in the bag, pose), sorted by stamp then order.
    poses: Vec<(i64, usize, Pose)>,
}

impl Truth {
    /// The true pose at `stamp` of the scan `order`-th in the bag and `rank`-th of those with
    /// its stamp.
    fn at(&self, stamp: i64, rank: usize, order: usize) -> Option<Pose> {
        let from = self.poses.partition_point(|p| p.0 < stamp);
        let to = self.poses.partition_point(|p| p.0 <= stamp);
        if from < to {
            let same = &self.poses[from..to];
            return same.get(rank).or_else(|| same.iter().min_by_key(|p| p.1.abs_diff(order))).map(|p| p.2);
        }
        let (before, after) = (self.poses.get(from.checked_sub(1)?)?, self.poses.get(from)?);
        if after.0 - before.0 > MAX_TRUTH_GAP_NS {
            return None;
        }
        let s = (stamp - before.0) as f64 / (after.0 - before.0) as f64;
        Some(interpolate(&before.2, &after.2, s))
    }
}

/// The frame of `/tf` whose transforms from the odometry frame are the robot's odometry, among
/// `children` (the frames the odometry frame has transforms to, first seen first): the one the
/// laser (`laser`) hangs from through `/tf_static`, else the robot's frame `base`, else the
/// only one.
fn odometry_child<'a>(
    children: &'a [String],
    laser: Option<&str>,
    frames: &StaticFrames,
    base: &str,
) -> Option<&'a str> {
    let carries_laser = |c: &&String| laser.is_some_and(|l| frames.pose_of(l, c).is_some());
    let found = children.iter().find(carries_laser).or_else(|| children.iter().find(|c| *c == base));
    found
        .or(match children {
            [only] => Some(only),
            _ => None,
        })
        .map(String::as_str)
}

/// Odometry read off a TFMessage topic, before its frame is chosen: each transform from the
/// odometry frame (stamp, order among the scans and the topic's messages, child, pose), and the
/// other transforms' frames (parent, child), a few, for an error that says what the topic holds.
#[derive(Default)]
struct TfOdometry {
    samples: Vec<(i64, usize, String, Pose)>,
    others: Vec<(String, String)>,
}

impl TfOdometry {
    /// Keeps the transforms of `tf` from `odom_frame`.
    fn add(&mut self, tf: &msg::TfMessage, odom_frame: &str, order: usize) {
        for t in &tf.transforms {
            let (parent, child) = (frame_name(&t.header.frame_id), frame_name(&t.child_frame_id));
            if parent == odom_frame {
                if let Some(p) = crate::frames::planar(&t.transform) {
                    self.samples.push((t.header.stamp.nanos(), order, child.to_owned(), p));
                }
            } else if self.others.len() < 8 && !self.others.iter().any(|(a, b)| a == parent && b == child) {
                self.others.push((parent.to_owned(), child.to_owned()));
            }
        }
    }

    /// The frames the odometry frame has transforms to, first seen first.
    fn children(&self) -> Vec<String> {
        let mut children: Vec<String> = Vec::new();
        for (_, _, c, _) in &self.samples {
            if !children.contains(c) {
                children.push(c.clone());
            }
        }
        children
    }
}

/// A pose message's stamp and planar pose, by its type.
/// With an Odometry, the frame whose pose it is (`child_frame_id`).
fn stamped_pose(ros_type: &str, encoding: Encoding, data: &[u8]) -> Result<(i64, Pose, Option<String>), String> {
    let (header, p, child) = match ros_type {
        msg::PoseStamped::TYPE => {
            let m = msg::PoseStamped::decode_as(encoding, data).map_err(|e| e.to_string())?;
            (m.header, m.pose, None)
        }
        msg::Odometry::TYPE => {
            let m = msg::Odometry::decode_as(encoding, data).map_err(|e| e.to_string())?;
            (m.header, m.pose.pose, Some(m.child_frame_id))
        }
        other => return Err(format!("a {other}, not a PoseStamped or Odometry")),
    };
    let (x, y, yaw) = p.planar();
    if !(x.is_finite() && y.is_finite() && yaw.is_finite()) {
        return Err("a pose that is not finite".into());
    }
    Ok((header.stamp.nanos(), pose(x, y, yaw), child))
}

/// The scans of a bag, in bag order.
pub struct BagScans {
    messages: Messages,
    topic: String,
    truth: Option<Truth>,
    odometry: Option<Truth>,
    laser_pose: Option<Pose>,
    index: usize,
    /// Messages of the bag read so far (scans and others), for matching truth.
    order: usize,
    /// Scans read so far with each stamp.
    ranks: std::collections::HashMap<i64, usize>,
    /// Scans the bag holds on the topic, when its summaries say.
    pub total: Option<u64>,
    /// Messages of the truth, odometry, `/tf` and `/tf_static` topics that did not decode.
    pub bad_truth: usize,
    /// The bag's static transforms, and the robot's frame among them.
    frames: StaticFrames,
    base_frame: String,
    /// The first scan's frame and its place on the robot, when `/tf_static` gives one.
    mount: Option<(String, Mount)>,
    /// Where the odometry comes from, when it takes more than its topic's name to say.
    odometry_said: Option<String>,
}

impl BagScans {
    /// The scans of `bag` on `topics.scan`, with truth from `topics.truth`. Reads the truth
    /// topic through first.
    pub fn open(bag: &Bag, topics: &ScanTopics) -> Result<Self, BagScanError> {
        let refused = |message: String| BagScanError::Topic { bag: bag.path.clone(), message };
        let all = bag.topics()?;
        let listing = || all.iter().map(|t| format!("{} ({})", t.name, t.ros_type)).collect::<Vec<_>>().join(", ");
        let scans: Vec<_> = all.iter().filter(|t| t.ros_type == msg::LaserScan::TYPE).collect();
        let topic = match &topics.scan {
            Some(name) => match all.iter().find(|t| &t.name == name) {
                Some(t) if t.ros_type == msg::LaserScan::TYPE => t,
                Some(t) => return Err(refused(format!("{name} holds {}, not LaserScan", t.ros_type))),
                None => return Err(refused(format!("no topic {name} in the bag; it has {}", listing()))),
            },
            None => match scans.as_slice() {
                [only] => only,
                [] => return Err(refused(format!("no LaserScan topic in the bag; it has {}", listing()))),
                several => {
                    let names: Vec<&str> = several.iter().map(|t| t.name.as_str()).collect();
                    return Err(refused(format!(
                        "the bag has {} LaserScan topics ({}): say which with --scan-topic",
                        names.len(),
                        names.join(", ")
                    )));
                }
            },
        };
        // the truth and odometry topics, checked before anything is read
        let pose_topic = |name: &String, what: &str, tf: bool| -> Result<bool, BagScanError> {
            let Some(t) = all.iter().find(|t| &t.name == name) else {
                return Err(refused(format!("no {what} topic {name} in the bag; it has {}", listing())));
            };
            if tf && t.ros_type == msg::TfMessage::TYPE {
                return Ok(true);
            }
            if t.ros_type != msg::PoseStamped::TYPE && t.ros_type != msg::Odometry::TYPE {
                let tf = if tf { ", TFMessage" } else { "" };
                return Err(refused(format!(
                    "the {what} topic {name} holds {}, not PoseStamped{tf} or Odometry",
                    t.ros_type
                )));
            }
            Ok(false)
        };
        if let Some(name) = &topics.truth {
            pose_topic(name, "truth", false)?;
        }
        let odometry_tf = match &topics.odometry {
            Some(name) => pose_topic(name, "odometry", true)?,
            None => false,
        };
        let odom_frame = topics.odom_frame.as_deref().map_or("odom", frame_name).to_owned();
        let mut tf_odometry = TfOdometry::default();
        // whose pose the odometry is, when its messages say (an Odometry's child frame)
        let mut odometry_frame: Option<String> = None;
        let has_tf_static = all.iter().any(|t| t.name == TF_STATIC && t.ros_type == msg::TfMessage::TYPE);
        let has_tf_dynamic = all.iter().any(|t| t.name == TF && t.ros_type == msg::TfMessage::TYPE);
        let has_tf = has_tf_static || has_tf_dynamic;
        // the mounts a bag repeats on /tf, for the frames /tf_static does not place
        let mut unchanging = UnchangingTf::default();
        // one pass through the bag for the truth, the odometry, /tf_static and the laser's
        // frame. Each pose keeps its place among the scans and its own topic's messages: the
        // scans' reading pass counts the truth's order the same way
        let mut bad_truth = 0;
        let (mut truth_poses, mut odometry_poses) = (Vec::new(), Vec::new());
        // whose pose the truth is, when its messages say (an Odometry's child frame)
        let mut truth_frame: Option<String> = None;
        let mut frames = StaticFrames::default();
        let mut pass: Vec<&str> = Vec::new();
        for name in [
            topics.truth.as_deref(),
            topics.odometry.as_deref(),
            has_tf_static.then_some(TF_STATIC),
            has_tf_dynamic.then_some(TF),
        ]
        .into_iter()
        .flatten()
        {
            if !pass.contains(&name) {
                pass.push(name);
            }
        }
        // the first scan that decodes names the laser's frame, for its place on /tf_static
        let mut laser_frame: Option<String> = None;
        if !pass.is_empty() {
            pass.push(&topic.name);
            let (mut truth_order, mut odometry_order) = (0, 0);
            for m in bag.messages(&pass) {
                let m = m?;
                let on_scans = *m.topic == *topic.name;
                let on_truth = topics.truth.as_deref() == Some(&*m.topic);
                let on_odometry = topics.odometry.as_deref() == Some(&*m.topic);
                if on_odometry && odometry_tf {
                    match msg::TfMessage::decode_as(m.encoding, &m.data) {
                        Ok(tf) => {
                            tf_odometry.add(&tf, &odom_frame, odometry_order);
                            if *m.topic == *TF {
                                unchanging.observe(&tf);
                            }
                        }
                        Err(_) => bad_truth += 1,
                    }
                } else if on_truth || on_odometry {
                    match stamped_pose(&m.ros_type, m.encoding, &m.data) {
                        Ok((stamp, p, frame)) => {
                            if on_truth {
                                truth_poses.push((stamp, truth_order, p));
                                truth_frame = truth_frame.or_else(|| frame.clone());
                            }
                            if on_odometry {
                                odometry_poses.push((stamp, odometry_order, p));
                                odometry_frame = odometry_frame.or_else(|| frame.clone());
                            }
                        }
                        Err(_) => bad_truth += usize::from(on_truth) + usize::from(on_odometry),
                    }
                } else if *m.topic == *TF_STATIC {
                    match msg::TfMessage::decode_as(m.encoding, &m.data) {
                        Ok(tf) => frames.add(&tf),
                        Err(_) => bad_truth += 1,
                    }
                } else if *m.topic == *TF {
                    match msg::TfMessage::decode_as(m.encoding, &m.data) {
                        Ok(tf) => unchanging.observe(&tf),
                        Err(_) => bad_truth += 1,
                    }
                } else if on_scans && has_tf && laser_frame.is_none() {
                    laser_frame = msg::LaserScan::decode_as(m.encoding, &m.data).ok().map(|s| s.header.frame_id);
                }
                truth_order += usize::from(on_scans || on_truth);
                odometry_order += usize::from(on_scans || on_odometry);
            }
        }
        let sorted = |mut poses: Vec<(i64, usize, Pose)>| {
            poses.sort_by_key(|p| (p.0, p.1));
            Truth { poses }
        };
        unchanging.add_to(&mut frames);
        let truth = topics.truth.as_ref().map(|_| sorted(truth_poses));
        let base_frame = topics.base_frame.clone().unwrap_or_else(|| "base_link".into());
        // the odometry of one frame: a TFMessage topic's child of the odometry frame chosen
        let mut odometry_said = None;
        if let (Some(name), true) = (&topics.odometry, odometry_tf) {
            let children = tf_odometry.children();
            let Some(child) = odometry_child(&children, laser_frame.as_deref(), &frames, &base_frame) else {
                let had = |pairs: Vec<String>| if pairs.is_empty() { "none".to_owned() } else { pairs.join(", ") };
                let others = tf_odometry.others.iter().map(|(a, b)| format!("{a} -> {b}")).collect();
                let from_odom = children.iter().map(|c| format!("{odom_frame} -> {c}")).collect();
                return Err(refused(format!(
                    "the odometry topic {name} holds no transform from {odom_frame} to the robot \
                     ({base_frame}, or a frame /tf_static hangs the laser from); from {odom_frame}: {}; \
                     others: {} (--odom-frame names the odometry frame)",
                    had(from_odom),
                    had(others)
                )));
            };
            odometry_poses = tf_odometry
                .samples
                .iter()
                .filter(|s| s.2 == child)
                .map(|&(stamp, order, _, p)| (stamp, order, p))
                .collect();
            odometry_said = Some(format!("odometry from {name}: {odom_frame} -> {child}"));
            odometry_frame = Some(child.to_owned());
        }
        // the laser's motion: the odometry composed with the laser's place on its frame
        let place = odometry_frame.as_deref().and_then(|f| frames.pose_of(laser_frame.as_deref()?, frame_name(f)));
        if let (Some(place), Some(frame)) = (place.filter(|p| *p != Pose::identity()), &odometry_frame) {
            for p in &mut odometry_poses {
                p.2 *= place;
            }
            let said = odometry_said.get_or_insert_with(|| format!("odometry of {}", frame_name(frame)));
            let (x, y) = (place.translation.x, place.translation.y);
            let yaw = place.rotation.angle().to_degrees();
            said.push_str(&format!(", composed with the laser's place on it ({x:.3}, {y:.3}) m, {yaw:.1} deg"));
        }
        let odometry = topics.odometry.as_ref().map(|_| sorted(odometry_poses));
        // the laser's place, by the frame of the first scan that decodes
        let mount = laser_frame.and_then(|f| Some((f.clone(), frames.mount_of(&f, &base_frame)?)));
        // the truth is the robot's when an Odometry says so: the laser sits where /tf_static
        // puts it, unless told otherwise
        let of_robot = truth_frame.as_deref().map(frame_name) == Some(base_frame.as_str());
        let laser_pose = topics
            .laser_pose
            .map(|(x, y, t)| pose(x, y, t))
            .or_else(|| mount.as_ref().filter(|_| of_robot).map(|(_, m): &(String, Mount)| m.pose));
        // the scans' order among the truth topic's messages, as `read` counted it
        let wanted: Vec<&str> = [Some(topic.name.as_str()), topics.truth.as_deref()].into_iter().flatten().collect();
        Ok(BagScans {
            messages: bag.messages(&wanted),
            topic: topic.name.clone(),
            truth,
            odometry,
            laser_pose,
            index: 0,
            order: 0,
            ranks: Default::default(),
            total: topic.messages,
            bad_truth,
            frames,
            base_frame,
            mount,
            odometry_said,
        })
    }

    /// Where the odometry comes from, when it takes more than its topic's name to say: the
    /// transforms read off a TFMessage topic, and the laser's place it was composed with.
    pub fn odometry_said(&self) -> Option<&str> {
        self.odometry_said.as_deref()
    }

    /// The scans' frame (the first scan's) and its place on the robot, from the bag's
    /// `/tf_static`.
    pub fn mount(&self) -> Option<&(String, Mount)> {
        self.mount.as_ref()
    }

    /// The topic read.
    pub fn topic(&self) -> &str {
        &self.topic
    }
}

impl Iterator for BagScans {
    type Item = Result<BagScan, BagScanError>;

    fn next(&mut self) -> Option<Self::Item> {
        loop {
            let m = match self.messages.next()? {
                Ok(m) => m,
                Err(e) => return Some(Err(e.into())),
            };
            let order = self.order;
            self.order += 1;
            if *m.topic != *self.topic {
                continue;
            }
            let index = self.index;
            self.index += 1;
            let lost = |cause: String| BagScanError::Message { topic: self.topic.clone(), index, cause };
            let mut message = match msg::LaserScan::decode_as(m.encoding, &m.data) {
                Ok(message) => message,
                Err(e) => return Some(Err(lost(e.to_string()))),
            };
            if self.frames.mount_of(&message.header.frame_id, &self.base_frame).is_some_and(|m| m.upside_down) {
                message = crate::scan::mirrored(message);
            }
            let mut scan = match crate::scan::laser_scan(&message) {
                Ok(scan) => scan,
                Err(e) => return Some(Err(lost(e.to_string()))),
            };
            let stamp = message.header.stamp.nanos();
            let rank = self.ranks.entry(stamp).or_default();
            scan.truth = self.truth.as_ref().and_then(|t| t.at(stamp, *rank, order));
            let odometry = self.odometry.as_ref().and_then(|t| t.at(stamp, *rank, order));
            *rank += 1;
            if let (Some(truth), Some(mount)) = (scan.truth.as_mut(), self.laser_pose) {
                *truth *= mount;
            }
            return Some(Ok(BagScan { index, scan, odometry }));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use laser::pose_theta;

    fn truth(poses: &[(i64, f64)]) -> Truth {
        Truth { poses: poses.iter().enumerate().map(|(k, &(t, x))| (t, 2 * k, pose(x, 0.0, 0.0))).collect() }
    }

    #[test]
    fn truth_is_the_pose_at_the_stamp_or_between_the_two_around_it() {
        let t = truth(&[(0, 0.0), (100_000_000, 1.0), (100_000_000, 5.0), (3_000_000_000, 9.0)]);
        assert_eq!(t.at(0, 0, 0).unwrap().translation.x, 0.0);
        // two poses share a stamp: the first scan with it takes the first, the second the second
        assert_eq!(t.at(100_000_000, 0, 3).unwrap().translation.x, 1.0);
        assert_eq!(t.at(100_000_000, 1, 3).unwrap().translation.x, 5.0);
        // a third takes the one nearest in the bag
        assert_eq!(t.at(100_000_000, 2, 5).unwrap().translation.x, 5.0);
        assert!((t.at(50_000_000, 0, 1).unwrap().translation.x - 0.5).abs() < 1e-12);
        assert!(t.at(2_000_000_000, 0, 6).is_none(), "poses 2.9 s apart");
        assert!(t.at(-1, 0, 0).is_none() && t.at(4_000_000_000, 0, 9).is_none(), "outside the poses");
    }

    #[test]
    fn odometry_follows_the_frame_that_carries_the_laser_else_the_robot_s_else_the_only_one() {
        let mut frames = StaticFrames::default();
        let level = [0.0, 0.0, 0.0, 1.0];
        frames.insert("base_link", "laser", [0.3, 0.0, 0.2], level);
        frames.insert("base_footprint", "base_link", [0.0; 3], level);
        let children = |c: &[&str]| c.iter().map(|s| s.to_string()).collect::<Vec<_>>();
        let two = children(&["odom_helper", "base_footprint"]);
        assert_eq!(odometry_child(&two, Some("laser"), &frames, "base_link"), Some("base_footprint"));
        // no laser frame known, or one /tf_static does not place: the robot's frame
        let with_base = children(&["odom_helper", "base_link"]);
        assert_eq!(odometry_child(&with_base, None, &frames, "base_link"), Some("base_link"));
        assert_eq!(odometry_child(&with_base, Some("camera"), &frames, "base_link"), Some("base_link"));
        // else the only one, and with two that neither rule picks, none
        assert_eq!(odometry_child(&children(&["chassis"]), None, &frames, "base_link"), Some("chassis"));
        assert_eq!(odometry_child(&children(&["a", "b"]), None, &frames, "base_link"), None);
        assert_eq!(odometry_child(&[], Some("laser"), &frames, "base_link"), None);
    }

    #[test]
    fn headings_are_interpolated_the_short_way_round() {
        let t = Truth { poses: vec![(0, 0, pose(0.0, 0.0, 3.0)), (10, 1, pose(0.0, 0.0, -3.0))] };
        let mid = pose_theta(&t.at(5, 0, 0).unwrap());
        assert!((mid.abs() - std::f64::consts::PI).abs() < 1e-9, "{mid}");
    }
}
