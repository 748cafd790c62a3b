//! The map server process (see `mapserver::node`).

use clap::Parser;

#[derive(Parser)]
#[command(name = "mapserver", about = "GEMA2 map server: the map with history, corner queries, reload on change")]
struct Cli {
    #[command(flatten)]
    args: mapserver::node::MapServerArgs,
}

fn main() -> anyhow::Result<()> {
    mapserver::node::run(Cli::parse().args)
}
