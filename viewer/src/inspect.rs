//! What a recording holds, read back with rerun's own decoder: per scan the instance count of
//! every entity, the latencies, the status and accuracy metrics, and the text log.

use crate::entities::*;
use re_log_encoding::DecoderApp;
use rerun::log::{Chunk, LogMsg};
use rerun::{Arrows2D, Image, LineStrips2D, Points2D, Scalars, TextLog};
use std::collections::BTreeMap;
use std::io::BufReader;
use std::path::{Path, PathBuf};
use thiserror::Error;

#[derive(Debug, Error)]
pub enum InspectError {
    #[error("{path}: {message}")]
    Open { path: PathBuf, message: String },
    #[error("{path}: not a clean rerun recording, message {index}: {message}")]
    Decode { path: PathBuf, index: usize, message: String },
}

/// One recording (all its parts), summarised.
#[derive(Clone, Debug, Default)]
pub struct Inspection {
    /// Decoded messages, over all parts.
    pub messages: usize,
    /// Per scan sequence number: per entity path, the instances logged.
    pub scans: BTreeMap<i64, BTreeMap<String, usize>>,
    /// Acquisition time span, nanoseconds on the source's monotonic clock.
    pub acquired: Option<(i64, i64)>,
    /// Per latency name (`acquire`, `hop/scan`, ...): every value, microseconds.
    pub latencies: BTreeMap<String, Vec<f64>>,
    /// Per scan: the status (0 ok, 1 ambiguous, 2 failed).
    pub status: BTreeMap<i64, u32>,
    /// Per scan with truth: success.
    pub success: BTreeMap<i64, bool>,
    /// Per scan with truth: position error, metres.
    pub position_error: BTreeMap<i64, f64>,
    /// Text log entries, with their scan (None for static ones).
    pub log: Vec<(Option<i64>, String)>,
    /// Static entities: instances of the map's walls and corners.
    pub map_walls: usize,
    pub map_corners: usize,
    /// Cells drawn as seen free by the map's survey ([`MAP_SEEN_FREE`]), 0 without.
    pub map_seen_free: usize,
    /// Where a part is damaged (cut short, never closed, a message that does not decode): the
    /// figures are of the messages before the damage, and of the parts after it.
    pub damage: Vec<String>,
    map_seen_free_row: Option<rerun::log::RowId>,
}

/// The component whose list length is an entity's instance count.
fn counted_component(path: &str) -> Option<rerun::ComponentIdentifier> {
    Some(match path {
        SCAN_READINGS | SCAN_CORNERS | SCAN_CHOSEN_CORNER | WORLD_READINGS | MAP_CORNERS => {
            Points2D::descriptor_positions().component
        }
        SCAN_LINES | MAP_WALLS => LineStrips2D::descriptor_strips().component,
        WORLD_HYPOTHESES | WORLD_POSE | WORLD_TRUTH => Arrows2D::descriptor_vectors().component,
        _ => return None,
    })
}

impl Inspection {
    /// Decodes the parts of one recording, in order. A part that cannot be opened is an error;
    /// a damaged one (a recorder killed mid-write, a full disk) gives what it holds up to the
    /// damage, which [`damage`](Self::damage) describes: a recording that lost its end keeps
    /// everything before it.
    pub fn read(paths: &[PathBuf]) -> Result<Self, InspectError> {
        let mut out = Inspection::default();
        for p in paths {
            if let Err(e) = out.read_part(p) {
                match e {
                    InspectError::Open { .. } => return Err(e),
                    InspectError::Decode { .. } => out.damage.push(e.to_string()),
                }
            }
        }
        Ok(out)
    }

