//! A survey of an occupancy grid by a virtual laser, so that a grid can be made into walls the
//! way a log is ([`crate::build()`], as `gema2 map build` does) rather than by tracing its
//! cells' faces ([`crate::trace`]).
//!
//! A SLAM grid of a real building draws a wall as a jagged, broken band of cells one to three
//! wide. Traced face by face, it becomes many short walls and spurious corners (21-88 % of the
//! traced length of the CARMEN buildings' grids lies in pieces under 10 cells), which the
//! corner matching of eqs. 5-6 and the slide along long walls cannot use. A laser standing in
//! the grid's free space sees the same band as a line a scan segmenter fits through, as it
//! fits one through a real wall's noisy readings. A pose stands in each square of a lattice
//! over the grid, at its clearest free cell amid known floor ([`VirtualSurvey::poses`]); each
//! casts a full circle of beams to the first occupied cell. A beam that crosses more than a short run of unknown cells or leaves the grid reads
//! nothing: no wall is made up where the grid does not know.

use crate::build::BuildConfig;
use crate::ros::{GridError, OccupancyGrid, ROUGH_SHARE};
use crate::trace::{Cell, Raster, TraceConfig};
use laser::{LaserScan, Pose, ScanGeometry};
use map::WallMap;
use nalgebra::{Isometry2, Point2, Vector2};

/// How the virtual survey stands and looks.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VirtualSurvey {
    /// Metres between the lattice's poses.
    pub spacing: f64,
    /// The least distance (metres) from a pose to any occupied cell.
    pub clearance: f64,
    /// Beams of a scan, evenly over the full circle.
    pub beams: usize,
    /// The virtual laser's range, metres.
    pub range: f64,
    /// Most poses: a larger grid is surveyed on a wider lattice.
    pub max_poses: usize,
    /// The longest run of unknown cells a beam crosses, metres: a SLAM grid leaves cells
    /// unknown between its survey's beams far from the sensor, and beyond a wider unknown
    /// stretch lies what the survey never saw.
    pub unknown: f64,
}

impl Default for VirtualSurvey {
    fn default() -> Self {
        VirtualSurvey { spacing: 1.5, clearance: 0.3, beams: 720, range: 20.0, max_poses: 20_000, unknown: 0.5 }
    }
}

impl VirtualSurvey {
    /// Whether every setting is usable: finite and positive, beams at least 8.
    pub fn is_usable(&self) -> bool {
        let metres = [self.spacing, self.range];
        metres.iter().all(|v| v.is_finite() && *v > 0.0)
            && self.clearance.is_finite()
            && self.clearance >= 0.0
            && self.unknown.is_finite()
            && self.unknown >= 0.0
            && self.beams >= 8
            && self.max_poses > 0
    }

    /// The poses of the survey in the map frame, heading 0: in each square of a lattice, its
    /// free cell farthest from any occupied one, when no occupied cell lies within `clearance`
    /// of it (unknown ones may: a SLAM grid leaves cells unknown among the free ones); the
    /// lattice widened until at most `max_poses` remain. Taking the clearest cell of a square,
    /// not its centre, finds room among clutter a fixed lattice would miss.
    pub fn poses(&self, grid: &OccupancyGrid) -> Vec<Pose> {
        let res = grid.resolution;
        if !(self.is_usable() && res.is_finite() && res > 0.0) || grid.cells.len() != grid.width * grid.height {
            return Vec::new();
        }
        let raster = grid.raster();
        let reach = (self.clearance / res).ceil() as i64;
        let clear = |c: i64, r: i64| {
            (-reach..=reach).all(|dr| {
                (-reach..=reach).all(|dc| {
                    // the cells whose nearest point lies within the clearance
                    let (x, y) = ((dc.abs() - 1).max(0) as f64 * res, (dr.abs() - 1).max(0) as f64 * res);
                    x.hypot(y) > self.clearance || raster.at(c + dc, r + dr) != Some(Cell::Occupied)
                })
            })
        };
        let room = room(grid);
        // free cells in the square of cells within `reach` of each: a pose stands where the grid
        // knows the floor, not on a streak of free cells a lone beam drew into unknown space
        let known = KnownFloor::of(grid, reach);
        // a lattice of at most about `max_poses` free cells from the start, so that a grid of
        // millions of small cells needs a widening or two, not dozens
        let free = f64::from(known.free_cells());
        let mut step = (self.spacing / res).max((free / self.max_poses as f64).sqrt()).max(1.0);
        loop {
            let edges = |n: usize| -> Vec<usize> {
                let squares = (n as f64 / step).ceil() as usize;
                (0..=squares).map(|k| ((k as f64 * step) as usize).min(n)).collect()
            };
            let (xs, ys) = (edges(grid.width), edges(grid.height));
            let mut found = Vec::new();
            for rows in ys.windows(2) {
                for cols in xs.windows(2) {
                    let clearest = (rows[0]..rows[1])
                        .flat_map(|r| (cols[0]..cols[1]).map(move |c| (c, r)))
                        .filter(|&(c, r)| grid.cells[r * grid.width + c] == Cell::Free && known.mostly_free(c, r))
                        .max_by(|a, b| room[a.1 * grid.width + a.0].total_cmp(&room[b.1 * grid.width + b.0]));
                    if let Some((c, r)) = clearest.filter(|&(c, r)| clear(c as i64, r as i64)) {
                        found.push(Point2::new(c as f64 + 0.5, r as f64 + 0.5));
                    }
                }
            }
            if found.len() <= self.max_poses {
                return found
                    .into_iter()
                    .map(|p| Isometry2::new(grid.corner(p.x, p.y).coords, grid.origin[2]))
                    .collect();
            }
            step *= 1.25;
        }
    }

