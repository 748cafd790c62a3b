//! The acquisition process: scans from the simulator or a log, published on `gema2/scan` at a
//! fixed rate or as fast as the pipeline takes them. At `--rate max` publishing waits for room
//! in the subscribers' buffers, so no scan is dropped; at a fixed rate a scan that finds a full
//! buffer is not delivered to that subscriber (the stage is too slow), and the run goes on.

use crate::{CarmenReader, Scenario, SensorModel, Simulator, Walk};
use anyhow::{anyhow, Context, Result};
use clap::Args;
use laser::motion::OdometryNoise;
use laser::{pose_theta, LaserScan};
use messages::iceoryx2::prelude::*;
use messages::{monotonic_ns, Header, Outlet, PoseMsgXyt, ScanMsg, Stage, Topic, MAX_BEAMS};
use std::path::PathBuf;
use std::time::Duration;

impl AcquireArgs {
    /// Whether scans come from a sensor, which paces itself and carries no truth.
    fn is_sensor(&self) -> bool {
        self.serial.is_some() || self.tcp.is_some()
    }
}

/// What the stage is, for its `--help` (its own program's and `gema2 stage acquire`'s).
pub const ABOUT: &str = "GEMA2 acquisition stage: a simulated laser or a log, published as scans";

#[derive(Args, Debug, Clone)]
pub struct AcquireArgs {
    #[command(flatten)]
    pub stage: messages::StageArgs,
    /// Replay this CARMEN log instead of simulating. A malformed line is reported (file and
    /// line) and skipped, as a corrupt frame from a sensor would be; the replay goes on.
    #[arg(long)]
    pub log: Option<PathBuf>,
    #[command(flatten)]
    pub flaser: crate::FlaserArgs,
    /// Replay a URG-04LX log (the format of datasets/urg04lx) instead of simulating.
    #[arg(long)]
    pub urg_log: Option<PathBuf>,
    /// Replay the LaserScans of a ROS 2 bag (a bag directory or one .mcap file) instead of
    /// simulating; `--rate recorded` keeps their recorded pace. A message that does not decode
    /// is reported and skipped.
    #[arg(long)]
    pub bag: Option<PathBuf>,
    /// The bag's LaserScan topic (default: its only one).
    #[arg(long, requires = "bag")]
    pub scan_topic: Option<String>,
    /// The bag's nav_msgs/Odometry topic: each scan carries the odometry at its stamp, for the
    /// sequential localizer (a log's odometry travels without asking). Or `/tf`: the
    /// transforms from the odometry frame (--odom-frame) to the robot.
    #[arg(long, requires = "bag")]
    pub odom_topic: Option<String>,
    /// The odometry frame, when --odom-topic is a tf2_msgs/TFMessage topic such as /tf.
    #[arg(long, requires = "odom_topic", default_value = "odom")]
    pub odom_frame: String,
    /// Read a real Hokuyo URG-04LX on this serial port (SCIP 2.0).
    #[arg(long, conflicts_with = "tcp")]
    pub serial: Option<String>,
    /// Read a Hokuyo Ethernet lidar (UST-10LX/20LX, UTM-30LX-EW) at this HOST:PORT, SCIP 2.0
    /// over TCP; the factory address is 192.168.0.10:10940.
    #[arg(long)]
    pub tcp: Option<String>,
    /// Baud rate of the serial port (ignored by USB models). An RS-232 sensor that does not
    /// answer at it is looked for at the other SCIP rates and switched to it.
    #[arg(long, default_value_t = 115_200)]
    pub baud: u32,
    /// Also write every scan as a ROBOTLASER1 line to this file.
    #[arg(long)]
    pub carmen_out: Option<PathBuf>,
    /// Simulator: a bundled map's name, a JSON wall map or a ROS map_server .yaml.
    #[arg(long, default_value = "office")]
    pub map: String,
    /// Simulator: clean, people or furniture.
    #[arg(long, default_value = "clean")]
    pub scenario: Scenario,
    /// Simulator: seed of the path, the noise and the people.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Simulator: walk the robot through the free space about this many metres a scan (as
    /// `gema2 sim --trajectory --step`), instead of drawing each scan's pose anew.
    #[arg(long, value_parser = walk_step)]
    pub step: Option<f64>,
    /// Simulator, with --step: wheel odometry drawn from the walk by the odometry motion model
    /// with these alphas (AMCL's alpha1..alpha4), so that it drifts; without, it is exact.
    #[arg(long, value_name = "A1,A2,A3,A4", value_delimiter = ',', requires = "step")]
    pub odom_noise: Option<Vec<f64>>,
    /// Scans to publish (0: until the source ends or forever).
    #[arg(long, default_value_t = 0)]
    pub scans: u64,
    /// Scans per second, `max`, or `recorded` (a log's or bag's scans at the pace of their
    /// stamps).
    #[arg(long, default_value = "10", value_parser = rate_arg)]
    pub rate: String,
    /// Number of the first scan.
    #[arg(long, default_value_t = 0)]
    pub first_seq: u64,
    /// At a fixed rate, wake the pipeline this many microseconds before each scan without a
    /// message (`messages::WARM_UP`), so that the scan's own wake-ups find a warm path; 0: never.
    #[arg(long, default_value_t = DEFAULT_WARM_UP_US)]
    pub warm_up_us: u64,
    /// Take over from the source this one replaces (a hot swap): announce readiness, then
    /// publish only once the other source is gone, numbering from one after the last scan it
    /// published, so downstream sees no gap and no repeat. With no scan seen from it, from
    /// `--first-seq`.
    #[arg(long)]
    pub handover: bool,
    /// Seconds the source stays up after its last scan (SIGINT or SIGTERM end it sooner), so
    /// the segment stage can take that scan: iceoryx2 drops what a publisher sent once the
    /// publisher is gone, and a short replay ends before its first scan is read.
    #[arg(long, default_value_t = 1.0)]
    pub linger: f64,
}

