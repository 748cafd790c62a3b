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
/// A message this much older than the newest kept starts the record anew, nanoseconds. The
/// clock went back (a bag played again from its start, a simulator restarted), or the newest
/// was stamped wrongly (a bad clock, a damaged or hostile message): kept, it would shut out
/// every later message, and the odometry would stop for good. A message out of order by less
/// (reordered on the way) is left out.
const CLOCK_WENT_BACK: i64 = 1_000_000_000;

/// The recent odometry poses by stamp.
#[derive(Debug, Default)]
pub struct Odometry {
    /// (stamp ns, pose), in stamp order.
    poses: VecDeque<(i64, Pose)>,
}

impl Odometry {
    /// Takes one message's stamp and planar pose; one not finite, or out of stamp order by up
    /// to `CLOCK_WENT_BACK`, is left out; one older still starts the record anew.
    pub fn add(&mut self, stamp: i64, x: f64, y: f64, yaw: f64) -> bool {
        if !(x.is_finite() && y.is_finite() && yaw.is_finite()) {
            return false;
        }
        if let Some(&(newest, _)) = self.poses.back() {
            if newest > stamp {
                if newest.saturating_sub(stamp) <= CLOCK_WENT_BACK {
                    return false;
                }
                self.poses.clear();
            }
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

    /// One message stamped far ahead (a bad clock, a damaged message) does not shut out the
    /// ones after it: the next, older by more than a second, starts the record anew.
    #[test]
    fn a_message_stamped_far_ahead_does_not_stop_the_odometry() {
        let mut o = Odometry::default();
        let second = 1_000_000_000i64;
        assert!(o.add(second, 0.0, 0.0, 0.0));
        assert!(o.add(2_000_000_000_000_000_000, 50.0, 0.0, 0.0));
        for k in 1..=10 {
            assert!(o.add(second + k * second / 10, k as f64, 0.0, 0.0), "message {k} left out");
        }
        let p = o.at(second + 95 * second / 100).expect("the odometry at a later scan");
        assert!((p.translation.x - 9.5).abs() < 1e-9, "{p:?}");
    }

    /// A bag played again from its start: the odometry goes on from the new stamps.
    #[test]
    fn a_clock_gone_back_starts_the_odometry_anew() {
        let mut o = Odometry::default();
        for k in 0..10 {
            assert!(o.add(100_000_000_000 + k * 100_000_000, 7.0 + k as f64, 0.0, 0.0));
        }
        assert!(o.add(1_000_000_000, 0.0, 0.0, 0.0));
        assert!(o.add(1_100_000_000, 1.0, 0.0, 0.0));
        let p = o.at(1_050_000_000).expect("the odometry after the clock went back");
        assert!((p.translation.x - 0.5).abs() < 1e-9, "{p:?}");
        assert!(o.at(100_500_000_000).is_none(), "the old record was kept");
    }
}
