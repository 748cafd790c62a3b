//! Lines: clusters of aligned samples and their fitted geometry.

use crate::fit::{LineFit, Moments};
use crate::sample::{ErrorModel, Sample};
use nalgebra::{Point2, Vector2};

/// A line l_k: consecutive samples accepted by line visibility (or merged by filtering), with
/// its total least squares fit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Line {
    /// Index of the first and last sample (into the scan's sample list).
    pub first_sample: u32,
    pub last_sample: u32,
    /// |l|: number of samples (eq. 4, eq. 5).
    pub samples: u32,
    pub moments: Moments,
    pub fit: LineFit,
    /// The first and last samples projected onto the fitted line: the visible extent.
    pub start: Point2<f64>,
    pub end: Point2<f64>,
    /// Unit vector from `start` to `end`.
    pub direction: Vector2<f64>,
    /// Unit normal pointing to the side the sensor sees (the wall's visible face).
    pub normal: Vector2<f64>,
    /// Standard deviation of `direction`, radians.
    pub direction_sigma: f64,
}

impl Line {
    /// Builds the line of `samples[first..=last]` from their moments; `None` when the fit is
    /// degenerate (fewer than two distinct points).
    pub fn from_moments(
        samples: &[Sample],
        first: usize,
        last: usize,
        moments: Moments,
        error: &ErrorModel,
    ) -> Option<Line> {
        let fit = moments.fit()?;
        let start = fit.project(samples[first].point());
        let end = fit.project(samples[last].point());
        let mut direction = fit.direction;
        if (end - start).dot(&direction) < 0.0 {
            direction = -direction;
        }
        let mut normal = Vector2::new(-direction.y, direction.x);
        if normal.dot(&fit.centroid.coords) > 0.0 {
            normal = -normal;
        }
        let sigma_floor = error.at(fit.centroid.coords.norm()) / 3.0;
        Some(Line {
            first_sample: first as u32,
            last_sample: last as u32,
            samples: moments.n as u32,
            moments,
            fit,
            start,
            end,
            direction,
            normal,
            direction_sigma: fit.direction_sigma(sigma_floor),
        })
    }

    /// Visible length, metres.
    pub fn length(&self) -> f64 {
        (self.end - self.start).norm()
    }

    /// Orthogonal distance from `p` to the (infinite) fitted line.
    pub fn distance_to(&self, p: Point2<f64>) -> f64 {
        (p - self.fit.centroid).dot(&self.normal).abs()
    }
}
