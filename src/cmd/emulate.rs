//! `gema2 emulate-urg`: an emulated Hokuyo URG-04LX speaking SCIP 2.0 on a pseudo-terminal,
//! fed by the simulator, so the whole pipeline runs without hardware:
//! `gema2 emulate-urg &` then `gema2 stage acquire --serial <printed path>`.

use acquire::scip::emulator::{EmulatorFaults, ServeEnd, UrgEmulator};
use acquire::{Scenario, SensorModel, Simulator};
use anyhow::{Context, Result};
use clap::Args;
use serialport::{SerialPort, TTYPort};
use std::path::PathBuf;
use std::time::Duration;

#[derive(Args)]
pub struct EmulateArgs {
    /// The map the emulated sensor scans: a bundled map's name, a JSON wall map or a ROS .yaml.
    #[arg(long, default_value = "office")]
    pub map: String,
    /// clean, people or furniture.
    #[arg(long, default_value = "clean")]
    pub scenario: Scenario,
    /// Seed of the path, the noise and the people.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Milliseconds between scans (the URG-04LX turns at 600 rpm: 100).
    #[arg(long, default_value_t = 100)]
    pub period_ms: u64,
    /// Also make this path a symlink to the pseudo-terminal.
    #[arg(long)]
    pub link: Option<PathBuf>,
    /// Start speaking SCIP 1.1, as older URG-04LX firmware does after power-up.
    #[arg(long)]
    pub scip11: bool,
    /// Start in time-adjust mode, as a sensor whose last client died while reading its clock.
    #[arg(long)]
    pub time_adjust: bool,
    /// Emulate an RS-232 link at this bit rate (the sensor powers up at 19200): commands sent
    /// at another rate go unanswered until the client finds it. Without it, a USB link.
    #[arg(long)]
    pub rs232: Option<u32>,
}

pub fn run(a: EmulateArgs) -> Result<()> {
    if let Some(r) = a.rs232.filter(|r| !acquire::scip::BIT_RATES.contains(r)) {
        anyhow::bail!("--rs232 {r}: a URG-04LX runs at one of {:?} bit/s", acquire::scip::BIT_RATES);
    }
    let map = mapio::load_map(&a.map)?;
    let mut sim = Simulator::new(&map, SensorModel::urg04lx(), a.scenario, a.seed);
    let source = Box::new(move || {
        let scan = sim.next_scan();
        let max = scan.geometry.range_max as f32;
        // the sensor reports no return and lost readings as error codes (below 20 mm)
        scan.ranges
            .iter()
            .map(|&r| if r.is_finite() && r > 0.02 && r < max { (r * 1000.0).round() as u32 } else { 0 })
            .collect()
    });
    let faults = EmulatorFaults {
        starts_in_scip11: a.scip11,
        starts_in_time_adjust: a.time_adjust,
        rs232_bit_rate: a.rs232,
        ..Default::default()
    };
    let mut emu = UrgEmulator::urg04lx(source, Duration::from_millis(a.period_ms), faults);
    let (mut master, slave) = TTYPort::pair().context("creating a pseudo-terminal")?;
    master.set_timeout(Duration::from_millis(5))?;
    let path = slave.name().context("the pseudo-terminal has no name")?;
    if let Some(link) = &a.link {
        let _ = std::fs::remove_file(link);
        std::os::unix::fs::symlink(&path, link).with_context(|| format!("linking {}", link.display()))?;
    }
    acquire::node::install_stop_handlers();
    println!("{path}");
    eprintln!("emulated URG-04LX on {path}; Ctrl-C to stop");
    loop {
        match emu.serve(&mut master, acquire::node::stop_flag())? {
            ServeEnd::Stopped => break,
            // no client on the other side (yet, or any more): wait for one
            _ => std::thread::sleep(Duration::from_millis(50)),
        }
    }
    if let Some(link) = &a.link {
        let _ = std::fs::remove_file(link);
    }
    drop(slave);
    Ok(())
}
