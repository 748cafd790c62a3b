//! `gema2 map ...`: bundled and procedural maps.

use anyhow::{bail, Context, Result};
use clap::Subcommand;
use map::MapCornerConfig;
use std::path::{Path, PathBuf};

#[derive(Subcommand)]
pub enum MapCommand {
    /// Write a generated map as JSON: office, apartment, warehouse, radial, or office-N
    /// (an office of about N walls). Without --seed, the bundled map of that name.
    Generate {
        /// office, apartment, warehouse, radial, or office-N.
        kind: String,
        /// Draw another layout of the same kind (for the apartment, whose bundled plan is
        /// fixed, a flat of another layout)
        #[arg(long)]
        seed: Option<u64>,
        /// The JSON wall map to write.
        #[arg(long)]
        out: PathBuf,
    },
    /// Ask a running map server for its map's corners near an inner angle (and a place).
    Corners(super::corners::CornersArgs),
    /// Print a map's size and corner counts.
    Info {
        /// A bundled map's name or a map file.
        map: String,
    },
    /// Build a wall map from a log whose poses are true (a SLAM-corrected log).
    Build(Box<super::build_map::BuildArgs>),
    /// Make a ROS map_server map (YAML naming a PGM occupancy grid) into a wall map: the
    /// occupied cells' faces traced into walls, or, for a rough grid (a SLAM map of a real
    /// building), the walls built from a virtual laser's scans of its free space, as `map
    /// build` builds them from a log's. The free cells become the free space. Every command's
    /// --map also takes the .yaml directly, with these defaults.
    ImportRos {
        /// The map_server YAML file.
        yaml: PathBuf,
        /// Largest distance of the outline from its walls, in cells.
        #[arg(long, default_value_t = mapio::trace::TraceConfig::default().tolerance)]
        tolerance: f64,
        /// Occupied blobs of fewer cells are noise.
        #[arg(long, default_value_t = mapio::trace::TraceConfig::default().min_cells)]
        min_cells: f64,
        /// How far behind the edge of a face's cells the surface is, in cells (half a cell:
        /// a surface lies anywhere in the cell it marks occupied).
        #[arg(long, default_value_t = mapio::trace::TraceConfig::default().face_depth)]
        face_depth: f64,
        /// The map's accuracy, metres (default: half a cell).
        #[arg(long)]
        sigma: Option<f64>,
        /// Trace the cells' faces even when the grid is rough.
        #[arg(long, conflicts_with = "survey")]
        trace: bool,
        /// Build the walls from a virtual survey even when the grid is not rough.
        #[arg(long)]
        survey: bool,
        /// The JSON wall map to write (with the free space the grid shows).
        #[arg(long)]
        out: PathBuf,
    },
    /// Draw a wall map as a ROS map_server map (YAML and PGM), for AMCL and other grid-based
    /// localizers: walls occupied, the building's inside free, the rest unknown.
    ExportRos {
        /// A bundled map's name or a map file.
        #[arg(long, default_value = "office")]
        map: String,
        /// Metres a cell.
        #[arg(long, default_value_t = 0.05)]
        resolution: f64,
        /// Walls are drawn this thick, metres (at least the cells they cross).
        #[arg(long, default_value_t = 0.0)]
        thickness: f64,
        /// The YAML file; the PGM is written beside it.
        #[arg(long)]
        out: PathBuf,
    },
    /// Draw a centre-line map's walls with thickness, as a floor plan does: two faces per wall
    /// and a jamb at each door (the outline of the walls' union).
    Thicken {
        /// A bundled map's name or a map file.
        map: String,
        /// Wall thickness, metres.
        #[arg(long, default_value_t = 0.12)]
        thickness: f64,
        /// The JSON wall map to write.
        #[arg(long)]
        out: PathBuf,
    },
}

