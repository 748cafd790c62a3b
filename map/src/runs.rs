//! Straight runs: a map's walls as the straight stretches a scan's lines can match.
//!
//! Maps draw one straight wall in many ways: one segment, pieces split wherever another wall
//! meets it (as CAD exports and plan tracers do), or a chain of short, slightly kinked pieces
//! (a wall traced from an occupancy grid). Line inference (section 4.2) sees one line along
//! all of them, so corners (section 5.1) must come from the wall as a whole: every piece's
//! end would be a wall end in the middle of a wall, and a piece shorter than the scan's line
//! would make the real corner's arm too short to match. Measured on the bundled office's clean
//! log with each wall split into 0.3-1 m pieces: 98.7 % success drawn whole, 96.7 % in pieces;
//! with the joints moved up to 1 cm, 68.3 % and one `ok` in nine wrong. From straight runs:
//! 98.0 and 97.0 %, every `ok` right.
//!
//! Runs are found by merging walls that overlap along one line (drawn twice, or in overlapping
//! pieces), joining walls end to end where they continue each other (ends within
//! [`SNAP`], directions within [`MAX_TURN`]) and simplifying each chain (Douglas-Peucker)
//! so that every drawn point lies within a tolerance of its run. Curved walls keep their
//! vertices where the curve leaves the tolerance. Ray casting and the cost function keep the
//! drawn geometry: for them only pieces that continue each other to within [`JOINED`] are
//! joined ([`crate::WallMap::joined_walls`]).

use crate::simplify::douglas_peucker;
use crate::wall::Wall;
use nalgebra::Point2;
use std::collections::HashMap;

/// Wall ends closer than this are joined, metres.
pub const SNAP: f64 = 0.02;

/// Largest turn between two walls that may continue each other, radians (the tolerance then
/// decides whether they do).
pub const MAX_TURN: f64 = 0.26;

/// The default tolerance: how far a drawn wall may lie from its run, metres. Well inside what
/// line visibility merges at any range (e(d) is 3 cm at the sensor).
pub const STRAIGHTNESS: f64 = 0.03;

/// The tolerance of [`crate::WallMap::joined_walls`], metres: far below any range noise, so
/// the joined walls are the drawn ones (only gaps narrower than [`SNAP`] between pieces that
/// continue each other close).
pub const JOINED: f64 = 0.001;

/// `walls` as straight runs: walls that overlap along one line are merged first; then chains
/// of walls that continue each other become one wall when every drawn point of the chain lies
/// within `tolerance` of it (otherwise the chain is split where it bends most, and so on).
/// Walls that continue and overlap nothing are returned as they are.
pub fn straight_runs(walls: &[Wall], tolerance: f64) -> Vec<Wall> {
    let mut runs = Vec::with_capacity(walls.len());
    for chain in chains_of_runs(walls, tolerance) {
        runs.extend(chain.runs());
    }
    runs
}

/// Chains of straight runs that continue each other, each turning by less than [`MAX_TURN`]
/// from the last: a curved or bent wall drawn as a polygon. Runs that continue no other form a
/// chain of one run.
#[derive(Clone, Debug, PartialEq)]
pub struct RunChain {
    /// The runs' ends in order along the chain; a closed chain's last run returns to the
    /// first point, which is not repeated.
    pub points: Vec<Point2<f64>>,
    pub closed: bool,
}

impl RunChain {
    /// The chain's runs in order, leaving out any of no length.
    pub fn runs(&self) -> impl Iterator<Item = Wall> + '_ {
        let n = self.points.len();
        let count = if self.closed && n >= 2 { n } else { n.saturating_sub(1) };
        (0..count)
            .map(move |k| Wall { a: self.points[k], b: self.points[(k + 1) % n] })
            .filter(|w| (w.b - w.a).norm() > 0.0)
    }

    /// Number of runs (as [`runs`](Self::runs) gives them).
    pub fn run_count(&self) -> usize {
        self.runs().count()
    }

    /// Total length, metres.
    pub fn length(&self) -> f64 {
        self.runs().map(|w| w.length()).sum()
    }
}

