//! The map's free space split into connected regions, so the simulator puts the robot where a
//! robot can be: in the building's main space, never inside a closed outline such as a rack, a
//! pillar or a box drawn as four walls (from inside one, every rack of the same size looks
//! alike, and no real scan is taken there). And the space around a building whose walls close
//! it off ([`Outside`]), where the localizer makes no hypothesis.
//!
//! Cells of a grid are passable when they lie at least one cell from every wall; 4-neighbour
//! passable cells are connected. Two cells on either side of a wall are then at least two cells
//! apart, so no region leaks through a wall, while any gap wider than two cells (a door) joins
//! the rooms it opens onto.

use crate::bitgrid::{BitGrid, Grid};
use crate::field::DistanceField;
use crate::flat::{Flat, FlatError, FlatReader, FlatWriter};
use nalgebra::Point2;

/// Largest number of cells before the grid is coarsened.
const MAX_CELLS: f64 = crate::limits::FREE_SPACE_CELLS as f64;

/// Finest cell size, metres.
const FINEST_CELL: f64 = 0.1;

/// Connected regions of the free space, labelled on a grid.
#[derive(Clone, Debug)]
pub struct FreeSpace {
    grid: Grid,
    /// Region of each cell, 0 where the cell is not passable.
    labels: Vec<u32>,
    regions: u32,
    /// Cells of each region, by label (index 0 unused).
    sizes: Vec<usize>,
}

impl FreeSpace {
    /// Labels the free space of `field` within `bounds` (the map's bounding box; the grid extends
    /// two cells beyond it, so the space outside a closed building is one region).
    pub fn new(field: &DistanceField, bounds: (Point2<f64>, Point2<f64>)) -> Self {
        let (lo, hi) = bounds;
        let (w, h) = (hi.x - lo.x, hi.y - lo.y);
        // twice the field's resolution: a cell read through the field is off by at most
        // 0.71 field cells, which must not let two cells on either side of a wall pass
        let cell = crate::grid::coarsened(FINEST_CELL.max(2.0 * field.resolution()), w + 0.4, h + 0.4, MAX_CELLS);
        let origin = Point2::new(lo.x - 2.0 * cell, lo.y - 2.0 * cell);
        let cols = (w / cell).ceil() as usize + 4;
        let rows = (h / cell).ceil() as usize + 4;
        let grid = Grid { origin, cell, cols, rows };
        let passable: Vec<bool> =
            (0..rows * cols).map(|i| field.distance(grid.centre(i % cols, i / cols)) >= cell).collect();
        let (labels, sizes) = connected_regions(&passable, cols, rows);
        let regions = (sizes.len() - 1) as u32;
        FreeSpace { grid, labels, regions, sizes }
    }

    /// The region holding `q`, or `None` where `q` is off the grid or too near a wall.
    pub fn region(&self, q: Point2<f64>) -> Option<u32> {
        Some(self.labels[self.grid.index(q)?]).filter(|&l| l != 0)
    }

    /// The grid the regions are labelled on.
    pub(crate) fn grid(&self) -> Grid {
        self.grid
    }

    /// The region of cell `i` of [`grid`](Self::grid), 0 where the cell is not passable.
    pub(crate) fn label(&self, i: usize) -> u32 {
        self.labels.get(i).copied().unwrap_or(0)
    }

    /// The region with the most cells: the building's main space (its inside, or inside and
    /// around together when its outline is open).
    pub fn largest_region(&self) -> Option<u32> {
        let (region, &size) = self.sizes.iter().enumerate().skip(1).max_by_key(|&(r, &s)| (s, std::cmp::Reverse(r)))?;
        (size > 0).then_some(region as u32)
    }

    /// How many regions the free space has (the outside of a closed building counts as one).
    pub fn regions(&self) -> u32 {
        self.regions
    }

    /// The space around the map, when its walls close a larger space off from it; see
    /// [`Outside`].
    pub fn outside(&self) -> Option<Outside> {
        // the grid's first cell lies beyond the bounds by 1.5 cells each way, so it is passable
        // and in the region around the map
        let around = self.labels.first().copied().filter(|&l| l != 0)?;
        let largest = self.largest_region().map_or(0, |r| self.sizes[r as usize]);
        if self.sizes[around as usize] >= largest {
            return None;
        }
        let mut raster = BitGrid::clear(self.grid);
        for (i, &l) in self.labels.iter().enumerate() {
            if l == around {
                raster.set(i);
            }
        }
        Some(Outside::from_raster(raster))
    }

