//! A Hokuyo driver speaking SCIP 2.0 (URG-04LX on a serial port; UST-10LX/20LX and UTM-30LX-EW
//! over TCP), generic over `Read + Write` so tests can script the transport, plus an emulated
//! sensor that speaks SCIP 2.0 on a pseudo-terminal or TCP.

pub mod codec;
pub mod driver;
pub mod emulator;
pub mod frame;
pub mod model;
pub mod serial;
pub mod source;
pub mod tcp;

use thiserror::Error;

pub use driver::{Encoding, RawScan, SensorInfo, Urg};
pub use emulator::{EmulatorFaults, UrgEmulator};
pub use model::ScipModel;
pub use serial::SerialSource;
pub use source::ScipSource;
pub use tcp::TcpSource;

#[derive(Debug, Error)]
pub enum ScipError {
    // the cause in the message, not chained as a source too (it would print twice)
    #[error("I/O: {0}")]
    Io(std::io::Error),
    #[error("no answer from the sensor in time")]
    Timeout,
    #[error("the sensor closed the connection")]
    Closed,
    #[error("checksum mismatch in {0:?}")]
    Checksum(String),
    #[error("{command}: the sensor answered status {status}: {meaning}")]
    Status { command: String, status: String, meaning: &'static str },
    #[error("malformed response: {0}")]
    Malformed(String),
}

impl From<std::io::Error> for ScipError {
    fn from(e: std::io::Error) -> Self {
        ScipError::Io(e)
    }
}

/// The bit rates `SS` can set, the URG-04LX's power-up rate first.
pub const BIT_RATES: [u32; 7] = [19_200, 38_400, 57_600, 115_200, 250_000, 500_000, 750_000];

/// What a status code means, for messages.
pub fn status_meaning(command: &str, status: &str) -> &'static str {
    match (command.get(..2).unwrap_or(""), status) {
        (_, "00") => "ok",
        (_, "99") => "data",
        ("BM", "01") => "the laser cannot be switched on (laser malfunction)",
        ("BM", "02") => "the laser is already on",
        ("SS", "01") => "the bit rate is not a number",
        ("SS", "02") => "the sensor does not support that bit rate",
        ("SS", "04") => "this sensor model cannot change its bit rate",
        (_, "01") => "the starting step is not a number",
        (_, "02") => "the ending step is not a number",
        (_, "03") => "the cluster count is not a number",
        (_, "04") => "the ending step is out of range",
        (_, "05") => "the ending step is smaller than the starting step",
        (_, "06") => "the scan interval is not a number",
        (_, "07") => "the number of scans is not a number",
        (_, "0E") => "the command is not defined",
        (_, "0F") => "the parameters are wrong",
        (_, "10") => "the laser is off",
        (_, s) if s.starts_with('5') || s.starts_with('6') => "hardware failure (see the sensor's manual)",
        _ => "an undocumented status",
    }
}

/// Unwraps the sensor's 24-bit millisecond timestamps into a steadily increasing count.
#[derive(Clone, Copy, Debug, Default)]
pub struct TimestampUnwrapper {
    last: Option<u32>,
    wraps: u64,
}

impl TimestampUnwrapper {
    pub const PERIOD: u64 = 1 << 24;

    /// The unwrapped time, milliseconds, of a raw 24-bit timestamp.
    pub fn unwrap(&mut self, raw: u32) -> u64 {
        let raw = raw & 0xFF_FFFF;
        if let Some(last) = self.last {
            // a step back of more than half the period is a wrap, not jitter
            if raw < last && last - raw > (Self::PERIOD / 2) as u32 {
                self.wraps += 1;
            }
        }
        self.last = Some(raw);
        self.wraps * Self::PERIOD + raw as u64
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn timestamps_keep_increasing_across_the_24_bit_wrap() {
        let mut u = TimestampUnwrapper::default();
        let raws = [0xFF_FF00, 0xFF_FFA0, 0x00_0010, 0x00_0070, 0x00_0060, 0xFF_FFF0, 0x00_0100];
        let got: Vec<u64> = raws.iter().map(|&r| u.unwrap(r)).collect();
        assert_eq!(got[2], (1 << 24) + 0x10);
        // a little jitter backwards is not a wrap
        assert_eq!(got[4], (1 << 24) + 0x60);
        // but a step back of most of the period is
        assert_eq!(got[6], (2 << 24) + 0x100);
    }
}
