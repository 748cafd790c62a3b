//! The ROS 2 bridge process. Two threads, each with its own iceoryx2 node:
//! - scans in: waits on the DDS LaserScan subscription (and `/tf_static`), turns each scan
//!   into a `gema2/scan` message (numbered as it came), and remembers its ROS stamp and frame;
//! - poses out (the main thread): waits on `gema2/pose` as every stage waits, and publishes
//!   each located scan's robot pose with the scan's stamp, and, with `--initialpose`, seeds
//!   Nav2.
//!
//! Bad input loses only itself: a LaserScan that does not decode or describes no usable scan
//! is counted and reported, never published; a pose whose scan's stamp is no longer known is
//! stamped with the time it was published.

use crate::covariance::covariance;
use crate::seeding::Seeding;
use anyhow::{anyhow, Context as _, Result};
use clap::Args;
use laser::{pose, pose_theta, Pose};
use messages::iceoryx2::prelude::*;
use messages::{monotonic_ns, Freshness, Look, Outlet, PoseMsg, ScanMsg, Stage, Topic, STATUS_FAILED, STATUS_OK};
use ros::frames::{frame_name, Mount, StaticFrames};
use ros::msg;
use ros2_client::dds::rustdds::mio1::{Events, Interest, Poll, Token};
use ros2_client::dds::{Context, ContextOptions, Publisher, Subscription};
use ros2_client::qos::{Durability, History, WhenFull};
use ros2_client::{MessageTypeName, Name, NodeName, NodeOptions, QosProfile};
use std::collections::VecDeque;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

pub const ABOUT: &str = "GEMA2 ROS 2 bridge: LaserScan in over DDS, poses out on /gema2/pose and to Nav2";

#[derive(Args, Debug, Clone)]
pub struct Ros2Args {
    #[command(flatten)]
    pub stage: messages::StageArgs,
    /// The sensor_msgs/LaserScan topic to locate (sensor-data QoS: best effort).
    #[arg(long, default_value = "/scan")]
    pub scan_topic: String,
    /// Where the poses go (geometry_msgs/PoseWithCovarianceStamped, reliable).
    #[arg(long, default_value = "/gema2/pose")]
    pub pose_topic: String,
    /// Also seed Nav2's AMCL: an `ok` pose goes on /initialpose too, at most once per
    /// --initialpose-every.
    #[arg(long)]
    pub initialpose: bool,
    /// Seconds between two seeds of /initialpose.
    #[arg(long, default_value_t = 10.0, value_parser = positive_seconds)]
    pub initialpose_every: f64,
    /// The robot's nav_msgs/Odometry topic: each scan carries the odometry at its stamp, for
    /// the sequential localizer (`localize --impl sequential`). Scans go on without it. `/tf`
    /// reads the odometry off the transforms from --odom-frame to the robot instead.
    #[arg(long, default_value = "/odom")]
    pub odom_topic: String,
    /// The odometry frame, when --odom-topic is /tf.
    #[arg(long, default_value = "odom")]
    pub odom_frame: String,
    /// The map's frame, the published poses' frame_id.
    #[arg(long, default_value = "map")]
    pub map_frame: String,
    /// The robot's frame: the pose published is this frame's (REP 105).
    #[arg(long, default_value = "base_link")]
    pub base_frame: String,
    /// The laser's place on the robot, `x,y,yaw` (metres, radians); without it, from
    /// /tf_static (base frame -> the scan's frame_id).
    #[arg(long, value_parser = ros::planar_pose_arg, allow_hyphen_values = true)]
    pub laser_pose: Option<(f64, f64, f64)>,
    /// The DDS domain (default: $ROS_DOMAIN_ID, else 0).
    #[arg(long)]
    pub domain: Option<u16>,
}

fn positive_seconds(s: &str) -> Result<f64, String> {
    match s.parse::<f64>() {
        Ok(v) if v > 0.0 && v.is_finite() => Ok(v),
        _ => Err(format!("{s}: a positive number of seconds")),
    }
}

