//! The localization process: corners (with their scan) and the map model in, ranked poses out
//! (`gema2/pose`). The model arrives on `gema2/map/model` with history, built by the map
//! server once per map version and read here in place ([`MapModel::from_block`]), so a late
//! start, a restart or a swapped-in localizer locates from its first scan. That first scan is
//! the latest one the segment stage sent: the corners topic keeps it, and the segment stage
//! hands it over when this stage announces itself ready; a scan that comes before the model
//! waits for it. A new version is
//! used from the next scan on; the old one is read until then. A model built for other corner
//! settings than this stage's is refused. A scan seen before (two segmenters during a hot swap)
//! is skipped; gaps are fine.

use crate::slide::SlideLine;
use crate::{Gema2Config, Localization, Localizer, MapModel, Status};
use anyhow::{anyhow, bail, Context, Result};
use clap::Args;
use laser::{pose_theta, ScanView};
use map::flat::{FlatError, FlatReader};
use map::model::MODEL_LAYOUT;
use messages::iceoryx2::prelude::*;
use messages::iceoryx2::sample::Sample;
use messages::{
    monotonic_ns, open_model_topic, CornersMsg, Freshness, HypothesisMsg, Inlet, Look, ModelHeader, Outlet, PoseMsg,
    PoseMsgXyt, Refused, Stage, Topic, MAX_HYPOTHESES, STATUS_AMBIGUOUS, STATUS_FAILED, STATUS_OK,
};
use segment::noise::usable_scale;
use segment::sample::build_samples;
use segment::wire::{corner_from_msg, scan_view};
use segment::Segmentation;
use std::sync::Arc;

/// What the stage is, for its `--help` (its own program's and `gema2 stage localize`'s).
pub const ABOUT: &str = "GEMA2 localization stage: corners and map in, ranked poses out";

#[derive(Args, Debug, Clone)]
pub struct LocalizeArgs {
    #[command(flatten)]
    pub stage: messages::StageArgs,
    /// Track: after an ok scan, make only poses within this radius (metres) of it: the most the
    /// robot moves between two located scans.
    #[arg(long, value_parser = track_radius)]
    pub track: Option<f64>,
    /// Override a parameter, KEY=VALUE (repeatable), as `gema2 locate --set`. Settings of the
    /// segmentation's error model and `wall_ends` must match the segment stage's.
    #[arg(long = "set", value_name = "KEY=VALUE")]
    pub set: Vec<String>,
    /// The implementation: `gema2`, one scan at a time, or `sequential`, hypotheses carried
    /// from scan to scan by the odometry the scans carry (`localize::sequential`).
    #[arg(long = "impl", default_value = "gema2", value_parser = implementation)]
    pub implementation: String,
}

/// Parses `--impl`: one of [`crate::LOCALIZERS`].
fn implementation(s: &str) -> Result<String, String> {
    crate::LOCALIZERS.contains(&s).then(|| s.to_owned()).ok_or_else(|| format!("{s}: one of {:?}", crate::LOCALIZERS))
}

/// The localizer the stage runs.
enum Engine {
    Single(Box<Localizer>),
    Sequential(Box<(crate::Sequential, Localization)>),
}

impl Engine {
    fn new(model: Arc<MapModel>, config: &Gema2Config, sequential: bool) -> Self {
        let localizer = Localizer::new(model, config.localizer);
        if !sequential {
            return Engine::Single(Box::new(localizer));
        }
        Engine::Sequential(Box::new((crate::Sequential::new(localizer, config.sequential), Localization::none())))
    }

    fn set_model(&mut self, model: Arc<MapModel>) {
        match self {
            Engine::Single(l) => l.set_model(model),
            Engine::Sequential(b) => b.0.set_model(model),
        }
    }

    /// Locates one scan; the answer and how many scans it rests on.
    fn locate(
        &mut self,
        view: &ScanView<'_>,
        seg: &Segmentation,
        lines: impl IntoIterator<Item = SlideLine>,
        odometry: Option<laser::Pose>,
    ) -> (&Localization, u32) {
        match self {
            Engine::Single(l) => {
                let loc = l.locate_with_lines(view, seg, lines);
                let scans = u32::from(loc.status != Status::Failed);
                (loc, scans)
            }
            Engine::Sequential(b) => {
                let (s, out) = &mut **b;
                let answer = s.locate_with_lines(view, seg, lines, odometry);
                out.status = answer.status;
                out.hypotheses.clear();
                out.hypotheses.extend(s.hypotheses(&answer));
                (out, answer.scans)
            }
        }
    }
}

