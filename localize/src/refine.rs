//! Pose refinement: a corner-derived pose inherits the angular error of two short lines, which
//! at 5 m is several centimetres. A few Gauss-Newton steps of point-to-line least squares
//! against the map's walls remove it. Points farther than a shrinking gate from any wall (people,
//! furniture) are left out, and the rest are weighted by a Cauchy kernel. A prior that the
//! correction stays within the gate keeps directions the points do not pin down where they
//! started.

use crate::model::MapModel;
use laser::Pose;
use nalgebra::{Isometry2, Matrix3, Point2, Vector2, Vector3};

/// Refinement parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RefineConfig {
    pub iterations: usize,
    /// Pairing gate of the first iteration, metres; it halves each step down to `final_gate`.
    pub first_gate: f64,
    pub final_gate: f64,
    /// Scale of the Cauchy weight, metres.
    pub kernel: f64,
}

impl Default for RefineConfig {
    fn default() -> Self {
        RefineConfig { iterations: 8, first_gate: 0.5, final_gate: 0.12, kernel: 0.05 }
    }
}

/// Refines `pose` so that `points` (sensor frame) lie on the map's walls; returns the refined
/// pose and the fraction of points that ended within the final gate.
pub fn refine(model: &MapModel, points: &[Point2<f64>], pose: &Pose, cfg: &RefineConfig) -> (Pose, f64) {
    let mut theta = pose.rotation.angle();
    let mut t = pose.translation.vector;
    let (start, start_theta) = (t, theta);
    let mut gate = cfg.first_gate;
    let mut paired = 0usize;
    let inverse_kernel_squared = 1.0 / (cfg.kernel * cfg.kernel);
    let nearer_end_squared =
        |p: Point2<f64>, a: Point2<f64>, b: Point2<f64>| (p - a).norm_squared().min((p - b).norm_squared());
    for _ in 0..cfg.iterations {
        let (sin, cos) = theta.sin_cos();
        // the normal equations' upper triangle (h) and gradient (g), accumulated as scalars
        let [mut h00, mut h01, mut h02, mut h11, mut h12, mut h22] = [0.0f64; 6];
        let [mut g0, mut g1, mut g2] = [0.0f64; 3];
        // weighted sums of the paired points' squared lever arms and of their weights
        let (mut lever_squared, mut weights) = (0.0f64, 0.0f64);
        let gate_squared = gate * gate;
        paired = 0;
        for q in points {
            let rq = Vector2::new(cos * q.x - sin * q.y, sin * q.x + cos * q.y);
            let p = Point2::from(rq + t);
            let Some(k) = model.field.nearest_wall(p) else {
                continue;
            };
            let wall = &model.frames[k as usize];
            let normal = wall.normal;
            // signed distance to the wall's line; to the wall itself when p projects onto it,
            // else to its nearer end
            let r = (p - wall.a).dot(&normal);
            let along = (p - wall.a).dot(&wall.e);
            let distance_squared = if (0.0..=wall.length_squared).contains(&along) {
                r * r
            } else {
                nearer_end_squared(p, wall.a, wall.a + wall.e)
            };
            if distance_squared > gate_squared {
                continue;
            }
            paired += 1;
            // the residual's Jacobian in (x, y, theta)
            let (j0, j1, j2) = (normal.x, normal.y, normal.y * rq.x - normal.x * rq.y);
            let w = 1.0 / (1.0 + r * r * inverse_kernel_squared);
            let (wj0, wj1, wj2) = (w * j0, w * j1, w * j2);
            h00 += wj0 * j0;
            h01 += wj0 * j1;
            h02 += wj0 * j2;
            h11 += wj1 * j1;
            h12 += wj1 * j2;
            h22 += wj2 * j2;
            g0 += wj0 * r;
            g1 += wj1 * r;
            g2 += wj2 * r;
            lever_squared += w * rq.norm_squared();
            weights += w;
        }
        let h = Matrix3::new(h00, h01, h02, h01, h11, h12, h02, h12, h22);
        let g = Vector3::new(g0, g1, g2);
        if paired < 3 {
            break;
        }
        // the prior holds the whole correction, not each step: steps cannot add up along a
        // direction the points do not pin down
        let prior = prior_damping(cfg.kernel, gate, lever_squared / weights);
        let offset = Vector3::new(t.x - start.x, t.y - start.y, theta - start_theta);
        let Some(step) = (h + prior).lu().solve(&(-(g + prior * offset))) else {
            break;
        };
        t += Vector2::new(step.x, step.y);
        theta += step.z;
        gate = (gate * 0.5).max(cfg.final_gate);
        if step.xy().norm() < 1e-5 && step.z.abs() < 1e-6 && gate <= cfg.final_gate {
            break;
        }
    }
    let fraction = if points.is_empty() { 0.0 } else { paired as f64 / points.len() as f64 };
    (Isometry2::new(t, theta), fraction)
}