    /// What the virtual laser at `pose` (map frame) reads: `beams` beams over the full circle
    /// from the pose's heading, each to where it enters the first occupied cell plus half a
    /// cell (a surface lies anywhere in the cell it marks); `range` (no return) for a beam that
    /// meets an unknown cell, leaves the grid or reaches no occupied cell within `range`.
    pub fn scan(&self, grid: &OccupancyGrid, pose: &Pose) -> LaserScan {
        let n = self.beams.max(1);
        let increment = std::f64::consts::TAU / n as f64;
        let geometry =
            ScanGeometry { angle_min: 0.0, angle_increment: increment, range_min: 0.0, range_max: self.range };
        let res = grid.resolution;
        let from = grid.in_cells(pose.translation.vector.into());
        // a grid whose cells do not fill it reads nothing
        let raster = (grid.cells.len() == grid.width * grid.height).then(|| grid.raster());
        let heading = pose.rotation.angle() - grid.origin[2];
        let ranges = (0..n)
            .map(|i| {
                let a = heading + i as f64 * increment;
                let dir = Vector2::new(a.cos(), a.sin());
                match raster.as_ref().and_then(|g| first_occupied(g, from, dir, (self.range / res, self.unknown / res)))
                {
                    Some(t) => ((t + 0.5) * res).min(self.range) as f32,
                    None => self.range as f32,
                }
            })
            .collect();
        LaserScan { geometry, ranges, stamp: 0.0, truth: Some(*pose) }
    }
}

/// The scans of a virtual survey, each with its pose ([`crate::build::Survey`]).
struct VirtualScans(Vec<LaserScan>);

impl crate::build::Survey for VirtualScans {
    type Error = std::convert::Infallible;

    fn walk(&mut self, each: &mut dyn FnMut(&LaserScan, &Pose)) -> Result<(), Self::Error> {
        for scan in &self.0 {
            if let Some(pose) = &scan.truth {
                each(scan, pose);
            }
        }
        Ok(())
    }
}

/// `grid` surveyed by `survey` and built into walls by `build` ([`crate::build()`]), with the
/// number of scans cast; `None` when no pose stands clear in its free space or no wall was
/// seen. The map's free space is the grid's free cells ([`OccupancyGrid::free_space`]), as a
/// traced grid's is, rather than the cells the virtual beams crossed.
pub fn build_from_grid(grid: &OccupancyGrid, survey: &VirtualSurvey, build: &BuildConfig) -> Option<(WallMap, usize)> {
    let scans: Vec<LaserScan> = survey.poses(grid).iter().map(|p| survey.scan(grid, p)).collect();
    if scans.is_empty() {
        return None;
    }
    let mut surveyed = VirtualScans(scans);
    let built = crate::build::build(&mut surveyed, &BuildConfig { seen_cell: 0.0, ..*build }).ok()?;
    let mut map = built.map;
    if build.seen_cell > 0.0 {
        map.seen_free = grid.free_space();
    }
    Some((map, built.scans))
}

/// How a grid's walls were made ([`grid_walls`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum GridWalls {
    /// Its occupied cells' faces traced ([`OccupancyGrid::to_wall_map`]); `rough` is
    /// [`crate::roughness`] of the faces.
    Traced { rough: f64 },
    /// Built from `scans` scans of a virtual survey ([`build_from_grid`]), the grid being rough.
    Surveyed { rough: f64, scans: usize },
}

