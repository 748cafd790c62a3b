//! Walls from an occupancy raster: the faces of the occupied cells that look onto free ones,
//! traced along the cell edges and simplified into straight walls.
//!
//! A laser sees a wall's face, and in an occupancy grid the face is where occupied cells meet
//! free ones; so only those cell edges become walls. Where occupied cells meet unknown ones
//! (the inside of a thick wall, the far side of the building's outer wall) nothing was seen,
//! and where free cells meet unknown ones (the edge of what the survey explored, a door into a
//! room it never entered) there is no wall; but an unknown cell touching an occupied one is
//! taken as occupied first ([`close_fringes`]), since hits smear across cell edges.
//!
//! The outlines are traced around everything that is not free, with the free cells on the
//! right; where two such cells touch only at a corner the outline turns right, so a wall drawn
//! diagonally (a staircase of cells touching at their corners) is one outline, not a chain of
//! single cells. Each stretch of an outline that faces free cells from occupied ones is
//! simplified by Douglas-Peucker to within a tolerance, keeping the points where it turns back
//! round the end of a thin wall, pieces are joined across bumps (where
//! nine tenths of what they replace lies within the tolerance), each piece is refitted by
//! total least squares to the boundary points it replaces and set half a cell behind the cell
//! edge ([`TraceConfig::face_depth`]), and neighbouring pieces meet where their lines cross.

/// What a cell of an occupancy grid says.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Cell {
    Free,
    Occupied,
    Unknown,
}

/// A raster of `width` x `height` cells, row 0 at the bottom (y grows with the row); cell
/// (c, r) is `cells[r * width + c]`.
#[derive(Clone, Copy, Debug)]
pub struct Raster<'a> {
    pub width: usize,
    pub height: usize,
    pub cells: &'a [Cell],
}

impl Raster<'_> {
    /// The cell at (c, r), `None` off the raster.
    pub(crate) fn at(&self, c: i64, r: i64) -> Option<Cell> {
        let inside = c >= 0 && r >= 0 && (c as usize) < self.width && (r as usize) < self.height;
        inside.then(|| self.cells[r as usize * self.width + c as usize])
    }

    /// Whether (c, r) is on the raster and not free: what the outlines go around.
    fn solid(&self, c: i64, r: i64) -> bool {
        self.at(c, r).is_some_and(|x| x != Cell::Free)
    }
}

/// How outlines become walls.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TraceConfig {
    /// Largest distance of a boundary point from the wall that replaces it, in cells (the
    /// Douglas-Peucker tolerance; pieces are then joined where nine tenths of the outline
    /// they replace stays within it and none strays past four times it). A staircase of cells
    /// drawing a diagonal wall strays 0.7 cells from it, and a SLAM map's walls are ragged by a
    /// cell.
    pub tolerance: f64,
    /// Outlines enclosing fewer cells than this are noise (a speck, a pinhole) and give no walls.
    pub min_cells: f64,
    /// How far behind a face's cell edge the surface is taken to be, in cells. A cell is
    /// occupied when a surface (a beam's end) lies anywhere in it, so the edge of the cell
    /// facing the free space stands in front of the surface by half a cell on average.
    pub face_depth: f64,
}

impl Default for TraceConfig {
    fn default() -> Self {
        TraceConfig { tolerance: 1.5, min_cells: 3.0, face_depth: 0.5 }
    }
}

/// Share of a path's length that must lie within the tolerance of a wall for the wall to
/// replace it ([`join_pieces`]).
const JOIN_SHARE: f64 = 0.9;

/// How far (in tolerances) any of a path may stray from a wall that replaces it.
const JOIN_REACH: f64 = 4.0;

/// Unit steps east, north, west and south on the lattice of cell corners.
const STEPS: [(i64, i64); 4] = [(1, 0), (0, 1), (-1, 0), (0, -1)];

/// One closed outline around cells that are not free.
#[derive(Clone, Debug, PartialEq)]
pub struct Outline {
    /// The cell corners it passes (in cell units, corner (i, j) at x = i, y = j), the cells it
    /// goes around on the left; it closes from the last back to the first.
    pub points: Vec<(i64, i64)>,
    /// Whether the edge from `points[k]` to the next is a face: an occupied cell on its left, a
    /// free one on its right.
    pub faces: Vec<bool>,
}

