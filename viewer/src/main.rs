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

/// Prints `text` and a newline on stdout. A reader that stops early (`viewer inspect R.rrd |
/// head -8`) ends the printing quietly, as it ends `ls`, instead of the panic `println!` gives
/// on a broken pipe.
fn print_until_the_reader_leaves(text: &str) -> Result<()> {
    use std::io::Write;
    let mut out = std::io::stdout().lock();
    match out.write_all(text.as_bytes()).and_then(|_| out.write_all(b"\n")).and_then(|_| out.flush()) {
        Err(e) if e.kind() != std::io::ErrorKind::BrokenPipe => Err(e.into()),
        _ => Ok(()),
    }
}

fn main() -> Result<()> {
    let cli = Cli::parse();
    match cli.command {
        Some(Command::Inspect(a)) => {
            let inspection = Inspection::read(&a.files)?;
            let mut text = inspection.render();
            if a.per_scan {
                text.push('\n');
                text.push_str(&inspection.render_per_scan());
            }
            print_until_the_reader_leaves(&text)?;
            match inspection.damage.len() {
                0 => Ok(()),
                n => anyhow::bail!("{n} of {} parts damaged (see above)", a.files.len()),
            }
        }
        Some(Command::Record(r)) => viewer::node::run(r).map(|_| ()),
        None => viewer::node::run(cli.record).map(|_| ()),
    }
}
