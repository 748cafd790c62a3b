//! Lines of sight over short distances: how far one can look from a point before a wall stops
//! the view. What tells the side of a wall a sensor can stand on, when a map draws walls with
//! thickness (the space between a wall's two faces is closed to every beam).

use crate::grid::WallGrid;
use crate::wall::Wall;
use nalgebra::{Point2, Vector2};

/// Every wall within `reach` of a point, found through a grid, for lines of sight up to
/// `reach` long.
///
/// Two grids: a coarse one whose cells list every wall within `reach` (for [`clearance`]), and
/// a fine one whose cells list the walls that touch them, along which a line of sight is
/// marched cell by cell and stops at the first wall ([`free_run`]). Building a map's corners
/// asks millions of short looks ([`crate::view`]); walking the fine cells a look crosses reads
/// a few walls where the coarse cell listed every wall a metre around.
///
/// [`clearance`]: Self::clearance
/// [`free_run`]: Self::free_run
#[derive(Clone, Debug)]
pub struct SightLines {
    walls: Vec<Wall>,
    grid: WallGrid,
    fine: WallGrid,
    reach: f64,
}

/// Side of the coarse grid's cells, metres.
const CELL: f64 = 1.0;

/// Side of the fine grid's cells, metres: about the looks' scale ([`crate::view`] steps 5-10 cm
/// and asks for 15 cm of clearance).
const FINE_CELL: f64 = 0.25;

/// How close to a fine cell a wall must pass to be listed in it, metres: touching, with room
/// for rounding.
const TOUCHING: f64 = 1e-6;

impl SightLines {
    /// Lines of sight up to `reach` metres among `walls`.
    pub fn new(walls: &[Wall], reach: f64) -> Self {
        let reach = if reach.is_finite() { reach.max(0.0) } else { 0.0 };
        SightLines {
            walls: walls.to_vec(),
            grid: WallGrid::new(walls, CELL, reach),
            fine: WallGrid::new(walls, FINE_CELL, TOUCHING),
            reach,
        }
    }

    /// How far from `from` along the unit vector `dir` the first wall lies, or [`reach`]
    /// (the constructor's) when none lies nearer ([`Wall::ray_hit`]: a wall through `from`
    /// itself does not stop the view).
    ///
    /// The ray is marched through the fine grid; a wall it meets at `t` passes through the
    /// cell the ray is in at `t`, so once the nearest hit so far lies within the cells walked,
    /// no wall further on can be nearer.
    ///
    /// [`reach`]: Self::new
    pub fn free_run(&self, from: Point2<f64>, dir: Vector2<f64>) -> f64 {
        self.free_run_within(from, dir, self.reach)
    }

    /// [`free_run`](Self::free_run) with the look cut at `reach` (at most the constructor's):
    /// the first wall's distance when one lies nearer, `reach` otherwise.
    pub fn free_run_within(&self, from: Point2<f64>, dir: Vector2<f64>, reach: f64) -> f64 {
        let mut best = reach.min(self.reach);
        self.fine.march(from, dir, best, |c, r, leave| {
            for &k in self.fine.walls_in(c, r) {
                if let Some(t) = self.walls[k as usize].ray_hit(from, dir) {
                    best = best.min(t);
                }
            }
            best > leave
        });
        best
    }

    /// The walls the lines of sight run among.
    pub fn walls(&self) -> &[Wall] {
        &self.walls
    }

    /// Distance from `p` to the nearest wall, or the reach when none lies nearer.
    pub fn clearance(&self, p: Point2<f64>) -> f64 {
        self.grid.walls_near(p).iter().map(|&k| self.walls[k as usize].closest(p).0).fold(self.reach, f64::min)
    }

    /// Whether no wall lies closer than `r` to `p`: `clearance(p) >= r` for `r` up to the
    /// reach, read from the fine cells within `r` of `p`.
    pub fn is_clear(&self, p: Point2<f64>, r: f64) -> bool {
        if r.is_nan() || r > self.reach {
            return self.clearance(p) >= r;
        }
        let d = Vector2::new(r, r);
        let ((c0, r0), (c1, r1)) = self.fine.cell_range(p - d, p + d);
        (r0..=r1).all(|row| {
            (c0..=c1).all(|col| self.fine.walls_in(col, row).iter().all(|&k| self.walls[k as usize].closest(p).0 >= r))
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn a_wall_ahead_stops_the_view_and_one_behind_does_not() {
        let walls = [Wall::new(1.0, -1.0, 1.0, 1.0), Wall::new(-0.5, -1.0, -0.5, 1.0)];
        let sight = SightLines::new(&walls, 2.0);
        let o = Point2::new(0.0, 0.0);
        assert!((sight.free_run(o, Vector2::new(1.0, 0.0)) - 1.0).abs() < 1e-12);
        assert!((sight.free_run(o, Vector2::new(-1.0, 0.0)) - 0.5).abs() < 1e-12);
        // nothing within reach upwards
        assert_eq!(sight.free_run(o, Vector2::new(0.0, 1.0)), 2.0);
        assert!((sight.clearance(o) - 0.5).abs() < 1e-12);
        assert_eq!(sight.clearance(Point2::new(0.0, 30.0)), 2.0);
    }

    proptest! {
        /// The grid finds the walls a brute-force pass over every wall finds.
        #[test]
        fn free_run_agrees_with_brute_force(
            segs in proptest::collection::vec((-5.0f64..5.0, -5.0f64..5.0, -5.0f64..5.0, -5.0f64..5.0), 1..40),
            ox in -5.0f64..5.0, oy in -5.0f64..5.0, angle in -3.2f64..3.2, reach in 0.1f64..3.0,
        ) {
            let walls: Vec<Wall> = segs.iter().map(|&(a, b, c, d)| Wall::new(a, b, c, d)).collect();
            let sight = SightLines::new(&walls, reach);
            let (o, dir) = (Point2::new(ox, oy), Vector2::new(angle.cos(), angle.sin()));
            let brute = walls.iter().filter_map(|w| w.ray_hit(o, dir)).fold(reach, f64::min);
            prop_assert!((sight.free_run(o, dir) - brute).abs() < 1e-9);
            let short = reach * 0.3;
            prop_assert!((sight.free_run_within(o, dir, short) - brute.min(short)).abs() < 1e-9);
            let nearest = walls.iter().map(|w| w.closest(o).0).fold(reach, f64::min);
            prop_assert!((sight.clearance(o) - nearest).abs() < 1e-9);
            for r in [0.05, 0.15, reach * 0.5, reach] {
                prop_assert_eq!(sight.is_clear(o, r), nearest >= r);
            }
        }
    }
}
