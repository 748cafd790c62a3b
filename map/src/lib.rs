//! The map model of GEMA2: the wall map and everything derived from it that localization reads.
//!
//! One job: what a map *is* for the localizer. The JSON wall map ([`map`], [`wall`]), its
//! straight runs ([`runs`]), its corners sorted by inner angle (section 5.1, [`corners`]) and
//! which of them a sensor can see ([`view`], [`sight`]), ray casting for eq. 7's expected ranges
//! ([`raycast`] over the [`grid`] of walls), the truncated distance field that also names each
//! point's nearest wall ([`field`]), and where a robot can stand ([`free_space`], [`seen`],
//! [`open_floor`]). [`model`] gathers all of it, built once: what the localizer reads and the map
//! server serves. The four bundled plans ship inside it ([`bundled`](mod@bundled)).
//!
//! Depends on `laser` (poses and scan geometry) and nothing of the pipeline: no IPC, no file
//! format but its own JSON. Map import and building live in `mapio`, generated plans in
//! `worlds`, the map server process in `mapserver`.
//!
//! Inside the crate imports run one way: `hash`, `slab` <- `flat` <- `wall`, `bitgrid` <- `grid`
//! <- `field`, `raycast`, `sight`, `free_space` <- `seen`, `runs` <- `map` <- `corners`, `view`,
//! `open_floor`, `thick`, `bundled` <- `model`.

pub mod bitgrid;
pub mod bundled;
pub mod corners;
pub mod field;
pub mod flat;
pub mod free_space;
pub mod grid;
pub mod hash;
pub mod limits;
pub mod map;
pub mod model;
pub mod open_floor;
pub mod raycast;
pub mod runs;
pub mod seen;
pub mod sight;
pub mod simplify;
pub mod slab;
pub mod thick;
pub mod view;
pub mod wall;

pub use bundled::{bundled, BUNDLED};
pub use corners::{CornerIndex, MapArm, MapCorner, MapCornerConfig};
pub use field::{DistanceField, FieldCell};
pub use free_space::{FreeSpace, Outside};
pub use map::{MapError, WallMap, APPROXIMATE_MAP, MAX_EXTENT, MIN_WALL_LENGTH};
pub use model::MapModel;
pub use open_floor::OpenFloor;
pub use raycast::{RayCaster, RayScratch};
pub use seen::SeenFree;
pub use sight::SightLines;
pub use wall::{bounds_of, Wall};