/// What the two threads share: the scans' ROS stamps by number, and the static frames.
#[derive(Default)]
struct Shared {
    /// (scan number, its header) of the latest scans, oldest first.
    stamps: VecDeque<(u64, msg::Header)>,
    frames: StaticFrames,
}

/// Scans whose stamps are kept for their poses: seconds of scans at 40 Hz.
const STAMPS_KEPT: usize = 4096;

/// How often the scan thread looks for the stop flag.
const STOP_POLL: Duration = Duration::from_millis(100);

fn topic_name(name: &str) -> Result<Name> {
    Name::parse(name).map_err(|e| anyhow!("{name}: not a ROS topic name: {e:?}"))
}

pub fn run(a: Ros2Args) -> Result<()> {
    a.stage.place()?;
    let domain = ros::domain_id(a.domain).map_err(anyhow::Error::msg)?;
    let context = Context::with_options(ContextOptions::new().domain_id(domain))
        .map_err(|e| anyhow!("ros2: starting DDS (domain {domain}): {e:?}"))?;
    let shared = Arc::new(Mutex::new(Shared::default()));
    let stop = Arc::new(AtomicBool::new(false));
    // poses out: the publishers live on this thread
    let mut dds = context
        .new_node(NodeName::new("/", "gema2").map_err(|e| anyhow!("{e:?}"))?, NodeOptions::new())
        .map_err(|e| anyhow!("ros2: creating the ROS node: {e:?}"))?;
    let reliable = QosProfile::publisher_default()
        .reliability_reliable(WhenFull::Wait(Duration::from_millis(100)))
        .durability(Durability::Volatile)
        .history(History::KeepLast { depth: 16 });
    let pose_type = MessageTypeName::new("geometry_msgs", "PoseWithCovarianceStamped");
    let poses_topic = dds
        .create_topic(&topic_name(&a.pose_topic)?, pose_type.clone(), &reliable)
        .map_err(|e| anyhow!("ros2: {}: {e:?}", a.pose_topic))?;
    let poses_out: Publisher<msg::PoseWithCovarianceStamped> =
        dds.create_publisher(&poses_topic, None).map_err(|e| anyhow!("ros2: {}: {e:?}", a.pose_topic))?;
    let seeds_out: Option<Publisher<msg::PoseWithCovarianceStamped>> = match a.initialpose {
        true => {
            let t = dds
                .create_topic(&topic_name("/initialpose")?, pose_type, &reliable)
                .map_err(|e| anyhow!("ros2: /initialpose: {e:?}"))?;
            Some(dds.create_publisher(&t, None).map_err(|e| anyhow!("ros2: /initialpose: {e:?}"))?)
        }
        false => None,
    };
    // scans in, on their own thread
    let scans = {
        let (context, shared, stop, a) = (context.clone(), Arc::clone(&shared), Arc::clone(&stop), a.clone());
        std::thread::Builder::new().name("scans-in".into()).spawn(move || {
            let done = scans_in(&context, &a, &shared, &stop);
            stop.store(true, Ordering::Relaxed);
            done
        })?
    };
    let node = messages::create_node("ros2")?;
    let poses = messages::Inlet::<PoseMsg>::open(&node, &a.stage.prefix, Topic::Pose)?;
    messages::announce_ready(&node, &a.stage.prefix)?;
    let mut out = PosesOut {
        poses: poses_out,
        seeds: seeds_out,
        seeding: Seeding::new(Duration::from_secs_f64(a.initialpose_every)),
        shared: Arc::clone(&shared),
        a: a.clone(),
        published: 0,
        fresh: Freshness::default(),
        unstamped: 0,
        unusable: 0,
        unmounted_said: false,
        latency_us: messages::latency::Latest::new(LATENCIES_KEPT),
    };
    let mut failure = None;
    let on_event = |woken: &[bool]| {
        if stop.load(Ordering::Relaxed) {
            return CallbackProgression::Stop;
        }
        let mut look = Look::new([&poses.listener], woken[0]);
        while look.next_pass() {
            loop {
                match look.receive(&poses.subscriber) {
                    Ok(Some((sample, _))) => {
                        if let Err(e) = out.publish(&sample) {
                            failure = Some(e);
                            return CallbackProgression::Stop;
                        }
                    }
                    Ok(None) => break,
                    Err(e) => {
                        failure = Some(anyhow!("{}: receive: {e}", poses.name));
                        return CallbackProgression::Stop;
                    }
                }
            }
        }
        CallbackProgression::Continue
    };
    let waited = messages::run_stage(&node, &[(&poses.name, &poses.listener)], messages::MISSED_WAKEUP_POLL, on_event);
    stop.store(true, Ordering::Relaxed);
    let scanned = scans.join().map_err(|_| anyhow!("ros2: the scan thread panicked"))?;
    messages::say!("ros2: published {} poses on {}", out.published, a.pose_topic);
    if !out.latency_us.is_empty() {
        let values: Vec<f64> = out.latency_us.iter().copied().collect();
        let (p50, p99) = messages::latency::p50_p99(&values);
        messages::say!(
            "ros2: latency from a LaserScan taken to its pose published, ms: p50 {:.3} p99 {:.3} (last {} poses)",
            p50 / 1e3,
            p99 / 1e3,
            out.latency_us.len()
        );
    }
    if out.unstamped > 0 {
        messages::say!("ros2: {} poses whose scan's stamp was no longer known were stamped when sent", out.unstamped);
    }
    if out.unusable > 0 {
        messages::say!("ros2: {} pose messages whose best hypothesis was not finite were not sent", out.unusable);
    }
    waited?;
    scanned?;
    failure.map_or(Ok(()), Err).context("ros2")
}

