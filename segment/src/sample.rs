//! Samples: each valid reading with its near and far bounds (section 4.1, eqs. 1-2).

use laser::{Reading, ScanView};
use nalgebra::{Point2, Vector2};
use serde::{Deserialize, Serialize};

/// The sensor's measurement error e(d) (section 3): a bound on how far a reading at range d can
/// be from the true surface. The paper calibrated a constant 2 cm; at realistic noise a term
/// proportional to range is needed (docs/how-it-works.md, "Where the paper falls short"), so both are allowed.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct ErrorModel {
    /// Constant part, metres.
    pub constant: f64,
    /// Part proportional to range (0.015 = 1.5 % of d).
    pub proportional: f64,
}

impl ErrorModel {
    /// The paper's calibration: e(d) = 2 cm.
    pub const PAPER: ErrorModel = ErrorModel { constant: 0.02, proportional: 0.0 };

    /// This model with both terms multiplied by `k`.
    pub fn scaled(&self, k: f64) -> ErrorModel {
        ErrorModel { constant: self.constant * k, proportional: self.proportional * k }
    }

    /// e(d), metres; never negative (eq. 2 uses |e(d)|).
    #[inline]
    pub fn at(&self, d: f64) -> f64 {
        (self.constant + self.proportional * d).abs()
    }
}

impl Default for ErrorModel {
    /// 3 cm + 1.5 % of range: about three standard deviations of a URG-04LX-class sensor
    /// (1 cm + 0.5 % of range), the best of those measured in docs/how-it-works.md, "Where the paper falls short".
    fn default() -> Self {
        ErrorModel { constant: 0.03, proportional: 0.015 }
    }
}

/// One sample s_i (eq. 2): the measured point and its near/far bounds along the beam.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sample {
    /// First beam this sample stands for (several when averaging).
    pub beam: u32,
    /// Unit vector of the beam, sensor frame (eq. 1's projection angle).
    pub dir: Vector2<f64>,
    /// Measured distance d_i.
    pub d: f64,
    /// Nearest possible distance, d_i - |e(d_i)| (the paper's lower bracket).
    pub near: f64,
    /// Farthest possible distance, d_i + |e(d_i)| (the paper's upper bracket).
    pub far: f64,
    /// True when invalid readings (or the start of the scan) come right before this sample:
    /// a line never spans such a gap.
    pub gap_before: bool,
}

impl Sample {
    /// s_i in sensor coordinates (eq. 1).
    #[inline]
    pub fn point(&self) -> Point2<f64> {
        Point2::from(self.dir * self.d)
    }

    #[inline]
    pub fn near_point(&self) -> Point2<f64> {
        Point2::from(self.dir * self.near)
    }

    #[inline]
    pub fn far_point(&self) -> Point2<f64> {
        Point2::from(self.dir * self.far)
    }
}

/// Turns readings into samples. `averaging` > 1 makes each sample stand for that many
/// consecutive beams (section 4.1's simplification); a group with any invalid reading is
/// dropped and breaks lines like an invalid reading does.
///
/// `out` is cleared and refilled so a caller can reuse its allocation scan after scan.
pub fn build_samples(scan: &ScanView<'_>, error: &ErrorModel, averaging: usize, out: &mut Vec<Sample>) {
    out.clear();
    let m = averaging.max(1);
    // room for every group at once: grown by doubling, the buffer would take up to twice
    // what a scan needs, and the smaller buffers it outgrew stay in the process's heap
    out.reserve_exact(scan.len().div_ceil(m));
    let g = scan.geometry;
    let mut gap = true;
    let mut first = 0;
    // the direction of a whole group's centre beam, turned by one group's angle per group:
    // a rotation per sample instead of a sine and cosine (drift after 10^4 groups ~1e-12 rad)
    let centre = |first: usize, count: f64| {
        let angle = g.angle_min + (first as f64 + (count - 1.0) / 2.0) * g.angle_increment;
        Vector2::new(angle.cos(), angle.sin())
    };
    let (step_sin, step_cos) = (m as f64 * g.angle_increment).sin_cos();
    let mut group_dir = centre(0, m as f64);
    while first < scan.len() {
        let last = (first + m).min(scan.len());
        let mut sum_d = 0.0;
        let mut ok = true;
        for i in first..last {
            match scan.reading(i) {
                Reading::Valid(d) => sum_d += d,
                _ => {
                    ok = false;
                    break;
                }
            }
        }
        if ok {
            let count = (last - first) as f64;
            let d = sum_d / count;
            let e = error.at(d);
            out.push(Sample {
                beam: first as u32,
                dir: if last - first == m { group_dir } else { centre(first, count) },
                d,
                near: (d - e).max(0.0),
                far: d + e,
                gap_before: gap,
            });
            gap = false;
        } else {
            gap = true;
        }
        first = last;
        group_dir = Vector2::new(
            group_dir.x * step_cos - group_dir.y * step_sin,
            group_dir.x * step_sin + group_dir.y * step_cos,
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use laser::ScanGeometry;

    #[test]
    fn invalid_readings_break_and_are_never_samples() {
        let g = ScanGeometry::centred(6, 1.0, 5.6);
        let ranges = [1.0, f32::NAN, 1.0, 1.0, 0.0, 9.0];
        let scan = ScanView { geometry: g, ranges: &ranges };
        let mut s = Vec::new();
        build_samples(&scan, &ErrorModel::PAPER, 1, &mut s);
        assert_eq!(s.len(), 3);
        assert_eq!(s.iter().map(|s| s.beam).collect::<Vec<_>>(), vec![0, 2, 3]);
        assert_eq!(s.iter().map(|s| s.gap_before).collect::<Vec<_>>(), vec![true, true, false]);
        assert!((s[1].near - 0.98).abs() < 1e-12 && (s[1].far - 1.02).abs() < 1e-12);
    }

    #[test]
    fn averaging_merges_groups_and_drops_groups_with_invalid_readings() {
        let g = ScanGeometry::centred(6, 1.0, 5.6);
        let ranges = [1.0, 2.0, 3.0, f32::NAN, 4.0, 4.0];
        let scan = ScanView { geometry: g, ranges: &ranges };
        let mut s = Vec::new();
        build_samples(&scan, &ErrorModel::PAPER, 2, &mut s);
        assert_eq!(s.len(), 2);
        assert!((s[0].d - 1.5).abs() < 1e-12);
        assert!((s[1].d - 4.0).abs() < 1e-12 && s[1].gap_before);
        let mid = g.angle_min + 4.5 * g.angle_increment;
        assert!((s[1].dir.y.atan2(s[1].dir.x) - mid).abs() < 1e-12);
    }

    #[test]
    fn error_grows_with_range() {
        let e = ErrorModel::default();
        assert!((e.at(0.0) - 0.03).abs() < 1e-12);
        assert!((e.at(4.0) - 0.09).abs() < 1e-12);
    }
}
