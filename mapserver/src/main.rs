//! The map server process (see `mapserver::node`).

use clap::Parser;

#[derive(Parser)]
#[command(name = "mapserver", about = mapserver::node::ABOUT)]
struct Cli {
    #[command(flatten)]
    args: mapserver::node::MapServerArgs,
}

fn main() -> anyhow::Result<()> {
    mapserver::node::run(Cli::parse().args)
}
