//! Messages to rerun: each pipeline message becomes the entities of [`crate::entities`] at its
//! scan's time. Pure of IPC, so it is tested with hand-made messages.

use crate::entities::*;
use crate::output::{Output, OutputError};
use laser::ScanGeometry;
use map::{CornerIndex, MapCornerConfig, SeenFree};
use mapserver::wire::map_from_msg;
use messages::{
    status_name, CornersMsg, Freshness, Header, HypothesisMsg, LinesMsg, MapMsg, PoseMsg, PoseMsgXyt, Refused, ScanMsg,
    Topic, MAX_BEAMS, MAX_CORNERS, MAX_HYPOTHESES, MAX_LINES, STATUS_AMBIGUOUS, STATUS_OK,
};
use rerun::components::TextLogLevel;
use rerun::datatypes::Rgba32;
use rerun::{Arrows2D, Color, Image, LineStrips2D, Points2D, RecordingStream, Scalars, TextLog, Transform3D};
use std::collections::VecDeque;
use std::time::Duration;

/// Success, as `gema2 locate` counts it: within this distance of the truth...
pub const SUCCESS_DISTANCE: f64 = 0.30;
/// ... and within this heading.
pub const SUCCESS_HEADING_DEG: f64 = 5.0;

/// Scans (and their corners) kept to place readings at a pose that arrives later.
const KEPT_SCANS: usize = 128;
/// Length of the arrows drawn for poses, metres.
const ARROW: f32 = 0.5;

const OK_COLOUR: Color = Color(Rgba32::from_rgb(40, 190, 80));
const AMBIGUOUS_COLOUR: Color = Color(Rgba32::from_rgb(240, 160, 20));
const FAILED_COLOUR: Color = Color(Rgba32::from_rgb(220, 40, 40));
const TRUTH_COLOUR: Color = Color(Rgba32::from_rgb(60, 120, 250));
const HYPOTHESIS_COLOUR: Color = Color(Rgba32::from_rgb(150, 150, 150));

/// What one topic delivered to the recorder.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TopicCount {
    /// Messages recorded.
    pub recorded: u64,
    /// Sequence numbers skipped between recorded messages: messages this recorder never saw.
    pub missed: u64,
    /// Messages seen twice (two producers during a hot swap, a resend to a late-connecting
    /// subscriber), not recorded again.
    pub duplicates: u64,
    /// Messages refused as malformed (logged as errors in the recording), and those stamped
    /// ahead of the monotonic clock (counted only).
    pub malformed: u64,
    pub first_seq: Option<u64>,
    pub last_seq: Option<u64>,
    /// Tells copies by their acquisition stamp: a copy carries a stamp already seen, a
    /// restarted source (numbering from 0 again) a later one.
    fresh: Freshness,
}

impl TopicCount {
    /// Whether the message with `header` is new; counts gaps and duplicates (the caller counts
    /// it recorded). A copy is told by its stamp, not its number, so the scans of a restarted
    /// source are recorded although their numbers were seen before.
    fn accept(&mut self, header: &Header) -> bool {
        match self.fresh.check(header, messages::monotonic_ns()) {
            Ok(()) => {}
            Err(Refused::Seen) => {
                self.duplicates += 1;
                return false;
            }
            // stamped with no clock of this machine's: a damaged message
            Err(Refused::Ahead { .. }) => {
                self.malformed += 1;
                return false;
            }
        }
        let seq = header.seq;
        match self.last_seq {
            // saturating: a damaged number (up to u64::MAX) must not overflow the count
            Some(last) if seq > last => self.missed = self.missed.saturating_add(seq - last - 1),
            Some(_) => {} // a restarted source: no gap to count
            None => self.first_seq = Some(seq),
        }
        self.last_seq = Some(seq);
        true
    }
}

