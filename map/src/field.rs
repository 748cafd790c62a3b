//! A truncated distance field: distance from any point to the nearest wall, capped, on a
//! regular grid, with the nearest wall's index. Looking a point up is O(1), so many pose
//! hypotheses can be screened cheaply before the ray-cast cost function ranks the survivors,
//! and refinement finds the wall each scan point lies on without searching.

use crate::bitgrid::Grid;
use crate::flat::{check_len, Flat, FlatError, FlatReader, FlatWriter};
use crate::slab::Slab;
use crate::wall::Wall;
use nalgebra::Point2;

/// A cell of a [`DistanceField`], found once ([`DistanceField::cell_of`]) to read several of
/// its tables at one point.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FieldCell(usize);

#[derive(Clone, Debug)]
pub struct DistanceField {
    origin: Point2<f64>,
    resolution: f64,
    cols: usize,
    rows: usize,
    inverse_resolution: f64,
    cap: f64,
    /// What one unit of `cells` is, metres: `cap / 255`, divided once here rather than at
    /// every lookup.
    quantum: f64,
    /// Distance in units of `cap / 255` (one byte, so the field of a whole floor stays in
    /// cache: screening thousands of poses is bound by these lookups), stored in tiles of
    /// [`TILE`] x [`TILE`] cells (see [`tile_index`]).
    cells: Slab<u8>,
    /// Tiles per row of tiles.
    tile_cols: usize,
    /// The least of `cells` over each block of [`POOL`] x [`POOL`] cells (the last row and
    /// column of blocks may be partial): a lower bound of the distance from a table a
    /// `POOL * POOL`-th of the size, which stays in cache where `cells` of a large map do not.
    pooled: Slab<u8>,
    pooled_cols: usize,
    /// One bit a cell, in the order of `cells`: whether its nearest wall is one [`mark_nearest`](Self::mark_nearest)
    /// marked. Empty until then.
    marked: Slab<u64>,
    /// Nearest wall of each cell's centre, in the order of `cells`.
    nearest: NearestWalls,
}

/// Wall indices of the cells, in 16 bits when the map has fewer than 65535 walls: half the
/// memory, and refinement's lookups are cache misses.
#[derive(Clone, Debug)]
enum NearestWalls {
    /// `u16::MAX`: no wall within the cap.
    Narrow(Slab<u16>),
    /// `u32::MAX`: no wall within the cap.
    Wide(Slab<u32>),
}

/// Side of the blocks of cells [`DistanceField::lower_bound`] reads, in cells.
pub const POOL: usize = 4;

/// Side of the tiles the cells are stored in, in cells: a tile of one-byte distances is one
/// 64-byte cache line. Stored row by row, a point and the point a cell above it lie a whole row
/// of the field apart, a cache miss each once the field outgrows the cache (a map built from a
/// survey of a building: a megabyte and more). The scan points of neighbouring poses, which
/// the screen reads one after the other, fall in the same few tiles. On the map built from
/// the csail CARMEN log (a 1.3 MB field), screening went from 5.9-6.3 to 5.3-5.7 ms a scan and
/// refinement from 484-503 to 440-462 us; a field that fits in the cache reads as fast either way.
pub const TILE: usize = 8;

/// Where cell (`c`, `r`) is stored, in a field `tile_cols` tiles wide.
#[inline]
fn tile_index(c: usize, r: usize, tile_cols: usize) -> usize {
    (((r / TILE) * tile_cols + c / TILE) * TILE + r % TILE) * TILE + c % TILE
}

/// How many cells a field of `cols` x `rows` stores: whole tiles (see [`tile_index`]).
fn stored_cells(cols: usize, rows: usize) -> usize {
    cols.div_ceil(TILE) * rows.div_ceil(TILE) * TILE * TILE
}

/// How many blocks of [`POOL`] x [`POOL`] cells a field of `cols` x `rows` pools.
fn pooled_blocks(cols: usize, rows: usize) -> usize {
    cols.div_ceil(POOL) * rows.div_ceil(POOL)
}

/// Largest number of cells a field may have before its resolution is coarsened.
const MAX_CELLS: f64 = crate::limits::FIELD_CELLS as f64;

