//! The wall map (docs/design.md, "File formats"): `{"walls": [[x1, y1, x2, y2], ...]}` in metres, map frame. Other
//! keys are ignored. A malformed file is rejected with the file's name and the offending
//! element.

use nalgebra::Point2;
use serde_json::Value;
use std::path::{Path, PathBuf};
use thiserror::Error;

use crate::runs::{RunChain, JOINED, STRAIGHTNESS};
use crate::seen::SeenFree;
use crate::slab::Slab;
pub use crate::wall::{bounds_of, Wall};

/// A map whose `sigma` is at least this (metres) is approximate: built from scans, its walls
/// drawn to within that and ending where the survey stopped seeing them
/// ([`CornerIndex::of_map`](crate::CornerIndex::of_map) lists no wall ends for it).
pub const APPROXIMATE_MAP: f64 = 0.05;

/// Walls shorter than this are rejected as degenerate, metres.
pub const MIN_WALL_LENGTH: f64 = 1e-3;

/// A map file whose walls span more than this, metres, in x or y is rejected: no indoor floor
/// does, while a plan in millimetres or a stray wall far from the rest does.
pub const MAX_EXTENT: f64 = 10_000.0;

/// A length for a message: whole metres, or in scientific notation when absurdly large.
fn metres(v: f64) -> String {
    if v < 1e7 {
        format!("{v:.0}")
    } else {
        format!("{v:.1e}")
    }
}

/// The median of `values` (the upper one of an even count; 0 for none).
fn median(values: impl Iterator<Item = f64>) -> f64 {
    let mut v: Vec<f64> = values.collect();
    if v.is_empty() {
        return 0.0;
    }
    let k = v.len() / 2;
    *v.select_nth_unstable_by(k, f64::total_cmp).1
}

/// Why a list of walls is no map.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum WallsProblem {
    /// Wall `index` is not finite or shorter than [`MIN_WALL_LENGTH`].
    #[error("wall {index}: {message}")]
    Wall { index: usize, message: String },
    /// The walls span more than [`MAX_EXTENT`].
    #[error("{0}")]
    Extent(String),
}

/// The one check of a map's walls, wherever they come from (a file, the wire): finite, at least
/// [`MIN_WALL_LENGTH`] long, and within [`MAX_EXTENT`] of each other.
pub fn check_walls(walls: &[Wall]) -> Result<(), WallsProblem> {
    for (index, w) in walls.iter().enumerate() {
        if !w.a.coords.iter().chain(w.b.coords.iter()).all(|v| v.is_finite()) {
            return Err(WallsProblem::Wall { index, message: "coordinates must be finite".into() });
        }
        if w.length() < MIN_WALL_LENGTH {
            return Err(WallsProblem::Wall { index, message: format!("wall is shorter than {MIN_WALL_LENGTH} m") });
        }
    }
    let (lo, hi) = bounds_of(walls);
    let span = hi - lo;
    if span.x > MAX_EXTENT || span.y > MAX_EXTENT {
        // the wall farthest from the middle of the others is the likeliest stray
        let mid = Point2::new(median(walls.iter().map(|w| w.a.x)), median(walls.iter().map(|w| w.a.y)));
        let (index, far) = walls
            .iter()
            .enumerate()
            .map(|(k, w)| (k, (w.a - mid).norm().max((w.b - mid).norm())))
            .fold((0, 0.0), |best, k| if k.1 > best.1 { k } else { best });
        return Err(WallsProblem::Extent(format!(
            "the walls span {} x {} m, more than the {MAX_EXTENT} m an indoor map may span: are the \
                     coordinates in millimetres, or is a wall astray (walls[{index}] reaches {} m from the middle \
                     of the others)?",
            metres(span.x),
            metres(span.y),
            metres(far)
        )));
    }
    Ok(())
}

/// A map of walls.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct WallMap {
    /// Owned, or viewed in place in a map model served in shared memory ([`Slab`]).
    pub walls: Slab<Wall>,
    /// How far the walls may be from the real ones, metres (the optional `"sigma"` key): 0 for
    /// an exact plan, about 0.1 for a map built from scans. The cost function never expects
    /// the sensor to agree with the map better than this.
    pub sigma: f64,
    /// Where the survey that built the map saw free space (the optional `"seen_free"` key);
    /// see [`SeenFree`].
    pub seen_free: Option<SeenFree>,
}

