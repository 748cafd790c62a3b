//! A uniform grid over the map whose cells list the walls within a margin of them: the spatial
//! index behind ray casting and nearest-wall queries.

use crate::bitgrid::{cell_holding, centre_of, Grid};
use crate::flat::{check_indices, Flat, FlatError, FlatReader, FlatWriter};
use crate::slab::Slab;
use crate::wall::Wall;
use nalgebra::{Point2, Vector2};

/// Most cells a [`WallGrid`] has: its cells are coarsened beyond that (a map kilometres
/// across), which makes lists longer but keeps every query's answer.
const MAX_CELLS: f64 = crate::limits::WALL_GRID_CELLS as f64;

/// `cell`, coarsened as needed so that a grid over `width` x `height` metres has at most about
/// `max_cells` cells, and at most that many along either side whatever its shape.
pub fn coarsened(cell: f64, width: f64, height: f64, max_cells: f64) -> f64 {
    cell.max((width * height / max_cells).sqrt()).max(width.max(height) / max_cells)
}

#[derive(Clone, Debug)]
pub struct WallGrid {
    /// The cells, and the margin they list walls within.
    frame: ReachFrame,
    /// Start of each cell's run in `items` (CSR layout, `cols * rows + 1` entries).
    starts: Slab<u32>,
    items: Slab<u32>,
    /// Per cell, how many cells away (along x, y or a diagonal: the Chebyshev distance) the
    /// nearest cell that lists a wall lies, at most 255: 0 for a cell that lists one. A ray in
    /// a cell of clearance k crosses no wall before it leaves the square of k - 1 cells either
    /// side of it ([`march_walls`](Self::march_walls)).
    clear: Slab<u8>,
}

/// A march jumps across the empty square about a cell from this clearance on: a smaller square
/// is crossed in about as few cell steps as the jump costs.
const JUMP_CLEARANCE: u8 = 3;

