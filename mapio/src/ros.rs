//! ROS map_server maps: a YAML file that names a PGM image of an occupancy grid, the maps
//! AMCL, gmapping, Cartographer and slam_toolbox users already have.
//!
//! [`OccupancyGrid::load`] reads one as map_server does (`resolution`, `origin` of the
//! lower-left pixel, `negate`, `occupied_thresh`, `free_thresh`, `mode`), and
//! [`OccupancyGrid::to_wall_map`] turns it into a wall map: the faces of the occupied cells
//! ([`crate::trace`]) are the walls, the free cells are where the robot may be
//! ([`SeenFree`]), and the map's accuracy is stated as half a cell unless told otherwise.
//! [`OccupancyGrid::from_walls`] and [`OccupancyGrid::save`] go the other way, so a plan can
//! be given to AMCL as the same map.
//!
//! The image is PGM or PNG ([`crate::image`]).

pub use crate::image::Pgm;
use crate::image::{self, Channels, ImageError};
use crate::trace::{Raster, TraceConfig};
use map::bitgrid::Grid;
use map::SeenFree;
use map::{Wall, WallMap, MIN_WALL_LENGTH};
use nalgebra::{Point2, Vector2};
use std::path::{Path, PathBuf};
use thiserror::Error;

/// Most cells a grid may have.
pub const MAX_CELLS: usize = map::limits::GRID_FILE_CELLS;

/// Traced walls shorter than this many cells are a surface the grid draws jagged or broken
/// ([`roughness`]).
pub const ROUGH_WALL_CELLS: f64 = 10.0;

/// A grid whose traced walls shorter than [`ROUGH_WALL_CELLS`] hold more than this share of
/// their length is rough. Measured at 5 cm: plans drawn into grids (`gema2 map export-ros` of
/// the bundled and generated plans, thick walls too) 0.00-0.02; grids of real buildings (the
/// CARMEN logs' `map build --grid`, and their built maps drawn into grids) 0.21-0.88.
pub const ROUGH_SHARE: f64 = 0.15;

/// The share of the traced walls' length (`[x1, y1, x2, y2]` in cells) in walls shorter than
/// [`ROUGH_WALL_CELLS`]: near 0 where the grid draws long straight surfaces, a fifth or more
/// where a SLAM map's walls come out jagged, speckled and broken
/// ([`OccupancyGrid::to_wall_map_with_roughness`]).
/// 0 with no walls.
pub fn roughness(traced: &[[f64; 4]]) -> f64 {
    let lengths = traced.iter().map(|w| (w[2] - w[0]).hypot(w[3] - w[1]));
    let (short, total) =
        lengths.fold((0.0, 0.0), |(short, total), l| (if l < ROUGH_WALL_CELLS { short + l } else { short }, total + l));
    if total > 0.0 {
        short / total
    } else {
        0.0
    }
}

/// Why a ROS map was rejected.
#[derive(Debug, Error)]
pub enum RosMapError {
    // the cause is in the message, not chained too: it would print twice ("Caused by")
    #[error("{path}: cannot read: {cause}")]
    Io { path: PathBuf, cause: std::io::Error },
    #[error("{path}: line {line}: {message}")]
    Yaml { path: PathBuf, line: usize, message: String },
    #[error("{path}: {message}")]
    Meta { path: PathBuf, message: String },
    #[error("{path}: {message}")]
    Image { path: PathBuf, message: String },
}

impl From<ImageError> for RosMapError {
    fn from(e: ImageError) -> Self {
        RosMapError::Image { path: e.path, message: e.message }
    }
}

/// Why a grid gives no wall map, or a wall map no grid.
#[derive(Debug, Error, PartialEq)]
pub enum GridError {
    #[error("no occupied cells outline a wall: is the image negated (negate: 1), or are the thresholds off?")]
    NoWalls,
    #[error("resolution {resolution} and thickness {thickness}: a positive and a non-negative number of metres")]
    Drawing { resolution: f64, thickness: f64 },
    #[error("{width} x {height} cells of {resolution} m: at most {MAX_CELLS} are written")]
    TooLarge { width: usize, height: usize, resolution: f64 },
}

pub use crate::trace::Cell;

/// How image values become occupancy (map_server's `mode`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mode {
    /// Darker is more occupied (or lighter, with `negate`); above `occupied_thresh` occupied,
    /// below `free_thresh` free, unknown between.
    Trinary,
    /// As trinary for walls and free space (the values between are kept as unknown here).
    Scale,
    /// The value is the occupancy in percent; anything above 100 is unknown.
    Raw,
}

/// The YAML file's fields.
#[derive(Clone, Debug, PartialEq)]
pub struct MapMeta {
    /// The image, relative to the YAML file's folder unless absolute.
    pub image: PathBuf,
    /// Metres a cell.
    pub resolution: f64,
    /// Pose (x, y, yaw) of the image's lower-left corner in the map frame.
    pub origin: [f64; 3],
    pub negate: bool,
    pub occupied_thresh: f64,
    pub free_thresh: f64,
    pub mode: Mode,
}

/// An occupancy grid: `width` x `height` cells, row 0 at the bottom (the image's last row).
#[derive(Clone, Debug, PartialEq)]
pub struct OccupancyGrid {
    pub resolution: f64,
    pub origin: [f64; 3],
    pub width: usize,
    pub height: usize,
    pub cells: Vec<Cell>,
}

impl MapMeta {
    /// Parses the YAML text of a map_server map; `path` names it in errors.
    pub fn parse(text: &str, path: &Path) -> Result<Self, RosMapError> {
        let mut fields = MetaFields::default();
        let entries =
            yaml_entries(text).map_err(|(line, message)| RosMapError::Yaml { path: path.to_owned(), line, message })?;
        for (line, key, value) in entries {
            let err = |message: String| RosMapError::Yaml { path: path.to_owned(), line, message };
            fields.take(&key, unquote(&value)).map_err(err)?;
        }
        fields.finish(path)
    }