/// The outlines of the raster's cells that are not free. Outer boundaries run
/// counter-clockwise, holes (free space enclosed) clockwise.
pub fn outlines(raster: &Raster<'_>) -> Vec<Outline> {
    let (w, h) = (raster.width as i64, raster.height as i64);
    let vertex = |i: i64, j: i64| (j * (w + 1) + i) as usize;
    // out-going boundary edges of each lattice corner, one bit per direction
    let mut out = vec![0u8; ((w + 1) * (h + 1)) as usize];
    for r in 0..h {
        for c in 0..w {
            if !raster.solid(c, r) {
                continue;
            }
            if !raster.solid(c, r - 1) {
                out[vertex(c, r)] |= 1 << 0;
            }
            if !raster.solid(c + 1, r) {
                out[vertex(c + 1, r)] |= 1 << 1;
            }
            if !raster.solid(c, r + 1) {
                out[vertex(c + 1, r + 1)] |= 1 << 2;
            }
            if !raster.solid(c - 1, r) {
                out[vertex(c, r + 1)] |= 1 << 3;
            }
        }
    }
    let mut loops = Vec::new();
    for j in 0..=h {
        for i in 0..=w {
            while out[vertex(i, j)] != 0 {
                let d0 = out[vertex(i, j)].trailing_zeros() as usize;
                let points = trace_from((i, j), d0, &mut out, vertex);
                let faces = (0..points.len())
                    .map(|k| {
                        let (a, b) = (points[k], points[(k + 1) % points.len()]);
                        // the cells left and right of the edge a -> b
                        let (dx, dy) = (b.0 - a.0, b.1 - a.1);
                        let (cx, cy) = (a.0.min(b.0), a.1.min(b.1));
                        let (left, right) = match (dx, dy) {
                            (1, 0) => ((cx, cy), (cx, cy - 1)),
                            (-1, 0) => ((cx, cy - 1), (cx, cy)),
                            (0, 1) => ((cx - 1, cy), (cx, cy)),
                            _ => ((cx, cy), (cx - 1, cy)),
                        };
                        raster.at(left.0, left.1) == Some(Cell::Occupied)
                            && raster.at(right.0, right.1) == Some(Cell::Free)
                    })
                    .collect();
                loops.push(Outline { points, faces });
            }
        }
    }
    loops
}

/// Follows the outline that leaves `start` in direction `d0`, consuming its edges: at each
/// corner the right turn first (it joins cells that touch at a corner), then straight on, then
/// left. Every corner passed is listed.
fn trace_from(start: (i64, i64), d0: usize, out: &mut [u8], vertex: impl Fn(i64, i64) -> usize) -> Vec<(i64, i64)> {
    let mut points = vec![start];
    let (mut v, mut d) = (start, d0);
    loop {
        v = (v.0 + STEPS[d].0, v.1 + STEPS[d].1);
        let edges = out[vertex(v.0, v.1)];
        // every corner an outline reaches has an edge leaving it: in-degree equals out-degree
        let Some(next) = [(d + 3) % 4, d, (d + 1) % 4].into_iter().find(|&n| edges & (1 << n) != 0) else {
            break;
        };
        if v == start && next == d0 {
            break;
        }
        out[vertex(v.0, v.1)] &= !(1 << next);
        points.push(v);
        d = next;
    }
    out[vertex(start.0, start.1)] &= !(1 << d0);
    points
}

/// Twice the signed area of a closed loop (shoelace).
fn twice_area(points: &[(i64, i64)]) -> i64 {
    let n = points.len();
    (0..n).map(|k| points[k].0 * points[(k + 1) % n].1 - points[(k + 1) % n].0 * points[k].1).sum()
}

/// The raster with every unknown cell that touches an occupied one (of its eight neighbours)
/// occupied. A survey's hits smear across cell boundaries: a wall's occupied cells are often
/// fringed with unknown ones, between them and the free space, and a face the survey missed
/// for a cell leaves an unknown cell in the wall's line; either would otherwise cost the
/// face its wall.
pub fn close_fringes(raster: &Raster<'_>) -> Vec<Cell> {
    let occupied = |c: i64, r: i64| raster.at(c, r) == Some(Cell::Occupied);
    (0..raster.width * raster.height)
        .map(|i| {
            let (c, r) = ((i % raster.width) as i64, (i / raster.width) as i64);
            let cell = raster.cells[i];
            let touches = (-1..=1).any(|dr| (-1..=1).any(|dc| (dc, dr) != (0, 0) && occupied(c + dc, r + dr)));
            if cell == Cell::Unknown && touches {
                Cell::Occupied
            } else {
                cell
            }
        })
        .collect()
}

