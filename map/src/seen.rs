//! Where the survey that built a map saw free space: the cells its beams crossed on their way
//! to the walls they hit. An occupancy grid keeps this as its free cells, and AMCL spreads its
//! particles over those alone; a wall map built from scans loses it unless it is kept beside
//! the walls. The localizer answers with no pose where no beam of the survey has been
//! ([`SeenFree::unseen`]): out there, beyond the building's open outline, every beam away from
//! the walls reads "no return" as the map predicts, and a scan with a wide open side is
//! explained as well as inside.
//!
//! In a map file it is the optional `"seen_free"` key: `{"origin": [x, y], "cell": c, "cols":
//! n, "rows": m, "runs": [r0, r1, ...]}`, the cells row by row from `origin` (the first row's
//! first cell's corner) as run lengths, alternately not seen and seen, starting with not seen.

use crate::bitgrid::{BitGrid, Grid};
use crate::flat::{Flat, FlatError, FlatReader, FlatWriter};
use crate::free_space::Outside;
use nalgebra::Point2;
use serde_json::{json, Value};

/// Most cells a raster may have (a square kilometre at 0.2 m is 25 million).
pub const MAX_CELLS: usize = crate::limits::SEEN_CELLS;

/// Cells seen free, one bit each.
#[derive(Clone, Debug, PartialEq)]
pub struct SeenFree {
    raster: BitGrid,
}

/// Why a `"seen_free"` value is no raster: what is wrong with it, in words.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("seen free space: {0}")]
pub struct SeenError(pub String);

impl From<String> for SeenError {
    fn from(s: String) -> Self {
        SeenError(s)
    }
}

impl From<&str> for SeenError {
    fn from(s: &str) -> Self {
        SeenError(s.to_owned())
    }
}

impl SeenFree {
    /// A raster of `cell`-sized cells covering `lo`..`hi`, nothing seen yet. `None` when the
    /// cell is not a positive finite size or the raster would exceed [`MAX_CELLS`].
    pub fn covering(lo: Point2<f64>, hi: Point2<f64>, cell: f64) -> Option<Self> {
        if !(cell.is_finite() && cell > 0.0 && lo.x <= hi.x && lo.y <= hi.y) {
            return None;
        }
        let cols = ((hi.x - lo.x) / cell).ceil().max(1.0);
        let rows = ((hi.y - lo.y) / cell).ceil().max(1.0);
        // NaN bounds fail this as well
        if cols * rows > MAX_CELLS as f64 || (cols * rows).is_nan() {
            return None;
        }
        Self::empty(lo, cell, cols as usize, rows as usize).ok()
    }

    /// Nothing seen yet, on a grid whose origin is finite, whose cell is positive and finite
    /// and whose cells number 1 to [`MAX_CELLS`]; the error says which does not hold.
    fn empty(origin: Point2<f64>, cell: f64, cols: usize, rows: usize) -> Result<Self, String> {
        if !(origin.x.is_finite() && origin.y.is_finite() && cell.is_finite() && cell > 0.0) {
            return Err(format!("origin {origin} and cell {cell} must be finite, the cell positive"));
        }
        cols.checked_mul(rows)
            .filter(|&n| n > 0 && n <= MAX_CELLS)
            .ok_or(format!("{cols} x {rows} cells: between 1 and {MAX_CELLS} are allowed"))?;
        Ok(SeenFree { raster: BitGrid::clear(Grid { origin, cell, cols, rows }) })
    }

    pub fn origin(&self) -> Point2<f64> {
        self.raster.grid.origin
    }

    pub fn cell(&self) -> f64 {
        self.raster.grid.cell
    }

    /// Columns and rows.
    pub fn size(&self) -> (usize, usize) {
        (self.raster.grid.cols, self.raster.grid.rows)
    }

