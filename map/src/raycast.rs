//! Ray casting against the walls by angular sweep: for a sensor pose, each wall within range is
//! turned into the arc of beams it covers, and only those beams are intersected with it (a
//! z-buffer over beams). Cost: the walls near the pose (found through a [`WallGrid`]) times the
//! beams each covers, so it grows with the beams and the depth of the scene, not with the map.
//! Where a cast has few beams and the sweep many walls (a sparse cost at a long reach), each
//! beam instead marches through the wall grid to its first wall; both give the same ranges.

use crate::flat::{Flat, FlatError, FlatReader, FlatWriter};
use crate::grid::{ReachFrame, WallGrid};
use crate::slab::Slab;
use crate::wall::Wall;
use laser::{Pose, ScanGeometry};
use nalgebra::{Point2, Vector2};
use std::f64::consts::TAU;
use std::sync::atomic::{AtomicU16, AtomicU32, Ordering};
use std::sync::{Arc as Shared, Mutex, OnceLock, PoisonError};

/// Expected ranges d'_i of eq. 7: what an ideal sensor at a pose would read in the map.
#[derive(Clone, Debug)]
pub struct RayCaster {
    walls: Slab<Wall>,
    grid: WallGrid,
    /// Set up on the first cast: for each cell, every wall within the sensor's reach of it (the
    /// reach of that first cast), and, built on the first cast from the cell, those another
    /// wall does not hide from the whole cell, so a cast reads one short list instead of
    /// gathering and de-duplicating the walls of the hundred-odd cells around the sensor.
    /// `None` when the lists would be too large (a long-range sensor in a large map).
    reach: OnceLock<Option<ReachLists>>,
}

/// The per-cell lists of walls a cast may meet, filtered when set up if that is cheap, else each
/// on first use: a cell costs its walls squared, and at a long reach every cell holds the whole
/// map. Filtering the cells of a 200-wall map at 82 m reach held up the first scan by 0.1 s
/// (after the quick tests of [`potentially_visible`]; 0.6-0.8 s before), while that scan's casts
/// touch a few dozen cells. Filtered lazily, the office's cells (5.6 m reach; about 5 ms in
/// all, paid by the first scan when filtered up front) would instead be paid by the first few
/// hundred scans of a benchmark, some tens of microseconds each.
#[derive(Debug)]
struct ReachLists {
    range: f64,
    /// The cells, each listing every wall within `range` of it, made when asked: kept whole,
    /// the lists repeat most of the map in every cell (11 MB on freiburg-079's built map at
    /// 50 m), in every localizer that shares the map's model.
    within: ReachFrame,
    /// How many walls each cell lists, counted on first need ([`NOT_COUNTED`] until then),
    /// at most [`MOST_COUNTED`]: a cell with that many walls in reach is marched from until
    /// it pays for filtering, and is never filtered up front, whatever the count beyond.
    counts: Vec<AtomicU16>,
    /// Beams marched from each cell whose list is not filtered (kept) now ([`Plan`]),
    /// saturating; back to 0 when its list is dropped.
    marched: Vec<AtomicU32>,
    /// The filtered lists this process keeps, at most [`KeptLists::budget`] bytes.
    kept: Mutex<KeptLists>,
}

/// A cell whose walls are not counted yet ([`ReachLists::counts`]).
const NOT_COUNTED: u16 = u16::MAX;

/// The most walls a cell is counted to have ([`ReachLists::counts`]).
const MOST_COUNTED: u16 = u16::MAX - 1;

/// The cells' filtered lists ([`potentially_visible`]) this process holds: those it cast from
/// most recently, in at most `budget` bytes. Every cell's list, kept whole, would grow with
/// the cells a long run casts from, up to 1-17 MB on the maps built from the CARMEN logs
/// (11-61 % of the shared model), in each localizer that shares the model; a global search
/// gains nothing from them (it marches), and tracking casts from a few cells.
#[derive(Clone, Debug)]
struct KeptLists {
    /// Per cell: its place in `lists`, or [`NOT_KEPT`]; so at most [`MOST_KEPT`] lists.
    slot: Vec<u16>,
    lists: Vec<KeptList>,
    bytes: usize,
    budget: usize,
    /// Counts the lists' uses, so the least recently used one makes room.
    clock: u64,
}

#[derive(Clone, Debug)]
struct KeptList {
    cell: u32,
    list: Shared<WallList>,
    used: u64,
}

/// A cell whose list is not kept ([`KeptLists::slot`]).
const NOT_KEPT: u16 = u16::MAX;

/// The most lists kept at once, whatever the budget ([`KeptLists::slot`]).
const MOST_KEPT: usize = NOT_KEPT as usize;

/// What a kept list takes beside its indices: its entry in [`KeptLists::lists`], and the
/// shared allocation's two counts and the list's own header.
const KEPT_LIST_OVERHEAD: usize =
    std::mem::size_of::<KeptList>() + 2 * std::mem::size_of::<usize>() + std::mem::size_of::<WallList>();

/// The bytes the filtered lists of one caster may hold (`KeptLists`). Tracking a robot
/// casts from the few cells around it, each list a few hundred walls (2 bytes a wall); a
/// global search's casts from cells it has not filtered march. On the shared CARMEN logs,
/// tracking took the same time with 64 KB as with 256 KB.
pub const KEPT_LISTS_BYTES: usize = 64 * 1024;

impl KeptLists {
    fn new(cells: usize, budget: usize) -> Self {
        KeptLists { slot: vec![NOT_KEPT; cells], lists: Vec::new(), bytes: 0, budget, clock: 0 }
    }

    /// Cell `cell`'s list, if kept; counts a use.
    fn get(&mut self, cell: usize) -> Option<Shared<WallList>> {
        let k = *self.slot.get(cell)?;
        let kept = self.lists.get_mut(k as usize)?;
        self.clock += 1;
        kept.used = self.clock;
        Some(Shared::clone(&kept.list))
    }

    /// Keeps `list` as cell `cell`'s (or the one already kept), dropping the least recently
    /// used lists while the budget has no room for it; returns the cells dropped, which must
    /// pay for filtering again before they are.
    fn keep(&mut self, cell: usize, list: Shared<WallList>, dropped: &mut Vec<usize>) -> Shared<WallList> {
        if let Some(kept) = self.get(cell) {
            return kept;
        }
        let bytes = list.bytes();
        while (self.bytes + bytes > self.budget || self.lists.len() >= MOST_KEPT) && !self.lists.is_empty() {
            let oldest = (0..self.lists.len()).min_by_key(|&k| self.lists[k].used).unwrap_or(0);
            let gone = self.lists.swap_remove(oldest);
            self.bytes -= gone.list.bytes();
            self.slot[gone.cell as usize] = NOT_KEPT;
            if let Some(moved) = self.lists.get(oldest) {
                self.slot[moved.cell as usize] = oldest as u16;
            }
            dropped.push(gone.cell as usize);
        }
        self.clock += 1;
        // below MOST_KEPT: the loop above made room
        self.slot[cell] = self.lists.len() as u16;
        self.lists.push(KeptList { cell: cell as u32, list: Shared::clone(&list), used: self.clock });
        self.bytes += bytes;
        list
    }
}

impl Clone for ReachLists {
    fn clone(&self) -> Self {
        let kept = self.kept.lock().unwrap_or_else(PoisonError::into_inner).clone();
        ReachLists {
            range: self.range,
            within: self.within,
            counts: self.counts.iter().map(|m| AtomicU16::new(m.load(Ordering::Relaxed))).collect(),
            marched: self.marched.iter().map(|m| AtomicU32::new(m.load(Ordering::Relaxed))).collect(),
            kept: Mutex::new(kept),
        }
    }
}

