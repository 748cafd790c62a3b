//! The acquisition process (see `acquire::node`).

use clap::Parser;

#[derive(Parser)]
#[command(name = "acquire", about = acquire::node::ABOUT)]
struct Cli {
    #[command(flatten)]
    args: acquire::node::AcquireArgs,
}

fn main() -> anyhow::Result<()> {
    acquire::node::run(Cli::parse().args)
}