    /// The image's path, relative to the folder of the YAML file at `yaml` unless absolute.
    pub fn image_beside(&self, yaml: &Path) -> PathBuf {
        if self.image.is_absolute() {
            self.image.clone()
        } else {
            yaml.parent().unwrap_or(Path::new("")).join(&self.image)
        }
    }

    /// How a colour image's channels become one value under this `mode`.
    pub fn channels(&self) -> Channels {
        match self.mode {
            Mode::Trinary => Channels::WithAlpha,
            Mode::Scale => Channels::ColourOnly,
            Mode::Raw => Channels::ColourTruncated,
        }
    }

    /// What a pixel of value `v` (of `maxval`) says, as map_server reads it.
    pub fn classify(&self, v: u16, maxval: u16) -> Cell {
        if self.mode == Mode::Raw {
            return match v {
                _ if v > 100 => Cell::Unknown,
                _ if f64::from(v) / 100.0 > self.occupied_thresh => Cell::Occupied,
                _ if f64::from(v) / 100.0 < self.free_thresh => Cell::Free,
                _ => Cell::Unknown,
            };
        }
        let shade = f64::from(v) / f64::from(maxval.max(1));
        let occupancy = if self.negate { shade } else { 1.0 - shade };
        if occupancy > self.occupied_thresh {
            Cell::Occupied
        } else if occupancy < self.free_thresh {
            Cell::Free
        } else {
            Cell::Unknown
        }
    }
}

/// The keys of a map_server YAML read so far; [`MetaFields::finish`] makes the [`MapMeta`].
#[derive(Default)]
struct MetaFields {
    image: Option<PathBuf>,
    resolution: Option<f64>,
    origin: Option<[f64; 3]>,
    negate: Option<bool>,
    occupied_thresh: Option<f64>,
    free_thresh: Option<f64>,
    mode: Option<Mode>,
}

impl MetaFields {
    /// Takes one `key: value` line; the error says what is wrong with the value.
    fn take(&mut self, key: &str, value: &str) -> Result<(), String> {
        let number = |what: &str| -> Result<f64, String> {
            value
                .parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| format!("{what} must be a number, found {value:?}"))
        };
        match key {
            "image" if value.is_empty() => return Err("image names no file".into()),
            "image" => self.image = Some(PathBuf::from(value)),
            "resolution" => {
                let r = number("resolution")?;
                if r <= 0.0 {
                    return Err(format!("resolution must be a positive number of metres, found {r}"));
                }
                self.resolution = Some(r);
            }
            "origin" => {
                let origin = parse_origin(value);
                self.origin =
                    Some(origin.ok_or_else(|| format!("origin must be [x, y, yaw], three numbers, found {value:?}"))?);
            }
            "negate" => {
                self.negate = Some(match value {
                    "0" | "false" | "False" => false,
                    "1" | "true" | "True" => true,
                    _ => return Err(format!("negate must be 0 or 1, found {value:?}")),
                })
            }
            "occupied_thresh" | "free_thresh" => {
                let t = number(key)?;
                if !(0.0..=1.0).contains(&t) {
                    return Err(format!("{key} must lie in [0, 1], found {t}"));
                }
                if key == "free_thresh" {
                    self.free_thresh = Some(t);
                } else {
                    self.occupied_thresh = Some(t);
                }
            }
            "mode" => {
                self.mode = Some(match value {
                    "trinary" => Mode::Trinary,
                    "scale" => Mode::Scale,
                    "raw" => Mode::Raw,
                    _ => return Err(format!("mode must be trinary, scale or raw, found {value:?}")),
                })
            }
            // other keys (a map's name, slam_toolbox's extras) say nothing about the grid
            _ => {}
        }
        Ok(())
    }

    /// The map's description: `image`, `resolution` and `origin` must have been given; the
    /// rest default as map_server's do.
    fn finish(self, path: &Path) -> Result<MapMeta, RosMapError> {
        let meta_err = |message: String| RosMapError::Meta { path: path.to_owned(), message };
        let missing = |key: &str| meta_err(format!("no `{key}:`"));
        let meta = MapMeta {
            image: self.image.ok_or_else(|| missing("image"))?,
            resolution: self.resolution.ok_or_else(|| missing("resolution"))?,
            origin: self.origin.ok_or_else(|| missing("origin"))?,
            negate: self.negate.unwrap_or(false),
            occupied_thresh: self.occupied_thresh.unwrap_or(0.65),
            free_thresh: self.free_thresh.unwrap_or(0.196),
            mode: self.mode.unwrap_or(Mode::Trinary),
        };
        if meta.free_thresh > meta.occupied_thresh {
            return Err(meta_err(format!(
                "free_thresh {} is above occupied_thresh {}: no value could be free",
                meta.free_thresh, meta.occupied_thresh
            )));
        }
        Ok(meta)
    }
}

/// `[x, y, yaw]`: exactly three finite numbers in brackets.
fn parse_origin(value: &str) -> Option<[f64; 3]> {
    let inner = value.strip_prefix('[')?.strip_suffix(']')?;
    let parts: Vec<&str> = inner.split(',').collect();
    let [x, y, yaw] = parts.as_slice() else { return None };
    let num = |t: &str| t.trim().parse::<f64>().ok().filter(|v| v.is_finite());
    Some([num(x)?, num(y)?, num(yaw)?])
}

/// `line` without a `#` comment (a `#` at the start or after a space, outside quotes).
/// A `key: value` of a YAML file and the line its key is on.
type YamlEntry = (usize, String, String);