/// Parses `--track`: a radius in metres above 0 (tracking within none would fail every scan
/// after the first `ok` one).
pub fn track_radius(s: &str) -> Result<f64, String> {
    match s.parse::<f64>() {
        Ok(r) if r.is_finite() && r > 0.0 => Ok(r),
        _ => Err(format!("{s}: a radius in metres above 0")),
    }
}

pub fn run(a: LocalizeArgs) -> Result<()> {
    let mut config = Gema2Config::default();
    config.localizer.track_radius = a.track;
    config.apply(&a.set).context("localize: --set")?;
    a.stage.place()?;
    let node = messages::create_node("localize")?;
    let corners = Inlet::<CornersMsg>::open(&node, &a.stage.prefix, Topic::Corners)?;
    let model_ports = open_model_topic(&node, &a.stage.prefix)?;
    let models = model_ports.subscriber()?;
    let model_listener =
        model_ports.event.listener_builder().create().map_err(|e| anyhow!("{}: listener: {e:?}", model_ports.name))?;
    let mut pose_out =
        Outlet::<PoseMsg>::open(&node, &a.stage.prefix, Topic::Pose, BackpressureStrategy::RetryUntilDelivered)?;

    let mut state = Located::new(config, a.implementation == "sequential");
    let mut failure: Option<anyhow::Error> = None;
    let on_event = |woken: &[bool]| {
        // both queues in each pass (messages::Look)
        let mut look = Look::new([&model_listener, &corners.listener], woken[0]);
        while look.next_pass() {
            // the model: newest version wins
            loop {
                let taken = match models.receive() {
                    Ok(Some(sample)) => state.take_model(sample),
                    Ok(None) => break,
                    Err(e) => Err(anyhow!("{}: receive: {e:?}", model_ports.name)),
                };
                match taken {
                    // ready once there is a model to localize against: the scan that waited
                    // for it is located now, and the segment stage hands over its latest
                    Ok(true) => {
                        if let Err(e) = state.locate_held(&mut pose_out) {
                            failure = Some(e);
                            return CallbackProgression::Stop;
                        }
                        if let Err(e) = messages::announce_ready(&node, &a.stage.prefix) {
                            messages::say!("localize: {e}");
                        }
                    }
                    Ok(false) => {}
                    Err(e) => {
                        failure = Some(e);
                        return CallbackProgression::Stop;
                    }
                }
            }
            loop {
                let taken = match look.receive(&corners.subscriber) {
                    Ok(Some((sample, _))) if state.localizer.is_none() => {
                        state.hold(sample);
                        Ok(())
                    }
                    Ok(Some((sample, enter))) => {
                        let taken = state.take(&sample, enter, &mut look, &mut pose_out);
                        // a scan that filtered a cell's walls (map::raycast) freed a list the
                        // size of the map's walls; kept, its pages would count against the
                        // process for good
                        messages::return_freed_memory();
                        taken
                    }
                    Ok(None) => break,
                    Err(e) => Err(anyhow!("{}: receive: {e}", corners.name)),
                };
                if let Err(e) = taken {
                    failure = Some(e);
                    return CallbackProgression::Stop;
                }
            }
        }
        // woken ahead of a scan: wake the pose's readers too
        if look.warm_up_to_pass_on() {
            if let Err(e) = pose_out.warm_up() {
                messages::say!("localize: {e}");
            }
        }
        CallbackProgression::Continue
    };
    // the map may already be waiting in history; a wake-up may be lost (MISSED_WAKEUP_POLL)
    let listeners = [(corners.name.as_str(), &corners.listener), (model_ports.name.as_str(), &model_listener)];
    messages::run_stage(&node, &listeners, messages::MISSED_WAKEUP_POLL, on_event).context("localize")?;
    state.report(&pose_out);
    match failure {
        Some(e) => Err(e),
        None => Ok(()),
    }
    .context("localize")
}

/// A model block in shared memory that a model read from it views, and the lease its views
/// hold: the block is released to the map server only once nothing holds the lease but this.
struct HeldBlock {
    _sample: Sample<ipc::Service, [u8], ModelHeader>,
    lease: Arc<Lease>,
}

/// What a model's views of a [`HeldBlock`] keep alive: while any holds it, the block is not
/// released (and so never reused by the map server).
struct Lease;