/// The walls of the raster's faces, in cell units: `(x1, y1, x2, y2)`, the free side on the
/// right of each wall's direction. Unknown cells touching occupied ones are taken as occupied
/// first ([`close_fringes`]).
pub fn walls(raster: &Raster<'_>, cfg: &TraceConfig) -> Vec<[f64; 4]> {
    let fringed = close_fringes(raster);
    let raster = &Raster { cells: &fringed, ..*raster };
    let mut walls = Vec::new();
    for outline in outlines(raster) {
        if (twice_area(&outline.points).abs() as f64) < 2.0 * cfg.min_cells {
            continue;
        }
        let n = outline.points.len();
        let point = |k: usize| {
            let (i, j) = outline.points[k % n];
            [i as f64, j as f64]
        };
        let vertices: Vec<Vec<[f64; 2]>> = match outline.faces.iter().position(|&f| !f) {
            None => vec![polyline(&turning_points((0..n).map(point), true), true, cfg)],
            // the stretches of faces, from an edge that is none
            Some(gap) => {
                let mut stretches = Vec::new();
                let mut k = gap;
                while k < gap + n {
                    if !outline.faces[k % n] {
                        k += 1;
                        continue;
                    }
                    let first = k;
                    while k < gap + n && outline.faces[k % n] {
                        k += 1;
                    }
                    stretches.push(polyline(&turning_points((first..=k).map(point), false), false, cfg));
                }
                stretches
            }
        };
        let all_faces = outline.faces.iter().all(|&f| f);
        for v in &vertices {
            let count = if all_faces { v.len() } else { v.len().saturating_sub(1) };
            for k in 0..count {
                let (a, b) = (v[k], v[(k + 1) % v.len()]);
                if (a[0] - b[0]).hypot(a[1] - b[1]) > 1e-9 {
                    walls.push([a[0], a[1], b[0], b[1]]);
                }
            }
        }
    }
    walls
}

/// The points where a path of unit steps turns (and, for an open one, its two ends).
fn turning_points(points: impl Iterator<Item = [f64; 2]>, closed: bool) -> Vec<[f64; 2]> {
    let all: Vec<[f64; 2]> = points.collect();
    let n = all.len();
    let direction = |a: [f64; 2], b: [f64; 2]| [b[0] - a[0], b[1] - a[1]];
    (0..n)
        .filter(|&k| {
            if !closed && (k == 0 || k + 1 == n) {
                return true;
            }
            let (prev, next) = (all[(k + n - 1) % n], all[(k + 1) % n]);
            direction(prev, all[k]) != direction(all[k], next)
        })
        .map(|k| all[k])
        .collect()
}

/// The vertices of the walls replacing a path: simplified, then refitted.
fn polyline(points: &[[f64; 2]], closed: bool, cfg: &TraceConfig) -> Vec<[f64; 2]> {
    let back = u_turns(points, closed);
    let (kept, anchors) = if closed {
        simplify_closed(points, &back, cfg.tolerance)
    } else {
        (simplify_open(points, &back, cfg.tolerance), back)
    };
    let kept = join_pieces(points, kept, &anchors, closed, cfg.tolerance);
    refit(points, &kept, closed, cfg.tolerance, cfg.face_depth)
}

/// Length of outline, in cells, either side of a point over which [`u_turns`] judges its
/// direction: longer than a staircase's steps and a bump, shorter than a wall's face.
const TURN_WINDOW: f64 = 3.0;

/// The points where the path turns back on itself (by more than 120 degrees within
/// [`TURN_WINDOW`] cells either side): the end of a wall body one or two cells thick, where
/// its outline comes round from one face to the other. Douglas-Peucker would take the two
/// faces, closer than its tolerance, for one line along the body's diagonal; so these points
/// are kept.
fn u_turns(points: &[[f64; 2]], closed: bool) -> Vec<usize> {
    let n = points.len();
    let length = |a: [f64; 2], b: [f64; 2]| (b[0] - a[0]).hypot(b[1] - a[1]);
    // the point `TURN_WINDOW` along the path from `k`, going `forward` or back
    let reach = |k: usize, forward: bool| -> Option<[f64; 2]> {
        let (mut at, mut walked) = (k, 0.0);
        for _ in 0..n {
            let next = match (forward, closed) {
                (true, true) => (at + 1) % n,
                (false, true) => (at + n - 1) % n,
                (true, false) => (at + 1 < n).then_some(at + 1)?,
                (false, false) => at.checked_sub(1)?,
            };
            walked += length(points[at], points[next]);
            at = next;
            if walked >= TURN_WINDOW {
                return Some(points[at]);
            }
        }
        None
    };
    (0..n)
        .filter(|&k| {
            let (Some(back), Some(ahead)) = (reach(k, false), reach(k, true)) else {
                return false;
            };
            let p = points[k];
            let (u, v) = ([p[0] - back[0], p[1] - back[1]], [ahead[0] - p[0], ahead[1] - p[1]]);
            let norms = u[0].hypot(u[1]) * v[0].hypot(v[1]);
            norms > 0.0 && (u[0] * v[0] + u[1] * v[1]) < -0.5 * norms
        })
        .collect()
}

