//! `gema2`: the user-facing command line.

mod cmd;
mod diagnose;
mod report;

use clap::{Parser, Subcommand};

#[derive(Parser)]
#[command(name = "gema2", version, about = "Fast global single-scan self-localization from a 2D laser (GEMA2)")]
struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
}

#[derive(Subcommand)]
enum Command {
    /// Maps: list and export the bundled ones, generate procedural ones, inspect corners.
    #[command(subcommand)]
    Map(cmd::map::MapCommand),
    /// Simulate a laser in a map and write a ROBOTLASER1 log with the true poses.
    Sim(cmd::sim::SimArgs),
    /// Localize every scan of a log offline and report time and accuracy.
    Locate(cmd::locate::LocateArgs),
    /// The algorithm on the bundled office with simulated scans (what plain `gema2` runs).
    Demo(cmd::demo::DemoArgs),
    /// Time each stage per scan and print how locate scales with beams and map walls.
    Bench(cmd::bench::BenchArgs),
}

fn main() -> anyhow::Result<()> {
    let cli = Cli::parse();
    match cli.command {
        Some(Command::Map(c)) => cmd::map::run(c),
        Some(Command::Sim(a)) => cmd::sim::run(a),
        Some(Command::Locate(a)) => cmd::locate::run(a),
        Some(Command::Bench(a)) => cmd::bench::run_bench(a),
        Some(Command::Demo(a)) => cmd::demo::run(a),
        None => cmd::demo::run(cmd::demo::DemoArgs::default()),
    }
}
