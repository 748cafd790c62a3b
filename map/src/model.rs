//! Everything the localizer pre-computes from a wall map, once: the map model.
//!
//! Built here by [`MapModel::new`] (offline `locate`, a user's program), or by the map server,
//! which publishes it as one block of bytes ([`MapModel::to_block`], layout [`MODEL_LAYOUT`])
//! that every localizer reads in place ([`MapModel::from_block`]): its large arrays are
//! [`Slab`]s viewing the block, so a second localizer adds no copy of them.

use crate::flat::{Flat, FlatError, FlatReader, FlatWriter};
use crate::runs::RunChain;
use crate::slab::{Plain, Slab};
use crate::SeenFree;
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
    pub runs: Slab<Wall>,
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
    pub frames: Slab<WallFrame>,
    /// Which sides of each wall face no space a sensor can stand in (the inside of a thick
    /// wall's faces), by wall as `frames`: left (along `normal`) then right. `None` when every
    /// side is open.
    pub closed_sides: Option<Vec<[bool; 2]>>,
    /// The space around the building; `None` when the map's outline is open.
    pub outside: Option<Outside>,
    /// Where the map's survey saw no free space (more than a cell from any it saw); `None`
    /// when the map does not say.
    pub unseen: Option<Outside>,
    /// The corner settings the model was built with: a localizer built for others must not
    /// read it.
    pub corner_config: MapCornerConfig,
}

/// A wall's start, direction, squared length and unit normal: what point-to-wall distances
/// need, together so one cache line holds them.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C)]
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
            runs: runs.into(),
            bends: chains.into_iter().filter(|c| c.run_count() >= 2).collect(),
            caster: RayCaster::new(&walls),
            outside: free_space.outside(),
            open_floor: OpenFloor::new(&walls, &free_space, OPEN_FLOOR_REACH),
            unseen: map.seen_free.as_ref().map(|seen| seen.unseen(1)),
            field,
            frames: walls.iter().map(WallFrame::of).collect::<Vec<_>>().into(),
            closed_sides,
            map,
            corner_config: *corners,
        }
    }
}

// SAFETY: `repr(C)`, seven f64 and no padding (checked), valid for any bits.
unsafe impl Plain for WallFrame {}
const _: () = assert!(std::mem::size_of::<WallFrame>() == 56);

/// The version of the model block's layout: raised whenever a [`Flat::put`] of the model's
/// parts changes what it writes. A block of another layout is refused.
pub const MODEL_LAYOUT: u64 = 3;

/// The first 8 bytes of a model block, as written on this machine: also tells a block of
/// another byte order.
const MAGIC: u64 = u64::from_le_bytes(*b"gema2mdl");

impl MapModel {
    /// The model as one block of bytes (see [`crate::flat`]): what the map server publishes.
    pub fn to_block(&self) -> FlatWriter {
        let mut w = FlatWriter::new();
        w.put_u64(MAGIC);
        w.put_u64(MODEL_LAYOUT);
        self.corner_config.put(&mut w);
        w.put_slice(&self.map.walls);
        w.put_f64(self.map.sigma);
        self.map.seen_free.put(&mut w);
        self.runs.put(&mut w);
        w.put_slice(&self.wall_directions);
        w.put_usize(self.bends.len());
        for chain in &self.bends {
            w.put_slice(&chain.points);
            w.put_bool(chain.closed);
        }
        self.corners.put(&mut w);
        self.caster.put(&mut w);
        self.field.put(&mut w);
        self.open_floor.put(&mut w);
        self.frames.put(&mut w);
        let sides: Option<Vec<u8>> =
            self.closed_sides.as_ref().map(|c| c.iter().flat_map(|s| s.map(u8::from)).collect());
        w.put_bool(sides.is_some());
        if let Some(sides) = sides {
            w.put_slice(&sides);
        }
        self.outside.put(&mut w);
        self.unseen.put(&mut w);
        w
    }