/// The source's default warm-up lead, microseconds (`--warm-up-us`): on this project's VM
/// 200 us left hops faster than 500 or 2000 (the warmth fades) in `gema2 bench --pipeline`.
pub const DEFAULT_WARM_UP_US: u64 = 200;

/// Every how many beams a scan of `beams` beams is thinned to fit a message of [`MAX_BEAMS`]:
/// 1 for any scan that fits.
pub fn thinning(beams: usize) -> usize {
    beams.div_ceil(MAX_BEAMS).max(1)
}

/// Writes a scan into a message. A scan of more than [`MAX_BEAMS`] beams keeps every
/// [`thinning`]-th beam, over the whole field of view, with the angle between beams widened to
/// match: the localizer works with any number of beams, and cutting the scan short would
/// lose part of its view.
///
/// `odometry` is the robot's odometry pose at the scan, when the source has it.
pub fn scan_to_msg(scan: &LaserScan, odometry: Option<&laser::Pose>, seq: u64, stamp_ns: u64, m: &mut ScanMsg) {
    m.header = Header::new(seq, stamp_ns);
    let g = &scan.geometry;
    let every = thinning(scan.ranges.len());
    m.angle_min = g.angle_min;
    m.angle_increment = g.angle_increment * every as f64;
    m.range_min = g.range_min;
    m.range_max = g.range_max;
    let kept = scan.ranges.iter().step_by(every);
    let n = kept.len().min(MAX_BEAMS);
    m.count = n as u32;
    for (slot, &r) in m.ranges.iter_mut().zip(kept) {
        *slot = r;
    }
    if let Some(t) = &scan.truth {
        m.has_truth = 1;
        m.truth = PoseMsgXyt { x: t.translation.x, y: t.translation.y, theta: pose_theta(t) };
    }
    (m.has_odometry, m.odometry) = match odometry {
        Some(o) => (1, PoseMsgXyt { x: o.translation.x, y: o.translation.y, theta: pose_theta(o) }),
        None => (0, PoseMsgXyt::default()),
    };
}

/// A scan of a source that could not be read, the ones after it still can: a bag message that
/// does not decode.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
struct Skipped(String);

/// A log line that does not parse, or a bag message that does not decode: the scans after it
/// can still be read.
fn is_malformed_line(e: &anyhow::Error) -> bool {
    matches!(e.downcast_ref::<crate::LogError>(), Some(crate::LogError::Line { .. })) || e.is::<Skipped>()
}

