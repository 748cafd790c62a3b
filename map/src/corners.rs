//! The map's corners, pre-computed and sorted by inner angle (section 5.1).
//!
//! A corner is where walls meet, or where their extensions meet within `reach` of both walls'
//! ends (a door or a gap between the walls still makes the corner a scan can see). At each such
//! junction the walls offer *arms*: the directions from the junction along each wall towards
//! the wall material (two when the junction falls inside a wall: a T). Every ordered pair of
//! arms is one corner, with the same convention as scan corners (crate `segment`): beta is
//! swept counter-clockwise from the right arm to the left arm. Pairs that are not angular
//! neighbours matter: an arm that starts after a door gap does not hide the corner of the two
//! arms either side of it from a sensor looking through the door. A map does not say which side of a wall is free, so a junction of
//! two walls gives both corners (beta and 2 pi - beta); hypotheses from the wrong one are
//! rejected by the cost function.

use crate::flat::{Flat, FlatError, FlatReader, FlatWriter};
use crate::hash::BuildMix;
use crate::slab::{Plain, Slab};
use crate::wall::Wall;
use nalgebra::{Point2, Vector2};
use std::collections::HashMap;
use std::f64::consts::{PI, TAU};

/// One side of a map corner.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C)]
pub struct MapArm {
    /// Unit vector from the corner along the wall.
    pub direction: Vector2<f64>,
    /// Distance from the corner to where the wall starts.
    pub gap: f64,
    /// Length of the wall beyond the gap.
    pub length: f64,
    /// How far from the corner wall material runs along the arm's line, following collinear
    /// walls across gaps of up to [`MapCornerConfig::max_gap`] (doors): the longest arm a scan
    /// can see here.
    pub extent: f64,
    pub wall: u32,
    /// Nothing: spells out the padding, so a corner is plain bytes ([`crate::slab::Plain`]).
    pub reserved: u32,
}

/// A corner m of the map.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C)]
pub struct MapCorner {
    pub position: Point2<f64>,
    /// beta_m in (0, 2 pi); exactly 2 pi for a wall end.
    pub inner_angle: f64,
    /// theta_m: direction of the right arm, map frame.
    pub orientation: f64,
    /// Right then left arm.
    pub arms: [MapArm; 2],
}

/// Parameters of map corner extraction; keep them consistent with scan corner extraction.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MapCornerConfig {
    /// Regions narrower than this, or within this of a straight angle, make no corner.
    pub min_angle: f64,
    /// How far a junction may lie beyond a wall's end, metres. The default is the scan's reach
    /// between long lines (`segment::CornerConfig::long_reach`): every corner a scan can infer
    /// from two walls' extensions (furniture hiding their junction, a doorway in between) then
    /// has its map counterpart. At 1 m, 28 % of furnished office scans found no map corner to
    /// match (`gema2 locate --diagnose`).
    pub reach: f64,
    /// How far a junction may lie beyond the end of a wall shorter than `long_wall`, metres:
    /// the scan's reach (`segment::CornerConfig::reach`), which makes corners farther out only
    /// between two long lines. On a map built from a real log most walls are short pieces of
    /// clutter, and at `reach` each one met hundreds of others.
    pub short_reach: f64,
    /// A wall at least this long may meet another long one up to `reach` beyond its end,
    /// metres: the scan's `long_line`.
    pub long_wall: f64,
    /// Shortest arm, metres.
    pub min_arm_length: f64,
    /// Largest gap between collinear walls that an arm's extent bridges, metres.
    pub max_gap: f64,
    /// Also list wall ends, as corners of inner angle 2 pi (see `segment::end`).
    pub wall_ends: bool,
    /// List only the corners a sensor can see ([`crate::view`]): none whose wedge lies in a
    /// wall drawn with thickness.
    pub only_in_view: bool,
}

impl Default for MapCornerConfig {
    fn default() -> Self {
        MapCornerConfig {
            min_angle: 25f64.to_radians(),
            reach: 5.0,
            short_reach: 1.0,
            long_wall: 0.6,
            min_arm_length: 0.1,
            max_gap: 3.0,
            wall_ends: true,
            only_in_view: true,
        }
    }
}

/// Junctions closer than this are one junction, metres.
const MERGE: f64 = 0.02;

