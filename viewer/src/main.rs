//! `viewer`: record a running gema2 pipeline to rerun, or inspect a recording.

use anyhow::Result;
use clap::{Parser, Subcommand};
use std::path::PathBuf;
use viewer::node::RecordArgs;
use viewer::Inspection;

#[derive(Parser)]
#[command(name = "viewer", version, about = "Record a gema2 pipeline to rerun (.rrd or live), or inspect a recording")]
struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
    #[command(flatten)]
    record: RecordArgs,
}

#[derive(Subcommand)]
enum Command {
    /// Record every message of a running pipeline (the default command).
    Record(RecordArgs),
    /// Print what a recording holds: scans, time span, success, latencies, failed scans.
    Inspect(InspectArgs),
}

#[derive(clap::Args)]
struct InspectArgs {
    /// The recording's files, in order (part 0, then the numbered parts).
    #[arg(required = true)]
    files: Vec<PathBuf>,
    /// Also print, per scan, the instances of every per-scan entity (tab-separated).
    #[arg(long)]
    per_scan: bool,
}

fn main() -> Result<()> {
    let cli = Cli::parse();
    match cli.command {
        Some(Command::Inspect(a)) => {
            let inspection = Inspection::read(&a.files)?;
            println!("{}", inspection.render());
            if a.per_scan {
                println!("{}", inspection.render_per_scan());
            }
            match inspection.damage.len() {
                0 => Ok(()),
                n => anyhow::bail!("{n} of {} parts damaged (see above)", a.files.len()),
            }
        }
        Some(Command::Record(r)) => viewer::node::run(r).map(|_| ()),
        None => viewer::node::run(cli.record).map(|_| ()),
    }
}