impl ReachLists {
    fn new(walls: &[Wall], range: f64, budget: usize) -> Self {
        Self::filtering_eagerly_up_to(walls, range, EAGER_PAIRS, budget)
    }

    /// Lists filtered up front when their walls' pairs, summed over the cells, are at most
    /// `eager_pairs` and every list fits in `budget` bytes at once.
    fn filtering_eagerly_up_to(walls: &[Wall], range: f64, eager_pairs: f64, budget: usize) -> Self {
        let within = ReachFrame::covering(walls, CELL, range, CELL);
        let cells_n = within.cell_count();
        let counts = (0..cells_n).map(|_| AtomicU16::new(NOT_COUNTED)).collect();
        let marched = (0..cells_n).map(|_| AtomicU32::new(0)).collect();
        let kept = Mutex::new(KeptLists::new(cells_n, budget));
        let lists = ReachLists { range, within, counts, marched, kept };
        let cells = || (0..lists.within.rows()).flat_map(|r| (0..lists.within.cols()).map(move |c| (c, r)));
        // counted only until the sum passes the bound: counting every cell of a large map at a
        // long reach took 40 ms, all of it in the first scan of a localizer that just started
        let (mut pairs, mut bytes) = (0.0, 0);
        let few = cells().all(|(c, r)| {
            let n = lists.count(walls, c, r);
            pairs += (n as f64).powi(2);
            bytes += WallList::bytes_for(n, walls.len());
            pairs <= eager_pairs && bytes <= budget
        });
        if few {
            for (c, r) in cells() {
                lists.visible_in(walls, c, r);
            }
        }
        lists
    }

    /// How to cast `beams` beams from `p`, when `p` lies on the grid: sweep the walls of its
    /// cell's list, or march the beams. A cell's list is filtered once marching from it has
    /// cost [`FILTER_AFTER`] times what filtering would (rent, then buy): a cell a global search
    /// visits a few times is not worth filtering at a long reach, one the robot keeps returning
    /// to is. A list dropped to make room ([`KeptLists`]) is paid for again the same way, so
    /// filtering never costs more than an eighth of the marching it saves.
    fn plan(&self, walls: &[Wall], p: Point2<f64>, beams: usize) -> Option<Plan> {
        let (c, r) = self.within.cell_of(p)?;
        let cell = self.within.cell_index(c, r);
        let kept = self.kept.lock().unwrap_or_else(PoisonError::into_inner).get(cell);
        let kept = match kept {
            Some(kept) => kept,
            None => {
                let unfiltered = self.count(walls, c, r) as f64;
                let filtering = unfiltered * unfiltered * FILTER_NS_PER_PAIR;
                let marching = beams as f64 * MARCH_NS_PER_BEAM;
                // a short list is filtered at once: that and a sweep cost less than this march
                if filtering + unfiltered * SWEEP_NS_PER_WALL > marching {
                    let beams = u32::try_from(beams).unwrap_or(u32::MAX);
                    let marched = match self.marched[cell]
                        .fetch_update(Ordering::Relaxed, Ordering::Relaxed, |m| Some(m.saturating_add(beams)))
                    {
                        Ok(before) | Err(before) => before.saturating_add(beams),
                    };
                    if (marched as f64) * MARCH_NS_PER_BEAM < FILTER_AFTER * filtering {
                        return Some(Plan::March);
                    }
                }
                self.filter_and_keep(walls, c, r)
            }
        };
        Some(Plan::cheaper(kept, beams))
    }

    /// How many walls lie within reach of cell (c, r), counted on the first call.
    fn count(&self, walls: &[Wall], c: usize, r: usize) -> usize {
        let count = &self.counts[self.within.cell_index(c, r)];
        match count.load(Ordering::Relaxed) {
            NOT_COUNTED => {
                // two threads may both count a cell: they store the same number
                let n = u16::try_from(self.within.count_of(walls, c, r)).unwrap_or(MOST_COUNTED).min(MOST_COUNTED);
                count.store(n, Ordering::Relaxed);
                n as usize
            }
            n => n as usize,
        }
    }

    /// The walls of cell (c, r) not hidden from it: the list kept, or filtered now and kept.
    fn visible_in(&self, walls: &[Wall], c: usize, r: usize) -> Shared<WallList> {
        let kept = self.kept.lock().unwrap_or_else(PoisonError::into_inner).get(self.within.cell_index(c, r));
        kept.unwrap_or_else(|| self.filter_and_keep(walls, c, r))
    }

    /// Filters the walls of cell (c, r) and keeps the list, or the one kept meanwhile.
    fn filter_and_keep(&self, walls: &[Wall], c: usize, r: usize) -> Shared<WallList> {
        let cell = self.within.cell_index(c, r);
        // filtered without the lock (it takes up to milliseconds); two threads may both filter
        // a cell, and the first kept is the one both use
        let (mut list, mut visible) = (Vec::new(), Vec::new());
        self.within.list_of(walls, c, r, &mut list);
        potentially_visible(walls, &self.within.cell_corners(c, r), &list, &mut visible);
        let list = Shared::new(WallList::new(&visible, walls.len()));
        let mut dropped = Vec::new();
        let kept = self.kept.lock().unwrap_or_else(PoisonError::into_inner).keep(cell, list, &mut dropped);
        for gone in dropped {
            self.marched[gone].store(0, Ordering::Relaxed);
        }
        kept
    }
}

/// A filtered list of walls, by index: two bytes an index where the map has at most 65536
/// walls (every map built from the CARMEN logs), else four. A localizer keeps the lists of
/// the cells it cast from most recently ([`KeptLists`]), a few hundred walls each.
#[derive(Clone, Debug, PartialEq)]
enum WallList {
    Short(Box<[u16]>),
    Long(Box<[u32]>),
}

impl WallList {
    fn new(kept: &[u32], walls: usize) -> Self {
        if Self::index_bytes(walls) == 2 {
            // every index is below `walls`, so each fits
            WallList::Short(kept.iter().map(|&k| k as u16).collect())
        } else {
            WallList::Long(kept.into())
        }
    }

    fn len(&self) -> usize {
        match self {
            WallList::Short(v) => v.len(),
            WallList::Long(v) => v.len(),
        }
    }

    /// The bytes an index takes in a list of a map of `walls` walls.
    fn index_bytes(walls: usize) -> usize {
        if walls <= usize::from(u16::MAX) + 1 {
            2
        } else {
            4
        }
    }

    /// The heap bytes a list of `len` of `walls` walls takes, with its [`KeptList`] entry.
    fn bytes_for(len: usize, walls: usize) -> usize {
        len * Self::index_bytes(walls) + KEPT_LIST_OVERHEAD
    }

    /// The heap bytes this list takes, with its [`KeptList`] entry.
    fn bytes(&self) -> usize {
        let indices = match self {
            WallList::Short(v) => std::mem::size_of_val::<[u16]>(v),
            WallList::Long(v) => std::mem::size_of_val::<[u32]>(v),
        };
        indices + KEPT_LIST_OVERHEAD
    }

    /// Calls `f` with each wall's index, in order.
    #[inline]
    fn for_each(&self, mut f: impl FnMut(usize)) {
        match self {
            WallList::Short(v) => v.iter().for_each(|&k| f(usize::from(k))),
            WallList::Long(v) => v.iter().for_each(|&k| f(k as usize)),
        }
    }