/// Extracts every corner of `walls`.
pub fn extract_map_corners(walls: &[Wall], cfg: &MapCornerConfig) -> Vec<MapCorner> {
    extract_map_corners_where(walls, cfg, |_| true)
}

/// The corners of `walls` that `keep` says yes to, in the order they are found (junction by
/// junction, then the wall ends): a filter applied as they come, so the corners left out are
/// never stored (on a map built from a real log, two in three).
pub fn extract_map_corners_where(
    walls: &[Wall],
    cfg: &MapCornerConfig,
    mut keep: impl FnMut(&MapCorner) -> bool,
) -> Vec<MapCorner> {
    let junctions = junctions(walls, cfg);
    let mut lines = CollinearWalls::new(walls);
    let mut corners = Vec::new();
    let mut arms: Vec<MapArm> = Vec::new();
    let mut angles: Vec<f64> = Vec::new();
    for (x, members) in junctions {
        arms.clear();
        for &w in &members {
            arms_of(&walls[w as usize], w, x, cfg, &mut arms);
        }
        dedupe_arms(&mut arms);
        if arms.len() < 2 {
            continue;
        }
        for arm in arms.iter_mut() {
            arm.extent = lines.extent(walls, arm, x, cfg.max_gap);
        }
        // every ordered pair of arms is a corner: an arm that starts after a gap (a door next
        // to the junction) does not hide the region it splits from a sensor looking through
        // the gap
        angles.clear();
        angles.extend(arms.iter().map(|a| angle_of(a.direction)));
        for (i, right) in arms.iter().enumerate() {
            for (j, left) in arms.iter().enumerate() {
                if i == j {
                    continue;
                }
                let beta = (angles[j] - angles[i]).rem_euclid(TAU);
                if beta < cfg.min_angle || beta > TAU - cfg.min_angle || (beta - PI).abs() < cfg.min_angle {
                    continue;
                }
                let c = MapCorner { position: x, inner_angle: beta, orientation: angles[i], arms: [*right, *left] };
                if keep(&c) {
                    corners.push(c);
                }
            }
        }
    }
    if cfg.wall_ends {
        wall_ends(walls, &mut lines, cfg, &mut keep, &mut corners);
    }
    corners
}

/// Every wall's two ends, as corners of inner angle 2 pi with both arms into the wall, as scan
/// wall ends are (`segment::end`). Not only free ends (a door jamb, the end of a rack): a map's
/// walls have no thickness, so from outside a junction a sensor can see one wall end with the
/// other wall edge-on or out of view. In the simulated warehouse (racks are closed outlines)
/// keeping only free ends left 45 of 300 scans with no candidate near the truth.
fn wall_ends(
    walls: &[Wall],
    lines: &mut CollinearWalls,
    cfg: &MapCornerConfig,
    keep: &mut impl FnMut(&MapCorner) -> bool,
    out: &mut Vec<MapCorner>,
) {
    for (k, w) in walls.iter().enumerate() {
        let len = w.length();
        if len < cfg.min_arm_length {
            continue;
        }
        for (end, other) in [(w.a, w.b), (w.b, w.a)] {
            let direction = (other - end) / len;
            let mut arm = MapArm { direction, gap: 0.0, length: len, extent: len, wall: k as u32, reserved: 0 };
            arm.extent = lines.extent(walls, &arm, end, cfg.max_gap);
            let c = MapCorner { position: end, inner_angle: TAU, orientation: angle_of(direction), arms: [arm, arm] };
            if keep(&c) {
                out.push(c);
            }
        }
    }
}

fn angle_of(v: Vector2<f64>) -> f64 {
    v.y.atan2(v.x)
}

