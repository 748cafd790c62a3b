//! Where a recording goes: a `.rrd` file (rolling over to numbered files past a size), a live
//! rerun viewer (spawned, or at an address), or both at once.

use crate::live::{LiveSink, LiveTally};
use rerun::blueprint::{
    Blueprint, BlueprintActivation, Horizontal, Spatial2DView, TextLogView, TimePanel, TimeSeriesView, Vertical,
};
use rerun::sink::{FileSink, GrpcSink, LogSink};
use rerun::{RecordingStream, RecordingStreamBuilder};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Duration;
use thiserror::Error;

/// The application id every gema2 recording carries.
pub const APPLICATION_ID: &str = "gema2";

#[derive(Debug, Error)]
pub enum OutputError {
    #[error("nothing to record to: give a file, --spawn or --connect")]
    Nowhere,
    #[error("{path}: cannot record there: {message}")]
    File { path: PathBuf, message: String },
    #[error("live viewer at {url}: {message}")]
    Live { url: String, message: String },
    #[error("spawning the rerun viewer (pip install rerun-sdk==0.36.3 puts `rerun` on PATH): {0}")]
    Spawn(String),
    #[error("rerun: {0}")]
    Stream(String),
}

impl OutputError {
    /// A failure of the rerun stream (logging, flushing), as `map_err` takes it.
    pub fn stream(e: impl std::fmt::Display) -> Self {
        OutputError::Stream(e.to_string())
    }
}

/// What to record to.
#[derive(Clone, Debug, Default)]
pub struct OutputSpec {
    /// The `.rrd` file; later parts are numbered beside it (see [`part_path`]).
    pub file: Option<PathBuf>,
    /// Start a new part once the current file holds this many bytes.
    pub max_size: Option<u64>,
    /// Spawn a rerun viewer (from PATH) and stream to it.
    pub spawn: bool,
    /// Stream to a running viewer: `HOST:PORT` or a `rerun+http://.../proxy` URL.
    pub connect: Option<String>,
    /// The recording id; every part shares it, so a viewer merges the parts into one recording.
    pub recording_id: Option<String>,
}

/// How a viewer lays out a gema2 recording: the map frame large, the sensor frame, latencies,
/// status and the log beside it, on the `scan` timeline.
pub fn layout() -> Blueprint {
    use crate::entities::*;
    let left = Vertical::new([
        Spatial2DView::new("map frame: poses, hypotheses, readings at the pose").with_origin("world").into(),
        TextLogView::new("log").with_origin(LOG).into(),
    ])
    .with_row_shares([4.0, 1.0]);
    let right = Vertical::new([
        Spatial2DView::new("sensor frame: readings, lines, corners").with_origin("scan").into(),
        TimeSeriesView::new("latency (µs)").with_origin(LATENCY).into(),
        TimeSeriesView::new("status (0 ok, 1 ambiguous, 2 failed), success, error (m)").with_origin("metrics").into(),
    ]);
    Blueprint::new(Horizontal::new([left.into(), right.into()]).with_column_shares([3.0, 2.0]))
        .with_time_panel(TimePanel::new().with_timeline(TIMELINE_SCAN))
}

/// The path of part `k` of a recording: part 0 is `file` itself, part k > 0 is
/// `<stem>.<k>.rrd` beside it.
pub fn part_path(file: &Path, k: u32) -> PathBuf {
    if k == 0 {
        return file.to_path_buf();
    }
    let stem = file.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_else(|| "recording".into());
    let ext = file.extension().map(|e| e.to_string_lossy().into_owned()).unwrap_or_else(|| "rrd".into());
    file.with_file_name(format!("{stem}.{k}.{ext}"))
}

/// The longest a recording's closing flush waits (for a live viewer slow to take what it is
/// sent; files flush in far less).
const CLOSE_WAIT: Duration = Duration::from_secs(30);

/// The proxy URL for `--connect`: a bare `HOST:PORT` becomes `rerun+http://HOST:PORT/proxy`.
pub fn connect_url(addr: &str) -> String {
    if addr.contains("://") {
        addr.to_owned()
    } else {
        format!("rerun+http://{addr}/proxy")
    }
}

