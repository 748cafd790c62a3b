//! How many cells each raster gema2 builds may have: every limit in one place, each with what a
//! cell costs, under one memory budget. A map kilometres across is then coarsened (or, read from
//! a file, refused) instead of exhausting memory. Each raster's module takes its limit from here.

/// The most memory one raster may take, bytes.
pub const RASTER_BUDGET: usize = 1 << 30;

/// A map_server image read from a file: a `u16` value and a one-byte cell each (refused beyond).
pub const GRID_FILE_CELLS: usize = 1 << 27;
/// Bytes a cell of [`GRID_FILE_CELLS`] costs.
pub const GRID_FILE_CELL_BYTES: usize = 3;

/// The occupancy evidence of a survey (`mapio::occupancy`): hit and pass counts with the last
/// scan of each, and a drawn wall's direction, 20 bytes a cell (coarsened beyond).
pub const SURVEY_CELLS: usize = 1 << 25;
/// Bytes a cell of [`SURVEY_CELLS`] costs.
pub const SURVEY_CELL_BYTES: usize = 20;

/// The free space a survey saw ([`crate::SeenFree`]): one bit a cell (refused beyond; the map
/// message carries fewer, coarsened to fit).
pub const SEEN_CELLS: usize = 1 << 26;

/// The distance field ([`crate::DistanceField`]): one byte a cell, tiled; coarsened beyond, as a
/// larger field no longer fits any cache and every lookup misses.
pub const FIELD_CELLS: usize = 16_000_000;

/// The wall lists of a [`crate::grid::WallGrid`]: a list head a cell (24 bytes) and the walls'
/// indices; coarsened beyond, which makes lists longer but keeps every query's answer.
pub const WALL_GRID_CELLS: usize = 4_000_000;
/// Bytes a cell of [`WALL_GRID_CELLS`] costs, before its walls' indices.
pub const WALL_GRID_CELL_BYTES: usize = 24;

/// The raster of [`crate::FreeSpace`]: one byte a cell; coarsened beyond.
pub const FREE_SPACE_CELLS: usize = 4_000_000;

/// The positions the localizer's grid search visits over a map's bounds: a time limit, not a
/// memory one (a map kilometres wide with little free space is not walked at a room's step).
pub const SEARCH_GRID_CELLS: usize = 4_000_000;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_raster_fits_the_budget_at_its_limit() {
        for (what, cells, bytes) in [
            ("a map_server image", GRID_FILE_CELLS, GRID_FILE_CELL_BYTES),
            ("the survey's occupancy", SURVEY_CELLS, SURVEY_CELL_BYTES),
            ("the seen free space", SEEN_CELLS / 8, 1),
            ("the distance field", FIELD_CELLS, 1),
            ("the wall grid", WALL_GRID_CELLS, WALL_GRID_CELL_BYTES),
            ("the free space", FREE_SPACE_CELLS, 1),
        ] {
            assert!(cells * bytes <= RASTER_BUDGET, "{what}: {} MiB", (cells * bytes) >> 20);
        }
    }
}
