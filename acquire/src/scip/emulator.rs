//! An emulated Hokuyo sensor (a URG-04LX, UST-10LX or UTM-30LX, [`ScipModel`]): answers SCIP 2.0
//! commands on a pseudo-terminal or a TCP connection with scans from any source, and can
//! misbehave on purpose for tests.

use super::codec::{checksum, data_lines, encode};
use super::model::ScipModel;
use serialport::{SerialPort, TTYPort};
use std::io::{ErrorKind, Read, Write};
use std::net::{TcpListener, TcpStream};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

/// Ways to misbehave.
#[derive(Clone, Copy, Debug, Default)]
pub struct EmulatorFaults {
    /// Corrupt the checksum of this scan's first data line (0-based scan count).
    pub corrupt_scan: Option<u64>,
    /// Write garbage and a partial line before this scan.
    pub garbage_before_scan: Option<u64>,
    /// Stop serving (the caller then closes the port) after this many scans.
    pub close_after_scans: Option<u64>,
    /// Refuse to switch the laser on (`BM` answers status 01).
    pub laser_broken: bool,
    /// Sensor clock at start, milliseconds (set near 2^24 to test the wrap).
    pub start_time_ms: u32,
    /// Start speaking SCIP 1.1, as URG-04LX firmware older than 3.x does after power-up: every
    /// command but `SCIP2.0` is answered with the bare status `E`.
    pub starts_in_scip11: bool,
    /// Start in time-adjust mode (`TM0` sent, `TM2` never: a client that died while reading
    /// the clock): every command but `TM1` and `TM2` is answered with status `0E`.
    pub starts_in_time_adjust: bool,
    /// Connected by RS-232 at this bit rate (the URG-04LX powers up at 19200): a command sent
    /// at another rate arrives as framing errors and is not answered; `SS` changes the rate.
    /// `None`: connected by USB, where the rate does not matter.
    pub rs232_bit_rate: Option<u32>,
    /// Know only the commands scanning needs: `II` is answered with status `0E` (undefined),
    /// and `VV`'s firmware line carries a wrong checksum, as in a minimal third-party
    /// implementation of SCIP 2.0.
    pub minimal_describe: bool,
}

/// Why serving ended.
#[derive(Debug, PartialEq, Eq)]
pub enum ServeEnd {
    Stopped,
    CloseRequested,
    PortClosed,
}

/// A byte link the emulator serves on, and the bit rate its host side set (a serial link's),
/// which an RS-232 sensor must match to understand a command.
pub trait Link: Read + Write {
    fn host_bit_rate(&self) -> Option<u32>;
}

impl Link for TTYPort {
    /// A pseudo-terminal's master side reads the rate its client set.
    fn host_bit_rate(&self) -> Option<u32> {
        self.baud_rate().ok()
    }
}

impl Link for TcpStream {
    fn host_bit_rate(&self) -> Option<u32> {
        None
    }
}

pub type ScanSource = Box<dyn FnMut() -> Vec<u32> + Send>;

pub struct UrgEmulator {
    pub model: ScipModel,
    source: ScanSource,
    pub period: Duration,
    pub faults: EmulatorFaults,
    laser_on: bool,
    origin: Instant,
    pub scans_sent: u64,
    /// (echo prefix, three-character?, first, last, cluster, remaining or 0 for endless)
    stream: Option<(String, bool, u32, u32, u32, u32)>,
    next_scan: Instant,
    scip11: bool,
    time_adjust: bool,
    bit_rate: Option<u32>,
}

fn info_line(key: &str, value: &str, out: &mut Vec<u8>) {
    let body = format!("{key}:{value}");
    out.extend_from_slice(body.as_bytes());
    out.push(b';');
    out.push(checksum(body.as_bytes()));
    out.push(b'\n');
}

fn status(code: &str, out: &mut Vec<u8>) {
    out.extend_from_slice(code.as_bytes());
    out.push(checksum(code.as_bytes()));
    out.push(b'\n');
}

impl UrgEmulator {
    /// An emulated URG-04LX whose scans come from `source` (682 readings in mm, steps
    /// 44..=725), one every `period`.
    pub fn urg04lx(source: ScanSource, period: Duration, faults: EmulatorFaults) -> Self {
        Self::new(ScipModel::URG_04LX, source, period, faults)
    }