/// Why no rerun viewer answers at `url` (a `--connect` address) right now, or `None` when one
/// does (or the address names no host and port to try). The stream itself never refuses an
/// address: it holds messages until a viewer answers and fails only when it is closed, which
/// leaves a mistyped address unnoticed for the whole run. A viewer started after the recorder
/// still gets the messages, so this is a warning, not a refusal.
pub fn unanswered(url: &str, wait: Duration) -> Option<String> {
    use std::net::{TcpStream, ToSocketAddrs};
    let rest = url.split_once("://").map_or(url, |(_, rest)| rest);
    let host_port = rest.split('/').next().unwrap_or(rest);
    let addrs = match host_port.to_socket_addrs() {
        Ok(a) => a.collect::<Vec<_>>(),
        Err(e) => return Some(format!("{host_port}: {e}")),
    };
    let mut why = format!("{host_port}: no address");
    for addr in addrs {
        match TcpStream::connect_timeout(&addr, wait) {
            Ok(_) => return None,
            Err(e) => why = format!("{addr}: {e}"),
        }
    }
    Some(why)
}

/// An open recording: the stream, and which file part it is writing.
pub struct Output {
    spec: OutputSpec,
    live_url: Option<String>,
    /// What the live viewer got, over every part.
    live: Arc<LiveTally>,
    recording_id: String,
    part: u32,
    stream: RecordingStream,
    parts: Vec<PathBuf>,
    /// The current part's size when last measured, and an estimate of what was logged since:
    /// the file is written asynchronously, so it is only measured (after a flush) once the two
    /// together could pass the limit.
    measured: u64,
    logged_since: u64,
}

impl Output {
    /// Opens the first part (and spawns or connects the live viewer).
    pub fn open(spec: OutputSpec) -> Result<Self, OutputError> {
        if spec.file.is_none() && !spec.spawn && spec.connect.is_none() {
            return Err(OutputError::Nowhere);
        }
        let live_url = if spec.spawn {
            let info = rerun::spawn(&rerun::SpawnOptions::default()).map_err(|e| OutputError::Spawn(e.to_string()))?;
            Some(format!("rerun+http://127.0.0.1:{}/proxy", info.port))
        } else {
            spec.connect.as_deref().map(connect_url)
        };
        let recording_id = spec.recording_id.clone().unwrap_or_else(|| format!("gema2-{}", std::process::id()));
        let live = Arc::new(LiveTally::default());
        let stream = Self::stream_for(&spec, live_url.as_deref(), &live, &recording_id, 0)?;
        let parts = spec.file.iter().cloned().collect();
        Ok(Output { spec, live_url, live, recording_id, part: 0, stream, parts, measured: 0, logged_since: 0 })
    }

    fn stream_for(
        spec: &OutputSpec,
        live_url: Option<&str>,
        live: &Arc<LiveTally>,
        recording_id: &str,
        part: u32,
    ) -> Result<RecordingStream, OutputError> {
        let mut sinks: Vec<Box<dyn LogSink>> = Vec::new();
        if let Some(file) = &spec.file {
            let path = part_path(file, part);
            let sink =
                FileSink::new(&path).map_err(|e| OutputError::File { path: path.clone(), message: e.to_string() })?;
            sinks.push(Box::new(sink));
        }
        if let Some(url) = live_url {
            let uri = match url.parse::<rerun::external::re_uri::RedapUri>() {
                Ok(rerun::external::re_uri::RedapUri::Proxy(uri)) => uri,
                Ok(_) => return Err(OutputError::Live { url: url.into(), message: "not a proxy address".into() }),
                Err(e) => return Err(OutputError::Live { url: url.into(), message: e.to_string() }),
            };
            sinks.push(Box::new(LiveSink::new(GrpcSink::new(uri), Arc::clone(live))));
        }
        let stream = RecordingStreamBuilder::new(APPLICATION_ID)
            .recording_id(recording_id)
            .set_sinks(sinks)
            .map_err(OutputError::stream)?;
        layout()
            .send(&stream, BlueprintActivation { make_active: true, make_default: true })
            .map_err(OutputError::stream)?;
        Ok(stream)
    }

