//! The segmentation process (see `segment::node`).

use clap::Parser;

#[derive(Parser)]
#[command(name = "segment", about = "GEMA2 segmentation stage: scans in, lines and corners out")]
struct Cli {
    #[command(flatten)]
    args: segment::node::SegmentArgs,
}

fn main() -> anyhow::Result<()> {
    segment::node::run(Cli::parse().args)
}
