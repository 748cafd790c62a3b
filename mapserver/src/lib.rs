//! The map server process of the GEMA2 pipeline, and the map's form on the wire.
//!
//! One job: serving the map. [`node`] loads a map (through `mapio`), publishes it on
//! `gema2/map` with history, answers corner queries and publishes a new version when the file
//! changes; [`wire`] writes a [`map::WallMap`] into the map message and reads it back, checked,
//! for every process that subscribes.
//!
//! Depends on `map` (the model), `mapio` (loading what a user names) and `messages` (the wire
//! contract). Inside the crate: `wire` <- `node`.

pub mod node;
pub mod wire;