/// The robot's poses and costs of a pose message's `hypotheses`, best first (`inverse`: the
/// laser's place on the robot, inverted); `None` when the best is not a finite pose and cost,
/// as in a damaged message. Alternatives that are not are left out: a pose that is not a
/// number would go out to ROS, and could seed AMCL there.
fn robot_hypotheses(hypotheses: &[messages::HypothesisMsg], inverse: &Pose) -> Option<Vec<(Pose, f64)>> {
    let finite =
        |h: &&messages::HypothesisMsg| [h.pose.x, h.pose.y, h.pose.theta, h.cost].iter().all(|v| v.is_finite());
    if !hypotheses.first().is_some_and(|h| finite(&h)) {
        return None;
    }
    Some(hypotheses.iter().filter(finite).map(|h| (pose(h.pose.x, h.pose.y, h.pose.theta) * inverse, h.cost)).collect())
}

/// The main thread's side: poses from the pipeline to ROS.
struct PosesOut {
    poses: Publisher<msg::PoseWithCovarianceStamped>,
    seeds: Option<Publisher<msg::PoseWithCovarianceStamped>>,
    seeding: Seeding,
    shared: Arc<Mutex<Shared>>,
    a: Ros2Args,
    published: u64,
    /// What tells a scan's pose seen before: two localizers during a hot swap, or a restarted
    /// one handed the latest scan again, each publish one.
    fresh: Freshness,
    unstamped: u64,
    /// Pose messages whose best hypothesis is not a finite pose and cost (a damaged message).
    unusable: u64,
    unmounted_said: bool,
    /// Microseconds from each scan taken off DDS to its pose handed to DDS (the latest
    /// [`LATENCIES_KEPT`]).
    latency_us: messages::latency::Latest<f64>,
}

/// Latencies kept for the report: the last hour at 40 Hz.
const LATENCIES_KEPT: usize = 144_000;

