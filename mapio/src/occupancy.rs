//! Which places a survey's beams hit, and which they passed through: the evidence an occupancy
//! grid keeps, used to tell a building's walls from what moved while the survey went by.
//!
//! A wall map built from scans takes its walls from lines the scans saw. A line may be a
//! person or a door that later opened; a short piece of wall (a door frame, a recess, a
//! cabinet) may be seen by a single scan of a sparse survey, or by several whose lines never
//! agreed closely enough in direction to be merged. Counting, for each cell, the scans that hit
//! it and the scans that saw through it tells these apart: a wall's cells are hit and never
//! seen through, a person's are hit by a scan or two and crossed by the beams of the scans
//! before and after. A cell *stayed* when at least one scan hit it and no more scans passed
//! through it than hit it.

use map::bitgrid::Grid;
use map::Wall;
use nalgebra::{Point2, Vector2};
use std::f64::consts::PI;

/// Most cells an [`Occupancy`] may have (20 bytes each).
pub const MAX_CELLS: usize = map::limits::SURVEY_CELLS;

/// Walls closer in direction than this (radians) are one wall where they overlap.
const ALIKE: f64 = 0.26;

/// How many scans hit a cell and how many passed through it.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct Evidence {
    hit_scans: u32,
    pass_scans: u32,
    /// The last scan (numbered from 1) that hit the cell, and that passed through it: a scan
    /// counts once per cell, however many of its beams meet the cell.
    last_hit: u32,
    last_pass: u32,
}

impl Evidence {
    fn stayed(&self) -> bool {
        self.hit_scans > 0 && self.hit_scans >= self.pass_scans
    }
}

/// Hit and pass counts per cell over a survey, and the walls drawn from them so far.
#[derive(Clone, Debug)]
pub struct Occupancy {
    grid: Grid,
    cells: Vec<Evidence>,
    scan: u32,
    /// Per cell, the direction (radians, in [0, pi)) of a wall already drawn through it, or
    /// NaN.
    drawn: Vec<f32>,
}

impl Occupancy {
    /// Cells of `cell` metres covering `lo`..`hi`, no scan yet; over a survey so wide that
    /// [`MAX_CELLS`] would not do, the cells grow until they do ([`cell`](Self::cell) says how
    /// large they are). `None` when the cell is not a positive finite size or the bounds are
    /// not finite.
    pub fn covering(lo: Point2<f64>, hi: Point2<f64>, cell: f64) -> Option<Self> {
        let grid = Self::grid_over(lo, hi, cell)?;
        let cells = grid.cells();
        Some(Occupancy { grid, cells: vec![Evidence::default(); cells], scan: 0, drawn: vec![f32::NAN; cells] })
    }

    /// The grid [`covering`](Self::covering) allocates.
    fn grid_over(lo: Point2<f64>, hi: Point2<f64>, cell: f64) -> Option<Grid> {
        let finite = [lo.x, lo.y, hi.x, hi.y].iter().all(|v| v.is_finite());
        if !(finite && cell.is_finite() && cell > 0.0 && lo.x <= hi.x && lo.y <= hi.y) {
            return None;
        }
        let (width, height) = (hi.x - lo.x, hi.y - lo.y);
        // half the budget: rounding each side up adds a row and a column
        let cell = map::grid::coarsened(cell, width, height, (MAX_CELLS / 2) as f64);
        let cols = (width / cell).ceil().max(1.0) as usize;
        let rows = (height / cell).ceil().max(1.0) as usize;
        let grid = Grid { origin: lo, cell, cols, rows };
        (grid.cells() <= MAX_CELLS).then_some(grid)
    }

    pub fn cell(&self) -> f64 {
        self.grid.cell
    }

    /// Starts the next scan: the beams added from now on count as one scan's.
    pub fn next_scan(&mut self) {
        self.scan += 1;
    }

    /// One beam of the current scan from `sensor` that hit something at `hit`: the cells it
    /// crossed up to `clearance` metres short of the hit are passed through, the hit's cell is
    /// hit. Points off the grid are skipped.
    pub fn add_beam(&mut self, sensor: Point2<f64>, hit: Point2<f64>, clearance: f64) {
        let d = hit - sensor;
        let length = d.norm();
        if length > clearance {
            self.pass_through(sensor, sensor + d * ((length - clearance) / length));
        }
        let scan = self.scan.max(1);
        if let Some(i) = self.grid.index(hit) {
            let e = &mut self.cells[i];
            if e.last_hit != scan {
                e.last_hit = scan;
                e.hit_scans += 1;
            }
        }
    }

