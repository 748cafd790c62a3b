//! Lines of sight over short distances: how far one can look from a point before a wall stops
//! the view. What tells the side of a wall a sensor can stand on, when a map draws walls with
//! thickness (the space between a wall's two faces is closed to every beam).

use crate::grid::WallGrid;
use crate::wall::Wall;
use nalgebra::{Point2, Vector2};

/// Every wall within `reach` of a point, found through a grid, for lines of sight up to
/// `reach` long.
///
/// The grid's cells are small and list the walls that touch them: a line of sight is marched
/// cell by cell and stops at the first wall ([`free_run`]), and a clearance reads the cells
/// within its radius ([`clearance`], [`is_clear`]). Building a map's corners asks millions of
/// short looks ([`crate::view`]); walking the cells a look crosses reads a few walls where a
/// cell of the look's length would list every wall a metre around.
///
/// [`clearance`]: Self::clearance
/// [`free_run`]: Self::free_run
/// [`is_clear`]: Self::is_clear
#[derive(Clone, Debug)]
pub struct SightLines {
    walls: Vec<Wall>,
    grid: WallGrid,
    reach: f64,
}

/// Side of the grid's cells, metres: about the looks' scale ([`crate::view`] steps 5-10 cm and
/// asks for 15 cm of clearance).
const CELL: f64 = 0.25;

/// How close to a cell a wall must pass to be listed in it, metres: touching, with room for
/// rounding.
const TOUCHING: f64 = 1e-6;

impl SightLines {
    /// Lines of sight up to `reach` metres among `walls`.
    pub fn new(walls: &[Wall], reach: f64) -> Self {
        let reach = if reach.is_finite() { reach.max(0.0) } else { 0.0 };
        SightLines { walls: walls.to_vec(), grid: WallGrid::new(walls, CELL, TOUCHING), reach }
    }

    /// How far from `from` along the unit vector `dir` the first wall lies, or [`reach`]
    /// (the constructor's) when none lies nearer ([`Wall::ray_hit`]: a wall through `from`
    /// itself does not stop the view).
    ///
    /// The ray is marched through the grid; a wall it meets at `t` passes through the cell the
    /// ray is in at `t`, so once the nearest hit so far lies within the cells walked, no wall
    /// further on can be nearer.
    ///
    /// [`reach`]: Self::new
    pub fn free_run(&self, from: Point2<f64>, dir: Vector2<f64>) -> f64 {
        let mut best = self.reach;
        self.grid.march(from, dir, best, |c, r, leave| {
            for &k in self.grid.walls_in(c, r) {
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

    /// The walls listed in the cells within `r` of `p` (some more than once): every wall
    /// closer than `r` to `p` among them.
    fn walls_around(&self, p: Point2<f64>, r: f64) -> impl Iterator<Item = &Wall> + '_ {
        let d = Vector2::new(r, r);
        let ((c0, r0), (c1, r1)) = self.grid.cell_range(p - d, p + d);
        (r0..=r1)
            .flat_map(move |row| (c0..=c1).flat_map(move |col| self.grid.walls_in(col, row)))
            .map(|&k| &self.walls[k as usize])
    }

    /// Distance from `p` to the nearest wall, or the reach when none lies nearer.
    pub fn clearance(&self, p: Point2<f64>) -> f64 {
        self.walls_around(p, self.reach).map(|w| w.closest(p).0).fold(self.reach, f64::min)
    }

    /// Whether no wall lies closer than `r` to `p`: `clearance(p) >= r` (never, for `r` past
    /// the reach), reading only the cells within `r` of `p`.
    pub fn is_clear(&self, p: Point2<f64>, r: f64) -> bool {
        r <= self.reach && self.walls_around(p, r).all(|w| w.closest(p).0 >= r)
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
            let nearest = walls.iter().map(|w| w.closest(o).0).fold(reach, f64::min);
            prop_assert!((sight.clearance(o) - nearest).abs() < 1e-9);
            for r in [0.05, 0.15, reach * 0.5, reach] {
                prop_assert_eq!(sight.is_clear(o, r), nearest >= r);
            }
        }
    }
}