impl PosesOut {
    /// Publishes the robot's pose of a located scan (a failed scan has none).
    fn publish(&mut self, m: &PoseMsg) -> Result<()> {
        let count = (m.count as usize).min(m.hypotheses.len());
        if !self.fresh.admit(&m.header) || m.status == STATUS_FAILED || count == 0 {
            return Ok(());
        }
        let (header, mount) = self.scan_header(m.header.seq);
        let Some(mount) = mount.or_else(|| self.unmounted(&header.frame_id)) else { return Ok(()) };
        let inverse = mount.inverse();
        let Some(robot) = robot_hypotheses(&m.hypotheses[..count], &inverse) else {
            self.unusable += 1;
            if self.unusable == 1 {
                messages::say!(
                    "ros2: pose message {}: its best hypothesis is not a finite pose; not sent",
                    m.header.seq
                );
            }
            return Ok(());
        };
        let best = robot[0].0;
        let message = msg::PoseWithCovarianceStamped {
            header: msg::Header { stamp: header.stamp, frame_id: self.a.map_frame.clone() },
            pose: msg::PoseWithCovariance {
                pose: msg::Pose::from_planar(best.translation.x, best.translation.y, pose_theta(&best)),
                covariance: msg::Covariance(covariance(m.status == STATUS_OK, &robot)),
            },
        };
        if let Some(seeds) = &self.seeds {
            if self.seeding.admit(m.status == STATUS_OK, Instant::now()) {
                seeds.publish(message.clone()).map_err(|e| anyhow!("/initialpose: {e:?}"))?;
            }
        }
        self.poses.publish(message).map_err(|e| anyhow!("{}: {e:?}", self.a.pose_topic))?;
        self.published += 1;
        self.latency_us
            .push(messages::latency::between_us(m.header.stages[Stage::Acquire as usize].enter_ns, monotonic_ns()));
        Ok(())
    }

    /// Scan `seq`'s ROS header (its stamp, or now when it is no longer known) and the laser's
    /// place on the robot, when known.
    fn scan_header(&mut self, seq: u64) -> (msg::Header, Option<Pose>) {
        let mut shared = self.shared.lock().unwrap_or_else(|p| p.into_inner());
        while shared.stamps.front().is_some_and(|(s, _)| *s < seq) {
            shared.stamps.pop_front();
        }
        let header = match shared.stamps.front() {
            Some((s, h)) if *s == seq => h.clone(),
            _ => {
                self.unstamped += 1;
                let now = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).unwrap_or_default();
                msg::Header { stamp: msg::Time::from_nanos(now.as_nanos() as u64), frame_id: String::new() }
            }
        };
        let mount = laser_place(&self.a, &shared.frames, &header.frame_id, None);
        (header, mount)
    }

    /// The mount to use when /tf_static has not (yet) placed the laser: the laser's own pose,
    /// said once.
    fn unmounted(&mut self, frame: &str) -> Option<Pose> {
        if !self.unmounted_said {
            self.unmounted_said = true;
            messages::say!(
                "ros2: no transform {} -> {frame:?} on /tf_static (nor --laser-pose): publishing the laser's pose as \
                 the robot's until one comes",
                self.a.base_frame
            );
        }
        Some(Pose::identity())
    }
}

/// A subscription to the topic `name` of type `ty`; an error names the topic.
fn subscribe<M: 'static>(
    dds: &mut ros2_client::Node,
    name: &str,
    ty: MessageTypeName,
    qos: &QosProfile,
) -> Result<Subscription<M>> {
    let topic = dds.create_topic(&topic_name(name)?, ty, qos).map_err(|e| anyhow!("ros2: {name}: {e:?}"))?;
    dds.create_subscription(&topic, None).map_err(|e| anyhow!("ros2: {name}: {e:?}"))
}

