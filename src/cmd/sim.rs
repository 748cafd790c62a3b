//! `gema2 sim`: writes a simulated ROBOTLASER1 log whose laser pose is the truth.

use acquire::{write_robotlaser1, Scenario, SensorModel, Simulator};
use anyhow::{Context, Result};
use clap::Args;
use laser::ScanGeometry;
use std::io::{BufWriter, Write};
use std::path::PathBuf;

#[derive(Args)]
pub struct SimArgs {
    /// The map: a bundled one's name (office, apartment, warehouse, radial), a JSON wall map, or a
    /// ROS map_server map's .yaml (the PGM beside it is read and made into walls: docs/maps.md).
    #[arg(long, default_value = "office")]
    pub map: String,
    /// clean, people or furniture.
    #[arg(long, default_value = "clean")]
    pub scenario: Scenario,
    /// Scans to simulate along the random path.
    #[arg(long, default_value_t = 300, value_parser = super::positive_count)]
    pub scans: usize,
    /// Seed of the path, the noise and the people (the same seed, the same log).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Beams over the field of view (682 over 240 degrees is the URG-04LX).
    #[arg(long, default_value_t = 682)]
    pub beams: usize,
    /// Field of view, degrees, centred ahead; without it, the URG-04LX's 240 degrees (steps
    /// 44..725 of a 1024-step turn). 180 with 181 or 361 beams is a SICK LMS.
    #[arg(long)]
    pub fov: Option<f64>,
    /// Largest range, metres (readings beyond it are "no return").
    #[arg(long, default_value_t = 5.6)]
    pub range_max: f64,
    /// Range noise: constant and proportional standard deviation.
    #[arg(long, default_value_t = 0.01)]
    pub noise: f64,
    /// Range noise per metre of range (0.005 = 0.5 %).
    #[arg(long, default_value_t = 0.005)]
    pub noise_proportional: f64,
    /// Probability that a reading is lost.
    #[arg(long, default_value_t = 0.005)]
    pub dropout: f64,
    /// Lost readings read as the maximum range (a SICK LMS) instead of 0 (a URG's error code).
    #[arg(long)]
    pub dropout_as_max_range: bool,
    /// The log to write: ROBOTLASER1 lines carrying the true poses.
    #[arg(long)]
    pub out: PathBuf,
    /// Walk a robot through the free space, about --step metres a scan, instead of drawing each
    /// scan's pose anew; its odometry goes in each line's robot pose (exact unless
    /// --odom-noise).
    #[arg(long)]
    pub trajectory: bool,
    /// With --trajectory: metres between two scans.
    #[arg(long, default_value_t = 0.2, requires = "trajectory")]
    pub step: f64,
    /// With --trajectory: wheel odometry drawn from the walk by the odometry motion model with
    /// these alphas (AMCL's alpha1..alpha4), so that it drifts.
    #[arg(long, value_name = "A1,A2,A3,A4", value_delimiter = ',', requires = "trajectory")]
    pub odom_noise: Option<Vec<f64>>,
}

impl SimArgs {
    /// The simulated sensor: the URG-04LX, or the layout and reach these arguments give.
    pub fn sensor(&self) -> Result<SensorModel> {
        anyhow::ensure!(self.beams >= 2, "--beams must be at least 2, not {}", self.beams);
        anyhow::ensure!(
            self.range_max.is_finite() && self.range_max > 0.1,
            "--range-max must be a finite range above 0.1 m, not {}",
            self.range_max
        );
        anyhow::ensure!(
            self.noise.is_finite()
                && self.noise >= 0.0
                && self.noise_proportional.is_finite()
                && self.noise_proportional >= 0.0,
            "--noise and --noise-proportional must be finite and not negative"
        );
        anyhow::ensure!((0.0..=1.0).contains(&self.dropout), "--dropout must be a probability, not {}", self.dropout);
        let mut s = match self.fov {
            None if self.beams == 682 => SensorModel::urg04lx(),
            None => SensorModel::urg04lx_with_beams(self.beams),
            Some(fov) => {
                anyhow::ensure!(fov > 0.0 && fov <= 360.0, "--fov must be in (0, 360] degrees, not {fov}");
                SensorModel {
                    geometry: ScanGeometry::centred(self.beams, fov.to_radians(), self.range_max),
                    beams: self.beams,
                    ..SensorModel::urg04lx()
                }
            }
        };
        s.geometry.range_max = self.range_max;
        s.noise_constant = self.noise;
        s.noise_proportional = self.noise_proportional;
        s.dropout = self.dropout;
        s.dropout_reads_max = self.dropout_as_max_range;
        Ok(s)
    }
}

pub fn run(a: SimArgs) -> Result<()> {
    let map = mapio::load_map(&a.map)?;
    let mut sim = Simulator::new(&map, a.sensor()?, a.scenario, a.seed);
    let file = std::fs::File::create(&a.out).with_context(|| format!("creating {}", a.out.display()))?;
    let mut w = BufWriter::new(file);
    writeln!(
        w,
        "# gema2 sim --map {} --scenario {} --scans {} --seed {} --beams {}{} --range-max {} --noise {} --noise-proportional {} --dropout {}{}",
        a.map,
        a.scenario,
        a.scans,
        a.seed,
        a.beams,
        a.fov.map(|f| format!(" --fov {f}")).unwrap_or_default(),
        a.range_max,
        a.noise,
        a.noise_proportional,
        a.dropout,
        if a.dropout_as_max_range { " --dropout-as-max-range" } else { "" }
    )?;
    if !a.trajectory {
        for _ in 0..a.scans {
            write_robotlaser1(&mut w, &sim.next_scan())?;
        }
    } else {
        anyhow::ensure!(a.step.is_finite() && a.step > 0.0, "--step must be a distance above 0, not {}", a.step);
        let noise = a.odom_noise.as_deref().map(crate::sequential::odometry_noise).transpose()?;
        let noise = noise.unwrap_or(laser::motion::OdometryNoise::NONE);
        writeln!(w, "# gema2 sim: --trajectory --step {} --odom-noise {:?}", a.step, noise.alphas)?;
        let mut walk = acquire::Walk::new(sim, a.step, Some(noise), a.seed);
        for _ in 0..a.scans {
            let (scan, odometry) = walk.next_scan();
            acquire::write_robotlaser1_with_odometry(&mut w, &scan, odometry.as_ref())?;
        }
    }
    w.flush().with_context(|| format!("writing {}", a.out.display()))?;
    eprintln!("{}: {} scans of {} in {}", a.out.display(), a.scans, a.scenario, a.map);
    Ok(())
}
