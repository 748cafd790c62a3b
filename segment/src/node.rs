//! The segmentation process: scans in (`gema2/scan`), lines and corners out (`gema2/lines`,
//! `gema2/corners`). Blocks in a WaitSet on the scan topic's event; allocates nothing per scan.
//! Its outputs wait for room in their subscribers' buffers instead of dropping: only the
//! source drops scans, so a pipeline that falls behind sheds load at its entry, never between
//! stages. The corners topic keeps its latest message: when a stage announces itself ready (a
//! localizer that started, restarted or was swapped in), this stage hands it that message at
//! once ([`Outlet::serve_history`]) rather than at the next scan.

use crate::split_merge::{segmenter_by_name, SEGMENTERS};
use crate::wire::{corner_to_msg, line_to_msg, scan_view};
use crate::{Segmentation, SegmenterConfig};
use anyhow::{anyhow, Context, Result};
use clap::Args;
use messages::iceoryx2::prelude::*;
use messages::{
    monotonic_ns, CornersMsg, Freshness, Header, Inlet, LinesMsg, Look, Outlet, Refused, ScanMsg, Stage, Topic,
    MAX_CORNERS, MAX_LINES,
};

/// What the stage is, for its `--help` (its own program's and `gema2 stage segment`'s).
pub const ABOUT: &str = "GEMA2 segmentation stage: scans in, lines and corners out";

#[derive(Args, Debug, Clone)]
pub struct SegmentArgs {
    #[command(flatten)]
    pub stage: messages::StageArgs,
    /// Implementation: line-visibility (the paper's) or split-and-merge.
    #[arg(long = "impl", default_value = "line-visibility")]
    pub implementation: String,
    /// Override a segmentation parameter, KEY=VALUE (repeatable), as `gema2 locate --set`.
    /// Give the localize stage the same error model and `wall_ends`.
    #[arg(long = "set", value_name = "KEY=VALUE")]
    pub set: Vec<String>,
}

pub fn run(a: SegmentArgs) -> Result<()> {
    let mut config = SegmenterConfig::default();
    config.apply(&a.set).context("segment: --set")?;
    a.stage.place()?;
    let segmenter = segmenter_by_name(&a.implementation, config)
        .ok_or_else(|| anyhow!("unknown segment implementation {:?}: one of {SEGMENTERS:?}", a.implementation))?;
    let node = messages::create_node(&format!("segment-{}", a.implementation))?;
    let scans = Inlet::<ScanMsg>::open(&node, &a.stage.prefix, Topic::Scan)?;
    // inner links wait for room rather than drop: a slow pipeline sheds load at its source
    let mut stage = Segmenting {
        segmenter,
        fresh: Freshness::default(),
        bad_scans: 0,
        found_by_poll: 0,
        lines_out: Outlet::open(&node, &a.stage.prefix, Topic::Lines, BackpressureStrategy::RetryUntilDelivered)?,
        corners_out: Outlet::open(&node, &a.stage.prefix, Topic::Corners, BackpressureStrategy::RetryUntilDelivered)?,
    };
    // without it the stage still segments; a new localizer then waits for the next scan
    let ready = messages::ready_listener(&node, &a.stage.prefix)
        .map_err(|e| messages::say!("segment: a new localizer will wait for the next scan: {e}"))
        .ok();
    messages::announce_ready(&node, &a.stage.prefix)?;
    let mut failure: Option<anyhow::Error> = None;
    let on_event = |woken: &[bool]| {
        if let Some(ready) = ready.as_ref().filter(|_| woken.get(1) == Some(&true)) {
            // a stage is ready: a new localizer gets the latest scan's corners now
            let _ = ready.try_wait(|_| {});
            if let Err(e) = stage.corners_out.serve_history() {
                messages::say!("segment: {e}");
            }
        }
        let mut look = Look::new([&scans.listener], woken[0]);
        while look.next_pass() {
            loop {
                let taken = match look.receive(&scans.subscriber) {
                    Ok(Some((sample, enter))) => stage.take(&sample, enter, &mut look),
                    Ok(None) => break,
                    Err(e) => Err(anyhow!("{}: receive: {e}", scans.name)),
                };
                if let Err(e) = taken {
                    failure = Some(e);
                    return CallbackProgression::Stop;
                }
            }
        }
        // woken ahead of a scan: wake the localizer too (the lines' only reader records them)
        if look.warm_up_to_pass_on() {
            if let Err(e) = stage.corners_out.warm_up() {
                messages::say!("segment: {e}");
            }
        }
        CallbackProgression::Continue
    };
    let mut listeners = vec![(scans.name.as_str(), &scans.listener)];
    listeners.extend(ready.as_ref().map(|r| ("the readiness event", r)));
    messages::run_stage(&node, &listeners, messages::MISSED_WAKEUP_POLL, on_event)?;
    stage.report();
    match failure {
        Some(e) => Err(e),
        None => Ok(()),
    }
    .context("segment")
}

