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

    /// The sizes of the two turns, each folded on its own ([`Split::turn_size`]).
    fn folded_turns(&self) -> (f64, f64) {
        (Split::turn_size(self.rot1), Split::turn_size(self.rot2))
    }

    /// The sizes of the two turns, taking the motion as driven forwards or backwards (the
    /// first turn half a turn further, the second half a turn back), whichever turns less in
    /// all: reversing turns by nothing, a turn on the spot by all of it.
    fn least_turns(&self) -> (f64, f64) {
        let forwards = (self.rot1.abs(), self.rot2.abs());
        let backwards = (angle_diff(self.rot1, PI).abs(), angle_diff(self.rot2, -PI).abs());
        if backwards.0 + backwards.1 < forwards.0 + forwards.1 {
            backwards
        } else {
            forwards
        }
    }
}

impl OdometryNoise {
    pub const NONE: OdometryNoise = OdometryNoise { alphas: [0.0; 4] };

    pub fn new(alphas: [f64; 4]) -> Self {
        OdometryNoise { alphas }
    }

    /// The model of four alphas as a user writes them (`--odom-noise A1,A2,A3,A4`): four
    /// finite numbers, none negative; else what is wrong, in words.
    pub fn from_alphas(alphas: &[f64]) -> Result<Self, String> {
        let &[a1, a2, a3, a4] = alphas else {
            return Err(format!("four alphas, A1,A2,A3,A4 (got {})", alphas.len()));
        };
        let alphas = [a1, a2, a3, a4];
        if alphas.iter().any(|v| !v.is_finite() || *v < 0.0) {
            return Err(format!("each alpha is a finite number, 0 or more (got {alphas:?})"));
        }
        Ok(OdometryNoise::new(alphas))
    }

    /// The standard deviations of the first turn, the drive and the second turn of a motion
    /// that turns by `r1` and `r2` (their sizes) and drives `trans`.
    fn sigmas(&self, (r1, r2): (f64, f64), trans: f64) -> (f64, f64, f64) {
        let [a1, a2, a3, a4] = self.alphas;
        let t2 = trans * trans;
        ((a1 * r1 * r1 + a2 * t2).sqrt(), (a3 * t2 + a4 * (r1 * r1 + r2 * r2)).sqrt(), (a1 * r2 * r2 + a2 * t2).sqrt())
    }

    /// Odometry's report of a true motion from `truth_from` to `truth_to`, applied to where
    /// odometry was (`odom_from`): the motion, with each of its three parts disturbed.
    pub fn sample(&self, truth_from: &Pose, truth_to: &Pose, odom_from: &Pose, rng: &mut Rng) -> Pose {
        let s = Split::between(truth_from, truth_to);
        let (s1, st, s2) = self.sigmas(s.folded_turns(), s.trans);
        let noisy = Split {
            rot1: s.rot1 + s1 * rng.normal(),
            trans: s.trans + st * rng.normal(),
            rot2: s.rot2 + s2 * rng.normal(),
        };
        noisy.apply(odom_from)
    }

    /// How far off the end of a motion odometry reports from `a` to `b` may be, one standard
    /// deviation: (position, metres; heading, radians). The position's spread takes in the
    /// drive's noise and the sideways error of the first turn's, as [`OdometryNoise::sample`]
    /// sizes them.
    ///
    /// The heading's takes the turns of the split that turns least, forwards or backwards, each
    /// as big as it is. Folding each turn on its own, as AMCL's noise does, takes a turn on
    /// the spot of 150 degrees for one of 30: a tracked robot that spun past a right angle
    /// was searched for over a sixth of the headings it could face. The position keeps the
    /// folded turns: sized by whole turns, a spin's drive-from-turn term spread the search 0.4
    /// m along an aisle that pins nothing down, where the pose then wandered.
    pub fn spread(&self, a: &Pose, b: &Pose) -> (f64, f64) {
        let s = Split::between(a, b);
        let (s1, st, _) = self.sigmas(s.folded_turns(), s.trans);
        let (h1, _, h2) = self.sigmas(s.least_turns(), s.trans);
        ((st * st + (s.trans * s1).powi(2)).sqrt(), (h1 * h1 + h2 * h2).sqrt())
    }
}