/// Why a map was rejected.
#[derive(Debug, Error)]
pub enum MapError {
    // the cause is in the message, not chained too: it would print twice ("Caused by")
    #[error("{path}: cannot read the map: {cause}")]
    Io { path: PathBuf, cause: std::io::Error },
    #[error("{path}: not valid JSON at line {line}, column {column}: {message}")]
    Json { path: PathBuf, line: usize, column: usize, message: String },
    #[error("{path}: {message}")]
    Shape { path: PathBuf, message: String },
    #[error("{path}: walls[{index}]: {message}")]
    Wall { path: PathBuf, index: usize, message: String },
}

impl WallMap {
    pub fn new(walls: Vec<Wall>) -> Self {
        WallMap { walls: walls.into(), sigma: 0.0, seen_free: None }
    }

    /// Whether the map declares itself approximate: a `sigma` of [`APPROXIMATE_MAP`]
    /// or more, as maps built from scans do.
    pub fn is_approximate(&self) -> bool {
        self.sigma >= APPROXIMATE_MAP
    }

    /// The walls as the straight stretches a scan's lines can match ([`crate::runs`]), to
    /// within the map's `sigma` or [`STRAIGHTNESS`], whichever is larger.
    pub fn straight_runs(&self) -> Vec<Wall> {
        crate::runs::straight_runs(&self.walls, STRAIGHTNESS.max(self.sigma))
    }

    /// [`straight_runs`](Self::straight_runs) with the runs that continue each other (a curved
    /// or bent wall) kept together as chains, in the same order.
    pub fn chains_of_runs(&self) -> Vec<RunChain> {
        crate::runs::chains_of_runs(&self.walls, STRAIGHTNESS.max(self.sigma))
    }

    /// The walls as drawn, with pieces that continue or overlap each other along one line
    /// joined into one wall ([`crate::runs`] to within [`JOINED`]): the same
    /// geometry in fewer walls, for ray casting and distance fields. A plan traced in pieces
    /// split wherever another wall meets them has several times the walls it draws.
    pub fn joined_walls(&self) -> Vec<Wall> {
        crate::runs::straight_runs(&self.walls, JOINED)
    }

    /// Loads and validates a JSON map file.
    pub fn load(path: &Path) -> Result<Self, MapError> {
        let text = std::fs::read_to_string(path).map_err(|cause| MapError::Io { path: path.to_owned(), cause })?;
        Self::parse(&text, path)
    }

    /// Parses and validates JSON text; `origin` names the source in errors.
    pub fn parse(text: &str, origin: &Path) -> Result<Self, MapError> {
        let path = origin.to_owned();
        let doc: Value = serde_json::from_str(text).map_err(|e| MapError::Json {
            path: path.clone(),
            line: e.line(),
            column: e.column(),
            message: e.to_string(),
        })?;
        let Some(list) = doc.get("walls") else {
            return Err(MapError::Shape { path, message: "no \"walls\" key at the top level".into() });
        };
        let Some(list) = list.as_array() else {
            return Err(MapError::Shape { path, message: "\"walls\" is not a list".into() });
        };
        if list.is_empty() {
            return Err(MapError::Shape { path, message: "\"walls\" is empty: a map needs walls".into() });
        }
        let sigma = match doc.get("sigma") {
            None => 0.0,
            Some(v) => match v.as_f64() {
                Some(x) if x.is_finite() && x >= 0.0 => x,
                _ => {
                    return Err(MapError::Shape {
                        path,
                        message: format!("\"sigma\" must be a non-negative number of metres, found {v}"),
                    })
                }
            },
        };
        let seen_free = match doc.get("seen_free") {
            None => None,
            Some(v) => Some(
                SeenFree::from_json(v)
                    .map_err(|e| MapError::Shape { path: path.clone(), message: format!("\"seen_free\": {}", e.0) })?,
            ),
        };
        let mut walls = Vec::with_capacity(list.len());
        for (index, item) in list.iter().enumerate() {
            let bad = |message: String| MapError::Wall { path: path.clone(), index, message };
            let nums: Vec<f64> = match item.as_array() {
                Some(a) if a.len() == 4 => a.iter().filter_map(Value::as_f64).collect(),
                _ => Vec::new(),
            };
            if nums.len() != 4 {
                return Err(bad(format!("expected four numbers [x1, y1, x2, y2], found {item}")));
            }
            walls.push(Wall::new(nums[0], nums[1], nums[2], nums[3]));
        }
        match check_walls(&walls) {
            Ok(()) => {}
            Err(WallsProblem::Wall { index, message }) => {
                return Err(MapError::Wall { path, index, message: format!("{message}: {}", list[index]) })
            }
            Err(WallsProblem::Extent(message)) => return Err(MapError::Shape { path, message }),
        }
        Ok(WallMap { walls: walls.into(), sigma, seen_free })
    }