/// What the stage keeps from scan to scan: the localizer with its map's version (none before
/// the first map), the model blocks it reads, and what tells a scan seen before.
struct Located {
    config: Gema2Config,
    /// Whether the stage runs the sequential localizer.
    sequential: bool,
    localizer: Option<(Engine, u32)>,
    /// The blocks the models in use view; the oldest is released once its model is dropped.
    blocks: Vec<HeldBlock>,
    /// The latest scan that came before any model: located as soon as the model is there.
    held: Option<Sample<ipc::Service, CornersMsg, ()>>,
    seg: Segmentation,
    fresh: Freshness,
    /// Scans dropped for a stamp ahead of the clock ([`Refused::Ahead`]).
    ahead: u64,
    waiting_for_map: u64,
    found_by_poll: u64,
    /// When the stage started, until its first pose is published (then said, with the time).
    started: Option<std::time::Instant>,
}

impl Located {
    fn new(config: Gema2Config, sequential: bool) -> Self {
        Located {
            config,
            sequential,
            localizer: None,
            blocks: Vec::new(),
            held: None,
            seg: Segmentation::default(),
            fresh: Freshness::default(),
            ahead: 0,
            waiting_for_map: 0,
            found_by_poll: 0,
            started: Some(std::time::Instant::now()),
        }
    }

    /// Takes a model block from the map server: reads the model in place and locates with it
    /// from the next scan on. Returns whether this was the first model, so the stage is now
    /// ready. A block that is no readable model is refused, said and skipped. A model of another
    /// layout or built for other corner settings is refused too: an error when there is no
    /// model to go on with, said and skipped when there is.
    fn take_model(&mut self, sample: Sample<ipc::Service, [u8], ModelHeader>) -> Result<bool> {
        let header = *sample.user_header();
        if self.localizer.as_ref().is_some_and(|(_, v)| *v == header.map_version) {
            return Ok(false);
        }
        let started = std::time::Instant::now();
        let lease = Arc::new(Lease);
        let read = self.read_model(&sample, &lease);
        let (model, copied) = match read {
            Ok(m) => m,
            Err(e) if self.localizer.is_some() => {
                messages::say!(
                    "localize: kept map version {}: refused version {}: {e:#}",
                    self.version(),
                    header.map_version
                );
                return Ok(false);
            }
            // a block that is no readable model (damaged, or none at all: a faulty or hostile
            // publisher on the topic) is no reason to stop: the map server's model may come
            // after it; a model of another layout or settings is this pipeline's own mistake
            Err(e) if e.downcast_ref::<FlatError>().is_some() => {
                messages::say!("localize: no map yet: refused version {}: {e:#}", header.map_version);
                return Ok(false);
            }
            Err(e) => return Err(e.context(format!("map version {}", header.map_version))),
        };
        messages::say!(
            "localize: map version {} ({} walls, {} corners): {:.1} MB read in place, {} KB copied, in {:.1} ms{}",
            header.map_version,
            model.map.walls.len(),
            model.corners.corners().len(),
            header.block_len as f64 / 1e6,
            copied / 1024,
            started.elapsed().as_secs_f64() * 1e3,
            self.started.map_or(String::new(), |s| format!(
                "; ready {:.1} ms after the stage started",
                s.elapsed().as_secs_f64() * 1e3
            ))
        );
        self.blocks.push(HeldBlock { _sample: sample, lease });
        let model = Arc::new(model);
        let first = match self.localizer.as_mut() {
            Some((l, v)) => {
                l.set_model(model);
                *v = header.map_version;
                false
            }
            None => {
                self.localizer = Some((Engine::new(model, &self.config, self.sequential), header.map_version));
                true
            }
        };
        // the blocks no model views any more go back to the map server
        self.blocks.retain(|b| Arc::strong_count(&b.lease) > 1);
        Ok(first)
    }

    /// The model in the block `sample` holds, its views owned by `lease`, with the bytes it
    /// copied out; an error for a block of another layout, a damaged one, or a model built for
    /// other corner settings than this stage's.
    fn read_model(
        &self,
        sample: &Sample<ipc::Service, [u8], ModelHeader>,
        lease: &Arc<Lease>,
    ) -> Result<(MapModel, usize)> {
        let layout = sample.user_header().layout;
        if layout != MODEL_LAYOUT {
            bail!(
                "the map server's model has layout {layout}, this localizer reads {MODEL_LAYOUT}: rebuild both \
                 from the same sources"
            );
        }
        let bytes: &[u8] = sample.payload();
        let owner: map::slab::Owner = lease.clone();
        // SAFETY: the block lies in the sample, which `blocks` keeps (unchanged: the publisher
        // never writes a sent sample) until nothing holds `lease`, the owner of every view read
        // from it; the subscriber outlives the stage's state
        let mut r = unsafe { FlatReader::new(std::slice::from_raw_parts(bytes.as_ptr(), bytes.len()), owner) }?;
        let model = MapModel::from_block(&mut r)?;
        if let Some(d) = self.config.model_disagreement(&model.corner_config) {
            bail!(
                "the map server's model was built for other corner settings ({d}): give the map server and \
                 the localizer the same --set, or put it in the pipeline file's top-level settings"
            );
        }
        Ok((model, r.copied()))
    }