/// Per-topic counts, indexed by [`Topic`].
#[derive(Clone, Debug, Default)]
pub struct Counts {
    pub scan: TopicCount,
    pub lines: TopicCount,
    pub corners: TopicCount,
    pub pose: TopicCount,
    pub map: TopicCount,
}

impl Counts {
    pub fn of(&self, topic: Topic) -> &TopicCount {
        match topic {
            Topic::Scan => &self.scan,
            Topic::Lines => &self.lines,
            Topic::Corners => &self.corners,
            Topic::Pose => &self.pose,
            Topic::Map => &self.map,
        }
    }

    /// One line per topic, for the log and stderr.
    pub fn render(&self) -> String {
        messages::ALL_TOPICS
            .iter()
            .map(|&t| {
                let c = self.of(t);
                let span = match (c.first_seq, c.last_seq) {
                    (Some(a), Some(b)) => format!(", seq {a}..={b}"),
                    _ => String::new(),
                };
                format!(
                    "{}: {} recorded, {} missed, {} duplicates, {} malformed{span}",
                    t.suffix(),
                    c.recorded,
                    c.missed,
                    c.duplicates,
                    c.malformed
                )
            })
            .collect::<Vec<_>>()
            .join("\n")
    }
}

/// A scan kept until its pose arrives.
struct KeptScan {
    seq: u64,
    /// Valid readings in the sensor frame.
    points: Vec<[f32; 2]>,
    /// Corner positions in the sensor frame, once the corners arrive.
    corners: Vec<[f32; 2]>,
}

/// The map's static entities.
struct MapStatic {
    walls: LineStrips2D,
    corners: Points2D,
    seen_free: Option<(Image, Transform3D)>,
}

/// Colour of a cell the map's survey saw free.
const SEEN_FREE_RGBA: [u8; 4] = [80, 200, 120, 60];

/// [`MAP_SEEN_FREE`]: pixel (c, r) is cell (c, r), so the image is scaled by the cell size and
/// moved to the raster's origin (the map frame's y and the image's rows both grow from it).
fn seen_free_image(seen: &SeenFree) -> (Image, Transform3D) {
    let (cols, rows) = seen.size();
    let mut rgba = vec![0u8; cols * rows * 4];
    for (px, seen) in rgba.chunks_exact_mut(4).zip(seen.cells()) {
        if seen {
            px.copy_from_slice(&SEEN_FREE_RGBA);
        }
    }
    let image = Image::from_rgba32(rgba, [cols as u32, rows as u32]).with_draw_order(-20.0);
    let o = seen.origin();
    let place = Transform3D::from_translation_scale([o.x as f32, o.y as f32, 0.0], seen.cell() as f32);
    (image, place)
}

/// Turns pipeline messages into a rerun recording.
pub struct Recorder {
    output: Output,
    counts: Counts,
    kept: VecDeque<KeptScan>,
    map_version: Option<u32>,
    /// The last map, kept to log again into each new file part.
    map_static: Option<MapStatic>,
    last_status: Option<u32>,
}

fn arrow(p: &PoseMsgXyt) -> ([f32; 2], [f32; 2]) {
    ([p.x as f32, p.y as f32], [ARROW * p.theta.cos() as f32, ARROW * p.theta.sin() as f32])
}

impl Recorder {
    pub fn new(output: Output) -> Self {
        Recorder {
            output,
            counts: Counts::default(),
            kept: VecDeque::with_capacity(KEPT_SCANS),
            map_version: None,
            map_static: None,
            last_status: None,
        }
    }

    pub fn counts(&self) -> &Counts {
        &self.counts
    }

    fn rec(&self) -> &RecordingStream {
        self.output.stream()
    }

    fn at(&self, h: &Header) {
        let rec = self.rec();
        rec.set_time_sequence(TIMELINE_SCAN, h.seq.min(i64::MAX as u64) as i64);
        rec.set_time(TIMELINE_ACQUIRED, Duration::from_nanos(h.stamp_ns));
    }

