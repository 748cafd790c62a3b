//! Where each beam points and which readings count as measurements.

use serde::{Deserialize, Serialize};

/// Readings at or below this range are error codes or noise, never points (docs/design.md).
pub const MIN_VALID_RANGE: f64 = 0.02;

/// Most "no return" readings in a row that can be returns lost on a surface the sensor sees on
/// both sides (a SICK LMS reports a lost return as its maximum range); more in a row are as
/// likely an opening.
pub const MAX_LOST_RETURNS: usize = 2;

/// The beam layout of a scan: beam `i` points at `angle_min + i * angle_increment` in the
/// sensor frame. This generalises eq. 1's `phi_i = f * (i/n - 1/2)` to sensors whose field of
/// view is not centred or whose beams do not span `f` exactly.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[repr(C)]
pub struct ScanGeometry {
    /// Angle of beam 0, radians, REP 103 sensor frame.
    pub angle_min: f64,
    /// Angle between consecutive beams, radians (positive: beams go counter-clockwise).
    pub angle_increment: f64,
    /// Smallest range the sensor measures, metres.
    pub range_min: f64,
    /// Largest range the sensor measures, metres; readings at or beyond it mean "no return".
    pub range_max: f64,
}

/// What one reading says.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Reading {
    /// A measured range, metres.
    Valid(f64),
    /// The beam saw nothing up to the sensor's maximum range.
    NoReturn,
    /// NaN, an error code or a reading too close to trust: no information.
    Unknown,
}

impl ScanGeometry {
    /// Hokuyo URG-04LX: steps 44..=725 of a 1024-step turn, front at step 384, 0.02-5.6 m.
    pub const URG04LX_STEPS_PER_TURN: u32 = 1024;
    pub const URG04LX_FIRST_STEP: u32 = 44;
    pub const URG04LX_LAST_STEP: u32 = 725;
    pub const URG04LX_FRONT_STEP: u32 = 384;

    /// The URG-04LX layout (682 beams, 239.41 degrees from first to last).
    pub fn urg04lx() -> Self {
        Self::urg04lx_decimated(1)
    }

    /// The URG-04LX layout keeping every `stride`-th step (the sensor's cluster count).
    pub fn urg04lx_decimated(stride: u32) -> Self {
        let inc = std::f64::consts::TAU / Self::URG04LX_STEPS_PER_TURN as f64;
        let first = Self::URG04LX_FIRST_STEP as f64 - Self::URG04LX_FRONT_STEP as f64;
        ScanGeometry {
            angle_min: first * inc,
            angle_increment: inc * stride.max(1) as f64,
            range_min: MIN_VALID_RANGE,
            range_max: 5.6,
        }
    }

    /// Number of URG-04LX beams for a given decimation.
    pub fn urg04lx_beams(stride: u32) -> usize {
        let steps = Self::URG04LX_LAST_STEP - Self::URG04LX_FIRST_STEP + 1;
        steps.div_ceil(stride.max(1)) as usize
    }

    /// A layout of `n` beams spread evenly over `fov` radians, centred on the x axis.
    pub fn centred(n: usize, fov: f64, range_max: f64) -> Self {
        let inc = if n > 1 { fov / (n - 1) as f64 } else { 0.0 };
        ScanGeometry { angle_min: -fov / 2.0, angle_increment: inc, range_min: MIN_VALID_RANGE, range_max }
    }

    /// Angle of beam `i`, sensor frame.
    #[inline]
    pub fn angle(&self, i: usize) -> f64 {
        self.angle_min + i as f64 * self.angle_increment
    }

    /// Whether a reading is a measurement (docs/design.md).
    ///
    /// Ranges travel as `f32`: a "no return" written as the maximum range comes back a hair
    /// below it (5.6 becomes 5.5999999), so the comparison with the maximum allows for `f32`
    /// rounding.
    #[inline]
    pub fn is_valid(&self, r: f64) -> bool {
        r.is_finite() && r > self.range_min.max(MIN_VALID_RANGE) && r < self.no_return_at()
    }

    /// Readings at or beyond this are "no return": the maximum range less `f32` rounding.
    #[inline]
    pub fn no_return_at(&self) -> f64 {
        self.range_max * (1.0 - 1e-6)
    }

    /// Classifies one reading.
    #[inline]
    pub fn classify(&self, r: f64) -> Reading {
        if self.is_valid(r) {
            Reading::Valid(r)
        } else if r.is_finite() && r >= self.no_return_at() {
            Reading::NoReturn
        } else {
            Reading::Unknown
        }
    }

    /// Whether the layout itself is usable: finite numbers, a non-zero increment and a range
    /// window that can hold a valid reading.
    pub fn is_well_formed(&self) -> bool {
        self.angle_min.is_finite()
            && self.angle_increment.is_finite()
            && self.angle_increment != 0.0
            && self.range_min.is_finite()
            && self.range_max.is_finite()
            && self.range_max > self.range_min.max(MIN_VALID_RANGE)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn urg04lx_layout_matches_the_datasheet() {
        let g = ScanGeometry::urg04lx();
        assert_eq!(ScanGeometry::urg04lx_beams(1), 682);
        // front beam (step 384) is beam 340 and points along x
        assert!(g.angle(340).abs() < 1e-12);
        let fov = g.angle(681) - g.angle(0);
        assert!((fov.to_degrees() - 239.414).abs() < 0.001, "{}", fov.to_degrees());
    }

    #[test]
    fn readings_are_classified_by_the_design_rule() {
        let g = ScanGeometry::urg04lx();
        assert_eq!(g.classify(1.0), Reading::Valid(1.0));
        assert_eq!(g.classify(f64::NAN), Reading::Unknown);
        assert_eq!(g.classify(f64::INFINITY), Reading::Unknown);
        assert_eq!(g.classify(0.02), Reading::Unknown);
        assert_eq!(g.classify(0.0), Reading::Unknown);
        assert_eq!(g.classify(-1.0), Reading::Unknown);
        assert_eq!(g.classify(5.6), Reading::NoReturn);
        assert_eq!(g.classify(80.0), Reading::NoReturn);
        assert!(g.is_valid(5.599));
        // a maximum range that went through f32 is still "no return"
        assert_eq!(g.classify(5.6f32 as f64), Reading::NoReturn);
        assert_eq!(g.classify(80.0f32 as f64), Reading::NoReturn);
    }
}
