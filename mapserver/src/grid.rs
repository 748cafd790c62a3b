//! A uniform grid over the map whose cells list the walls within a margin of them: the spatial
//! index behind ray casting and nearest-wall queries.

use crate::map::Wall;
use nalgebra::Point2;

/// Most cells a [`WallGrid`] has: its cells are coarsened beyond that (a map kilometres
/// across), which makes lists longer but keeps every query's answer.
const MAX_CELLS: f64 = 4.0e6;

/// `cell`, coarsened as needed so that a grid over `width` x `height` metres has at most about
/// `max_cells` cells, and at most that many along either side whatever its shape.
pub(crate) fn coarsened(cell: f64, width: f64, height: f64, max_cells: f64) -> f64 {
    cell.max((width * height / max_cells).sqrt()).max(width.max(height) / max_cells)
}

#[derive(Clone, Debug)]
pub struct WallGrid {
    origin: Point2<f64>,
    cell: f64,
    cols: usize,
    rows: usize,
    /// Start of each cell's run in `items` (CSR layout, `cols * rows + 1` entries).
    starts: Vec<u32>,
    items: Vec<u32>,
}

impl WallGrid {
    /// Indexes `walls` in cells of side `cell`; a cell lists every wall closer than `margin` to
    /// any point of the cell. The grid covers the walls' bounding box and `margin` beyond.
    pub fn new(walls: &[Wall], cell: f64, margin: f64) -> Self {
        Self::covering(walls, cell, margin, margin + cell)
    }

    /// [`new`](Self::new) with a grid that covers the walls' bounding box and only `pad`
    /// beyond: lists of a long reach for points that lie among the walls.
    pub fn covering(walls: &[Wall], cell: f64, margin: f64, pad: f64) -> Self {
        let (lo, hi) = crate::map::bounds_of(walls);
        let cell = coarsened(cell, hi.x - lo.x + 2.0 * pad, hi.y - lo.y + 2.0 * pad, MAX_CELLS);
        let origin = Point2::new(lo.x - pad, lo.y - pad);
        let cols = (((hi.x - lo.x) + 2.0 * pad) / cell).ceil().max(1.0) as usize;
        let rows = (((hi.y - lo.y) + 2.0 * pad) / cell).ceil().max(1.0) as usize;
        let half_diag = cell * std::f64::consts::FRAC_1_SQRT_2;
        let mut per_cell: Vec<Vec<u32>> = vec![Vec::new(); cols * rows];
        for (k, w) in walls.iter().enumerate() {
            let reach = margin + cell;
            let (c0, r0) = Self::clamp_cell(
                origin,
                cell,
                cols,
                rows,
                Point2::new(w.a.x.min(w.b.x) - reach, w.a.y.min(w.b.y) - reach),
            );
            let (c1, r1) = Self::clamp_cell(
                origin,
                cell,
                cols,
                rows,
                Point2::new(w.a.x.max(w.b.x) + reach, w.a.y.max(w.b.y) + reach),
            );
            for r in r0..=r1 {
                for c in c0..=c1 {
                    let centre = centre_of(origin, cell, c, r);
                    if w.closest(centre).0 <= margin + half_diag {
                        per_cell[r * cols + c].push(k as u32);
                    }
                }
            }
        }
        let mut starts = Vec::with_capacity(cols * rows + 1);
        let mut items = Vec::new();
        for list in &per_cell {
            starts.push(items.len() as u32);
            items.extend_from_slice(list);
        }
        starts.push(items.len() as u32);
        WallGrid { origin, cell, cols, rows, starts, items }
    }

    fn clamp_cell(origin: Point2<f64>, cell: f64, cols: usize, rows: usize, p: Point2<f64>) -> (usize, usize) {
        let c = ((p.x - origin.x) / cell).floor().clamp(0.0, (cols - 1) as f64) as usize;
        let r = ((p.y - origin.y) / cell).floor().clamp(0.0, (rows - 1) as f64) as usize;
        (c, r)
    }

