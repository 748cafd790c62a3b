//! Everything the localizer pre-computes from a wall map, once.

use crate::runs::RunChain;
use crate::{CornerIndex, DistanceField, FreeSpace, MapCornerConfig, OpenFloor, Outside, RayCaster, Wall, WallMap};
use nalgebra::{Point2, Vector2};
use std::f64::consts::PI;

/// Distance field resolution, metres.
const FIELD_RESOLUTION: f64 = 0.05;
/// Distances beyond this count as "far from any wall" when screening, metres.
pub const FIELD_CAP: f64 = 0.5;
/// How far [`MapModel::open_floor`] measures distances to the walls, metres: 1.5 times a
/// `clutter_reach` of up to 1.33 m (the localizer's `CostConfig::openness`).
const OPEN_FLOOR_REACH: f64 = 2.0;

/// How many of the map's main wall directions the grid search lays scan lines along.
const WALL_DIRECTIONS: usize = 4;

/// A map prepared for localization: its corners sorted by inner angle, a ray caster for eq. 7,
/// a distance field for screening that also names each point's nearest wall for refinement.
pub struct MapModel {
    pub map: WallMap,
    /// The walls as straight runs ([`crate::runs`]): what corners come from and scan
    /// lines slide along.
    pub runs: Vec<Wall>,
    /// The main directions of the runs, in [0, pi), the heaviest first: the headings the grid
    /// search tries lay the scan's lines along them ([`wall_directions`]).
    pub wall_directions: Vec<f64>,
    /// The chains of more than one run (curved or bent walls), along which the slide search
    /// also lays scan lines as chords (the localizer's slide search).
    pub bends: Vec<RunChain>,
    pub corners: CornerIndex,
    pub caster: RayCaster,
    pub field: DistanceField,
    /// Where a point stands among the walls, on the free space's 0.1 m grid: how far from the
    /// nearest wall, further than `field` reaches (a scan line standing in open floor is a
    /// wall misplaced), and whether outside the main free space (a scan point there was seen
    /// through a wall). What the screen asks of a point no wall explains; one byte a cell.
    pub open_floor: OpenFloor,
    /// Each wall as refinement reads it, in one place.
    pub frames: Vec<WallFrame>,
    /// Which sides of each wall face no space a sensor can stand in (the inside of a thick
    /// wall's faces), by wall as `frames`: left (along `normal`) then right. `None` when every
    /// side is open.
    pub closed_sides: Option<Vec<[bool; 2]>>,
    /// The space around the building; `None` when the map's outline is open.
    pub outside: Option<Outside>,
    /// Where the map's survey saw no free space (more than a cell from any it saw); `None`
    /// when the map does not say.
    pub unseen: Option<Outside>,
}

/// A wall's start, direction, squared length and unit normal: what point-to-wall distances
/// need, together so one cache line holds them.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WallFrame {
    pub a: Point2<f64>,
    /// b - a.
    pub e: Vector2<f64>,
    pub length_squared: f64,
    pub normal: Vector2<f64>,
}

impl WallFrame {
    pub fn of(w: &Wall) -> Self {
        let e = w.b - w.a;
        let u = e.normalize();
        WallFrame { a: w.a, e, length_squared: e.norm_squared(), normal: Vector2::new(-u.y, u.x) }
    }
}

impl MapModel {
    /// Whether the robot cannot be at `q`: outside a closed outline, or where the map's
    /// survey saw no free space. Such poses are never an answer.
    pub fn off_limits(&self, q: Point2<f64>) -> bool {
        self.outside.as_ref().is_some_and(|o| o.contains(q)) || self.unseen.as_ref().is_some_and(|o| o.contains(q))
    }