/// Junction points with the walls that meet there.
fn junctions(walls: &[Wall], cfg: &MapCornerConfig) -> Vec<(Point2<f64>, Vec<u32>)> {
    let min_sin = cfg.min_angle.sin();
    let mut found: Vec<(Point2<f64>, u32, u32)> = Vec::new();
    let boxes: Vec<(Point2<f64>, Point2<f64>)> = walls
        .iter()
        .map(|w| {
            let reach = wall_reach(w, cfg);
            let r = Vector2::new(reach, reach);
            (w.a.inf(&w.b) - r, w.a.sup(&w.b) + r)
        })
        .collect();
    let directions: Vec<Vector2<f64>> = walls.iter().map(|w| (w.b - w.a).normalize()).collect();
    let long: Vec<bool> = walls.iter().map(|w| w.length() >= cfg.long_wall).collect();
    for i in 0..walls.len() {
        let bi = boxes[i];
        for j in i + 1..walls.len() {
            let bj = &boxes[j];
            if bi.0.x > bj.1.x || bj.0.x > bi.1.x || bi.0.y > bj.1.y || bj.0.y > bi.1.y {
                continue;
            }
            let (a, b) = (&walls[i], &walls[j]);
            let (da, db) = (directions[i], directions[j]);
            let den = da.perp(&db);
            if den.abs() < min_sin {
                continue;
            }
            let t = (b.a - a.a).perp(&db) / den;
            let x = a.a + da * t;
            // as the scan makes its corners: beyond the short reach only between two long walls
            let reach = if long[i] && long[j] { cfg.reach } else { cfg.short_reach.min(cfg.reach) };
            if a.closest(x).0 <= reach && b.closest(x).0 <= reach {
                found.push((x, i as u32, j as u32));
            }
        }
    }
    // cluster intersection points that coincide (several walls meeting at one point)
    found.sort_by(|p, q| p.0.x.total_cmp(&q.0.x));
    let mut out: Vec<(Point2<f64>, Vec<u32>)> = Vec::new();
    let mut used = vec![false; found.len()];
    // the points by cells of side MERGE, each cell's in the sorted order: the points within
    // MERGE of one lie in its cell and the eight around (on a wall drawn along y, thousands of
    // junctions share one x, which made a scan along x quadratic)
    let cell = |p: Point2<f64>| ((p.x / MERGE).floor() as i64, (p.y / MERGE).floor() as i64);
    let mut cells: HashMap<(i64, i64), Vec<u32>, BuildMix> = HashMap::default();
    for (k, f) in found.iter().enumerate() {
        cells.entry(cell(f.0)).or_default().push(k as u32);
    }
    for k in 0..found.len() {
        if used[k] {
            continue;
        }
        let x = found[k].0;
        let mut members = vec![found[k].1, found[k].2];
        let (cx, cy) = cell(x);
        for (dx, dy) in (-1..=1).flat_map(|dx| (-1..=1).map(move |dy| (dx, dy))) {
            for &m in cells.get(&(cx + dx, cy + dy)).map_or(&[][..], Vec::as_slice) {
                let m = m as usize;
                if m > k && !used[m] && (found[m].0 - x).norm() <= MERGE {
                    used[m] = true;
                    members.extend([found[m].1, found[m].2]);
                }
            }
        }
        members.sort_unstable();
        members.dedup();
        out.push((x, members));
    }
    out
}

/// How far beyond its ends a junction of `w` may lie: `reach` for a long wall, else the short
/// reach.
fn wall_reach(w: &Wall, cfg: &MapCornerConfig) -> f64 {
    if w.length() >= cfg.long_wall {
        cfg.reach
    } else {
        cfg.short_reach.min(cfg.reach)
    }
}

fn arms_of(w: &Wall, index: u32, x: Point2<f64>, cfg: &MapCornerConfig, out: &mut Vec<MapArm>) {
    let len = w.length();
    let reach = wall_reach(w, cfg);
    let dir = (w.b - w.a) / len;
    let t = (x - w.a).dot(&dir);
    for (direction, gap, length) in [(dir, (-t).max(0.0), len - t.max(0.0)), (-dir, (t - len).max(0.0), t.min(len))] {
        if gap <= reach && length >= cfg.min_arm_length {
            out.push(MapArm { direction, gap, length, extent: gap + length, wall: index, reserved: 0 });
        }
    }
}

/// Walls grouped by the line they lie on (direction within about a degree, offset within a
/// few centimetres), to follow an arm across door gaps.
struct CollinearWalls {
    groups: HashMap<(i64, i64), Vec<u32>, BuildMix>,
    /// Each wall's group.
    keys: Vec<(i64, i64)>,
    /// Room for the spans [`extent`](Self::extent) sorts.
    spans: Vec<(f64, f64)>,
}

const ANGLE_BUCKET: f64 = 0.02;
const OFFSET_BUCKET: f64 = 0.05;

