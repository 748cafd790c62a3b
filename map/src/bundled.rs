//! Maps shipped inside the binary (their JSON lives in the repository's `maps/` folder and is
//! produced by the `worlds` crate's generators): runs need no files and no downloads.

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

#[cfg(test)]
mod tests {
    use super::*;

    /// Every bundled map is a building closed off from the space around it, where the
    /// localizer then answers with no pose ([`crate::Outside`]).
    #[test]
    fn bundled_maps_close_their_outline() {
        for (name, _) in BUNDLED {
            let map = bundled(name).unwrap().unwrap();
            let field = crate::field::DistanceField::new(&map.walls, 0.05, 0.5);
            let (lo, hi) = map.bounds();
            let outside = crate::free_space::FreeSpace::new(&field, (lo, hi)).outside();
            let outside = outside.unwrap_or_else(|| panic!("{name} has an open outline"));
            assert!(outside.contains(lo - nalgebra::Vector2::new(0.5, 0.5)), "{name}");
            assert!(outside.contains(hi + nalgebra::Vector2::new(0.5, 0.5)), "{name}");
        }
    }
}