/// `walls` as [`RunChain`]s: [`straight_runs`] with the runs that continue each other kept
/// together, in the same order.
pub fn chains_of_runs(walls: &[Wall], tolerance: f64) -> Vec<RunChain> {
    let merged = merge_overlaps(walls, tolerance);
    let walls = &merged[..];
    let next = continuations(walls);
    let mut visited = vec![false; walls.len()];
    let mut chains = Vec::new();
    let mut chain: Vec<Point2<f64>> = Vec::new();
    for start in 0..walls.len() {
        if visited[start] {
            continue;
        }
        // walk back to the chain's first wall (or round a ring back to `start`)
        let (mut wall, mut forward) = (start, true);
        // each wall end continues at most one other, so chains are paths or rings: the walk
        // ends within a chain's length (the bound only guards that reasoning)
        for _ in 0..walls.len() {
            let back = 2 * wall + usize::from(!forward);
            match next[back] {
                Some(e) if e / 2 != start => (wall, forward) = (e / 2, is_b(e)),
                Some(_) => {
                    (wall, forward) = (start, true);
                    break;
                }
                None => break,
            }
        }
        // then forward along it, collecting its points
        chain.clear();
        let first = wall;
        let ends = |w: usize, fwd: bool| if fwd { (walls[w].a, walls[w].b) } else { (walls[w].b, walls[w].a) };
        chain.push(ends(wall, forward).0);
        let mut ring = false;
        loop {
            visited[wall] = true;
            chain.push(ends(wall, forward).1);
            let out = 2 * wall + usize::from(forward);
            match next[out] {
                Some(e) if e / 2 == first => {
                    ring = true;
                    break;
                }
                Some(e) if !visited[e / 2] => (wall, forward) = (e / 2, !is_b(e)),
                _ => break,
            }
        }
        let mut points = Vec::new();
        if ring {
            chain.pop();
            simplify_ring(&chain, tolerance, &mut points);
        } else if let Some(&last) = chain.last() {
            simplify(&chain, tolerance, &mut points);
            points.push(last);
        }
        if points.len() >= 2 {
            chains.push(RunChain { points, closed: ring });
        }
    }
    chains
}

/// Largest angle between walls that overlap along one line, radians.
const OVERLAP_ANGLE: f64 = 0.01;

/// `walls` with those that overlap along one line (a wall drawn twice, or in pieces that
/// overlap) replaced by one wall over their union: nearly parallel, each within `tolerance` of
/// the other's line, sharing some of their length.
fn merge_overlaps(walls: &[Wall], tolerance: f64) -> Vec<Wall> {
    let n = walls.len();
    let mut parent: Vec<usize> = (0..n).collect();
    fn root(parent: &mut [usize], mut k: usize) -> usize {
        while parent[k] != k {
            parent[k] = parent[parent[k]];
            k = parent[k];
        }
        k
    }
    // sweep along x: only walls whose x ranges overlap can overlap
    let mut order: Vec<usize> = (0..n).collect();
    let min_x = |k: usize| walls[k].a.x.min(walls[k].b.x);
    let max_x = |k: usize| walls[k].a.x.max(walls[k].b.x);
    order.sort_by(|&i, &j| min_x(i).total_cmp(&min_x(j)));
    for (oi, &i) in order.iter().enumerate() {
        for &j in &order[oi + 1..] {
            if min_x(j) > max_x(i) + tolerance {
                break;
            }
            if overlap(&walls[i], &walls[j], tolerance) {
                let (ri, rj) = (root(&mut parent, i), root(&mut parent, j));
                parent[ri] = rj;
            }
        }
    }
    let mut groups: HashMap<usize, Vec<usize>> = HashMap::new();
    for k in 0..n {
        let r = root(&mut parent, k);
        groups.entry(r).or_default().push(k);
    }
    let mut out = Vec::with_capacity(n);
    for k in 0..n {
        let Some(members) = groups.remove(&root(&mut parent, k)) else {
            continue;
        };
        if let [only] = members[..] {
            out.push(walls[only]);
            continue;
        }
        // the union along the longest member's line
        let longest =
            members.iter().copied().max_by(|&i, &j| walls[i].length().total_cmp(&walls[j].length())).unwrap_or(k);
        let w = &walls[longest];
        let u = (w.b - w.a) / w.length();
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        for &m in &members {
            for p in [walls[m].a, walls[m].b] {
                let t = (p - w.a).dot(&u);
                (lo, hi) = (lo.min(t), hi.max(t));
            }
        }
        out.push(Wall { a: w.a + u * lo, b: w.a + u * hi });
    }
    out
}