    /// Cell centres on a lattice of about `count` points over the grid, for sampling.
    pub fn lattice(&self, count: usize) -> impl Iterator<Item = Point2<f64>> + '_ {
        let grid = self.grid;
        let Grid { cols, rows, .. } = grid;
        let stride = ((cols * rows) as f64 / count.max(1) as f64).sqrt().ceil().max(1.0) as usize;
        (0..rows).step_by(stride).flat_map(move |r| (0..cols).step_by(stride).map(move |c| grid.centre(c, r)))
    }
}

/// The space around a building whose walls close it off: the free space connected to what lies
/// beyond the map's bounds, when another region (the building) is larger. A robot localizing
/// in the building is not out there, and the map says nothing of what it would see there: from
/// outside, every beam away from the building reads "no return" as the map predicts, so a
/// wrong pose outside can explain a scan as well as the right one inside (AMCL likewise spreads
/// its particles over known free cells only). A map whose outline is open (a gap wider than two
/// cells, an unclosed side) joins its inside to the outside and has no `Outside`: nothing is
/// ruled out. One bit a cell.
#[derive(Clone, Debug)]
pub struct Outside {
    /// Set where a cell lies in the space around the map.
    raster: BitGrid,
}

impl Outside {
    /// Outside where `raster` is set, and everywhere off it.
    pub(crate) fn from_raster(raster: BitGrid) -> Self {
        Outside { raster }
    }

    /// Whether `q` lies outside the building: beyond the grid, or in a cell of the space around
    /// it. Points within a cell of a wall are never outside.
    pub fn contains(&self, q: Point2<f64>) -> bool {
        // NaN coordinates are no position at all, not a position outside
        self.raster.at(q).unwrap_or(!(q.x.is_nan() || q.y.is_nan()))
    }
}

/// The 4-connected regions of the `passable` cells of a `cols` x `rows` raster (numbered row
/// by row): each cell's region, numbered from 1 (0 for a cell that is not passable), and each
/// region's cell count by number (index 0 unused).
pub fn connected_regions(passable: &[bool], cols: usize, rows: usize) -> (Vec<u32>, Vec<usize>) {
    let mut labels = vec![0u32; rows * cols];
    let mut sizes = vec![0];
    let mut stack = Vec::new();
    for start in 0..rows * cols {
        if !passable[start] || labels[start] != 0 {
            continue;
        }
        let region = sizes.len() as u32;
        labels[start] = region;
        sizes.push(0);
        stack.push(start);
        while let Some(i) = stack.pop() {
            sizes[region as usize] += 1;
            let (c, r) = (i % cols, i / cols);
            let neighbours = [
                (c > 0).then(|| i - 1),
                (c + 1 < cols).then(|| i + 1),
                (r > 0).then(|| i - cols),
                (r + 1 < rows).then(|| i + cols),
            ];
            for n in neighbours.into_iter().flatten() {
                if passable[n] && labels[n] == 0 {
                    labels[n] = region;
                    stack.push(n);
                }
            }
        }
    }
    (labels, sizes)
}