    /// An emulated `model` whose scans come from `source` (a reading in mm for each measurable
    /// step, [`ScipModel::readings`]), one every `period`.
    pub fn new(model: ScipModel, source: ScanSource, period: Duration, faults: EmulatorFaults) -> Self {
        UrgEmulator {
            model,
            source,
            period,
            faults,
            laser_on: false,
            origin: Instant::now(),
            scans_sent: 0,
            stream: None,
            next_scan: Instant::now(),
            scip11: faults.starts_in_scip11,
            time_adjust: faults.starts_in_time_adjust,
            bit_rate: faults.rs232_bit_rate,
        }
    }

    fn now_ms(&self) -> u32 {
        (self.faults.start_time_ms as u64 + self.origin.elapsed().as_millis() as u64) as u32 & 0xFF_FFFF
    }

    /// Serves until `stop`, a requested close, or the link closing. The link's own rate stands
    /// for the host's ([`Link::host_bit_rate`]).
    pub fn serve<L: Link>(&mut self, port: &mut L, stop: &AtomicBool) -> std::io::Result<ServeEnd> {
        let mut pending: Vec<u8> = Vec::new();
        let mut buf = [0u8; 512];
        loop {
            if stop.load(Ordering::Relaxed) {
                return Ok(ServeEnd::Stopped);
            }
            match port.read(&mut buf) {
                Ok(0) => return Ok(ServeEnd::PortClosed),
                Ok(n) => pending.extend_from_slice(&buf[..n]),
                Err(e) if matches!(e.kind(), ErrorKind::TimedOut | ErrorKind::WouldBlock | ErrorKind::Interrupted) => {}
                Err(_) => return Ok(ServeEnd::PortClosed),
            }
            while let Some(k) = pending.iter().position(|&b| b == b'\n' || b == b'\r') {
                let line: Vec<u8> = pending.drain(..=k).collect();
                let cmd = String::from_utf8_lossy(&line[..line.len() - 1]).trim().to_owned();
                let garbled = self.bit_rate.is_some_and(|r| port.host_bit_rate() != Some(r));
                if !cmd.is_empty() && !garbled {
                    let reply = self.answer(&cmd);
                    if port.write_all(&reply).is_err() {
                        return Ok(ServeEnd::PortClosed);
                    }
                }
            }
            if self.stream.is_some() && Instant::now() >= self.next_scan {
                if self.faults.close_after_scans.is_some_and(|n| self.scans_sent >= n) {
                    return Ok(ServeEnd::CloseRequested);
                }
                let out = self.scan_frame();
                if port.write_all(&out).is_err() {
                    return Ok(ServeEnd::PortClosed);
                }
                let _ = port.flush();
                self.next_scan += self.period;
            }
        }
    }

    /// Serves one TCP client after another, as an Ethernet sensor does, until `stop`. A
    /// requested close ([`EmulatorFaults::close_after_scans`]) drops that client's connection
    /// once; the next client is served on.
    pub fn serve_clients(&mut self, listener: &TcpListener, stop: &AtomicBool) -> std::io::Result<()> {
        // accept without blocking, to notice a stop between clients
        listener.set_nonblocking(true)?;
        while !stop.load(Ordering::Relaxed) {
            let mut client = match listener.accept() {
                Ok((client, _)) => client,
                Err(e) if matches!(e.kind(), ErrorKind::WouldBlock | ErrorKind::Interrupted) => {
                    std::thread::sleep(Duration::from_millis(20));
                    continue;
                }
                Err(e) => return Err(e),
            };
            client.set_nonblocking(false)?;
            client.set_read_timeout(Some(Duration::from_millis(5)))?;
            client.set_nodelay(true)?;
            let end = self.serve(&mut client, stop)?;
            drop(client);
            self.disconnected();
            match end {
                ServeEnd::Stopped => break,
                ServeEnd::CloseRequested => self.faults.close_after_scans = None,
                ServeEnd::PortClosed => {}
            }
        }
        Ok(())
    }

    /// What a sensor does when its client goes: an Ethernet sensor stops measuring when its
    /// TCP connection closes, and the next client finds it idle.
    pub fn disconnected(&mut self) {
        self.stream = None;
        self.laser_on = false;
        self.time_adjust = false;
    }