impl CollinearWalls {
    fn key(w: &Wall) -> (i64, i64) {
        let mut angle = w.direction();
        if angle >= PI - ANGLE_BUCKET / 2.0 {
            angle -= PI;
        }
        let normal = Vector2::new(-angle.sin(), angle.cos());
        ((angle / ANGLE_BUCKET).round() as i64, (normal.dot(&w.a.coords) / OFFSET_BUCKET).round() as i64)
    }

    fn new(walls: &[Wall]) -> Self {
        let mut groups: HashMap<(i64, i64), Vec<u32>, BuildMix> = HashMap::default();
        let keys: Vec<(i64, i64)> = walls.iter().map(Self::key).collect();
        for (k, &key) in keys.iter().enumerate() {
            groups.entry(key).or_default().push(k as u32);
        }
        CollinearWalls { groups, keys, spans: Vec::new() }
    }

    /// How far wall material runs from `x` along `arm`, bridging gaps up to `max_gap`.
    fn extent(&mut self, walls: &[Wall], arm: &MapArm, x: Point2<f64>, max_gap: f64) -> f64 {
        let (ka, ko) = self.keys[arm.wall as usize];
        let u = arm.direction;
        let n = Vector2::new(-u.y, u.x);
        let spans = &mut self.spans;
        spans.clear();
        for da in -1..=1 {
            for dof in -1..=1 {
                for &k in self.groups.get(&(ka + da, ko + dof)).map(Vec::as_slice).unwrap_or(&[]) {
                    let w = &walls[k as usize];
                    let (sa, sb) = ((w.a - x).dot(&u), (w.b - x).dot(&u));
                    let off = (w.a - x).dot(&n).abs().max((w.b - x).dot(&n).abs());
                    if off < OFFSET_BUCKET && sa.max(sb) > 0.0 {
                        spans.push((sa.min(sb), sa.max(sb)));
                    }
                }
            }
        }
        // spans starting together are taken either both or neither, in any order
        spans.sort_unstable_by(|a, b| a.0.total_cmp(&b.0));
        let mut reach = arm.gap + arm.length;
        for &(s0, s1) in spans.iter() {
            if s0 <= reach + max_gap {
                reach = reach.max(s1);
            }
        }
        reach
    }
}

/// Arms along the same direction (a wall split in two at the junction, or overlapping walls)
/// are one arm: keep the one that starts closest.
fn dedupe_arms(arms: &mut Vec<MapArm>) {
    let cos_same = 1f64.to_radians().cos();
    let mut k = 0;
    while k < arms.len() {
        let mut m = k + 1;
        while m < arms.len() {
            if arms[k].direction.dot(&arms[m].direction) > cos_same {
                if arms[m].gap < arms[k].gap || (arms[m].gap == arms[k].gap && arms[m].length > arms[k].length) {
                    arms[k] = arms[m];
                }
                arms.swap_remove(m);
            } else {
                m += 1;
            }
        }
        k += 1;
    }
}

/// Map corners sorted by inner angle: similar-angle look-ups in O(log n + k) (section 5.1).
#[derive(Clone, Debug, Default)]
pub struct CornerIndex {
    corners: Slab<MapCorner>,
}

impl CornerIndex {
    pub fn new(mut corners: Vec<MapCorner>) -> Self {
        corners.sort_by(|a, b| a.inner_angle.total_cmp(&b.inner_angle));
        CornerIndex { corners: corners.into() }
    }

    pub fn build(walls: &[Wall], cfg: &MapCornerConfig) -> Self {
        Self::new(extract_map_corners(walls, cfg))
    }

    /// Every corner, sorted by inner angle.
    pub fn corners(&self) -> &[MapCorner] {
        &self.corners
    }

    /// Corners with |beta_m - beta| <= tolerance: a contiguous run found by binary search.
    pub fn similar(&self, beta: f64, tolerance: f64) -> &[MapCorner] {
        &self.corners[self.similar_range(beta, tolerance)]
    }

    /// Indices (into [`corners`](Self::corners)) of [`similar`](Self::similar)'s run.
    pub fn similar_range(&self, beta: f64, tolerance: f64) -> std::ops::Range<usize> {
        let lo = self.corners.partition_point(|c| c.inner_angle < beta - tolerance);
        let hi = self.corners.partition_point(|c| c.inner_angle <= beta + tolerance);
        lo..hi.max(lo)
    }

