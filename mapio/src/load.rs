//! A map as a user names it on a command line: a bundled map's name, a JSON wall map, or a ROS
//! map_server map (a `.yaml` naming a PGM image), made into walls ([`grid_walls`]).

use crate::resurvey::{grid_walls, GridWalls};
use crate::ros::{is_ros_map, OccupancyGrid, RosMapError};
use map::{bundled, MapError, WallMap, BUNDLED};
use std::path::{Path, PathBuf};
use thiserror::Error;

/// Why a map named on a command line could not be loaded.
#[derive(Debug, Error)]
pub enum LoadError {
    #[error(transparent)]
    Map(#[from] MapError),
    #[error(transparent)]
    Ros(#[from] RosMapError),
    #[error("{path}: {problem}")]
    Trace { path: PathBuf, problem: crate::ros::GridError },
    #[error("{spec:?} is neither a bundled map ({bundled}) nor a map file")]
    Unknown { spec: String, bundled: String },
}

/// Loads `spec`: a bundled map's name, a path to a JSON map, or a ROS map_server map (a
/// `.yaml` file naming a PGM image), made into walls by [`grid_walls`].
pub fn load_map(spec: &str) -> Result<WallMap, LoadError> {
    load_map_with_grid(spec).map(|(map, _)| map)
}

/// [`load_map`], and for a ROS map_server map how its walls were made; `None` for any other
/// map.
pub fn load_map_with_grid(spec: &str) -> Result<(WallMap, Option<GridWalls>), LoadError> {
    if !Path::new(spec).exists() {
        if let Some(m) = bundled(spec) {
            return Ok((m?, None));
        }
    }
    let path = Path::new(spec);
    // a bare name that is no file: most likely a mistyped bundled map
    let looks_like_a_name = path.components().count() == 1 && path.extension().is_none();
    if looks_like_a_name && !path.exists() {
        let names: Vec<&str> = BUNDLED.iter().map(|(n, _)| *n).collect();
        return Err(LoadError::Unknown { spec: spec.into(), bundled: names.join(", ") });
    }
    if is_ros_map(path) {
        let grid = OccupancyGrid::load(path)?;
        let (map, how) = grid_walls(&grid).map_err(|problem| LoadError::Trace { path: path.to_owned(), problem })?;
        return Ok((map, Some(how)));
    }
    Ok((WallMap::load(path)?, None))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_unknown_map_name_lists_the_bundled_ones() {
        let e = load_map("ofice").unwrap_err().to_string();
        assert!(e.contains("\"ofice\"") && e.contains("office, apartment"), "{e}");
        // a path still reports the file system's error, naming the file
        let e = load_map("no/such/map.json").unwrap_err().to_string();
        assert!(e.contains("no/such/map.json: cannot read the map"), "{e}");
    }
}
