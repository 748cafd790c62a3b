//! The acquisition process (see `acquire::node`).

use clap::Parser;

#[derive(Parser)]
#[command(name = "acquire", about = "GEMA2 acquisition stage: a simulated laser or a log, published as scans")]
struct Cli {
    #[command(flatten)]
    args: acquire::node::AcquireArgs,
}

fn main() -> anyhow::Result<()> {
    acquire::node::run(Cli::parse().args)
}