impl GridWalls {
    /// How rough the grid's traced faces are.
    pub fn rough(&self) -> f64 {
        match *self {
            GridWalls::Traced { rough } | GridWalls::Surveyed { rough, .. } => rough,
        }
    }
}

/// How a grid's walls are to be made ([`grid_walls_with`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MakeWalls {
    /// Surveyed when the grid is rough, else traced.
    AsRough,
    Traced,
    Surveyed,
}

impl MakeWalls {
    /// Whether a grid of roughness `rough` ([`crate::roughness`]) is to be surveyed.
    pub fn surveys(self, rough: f64) -> bool {
        self == MakeWalls::Surveyed || self == MakeWalls::AsRough && rough > ROUGH_SHARE
    }
}

/// A grid's walls as `--map GRID.yaml` makes them: its faces traced, unless the grid is rough
/// (more than [`ROUGH_SHARE`] of the traced length in pieces under [`crate::ROUGH_WALL_CELLS`]
/// cells, as a SLAM map of a real building is; a plan drawn into a grid has 0-2 %): then built
/// from a virtual survey ([`VirtualSurvey::default`], [`BuildConfig::default`]: approximate to
/// a decimetre, as a map built from a log is). A rough grid no pose of the survey stands clear
/// in stays traced.
pub fn grid_walls(grid: &OccupancyGrid) -> Result<(WallMap, GridWalls), GridError> {
    grid_walls_with(grid, &TraceConfig::default(), None, MakeWalls::AsRough)
}

/// [`grid_walls`] traced with `trace`, at accuracy `sigma` when given (else half a cell traced,
/// [`BuildConfig`]'s surveyed), surveyed or traced as `how` says. A survey that finds no pose
/// or no wall leaves the grid traced.
pub fn grid_walls_with(
    grid: &OccupancyGrid,
    trace: &TraceConfig,
    sigma: Option<f64>,
    how: MakeWalls,
) -> Result<(WallMap, GridWalls), GridError> {
    let (traced, rough) = grid.to_wall_map_with_roughness(trace, sigma)?;
    if how.surveys(rough) {
        let build = BuildConfig { sigma: sigma.unwrap_or(BuildConfig::default().sigma), ..BuildConfig::default() };
        if let Some((map, scans)) = build_from_grid(grid, &VirtualSurvey::default(), &build) {
            return Ok((map, GridWalls::Surveyed { rough, scans }));
        }
    }
    Ok((traced, GridWalls::Traced { rough }))
}

// The two rasters the poses are chosen on ([`room`], [`KnownFloor`]) take 4 bytes a cell of
// the grid, which a file limits to `GRID_FILE_CELLS`: each stays within the raster budget.
const _: () = assert!(map::limits::GRID_FILE_CELLS * 4 <= map::limits::RASTER_BUDGET);

/// The share of a square of cells about a cell that a grid knows to be free, from a summed
/// table of its free cells.
struct KnownFloor {
    /// Free cells in columns `0..c` and rows `0..r`, at `r * (width + 1) + c`.
    sums: Vec<u32>,
    width: usize,
    height: usize,
    reach: usize,
}

impl KnownFloor {
    /// Squares of `reach` cells either way of a cell.
    fn of(grid: &OccupancyGrid, reach: i64) -> Self {
        let (w, h) = (grid.width, grid.height);
        let mut sums = vec![0u32; (w + 1) * (h + 1)];
        for r in 0..h {
            let mut row = 0;
            for c in 0..w {
                row += u32::from(grid.cells[r * w + c] == Cell::Free);
                sums[(r + 1) * (w + 1) + c + 1] = sums[r * (w + 1) + c + 1] + row;
            }
        }
        KnownFloor { sums, width: w, height: h, reach: reach.max(0) as usize }
    }

    /// The grid's free cells in all.
    fn free_cells(&self) -> u32 {
        self.sums.last().copied().unwrap_or(0)
    }

    /// Whether at least 90 % of the square about (c, r), as far as it lies in the grid, is
    /// free. A SLAM grid's unknown specks among the free cells leave it so; the fringe of what
    /// its survey saw does not.
    fn mostly_free(&self, c: usize, r: usize) -> bool {
        let (c0, c1) = (c.saturating_sub(self.reach), (c + self.reach + 1).min(self.width));
        let (r0, r1) = (r.saturating_sub(self.reach), (r + self.reach + 1).min(self.height));
        let w = self.width + 1;
        let free = self.sums[r1 * w + c1] + self.sums[r0 * w + c0] - self.sums[r0 * w + c1] - self.sums[r1 * w + c0];
        let side = 2 * self.reach + 1;
        10 * free as usize >= 9 * side * side
    }
}