    /// Like [`similar`](Self::similar), restricted to corners within `radius` of `centre`
    /// (section 5.1: once localized, only corners around the last pose need checking).
    pub fn similar_near(
        &self,
        beta: f64,
        tolerance: f64,
        centre: Point2<f64>,
        radius: f64,
    ) -> impl Iterator<Item = &MapCorner> {
        self.similar(beta, tolerance).iter().filter(move |c| (c.position - centre).norm() <= radius)
    }
}

// SAFETY: `repr(C)`, f64 and u32 fields with the padding spelled out (checked), valid for any
// bits.
unsafe impl Plain for MapArm {}
// SAFETY: as above.
unsafe impl Plain for MapCorner {}
const _: () = assert!(std::mem::size_of::<MapArm>() == 48 && std::mem::size_of::<MapCorner>() == 128);

impl CornerIndex {
    /// Whether every corner's arms name one of `walls` walls and the corners are sorted by
    /// inner angle, as a look-up needs: for an index read from a block.
    pub fn check(&self, walls: usize) -> Result<(), FlatError> {
        if let Some(k) = self.corners.iter().position(|c| c.arms.iter().any(|a| a.wall as usize >= walls)) {
            return Err(FlatError::new(format!("corner {k} names a wall past the {walls} there are")));
        }
        if !self.corners.windows(2).all(|p| p[0].inner_angle <= p[1].inner_angle) {
            return Err(FlatError::new("the corners are not sorted by inner angle"));
        }
        Ok(())
    }
}

