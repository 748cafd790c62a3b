//! `gema2`: the user-facing command line.

mod cmd;

use clap::{Parser, Subcommand};

#[derive(Parser)]
#[command(
    name = "gema2",
    version,
    about = "Fast global single-scan self-localization from a 2D laser (GEMA2)"
)]
struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
}

#[derive(Subcommand)]
enum Command {
    /// Maps: list and export the bundled ones, generate procedural ones, inspect corners.
    #[command(subcommand)]
    Map(cmd::map::MapCommand),
}

fn main() -> anyhow::Result<()> {
    let cli = Cli::parse();
    match cli.command {
        Some(Command::Map(c)) => cmd::map::run(c),
        None => {
            println!("try `gema2 --help`");
            Ok(())
        }
    }
}
