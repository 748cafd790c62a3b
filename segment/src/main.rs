//! The segmentation process (see `segment::node`).

use clap::Parser;

#[derive(Parser)]
#[command(name = "segment", about = segment::node::ABOUT)]
struct Cli {
    #[command(flatten)]
    args: segment::node::SegmentArgs,
}

fn main() -> anyhow::Result<()> {
    segment::node::run(Cli::parse().args)
}