/// What the stage keeps from scan to scan: the segmenter, what tells a scan seen before, its
/// counts, and its two outlets.
struct Segmenting {
    segmenter: Box<dyn crate::Segmenter>,
    fresh: Freshness,
    bad_scans: u64,
    found_by_poll: u64,
    lines_out: Outlet<LinesMsg>,
    corners_out: Outlet<CornersMsg>,
}

impl Segmenting {
    /// Segments `scan`, taken at `enter` in `look`, and publishes its lines and corners. A copy
    /// of a scan already segmented is skipped; one that cannot be read, or is stamped ahead of
    /// the clock, is dropped with a notice.
    fn take<const N: usize>(&mut self, scan: &ScanMsg, enter: u64, look: &mut Look<'_, N>) -> Result<()> {
        match self.fresh.check(&scan.header, monotonic_ns()) {
            Ok(()) => {}
            Err(Refused::Seen) => return Ok(()),
            Err(refused) => {
                self.bad_scans += 1;
                messages::say!("segment: dropped scan {}: {refused} ({} so far)", scan.header.seq, self.bad_scans);
                return Ok(());
            }
        }
        self.found_by_poll += u64::from(look.found_by_poll());
        let view = match scan_view(scan) {
            Ok(v) => v,
            Err(e) => {
                self.bad_scans += 1;
                messages::say!("segment: dropped {e} ({} so far)", self.bad_scans);
                return Ok(());
            }
        };
        let name = self.segmenter.name();
        let seg = self.segmenter.segment(&view);
        let mut header = scan.header;
        header.span(Stage::Segment).enter_ns = enter;
        header.set_producer(name);
        self.lines_out
            .send(|m: &mut LinesMsg| write_lines(m, header, seg))
            .and_then(|_| self.corners_out.send(|m: &mut CornersMsg| write_corners(m, scan, header, seg)))
            .map(|_| ())
            .map_err(|e| anyhow!("segment: publishing scan {}: {e}", header.seq))
    }

    /// What the stage says when it stops.
    fn report(&self) {
        if self.found_by_poll > 0 {
            messages::say!("segment: scans found by the poll, not by a wake-up, {} times", self.found_by_poll);
        }
        for r in [self.lines_out.report(), self.corners_out.report()].into_iter().flatten() {
            messages::say!("segment: {r}");
        }
    }
}

/// Writes a scan's lines into `m` (the viewer's record of them). The message leaves the
/// stage as it is sent: the hop after it is transport only.
fn write_lines(m: &mut LinesMsg, header: Header, seg: &Segmentation) {
    m.header = header;
    m.raw_count = seg.raw_lines.len() as u32;
    m.count = write_line_msgs(&mut m.lines, seg);
    m.header.span(Stage::Segment).leave_ns = monotonic_ns();
}

/// Writes what the localizer needs of a scan into `m`: the scan itself (the localizer casts
/// its beams), its corners, its lines (for the slide search) and the noise scale the
/// segmenter found.
fn write_corners(m: &mut CornersMsg, scan: &ScanMsg, header: Header, seg: &Segmentation) {
    m.scan = *scan;
    m.scan.header = header;
    m.noise_scale = seg.noise_scale;
    let n = seg.corners.len().min(MAX_CORNERS);
    m.count = n as u32;
    for (slot, c) in m.corners.iter_mut().zip(&seg.corners[..n]) {
        *slot = corner_to_msg(c);
    }
    m.line_count = write_line_msgs(&mut m.lines, seg);
    m.scan.header.span(Stage::Segment).leave_ns = monotonic_ns();
}

/// Writes the scan's lines into a message's line slots, as many as fit ([`MAX_LINES`]);
/// returns how many.
fn write_line_msgs(slots: &mut [messages::LineMsg; MAX_LINES], seg: &Segmentation) -> u32 {
    let n = seg.lines.len().min(MAX_LINES);
    for (slot, l) in slots.iter_mut().zip(&seg.lines[..n]) {
        *slot = line_to_msg(l);
    }
    n as u32
}
