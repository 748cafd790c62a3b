//! `gema2 map build`: a wall map from the scans of a log whose poses are true (a
//! SLAM-corrected log). Every scan's lines are placed in the world; lines on the same wall are
//! clustered (direction, then offset) and their extents merged into candidate walls. A second
//! pass over the scans counts, per cell, the scans that hit it and the scans that saw through
//! it ([`Occupancy`]); of each candidate, the best seen first, the map keeps the parts where
//! something stayed and that no wall kept before covers. People and doors that moved are
//! seen through and go; a door frame seen by one scan stays. Evaluate on scans the map was not
//! built from (`--every 2` here, `locate --every 2 --offset 1` there).

use super::scans::{Source, SourceError};
use super::Malformed;
use anyhow::{bail, Context, Result};
use clap::Args;
use laser::{LaserScan, Pose, Reading};
use map::{SeenFree, Wall, WallMap};
use mapio::Occupancy;
use nalgebra::{Point2, Vector2};
use segment::{LineVisibilitySegmenter, Segmenter, SegmenterConfig};
use std::f64::consts::PI;
use std::path::{Path, PathBuf};

#[derive(Args)]
pub struct BuildArgs {
    /// A CARMEN log with true poses.
    #[arg(long, required_unless_present = "bag")]
    pub log: Option<PathBuf>,
    #[command(flatten)]
    pub flaser: acquire::FlaserArgs,
    /// A ROS 2 bag with true poses on `--truth-topic`, instead of a log.
    #[command(flatten)]
    pub bag: super::scans::BagArgs,
    /// Use every K-th scan...
    #[arg(long, default_value_t = 2, value_parser = super::positive_count)]
    pub every: usize,
    /// ...starting at this one.
    #[arg(long, default_value_t = 0)]
    pub offset: usize,
    /// Lines farther than this from the sensor are left out (metres).
    #[arg(long, default_value_t = 15.0)]
    pub max_range: f64,
    /// Shortest line of a scan taken as a sighting of a wall, metres.
    #[arg(long, default_value_t = 0.1)]
    pub min_length: f64,
    /// Cell of the occupancy grid that keeps of each wall the parts where something stayed,
    /// metres. 0 turns it off: walls are then kept whole when `--min-support` lines saw them.
    #[arg(long, default_value_t = 0.05)]
    pub occupancy_cell: f64,
    /// Without an occupancy grid, the lines a wall needs to be kept.
    #[arg(long, default_value_t = 2)]
    pub min_support: usize,
    /// The map's accuracy written into it, metres: the cost function expects no better.
    #[arg(long, default_value_t = 0.1)]
    pub sigma: f64,
    /// Cell of the free space the scans saw, written into the map (`"seen_free"`), metres; 0
    /// writes none. The localizer answers with no pose where no beam has been.
    #[arg(long, default_value_t = 0.2)]
    pub seen_cell: f64,
    /// Where to write the map, as a JSON wall map (what `--map` of locate and the map server take).
    #[arg(long)]
    pub out: PathBuf,
    /// Also write the survey as a ROS map_server occupancy grid (this YAML and a PGM beside
    /// it): each beam's end adds evidence of a wall, the cells it crossed evidence of free
    /// space, in log odds, as a grid-mapping SLAM does at these poses. For AMCL, or to compare
    /// a grid traced into walls (`--map GRID.yaml`) with the map built here.
    #[arg(long)]
    pub grid: Option<PathBuf>,
    /// Cell of `--grid`, metres.
    #[arg(long, default_value_t = 0.05)]
    pub grid_cell: f64,
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

/// Refuses a length flag that is not a non-negative number of metres.
fn check_metres(flag: &str, value: f64) -> Result<()> {
    if !(value.is_finite() && value >= 0.0) {
        bail!("{flag} must be a non-negative number of metres, not {value}");
    }
    Ok(())
}

impl BuildArgs {
    /// The log or bag read, for messages.
    fn source_path(&self) -> &Path {
        self.bag.bag.as_deref().or(self.log.as_deref()).unwrap_or(Path::new("-"))
    }