/// The `key: value` entries of a map_server YAML file, with the line each key is on, in the
/// layouts tools write: a key a line (`map_saver`), a list as `[a, b, c]` (also across lines)
/// or as a block of `- item` lines under its key (PyYAML's default), or the whole map in
/// braces (`{image: m.pgm, resolution: 0.05, ...}`). A list's value is given as `[a, b, c]`.
/// Errors carry their line.
fn yaml_entries(text: &str) -> Result<Vec<YamlEntry>, (usize, String)> {
    let lines: Vec<(usize, &str)> = text
        .lines()
        .enumerate()
        .map(|(k, raw)| (k + 1, strip_comment(raw).trim()))
        .filter(|(_, l)| !l.is_empty() && *l != "---" && *l != "...")
        .collect();
    let mut entries = Vec::new();
    if let Some(&(first, l)) = lines.first().filter(|(_, l)| l.starts_with('{')) {
        // one flow mapping, perhaps over several lines
        let whole: Vec<&str> = lines.iter().map(|(_, l)| *l).collect();
        let whole = whole.join(" ");
        let inner = whole
            .strip_prefix('{')
            .and_then(|w| w.strip_suffix('}'))
            .ok_or((first, format!("a mapping in braces that does not close, from {l:?}")))?;
        for item in split_top_level(inner).into_iter().filter(|i| !i.trim().is_empty()) {
            let (key, value) = item.split_once(':').ok_or((first, format!("expected `key: value`, found {item:?}")))?;
            entries.push((first, key.trim().to_owned(), value.trim().to_owned()));
        }
        return Ok(entries);
    }
    let mut k = 0;
    while let Some(&(line, content)) = lines.get(k) {
        k += 1;
        if content.starts_with("- ") || content == "-" {
            return Err((line, format!("a list item {content:?} under no key")));
        }
        let Some((key, value)) = content.split_once(':') else {
            return Err((line, format!("expected `key: value`, found {content:?}")));
        };
        let mut value = value.trim().to_owned();
        if value.is_empty() {
            // a block list: the `- item` lines that follow
            let mut items = Vec::new();
            while let Some(item) = lines.get(k).and_then(|(_, l)| l.strip_prefix("- ").or((*l == "-").then_some(""))) {
                items.push(item.trim().to_owned());
                k += 1;
            }
            if !items.is_empty() {
                value = format!("[{}]", items.join(", "));
            }
        } else if value.starts_with('[') && !value.contains(']') {
            // a flow list over several lines
            while let Some(&(_, more)) = lines.get(k) {
                k += 1;
                value.push(' ');
                value.push_str(more);
                if more.contains(']') {
                    break;
                }
            }
        }
        entries.push((line, key.trim().to_owned(), value));
    }
    Ok(entries)
}

/// `text` split at its commas outside brackets and quotes.
fn split_top_level(text: &str) -> Vec<&str> {
    let (mut parts, mut depth, mut quote, mut start) = (Vec::new(), 0i32, None, 0);
    for (k, ch) in text.char_indices() {
        match (quote, ch) {
            (None, '"' | '\'') => quote = Some(ch),
            (Some(q), c) if c == q => quote = None,
            (None, '[' | '{') => depth += 1,
            (None, ']' | '}') => depth -= 1,
            (None, ',') if depth == 0 => {
                parts.push(&text[start..k]);
                start = k + 1;
            }
            _ => {}
        }
    }
    parts.push(&text[start..]);
    parts
}

fn strip_comment(line: &str) -> &str {
    let mut quote = None;
    let mut previous = ' ';
    for (k, ch) in line.char_indices() {
        match (quote, ch) {
            (None, '"' | '\'') => quote = Some(ch),
            (Some(q), c) if c == q => quote = None,
            (None, '#') if previous.is_whitespace() => return &line[..k],
            _ => {}
        }
        previous = ch;
    }
    line
}

fn unquote(v: &str) -> &str {
    for q in ['"', '\''] {
        if let Some(inner) = v.strip_prefix(q).and_then(|v| v.strip_suffix(q)) {
            return inner;
        }
    }
    v
}

/// Shades written for each cell: map_server's own (black walls, white free, grey unknown).
const OCCUPIED_SHADE: u16 = 0;
const FREE_SHADE: u16 = 254;
const UNKNOWN_SHADE: u16 = 205;

impl OccupancyGrid {
    /// Reads a map_server YAML file and the image it names.
    pub fn load(yaml: &Path) -> Result<Self, RosMapError> {
        let text = std::fs::read_to_string(yaml).map_err(|cause| RosMapError::Io { path: yaml.to_owned(), cause })?;
        let meta = MapMeta::parse(&text, yaml)?;
        let image = meta.image_beside(yaml);
        let bytes = std::fs::read(&image).map_err(|cause| RosMapError::Io { path: image.clone(), cause })?;
        let pgm = image::read(&bytes, &image, meta.channels())?;
        Self::from_image(&meta, &pgm).ok_or_else(|| RosMapError::Image {
            path: image,
            message: "the image's values do not fill its width and height".into(),
        })
    }

    /// The grid an image shows under `meta`; `None` when the image's values do not fill its
    /// width and height.
    pub fn from_image(meta: &MapMeta, pgm: &Pgm) -> Option<Self> {
        let (width, height) = (pgm.width, pgm.height);
        if width.checked_mul(height) != Some(pgm.values.len()) {
            return None;
        }
        let mut cells = Vec::with_capacity(width * height);
        // the image's top row is the grid's last
        for r in 0..height {
            let row = &pgm.values[(height - 1 - r) * width..(height - r) * width];
            cells.extend(row.iter().map(|&v| meta.classify(v, pgm.maxval)));
        }
        Some(OccupancyGrid { resolution: meta.resolution, origin: meta.origin, width, height, cells })
    }

    /// The grid a ROS `nav_msgs/OccupancyGrid` carries (`values` row-major from cell (0, 0), -1
    /// unknown or 0-100 percent), read with map_server's thresholds: occupied above 65 %, free
    /// below 19.6 %. `None` when the values do not fill `width` x `height` or the resolution
    /// or origin is not a number.
    pub fn from_occupancy(
        resolution: f64,
        origin: [f64; 3],
        width: usize,
        height: usize,
        values: &[i8],
    ) -> Option<Self> {
        let usable = resolution.is_finite() && resolution > 0.0 && origin.iter().all(|v| v.is_finite());
        if !usable || width.checked_mul(height) != Some(values.len()) {
            return None;
        }
        let cells = values
            .iter()
            .map(|&v| match v {
                v if !(0..=100).contains(&v) => Cell::Unknown,
                v if f64::from(v) / 100.0 > 0.65 => Cell::Occupied,
                v if f64::from(v) / 100.0 < 0.196 => Cell::Free,
                _ => Cell::Unknown,
            })
            .collect();
        Some(OccupancyGrid { resolution, origin, width, height, cells })
    }

