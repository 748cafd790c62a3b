//! Walls with thickness: the outline a floor plan draws, from a map of centre lines.
//!
//! A plan drawn from a building (a CAD export, a traced floor plan) gives each wall two faces
//! a wall's thickness apart and a short jamb face at every door, where the generated maps give
//! one segment per wall. Those faces change what the localizer sees: four times the segments,
//! corners on both faces, door jambs 10-20 cm long. [`thicken`] turns a centre-line map into
//! that outline so the same scenes can be measured both ways.

use crate::map::{WallMap, MIN_WALL_LENGTH};
use crate::wall::Wall;
use nalgebra::{Point2, Vector2};

/// Distance within which a point counts as on a rectangle's boundary, metres.
const ON_BOUNDARY: f64 = 1e-9;

/// The outline of the union of every wall drawn `thickness` metres thick with square ends (each
/// wall's rectangle reaches half the thickness past its ends, so walls that meet at a junction
/// overlap): the parts of each rectangle's edges that lie outside every other rectangle. Where
/// two rectangles' edges coincide (collinear walls in a row, a wall ending against another's
/// face) the edge is kept once. The map's `sigma` carries over.
pub fn thicken(map: &WallMap, thickness: f64) -> WallMap {
    let half = thickness / 2.0;
    let rects: Vec<Rect> = map.walls.iter().filter_map(|w| Rect::around(w, half)).collect();
    let mut walls = Vec::new();
    let mut removed: Vec<(f64, f64)> = Vec::new();
    for (i, r) in rects.iter().enumerate() {
        for (a, b) in r.edges() {
            removed.clear();
            for (j, other) in rects.iter().enumerate() {
                if j != i {
                    // strictly inside the other rectangle; on its boundary only for the first of
                    // the two, so a shared edge is kept once
                    if let Some(span) = other.clip(a, b, if j < i { -ON_BOUNDARY } else { ON_BOUNDARY }) {
                        removed.push(span);
                    }
                }
            }
            push_remaining(a, b, &mut removed, &mut walls);
        }
    }
    WallMap { walls: merge_collinear(walls).into(), ..map.clone() }
}

/// Joins pieces that continue one another (collinear, meeting end to end where nothing else
/// meets), so each face is one wall as a plan draws it: a face split where another wall's
/// rectangle touched it would otherwise show wall ends in the middle of a face.
fn merge_collinear(mut walls: Vec<Wall>) -> Vec<Wall> {
    use std::collections::HashMap;
    let key = |p: Point2<f64>| ((p.x * 1e6).round() as i64, (p.y * 1e6).round() as i64);
    let mut at: HashMap<(i64, i64), Vec<usize>> = HashMap::new();
    for (k, w) in walls.iter().enumerate() {
        at.entry(key(w.a)).or_default().push(k);
        at.entry(key(w.b)).or_default().push(k);
    }
    let mut alive = vec![true; walls.len()];
    let mut points: Vec<(i64, i64)> = at.keys().copied().collect();
    points.sort_unstable();
    for p in points {
        let Some(ends) = at.get(&p) else { continue };
        let [i, j] = ends[..] else { continue };
        if i == j {
            continue;
        }
        let (wi, wj) = (walls[i], walls[j]);
        // the far end of each from the shared point
        let far = |w: Wall| if key(w.a) == p { w.b } else { w.a };
        let (fi, fj) = (far(wi), far(wj));
        // collinear, and on opposite sides of the shared point
        let straight = (wi.b - wi.a).normalize().perp(&(wj.b - wj.a).normalize()).abs() < 1e-7;
        if !straight || (fj - fi).norm() < wi.length() + wj.length() - 1e-6 {
            continue;
        }
        walls[i] = Wall { a: fi, b: fj };
        alive[j] = false;
        // fj's segment is now i
        if let Some(list) = at.get_mut(&key(fj)) {
            list.iter_mut().filter(|k| **k == j).for_each(|k| *k = i);
        }
        at.remove(&p);
    }
    walls.into_iter().zip(alive).filter_map(|(w, a)| a.then_some(w)).collect()
}

