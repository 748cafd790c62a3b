//! The segmentation stage as one object: scan in, lines and corners out, buffers reused.

use crate::corner::{extract_corners, Corner, CornerConfig};
use crate::end::{extract_wall_ends, EndConfig};
use crate::filter::{filter_lines, FilterConfig};
use crate::inference::infer_lines;
use crate::line::Line;
use crate::noise::noise_scale;
use crate::sample::{build_samples, ErrorModel, Sample};
use laser::ScanView;
use serde::{Deserialize, Serialize};
use std::time::{Duration, Instant};

/// Everything the segmentation stage needs to know.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct SegmenterConfig {
    /// e(d) of the sensor (section 3).
    pub error: ErrorModel,
    /// Readings averaged into one sample (section 4.1); 1 keeps every reading.
    pub averaging: usize,
    pub filter: FilterConfig,
    pub corner: CornerConfig,
    /// Wall ends, ranked with the corners (see [`crate::end`]).
    pub ends: EndConfig,
    /// A scan measured noisier than `error` by more than this factor is segmented (and
    /// localized) with `error` widened to its measured noise ([`crate::noise`]); 0 never
    /// widens.
    #[serde(default = "default_noise_tolerance")]
    pub noise_tolerance: f64,
}

fn default_noise_tolerance() -> f64 {
    1.25
}

impl Default for SegmenterConfig {
    fn default() -> Self {
        SegmenterConfig {
            error: ErrorModel::default(),
            averaging: 1,
            filter: FilterConfig::default(),
            corner: CornerConfig::default(),
            ends: EndConfig::default(),
            noise_tolerance: default_noise_tolerance(),
        }
    }
}

/// What segmentation produced for one scan.
#[derive(Clone, Debug)]
pub struct Segmentation {
    /// The configured e(d) was multiplied by this for the scan (1, or the scan's measured
    /// noise relative to it; see [`crate::noise`]). The localizer widens its own e(d) alike.
    pub noise_scale: f64,
    pub samples: Vec<Sample>,
    /// L: lines as line visibility inferred them (lines of one sample are not kept).
    pub raw_lines: Vec<Line>,
    /// L': lines after filtering (section 4.3).
    pub lines: Vec<Line>,
    /// C: corners and wall ends (inner angle 2 pi), best quality first.
    pub corners: Vec<Corner>,
    /// Time spent building samples, inferring lines, and filtering + extracting corners.
    pub times: SegmentTimes,
}

impl Default for Segmentation {
    fn default() -> Self {
        Segmentation {
            noise_scale: 1.0,
            samples: Vec::new(),
            raw_lines: Vec::new(),
            lines: Vec::new(),
            corners: Vec::new(),
            times: SegmentTimes::default(),
        }
    }
}

/// Per-step compute time of one segmentation.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SegmentTimes {
    pub samples: Duration,
    pub inference: Duration,
    pub corners: Duration,
}

/// A segmentation implementation, chosen by name at start-up.
pub trait Segmenter: Send {
    /// The implementation's name, as published in message headers.
    fn name(&self) -> &'static str;
    /// Segments one scan; the result borrows the segmenter's reusable buffers.
    fn segment(&mut self, scan: &ScanView<'_>) -> &Segmentation;
}

/// The paper's segmentation: line visibility (Codes 1-2), filtering, corners.
#[derive(Clone, Debug)]
pub struct LineVisibilitySegmenter {
    pub config: SegmenterConfig,
    out: Segmentation,
    scratch: Vec<f64>,
}

impl LineVisibilitySegmenter {
    pub fn new(config: SegmenterConfig) -> Self {
        LineVisibilitySegmenter { config, out: Segmentation::default(), scratch: Vec::new() }
    }
}

impl Segmenter for LineVisibilitySegmenter {
    fn name(&self) -> &'static str {
        "line-visibility"
    }

    fn segment(&mut self, scan: &ScanView<'_>) -> &Segmentation {
        let c = &self.config;
        let out = &mut self.out;
        let t0 = Instant::now();
        out.noise_scale = noise_scale(scan, &c.error, c.noise_tolerance, &mut self.scratch);
        let error = c.error.scaled(out.noise_scale);
        build_samples(scan, &error, c.averaging, &mut out.samples);
        let t1 = Instant::now();
        infer_lines(&out.samples, scan.geometry.angle_increment, &error, &mut out.raw_lines);
        finish(scan, c, &error, [t0, t1, Instant::now()], out);
        out
    }
}

/// What every segmenter does once its raw lines are inferred: filtering (section 4.3), corners
/// (eq. 4) and wall ends, then the steps' times from `started` (the scan's start, samples
/// built, lines inferred).
pub(crate) fn finish(
    scan: &ScanView<'_>,
    c: &SegmenterConfig,
    error: &ErrorModel,
    started: [Instant; 3],
    out: &mut Segmentation,
) {
    filter_lines(&out.raw_lines, &out.samples, error, &c.filter, &mut out.lines);
    extract_corners(&out.lines, &c.corner, &mut out.corners);
    extract_wall_ends(scan, &out.samples, &out.lines, c.averaging, &c.corner, &c.ends, &mut out.corners);
    let [t0, t1, t2] = started;
    out.times = SegmentTimes { samples: t1 - t0, inference: t2 - t1, corners: t2.elapsed() };
}