impl DistanceField {
    /// Builds the field at `resolution` (coarsened if the map is very large), with distances
    /// capped at `cap` metres.
    pub fn new(walls: &[Wall], resolution: f64, cap: f64) -> Self {
        let (lo, hi) = crate::wall::bounds_of(walls);
        let (w, h) = (hi.x - lo.x + 2.0 * cap, hi.y - lo.y + 2.0 * cap);
        let resolution = crate::grid::coarsened(resolution, w, h, MAX_CELLS);
        let origin = Point2::new(lo.x - cap, lo.y - cap);
        let cols = (w / resolution).ceil().max(1.0) as usize;
        let rows = (h / resolution).ceil().max(1.0) as usize;
        let tile_cols = cols.div_ceil(TILE);
        // whole tiles: the cells past the last row and column are never read (`cell` says
        // they lie outside) and say no wall is near
        let stored = stored_cells(cols, rows);
        let mut cells = vec![u8::MAX; stored];
        let mut nearest = vec![u32::MAX; stored];
        let scale = 255.0 / cap;
        for (k, wall) in walls.iter().enumerate() {
            let c0 = (((wall.a.x.min(wall.b.x) - cap - origin.x) / resolution).floor().max(0.0)) as usize;
            let r0 = (((wall.a.y.min(wall.b.y) - cap - origin.y) / resolution).floor().max(0.0)) as usize;
            let c1 = ((((wall.a.x.max(wall.b.x) + cap - origin.x) / resolution).ceil()) as usize).min(cols - 1);
            let r1 = ((((wall.a.y.max(wall.b.y) + cap - origin.y) / resolution).ceil()) as usize).min(rows - 1);
            for r in r0..=r1 {
                for c in c0..=c1 {
                    let centre =
                        Point2::new(origin.x + (c as f64 + 0.5) * resolution, origin.y + (r as f64 + 0.5) * resolution);
                    let d = wall.closest(centre).0;
                    if d < cap {
                        let q = (d * scale) as u8;
                        let i = tile_index(c, r, tile_cols);
                        if q < cells[i] {
                            cells[i] = q;
                            nearest[i] = k as u32;
                        }
                    }
                }
            }
        }
        let nearest = if walls.len() < u16::MAX as usize {
            NearestWalls::Narrow(nearest.iter().map(|&k| k.min(u16::MAX as u32) as u16).collect::<Vec<_>>().into())
        } else {
            NearestWalls::Wide(nearest.into())
        };
        let pooled_cols = cols.div_ceil(POOL);
        let mut pooled = vec![u8::MAX; pooled_blocks(cols, rows)];
        for r in 0..rows {
            for c in 0..cols {
                let b = (r / POOL) * pooled_cols + c / POOL;
                pooled[b] = pooled[b].min(cells[tile_index(c, r, tile_cols)]);
            }
        }
        Self::of_parts(
            Grid { origin, cell: resolution, cols, rows },
            cap,
            cells.into(),
            pooled.into(),
            Slab::default(),
            nearest,
        )
    }

    /// A field from its stored parts, with what follows from them.
    fn of_parts(
        grid: Grid,
        cap: f64,
        cells: Slab<u8>,
        pooled: Slab<u8>,
        marked: Slab<u64>,
        nearest: NearestWalls,
    ) -> Self {
        let Grid { origin, cell: resolution, cols, rows } = grid;
        DistanceField {
            origin,
            resolution,
            inverse_resolution: 1.0 / resolution,
            cols,
            rows,
            cap,
            quantum: cap / 255.0,
            cells,
            tile_cols: cols.div_ceil(TILE),
            pooled,
            pooled_cols: cols.div_ceil(POOL),
            marked,
            nearest,
        }
    }