    /// Whether each cell was seen, row by row from the origin (the order of [`bits`](Self::bits)).
    pub fn cells(&self) -> impl Iterator<Item = bool> + '_ {
        (0..self.raster.grid.cells()).map(|i| self.raster.get(i))
    }

    /// How many cells were seen.
    pub fn seen_cells(&self) -> usize {
        self.raster.bits.iter().map(|w| w.count_ones() as usize).sum()
    }

    /// The raster's bits, row by row, bit i of word i / 64 for cell i.
    pub fn bits(&self) -> &[u64] {
        &self.raster.bits
    }

    /// A raster from its parts, as [`bits`](Self::bits) gives them; `None` when they do not
    /// fit together.
    pub fn from_bits(origin: Point2<f64>, cell: f64, cols: usize, rows: usize, bits: &[u64]) -> Option<Self> {
        let mut seen = Self::empty(origin, cell, cols, rows).ok()?;
        if bits.len() != seen.raster.bits.len() {
            return None;
        }
        seen.raster.bits.to_mut().copy_from_slice(bits);
        seen.raster.clear_padding();
        Some(seen)
    }

    /// Whether a beam of the survey crossed the cell of `q`.
    pub fn contains(&self, q: Point2<f64>) -> bool {
        self.raster.at(q).unwrap_or(false)
    }

    /// Marks the cells a beam from `from` to `to` crosses (sampled every half cell, both ends
    /// included); cells off the raster are skipped.
    pub fn mark_ray(&mut self, from: Point2<f64>, to: Point2<f64>) {
        let grid = self.raster.grid;
        for i in grid.cells_along(from, to) {
            self.raster.set(i);
        }
    }

    /// The raster with every cell within `cells` cells (8-connected) of a seen one seen.
    pub fn dilated(&self, cells: usize) -> SeenFree {
        let (cols, rows) = self.size();
        let mut out = self.clone();
        for _ in 0..cells {
            let before = out.raster.clone();
            for r in 0..rows {
                for c in 0..cols {
                    if before.get(r * cols + c) {
                        continue;
                    }
                    let near = (r.saturating_sub(1)..=(r + 1).min(rows - 1))
                        .any(|rr| (c.saturating_sub(1)..=(c + 1).min(cols - 1)).any(|cc| before.get(rr * cols + cc)));
                    if near {
                        out.raster.set(r * cols + c);
                    }
                }
            }
        }
        out
    }

    /// The raster at twice the cell size, a cell seen when any of its four was: fits a
    /// message of bounded size, and rules out no point the finer one allowed.
    pub fn coarsened(&self) -> SeenFree {
        let (cols, rows) = self.size();
        let grid =
            Grid { origin: self.origin(), cell: 2.0 * self.cell(), cols: cols.div_ceil(2), rows: rows.div_ceil(2) };
        let mut raster = BitGrid::clear(grid);
        for r in 0..rows {
            for c in 0..cols {
                if self.raster.get(r * cols + c) {
                    raster.set((r / 2) * grid.cols + c / 2);
                }
            }
        }
        SeenFree { raster }
    }

    /// Where the robot is not: every point farther than `slack` cells from a seen cell,
    /// including everything off the raster.
    pub fn unseen(&self, slack: usize) -> Outside {
        Outside::from_raster(self.dilated(slack).raster.inverted())
    }

    /// The `"seen_free"` value of a map file.
    pub fn to_json(&self) -> Value {
        let mut runs = Vec::new();
        let (mut current, mut run) = (false, 0u64);
        for i in 0..self.raster.grid.cells() {
            if self.raster.get(i) != current {
                runs.push(run);
                (current, run) = (!current, 0);
            }
            run += 1;
        }
        runs.push(run);
        let (cols, rows) = self.size();
        json!({
            "origin": [self.origin().x, self.origin().y],
            "cell": self.cell(),
            "cols": cols,
            "rows": rows,
            "runs": runs,
        })
    }

    /// Reads a `"seen_free"` value; the error says what is wrong with it.
    pub fn from_json(v: &Value) -> Result<SeenFree, SeenError> {
        let number = |key: &str| v.get(key).and_then(Value::as_f64).ok_or(format!("\"{key}\" must be a number"));
        let count = |key: &str| v.get(key).and_then(Value::as_u64).ok_or(format!("\"{key}\" must be a whole number"));
        let origin = v
            .get("origin")
            .and_then(Value::as_array)
            .filter(|a| a.len() == 2)
            .and_then(|a| Some(Point2::new(a[0].as_f64()?, a[1].as_f64()?)))
            .ok_or("\"origin\" must be [x, y]")?;
        let cell = number("cell")?;
        let (cols, rows) = (count("cols")? as usize, count("rows")? as usize);
        let mut seen = Self::empty(origin, cell, cols, rows)?;
        let runs = v.get("runs").and_then(Value::as_array).ok_or("\"runs\" must be a list of run lengths")?;
        let (mut at, mut seen_run) = (0usize, false);
        for (k, run) in runs.iter().enumerate() {
            let n = run.as_u64().ok_or(format!("run {k} is not a whole number: {run}"))? as usize;
            let end = at
                .checked_add(n)
                .filter(|&e| e <= cols * rows)
                .ok_or(format!("run {k} goes past the {} cells", cols * rows))?;
            if seen_run {
                for i in at..end {
                    seen.raster.set(i);
                }
            }
            (at, seen_run) = (end, !seen_run);
        }
        if at != cols * rows {
            return Err(format!("the runs cover {at} of the {} cells", cols * rows).into());
        }
        Ok(seen)
    }
}