/// The Chebyshev distance, in cells, from each cell of a `cols` x `rows` grid to the nearest
/// cell for which `occupied` holds, at most 255 (255 everywhere when none is): two passes of
/// the eight-neighbour chamfer, which is exact for this distance.
fn clearance(cols: usize, rows: usize, occupied: impl Fn(usize) -> bool) -> Vec<u8> {
    let mut d: Vec<u8> = (0..cols * rows).map(|k| if occupied(k) { 0 } else { u8::MAX }).collect();
    let at = |c: usize, r: usize| r * cols + c;
    for r in 0..rows {
        for c in 0..cols {
            let mut v = d[at(c, r)];
            if c > 0 {
                v = v.min(d[at(c - 1, r)].saturating_add(1));
            }
            if r > 0 {
                for cc in c.saturating_sub(1)..=(c + 1).min(cols - 1) {
                    v = v.min(d[at(cc, r - 1)].saturating_add(1));
                }
            }
            d[at(c, r)] = v;
        }
    }
    for r in (0..rows).rev() {
        for c in (0..cols).rev() {
            let mut v = d[at(c, r)];
            if c + 1 < cols {
                v = v.min(d[at(c + 1, r)].saturating_add(1));
            }
            if r + 1 < rows {
                for cc in c.saturating_sub(1)..=(c + 1).min(cols - 1) {
                    v = v.min(d[at(cc, r + 1)].saturating_add(1));
                }
            }
            d[at(c, r)] = v;
        }
    }
    d
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
        let frame = ReachFrame::covering(walls, cell, margin, pad);
        let ReachFrame { origin, cell, cols, rows, .. } = frame;
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
                    if frame.lists(w, c, r) {
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
        let clear = clearance(cols, rows, |k| starts[k + 1] > starts[k]);
        WallGrid { frame, starts: starts.into(), items: items.into(), clear: clear.into() }
    }

    fn clamp_cell(origin: Point2<f64>, cell: f64, cols: usize, rows: usize, p: Point2<f64>) -> (usize, usize) {
        // `as` saturates (a negative or NaN index is 0) and truncates, which is the floor from 0
        // up: no library floor, which baseline x86-64 calls out of line
        let c = (((p.x - origin.x) / cell) as usize).min(cols - 1);
        let r = (((p.y - origin.y) / cell) as usize).min(rows - 1);
        (c, r)
    }

    /// The cell holding `p`, if inside the grid.
    #[inline]
    pub fn cell_of(&self, p: Point2<f64>) -> Option<(usize, usize)> {
        self.frame.cell_of(p)
    }

    /// Walls listed in cell (c, r).
    #[inline]
    pub fn walls_in(&self, c: usize, r: usize) -> &[u32] {
        let k = r * self.frame.cols + c;
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
            Self::clamp_cell(self.frame.origin, self.frame.cell, self.frame.cols, self.frame.rows, lo),
            Self::clamp_cell(self.frame.origin, self.frame.cell, self.frame.cols, self.frame.rows, hi),
        )
    }

    pub fn cell_count(&self) -> usize {
        self.frame.cell_count()
    }

    /// Index of cell (c, r) among the grid's `cell_count()` cells.
    #[inline]
    pub fn cell_index(&self, c: usize, r: usize) -> usize {
        self.frame.cell_index(c, r)
    }

    pub fn cols(&self) -> usize {
        self.frame.cols
    }

    pub fn rows(&self) -> usize {
        self.frame.rows
    }

    /// Centre of cell (c, r).
    pub fn cell_centre(&self, c: usize, r: usize) -> Point2<f64> {
        centre_of(self.frame.origin, self.frame.cell, c, r)
    }

    /// Corners of cell (c, r), counter-clockwise from its lowest x and y.
    pub fn cell_corners(&self, c: usize, r: usize) -> [Point2<f64>; 4] {
        self.frame.cell_corners(c, r)
    }

    /// How many cells list a wall.
    pub fn listing_cells(&self) -> usize {
        self.clear.iter().filter(|&&k| k == 0).count()
    }

    /// Total length of the cells' lists.
    pub fn entries(&self) -> usize {
        self.items.len()
    }

    /// Total length of the lists of the cells from `(c0, r0)` to `(c1, r1)` inclusive: a wall
    /// in several of them counts in each.
    pub fn entries_within(&self, (c0, r0): (usize, usize), (c1, r1): (usize, usize)) -> usize {
        (r0..=r1)
            .map(|r| (self.starts[self.cell_index(c1, r) + 1] - self.starts[self.cell_index(c0, r)]) as usize)
            .sum()
    }

    /// Visits, in order, the cells the ray `from + t dir` (t >= 0) crosses within the grid,
    /// each with the `t` at which the ray leaves it, until `visit` returns false or the ray has
    /// gone past `max_t` or out of the grid (Amanatides and Woo's traversal).
    pub fn march(
        &self,
        from: Point2<f64>,
        dir: Vector2<f64>,
        max_t: f64,
        mut visit: impl FnMut(usize, usize, f64) -> bool,
    ) {
        let Some((enter, _)) = self.clip(from, dir, max_t) else { return };
        let mut ray = Traversal::at(&self.frame, from, dir, enter);
        loop {
            let exit = ray.exit();
            if !visit(ray.c as usize, ray.r as usize, exit) || exit > max_t || !ray.advance() {
                return;
            }
        }
    }

    /// Where the ray `from + t dir` is inside the grid's box, `t` in `[enter, leave]` with
    /// `leave` at most `max_t`; `None` when nowhere (or the ray is not finite).
    fn clip(&self, from: Point2<f64>, dir: Vector2<f64>, max_t: f64) -> Option<(f64, f64)> {
        let f = &self.frame;
        let size = Vector2::new(f.cols as f64, f.rows as f64) * f.cell;
        let (mut enter, mut leave) = (0.0f64, max_t);
        for axis in 0..2 {
            let (o, d, lo) = (from[axis], dir[axis], f.origin[axis]);
            if d == 0.0 {
                if o < lo || o >= lo + size[axis] {
                    return None;
                }
            } else {
                let (t0, t1) = ((lo - o) / d, (lo + size[axis] - o) / d);
                enter = enter.max(t0.min(t1));
                leave = leave.min(t0.max(t1));
            }
        }
        let finite = from.coords.iter().chain(dir.iter()).all(|v| v.is_finite());
        (finite && !max_t.is_nan() && enter <= leave).then_some((enter, leave))
    }
}

/// Amanatides and Woo's traversal of a grid's cells along a ray: the cell it is in, and per
/// axis the `t` of the next cell boundary, the `t` between boundaries, the step of the cell
/// index and the index at which the ray leaves the grid.
struct Traversal {
    c: isize,
    r: isize,
    next: [f64; 2],
    delta: [f64; 2],
    step: [isize; 2],
    end: [isize; 2],
}