    /// The map as JSON (docs/design.md's format), with a name.
    pub fn to_json(&self, name: &str) -> String {
        let mut s = format!("{{\n  \"name\": {},\n", Value::String(name.into()));
        if self.sigma > 0.0 {
            s += &format!("  \"sigma\": {},\n", self.sigma);
        }
        if let Some(seen) = &self.seen_free {
            s += &format!("  \"seen_free\": {},\n", seen.to_json());
        }
        s += "  \"walls\": [\n";
        for (k, w) in self.walls.iter().enumerate() {
            let sep = if k + 1 < self.walls.len() { "," } else { "" };
            s += &format!("    [{:.3}, {:.3}, {:.3}, {:.3}]{sep}\n", w.a.x, w.a.y, w.b.x, w.b.y);
        }
        s + "  ]\n}\n"
    }

    /// Axis-aligned bounds (min, max) of all walls.
    pub fn bounds(&self) -> (Point2<f64>, Point2<f64>) {
        bounds_of(&self.walls)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(s: &str) -> Result<WallMap, MapError> {
        WallMap::parse(s, Path::new("m.json"))
    }

    #[test]
    fn a_good_map_with_extra_keys_loads() {
        let m = parse(r#"{"name": "x", "resolution": 0.05, "walls": [[0,0,1,0],[1,0,1,1.5]]}"#).unwrap();
        assert_eq!(m.walls.len(), 2);
        assert_eq!(m.walls[1].b, Point2::new(1.0, 1.5));
        let again = parse(&m.to_json("x")).unwrap();
        assert_eq!(again, m);
        // with the seen free space of a survey
        let mut seen = SeenFree::covering(Point2::new(0.0, 0.0), Point2::new(1.0, 1.5), 0.1).unwrap();
        seen.mark_ray(Point2::new(0.5, 1.0), Point2::new(0.5, 0.2));
        let surveyed = WallMap { seen_free: Some(seen), ..m };
        assert_eq!(parse(&surveyed.to_json("x")).unwrap(), surveyed);
    }

    #[test]
    fn bad_maps_name_the_file_and_the_element() {
        let cases = [
            (r#"{"walls": [[0,0,1,0], [1,0,1]]}"#, "m.json: walls[1]: expected four numbers"),
            (r#"{"walls": [[0,0,1,0], [1,0,"a",1]]}"#, "m.json: walls[1]"),
            (r#"{"walls": [[0,0,0,0]]}"#, "m.json: walls[0]: wall is shorter"),
            (r#"{"walls": []}"#, "m.json: \"walls\" is empty"),
            (
                r#"{"walls": [[0,0,5,0],[5,0,5,4],[5,4,0,4],[9000,20000,9001,20000]]}"#,
                "m.json: the walls span 9001 x 20000 m, more than the 10000 m an indoor map may span: are the \
                 coordinates in millimetres, or is a wall astray (walls[3] reaches",
            ),
            (r#"{"walls": [[0,0,1e300,0]]}"#, "m.json: the walls span"),
            (r#"{"wall": []}"#, "m.json: no \"walls\""),
            (r#"{"walls": 3}"#, "m.json: \"walls\" is not a list"),
            (r#"{"sigma": -1, "walls": [[0,0,1,0]]}"#, "m.json: \"sigma\" must be"),
            (
                r#"{"seen_free": {"origin": [0, 0], "cell": 0.5, "cols": 2, "rows": 2, "runs": [1, 2]}, "walls": [[0,0,1,0]]}"#,
                "m.json: \"seen_free\": the runs cover 3 of the 4 cells",
            ),
            ("{\"walls\": [\n[0,0,1,0],\n]}", "m.json: not valid JSON at line 3"),
        ];
        for (text, want) in cases {
            let err = parse(text).unwrap_err().to_string();
            assert!(err.starts_with(want), "{err:?} does not start with {want:?}");
        }
        let missing = WallMap::load(Path::new("/nonexistent/map.json")).unwrap_err().to_string();
        assert!(missing.starts_with("/nonexistent/map.json: cannot read"));
    }
}