    /// Where lattice point (i, j) (a cell corner, in cells) lies in the map frame.
    pub(crate) fn corner(&self, i: f64, j: f64) -> Point2<f64> {
        let (s, c) = self.origin[2].sin_cos();
        let (x, y) = (i * self.resolution, j * self.resolution);
        Point2::new(self.origin[0] + c * x - s * y, self.origin[1] + s * x + c * y)
    }

    /// Where a point of the map frame lies on the grid, in cells from its origin: the inverse
    /// of [`corner`](Self::corner).
    pub(crate) fn in_cells(&self, p: Point2<f64>) -> Point2<f64> {
        let (s, c) = self.origin[2].sin_cos();
        let (x, y) = (p.x - self.origin[0], p.y - self.origin[1]);
        Point2::new((c * x + s * y) / self.resolution, (-s * x + c * y) / self.resolution)
    }

    /// The grid's cells as a [`Raster`].
    pub(crate) fn raster(&self) -> Raster<'_> {
        Raster { width: self.width, height: self.height, cells: &self.cells }
    }

    /// The wall map of the grid: the occupied cells' faces as walls, simplified to within
    /// `trace.tolerance` cells; the free cells as the free space seen (no answer is given
    /// farther from them than the localizer's slack); accuracy `sigma` metres (half a cell when
    /// `None`: how far a surface may lie from where its face is drawn; a SLAM map's walls are
    /// often worse, and should say so: [`roughness`] tells such a grid).
    pub fn to_wall_map(&self, trace: &TraceConfig, sigma: Option<f64>) -> Result<WallMap, GridError> {
        self.to_wall_map_with_roughness(trace, sigma).map(|(map, _)| map)
    }

    /// [`to_wall_map`](Self::to_wall_map), and how rough the grid's surfaces are
    /// ([`roughness`] of the walls traced), from one tracing.
    pub fn to_wall_map_with_roughness(
        &self,
        trace: &TraceConfig,
        sigma: Option<f64>,
    ) -> Result<(WallMap, f64), GridError> {
        let traced = crate::trace::walls(&self.raster(), trace);
        let rough = roughness(&traced);
        let walls: Vec<Wall> = traced
            .into_iter()
            .map(|w| {
                let (a, b) = (self.corner(w[0], w[1]), self.corner(w[2], w[3]));
                Wall::new(a.x, a.y, b.x, b.y)
            })
            // a face shorter than a quarter cell is where two refitted lines meet, not a wall
            .filter(|w| w.length() >= MIN_WALL_LENGTH.max(0.25 * self.resolution))
            .collect();
        if walls.is_empty() {
            return Err(GridError::NoWalls);
        }
        let seen_free = self.free_space();
        Ok((WallMap { walls: walls.into(), sigma: sigma.unwrap_or(self.resolution / 2.0), seen_free }, rough))
    }

    /// The grid's free cells as the free space seen, on a raster of its own cells (coarser when
    /// that would be too large); `None` when even the coarsest would be.
    pub fn free_space(&self) -> Option<SeenFree> {
        let corners =
            [(0.0, 0.0), (self.width as f64, 0.0), (0.0, self.height as f64), (self.width as f64, self.height as f64)]
                .map(|(i, j)| self.corner(i, j));
        let lo = corners.iter().fold(Point2::new(f64::INFINITY, f64::INFINITY), |m, p| m.inf(p));
        let hi = corners.iter().fold(Point2::new(f64::NEG_INFINITY, f64::NEG_INFINITY), |m, p| m.sup(p));
        // the raster at the grid's own cells (coarser when it would be too large)
        let mut cell = self.resolution;
        let seen_free = loop {
            match SeenFree::covering(lo, hi, cell) {
                Some(s) => break Some(s),
                None if cell < 1.0e3 => cell *= 2.0,
                None => break None,
            }
        };
        seen_free.map(|mut seen| {
            for (k, _) in self.cells.iter().enumerate().filter(|(_, &c)| c == Cell::Free) {
                let q = self.corner((k % self.width) as f64 + 0.5, (k / self.width) as f64 + 0.5);
                seen.mark_ray(q, q);
            }
            seen
        })
    }

    /// A grid of `resolution` metres drawing `map`: a cell is occupied when a wall passes
    /// through it or within `thickness / 2` of its centre; free when it lies inside the
    /// building (a 4-connected region of cells at least a twentieth the size of the largest,
    /// not the one around a closed building) and, when the map says where its survey saw free
    /// space, there; unknown elsewhere.
    pub fn from_walls(map: &WallMap, resolution: f64, thickness: f64) -> Result<Self, GridError> {
        if !(resolution.is_finite() && resolution > 0.0 && thickness.is_finite() && thickness >= 0.0) {
            return Err(GridError::Drawing { resolution, thickness });
        }
        let (lo, hi) = map.bounds();
        let margin = 2.0 * resolution + thickness;
        let origin = lo - Vector2::new(margin, margin);
        let width = ((hi.x - lo.x + 2.0 * margin) / resolution).ceil() as usize;
        let height = ((hi.y - lo.y + 2.0 * margin) / resolution).ceil() as usize;
        if width.checked_mul(height).is_none_or(|n| n > MAX_CELLS) {
            return Err(GridError::TooLarge { width, height, resolution });
        }
        let mut occupied = vec![false; width * height];
        let grid = Grid { origin, cell: resolution, cols: width, rows: height };
        let half = thickness / 2.0;
        for w in &map.walls {
            // the cells the wall crosses, at quarter-cell steps
            let steps = (w.length() / (0.25 * resolution)).ceil().max(1.0) as usize;
            for k in 0..=steps {
                if let Some(i) = grid.index(w.a + (w.b - w.a) * (k as f64 / steps as f64)) {
                    occupied[i] = true;
                }
            }
            // and those whose centre lies within half the thickness
            let (wl, wh) = (w.a.inf(&w.b) - Vector2::new(half, half), w.a.sup(&w.b) + Vector2::new(half, half));
            let c0 = ((wl.x - origin.x) / resolution).floor().max(0.0) as usize;
            let r0 = ((wl.y - origin.y) / resolution).floor().max(0.0) as usize;
            let c1 = (((wh.x - origin.x) / resolution).ceil() as usize).min(width);
            let r1 = (((wh.y - origin.y) / resolution).ceil() as usize).min(height);
            for r in r0..r1 {
                for c in c0..c1 {
                    if w.closest(grid.centre(c, r)).0 <= half {
                        occupied[r * width + c] = true;
                    }
                }
            }
        }
        let inside = inside_space(&occupied, width, height);
        let cells = (0..width * height)
            .map(|i| {
                if occupied[i] {
                    Cell::Occupied
                } else if !inside[i]
                    || map.seen_free.as_ref().is_some_and(|s| !s.contains(grid.centre(i % width, i / width)))
                {
                    Cell::Unknown
                } else {
                    Cell::Free
                }
            })
            .collect();
        Ok(OccupancyGrid { resolution, origin: [origin.x, origin.y, 0.0], width, height, cells })
    }

    /// The image of the grid, map_server's shades (top row first).
    pub fn to_pgm(&self) -> Pgm {
        let mut values = Vec::with_capacity(self.cells.len());
        for r in (0..self.height).rev() {
            values.extend(self.cells[r * self.width..(r + 1) * self.width].iter().map(|c| match c {
                Cell::Occupied => OCCUPIED_SHADE,
                Cell::Free => FREE_SHADE,
                Cell::Unknown => UNKNOWN_SHADE,
            }));
        }
        Pgm { width: self.width, height: self.height, maxval: 255, values }
    }

    /// Writes the grid as `yaml` and the PGM beside it (same name, `.pgm`).
    pub fn save(&self, yaml: &Path) -> Result<(), RosMapError> {
        let image = yaml.with_extension("pgm");
        let name = image.file_name().map_or("map.pgm".into(), |n| n.to_string_lossy().into_owned());
        std::fs::write(&image, self.to_pgm().to_bytes())
            .map_err(|cause| RosMapError::Io { path: image.clone(), cause })?;
        let text = format!(
            "image: {name}\nresolution: {}\norigin: [{}, {}, {}]\nnegate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\nmode: trinary\n",
            self.resolution, self.origin[0], self.origin[1], self.origin[2]
        );
        std::fs::write(yaml, text).map_err(|cause| RosMapError::Io { path: yaml.to_owned(), cause })
    }
}

