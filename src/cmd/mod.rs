//! One module per subcommand.

pub mod bench;
pub mod demo;
pub mod locate;
pub mod map;
pub mod sim;