/// How well `points` at `pose` pin down the position: the smaller eigenvalue of the sum of
/// n n^T over the points, n the normal of the wall each lies on (within `gate` of it), so in
/// points' worth: a point on no wall adds nothing, one on a wall across the weakest direction
/// one. 0 in a corridor: every wall runs one way, the position along it is free. Also the
/// direction it is taken along: the unit eigenvector of the smaller eigenvalue (the direction
/// the points pin down least).
pub fn weakest_direction(model: &MapModel, points: &[Point2<f64>], pose: &Pose, gate: f64) -> (f64, Vector2<f64>) {
    let (mut xx, mut xy, mut yy) = (0.0f64, 0.0f64, 0.0f64);
    for q in points {
        let p = pose * q;
        let Some(k) = model.field.nearest_wall(p) else { continue };
        let wall = &model.frames[k as usize];
        let along = (p - wall.a).dot(&wall.e);
        if !(0.0..=wall.length_squared).contains(&along) || (p - wall.a).dot(&wall.normal).abs() > gate {
            continue;
        }
        let n = wall.normal;
        (xx, xy, yy) = (xx + n.x * n.x, xy + n.x * n.y, yy + n.y * n.y);
    }
    // the smaller root of the 2 x 2 symmetric matrix's characteristic polynomial
    let half_trace = (xx + yy) / 2.0;
    let least = half_trace - (((xx - yy) / 2.0).powi(2) + xy * xy).sqrt();
    // its eigenvector: (xy, least - xx) or (least - yy, xy), whichever is longer
    let (u, v) = (Vector2::new(xy, least - xx), Vector2::new(least - yy, xy));
    let e = if u.norm_squared() >= v.norm_squared() { u } else { v };
    let dir = if e.norm_squared() > 1e-18 { e.normalize() } else { Vector2::new(1.0, 0.0) };
    (least.max(0.0), dir)
}

/// A prior that the correction from the starting pose lies within the pairing gate, as the
/// matrix added to the normal equations (the prior's information, scaled by `kernel`^2).
///
/// Residuals have the scale of the Cauchy kernel, `kernel`; the correction is taken to be
/// about `gate` in position and `gate / lever` in heading (`lever` the points' rms distance
/// from the sensor, `lever_squared` its square): beyond the gate, pairing a point with its
/// nearest wall means nothing. Directions the points pin down are left as they were (their
/// curvature is tens to hundreds, the prior under 0.2); directions they do not pin down stay
/// where they started instead of taking the noise divided by a near-zero curvature, metres: a
/// corridor's walls say nothing about where along it the sensor is, a lone pillar nothing
/// about turning around it.
fn prior_damping(kernel: f64, gate: f64, lever_squared: f64) -> Matrix3<f64> {
    let k = (kernel / gate).powi(2);
    let lever_squared = if lever_squared.is_finite() { lever_squared.max(1e-6) } else { 1.0 };
    Matrix3::from_diagonal(&Vector3::new(k, k, k * lever_squared))
}