impl Traversal {
    /// The traversal of the ray `from + t dir` from the cell holding its point at `t` (which
    /// lies in the grid, to rounding).
    fn at(f: &ReachFrame, from: Point2<f64>, dir: Vector2<f64>, t: f64) -> Self {
        let start = from + dir * t;
        // `as` saturates and truncates: the floor, clamped to the grid
        let cell_at = |axis: usize, count: usize| (((start[axis] - f.origin[axis]) / f.cell) as usize).min(count - 1);
        let at = [cell_at(0, f.cols) as isize, cell_at(1, f.rows) as isize];
        let counts = [f.cols as isize, f.rows as isize];
        let (mut next, mut delta, mut step, mut end) = ([0.0; 2], [0.0; 2], [0; 2], [0; 2]);
        for k in 0..2 {
            let d = dir[k];
            if d == 0.0 {
                // never crossed, unless neither is: then the ray steps back out of the grid
                (next[k], delta[k], step[k], end[k]) = (f64::INFINITY, f64::INFINITY, -1, -1);
                continue;
            }
            let boundary = f.origin[k] + (at[k] as f64 + if d > 0.0 { 1.0 } else { 0.0 }) * f.cell;
            next[k] = (boundary - from[k]) / d;
            delta[k] = f.cell / d.abs();
            (step[k], end[k]) = if d > 0.0 { (1, counts[k]) } else { (-1, -1) };
        }
        Traversal { c: at[0], r: at[1], next, delta, step, end }
    }

    /// The `t` at which the ray leaves the cell it is in.
    fn exit(&self) -> f64 {
        self.next[0].min(self.next[1])
    }

    /// Steps into the next cell: across the boundary crossed first (x on a tie). False when
    /// that step leaves the grid.
    fn advance(&mut self) -> bool {
        if self.next[1] < self.next[0] {
            self.r += self.step[1];
            self.next[1] += self.delta[1];
            self.r != self.end[1]
        } else {
            self.c += self.step[0];
            self.next[0] += self.delta[0];
            self.c != self.end[0]
        }
    }
}

/// Whether `clear` never claims more room than there is: 0 on every cell `occupied` holds for,
/// and nowhere more than one above any of the eight neighbours. Then along the shortest path
/// from a cell to its nearest occupied cell the clearance falls by at most one a step to 0, so
/// it is at most the true distance and a march never jumps across a wall. (The clearance
/// [`clearance`] makes is exactly the distance; this is what a block read from elsewhere must
/// hold, checked without another array.)
fn clearance_is_safe(cols: usize, rows: usize, occupied: impl Fn(usize) -> bool, clear: &[u8]) -> bool {
    (0..rows).all(|r| {
        (0..cols).all(|c| {
            let v = clear[r * cols + c];
            if occupied(r * cols + c) {
                return v == 0;
            }
            (r.saturating_sub(1)..=(r + 1).min(rows - 1)).all(|r2| {
                (c.saturating_sub(1)..=(c + 1).min(cols - 1)).all(|c2| v <= clear[r2 * cols + c2].saturating_add(1))
            })
        })
    })
}

impl WallGrid {
    /// [`march`](Self::march), visiting only the cells that list a wall: the same cells in the
    /// same order, each with the `t` at which the ray leaves it (to rounding). Across a cell of
    /// clearance `JUMP_CLEARANCE` or more it jumps to where the ray leaves the empty square
    /// about the cell, instead of stepping through its cells one by one: a beam crosses a room
    /// in a few jumps, and the grid's cells can be small enough to list few walls each.
    pub fn march_walls(
        &self,
        from: Point2<f64>,
        dir: Vector2<f64>,
        max_t: f64,
        mut visit: impl FnMut(usize, usize, f64) -> bool,
    ) {
        if dir.x == 0.0 || dir.y == 0.0 {
            // along an axis a jump saves little; the plain march, its empty cells passed over
            self.march(from, dir, max_t, |c, r, exit| self.walls_in(c, r).is_empty() || visit(c, r, exit));
            return;
        }
        let Some((enter, leave)) = self.clip(from, dir, max_t) else { return };
        let mut t = enter;
        loop {
            // (re)start the traversal at `t`
            let mut ray = Traversal::at(&self.frame, from, dir, t);
            // after a jump, one step at least before the next: the landing cell may still be
            // inside the square jumped across, by rounding
            let mut may_jump = false;
            loop {
                let k = self.clear[ray.r as usize * self.frame.cols + ray.c as usize];
                if may_jump && k >= JUMP_CLEARANCE {
                    // the empty square of k - 1 cells either side: where the ray leaves it
                    let half = f64::from(k - 1);
                    t = (ray.next[0] + half * ray.delta[0]).min(ray.next[1] + half * ray.delta[1]);
                    if t > max_t || t >= leave {
                        return;
                    }
                    break;
                }
                may_jump = true;
                let exit = ray.exit();
                if k == 0 && !visit(ray.c as usize, ray.r as usize, exit) || exit > max_t || !ray.advance() {
                    return;
                }
            }
        }
    }
}

