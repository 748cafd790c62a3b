//! The localization process: corners (with their scan) and the map in, ranked poses out
//! (`gema2/pose`). The map arrives on `gema2/map` with history, so a late start still gets it;
//! a new map version is used from the next scan on. A scan seen before (two segmenters during a
//! hot swap) is skipped; gaps are fine.

use crate::slide::SlideLine;
use crate::{Gema2Config, Localization, Localizer, MapModel, Status};
use anyhow::{anyhow, Context, Result};
use clap::Args;
use laser::{pose_theta, ScanView};
use mapserver::wire::map_from_msg;
use messages::iceoryx2::prelude::*;
use messages::{
    monotonic_ns, CornersMsg, Freshness, HypothesisMsg, Inlet, Look, MapMsg, Outlet, PoseMsg, PoseMsgXyt, Stage, Topic,
    MAX_HYPOTHESES, STATUS_AMBIGUOUS, STATUS_FAILED, STATUS_OK,
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
    let map = Inlet::<MapMsg>::open(&node, &a.stage.prefix, Topic::Map)?;
    let mut pose_out =
        Outlet::<PoseMsg>::open(&node, &a.stage.prefix, Topic::Pose, BackpressureStrategy::RetryUntilDelivered)?;

    let mut state = Located::new(config);
    let mut failure: Option<anyhow::Error> = None;
    let on_event = |woken: &[bool]| {
        // both queues in each pass (messages::Look)
        let mut look = Look::new([&map.listener, &corners.listener], woken[0]);
        while look.next_pass() {
            // the map: newest version wins
            while let Ok(Some(m)) = map.subscriber.receive() {
                // ready once there is a map to localize against
                if state.take_map(&m) {
                    if let Err(e) = messages::announce_ready(&node, &a.stage.prefix) {
                        eprintln!("localize: {e}");
                    }
                }
            }
            loop {
                let taken = match look.receive(&corners.subscriber) {
                    Ok(Some((sample, enter))) => state.take(&sample, enter, &mut look, &mut pose_out),
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
                eprintln!("localize: {e}");
            }
        }
        CallbackProgression::Continue
    };
    // the map may already be waiting in history; a wake-up may be lost (MISSED_WAKEUP_POLL)
    let listeners = [(corners.name.as_str(), &corners.listener), (map.name.as_str(), &map.listener)];
    messages::run_stage(&node, &listeners, messages::MISSED_WAKEUP_POLL, on_event).context("localize")?;
    state.report(&pose_out);
    match failure {
        Some(e) => Err(e),
        None => Ok(()),
    }
    .context("localize")
}

/// What the stage keeps from scan to scan: the localizer with its map's version (none before
/// the first map), and what tells a scan seen before.
struct Located {
    config: Gema2Config,
    localizer: Option<(Localizer, u32)>,
    seg: Segmentation,
    fresh: Freshness,
    waiting_for_map: u64,
    found_by_poll: u64,
}

impl Located {
    fn new(config: Gema2Config) -> Self {
        Located {
            config,
            localizer: None,
            seg: Segmentation::default(),
            fresh: Freshness::default(),
            waiting_for_map: 0,
            found_by_poll: 0,
        }
    }

    /// Takes a map from the wire when its version is new; a bad map is reported and ignored.
    /// Returns whether this was the first map, so the stage is now ready.
    fn take_map(&mut self, m: &MapMsg) -> bool {
        if self.localizer.as_ref().is_some_and(|(_, v)| *v == m.version) {
            return false;
        }
        let walls = match map_from_msg(m) {
            Ok(walls) => walls,
            Err(e) => {
                eprintln!("localize: ignored a bad map: {e}");
                return false;
            }
        };
        let model = Arc::new(MapModel::new(walls, &self.config.map_corners));
        eprintln!("localize: map version {} ({} walls)", m.version, m.count);
        match self.localizer.as_mut() {
            Some((l, v)) => {
                l.set_model(model);
                *v = m.version;
                false
            }
            None => {
                self.localizer = Some((Localizer::new(model, self.config.localizer), m.version));
                true
            }
        }
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
        let Some((result, version)) = self.locate(msg) else { return Ok(()) };
        out.send(|p: &mut PoseMsg| write_pose(p, msg, result, version, enter))
            .map(|_| ())
            .map_err(|e| anyhow!("localize: publishing pose {}: {e}", msg.scan.header.seq))
    }

    /// What the stage says when it stops, with its outlet's report.
    fn report(&self, out: &Outlet<PoseMsg>) {
        if self.found_by_poll > 0 {
            eprintln!("localize: scans found by the poll, not by a wake-up, {} times", self.found_by_poll);
        }
        if let Some(r) = out.report() {
            eprintln!("localize: {r}");
        }
    }

    /// Whether the scan `msg` carries is one to locate: not one seen before (a resend, or a
    /// second segmenter during a hot swap), and not one before any map (counted, and said now
    /// and then).
    fn admit(&mut self, msg: &CornersMsg) -> bool {
        if !self.fresh.admit(&msg.scan.header) {
            return false;
        }
        if self.localizer.is_none() {
            self.waiting_for_map += 1;
            if self.waiting_for_map == 1 || self.waiting_for_map.is_multiple_of(100) {
                eprintln!("localize: no map yet, {} scans skipped", self.waiting_for_map);
            }
            return false;
        }
        true
    }

    /// Locates the scan of an admitted `msg` ([`admit`](Self::admit)), with the version of the
    /// map it was located in; `None` before any map, and for a scan that cannot be read
    /// (reported).
    fn locate(&mut self, msg: &CornersMsg) -> Option<(&Localization, u32)> {
        let (loc, version) = self.localizer.as_mut()?;
        let view = match scan_view(&msg.scan) {
            Ok(v) => v,
            Err(e) => {
                eprintln!("localize: dropped {e}");
                return None;
            }
        };
        segmentation_from(msg, &view, &self.config, &mut self.seg);
        let lines = msg.lines[..(msg.line_count as usize).min(msg.lines.len())].iter().filter_map(slide_line);
        Some((loc.locate_with_lines(&view, &self.seg, lines), *version))
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
            let result = Localization {
                hypotheses: Vec::new(),
                status,
                candidates: 0,
                times: Default::default(),
                all_candidates: Vec::new(),
                slide_step: None,
            };
            write_pose(&mut p, &corners, &result, 1, 0);
            assert_eq!(messages::status_name(p.status), status.as_str());
        }
    }
}