    #[cfg(test)]
    fn to_vec(&self) -> Vec<u32> {
        let mut out = Vec::with_capacity(self.len());
        self.for_each(|k| out.push(k as u32));
        out
    }
}

/// Per-caller scratch space: the direction of every beam of the current layout and wall
/// de-duplication marks. Reused across calls (whatever their stride) so casting allocates
/// nothing and computes no trigonometry per beam.
#[derive(Clone, Debug, Default)]
pub struct RayScratch {
    key: Option<(u64, u64, usize)>,
    dirs: Vec<Vector2<f64>>,
    mark: Vec<u32>,
    epoch: u32,
}

impl RayScratch {
    fn prepare(&mut self, g: &ScanGeometry, beams: usize, walls: usize) {
        let key = (g.angle_min.to_bits(), g.angle_increment.to_bits(), beams);
        if self.key != Some(key) {
            self.dirs.clear();
            self.dirs.extend((0..beams).map(|i| {
                let a = g.angle(i);
                Vector2::new(a.cos(), a.sin())
            }));
            self.key = Some(key);
        }
        if self.mark.len() != walls {
            self.mark = vec![0; walls];
            self.epoch = 0;
        }
        self.epoch = self.epoch.wrapping_add(1);
        if self.epoch == 0 {
            self.mark.iter_mut().for_each(|m| *m = 0);
            self.epoch = 1;
        }
    }
}

/// How one cast is made: by sweeping a list of walls, or by marching each beam through the
/// wall grid ([`RayCaster::march`]). Both give the same ranges; which is cheaper depends on
/// how many walls the sweep would visit against how many beams are cast.
enum Plan {
    Sweep(Shared<WallList>),
    March,
}

impl Plan {
    fn cheaper(walls: Shared<WallList>, beams: usize) -> Self {
        if Self::march_pays(walls.len(), beams) {
            Plan::March
        } else {
            Plan::Sweep(walls)
        }
    }

    /// Whether marching `beams` beams costs less than sweeping `walls` walls.
    fn march_pays(walls: usize, beams: usize) -> bool {
        beams as f64 * MARCH_NS_PER_BEAM < walls as f64 * SWEEP_NS_PER_WALL
    }
}

/// What a sweep costs per wall it visits and a march per beam, and what filtering a cell's list
/// costs per pair of its walls, nanoseconds: measured with the maps built from the CARMEN logs
/// (350-1000 walls, 50 m reach, 33 and 361 beams), where sweeps visit 190-290 walls of each
/// cell's filtered list at about 80 ns each, a beam marches about 300 ns, and filtering a cell
/// took 0.5-1.3 ns per pair (340-540 us a cell). With the URG-04LX's 5.6 m, marching is
/// cheaper per beam (about 130 ns) but sweeps visit a few dozen walls: they stay sweeps.
const SWEEP_NS_PER_WALL: f64 = 80.0;
const MARCH_NS_PER_BEAM: f64 = 300.0;
const FILTER_NS_PER_PAIR: f64 = 1.0;

/// A cell's list is filtered once the beams marched from it have cost this many times what
/// filtering it does. At 1 (rent or buy at the price) a global search, which scatters its
/// poses over the whole map and comes back to few cells often, filtered cells it then hardly
/// used: on maps built from the CARMEN logs freiburg-101 and csail took 8.2 and 7.8 ms a scan,
/// at 10 7.1 and 7.2 ms, never filtering 7.0 and 7.2 ms. A robot that stays in a few cells
/// still has them filtered after a few dozen scans.
const FILTER_AFTER: f64 = 8.0;

/// Cell side of the caster's wall grids, metres.
const CELL: f64 = 1.0;

/// A beam's march tests every wall of each cell it crosses until one holds a hit: its cost is
/// in those tests where walls are dense (a map built from a log draws a wall as many short
/// ones), and in stepping from cell to cell where they are sparse. The march's grid starts at
/// [`CELL`] and its cells are halved, down to [`MARCH_CELL_LEAST`], while a cell that lists any
/// wall lists more than this many on average. On the maps built from the CARMEN logs: the
/// 3552-wall freiburg-079 map went to 0.25 m (one scan's search 58 -> 38 ms median), the
/// others stayed at 1 m, where halving made them no faster or slower (more cells to step).
const MARCH_WALLS_PER_CELL: f64 = 6.0;
const MARCH_CELL_LEAST: f64 = 0.25;

/// The grid a beam marches through: cells listing the walls that cross them, sized as
/// [`MARCH_WALLS_PER_CELL`] says.
fn march_grid(walls: &[Wall]) -> WallGrid {
    let mut cell = CELL;
    loop {
        let grid = WallGrid::new(walls, cell, 0.0);
        let per_cell = grid.entries() as f64 / grid.listing_cells().max(1) as f64;
        if per_cell <= MARCH_WALLS_PER_CELL || cell / 2.0 < MARCH_CELL_LEAST {
            return grid;
        }
        cell /= 2.0;
    }
}

/// Most wall pairs (summed over cells) for which every cell's list is filtered when the lists
/// are set up: about 10-20 ms.
const EAGER_PAIRS: f64 = 1.0e7;

/// Largest number of wall entries the per-cell reach lists may hold (4 bytes each).
const MAX_REACH_ENTRIES: f64 = 8.0e6;

impl RayCaster {
    pub fn new(walls: &[Wall]) -> Self {
        RayCaster { walls: walls.to_vec().into(), grid: march_grid(walls), reach: OnceLock::new() }
    }

    /// How to cast `beams` beams from `p` with the per-cell reach lists, when they cover
    /// `range` and `p`.
    fn plan_with_lists(&self, p: Point2<f64>, range: f64, beams: usize) -> Option<Plan> {
        let lists = self.reach.get_or_init(|| {
            // the lists cover the map's bounding box (poses outside it use the plain grid); each
            // wall is listed in the cells within reach of it
            let (lo, hi) = crate::wall::bounds_of(&self.walls);
            let (width, height) = (hi.x - lo.x + 2.0 * CELL, hi.y - lo.y + 2.0 * CELL);
            let entries: f64 = self
                .walls
                .iter()
                .map(|w| {
                    let (dx, dy) = ((w.b.x - w.a.x).abs(), (w.b.y - w.a.y).abs());
                    (dx + 2.0 * range + 2.0 * CELL).min(width) * (dy + 2.0 * range + 2.0 * CELL).min(height)
                        / (CELL * CELL)
                })
                .sum();
            (range.is_finite() && entries <= MAX_REACH_ENTRIES)
                .then(|| ReachLists::new(&self.walls, range, KEPT_LISTS_BYTES))
        });
        let lists = lists.as_ref()?;
        if range > lists.range {
            return None;
        }
        lists.plan(&self.walls, p, beams)
    }

    pub fn walls(&self) -> &[Wall] {
        &self.walls
    }

    /// Casts beams `0, stride, 2 stride, ...` of a `beams`-beam scan with layout `g` from `pose`
    /// into `out` (one value per cast beam: the distance to the first wall, or +inf when no wall
    /// lies within `g.range_max`).
    pub fn cast(
        &self,
        pose: &Pose,
        g: &ScanGeometry,
        beams: usize,
        stride: usize,
        scratch: &mut RayScratch,
        out: &mut Vec<f64>,
    ) {
        self.cast_while(pose, g, beams, stride, usize::MAX, scratch, out, |_, _| true);
    }

