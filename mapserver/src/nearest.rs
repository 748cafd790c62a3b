//! Nearest-wall queries within a bounded radius: for each scan point, which wall it lies on.
//! Used to refine a pose hypothesis by point-to-line least squares.

use crate::grid::WallGrid;
use crate::map::Wall;
use nalgebra::{Point2, Vector2};

/// The wall nearest to a query point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NearestWall {
    pub wall: u32,
    pub distance: f64,
    /// Closest point on the wall.
    pub point: Point2<f64>,
    /// Unit normal of the wall's line.
    pub normal: Vector2<f64>,
}

#[derive(Clone, Debug)]
pub struct NearestWalls {
    walls: Vec<Wall>,
    normals: Vec<Vector2<f64>>,
    grid: WallGrid,
    radius: f64,
}

impl NearestWalls {
    /// Answers queries up to `radius` metres from a wall.
    pub fn new(walls: &[Wall], radius: f64) -> Self {
        let normals = walls
            .iter()
            .map(|w| {
                let e = (w.b - w.a).normalize();
                Vector2::new(-e.y, e.x)
            })
            .collect();
        NearestWalls { walls: walls.to_vec(), normals, grid: WallGrid::new(walls, 0.5, radius), radius }
    }

    pub fn radius(&self) -> f64 {
        self.radius
    }

    /// The nearest wall within `max_distance` (at most the build radius) of `p`.
    #[inline]
    pub fn nearest(&self, p: Point2<f64>, max_distance: f64) -> Option<NearestWall> {
        let limit = max_distance.min(self.radius);
        let mut best: Option<NearestWall> = None;
        for &k in self.grid.walls_near(p) {
            let (d, q) = self.walls[k as usize].closest(p);
            if d <= limit && best.is_none_or(|b| d < b.distance) {
                best = Some(NearestWall { wall: k, distance: d, point: q, normal: self.normals[k as usize] });
            }
        }
        best
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #[test]
        fn agrees_with_brute_force(x in -4.0f64..4.0, y in -4.0f64..4.0) {
            let walls = vec![Wall::new(-3.0, -3.0, 3.0, -3.0), Wall::new(3.0, -3.0, 3.0, 3.0), Wall::new(-1.0, 0.0, 1.0, 1.0)];
            let nw = NearestWalls::new(&walls, 0.4);
            let p = Point2::new(x, y);
            let brute = walls.iter().enumerate().map(|(k, w)| (w.closest(p).0, k)).min_by(|a, b| a.0.total_cmp(&b.0)).unwrap();
            match nw.nearest(p, 0.4) {
                Some(n) => prop_assert!((n.distance - brute.0).abs() < 1e-12),
                None => prop_assert!(brute.0 > 0.4),
            }
        }
    }
}
