//! Which of the map's corners a sensor can see.
//!
//! A plan drawn with thick walls (two faces per wall, jambs at doors: [`crate::thick`]) gives
//! every face corners on both of its sides, and the extensions of faces meet all over the
//! plan. The corners whose wedge (the region between their arms) lies in a wall's body are
//! never seen, since no beam enters a wall, yet each would make a candidate pose for every
//! scan corner of its inner angle: in the bundled office drawn 12 cm thick they were 74 % of
//! its 15464 corners.
//!
//! A corner is in view when, along each of its arms' lines and within the arm's extent (the
//! collinear walls a scan sees as one), some wall faces the wedge with space a sensor can
//! stand in: a point clear of every wall by [`STANDING_CLEARANCE`], reached from the wall
//! along its normal without crossing another. A wall end (inner angle 2 pi) is seen from
//! either side of its wall, so one arm facing such space is enough.
//!
//! Corners facing the space around a closed building stay: poses out there are never the
//! answer, but one that explains a scan as well as the answer tells the localizer the scan is
//! ambiguous (dropping them made 7 more wrong `ok` answers over 42 simulated logs).

use crate::corners::{CornerIndex, MapCorner, MapCornerConfig};
use crate::hash::BuildMix;
use crate::sight::SightLines;
use crate::wall::Wall;
use nalgebra::{Point2, Vector2};
use std::f64::consts::{FRAC_1_SQRT_2, TAU};

/// How far from a wall the look for space to stand in goes, metres: the reach of the
/// [`SightLines`] that [`in_view`] takes.
pub const LOOK: f64 = 1.0;

/// Clearance from every wall of a point a sensor can stand at, metres: more than half the
/// thickness of a wall drawn with both faces (10-25 cm), so the body between two faces never
/// counts.
pub const STANDING_CLEARANCE: f64 = 0.15;

/// How far along an arm's extent the look for a wall facing the corner goes, metres.
const ARM_LOOK: f64 = 3.0;

/// Step of the look along an arm, metres.
const ARM_STEP: f64 = 0.1;

/// Step of the look along a wall's normal, metres.
const STEP: f64 = 0.05;

/// How far beside an arm's line its wall may lie, metres: junctions are merged within
/// millimetres, so an arm's line may pass a little beside the wall it stands for.
const ON_LINE: f64 = 0.03;

/// How far off a wall the look along its normal starts, metres.
const OFF_WALL: f64 = 1e-3;

/// Whether a sensor can see corner `c` of the walls `sight` was built on (with reach
/// [`LOOK`]); see the module documentation.
pub fn in_view(c: &MapCorner, sight: &SightLines) -> bool {
    Looks::new(sight).in_view(c)
}

/// The looks [`in_view`] takes, remembered. An arm is looked along at the points of its line
/// that lie on a lattice of `ARM_STEP` along that line (see `Looks::arm_faces_wedge`), so
/// every corner along one wall asks about the same points; the answer at each is found once.
/// On a map built from a real log (freiburg-079) 1.2 million corners ask about some 20 million
/// points, most of them the same few hundred thousand.
pub struct Looks<'a> {
    sight: &'a SightLines,
    known: std::collections::HashMap<u128, bool, BuildMix>,
    /// Where the looks' points are measured from (the walls' lowest corner), so that a point
    /// of any map within [`crate::MAX_EXTENT`] keys in 32 bits.
    origin: Point2<f64>,
}

/// The precision the remembered looks are told apart at: 1 mm, and 1e-5 of a unit direction.
const LOOK_KEY: f64 = 1e3;
const TURN_KEY: f64 = 1e5;
/// What makes a direction's keyed component positive: `TURN_KEY`, rounded up to a power of two.
const TURN_OFFSET: i64 = 1 << 17;

impl<'a> Looks<'a> {
    pub fn new(sight: &'a SightLines) -> Self {
        Looks { sight, known: Default::default(), origin: crate::wall::bounds_of(sight.walls()).0 }
    }

