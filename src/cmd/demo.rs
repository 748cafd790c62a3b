//! `gema2 demo` (also what plain `gema2` runs): the whole algorithm on the bundled office,
//! with simulated scans of each scenario, no files and no hardware.

use crate::report::{Outcome, Summary};
use acquire::{Scenario, SensorModel, Simulator};
use anyhow::Result;
use clap::Args;
use localize::{Gema2, LocalizerConfig, MapModel};
use mapserver::MapCornerConfig;
use segment::SegmenterConfig;
use std::sync::Arc;
use std::time::Instant;

#[derive(Args)]
pub struct DemoArgs {
    /// A bundled map's name or a JSON map file.
    #[arg(long, default_value = "office")]
    pub map: String,
    /// Scans per scenario.
    #[arg(long, default_value_t = 300)]
    pub scans: usize,
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
}

impl Default for DemoArgs {
    fn default() -> Self {
        DemoArgs { map: "office".into(), scans: 300, seed: 1 }
    }
}

pub fn run(a: DemoArgs) -> Result<()> {
    let map = mapserver::load_map(&a.map)?;
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
            let scan = sim.next_scan();
            let start = Instant::now();
            let (seg, loc) = gema2.process(&scan.view());
            let micros = start.elapsed().as_secs_f64() * 1e6;
            let outcome = Outcome::of(loc.status, loc.best().map(|h| h.pose), scan.truth, micros);
            summary.add(outcome.with_steps(&seg.times, &loc.times));
        }
        println!("\n== {scenario}");
        print!("{}", summary.render());
    }
    Ok(())
}