/// Wheel odometry drawn along a robot's true path: each true motion between two poses is
/// disturbed by [`OdometryNoise::sample`] and added to where odometry was, so it drifts as
/// wheels do. The simulator's walking robot and the evaluation's `--odom-noise` draw it.
#[derive(Clone, Debug)]
pub struct DriftingOdometry {
    noise: OdometryNoise,
    rng: Rng,
    /// The last true pose and the odometry drawn for it.
    last: Option<(Pose, Pose)>,
}

impl DriftingOdometry {
    pub fn new(noise: OdometryNoise, seed: u64) -> Self {
        DriftingOdometry { noise, rng: Rng::new(seed), last: None }
    }

    /// The odometry at the true pose `truth`: `truth` itself the first time, then the last
    /// odometry moved by the true motion since, disturbed. A `cut` (the robot was carried
    /// elsewhere) is no motion to the wheels: the odometry stays.
    pub fn next(&mut self, truth: &Pose, cut: bool) -> Pose {
        let odometry = match self.last {
            None => *truth,
            Some((_, odometry)) if cut => odometry,
            Some((from, odometry)) => self.noise.sample(&from, truth, &odometry, &mut self.rng),
        };
        self.last = Some((*truth, odometry));
        odometry
    }
}

/// The alphas [`OdometryNoise::fit`] found, and what they rest on.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OdometryFit {
    pub noise: OdometryNoise,
    /// Motions the fit used, and those left out: a split that one side took as a drive and
    /// the other as a turn on the spot or a drive the other way, or an error beyond four
    /// standard deviations of the first fit (a glitch of the truth, a wheel that slipped).
    pub used: usize,
    pub left_out: usize,
}

impl OdometryNoise {
    /// The alphas that best explain how odometry's motions differ from the true ones: each
    /// of `motions` is (truth from, truth to, odometry from, odometry to). Each part's squared
    /// error is fitted, by least squares with no alpha negative, to the variance
    /// [`OdometryNoise::sample`] gives it (turns: a1 turn^2 + a2 drive^2; drive: a3 drive^2 +
    /// a4 turns^2), then again without the errors beyond four standard deviations of that
    /// fit. `None` with fewer than 10 motions to fit.
    pub fn fit(motions: &[(Pose, Pose, Pose, Pose)]) -> Option<OdometryFit> {
        // (squared error, regressors) of the turns and of the drive
        let mut turns = Vec::new();
        let mut drives = Vec::new();
        let mut ambiguous = 0;
        for (ta, tb, oa, ob) in motions {
            let (s, o) = (Split::between(ta, tb), Split::between(oa, ob));
            let first_turn_error = angle_diff(o.rot1, s.rot1);
            // a split one side takes as a drive and the other as a turn on the spot, or as a
            // drive the other way, is not one the model's errors describe
            if (s.trans < STILL) != (o.trans < STILL) || first_turn_error.abs() > PI / 2.0 {
                ambiguous += 1;
                continue;
            }
            let (r1, r2) = s.folded_turns();
            let t2 = s.trans * s.trans;
            turns.push((first_turn_error.powi(2), [r1 * r1, t2]));
            turns.push((angle_diff(o.rot2, s.rot2).powi(2), [r2 * r2, t2]));
            drives.push(((o.trans - s.trans).powi(2), [t2, r1 * r1 + r2 * r2]));
        }
        if drives.len() < 10 {
            return None;
        }
        let ((a1, a2), turn_out) = fit_robust(&mut turns);
        let ((a3, a4), drive_out) = fit_robust(&mut drives);
        Some(OdometryFit {
            noise: OdometryNoise::new([a1, a2, a3, a4]),
            used: drives.len(),
            left_out: ambiguous + turn_out.max(drive_out),
        })
    }
}