    /// Whether a sensor can see corner `c`: both arms face the wedge with space to stand in,
    /// or, for a wall end, either does.
    pub fn in_view(&mut self, c: &MapCorner) -> bool {
        if c.inner_angle >= TAU {
            (0..2).any(|k| self.arm_faces_wedge(c, k))
        } else {
            (0..2).all(|k| self.arm_faces_wedge(c, k))
        }
    }

    /// Whether arm `k` of corner `c` (0 the right, 1 the left) has, within its extent, a wall
    /// that faces the wedge with space a sensor can stand in. It looks from the points of the
    /// arm's line at whole multiples of [`ARM_STEP`] along it (measured along the line's
    /// direction from the map's origin), or from the middle of an arm too short to hold one.
    fn arm_faces_wedge(&mut self, c: &MapCorner, k: usize) -> bool {
        let arm = &c.arms[k];
        // the wedge lies counter-clockwise of the right arm and clockwise of the left
        let u = arm.direction;
        let side = if k == 0 { Vector2::new(-u.y, u.x) } else { Vector2::new(u.y, -u.x) };
        let end = arm.extent.min(arm.gap + ARM_LOOK).max(arm.gap + arm.length);
        let along = c.position.coords.dot(&u);
        let mut t = ((along + arm.gap) / ARM_STEP).ceil() * ARM_STEP - along;
        if t > arm.gap + arm.length {
            t = arm.gap + 0.5 * arm.length;
        }
        while t <= end {
            if self.faces_standing_space(c.position + u * t, u, side) {
                return true;
            }
            t += ARM_STEP;
        }
        false
    }

    fn faces_standing_space(&mut self, on_line: Point2<f64>, along: Vector2<f64>, side: Vector2<f64>) -> bool {
        // millimetres from the origin in 32 bits each, the direction's components in 20 bits
        // each (offset to be positive), the side in one
        let q = |v: f64, scale: f64| (v * scale).round() as i64;
        let (x, y) = (q(on_line.x - self.origin.x, LOOK_KEY), q(on_line.y - self.origin.y, LOOK_KEY));
        let (ux, uy) = (q(along.x, TURN_KEY) + TURN_OFFSET, q(along.y, TURN_KEY) + TURN_OFFSET);
        let left = along.perp(&side) > 0.0;
        let key = (x as u32 as u128)
            | (y as u32 as u128) << 32
            | ((ux as u128) & 0xf_ffff) << 64
            | ((uy as u128) & 0xf_ffff) << 84
            | u128::from(left) << 104;
        let (sight, origin) = (self.sight, self.origin);
        *self.known.entry(key).or_insert_with(|| {
            // looked at from the key's own point and direction, so the answer is the key's
            // whichever corner asks first
            let at = origin + Vector2::new(x as f64, y as f64) / LOOK_KEY;
            let u = Vector2::new((ux - TURN_OFFSET) as f64, (uy - TURN_OFFSET) as f64).normalize();
            let normal = Vector2::new(-u.y, u.x);
            faces_standing_space(at, u, if left { normal } else { -normal }, sight)
        })
    }
}

/// For each wall, whether each of its sides (left then right of `a` to `b`) is closed: no point
/// along it faces space a sensor can stand in, as the sides of a thick wall's faces that look
/// into its body. `None` when every side of every wall is open (walls drawn as lines).
pub fn closed_sides(walls: &[Wall]) -> Option<Vec<[bool; 2]>> {
    let sight = SightLines::new(walls, LOOK);
    let sides: Vec<[bool; 2]> = walls
        .iter()
        .map(|w| {
            let e = w.b - w.a;
            let Some(u) = e.try_normalize(1e-12) else {
                return [false, false];
            };
            let left = Vector2::new(-u.y, u.x);
            [left, -left].map(|side| !SIDE_SAMPLES.iter().any(|&f| faces_standing_space(w.a + e * f, u, side, &sight)))
        })
        .collect();
    sides.iter().any(|s| s[0] || s[1]).then_some(sides)
}

