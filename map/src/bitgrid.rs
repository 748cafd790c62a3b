//! A grid of square cells over a rectangle of the map, and a raster of one bit a cell on it:
//! what [`crate::Outside`] and [`crate::SeenFree`] keep, and how [`crate::FreeSpace`] finds a
//! point's cell. Its cell arithmetic (`cell_holding`, `centre_of`) is also the wall
//! grids' ([`crate::grid`]).

use crate::flat::{check_len, Flat, FlatError, FlatReader, FlatWriter};
use crate::slab::Slab;
use nalgebra::Point2;

/// `cols` x `rows` cells of `cell` metres, the first cell's corner at `origin`, numbered row by
/// row.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Grid {
    pub origin: Point2<f64>,
    pub cell: f64,
    pub cols: usize,
    pub rows: usize,
}

impl Grid {
    /// The number of the cell holding `q`, `None` off the grid (or for NaN coordinates).
    #[inline]
    pub fn index(&self, q: Point2<f64>) -> Option<usize> {
        let (c, r) = cell_holding(self.origin, self.cell, (self.cols, self.rows), q)?;
        Some(r * self.cols + c)
    }

    /// Centre of cell (c, r).
    pub fn centre(&self, c: usize, r: usize) -> Point2<f64> {
        centre_of(self.origin, self.cell, c, r)
    }

    pub fn cells(&self) -> usize {
        self.cols * self.rows
    }

    /// Points from `from` to `to` every half cell or less, both ends included: no cell the
    /// segment crosses is missed by more than a corner. Just `from` for a segment of no
    /// length; none when the segment is not finite.
    pub fn points_along(&self, from: Point2<f64>, to: Point2<f64>) -> impl Iterator<Item = Point2<f64>> {
        let d = to - from;
        let steps = (d.norm() / (0.5 * self.cell)).ceil();
        // a segment of 10^9 half cells is no beam or wall of a map; stop there
        let steps = steps.is_finite().then(|| steps.min(1e9) as usize);
        steps
            .into_iter()
            .flat_map(move |n| (0..=n).map(move |k| if n == 0 { from } else { from + d * (k as f64 / n as f64) }))
    }

    /// The cells of [`points_along`](Self::points_along) that lie on the grid (a cell may come
    /// more than once).
    pub fn cells_along(&self, from: Point2<f64>, to: Point2<f64>) -> impl Iterator<Item = usize> + '_ {
        self.points_along(from, to).filter_map(|q| self.index(q))
    }
}

/// Column and row of the cell holding `p` in a grid of `cols` x `rows` cells of side `cell`
/// whose first cell starts at `origin`; `None` off the grid (or for NaN coordinates).
#[inline]
pub(crate) fn cell_holding(
    origin: Point2<f64>,
    cell: f64,
    (cols, rows): (usize, usize),
    p: Point2<f64>,
) -> Option<(usize, usize)> {
    // from 0 up, truncation is the floor (no library floor, which baseline x86-64 calls out of
    // line); below 0 (or NaN) the point is off the grid either way
    let c = (p.x - origin.x) / cell;
    let r = (p.y - origin.y) / cell;
    (c >= 0.0 && r >= 0.0 && (c as usize) < cols && (r as usize) < rows).then_some((c as usize, r as usize))
}

/// Centre of cell (c, r) of a grid of cells of side `cell` whose first cell starts at `origin`.
#[inline]
pub(crate) fn centre_of(origin: Point2<f64>, cell: f64, c: usize, r: usize) -> Point2<f64> {
    Point2::new(origin.x + (c as f64 + 0.5) * cell, origin.y + (r as f64 + 0.5) * cell)
}

/// One bit per cell of a [`Grid`]: bit i of word i / 64 for cell i; the bits past the last
/// cell stay clear.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct BitGrid {
    pub grid: Grid,
    pub bits: Slab<u64>,
}

impl BitGrid {
    /// Every bit clear.
    pub fn clear(grid: Grid) -> Self {
        BitGrid { grid, bits: vec![0; grid.cells().div_ceil(64)].into() }
    }

    #[inline]
    pub fn get(&self, i: usize) -> bool {
        self.bits[i / 64] & (1 << (i % 64)) != 0
    }

    #[inline]
    pub fn set(&mut self, i: usize) {
        self.bits.to_mut()[i / 64] |= 1 << (i % 64);
    }