/// For each cell, about how far (in cells) its centre lies from the nearest occupied cell's
/// (a two-pass chamfer distance, steps of 1 and the square root of 2); infinite with none.
fn room(grid: &OccupancyGrid) -> Vec<f32> {
    let (w, h) = (grid.width, grid.height);
    let mut d: Vec<f32> = grid.cells.iter().map(|&c| if c == Cell::Occupied { 0.0 } else { f32::INFINITY }).collect();
    let diagonal = std::f32::consts::SQRT_2;
    let relax = |d: &mut Vec<f32>, k: usize, from: usize, by: f32| {
        let via = d[from] + by;
        if via < d[k] {
            d[k] = via;
        }
    };
    for r in 0..h {
        for c in 0..w {
            let k = r * w + c;
            if c > 0 {
                relax(&mut d, k, k - 1, 1.0);
            }
            if r > 0 {
                relax(&mut d, k, k - w, 1.0);
                if c > 0 {
                    relax(&mut d, k, k - w - 1, diagonal);
                }
                if c + 1 < w {
                    relax(&mut d, k, k - w + 1, diagonal);
                }
            }
        }
    }
    for r in (0..h).rev() {
        for c in (0..w).rev() {
            let k = r * w + c;
            if c + 1 < w {
                relax(&mut d, k, k + 1, 1.0);
            }
            if r + 1 < h {
                relax(&mut d, k, k + w, 1.0);
                if c + 1 < w {
                    relax(&mut d, k, k + w + 1, diagonal);
                }
                if c > 0 {
                    relax(&mut d, k, k + w - 1, diagonal);
                }
            }
        }
    }
    d
}

