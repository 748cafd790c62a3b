//! A SCIP 2.0 sensor on a serial port (USB or RS-232). An RS-232 sensor that does not answer
//! at the requested bit rate (a URG-04LX powers up at 19200) is looked for at the others and
//! then switched to the requested one.

use super::driver::{SensorInfo, Urg};
use super::source::{Connector, ScipSource};
use super::{ScipError, BIT_RATES};
use serialport::{SerialPort, TTYPort};
use std::time::Duration;

/// A serial port and the bit rate asked of it.
pub struct SerialLink {
    pub path: String,
    pub baud: u32,
}

/// Scans from a sensor on a serial port.
pub type SerialSource = ScipSource<SerialLink>;

impl SerialSource {
    pub fn new(path: &str, baud: u32) -> Self {
        ScipSource::on(SerialLink { path: path.into(), baud })
    }
}

/// Whether a failed connection may be a bit rate mismatch: no answer, or garbage.
fn at_wrong_bit_rate(e: &ScipError) -> bool {
    matches!(e, ScipError::Timeout | ScipError::Malformed(_) | ScipError::Checksum(_))
}

impl Connector for SerialLink {
    type Port = TTYPort;

    fn name(&self) -> &str {
        &self.path
    }

    fn open(&mut self) -> Result<Urg<TTYPort>, ScipError> {
        let port = serialport::new(&self.path, self.baud)
            .timeout(Duration::from_millis(500))
            .open_native()
            .map_err(|e| self.port_error(e))?;
        let mut urg = Urg::new(port, Duration::from_secs(2));
        match urg.connect() {
            Ok(_) => {}
            Err(e) if at_wrong_bit_rate(&e) => {
                self.find_bit_rate(&mut urg).ok_or(e)??;
            }
            Err(e) => return Err(e),
        }
        Ok(urg)
    }
}

impl SerialLink {
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
    fn find_bit_rate(&self, urg: &mut Urg<TTYPort>) -> Option<Result<SensorInfo, ScipError>> {
        let found = BIT_RATES
            .into_iter()
            .filter(|&r| r != self.baud)
            .find(|&r| self.retune(urg, r).is_ok() && urg.connect().is_ok())?;
        messages::say!("acquire: {}: the sensor answers at {found} bit/s; switching it to {}", self.path, self.baud);
        let switched = urg.set_bit_rate(self.baud).and_then(|()| {
            self.retune(urg, self.baud)?;
            urg.connect().cloned()
        });
        Some(switched)
    }
}