/// The occupancy grid a survey makes, as a grid-mapping SLAM does at known poses: each beam
/// adds evidence that its end cell is occupied and that the cells it crossed are free, in log
/// odds. What `gema2 map build --grid` writes for AMCL, and a grid of real scans to test
/// [`OccupancyGrid::to_wall_map`] on. Not [`crate::occupancy::Occupancy`], which counts scans
/// (not beams) per cell, short of each hit by a clearance, to tell what stayed from what moved
/// while a map is built; both walk the same [`map::bitgrid::Grid`].
#[derive(Clone, Debug)]
pub struct SurveyGrid {
    grid: Grid,
    log_odds: Vec<f32>,
}

/// Log odds a beam's end adds to its cell, and a crossed cell loses (gmapping's and
/// slam_toolbox's usual 0.9 and 0.4, as probabilities about 0.71 and 0.40).
const HIT_LOG_ODDS: f32 = 0.9;
const PASS_LOG_ODDS: f32 = 0.4;
/// A cell is occupied above this log odds, free below minus it, unknown between.
const DECIDED_LOG_ODDS: f32 = 0.5;

impl SurveyGrid {
    /// A grid of `cell` metres covering `lo`..`hi`, nothing seen; `None` when the cell is not
    /// positive and finite or the grid would exceed [`MAX_CELLS`].
    pub fn covering(lo: Point2<f64>, hi: Point2<f64>, cell: f64) -> Option<Self> {
        if !(cell.is_finite() && cell > 0.0 && lo.x <= hi.x && lo.y <= hi.y) {
            return None;
        }
        let (w, h) = (((hi.x - lo.x) / cell).ceil().max(1.0), ((hi.y - lo.y) / cell).ceil().max(1.0));
        // finite: the bounds were compared above, which NaN fails
        if w * h > MAX_CELLS as f64 {
            return None;
        }
        let grid = Grid { origin: lo, cell, cols: w as usize, rows: h as usize };
        Some(SurveyGrid { grid, log_odds: vec![0.0; grid.cells()] })
    }

    /// A beam from `sensor` whose end lies at `end`: the cells it crosses before its end's
    /// cell lose evidence, and that cell gains it when `hit` (a return; a beam that ran out of
    /// range only crossed).
    pub fn add_beam(&mut self, sensor: Point2<f64>, end: Point2<f64>, hit: bool) {
        let last = self.grid.index(end);
        let mut previous = None;
        for i in self.grid.points_along(sensor, end).map(|q| self.grid.index(q)) {
            if let Some(j) = i.filter(|_| i != previous && i != last) {
                self.log_odds[j] -= PASS_LOG_ODDS;
            }
            previous = i;
        }
        if let (true, Some(i)) = (hit, last) {
            self.log_odds[i] += HIT_LOG_ODDS;
        }
    }

    /// The grid as map_server would load it.
    pub fn to_occupancy_grid(&self) -> OccupancyGrid {
        let cells = self
            .log_odds
            .iter()
            .map(|&l| match l {
                _ if l > DECIDED_LOG_ODDS => Cell::Occupied,
                _ if l < -DECIDED_LOG_ODDS => Cell::Free,
                _ => Cell::Unknown,
            })
            .collect();
        let g = &self.grid;
        OccupancyGrid {
            resolution: g.cell,
            origin: [g.origin.x, g.origin.y, 0.0],
            width: g.cols,
            height: g.rows,
            cells,
        }
    }
}