    /// [`cast`](Self::cast), showing the ranges to `go_on` as they come: `go_on(out, cast)`
    /// sees the first `cast` of them final (the rest +inf) and says whether to cast more. A cast
    /// that marches its beams marches them `part` at a time, so a caller that can judge a pose
    /// on some of its beams stops early; a sweep casts every beam at once and shows them once.
    /// The way of casting is chosen as for the whole cast.
    #[allow(clippy::too_many_arguments)]
    pub fn cast_while(
        &self,
        pose: &Pose,
        g: &ScanGeometry,
        beams: usize,
        stride: usize,
        part: usize,
        scratch: &mut RayScratch,
        out: &mut Vec<f64>,
        mut go_on: impl FnMut(&[f64], usize) -> bool,
    ) {
        let stride = stride.max(1);
        scratch.prepare(g, beams, self.walls.len());
        out.clear();
        out.resize(beams.div_ceil(stride), f64::INFINITY);
        if beams == 0 || g.angle_increment == 0.0 {
            go_on(out, out.len());
            return;
        }
        let p = Point2::from(pose.translation.vector);
        let (sin, cos) = pose.rotation.angle().sin_cos();
        let to_sensor = |q: Point2<f64>| {
            let d = q - p;
            Vector2::new(cos * d.x + sin * d.y, -sin * d.x + cos * d.y)
        };
        let range = g.range_max;
        let cast_beams = out.len();
        let layout = Layout::new(g, beams, stride);
        let lo = Point2::new(p.x - range, p.y - range);
        let hi = Point2::new(p.x + range, p.y + range);
        let visit = |k: usize, scratch: &mut RayScratch, out: &mut Vec<f64>| {
            let w = &self.walls[k];
            // outside the square of side 2 range around the sensor: out of reach
            if w.a.x.max(w.b.x) < lo.x || w.a.x.min(w.b.x) > hi.x || w.a.y.max(w.b.y) < lo.y || w.a.y.min(w.b.y) > hi.y
            {
                return;
            }
            sweep(to_sensor(w.a), to_sensor(w.b), &layout, &scratch.dirs, out);
        };
        match self.plan_with_lists(p, range, cast_beams) {
            Some(Plan::Sweep(near)) => {
                near.for_each(|k| visit(k, scratch, out));
                go_on(out, out.len());
                return;
            }
            Some(Plan::March) => return self.march_in_parts(p, (sin, cos), range, stride, part, scratch, out, go_on),
            None => {}
        }
        let ((c0, r0), (c1, r1)) = self.grid.cell_range(lo, hi);
        let visit_all = (c1 - c0 + 1) * (r1 - r0 + 1) * 2 > self.grid.cell_count();
        let swept = if visit_all { self.walls.len() } else { self.grid.entries_within((c0, r0), (c1, r1)) };
        if Plan::march_pays(swept, cast_beams) {
            return self.march_in_parts(p, (sin, cos), range, stride, part, scratch, out, go_on);
        }
        let epoch = scratch.epoch;
        if visit_all {
            for k in 0..self.walls.len() {
                visit(k, scratch, out);
            }
        } else {
            for r in r0..=r1 {
                for c in c0..=c1 {
                    for &k in self.grid.walls_in(c, r) {
                        let k = k as usize;
                        if scratch.mark[k] != epoch {
                            scratch.mark[k] = epoch;
                            visit(k, scratch, out);
                        }
                    }
                }
            }
        }
        go_on(out, out.len());
    }

    /// [`march`](Self::march)es the beams `part` at a time while `go_on` says so (see
    /// [`cast_while`](Self::cast_while)).
    #[allow(clippy::too_many_arguments)]
    fn march_in_parts(
        &self,
        p: Point2<f64>,
        (sin, cos): (f64, f64),
        range: f64,
        stride: usize,
        part: usize,
        scratch: &RayScratch,
        out: &mut [f64],
        mut go_on: impl FnMut(&[f64], usize) -> bool,
    ) {
        let mut cast = 0;
        while cast < out.len() {
            let end = cast.saturating_add(part.max(1)).min(out.len());
            self.march(p, (sin, cos), range, stride, cast, scratch, &mut out[cast..end]);
            cast = end;
            if !go_on(out, cast) {
                return;
            }
        }
    }

    /// Casts each beam on its own through the wall grid, nearest cells first (jumping across
    /// empty ones), stopping at the first cell that holds a hit: cheaper than a sweep when few
    /// beams are cast among many walls (a sparse cost over a large map at a long range).
    /// `out` takes the cast beams from the `first`-th on.
    #[allow(clippy::too_many_arguments)]
    fn march(
        &self,
        p: Point2<f64>,
        (sin, cos): (f64, f64),
        range: f64,
        stride: usize,
        first: usize,
        scratch: &RayScratch,
        out: &mut [f64],
    ) {
        for (d, o) in scratch.dirs.iter().step_by(stride).skip(first).zip(out.iter_mut()) {
            let dir = Vector2::new(cos * d.x - sin * d.y, sin * d.x + cos * d.y);
            let mut best = f64::INFINITY;
            // only the cells that list a wall: an empty one holds no hit
            self.grid.march_walls(p, dir, range, |c, r, exit| {
                for &k in self.grid.walls_in(c, r) {
                    let w = &self.walls[k as usize];
                    // a wall whose line passes through the sensor is skipped, as the sweep does
                    if (w.a - p).perp(&(w.b - w.a)).abs() < 1e-12 {
                        continue;
                    }
                    if let Some(t) = w.ray_hit(p, dir) {
                        best = best.min(t);
                    }
                }
                best > exit
            });
            *o = best;
        }
    }

    /// Brute force: one ray against every wall. The reference the sweep is tested against.
    pub fn cast_ray_brute(&self, origin: Point2<f64>, angle: f64) -> f64 {
        let dir = Vector2::new(angle.cos(), angle.sin());
        self.walls.iter().filter_map(|w| w.ray_hit(origin, dir)).fold(f64::INFINITY, f64::min)
    }
}

/// Writes into `kept` the walls of `list` (a cell's walls within reach) that no single other
/// wall of `list` hides from the whole cell (corners `corners`).
///
/// A wall that one wall hides from every point of the cell is never the first hit of a beam
/// cast from the cell: every line of sight to it crosses the hiding wall first, and a wall
/// nearer than one within reach is within reach, so the hiding wall is in `list` too (or is
/// hidden in turn by one nearer still). Dropping hidden walls therefore changes no cast; in an
/// office it leaves about a third of the walls within reach, and each cast costs per wall.
///
/// Two tests that [`hides`] implies, both seen from the cell's centre, pass over most pairs
/// before its eight segment crossings: the hiding wall is nearer (the line of sight to the
/// hidden wall's nearest point crosses it first), and its angular interval holds the hidden
/// wall's. A long-range sensor has the whole map within reach of every cell, so a cell costs
/// its walls squared: they halved it.
///
/// The two tests run in `f32`, 24 bytes a wall instead of 48: a cell's working list is the
/// largest thing a localizer allocates (a whole built map's walls are within reach of a
/// long-range sensor), and what it held stays in the process. Rounding cannot change a cast:
/// a pair the rounded tests pass wrongly goes on to the exact [`hides`], and one they fail
/// wrongly leaves a wall in the list that a cast then finds hidden. Distances round up or down
/// together (rounding is monotone), so every wall nearer than another still comes before it.
fn potentially_visible(walls: &[Wall], corners: &[Point2<f64>; 4], list: &[u32], kept: &mut Vec<u32>) {
    let centre = Point2::from((corners[0].coords + corners[2].coords) / 2.0);
    // nearest first: the walls that hide others are mostly the near ones; the order of equally
    // near walls is immaterial (each takes all of them as candidates), so the sort need not be
    // stable and allocates nothing
    let mut by_distance: Vec<(f32, u32, Arc)> = list
        .iter()
        .map(|&k| (walls[k as usize].closest(centre).0 as f32, k, Arc::of(&walls[k as usize], centre)))
        .collect();
    by_distance.sort_unstable_by(|a, b| a.0.total_cmp(&b.0));
    for &(distance, k, arc) in &by_distance {
        let w = &walls[k as usize];
        let hidden = by_distance
            .iter()
            .take_while(|&&(d, _, _)| d <= distance)
            .any(|&(_, o, o_arc)| o != k && o_arc.holds(&arc) && hides(&walls[o as usize], w, corners));
        if !hidden {
            kept.push(k);
        }
    }
    kept.sort_unstable();
}