    fn answer(&mut self, cmd: &str) -> Vec<u8> {
        let mut out = cmd.as_bytes().to_vec();
        out.push(b'\n');
        let code = cmd.get(..2).unwrap_or("");
        if self.scip11 {
            self.answer_in_scip11(cmd, &mut out);
            return out;
        }
        match code {
            _ if self.time_adjust && code != "TM" => status("0E", &mut out),
            "QT" | "RS" => {
                self.stream = None;
                self.laser_on = false;
                status("00", &mut out);
            }
            "BM" if self.faults.laser_broken => status("01", &mut out),
            "BM" => {
                status(if self.laser_on { "02" } else { "00" }, &mut out);
                self.laser_on = true;
            }
            "II" if self.faults.minimal_describe => status("0E", &mut out),
            "VV" | "PP" | "II" => self.describe(code, &mut out),
            "TM" => self.time_command(cmd, &mut out),
            "MD" | "MS" | "GD" | "GS" => self.scan_command(cmd, &mut out),
            "SS" => self.switch_bit_rate(cmd, &mut out),
            // an unknown command, or SCIP2.0 to a sensor already speaking it
            _ => status("0E", &mut out),
        }
        out.push(b'\n');
        out
    }

    /// A sensor still speaking SCIP 1.1 knows only the switch to 2.0; its status lines carry no
    /// checksum.
    fn answer_in_scip11(&mut self, cmd: &str, out: &mut Vec<u8>) {
        if cmd == "SCIP2.0" {
            self.scip11 = false;
            out.extend_from_slice(b"0\n");
        } else {
            out.extend_from_slice(b"E\n");
        }
        out.push(b'\n');
    }

    /// VV (version), PP (parameters) and II (state): a status, then `KEY:value;sum` lines.
    fn describe(&self, code: &str, out: &mut Vec<u8>) {
        let m = &self.model;
        status("00", out);
        match code {
            "VV" => {
                info_line("VEND", "Hokuyo Automatic Co.,Ltd.", out);
                info_line("PROD", m.product, out);
                info_line("FIRM", "3.4.03(gema2 emulator)", out);
                if self.faults.minimal_describe {
                    // the checksum of the line just written, made wrong
                    let sum = out.len() - 2;
                    out[sum] = if out[sum] == b'0' { b'1' } else { b'0' };
                }
                info_line("PROT", "SCIP 2.0", out);
                info_line("SERI", "H0000000", out);
            }
            "PP" => {
                info_line("MODL", m.name, out);
                for (k, v) in [
                    ("DMIN", m.dmin),
                    ("DMAX", m.dmax),
                    ("ARES", m.ares),
                    ("AMIN", m.amin),
                    ("AMAX", m.amax),
                    ("AFRT", m.afrt),
                    ("SCAN", m.rpm),
                ] {
                    info_line(k, &v.to_string(), out);
                }
            }
            _ => {
                let mut t = Vec::new();
                encode(self.now_ms(), 4, &mut t);
                info_line("MODL", m.name, out);
                info_line("LASR", if self.laser_on { "ON" } else { "OFF" }, out);
                info_line("SCSP", &m.rpm.to_string(), out);
                info_line("MESM", "Measuring mode", out);
                info_line("SBPS", "115200", out);
                info_line("TIME", &String::from_utf8_lossy(&t), out);
                info_line("STAT", "Sensor works well.", out);
            }
        }
    }

    /// TM0 enters the time-adjust mode, TM1 reads the clock in it, TM2 leaves it.
    fn time_command(&mut self, cmd: &str, out: &mut Vec<u8>) {
        match cmd {
            "TM0" | "TM2" => {
                let entering = cmd == "TM0";
                let code = match (entering, self.time_adjust) {
                    (true, true) => "02",   // already in time-adjust mode
                    (false, false) => "03", // already out of it
                    _ => "00",
                };
                status(code, out);
                self.time_adjust = entering;
            }
            "TM1" if !self.time_adjust => status("01", out),
            "TM1" => {
                status("00", out);
                let mut t = Vec::new();
                encode(self.now_ms(), 4, &mut t);
                data_lines(&t, out);
            }
            _ => status("0F", out),
        }
    }

