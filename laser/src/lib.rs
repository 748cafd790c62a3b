//! Laser scans as every GEMA2 stage sees them.
//!
//! A scan is a [`ScanGeometry`] (where each beam points, which ranges the sensor can measure)
//! plus one range per beam. Stages read ranges through a borrowed [`ScanView`], so a process can
//! hand a slice that lives in shared memory straight to the algorithms without copying.
//!
//! Conventions (docs/design.md): SI units; the sensor frame follows ROS REP 103 (x forward, y left,
//! angles counter-clockwise). A reading is valid only when it is finite, above
//! [`MIN_VALID_RANGE`] and below the sensor's maximum range; invalid readings are never points.
//!
//! One job: what a scan and a pose are, and the line fit every stage that draws lines through
//! points shares ([`fit`]). Depends on nalgebra and serde only; every other crate may depend on
//! it.

pub mod fit;
mod geometry;
pub mod motion;
mod pose;
pub mod rng;

pub use geometry::{Reading, ScanGeometry, MAX_LOST_RETURNS, MIN_VALID_RANGE};
pub use pose::{angle_diff, interpolate, pose, pose_theta, wrap_angle, Pose};

/// A scan that owns its ranges, with the ground-truth sensor pose when the source knows it
/// (a simulator, a corrected log).
#[derive(Clone, Debug, PartialEq)]
pub struct LaserScan {
    pub geometry: ScanGeometry,
    /// One range per beam, metres; invalid readings are kept as they came (NaN, 0, max range).
    pub ranges: Vec<f32>,
    /// Acquisition time, seconds.
    pub stamp: f64,
    /// Sensor (not robot) pose in the map frame, when known.
    pub truth: Option<Pose>,
}

impl LaserScan {
    pub fn view(&self) -> ScanView<'_> {
        ScanView { geometry: self.geometry, ranges: &self.ranges }
    }
}

/// A borrowed scan: what segmentation and the cost function read.
#[derive(Clone, Copy, Debug)]
pub struct ScanView<'a> {
    pub geometry: ScanGeometry,
    pub ranges: &'a [f32],
}

impl ScanView<'_> {
    #[inline]
    pub fn len(&self) -> usize {
        self.ranges.len()
    }

    #[inline]
    pub fn is_empty(&self) -> bool {
        self.ranges.is_empty()
    }

    /// Classifies reading `i` (docs/design.md's validity rule).
    #[inline]
    pub fn reading(&self, i: usize) -> Reading {
        self.geometry.classify(self.ranges[i] as f64)
    }

    /// Number of valid readings.
    pub fn valid_count(&self) -> usize {
        self.ranges.iter().filter(|&&r| self.geometry.is_valid(r as f64)).count()
    }
}