    fn log_text(&self, level: &str, text: String) -> Result<(), OutputError> {
        self.rec().log(LOG, &TextLog::new(text).with_level(level)).map_err(OutputError::stream)
    }

    fn scalar(&self, path: &str, value: Option<f64>) -> Result<(), OutputError> {
        match value {
            Some(v) => self.rec().log(path, &Scalars::single(v)).map_err(OutputError::stream),
            None => Ok(()),
        }
    }

    /// A supervisor event (a swap, or its failure), as a log entry.
    pub fn event(&mut self, m: &messages::EventMsg) -> Result<(), OutputError> {
        let level = if m.ok == 1 { TextLogLevel::INFO } else { TextLogLevel::WARN };
        self.log_text(level, format!("supervisor: {}", messages::unpadded(&m.text)))
    }

    /// A new map version: walls and corners as static entities.
    pub fn map(&mut self, m: &MapMsg) -> Result<(), OutputError> {
        if self.map_version == Some(m.version) {
            self.counts.map.duplicates += 1;
            return Ok(());
        }
        let walls = match map_from_msg(m) {
            Ok(w) => w,
            Err(e) => {
                self.counts.map.malformed += 1;
                return self.log_text(TextLogLevel::ERROR, format!("bad map ignored: {e}"));
            }
        };
        self.counts.map.recorded += 1;
        self.counts.map.first_seq.get_or_insert(m.version as u64);
        self.counts.map.last_seq = Some(m.version as u64);
        self.map_version = Some(m.version);
        let corners = CornerIndex::of_map(&walls, &MapCornerConfig::default());
        let strips =
            LineStrips2D::new(walls.walls.iter().map(|w| [[w.a.x as f32, w.a.y as f32], [w.b.x as f32, w.b.y as f32]]))
                .with_radii([0.03]);
        let points = Points2D::new(corners.corners().iter().map(|c| [c.position.x as f32, c.position.y as f32]))
            .with_labels(corners.corners().iter().map(|c| format!("{:.0}°", c.inner_angle.to_degrees())))
            .with_radii([0.06]);
        self.log_text(
            TextLogLevel::INFO,
            format!("map version {}: {} walls, {} corners", m.version, walls.walls.len(), corners.corners().len()),
        )?;
        let seen_free = walls.seen_free.as_ref().map(seen_free_image);
        if seen_free.is_none() && self.map_static.as_ref().is_some_and(|m| m.seen_free.is_some()) {
            // the previous version's free space is not this one's
            self.rec().log_static(MAP_SEEN_FREE, &rerun::Clear::flat()).map_err(OutputError::stream)?;
        }
        self.map_static = Some(MapStatic { walls: strips, corners: points, seen_free });
        self.log_map()
    }

    fn log_map(&self) -> Result<(), OutputError> {
        if let Some(m) = &self.map_static {
            self.rec().log_static(MAP_WALLS, &m.walls).map_err(OutputError::stream)?;
            self.rec().log_static(MAP_CORNERS, &m.corners).map_err(OutputError::stream)?;
            if let Some((image, place)) = &m.seen_free {
                self.rec()
                    .log_static(MAP_SEEN_FREE, &[image as &dyn rerun::AsComponents, place])
                    .map_err(OutputError::stream)?;
            }
        }
        Ok(())
    }

