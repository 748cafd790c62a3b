//! The map on the wire: [`MapMsg`] written from a [`WallMap`] and read back, checked, by every
//! process that subscribes to it.

use crate::{Wall, WallMap};
use messages::{MapMsg, MAX_WALLS};

/// Writes `map` into a (zeroed) map message as `version`. Walls beyond [`MAX_WALLS`] are an
/// error, never cut silently.
pub fn map_to_msg(map: &WallMap, version: u32, m: &mut MapMsg) -> Result<(), String> {
    if map.walls.len() > MAX_WALLS {
        return Err(format!("{} walls, a map message holds at most {MAX_WALLS}", map.walls.len()));
    }
    m.version = version;
    m.count = map.walls.len() as u32;
    m.sigma = map.sigma;
    for (slot, w) in m.walls.iter_mut().zip(&map.walls) {
        *slot = [w.a.x, w.a.y, w.b.x, w.b.y];
    }
    Ok(())
}

/// The walls of a map message, if it is well formed: a count within [`MAX_WALLS`], finite
/// coordinates, no zero-length wall.
pub fn map_from_msg(m: &MapMsg) -> Result<WallMap, String> {
    let n = m.count as usize;
    if n == 0 || n > MAX_WALLS {
        return Err(format!("map version {}: {n} walls", m.version));
    }
    let walls: Vec<Wall> = m.walls[..n].iter().map(|w| Wall::new(w[0], w[1], w[2], w[3])).collect();
    match walls
        .iter()
        .position(|w| !(w.a.coords.iter().chain(w.b.coords.iter()).all(|v| v.is_finite()) && w.length() > 0.0))
    {
        Some(k) => Err(format!("map version {}: wall {k} is degenerate", m.version)),
        None => Ok(WallMap { walls, sigma: if m.sigma.is_finite() { m.sigma.max(0.0) } else { 0.0 } }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn boxed_msg() -> Box<MapMsg> {
        // SAFETY: MapMsg is Zeroable (numbers only); the zeroed heap block is a valid MapMsg.
        unsafe { Box::<MapMsg>::new_zeroed().assume_init() }
    }

    #[test]
    fn a_map_round_trips_and_bad_messages_are_refused() {
        let map = crate::procedural::by_name("apartment").expect("bundled procedural map");
        let mut m = boxed_msg();
        map_to_msg(&map, 7, &mut m).unwrap();
        let back = map_from_msg(&m).unwrap();
        assert_eq!(back.walls.len(), map.walls.len());
        assert_eq!(back.walls[3].a, map.walls[3].a);
        m.walls[2][1] = f64::NAN;
        assert!(map_from_msg(&m).unwrap_err().contains("wall 2"));
        m.count = 0;
        assert!(map_from_msg(&m).is_err());
        m.count = (MAX_WALLS + 1) as u32;
        assert!(map_from_msg(&m).is_err());
    }
}