    pub fn new(map: WallMap, corners: &MapCornerConfig) -> Self {
        // the cost, screening and refinement read the drawn geometry, in as few walls as hold it
        let walls = map.joined_walls();
        let mut field = DistanceField::new(&walls, FIELD_RESOLUTION, FIELD_CAP);
        let closed_sides = crate::view::closed_sides(&walls);
        // the screen asks the field which points' nearest wall has a closed side before it
        // looks the wall up (few walls have one: a building's outer walls)
        if let Some(closed) = &closed_sides {
            field.mark_nearest(|k| closed.get(k as usize).is_some_and(|s| s[0] || s[1]));
        }
        let free_space = FreeSpace::new(&field, map.bounds());
        let chains = map.chains_of_runs();
        let runs: Vec<Wall> = chains.iter().flat_map(RunChain::runs).collect();
        MapModel {
            corners: CornerIndex::of_runs(&map, &runs, corners),
            wall_directions: wall_directions(&runs, WALL_DIRECTIONS),
            runs,
            bends: chains.into_iter().filter(|c| c.run_count() >= 2).collect(),
            caster: RayCaster::new(&walls),
            outside: free_space.outside(),
            open_floor: OpenFloor::new(&walls, &free_space, OPEN_FLOOR_REACH),
            unseen: map.seen_free.as_ref().map(|seen| seen.unseen(1)),
            field,
            frames: walls.iter().map(WallFrame::of).collect(),
            closed_sides,
            map,
        }
    }
}

/// The map's main wall directions, in [0, pi): peaks of the histogram of its walls' directions
/// (1 degree bins, weighted by length) that hold at least 3 % of the walls' length, at most
/// `max` of them, the heaviest first. Each is the length-weighted mean direction of the walls in
/// its bin and the two beside it.
pub fn wall_directions(walls: &[Wall], max: usize) -> Vec<f64> {
    const BINS: usize = 180;
    let bin_of = |w: &Wall| {
        let d = w.b - w.a;
        let a = d.y.atan2(d.x).rem_euclid(PI);
        ((a / PI * BINS as f64) as usize).min(BINS - 1)
    };
    let mut histogram = [0.0f64; BINS];
    for w in walls {
        histogram[bin_of(w)] += w.length();
    }
    let total: f64 = histogram.iter().sum();
    let mut peaks: Vec<(usize, f64)> = (0..BINS)
        .filter(|&k| {
            let (before, after) = (histogram[(k + BINS - 1) % BINS], histogram[(k + 1) % BINS]);
            histogram[k] > 0.0 && histogram[k] >= 0.03 * total && histogram[k] >= before && histogram[k] > after
        })
        .map(|k| (k, histogram[k]))
        .collect();
    peaks.sort_by(|a, b| b.1.total_cmp(&a.1));
    peaks.truncate(max);
    peaks
        .into_iter()
        .map(|(k, _)| {
            // mean of the doubled angles, so that directions either side of 0 = pi average right
            let (mut s, mut c) = (0.0, 0.0);
            for w in walls.iter().filter(|w| (bin_of(w) + BINS - k + 1) % BINS <= 2) {
                let d = w.b - w.a;
                let a2 = 2.0 * d.y.atan2(d.x);
                (s, c) = (s + w.length() * a2.sin(), c + w.length() * a2.cos());
            }
            (s.atan2(c) / 2.0).rem_euclid(PI)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use laser::angle_diff;

    /// A room's walls along 0 and 90 degrees, and a short diagonal one too light to count.
    #[test]
    fn the_main_wall_directions_are_the_heaviest_peaks() {
        let mut walls = Wall::rectangle(0.0, 0.0, 20.0, 10.0).to_vec();
        walls.push(Wall::new(5.0, 5.0, 5.3, 5.3));
        // a wall drawn a hair off the axis still counts with its neighbours, either side of 0
        walls.push(Wall::new(0.0, 2.0, 10.0, 2.0 - 0.01));
        let dirs = wall_directions(&walls, 4);
        assert_eq!(dirs.len(), 2, "{dirs:?}");
        assert!(angle_diff(2.0 * dirs[0], 0.0).abs() < 0.002, "{dirs:?}");
        assert!((dirs[1] - PI / 2.0).abs() < 1e-9, "{dirs:?}");
        assert_eq!(wall_directions(&walls, 1).len(), 1);
        assert!(wall_directions(&[], 4).is_empty());
    }
}