/// Where along a wall [`closed_sides`] looks, as fractions of its length.
const SIDE_SAMPLES: [f64; 3] = [0.25, 0.5, 0.75];

/// Whether a wall within [`ON_LINE`] of `on_line` (a point on an arm's line, whose direction
/// away from the corner is `along`) faces `side` with space a sensor can stand in: a point of
/// that clearance in sight of the wall. The looks leave the wall at several angles, as a
/// narrow wedge opens away from its corner rather than straight across from the wall.
fn faces_standing_space(on_line: Point2<f64>, along: Vector2<f64>, side: Vector2<f64>, sight: &SightLines) -> bool {
    let ahead = on_line + side * ON_LINE;
    let back = sight.free_run(ahead, -side);
    if back > 2.0 * ON_LINE {
        // no wall here: a gap (a door) along the arm's line, which faces nothing
        return false;
    }
    let from = ahead - side * (back - OFF_WALL);
    LOOK_ANGLES.iter().any(|&(cos, sin)| {
        let dir = along * cos + side * sin;
        let run = sight.free_run(from, dir);
        // a point clear by STANDING_CLEARANCE lies at least that far from the wall it looks at
        let steps = ((run - STANDING_CLEARANCE) / STEP).floor().max(0.0) as usize;
        (1..=steps).any(|i| sight.is_clear(from + dir * (i as f64 * STEP), STANDING_CLEARANCE))
    })
}

/// The looks' directions as (cosine, sine) of their angle from the arm's direction towards the
/// wedge: straight across first, then turned 45 degrees either way.
const LOOK_ANGLES: [(f64, f64); 3] = [(0.0, 1.0), (FRAC_1_SQRT_2, FRAC_1_SQRT_2), (-FRAC_1_SQRT_2, FRAC_1_SQRT_2)];

/// How far past a wall's end a map built from scans must have seen free space for the end to
/// be a corner, metres: past a true end (a door jamb, a pillar) beams went on, past an end
/// where the survey only stopped seeing the wall they stopped at it.
pub const SEEN_PAST_END: f64 = 0.3;

/// Whether the survey saw free space [`SEEN_PAST_END`] past wall end `c`, on its wall's line.
fn seen_past_its_end(c: &MapCorner, seen: &crate::SeenFree) -> bool {
    seen.contains(c.position - c.arms[0].direction * SEEN_PAST_END)
}

/// The corners a map offers: built from its straight runs, and only those a sensor can see.
impl CornerIndex {
    /// The corners of `map`. A map that declares itself approximate (`sigma` of
    /// [`APPROXIMATE_MAP`](crate::map::APPROXIMATE_MAP) or more: typically built from scans)
    /// lists only the wall ends its survey saw free space past ([`SEEN_PAST_END`]), and none
    /// when it keeps no survey: most of its walls end where the survey stopped seeing them, not
    /// where the walls do.
    ///
    /// Corners come from the map's straight runs ([`crate::runs`]), not from its walls as
    /// drawn: a wall drawn in pieces is one wall to a scan. With
    /// [`MapCornerConfig::only_in_view`], corners no sensor can see are left out
    /// ([`crate::view`]).
    pub fn of_map(map: &crate::map::WallMap, cfg: &MapCornerConfig) -> Self {
        Self::of_runs(map, &map.straight_runs(), cfg)
    }