/// The cells of a [`WallGrid::covering`] grid, without their lists: each cell's list is made
/// when asked ([`list_of`](Self::list_of)), the same list `covering` would keep. For lists of a
/// long reach (a ray caster's, at a sensor's range), which kept whole hold the map once per
/// cell, and which a process needs for the cells it casts from only.
#[derive(Clone, Copy, Debug)]
pub struct ReachFrame {
    origin: Point2<f64>,
    cell: f64,
    cols: usize,
    rows: usize,
    margin: f64,
    /// Whether the margin spans the grid, so that every cell lists every wall.
    every_cell: bool,
}

impl ReachFrame {
    /// The frame of `WallGrid::covering(walls, cell, margin, pad)`.
    pub fn covering(walls: &[Wall], cell: f64, margin: f64, pad: f64) -> Self {
        let (lo, hi) = crate::wall::bounds_of(walls);
        let cell = coarsened(cell, hi.x - lo.x + 2.0 * pad, hi.y - lo.y + 2.0 * pad, MAX_CELLS);
        let origin = Point2::new(lo.x - pad, lo.y - pad);
        let cols = (((hi.x - lo.x) + 2.0 * pad) / cell).ceil().max(1.0) as usize;
        let rows = (((hi.y - lo.y) + 2.0 * pad) / cell).ceil().max(1.0) as usize;
        ReachFrame::of(origin, cell, (cols, rows), margin)
    }

    /// `cols` x `rows` cells of side `cell` from `origin` listing the walls within `margin`.
    fn of(origin: Point2<f64>, cell: f64, (cols, rows): (usize, usize), margin: f64) -> Self {
        // every wall lies within the grid, so within its diagonal of any point of it
        let every_cell = margin >= (cols as f64 * cell).hypot(rows as f64 * cell);
        ReachFrame { origin, cell, cols, rows, margin, every_cell }
    }

    /// Whether cell (c, r) lists wall `w`: it passes within the margin of the cell.
    #[inline]
    fn lists(&self, w: &Wall, c: usize, r: usize) -> bool {
        let centre = centre_of(self.origin, self.cell, c, r);
        let near = w.closest(centre).0;
        let (margin, half) = (self.margin, 0.5 * self.cell);
        // within the circle round the cell; then exactly, for those it may miss
        near <= margin + self.cell * std::f64::consts::FRAC_1_SQRT_2
            && (near <= margin + half || distance_to_square(w, centre, half) <= margin)
    }

    /// The walls cell (c, r) lists, in the order of `walls`.
    fn listed<'w>(&'w self, walls: &'w [Wall], c: usize, r: usize) -> impl Iterator<Item = u32> + 'w {
        (0..walls.len() as u32).filter(move |&k| self.every_cell || self.lists(&walls[k as usize], c, r))
    }

    /// Writes into `out` the walls cell (c, r) lists, in the order of `walls`.
    pub fn list_of(&self, walls: &[Wall], c: usize, r: usize, out: &mut Vec<u32>) {
        out.clear();
        out.extend(self.listed(walls, c, r));
    }

    /// How many walls cell (c, r) lists.
    pub fn count_of(&self, walls: &[Wall], c: usize, r: usize) -> usize {
        self.listed(walls, c, r).count()
    }

    /// The cell holding `p`, if inside the grid.
    #[inline]
    pub fn cell_of(&self, p: Point2<f64>) -> Option<(usize, usize)> {
        cell_holding(self.origin, self.cell, (self.cols, self.rows), p)
    }

    pub fn cell_count(&self) -> usize {
        self.cols * self.rows
    }

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
}

