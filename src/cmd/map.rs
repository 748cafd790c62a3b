//! `gema2 map ...`: bundled and procedural maps.

use anyhow::{bail, Context, Result};
use clap::Subcommand;
use mapserver::{procedural, MapCornerConfig};
use std::path::PathBuf;

#[derive(Subcommand)]
pub enum MapCommand {
    /// Write a generated map as JSON: office, apartment, warehouse, radial, or office-N
    /// (an office of about N walls). Without --seed, the bundled map of that name.
    Generate {
        kind: String,
        /// Draw another layout of the same kind (for the apartment, whose bundled plan is
        /// fixed, a flat of another layout)
        #[arg(long)]
        seed: Option<u64>,
        #[arg(long)]
        out: PathBuf,
    },
    /// Print a map's size and corner counts.
    Info {
        /// A bundled map's name or a map file.
        map: String,
    },
    /// Build a wall map from a log whose poses are true (a SLAM-corrected log).
    Build(super::build_map::BuildArgs),
    /// Draw a centre-line map's walls with thickness, as a floor plan does: two faces per wall
    /// and a jamb at each door (the outline of the walls' union).
    Thicken {
        /// A bundled map's name or a map file.
        map: String,
        /// Wall thickness, metres.
        #[arg(long, default_value_t = 0.12)]
        thickness: f64,
        #[arg(long)]
        out: PathBuf,
    },
}

pub fn run(c: MapCommand) -> Result<()> {
    match c {
        MapCommand::Generate { kind, seed, out } => {
            let map = if let Some(n) = kind.strip_prefix("office-") {
                procedural::office_with_walls(seed.unwrap_or(1), n.parse().context("office-N needs a number")?)
            } else {
                let map = match seed {
                    None => procedural::by_name(&kind),
                    Some(seed) => procedural::by_name_seeded(&kind, seed),
                };
                match map {
                    Some(m) => m,
                    None => bail!("unknown map kind {kind:?}: office, apartment, warehouse, radial or office-N"),
                }
            };
            std::fs::write(&out, map.to_json(&kind)).with_context(|| format!("writing {}", out.display()))?;
            eprintln!("{}: {} walls", out.display(), map.walls.len());
            Ok(())
        }
        MapCommand::Build(a) => super::build_map::run(a),
        MapCommand::Thicken { map, thickness, out } => {
            if !(thickness.is_finite() && thickness > 0.0) {
                bail!("--thickness {thickness}: a wall thickness is a positive number of metres");
            }
            let m = mapserver::load_map(&map)?;
            let thick = mapserver::thick::thicken(&m, thickness);
            let name = format!("{}-thick", out.file_stem().map_or("map".into(), |s| s.to_string_lossy()));
            std::fs::write(&out, thick.to_json(&name)).with_context(|| format!("writing {}", out.display()))?;
            eprintln!("{}: {} walls (from {})", out.display(), thick.walls.len(), m.walls.len());
            Ok(())
        }
        MapCommand::Info { map } => {
            // what the localizer prepares from the map: its corners and what it rules out
            let model = localize::model::MapModel::new(mapserver::load_map(&map)?, &MapCornerConfig::default());
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
    }
}