    /// SSnnnnnn: the RS-232 bit rate from the next command on. An Ethernet model has none.
    fn switch_bit_rate(&mut self, cmd: &str, out: &mut Vec<u8>) {
        match cmd.get(2..).filter(|d| d.len() == 6).and_then(|d| d.parse::<u32>().ok()) {
            _ if !self.model.serial => status("04", out),
            None => status("01", out),
            Some(r) if !super::BIT_RATES.contains(&r) => status("02", out),
            Some(r) if self.bit_rate == Some(r) => status("03", out),
            Some(r) => {
                // the answer still goes out at the old rate; USB ignores the rate
                status("00", out);
                self.bit_rate = self.bit_rate.map(|_| r);
            }
        }
    }

    fn scan_command(&mut self, cmd: &str, out: &mut Vec<u8>) {
        let num = |a: usize, b: usize| cmd.get(a..b).and_then(|s| s.parse::<u32>().ok());
        let (Some(first), Some(last), Some(cluster)) = (num(2, 6), num(6, 10), num(10, 12)) else {
            status("01", out);
            return;
        };
        if last > self.model.amax || last < first {
            status("04", out);
            return;
        }
        let three = cmd.starts_with("MD") || cmd.starts_with("GD");
        if cmd.starts_with('G') {
            if !self.laser_on {
                status("10", out);
                return;
            }
            status("00", out);
            self.scan_data(three, first, last, cluster.max(1), out);
            return;
        }
        let Some(scans) = num(13, 15) else {
            status("07", out);
            return;
        };
        status("00", out);
        self.laser_on = true;
        self.stream = Some((cmd[..13].to_owned(), three, first, last, cluster.max(1), scans));
        self.next_scan = Instant::now() + self.period;
    }

    /// Timestamp and data lines of one scan.
    fn scan_data(&mut self, three: bool, first: u32, last: u32, cluster: u32, out: &mut Vec<u8>) {
        let mut t = Vec::new();
        encode(self.now_ms(), 4, &mut t);
        data_lines(&t, out);
        let readings = (self.source)();
        let (amin, amax) = (self.model.amin, self.model.amax);
        let mut data = Vec::new();
        let width = if three { 3 } else { 2 };
        let mut step = first;
        while step <= last {
            let group: Vec<u32> = (step..(step + cluster).min(last + 1))
                .map(|s| {
                    if (amin..=amax).contains(&s) {
                        readings.get((s - amin) as usize).copied().unwrap_or(0)
                    } else {
                        0
                    }
                })
                .collect();
            // the sensor reports the nearest reading of a cluster
            let v = group.iter().copied().filter(|&v| v >= 20).min().unwrap_or(group.first().copied().unwrap_or(0));
            encode(if three { v.min(0x3FFFF) } else { v.min(4095) }, width, &mut data);
            step += cluster;
        }
        data_lines(&data, out);
    }

    fn scan_frame(&mut self) -> Vec<u8> {
        let Some((prefix, three, first, last, cluster, remaining)) = self.stream.clone() else { return Vec::new() };
        let mut out = Vec::new();
        if self.faults.garbage_before_scan == Some(self.scans_sent) {
            out.extend_from_slice(b"\x07#garbage!!\n\nMD00440725\n");
            out.extend_from_slice(&[0x30; 300]);
            out.push(b'\n');
            out.push(b'\n');
        }
        let left = if remaining > 0 { remaining - 1 } else { 0 };
        out.extend_from_slice(format!("{prefix}{left:02}\n").as_bytes());
        status("99", &mut out);
        let start = out.len();
        self.scan_data(three, first, last, cluster, &mut out);
        if self.faults.corrupt_scan == Some(self.scans_sent) {
            // the checksum of the first data line (after the timestamp line: 4 + sum + LF)
            let k = start + 6 + 64;
            if k < out.len() {
                out[k] = if out[k] == b'0' { b'1' } else { b'0' };
            }
        }
        out.push(b'\n');
        self.scans_sent += 1;
        if remaining == 1 {
            self.stream = None;
        } else if remaining > 1 {
            if let Some(s) = self.stream.as_mut() {
                s.5 = remaining - 1;
            }
        }
        out
    }
}