/// Distance from wall `w` to the square of centre `centre` and half side `half`: 0 when they
/// meet.
fn distance_to_square(w: &Wall, centre: Point2<f64>, half: f64) -> f64 {
    let inside = |p: Point2<f64>| (p.x - centre.x).abs() <= half && (p.y - centre.y).abs() <= half;
    if inside(w.a) || inside(w.b) {
        return 0.0;
    }
    let corners = [
        Point2::new(centre.x - half, centre.y - half),
        Point2::new(centre.x + half, centre.y - half),
        Point2::new(centre.x + half, centre.y + half),
        Point2::new(centre.x - half, centre.y + half),
    ];
    let mut best = f64::INFINITY;
    for k in 0..4 {
        let side = Wall::new(corners[k].x, corners[k].y, corners[(k + 1) % 4].x, corners[(k + 1) % 4].y);
        if segments_cross(w, &side) {
            return 0.0;
        }
        // apart, the nearest points include an end of one of them
        best = best.min(side.closest(w.a).0).min(side.closest(w.b).0).min(w.closest(corners[k]).0);
    }
    best
}

/// Whether two segments meet (touching counts).
fn segments_cross(p: &Wall, q: &Wall) -> bool {
    let (d, e) = (p.b - p.a, q.b - q.a);
    let side = |o: Point2<f64>, v: Vector2<f64>, x: Point2<f64>| v.perp(&(x - o));
    let (s1, s2) = (side(p.a, d, q.a), side(p.a, d, q.b));
    let (t1, t2) = (side(q.a, e, p.a), side(q.a, e, p.b));
    s1 * s2 <= 0.0 && t1 * t2 <= 0.0
}

impl WallGrid {
    /// Whether every wall the cells list is one of `walls` walls: for a grid read from a block,
    /// whose lists index another array of it.
    pub fn check_walls(&self, walls: usize) -> Result<(), FlatError> {
        check_indices("wall grid", &self.items, walls)
    }
}