/// How far (in cells) along the unit direction `dir` from `from` (grid frame) the ray enters the
/// first occupied cell; `None` when it meets an unknown cell, leaves the grid or goes `max_t`
/// cells first. The cells are walked in the order the ray crosses them (Amanatides and Woo).
fn first_occupied(
    raster: &Raster<'_>,
    from: Point2<f64>,
    dir: Vector2<f64>,
    (max_t, max_unknown): (f64, f64),
) -> Option<f64> {
    let (mut c, mut r) = (from.x.floor() as i64, from.y.floor() as i64);
    let step = |d: f64| if d > 0.0 { 1 } else { -1 };
    let (sc, sr) = (step(dir.x), step(dir.y));
    let delta = |d: f64| if d == 0.0 { f64::INFINITY } else { 1.0 / d.abs() };
    let (dc, dr) = (delta(dir.x), delta(dir.y));
    let first = |p: f64, cell: i64, d: f64| {
        if d > 0.0 {
            (cell as f64 + 1.0 - p) / d
        } else if d < 0.0 {
            (p - cell as f64) / -d
        } else {
            f64::INFINITY
        }
    };
    let (mut next_c, mut next_r) = (first(from.x, c, dir.x), first(from.y, r, dir.y));
    let mut t = 0.0;
    // where the ray entered the run of unknown cells it is in
    let mut unknown_since = None;
    loop {
        match raster.at(c, r)? {
            Cell::Occupied => return Some(t),
            Cell::Unknown => {
                let since = *unknown_since.get_or_insert(t);
                if t - since > max_unknown {
                    return None;
                }
            }
            Cell::Free => unknown_since = None,
        }
        if next_c < next_r {
            t = next_c;
            next_c += dc;
            c += sc;
        } else {
            t = next_r;
            next_r += dr;
            r += sr;
        }
        if t > max_t {
            return None;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use laser::Reading;

    /// A `w` x `h` room of 0.05 m cells at `origin`: a wall of occupied cells round a free
    /// inside, unknown outside.
    fn room(w: usize, h: usize, origin: [f64; 3]) -> OccupancyGrid {
        let mut cells = vec![Cell::Unknown; (w + 4) * (h + 4)];
        for r in 1..h + 3 {
            for c in 1..w + 3 {
                let edge = r == 1 || c == 1 || r == h + 2 || c == w + 2;
                cells[r * (w + 4) + c] = if edge { Cell::Occupied } else { Cell::Free };
            }
        }
        OccupancyGrid { resolution: 0.05, origin, width: w + 4, height: h + 4, cells }
    }

    #[test]
    fn the_poses_stand_clear_of_the_walls_and_the_beams_end_on_them() {
        let grid = room(80, 60, [-1.0, 2.0, 0.0]);
        let survey = VirtualSurvey { spacing: 0.5, ..VirtualSurvey::default() };
        let poses = survey.poses(&grid);
        assert!(!poses.is_empty());
        // the wall cells' inner faces: x from -0.9 to 3.1, y from 2.1 to 5.1
        for p in &poses {
            let t = p.translation.vector;
            assert!(t.x >= -0.9 + 0.3 && t.x <= 3.1 - 0.3 && t.y >= 2.1 + 0.3 && t.y <= 5.1 - 0.3, "{t:?}");
        }
        let scan = survey.scan(&grid, &poses[0]);
        let view = scan.view();
        let t = poses[0].translation.vector;
        // the beam along +x ends half a cell into the east wall's cells, the one along -x in
        // the west wall's
        let east = (3.1 - t.x) + 0.025;
        let west = (t.x + 0.9) + 0.025;
        assert!(matches!(view.reading(0), Reading::Valid(d) if (d - east).abs() < 1e-3), "{:?}", view.reading(0));
        let half = survey.beams / 2;
        assert!(matches!(view.reading(half), Reading::Valid(d) if (d - west).abs() < 1e-3), "{:?}", view.reading(half));
        // every beam of a closed room ends on its wall
        assert!((0..view.len()).all(|i| matches!(view.reading(i), Reading::Valid(_))));
    }

    #[test]
    fn a_rotated_grid_is_surveyed_in_the_map_frame() {
        let yaw = 0.5f64;
        let grid = room(60, 60, [1.0, -2.0, yaw]);
        let survey = VirtualSurvey::default();
        let poses = survey.poses(&grid);
        assert!(!poses.is_empty());
        for p in &poses {
            assert!((p.rotation.angle() - yaw).abs() < 1e-12);
            let g = grid.in_cells(p.translation.vector.into());
            assert!(g.x > 7.0 && g.x < 57.0 && g.y > 7.0 && g.y < 57.0, "{g:?}");
        }
        // along the pose's heading, the grid's x axis: to the east wall's cells
        let scan = survey.scan(&grid, &poses[0]);
        let g = grid.in_cells(poses[0].translation.vector.into());
        let expected = (62.0 - g.x) * 0.05 + 0.025;
        assert!(matches!(scan.view().reading(0), Reading::Valid(d) if (d - expected).abs() < 1e-3));
    }

    #[test]
    fn unknown_cells_and_the_grids_edge_read_nothing() {
        let mut grid = room(40, 40, [0.0, 0.0, 0.0]);
        // a gap in the east wall onto the unknown outside
        for r in 10..30 {
            grid.cells[r * grid.width + 42] = Cell::Unknown;
        }
        let survey = VirtualSurvey { spacing: 0.5, clearance: 0.2, ..VirtualSurvey::default() };
        let pose = Isometry2::new(Vector2::new(1.0, 1.0), 0.0);
        let view_scan = survey.scan(&grid, &pose);
        assert!(matches!(view_scan.view().reading(0), Reading::NoReturn));
        let open = OccupancyGrid { cells: vec![Cell::Free; 100], width: 10, height: 10, ..grid.clone() };
        let scan = survey.scan(&open, &Isometry2::new(Vector2::new(0.25, 0.25), 0.0));
        assert!((0..scan.ranges.len()).all(|i| matches!(scan.view().reading(i), Reading::NoReturn)));
    }

    /// An 8 x 5 m room as a SLAM map draws it, in 0.05 m cells: each wall a band one to three
    /// cells deep whose inner face steps a cell in and out, unknown cells left among the free
    /// ones, unknown outside.
    fn slam_room() -> OccupancyGrid {
        let (w, h) = (170usize, 110usize);
        let mut cells = vec![Cell::Unknown; w * h];
        let mut seed = 7u64;
        let mut next = move || {
            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (seed >> 33) as usize
        };
        // inside: columns 5..165, rows 5..105 (8 x 5 m)
        for r in 5..105 {
            for c in 5..165 {
                cells[r * w + c] = if next() % 40 == 0 { Cell::Unknown } else { Cell::Free };
            }
        }
        // each wall cell along the outline: a band from one cell inside the face (every third
        // cell or so) to one to three cells outside it
        let mut band = |cells: &mut Vec<Cell>, c: i64, r: i64, inward: (i64, i64)| {
            let (into, depth) = (if next() % 3 == 0 { 1 } else { 0 }, 1 + (next() % 3) as i64);
            for k in -into..depth {
                let (cc, rr) = (c - inward.0 * k, r - inward.1 * k);
                cells[rr as usize * w + cc as usize] = Cell::Occupied;
            }
        };
        for c in 5..165 {
            band(&mut cells, c, 4, (0, 1));
            band(&mut cells, c, 105, (0, -1));
        }
        for r in 5..105 {
            band(&mut cells, 4, r, (1, 0));
            band(&mut cells, 165, r, (-1, 0));
        }
        OccupancyGrid { resolution: 0.05, origin: [0.0, 0.0, 0.0], width: w, height: h, cells }
    }

    #[test]
    fn a_slam_grids_jagged_wall_becomes_one_long_wall() {
        let grid = slam_room();
        let (traced, rough) = grid.to_wall_map_with_roughness(&TraceConfig::default(), None).unwrap();
        assert!(rough > ROUGH_SHARE, "{rough}");
        let (map, how) = grid_walls(&grid).unwrap();
        assert!(matches!(how, GridWalls::Surveyed { scans, .. } if scans > 10), "{how:?}");
        assert!(map.is_approximate());
        let longest = |walls: &[map::Wall]| walls.iter().map(|w| w.length()).fold(0.0, f64::max);
        // the room's long sides are 8 m: traced, the steps of the face cut them up
        let (surveyed, cut) = (longest(&map.walls), longest(&traced.walls));
        assert!(surveyed > 7.5, "surveyed {surveyed} m, traced {cut} m");
        let (n, pieces) = (map.walls.len(), traced.walls.len());
        assert!(n * 3 < pieces, "surveyed {n} walls, traced {pieces}");
        // and every wall of it lies on the room's faces (x 0.25 or 8.25, y 0.25 or 5.25),
        // within a cell and a half and the bands' depth
        let near_face = |p: Point2<f64>| {
            let d = [(p.x - 0.25).abs(), (p.x - 8.25).abs(), (p.y - 0.25).abs(), (p.y - 5.25).abs()];
            d.iter().copied().fold(f64::INFINITY, f64::min) < 0.15
        };
        assert!(map.walls.iter().all(|w| near_face(w.a) && near_face(w.b)), "{:?}", map.walls);
        assert!(map.seen_free.is_some());
    }

    #[test]
    fn a_cluttered_grid_is_surveyed_from_the_clear_spots_among_the_clutter() {
        let mut grid = room(120, 120, [0.0, 0.0, 0.0]);
        let w = grid.width;
        // 3 x 3 blobs 0.75 m apart: a lattice point 1 m apart often falls within 0.3 m of one
        for r in (10..120).step_by(15) {
            for c in (10..120).step_by(15) {
                for k in 0..9 {
                    grid.cells[(r + k / 3) * w + c + k % 3] = Cell::Occupied;
                }
            }
        }
        // 36 squares of 1 m
        let survey = VirtualSurvey { spacing: 1.0, ..VirtualSurvey::default() };
        let poses = survey.poses(&grid);
        assert!(poses.len() >= 20, "{}", poses.len());
        let occupied: Vec<(f64, f64)> = (0..grid.cells.len())
            .filter(|&k| grid.cells[k] == Cell::Occupied)
            .map(|k| ((k % w) as f64 * 0.05, (k / w) as f64 * 0.05))
            .collect();
        for p in &poses {
            let t = p.translation.vector;
            // the nearest point of each occupied cell
            let gap = occupied
                .iter()
                .map(|&(x, y)| (t.x - t.x.clamp(x, x + 0.05)).hypot(t.y - t.y.clamp(y, y + 0.05)))
                .fold(f64::INFINITY, f64::min);
            assert!(gap >= survey.clearance - 1e-9, "{t:?}: {gap}");
        }
    }

    #[test]
    fn a_large_grid_is_surveyed_on_a_wider_lattice() {
        let grid = room(200, 200, [0.0, 0.0, 0.0]);
        let few = VirtualSurvey { spacing: 0.1, max_poses: 50, ..VirtualSurvey::default() };
        let poses = few.poses(&grid);
        assert!(!poses.is_empty() && poses.len() <= 50, "{}", poses.len());
        let unusable = VirtualSurvey { spacing: f64::NAN, ..VirtualSurvey::default() };
        assert!(unusable.poses(&grid).is_empty());
    }
}
