//! `gema2 emulate-urg`: an emulated Hokuyo sensor speaking SCIP 2.0 (a URG-04LX on a
//! pseudo-terminal, or a UST-10LX, UTM-30LX or URG-04LX on TCP), fed by the simulator, so the
//! whole pipeline runs without hardware: `gema2 emulate-urg &` then
//! `gema2 stage acquire --serial <printed path>`, or `gema2 emulate-urg --tcp 127.0.0.1:0
//! --model ust-10lx &` then `gema2 stage acquire --tcp <printed address>`.

use acquire::scip::emulator::{EmulatorFaults, ServeEnd, UrgEmulator};
use acquire::scip::ScipModel;
use acquire::{Scenario, SensorModel, Simulator};
use anyhow::{Context, Result};
use clap::Args;
use serialport::{SerialPort, TTYPort};
use std::net::TcpListener;
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
    /// The sensor: urg-04lx, ust-10lx or utm-30lx (its field of view, steps, ranges and rate).
    #[arg(long, default_value = "urg-04lx", value_parser = model_arg)]
    pub model: ScipModel,
    /// Serve SCIP 2.0 on TCP at this HOST:PORT instead of a pseudo-terminal (port 0: any free
    /// port); prints the address it listens on. One client at a time, as the sensors do.
    #[arg(long)]
    pub tcp: Option<String>,
    /// Milliseconds between scans (default: one turn of the model's motor: 100 for the
    /// URG-04LX, 25 for the others).
    #[arg(long)]
    pub period_ms: Option<u64>,
    /// Also make this path a symlink to the pseudo-terminal.
    #[arg(long, conflicts_with = "tcp")]
    pub link: Option<PathBuf>,
    /// Start speaking SCIP 1.1, as older URG-04LX firmware does after power-up.
    #[arg(long)]
    pub scip11: bool,
    /// Start in time-adjust mode, as a sensor whose last client died while reading its clock.
    #[arg(long)]
    pub time_adjust: bool,
    /// Emulate an RS-232 link at this bit rate (the sensor powers up at 19200): commands sent
    /// at another rate go unanswered until the client finds it. Without it, a USB link.
    #[arg(long, conflicts_with = "tcp")]
    pub rs232: Option<u32>,
}

fn model_arg(name: &str) -> Result<ScipModel, String> {
    ScipModel::named(name).ok_or_else(|| {
        let known: Vec<&str> = ScipModel::ALL.iter().map(|(n, _)| *n).collect();
        format!("{name}: not a model this emulates ({})", known.join(", "))
    })
}

pub fn run(a: EmulateArgs) -> Result<()> {
    if let Some(r) = a.rs232.filter(|r| !acquire::scip::BIT_RATES.contains(r)) {
        anyhow::bail!("--rs232 {r}: a URG-04LX runs at one of {:?} bit/s", acquire::scip::BIT_RATES);
    }
    let model = a.model;
    let map = mapio::load_map(&a.map)?;
    let sensor = SensorModel { geometry: model.geometry(), beams: model.readings(), ..SensorModel::urg04lx() };
    let mut sim = Simulator::new(&map, sensor, a.scenario, a.seed);
    let source = Box::new(move || {
        let scan = sim.next_scan();
        let (min, max) = (model.dmin as f32 / 1000.0, model.dmax as f32 / 1000.0);
        // the sensor reports no return and lost readings as error codes (below 20 mm)
        scan.ranges
            .iter()
            .map(|&r| if r.is_finite() && r >= min && r < max { (r * 1000.0).round() as u32 } else { 0 })
            .collect()
    });
    let faults = EmulatorFaults {
        starts_in_scip11: a.scip11,
        starts_in_time_adjust: a.time_adjust,
        rs232_bit_rate: a.rs232,
        ..Default::default()
    };
    let period = Duration::from_millis(a.period_ms.unwrap_or(model.period_ms()));
    let mut emu = UrgEmulator::new(model, source, period, faults);
    acquire::node::install_stop_handlers();
    match &a.tcp {
        Some(address) => serve_tcp(&mut emu, address),
        None => serve_pty(&mut emu, a.link.as_ref()),
    }
}

/// Serves on a new pseudo-terminal until SIGINT or SIGTERM.
fn serve_pty(emu: &mut UrgEmulator, link: Option<&PathBuf>) -> Result<()> {
    let (mut master, slave) = TTYPort::pair().context("creating a pseudo-terminal")?;
    master.set_timeout(Duration::from_millis(5))?;
    let path = slave.name().context("the pseudo-terminal has no name")?;
    if let Some(link) = link {
        let _ = std::fs::remove_file(link);
        std::os::unix::fs::symlink(&path, link).with_context(|| format!("linking {}", link.display()))?;
    }
    println!("{path}");
    eprintln!("emulated {} on {path}; Ctrl-C to stop", emu.model.product);
    loop {
        match emu.serve(&mut master, acquire::node::stop_flag())? {
            ServeEnd::Stopped => break,
            // no client on the other side (yet, or any more): wait for one
            _ => std::thread::sleep(Duration::from_millis(50)),
        }
    }
    if let Some(link) = link {
        let _ = std::fs::remove_file(link);
    }
    drop(slave);
    Ok(())
}

/// Serves one TCP client after another until SIGINT or SIGTERM.
fn serve_tcp(emu: &mut UrgEmulator, address: &str) -> Result<()> {
    let listener = TcpListener::bind(address).with_context(|| format!("listening on {address}"))?;
    let local = listener.local_addr()?;
    println!("{local}");
    eprintln!("emulated {} on tcp {local}; Ctrl-C to stop", emu.model.product);
    emu.serve_clients(&listener, acquire::node::stop_flag()).context("serving TCP clients")
}
