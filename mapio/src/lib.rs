//! Maps in and out of GEMA2: what turns other people's maps and a robot's survey into a
//! [`map::WallMap`], and a wall map back into what other tools read.
//!
//! One job: map formats and map making. ROS map_server grids read and written ([`ros`], their
//! PGM or PNG images in [`image`]), a
//! grid's occupied faces traced into walls ([`trace`]), a wall map built from scans at known
//! poses ([`build()`], over the evidence per cell of [`occupancy`]), a rough grid surveyed by a
//! virtual laser and built so ([`resurvey`]), and [`load_map`], which takes whatever a user
//! names on a command line.
//!
//! Depends on `map` (the model it produces), `laser`, and `segment` (the scans' lines a map is
//! built from); nothing of the pipeline. Inside the crate: `image`, `trace` <- `ros` <- `resurvey` <-
//! `load`; `occupancy` <- `build` <- `resurvey`.

pub mod build;
pub mod image;
pub mod load;
pub mod occupancy;
pub mod resurvey;
pub mod ros;
pub mod trace;

pub use build::{build, BuildConfig, BuildError, Built, Survey};
pub use load::{load_map, load_map_with_grid, LoadError};
pub use occupancy::Occupancy;
pub use resurvey::{grid_walls, grid_walls_with, GridWalls, MakeWalls, VirtualSurvey};
pub use ros::{roughness, GridError, OccupancyGrid, RosMapError, SurveyGrid, ROUGH_SHARE, ROUGH_WALL_CELLS};
