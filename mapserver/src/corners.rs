//! The map's corners, pre-computed and sorted by inner angle (section 5.1).
//!
//! A corner is where walls meet, or where their extensions meet within `reach` of both walls'
//! ends (a door or a gap between the walls still makes the corner a scan can see). At each such
//! junction the walls offer *arms*: the directions from the junction along each wall towards
//! the wall material (two when the junction falls inside a wall: a T). Arms are sorted
//! counter-clockwise and each angular region between neighbouring arms is one corner, with the
//! same convention as scan corners (crate `segment`): beta is swept counter-clockwise from the
//! right arm to the left arm. A map does not say which side of a wall is free, so a junction of
//! two walls gives both corners (beta and 2 pi - beta); hypotheses from the wrong one are
//! rejected by the cost function.

use crate::map::Wall;
use nalgebra::{Point2, Vector2};
use std::f64::consts::{PI, TAU};

/// One side of a map corner.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MapArm {
    /// Unit vector from the corner along the wall.
    pub direction: Vector2<f64>,
    /// Distance from the corner to where the wall starts.
    pub gap: f64,
    /// Length of the wall beyond the gap.
    pub length: f64,
    pub wall: u32,
}

/// A corner m of the map.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MapCorner {
    pub position: Point2<f64>,
    /// beta_m in (0, 2 pi).
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
    /// How far a junction may lie beyond a wall's end, metres.
    pub reach: f64,
    /// Shortest arm, metres.
    pub min_arm_length: f64,
}

impl Default for MapCornerConfig {
    fn default() -> Self {
        MapCornerConfig {
            min_angle: 25f64.to_radians(),
            reach: 1.0,
            min_arm_length: 0.1,
        }
    }
}

/// Junctions closer than this are one junction, metres.
const MERGE: f64 = 0.02;

/// Extracts every corner of `walls`.
pub fn extract_map_corners(walls: &[Wall], cfg: &MapCornerConfig) -> Vec<MapCorner> {
    let junctions = junctions(walls, cfg);
    let mut corners = Vec::new();
    let mut arms: Vec<MapArm> = Vec::new();
    for (x, members) in junctions {
        arms.clear();
        for &w in &members {
            arms_of(&walls[w as usize], w, x, cfg, &mut arms);
        }
        dedupe_arms(&mut arms);
        if arms.len() < 2 {
            continue;
        }
        arms.sort_by(|a, b| angle_of(a.direction).total_cmp(&angle_of(b.direction)));
        for k in 0..arms.len() {
            let (right, left) = (arms[k], arms[(k + 1) % arms.len()]);
            let beta = (angle_of(left.direction) - angle_of(right.direction)).rem_euclid(TAU);
            let beta = if arms.len() == 1 || beta == 0.0 {
                TAU
            } else {
                beta
            };
            if beta < cfg.min_angle
                || beta > TAU - cfg.min_angle
                || (beta - PI).abs() < cfg.min_angle
            {
                continue;
            }
            corners.push(MapCorner {
                position: x,
                inner_angle: beta,
                orientation: angle_of(right.direction),
                arms: [right, left],
            });
        }
    }
    corners
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
            let r = Vector2::new(cfg.reach, cfg.reach);
            (w.a.inf(&w.b) - r, w.a.sup(&w.b) + r)
        })
        .collect();
    for i in 0..walls.len() {
        for j in i + 1..walls.len() {
            let (bi, bj) = (&boxes[i], &boxes[j]);
            if bi.0.x > bj.1.x || bj.0.x > bi.1.x || bi.0.y > bj.1.y || bj.0.y > bi.1.y {
                continue;
            }
            let (a, b) = (&walls[i], &walls[j]);
            let (da, db) = ((a.b - a.a).normalize(), (b.b - b.a).normalize());
            let den = da.perp(&db);
            if den.abs() < min_sin {
                continue;
            }
            let t = (b.a - a.a).perp(&db) / den;
            let x = a.a + da * t;
            if a.closest(x).0 <= cfg.reach && b.closest(x).0 <= cfg.reach {
                found.push((x, i as u32, j as u32));
            }
        }
    }
    // cluster intersection points that coincide (several walls meeting at one point)
    found.sort_by(|p, q| p.0.x.total_cmp(&q.0.x));
    let mut out: Vec<(Point2<f64>, Vec<u32>)> = Vec::new();
    let mut used = vec![false; found.len()];
    for k in 0..found.len() {
        if used[k] {
            continue;
        }
        let x = found[k].0;
        let mut members = vec![found[k].1, found[k].2];
        for m in k + 1..found.len() {
            if found[m].0.x - x.x > MERGE {
                break;
            }
            if !used[m] && (found[m].0 - x).norm() <= MERGE {
                used[m] = true;
                members.extend([found[m].1, found[m].2]);
            }
        }
        members.sort_unstable();
        members.dedup();
        out.push((x, members));
    }
    out
}

