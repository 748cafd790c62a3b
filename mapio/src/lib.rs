//! Maps in and out of GEMA2: what turns other people's maps and a robot's survey into a
//! [`map::WallMap`], and a wall map back into what other tools read.
//!
//! One job: map formats and map making. ROS map_server grids read and written ([`ros`]), a
//! grid's occupied faces traced into walls ([`trace`]), the evidence a survey's beams leave per
//! cell for building a map from scans ([`occupancy`]), and [`load_map`], which takes whatever a
//! user names on a command line.
//!
//! Depends on `map` (the model it produces) and `laser`; nothing of the pipeline. Inside the
//! crate: `trace` <- `ros` <- `load`; `occupancy` stands alone.

pub mod load;
pub mod occupancy;
pub mod ros;
pub mod trace;

pub use load::{load_map, load_map_with_roughness, LoadError};
pub use occupancy::Occupancy;
pub use ros::{roughness, GridError, OccupancyGrid, RosMapError, SurveyGrid, ROUGH_SHARE, ROUGH_WALL_CELLS};
