//! Sensor poses in the map frame (REP 103: theta counter-clockwise from the map's x axis).

use nalgebra::{Isometry2, Vector2};

/// A planar rigid transform taking sensor-frame points into the map frame.
pub type Pose = Isometry2<f64>;

/// Builds a pose from its position and heading.
pub fn pose(x: f64, y: f64, theta: f64) -> Pose {
    Isometry2::new(Vector2::new(x, y), theta)
}

/// The heading of a pose in (-pi, pi].
pub fn pose_theta(p: &Pose) -> f64 {
    wrap_angle(p.rotation.angle())
}

/// Wraps an angle into (-pi, pi].
pub fn wrap_angle(a: f64) -> f64 {
    use std::f64::consts::{PI, TAU};
    let mut w = a % TAU;
    if w <= -PI {
        w += TAU;
    } else if w > PI {
        w -= TAU;
    }
    w
}

/// The signed difference `a - b` wrapped into (-pi, pi].
pub fn angle_diff(a: f64, b: f64) -> f64 {
    wrap_angle(a - b)
}

/// The pose a fraction `f` of the way from `a` to `b`: position along the straight line,
/// heading through the smaller turn. What a timestamp between two poses' stamps reads.
pub fn interpolate(a: &Pose, b: &Pose, f: f64) -> Pose {
    let (pa, pb) = (a.translation.vector, b.translation.vector);
    let (ta, tb) = (pose_theta(a), pose_theta(b));
    pose(pa.x + f * (pb.x - pa.x), pa.y + f * (pb.y - pa.y), wrap_angle(ta + f * angle_diff(tb, ta)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use std::f64::consts::PI;

    #[test]
    fn interpolation_turns_the_short_way_round() {
        let (a, b) = (pose(0.0, 0.0, 3.0), pose(2.0, -4.0, -3.0));
        let mid = interpolate(&a, &b, 0.5);
        assert!((mid.translation.x - 1.0).abs() < 1e-12 && (mid.translation.y + 2.0).abs() < 1e-12);
        assert!((pose_theta(&mid).abs() - PI).abs() < 1e-9, "{}", pose_theta(&mid));
        assert_eq!(interpolate(&a, &b, 0.0), a);
    }

    proptest! {
        #[test]
        fn wrapped_angles_lie_in_the_half_open_interval(a in -100.0f64..100.0) {
            let w = wrap_angle(a);
            prop_assert!(w > -PI && w <= PI);
            prop_assert!(((a - w) / std::f64::consts::TAU).fract().abs() < 1e-9
                || (1.0 - ((a - w) / std::f64::consts::TAU).fract().abs()) < 1e-9);
        }
    }

    #[test]
    fn pi_maps_to_pi() {
        assert_eq!(wrap_angle(PI), PI);
        assert_eq!(wrap_angle(-PI), PI);
        assert!((pose_theta(&pose(1.0, 2.0, 3.0)) - 3.0).abs() < 1e-12);
    }
}
