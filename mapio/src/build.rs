//! A wall map built from scans at known poses: what `gema2 map build` makes of a SLAM-corrected
//! log, and what a grid becomes through a virtual survey ([`crate::resurvey`]).
//!
//! Every scan's lines (the same line visibility segmentation the localizer's scans go through)
//! are placed in the world; lines on the same wall are clustered (direction, then offset) and
//! their extents merged into candidate walls. A second pass over the scans counts, per cell,
//! the scans that hit it and the scans that saw through it ([`Occupancy`]); of each candidate,
//! the best seen first, the map keeps the parts where something stayed and that no wall kept
//! before covers. People and doors that moved are seen through and go; a door frame seen by one
//! scan stays. The valid beams also mark the free space the survey saw ([`SeenFree`]).

use crate::occupancy::Occupancy;
use laser::{LaserScan, Pose, Reading};
use map::{SeenFree, Wall, WallMap};
use nalgebra::{Point2, Vector2};
use segment::{LineVisibilitySegmenter, Segmenter, SegmenterConfig};
use std::f64::consts::PI;

/// A survey that can be walked more than once: its scans in order, each with its true pose.
/// [`build`] walks it twice (so that no beam need be kept in memory).
pub trait Survey {
    type Error;
    /// Calls `each` with every scan of the survey and its sensor's true pose.
    fn walk(&mut self, each: &mut dyn FnMut(&LaserScan, &Pose)) -> Result<(), Self::Error>;
}

/// How a map is built from a survey.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BuildConfig {
    /// Lines farther than this from the sensor are left out, and hits farther than this are
    /// not counted as evidence of a wall (metres): far hits are sparse and blurred.
    pub max_range: f64,
    /// Shortest line of a scan taken as a sighting of a wall, metres.
    pub min_length: f64,
    /// Cell of the occupancy grid that keeps of each wall the parts where something stayed,
    /// metres; 0: none, walls are then kept whole when `min_support` lines saw them.
    pub occupancy_cell: f64,
    /// Without an occupancy grid, the lines a wall needs to be kept.
    pub min_support: usize,
    /// The map's accuracy written into it, metres.
    pub sigma: f64,
    /// Cell of the free space the scans saw, metres; 0: none.
    pub seen_cell: f64,
}

impl Default for BuildConfig {
    fn default() -> Self {
        // a map from scans is good to about a decimetre (pose corrections, merging)
        BuildConfig {
            max_range: 15.0,
            min_length: 0.1,
            occupancy_cell: 0.05,
            min_support: 2,
            sigma: 0.1,
            seen_cell: 0.2,
        }
    }
}

/// A map built from a survey, with what it was built from.
#[derive(Clone, Debug)]
pub struct Built {
    pub map: WallMap,
    /// Scans and scan lines used.
    pub scans: usize,
    pub lines: usize,
    /// The occupancy grid's cell, when the survey spanned too much for the one asked.
    pub coarser_cell: Option<f64>,
}

/// Why no map was built: a setting, no wall, or the survey's own error.
#[derive(Debug)]
pub enum BuildError<E> {
    Setting(&'static str),
    NoWalls,
    Survey(E),
}

impl<E: std::fmt::Display> std::fmt::Display for BuildError<E> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            BuildError::Setting(name) => write!(f, "{name}: a length must be a non-negative number of metres"),
            BuildError::NoWalls => write!(f, "no wall was seen (seen twice, without an occupancy grid)"),
            BuildError::Survey(e) => write!(f, "{e}"),
        }
    }
}

impl<E: std::fmt::Debug + std::fmt::Display> std::error::Error for BuildError<E> {}

/// The wall map of `survey` ([module docs](self)).
pub fn build<S: Survey>(survey: &mut S, cfg: &BuildConfig) -> Result<Built, BuildError<S::Error>> {
    let metres = [
        ("max_range", cfg.max_range),
        ("min_length", cfg.min_length),
        ("occupancy_cell", cfg.occupancy_cell),
        ("sigma", cfg.sigma),
        ("seen_cell", cfg.seen_cell),
    ];
    if let Some((name, _)) = metres.iter().find(|(_, v)| !(v.is_finite() && *v >= 0.0)) {
        return Err(BuildError::Setting(name));
    }
    let mut seg = LineVisibilitySegmenter::new(SegmenterConfig::default());
    let mut seen = Vec::new();
    let mut scans = 0;
    survey
        .walk(&mut |scan, truth| {
            scans += 1;
            for l in &seg.segment(&scan.view()).lines {
                if l.start.coords.norm().max(l.end.coords.norm()) > cfg.max_range || l.length() < cfg.min_length {
                    continue;
                }
                seen.push(Observed::new(truth * l.start, truth * l.end));
            }
        })
        .map_err(BuildError::Survey)?;
    let candidates = merge(&mut seen);
    let (walls, seen_free, coarser_cell) = second_pass(survey, cfg, &candidates)?;
    if walls.is_empty() {
        return Err(BuildError::NoWalls);
    }
    Ok(Built {
        map: WallMap { walls: walls.into(), sigma: cfg.sigma, seen_free },
        scans,
        lines: seen.len(),
        coarser_cell,
    })
}

