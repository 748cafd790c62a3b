//! `gema2 map build`: a wall map from the scans of a log whose poses are true (a
//! SLAM-corrected log), as [`mapio::build()`] makes it. Evaluate on scans the map was not built
//! from (`--every 2` here, `locate --every 2 --offset 1` there).

use super::scans::{Source, SourceError};
use super::Malformed;
use anyhow::{bail, Context, Result};
use clap::Args;
use laser::{LaserScan, Pose, Reading};
use mapio::{BuildConfig, BuildError, Built};
use nalgebra::{Point2, Vector2};
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
    /// a grid made into walls (`--map GRID.yaml`) with the map built here.
    #[arg(long)]
    pub grid: Option<PathBuf>,
    /// Cell of `--grid`, metres.
    #[arg(long, default_value_t = 0.05)]
    pub grid_cell: f64,
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

    /// How the map is built.
    fn config(&self) -> BuildConfig {
        BuildConfig {
            max_range: self.max_range,
            min_length: self.min_length,
            occupancy_cell: self.occupancy_cell,
            min_support: self.min_support,
            sigma: self.sigma,
            seen_cell: self.seen_cell,
        }
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
    let Built { map, scans, lines, .. } = build(&a, &mut malformed)?;
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

/// The map of `a`'s scans ([`mapio::build()`]). Malformed laser lines are left out, added to
/// `malformed`.
pub fn build(a: &BuildArgs, malformed: &mut Malformed) -> Result<Built> {
    // before the first pass over the log, which may be long
    check_metres("--min-length", a.min_length)?;
    check_metres("--seen-cell", a.seen_cell)?;
    check_metres("--occupancy-cell", a.occupancy_cell)?;
    let mut log = LogSurvey { a, malformed, walks: 0 };
    let built = mapio::build(&mut log, &a.config()).map_err(|e| match e {
        BuildError::Survey(e) => e,
        e => anyhow::anyhow!("{}: {e}", a.source_path().display()),
    })?;
    if let Some(cell) = built.coarser_cell {
        eprintln!("  occupancy cells of {cell:.3} m instead of {} m: the survey spans too much", a.occupancy_cell);
    }
    Ok(built)
}

/// The log's scans (every `every`-th from `offset`) with their true poses, walked once for
/// each pass of the build: the first counts the malformed lines and shows progress.
struct LogSurvey<'a> {
    a: &'a BuildArgs,
    malformed: &'a mut Malformed,
    walks: usize,
}

impl mapio::Survey for LogSurvey<'_> {
    type Error = anyhow::Error;

    fn walk(&mut self, each: &mut dyn FnMut(&LaserScan, &Pose)) -> Result<()> {
        let first = self.walks == 0;
        self.walks += 1;
        let progress = first.then(|| crate::progress::Progress::of_log("surveying ", self.a.source_path(), None));
        let mut scans = 0;
        for item in survey(self.a)? {
            match item? {
                Surveyed::Scan(item, truth) => {
                    each(&item.scan, &truth);
                    scans += 1;
                    if let Some(p) = progress.as_ref() {
                        p.set(scans as u64, 0, 0);
                    }
                }
                Surveyed::Malformed(e) if first => self.malformed.add(e),
                Surveyed::Malformed(_) => {}
            }
        }
        if let Some(p) = progress {
            p.finish();
        }
        Ok(())
    }
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