impl Flat for CornerIndex {
    fn put(&self, w: &mut FlatWriter) {
        self.corners.put(w);
    }
    fn take(r: &mut FlatReader<'_>) -> Result<Self, FlatError> {
        Ok(CornerIndex { corners: Slab::take(r)? })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::FRAC_PI_2;

    fn square() -> Vec<Wall> {
        vec![
            Wall::new(0.0, 0.0, 4.0, 0.0),
            Wall::new(4.0, 0.0, 4.0, 3.0),
            Wall::new(4.0, 3.0, 0.0, 3.0),
            Wall::new(0.0, 3.0, 0.0, 0.0),
        ]
    }

    #[test]
    fn a_square_room_has_an_inside_and_an_outside_corner_at_each_vertex() {
        let idx = CornerIndex::build(&square(), &MapCornerConfig { wall_ends: false, ..MapCornerConfig::default() });
        assert_eq!(idx.corners().len(), 8);
        assert_eq!(idx.similar(FRAC_PI_2, 0.01).len(), 4);
        assert_eq!(idx.similar(3.0 * FRAC_PI_2, 0.01).len(), 4);
        // the inside corner at (4, 0): from the wall towards -x... counter-clockwise to +y
        let c =
            idx.similar(FRAC_PI_2, 0.01).iter().find(|c| (c.position - Point2::new(4.0, 0.0)).norm() < 1e-9).unwrap();
        assert!(
            (c.arms[0].direction - Vector2::new(0.0, 1.0)).norm() < 1e-9
                || (c.arms[0].direction - Vector2::new(-1.0, 0.0)).norm() < 1e-9
        );
        let sweep = (angle_of(c.arms[1].direction) - angle_of(c.arms[0].direction)).rem_euclid(TAU);
        assert!((sweep - FRAC_PI_2).abs() < 1e-9);
    }

    #[test]
    fn a_door_gap_still_makes_the_corner_and_a_t_junction_makes_two() {
        // wall y = 0 from x = 0.9 (a door from 0 to 0.9) and wall x = 0 upwards: they would meet
        // at the origin
        let walls = vec![Wall::new(0.9, 0.0, 5.0, 0.0), Wall::new(0.0, 0.0, 0.0, 3.0)];
        let junctions_only = MapCornerConfig { wall_ends: false, ..MapCornerConfig::default() };
        let idx = CornerIndex::build(&walls, &junctions_only);
        assert_eq!(idx.corners().len(), 2);
        assert!(idx.corners().iter().all(|c| c.position.coords.norm() < 1e-9));
        assert!((idx.corners()[0].arms.iter().map(|a| a.gap).fold(0.0, f64::max) - 0.9).abs() < 1e-9);
        let t = vec![Wall::new(-3.0, 0.0, 3.0, 0.0), Wall::new(0.0, 0.0, 0.0, 2.0)];
        let idx = CornerIndex::build(&t, &junctions_only);
        // 90 degrees either side of the stem, and 270 degrees from the stem round the back to
        // either half of the bar; the straight 180 degree pairs make none
        assert_eq!(idx.corners().len(), 4);
        assert_eq!(idx.similar(FRAC_PI_2, 1e-9).len(), 2);
        assert_eq!(idx.similar(3.0 * FRAC_PI_2, 1e-9).len(), 2);
    }

    /// As a scan makes its corners (`segment::corner`): a junction beyond a wall's end by more
    /// than the short reach is a corner only between two long walls.
    #[test]
    fn only_long_walls_meet_far_beyond_their_ends() {
        let junctions_only = MapCornerConfig { wall_ends: false, ..MapCornerConfig::default() };
        // a wall up from (0, 3) would meet y = 0 at the origin, 3 m below its end
        let far = |length: f64| {
            let walls = vec![Wall::new(0.5, 0.0, 5.0, 0.0), Wall::new(0.0, 3.0, 0.0, 3.0 + length)];
            CornerIndex::build(&walls, &junctions_only).corners().len()
        };
        assert_eq!(far(2.0), 2);
        assert_eq!(far(0.5), 0);
        // within the short reach, a short wall meets any other
        let near = vec![Wall::new(0.5, 0.0, 5.0, 0.0), Wall::new(0.0, 0.8, 0.0, 1.2)];
        assert_eq!(CornerIndex::build(&near, &junctions_only).corners().len(), 2);
        // the short reach never exceeds the reach
        let tight = MapCornerConfig { reach: 0.5, ..junctions_only };
        assert_eq!(CornerIndex::build(&near, &tight).corners().len(), 0);
    }

    #[test]
    fn wall_ends_are_corners_of_a_full_turn_pointing_into_their_wall() {
        // the door gap of the test above: four wall ends
        let walls = vec![Wall::new(0.9, 0.0, 5.0, 0.0), Wall::new(0.0, 0.0, 0.0, 3.0)];
        let idx = CornerIndex::build(&walls, &MapCornerConfig::default());
        let ends = idx.similar(TAU, 1e-9);
        assert_eq!(ends.len(), 4);
        let jamb = ends.iter().find(|c| (c.position - Point2::new(0.9, 0.0)).norm() < 1e-9).unwrap();
        assert_eq!(jamb.arms[0], jamb.arms[1]);
        assert!((jamb.arms[0].direction - Vector2::new(1.0, 0.0)).norm() < 1e-9);
        assert!((jamb.arms[0].extent - 4.1).abs() < 1e-9);
        // the junction corners are still there, before the ends in inner angle order
        assert_eq!(idx.corners().len(), 6);
        assert!(idx.corners()[..2].iter().all(|c| c.inner_angle < TAU));
        assert_eq!(CornerIndex::build(&square(), &MapCornerConfig::default()).similar(TAU, 1e-9).len(), 8);
    }

    #[test]
    fn arm_extents_follow_collinear_walls_across_doors() {
        // a corridor wall in three pieces with 0.9 m doors, meeting an end wall at x = 0
        let walls = vec![
            Wall::new(0.0, 0.0, 3.0, 0.0),
            Wall::new(3.9, 0.0, 7.0, 0.0),
            Wall::new(7.9, 0.0, 10.0, 0.0),
            Wall::new(0.0, 0.0, 0.0, 3.0),
        ];
        let idx = CornerIndex::build(&walls, &MapCornerConfig::default());
        let c = idx.corners().iter().find(|c| c.position.coords.norm() < 1e-9).unwrap();
        let along_x = c.arms.iter().find(|a| a.direction.x > 0.5).unwrap();
        assert!((along_x.extent - 10.0).abs() < 1e-9, "{}", along_x.extent);
        assert!((along_x.length - 3.0).abs() < 1e-9);
    }

    #[test]
    fn similar_is_a_contiguous_run_of_the_sorted_list() {
        let idx = CornerIndex::build(&square(), &MapCornerConfig { wall_ends: false, ..MapCornerConfig::default() });
        assert!(idx.similar(1.0, 0.1).is_empty());
        assert_eq!(idx.similar(PI, PI).len(), 8);
        assert_eq!(idx.similar_near(FRAC_PI_2, 0.1, Point2::new(0.0, 0.0), 0.5).count(), 1);
    }
}