/// A scan's line in the world, with its direction either way along it.
#[derive(Clone, Copy)]
struct Observed {
    a: Point2<f64>,
    b: Point2<f64>,
    angle: f64,
}

impl Observed {
    fn new(a: Point2<f64>, b: Point2<f64>) -> Self {
        Observed { a, b, angle: Wall { a, b }.direction() }
    }
}

/// Gaps along a wall up to this long (metres) are bridged, between sightings and along the
/// occupancy grid: a doorway is wider.
const BRIDGE: f64 = 0.3;

/// Shorter walls are left out of the map (metres): a few beams' worth, too short to give a
/// corner a direction.
const SHORTEST_WALL: f64 = 0.2;

/// A wall merged from sightings, with how many scan lines saw it.
struct Candidate {
    wall: Wall,
    support: usize,
}

/// What the second pass gives: the walls kept, the free space seen, and the occupancy grid's
/// cell when coarser than asked.
type Kept = (Vec<Wall>, Option<SeenFree>, Option<f64>);

/// The second pass over the survey. It gives the walls kept of `candidates` and the cells the
/// valid beams crossed, from the sensor to a little short of what each hit, on a raster over
/// the candidates' bounds and a metre around them (`None` when that raster would be too
/// large).
///
/// Of each candidate, the parts where something stayed are kept ([`Occupancy`]); without an
/// occupancy grid, a candidate is kept whole when enough lines saw it and it is long enough
/// not to be a fragment.
fn second_pass<S: Survey>(
    survey: &mut S,
    cfg: &BuildConfig,
    candidates: &[Candidate],
) -> Result<Kept, BuildError<S::Error>> {
    let all: Vec<Wall> = candidates.iter().map(|c| c.wall).collect();
    if all.is_empty() {
        return Ok((all, None, None));
    }
    let (lo, hi) = map::map::bounds_of(&all);
    let (lo, hi) = (lo - Vector2::new(1.0, 1.0), hi + Vector2::new(1.0, 1.0));
    let mut seen = if cfg.seen_cell > 0.0 { SeenFree::covering(lo, hi, cfg.seen_cell) } else { None };
    let mut occupancy = if cfg.occupancy_cell > 0.0 { Occupancy::covering(lo, hi, cfg.occupancy_cell) } else { None };
    let coarser_cell = occupancy.as_ref().map(|o| o.cell()).filter(|&c| c > cfg.occupancy_cell);
    let short = 2.0 * cfg.sigma.max(0.05);
    if seen.is_some() || occupancy.is_some() {
        survey
            .walk(&mut |scan, truth| {
                let view = scan.view();
                let sensor = truth * Point2::origin();
                if let Some(o) = occupancy.as_mut() {
                    o.next_scan();
                }
                for i in 0..view.len() {
                    let Reading::Valid(d) = view.reading(i) else { continue };
                    let angle = view.geometry.angle(i);
                    let along = |t: f64| truth * (Point2::new(angle.cos(), angle.sin()) * t);
                    if let Some(s) = seen.as_mut() {
                        if d > short {
                            s.mark_ray(sensor, along(d - short));
                        }
                    }
                    if let Some(o) = occupancy.as_mut() {
                        // far hits are too sparse and too blurred to count; the beam still saw
                        // through everything before them
                        if d <= cfg.max_range {
                            o.add_beam(sensor, along(d), cfg.sigma);
                        } else {
                            o.pass_through(sensor, along(d - cfg.sigma));
                        }
                    }
                }
            })
            .map_err(BuildError::Survey)?;
    }
    let walls = match occupancy.as_mut() {
        Some(o) => {
            // the best seen first: each wall then adds only what those before it left out
            let mut order: Vec<&Candidate> = candidates.iter().collect();
            order.sort_by(|p, q| q.support.cmp(&p.support).then(q.wall.length().total_cmp(&p.wall.length())));
            let mut walls = Vec::new();
            for c in order {
                for part in o.static_parts(&c.wall, BRIDGE) {
                    if part.length() >= SHORTEST_WALL {
                        o.draw(&part);
                        walls.push(part);
                    }
                }
            }
            walls
        }
        None => candidates
            .iter()
            .filter(|c| c.support >= cfg.min_support && c.wall.length() >= SHORTEST_WALL.max(0.3))
            .map(|c| c.wall)
            .collect(),
    };
    Ok((walls, seen, coarser_cell))
}