/// The directions in which a wall is seen from a point: the cone counter-clockwise from
/// `start` to `end` (the wall's ends relative to the point), less than half a turn wide; in
/// `f32`, for [`potentially_visible`]'s pre-test.
#[derive(Clone, Copy, Debug)]
struct Arc {
    start: Vector2<f32>,
    end: Vector2<f32>,
}

impl Arc {
    fn of(w: &Wall, from: Point2<f64>) -> Arc {
        let (a, b) = (w.a - from, w.b - from);
        let (a32, b32) = (a.cast::<f32>(), b.cast::<f32>());
        if a.perp(&b) >= 0.0 {
            Arc { start: a32, end: b32 }
        } else {
            Arc { start: b32, end: a32 }
        }
    }

    /// Whether direction `v` lies in the cone, with a margin that leaves borderline directions
    /// in (the exact test decides them).
    #[inline]
    fn contains(&self, v: Vector2<f32>) -> bool {
        let margin = 1e-6 * (self.start.norm_squared() + self.end.norm_squared() + v.norm_squared());
        self.start.perp(&v) >= -margin && v.perp(&self.end) >= -margin
    }

    /// Whether `other` lies within this cone: both its ends do, and the cone is convex.
    #[inline]
    fn holds(&self, other: &Arc) -> bool {
        self.contains(other.start) && self.contains(other.end)
    }
}

/// Whether every line of sight from the cell with corners `corners` to wall `w` crosses wall
/// `o` strictly inside both. The points that a segment hides from a point form a convex
/// region, so it is enough that the lines from each corner to each end of `w` cross `o`: then
/// every point of `w` is hidden from every corner, and, the points that see a given point past
/// `o` forming a convex region too, from every point of the cell.
fn hides(o: &Wall, w: &Wall, corners: &[Point2<f64>; 4]) -> bool {
    corners.iter().all(|&c| crosses(c, w.a, o) && crosses(c, w.b, o))
}

/// Whether segment [p, q] crosses wall `o` at a point strictly inside both, with a margin that
/// leaves near-grazing lines of sight unhidden.
#[inline]
fn crosses(p: Point2<f64>, q: Point2<f64>, o: &Wall) -> bool {
    let d = q - p;
    let e = o.b - o.a;
    let margin = 1e-9 * (d.norm_squared() + e.norm_squared());
    let (s1, s2) = (d.perp(&(o.a - p)), d.perp(&(o.b - p)));
    if !((s1 > margin && s2 < -margin) || (s1 < -margin && s2 > margin)) {
        return false;
    }
    let (t1, t2) = (e.perp(&(p - o.a)), e.perp(&(q - o.a)));
    (t1 > margin && t2 < -margin) || (t1 < -margin && t2 > margin)
}

/// What [`sweep`] needs of a cast's beam layout, computed once per cast rather than per wall.
#[derive(Clone, Copy, Debug)]
struct Layout {
    beams: usize,
    stride: usize,
    /// |angle increment| and its inverse.
    inc: f64,
    inverse_inc: f64,
    /// Whether beam angles increase with the index.
    increasing: bool,
    /// The smallest beam angle.
    first_angle: f64,
    /// Beams this close to an end of a wall's arc (in beams) are tested against its wedge: the
    /// margin beam, and any within fast_atan2's error of the end.
    edge: usize,
}

impl Layout {
    fn new(g: &ScanGeometry, beams: usize, stride: usize) -> Self {
        let inc = g.angle_increment.abs();
        let increasing = g.angle_increment > 0.0;
        Layout {
            beams,
            stride,
            inc,
            inverse_inc: 1.0 / inc,
            increasing,
            // beams sorted by increasing angle: index j counts from the smallest angle
            first_angle: if increasing { g.angle_min } else { g.angle(beams - 1) },
            edge: 2 + (4.0 * ATAN_ERROR / inc) as usize,
        }
    }
}

/// Fills the beams that the wall (a, b) (sensor frame) covers.
#[inline]
fn sweep(a: Vector2<f64>, b: Vector2<f64>, layout: &Layout, dirs: &[Vector2<f64>], out: &mut [f64]) {
    let e = b - a;
    let cross = a.perp(&e);
    let cross_abs = cross.abs();
    if cross_abs < 1e-12 {
        return; // the wall is seen edge-on (or passes through the sensor)
    }
    let (aa, ab) = (fast_atan2(a.y, a.x), fast_atan2(b.y, b.x));
    let mut span = ab - aa;
    if span > std::f64::consts::PI {
        span -= TAU;
    } else if span < -std::f64::consts::PI {
        span += TAU;
    }
    let start = if span >= 0.0 { aa } else { ab };
    let span = span.abs();
    let Layout { beams, stride, inc, inverse_inc, increasing, first_angle, edge } = *layout;
    let u = start - first_angle;
    let u = u - TAU * floor(u / TAU);
    let ab_cross = a.perp(&b);
    let mut fill = |from: f64, to: f64| {
        // one beam of margin each side: the angles are approximate, the wedge test is exact
        let j0 = (ceil(from * inverse_inc) - 1.0).max(0.0) as usize;
        let j1f = floor(to * inverse_inc) + 1.0;
        if j1f < 0.0 {
            return;
        }
        let j1 = (j1f as usize).min(beams - 1);
        if j0 > j1 {
            return;
        }
        let (lo, hi) = if increasing { (j0, j1) } else { (beams - 1 - j1, beams - 1 - j0) };
        let first = lo.div_ceil(stride);
        let i0 = first * stride;
        if i0 > hi {
            return;
        }
        let count = (hi - i0) / stride + 1;
        // beams near the arc's ends may lie outside the wall's angular wedge (which is narrower
        // than pi): the first `inner_from` and those from `inner_to` on are tested exactly; the
        // rest (i >= lo + edge and i + edge <= hi) are inside
        let inner_from = ((lo + edge).saturating_sub(i0)).div_ceil(stride).min(count);
        let inner_to = match (hi.checked_sub(edge)).and_then(|h| h.checked_sub(i0)) {
            Some(span) => span / stride + 1,
            None => 0,
        }
        .clamp(inner_from, count);
        let mut cast = dirs[i0..=hi].iter().step_by(stride).zip(out[first..first + count].iter_mut());
        // inside the wedge the beam crosses the wall in front of the sensor, so cross and den
        // share a sign and the distance is |cross| / |den| (+inf when den underflows);
        // branch-free, as a beam's nearest wall is unpredictable; a select, not f64::min: t is
        // never NaN (cross_abs > 0), so no NaN handling
        let nearest = |d: &Vector2<f64>, o: &mut f64| {
            let t = cross_abs / d.perp(&e).abs();
            *o = if t < *o { t } else { *o };
        };
        let in_wedge = |d: &Vector2<f64>| a.perp(d) * ab_cross >= 0.0 && d.perp(&b) * ab_cross >= 0.0;
        for (d, o) in cast.by_ref().take(inner_from) {
            if in_wedge(d) {
                nearest(d, o);
            }
        }
        for (d, o) in cast.by_ref().take(inner_to - inner_from) {
            nearest(d, o);
        }
        for (d, o) in cast {
            if in_wedge(d) {
                nearest(d, o);
            }
        }
    };
    fill(u, u + span);
    if u + span >= TAU - inc {
        fill(u - TAU, u + span - TAU);
    }
}