    /// The model a block holds, its large arrays viewed where they lie (the reader's owner
    /// keeps the block). Every length, offset and index is checked; a block of another layout
    /// or byte order, or a damaged one, is an error.
    pub fn from_block(r: &mut FlatReader<'_>) -> Result<Self, FlatError> {
        if r.take_u64("magic")? != MAGIC {
            return Err(FlatError::new("not a map model block (or one of another byte order)"));
        }
        let layout = r.take_u64("layout")?;
        if layout != MODEL_LAYOUT {
            return Err(FlatError::new(format!(
                "a block of layout {layout}; this program reads layout {MODEL_LAYOUT} (a map server of another build?)"
            )));
        }
        let corner_config = MapCornerConfig::take(r)?;
        let walls: Slab<Wall> = r.take_slab("walls")?;
        let sigma = r.take_finite("sigma")?;
        let seen_free = <Option<SeenFree> as Flat>::take(r)?;
        let map = WallMap { walls, sigma, seen_free };
        let runs: Slab<Wall> = Slab::take(r)?;
        let wall_directions = r.take_vec::<f64>("wall directions")?;
        let chains = r.take_usize("bends")?;
        let mut bends = Vec::new();
        for _ in 0..chains {
            let points = r.take_vec::<Point2<f64>>("bend")?;
            bends.push(RunChain { points, closed: r.take_bool("bend closed")? });
        }
        let corners = CornerIndex::take(r)?;
        corners.check(runs.len())?;
        let caster = RayCaster::take(r)?;
        let field = DistanceField::take(r)?;
        let open_floor = OpenFloor::take(r)?;
        let frames: Slab<WallFrame> = Slab::take(r)?;
        field.check_walls(frames.len())?;
        let closed_sides = if r.take_bool("closed sides")? {
            let bytes = r.take_vec::<u8>("closed sides")?;
            if bytes.len() != 2 * frames.len() || bytes.iter().any(|&b| b > 1) {
                return Err(FlatError::new("closed sides: not two yes-or-no bytes a wall"));
            }
            Some(bytes.chunks(2).map(|p| [p[0] == 1, p[1] == 1]).collect())
        } else {
            None
        };
        let outside = <Option<Outside> as Flat>::take(r)?;
        let unseen = <Option<Outside> as Flat>::take(r)?;
        r.finish()?;
        Ok(MapModel {
            map,
            runs,
            wall_directions,
            bends,
            corners,
            caster,
            field,
            open_floor,
            frames,
            closed_sides,
            outside,
            unseen,
            corner_config,
        })
    }
}

impl Flat for MapCornerConfig {
    fn put(&self, w: &mut FlatWriter) {
        for v in [self.min_angle, self.reach, self.short_reach, self.long_wall, self.min_arm_length, self.max_gap] {
            w.put_f64(v);
        }
        w.put_bool(self.wall_ends);
        w.put_bool(self.only_in_view);
    }
    fn take(r: &mut FlatReader<'_>) -> Result<Self, FlatError> {
        Ok(MapCornerConfig {
            min_angle: r.take_f64("min_angle")?,
            reach: r.take_f64("reach")?,
            short_reach: r.take_f64("short_reach")?,
            long_wall: r.take_f64("long_wall")?,
            min_arm_length: r.take_f64("min_arm_length")?,
            max_gap: r.take_f64("max_gap")?,
            wall_ends: r.take_bool("wall_ends")?,
            only_in_view: r.take_bool("only_in_view")?,
        })
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

    fn office() -> MapModel {
        let map = crate::bundled("office").and_then(Result::ok).expect("the bundled office parses");
        MapModel::new(map, &MapCornerConfig::default())
    }

    /// A model read from its block is the same model, its large arrays viewing the block.
    #[test]
    fn a_model_read_from_its_block_is_the_model_and_views_the_block() {
        let model = office();
        let block = model.to_block();
        let mut r = FlatReader::of_copy(block.bytes());
        let back = MapModel::from_block(&mut r).expect("its own block reads");
        assert_eq!(back.to_block().bytes(), block.bytes());
        assert!(back.corners.corners().len() > 100);
        assert_eq!(back.corners.corners(), model.corners.corners());
        assert!(back.runs.is_shared() && back.frames.is_shared());
        // what is copied rather than viewed is small: the walls, directions, bends, sides
        assert!(r.copied() * 10 < block.len(), "{} of {} bytes copied", r.copied(), block.len());
        for k in 0..200 {
            let p = Point2::new(0.1 * k as f64, 0.07 * k as f64);
            assert_eq!(back.field.distance(p).to_bits(), model.field.distance(p).to_bits());
            let angle = k as f64 * 0.1;
            assert_eq!(back.caster.cast_ray_brute(p, angle).to_bits(), model.caster.cast_ray_brute(p, angle).to_bits());
            assert_eq!(back.off_limits(p), model.off_limits(p));
        }
    }

    /// A cut or damaged block is refused or read, never a panic or a read out of bounds.
    #[test]
    fn a_cut_or_damaged_block_is_refused_not_a_panic() {
        let block = office().to_block();
        let bytes = block.bytes();
        for cut in (0..bytes.len()).step_by(bytes.len() / 97 + 1) {
            assert!(MapModel::from_block(&mut FlatReader::of_copy(&bytes[..cut])).is_err(), "cut at {cut}");
        }
        let mut other = bytes.to_vec();
        other[8..16].copy_from_slice(&(MODEL_LAYOUT + 1).to_ne_bytes());
        let err = MapModel::from_block(&mut FlatReader::of_copy(&other)).err().expect("another layout is refused");
        assert!(err.to_string().contains("layout"), "{err}");
        // flip bytes all over: any outcome but a panic
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        for _ in 0..300 {
            let mut damaged = bytes.to_vec();
            for _ in 0..4 {
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                let at = (state % damaged.len() as u64) as usize;
                damaged[at] ^= (state >> 32) as u8 | 1;
            }
            let _ = MapModel::from_block(&mut FlatReader::of_copy(&damaged));
        }
    }
}
