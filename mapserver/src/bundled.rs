//! Maps shipped inside the binary (their JSON lives in the repository's `maps/` folder and is
//! produced by [`crate::procedural`]): runs need no files and no downloads.

use crate::map::{MapError, WallMap};
use std::path::Path;

/// Name and JSON text of every bundled map; the first is the default.
pub const BUNDLED: [(&str, &str); 4] = [
    ("office", include_str!("../../maps/office.json")),
    ("apartment", include_str!("../../maps/apartment.json")),
    ("warehouse", include_str!("../../maps/warehouse.json")),
    ("radial", include_str!("../../maps/radial.json")),
];

/// The bundled map called `name`.
pub fn bundled(name: &str) -> Option<Result<WallMap, MapError>> {
    BUNDLED.iter().find(|(n, _)| *n == name).map(|(n, text)| WallMap::parse(text, Path::new(&format!("<bundled {n}>"))))
}

/// Loads `spec`: a bundled map's name, a path to a JSON map, or a ROS map_server map (a
/// `.yaml` file naming a PGM image), traced into walls with the defaults of
/// [`crate::ros::OccupancyGrid::to_wall_map`].
pub fn load_map(spec: &str) -> Result<WallMap, MapError> {
    if !Path::new(spec).exists() {
        if let Some(m) = bundled(spec) {
            return m;
        }
    }
    let path = Path::new(spec);
    // a bare name that is no file: most likely a mistyped bundled map
    let looks_like_a_name = path.components().count() == 1 && path.extension().is_none();
    if looks_like_a_name && !path.exists() {
        let names: Vec<&str> = BUNDLED.iter().map(|(n, _)| *n).collect();
        return Err(MapError::Unknown { spec: spec.into(), bundled: names.join(", ") });
    }
    if crate::ros::is_ros_map(path) {
        let grid = crate::ros::OccupancyGrid::load(path)?;
        return grid
            .to_wall_map(&crate::trace::TraceConfig::default(), None)
            .map_err(|message| MapError::Shape { path: path.to_owned(), message });
    }
    WallMap::load(path)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::procedural;

    #[test]
    fn an_unknown_map_name_lists_the_bundled_ones() {
        let e = load_map("ofice").unwrap_err().to_string();
        assert!(e.contains("\"ofice\"") && e.contains("office, apartment"), "{e}");
        // a path still reports the file system's error, naming the file
        let e = load_map("no/such/map.json").unwrap_err().to_string();
        assert!(e.contains("no/such/map.json: cannot read the map"), "{e}");
    }

    /// Every bundled map is a building closed off from the space around it, where the
    /// localizer then answers with no pose ([`crate::Outside`]).
    #[test]
    fn bundled_maps_close_their_outline() {
        for (name, _) in BUNDLED {
            let map = bundled(name).unwrap().unwrap();
            let field = crate::DistanceField::new(&map.walls, 0.05, 0.5);
            let (lo, hi) = map.bounds();
            let outside = crate::FreeSpace::new(&field, (lo, hi)).outside();
            let outside = outside.unwrap_or_else(|| panic!("{name} has an open outline"));
            assert!(outside.contains(lo - nalgebra::Vector2::new(0.5, 0.5)), "{name}");
            assert!(outside.contains(hi + nalgebra::Vector2::new(0.5, 0.5)), "{name}");
        }
    }

    #[test]
    fn bundled_maps_are_what_the_generators_make() {
        for (name, _) in BUNDLED {
            let shipped = bundled(name).unwrap().unwrap();
            let made = procedural::by_name(name).unwrap();
            assert_eq!(shipped.walls.len(), made.walls.len(), "{name}");
            for (a, b) in shipped.walls.iter().zip(&made.walls) {
                assert!((a.a - b.a).norm() < 1e-3 && (a.b - b.b).norm() < 1e-3, "{name}: regenerate maps/{name}.json");
            }
        }
    }
}