/// Drops kept points (never an anchor, nor an open path's ends) while the path between the
/// two neighbouring kept points lies along the chord joining them: at least
/// [`JOIN_SHARE`] of its length within `tolerance` of it, and none of it farther than
/// [`JOIN_REACH`] times `tolerance`. A SLAM map's face carries bumps and dents of a cell or
/// two (a person who stood by the wall, a few missed hits) that Douglas-Peucker keeps as
/// corners; a door recess or a jamb at a wall's end moves too much of the path off the chord
/// to be dropped.
fn join_pieces(
    points: &[[f64; 2]],
    mut kept: Vec<usize>,
    anchors: &[usize],
    closed: bool,
    tolerance: f64,
) -> Vec<usize> {
    let n = points.len();
    loop {
        let m = kept.len();
        if m < if closed { 4 } else { 3 } {
            return kept;
        }
        let inner = if closed { 0..m } else { 1..m - 1 };
        let joinable = inner.into_iter().filter(|&j| !anchors.contains(&kept[j])).find(|&j| {
            let (i, k) = (kept[(j + m - 1) % m], kept[(j + 1) % m]);
            let last = if k <= i { k + n } else { k };
            let (mut near, mut total) = (0.0, 0.0);
            for q in i..last {
                let (a, b) = (points[q % n], points[(q + 1) % n]);
                let (da, db) =
                    (distance_to_segment(a, points[i], points[k]), distance_to_segment(b, points[i], points[k]));
                if da.max(db) > JOIN_REACH * tolerance {
                    return false;
                }
                let length = (b[0] - a[0]).hypot(b[1] - a[1]);
                total += length;
                if da.max(db) <= tolerance {
                    near += length;
                }
            }
            near >= JOIN_SHARE * total
        });
        match joinable {
            Some(j) => {
                kept.remove(j);
            }
            None => return kept,
        }
    }
}

/// Distance from `p` to the segment `a`-`b`.
fn distance_to_segment(p: [f64; 2], a: [f64; 2], b: [f64; 2]) -> f64 {
    let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
    let len2 = dx * dx + dy * dy;
    let t = if len2 > 0.0 { (((p[0] - a[0]) * dx + (p[1] - a[1]) * dy) / len2).clamp(0.0, 1.0) } else { 0.0 };
    (p[0] - a[0] - t * dx).hypot(p[1] - a[1] - t * dy)
}

/// Douglas-Peucker over a closed loop: the indices of the points kept, in order, and the
/// anchors among them. The loop is first split at four anchors, which are always kept: its first point, the point farthest from
/// it, and the point of each half farthest from the chord between those two. A wall body
/// thinner than the tolerance (a wall one cell thick) keeps its four corners that way, where
/// two halves would each lie within the tolerance of the body's diagonal.
fn simplify_closed(points: &[[f64; 2]], turns: &[usize], tolerance: f64) -> (Vec<usize>, Vec<usize>) {
    let n = points.len();
    if n <= 4 {
        return ((0..n).collect(), (0..n).collect());
    }
    let dist = |k: usize| (points[k][0] - points[0][0]).hypot(points[k][1] - points[0][1]);
    let far = (1..n).max_by(|&a, &b| dist(a).total_cmp(&dist(b))).unwrap_or(n / 2);
    let off_chord = |range: std::ops::Range<usize>| {
        range.max_by(|&a, &b| {
            distance_to_segment(points[a], points[0], points[far]).total_cmp(&distance_to_segment(
                points[b],
                points[0],
                points[far],
            ))
        })
    };
    let mut anchors = vec![0, far, n];
    anchors.extend(off_chord(1..far));
    anchors.extend(off_chord(far + 1..n));
    anchors.extend_from_slice(turns);
    anchors.sort_unstable();
    anchors.dedup();
    let kept = douglas_peucker(points, anchors.windows(2).map(|w| (w[0], w[1])).collect(), tolerance);
    anchors.pop();
    (kept, anchors)
}

