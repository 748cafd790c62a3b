//! Pose refinement: a corner-derived pose inherits the angular error of two short lines, which
//! at 5 m is several centimetres. A few Gauss-Newton steps of point-to-line least squares
//! against the map's walls remove it. Points farther than a shrinking gate from any wall (people,
//! furniture) are left out, and the rest are weighted by a Cauchy kernel.

use crate::model::MapModel;
use laser::Pose;
use nalgebra::{Isometry2, Matrix3, Point2, UnitComplex, Vector2, Vector3};

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
    let mut gate = cfg.first_gate;
    let mut paired = 0usize;
    for _ in 0..cfg.iterations {
        let rot = UnitComplex::new(theta);
        let mut h = Matrix3::<f64>::zeros();
        let mut g = Vector3::<f64>::zeros();
        paired = 0;
        for q in points {
            let rq = rot * q.coords;
            let p = Point2::from(rq + t);
            let Some(k) = model.field.nearest_wall(p) else {
                continue;
            };
            let wall = &model.map.walls[k as usize];
            let (distance, on_wall) = wall.closest(p);
            if distance > gate {
                continue;
            }
            paired += 1;
            let normal = model.normals[k as usize];
            let r = (p - on_wall).dot(&normal);
            let j = Vector3::new(normal.x, normal.y, normal.dot(&Vector2::new(-rq.y, rq.x)));
            let w = 1.0 / (1.0 + (r / cfg.kernel).powi(2));
            h += j * j.transpose() * w;
            g += j * (w * r);
        }
        if paired < 3 {
            break;
        }
        // a little damping keeps corridor-like scenes (all walls parallel) from sliding
        let damping = 1e-6 * h.trace().max(1e-9);
        let Some(step) = (h + Matrix3::identity() * damping).lu().solve(&(-g)) else {
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
