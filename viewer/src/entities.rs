//! The recording's layout: every entity path and timeline the recorder writes, in one place, so
//! the recorder, `viewer inspect`, the tests and the README agree.
//!
//! Two frames: `world/...` is the map frame (REP 103, metres), `scan/...` the sensor frame of the
//! current scan. Every per-scan entity is logged once for every scan that reaches it, with zero
//! instances when there is nothing to show (no pose, no corner), so a scan's absence from an
//! entity always means the message never arrived.

/// Timeline: the scan's sequence number (`Header::seq`).
pub const TIMELINE_SCAN: &str = "scan";
/// Timeline: the scan's acquisition time, on the machine's monotonic clock.
pub const TIMELINE_ACQUIRED: &str = "acquired";

/// Static: the map's walls (`LineStrips2D`), map frame.
pub const MAP_WALLS: &str = "world/map/walls";
/// Static: the map's corners (`Points2D`), labelled with their inner angle in degrees.
pub const MAP_CORNERS: &str = "world/map/corners";
/// Static, for a map that keeps its survey's free space (`map::SeenFree`, as maps built
/// from logs do): an `Image` of one pixel per cell, translucent where a beam of the survey
/// passed and clear elsewhere, scaled and placed on the map by its `Transform3D`. The localizer
/// answers with no pose outside it.
pub const MAP_SEEN_FREE: &str = "world/map/seen_free";

/// Per scan: the valid readings in the sensor frame (`Points2D`).
pub const SCAN_READINGS: &str = "scan/readings";
/// Per scan: the inferred lines in the sensor frame (`LineStrips2D`), labelled with their
/// sample counts.
pub const SCAN_LINES: &str = "scan/lines";
/// Per scan: the corners in the sensor frame (`Points2D`), labelled with their inner angle.
pub const SCAN_CORNERS: &str = "scan/corners";
/// Per scan: the scan corner the best hypothesis was matched from (`Points2D`, 0 or 1).
pub const SCAN_CHOSEN_CORNER: &str = "scan/corners/chosen";

/// Per scan: the readings placed at the estimated pose in the map frame (`Points2D`).
pub const WORLD_READINGS: &str = "world/readings";
/// Per scan: every ranked pose hypothesis (`Arrows2D`), labelled with its cost (eq. 7).
pub const WORLD_HYPOTHESES: &str = "world/hypotheses";
/// Per scan: the chosen pose (`Arrows2D`, 0 or 1), coloured by status.
pub const WORLD_POSE: &str = "world/pose";
/// Per scan, when the source knows it: the true pose (`Arrows2D`), in another colour.
pub const WORLD_TRUTH: &str = "world/truth";

/// Per-stage latencies, microseconds (`Scalars`): `latency/acquire`, `latency/segment`,
/// `latency/localize`, the hops `latency/hop/scan` (acquire → segment) and `latency/hop/corners`
/// (segment → localize), and `latency/end_to_end` (acquisition → pose published).
pub const LATENCY: &str = "latency";
/// Per scan: the pose status (`Scalars`): 0 ok, 1 ambiguous, 2 failed.
pub const METRICS_STATUS: &str = "metrics/status";
/// Per scan with truth: 1 if the chosen pose is within 0.30 m and 5 degrees of the truth, else 0
/// (also when there is no pose).
pub const METRICS_SUCCESS: &str = "metrics/success";
/// Per scan with truth and a pose: position error, metres.
pub const METRICS_POSITION_ERROR: &str = "metrics/position_error";
/// The segmenter's e(d) widening for the scan's measured noise (1: as configured).
pub const METRICS_NOISE_SCALE: &str = "metrics/noise_scale";
/// Status changes, bad messages and map versions (`TextLog`).
pub const LOG: &str = "log";

/// The per-scan entities and the topic each comes from, in pipeline order.
pub const PER_SCAN: [&str; 9] = [
    SCAN_READINGS,
    SCAN_LINES,
    SCAN_CORNERS,
    SCAN_CHOSEN_CORNER,
    WORLD_READINGS,
    WORLD_HYPOTHESES,
    WORLD_POSE,
    WORLD_TRUTH,
    METRICS_STATUS,
];

/// A latency entity's path.
pub fn latency(name: &str) -> String {
    format!("{LATENCY}/{name}")
}