/// Hands `f` every message `sub` holds now; one that does not decode is said, naming `topic`,
/// and passed over. The subscriptions are edge-triggered: a wake-up must take all that came.
fn take_all<M: 'static + serde::de::DeserializeOwned>(sub: &Subscription<M>, topic: &str, mut f: impl FnMut(M)) {
    while let Some(taken) = sub.take().transpose() {
        match taken {
            Ok((m, _)) => f(m),
            Err(e) => messages::say!("ros2: {topic}: a message that does not decode: {e:?}"),
        }
    }
}

/// Scan `m` as the robot's plane sees it: mirrored when /tf_static mounts its laser upside
/// down (unless `--laser-pose` places the laser), said once per change, with a laser's tilt
/// out of the plane.
fn read_as_mounted(
    m: msg::LaserScan,
    a: &Ros2Args,
    shared: &Mutex<Shared>,
    said: &mut Option<Mount>,
) -> msg::LaserScan {
    if a.laser_pose.is_some() {
        return m;
    }
    let mount = shared.lock().unwrap_or_else(|p| p.into_inner()).frames.mount_of(&m.header.frame_id, &a.base_frame);
    let Some(mount) = mount else { return m };
    if said.is_none_or(|s| s.upside_down != mount.upside_down) {
        if mount.upside_down {
            messages::say!(
                "ros2: {:?} is mounted upside down (/tf_static): its scans are read mirrored",
                m.header.frame_id
            );
        }
        if mount.tilt_deg > TILT_SAID_DEG {
            messages::say!(
                "ros2: {:?} is tilted {:.0} degrees out of the floor's plane (/tf_static): its ranges are taken as level",
                m.header.frame_id,
                mount.tilt_deg
            );
        }
        *said = Some(mount);
    }
    if mount.upside_down {
        ros::scan::mirrored(m)
    } else {
        m
    }
}

/// A laser tilted more than this (degrees) is said to be.
const TILT_SAID_DEG: f64 = 5.0;

/// Where the odometry comes from: `nav_msgs/Odometry` messages, or `/tf`'s transforms from
/// the odometry frame to the robot.
enum OdometryIn {
    Odometry(Subscription<msg::Odometry>),
    Tf(Subscription<msg::TfMessage>),
}

/// The odometry poses of one frame read off a `/tf` message: the transforms from `odom_frame`
/// to `child` (the one followed so far), or, with none yet, to the robot's frame `base` or a
/// frame `/tf_static` hangs it from, which is then followed.
fn odometry_off_tf(
    tf: &msg::TfMessage,
    odom_frame: &str,
    base: &str,
    frames: &StaticFrames,
    child: &mut Option<String>,
) -> Vec<(i64, Pose)> {
    let mut poses = Vec::new();
    for t in &tf.transforms {
        if frame_name(&t.header.frame_id) != frame_name(odom_frame) {
            continue;
        }
        let c = frame_name(&t.child_frame_id);
        let followed = match child {
            Some(followed) => followed == c,
            None => c == frame_name(base) || frames.pose_of(base, c).is_some(),
        };
        if let (true, Some(p)) = (followed, ros::frames::planar(&t.transform)) {
            *child = Some(c.to_owned());
            poses.push((t.header.stamp.nanos(), p));
        }
    }
    poses
}

/// The laser's place on frame `on` (the robot's, `--base-frame`, when `None` or empty), for a
/// scan of frame `scan_frame`: `--laser-pose` on the robot, or the static transforms from the
/// scan's frame. On the robot it is the mount a pose is published through; on the frame the
/// odometry follows, the odometry composed with it moves as the laser does. `None` while
/// neither places it.
fn laser_place(a: &Ros2Args, frames: &StaticFrames, scan_frame: &str, on: Option<&str>) -> Option<Pose> {
    let on = on.map(frame_name).filter(|f| !f.is_empty()).unwrap_or(frame_name(&a.base_frame));
    match a.laser_pose {
        Some((x, y, yaw)) if on == frame_name(&a.base_frame) => Some(pose(x, y, yaw)),
        Some((x, y, yaw)) => frames.pose_of(&a.base_frame, on).map(|b| b * pose(x, y, yaw)),
        None if frame_name(scan_frame) == on => Some(Pose::identity()),
        None => frames.pose_of(scan_frame, on),
    }
}

