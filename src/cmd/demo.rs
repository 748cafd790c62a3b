//! `gema2 demo` (also what plain `gema2` runs): the whole algorithm on the bundled office,
//! with simulated scans of each scenario, no files and no hardware.

use crate::report::{Outcome, Summary};
use acquire::{Scenario, SensorModel, Simulator};
use anyhow::Result;
use clap::Args;
use localize::{Gema2, LocalizerConfig, MapModel};
use map::MapCornerConfig;
use segment::SegmenterConfig;
use std::sync::Arc;

#[derive(Args)]
pub struct DemoArgs {
    /// The map: a bundled one's name (office, apartment, warehouse, radial), a JSON wall map, or a
    /// ROS map_server map's .yaml (the PGM beside it is read and made into walls: docs/maps.md).
    #[arg(long, default_value = "office")]
    pub map: String,
    /// Scans per scenario.
    #[arg(long, default_value_t = 300, value_parser = super::positive_count)]
    pub scans: usize,
    /// Seed of the paths, the noise and the people.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
}

impl Default for DemoArgs {
    fn default() -> Self {
        DemoArgs { map: "office".into(), scans: 300, seed: 1 }
    }
}

pub fn run(a: DemoArgs) -> Result<()> {
    let map = mapio::load_map(&a.map)?;
    let model = Arc::new(MapModel::new(map.clone(), &MapCornerConfig::default()));
    println!(
        "GEMA2 on the {} map ({} walls, {} corners): simulated URG-04LX, {} scans per scenario",
        a.map,
        map.walls.len(),
        model.corners.corners().len(),
        a.scans
    );
    for scenario in [Scenario::Clean, Scenario::People, Scenario::Furniture] {
        let mut sim = Simulator::new(&map, SensorModel::urg04lx(), scenario, a.seed);
        let mut gema2 = Gema2::new(Arc::clone(&model), SegmenterConfig::default(), LocalizerConfig::default());
        let mut summary = Summary::default();
        for _ in 0..a.scans {
            summary.add(Outcome::located(&mut gema2, &sim.next_scan()));
        }
        println!("\n== {scenario}");
        print!("{}", summary.render());
    }
    Ok(())
}
