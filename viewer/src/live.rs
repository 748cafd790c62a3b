//! The live viewer's side of a recording: rerun's gRPC sink, kept from holding the file back.
//!
//! rerun's gRPC client queues 100 messages and then blocks the sender until a viewer takes
//! them. A recording's sinks are fed one after the other by one thread, so a viewer that never
//! answers (a mistyped `--connect` address) or that goes away stops the file too, and the
//! closing flush then waits for ever: measured, a recorder stopped at 47 of 60 scans and
//! ignored SIGINT. [`LiveSink`] passes messages on only while they can go somewhere: all of
//! them once a viewer is connected, the first [`UNCONNECTED_QUEUE`] while it is still
//! connecting (the map and layout, which a viewer started a moment later still gets), and it
//! counts the rest as not shown.

use rerun::log::LogMsg;
use rerun::sink::{GrpcSink, GrpcSinkConnectionState, LogSink, SinkFlushError};
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

/// Messages handed to a viewer that is not connected yet, well inside the client's queue of
/// 100 so that sending never blocks.
pub const UNCONNECTED_QUEUE: usize = 64;

/// What happened to the live stream over the whole recording (every file part's sink adds to
/// the same tally).
#[derive(Debug, Default)]
pub struct LiveTally {
    sent: AtomicU64,
    not_shown: AtomicU64,
    connected: AtomicBool,
    failure: Mutex<Option<String>>,
}

impl LiveTally {
    /// Why the live viewer did not get everything, or `None` when it did.
    pub fn shortfall(&self) -> Option<String> {
        let not_shown = self.not_shown.load(Ordering::Relaxed);
        let failure = self.failure.lock().map(|f| f.clone()).unwrap_or_default();
        if not_shown == 0 && failure.is_none() {
            return None;
        }
        let total = not_shown + self.sent.load(Ordering::Relaxed);
        let when = if self.connected.load(Ordering::Relaxed) { "went away" } else { "never answered" };
        Some(match failure {
            Some(why) => format!("the viewer {when}: {not_shown} of {total} messages not shown ({why})"),
            None => format!("the viewer {when}: {not_shown} of {total} messages not shown"),
        })
    }

    fn fail(&self, why: String) {
        if let Ok(mut f) = self.failure.lock() {
            f.get_or_insert(why);
        }
    }
}

/// rerun's [`GrpcSink`] that drops what no viewer can take instead of blocking (module docs).
pub struct LiveSink {
    grpc: GrpcSink,
    /// Messages this sink queued while its client was still connecting.
    queued: AtomicUsize,
    tally: Arc<LiveTally>,
}

impl LiveSink {
    pub fn new(grpc: GrpcSink, tally: Arc<LiveTally>) -> Self {
        LiveSink { grpc, queued: AtomicUsize::new(0), tally }
    }

    /// Whether a message may go to the client now without blocking for a viewer.
    fn may_send(&self) -> bool {
        match self.grpc.status() {
            GrpcSinkConnectionState::Connected => {
                self.tally.connected.store(true, Ordering::Relaxed);
                true
            }
            GrpcSinkConnectionState::Connecting { .. } => {
                self.queued.fetch_add(1, Ordering::Relaxed) < UNCONNECTED_QUEUE
            }
            GrpcSinkConnectionState::Disconnected(_) => false,
        }
    }
}

impl LogSink for LiveSink {
    fn send(&self, msg: LogMsg) {
        if self.may_send() {
            self.tally.sent.fetch_add(1, Ordering::Relaxed);
            self.grpc.send(msg);
        } else {
            self.tally.not_shown.fetch_add(1, Ordering::Relaxed);
        }
    }

    /// Flushes to a connected viewer; never fails the recording's flush (the files are what a
    /// flush must not lose): a failure is kept for [`LiveTally::shortfall`].
    fn flush_blocking(&self, timeout: Duration) -> Result<(), SinkFlushError> {
        if matches!(self.grpc.status(), GrpcSinkConnectionState::Connected) {
            if let Err(e) = self.grpc.flush_blocking(timeout) {
                self.tally.fail(e.to_string());
            }
        }
        Ok(())
    }

    fn default_batcher_config(&self) -> rerun::log::ChunkBatcherConfig {
        self.grpc.default_batcher_config()
    }
}