    /// The current scan saw through the cells from `from` to `to`.
    pub fn pass_through(&mut self, from: Point2<f64>, to: Point2<f64>) {
        let scan = self.scan.max(1);
        for i in self.grid.cells_along(from, to) {
            let e = &mut self.cells[i];
            if e.last_pass != scan {
                e.last_pass = scan;
                e.pass_scans += 1;
            }
        }
    }

    /// Whether something stayed in the cell of `q` (see the module's comment).
    pub fn stayed(&self, q: Point2<f64>) -> bool {
        self.grid.index(q).is_some_and(|i| self.cells[i].stayed())
    }

    /// Whether something stayed in `q`'s cell or one of the 8 around it: a line fitted to a
    /// wall's points may run a cell off the cells they fell in.
    pub fn stayed_near(&self, q: Point2<f64>) -> bool {
        self.around(q).any(|i| self.cells[i].stayed())
    }

    /// The parts of `wall` along which something stayed and which no wall drawn before
    /// ([`draw`](Self::draw)) already covers, sampled every half cell; gaps up to `bridge`
    /// metres are bridged (a beam that missed a cell, a door frame's shadow).
    pub fn static_parts(&self, wall: &Wall, bridge: f64) -> Vec<Wall> {
        let direction = wall.direction();
        let points: Vec<Point2<f64>> = self.grid.points_along(wall.a, wall.b).collect();
        let spacing = wall.length() / points.len().saturating_sub(1).max(1) as f64;
        let mut parts = Vec::new();
        // the current part's first and last sample
        let mut part: Option<(usize, usize)> = None;
        for (k, &q) in points.iter().enumerate() {
            if !self.stayed_near(q) || self.drawn_at(q, direction) {
                continue;
            }
            part = match part {
                Some((first, last)) if (k - last) as f64 * spacing <= bridge => Some((first, k)),
                Some((first, last)) => {
                    parts.push(Wall { a: points[first], b: points[last] });
                    Some((k, k))
                }
                None => Some((k, k)),
            };
        }
        if let Some((first, last)) = part {
            parts.push(Wall { a: points[first], b: points[last] });
        }
        parts
    }

    /// Marks `wall` as drawn on the cells it crosses: [`static_parts`](Self::static_parts)
    /// leaves out what it covers.
    pub fn draw(&mut self, wall: &Wall) {
        let direction = wall.direction() as f32;
        for i in self.grid.cells_along(wall.a, wall.b) {
            self.drawn[i] = direction;
        }
    }

    /// Whether a wall within [`ALIKE`] of `direction` was drawn through `q`'s cell.
    fn drawn_at(&self, q: Point2<f64>, direction: f64) -> bool {
        self.grid.index(q).is_some_and(|i| {
            // directions live on a circle of circumference pi (NaN, none drawn, compares false)
            let diff = (self.drawn[i] as f64 - direction).rem_euclid(PI);
            diff.min(PI - diff) < ALIKE
        })
    }