    /// `gema2 map build`'s defaults for every other scan of `log` from `offset` (its `out`
    /// is "-", unused: for a caller that keeps the map).
    pub fn every_other(log: &std::path::Path, offset: usize) -> Result<Self> {
        #[derive(clap::Parser)]
        struct Command {
            #[command(flatten)]
            args: BuildArgs,
        }
        let offset = offset.to_string();
        let argv = ["build", "--out", "-", "--every", "2", "--offset", &offset, "--log"];
        let log = log.as_os_str();
        let parsed = <Command as clap::Parser>::try_parse_from(argv.iter().map(std::ffi::OsStr::new).chain([log]))?;
        Ok(parsed.args)
    }
}

pub fn run(a: BuildArgs) -> Result<()> {
    if let Some(path) = &a.grid {
        check_metres("--grid-cell", a.grid_cell)?;
        let grid = survey_grid(&a)?;
        grid.save(path)?;
        eprintln!("{}: a {} x {} grid of {} m", path.display(), grid.width, grid.height, grid.resolution);
    }
    let mut malformed = Malformed::default();
    let Built { map, scans, lines } = build(&a, &mut malformed)?;
    std::fs::write(&a.out, map.to_json("built")).with_context(|| format!("writing {}", a.out.display()))?;
    eprintln!("{}: {} walls from {lines} lines of {scans} scans", a.out.display(), map.walls.len());
    // nothing in a CARMEN log tells corrected poses from raw odometry (corrected logs overwrite
    // the odometry too), so the user is told what the map rests on
    eprintln!(
        "  built on the log's poses, taken as ground truth: the map is only as good as they are (raw \
         odometry drifts, and bends and doubles the walls; build from a SLAM-corrected log)"
    );
    match &map.seen_free {
        Some(s) => eprintln!("  free space seen on {} cells of {} m", s.seen_cells(), s.cell()),
        None if a.seen_cell > 0.0 => {
            eprintln!("  no free space kept: the raster would exceed {} cells", map::seen::MAX_CELLS)
        }
        None => {}
    }
    // the map is written, built from the scans that could be read; the run still fails, so no
    // script takes the survey for whole
    malformed.into_result("left out of the map")?;
    Ok(())
}

/// The map of `a`'s scans, with how many scans and scan lines it was built from. Malformed
/// laser lines are left out, added to `malformed`.
pub fn build(a: &BuildArgs, malformed: &mut Malformed) -> Result<Built> {
    // before the first pass over the log, which may be long
    check_metres("--min-length", a.min_length)?;
    check_metres("--seen-cell", a.seen_cell)?;
    check_metres("--occupancy-cell", a.occupancy_cell)?;
    let mut seg = LineVisibilitySegmenter::new(SegmenterConfig::default());
    let mut seen = Vec::new();
    let mut scans = 0;
    let progress = crate::progress::Progress::of_log("surveying ", a.source_path(), None);
    for item in survey(a)? {
        progress.set(scans as u64, 0, 0);
        let (scan, truth) = match item? {
            Surveyed::Scan(item, truth) => (item.scan, truth),
            Surveyed::Malformed(e) => {
                malformed.add(e);
                continue;
            }
        };
        scans += 1;
        for l in &seg.segment(&scan.view()).lines {
            if l.start.coords.norm().max(l.end.coords.norm()) > a.max_range || l.length() < a.min_length {
                continue;
            }
            seen.push(Observed::new(truth * l.start, truth * l.end));
        }
    }
    progress.finish();
    let candidates = merge(&mut seen);
    let (walls, seen_free) = second_pass(a, &candidates)?;
    if walls.is_empty() {
        bail!("{}: no wall was seen (seen twice, with --occupancy-cell 0)", a.source_path().display());
    }
    // a map from scans is good to about a decimetre (pose corrections, merging)
    Ok(Built { map: WallMap { walls: walls.into(), sigma: a.sigma, seen_free }, scans, lines: seen.len() })
}

/// A map built from a survey, with what it was built from.
pub struct Built {
    pub map: WallMap,
    /// Scans and scan lines used.
    pub scans: usize,
    pub lines: usize,
}

/// The occupancy grid of the survey's beams ([`mapio::SurveyGrid`]): returns up to
/// `--max-range` only (far hits are sparse and blurred), and the cells crossed that far by the
/// beams that reach farther or return nothing.
pub(crate) fn survey_grid(a: &BuildArgs) -> Result<mapio::OccupancyGrid> {
    // each beam's sensor, end and whether the end is a return
    let beams = |scan: &LaserScan, truth: &Pose| -> Vec<(Point2<f64>, Point2<f64>, bool)> {
        let view = scan.view();
        let sensor = truth * Point2::origin();
        (0..view.len())
            .filter_map(|i| {
                let angle = view.geometry.angle(i);
                let along = |t: f64| truth * (Point2::new(angle.cos(), angle.sin()) * t);
                match view.reading(i) {
                    Reading::Valid(d) if d <= a.max_range => Some((sensor, along(d), true)),
                    Reading::Valid(_) | Reading::NoReturn => Some((sensor, along(a.max_range), false)),
                    Reading::Unknown => None,
                }
            })
            .collect()
    };
    // the log twice: once for the grid's bounds, once for the beams
    let mut bounds: Option<(Point2<f64>, Point2<f64>)> = None;
    for item in survey(a)? {
        let Some((scan, truth)) = scan_of(item)? else { continue };
        for (s, e, _) in beams(&scan, &truth) {
            let (lo, hi) = bounds.unwrap_or((s, s));
            bounds = Some((lo.inf(&s).inf(&e), hi.sup(&s).sup(&e)));
        }
    }
    let Some((lo, hi)) = bounds else {
        bail!("{}: no beam to draw a grid from", a.source_path().display());
    };
    let margin = Vector2::new(2.0 * a.grid_cell, 2.0 * a.grid_cell);
    let Some(mut grid) = mapio::SurveyGrid::covering(lo - margin, hi + margin, a.grid_cell) else {
        bail!("--grid-cell {}: the survey spans too many cells of that size", a.grid_cell);
    };
    for item in survey(a)? {
        let Some((scan, truth)) = scan_of(item)? else { continue };
        for (sensor, end, hit) in beams(&scan, &truth) {
            grid.add_beam(sensor, end, hit);
        }
    }
    Ok(grid.to_occupancy_grid())
}

/// A laser line of the survey: a scan with its true pose, or a line that could not be read
/// as one, which the map is built without.
enum Surveyed {
    Scan(acquire::LogScan, Pose),
    Malformed(String),
}

/// The scans the map is built from (every `every`-th from `offset`), each with its true pose.
/// A malformed laser line is handed on as such, for the first pass to report; an unreadable
/// log or a scan without a pose is an error.
fn survey(a: &BuildArgs) -> Result<impl Iterator<Item = Result<Surveyed>> + '_> {
    let source = Source::open(a.log.as_deref(), &a.bag, &a.flaser)?;
    let path = source.path;
    Ok(source.scans.enumerate().filter(move |(k, _)| super::selected(*k, a.every, a.offset)).map(move |(k, item)| {
        let item = match item {
            Ok(item) => item,
            Err(SourceError::Skip(e)) => return Ok(Surveyed::Malformed(e)),
            Err(SourceError::Stop(e)) => return Err(e),
        };
        let truth = item.scan.truth.with_context(|| {
            format!("{}: scan {k} has no pose: a map needs a corrected log, or a bag's --truth-topic", path.display())
        })?;
        Ok(Surveyed::Scan(item, truth))
    }))
}