    /// The map version located with; 0 before any.
    fn version(&self) -> u32 {
        self.localizer.as_ref().map_or(0, |(_, v)| *v)
    }

    /// Locates the scan of `msg`, taken at `enter` in `look`, and publishes its pose to `out`;
    /// a scan not [`admit`](Self::admit)ted is skipped.
    fn take<const N: usize>(
        &mut self,
        msg: &CornersMsg,
        enter: u64,
        look: &mut Look<'_, N>,
        out: &mut Outlet<PoseMsg>,
    ) -> Result<()> {
        if !self.admit(msg) {
            return Ok(());
        }
        self.found_by_poll += u64::from(look.found_by_poll());
        self.publish(msg, enter, out)
    }

    /// Locates the scan of an admitted `msg`, taken at `enter`, and publishes its pose to
    /// `out`: what [`take`](Self::take) does, and what a scan held for the model gets.
    fn publish(&mut self, msg: &CornersMsg, enter: u64, out: &mut Outlet<PoseMsg>) -> Result<()> {
        let Some((result, scans, version)) = self.locate(msg) else { return Ok(()) };
        out.send(|p: &mut PoseMsg| {
            write_pose(p, msg, result, version, enter);
            p.scans = scans;
        })
        .map_err(|e| anyhow!("localize: publishing pose {}: {e}", msg.scan.header.seq))?;
        if let Some(started) = self.started.take() {
            let ms = |ns: u64| ns as f64 / 1e6;
            messages::say!(
                "localize: first pose {:.1} ms after the stage started (scan {}, {:.1} ms old when taken, located in \
                 {:.1} ms)",
                started.elapsed().as_secs_f64() * 1e3,
                msg.scan.header.seq,
                ms(enter.saturating_sub(msg.scan.header.stamp_ns)),
                ms(monotonic_ns().saturating_sub(enter))
            );
        }
        Ok(())
    }

    /// What the stage says when it stops, with its outlet's report.
    fn report(&self, out: &Outlet<PoseMsg>) {
        if self.found_by_poll > 0 {
            messages::say!("localize: scans found by the poll, not by a wake-up, {} times", self.found_by_poll);
        }
        if let Some(r) = out.report() {
            messages::say!("localize: {r}");
        }
    }

    /// Keeps `sample`, a scan that came before any model, to be located once the model is
    /// there ([`locate_held`](Self::locate_held)); the one it replaces is skipped.
    fn hold(&mut self, sample: Sample<ipc::Service, CornersMsg, ()>) {
        if self.held.replace(sample).is_some() {
            self.skipped_for_want_of_a_map();
        }
    }

    /// Locates the scan [`hold`](Self::hold) kept, if any, and publishes its pose to `out`.
    fn locate_held(&mut self, out: &mut Outlet<PoseMsg>) -> Result<()> {
        match self.held.take() {
            Some(sample) if self.admit(&sample) => self.publish(&sample, monotonic_ns(), out),
            _ => Ok(()),
        }
    }

    /// Counts a scan skipped before any map, and says so now and then.
    fn skipped_for_want_of_a_map(&mut self) {
        self.waiting_for_map += 1;
        if self.waiting_for_map == 1 || self.waiting_for_map.is_multiple_of(100) {
            messages::say!("localize: no map yet, {} scans skipped", self.waiting_for_map);
        }
    }

    /// Whether the scan `msg` carries is one to locate: not one seen before (a resend, or a
    /// second segmenter during a hot swap), not one stamped ahead of the clock (a damaged
    /// message, or a source stamping with another clock), and not one before any map. The last
    /// two are counted, and said now and then.
    fn admit(&mut self, msg: &CornersMsg) -> bool {
        let header = &msg.scan.header;
        match self.fresh.check(header, monotonic_ns()) {
            Ok(()) => {}
            Err(Refused::Seen) => return false,
            Err(refused) => {
                self.ahead += 1;
                if self.ahead == 1 || self.ahead.is_multiple_of(100) {
                    messages::say!("localize: dropped scan {}: {refused} ({} so far)", header.seq, self.ahead);
                }
                return false;
            }
        }
        if self.localizer.is_none() {
            self.skipped_for_want_of_a_map();
            return false;
        }
        true
    }