/// The pieces of segment a-b outside the parameter intervals `removed` (sorted in place).
fn push_remaining(a: Point2<f64>, b: Point2<f64>, removed: &mut [(f64, f64)], out: &mut Vec<Wall>) {
    removed.sort_by(|x, y| x.0.total_cmp(&y.0));
    let length = (b - a).norm();
    let mut from = 0.0;
    let mut keep = |t0: f64, t1: f64| {
        if (t1 - t0) * length >= MIN_WALL_LENGTH {
            out.push(Wall { a: a + (b - a) * t0, b: a + (b - a) * t1 });
        }
    };
    for &(t0, t1) in removed.iter() {
        if t0 > from {
            keep(from, t0);
        }
        from = f64::max(from, t1);
    }
    if from < 1.0 {
        keep(from, 1.0);
    }
}

/// A wall's rectangle: centre `c`, unit axis `u` along the wall, half extents.
#[derive(Clone, Copy, Debug)]
struct Rect {
    c: Point2<f64>,
    u: Vector2<f64>,
    half_length: f64,
    half_width: f64,
}

impl Rect {
    fn around(w: &Wall, half: f64) -> Option<Rect> {
        let length = w.length();
        (length > 0.0 && half > 0.0).then(|| Rect {
            c: Point2::from((w.a.coords + w.b.coords) / 2.0),
            u: (w.b - w.a) / length,
            half_length: length / 2.0 + half,
            half_width: half,
        })
    }

    /// The unit axis across the wall, `u` turned a quarter counter-clockwise.
    fn across(&self) -> Vector2<f64> {
        Vector2::new(-self.u.y, self.u.x)
    }

    /// The four edges, counter-clockwise.
    fn edges(&self) -> [(Point2<f64>, Point2<f64>); 4] {
        let (u, v) = (self.u * self.half_length, self.across() * self.half_width);
        let p = [self.c - u - v, self.c + u - v, self.c + u + v, self.c - u + v];
        [(p[0], p[1]), (p[1], p[2]), (p[2], p[3]), (p[3], p[0])]
    }

    /// The parameter interval of segment a-b (0 at a, 1 at b) inside the rectangle shrunk by
    /// `margin` (grown when negative), if it is not empty (Cyrus-Beck clipping).
    fn clip(&self, a: Point2<f64>, b: Point2<f64>, margin: f64) -> Option<(f64, f64)> {
        let v = self.across();
        let (mut t0, mut t1) = (0.0f64, 1.0f64);
        for (axis, extent) in [(self.u, self.half_length), (v, self.half_width)] {
            // |axis . (p(t) - c)| < extent - margin, with p(t) = a + t (b - a)
            let (start, rate) = (axis.dot(&(a - self.c)), axis.dot(&(b - a)));
            let limit = extent - margin;
            if rate.abs() < 1e-15 {
                if start.abs() >= limit {
                    return None;
                }
                continue;
            }
            let (lo, hi) = ((-limit - start) / rate, (limit - start) / rate);
            let (lo, hi) = if lo < hi { (lo, hi) } else { (hi, lo) };
            t0 = t0.max(lo);
            t1 = t1.min(hi);
        }
        (t1 > t0).then_some((t0, t1))
    }

