//! One module per subcommand.

pub mod locate;
pub mod map;
pub mod sim;