/// The scan of a surveyed line, `None` for a malformed one (passed over).
fn scan_of(item: Result<Surveyed>) -> Result<Option<(LaserScan, Pose)>> {
    Ok(match item? {
        Surveyed::Scan(item, truth) => Some((item.scan, truth)),
        Surveyed::Malformed(_) => None,
    })
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

/// The second pass over the survey (so no beam is kept in memory). It gives the walls kept of
/// `candidates` and the cells the valid beams crossed, from the sensor to a little short of
/// what each hit, on a raster over the candidates' bounds and a metre around them (`None`
/// when that raster would be too large).
///
/// Of each candidate, the parts where something stayed are kept ([`Occupancy`]); without an
/// occupancy grid, a candidate is kept whole when enough lines saw it and it is long enough
/// not to be a fragment.
fn second_pass(a: &BuildArgs, candidates: &[Candidate]) -> Result<(Vec<Wall>, Option<SeenFree>)> {
    let all: Vec<Wall> = candidates.iter().map(|c| c.wall).collect();
    if all.is_empty() {
        return Ok((all, None));
    }
    let (lo, hi) = map::map::bounds_of(&all);
    let (lo, hi) = (lo - Vector2::new(1.0, 1.0), hi + Vector2::new(1.0, 1.0));
    let mut seen = if a.seen_cell > 0.0 { SeenFree::covering(lo, hi, a.seen_cell) } else { None };
    let mut occupancy = if a.occupancy_cell > 0.0 { Occupancy::covering(lo, hi, a.occupancy_cell) } else { None };
    if let Some(o) = occupancy.as_ref().filter(|o| o.cell() > a.occupancy_cell) {
        eprintln!(
            "  occupancy cells of {:.3} m instead of {} m: the survey spans too much",
            o.cell(),
            a.occupancy_cell
        );
    }
    let short = 2.0 * a.sigma.max(0.05);
    if seen.is_some() || occupancy.is_some() {
        for item in survey(a)? {
            let Some((scan, truth)) = scan_of(item)? else { continue };
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
                    if d <= a.max_range {
                        o.add_beam(sensor, along(d), a.sigma);
                    } else {
                        o.pass_through(sensor, along(d - a.sigma));
                    }
                }
            }
        }
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
            .filter(|c| c.support >= a.min_support && c.wall.length() >= SHORTEST_WALL.max(0.3))
            .map(|c| c.wall)
            .collect(),
    };
    Ok((walls, seen))
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
            let mut moments = segment::fit::Moments::default();
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
