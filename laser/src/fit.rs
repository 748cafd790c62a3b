//! Total (orthogonal) least squares line fit from sufficient statistics: the segmenter's lines
//! (section 4.2) and the walls traced from an occupancy grid (`mapio::trace`) use this one fit.
//!
//! The paper notes that ordinary least squares is biased for steep lines and suggests rotating
//! the samples first (section 4.2); fitting the principal axis of the samples' scatter is the
//! rotation-invariant form of that idea. Because the fit needs only sums, merging two lines
//! (section 4.3) is adding their moments: no sample lists are kept.

use nalgebra::{Point2, Vector2};
use std::ops::AddAssign;

/// Sums of the sample points of a line.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Moments {
    pub n: f64,
    pub sx: f64,
    pub sy: f64,
    pub sxx: f64,
    pub sxy: f64,
    pub syy: f64,
}

impl Moments {
    #[inline]
    pub fn add(&mut self, p: Point2<f64>) {
        self.n += 1.0;
        self.sx += p.x;
        self.sy += p.y;
        self.sxx += p.x * p.x;
        self.sxy += p.x * p.y;
        self.syy += p.y * p.y;
    }

    /// Removes a point previously added.
    #[inline]
    pub fn remove(&mut self, p: Point2<f64>) {
        self.n -= 1.0;
        self.sx -= p.x;
        self.sy -= p.y;
        self.sxx -= p.x * p.x;
        self.sxy -= p.x * p.y;
        self.syy -= p.y * p.y;
    }

    /// The total least squares fit; `None` for fewer than two points or coincident points.
    pub fn fit(&self) -> Option<LineFit> {
        if self.n < 2.0 {
            return None;
        }
        let cx = self.sx / self.n;
        let cy = self.sy / self.n;
        // scatter about the centroid (sums, not means)
        let xx = (self.sxx - self.sx * cx).max(0.0);
        let yy = (self.syy - self.sy * cy).max(0.0);
        let xy = self.sxy - self.sx * cy;
        let half_diff = 0.5 * (xx - yy);
        let root = (half_diff * half_diff + xy * xy).sqrt();
        let mean = 0.5 * (xx + yy);
        let along = mean + root;
        if along <= 1e-18 {
            return None;
        }
        let across = (mean - root).max(0.0);
        let angle = 0.5 * (2.0 * xy).atan2(xx - yy);
        Some(LineFit {
            centroid: Point2::new(cx, cy),
            direction: Vector2::new(angle.cos(), angle.sin()),
            scatter_along: along,
            scatter_across: across,
            n: self.n,
        })
    }
}

impl AddAssign for Moments {
    fn add_assign(&mut self, o: Moments) {
        self.n += o.n;
        self.sx += o.sx;
        self.sy += o.sy;
        self.sxx += o.sxx;
        self.sxy += o.sxy;
        self.syy += o.syy;
    }
}

/// A fitted line: centroid and unit direction, with the scatter of the points along and
/// across it (sums of squares).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LineFit {
    pub centroid: Point2<f64>,
    pub direction: Vector2<f64>,
    pub scatter_along: f64,
    pub scatter_across: f64,
    pub n: f64,
}

impl LineFit {
    /// Root mean square orthogonal distance of the points to the line.
    pub fn rms(&self) -> f64 {
        (self.scatter_across / self.n).sqrt()
    }

    /// Standard deviation of the fitted direction, radians, for points whose distance to the
    /// line has standard deviation at least `sigma_floor`.
    pub fn direction_sigma(&self, sigma_floor: f64) -> f64 {
        let dof = (self.n - 2.0).max(1.0);
        let var = (self.scatter_across / dof).max(sigma_floor * sigma_floor);
        (var / self.scatter_along).sqrt()
    }

    /// Projection of `p` onto the line.
    pub fn project(&self, p: Point2<f64>) -> Point2<f64> {
        self.centroid + self.direction * (p - self.centroid).dot(&self.direction)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        /// A vertical (or any) wall is fitted without bias: the TLS fit of exact points on a
        /// line recovers the line whatever its direction.
        #[test]
        fn exact_points_are_fitted_exactly(angle in -3.2f64..3.2, ox in -5.0f64..5.0, oy in -5.0f64..5.0) {
            let d = Vector2::new(angle.cos(), angle.sin());
            let o = Point2::new(ox, oy);
            let mut m = Moments::default();
            for k in 0..20 {
                m.add(o + d * (k as f64 * 0.1));
            }
            let f = m.fit().unwrap();
            prop_assert!(f.direction.perp(&d).abs() < 1e-9);
            prop_assert!(f.rms() < 1e-6);
            prop_assert!((f.project(o) - o).norm() < 1e-9);
        }
    }

    #[test]
    fn merging_moments_equals_fitting_all_points() {
        let pts: Vec<Point2<f64>> = (0..30).map(|k| Point2::new(k as f64 * 0.1, 0.01 * ((k * 7) % 5) as f64)).collect();
        let mut all = Moments::default();
        let mut a = Moments::default();
        let mut b = Moments::default();
        for (k, p) in pts.iter().enumerate() {
            all.add(*p);
            if k < 12 {
                a.add(*p)
            } else {
                b.add(*p)
            }
        }
        a += b;
        let (fa, fb) = (all.fit().unwrap(), a.fit().unwrap());
        assert!((fa.direction.perp(&fb.direction)).abs() < 1e-12);
        assert!((fa.rms() - fb.rms()).abs() < 1e-12);
    }

    #[test]
    fn direction_uncertainty_shrinks_with_length() {
        let fit_of = |len: f64| {
            let mut m = Moments::default();
            for k in 0..10 {
                m.add(Point2::new(k as f64 * len / 9.0, 0.0));
            }
            m.fit().unwrap().direction_sigma(0.01)
        };
        assert!(fit_of(2.0) < fit_of(0.2) / 5.0);
    }
}
