//! The odometry motion model (Thrun, Burgard and Fox, *Probabilistic Robotics*, section 5.4;
//! the "diff" model of Nav2's AMCL): a motion between two odometry poses is a turn, a straight
//! drive and a second turn, and each is disturbed by Gaussian noise whose variance grows with
//! the motion. The four alphas are AMCL's: `a1` turn from turn, `a2` turn from drive, `a3`
//! drive from drive, `a4` drive from turn.
//!
//! One model, two uses: the simulator and the evaluation draw drifting odometry from a true
//! motion ([`OdometryNoise::sample`]), and the sequential localizer asks how far a motion the
//! odometry reports may be off ([`OdometryNoise::spread`]).

use crate::pose::{angle_diff, pose, pose_theta, Pose};
use crate::rng::Rng;
use std::f64::consts::PI;

/// The four alphas of the odometry motion model, each a variance per squared unit of motion.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OdometryNoise {
    pub alphas: [f64; 4],
}

/// Below this drive, metres, the first turn is taken as none: its direction is noise.
const STILL: f64 = 0.01;

/// A motion split as the model splits it: first turn, drive, second turn.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Split {
    rot1: f64,
    trans: f64,
    rot2: f64,
}

impl Split {
    /// The motion from `a` to `b`, both in one frame.
    fn between(a: &Pose, b: &Pose) -> Self {
        let d = b.translation.vector - a.translation.vector;
        let trans = d.norm();
        let (ta, tb) = (pose_theta(a), pose_theta(b));
        let rot1 = if trans < STILL { 0.0 } else { angle_diff(d.y.atan2(d.x), ta) };
        Split { rot1, trans, rot2: angle_diff(angle_diff(tb, ta), rot1) }
    }

    /// `from` moved by this motion.
    fn apply(&self, from: &Pose) -> Pose {
        let heading = pose_theta(from) + self.rot1;
        let t = from.translation.vector;
        pose(t.x + self.trans * heading.cos(), t.y + self.trans * heading.sin(), heading + self.rot2)
    }

    /// A turn's size for the noise: driving backwards is a small turn, not a half turn.
    fn turn_size(rot: f64) -> f64 {
        rot.abs().min((PI - rot.abs()).abs())
    }
}

impl OdometryNoise {
    pub const NONE: OdometryNoise = OdometryNoise { alphas: [0.0; 4] };

    pub fn new(alphas: [f64; 4]) -> Self {
        OdometryNoise { alphas }
    }

    /// The standard deviations of the first turn, the drive and the second turn of the motion
    /// from `a` to `b`.
    fn sigmas(&self, s: &Split) -> (f64, f64, f64) {
        let [a1, a2, a3, a4] = self.alphas;
        let (r1, r2) = (Split::turn_size(s.rot1), Split::turn_size(s.rot2));
        let t2 = s.trans * s.trans;
        ((a1 * r1 * r1 + a2 * t2).sqrt(), (a3 * t2 + a4 * (r1 * r1 + r2 * r2)).sqrt(), (a1 * r2 * r2 + a2 * t2).sqrt())
    }

    /// Odometry's report of a true motion from `truth_from` to `truth_to`, applied to where
    /// odometry was (`odom_from`): the motion, with each of its three parts disturbed.
    pub fn sample(&self, truth_from: &Pose, truth_to: &Pose, odom_from: &Pose, rng: &mut Rng) -> Pose {
        let s = Split::between(truth_from, truth_to);
        let (s1, st, s2) = self.sigmas(&s);
        let noisy = Split {
            rot1: s.rot1 + s1 * rng.normal(),
            trans: s.trans + st * rng.normal(),
            rot2: s.rot2 + s2 * rng.normal(),
        };
        noisy.apply(odom_from)
    }

    /// How far off the end of a motion odometry reports from `a` to `b` may be, one standard
    /// deviation: (position, metres; heading, radians). The position's spread takes in the
    /// drive's noise and the sideways error of the first turn's.
    pub fn spread(&self, a: &Pose, b: &Pose) -> (f64, f64) {
        let s = Split::between(a, b);
        let (s1, st, s2) = self.sigmas(&s);
        ((st * st + (s.trans * s1).powi(2)).sqrt(), (s1 * s1 + s2 * s2).sqrt())
    }
}

/// The motion from odometry pose `a` to odometry pose `b`, in `a`'s frame: what a pose moves by
/// between two scans (`pose * motion(a, b)`).
pub fn motion(a: &Pose, b: &Pose) -> Pose {
    a.inverse() * b
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: &Pose, b: &Pose) -> bool {
        (a.translation.vector - b.translation.vector).norm() < 1e-9
            && angle_diff(pose_theta(a), pose_theta(b)).abs() < 1e-9
    }

    #[test]
    fn a_split_motion_puts_the_pose_back_together() {
        let (a, b) = (pose(1.0, 2.0, 0.3), pose(2.5, 1.0, -2.0));
        assert!(close(&Split::between(&a, &b).apply(&a), &b));
        // a turn on the spot has no drive and no first turn
        let s = Split::between(&a, &pose(1.0, 2.0, 1.0));
        assert_eq!((s.rot1, s.trans), (0.0, 0.0));
        assert!((s.rot2 - 0.7).abs() < 1e-12);
    }

    #[test]
    fn without_noise_odometry_reports_the_true_motion_from_where_it_was() {
        let (a, b) = (pose(0.0, 0.0, 0.0), pose(1.0, 1.0, 1.0));
        let odom_from = pose(10.0, -3.0, 2.0);
        let got = OdometryNoise::NONE.sample(&a, &b, &odom_from, &mut Rng::new(1));
        assert!(close(&got, &(odom_from * motion(&a, &b))));
        assert_eq!(OdometryNoise::NONE.spread(&a, &b), (0.0, 0.0));
    }

    /// The drawn drive's spread matches the model's: sqrt(a3) per metre driven straight.
    #[test]
    fn drawn_drives_spread_as_the_model_says() {
        let noise = OdometryNoise::new([0.0, 0.0, 0.04, 0.0]);
        let (a, b) = (pose(0.0, 0.0, 0.0), pose(2.0, 0.0, 0.0));
        let mut rng = Rng::new(7);
        let n = 20_000;
        let xs: Vec<f64> = (0..n).map(|_| noise.sample(&a, &b, &a, &mut rng).translation.x).collect();
        let mean = xs.iter().sum::<f64>() / n as f64;
        let sd = (xs.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / n as f64).sqrt();
        assert!((mean - 2.0).abs() < 0.01, "{mean}");
        assert!((sd - 0.4).abs() < 0.01, "{sd}");
        assert!((noise.spread(&a, &b).0 - 0.4).abs() < 1e-12);
    }

    /// Driving backwards is a small turn for the noise, not a half turn.
    #[test]
    fn reversing_is_not_a_half_turn() {
        let noise = OdometryNoise::new([1.0, 0.0, 0.0, 0.0]);
        let (a, back) = (pose(0.0, 0.0, 0.0), pose(-1.0, 0.0, 0.0));
        assert!(noise.spread(&a, &back).1 < 1e-9);
    }
}