/// Scans, each with the robot's odometry pose when the source has it.
type Source = Box<dyn Iterator<Item = Result<(LaserScan, Option<laser::Pose>)>>>;

/// How often a sensor source waiting to reconnect looks for SIGINT/SIGTERM.
const STOP_POLL: Duration = Duration::from_millis(20);

/// A sensor's scans as a source that stops on SIGINT/SIGTERM, also in the middle of a wait
/// for reconnection.
fn sensor<C: crate::scip::source::Connector + 'static>(mut sensor: crate::scip::ScipSource<C>) -> Source {
    Box::new(std::iter::from_fn(move || {
        sensor
            .next_scan(&mut |wait| {
                let until = std::time::Instant::now() + wait;
                while !stop_requested() && std::time::Instant::now() < until {
                    std::thread::sleep(until.saturating_duration_since(std::time::Instant::now()).min(STOP_POLL));
                }
                !stop_requested()
            })
            .map(|r| r.map(|scan| (scan, None)).map_err(anyhow::Error::from))
    }))
}

fn source(a: &AcquireArgs) -> Result<(Source, &'static str)> {
    if let Some(port) = &a.serial {
        return Ok((sensor(crate::scip::SerialSource::new(port, a.baud)), "scip2-serial"));
    }
    if let Some(address) = &a.tcp {
        return Ok((sensor(crate::scip::TcpSource::new(address)), "scip2-tcp"));
    }
    if let Some(path) = &a.bag {
        let bag = ros::Bag::open(path)?;
        let topics = ros::ScanTopics {
            scan: a.scan_topic.clone(),
            odometry: a.odom_topic.clone(),
            odom_frame: Some(a.odom_frame.clone()),
            ..Default::default()
        };
        let scans = ros::BagScans::open(&bag, &topics)?;
        if let Some(said) = scans.odometry_said() {
            messages::say!("acquire: {}: {said}", path.display());
        }
        if let Some((frame, _)) = scans.mount().filter(|(_, m)| m.upside_down) {
            messages::say!(
                "acquire: {}: /tf_static mounts {frame:?} upside down: its scans are read mirrored",
                path.display()
            );
        }
        let items = scans.map(|item| {
            item.map(|s| (s.scan, s.odometry)).map_err(|e| match e.is_one_message() {
                true => anyhow::Error::new(Skipped(e.to_string())),
                false => e.into(),
            })
        });
        return Ok((Box::new(items), "ros2-bag"));
    }
    if let Some(path) = &a.urg_log {
        let reader = crate::urg_log::UrgLogReader::open(path)?;
        return Ok((Box::new(reader.map(|r| r.map(|scan| (scan, None)).map_err(anyhow::Error::from))), "urg04lx-log"));
    }
    if let Some(path) = &a.log {
        let reader = CarmenReader::open(path, a.flaser.layout()?)?;
        return Ok((
            Box::new(reader.map(|r| r.map(|s| (s.scan, s.odometry)).map_err(anyhow::Error::from))),
            "carmen-log",
        ));
    }
    let map = mapio::load_map(&a.map)?;
    let mut sim = Simulator::new(&map, SensorModel::urg04lx(), a.scenario, a.seed);
    let noise = a
        .odom_noise
        .as_deref()
        .map(OdometryNoise::from_alphas)
        .transpose()
        .map_err(|e| anyhow!("--odom-noise: {e}"))?;
    // a robot drawn anew each scan, where its odometry says; or walking, its odometry exact or
    // drifting
    let scans: Source = match a.step {
        Some(step) => {
            let mut walk = Walk::new(sim, step, noise, a.seed);
            Box::new(std::iter::from_fn(move || Some(Ok(walk.next_scan()))))
        }
        None => Box::new(std::iter::from_fn(move || {
            let scan = sim.next_scan();
            let odometry = scan.truth;
            Some(Ok((scan, odometry)))
        })),
    };
    Ok((scans, "simulator"))
}