/// Clusters lines by direction (within 2 degrees) and then offset (within 6 cm), and merges
/// each cluster's extents along the line, bridging gaps up to [`BRIDGE`].
fn merge(seen: &mut [Observed]) -> Vec<Candidate> {
    // directions live on a circle of circumference pi: cut it at the widest empty gap, so a wall
    // seen at 0.1 and 179.9 degrees stays one cluster
    seen.sort_by(|p, q| p.angle.total_cmp(&q.angle));
    if seen.len() > 1 {
        let n = seen.len();
        let gap =
            |k: usize| if k == 0 { seen[0].angle + PI - seen[n - 1].angle } else { seen[k].angle - seen[k - 1].angle };
        let cut = (0..n).max_by(|&a, &b| gap(a).total_cmp(&gap(b))).unwrap_or(0);
        seen.rotate_left(cut);
        for o in seen[n - cut..].iter_mut() {
            o.angle += PI;
        }
    }
    let mut walls = Vec::new();
    let mut start = 0;
    while start < seen.len() {
        let mut end = start + 1;
        // no chaining: a direction cluster spans at most 3 degrees
        while end < seen.len() && seen[end].angle - seen[start].angle < 3f64.to_radians() {
            end += 1;
        }
        let group = &seen[start..end];
        let mean = group.iter().map(|o| o.angle).sum::<f64>() / group.len() as f64;
        let dir = Vector2::new(mean.cos(), mean.sin());
        let normal = Vector2::new(-dir.y, dir.x);
        let mut by_offset: Vec<(f64, usize)> =
            group.iter().enumerate().map(|(i, o)| (normal.dot(&((o.a.coords + o.b.coords) / 2.0)), i)).collect();
        by_offset.sort_by(|p, q| p.0.total_cmp(&q.0));
        let mut k = 0;
        while k < by_offset.len() {
            let mut m = k + 1;
            while m < by_offset.len() && by_offset[m].0 - by_offset[m - 1].0 < 0.06 {
                m += 1;
            }
            // the wall's line: a total least squares fit of its members' endpoints
            let mut moments = laser::fit::Moments::default();
            for &(_, i) in &by_offset[k..m] {
                moments.add(group[i].a);
                moments.add(group[i].b);
            }
            let Some(fit) = moments.fit() else {
                k = m;
                continue;
            };
            let (d, c) = (fit.direction, fit.centroid);
            let mut spans: Vec<(f64, f64)> = by_offset[k..m]
                .iter()
                .map(|&(_, i)| {
                    let (s0, s1) = ((group[i].a - c).dot(&d), (group[i].b - c).dot(&d));
                    (s0.min(s1), s0.max(s1))
                })
                .collect();
            spans.sort_by(|p, q| p.0.total_cmp(&q.0));
            let (mut lo, mut hi, mut support) = (spans[0].0, spans[0].1, 1);
            let flush = |lo: f64, hi: f64, support: usize, walls: &mut Vec<Candidate>| {
                let (p, q) = (c + d * lo, c + d * hi);
                walls.push(Candidate { wall: Wall::new(p.x, p.y, q.x, q.y), support });
            };
            for &(s0, s1) in spans.iter().skip(1) {
                if s0 <= hi + BRIDGE {
                    hi = hi.max(s1);
                    support += 1;
                } else {
                    flush(lo, hi, support, &mut walls);
                    (lo, hi, support) = (s0, s1, 1);
                }
            }
            flush(lo, hi, support, &mut walls);
            k = m;
        }
        start = end;
    }
    walls
}

#[cfg(test)]
mod tests {
    use super::*;

    fn obs(x1: f64, y1: f64, x2: f64, y2: f64) -> Observed {
        Observed::new(Point2::new(x1, y1), Point2::new(x2, y2))
    }

    #[test]
    fn overlapping_sightings_of_a_wall_merge_and_lone_ones_go() {
        let mut seen = vec![
            obs(0.0, 1.0, 2.0, 1.01),
            obs(1.8, 1.0, 4.0, 0.99),
            obs(4.2, 1.0, 5.0, 1.0),
            // a parallel wall 0.5 m away, seen once: clutter
            obs(0.0, 1.5, 3.0, 1.5),
            // a perpendicular wall seen twice
            obs(5.0, 1.0, 5.0, 3.0),
            obs(5.01, 2.5, 5.0, 4.0),
        ];
        let walls: Vec<Wall> = merge(&mut seen).into_iter().filter(|c| c.support >= 2).map(|c| c.wall).collect();
        assert_eq!(walls.len(), 2, "{walls:?}");
        let long = walls.iter().map(|w| w.length()).fold(0.0, f64::max);
        assert!((long - 5.0).abs() < 0.05, "{long}");
    }
}