impl Flat for SeenFree {
    fn put(&self, w: &mut FlatWriter) {
        self.raster.put(w);
    }
    fn take(r: &mut FlatReader<'_>) -> Result<Self, FlatError> {
        Ok(SeenFree { raster: BitGrid::take(r)? })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn raster() -> SeenFree {
        let mut s = SeenFree::covering(Point2::new(0.0, 0.0), Point2::new(10.0, 6.0), 0.2).unwrap();
        s.mark_ray(Point2::new(1.0, 1.0), Point2::new(9.0, 1.0));
        s.mark_ray(Point2::new(1.0, 1.0), Point2::new(1.0, 5.0));
        s
    }

    #[test]
    fn a_ray_marks_the_cells_it_crosses_and_no_others() {
        let s = raster();
        // 41 cells along x, 21 along y, one of them shared
        assert_eq!(s.seen_cells(), 61);
        for (x, y) in [(1.0, 1.0), (5.0, 1.05), (8.99, 1.0), (1.05, 4.9)] {
            assert!(s.contains(Point2::new(x, y)), "({x}, {y})");
        }
        for (x, y) in [(5.0, 3.0), (9.5, 1.0), (1.0, 5.5), (-1.0, 1.0), (f64::NAN, 1.0)] {
            assert!(!s.contains(Point2::new(x, y)), "({x}, {y})");
        }
    }

    #[test]
    fn unseen_space_is_outside_with_slack_around_what_was_seen() {
        let s = raster();
        let out = s.unseen(1);
        assert!(!out.contains(Point2::new(5.0, 1.0)));
        // one cell beside the ray is within the slack, three are not
        assert!(!out.contains(Point2::new(5.0, 1.25)));
        assert!(out.contains(Point2::new(5.0, 1.65)));
        assert!(out.contains(Point2::new(5.0, 3.0)));
        assert!(out.contains(Point2::new(-3.0, 1.0)), "off the raster");
    }

    #[test]
    fn the_file_form_round_trips_and_bad_values_are_named() {
        let s = raster();
        let back = SeenFree::from_json(&s.to_json()).unwrap();
        assert_eq!(back, s);
        let mut v = s.to_json();
        v["runs"].as_array_mut().unwrap().push(json!(5));
        assert!(SeenFree::from_json(&v).unwrap_err().0.contains("goes past"));
        let mut v = s.to_json();
        v["runs"].as_array_mut().unwrap().pop();
        assert!(SeenFree::from_json(&v).unwrap_err().0.contains("the runs cover"));
        let mut v = s.to_json();
        v["cell"] = json!(-0.2);
        assert!(SeenFree::from_json(&v).unwrap_err().0.contains("positive"));
        let mut v = s.to_json();
        v["cols"] = json!(1u64 << 40);
        assert!(SeenFree::from_json(&v).unwrap_err().0.contains("cells"));
        let mut v = s.to_json();
        v["runs"][1] = json!("x");
        assert!(SeenFree::from_json(&v).unwrap_err().0.contains("run 1"));
        assert!(SeenFree::from_json(&json!({"cell": 0.2})).unwrap_err().0.contains("origin"));
    }

    #[test]
    fn coarsening_keeps_every_seen_point_seen() {
        let s = raster();
        let c = s.coarsened().coarsened();
        assert_eq!(c.cell(), 0.8);
        for k in 0..=80 {
            let q = Point2::new(1.0 + 0.1 * k as f64, 1.0);
            assert!(!s.contains(q) || c.contains(q), "{q}");
        }
        assert!(!c.contains(Point2::new(8.0, 5.0)));
        let parts = SeenFree::from_bits(c.origin(), c.cell(), c.size().0, c.size().1, c.bits()).unwrap();
        assert_eq!(parts, c);
        assert!(SeenFree::from_bits(c.origin(), c.cell(), c.size().0 + 64, c.size().1, c.bits()).is_none());
    }
}