/// Parses `--step`: metres above 0.
fn walk_step(s: &str) -> Result<f64, String> {
    match s.parse::<f64>() {
        Ok(v) if v.is_finite() && v > 0.0 => Ok(v),
        _ => Err(format!("{s}: a distance in metres above 0")),
    }
}

static STOP: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);

/// Whether SIGINT or SIGTERM arrived since [`install_stop_handlers`].
pub fn stop_requested() -> bool {
    STOP.load(std::sync::atomic::Ordering::Relaxed)
}

/// The flag a blocking source (a serial port, a pty) checks: set on SIGINT and SIGTERM. (Loops
/// that wait in iceoryx2 see those signals through their node instead.)
pub fn stop_flag() -> &'static std::sync::atomic::AtomicBool {
    &STOP
}

/// The handlers [`install_stop_handlers`] found for SIGINT and SIGTERM, called on after it.
static PREVIOUS: [std::sync::atomic::AtomicUsize; 2] =
    [std::sync::atomic::AtomicUsize::new(0), std::sync::atomic::AtomicUsize::new(0)];

extern "C" fn on_stop(signal: libc::c_int) {
    STOP.store(true, std::sync::atomic::Ordering::Relaxed);
    let previous = PREVIOUS[usize::from(signal == libc::SIGTERM)].load(std::sync::atomic::Ordering::Relaxed);
    if previous != libc::SIG_DFL && previous != libc::SIG_IGN && previous != libc::SIG_ERR {
        // SAFETY: `previous` is a plain handler sigaction returned for this signal; calling it
        // is what the signal would have done without this one.
        let handler: extern "C" fn(libc::c_int) = unsafe { std::mem::transmute(previous) };
        handler(signal);
    }
}

/// Makes SIGINT and SIGTERM set [`stop_requested`], and still do what they did before: a
/// process with an iceoryx2 node installs this after the node's own handler (see
/// [`messages::termination_requested`]), which records them for the node's waits; without
/// that order one of the two handlers never ran, and a serial source waiting for its port
/// ignored SIGTERM.
pub fn install_stop_handlers() {
    let ours = on_stop as *const () as libc::sighandler_t;
    for (slot, signal) in PREVIOUS.iter().zip([libc::SIGINT, libc::SIGTERM]) {
        // SAFETY: sigaction reads `action` and writes `previous`, both ours; the handler stores
        // to an atomic and calls the handler it replaced.
        unsafe {
            let mut action: libc::sigaction = std::mem::zeroed();
            action.sa_sigaction = ours;
            action.sa_flags = libc::SA_RESTART;
            libc::sigemptyset(&mut action.sa_mask);
            let mut previous: libc::sigaction = std::mem::zeroed();
            if libc::sigaction(signal, &action, &mut previous) != 0 {
                continue;
            }
            // only a one-argument handler can be called on as one (not an SA_SIGINFO one)
            if previous.sa_sigaction != ours && previous.sa_flags & libc::SA_SIGINFO == 0 {
                slot.store(previous.sa_sigaction, std::sync::atomic::Ordering::Relaxed);
            }
        }
    }
}