    fn read_part(&mut self, path: &Path) -> Result<(), InspectError> {
        let file = std::fs::File::open(path)
            .map_err(|e| InspectError::Open { path: path.to_path_buf(), message: e.to_string() })?;
        let decode_err =
            |index: usize, message: String| InspectError::Decode { path: path.to_path_buf(), index, message };
        let size = file.metadata().map(|m| m.len()).unwrap_or(0);
        if size == 0 {
            return Err(decode_err(0, "the file is empty".into()));
        }
        let mut messages = DecoderApp::decode_lazy(BufReader::new(file));
        let mut index = 0;
        let decoded_all = messages.by_ref().try_for_each(|msg| {
            let msg = msg.map_err(|e| decode_err(index, e.to_string()))?;
            index += 1;
            // the recording's data; the layout (a blueprint store) says nothing about the run
            if let LogMsg::ArrowMsg(store, arrow) = msg {
                if store.kind() == rerun::StoreKind::Recording {
                    let chunk = Chunk::from_arrow_msg(&arrow).map_err(|e| decode_err(index, e.to_string()))?;
                    self.add_chunk(&chunk);
                }
            }
            Ok(())
        });
        self.messages += index;
        decoded_all?;
        let decoded = messages.num_bytes_processed();
        if decoded < size {
            return Err(decode_err(index, format!("truncated: only {decoded} of {size} bytes form whole messages")));
        }
        let footers = messages.rrd_manifests().map_err(|e| decode_err(index, e.to_string()))?;
        if footers.is_empty() {
            return Err(decode_err(index, "no footer: the recorder did not close the file".into()));
        }
        Ok(())
    }

    fn add_chunk(&mut self, chunk: &Chunk) {
        let path = chunk.entity_path().to_string();
        let path = path.trim_start_matches('/');
        let scan_timeline = rerun::TimelineName::from_static_str(TIMELINE_SCAN);
        if let Some(times) = chunk.timelines().get(&rerun::TimelineName::from_static_str(TIMELINE_ACQUIRED)) {
            for t in times.times() {
                let t = t.as_i64();
                let (lo, hi) = self.acquired.get_or_insert((t, t));
                *lo = (*lo).min(t);
                *hi = (*hi).max(t);
            }
        }
        if path == MAP_SEEN_FREE && chunk.is_static() {
            // the newest row wins, as in rerun, whatever order the chunks were written in: an
            // RGBA image (a cell is seen where its pixel is not clear), or a later map's clear
            let buffer = Image::descriptor_buffer().component;
            let cells: Vec<usize> = if chunk.components().contains_component(buffer) {
                chunk
                    .iter_slices::<&[u8]>(buffer)
                    .map(|b| b.iter().map(|b| b.chunks_exact(4).filter(|px| px[3] > 0).count()).sum())
                    .collect()
            } else {
                vec![0; chunk.num_rows()]
            };
            for (row, n) in chunk.row_ids().zip(cells) {
                if self.map_seen_free_row.is_none_or(|newest| row > newest) {
                    (self.map_seen_free_row, self.map_seen_free) = (Some(row), n);
                }
            }
            return;
        }
        if let Some(component) = counted_component(path) {
            let rows = chunk.iter_component_indices(scan_timeline, component);
            let lens = chunk.iter_component_offsets(component).map(|s| s.len);
            for ((time, _), len) in rows.zip(lens) {
                if chunk.is_static() {
                    match path {
                        MAP_WALLS => self.map_walls = len,
                        MAP_CORNERS => self.map_corners = len,
                        _ => {}
                    }
                } else {
                    *self.scans.entry(time.as_i64()).or_default().entry(path.to_owned()).or_default() += len;
                }
            }
            return;
        }
        if path == LOG {
            let component = TextLog::descriptor_text().component;
            let timed = chunk.timelines().contains_key(&scan_timeline);
            let rows = chunk.iter_component_offsets(component);
            let times: Vec<Option<i64>> = if timed && !chunk.is_static() {
                chunk.iter_component_indices(scan_timeline, component).map(|(t, _)| Some(t.as_i64())).collect()
            } else {
                rows.map(|_| None).collect()
            };
            for (scan, texts) in times.into_iter().zip(chunk.iter_slices::<String>(component)) {
                for t in texts {
                    self.log.push((scan, t.to_string()));
                }
            }
            return;
        }
        let component = Scalars::descriptor_scalars().component;
        let rows = chunk.iter_component_indices(scan_timeline, component);
        for ((time, _), values) in rows.zip(chunk.iter_slices::<f64>(component)) {
            let (scan, Some(&v)) = (time.as_i64(), values.first()) else { continue };
            if let Some(name) = path.strip_prefix(LATENCY).and_then(|p| p.strip_prefix('/')) {
                self.latencies.entry(name.to_owned()).or_default().push(v);
            } else if path == METRICS_STATUS {
                self.status.insert(scan, v as u32);
                self.scans.entry(scan).or_default().insert(METRICS_STATUS.to_owned(), 1);
            } else if path == METRICS_SUCCESS {
                self.success.insert(scan, v > 0.5);
            } else if path == METRICS_POSITION_ERROR {
                self.position_error.insert(scan, v);
            }
        }
    }