fn arms_of(w: &Wall, index: u32, x: Point2<f64>, cfg: &MapCornerConfig, out: &mut Vec<MapArm>) {
    let len = w.length();
    let dir = (w.b - w.a) / len;
    let t = (x - w.a).dot(&dir);
    for (direction, gap, length) in [
        (dir, (-t).max(0.0), len - t.max(0.0)),
        (-dir, (t - len).max(0.0), t.min(len)),
    ] {
        if gap <= cfg.reach && length >= cfg.min_arm_length {
            out.push(MapArm {
                direction,
                gap,
                length,
                wall: index,
            });
        }
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
                if arms[m].gap < arms[k].gap
                    || (arms[m].gap == arms[k].gap && arms[m].length > arms[k].length)
                {
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
    corners: Vec<MapCorner>,
}

impl CornerIndex {
    pub fn new(mut corners: Vec<MapCorner>) -> Self {
        corners.sort_by(|a, b| a.inner_angle.total_cmp(&b.inner_angle));
        CornerIndex { corners }
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
        let lo = self
            .corners
            .partition_point(|c| c.inner_angle < beta - tolerance);
        let hi = self
            .corners
            .partition_point(|c| c.inner_angle <= beta + tolerance);
        &self.corners[lo..hi.max(lo)]
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
        self.similar(beta, tolerance)
            .iter()
            .filter(move |c| (c.position - centre).norm() <= radius)
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
        let idx = CornerIndex::build(&square(), &MapCornerConfig::default());
        assert_eq!(idx.corners().len(), 8);
        assert_eq!(idx.similar(FRAC_PI_2, 0.01).len(), 4);
        assert_eq!(idx.similar(3.0 * FRAC_PI_2, 0.01).len(), 4);
        // the inside corner at (4, 0): from the wall towards -x... counter-clockwise to +y
        let c = idx
            .similar(FRAC_PI_2, 0.01)
            .iter()
            .find(|c| (c.position - Point2::new(4.0, 0.0)).norm() < 1e-9)
            .unwrap();
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
        let idx = CornerIndex::build(&walls, &MapCornerConfig::default());
        assert_eq!(idx.corners().len(), 2);
        assert!(idx
            .corners()
            .iter()
            .all(|c| c.position.coords.norm() < 1e-9));
        assert!(
            (idx.corners()[0]
                .arms
                .iter()
                .map(|a| a.gap)
                .fold(0.0, f64::max)
                - 0.9)
                .abs()
                < 1e-9
        );
        let t = vec![
            Wall::new(-3.0, 0.0, 3.0, 0.0),
            Wall::new(0.0, 0.0, 0.0, 2.0),
        ];
        let idx = CornerIndex::build(&t, &MapCornerConfig::default());
        // two 90 degree corners either side of the stem; the 180 degree side makes none
        assert_eq!(idx.corners().len(), 2);
        assert!(idx
            .corners()
            .iter()
            .all(|c| (c.inner_angle - FRAC_PI_2).abs() < 1e-9));
    }

    #[test]
    fn similar_is_a_contiguous_run_of_the_sorted_list() {
        let idx = CornerIndex::build(&square(), &MapCornerConfig::default());
        assert!(idx.similar(1.0, 0.1).is_empty());
        assert_eq!(idx.similar(PI, PI).len(), 8);
        assert_eq!(
            idx.similar_near(FRAC_PI_2, 0.1, Point2::new(0.0, 0.0), 0.5)
                .count(),
            1
        );
    }
}
