//! Matching calculation (section 5.1): aligning a scan corner c with a map corner m gives the
//! sensor pose.

use laser::Pose;
use map::MapCorner;
use nalgebra::{Isometry2, Vector2};
use segment::Corner;

/// Whether the scan corner's arms fit the map corner's: a scan sees no more of an arm than the
/// map has (its extent), and no wall where the map has a gap at the corner. `slack` absorbs
/// line-end noise, metres.
pub fn arms_fit(c: &Corner, m: &MapCorner, slack: f64) -> bool {
    c.arms.iter().zip(&m.arms).all(|(s, a)| s.gap + s.length <= a.extent + slack && s.gap + slack >= a.gap)
}

/// The sensor pose that lays scan corner `c` onto map corner `m` (eqs. 5 and 6).
///
/// Eq. 5 in this project's frames: each arm alone implies a rotation (map arm direction minus
/// scan arm direction); they differ by beta_m - beta_c, and the rotation is their mean weighted
/// by each arm's sample count, so the better-supported arm counts more. The paper's pi/2 comes
/// from its v-forward sensor frame and disappears in REP 103. Eq. 6: the translation takes the
/// scan corner's position onto the map corner's, x = x_m - R(theta) x_c.
pub fn pose_from_corners(c: &Corner, m: &MapCorner) -> Pose {
    // each arm's rotation as a unit complex number: map direction times conjugate scan direction
    let turn = |map: Vector2<f64>, scan: Vector2<f64>| {
        Vector2::new(map.x * scan.x + map.y * scan.y, map.y * scan.x - map.x * scan.y)
    };
    let right = turn(m.arms[0].direction, c.arms[0].direction);
    let left = turn(m.arms[1].direction, c.arms[1].direction);
    let (wr, wl) = (c.arms[0].samples.max(1e-9), c.arms[1].samples.max(1e-9));
    // their mean weighted by sample counts, on the unit circle: eq. 5's weighted angle to third
    // order in the inner angle mismatch, with no trigonometry
    let mean = right * wr + left * wl;
    let norm = mean.norm();
    let rotation = if norm > 1e-12 {
        nalgebra::UnitComplex::from_cos_sin_unchecked(mean.x / norm, mean.y / norm)
    } else {
        nalgebra::UnitComplex::from_cos_sin_unchecked(right.x, right.y)
    };
    let t = m.position.coords - rotation * c.position.coords;
    Isometry2::from_parts(t.into(), rotation)
}

#[cfg(test)]
mod tests {
    use super::*;
    use laser::{pose, pose_theta, wrap_angle};
    use map::MapArm;
    use nalgebra::Point2;
    use proptest::prelude::*;
    use segment::Arm;

    fn arm(direction: Vector2<f64>, samples: f64) -> Arm {
        Arm { direction, gap: 0.0, length: 1.0, samples, direction_sigma: 0.01, line: 0 }
    }

    proptest! {
        /// A map corner seen from a known pose, transformed into the sensor frame, gives back
        /// that pose (eqs. 5-6 invert the projection exactly when the angles agree).
        #[test]
        fn a_corner_seen_from_a_pose_gives_that_pose(
            x in -20.0f64..20.0, y in -20.0f64..20.0, th in -3.1f64..3.1,
            mx in -20.0f64..20.0, my in -20.0f64..20.0, a in -3.1f64..3.1, beta in 0.5f64..5.8,
            n1 in 5.0f64..300.0, n2 in 5.0f64..300.0,
        ) {
            let truth = pose(x, y, th);
            let (dr, dl) = (Vector2::new(a.cos(), a.sin()), Vector2::new((a + beta).cos(), (a + beta).sin()));
            let marm = |d| MapArm { direction: d, gap: 0.0, length: 2.0, extent: 2.0, wall: 0, reserved: 0 };
            let m = MapCorner { position: Point2::new(mx, my), inner_angle: beta, orientation: a, arms: [marm(dr), marm(dl)] };
            let inv = truth.inverse();
            let c = Corner {
                position: inv * m.position,
                inner_angle: beta,
                orientation: 0.0,
                quality: 1.0,
                arms: [arm(inv.rotation * dr, n1), arm(inv.rotation * dl, n2)],
            };
            let got = pose_from_corners(&c, &m);
            prop_assert!((got.translation.vector - truth.translation.vector).norm() < 1e-9);
            prop_assert!(wrap_angle(pose_theta(&got) - th).abs() < 1e-9);
        }
    }

    #[test]
    fn eq5_splits_an_inner_angle_mismatch_by_sample_counts() {
        // the scan's left arm is 2 degrees off; the right arm has 3x the samples
        let m = MapCorner {
            position: Point2::origin(),
            inner_angle: std::f64::consts::FRAC_PI_2,
            orientation: 0.0,
            arms: [
                MapArm { direction: Vector2::x(), gap: 0.0, length: 1.0, extent: 1.0, wall: 0, reserved: 0 },
                MapArm { direction: Vector2::y(), gap: 0.0, length: 1.0, extent: 1.0, wall: 1, reserved: 0 },
            ],
        };
        let off = 2f64.to_radians();
        let c = Corner {
            position: Point2::origin(),
            inner_angle: std::f64::consts::FRAC_PI_2 + off,
            orientation: 0.0,
            quality: 1.0,
            arms: [arm(Vector2::x(), 300.0), arm(Vector2::new(-off.sin(), off.cos()), 100.0)],
        };
        let got = pose_theta(&pose_from_corners(&c, &m));
        assert!((got - (-off * 0.25)).abs() < 1e-6, "{got}");
    }
}