impl Flat for Outside {
    fn put(&self, w: &mut FlatWriter) {
        self.raster.put(w);
    }
    fn take(r: &mut FlatReader<'_>) -> Result<Self, FlatError> {
        Ok(Outside { raster: BitGrid::take(r)? })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::wall::Wall;

    fn rectangle(x0: f64, y0: f64, x1: f64, y1: f64) -> Vec<Wall> {
        Wall::rectangle(x0, y0, x1, y1).to_vec()
    }

    fn free_space(walls: &[Wall]) -> FreeSpace {
        let field = DistanceField::new(walls, 0.05, 1.0);
        FreeSpace::new(&field, crate::wall::bounds_of(walls))
    }

    #[test]
    fn a_closed_box_in_a_hall_is_a_region_of_its_own() {
        let mut walls = rectangle(0.0, 0.0, 10.0, 6.0);
        walls.extend(rectangle(3.0, 2.0, 7.0, 3.0));
        let space = free_space(&walls);
        let hall = space.region(Point2::new(1.0, 1.0)).unwrap();
        let rack = space.region(Point2::new(5.0, 2.5)).unwrap();
        let outside = space.region(Point2::new(-0.15, -0.15)).unwrap();
        assert_ne!(hall, rack);
        assert_ne!(hall, outside);
        assert_ne!(rack, outside);
        assert_eq!(space.region(Point2::new(9.0, 5.0)), Some(hall));
        assert_eq!(space.regions(), 3);
        // on a wall: no region
        assert_eq!(space.region(Point2::new(5.0, 2.0)), None);
    }

    /// Whether `a` and `b` lie in different regions of the free space of `walls`.
    fn apart(walls: &[Wall], a: (f64, f64), b: (f64, f64)) -> bool {
        let space = free_space(walls);
        let (ra, rb) = (space.region(Point2::new(a.0, a.1)), space.region(Point2::new(b.0, b.1)));
        assert!(ra.is_some() && rb.is_some(), "both points are clear of walls");
        ra != rb
    }

    #[test]
    fn a_door_joins_two_rooms_and_a_wall_does_not() {
        // a partition at x = 5 with a 0.8 m door, then without one
        let mut with_door = rectangle(0.0, 0.0, 10.0, 4.0);
        with_door.extend([Wall::new(5.0, 0.0, 5.0, 1.6), Wall::new(5.0, 2.4, 5.0, 4.0)]);
        assert!(!apart(&with_door, (2.0, 2.0), (8.0, 2.0)));
        let mut closed = rectangle(0.0, 0.0, 10.0, 4.0);
        closed.push(Wall::new(5.0, 0.0, 5.0, 4.0));
        assert!(apart(&closed, (2.0, 2.0), (8.0, 2.0)));
    }

    #[test]
    fn a_slanted_wall_does_not_leak() {
        let mut walls = rectangle(0.0, 0.0, 10.0, 10.0);
        walls.push(Wall::new(0.0, 0.0, 10.0, 10.0));
        assert!(apart(&walls, (7.0, 3.0), (3.0, 7.0)));
    }

    fn outside(walls: &[Wall]) -> Option<Outside> {
        free_space(walls).outside()
    }

    #[test]
    fn the_space_around_a_closed_building_is_outside_and_its_rooms_and_racks_are_not() {
        let mut walls = rectangle(0.0, 0.0, 10.0, 6.0);
        walls.extend(rectangle(3.0, 2.0, 7.0, 3.0));
        walls.push(Wall::new(5.0, 3.0, 5.0, 6.0));
        let out = outside(&walls).expect("a closed outline has an outside");
        for (x, y) in [(-0.15, 3.0), (11.0, 3.0), (-50.0, 80.0), (5.0, -0.15), (5.0, 1e9)] {
            assert!(out.contains(Point2::new(x, y)), "({x}, {y}) is outside");
        }
        // the hall, a closed room, a rack's inside, a point on the outline
        for (x, y) in [(1.0, 1.0), (9.5, 5.5), (6.0, 5.0), (5.0, 2.5), (0.0, 3.0), (10.02, 3.0)] {
            assert!(!out.contains(Point2::new(x, y)), "({x}, {y}) is not outside");
        }
        assert!(!out.contains(Point2::new(f64::NAN, 1.0)));
    }

    #[test]
    fn an_open_outline_rules_nothing_out() {
        // a hall with a 1 m gap in one side: its inside is the outside
        let walls = vec![
            Wall::new(0.0, 0.0, 10.0, 0.0),
            Wall::new(10.0, 0.0, 10.0, 6.0),
            Wall::new(10.0, 6.0, 0.0, 6.0),
            Wall::new(0.0, 6.0, 0.0, 3.5),
            Wall::new(0.0, 2.5, 0.0, 0.0),
        ];
        assert!(outside(&walls).is_none());
        // one wall, or walls that enclose nothing larger than the space around them
        assert!(outside(&[Wall::new(0.0, 0.0, 10.0, 0.0)]).is_none());
        assert!(outside(&rectangle(0.0, 0.0, 0.3, 0.3)).is_none());
        // a narrow crack (under two cells) does not open it
        let mut cracked = walls.clone();
        cracked[3] = Wall::new(0.0, 6.0, 0.0, 3.05);
        cracked[4] = Wall::new(0.0, 2.95, 0.0, 0.0);
        assert!(outside(&cracked).is_some());
    }

    #[test]
    fn the_lattice_covers_the_grid() {
        let space = free_space(&rectangle(0.0, 0.0, 10.0, 6.0));
        let points: Vec<_> = space.lattice(1000).collect();
        assert!((500..=2000).contains(&points.len()), "{}", points.len());
        assert!(points.iter().any(|q| q.x < 1.0 && q.y < 1.0));
        assert!(points.iter().any(|q| q.x > 9.0 && q.y > 5.0));
    }
}