/// Which cells that are not `occupied` a robot can be in: the 4-connected regions of them at
/// least a twentieth the size of the largest, leaving out the region around a closed building
/// (it touches the raster's border) unless the building is open (that region is then the
/// largest). The inside of a wall drawn as two faces, of a rack or a pillar, is too small.
fn inside_space(occupied: &[bool], width: usize, height: usize) -> Vec<bool> {
    let free: Vec<bool> = occupied.iter().map(|&o| !o).collect();
    let (labels, sizes) = map::free_space::connected_regions(&free, width, height);
    let mut touches_border = vec![false; sizes.len()];
    for (i, &l) in labels.iter().enumerate() {
        let (c, r) = (i % width, i / width);
        if c == 0 || r == 0 || c + 1 == width || r + 1 == height {
            touches_border[l as usize] = true;
        }
    }
    // the largest region that touches the border (`true`) or does not
    let largest =
        |border: bool| (1..sizes.len()).filter(|&l| touches_border[l] == border).map(|l| sizes[l]).max().unwrap_or(0);
    let open = largest(true) > largest(false);
    let least = largest(open).max(largest(false)) / 20;
    let kept: Vec<bool> =
        (0..sizes.len()).map(|l| l != 0 && (open || !touches_border[l]) && sizes[l] >= least.max(1)).collect();
    labels.iter().map(|&l| kept[l as usize]).collect()
}

/// The files a map_server map is read from: the YAML file and, when it parses, the image it
/// names (what a map server watches for changes).
pub fn files_of(yaml: &Path) -> Vec<PathBuf> {
    let mut files = vec![yaml.to_owned()];
    let meta = std::fs::read_to_string(yaml).ok().and_then(|text| MapMeta::parse(&text, yaml).ok());
    files.extend(meta.map(|m| m.image_beside(yaml)));
    files
}