/// `x.floor()` for |x| < 2^52, without the library call that baseline x86-64 (no SSE4.1)
/// makes of it.
#[inline]
fn floor(x: f64) -> f64 {
    let t = x as i64 as f64;
    if t > x {
        t - 1.0
    } else {
        t
    }
}

/// `x.ceil()` for |x| < 2^52 (see [`floor`]).
#[inline]
fn ceil(x: f64) -> f64 {
    let t = x as i64 as f64;
    if t < x {
        t + 1.0
    } else {
        t
    }
}

/// The largest error of [`fast_atan2`], radians.
const ATAN_ERROR: f64 = 1e-5;

/// atan2 to about [`ATAN_ERROR`]: octant reduction and a minimax polynomial for atan on [0, 1].
#[inline]
fn fast_atan2(y: f64, x: f64) -> f64 {
    let (ax, ay) = (x.abs(), y.abs());
    let (small, large) = if ax < ay { (ax, ay) } else { (ay, ax) };
    if large == 0.0 {
        return 0.0;
    }
    let t = small / large;
    let s = t * t;
    let mut r = ((((0.0208351 * s - 0.085133) * s + 0.180141) * s - 0.3302995) * s + 0.999866) * t;
    if ay > ax {
        r = std::f64::consts::FRAC_PI_2 - r;
    }
    if x < 0.0 {
        r = std::f64::consts::PI - r;
    }
    if y < 0.0 {
        -r
    } else {
        r
    }
}

