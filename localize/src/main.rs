//! The localization process (see `localize::node`).

use clap::Parser;

#[derive(Parser)]
#[command(name = "localize", about = localize::node::ABOUT)]
struct Cli {
    #[command(flatten)]
    args: localize::node::LocalizeArgs,
}

fn main() -> anyhow::Result<()> {
    localize::node::run(Cli::parse().args)
}