    pub fn stream(&self) -> &RecordingStream {
        &self.stream
    }

    /// The files written so far, in order.
    pub fn parts(&self) -> &[PathBuf] {
        &self.parts
    }

    /// Counts `bytes` (an estimate of what was just logged) towards the current part's size.
    pub fn account(&mut self, bytes: u64) {
        self.logged_since += bytes;
    }

    /// Starts the next part if the current file has reached the size limit. Returns true when
    /// it did: static data (the map) must then be logged again.
    pub fn roll_if_full(&mut self) -> Result<bool, OutputError> {
        let (Some(file), Some(max)) = (&self.spec.file, self.spec.max_size) else {
            return Ok(false);
        };
        if self.measured + self.logged_since < max {
            return Ok(false);
        }
        self.stream.flush_with_timeout(CLOSE_WAIT).map_err(OutputError::stream)?;
        let current = part_path(file, self.part);
        self.measured = std::fs::metadata(&current).map(|m| m.len()).unwrap_or(0);
        self.logged_since = 0;
        if self.measured < max {
            return Ok(false);
        }
        let next =
            Self::stream_for(&self.spec, self.live_url.as_deref(), &self.live, &self.recording_id, self.part + 1)?;
        let previous = std::mem::replace(&mut self.stream, next);
        previous.flush_with_timeout(CLOSE_WAIT).map_err(OutputError::stream)?;
        drop(previous);
        self.part += 1;
        self.parts.push(part_path(file, self.part));
        self.measured = 0;
        Ok(true)
    }

    /// Flushes everything logged so far and closes the file(s): the files written, and whether
    /// every sink took everything. The files are whole even when the live viewer got nothing
    /// (one that never answered, or went away): its sink never holds them back.
    pub fn close(self) -> (Vec<PathBuf>, Result<(), OutputError>) {
        let mut closed = self.stream.flush_with_timeout(CLOSE_WAIT).map_err(OutputError::stream);
        drop(self.stream);
        if let (Ok(()), Some(url), Some(why)) = (&closed, &self.live_url, self.live.shortfall()) {
            closed = Err(OutputError::Live { url: url.clone(), message: why });
        }
        (self.parts, closed)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parts_are_numbered_beside_the_first_file() {
        assert_eq!(part_path(Path::new("/r/run.rrd"), 0), PathBuf::from("/r/run.rrd"));
        assert_eq!(part_path(Path::new("/r/run.rrd"), 3), PathBuf::from("/r/run.3.rrd"));
        assert_eq!(part_path(Path::new("run"), 1), PathBuf::from("run.1.rrd"));
        assert_eq!(connect_url("127.0.0.1:9876"), "rerun+http://127.0.0.1:9876/proxy");
        assert_eq!(connect_url("rerun+http://h:1/proxy"), "rerun+http://h:1/proxy");
    }

    #[test]
    fn an_address_nothing_listens_on_is_unanswered_and_a_listening_one_answers() {
        let wait = std::time::Duration::from_secs(2);
        let listener = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
        let port = listener.local_addr().unwrap().port();
        assert_eq!(unanswered(&connect_url(&format!("127.0.0.1:{port}")), wait), None);
        drop(listener);
        let why = unanswered(&connect_url(&format!("127.0.0.1:{port}")), wait).unwrap();
        assert!(why.contains(&format!("127.0.0.1:{port}")), "{why}");
        let why = unanswered(&connect_url("no-such-host.invalid:9876"), wait).unwrap();
        assert!(why.contains("no-such-host.invalid"), "{why}");
        assert!(unanswered("rerun+http://no-port/proxy", wait).is_some());
    }

    #[test]
    fn nowhere_to_record_is_an_error() {
        assert!(matches!(Output::open(OutputSpec::default()), Err(OutputError::Nowhere)));
    }
}