/// [`fit_nonnegative`] unweighted, then three times again without the samples beyond four
/// standard deviations of the last fit and each weighted by one over its variance squared
/// (a squared normal error's spread grows with its variance: unweighted, the few largest
/// motions decide); how many were left out.
fn fit_robust(samples: &mut Vec<(f64, [f64; 2])>) -> ((f64, f64), usize) {
    let before = samples.len();
    let variance = |c: (f64, f64), x: [f64; 2]| c.0 * x[0] + c.1 * x[1];
    let mut fit = fit_nonnegative(samples, |_| 1.0);
    for _ in 0..3 {
        let last = fit;
        samples.retain(|&(y, x)| y <= 16.0 * variance(last, x));
        if samples.is_empty() {
            break;
        }
        // a variance floor keeps a motion of no turn and no drive from weighing without end
        let floor = samples.iter().map(|&(_, x)| variance(last, x)).fold(0.0, f64::max) * 1e-6;
        fit = fit_nonnegative(samples, |x| 1.0 / (variance(last, x).max(floor).max(1e-300)).powi(2));
    }
    (fit, before - samples.len())
}

/// Weighted least squares y ~ c1 x1 + c2 x2 with c1, c2 >= 0, each sample weighing `weight(x)`.
fn fit_nonnegative(samples: &[(f64, [f64; 2])], weight: impl Fn([f64; 2]) -> f64) -> (f64, f64) {
    let (mut s11, mut s12, mut s22, mut b1, mut b2) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for &(y, x) in samples {
        let w = weight(x);
        let [x1, x2] = x;
        (s11, s12, s22) = (s11 + w * x1 * x1, s12 + w * x1 * x2, s22 + w * x2 * x2);
        (b1, b2) = (b1 + w * x1 * y, b2 + w * x2 * y);
    }
    let alone = |b: f64, s: f64| if s > 0.0 { (b / s).max(0.0) } else { 0.0 };
    let det = s11 * s22 - s12 * s12;
    if det > 1e-12 * (s11 * s22).max(f64::MIN_POSITIVE) {
        let (c1, c2) = ((b1 * s22 - b2 * s12) / det, (b2 * s11 - b1 * s12) / det);
        if c1 >= 0.0 && c2 >= 0.0 {
            return (c1, c2);
        }
    }
    // one of them at 0: the better of the two fits with one regressor
    let residual =
        |c1: f64, c2: f64| samples.iter().map(|&(y, x)| weight(x) * (y - c1 * x[0] - c2 * x[1]).powi(2)).sum::<f64>();
    let (only1, only2) = ((alone(b1, s11), 0.0), (0.0, alone(b2, s22)));
    if residual(only1.0, only1.1) <= residual(only2.0, only2.1) {
        only1
    } else {
        only2
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

    /// Odometry drawn with known alphas along a long walk of drives and turns: the fit finds
    /// them again, and leaves out a truth that jumped.
    #[test]
    fn the_fit_finds_the_alphas_odometry_was_drawn_with() {
        let mut rng = Rng::new(3);
        let mut truth = vec![pose(0.0, 0.0, 0.0)];
        for _ in 0..4000 {
            let last = *truth.last().unwrap();
            let (turn, drive) = (0.6 * rng.normal(), (0.5 + 0.4 * rng.normal()).abs());
            truth.push(last * pose(drive * (0.5 * turn).cos(), drive * (0.5 * turn).sin(), turn));
        }
        let alphas = [0.05, 0.01, 0.08, 0.02];
        let mut odometry = DriftingOdometry::new(OdometryNoise::new(alphas), 9);
        let odom: Vec<Pose> = truth.iter().map(|t| odometry.next(t, false)).collect();
        let mut motions: Vec<_> = (1..truth.len()).map(|k| (truth[k - 1], truth[k], odom[k - 1], odom[k])).collect();
        // a glitch of the truth: 2 m and a right angle off for one scan
        motions[100].1 *= pose(2.0, 0.0, 1.5);
        let fit = OdometryNoise::fit(&motions).expect("enough motions");
        for (k, (&got, &want)) in fit.noise.alphas.iter().zip(&alphas).enumerate() {
            assert!((got / want - 1.0).abs() < 0.25, "alpha{}: {got} against {want}", k + 1);
        }
        // the glitch, and the few drives so short that odometry took them backwards
        assert!(fit.left_out >= 1 && fit.left_out < motions.len() / 20, "{fit:?}");
        let exact: Vec<_> = motions.iter().map(|&(a, b, _, _)| (a, b, a, b)).collect();
        assert_eq!(OdometryNoise::fit(&exact).map(|f| f.noise), Some(OdometryNoise::NONE));
        assert_eq!(OdometryNoise::fit(&motions[..5]), None);
    }

    /// Drawn odometry starts at the truth, follows it exactly without noise, drifts with it,
    /// stays put over a cut, and draws the same for the same seed.
    #[test]
    fn drifting_odometry_follows_the_truth_as_far_as_its_noise_lets_it() {
        // 4 m along a circle of 5 m radius, facing along it
        let arc = |k: usize| 0.02 * k as f64;
        let path: Vec<Pose> = (0..40).map(|k| pose(5.0 * arc(k).sin(), 5.0 * (1.0 - arc(k).cos()), arc(k))).collect();
        let mut exact = DriftingOdometry::new(OdometryNoise::NONE, 1);
        assert!(path.iter().all(|p| close(&exact.next(p, false), p)));
        let draw = |seed: u64| {
            let mut d = DriftingOdometry::new(OdometryNoise::new([0.05, 0.01, 0.05, 0.01]), seed);
            path.iter().map(|p| d.next(p, false)).collect::<Vec<_>>()
        };
        let (a, b) = (draw(7), draw(7));
        assert!(close(&a[0], &path[0]) && a.iter().zip(&b).all(|(x, y)| close(x, y)));
        let drift = (a[39].translation.vector - path[39].translation.vector).norm();
        assert!(drift > 1e-3 && drift < 1.0, "drifted {drift} m over 4 m");
        let mut cut = DriftingOdometry::new(OdometryNoise::new([0.05, 0.01, 0.05, 0.01]), 7);
        let before = cut.next(&path[0], false);
        assert!(close(&cut.next(&path[30], true), &before));
        assert!(OdometryNoise::from_alphas(&[0.1, 0.0, 0.1]).is_err());
        assert!(OdometryNoise::from_alphas(&[0.1, -0.01, 0.1, 0.0]).is_err());
        assert!(OdometryNoise::from_alphas(&[0.1, f64::NAN, 0.1, 0.0]).is_err());
        assert_eq!(OdometryNoise::from_alphas(&[0.1, 0.0, 0.2, 0.3]), Ok(OdometryNoise::new([0.1, 0.0, 0.2, 0.3])));
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

    /// A turn on the spot past a right angle spreads as the whole turn, not as what is left of
    /// a half turn.
    #[test]
    fn a_turn_on_the_spot_spreads_as_all_of_it() {
        let noise = OdometryNoise::new([0.1, 0.0, 0.0, 0.0]);
        let a = pose(0.0, 0.0, 0.0);
        for turn in [0.5f64, 1.5, 2.6, -2.6, 3.0] {
            let spun = pose(0.0, 0.0, turn);
            assert!((noise.spread(&a, &spun).1 - 0.1f64.sqrt() * turn.abs()).abs() < 1e-9, "{turn}");
            // and as much with a little drive ahead, whichever way the drive first turned
            let ahead = pose(0.05, 0.0, turn);
            assert!((noise.spread(&a, &ahead).1 - 0.1f64.sqrt() * turn.abs()).abs() < 1e-9, "{turn}");
        }
        // the position's spread is the folded model's: drive from turn, a4, sized by what is
        // left of a half turn
        let drive_from_turn = OdometryNoise::new([0.0, 0.0, 0.0, 0.1]);
        let spun = pose(0.0, 0.0, 2.6);
        assert!((drive_from_turn.spread(&a, &spun).0 - 0.1f64.sqrt() * (PI - 2.6)).abs() < 1e-9);
    }
}