    /// Scans with a given status.
    pub fn scans_with_status(&self, status: u32) -> Vec<i64> {
        self.status.iter().filter(|(_, &s)| s == status).map(|(&k, _)| k).collect()
    }

    /// The human summary `viewer inspect` prints.
    pub fn render(&self) -> String {
        let mut out = Vec::new();
        for d in &self.damage {
            out.push(format!("damaged: {d}; what follows is what could be read"));
        }
        match (self.scans.keys().next(), self.scans.keys().next_back()) {
            (Some(a), Some(b)) => out.push(format!("scans: {} (seq {a}..={b})", self.scans.len())),
            _ => out.push("scans: 0".to_owned()),
        }
        if let Some((lo, hi)) = self.acquired {
            out.push(format!("time span: {:.3} s", (hi - lo) as f64 / 1e9));
        }
        let seen = match self.map_seen_free {
            0 => String::new(),
            n => format!(", {n} cells of seen free space"),
        };
        out.push(format!("map: {} walls, {} corners{seen}", self.map_walls, self.map_corners));
        if !self.success.is_empty() {
            let ok = self.success.values().filter(|&&s| s).count();
            let errors: Vec<f64> = self
                .success
                .iter()
                .filter(|(_, &s)| s)
                .filter_map(|(k, _)| self.position_error.get(k))
                .copied()
                .collect();
            let mean = if errors.is_empty() { f64::NAN } else { errors.iter().sum::<f64>() / errors.len() as f64 };
            out.push(format!(
                "success: {:.1} % of {} scans with truth (mean error of successes {:.1} cm)",
                100.0 * ok as f64 / self.success.len() as f64,
                self.success.len(),
                100.0 * mean
            ));
        }
        if !self.latencies.is_empty() {
            // the figures and labels `gema2 run` prints, in its order
            out.push(format!("latency (us){:34} p50       p99     count", ""));
            for f in messages::latency::FIGURES {
                let values = self.latencies.get(f.key).map(Vec::as_slice).unwrap_or_default();
                let (p50, p99) = messages::latency::p50_p99(values);
                out.push(format!("  {:42} {p50:8.1}  {p99:8.1} {:>9}", f.label, values.len()));
            }
        }
        for (label, status) in [("ambiguous", messages::STATUS_AMBIGUOUS), ("failed", messages::STATUS_FAILED)] {
            let scans = self.scans_with_status(status);
            out.push(format!("{label}: {} scans{}", scans.len(), compact(&scans)));
        }
        let errors = self.log.iter().filter(|(_, t)| t.contains("bad ") || t.contains("unusable")).count();
        out.push(format!("log entries: {} ({errors} about bad messages)", self.log.len()));
        let swaps: Vec<&str> = self.log.iter().filter_map(|(_, t)| t.strip_prefix("supervisor: ")).collect();
        out.push(format!("swaps: {}", swaps.len()));
        out.extend(swaps.iter().map(|t| format!("  {t}")));
        out.join("\n")
    }

    /// Per scan, tab-separated: seq, then each of [`PER_SCAN`]'s instance counts (`-` if the
    /// entity was not logged for that scan).
    pub fn render_per_scan(&self) -> String {
        let mut out = vec![format!("seq\t{}", PER_SCAN.join("\t"))];
        for (seq, entities) in &self.scans {
            let cols: Vec<String> =
                PER_SCAN.iter().map(|e| entities.get(*e).map_or("-".to_owned(), |n| n.to_string())).collect();
            out.push(format!("{seq}\t{}", cols.join("\t")));
        }
        out.join("\n")
    }
}

/// `: 3, 17, 40-42` for a sorted list of scans.
fn compact(scans: &[i64]) -> String {
    if scans.is_empty() {
        return String::new();
    }
    let mut runs: Vec<(i64, i64)> = Vec::new();
    for &s in scans {
        match runs.last_mut() {
            Some((_, hi)) if *hi + 1 == s => *hi = s,
            _ => runs.push((s, s)),
        }
    }
    let parts: Vec<String> =
        runs.iter().map(|&(a, b)| if a == b { a.to_string() } else { format!("{a}-{b}") }).collect();
    format!(": {}", parts.join(", "))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn runs_of_scans() {
        assert_eq!(compact(&[3, 17, 40, 41, 42]), ": 3, 17, 40-42");
        assert_eq!(compact(&[]), "");
    }
}