    /// Marks the cells whose nearest wall (if any within the cap) `marked` says yes to, for
    /// [`marked_nearest_wall`](Self::marked_nearest_wall): a table of one bit a cell, where the
    /// nearest walls take two or four bytes. A caller that only needs the nearest wall when it
    /// has some property most walls lack reads the bit first, and skips most lookups of a large
    /// map's nearest walls.
    pub fn mark_nearest(&mut self, marked: impl Fn(u32) -> bool) {
        let cells = self.cells.len();
        let mut bits = vec![0u64; cells.div_ceil(64)];
        for i in 0..cells {
            if self.nearest_of(i).is_some_and(&marked) {
                bits[i / 64] |= 1 << (i % 64);
            }
        }
        self.marked = bits.into();
    }

    /// [`nearest_wall`](Self::nearest_wall) when that wall is marked ([`mark_nearest`]); `None`
    /// when it is not, outside the field, and before any marking. The cell is found once, and
    /// the nearest walls are read only for a marked cell.
    ///
    /// [`mark_nearest`]: Self::mark_nearest
    #[inline]
    pub fn marked_nearest_wall(&self, p: Point2<f64>) -> Option<u32> {
        self.marked_nearest_wall_of(FieldCell(self.index(p)?))
    }

    /// The cell holding `p`, if it lies in the field: to read several of its tables at one
    /// point ([`distance_of`](Self::distance_of), [`marked_nearest_wall_of`](Self::marked_nearest_wall_of))
    /// finding the cell once.
    #[inline]
    pub fn cell_of(&self, p: Point2<f64>) -> Option<FieldCell> {
        self.index(p).map(FieldCell)
    }

    /// [`distance`](Self::distance) at a cell [`cell_of`](Self::cell_of) found (`cap` for none).
    #[inline]
    pub fn distance_of(&self, cell: Option<FieldCell>) -> f64 {
        match cell {
            Some(FieldCell(i)) => self.cells[i] as f64 * self.quantum,
            None => self.cap,
        }
    }

    /// [`marked_nearest_wall`](Self::marked_nearest_wall) at a cell [`cell_of`](Self::cell_of) found.
    #[inline]
    pub fn marked_nearest_wall_of(&self, FieldCell(i): FieldCell) -> Option<u32> {
        let marked = self.marked.get(i / 64).is_some_and(|b| b >> (i % 64) & 1 == 1);
        if marked {
            self.nearest_of(i)
        } else {
            None
        }
    }

    /// A lower bound of [`distance`](Self::distance) at `p`: the least distance over the
    /// [`POOL`] x [`POOL`] block of cells holding `p` (`cap` outside the field, as there).
    #[inline]
    pub fn lower_bound(&self, p: Point2<f64>) -> f64 {
        match self.cell(p) {
            Some((c, r)) => self.pooled[(r / POOL) * self.pooled_cols + c / POOL] as f64 * self.quantum,
            None => self.cap,
        }
    }

    /// The column and row of the cell holding `p`, if it lies in the field.
    #[inline]
    fn cell(&self, p: Point2<f64>) -> Option<(usize, usize)> {
        let c = ((p.x - self.origin.x) * self.inverse_resolution) as isize;
        let r = ((p.y - self.origin.y) * self.inverse_resolution) as isize;
        if p.x < self.origin.x || p.y < self.origin.y || c as usize >= self.cols || r as usize >= self.rows {
            return None;
        }
        Some((c as usize, r as usize))
    }

    #[inline]
    fn index(&self, p: Point2<f64>) -> Option<usize> {
        self.cell(p).map(|(c, r)| tile_index(c, r, self.tile_cols))
    }

    /// The wall nearest to the centre of cell `i`, if any lies within the cap.
    #[inline]
    fn nearest_of(&self, i: usize) -> Option<u32> {
        match &self.nearest {
            NearestWalls::Narrow(n) => Some(n[i]).filter(|&w| w != u16::MAX).map(u32::from),
            NearestWalls::Wide(n) => Some(n[i]).filter(|&w| w != u32::MAX),
        }
    }

    /// The wall nearest to the centre of the cell holding `p`, if any lies within the cap.
    #[inline]
    pub fn nearest_wall(&self, p: Point2<f64>) -> Option<u32> {
        self.nearest_of(self.index(p)?)
    }

    /// Distance from `p` to the nearest wall, capped (and `cap` outside the field).
    #[inline]
    pub fn distance(&self, p: Point2<f64>) -> f64 {
        self.distance_of(self.cell_of(p))
    }

