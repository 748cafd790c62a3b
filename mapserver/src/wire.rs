//! The map on the wire: [`MapMsg`] written from a [`WallMap`] and read back, checked, by every
//! process that subscribes to it.

use map::map::{check_walls, WallsProblem};
use map::{SeenFree, Wall, WallMap};
use messages::{MapMsg, MAX_SEEN_WORDS, MAX_WALLS};
use thiserror::Error;

/// Why a map does not go onto the wire, or a map message is not a map.
#[derive(Debug, Error, PartialEq)]
pub enum WireError {
    #[error("{0} walls, a map message holds at most {MAX_WALLS}")]
    TooManyWalls(usize),
    #[error("map version {version}: {count} walls")]
    WallCount { version: u32, count: usize },
    #[error("map version {version}: {problem}")]
    Walls { version: u32, problem: WallsProblem },
    #[error("map version {version}: {cols} x {rows} seen cells {why}")]
    Seen { version: u32, cols: usize, rows: usize, why: &'static str },
}

/// Writes `map` into a (zeroed) map message as `version`. Walls beyond [`MAX_WALLS`] are an
/// error, never cut silently.
pub fn map_to_msg(map: &WallMap, version: u32, m: &mut MapMsg) -> Result<(), WireError> {
    if map.walls.len() > MAX_WALLS {
        return Err(WireError::TooManyWalls(map.walls.len()));
    }
    m.version = version;
    m.count = map.walls.len() as u32;
    m.sigma = map.sigma;
    for (slot, w) in m.walls.iter_mut().zip(&map.walls) {
        *slot = [w.a.x, w.a.y, w.b.x, w.b.y];
    }
    (m.seen_cols, m.seen_rows) = (0, 0);
    if let Some(seen) = &map.seen_free {
        // coarser until it fits: a coarser raster rules out less, never more
        let mut seen = std::borrow::Cow::Borrowed(seen);
        while seen.bits().len() > MAX_SEEN_WORDS {
            seen = std::borrow::Cow::Owned(seen.coarsened());
        }
        let (cols, rows) = seen.size();
        m.seen_origin = [seen.origin().x, seen.origin().y];
        m.seen_cell = seen.cell();
        (m.seen_cols, m.seen_rows) = (cols as u32, rows as u32);
        m.seen_bits[..seen.bits().len()].copy_from_slice(seen.bits());
    }
    Ok(())
}

/// The walls of a map message, if it is well formed: a count within [`MAX_WALLS`], finite
/// coordinates, walls of at least [`map::MIN_WALL_LENGTH`] within [`map::MAX_EXTENT`] of each
/// other (the checks of a map file, [`check_walls`]).
pub fn map_from_msg(m: &MapMsg) -> Result<WallMap, WireError> {
    let (n, version) = (m.count as usize, m.version);
    if n == 0 || n > MAX_WALLS {
        return Err(WireError::WallCount { version, count: n });
    }
    let walls: Vec<Wall> = m.walls[..n].iter().map(|w| Wall::new(w[0], w[1], w[2], w[3])).collect();
    // checked as a map file is: a map from the wire is no more trusted than one from a disk
    match check_walls(&walls) {
        Err(problem) => Err(WireError::Walls { version, problem }),
        Ok(()) => {
            let (cols, rows) = (m.seen_cols as usize, m.seen_rows as usize);
            let seen = |why| WireError::Seen { version, cols, rows, why };
            let cells = cols.checked_mul(rows).ok_or(seen("are too many"))?;
            let seen_free = if cells == 0 {
                None
            } else {
                let words = cells.div_ceil(64);
                let bits = m.seen_bits.get(..words).ok_or(seen("do not fit"))?;
                let origin = nalgebra::Point2::new(m.seen_origin[0], m.seen_origin[1]);
                Some(SeenFree::from_bits(origin, m.seen_cell, cols, rows, bits).ok_or(seen("are malformed"))?)
            };
            Ok(WallMap {
                walls: walls.into(),
                sigma: if m.sigma.is_finite() { m.sigma.max(0.0) } else { 0.0 },
                seen_free,
            })
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn boxed_msg() -> Box<MapMsg> {
        messages::zeroed_box()
    }

    #[test]
    fn a_map_round_trips_and_bad_messages_are_refused() {
        let map = map::bundled("apartment").expect("a bundled map").expect("it parses");
        let mut m = boxed_msg();
        map_to_msg(&map, 7, &mut m).unwrap();
        let back = map_from_msg(&m).unwrap();
        assert_eq!(back.walls.len(), map.walls.len());
        assert_eq!(back.walls[3].a, map.walls[3].a);
        m.walls[2][1] = f64::NAN;
        assert!(map_from_msg(&m).unwrap_err().to_string().contains("wall 2"));
        // the checks of a map file: a wall shorter than a millimetre, walls 20 km apart
        map_to_msg(&map, 7, &mut m).unwrap();
        m.walls[4] = [1.0, 1.0, 1.0, 1.0005];
        assert!(map_from_msg(&m).unwrap_err().to_string().contains("wall 4: wall is shorter than"));
        map_to_msg(&map, 7, &mut m).unwrap();
        m.walls[5] = [20_000.0, 0.0, 20_001.0, 0.0];
        assert!(map_from_msg(&m).unwrap_err().to_string().contains("more than the 10000 m an indoor map may span"));
        m.count = 0;
        assert!(map_from_msg(&m).is_err());
        m.count = (MAX_WALLS + 1) as u32;
        assert!(map_from_msg(&m).is_err());
    }

    /// A survey's seen free space crosses as it is, or coarser when it does not fit; a
    /// malformed one is refused.
    #[test]
    fn the_seen_free_space_crosses_and_is_coarsened_to_fit() {
        let mut map = map::bundled("apartment").expect("a bundled map").expect("it parses");
        let (lo, hi) = map.bounds();
        let mut seen = SeenFree::covering(lo, hi, 0.2).unwrap();
        seen.mark_ray(lo + nalgebra::Vector2::new(1.0, 1.0), hi - nalgebra::Vector2::new(1.0, 1.0));
        map.seen_free = Some(seen);
        let mut m = boxed_msg();
        map_to_msg(&map, 1, &mut m).unwrap();
        assert_eq!(map_from_msg(&m).unwrap(), map);
        // 4000 x 1000 cells: 62500 words, published at four times the cell (3907 words)
        let mut big = SeenFree::covering(lo, lo + nalgebra::Vector2::new(400.0, 100.0), 0.1).unwrap();
        let q = lo + nalgebra::Vector2::new(250.0, 50.0);
        big.mark_ray(q, q);
        map.seen_free = Some(big);
        map_to_msg(&map, 2, &mut m).unwrap();
        let back = map_from_msg(&m).unwrap().seen_free.unwrap();
        assert_eq!(back.cell(), 0.4);
        assert!(back.contains(q) && !back.contains(lo));
        m.seen_cols = u32::MAX;
        assert!(map_from_msg(&m).unwrap_err().to_string().contains("seen"));
        m.seen_cols = 10;
        m.seen_cell = f64::NAN;
        assert!(map_from_msg(&m).unwrap_err().to_string().contains("seen cells are malformed"));
    }
}
