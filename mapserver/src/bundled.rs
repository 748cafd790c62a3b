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

/// Loads `spec`: a bundled map's name, or a path to a JSON map.
pub fn load_map(spec: &str) -> Result<WallMap, MapError> {
    if !Path::new(spec).exists() {
        if let Some(m) = bundled(spec) {
            return m;
        }
    }
    WallMap::load(Path::new(spec))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::procedural;

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