    /// Whether `p` lies strictly inside, by more than `margin`.
    #[cfg(test)]
    fn contains(&self, p: Point2<f64>, margin: f64) -> bool {
        let d = p - self.c;
        let v = self.across();
        d.dot(&self.u).abs() < self.half_length - margin && d.dot(&v).abs() < self.half_width - margin
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn total_length(m: &WallMap) -> f64 {
        m.walls.iter().map(Wall::length).sum()
    }

    #[test]
    fn one_wall_becomes_its_rectangle() {
        let m = thicken(&WallMap::new(vec![Wall::new(0.0, 0.0, 2.0, 0.0)]), 0.2);
        assert_eq!(m.walls.len(), 4);
        // 2.2 x 0.2 with the square ends
        assert!((total_length(&m) - 4.8).abs() < 1e-6, "{}", total_length(&m));
    }

    #[test]
    fn an_l_junction_is_one_outline() {
        let m = thicken(&WallMap::new(vec![Wall::new(0.0, 0.0, 2.0, 0.0), Wall::new(2.0, 0.0, 2.0, 3.0)]), 0.2);
        // outer faces 2.2 and 3.2, inner faces 2.0 and 3.0, two end faces 0.2: nothing inside
        // the corner, nothing twice where the rectangles' edges coincide
        assert!((total_length(&m) - 10.8).abs() < 1e-6, "{}", total_length(&m));
    }

    #[test]
    fn collinear_walls_in_a_row_share_their_faces_once() {
        let m = thicken(&WallMap::new(vec![Wall::new(0.0, 0.0, 1.0, 0.0), Wall::new(1.0, 0.0, 3.0, 0.0)]), 0.2);
        // the outline of one 3 m wall: 3.2 x 0.2
        assert!((total_length(&m) - 6.8).abs() < 1e-6, "{}", total_length(&m));
    }

    #[test]
    fn each_face_is_one_wall() {
        // a T: the crossbar's lower face is split by the stem, its upper face is whole
        let t = vec![Wall::new(0.0, 0.0, 4.0, 0.0), Wall::new(2.0, 0.0, 2.0, -3.0)];
        let m = thicken(&WallMap::new(t), 0.2);
        assert_eq!(m.walls.len(), 8, "{:#?}", m.walls);
        let upper: Vec<&Wall> =
            m.walls.iter().filter(|w| (w.a.y - 0.1).abs() < 1e-9 && (w.b.y - 0.1).abs() < 1e-9).collect();
        assert_eq!(upper.len(), 1);
        assert!((upper[0].length() - 4.2).abs() < 1e-6);
    }

    #[test]
    fn a_door_leaves_two_jambs() {
        let m = thicken(&WallMap::new(vec![Wall::new(0.0, 0.0, 2.0, 0.0), Wall::new(2.9, 0.0, 5.0, 0.0)]), 0.1);
        let jambs = m.walls.iter().filter(|w| (w.length() - 0.1).abs() < 1e-9).count();
        assert_eq!(jambs, 4, "two jambs at the door and the two far ends");
        let opening = m.walls.iter().filter(|w| w.a.x.max(w.b.x) > 2.06 && w.a.x.min(w.b.x) < 2.84).count();
        assert_eq!(opening, 0, "nothing drawn across the door");
    }

    proptest! {
        /// Every drawn point lies on the union's boundary (inside no rectangle), and every
        /// rectangle edge point outside all other rectangles is drawn.
        #[test]
        fn the_outline_is_the_union_boundary(
            walls in proptest::collection::vec((0.0f64..6.0, 0.0f64..6.0, 0.0f64..6.0, 0.0f64..6.0), 1..8),
            thickness in 0.05f64..0.3,
        ) {
            let walls: Vec<Wall> = walls.into_iter().map(|(a, b, c, d)| Wall::new(a, b, c, d)).filter(|w| w.length() > 0.05).collect();
            let map = WallMap::new(walls);
            let out = thicken(&map, thickness);
            let rects: Vec<Rect> = map.walls.iter().filter_map(|w| Rect::around(w, thickness / 2.0)).collect();
            for w in &out.walls {
                for k in 1..8 {
                    let p = w.a + (w.b - w.a) * (k as f64 / 8.0);
                    prop_assert!(!rects.iter().any(|r| r.contains(p, 1e-7)), "{p:?} drawn inside a wall");
                }
            }
            for (i, r) in rects.iter().enumerate() {
                for (a, b) in r.edges() {
                    for k in 1..16 {
                        let p = a + (b - a) * (k as f64 / 16.0);
                        let outside = rects.iter().enumerate().all(|(j, o)| j == i || !o.contains(p, -1e-7));
                        if outside {
                            let drawn = out.walls.iter().any(|w| w.closest(p).0 < 1e-7);
                            prop_assert!(drawn, "{p:?} on the union's boundary is not drawn");
                        }
                    }
                }
            }
        }
    }
}