    pub fn cap(&self) -> f64 {
        self.cap
    }

    pub fn resolution(&self) -> f64 {
        self.resolution
    }
}

impl DistanceField {
    /// Whether every nearest wall the cells name is one of `walls` walls: for a field read
    /// from a block, whose walls are another array of it.
    pub fn check_walls(&self, walls: usize) -> Result<(), FlatError> {
        let named = match &self.nearest {
            NearestWalls::Narrow(n) => n.iter().position(|&k| k != u16::MAX && k as usize >= walls),
            NearestWalls::Wide(n) => n.iter().position(|&k| k != u32::MAX && k as usize >= walls),
        };
        match named {
            None => Ok(()),
            Some(i) => Err(FlatError::new(format!("distance field: cell {i} names a wall past the {walls} there are"))),
        }
    }
}

impl Flat for DistanceField {
    fn put(&self, w: &mut FlatWriter) {
        Grid { origin: self.origin, cell: self.resolution, cols: self.cols, rows: self.rows }.put(w);
        w.put_f64(self.cap);
        self.cells.put(w);
        self.pooled.put(w);
        self.marked.put(w);
        match &self.nearest {
            NearestWalls::Narrow(n) => {
                w.put_u64(16);
                n.put(w);
            }
            NearestWalls::Wide(n) => {
                w.put_u64(32);
                n.put(w);
            }
        }
    }
    fn take(r: &mut FlatReader<'_>) -> Result<Self, FlatError> {
        let Grid { origin, cell: resolution, cols, rows } = Grid::take(r)?;
        let cap = r.take_finite("distance field cap")?;
        if cap <= 0.0 {
            return Err(FlatError::new(format!("distance field cap {cap}")));
        }
        let stored = stored_cells(cols, rows);
        let cells: Slab<u8> = Slab::take(r)?;
        check_len("distance field cells", cells.len(), stored)?;
        let pooled: Slab<u8> = Slab::take(r)?;
        check_len("distance field blocks", pooled.len(), pooled_blocks(cols, rows))?;
        let marked: Slab<u64> = Slab::take(r)?;
        if !marked.is_empty() {
            check_len("distance field marks", marked.len(), stored.div_ceil(64))?;
        }
        let nearest = match r.take_u64("distance field nearest walls")? {
            16 => NearestWalls::Narrow(Slab::take(r)?),
            32 => NearestWalls::Wide(Slab::take(r)?),
            bits => return Err(FlatError::new(format!("distance field: nearest walls in {bits} bits"))),
        };
        let nearest_len = match &nearest {
            NearestWalls::Narrow(n) => n.len(),
            NearestWalls::Wide(n) => n.len(),
        };
        check_len("distance field nearest walls", nearest_len, stored)?;
        Ok(Self::of_parts(Grid { origin, cell: resolution, cols, rows }, cap, cells, pooled, marked, nearest))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// Every cell of a field of any shape has its own place among the stored cells.
    #[test]
    fn tiles_store_each_cell_once() {
        for (cols, rows) in [(1usize, 1usize), (7, 3), (8, 8), (9, 17), (30, 5)] {
            let tile_cols = cols.div_ceil(TILE);
            let stored = stored_cells(cols, rows);
            let mut seen = vec![false; stored];
            for r in 0..rows {
                for c in 0..cols {
                    let i = tile_index(c, r, tile_cols);
                    assert!(i < stored && !seen[i], "cell ({c}, {r}) of {cols} x {rows}");
                    seen[i] = true;
                }
            }
        }
    }

    proptest! {
        #[test]
        /// Within half a cell diagonal, plus one quantum of the byte encoding.
        fn field_is_within_a_cell_of_the_exact_distance(x in -3.0f64..3.0, y in -3.0f64..3.0) {
            let walls = vec![Wall::new(-1.0, 0.0, 1.0, 0.5), Wall::new(0.0, -2.0, 0.0, -1.0)];
            let f = DistanceField::new(&walls, 0.05, 1.0);
            let p = Point2::new(x, y);
            let exact = walls.iter().map(|w| w.closest(p).0).fold(f64::INFINITY, f64::min).min(1.0);
            prop_assert!((f.distance(p) - exact).abs() <= 0.05 * std::f64::consts::SQRT_2 / 2.0 + 1.0 / 255.0 + 1e-9);
        }

        #[test]
        /// The lower bound never exceeds the distance, and is the least distance over the
        /// points of the block of cells around: what the distance reads somewhere within
        /// `POOL` cells.
        fn the_lower_bound_is_the_least_distance_of_the_block(x in -3.5f64..3.5, y in -3.5f64..3.5) {
            let walls = vec![Wall::new(-1.0, 0.0, 1.0, 0.5), Wall::new(0.0, -2.0, 0.0, -1.0)];
            let f = DistanceField::new(&walls, 0.05, 1.0);
            let p = Point2::new(x, y);
            let bound = f.lower_bound(p);
            prop_assert!(bound <= f.distance(p));
            // some cell within the block reads the bound
            let step = f.resolution();
            let reach = (POOL as f64) * step;
            let mut least = f64::INFINITY;
            let n = 2 * POOL as i64;
            for i in -n..=n {
                for j in -n..=n {
                    let q = Point2::new(x + i as f64 * step, y + j as f64 * step);
                    if (q.x - x).abs() <= reach && (q.y - y).abs() <= reach {
                        least = least.min(f.distance(q));
                    }
                }
            }
            prop_assert!(least <= bound + 1e-12, "least {} bound {}", least, bound);
        }

        #[test]
        /// A cell is marked exactly when its nearest wall is one the caller marked; nothing is
        /// marked before marking, or outside the field.
        fn a_cell_is_marked_when_its_nearest_wall_is(x in -3.5f64..3.5, y in -3.5f64..3.5) {
            let walls = vec![Wall::new(-1.0, 0.0, 1.0, 0.5), Wall::new(0.0, -2.0, 0.0, -1.0)];
            let mut f = DistanceField::new(&walls, 0.05, 1.0);
            let p = Point2::new(x, y);
            prop_assert_eq!(f.marked_nearest_wall(p), None);
            f.mark_nearest(|k| k == 1);
            prop_assert_eq!(f.marked_nearest_wall(p), f.nearest_wall(p).filter(|&k| k == 1));
            prop_assert_eq!(f.marked_nearest_wall(Point2::new(x + 100.0, y)), None);
        }

        #[test]
        /// A cell found once reads what the point itself reads, in and out of the field.
        fn a_cell_found_once_reads_as_its_point(x in -4.5f64..4.5, y in -4.5f64..4.5) {
            let walls = vec![Wall::new(-1.0, 0.0, 1.0, 0.5), Wall::new(0.0, -2.0, 0.0, -1.0)];
            let mut f = DistanceField::new(&walls, 0.05, 1.0);
            f.mark_nearest(|k| k == 0);
            let p = Point2::new(x, y);
            let cell = f.cell_of(p);
            prop_assert_eq!(f.distance_of(cell).to_bits(), f.distance(p).to_bits());
            prop_assert_eq!(cell.and_then(|c| f.marked_nearest_wall_of(c)), f.marked_nearest_wall(p));
        }

        #[test]
        /// The named wall is nearest to the cell's centre: at most a cell diagonal farther from
        /// the point than the nearest wall is; none only when every wall is beyond the cap.
        fn nearest_wall_is_nearest_within_a_cell(x in -3.0f64..3.0, y in -3.0f64..3.0) {
            let walls = vec![Wall::new(-1.0, 0.0, 1.0, 0.5), Wall::new(0.0, -2.0, 0.0, -1.0)];
            let f = DistanceField::new(&walls, 0.05, 1.0);
            let p = Point2::new(x, y);
            let exact = walls.iter().map(|w| w.closest(p).0).fold(f64::INFINITY, f64::min);
            let diagonal = 0.05 * std::f64::consts::SQRT_2;
            match f.nearest_wall(p) {
                Some(k) => prop_assert!(walls[k as usize].closest(p).0 <= exact + diagonal + 1e-9),
                None => prop_assert!(exact >= 1.0 - diagonal),
            }
        }
    }
}