    /// A scan: readings in the sensor frame, the truth if known, acquisition latency.
    pub fn scan(&mut self, m: &ScanMsg) -> Result<(), OutputError> {
        if !self.counts.scan.accept(&m.header) {
            return Ok(());
        }
        self.at(&m.header);
        let geometry = ScanGeometry {
            angle_min: m.angle_min,
            angle_increment: m.angle_increment,
            range_min: m.range_min,
            range_max: m.range_max,
        };
        let count = m.count as usize;
        if !geometry.is_well_formed() || count > MAX_BEAMS {
            self.counts.scan.malformed += 1;
            return self.log_text(
                TextLogLevel::ERROR,
                format!("scan {}: unusable ({count} readings, layout {geometry:?})", m.header.seq),
            );
        }
        // its corners may have been recorded first: keep them
        let mut kept = self.take_kept(m.header.seq);
        kept.points.clear();
        for (i, &r) in m.ranges[..count].iter().enumerate() {
            let r = r as f64;
            if geometry.is_valid(r) {
                let a = geometry.angle(i);
                kept.points.push([(r * a.cos()) as f32, (r * a.sin()) as f32]);
            }
        }
        let rec = self.rec();
        rec.log(SCAN_READINGS, &Points2D::new(kept.points.iter().copied()).with_radii([0.015]))
            .map_err(OutputError::stream)?;
        if m.has_truth != 0 {
            let (origin, vector) = arrow(&m.truth);
            rec.log(WORLD_TRUTH, &Arrows2D::from_vectors([vector]).with_origins([origin]).with_colors([TRUTH_COLOUR]))
                .map_err(OutputError::stream)?;
        }
        self.output.account(512 + 8 * kept.points.len() as u64);
        self.kept.push_back(kept);
        self.counts.scan.recorded += 1;
        Ok(())
    }

    /// A line set: the lines in the sensor frame with their sample counts.
    pub fn lines(&mut self, m: &LinesMsg) -> Result<(), OutputError> {
        if !self.counts.lines.accept(&m.header) {
            return Ok(());
        }
        self.at(&m.header);
        let n = (m.count as usize).min(MAX_LINES);
        if m.count as usize > MAX_LINES {
            self.counts.lines.malformed += 1;
            self.log_text(TextLogLevel::WARN, format!("lines {}: count {} cut to {MAX_LINES}", m.header.seq, m.count))?;
        }
        let lines = &m.lines[..n];
        let strips = LineStrips2D::new(
            lines.iter().map(|l| [[l.start[0] as f32, l.start[1] as f32], [l.end[0] as f32, l.end[1] as f32]]),
        )
        .with_labels(lines.iter().map(|l| l.samples.to_string()))
        .with_radii([0.02]);
        self.rec().log(SCAN_LINES, &strips).map_err(OutputError::stream)?;
        self.output.account(512 + 24 * n as u64);
        self.counts.lines.recorded += 1;
        Ok(())
    }

    /// A corner set: the corners in the sensor frame, labelled by inner angle.
    pub fn corners(&mut self, m: &CornersMsg) -> Result<(), OutputError> {
        let h = &m.scan.header;
        if !self.counts.corners.accept(h) {
            return Ok(());
        }
        self.at(h);
        let n = (m.count as usize).min(MAX_CORNERS);
        let corners = &m.corners[..n];
        let positions: Vec<[f32; 2]> = corners.iter().map(|c| [c.position[0] as f32, c.position[1] as f32]).collect();
        self.rec()
            .log(
                SCAN_CORNERS,
                &Points2D::new(positions.iter().copied())
                    .with_labels(corners.iter().map(|c| format!("{:.0}°", c.inner_angle.to_degrees())))
                    .with_radii([0.05]),
            )
            .map_err(OutputError::stream)?;
        self.scalar(METRICS_NOISE_SCALE, Some(m.noise_scale.max(1.0)).filter(|v| v.is_finite()))?;
        self.output.account(512 + 16 * n as u64);
        // kept for the pose even if the scan is recorded after them: the stages run while a
        // look reads the topics one after another
        let mut kept = self.take_kept(h.seq);
        kept.corners = positions;
        self.kept.push_back(kept);
        self.counts.corners.recorded += 1;
        Ok(())
    }

