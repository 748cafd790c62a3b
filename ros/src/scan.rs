//! A `sensor_msgs/LaserScan` as the scan every stage sees ([`laser::LaserScan`]), read as
//! REP 117 says and as drivers in the wild write it:
//! - `+inf` is "no return within range": it becomes the maximum range, a no-return reading;
//! - `-inf` (too close), NaN (no measurement), and finite readings outside
//!   `[range_min, range_max]` are invalid: they become NaN;
//! - a negative `angle_increment` lists the beams clockwise (a laser mounted upside down) and
//!   is kept as it is: the geometry handles either direction;
//! - an increment of 0 or not finite is derived from `angle_min`, `angle_max` and the count;
//! - intensities, present or empty, are not used.
//!
//! The scan's time is its header stamp.

use crate::msg;
use laser::{LaserScan, ScanGeometry};
use thiserror::Error;

#[derive(Debug, Error, PartialEq)]
pub enum ScanError {
    #[error("a LaserScan without ranges")]
    Empty,
    #[error(
        "an unusable LaserScan layout: angle_min {angle_min}, angle_max {angle_max}, angle_increment \
         {angle_increment}, range_min {range_min}, range_max {range_max}, {beams} ranges"
    )]
    Layout { angle_min: f32, angle_max: f32, angle_increment: f32, range_min: f32, range_max: f32, beams: usize },
}

/// `m` as a laser upright in its place would read it, when it is mounted upside down (rolled
/// 180 degrees): the same beams in the same order at the negated angles, clockwise.
pub fn mirrored(mut m: msg::LaserScan) -> msg::LaserScan {
    m.angle_min = -m.angle_min;
    m.angle_max = -m.angle_max;
    m.angle_increment = -m.angle_increment;
    m
}

/// The scan `m` describes.
pub fn laser_scan(m: &msg::LaserScan) -> Result<LaserScan, ScanError> {
    let n = m.ranges.len();
    if n == 0 {
        return Err(ScanError::Empty);
    }
    let increment = if m.angle_increment.is_finite() && m.angle_increment != 0.0 {
        m.angle_increment as f64
    } else if n > 1 {
        (m.angle_max as f64 - m.angle_min as f64) / (n - 1) as f64
    } else {
        f64::NAN
    };
    let geometry = ScanGeometry {
        angle_min: m.angle_min as f64,
        angle_increment: increment,
        range_min: (m.range_min as f64).max(0.0),
        range_max: m.range_max as f64,
    };
    // a layout whose beams would turn round more than once is not one sensor's
    let turns = (increment * (n - 1) as f64).abs() / std::f64::consts::TAU;
    if !geometry.is_well_formed() || turns > 1.0 + 1e-3 {
        return Err(ScanError::Layout {
            angle_min: m.angle_min,
            angle_max: m.angle_max,
            angle_increment: m.angle_increment,
            range_min: m.range_min,
            range_max: m.range_max,
            beams: n,
        });
    }
    // the bounds the geometry holds: a `range_min` below 0, -inf or NaN reads as 0, so that no
    // -inf reading passes as within range
    let (lo, hi) = (m.range_min.max(0.0), m.range_max);
    let ranges = m
        .ranges
        .iter()
        .map(|&r| match r {
            f32::INFINITY => hi,
            r if r >= lo && r <= hi => r,
            _ => f32::NAN,
        })
        .collect();
    Ok(LaserScan { geometry, ranges, stamp: m.header.stamp.seconds(), truth: None })
}

#[cfg(test)]
mod tests {
    use super::*;
    use laser::Reading;

    fn message(ranges: Vec<f32>) -> msg::LaserScan {
        msg::LaserScan {
            angle_min: -1.0,
            angle_max: 1.0,
            angle_increment: 2.0 / (ranges.len() - 1) as f32,
            range_min: 0.1,
            range_max: 10.0,
            ranges,
            ..Default::default()
        }
    }

    #[test]
    fn readings_are_classified_as_rep_117_says() {
        let m = message(vec![1.0, f32::INFINITY, f32::NEG_INFINITY, f32::NAN, 0.05, 12.0, 10.0, 0.0]);
        let s = laser_scan(&m).unwrap();
        let kinds: Vec<Reading> = s.ranges.iter().map(|&r| s.geometry.classify(r as f64)).collect();
        assert_eq!(kinds[0], Reading::Valid(1.0));
        assert_eq!(kinds[1], Reading::NoReturn, "+inf: nothing within range");
        assert!(kinds[2..6].iter().all(|k| *k == Reading::Unknown), "{kinds:?}");
        assert_eq!(kinds[6], Reading::NoReturn, "a reading at the maximum range");
        assert_eq!(kinds[7], Reading::Unknown);
    }

    #[test]
    fn a_range_min_below_zero_lets_no_infinite_reading_through() {
        for range_min in [f32::NEG_INFINITY, -1.0, f32::NAN] {
            let mut m = message(vec![1.0, f32::NEG_INFINITY, -0.5, 0.0]);
            m.range_min = range_min;
            let s = laser_scan(&m).unwrap();
            assert_eq!(s.ranges[0], 1.0);
            assert!(s.ranges[1..3].iter().all(|r| r.is_nan()), "range_min {range_min}: {:?}", s.ranges);
        }
    }

    #[test]
    fn beams_listed_clockwise_keep_their_angles() {
        let mut m = message(vec![1.0; 5]);
        (m.angle_min, m.angle_max, m.angle_increment) = (1.0, -1.0, -0.5);
        let g = laser_scan(&m).unwrap().geometry;
        assert_eq!((g.angle(0), g.angle(4)), (1.0, -1.0));
        // an increment left out is derived from the ends
        m.angle_increment = 0.0;
        assert_eq!(laser_scan(&m).unwrap().geometry.angle_increment, -0.5);
    }

    #[test]
    fn a_mirrored_scan_reads_each_beam_at_its_negated_angle() {
        let mut m = message(vec![1.0, 2.0, 3.0, 4.0, 5.0]);
        (m.angle_min, m.angle_max, m.angle_increment) = (-0.5, 1.5, 0.5);
        let (plain, flipped) = (laser_scan(&m).unwrap(), laser_scan(&mirrored(m)).unwrap());
        assert_eq!(plain.ranges, flipped.ranges);
        for i in 0..5 {
            assert_eq!(flipped.geometry.angle(i), -plain.geometry.angle(i));
        }
    }

    #[test]
    fn unusable_layouts_are_refused() {
        assert_eq!(laser_scan(&msg::LaserScan::default()), Err(ScanError::Empty));
        let mut m = message(vec![1.0; 5]);
        m.range_max = f32::NAN;
        assert!(matches!(laser_scan(&m), Err(ScanError::Layout { .. })));
        let mut m = message(vec![1.0; 5]);
        m.angle_increment = 3.0;
        assert!(matches!(laser_scan(&m), Err(ScanError::Layout { .. })), "two turns");
        let mut m = message(vec![1.0]);
        m.angle_increment = f32::NAN;
        assert!(laser_scan(&m).is_err());
    }
}
