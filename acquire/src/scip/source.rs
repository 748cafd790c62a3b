//! Scans from a SCIP 2.0 sensor on any link ([`Connector`]: a serial port or a TCP
//! connection), surviving what links do: a scan that fails its checksum is dropped and
//! counted; garbage is skipped; a link that goes away (cable pulled, sensor reset, connection
//! dropped) is opened again with backoff until it comes back. The scan area and geometry are
//! those the sensor reports (`PP`), never a model's constants.

use super::driver::{Encoding, LinkStats, Urg};
use super::ScipError;
use laser::LaserScan;
use std::io::{Read, Write};
use std::time::Duration;

/// How a source reaches its sensor.
pub trait Connector {
    type Port: Read + Write;
    /// The link's name in messages: a port's path, a host and port.
    fn name(&self) -> &str;
    /// Opens the link and brings the sensor to a known SCIP 2.0 state ([`Urg::connect`]).
    fn open(&mut self) -> Result<Urg<Self::Port>, ScipError>;
}

/// A sensor on a link, reopened whenever it fails.
pub struct ScipSource<C: Connector> {
    pub link: C,
    urg: Option<Urg<C::Port>>,
    backoff: Duration,
    /// Totals over every connection.
    pub stats: LinkStats,
    pub reconnects: u64,
}

/// The first wait before opening a link again, and the longest.
const FIRST_BACKOFF: Duration = Duration::from_millis(100);
const LONGEST_BACKOFF: Duration = Duration::from_secs(2);

/// Errors that reconnecting cannot fix.
fn fatal(e: &ScipError) -> bool {
    matches!(e, ScipError::Status { .. })
}

impl<C: Connector> ScipSource<C> {
    pub fn on(link: C) -> Self {
        ScipSource { link, urg: None, backoff: FIRST_BACKOFF, stats: LinkStats::default(), reconnects: 0 }
    }

    /// Opens the link, switches the laser on and starts streaming every measurable step.
    fn open(&mut self) -> Result<(), ScipError> {
        let mut urg = self.link.open()?;
        for what in &urg.info.unanswered {
            messages::say!("acquire: {}: {what}; going on without it", self.link.name());
        }
        urg.laser_on()?;
        let (amin, amax) = (urg.info.amin, urg.info.amax);
        urg.start(Encoding::Three, amin, amax, 1, 0)?;
        self.urg = Some(urg);
        self.backoff = FIRST_BACKOFF;
        Ok(())
    }

    fn retire(&mut self) {
        if let Some(u) = self.urg.take() {
            self.stats.scans += u.stats.scans;
            self.stats.checksum_drops += u.stats.checksum_drops;
            self.stats.resyncs += u.stats.resyncs;
        }
    }

    /// Counters including the current connection.
    pub fn totals(&self) -> LinkStats {
        let mut t = self.stats;
        if let Some(u) = &self.urg {
            t.scans += u.stats.scans;
            t.checksum_drops += u.stats.checksum_drops;
            t.resyncs += u.stats.resyncs;
        }
        t
    }

    /// The next scan. Transient failures are handled here; `keep_going` is asked before each
    /// wait so the caller can stop. Returns `None` when told to stop, `Err` for what retrying
    /// cannot fix (a status such as a broken laser).
    pub fn next_scan(&mut self, keep_going: &mut dyn FnMut(Duration) -> bool) -> Option<Result<LaserScan, ScipError>> {
        loop {
            if self.urg.is_none() {
                match self.open() {
                    Ok(()) => messages::say!("acquire: {} connected", self.link.name()),
                    Err(e) if fatal(&e) => return Some(Err(e)),
                    Err(e) => {
                        messages::say!("acquire: {}: {e}; retrying in {:?}", self.link.name(), self.backoff);
                        self.urg = None;
                        if !keep_going(self.backoff) {
                            return None;
                        }
                        self.backoff = (self.backoff * 2).min(LONGEST_BACKOFF);
                        self.reconnects += 1;
                        continue;
                    }
                }
            }
            if !keep_going(Duration::ZERO) {
                return None;
            }
            let urg = self.urg.as_mut()?;
            match urg.next_scan() {
                Ok(raw) => {
                    let stamp = raw.timestamp_ms as f64 / 1000.0;
                    return Some(Ok(raw.to_laser_scan(&urg.info, stamp)));
                }
                Err(ScipError::Checksum(_)) | Err(ScipError::Malformed(_)) => continue,
                Err(e) if fatal(&e) => return Some(Err(e)),
                Err(e) => {
                    messages::say!("acquire: {}: {e}; reconnecting", self.link.name());
                    self.retire();
                }
            }
        }
    }
}