/// Whether `path` names a map_server YAML file.
pub fn is_ros_map(path: &Path) -> bool {
    path.extension().is_some_and(|e| e.eq_ignore_ascii_case("yaml") || e.eq_ignore_ascii_case("yml"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_ros_occupancy_grid_reads_with_map_servers_thresholds() {
        let g = OccupancyGrid::from_occupancy(0.05, [1.0, 2.0, 0.0], 3, 2, &[-1, 0, 100, 66, 65, 19]).unwrap();
        use Cell::*;
        assert_eq!(g.cells, vec![Unknown, Free, Occupied, Occupied, Unknown, Free]);
        assert!(OccupancyGrid::from_occupancy(0.05, [0.0; 3], 3, 3, &[0; 6]).is_none(), "too few values");
        assert!(OccupancyGrid::from_occupancy(f64::NAN, [0.0; 3], 1, 1, &[0]).is_none());
    }
    use proptest::prelude::*;

    fn meta(text: &str) -> Result<MapMeta, RosMapError> {
        MapMeta::parse(text, Path::new("m.yaml"))
    }

    #[test]
    fn a_map_server_yaml_file_is_read_with_its_defaults() {
        let m = meta(
            "# a map\nimage: 'floor #2.pgm'  # the image\nresolution: 0.05\norigin: [-10.0, -5.5, 0.0]\nnegate: 0\n\
                      occupied_thresh: 0.65\nfree_thresh: 0.196\nname: x\n",
        )
        .unwrap();
        assert_eq!(m.image, PathBuf::from("floor #2.pgm"));
        assert_eq!((m.resolution, m.origin, m.negate, m.mode), (0.05, [-10.0, -5.5, 0.0], false, Mode::Trinary));
        let m = meta("image: a.pgm\nresolution: 0.1\norigin: [0, 0, 0]\nmode: raw\nnegate: 1").unwrap();
        assert_eq!((m.mode, m.negate, m.free_thresh), (Mode::Raw, true, 0.196));
    }

    #[test]
    fn a_bad_yaml_file_is_refused_naming_the_line() {
        for (text, says) in [
            ("image: a.pgm\nresolution: fine\norigin: [0, 0, 0]", "m.yaml: line 2: resolution must be a number"),
            ("image: a.pgm\nresolution: 0.05\norigin: [0, 0]", "m.yaml: line 3: origin must be [x, y, yaw]"),
            ("image: a.pgm\nresolution: -1\norigin: [0, 0, 0]", "line 2: resolution must be a positive"),
            ("image: a.pgm\nresolution: 0.05\norigin: [0, 0, nan]", "line 3: origin"),
            ("image: a.pgm\nthis is not yaml\n", "m.yaml: line 2: expected `key: value`"),
            ("resolution: 0.05\norigin: [0, 0, 0]", "m.yaml: no `image:`"),
            ("image: a.pgm\norigin: [0, 0, 0]", "no `resolution:`"),
            ("image: a.pgm\nresolution: 0.05\norigin: [0,0,0]\nfree_thresh: 0.9", "free_thresh 0.9 is above"),
            ("image: a.pgm\nresolution: 0.05\norigin: [0,0,0]\nnegate: maybe", "line 4: negate must be 0 or 1"),
            ("image: a.pgm\nresolution: 0.05\norigin: [0,0,0]\nmode: fancy", "line 4: mode must be"),
            // the layouts other tools write, broken
            ("image: a.pgm\n- 1\n", "line 2: a list item"),
            ("{image: a.pgm, resolution: 0.05", "line 1: a mapping in braces that does not close"),
            ("{image: a.pgm, resolution}", "line 1: expected `key: value`"),
            ("image: a.pgm\nresolution: 0.05\norigin:\n- 1\n- 2\nnegate: 0\n", "line 3: origin must be [x, y, yaw]"),
        ] {
            let e = meta(text).unwrap_err().to_string();
            assert!(e.contains(says), "{text:?}: {e}");
        }
    }

    #[test]
    fn pgm_images_are_read_in_both_encodings_and_bad_ones_refused() {
        let text = b"P2\n# made by hand\n3 2\n255\n0 254 205\n10 20 30\n";
        let p = Pgm::parse(text, Path::new("a.pgm")).unwrap();
        assert_eq!((p.width, p.height, p.maxval), (3, 2, 255));
        assert_eq!(p.values, vec![0, 254, 205, 10, 20, 30]);
        assert_eq!(Pgm::parse(&p.to_bytes(), Path::new("b.pgm")).unwrap(), p);
        let wide = Pgm { width: 2, height: 1, maxval: 1000, values: vec![1000, 3] };
        assert_eq!(Pgm::parse(&wide.to_bytes(), Path::new("c.pgm")).unwrap(), wide);
        for (bytes, says) in [
            (&b"P6\n1 1\n255\n\0\0\0"[..], "a.pgm: neither a PGM (P5, P2) nor a PNG image"),
            (b"P5\n3 2\n255\n\0\0", "stops after 2 of 6 bytes"),
            (b"P2\n2 2\n255\n1 2 3", "has 3 of 4 values"),
            (b"P2\n2 1\n100\n1 200", "pixel 1 has value 200 above maxval 100"),
            (b"P5\n0 2\n255\n", "none of them may be 0"),
            (b"P5\n99999 99999\n255\n", "at most"),
            (b"P5\n4", "the header has no height"),
        ] {
            let e = Pgm::parse(bytes, Path::new("a.pgm")).unwrap_err().to_string();
            assert!(e.contains(says), "{e}");
        }
    }

    #[test]
    fn yaml_files_in_the_layouts_tools_write_read_alike() {
        let expect = meta("image: a.pgm\nresolution: 0.05\norigin: [-1.5, 2, 0.1]\nnegate: 1").unwrap();
        for text in [
            // PyYAML's default: a list as a block of items
            "image: a.pgm\nnegate: 1\norigin:\n- -1.5\n- 2\n- 0.1\nresolution: 0.05\n",
            "image: a.pgm\nresolution: 0.05\norigin:\n  - -1.5   # x\n  - 2\n  - 0.1\nnegate: 1\n",
            // a flow list over lines, and the whole map in braces
            "image: a.pgm\nresolution: 0.05\norigin: [-1.5,\n  2, 0.1]\nnegate: 1\n",
            "{image: a.pgm, resolution: 0.05, origin: [-1.5, 2, 0.1], negate: 1}\n",
            "---\n{image: 'a.pgm',\n resolution: 0.05, origin: [-1.5, 2, 0.1],\n negate: 1}\n...\n",
        ] {
            assert_eq!(meta(text).unwrap(), expect, "{text:?}");
        }
    }

    #[test]
    fn values_become_cells_as_map_server_reads_them() {
        let m = meta("image: a.pgm\nresolution: 0.05\norigin: [0, 0, 0]").unwrap();
        assert_eq!(
            [0, 254, 205, 100].map(|v| m.classify(v, 255)),
            [Cell::Occupied, Cell::Free, Cell::Unknown, Cell::Unknown]
        );
        let negated = MapMeta { negate: true, ..m.clone() };
        assert_eq!([0, 254].map(|v| negated.classify(v, 255)), [Cell::Free, Cell::Occupied]);
        let raw = MapMeta { mode: Mode::Raw, ..m };
        assert_eq!(
            [0, 100, 50, 255].map(|v| raw.classify(v, 255)),
            [Cell::Free, Cell::Occupied, Cell::Unknown, Cell::Unknown]
        );
    }

    #[test]
    fn a_grid_is_read_bottom_row_first_and_placed_by_its_origin() {
        let m = meta("image: a.pgm\nresolution: 0.5\norigin: [10, 20, 0]").unwrap();
        // the top row free, the bottom row occupied
        let pgm = Pgm { width: 2, height: 2, maxval: 255, values: vec![254, 254, 0, 0] };
        let g = OccupancyGrid::from_image(&m, &pgm).unwrap();
        assert!(OccupancyGrid::from_image(&m, &Pgm { width: 3, ..pgm.clone() }).is_none());
        assert_eq!(g.cells, vec![Cell::Occupied, Cell::Occupied, Cell::Free, Cell::Free]);
        assert_eq!(g.corner(2.0, 1.0), Point2::new(11.0, 20.5));
        let turned = OccupancyGrid { origin: [10.0, 20.0, std::f64::consts::FRAC_PI_2], ..g };
        assert!((turned.corner(2.0, 0.0) - Point2::new(10.0, 21.0)).norm() < 1e-12);
    }

    #[test]
    fn a_grid_with_no_walls_is_refused() {
        let g = OccupancyGrid { resolution: 0.1, origin: [0.0; 3], width: 4, height: 4, cells: vec![Cell::Free; 16] };
        assert!(g.to_wall_map(&TraceConfig::default(), None).unwrap_err().to_string().contains("negate"));
    }

    #[test]
    fn a_plan_drawn_as_a_grid_and_traced_back_keeps_its_faces_and_free_space() {
        let room = WallMap::new(Wall::rectangle(0.0, 0.0, 6.0, 4.0).to_vec());
        let grid = OccupancyGrid::from_walls(&room, 0.05, 0.1).unwrap();
        let dir = std::env::temp_dir().join(format!("gema2-ros-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let yaml = dir.join("room.yaml");
        grid.save(&yaml).unwrap();
        // what a map server watches: the YAML file and the image beside it
        assert_eq!(files_of(&yaml), vec![yaml.clone(), dir.join("room.pgm")]);
        assert_eq!(files_of(&dir.join("none.yaml")), vec![dir.join("none.yaml")]);
        let again = OccupancyGrid::load(&yaml).unwrap();
        // the same image as an 8-bit RGB PNG, as an image tool converts it, reads the same
        let pgm = grid.to_pgm();
        let mut png = Vec::new();
        {
            let mut e = png::Encoder::new(&mut png, pgm.width as u32, pgm.height as u32);
            e.set_color(png::ColorType::Rgb);
            let mut w = e.write_header().unwrap();
            let rgb: Vec<u8> = pgm.values.iter().flat_map(|&v| [v as u8; 3]).collect();
            w.write_image_data(&rgb).unwrap();
        }
        std::fs::write(dir.join("room.png"), png).unwrap();
        let text = std::fs::read_to_string(&yaml).unwrap().replace("room.pgm", "room.png");
        std::fs::write(dir.join("png.yaml"), text).unwrap();
        let from_png = OccupancyGrid::load(&dir.join("png.yaml"));
        std::fs::remove_dir_all(&dir).ok();
        assert_eq!(again, grid);
        assert_eq!(from_png.unwrap(), grid);
        let map = again.to_wall_map(&TraceConfig::default(), None).unwrap();
        assert_eq!(map.sigma, 0.025);
        // the inner faces lie a half thickness inside the drawn walls, to within a cell
        let inner = Wall::rectangle(0.05, 0.05, 5.95, 3.95);
        for face in inner {
            let mid = face.a + (face.b - face.a) * 0.5;
            let nearest = map.walls.iter().map(|w| w.closest(mid).0).fold(f64::INFINITY, f64::min);
            assert!(nearest < 0.05, "no wall near {mid}: {nearest}");
        }
        let seen = map.seen_free.as_ref().unwrap();
        assert!(seen.contains(Point2::new(3.0, 2.0)) && !seen.contains(Point2::new(-0.5, 2.0)));
    }

    /// A room drawn into a grid traces into long walls: smooth. The same room with a blob of
    /// occupied cells every metre or so inside (a SLAM map's clutter and noise) traces into
    /// many short walls: rough.
    #[test]
    fn a_grid_drawn_straight_is_smooth_and_a_cluttered_one_rough() {
        let room = WallMap::new(Wall::rectangle(0.0, 0.0, 12.0, 8.0).to_vec());
        let straight = OccupancyGrid::from_walls(&room, 0.05, 0.1).unwrap();
        let rough_of = |g: &OccupancyGrid| g.to_wall_map_with_roughness(&TraceConfig::default(), None).unwrap().1;
        assert!(rough_of(&straight) < 0.05, "{}", rough_of(&straight));
        // blobs of 3 x 3 cells (smaller ones are traced as noise)
        let mut rough = straight.clone();
        let w = rough.width;
        for r in (20..rough.height - 20).step_by(17) {
            for c in (20..w - 20).step_by(23) {
                for (dr, dc) in (0..3).flat_map(|dr| (0..3).map(move |dc| (dr, dc))) {
                    rough.cells[(r + dr) * w + c + dc] = Cell::Occupied;
                }
            }
        }
        assert!(rough_of(&rough) > ROUGH_SHARE, "{}", rough_of(&rough));
        assert_eq!(roughness(&[]), 0.0);
    }

    #[test]
    fn a_survey_of_a_room_marks_its_walls_occupied_and_its_inside_free() {
        let mut grid = SurveyGrid::covering(Point2::new(-1.0, -1.0), Point2::new(5.0, 4.0), 0.05).unwrap();
        let caster = map::RayCaster::new(&Wall::rectangle(0.0, 0.0, 4.0, 3.0));
        let geometry = laser::ScanGeometry { angle_min: -3.1, angle_increment: 0.01, range_min: 0.02, range_max: 10.0 };
        let mut ranges = Vec::new();
        for &(x, y) in &[(1.0, 1.0), (3.0, 2.0), (2.0, 1.5)] {
            let pose = laser::pose(x, y, 0.0);
            caster.cast(&pose, &geometry, 620, 1, &mut map::RayScratch::default(), &mut ranges);
            for (k, d) in ranges.iter().enumerate() {
                let a = geometry.angle_min + k as f64 * geometry.angle_increment;
                grid.add_beam(Point2::new(x, y), Point2::new(x + d * a.cos(), y + d * a.sin()), true);
            }
        }
        let g = grid.to_occupancy_grid();
        let at = |x: f64, y: f64| g.cells[grid.grid.index(Point2::new(x, y)).unwrap()];
        // each wall's cells: the cell either side of its line holds its hits
        let wall = |a: Point2<f64>, b: Point2<f64>| at(a.x, a.y) == Cell::Occupied || at(b.x, b.y) == Cell::Occupied;
        for (x, y, dx, dy) in
            [(2.0, 0.0, 0.0, 0.01), (0.0, 1.5, 0.01, 0.0), (4.0, 2.0, 0.01, 0.0), (1.0, 3.0, 0.0, 0.01)]
        {
            assert!(wall(Point2::new(x - dx, y - dy), Point2::new(x + dx, y + dy)), "{x} {y}");
        }
        assert_eq!((at(2.0, 2.0), at(0.5, 0.5)), (Cell::Free, Cell::Free));
        assert_eq!(at(-0.5, 1.5), Cell::Unknown);
        // and traced, its walls lie on the room's
        let map = g.to_wall_map(&TraceConfig::default(), None).unwrap();
        let long: Vec<_> = map.walls.iter().filter(|w| w.length() > 2.5).collect();
        assert!(long.len() >= 4, "{:?}", map.walls);
        for w in long {
            let mid = w.a + (w.b - w.a) * 0.5;
            let off = [mid.x.abs(), (mid.x - 4.0).abs(), mid.y.abs(), (mid.y - 3.0).abs()]
                .into_iter()
                .fold(f64::INFINITY, f64::min);
            assert!(off < 0.06, "{w:?}");
        }
        assert!(SurveyGrid::covering(Point2::new(0.0, 0.0), Point2::new(1.0, 1.0), 0.0).is_none());
    }

    proptest! {
        /// Bytes that are no map never panic the readers.
        #[test]
        fn arbitrary_bytes_are_an_error_or_an_image(bytes in proptest::collection::vec(any::<u8>(), 0..64), text in "\\PC{0,80}") {
            let _ = Pgm::parse(&bytes, Path::new("x.pgm"));
            let mut with_header = b"P5\n".to_vec();
            with_header.extend(&bytes);
            let _ = Pgm::parse(&with_header, Path::new("x.pgm"));
            let _ = MapMeta::parse(&text, Path::new("x.yaml"));
        }
    }
}
