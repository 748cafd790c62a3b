//! GEMA2 maps: the JSON wall map, its corners sorted by inner angle (section 5.1), and the
//! spatial structures the localizer needs: ray casting for eq. 7's expected ranges and a
//! truncated distance field that also names each point's nearest wall.

mod bitgrid;
pub mod bundled;
pub mod corners;
pub mod field;
pub mod free_space;
pub mod grid;
pub mod map;
pub mod node;
pub mod occupancy;
pub mod open_floor;
pub mod procedural;
pub mod raycast;
pub mod ros;
pub mod runs;
pub mod seen;
pub mod sight;
pub mod thick;
pub mod trace;
pub mod view;
pub mod wire;

pub use bundled::{bundled, load_map, BUNDLED};
pub use corners::{CornerIndex, MapArm, MapCorner, MapCornerConfig};
pub use field::DistanceField;
pub use free_space::{FreeSpace, Outside};
pub use map::{MapError, Wall, WallMap};
pub use occupancy::Occupancy;
pub use open_floor::OpenFloor;
pub use raycast::{RayCaster, RayScratch};
pub use ros::{OccupancyGrid, SurveyGrid};
pub use seen::SeenFree;
pub use sight::SightLines;