pub fn run(c: MapCommand) -> Result<()> {
    match c {
        MapCommand::Corners(a) => super::corners::run(a),
        MapCommand::Generate { kind, seed, out } => generate(&kind, seed, &out),
        MapCommand::Build(a) => super::build_map::run(*a),
        MapCommand::Thicken { map, thickness, out } => thicken(&map, thickness, &out),
        MapCommand::ImportRos { yaml, tolerance, min_cells, face_depth, sigma, trace, survey, out } => {
            let config = mapio::trace::TraceConfig { tolerance, min_cells, face_depth };
            let how = match (trace, survey) {
                (true, _) => mapio::MakeWalls::Traced,
                (_, true) => mapio::MakeWalls::Surveyed,
                _ => mapio::MakeWalls::AsRough,
            };
            import_ros(&yaml, config, how, sigma, &out)
        }
        MapCommand::ExportRos { map, resolution, thickness, out } => export_ros(&map, resolution, thickness, &out),
        MapCommand::Info { map } => info(&map),
    }
}

/// `map generate`: a bundled or procedural map, as JSON.
fn generate(kind: &str, seed: Option<u64>, out: &Path) -> Result<()> {
    let mut asked = None;
    let map = if let Some(n) = kind.strip_prefix("office-") {
        let n =
            super::positive_count(n).map_err(|e| anyhow::anyhow!("{kind:?}: office-N needs a wall count N: {e}"))?;
        asked = Some(n);
        worlds::office_with_walls(seed.unwrap_or(1), n)
    } else {
        let map = match seed {
            None => worlds::by_name(kind),
            Some(seed) => worlds::by_name_seeded(kind, seed),
        };
        match map {
            Some(m) => m,
            None => bail!("unknown map kind {kind:?}: office, apartment, warehouse, radial or office-N"),
        }
    };
    std::fs::write(out, map.to_json(kind)).with_context(|| format!("writing {}", out.display()))?;
    eprintln!("{}: {} walls", out.display(), map.walls.len());
    // "about N walls": a count far from N is the generator's limit, not a near miss
    if let Some(n) = asked.filter(|&n| map.walls.len().abs_diff(n) * 5 > n) {
        eprintln!("  ({n} asked: the nearest office the generator makes has {})", map.walls.len());
    }
    Ok(())
}

/// `map thicken`: the walls drawn with a thickness.
fn thicken(map: &str, thickness: f64, out: &Path) -> Result<()> {
    if !(thickness.is_finite() && thickness > 0.0) {
        bail!("--thickness {thickness}: a wall thickness is a positive number of metres");
    }
    let m = mapio::load_map(map)?;
    let thick = map::thick::thicken(&m, thickness);
    let name = format!("{}-thick", out.file_stem().map_or("map".into(), |s| s.to_string_lossy()));
    std::fs::write(out, thick.to_json(&name)).with_context(|| format!("writing {}", out.display()))?;
    eprintln!("{}: {} walls (from {})", out.display(), thick.walls.len(), m.walls.len());
    Ok(())
}

/// `map import-ros`: a map_server grid made into walls.
fn import_ros(
    yaml: &Path,
    trace: mapio::trace::TraceConfig,
    how: mapio::MakeWalls,
    sigma: Option<f64>,
    out: &Path,
) -> Result<()> {
    let mapio::trace::TraceConfig { tolerance, min_cells, face_depth } = trace;
    let cells = [min_cells, face_depth];
    if !(tolerance.is_finite() && tolerance > 0.0 && cells.iter().all(|v| v.is_finite() && *v >= 0.0)) {
        bail!(
            "--tolerance {tolerance} --min-cells {min_cells} --face-depth {face_depth}: a positive number of \
             cells, then two non-negative ones"
        );
    }
    if let Some(s) = sigma.filter(|s| !(s.is_finite() && *s >= 0.0)) {
        bail!("--sigma {s}: a map's accuracy is a non-negative number of metres");
    }
    let start = std::time::Instant::now();
    let grid = mapio::OccupancyGrid::load(yaml)?;
    let (map, made) =
        mapio::grid_walls_with(&grid, &trace, sigma, how).map_err(|e| anyhow::anyhow!("{}: {e}", yaml.display()))?;
    let (rough, surveyed) = match made {
        mapio::GridWalls::Surveyed { rough, scans } => (rough, Some(scans)),
        mapio::GridWalls::Traced { rough } => (rough, None),
    };
    if how.surveys(rough) && surveyed.is_none() {
        eprintln!("  no free cell stands clear of the walls to survey from, or no wall was seen: traced instead");
    }
    let name = yaml.file_stem().map_or("map".into(), |s| s.to_string_lossy());
    std::fs::write(out, map.to_json(&name)).with_context(|| format!("writing {}", out.display()))?;
    let made = match surveyed {
        Some(scans) => format!("built from {scans} scans of a virtual laser in"),
        None => "traced from".into(),
    };
    eprintln!(
        "{}: {} walls {made} a {} x {} grid of {} m, in {:.1} s",
        out.display(),
        map.walls.len(),
        grid.width,
        grid.height,
        grid.resolution,
        start.elapsed().as_secs_f64()
    );
    eprintln!(
        "  accuracy {} m; {:.0} % of the traced wall length in pieces under {} cells",
        map.sigma,
        100.0 * rough,
        mapio::ROUGH_WALL_CELLS
    );
    if sigma.is_none() && surveyed.is_none() && rough > mapio::ROUGH_SHARE && !map.is_approximate() {
        eprintln!(
            "  a rough grid, as a SLAM map of a real building is (a plan drawn into a grid: under 3 %), traced: \
             --sigma 0.1 declares the map approximate, as a map built from scans is (docs/maps.md)"
        );
    }
    Ok(())
}