    /// Scan `seq`'s kept entry, taken out of the queue (to be pushed back), or a new empty one
    /// (the oldest entry's storage once [`KEPT_SCANS`] are kept).
    fn take_kept(&mut self, seq: u64) -> KeptScan {
        if let Some(i) = self.kept.iter().rposition(|k| k.seq == seq) {
            if let Some(k) = self.kept.remove(i) {
                return k;
            }
        }
        let mut k = if self.kept.len() >= KEPT_SCANS {
            self.kept.pop_front().unwrap_or_else(|| KeptScan { seq, points: Vec::new(), corners: Vec::new() })
        } else {
            KeptScan { seq, points: Vec::new(), corners: Vec::new() }
        };
        k.seq = seq;
        k.points.clear();
        k.corners.clear();
        k
    }

    /// Ranked poses: every hypothesis with its cost, the chosen pose, the readings placed at it,
    /// the chosen scan corner, status, accuracy against the truth and the latencies.
    pub fn pose(&mut self, m: &PoseMsg) -> Result<(), OutputError> {
        let h = &m.header;
        if !self.counts.pose.accept(h) {
            return Ok(());
        }
        self.at(h);
        let n = (m.count as usize).min(MAX_HYPOTHESES);
        let placed = self.pose_geometry(m, &m.hypotheses[..n])?;
        self.pose_metrics(m, m.hypotheses[..n].first())?;
        if self.last_status != Some(m.status) {
            self.status_changed(m, n)?;
        }
        self.counts.pose.recorded += 1;
        // ~12 bytes per point or arrow, plus per-entity overhead
        self.output.account(512 + 12 * (placed + 2 * n) as u64);
        if self.output.roll_if_full()? {
            self.log_map()?;
        }
        Ok(())
    }

    /// The world view of a pose message: the hypotheses as arrows labelled with their cost,
    /// the best one in the status's colour with the scan's readings placed at it, and the scan
    /// corner it came from. Returns how many readings were placed.
    fn pose_geometry(&self, m: &PoseMsg, hyps: &[HypothesisMsg]) -> Result<usize, OutputError> {
        let (origins, vectors): (Vec<_>, Vec<_>) = hyps.iter().map(|h| arrow(&h.pose)).unzip();
        let rec = self.rec();
        rec.log(
            WORLD_HYPOTHESES,
            &Arrows2D::from_vectors(vectors)
                .with_origins(origins)
                .with_labels(hyps.iter().map(|h| format!("{:.4}", h.cost)))
                .with_colors([HYPOTHESIS_COLOUR]),
        )
        .map_err(OutputError::stream)?;
        let colour = match m.status {
            STATUS_OK => OK_COLOUR,
            STATUS_AMBIGUOUS => AMBIGUOUS_COLOUR,
            _ => FAILED_COLOUR,
        };
        let kept = self.kept.iter().rev().find(|k| k.seq == m.header.seq);
        let (pose_arrow, placed, chosen): (Vec<_>, Vec<[f32; 2]>, Vec<[f32; 2]>) = match hyps.first() {
            Some(b) => {
                let (c, s) = (b.pose.theta.cos() as f32, b.pose.theta.sin() as f32);
                let (x, y) = (b.pose.x as f32, b.pose.y as f32);
                let placed = kept
                    .map(|k| k.points.iter().map(|p| [x + c * p[0] - s * p[1], y + s * p[0] + c * p[1]]).collect())
                    .unwrap_or_default();
                let chosen = kept.and_then(|k| k.corners.get(b.scan_corner as usize)).copied().into_iter().collect();
                (vec![arrow(&b.pose)], placed, chosen)
            }
            None => (Vec::new(), Vec::new(), Vec::new()),
        };
        let placed_len = placed.len();
        let (o, v): (Vec<_>, Vec<_>) = pose_arrow.into_iter().unzip();
        rec.log(WORLD_POSE, &Arrows2D::from_vectors(v).with_origins(o).with_colors([colour]).with_radii([0.05]))
            .map_err(OutputError::stream)?;
        rec.log(WORLD_READINGS, &Points2D::new(placed).with_colors([colour]).with_radii([0.015]))
            .map_err(OutputError::stream)?;
        rec.log(SCAN_CHOSEN_CORNER, &Points2D::new(chosen).with_colors([colour]).with_radii([0.12]))
            .map_err(OutputError::stream)?;
        Ok(placed_len)
    }