/// Douglas-Peucker over an open path: the indices kept, both ends and `turns` among them.
fn simplify_open(points: &[[f64; 2]], turns: &[usize], tolerance: f64) -> Vec<usize> {
    match points.len() {
        0 => Vec::new(),
        1 => vec![0],
        n => {
            let mut anchors = vec![0, n - 1];
            anchors.extend_from_slice(turns);
            anchors.sort_unstable();
            anchors.dedup();
            douglas_peucker(points, anchors.windows(2).map(|w| (w[0], w[1])).collect(), tolerance)
        }
    }
}

/// [`map::simplify::douglas_peucker`] over the traced points.
fn douglas_peucker(points: &[[f64; 2]], spans: Vec<(usize, usize)>, tolerance: f64) -> Vec<usize> {
    let points: Vec<nalgebra::Point2<f64>> = points.iter().map(|p| nalgebra::Point2::new(p[0], p[1])).collect();
    map::simplify::douglas_peucker(&points, spans, tolerance)
}

/// A line fitted by total least squares ([`laser::fit`]): a point on it and its unit direction.
fn fit_line(points: impl Iterator<Item = [f64; 2]>) -> Option<([f64; 2], [f64; 2])> {
    let mut m = laser::fit::Moments::default();
    points.for_each(|p| m.add(nalgebra::Point2::new(p[0], p[1])));
    m.fit().map(|f| ([f.centroid.x, f.centroid.y], [f.direction.x, f.direction.y]))
}