pub fn run(a: AcquireArgs) -> Result<()> {
    a.stage.place()?;
    let period = period(&a)?;
    let node = messages::create_node("acquire")?;
    if a.is_sensor() {
        // a sensor source can block on the port, away from the node's waits: notice SIGINT
        // and SIGTERM there too, after the node's own handler is in place (its first look
        // puts it there), so that both see them
        let _ = messages::termination_requested(&node);
        install_stop_handlers();
    }
    let (mut scans, producer) = source(&a)?;
    let strategy =
        if period.is_none() { BackpressureStrategy::RetryUntilDelivered } else { BackpressureStrategy::DiscardData };
    let mut out = Publishing {
        scans: Outlet::<ScanMsg>::open(&node, &a.stage.prefix, Topic::Scan, strategy)?,
        carmen: carmen_out(&a)?,
        producer,
        thinned: false,
    };
    let mut recorded = (a.rate == "recorded" && !a.is_sensor()).then(Pace::default);
    let mut seq = a.first_seq;
    if a.handover {
        match take_over(&node, &out.scans, &a.stage.prefix, a.first_seq)? {
            Some(next) => {
                messages::say!("acquire: took over from the source it replaces at scan {next}");
                seq = next;
            }
            None => return Ok(()), // SIGINT or SIGTERM while waiting
        }
    }
    let mut skipped = 0u64;
    let mut next = monotonic_ns();
    let mut signalled = false;
    loop {
        if a.scans > 0 && seq - a.first_seq >= a.scans {
            break;
        }
        // Wait first, then acquire and publish, then go straight back to waiting: work done
        // after publishing (simulating or parsing the next scan) would hold up a consumer that
        // shares this core, and count as transport in the hop after this stage.
        let go_on = match period {
            Some(p) => wait_for_turn(&node, &mut out.scans, &mut next, p, a.warm_up_us.saturating_mul(1000))?,
            None => !(messages::termination_requested(&node) || stop_requested()),
        };
        if !go_on {
            signalled = true; // SIGINT or SIGTERM
            break;
        }
        let mut enter = monotonic_ns();
        let (scan, odometry) = match scans.next() {
            None => break,
            Some(Ok(item)) => item,
            Some(Err(e)) if is_malformed_line(&e) => {
                skipped += 1;
                messages::say!("acquire: skipped {e} ({skipped} so far)");
                continue;
            }
            Some(Err(e)) => return Err(e.context("acquire: reading the source")),
        };
        if let Some(pace) = recorded.as_mut() {
            if !pace.wait(&node, scan.stamp) {
                signalled = true;
                break;
            }
            enter = monotonic_ns();
        }
        out.publish(&scan, odometry.as_ref(), seq, enter)?;
        seq += 1;
    }
    if let Some(w) = out.carmen.as_mut() {
        std::io::Write::flush(w).context("acquire: writing --carmen-out")?;
    }
    messages::say!("acquire: published {} scans", seq - a.first_seq);
    if !signalled && !stop_requested() && seq > a.first_seq && a.linger > 0.0 {
        // the scans still in the segment stage's queue live in this process's memory
        messages::sleep(&node, Duration::from_secs_f64(a.linger.min(3600.0)));
    } else if seq > a.first_seq && a.linger > 0.0 {
        // stopped (a swap hands over, Ctrl-C): the last scans still reach their readers
        std::thread::sleep(STOPPED_LINGER.min(Duration::from_secs_f64(a.linger)));
    }
    if skipped > 0 {
        messages::say!("acquire: skipped {skipped} malformed log lines");
    }
    if let Some(r) = out.scans.report() {
        messages::say!("acquire: {r}");
    }
    Ok(())
}

/// How often a source taking over looks whether the one it replaces is gone.
const HANDOVER_POLL: Duration = Duration::from_millis(2);

/// How long a source taking over waits to see a scan of the one it replaces before it says it
/// is ready: the last scan's number must be known when the other goes.
const HANDOVER_FIRST_SCAN: Duration = Duration::from_secs(3);

/// How long a source stopped by a signal stays up after its last scan: enough for readers to
/// take the scans still queued (iceoryx2 drops what a publisher sent once it is gone), short
/// enough for a swap.
const STOPPED_LINGER: Duration = Duration::from_millis(300);

/// `--handover`: watches the scans the other source publishes; says it is ready once it has
/// seen one (or waited [`HANDOVER_FIRST_SCAN`]); then, once the other is gone, the number to go
/// on from. `None` when SIGINT or SIGTERM came first.
fn take_over(node: &Node<ipc::Service>, out: &Outlet<ScanMsg>, prefix: &str, fallback: u64) -> Result<Option<u64>> {
    let watch = messages::Inlet::<ScanMsg>::open(node, prefix, Topic::Scan)?;
    let mut last: Option<u64> = None;
    let mut ready = false;
    let started = std::time::Instant::now();
    loop {
        // the other source waits for room in every reader's buffer, this one's too: drain it
        let gone = out.other_publishers() == 0;
        while let Some(sample) = watch.subscriber.receive().map_err(|e| anyhow!("{}: receive: {e:?}", watch.name))? {
            last = Some(last.map_or(sample.header.seq, |l| l.max(sample.header.seq)));
        }
        if !ready && (last.is_some() || gone || started.elapsed() > HANDOVER_FIRST_SCAN) {
            messages::announce_ready(node, prefix)?;
            ready = true;
        }
        if gone && ready {
            return Ok(Some(last.map_or(fallback, |l| l + 1)));
        }
        if !messages::sleep(node, HANDOVER_POLL) {
            return Ok(None);
        }
    }
}

