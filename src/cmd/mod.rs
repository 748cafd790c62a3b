//! One module per subcommand.

pub mod bench;
pub mod build_map;
pub mod demo;
pub mod emulate;
pub mod evaluate;
pub mod inspect;
pub mod lines;
pub mod locate;
pub mod map;
pub mod sim;
