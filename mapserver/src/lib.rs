//! The map server process of the GEMA2 pipeline, and the map's form on the wire.
//!
//! One job: serving the map. [`node`] loads a map (through `mapio`), publishes it on
//! `gema2/map` with history, answers corner queries and publishes a new version when the file
//! changes; [`wire`] writes a [`map::WallMap`] into the map message and reads it back, checked,
//! for every process that subscribes.
//!
//! Depends on `map` (the model), `mapio` (loading what a user names), `messages` (the wire
//! contract), and `ros` with `ros2-client` for a map taken from a ROS 2 map_server over DDS
//! ([`ros_map`]). Inside the crate: `wire`, `ros_map` <- `node`.

pub mod node;
pub mod ros_map;
pub mod wire;