impl Flat for WallGrid {
    fn put(&self, w: &mut FlatWriter) {
        let ReachFrame { origin, cell, cols, rows, margin, .. } = self.frame;
        Grid { origin, cell, cols, rows }.put(w);
        w.put_f64(margin);
        self.starts.put(w);
        self.items.put(w);
        self.clear.put(w);
    }
    fn take(r: &mut FlatReader<'_>) -> Result<Self, FlatError> {
        let Grid { origin, cell, cols, rows } = Grid::take(r)?;
        let margin = r.take_f64("wall grid margin")?;
        let starts: Slab<u32> = Slab::take(r)?;
        let items: Slab<u32> = Slab::take(r)?;
        let clear: Slab<u8> = Slab::take(r)?;
        crate::flat::check_len("wall grid starts", starts.len(), cols * rows + 1)?;
        crate::flat::check_len("wall grid clearance", clear.len(), cols * rows)?;
        // each cell's run lies within the items, in order: [starts[k], starts[k + 1])
        let ordered = starts.windows(2).all(|p| p[0] <= p[1]) && starts.first() == Some(&0);
        if !ordered || starts.last().map(|&e| e as usize) != Some(items.len()) {
            return Err(FlatError::new("wall grid: its cells' runs do not tile its items"));
        }
        if !clearance_is_safe(cols, rows, |k| starts[k + 1] > starts[k], &clear) {
            return Err(FlatError::new("wall grid: its clearance does not match its cells' lists"));
        }
        Ok(WallGrid { frame: ReachFrame::of(origin, cell, (cols, rows), margin), starts, items, clear })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::field::DistanceField;
    use crate::wall::walls_from_seed as walls_of;
    use proptest::prelude::*;

    /// A frame whose reach spans the grid (a long-range sensor over a small map) lists every
    /// wall in every cell without testing each.
    #[test]
    fn a_reach_across_the_whole_grid_lists_every_wall_everywhere() {
        let walls = [Wall::new(0.0, 0.0, 10.0, 0.0), Wall::new(10.0, 0.0, 10.0, 6.0), Wall::new(3.0, 3.0, 4.0, 5.0)];
        let frame = ReachFrame::covering(&walls, 1.0, 50.0, 1.0);
        assert!(frame.every_cell);
        let mut list = Vec::new();
        for r in 0..frame.rows() {
            for c in 0..frame.cols() {
                frame.list_of(&walls, c, r, &mut list);
                assert_eq!(list, [0, 1, 2]);
            }
        }
        // a reach short of the diagonal lists by cell
        let near = ReachFrame::covering(&walls, 1.0, 2.0, 1.0);
        near.list_of(&walls, 0, 0, &mut list);
        assert!(!near.every_cell && list == [0]);
    }

    proptest! {
        /// A frame's lists, made one cell at a time, are the lists of the grid kept whole.
        #[test]
        fn a_frame_lists_what_the_whole_grid_lists(
            seed in proptest::collection::vec((-5.0f64..5.0, -5.0f64..5.0, -3.2f64..3.2, 0.01f64..4.0), 1..12),
            cell in 0.3f64..1.5, margin in prop_oneof![Just(0.0), 0.0f64..3.0, 20.0f64..40.0],
        ) {
            let walls = walls_of(&seed);
            let grid = WallGrid::covering(&walls, cell, margin, cell);
            let frame = ReachFrame::covering(&walls, cell, margin, cell);
            prop_assert_eq!((frame.cols(), frame.rows()), (grid.cols(), grid.rows()));
            let mut list = Vec::new();
            for r in 0..grid.rows() {
                for c in 0..grid.cols() {
                    frame.list_of(&walls, c, r, &mut list);
                    prop_assert_eq!(&list[..], grid.walls_in(c, r));
                    prop_assert_eq!(frame.cell_corners(c, r), grid.cell_corners(c, r));
                }
            }
        }

        /// The cell of a point is the floor of its offset in cells, outside the grid none;
        /// the march starts in that cell, clamped.
        #[test]
        fn a_points_cell_is_the_floor_of_its_offset(
            x in prop_oneof![-20.0f64..20.0, Just(f64::NAN), Just(-0.0)], y in -20.0f64..20.0,
        ) {
            let grid = WallGrid::new(&[Wall::new(-4.0, -3.0, 5.0, 2.0)], 0.7, 0.0);
            let p = Point2::new(x, y);
            let c = ((x - grid.frame.origin.x) / grid.frame.cell).floor();
            let r = ((y - grid.frame.origin.y) / grid.frame.cell).floor();
            let inside = c >= 0.0 && r >= 0.0 && c < grid.cols() as f64 && r < grid.rows() as f64;
            prop_assert_eq!(grid.cell_of(p), inside.then_some((c as usize, r as usize)));
            let mut first = None;
            grid.march(p, Vector2::new(1.0, 0.0), 100.0, |c, r, _| {
                first = Some((c, r));
                false
            });
            if inside {
                prop_assert_eq!(first, Some((c as usize, r as usize)));
            }
        }

        /// A cell lists every wall within the margin of it, and no wall farther than that.
        #[test]
        fn a_cell_lists_exactly_the_walls_within_its_margin(
            seed in proptest::collection::vec((-5.0f64..5.0, -5.0f64..5.0, -3.2f64..3.2, 0.01f64..4.0), 1..12),
            cell in 0.3f64..1.5, margin in prop_oneof![Just(0.0), 0.0f64..1.0],
        ) {
            let walls = walls_of(&seed);
            let grid = WallGrid::new(&walls, cell, margin);
            for r in 0..grid.rows() {
                for c in 0..grid.cols() {
                    let centre = grid.cell_centre(c, r);
                    let listed = grid.walls_in(c, r);
                    for (k, w) in walls.iter().enumerate() {
                        // the distance from the wall to the cell, sampled finely over the cell
                        let mut near = f64::INFINITY;
                        for i in 0..=20 {
                            for j in 0..=20 {
                                let q = centre + Vector2::new((i as f64 / 20.0 - 0.5) * cell, (j as f64 / 20.0 - 0.5) * cell);
                                near = near.min(w.closest(q).0);
                            }
                        }
                        let sampling = cell / 20.0;
                        if near <= margin - 1e-9 {
                            prop_assert!(listed.contains(&(k as u32)), "wall {} at {} of cell ({}, {}) not listed", k, near, c, r);
                        }
                        if near > margin + sampling {
                            prop_assert!(!listed.contains(&(k as u32)), "wall {} at {} of cell ({}, {}) listed", k, near, c, r);
                        }
                    }
                }
            }
        }

        /// A march visits, in order, every cell the ray crosses up to its end, each with the
        /// distance at which the ray leaves it, from inside the grid or from outside it.
        #[test]
        fn a_march_visits_the_cells_along_the_ray_in_order(
            seed in proptest::collection::vec((-5.0f64..5.0, -5.0f64..5.0, -3.2f64..3.2, 0.01f64..4.0), 1..6),
            x in -12.0f64..12.0, y in -12.0f64..12.0, angle in -3.2f64..3.2, max_t in 0.0f64..30.0,
        ) {
            let walls = walls_of(&seed);
            let grid = WallGrid::new(&walls, 0.7, 0.0);
            let (from, dir) = (Point2::new(x, y), Vector2::new(angle.cos(), angle.sin()));
            let mut visited: Vec<(usize, usize, f64)> = Vec::new();
            grid.march(from, dir, max_t, |c, r, exit| {
                visited.push((c, r, exit));
                true
            });
            for pair in visited.windows(2) {
                prop_assert!(pair[1].2 >= pair[0].2 - 1e-12, "{:?}", pair);
            }
            // every point of the ray inside the grid, up to max_t, lies in a visited cell
            for i in 0..=400 {
                let t = max_t * i as f64 / 400.0;
                let q = from + dir * t;
                if let Some((c, r)) = grid.cell_of(q) {
                    let centre = grid.cell_centre(c, r);
                    // points within rounding of a cell border may be found in the neighbour
                    let border = (q.x - centre.x).abs().max((q.y - centre.y).abs()) > 0.35 - 1e-9;
                    prop_assert!(border || visited.iter().any(|v| (v.0, v.1) == (c, r)), "t {} in cell ({}, {}) not visited", t, c, r);
                }
            }
        }
    }

    proptest! {
        /// A march of the walls' cells visits the cells a plain march visits that list a wall,
        /// in the same order and with the same exits (to rounding), whatever it jumps across;
        /// and stops where the visitor says.
        #[test]
        fn a_march_of_the_walls_visits_the_listing_cells_a_march_visits(
            seed in proptest::collection::vec((-9.0f64..9.0, -9.0f64..9.0, -3.2f64..3.2, 0.01f64..3.0), 1..12),
            x in -12.0f64..12.0, y in -12.0f64..12.0, angle in -3.2f64..3.2, max_t in 0.0f64..40.0,
            cell in 0.1f64..0.6, stop_after in 1usize..6,
        ) {
            let walls = walls_of(&seed);
            let grid = WallGrid::new(&walls, cell, 0.0);
            let (from, dir) = (Point2::new(x, y), Vector2::new(angle.cos(), angle.sin()));
            let mut plain: Vec<(usize, usize, f64)> = Vec::new();
            grid.march(from, dir, max_t, |c, r, exit| {
                if !grid.walls_in(c, r).is_empty() {
                    plain.push((c, r, exit));
                }
                true
            });
            let mut jumped: Vec<(usize, usize, f64)> = Vec::new();
            grid.march_walls(from, dir, max_t, |c, r, exit| {
                jumped.push((c, r, exit));
                true
            });
            prop_assert_eq!(plain.len(), jumped.len(), "{:?} against {:?}", plain, jumped);
            for (p, j) in plain.iter().zip(&jumped) {
                prop_assert_eq!((p.0, p.1), (j.0, j.1));
                prop_assert!((p.2 - j.2).abs() <= 1e-9 * (1.0 + p.2.abs()), "{:?} against {:?}", p, j);
            }
            let mut told = 0;
            grid.march_walls(from, dir, max_t, |_, _, _| {
                told += 1;
                told < stop_after
            });
            prop_assert_eq!(told, stop_after.min(plain.len()));
        }

        /// The clearance is the Chebyshev distance to the nearest listing cell, as counted
        /// cell by cell.
        #[test]
        fn the_clearance_is_the_distance_to_the_nearest_cell_with_a_wall(
            cols in 1usize..14, rows in 1usize..14, occupied in proptest::collection::vec(0usize..200, 0..6),
        ) {
            let full: Vec<bool> = (0..cols * rows).map(|k| occupied.iter().any(|&o| o % (cols * rows) == k)).collect();
            let d = clearance(cols, rows, |k| full[k]);
            for r in 0..rows {
                for c in 0..cols {
                    let nearest = (0..rows)
                        .flat_map(|r2| (0..cols).map(move |c2| (c2, r2)))
                        .filter(|&(c2, r2)| full[r2 * cols + c2])
                        .map(|(c2, r2)| c.abs_diff(c2).max(r.abs_diff(r2)))
                        .min()
                        .map_or(u8::MAX, |m| m.min(255) as u8);
                    prop_assert_eq!(d[r * cols + c], nearest, "cell ({}, {})", c, r);
                }
            }
            prop_assert!(clearance_is_safe(cols, rows, |k| full[k], &d));
            // one more than the distance anywhere below the cap is caught
            if let Some(k) = d.iter().position(|&v| v > 0 && v < u8::MAX) {
                let mut over = d.clone();
                over[k] += 1;
                prop_assert!(!clearance_is_safe(cols, rows, |k| full[k], &over));
            }
        }
    }

    /// A block whose clearance says a cell with a wall is empty is refused: a march would jump
    /// across the wall.
    #[test]
    fn a_block_with_a_false_clearance_is_refused() {
        let grid = WallGrid::new(&[Wall::new(0.0, 0.0, 4.0, 0.0), Wall::new(0.0, 3.0, 4.0, 3.0)], 0.25, 0.0);
        let mut w = FlatWriter::new();
        grid.put(&mut w);
        assert!(WallGrid::take(&mut FlatReader::of_copy(w.bytes())).is_ok());
        let mut bad = grid.clone();
        let clear = bad.clear.to_vec();
        let k = clear.iter().position(|&v| v == 0).expect("a cell lists a wall");
        // a cell with a wall said to be empty, and an empty cell said to be further from a wall
        // than its neighbour's clearance allows
        let empty = clear.iter().position(|&v| v == 1).expect("a cell next to a wall");
        for (cell, value) in [(k, 5), (empty, 3)] {
            let mut wrong = clear.clone();
            wrong[cell] = value;
            bad.clear = wrong.into();
            let mut w = FlatWriter::new();
            bad.put(&mut w);
            let Err(err) = WallGrid::take(&mut FlatReader::of_copy(w.bytes())) else {
                panic!("a false clearance was read")
            };
            assert!(err.to_string().contains("clearance"), "{err}");
        }
    }

    /// A ray with a NaN or infinite start, direction or length visits no cell.
    #[test]
    fn a_march_of_a_bad_ray_visits_nothing() {
        let grid = WallGrid::new(&[Wall::new(0.0, 0.0, 4.0, 0.0)], 1.0, 0.0);
        let (p, d) = (Point2::new(1.0, 0.5), Vector2::new(1.0, 0.0));
        for (from, dir, max_t) in [
            (Point2::new(f64::NAN, 0.5), d, 5.0),
            (p, Vector2::new(f64::NAN, 0.0), 5.0),
            (p, Vector2::new(f64::INFINITY, 0.0), 5.0),
            (p, d, f64::NAN),
        ] {
            let mut visited = 0;
            grid.march(from, dir, max_t, |_, _, _| {
                visited += 1;
                true
            });
            assert_eq!(visited, 0, "{from} {dir} {max_t}");
        }
    }

    /// A ray along an axis visits the cells of its row or column in order, up to the grid's
    /// edge; one with no direction ends too, even with no length limit.
    #[test]
    fn a_march_along_an_axis_or_of_no_direction_ends() {
        let grid = WallGrid::new(&[Wall::new(0.0, 0.0, 4.0, 3.0)], 1.0, 0.0);
        let (cols, rows) = (grid.cols(), grid.rows());
        let from = grid.cell_centre(1, 1);
        for (dir, along) in [((1.0, 0.0), cols - 2), ((-1.0, 0.0), 1), ((0.0, 1.0), rows - 2), ((0.0, -1.0), 1)] {
            let mut visited = Vec::new();
            grid.march(from, Vector2::new(dir.0, dir.1), f64::INFINITY, |c, r, _| {
                visited.push((c, r));
                true
            });
            assert_eq!(visited.len(), along + 1, "{dir:?}: {visited:?}");
            for (k, &(c, r)) in visited.iter().enumerate() {
                let step = |d: f64| {
                    if d > 0.0 {
                        1 + k
                    } else if d < 0.0 {
                        1 - k
                    } else {
                        1
                    }
                };
                assert_eq!((c, r), (step(dir.0), step(dir.1)), "{dir:?}");
            }
        }
        let mut visited = 0;
        grid.march(from, Vector2::zeros(), f64::INFINITY, |_, _, _| {
            visited += 1;
            visited < 1000
        });
        assert!(visited < 1000, "a march with no direction did not end");
    }

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