/// The scan thread: LaserScans from DDS into the pipeline, static transforms into `shared`.
fn scans_in(context: &Context, a: &Ros2Args, shared: &Mutex<Shared>, stop: &AtomicBool) -> Result<()> {
    let mut dds = context
        .new_node(NodeName::new("/", "gema2_scans").map_err(|e| anyhow!("{e:?}"))?, NodeOptions::new())
        .map_err(|e| anyhow!("ros2: creating the ROS node: {e:?}"))?;
    let sensor = QosProfile::subscription_default().history(History::KeepLast { depth: 5 });
    let mut scans: Subscription<msg::LaserScan> =
        subscribe(&mut dds, &a.scan_topic, MessageTypeName::new("sensor_msgs", "LaserScan"), &sensor)?;
    let latched = QosProfile::publisher_default()
        .reliability_reliable(WhenFull::DEFAULT)
        .durability(Durability::TransientLocal)
        .history(History::KeepLast { depth: 100 });
    let mut tf: Subscription<msg::TfMessage> =
        subscribe(&mut dds, "/tf_static", MessageTypeName::new("tf2_msgs", "TFMessage"), &latched)?;
    // best effort takes both a reliable publisher's and a best-effort one's
    let odom_qos = QosProfile::subscription_default().history(History::KeepLast { depth: 50 });
    let mut odom = if frame_name(&a.odom_topic) == "tf" {
        OdometryIn::Tf(subscribe(&mut dds, &a.odom_topic, MessageTypeName::new("tf2_msgs", "TFMessage"), &odom_qos)?)
    } else {
        OdometryIn::Odometry(subscribe(
            &mut dds,
            &a.odom_topic,
            MessageTypeName::new("nav_msgs", "Odometry"),
            &odom_qos,
        )?)
    };
    let mut odometry = crate::odometry::Odometry::default();
    // the frame whose odometry it is (an Odometry's child frame, or the one /tf's followed)
    let mut odometry_frame: Option<String> = None;
    let mut poll = Poll::new()?;
    poll.registry().register(&mut scans, Token(0), Interest::READABLE)?;
    poll.registry().register(&mut tf, Token(1), Interest::READABLE)?;
    match &mut odom {
        OdometryIn::Odometry(s) => poll.registry().register(s, Token(2), Interest::READABLE)?,
        OdometryIn::Tf(s) => poll.registry().register(s, Token(2), Interest::READABLE)?,
    }
    let node = messages::create_node("ros2-scans")?;
    let mut out =
        Outlet::<ScanMsg>::open(&node, &a.stage.prefix, Topic::Scan, BackpressureStrategy::RetryUntilDelivered)?;
    let mut events = Events::with_capacity(8);
    let (mut seq, mut bad) = (0u64, 0u64);
    let mut mount_said = None;
    while !stop.load(Ordering::Relaxed) && !messages::termination_requested(&node) {
        if let Err(e) = poll.poll(&mut events, Some(STOP_POLL)) {
            if e.kind() != std::io::ErrorKind::Interrupted {
                return Err(anyhow!("ros2: waiting for DDS: {e}"));
            }
        }
        // edge-triggered: take all that came, from every subscription, on any wake-up
        take_all(&tf, "/tf_static", |m| shared.lock().unwrap_or_else(|p| p.into_inner()).frames.add(&m));
        // odometry before the scans, so a scan finds the message of its own instant
        match &odom {
            OdometryIn::Odometry(sub) => take_all(sub, &a.odom_topic, |m| {
                let (x, y, yaw) = m.pose.pose.planar();
                odometry.add(m.header.stamp.nanos(), x, y, yaw);
                odometry_frame = Some(m.child_frame_id);
            }),
            OdometryIn::Tf(sub) => take_all(sub, &a.odom_topic, |m| {
                let had = odometry_frame.is_some();
                let poses = {
                    let s = shared.lock().unwrap_or_else(|p| p.into_inner());
                    odometry_off_tf(&m, &a.odom_frame, &a.base_frame, &s.frames, &mut odometry_frame)
                };
                for (stamp, p) in poses {
                    odometry.add(stamp, p.translation.x, p.translation.y, pose_theta(&p));
                }
                if let (false, Some(f)) = (had, &odometry_frame) {
                    messages::say!("ros2: odometry from {}: {} -> {f}", a.odom_topic, frame_name(&a.odom_frame));
                }
            }),
        }
        while let Some(taken) = scans.take().transpose() {
            let enter = monotonic_ns();
            let scan = match taken.map_err(|e| format!("does not decode: {e:?}")).and_then(|(m, _)| {
                let m = read_as_mounted(m, a, shared, &mut mount_said);
                ros::laser_scan(&m).map(|s| (s, m.header)).map_err(|e| e.to_string())
            }) {
                Ok(scan) => scan,
                Err(e) => {
                    bad += 1;
                    if bad <= 10 {
                        messages::say!("ros2: {}: dropped a LaserScan: {e} ({bad} so far)", a.scan_topic);
                    }
                    continue;
                }
            };
            let (scan, header) = scan;
            let at_scan = {
                let mut s = shared.lock().unwrap_or_else(|p| p.into_inner());
                // the laser's odometry: the robot's composed with the laser's place on it
                let place = || laser_place(a, &s.frames, &header.frame_id, odometry_frame.as_deref());
                let at_scan = odometry.at(header.stamp.nanos()).map(|o| o * place().unwrap_or_else(Pose::identity));
                if s.stamps.len() >= STAMPS_KEPT {
                    s.stamps.pop_front();
                }
                s.stamps.push_back((seq, header));
                at_scan
            };
            out.send(|m: &mut ScanMsg| {
                acquire::node::scan_to_msg(&scan, at_scan.as_ref(), seq, enter, m);
                m.header.span(Stage::Acquire).enter_ns = enter;
                m.header.span(Stage::Acquire).leave_ns = monotonic_ns();
                m.header.set_producer("ros2");
            })
            .map_err(|e| anyhow!("ros2: {}: {e}", out.name()))?;
            seq += 1;
        }
    }
    messages::say!(
        "ros2: {} scans in from {}{}",
        seq,
        a.scan_topic,
        if bad > 0 { format!(", {bad} dropped") } else { String::new() }
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    #[derive(Parser)]
    struct Cli {
        #[command(flatten)]
        a: Ros2Args,
    }

    fn args(extra: &[&str]) -> Ros2Args {
        Cli::parse_from(["ros2"].iter().chain(extra)).a
    }

    fn transform(parent: &str, child: &str, x: f64, yaw: f64) -> msg::TransformStamped {
        let (s, c) = (yaw / 2.0).sin_cos();
        msg::TransformStamped {
            header: msg::Header { stamp: msg::Time::from_nanos(7), frame_id: parent.into() },
            child_frame_id: child.into(),
            transform: msg::Transform { translation: [x, 0.0, 0.0], rotation: [0.0, 0.0, s, c] },
        }
    }

    /// `/tf` as a robot publishes it: map -> odom from a localizer, odom -> base_footprint from
    /// the wheels, base_footprint -> base_link on /tf_static. The odometry is odom's transform
    /// to the frame the robot hangs from, and only that frame's is followed after.
    #[test]
    fn odometry_off_tf_follows_the_frame_the_robot_hangs_from() {
        let mut frames = StaticFrames::default();
        frames.insert("base_footprint", "base_link", [0.0, 0.0, 0.1], [0.0, 0.0, 0.0, 1.0]);
        let tf = |x: f64| msg::TfMessage {
            transforms: vec![
                transform("map", "odom", 5.0, 1.0),
                transform("/odom", "tracker", 9.0, 0.0),
                transform("odom", "base_footprint", x, 0.5),
            ],
        };
        let mut child = None;
        // "tracker" hangs no robot: passed over
        let got = odometry_off_tf(&tf(1.0), "odom", "base_link", &frames, &mut child);
        assert_eq!(child.as_deref(), Some("base_footprint"));
        assert_eq!(got.len(), 1);
        assert!((got[0].1.translation.x - 1.0).abs() < 1e-12 && (pose_theta(&got[0].1) - 0.5).abs() < 1e-12);
        assert_eq!(got[0].0, 7);
        let got = odometry_off_tf(&tf(2.0), "/odom", "base_link", &frames, &mut child);
        assert_eq!(got.iter().map(|g| g.1.translation.x).collect::<Vec<_>>(), vec![2.0]);
        // another odometry frame: nothing
        let mut none = None;
        assert!(odometry_off_tf(&tf(3.0), "wheel_odom", "base_link", &frames, &mut none).is_empty() && none.is_none());
    }

    /// The odometry is composed with the laser's place on the frame it follows, from
    /// /tf_static or --laser-pose, so that a turn moves the laser as it moved.
    #[test]
    fn the_laser_s_place_on_the_odometry_s_frame() {
        let mut frames = StaticFrames::default();
        let level = [0.0, 0.0, 0.0, 1.0];
        frames.insert("base_footprint", "base_link", [0.0, 0.0, 0.1], level);
        frames.insert("base_link", "laser", [0.3, 0.0, 0.2], level);
        let a = args(&[]);
        let x = |p: Option<Pose>| p.map(|p| p.translation.x);
        assert_eq!(x(laser_place(&a, &frames, "laser", Some("base_footprint"))), Some(0.3));
        // an Odometry without a child frame is taken as the robot's
        assert_eq!(x(laser_place(&a, &frames, "/laser", Some(""))), Some(0.3));
        assert_eq!(x(laser_place(&a, &frames, "laser", None)), Some(0.3));
        // not placed yet
        assert_eq!(laser_place(&a, &frames, "front_laser", None), None);
        // --laser-pose gives the laser on the robot's frame, hung from the odometry's
        let told = args(&["--laser-pose", "0.5,0,0"]);
        assert_eq!(x(laser_place(&told, &frames, "front_laser", Some("base_footprint"))), Some(0.5));
        assert_eq!(x(laser_place(&told, &frames, "front_laser", Some("base_link"))), Some(0.5));
        assert_eq!(laser_place(&told, &frames, "front_laser", Some("elsewhere")), None);
    }

    fn hypothesis(x: f64, cost: f64) -> messages::HypothesisMsg {
        messages::HypothesisMsg { pose: messages::PoseMsgXyt { x, y: 2.0, theta: 0.0 }, cost, ..Default::default() }
    }

    /// A damaged pose message never goes out as a pose that is not a number.
    #[test]
    fn a_pose_message_whose_best_is_not_finite_is_not_sent() {
        let inverse = pose(0.2, 0.0, 0.0).inverse();
        assert!(robot_hypotheses(&[hypothesis(f64::NAN, 0.1), hypothesis(1.0, 0.2)], &inverse).is_none());
        assert!(robot_hypotheses(&[hypothesis(1.0, f64::INFINITY)], &inverse).is_none());
        assert!(robot_hypotheses(&[], &inverse).is_none());
        let kept = robot_hypotheses(&[hypothesis(1.0, 0.1), hypothesis(f64::NAN, 0.2), hypothesis(3.0, 0.3)], &inverse)
            .expect("a finite best");
        assert_eq!(kept.len(), 2, "the alternative that is not a number is left out");
        // the laser 0.2 m ahead of the robot's centre, facing the map's x axis
        assert!((kept[0].0.translation.x - 0.8).abs() < 1e-9 && kept[1].1 == 0.3, "{kept:?}");
    }
}
