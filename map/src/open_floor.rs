//! Where a point stands among the walls, one byte a cell of the free space's grid: how far the
//! nearest wall is (up to a reach, in 7 bits) and whether the cell lies outside the free
//! space's main region (inside a closed rack or pillar, or around a closed building). It
//! answers what a localizer asks of a point no wall explains, in one lookup: does it stand
//! against a wall, as furniture does, or out in open floor; and could a beam from the main
//! space reach it without going through a wall.

use crate::bitgrid::Grid;
use crate::field::DistanceField;
use crate::flat::{check_len, Flat, FlatError, FlatReader, FlatWriter};
use crate::free_space::FreeSpace;
use crate::slab::Slab;
use crate::wall::Wall;
use nalgebra::Point2;

/// The distance's bits of a cell; the top bit marks a cell outside the main region.
const DISTANCE: u8 = 0x7f;
const AWAY: u8 = 0x80;

/// See the module docs.
#[derive(Clone, Debug)]
pub struct OpenFloor {
    grid: Grid,
    /// Distance to the nearest wall in units of `reach / 127`, and [`AWAY`].
    cells: Slab<u8>,
    reach: f64,
    /// What a point off the grid is: beyond the map's bounds, so in the space around it, which
    /// is the main region when the outline is open.
    off_grid: u8,
}

impl OpenFloor {
    /// The cells of `free_space`'s grid, with their distances to `walls` up to `reach` metres
    /// (the walls `free_space` was made from).
    pub fn new(walls: &[Wall], free_space: &FreeSpace, reach: f64) -> Self {
        let grid = free_space.grid();
        // the field names the wall nearest each of its cells; the distance is then taken to that
        // wall from this grid's cell centre, exactly (the field's own, read off its cells'
        // centres, would add their error to this grid's)
        let field = DistanceField::new(walls, grid.cell, reach.max(grid.cell));
        let from_wall = |q: Point2<f64>| {
            let nearest = field.nearest_wall(q).and_then(|k| walls.get(k as usize));
            nearest.map_or(reach, |w| w.closest(q).0.min(reach))
        };
        let main = free_space.largest_region();
        let scale = f64::from(DISTANCE) / reach.max(1e-9);
        let away = |label: u32| label != 0 && Some(label) != main;
        let mut cells = Vec::with_capacity(grid.cells());
        for r in 0..grid.rows {
            for c in 0..grid.cols {
                let d = (from_wall(grid.centre(c, r)) * scale).round() as u8;
                let flag = if away(free_space.label(r * grid.cols + c)) { AWAY } else { 0 };
                cells.push(d.min(DISTANCE) | flag);
            }
        }
        // the grid's first cell lies beyond the map's bounds, in the space around it
        let off_grid = DISTANCE | if away(free_space.label(0)) { AWAY } else { 0 };
        OpenFloor { grid, cells: cells.into(), reach, off_grid }
    }

    /// The distance from `p` to the nearest wall (metres, at most the reach; to within the
    /// cell's half diagonal and reach / 254), and
    /// whether `p` lies outside the main region. Off the grid (two cells or more beyond the
    /// map's bounds) the distance is the reach.
    #[inline]
    pub fn at(&self, p: Point2<f64>) -> (f64, bool) {
        let v = self.grid.index(p).map_or(self.off_grid, |i| self.cells[i]);
        (f64::from(v & DISTANCE) * (self.reach / f64::from(DISTANCE)), v & AWAY != 0)
    }
}

impl Flat for OpenFloor {
    fn put(&self, w: &mut FlatWriter) {
        self.grid.put(w);
        self.cells.put(w);
        w.put_f64(self.reach);
        w.put_u64(u64::from(self.off_grid));
    }
    fn take(r: &mut FlatReader<'_>) -> Result<Self, FlatError> {
        let grid = Grid::take(r)?;
        let cells: Slab<u8> = Slab::take(r)?;
        check_len("open floor", cells.len(), grid.cells())?;
        let reach = r.take_finite("open floor reach")?;
        let off_grid = u8::try_from(r.take_u64("open floor off the grid")?)
            .map_err(|_| FlatError::new("open floor: its off-grid value is no byte"))?;
        Ok(OpenFloor { grid, cells, reach, off_grid })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::map::WallMap;
    use proptest::prelude::*;

    /// A 12 x 8 m room with a closed 2 x 2 m pillar.
    fn room() -> (Vec<Wall>, FreeSpace) {
        let mut walls = Wall::rectangle(0.0, 0.0, 12.0, 8.0).to_vec();
        walls.extend(Wall::rectangle(8.0, 3.0, 10.0, 5.0));
        let map = WallMap::new(walls.clone());
        let free_space = FreeSpace::new(&DistanceField::new(&walls, 0.05, 0.5), map.bounds());
        (walls, free_space)
    }

    #[test]
    fn inside_the_pillar_and_around_the_room_are_away_from_the_main_space() {
        let (walls, free_space) = room();
        let floor = OpenFloor::new(&walls, &free_space, 2.0);
        assert!(!floor.at(Point2::new(3.0, 4.0)).1);
        assert!(floor.at(Point2::new(9.0, 4.0)).1, "inside the pillar");
        assert!(floor.at(Point2::new(-1.0, 4.0)).1, "around the closed room");
        assert!(floor.at(Point2::new(-50.0, 4.0)).1, "off the grid, around the closed room");
        // an open outline: the space around joins the room, and nothing but the pillar is away
        let open: Vec<Wall> = walls.iter().copied().skip(1).collect();
        let fs = FreeSpace::new(&DistanceField::new(&open, 0.05, 0.5), WallMap::new(open.clone()).bounds());
        let floor = OpenFloor::new(&open, &fs, 2.0);
        assert!(!floor.at(Point2::new(-1.0, 4.0)).1 && !floor.at(Point2::new(-50.0, 4.0)).1);
        assert!(floor.at(Point2::new(9.0, 4.0)).1);
    }

    proptest! {
        /// The distance is the nearest wall's, capped at the reach, to within a cell's half
        /// diagonal and the quantum.
        #[test]
        fn the_distance_agrees_with_the_walls(x in -0.15f64..12.15, y in -0.15f64..8.15) {
            let (walls, free_space) = room();
            let floor = OpenFloor::new(&walls, &free_space, 2.0);
            let p = Point2::new(x, y);
            let truth = walls.iter().map(|w| w.closest(p).0).fold(f64::INFINITY, f64::min).min(2.0);
            let slack = 0.1 * std::f64::consts::FRAC_1_SQRT_2 + 2.0 / 254.0 + 1e-9;
            let from_wall = floor.at(p).0;
            prop_assert!((from_wall - truth).abs() <= slack, "{} vs {}", from_wall, truth);
        }
    }
}