/// Whether two walls overlap along one line (see [`merge_overlaps`]).
fn overlap(p: &Wall, q: &Wall, tolerance: f64) -> bool {
    let (lp, lq) = (p.length(), q.length());
    if lp <= 0.0 || lq <= 0.0 {
        return false;
    }
    let (u, v) = ((p.b - p.a) / lp, (q.b - q.a) / lq);
    if u.perp(&v).abs() > OVERLAP_ANGLE {
        return false;
    }
    let off = |x: Point2<f64>| (x - p.a).perp(&u).abs();
    if off(q.a) > tolerance || off(q.b) > tolerance {
        return false;
    }
    let (ta, tb) = ((q.a - p.a).dot(&u), (q.b - p.a).dot(&u));
    ta.max(tb) > 0.0 && ta.min(tb) < lp
}

/// For each wall end (`2 k` is wall k's `a`, `2 k + 1` its `b`), the end of another wall that
/// continues it: ends within [`SNAP`] whose walls turn by less than [`MAX_TURN`], paired by
/// smallest turn first at each point.
fn continuations(walls: &[Wall]) -> Vec<Option<usize>> {
    let end_point = |e: usize| if is_b(e) { walls[e / 2].b } else { walls[e / 2].a };
    // outward direction: from the end into its wall
    let outward = |e: usize| {
        let w = &walls[e / 2];
        let d = (w.b - w.a).normalize();
        if is_b(e) {
            -d
        } else {
            d
        }
    };
    let cell = |p: Point2<f64>| ((p.x / SNAP).floor() as i64, (p.y / SNAP).floor() as i64);
    let mut grid: HashMap<(i64, i64), Vec<usize>> = HashMap::new();
    for e in 0..2 * walls.len() {
        grid.entry(cell(end_point(e))).or_default().push(e);
    }
    let min_cos = MAX_TURN.cos();
    let mut pairs: Vec<(f64, usize, usize)> = Vec::new();
    for e in 0..2 * walls.len() {
        let (p, (cx, cy)) = (end_point(e), cell(end_point(e)));
        for dx in -1..=1 {
            for dy in -1..=1 {
                for &f in grid.get(&(cx + dx, cy + dy)).map(Vec::as_slice).unwrap_or(&[]) {
                    if f <= e || f / 2 == e / 2 || (end_point(f) - p).norm() > SNAP {
                        continue;
                    }
                    // walls that continue each other leave the point in opposite directions
                    let straightness = -outward(e).dot(&outward(f));
                    if straightness >= min_cos {
                        pairs.push((straightness, e, f));
                    }
                }
            }
        }
    }
    pairs.sort_by(|a, b| b.0.total_cmp(&a.0));
    let mut next = vec![None; 2 * walls.len()];
    for (_, e, f) in pairs {
        if next[e].is_none() && next[f].is_none() {
            next[e] = Some(f);
            next[f] = Some(e);
        }
    }
    next
}

/// Whether wall end `e` (see [`continuations`]) is its wall's `b`.
fn is_b(e: usize) -> bool {
    e & 1 == 1
}