/// `--rate recorded`: scans published at the pace of their stamps, from the first one's
/// publication on. A stamp that is not a number, goes back, or comes more than [`Pace::LONGEST`]
/// after the one before starts the pace again from that scan, published at once.
#[derive(Default)]
struct Pace {
    /// A scan's stamp, seconds, and when it was published (monotonic ns).
    anchor: Option<(f64, u64)>,
    last: f64,
}

impl Pace {
    const LONGEST: f64 = 10.0;

    /// Waits until the scan stamped `stamp` is due; `false` when SIGINT or SIGTERM came instead.
    fn wait(&mut self, node: &Node<ipc::Service>, stamp: f64) -> bool {
        let now = monotonic_ns();
        let steady = stamp.is_finite() && stamp >= self.last && stamp - self.last <= Self::LONGEST;
        self.last = if stamp.is_finite() { stamp } else { self.last };
        let (t0, wall0) = match self.anchor {
            Some(anchor) if steady => anchor,
            _ => {
                self.anchor = stamp.is_finite().then_some((stamp, now));
                return true;
            }
        };
        let due = wall0 + ((stamp - t0) * 1e9) as u64;
        due <= now || messages::sleep(node, Duration::from_nanos(due - now))
    }
}

/// Where the stage's scans go: the scan topic, and the `--carmen-out` log when given.
struct Publishing {
    scans: Outlet<ScanMsg>,
    carmen: Option<std::io::BufWriter<std::fs::File>>,
    /// The source, named in each scan's header.
    producer: &'static str,
    /// Whether the stage has said that it thins its scans' beams.
    thinned: bool,
}

impl Publishing {
    /// Writes `scan` to the log and publishes it as scan `seq`, acquired at `enter`.
    fn publish(&mut self, scan: &LaserScan, odometry: Option<&laser::Pose>, seq: u64, enter: u64) -> Result<()> {
        if let Some(w) = self.carmen.as_mut() {
            crate::write_robotlaser1(w, scan).context("acquire: writing --carmen-out")?;
        }
        let every = thinning(scan.ranges.len());
        if every > 1 && !self.thinned {
            self.thinned = true;
            messages::say!(
                "acquire: scans of {} beams keep one beam in {every} to fit a message of {MAX_BEAMS}",
                scan.ranges.len()
            );
        }
        let producer = self.producer;
        self.scans
            .send(|m: &mut ScanMsg| {
                scan_to_msg(scan, odometry, seq, enter, m);
                m.header.span(Stage::Acquire).enter_ns = enter;
                m.header.span(Stage::Acquire).leave_ns = monotonic_ns();
                m.header.set_producer(producer);
            })
            .map(|_| ())
            .map_err(|e| anyhow!("{}: {e}", self.scans.name()))
    }
}

/// The time between published scans: `--rate` as a period, `None` for `max` and for a sensor,
/// which paces itself.
fn period(a: &AcquireArgs) -> Result<Option<Duration>> {
    match a.is_sensor() {
        true => Ok(None),
        false => parse_rate(&a.rate).map_err(|e| anyhow!("--rate {e}")),
    }
}

/// A `--rate`: scans per second as the time between them, or `max` (`None`: as fast as the
/// pipeline takes them). `recorded` is `None` here too: the stage paces such scans by their
/// stamps (`Pace`).
pub fn parse_rate(r: &str) -> Result<Option<Duration>, String> {
    match (r, r.parse::<f64>()) {
        ("max" | "recorded", _) => Ok(None),
        (_, Ok(hz)) if hz > 0.0 && hz.is_finite() => Ok(Some(Duration::from_secs_f64(1.0 / hz))),
        _ => Err(format!("{r}: a positive number of scans per second, max, or recorded")),
    }
}