    /// The cells of `q` and of the 8 around it that lie on the grid.
    fn around(&self, q: Point2<f64>) -> impl Iterator<Item = usize> + '_ {
        let c = self.grid.cell;
        (-1..=1).flat_map(move |dx| {
            (-1..=1).filter_map(move |dy| self.grid.index(q + Vector2::new(dx as f64 * c, dy as f64 * c)))
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn p(x: f64, y: f64) -> Point2<f64> {
        Point2::new(x, y)
    }

    /// A survey from (0, 0), one scan a step, of a wall at x = 3 from y = -2 to 2, with
    /// something at (2, 0.5) in the scans `standing`.
    fn survey(scans: u32, standing: std::ops::Range<u32>) -> Occupancy {
        let mut o = Occupancy::covering(p(-1.0, -3.0), p(4.0, 3.0), 0.05).unwrap();
        for s in 0..scans {
            o.next_scan();
            for k in -20..=20 {
                let y = k as f64 * 0.1;
                let blocked = standing.contains(&s) && (y - 0.75).abs() < 0.11;
                let hit = if blocked { p(2.0, y / 1.5) } else { p(3.0, y) };
                o.add_beam(p(0.0, 0.0), hit, 0.1);
            }
        }
        o
    }

    fn length(parts: &[Wall]) -> f64 {
        parts.iter().map(|w| w.length()).sum()
    }

    #[test]
    fn a_wall_hit_scan_after_scan_stays_and_a_passer_by_does_not() {
        let o = survey(10, 3..5);
        let wall = o.static_parts(&Wall::new(3.0, -2.0, 3.0, 2.0), 0.3);
        assert_eq!(wall.len(), 1, "{wall:?}");
        assert!(length(&wall) > 3.9, "{wall:?}");
        // hit by two scans, crossed by eight
        assert!(o.static_parts(&Wall::new(2.0, 0.43, 2.0, 0.57), 0.3).is_empty());
        // nothing was ever seen there
        assert!(o.static_parts(&Wall::new(-0.5, 2.5, 0.5, 2.5), 0.3).is_empty());
    }

    #[test]
    fn something_that_stood_through_the_survey_stays_and_shadows_no_wall() {
        let o = survey(10, 0..10);
        let standing = o.static_parts(&Wall::new(2.0, 0.43, 2.0, 0.57), 0.3);
        assert!(length(&standing) > 0.1, "{standing:?}");
        // the wall behind it was never hit there, yet a gap under `bridge` is bridged...
        assert_eq!(o.static_parts(&Wall::new(3.0, -2.0, 3.0, 2.0), 0.3).len(), 1);
        // ...and a narrower bridge leaves two parts
        assert_eq!(o.static_parts(&Wall::new(3.0, -2.0, 3.0, 2.0), 0.05).len(), 2);
    }

    #[test]
    fn a_wall_drawn_once_is_not_drawn_again_but_a_crossing_one_is() {
        let mut o = survey(10, 0..0);
        let first = o.static_parts(&Wall::new(3.0, -2.0, 3.0, 0.5), 0.3);
        for w in &first {
            o.draw(w);
        }
        // the same wall sighted again, overlapping the first: only the new stretch is left
        let again = o.static_parts(&Wall::new(3.0, -1.0, 3.0, 2.0), 0.3);
        assert_eq!(again.len(), 1, "{again:?}");
        assert!(again[0].a.y > 0.45 && again[0].b.y > 1.9, "{again:?}");
        // a wall of another direction through a drawn cell is not hidden there
        assert!(!o.drawn_at(p(3.0, 0.0), 0.0));
        assert!(o.drawn_at(p(3.0, 0.0), PI / 2.0 + 0.1));
    }

    #[test]
    fn one_scan_counts_once_however_many_beams_meet_a_cell() {
        let mut o = Occupancy::covering(p(0.0, 0.0), p(1.0, 1.0), 0.1).unwrap();
        o.next_scan();
        for _ in 0..5 {
            o.add_beam(p(0.05, 0.05), p(0.55, 0.05), 0.1);
        }
        // hit once; the next scan sees through it twice over
        assert!(o.stayed(p(0.55, 0.05)));
        o.next_scan();
        o.pass_through(p(0.05, 0.05), p(0.95, 0.05));
        o.pass_through(p(0.05, 0.05), p(0.95, 0.05));
        assert!(o.stayed(p(0.55, 0.05)), "one scan hit, one passed: a tie stays");
        o.next_scan();
        o.pass_through(p(0.05, 0.05), p(0.95, 0.05));
        assert!(!o.stayed(p(0.55, 0.05)));
    }

    #[test]
    fn bad_grids_and_segments_are_refused_or_harmless() {
        assert!(Occupancy::covering(p(0.0, 0.0), p(1.0, 1.0), 0.0).is_none());
        assert!(Occupancy::covering(p(0.0, 0.0), p(f64::NAN, 1.0), 0.1).is_none());
        // a survey 1000 km across gets cells of 250 m, within the budget
        let wide = Occupancy::grid_over(p(0.0, 0.0), p(1e6, 1e6), 0.05).unwrap();
        assert!(wide.cell > 100.0 && wide.cells() <= MAX_CELLS, "{}", wide.cell);
        let corridor = Occupancy::grid_over(p(0.0, 0.0), p(2e8, 2.0), 0.05).unwrap();
        assert!(corridor.cells() <= MAX_CELLS, "{}", corridor.cell);
        // a building keeps its 5 cm cells
        assert_eq!(Occupancy::grid_over(p(0.0, 0.0), p(200.0, 100.0), 0.05).unwrap().cell, 0.05);
        let mut o = Occupancy::covering(p(0.0, 0.0), p(1.0, 1.0), 0.1).unwrap();
        o.next_scan();
        o.add_beam(p(0.5, 0.5), p(f64::NAN, 0.5), 0.1);
        o.add_beam(p(0.5, 0.5), p(0.5, 0.5), 0.1);
        o.pass_through(p(0.5, 0.5), p(f64::INFINITY, 0.5));
        assert!(o.static_parts(&Wall::new(0.5, 0.5, 0.5, 0.5), 0.3).len() <= 1);
    }
}