/// Says on stderr how the walls of `spec`, a ROS grid read as `map`, were made when it is rough
/// ([`mapio::grid_walls`]): built from a virtual survey, or (when none could be) traced and
/// taken at the accuracy of a drawn plan, which `map import-ros --sigma` can change.
pub(crate) fn note_rough_grid(spec: &str, map: &map::WallMap, grid: Option<mapio::GridWalls>) {
    let Some(grid) = grid.filter(|g| g.rough() > mapio::ROUGH_SHARE) else { return };
    let rough = format!(
        "a rough grid ({:.0} % of its traced wall length in pieces under {} cells), as a SLAM map of a real \
         building is",
        100.0 * grid.rough(),
        mapio::ROUGH_WALL_CELLS
    );
    match grid {
        mapio::GridWalls::Surveyed { scans, .. } => eprintln!(
            "note: {spec} is {rough}: its walls were built from {scans} scans of a virtual laser in its free \
             space, as `map build` builds them from a log's; `gema2 map import-ros {spec} --out map.json` does \
             it once (docs/maps.md)"
        ),
        mapio::GridWalls::Traced { .. } if !map.is_approximate() => eprintln!(
            "note: {spec} is {rough}, traced and read as exact to half a cell; `gema2 map import-ros {spec} \
             --sigma 0.1 --out map.json` and `--map map.json` make it approximate, as a built map (docs/maps.md)"
        ),
        mapio::GridWalls::Traced { .. } => {}
    }
}

/// `map export-ros`: the walls drawn as a map_server grid.
fn export_ros(map: &str, resolution: f64, thickness: f64, out: &Path) -> Result<()> {
    let m = mapio::load_map(map)?;
    let grid = mapio::OccupancyGrid::from_walls(&m, resolution, thickness).map_err(anyhow::Error::msg)?;
    grid.save(out)?;
    eprintln!("{}: a {} x {} grid of {resolution} m", out.display(), grid.width, grid.height);
    Ok(())
}

/// `map info`: what the localizer prepares from the map, in brief.
fn info(map: &str) -> Result<()> {
    // its corners and what it rules out
    let model = localize::model::MapModel::new(mapio::load_map(map)?, &MapCornerConfig::default());
    let m = &model.map;
    let (lo, hi) = m.bounds();
    println!(
        "{}: {} walls, {} corners, {:.1} x {:.1} m",
        map,
        m.walls.len(),
        model.corners.corners().len(),
        hi.x - lo.x,
        hi.y - lo.y
    );
    if m.sigma > 0.0 {
        println!("  accuracy (sigma) {} m", m.sigma);
    }
    if let Some(seen) = &m.seen_free {
        let (cols, rows) = seen.size();
        println!(
            "  free space seen by its survey: {} of {cols} x {rows} cells of {} m",
            seen.seen_cells(),
            seen.cell()
        );
    }
    println!("  outline {}", if model.outside.is_some() { "closed: no answer outside it" } else { "open" });
    Ok(())
}
