//! A wall, the map's one element: a segment in the map frame, and what ray casting, distance
//! fields and corners ask of it.

use nalgebra::{Point2, Vector2};

/// A wall: a segment in the map frame.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C)]
pub struct Wall {
    pub a: Point2<f64>,
    pub b: Point2<f64>,
}

impl Wall {
    pub fn new(x1: f64, y1: f64, x2: f64, y2: f64) -> Self {
        Wall { a: Point2::new(x1, y1), b: Point2::new(x2, y2) }
    }

    /// The four walls of the axis-aligned rectangle with corners (x0, y0) and (x1, y1).
    pub fn rectangle(x0: f64, y0: f64, x1: f64, y1: f64) -> [Wall; 4] {
        [Wall::new(x0, y0, x1, y0), Wall::new(x1, y0, x1, y1), Wall::new(x1, y1, x0, y1), Wall::new(x0, y1, x0, y0)]
    }

    pub fn length(&self) -> f64 {
        (self.b - self.a).norm()
    }

    /// The wall's direction, either way along it: radians in [0, pi).
    pub fn direction(&self) -> f64 {
        let d = self.b - self.a;
        d.y.atan2(d.x).rem_euclid(std::f64::consts::PI)
    }

    /// Distance from `from` along `dir` at which the ray meets the wall (its ends included,
    /// with 1e-12 of slack), if strictly ahead; `None` when it misses or runs parallel.
    #[inline]
    pub fn ray_hit(&self, from: Point2<f64>, dir: Vector2<f64>) -> Option<f64> {
        let e = self.b - self.a;
        let den = dir.perp(&e);
        if den.abs() < 1e-15 {
            return None;
        }
        let ao = self.a - from;
        let t = ao.perp(&e) / den;
        let s = ao.perp(&dir) / den;
        (t > 0.0 && (-1e-12..=1.0 + 1e-12).contains(&s)).then_some(t)
    }

    /// Distance from `p` to the segment, and the closest point on it.
    #[inline]
    pub fn closest(&self, p: Point2<f64>) -> (f64, Point2<f64>) {
        let e = self.b - self.a;
        let len2 = e.norm_squared();
        let t = if len2 > 0.0 { ((p - self.a).dot(&e) / len2).clamp(0.0, 1.0) } else { 0.0 };
        let q = self.a + e * t;
        ((p - q).norm(), q)
    }
}

/// Axis-aligned bounds (min, max) of `walls`; the origin twice when there are none.
pub fn bounds_of(walls: &[Wall]) -> (Point2<f64>, Point2<f64>) {
    if walls.is_empty() {
        return (Point2::origin(), Point2::origin());
    }
    let mut lo = Point2::new(f64::INFINITY, f64::INFINITY);
    let mut hi = Point2::new(f64::NEG_INFINITY, f64::NEG_INFINITY);
    for w in walls {
        lo = lo.inf(&w.a).inf(&w.b);
        hi = hi.sup(&w.a).sup(&w.b);
    }
    (lo, hi)
}

// SAFETY: two points of two f64 each (nalgebra's points are `repr(C)` arrays), no padding
// (checked), valid for any bits.
unsafe impl crate::slab::Plain for Wall {}
// SAFETY: as above: two f64.
unsafe impl crate::slab::Plain for Point2<f64> {}
const _: () = assert!(std::mem::size_of::<Wall>() == 32 && std::mem::size_of::<Point2<f64>>() == 16);

/// Walls from `(x, y, direction, length)` tuples: how the property tests draw random maps.
#[cfg(test)]
pub(crate) fn walls_from_seed(seed: &[(f64, f64, f64, f64)]) -> Vec<Wall> {
    seed.iter().map(|&(x, y, a, l)| Wall::new(x, y, x + l * a.cos(), y + l * a.sin())).collect()
}
