//! Scans from a URG-04LX on a serial port, surviving what serial links do: a scan that fails
//! its checksum is dropped and counted; garbage is skipped; a port that disappears (cable
//! pulled, sensor reset) is reopened with backoff until it comes back. An RS-232 sensor that
//! does not answer at the requested bit rate (it powers up at 19200) is looked for at the
//! others and then switched to the requested one.

use super::driver::{Encoding, LinkStats, Urg};
use super::{ScipError, BIT_RATES};
use laser::LaserScan;
use serialport::{SerialPort, TTYPort};
use std::time::Duration;

pub struct SerialSource {
    pub path: String,
    pub baud: u32,
    urg: Option<Urg<TTYPort>>,
    backoff: Duration,
    /// Totals over every connection.
    pub stats: LinkStats,
    pub reconnects: u64,
}

/// Whether a failed connection may be a bit rate mismatch: no answer, or garbage.
fn at_wrong_bit_rate(e: &ScipError) -> bool {
    matches!(e, ScipError::Timeout | ScipError::Malformed(_) | ScipError::Checksum(_))
}

/// Errors that reconnecting cannot fix.
fn fatal(e: &ScipError) -> bool {
    matches!(e, ScipError::Status { .. })
}

impl SerialSource {
    pub fn new(path: &str, baud: u32) -> Self {
        SerialSource {
            path: path.into(),
            baud,
            urg: None,
            backoff: Duration::from_millis(100),
            stats: LinkStats::default(),
            reconnects: 0,
        }
    }

    fn open(&mut self) -> Result<(), ScipError> {
        let port = serialport::new(&self.path, self.baud)
            .timeout(Duration::from_millis(500))
            .open_native()
            .map_err(|e| self.port_error(e))?;
        let mut urg = Urg::new(port, Duration::from_secs(2));
        let info = match urg.connect() {
            Ok(info) => info.clone(),
            Err(e) if at_wrong_bit_rate(&e) => self.find_bit_rate(&mut urg).ok_or(e)??,
            Err(e) => return Err(e),
        };
        urg.laser_on()?;
        urg.start(Encoding::Three, info.amin, info.amax, 1, 0)?;
        self.urg = Some(urg);
        self.backoff = Duration::from_millis(100);
        Ok(())
    }

    /// Sets the port to `rate` and forgets what arrived at the old one.
    fn retune(&self, urg: &mut Urg<TTYPort>, rate: u32) -> Result<(), ScipError> {
        urg.port_mut().set_baud_rate(rate).map_err(|e| self.port_error(e))?;
        urg.discard_input();
        Ok(())
    }

    /// A serial port error, naming the port.
    fn port_error(&self, e: serialport::Error) -> ScipError {
        ScipError::Io(std::io::Error::other(format!("{}: {e}", self.path)))
    }

    /// Looks for the sensor at the other bit rates; where it answers, asks it to switch to
    /// the requested rate and connects again at that. `None` when it answers at none.
    fn find_bit_rate(&self, urg: &mut Urg<TTYPort>) -> Option<Result<super::SensorInfo, ScipError>> {
        let found = BIT_RATES
            .into_iter()
            .filter(|&r| r != self.baud)
            .find(|&r| self.retune(urg, r).is_ok() && urg.connect().is_ok())?;
        eprintln!("acquire: {}: the sensor answers at {found} bit/s; switching it to {}", self.path, self.baud);
        let switched = urg.set_bit_rate(self.baud).and_then(|()| {
            self.retune(urg, self.baud)?;
            urg.connect().cloned()
        });
        Some(switched)
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
                    Ok(()) => eprintln!("acquire: {} connected", self.path),
                    Err(e) if fatal(&e) => return Some(Err(e)),
                    Err(e) => {
                        eprintln!("acquire: {}: {e}; retrying in {:?}", self.path, self.backoff);
                        self.urg = None;
                        if !keep_going(self.backoff) {
                            return None;
                        }
                        self.backoff = (self.backoff * 2).min(Duration::from_secs(2));
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
                    let info = urg.info.clone();
                    return Some(Ok(raw.to_laser_scan(&info, stamp)));
                }
                Err(ScipError::Checksum(_)) | Err(ScipError::Malformed(_)) => continue,
                Err(e) if fatal(&e) => return Some(Err(e)),
                Err(e) => {
                    eprintln!("acquire: {}: {e}; reconnecting", self.path);
                    self.retire();
                }
            }
        }
    }
}