    /// The bit of the cell holding `q`; `None` off the grid.
    #[inline]
    pub fn at(&self, q: Point2<f64>) -> Option<bool> {
        self.grid.index(q).map(|i| self.get(i))
    }

    /// Every bit flipped (the padding stays clear).
    pub fn inverted(mut self) -> Self {
        for w in self.bits.to_mut().iter_mut() {
            *w = !*w;
        }
        self.clear_padding();
        self
    }

    /// Clears the bits past the last cell.
    pub fn clear_padding(&mut self) {
        let cells = self.grid.cells();
        if !cells.is_multiple_of(64) {
            if let Some(last) = self.bits.to_mut().last_mut() {
                *last &= (1u64 << (cells % 64)) - 1;
            }
        }
    }
}

impl Flat for Grid {
    fn put(&self, w: &mut FlatWriter) {
        w.put_f64(self.origin.x);
        w.put_f64(self.origin.y);
        w.put_f64(self.cell);
        w.put_usize(self.cols);
        w.put_usize(self.rows);
    }
    fn take(r: &mut FlatReader<'_>) -> Result<Self, FlatError> {
        let origin = Point2::new(r.take_finite("grid origin")?, r.take_finite("grid origin")?);
        let cell = r.take_finite("grid cell")?;
        let (cols, rows) = (r.take_usize("grid columns")?, r.take_usize("grid rows")?);
        if cell <= 0.0 || cols.checked_mul(rows).is_none_or(|n| n == usize::MAX) {
            return Err(FlatError::new(format!("a grid of {cols} x {rows} cells of {cell} m")));
        }
        Ok(Grid { origin, cell, cols, rows })
    }
}

impl Flat for BitGrid {
    fn put(&self, w: &mut FlatWriter) {
        self.grid.put(w);
        self.bits.put(w);
    }
    fn take(r: &mut FlatReader<'_>) -> Result<Self, FlatError> {
        let grid = Grid::take(r)?;
        let bits = Slab::take(r)?;
        check_len("raster bits", bits.len(), grid.cells().div_ceil(64))?;
        Ok(BitGrid { grid, bits })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// What a point's cell is, by the letter: the floor of its offset in cells, on the grid.
    fn cell_by_the_floor(
        origin: Point2<f64>,
        cell: f64,
        (cols, rows): (usize, usize),
        p: Point2<f64>,
    ) -> Option<(usize, usize)> {
        let (c, r) = (((p.x - origin.x) / cell).floor(), ((p.y - origin.y) / cell).floor());
        (c >= 0.0 && r >= 0.0 && c < cols as f64 && r < rows as f64).then_some((c as usize, r as usize))
    }

    fn coordinate() -> impl Strategy<Value = f64> {
        prop_oneof![
            -50.0..150.0f64,
            Just(f64::NAN),
            Just(f64::INFINITY),
            Just(f64::NEG_INFINITY),
            Just(-0.0),
            Just(1e300),
            Just(-1e300),
            Just(9.3e18),
        ]
    }

    proptest! {
        #[test]
        fn a_point_lies_in_the_cell_its_floor_names(
            ox in -10.0..10.0f64,
            oy in -10.0..10.0f64,
            cell in 0.01..2.0f64,
            cols in 1usize..400,
            rows in 1usize..400,
            x in coordinate(),
            y in coordinate(),
        ) {
            let origin = Point2::new(ox, oy);
            let p = Point2::new(x, y);
            prop_assert_eq!(cell_holding(origin, cell, (cols, rows), p), cell_by_the_floor(origin, cell, (cols, rows), p));
        }
    }

    #[test]
    fn a_point_on_a_cells_edge_lies_in_the_cell_it_starts() {
        let origin = Point2::new(-1.0, -2.0);
        assert_eq!(cell_holding(origin, 0.25, (10, 10), Point2::new(-1.0, -2.0)), Some((0, 0)));
        assert_eq!(cell_holding(origin, 0.25, (10, 10), Point2::new(-0.5, -1.75)), Some((2, 1)));
        assert_eq!(cell_holding(origin, 0.25, (10, 10), Point2::new(1.5, -2.0)), None);
        assert_eq!(cell_holding(origin, 0.25, (10, 10), Point2::new(-1.0 - 1e-12, -2.0)), None);
    }
}
