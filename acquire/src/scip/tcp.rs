//! A SCIP 2.0 sensor over Ethernet (UST-10LX/20LX, UTM-30LX-EW): SCIP 2.0 on a TCP connection,
//! the factory address being 192.168.0.10:10940. Same decoder, checks and reconnection as a
//! serial port ([`ScipSource`]); there is no bit rate to find.

use super::driver::Urg;
use super::source::{Connector, ScipSource};
use super::ScipError;
use std::net::{SocketAddr, TcpStream, ToSocketAddrs};
use std::time::Duration;

/// The address a Hokuyo Ethernet sensor leaves the factory with.
pub const FACTORY_ADDRESS: &str = "192.168.0.10:10940";

/// How long to wait for a connection, and for each answer or scan.
const CONNECT_TIMEOUT: Duration = Duration::from_secs(2);
const READ_TIMEOUT: Duration = Duration::from_millis(500);

/// A sensor's `HOST:PORT`.
pub struct TcpLink {
    pub address: String,
}

/// Scans from a sensor over TCP.
pub type TcpSource = ScipSource<TcpLink>;

impl TcpSource {
    pub fn new(address: &str) -> Self {
        ScipSource::on(TcpLink { address: address.into() })
    }
}

impl TcpLink {
    /// The addresses `HOST:PORT` names (looked up again at each connection: a sensor's name
    /// may move).
    fn addresses(&self) -> Result<Vec<SocketAddr>, ScipError> {
        let found = self.address.to_socket_addrs().map_err(ScipError::Io)?;
        Ok(found.collect())
    }
}

impl Connector for TcpLink {
    type Port = TcpStream;

    fn name(&self) -> &str {
        &self.address
    }

    fn open(&mut self) -> Result<Urg<TcpStream>, ScipError> {
        let mut last = None;
        for addr in self.addresses()? {
            match TcpStream::connect_timeout(&addr, CONNECT_TIMEOUT) {
                Ok(stream) => {
                    stream.set_read_timeout(Some(READ_TIMEOUT))?;
                    stream.set_write_timeout(Some(CONNECT_TIMEOUT))?;
                    // commands are short lines answered at once: no Nagle delay
                    stream.set_nodelay(true)?;
                    let mut urg = Urg::new(stream, Duration::from_secs(2));
                    urg.connect()?;
                    return Ok(urg);
                }
                Err(e) => last = Some(e),
            }
        }
        // the source names the address in what it says
        Err(ScipError::Io(last.unwrap_or_else(|| std::io::Error::other("the name has no address"))))
    }
}