    /// Locates the scan of an admitted `msg` ([`admit`](Self::admit)), with the version of the
    /// map it was located in; `None` before any map, and for a scan that cannot be read
    /// (reported).
    fn locate(&mut self, msg: &CornersMsg) -> Option<(&Localization, u32, u32)> {
        let (loc, version) = self.localizer.as_mut()?;
        let view = match scan_view(&msg.scan) {
            Ok(v) => v,
            Err(e) => {
                messages::say!("localize: dropped {e}");
                return None;
            }
        };
        segmentation_from(msg, &view, &self.config, &mut self.seg);
        let lines = msg.lines[..(msg.line_count as usize).min(msg.lines.len())].iter().filter_map(slide_line);
        // one that is not a number the sequential localizer takes as none
        let odometry = (msg.scan.has_odometry == 1)
            .then(|| laser::pose(msg.scan.odometry.x, msg.scan.odometry.y, msg.scan.odometry.theta));
        let (result, scans) = loc.locate(&view, &self.seg, lines, odometry);
        Some((result, scans, *version))
    }
}

/// The segmentation the localizer reads, from the segment stage's message: the scan's samples
/// rebuilt with the error model widened as the segmenter widened its own, and the corners.
/// The lines travel separately ([`slide_line`]).
fn segmentation_from(msg: &CornersMsg, view: &ScanView<'_>, config: &Gema2Config, seg: &mut Segmentation) {
    seg.noise_scale = usable_scale(msg.noise_scale);
    let error = config.segmenter.error.scaled(seg.noise_scale);
    build_samples(view, &error, config.segmenter.averaging, &mut seg.samples);
    seg.corners.clear();
    let n = (msg.count as usize).min(msg.corners.len());
    seg.corners.extend(msg.corners[..n].iter().filter_map(corner_from_msg));
}

/// Writes the outcome of the scan `msg` carried into the pose message `p`: status, the best
/// hypotheses, the map version, the scan's truth when it has one, and the stage's span.
fn write_pose(p: &mut PoseMsg, msg: &CornersMsg, result: &Localization, map_version: u32, enter_ns: u64) {
    p.header = msg.scan.header;
    p.header.span(Stage::Localize).enter_ns = enter_ns;
    p.header.set_producer("gema2");
    p.status = match result.status {
        Status::Ok => STATUS_OK,
        Status::Ambiguous => STATUS_AMBIGUOUS,
        Status::Failed => STATUS_FAILED,
    };
    p.candidates = result.candidates as u32;
    p.map_version = map_version;
    p.has_truth = msg.scan.has_truth;
    p.truth = msg.scan.truth;
    let k = result.hypotheses.len().min(MAX_HYPOTHESES);
    p.count = k as u32;
    for (slot, h) in p.hypotheses.iter_mut().zip(&result.hypotheses[..k]) {
        *slot = HypothesisMsg {
            pose: PoseMsgXyt { x: h.pose.translation.x, y: h.pose.translation.y, theta: pose_theta(&h.pose) },
            cost: h.cost.value,
            inliers: h.cost.inliers,
            through: h.cost.through,
            scan_corner: h.scan_corner as u32,
            map_corner: h.map_corner,
        };
    }
    // the stage ends as the message is sent: the hop after it is transport only
    p.header.span(Stage::Localize).leave_ns = monotonic_ns();
}

/// A line from the wire as the slide search reads it; `None` if any number is not finite.
fn slide_line(m: &messages::LineMsg) -> Option<SlideLine> {
    let finite = m.start.iter().chain(&m.end).chain([&m.direction_sigma]).all(|v| v.is_finite());
    finite.then(|| SlideLine {
        start: nalgebra::Point2::new(m.start[0], m.start[1]),
        end: nalgebra::Point2::new(m.end[0], m.end[1]),
        direction_sigma: m.direction_sigma,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The wire's outcome codes read back as the localizer names its statuses.
    #[test]
    fn a_status_on_the_wire_reads_as_the_localizer_names_it() {
        for status in [Status::Ok, Status::Ambiguous, Status::Failed] {
            let mut p: Box<PoseMsg> = messages::zeroed_box();
            let corners: Box<CornersMsg> = messages::zeroed_box();
            let result = Localization { status, ..Localization::none() };
            write_pose(&mut p, &corners, &result, 1, 0);
            assert_eq!(messages::status_name(p.status), status.as_str());
        }
    }
}