/// [`parse_rate`] as a command line's check: the rate as given, when it is one.
pub fn rate_arg(r: &str) -> Result<String, String> {
    parse_rate(r).map(|_| r.to_owned())
}

/// The `--carmen-out` file, when asked for. A sensor's scans carry no truth, and the file
/// says so on its first line.
fn carmen_out(a: &AcquireArgs) -> Result<Option<std::io::BufWriter<std::fs::File>>> {
    let Some(p) = &a.carmen_out else { return Ok(None) };
    let mut w = std::io::BufWriter::new(std::fs::File::create(p).with_context(|| format!("creating {}", p.display()))?);
    if a.is_sensor() || a.urg_log.is_some() || a.bag.is_some() {
        std::io::Write::write_all(&mut w, format!("{}\n", crate::NO_TRUTH_MARKER).as_bytes())?;
    }
    Ok(Some(w))
}

/// Sleeps until the next scan is due at `next` (monotonic ns), waking the scan's readers
/// `lead` ns ahead of it, and sets `next` one `period` on. `false` when SIGINT or SIGTERM
/// came instead.
fn wait_for_turn(
    node: &Node<ipc::Service>,
    scans_out: &mut Outlet<ScanMsg>,
    next: &mut u64,
    period: Duration,
    lead: u64,
) -> Result<bool> {
    let warm_up_at = next.saturating_sub(lead);
    let now = monotonic_ns();
    if lead > 0 && *next > now {
        if warm_up_at > now && !messages::sleep(node, Duration::from_nanos(warm_up_at - now)) {
            return Ok(false);
        }
        scans_out.warm_up().map_err(|e| anyhow!("acquire: {e}"))?;
    }
    let now = monotonic_ns();
    if *next > now && !messages::sleep(node, Duration::from_nanos(*next - now)) {
        return Ok(false);
    }
    *next = (*next).max(now) + period.as_nanos() as u64;
    Ok(true)
}

#[cfg(test)]
mod tests {
    use super::*;
    use laser::ScanGeometry;

    fn scan(beams: usize) -> LaserScan {
        LaserScan {
            geometry: ScanGeometry::centred(beams, 270f64.to_radians(), 30.0),
            ranges: (0..beams).map(|k| k as f32).collect(),
            stamp: 0.0,
            truth: None,
        }
    }

    /// A scan that fits goes whole; a larger one keeps every k-th beam over its whole field of
    /// view, its last beam no further round than the sensor's.
    #[test]
    fn a_scan_larger_than_a_message_is_thinned_over_its_whole_view() {
        let mut m = ScanMsg {
            header: Header::new(0, 0),
            angle_min: 0.0,
            angle_increment: 0.0,
            range_min: 0.0,
            range_max: 0.0,
            has_truth: 0,
            count: 0,
            truth: PoseMsgXyt::default(),
            ranges: [0.0; MAX_BEAMS],
            has_odometry: 0,
            _pad: 0,
            odometry: PoseMsgXyt::default(),
        };
        for beams in [1, 682, MAX_BEAMS] {
            let s = scan(beams);
            scan_to_msg(&s, None, 7, 0, &mut m);
            assert_eq!(m.count as usize, beams);
            assert_eq!(m.angle_increment, s.geometry.angle_increment);
            assert_eq!(&m.ranges[..beams], &s.ranges[..]);
        }
        for (beams, every) in [(MAX_BEAMS + 1, 2), (3240, 2), (4 * MAX_BEAMS + 5, 5)] {
            let s = scan(beams);
            scan_to_msg(&s, None, 7, 0, &mut m);
            let n = m.count as usize;
            assert_eq!(thinning(beams), every);
            assert_eq!(n, beams.div_ceil(every));
            assert!(n <= MAX_BEAMS);
            assert_eq!(m.angle_increment, s.geometry.angle_increment * every as f64);
            assert!((0..n).all(|i| m.ranges[i] == (i * every) as f32));
            let last = m.angle_min + (n - 1) as f64 * m.angle_increment;
            let sensor_last = s.geometry.angle_min + (beams - 1) as f64 * s.geometry.angle_increment;
            assert!(last <= sensor_last + 1e-9 && sensor_last - last < m.angle_increment);
        }
    }
}
