//! The localization process (see `localize::node`).

use clap::Parser;

#[derive(Parser)]
#[command(name = "localize", about = "GEMA2 localization stage: corners and map in, ranked poses out")]
struct Cli {
    #[command(flatten)]
    args: localize::node::LocalizeArgs,
}

fn main() -> anyhow::Result<()> {
    localize::node::run(Cli::parse().args)
}