    /// A pose message's scalars: its status, its error and success against the truth when the
    /// scan has one, and the localize stage's latencies.
    fn pose_metrics(&self, m: &PoseMsg, best: Option<&HypothesisMsg>) -> Result<(), OutputError> {
        self.rec().log(METRICS_STATUS, &Scalars::single(m.status as f64)).map_err(OutputError::stream)?;
        if m.has_truth != 0 {
            // as `gema2 locate` counts it: a scan without a pose is a miss
            let error = best.map(|b| (b.pose.x - m.truth.x).hypot(b.pose.y - m.truth.y));
            let success = best.zip(error).is_some_and(|(b, error)| {
                let heading = laser::angle_diff(b.pose.theta, m.truth.theta).abs().to_degrees();
                error <= SUCCESS_DISTANCE && heading <= SUCCESS_HEADING_DEG
            });
            self.scalar(METRICS_POSITION_ERROR, error)?;
            self.scalar(METRICS_SUCCESS, Some(if success { 1.0 } else { 0.0 }))?;
        }
        // every figure from the pose's own stamps, as `gema2 run` reports them
        for (figure, us) in messages::latency::FIGURES.iter().zip(messages::latency::of_pose(&m.header)) {
            self.scalar(&latency(figure.key), Some(us).filter(|v| v.is_finite()))?;
        }
        Ok(())
    }

    /// A text entry when the status differs from the last pose's: a timeline of when the
    /// localizer lost and regained its answer. `n`: the hypotheses the message holds.
    fn status_changed(&mut self, m: &PoseMsg, n: usize) -> Result<(), OutputError> {
        let level = match m.status {
            STATUS_OK => TextLogLevel::INFO,
            STATUS_AMBIGUOUS => TextLogLevel::WARN,
            _ => TextLogLevel::ERROR,
        };
        let was = self.last_status.map(status_name).unwrap_or("none");
        let h = &m.header;
        self.log_text(
            level,
            format!(
                "scan {}: status {} (was {was}), {} hypotheses from {} candidates, by {}",
                h.seq,
                status_name(m.status),
                n,
                m.candidates,
                h.producer()
            ),
        )?;
        self.last_status = Some(m.status);
        Ok(())
    }

    /// Records one text entry (errors seen by the process around the recorder).
    pub fn note(&self, level: &str, text: String) -> Result<(), OutputError> {
        self.log_text(level, text)
    }

    /// Flushes and closes; returns the files written.
    pub fn finish(self) -> Result<(Counts, Vec<std::path::PathBuf>), OutputError> {
        let (counts, parts, closed) = self.finish_keeping();
        closed.map(|()| (counts, parts))
    }

    /// [`finish`](Self::finish) that keeps the counts and the files written when closing
    /// fails, for a report of what the recording holds beside the failure.
    pub fn finish_keeping(self) -> (Counts, Vec<std::path::PathBuf>, Result<(), OutputError>) {
        let (parts, closed) = self.output.close();
        (self.counts, parts, closed)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Damaged sequence numbers (a jump to u64::MAX, then a source that seems to restart, again
    /// and again) count as missed without overflowing the count, and every new message is taken.
    #[test]
    fn damaged_sequence_numbers_never_overflow_the_missed_count() {
        let mut count = TopicCount::default();
        let start = messages::monotonic_ns().saturating_sub(1_000_000);
        for k in 0..6u64 {
            let seq = if k % 2 == 1 { u64::MAX } else { k };
            assert!(count.accept(&Header::new(seq, start + k)), "message {k} refused");
        }
        assert_eq!(count.missed, u64::MAX);
    }
}