/// The walls and their grid; the per-cell reach lists are this process's own, made on the
/// first cast as for a caster built here.
impl Flat for RayCaster {
    fn put(&self, w: &mut FlatWriter) {
        self.walls.put(w);
        self.grid.put(w);
    }
    fn take(r: &mut FlatReader<'_>) -> Result<Self, FlatError> {
        let walls: Slab<Wall> = Slab::take(r)?;
        let grid = WallGrid::take(r)?;
        grid.check_walls(walls.len())?;
        Ok(RayCaster { walls, grid, reach: OnceLock::new() })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use laser::pose;
    use proptest::prelude::*;

    use crate::wall::walls_from_seed as random_walls;

    /// Whether each of `out` (beams `0, stride, ...` of `g` cast from `from` at heading `theta`)
    /// is brute force's range, both counted as +inf from `reach` on. Beams grazing a wall's end
    /// may see it or not; both are right.
    fn agrees_with_brute_force(
        caster: &RayCaster,
        (from, theta): (Point2<f64>, f64),
        g: &ScanGeometry,
        stride: usize,
        out: &[f64],
        reach: f64,
    ) -> Result<(), TestCaseError> {
        for (k, &got) in out.iter().enumerate() {
            let i = k * stride;
            let want = caster.cast_ray_brute(from, theta + g.angle(i));
            let [got, want] = [got, want].map(|d| if d < reach { d } else { f64::INFINITY });
            let grazing = caster.walls().iter().any(|w| {
                let a = theta + g.angle(i);
                let d = Vector2::new(a.cos(), a.sin());
                [w.a, w.b].iter().any(|q| {
                    let v = q - from;
                    (v.perp(&d) / v.norm().max(1e-9)).abs() < 1e-7
                })
            });
            prop_assert!(
                grazing || (got - want).abs() < 1e-7 || (got.is_infinite() && want.is_infinite()),
                "beam {}: cast {} brute {}",
                i,
                got,
                want
            );
        }
        Ok(())
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(200))]
        /// The sweep agrees with brute force on every beam, for any walls, pose and layout,
        /// both through the per-cell reach lists and (when they were built for a shorter
        /// reach) through the wall grid.
        #[test]
        fn sweep_agrees_with_brute_force(
            seed in proptest::collection::vec((-8.0f64..8.0, -8.0f64..8.0, -3.2f64..3.2, 0.05f64..6.0), 1..40),
            x in -6.0f64..6.0, y in -6.0f64..6.0, theta in -3.2f64..3.2,
            beams in 2usize..400, fov in 0.5f64..6.2, stride in 1usize..4, reverse in proptest::bool::ANY,
            shorter_lists in proptest::bool::ANY,
        ) {
            let walls = random_walls(&seed);
            let caster = RayCaster::new(&walls);
            let mut scratch = RayScratch::default();
            let mut out = Vec::new();
            if shorter_lists {
                let short = ScanGeometry::centred(beams, fov, 3.0);
                caster.cast(&pose(0.0, 0.0, 0.0), &short, beams, stride, &mut scratch, &mut out);
            }
            let mut g = ScanGeometry::centred(beams, fov, 7.0);
            if reverse {
                g.angle_min = -g.angle_min;
                g.angle_increment = -g.angle_increment;
            }
            let p = pose(x, y, theta);
            caster.cast(&p, &g, beams, stride, &mut scratch, &mut out);
            agrees_with_brute_force(&caster, (Point2::new(x, y), theta), &g, stride, &out, 7.0 + 1e-9)?;
        }
    }

    proptest! {
        #[test]
        fn floor_and_ceil_match_the_library(x in -1.0e9f64..1.0e9, k in -1000i64..1000) {
            prop_assert_eq!(floor(x), x.floor());
            prop_assert_eq!(ceil(x), x.ceil());
            let whole = k as f64;
            prop_assert_eq!(floor(whole), whole);
            prop_assert_eq!(ceil(whole), whole);
        }

        #[test]
        fn fast_atan2_is_close(y in -10.0f64..10.0, x in -10.0f64..10.0) {
            prop_assert!((fast_atan2(y, x) - y.atan2(x)).abs() < 2e-5);
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(200))]
        /// Marching each beam through the grid agrees with brute force on every beam, from
        /// inside the walls' box or outside it.
        #[test]
        fn marching_agrees_with_brute_force(
            seed in proptest::collection::vec((-8.0f64..8.0, -8.0f64..8.0, -3.2f64..3.2, 0.05f64..6.0), 1..40),
            x in -12.0f64..12.0, y in -12.0f64..12.0, theta in -3.2f64..3.2,
            beams in 2usize..200, fov in 0.5f64..6.2, stride in 1usize..4, range in 1.0f64..30.0,
        ) {
            let walls = random_walls(&seed);
            let caster = RayCaster::new(&walls);
            let g = ScanGeometry::centred(beams, fov, range);
            let mut scratch = RayScratch::default();
            scratch.prepare(&g, beams, walls.len());
            let mut out = vec![f64::INFINITY; beams.div_ceil(stride)];
            caster.march(Point2::new(x, y), (theta.sin(), theta.cos()), range, stride, 0, &scratch, &mut out);
            agrees_with_brute_force(&caster, (Point2::new(x, y), theta), &g, stride, &out, range)?;
        }

        /// Marching in parts casts what one march does, part by part, shows each part as it is
        /// cast, and casts nothing after `go_on` says stop.
        #[test]
        fn marching_in_parts_casts_the_same_and_stops_when_told(
            seed in proptest::collection::vec((-8.0f64..8.0, -8.0f64..8.0, -3.2f64..3.2, 0.05f64..6.0), 1..40),
            x in -6.0f64..6.0, y in -6.0f64..6.0, theta in -3.2f64..3.2,
            beams in 2usize..200, stride in 1usize..4, part in 1usize..20, parts_wanted in 1usize..10,
        ) {
            let walls = random_walls(&seed);
            let caster = RayCaster::new(&walls);
            let g = ScanGeometry::centred(beams, 4.0, 20.0);
            let mut scratch = RayScratch::default();
            scratch.prepare(&g, beams, walls.len());
            let cast_beams = beams.div_ceil(stride);
            let (p, sc) = (Point2::new(x, y), (theta.sin(), theta.cos()));
            let mut whole = vec![f64::INFINITY; cast_beams];
            caster.march(p, sc, 20.0, stride, 0, &scratch, &mut whole);
            let mut parts = vec![f64::INFINITY; cast_beams];
            // each time it is shown: how many are cast, whether those are the whole march's
            // and the rest still +inf
            let mut shown = Vec::new();
            caster.march_in_parts(p, sc, 20.0, stride, part, &scratch, &mut parts, |out, cast| {
                shown.push((cast, out[..cast] == whole[..cast], out[cast..].iter().all(|d| d.is_infinite())));
                shown.len() < parts_wanted
            });
            for (k, &(cast, same, rest)) in shown.iter().enumerate() {
                prop_assert_eq!(cast, ((k + 1) * part).min(cast_beams));
                prop_assert!(same && rest, "part {}", k);
            }
            let last = shown.last().map_or(0, |s| s.0);
            prop_assert_eq!(last, (parts_wanted * part).min(cast_beams));
            prop_assert_eq!(&parts[..last], &whole[..last]);
            prop_assert!(parts[last..].iter().all(|d| d.is_infinite()));
        }
    }

    /// `n` walls scattered over a square of side `side` about the origin, by fixed steps:
    /// wall k starts at ((k ax) mod side, (k ay) mod side) less half the side, at heading
    /// k turn, 0.5 + (k grow) mod most long.
    fn scattered_walls(n: u32, side: f64, [ax, ay, turn, grow, most]: [f64; 5]) -> Vec<Wall> {
        let seed: Vec<(f64, f64, f64, f64)> = (0..n)
            .map(|k| {
                let k = f64::from(k);
                ((k * ax) % side - side / 2.0, (k * ay) % side - side / 2.0, k * turn, 0.5 + (k * grow) % most)
            })
            .collect();
        random_walls(&seed)
    }

    /// At a long reach a cell's list is filtered only once the beams marched from it have cost
    /// [`FILTER_AFTER`] times what filtering it does; the casts agree before and after.
    #[test]
    fn a_cell_is_marched_from_until_filtering_it_pays() {
        let walls = scattered_walls(120, 30.0, [7.3, 3.1, 0.7, 1.3, 4.0]);
        let caster = RayCaster::new(&walls);
        // few beams a cast: marching them costs less than filtering the cell's list, at first
        let beams = 12;
        let g = ScanGeometry::centred(beams, TAU * 11.0 / 12.0, 60.0);
        let p = pose(0.3, 0.4, 0.2);
        let mut scratch = RayScratch::default();
        let (mut first, mut out) = (Vec::new(), Vec::new());
        caster.cast(&p, &g, beams, 1, &mut scratch, &mut first);
        let lists = caster.reach.get().and_then(Option::as_ref).expect("reach lists for 60 m");
        let (c, r) = lists.within.cell_of(Point2::new(0.3, 0.4)).unwrap();
        let cell = lists.within.cell_index(c, r);
        let unfiltered = lists.count(&walls, c, r) as f64;
        let casts_to_pay =
            FILTER_AFTER * unfiltered * unfiltered * FILTER_NS_PER_PAIR / (beams as f64 * MARCH_NS_PER_BEAM);
        assert!(casts_to_pay > 3.0, "{casts_to_pay}");
        for _ in 1..casts_to_pay.floor() as usize - 1 {
            assert!(!lists.keeps(cell), "filtered before marching cost as much");
            caster.cast(&p, &g, beams, 1, &mut scratch, &mut out);
            assert_eq!(out, first);
        }
        for _ in 0..3 {
            caster.cast(&p, &g, beams, 1, &mut scratch, &mut out);
        }
        assert!(lists.keeps(cell), "still not filtered");
        for (a, b) in out.iter().zip(&first) {
            assert!((a - b).abs() < 1e-9 || (a.is_infinite() && b.is_infinite()), "{a} {b}");
        }
    }

    impl ReachLists {
        fn keeps(&self, cell: usize) -> bool {
            self.kept.lock().unwrap().slot[cell] != NOT_KEPT
        }
    }

    /// The kept lists stay within their budget: the least recently used list makes room, and
    /// its cell pays for filtering again (its marched beams start over). Casts give the same
    /// ranges with any budget.
    #[test]
    fn kept_lists_stay_within_their_budget_dropping_the_least_recently_used() {
        let walls = scattered_walls(80, 16.0, [7.3, 3.1, 0.7, 1.3, 4.0]);
        let whole = ReachLists::filtering_eagerly_up_to(&walls, 30.0, 0.0, usize::MAX);
        let cells: Vec<(usize, usize)> = (0..4).map(|k| (2 + 3 * k, 5)).collect();
        let sizes: Vec<usize> = cells.iter().map(|&(c, r)| whole.visible_in(&walls, c, r).bytes()).collect();
        // room for the largest two lists, not for three
        let mut by_size = sizes.clone();
        by_size.sort_unstable();
        let budget = by_size[3] + by_size[2];
        assert!(by_size[0] + by_size[1] + by_size[2] > budget);
        let small = ReachLists::filtering_eagerly_up_to(&walls, 30.0, 0.0, budget);
        let index = |(c, r): (usize, usize)| small.within.cell_index(c, r);
        small.marched[index(cells[1])].store(1000, Ordering::Relaxed);
        small.visible_in(&walls, cells[0].0, cells[0].1);
        small.visible_in(&walls, cells[1].0, cells[1].1);
        // the first is used again, so the second is the least recently used
        assert!(small.kept.lock().unwrap().get(index(cells[0])).is_some());
        small.visible_in(&walls, cells[2].0, cells[2].1);
        assert!(small.keeps(index(cells[2])), "the newest list is kept");
        assert!(!small.keeps(index(cells[1])), "the least recently used list made room");
        assert_eq!(small.marched[index(cells[1])].load(Ordering::Relaxed), 0, "its cell pays again");
        for &(c, r) in &cells {
            small.visible_in(&walls, c, r);
            let kept = small.kept.lock().unwrap();
            assert!(kept.bytes <= budget, "{} bytes kept, budget {budget}", kept.bytes);
            assert_eq!(kept.bytes, kept.lists.iter().map(|k| k.list.bytes()).sum::<usize>());
            assert!(kept.lists.iter().enumerate().all(|(k, l)| kept.slot[l.cell as usize] == k as u16));
        }
        for &(c, r) in &cells {
            assert_eq!(small.visible_in(&walls, c, r).to_vec(), whole.visible_in(&walls, c, r).to_vec());
        }
    }

    /// A budget with room for more lists than a cell's slot can number keeps at most
    /// [`MOST_KEPT`], dropping the least recently used, and every slot still points at its list.
    #[test]
    fn no_more_lists_are_kept_than_a_slot_can_number() {
        let cells = MOST_KEPT + 10;
        let mut kept = KeptLists::new(cells, usize::MAX);
        let mut dropped = Vec::new();
        for cell in 0..cells {
            let list = Shared::new(WallList::new(&[cell as u32 % 7], 8));
            kept.keep(cell, list, &mut dropped);
        }
        assert_eq!(kept.lists.len(), MOST_KEPT);
        assert_eq!(dropped, (0..10).collect::<Vec<_>>(), "the oldest made room");
        assert!(kept.lists.iter().enumerate().all(|(k, l)| kept.slot[l.cell as usize] == k as u16));
        assert!((0..10).all(|cell| kept.slot[cell] == NOT_KEPT));
        assert_eq!(kept.get(cells - 1).map(|l| l.to_vec()), Some(vec![(cells as u32 - 1) % 7]));
    }

    /// A caster whose lists hold a few cells at a time casts as one that keeps every cell's.
    #[test]
    fn a_small_budget_changes_no_cast() {
        let walls = scattered_walls(60, 20.0, [5.3, 2.9, 0.9, 1.7, 3.0]);
        let caster = RayCaster::new(&walls);
        let lists = ReachLists::filtering_eagerly_up_to(&walls, 40.0, 0.0, 600);
        caster.reach.set(Some(lists)).unwrap();
        let g = ScanGeometry::centred(181, TAU * 0.75, 40.0);
        let mut scratch = RayScratch::default();
        let mut out = Vec::new();
        for k in 0..200 {
            let k = f64::from(k);
            let (x, y, theta) = ((k * 1.37) % 18.0 - 9.0, (k * 0.71) % 18.0 - 9.0, k * 0.3);
            caster.cast(&pose(x, y, theta), &g, 181, 1, &mut scratch, &mut out);
            agrees_with_brute_force(&caster, (Point2::new(x, y), theta), &g, 1, &out, 40.0)
                .map_err(|e| format!("pose {k}: {e}"))
                .unwrap();
        }
        let reach = caster.reach.get().and_then(Option::as_ref).unwrap();
        let kept = reach.kept.lock().unwrap();
        assert!(kept.bytes <= 600 && !kept.lists.is_empty(), "{} bytes in {} lists", kept.bytes, kept.lists.len());
    }

    /// A cell's list filtered on first use is the one filtered when the lists are set up.
    #[test]
    fn lazy_and_eager_lists_agree() {
        let walls = scattered_walls(80, 16.0, [7.3, 3.1, 0.7, 1.3, 4.0]);
        let eager = ReachLists::filtering_eagerly_up_to(&walls, 30.0, f64::INFINITY, usize::MAX);
        let lazy = ReachLists::filtering_eagerly_up_to(&walls, 30.0, 0.0, usize::MAX);
        let cells = eager.within.cell_count();
        assert!((0..cells).all(|cell| eager.keeps(cell)));
        assert!((0..cells).all(|cell| !lazy.keeps(cell)));
        let mut hidden = 0;
        for r in 0..eager.within.rows() {
            for c in 0..eager.within.cols() {
                let (a, b) = (eager.visible_in(&walls, c, r).to_vec(), lazy.visible_in(&walls, c, r).to_vec());
                assert_eq!(a, b);
                hidden += eager.count(&walls, c, r) - a.len();
            }
        }
        assert!(hidden > 0, "some walls are hidden somewhere");
    }

    /// The visibility lists with the distance and arc tests are those of testing every pair.
    #[test]
    fn the_quick_tests_change_no_visibility_list() {
        let mut runner = proptest::test_runner::TestRunner::new(ProptestConfig::with_cases(300));
        let strategy = (
            proptest::collection::vec((-8.0f64..8.0, -8.0f64..8.0, -3.2f64..3.2, 0.05f64..6.0), 1..60),
            -6.0f64..6.0,
            -6.0f64..6.0,
            0.1f64..2.0,
        );
        runner
            .run(&strategy, |(seed, x, y, cell)| {
                let walls = random_walls(&seed);
                let corners = [
                    Point2::new(x, y),
                    Point2::new(x + cell, y),
                    Point2::new(x + cell, y + cell),
                    Point2::new(x, y + cell),
                ];
                let list: Vec<u32> = (0..walls.len() as u32).collect();
                let mut quick = Vec::new();
                potentially_visible(&walls, &corners, &list, &mut quick);
                let every_pair: Vec<u32> = list
                    .iter()
                    .copied()
                    .filter(|&k| {
                        !list.iter().any(|&o| o != k && hides(&walls[o as usize], &walls[k as usize], &corners))
                    })
                    .collect();
                prop_assert_eq!(quick, every_pair);
                Ok(())
            })
            .unwrap();
    }

    /// A filtered list holds its indices in two bytes while the map's walls all fit, in four
    /// beyond, and gives the same indices either way.
    #[test]
    fn a_wall_list_is_as_narrow_as_the_map_allows() {
        let kept = [0u32, 7, 65_535];
        let short = WallList::new(&kept, 65_536);
        assert!(matches!(short, WallList::Short(_)));
        assert_eq!(short.to_vec(), kept);
        let kept = [0u32, 7, 65_536];
        let long = WallList::new(&kept, 65_537);
        assert!(matches!(long, WallList::Long(_)));
        assert_eq!((long.to_vec(), long.len()), (kept.to_vec(), 3));
    }

    /// From inside a room, a wall behind the room's wall is dropped from the cell's list, and
    /// kept when a door in that wall lets the sensor see it.
    #[test]
    fn walls_hidden_from_a_whole_cell_are_not_listed() {
        let room = |right: &[Wall]| {
            let mut walls = vec![
                Wall::new(-2.0, -2.0, 2.0, -2.0),
                Wall::new(2.0, 2.0, -2.0, 2.0),
                Wall::new(-2.0, 2.0, -2.0, -2.0),
                // behind the right wall
                Wall::new(4.0, -1.0, 4.0, 1.0),
            ];
            walls.extend_from_slice(right);
            walls
        };
        let listed = |walls: &[Wall]| {
            let lists = ReachLists::new(walls, 7.0, usize::MAX);
            let (c, r) = lists.within.cell_of(Point2::new(0.5, 0.5)).expect("on the grid");
            lists.visible_in(walls, c, r).to_vec()
        };
        let closed = listed(&room(&[Wall::new(2.0, -2.0, 2.0, 2.0)]));
        assert_eq!(closed, vec![0, 1, 2, 4], "the wall behind the closed room is hidden");
        let with_door = listed(&room(&[Wall::new(2.0, -2.0, 2.0, -0.3), Wall::new(2.0, 0.3, 2.0, 2.0)]));
        assert_eq!(with_door, vec![0, 1, 2, 3, 4, 5], "seen through the door");
    }

    #[test]
    fn square_room_from_its_centre() {
        let walls = vec![
            Wall::new(-2.0, -2.0, 2.0, -2.0),
            Wall::new(2.0, -2.0, 2.0, 2.0),
            Wall::new(2.0, 2.0, -2.0, 2.0),
            Wall::new(-2.0, 2.0, -2.0, -2.0),
        ];
        let caster = RayCaster::new(&walls);
        let g = ScanGeometry::centred(361, TAU * 360.0 / 361.0, 10.0);
        let mut out = Vec::new();
        caster.cast(&pose(0.0, 0.0, 0.0), &g, 361, 1, &mut RayScratch::default(), &mut out);
        for (i, &d) in out.iter().enumerate() {
            let a = g.angle(i);
            let want = 2.0 / a.cos().abs().max(a.sin().abs());
            assert!((d - want).abs() < 1e-9, "beam {i}: {d} vs {want}");
        }
    }
}
