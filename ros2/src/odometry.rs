//! The robot's odometry at a scan's stamp, from the `nav_msgs/Odometry` messages heard so far:
//! what the ros2 stage sends with each scan, for the sequential localizer.

use laser::{interpolate, pose, Pose};
use std::collections::VecDeque;

/// Odometry messages kept: at 50 Hz, four seconds.
const KEPT: usize = 200;
/// Two messages further apart than this are not interpolated between, nanoseconds.
const WIDEST_GAP: i64 = 500_000_000;
/// A scan this much past the newest message (or before the oldest) takes it, nanoseconds: the
/// scan's own instant was not heard yet.
const NEAREST: i64 = 100_000_000;

/// The recent odometry poses by stamp.
#[derive(Debug, Default)]
pub struct Odometry {
    /// (stamp ns, pose), in stamp order.
    poses: VecDeque<(i64, Pose)>,
}

impl Odometry {
    /// Takes one message's stamp and planar pose; one out of stamp order, or not finite, is
    /// left out.
    pub fn add(&mut self, stamp: i64, x: f64, y: f64, yaw: f64) -> bool {
        if !(x.is_finite() && y.is_finite() && yaw.is_finite()) || self.poses.back().is_some_and(|b| b.0 > stamp) {
            return false;
        }
        if self.poses.len() >= KEPT {
            self.poses.pop_front();
        }
        self.poses.push_back((stamp, pose(x, y, yaw)));
        true
    }

    /// The odometry pose at `stamp`: between the two messages around it, or the nearest within
    /// a tenth of a second; none otherwise.
    pub fn at(&self, stamp: i64) -> Option<Pose> {
        let after = self.poses.partition_point(|p| p.0 < stamp);
        let before = after.checked_sub(1).and_then(|k| self.poses.get(k));
        match (before, self.poses.get(after)) {
            (Some(a), Some(b)) if b.0 - a.0 <= WIDEST_GAP => {
                let f = if b.0 > a.0 { (stamp - a.0) as f64 / (b.0 - a.0) as f64 } else { 0.0 };
                Some(interpolate(&a.1, &b.1, f))
            }
            (a, b) => [a, b]
                .into_iter()
                .flatten()
                .filter(|p| (p.0 - stamp).abs() <= NEAREST)
                .min_by_key(|p| (p.0 - stamp).abs())
                .map(|p| p.1),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use laser::pose_theta;

    #[test]
    fn a_scan_takes_the_odometry_between_the_messages_around_it() {
        let mut o = Odometry::default();
        assert!(o.add(1_000_000_000, 0.0, 0.0, 0.0));
        assert!(o.add(1_100_000_000, 1.0, 0.0, 0.2));
        let p = o.at(1_025_000_000).unwrap();
        assert!((p.translation.x - 0.25).abs() < 1e-9 && (pose_theta(&p) - 0.05).abs() < 1e-9);
        // just past the newest: the newest; long past: nothing
        assert!((o.at(1_150_000_000).unwrap().translation.x - 1.0).abs() < 1e-9);
        assert!(o.at(2_000_000_000).is_none());
        assert!(o.at(0).is_none());
        // out of order, or not finite: left out
        assert!(!o.add(1_050_000_000, 5.0, 5.0, 0.0));
        assert!(!o.add(1_200_000_000, f64::NAN, 0.0, 0.0));
    }

    #[test]
    fn messages_too_far_apart_are_not_interpolated_between() {
        let mut o = Odometry::default();
        o.add(0, 0.0, 0.0, 0.0);
        o.add(2_000_000_000, 9.0, 0.0, 0.0);
        assert!(o.at(1_000_000_000).is_none());
        assert!((o.at(50_000_000).unwrap().translation.x).abs() < 1e-9);
    }
}