/// The path's vertices after each simplified piece is refitted to the points it replaced and
/// moved `depth` to its left (behind the face): an inner vertex is where its two pieces' lines
/// cross, when they cross at a clear angle near the simplified vertex (otherwise the mean of
/// the simplified vertex's places on the two lines); an open path's ends are placed on their
/// piece's line.
fn refit(points: &[[f64; 2]], kept: &[usize], closed: bool, tolerance: f64, depth: f64) -> Vec<[f64; 2]> {
    let n = points.len();
    let m = kept.len();
    if m < 2 || (closed && m < 3) {
        return kept.iter().map(|&k| points[k]).collect();
    }
    let pieces = if closed { m } else { m - 1 };
    // the line of the piece from kept[k] to kept[k + 1], over the points between them
    let lines: Vec<Option<([f64; 2], [f64; 2])>> = (0..pieces)
        .map(|k| {
            let (first, mut last) = (kept[k], kept[(k + 1) % m]);
            if last <= first {
                last += n;
            }
            // directed from the piece's first point to its last, and moved to its left
            let (a, b) = (points[first], points[last % n]);
            fit_line((first..=last).map(|i| points[i % n])).map(|(q, u)| {
                let u = if u[0] * (b[0] - a[0]) + u[1] * (b[1] - a[1]) < 0.0 { [-u[0], -u[1]] } else { u };
                ([q[0] - depth * u[1], q[1] + depth * u[0]], u)
            })
        })
        .collect();
    let project = |p: [f64; 2], line: Option<([f64; 2], [f64; 2])>| match line {
        Some((q, u)) => {
            let t = (p[0] - q[0]) * u[0] + (p[1] - q[1]) * u[1];
            [q[0] + t * u[0], q[1] + t * u[1]]
        }
        None => p,
    };
    (0..m)
        .map(|k| {
            let corner = points[kept[k]];
            if !closed && k == 0 {
                return project(corner, lines[0]);
            }
            if !closed && k == m - 1 {
                return project(corner, lines[pieces - 1]);
            }
            let (before, after) = (lines[(k + pieces - 1) % pieces], lines[k % pieces]);
            let (Some((p, u)), Some((q, v))) = (before, after) else {
                return corner;
            };
            let (on_before, on_after) = (project(corner, before), project(corner, after));
            let between = [(on_before[0] + on_after[0]) / 2.0, (on_before[1] + on_after[1]) / 2.0];
            let cross = u[0] * v[1] - u[1] * v[0];
            // lines within 20 degrees of each other cross far from any corner, or not at all
            if cross.abs() < 20f64.to_radians().sin() {
                return between;
            }
            let t = ((q[0] - p[0]) * v[1] - (q[1] - p[1]) * v[0]) / cross;
            let x = [p[0] + t * u[0], p[1] + t * u[1]];
            if (x[0] - corner[0]).hypot(x[1] - corner[1]) <= tolerance {
                x
            } else {
                between
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// Occupied where `occupied` says, free elsewhere.
    fn raster(width: usize, height: usize, occupied: impl Fn(usize, usize) -> bool) -> Vec<Cell> {
        (0..width * height).map(|i| if occupied(i % width, i / width) { Cell::Occupied } else { Cell::Free }).collect()
    }

    #[test]
    fn a_block_is_one_counter_clockwise_outline_of_four_corners() {
        let cells = raster(6, 5, |c, r| (1..4).contains(&c) && (2..4).contains(&r));
        let loops = outlines(&Raster { width: 6, height: 5, cells: &cells });
        assert_eq!(loops.len(), 1);
        let points = &loops[0].points;
        assert_eq!(points.len(), 10);
        assert_eq!(points[..4], [(1, 2), (2, 2), (3, 2), (4, 2)]);
        assert!(loops[0].faces.iter().all(|&f| f));
        let corners = turning_points(points.iter().map(|&(i, j)| [i as f64, j as f64]), true);
        assert_eq!(corners, vec![[1.0, 2.0], [4.0, 2.0], [4.0, 4.0], [1.0, 4.0]]);
        assert_eq!(twice_area(points), 2 * 6);
    }

    #[test]
    fn a_room_gives_its_outer_and_inner_faces_and_the_hole_runs_clockwise() {
        // a 10 x 8 room whose walls are two cells thick, on a raster with a free border
        let cells = raster(14, 12, |c, r| {
            let inside_outer = (2..12).contains(&c) && (2..10).contains(&r);
            let inside_inner = (4..10).contains(&c) && (4..8).contains(&r);
            inside_outer && !inside_inner
        });
        let r = Raster { width: 14, height: 12, cells: &cells };
        let loops = outlines(&r);
        assert_eq!(loops.len(), 2);
        let areas: Vec<i64> = loops.iter().map(|l| twice_area(&l.points)).collect();
        assert!(areas.contains(&(2 * 80)) && areas.contains(&(-2 * 24)), "{areas:?}");
        // each wall with its lower-left end first
        let exact = TraceConfig { face_depth: 0.0, ..TraceConfig::default() };
        let w: Vec<[f64; 4]> = walls(&r, &exact)
            .into_iter()
            .map(|w| if (w[0], w[1]) <= (w[2], w[3]) { w } else { [w[2], w[3], w[0], w[1]] })
            .collect();
        assert_eq!(w.len(), 8);
        let has = |x: [f64; 4]| w.iter().any(|v| v.iter().zip(&x).all(|(a, b)| (a - b).abs() < 1e-9));
        assert!(has([4.0, 4.0, 4.0, 8.0]) && has([2.0, 2.0, 12.0, 2.0]), "{w:?}");
    }

    #[test]
    fn only_faces_that_look_onto_free_cells_are_walls() {
        // a one-cell wall ring around a free room, unknown outside it; an unknown patch (the
        // edge of what was explored) inside the room, and an opening six cells wide in the
        // ring's top onto the unknown
        let (w, h) = (12usize, 10usize);
        let cells: Vec<Cell> = (0..w * h)
            .map(|i| {
                let (c, r) = (i % w, i / w);
                let ring =
                    (1..11).contains(&c) && (1..9).contains(&r) && !((2..10).contains(&c) && (2..8).contains(&r));
                if (3..9).contains(&c) && r == 8 {
                    Cell::Free
                } else if ring {
                    Cell::Occupied
                } else if (2..10).contains(&c) && (2..8).contains(&r) && !((4..6).contains(&c) && (4..6).contains(&r)) {
                    Cell::Free
                } else {
                    Cell::Unknown
                }
            })
            .collect();
        let closed = close_fringes(&Raster { width: w, height: h, cells: &cells });
        let faces: Vec<((i64, i64), (i64, i64))> = outlines(&Raster { width: w, height: h, cells: &closed })
            .iter()
            .flat_map(|o| {
                (0..o.points.len()).filter(|&k| o.faces[k]).map(|k| (o.points[k], o.points[(k + 1) % o.points.len()]))
            })
            .collect();
        // the room's inner faces only: left, bottom and right, the top either side of the
        // opening, its jambs, and a cell of the unknown either side of it, which touches the
        // ring (`close_fringes`): 6 + 8 + 6 + 2 x (1 + 1 + 1)
        assert_eq!(faces.len(), 26, "{faces:?}");
        for &(a, b) in &faces {
            let mid = [(a.0 + b.0) as f64 / 2.0, (a.1 + b.1) as f64 / 2.0];
            assert!((2.0..=10.0).contains(&mid[0]) && (2.0..=9.0).contains(&mid[1]), "{a:?} {b:?}");
            // nothing across the opening, nor around the unknown patch
            assert!(!((4.0..=8.0).contains(&mid[0]) && mid[1] > 8.5), "{a:?} {b:?}");
            assert!(!((3.5..=6.5).contains(&mid[0]) && (3.5..=6.5).contains(&mid[1])), "{a:?} {b:?}");
            // the free side is on the right
            let right = [(b.1 - a.1) as f64, (a.0 - b.0) as f64];
            let probe = [mid[0] + 0.5 * right[0], mid[1] + 0.5 * right[1]];
            assert_eq!(cells[probe[1] as usize * w + probe[0] as usize], Cell::Free, "{a:?} {b:?}");
        }
        // and the walls lie on those faces
        for wall in walls(&Raster { width: w, height: h, cells: &cells }, &TraceConfig::default()) {
            let mid = [(wall[0] + wall[2]) / 2.0, (wall[1] + wall[3]) / 2.0];
            assert!((1.5..=10.5).contains(&mid[0]) && (1.5..=9.5).contains(&mid[1]), "{wall:?}");
        }
    }

    #[test]
    fn a_face_missing_one_cell_is_one_wall() {
        // free below, a row of occupied cells with one unknown, unknown above; the unknown
        // cells at the row's ends touch it and lengthen the wall by a cell each
        let (w, h) = (10usize, 4usize);
        let cells: Vec<Cell> = (0..w * h)
            .map(|i| match (i % w, i / w) {
                (_, 0) | (_, 1) => Cell::Free,
                (4, 2) => Cell::Unknown,
                (c, 2) if (1..9).contains(&c) => Cell::Occupied,
                _ => Cell::Unknown,
            })
            .collect();
        let got = walls(
            &Raster { width: w, height: h, cells: &cells },
            &TraceConfig { face_depth: 0.0, ..TraceConfig::default() },
        );
        assert_eq!(got, vec![[0.0, 2.0, 10.0, 2.0]]);
    }

    #[test]
    fn a_wall_one_cell_thick_keeps_its_faces_round_its_ends_and_joints() {
        // an L of walls one cell thick: thinner than the tolerance, so without its U-turns
        // anchored Douglas-Peucker drew each arm as a line along its diagonal
        let cells = raster(34, 24, |c, r| (r == 5 && (2..30).contains(&c)) || (c == 29 && (5..20).contains(&r)));
        let got = walls(&Raster { width: 34, height: 24, cells: &cells }, &TraceConfig::default());
        let long: Vec<&[f64; 4]> = got.iter().filter(|w| (w[2] - w[0]).hypot(w[3] - w[1]) > 3.0).collect();
        // each arm's two faces
        assert_eq!(long.len(), 4, "{got:?}");
        for w in long {
            assert!((w[2] - w[0]).abs() < 0.05 || (w[3] - w[1]).abs() < 0.05, "{w:?} is not along an arm");
        }
    }

    #[test]
    fn cells_touching_at_a_corner_are_one_outline() {
        // a diagonal wall one cell wide: a staircase of cells touching at their corners
        let cells = raster(12, 12, |c, r| c == r && (1..11).contains(&c));
        let r = Raster { width: 12, height: 12, cells: &cells };
        assert_eq!(outlines(&r).len(), 1);
        // its two long faces become two walls (and two short caps)
        let w = walls(&r, &TraceConfig::default());
        let long: Vec<_> = w.iter().filter(|w| (w[2] - w[0]).hypot(w[3] - w[1]) > 5.0).collect();
        assert_eq!(long.len(), 2, "{w:?}");
        for l in long {
            assert!(((l[3] - l[1]) / (l[2] - l[0]) - 1.0).abs() < 0.05, "{l:?}");
        }
    }

    #[test]
    fn specks_give_no_walls() {
        let cells = raster(8, 8, |c, r| (c, r) == (2, 2) || (c, r) == (5, 5) || (c, r) == (5, 6));
        assert!(walls(&Raster { width: 8, height: 8, cells: &cells }, &TraceConfig::default()).is_empty());
        assert!(walls(&Raster { width: 0, height: 0, cells: &[] }, &TraceConfig::default()).is_empty());
    }

    proptest! {
        /// Every outline closes and uses each boundary edge once: the loops' perimeters add up
        /// to the number of cell edges between cells that are not free and the rest, their
        /// areas to the cells that are not free (outer loops count the cells they enclose,
        /// holes subtract), and their faces to the edges between occupied and free cells.
        #[test]
        fn outlines_use_every_boundary_edge_once(states in proptest::collection::vec(0u8..3, 48)) {
            let (w, h) = (8i64, 6i64);
            let cells: Vec<Cell> = states.iter().map(|&s| [Cell::Free, Cell::Occupied, Cell::Unknown][s as usize]).collect();
            let r = Raster { width: w as usize, height: h as usize, cells: &cells };
            let (mut edges, mut faces) = (0i64, 0i64);
            for row in 0..h {
                for c in 0..w {
                    for d in [(1, 0), (-1, 0), (0, 1), (0, -1)] {
                        let other = r.at(c + d.0, row + d.1);
                        if r.solid(c, row) && !r.solid(c + d.0, row + d.1) {
                            edges += 1;
                        }
                        if r.at(c, row) == Some(Cell::Occupied) && other == Some(Cell::Free) {
                            faces += 1;
                        }
                    }
                }
            }
            let loops = outlines(&r);
            let perimeter: i64 = loops.iter().map(|l| l.points.len() as i64).sum();
            prop_assert_eq!(perimeter, edges);
            prop_assert_eq!(loops.iter().flat_map(|l| &l.faces).filter(|&&f| f).count() as i64, faces);
            for l in &loops {
                prop_assert_eq!(l.points.len(), l.faces.len());
                for k in 0..l.points.len() {
                    let (a, b) = (l.points[k], l.points[(k + 1) % l.points.len()]);
                    prop_assert_eq!((a.0 - b.0).abs() + (a.1 - b.1).abs(), 1);
                }
            }
            let area: i64 = loops.iter().map(|l| twice_area(&l.points)).sum();
            prop_assert_eq!(area, 2 * cells.iter().filter(|&&c| c != Cell::Free).count() as i64);
        }

        /// A rotated rectangle drawn in cells comes back as walls within the tolerance of its
        /// boundary, and every stretch of its boundary has a wall near it.
        #[test]
        fn a_rotated_block_is_traced_to_within_the_tolerance(
            angle in 0.0f64..1.57, len in 12.0f64..30.0, width in 3.0f64..8.0,
        ) {
            let (w, h) = (48usize, 48usize);
            let (cx, cy) = (24.0, 24.0);
            let (u, v) = ([angle.cos(), angle.sin()], [-angle.sin(), angle.cos()]);
            let inside = |x: f64, y: f64| {
                let (dx, dy) = (x - cx, y - cy);
                (dx * u[0] + dy * u[1]).abs() <= len / 2.0 && (dx * v[0] + dy * v[1]).abs() <= width / 2.0
            };
            let cells = raster(w, h, |c, r| inside(c as f64 + 0.5, r as f64 + 0.5));
            let cfg = TraceConfig::default();
            let got = walls(&Raster { width: w, height: h, cells: &cells }, &cfg);
            prop_assert!(!got.is_empty());
            // the rectangle's boundary, as the distance from a point to it
            let to_boundary = |x: f64, y: f64| {
                let (dx, dy) = (x - cx, y - cy);
                let (s, t) = ((dx * u[0] + dy * u[1]).abs(), (dx * v[0] + dy * v[1]).abs());
                if s <= len / 2.0 && t <= width / 2.0 {
                    (len / 2.0 - s).min(width / 2.0 - t)
                } else {
                    (s - len / 2.0).max(0.0).hypot((t - width / 2.0).max(0.0))
                }
            };
            for wall in &got {
                for k in 0..=10 {
                    let f = k as f64 / 10.0;
                    let (x, y) = (wall[0] + f * (wall[2] - wall[0]), wall[1] + f * (wall[3] - wall[1]));
                    prop_assert!(to_boundary(x, y) <= cfg.tolerance + 1.0, "{wall:?} strays at {x},{y}");
                }
            }
            for k in 0..40 {
                let t = k as f64 / 40.0 * std::f64::consts::TAU;
                let (px, py) = (cx + t.cos() * len / 2.0 * u[0] + t.sin() * width / 2.0 * v[0], cy + t.cos() * len / 2.0 * u[1] + t.sin() * width / 2.0 * v[1]);
                // the point of the boundary in this direction from the centre
                let (dx, dy) = (px - cx, py - cy);
                let scale = (0..60).map(|i| i as f64 / 20.0).take_while(|&s| inside(cx + dx * s, cy + dy * s)).last().unwrap_or(0.0);
                let (bx, by) = (cx + dx * scale, cy + dy * scale);
                let near = got.iter().map(|w| distance_to_segment([bx, by], [w[0], w[1]], [w[2], w[3]])).fold(f64::INFINITY, f64::min);
                prop_assert!(near <= cfg.tolerance + 1.0, "no wall near the boundary at {bx},{by}: {near}");
            }
        }
    }
}