/// Douglas-Peucker ([`crate::simplify`]) on an open chain of points: pushes the points its
/// runs start at (the chain's last point, where the last run ends, is left to the caller).
fn simplify(chain: &[Point2<f64>], tolerance: f64, out: &mut Vec<Point2<f64>>) {
    match chain.len() {
        0 => {}
        1 => out.push(chain[0]),
        n => {
            let kept = douglas_peucker(chain, vec![(0, n - 1)], tolerance);
            out.extend(kept[..kept.len() - 1].iter().map(|&k| chain[k]));
        }
    }
}

/// Douglas-Peucker on a closed ring: split at the point farthest from the first, then each
/// half as an open chain. Pushes the points its runs start at, the ring's first first.
fn simplify_ring(ring: &[Point2<f64>], tolerance: f64, out: &mut Vec<Point2<f64>>) {
    let Some(&start) = ring.first() else {
        return;
    };
    let far =
        (1..ring.len()).max_by(|&i, &j| (ring[i] - start).norm().total_cmp(&(ring[j] - start).norm())).unwrap_or(0);
    if far == 0 {
        return;
    }
    let kept = douglas_peucker(ring, vec![(0, far), (far, ring.len())], tolerance);
    out.extend(kept.iter().map(|&k| ring[k]));
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn w(x1: f64, y1: f64, x2: f64, y2: f64) -> Wall {
        Wall::new(x1, y1, x2, y2)
    }

    fn close(a: &Wall, b: &Wall) -> bool {
        let same = |p: Point2<f64>, q: Point2<f64>| (p - q).norm() < 1e-9;
        (same(a.a, b.a) && same(a.b, b.b)) || (same(a.a, b.b) && same(a.b, b.a))
    }

    #[test]
    fn a_wall_drawn_in_pieces_is_one_run() {
        // pieces in both directions, out of order
        let walls = [w(2.0, 0.0, 3.5, 0.0), w(0.0, 0.0, 1.2, 0.0), w(2.0, 0.0, 1.2, 0.0), w(3.5, 0.0, 6.0, 0.0)];
        let runs = straight_runs(&walls, STRAIGHTNESS);
        assert_eq!(runs.len(), 1, "{runs:?}");
        assert!(close(&runs[0], &w(0.0, 0.0, 6.0, 0.0)), "{runs:?}");
    }

    #[test]
    fn slightly_kinked_pieces_are_one_run_and_a_corner_stays_a_corner() {
        let walls = [
            w(0.0, 0.0, 1.0, 0.008),
            w(1.0, 0.008, 2.0, -0.006),
            w(2.0, -0.006, 3.0, 0.0),
            // a real corner, then a kinked second wall
            w(3.0, 0.0, 3.01, 1.5),
            w(3.01, 1.5, 3.0, 3.0),
        ];
        let runs = straight_runs(&walls, STRAIGHTNESS);
        assert_eq!(runs.len(), 2, "{runs:?}");
        assert!(runs.iter().any(|r| close(r, &w(0.0, 0.0, 3.0, 0.0))), "{runs:?}");
        assert!(runs.iter().any(|r| close(r, &w(3.0, 0.0, 3.0, 3.0))), "{runs:?}");
    }

    #[test]
    fn a_wall_split_where_another_meets_it_is_one_run_and_the_other_stays() {
        // a corridor wall split at a T junction, with a room wall ending on it
        let walls = [w(0.0, 0.0, 4.0, 0.0), w(4.0, 0.0, 9.0, 0.0), w(4.0, 0.0, 4.0, -3.0)];
        let runs = straight_runs(&walls, STRAIGHTNESS);
        assert_eq!(runs.len(), 2, "{runs:?}");
        assert!(runs.iter().any(|r| close(r, &w(0.0, 0.0, 9.0, 0.0))), "{runs:?}");
        assert!(runs.iter().any(|r| close(r, &walls[2])), "{runs:?}");
    }

    #[test]
    fn walls_drawn_twice_or_overlapping_are_one_run() {
        let walls = [w(0.0, 0.0, 4.0, 0.0), w(4.0, 0.0, 0.0, 0.0), w(3.5, 0.005, 7.0, 0.0), w(7.0, 0.0, 7.0, 3.0)];
        let runs = straight_runs(&walls, STRAIGHTNESS);
        assert_eq!(runs.len(), 2, "{runs:?}");
        assert!(runs.iter().any(|r| (r.length() - 7.0).abs() < 0.01 && r.a.y.abs() < 0.01), "{runs:?}");
    }

    /// A plan drawn in pieces (split where other walls meet, drawn twice, overlapping) joins
    /// back into its walls, and every ray meets the joined walls where it meets the drawn ones;
    /// pieces that turn by 1 cm at their joints stay pieces.
    #[test]
    fn joined_walls_hold_the_drawn_geometry_in_fewer_walls() {
        let whole = crate::bundled::bundled("apartment").unwrap().unwrap();
        let mut pieces = Vec::new();
        for (k, wall) in whole.walls.iter().enumerate() {
            let n = 1 + k % 4;
            let at = |t: f64| wall.a + (wall.b - wall.a) * t;
            for i in 0..n {
                let (p, q) = (at(i as f64 / n as f64), at((i + 1) as f64 / n as f64));
                // every other piece drawn backwards, every third wall drawn twice
                pieces.push(if i % 2 == 0 { Wall { a: p, b: q } } else { Wall { a: q, b: p } });
            }
            if k % 3 == 0 {
                pieces.push(Wall { a: at(0.2), b: at(0.7) });
            }
        }
        let drawn = crate::map::WallMap::new(pieces);
        let joined = drawn.joined_walls();
        assert!(joined.len() <= whole.walls.len(), "{} joined walls, {} drawn whole", joined.len(), whole.walls.len());
        let (drawn_caster, joined_caster) =
            (crate::raycast::RayCaster::new(&drawn.walls), crate::raycast::RayCaster::new(&joined));
        let (lo, hi) = drawn.bounds();
        let mut rng = laser::rng::Rng::new(3);
        for _ in 0..2000 {
            let origin = Point2::new(rng.range(lo.x, hi.x), rng.range(lo.y, hi.y));
            let angle = rng.range(-3.2, 3.2);
            let (a, b) = (drawn_caster.cast_ray_brute(origin, angle), joined_caster.cast_ray_brute(origin, angle));
            assert!(
                (a - b).abs() < 2e-3 || (a.is_infinite() && b.is_infinite()),
                "{origin} {angle}: {a} drawn, {b} joined"
            );
        }
        let kinked = [w(0.0, 0.0, 1.0, 0.01), w(1.0, 0.01, 2.0, 0.0)];
        assert_eq!(crate::map::WallMap::new(kinked.to_vec()).joined_walls().len(), 2);
    }

    #[test]
    fn a_curved_wall_is_one_chain_of_runs_and_a_corner_ends_a_chain() {
        // a half circle of 16 sides (11.25 degree turns), then a square corner into a straight wall
        let p = |k: usize| {
            let a = std::f64::consts::PI * k as f64 / 16.0;
            Point2::new(5.0 * a.cos(), 5.0 * a.sin())
        };
        let mut walls: Vec<Wall> = (0..16).map(|k| Wall { a: p(k), b: p(k + 1) }).collect();
        walls.push(w(-5.0, 0.0, -2.0, 0.0));
        let chains = chains_of_runs(&walls, STRAIGHTNESS);
        assert_eq!(chains.len(), 2, "{chains:?}");
        let arc = chains.iter().find(|c| c.run_count() == 16).expect("the arc as one chain");
        assert!(!arc.closed);
        assert!((arc.length() - walls[..16].iter().map(Wall::length).sum::<f64>()).abs() < 1e-9);
        assert!(chains.iter().any(|c| c.run_count() == 1 && close(&c.runs().next().unwrap(), &walls[16])));
        // the runs are the chains' runs, in order
        let flat: Vec<Wall> = chains.iter().flat_map(RunChain::runs).collect();
        assert_eq!(flat, straight_runs(&walls, STRAIGHTNESS));
        // a full circle is one closed chain whose runs return to its start
        let ring: Vec<Wall> = (0..32).map(|k| Wall { a: p(k), b: p(k + 1) }).collect();
        let chains = chains_of_runs(&ring, STRAIGHTNESS);
        assert_eq!(chains.len(), 1);
        assert!(chains[0].closed && chains[0].run_count() == 32, "{chains:?}");
        assert!((chains[0].length() - ring.iter().map(Wall::length).sum::<f64>()).abs() < 1e-9);
    }

    #[test]
    fn a_door_gap_is_not_bridged() {
        let walls = [w(0.0, 0.0, 2.0, 0.0), w(2.9, 0.0, 5.0, 0.0)];
        assert_eq!(straight_runs(&walls, STRAIGHTNESS).len(), 2);
    }

    #[test]
    fn a_coarse_polygon_keeps_its_vertices_and_a_fine_one_is_simplified() {
        let polygon = |n: usize, r: f64| -> Vec<Wall> {
            let p = |k: usize| {
                let a = std::f64::consts::TAU * k as f64 / n as f64;
                (r * a.cos(), r * a.sin())
            };
            (0..n).map(|k| w(p(k).0, p(k).1, p(k + 1).0, p(k + 1).1)).collect()
        };
        // 36 sides of 5 m radius: each side's sagitta over two sides is 7.6 cm
        assert_eq!(straight_runs(&polygon(36, 5.0), STRAIGHTNESS).len(), 36);
        // 360 sides: runs of several sides each, still every drawn point within tolerance
        let fine = polygon(360, 5.0);
        let runs = straight_runs(&fine, STRAIGHTNESS);
        assert!(runs.len() < 120 && runs.len() >= 20, "{} runs", runs.len());
        for piece in &fine {
            let d = runs.iter().map(|r| r.closest(piece.a).0).fold(f64::INFINITY, f64::min);
            assert!(d <= STRAIGHTNESS + 1e-9, "{d}");
        }
    }

    #[test]
    fn an_octagonal_pillar_stays_eight_walls() {
        let p = |k: usize| {
            let a = std::f64::consts::FRAC_PI_4 * k as f64;
            (0.25 * a.cos(), 0.25 * a.sin())
        };
        let walls: Vec<Wall> = (0..8).map(|k| w(p(k).0, p(k).1, p(k + 1).0, p(k + 1).1)).collect();
        assert_eq!(straight_runs(&walls, STRAIGHTNESS).len(), 8);
    }

    proptest! {
        /// Whatever the walls: every drawn wall end lies within the tolerance (and the snap) of
        /// a run, and every run end within the tolerance of a drawn wall end.
        #[test]
        fn runs_stay_within_the_tolerance_of_the_drawn_walls(
            raw in proptest::collection::vec((0u8..6, 0u8..6, 0u8..6, 0u8..6, -0.01f64..0.01), 1..30)
        ) {
            let walls: Vec<Wall> = raw
                .iter()
                .filter(|(x1, y1, x2, y2, _)| (x1, y1) != (x2, y2))
                .map(|&(x1, y1, x2, y2, j)| w(f64::from(x1), f64::from(y1) + j, f64::from(x2), f64::from(y2)))
                .collect();
            let runs = straight_runs(&walls, STRAIGHTNESS);
            prop_assert!(runs.len() <= walls.len());
            for wall in &walls {
                for p in [wall.a, wall.b] {
                    let d = runs.iter().map(|r| r.closest(p).0).fold(f64::INFINITY, f64::min);
                    prop_assert!(d <= STRAIGHTNESS + SNAP + 1e-9, "{:?} is {} from every run", p, d);
                }
            }
            for r in &runs {
                for p in [r.a, r.b] {
                    let near = |q: Point2<f64>| (q - p).norm() <= STRAIGHTNESS + 1e-9;
                    prop_assert!(walls.iter().any(|wall| near(wall.a) || near(wall.b)), "run end {:?}", p);
                }
            }
        }
    }
}
