//! The ROS 2 bridge process (see `ros2::node`).

use clap::Parser;

#[derive(Parser)]
#[command(name = "ros2", about = ros2::node::ABOUT)]
struct Cli {
    #[command(flatten)]
    args: ros2::node::Ros2Args,
}

fn main() -> anyhow::Result<()> {
    ros2::node::run(Cli::parse().args)
}
