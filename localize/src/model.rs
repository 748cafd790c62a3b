//! Everything the localizer pre-computes from a wall map, once.

use mapserver::{CornerIndex, DistanceField, MapCornerConfig, RayCaster, WallMap};
use nalgebra::Vector2;

/// Distance field resolution, metres.
const FIELD_RESOLUTION: f64 = 0.05;
/// Distances beyond this count as "far from any wall" when screening, metres.
pub const FIELD_CAP: f64 = 0.5;

/// A map prepared for localization: its corners sorted by inner angle, a ray caster for eq. 7,
/// a distance field for screening that also names each point's nearest wall for refinement.
pub struct MapModel {
    pub map: WallMap,
    pub corners: CornerIndex,
    pub caster: RayCaster,
    pub field: DistanceField,
    /// Unit normal of each wall.
    pub normals: Vec<Vector2<f64>>,
}

impl MapModel {
    pub fn new(map: WallMap, corners: &MapCornerConfig) -> Self {
        MapModel {
            corners: CornerIndex::of_map(&map, corners),
            caster: RayCaster::new(&map.walls),
            field: DistanceField::new(&map.walls, FIELD_RESOLUTION, FIELD_CAP),
            normals: map
                .walls
                .iter()
                .map(|w| {
                    let e = (w.b - w.a).normalize();
                    Vector2::new(-e.y, e.x)
                })
                .collect(),
            map,
        }
    }
}
