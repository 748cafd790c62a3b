//! The covariance published with a pose: what a ROS consumer (AMCL seeded on `/initialpose`,
//! a fusion filter) takes as the pose's uncertainty.
//!
//! How it is made, so that it says something true:
//! - An `ok` answer's error is its localization error: [`OK_SPREAD`], a standard deviation of
//!   5 cm in x and y and 0.02 rad (1.1 degrees) in heading, an upper bound on what `gema2
//!   evaluate` measures for right `ok` answers (mean error 0.4 cm on the simulated plans,
//!   2.5-5 cm on the maps built from real logs; docs/results.md).
//! - An `ambiguous` answer is one of several poses that explain the scan about equally well:
//!   the covariance adds, to the `ok` spread, the spread of those alternatives about the
//!   published (best) one: every hypothesis whose cost is within [`AMBIGUITY`] of the best's.
//!   Two poses 10 m apart give a standard deviation of several metres: the pose is not to be
//!   trusted alone, and the covariance says so.
//! - A `failed` scan has no pose and publishes nothing.
//!
//! What it cannot say: a confident wrong answer (an `ok` that is wrong, 0.3-2 % of `ok`s;
//! docs/results.md) carries the `ok` covariance.
//!
//! The 6x6 matrix is row-major over x, y, z and the rotations about x, y, z; z, roll and pitch
//! are not estimated and are 0, as 2D localizers publish them.

use laser::{angle_diff, pose_theta, Pose};

/// Standard deviations of an `ok` answer: metres in x and y, radians in heading.
pub const OK_SPREAD: (f64, f64) = (0.05, 0.02);

/// Hypotheses with a cost at most this many times the best's count as its alternatives.
pub const AMBIGUITY: f64 = 1.25;

/// Indices of x, y and yaw in the row-major 6x6 matrix.
const X: usize = 0;
const Y: usize = 1;
const YAW: usize = 5;

/// The covariance of the best of `hypotheses` (pose, cost; best first), the answer `ok` or not.
pub fn covariance(ok: bool, hypotheses: &[(Pose, f64)]) -> [f64; 36] {
    let (sxy, st) = OK_SPREAD;
    let mut c = [0.0; 36];
    let at = |r: usize, k: usize| r * 6 + k;
    c[at(X, X)] = sxy * sxy;
    c[at(Y, Y)] = sxy * sxy;
    c[at(YAW, YAW)] = st * st;
    let Some(&(best, best_cost)) = hypotheses.first() else { return c };
    if ok {
        return c;
    }
    let limit = best_cost.max(0.0) * AMBIGUITY + 1e-12;
    let alternatives: Vec<&(Pose, f64)> = hypotheses.iter().filter(|h| h.1 <= limit).collect();
    let n = alternatives.len() as f64;
    let theta = pose_theta(&best);
    for (p, _) in alternatives {
        let d = [
            p.translation.x - best.translation.x,
            p.translation.y - best.translation.y,
            angle_diff(pose_theta(p), theta),
        ];
        for (r, &i) in [X, Y, YAW].iter().enumerate() {
            for (k, &j) in [X, Y, YAW].iter().enumerate() {
                c[at(i, j)] += d[r] * d[k] / n;
            }
        }
    }
    c
}

#[cfg(test)]
mod tests {
    use super::*;
    use laser::pose;

    #[test]
    fn an_ok_answer_has_the_measured_spread() {
        let c = covariance(true, &[(pose(1.0, 2.0, 0.5), 0.1), (pose(9.0, 2.0, 0.5), 0.11)]);
        let near = |a: f64, b: f64| (a - b).abs() < 1e-15;
        assert!(near(c[0], 0.0025) && near(c[7], 0.0025) && near(c[35], 0.0004), "{c:?}");
        assert_eq!(c[1], 0.0);
        assert!(c[14] == 0.0 && c[21] == 0.0 && c[28] == 0.0, "z, roll and pitch are not estimated");
    }

    #[test]
    fn an_ambiguous_answer_spreads_over_its_alternatives() {
        // two poses 10 m apart along x explain the scan equally; a third much worse does not count
        let h = [(pose(0.0, 0.0, 0.0), 0.1), (pose(10.0, 0.0, 3.1), 0.11), (pose(0.0, 50.0, 0.0), 0.5)];
        let c = covariance(false, &h);
        assert!((c[0] - (0.0025 + 50.0)).abs() < 1e-9, "{}", c[0]);
        assert!((c[7] - 0.0025).abs() < 1e-12);
        assert!(c[35] > 4.0, "headings 3.1 rad apart: {}", c[35]);
        assert_eq!(c[5], c[30], "symmetric");
        // a positive semi-definite matrix: the x-yaw block's determinant is not negative
        assert!(c[0] * c[35] - c[5] * c[30] >= 0.0);
    }
}