    /// The cell holding `p`, if inside the grid.
    #[inline]
    pub fn cell_of(&self, p: Point2<f64>) -> Option<(usize, usize)> {
        let c = ((p.x - self.origin.x) / self.cell).floor();
        let r = ((p.y - self.origin.y) / self.cell).floor();
        (c >= 0.0 && r >= 0.0 && (c as usize) < self.cols && (r as usize) < self.rows)
            .then_some((c as usize, r as usize))
    }

    /// Walls listed in cell (c, r).
    #[inline]
    pub fn walls_in(&self, c: usize, r: usize) -> &[u32] {
        let k = r * self.cols + c;
        &self.items[self.starts[k] as usize..self.starts[k + 1] as usize]
    }

    /// Walls listed in the cell holding `p` (empty outside the grid).
    #[inline]
    pub fn walls_near(&self, p: Point2<f64>) -> &[u32] {
        match self.cell_of(p) {
            Some((c, r)) => self.walls_in(c, r),
            None => &[],
        }
    }

    /// Inclusive cell range covering the box [lo, hi], clamped to the grid.
    pub fn cell_range(&self, lo: Point2<f64>, hi: Point2<f64>) -> ((usize, usize), (usize, usize)) {
        (
            Self::clamp_cell(self.origin, self.cell, self.cols, self.rows, lo),
            Self::clamp_cell(self.origin, self.cell, self.cols, self.rows, hi),
        )
    }

    pub fn cell_count(&self) -> usize {
        self.cols * self.rows
    }

    /// Index of cell (c, r) among the grid's `cell_count()` cells.
    #[inline]
    pub fn cell_index(&self, c: usize, r: usize) -> usize {
        r * self.cols + c
    }

    pub fn cols(&self) -> usize {
        self.cols
    }

    pub fn rows(&self) -> usize {
        self.rows
    }

    /// Centre of cell (c, r).
    pub fn cell_centre(&self, c: usize, r: usize) -> Point2<f64> {
        centre_of(self.origin, self.cell, c, r)
    }

    /// Corners of cell (c, r), counter-clockwise from its lowest x and y.
    pub fn cell_corners(&self, c: usize, r: usize) -> [Point2<f64>; 4] {
        let (x, y) = (self.origin.x + c as f64 * self.cell, self.origin.y + r as f64 * self.cell);
        [
            Point2::new(x, y),
            Point2::new(x + self.cell, y),
            Point2::new(x + self.cell, y + self.cell),
            Point2::new(x, y + self.cell),
        ]
    }

    /// Total length of the cells' lists.
    pub fn entries(&self) -> usize {
        self.items.len()
    }
}

/// Centre of cell (c, r) of a grid of cells of side `cell` whose first cell starts at `origin`.
#[inline]
pub(crate) fn centre_of(origin: Point2<f64>, cell: f64, c: usize, r: usize) -> Point2<f64> {
    Point2::new(origin.x + (c as f64 + 0.5) * cell, origin.y + (r as f64 + 0.5) * cell)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::DistanceField;

    /// A map kilometres across, even a long thin one, gets coarser cells instead of more: its
    /// grids stay within their budget and still answer for every point.
    #[test]
    fn grids_over_a_map_kilometres_across_stay_within_their_cell_budget() {
        for walls in [
            vec![Wall::new(0.0, 0.0, 50_000.0, 0.0), Wall::new(0.0, 0.0, 0.0, 30_000.0)],
            // a corridor 200 km long and 2 m wide
            vec![Wall::new(0.0, 0.0, 200_000.0, 0.0), Wall::new(0.0, 2.0, 200_000.0, 2.0)],
        ] {
            let grid = WallGrid::new(&walls, 1.0, 0.5);
            assert!(grid.cell_count() as f64 <= 1.01 * MAX_CELLS, "{} cells", grid.cell_count());
            let p = Point2::new(20_000.0, 0.3);
            assert!(grid.walls_near(p).contains(&0), "the wall 0.3 m away is not listed");
            let field = DistanceField::new(&walls, 0.05, 1.0);
            assert!((field.distance(p) - 0.3).abs() <= field.resolution(), "{}", field.distance(p));
        }
    }
}