    /// [`of_map`](Self::of_map) with the map's straight runs already at hand.
    pub fn of_runs(map: &crate::map::WallMap, runs: &[Wall], cfg: &MapCornerConfig) -> Self {
        // a built map's wall ends are the ends its survey saw past; without a survey, none
        let survey = map.seen_free.as_ref().filter(|_| map.is_approximate());
        let wall_ends = cfg.wall_ends && (!map.is_approximate() || survey.is_some());
        let cfg = MapCornerConfig { wall_ends, ..*cfg };
        let real = |c: &MapCorner| c.inner_angle < TAU || survey.is_none_or(|seen| seen_past_its_end(c, seen));
        let corners = if cfg.only_in_view {
            // as they are found, junction by junction: the looks of one junction's corners are
            // remembered together, and only the corners kept are stored and sorted
            let sight = SightLines::new(runs, LOOK);
            let mut looks = Looks::new(&sight);
            crate::corners::extract_map_corners_where(runs, &cfg, |c| real(c) && looks.in_view(c))
        } else {
            crate::corners::extract_map_corners_where(runs, &cfg, real)
        };
        Self::new(corners)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::corners::{CornerIndex, MapCornerConfig};
    use crate::map::WallMap;
    use crate::thick::thicken;
    use std::f64::consts::FRAC_PI_2;

    /// A 6 x 4 m room split by a partition at x = 3 with a 0.9 m door.
    fn two_rooms() -> WallMap {
        let mut walls = Wall::rectangle(0.0, 0.0, 6.0, 4.0).to_vec();
        walls.extend([Wall::new(3.0, 0.0, 3.0, 1.5), Wall::new(3.0, 2.4, 3.0, 4.0)]);
        WallMap::new(walls)
    }

    fn all_corners(map: &WallMap) -> Vec<MapCorner> {
        let cfg = MapCornerConfig { only_in_view: false, ..MapCornerConfig::default() };
        CornerIndex::of_map(map, &cfg).corners().to_vec()
    }

    /// A map built from scans lists the wall ends its survey saw free space past (the door's
    /// jambs), not those it did not (where the partition meets the outer wall, and the outer
    /// walls' ends at the building's corners); without a survey it lists none. Its junctions
    /// stay as they are.
    #[test]
    fn a_built_map_lists_the_wall_ends_its_survey_saw_past() {
        let drawn = two_rooms();
        let mut seen = crate::SeenFree::covering(Point2::new(-1.0, -1.0), Point2::new(7.0, 5.0), 0.2).unwrap();
        // beams across each room, and through the door
        for k in 1..40 {
            let y = 0.1 * f64::from(k);
            seen.mark_ray(Point2::new(0.05, y), Point2::new(2.95, y));
            seen.mark_ray(Point2::new(3.05, y), Point2::new(5.95, y));
        }
        seen.mark_ray(Point2::new(2.0, 1.95), Point2::new(4.0, 1.95));
        let surveyed = WallMap { sigma: crate::APPROXIMATE_MAP, seen_free: Some(seen), ..drawn.clone() };
        let unsurveyed = WallMap { seen_free: None, ..surveyed.clone() };
        let ends = |map: &WallMap| {
            let mut ends: Vec<(i64, i64)> = all_corners(map)
                .iter()
                .filter(|c| c.inner_angle >= TAU)
                .map(|c| ((c.position.x * 10.0).round() as i64, (c.position.y * 10.0).round() as i64))
                .collect();
            ends.sort_unstable();
            ends
        };
        assert_eq!(ends(&surveyed), [(30, 15), (30, 24)], "the door's jambs");
        assert!(ends(&unsurveyed).is_empty());
        assert!(ends(&drawn).len() > 2, "a drawn map lists every end");
        let junctions = |map: &WallMap| all_corners(map).iter().filter(|c| c.inner_angle < TAU).count();
        assert_eq!(junctions(&surveyed), junctions(&drawn));
    }

    #[test]
    fn every_corner_of_walls_drawn_as_lines_is_in_view() {
        let map = two_rooms();
        let sight = SightLines::new(&map.straight_runs(), LOOK);
        let corners = all_corners(&map);
        assert!(corners.len() > 20);
        for c in &corners {
            assert!(in_view(c, &sight), "{c:?}");
        }
    }

    #[test]
    fn corners_whose_wedge_lies_in_a_thick_walls_body_are_out_of_view() {
        let map = thicken(&two_rooms(), 0.12);
        let sight = SightLines::new(&map.straight_runs(), LOOK);
        let corners = all_corners(&map);
        let at = |x: f64, y: f64, beta: f64| {
            corners
                .iter()
                .filter(move |c| (c.position - Point2::new(x, y)).norm() < 1e-3 && (c.inner_angle - beta).abs() < 1e-3)
        };
        // the left room's inside corner: its 90 degree wedge is the room, the 270 degree one
        // is mostly wall
        assert!(at(0.06, 0.06, FRAC_PI_2).count() >= 1);
        assert!(at(0.06, 0.06, FRAC_PI_2).all(|c| in_view(c, &sight)));
        assert!(at(0.06, 0.06, 3.0 * FRAC_PI_2).count() >= 1);
        assert!(at(0.06, 0.06, 3.0 * FRAC_PI_2).all(|c| !in_view(c, &sight)));
        // the door's jamb on the partition's left face: the convex corner (270 degrees, seen
        // from the room and the doorway) is in view, its 90 degrees inside the partition is not
        assert!(at(2.94, 1.56, 3.0 * FRAC_PI_2).any(|c| in_view(c, &sight)));
        assert!(at(2.94, 1.56, FRAC_PI_2).count() >= 1);
        assert!(at(2.94, 1.56, FRAC_PI_2).all(|c| !in_view(c, &sight)));
        // the building's outer face stays: its corners face the space around it
        assert!(at(-0.06, -0.06, 3.0 * FRAC_PI_2).any(|c| in_view(c, &sight)));
        let kept = corners.iter().filter(|c| in_view(c, &sight)).count();
        assert!(kept < corners.len() / 2, "{kept} of {} in view", corners.len());
    }

    #[test]
    fn the_sides_of_a_thick_walls_faces_that_look_into_its_body_are_closed() {
        let lines = two_rooms();
        assert_eq!(closed_sides(&lines.walls), None);
        let thick = thicken(&lines, 0.12);
        let sides = closed_sides(&thick.walls).expect("a thick wall's body closes a side of each face");
        let mut closed_count = 0;
        for (w, closed) in thick.walls.iter().zip(&sides) {
            let u = (w.b - w.a).normalize();
            let left = Vector2::new(-u.y, u.x);
            for (k, side) in [left, -left].into_iter().enumerate() {
                // 3 cm off the face's middle: in the body when within half the thickness of a
                // centre line
                let q = w.a + (w.b - w.a) / 2.0 + side * 0.03;
                let in_body = lines.walls.iter().any(|v| v.closest(q).0 < 0.06);
                assert_eq!(closed[k], in_body, "{w:?} side {k}");
                closed_count += usize::from(closed[k]);
            }
        }
        assert_eq!(closed_count, thick.walls.len());
    }

    #[test]
    fn an_office_drawn_thick_offers_about_as_many_corners_as_drawn_as_lines() {
        let lines = crate::bundled::bundled("office").unwrap().unwrap();
        let thick = thicken(&lines, 0.12);
        // one reach for every wall: a thick wall's faces are longer than its centre line by
        // the thickness, so the short walls' reach would count differently in the two
        let cfg = MapCornerConfig { short_reach: MapCornerConfig::default().reach, ..MapCornerConfig::default() };
        let in_view = |m: &WallMap| CornerIndex::of_map(m, &cfg).corners().len();
        let all_of_thick = CornerIndex::of_map(&thick, &MapCornerConfig { only_in_view: false, ..cfg }).corners().len();
        let (of_lines, of_thick) = (in_view(&lines), in_view(&thick));
        // the faces' corners on both sides and their extensions made five times as many
        assert!(all_of_thick > 4 * of_lines, "{all_of_thick} corners drawn thick, {of_lines} as lines");
        assert!(2 * of_thick < 3 * of_lines, "{of_thick} corners in view drawn thick, {of_lines} as lines");
    }
}
