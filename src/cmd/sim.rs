//! `gema2 sim`: writes a simulated ROBOTLASER1 log whose laser pose is the truth.

use acquire::{write_robotlaser1, Scenario, SensorModel, Simulator};
use anyhow::{Context, Result};
use clap::Args;
use std::io::{BufWriter, Write};
use std::path::PathBuf;

#[derive(Args)]
pub struct SimArgs {
    /// A bundled map's name or a JSON map file.
    #[arg(long, default_value = "office")]
    pub map: String,
    /// clean, people or furniture.
    #[arg(long, default_value = "clean")]
    pub scenario: Scenario,
    #[arg(long, default_value_t = 300)]
    pub scans: usize,
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Beams over the URG-04LX's 240 degrees (682 is the real sensor).
    #[arg(long, default_value_t = 682)]
    pub beams: usize,
    /// Range noise: constant and proportional standard deviation.
    #[arg(long, default_value_t = 0.01)]
    pub noise: f64,
    #[arg(long, default_value_t = 0.005)]
    pub noise_proportional: f64,
    #[arg(long)]
    pub out: PathBuf,
}

pub fn sensor_of(beams: usize, noise: f64, proportional: f64) -> SensorModel {
    let mut s = if beams == 682 { SensorModel::urg04lx() } else { SensorModel::urg04lx_with_beams(beams) };
    s.noise_constant = noise;
    s.noise_proportional = proportional;
    s
}

pub fn run(a: SimArgs) -> Result<()> {
    let map = mapserver::load_map(&a.map)?;
    let mut sim = Simulator::new(&map, sensor_of(a.beams, a.noise, a.noise_proportional), a.scenario, a.seed);
    let file = std::fs::File::create(&a.out).with_context(|| format!("creating {}", a.out.display()))?;
    let mut w = BufWriter::new(file);
    writeln!(
        w,
        "# gema2 sim --map {} --scenario {} --scans {} --seed {} --beams {}",
        a.map, a.scenario, a.scans, a.seed, a.beams
    )?;
    for _ in 0..a.scans {
        write_robotlaser1(&mut w, &sim.next_scan())?;
    }
    w.flush().with_context(|| format!("writing {}", a.out.display()))?;
    eprintln!("{}: {} scans of {} in {}", a.out.display(), a.scans, a.scenario, a.map);
    Ok(())
}
