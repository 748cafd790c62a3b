//! The SCIP 2.0 command set of the URG-04LX.

use super::codec::{decode, verified};
use super::frame::{read_frame, Frame, LineReader};
use super::{status_meaning, ScipError, TimestampUnwrapper};
use laser::{LaserScan, ScanGeometry};
use std::io::{Read, Write};
use std::time::{Duration, Instant};

/// The sensor's description from `VV`, `PP` and `II`.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SensorInfo {
    pub vendor: String,
    pub product: String,
    pub firmware: String,
    pub protocol: String,
    pub serial: String,
    pub model: String,
    /// Shortest and longest measurable range, mm.
    pub dmin: u32,
    pub dmax: u32,
    /// Steps in a full turn, first and last measurable step, front step.
    pub ares: u32,
    pub amin: u32,
    pub amax: u32,
    pub afrt: u32,
    /// Motor speed, rpm.
    pub scan_rpm: u32,
    pub laser_on: bool,
    pub state: String,
    /// What `VV` or `II` did not say, and why: a status other than `00` or a line that did not
    /// parse. Neither is needed to scan, so neither stops a connection.
    pub unanswered: Vec<String>,
}

impl SensorInfo {
    fn apply(&mut self, key: &str, value: &str) {
        let num = || value.split(|c: char| !c.is_ascii_digit()).next().and_then(|v| v.parse().ok()).unwrap_or(0);
        match key {
            "VEND" => self.vendor = value.into(),
            "PROD" => self.product = value.into(),
            "FIRM" => self.firmware = value.into(),
            "PROT" => self.protocol = value.into(),
            "SERI" => self.serial = value.into(),
            "MODL" => self.model = value.into(),
            "DMIN" => self.dmin = num(),
            "DMAX" => self.dmax = num(),
            "ARES" => self.ares = num(),
            "AMIN" => self.amin = num(),
            "AMAX" => self.amax = num(),
            "AFRT" => self.afrt = num(),
            "SCAN" => self.scan_rpm = num(),
            "LASR" => self.laser_on = value.starts_with("ON"),
            "STAT" => self.state = value.into(),
            _ => {}
        }
    }

    /// Whether the parameters needed to place beams were reported.
    pub fn usable(&self) -> bool {
        self.ares > 0 && self.amax >= self.amin && self.dmax > self.dmin
    }
}

/// 2 or 3 characters per reading (`MS`/`GS` or `MD`/`GD`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Encoding {
    Two,
    Three,
}

impl Encoding {
    fn width(self) -> usize {
        match self {
            Encoding::Two => 2,
            Encoding::Three => 3,
        }
    }
}

/// One scan as the sensor sent it.
#[derive(Clone, Debug, PartialEq)]
pub struct RawScan {
    /// Sensor time, milliseconds, unwrapped across the 24-bit wrap.
    pub timestamp_ms: u64,
    /// Steps covered and the cluster size.
    pub first_step: u32,
    pub last_step: u32,
    pub cluster: u32,
    /// Readings, mm; values below DMIN are error codes.
    pub ranges_mm: Vec<u32>,
}

impl RawScan {
    /// As a laser scan: readings below `dmin` (error codes) become 0, an invalid reading.
    pub fn to_laser_scan(&self, info: &SensorInfo, stamp: f64) -> LaserScan {
        let step = std::f64::consts::TAU / info.ares as f64;
        let cluster = self.cluster.max(1) as f64;
        let first_centre = self.first_step as f64 + (cluster - 1.0) / 2.0;
        let geometry = ScanGeometry {
            angle_min: (first_centre - info.afrt as f64) * step,
            angle_increment: cluster * step,
            range_min: info.dmin as f64 / 1000.0,
            range_max: info.dmax as f64 / 1000.0,
        };
        let ranges =
            self.ranges_mm.iter().map(|&mm| if mm < info.dmin.max(20) { 0.0 } else { mm as f32 / 1000.0 }).collect();
        LaserScan { geometry, ranges, stamp, truth: None }
    }

    /// How many readings carried each error code (readings below 20 mm).
    pub fn error_codes(&self) -> [u32; 20] {
        let mut counts = [0u32; 20];
        for &mm in &self.ranges_mm {
            if mm < 20 {
                counts[mm as usize] += 1;
            }
        }
        counts
    }
}

/// Counters of what the link suffered.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LinkStats {
    pub scans: u64,
    pub checksum_drops: u64,
    pub resyncs: u64,
}

/// A URG-04LX on any byte transport.
pub struct Urg<T: Read + Write> {
    reader: LineReader<T>,
    pub info: SensorInfo,
    pub stats: LinkStats,
    time: TimestampUnwrapper,
    streaming: Option<(Encoding, u32, u32, u32)>,
    timeout: Duration,
}

fn data_values(lines: &[Vec<u8>], width: usize, expected: usize) -> Result<Vec<u32>, ScipError> {
    let mut chars = Vec::with_capacity(expected * width);
    for l in lines {
        chars.extend_from_slice(verified(l)?);
    }
    if chars.len() != expected * width {
        return Err(ScipError::Malformed(format!(
            "{} data characters for {expected} readings of {width}",
            chars.len()
        )));
    }
    chars.chunks(width).map(decode).collect()
}

impl<T: Read + Write> Urg<T> {
    /// Wraps a transport; `timeout` bounds each wait for an answer.
    pub fn new(port: T, timeout: Duration) -> Self {
        Urg {
            reader: LineReader::new(port),
            info: SensorInfo::default(),
            stats: LinkStats::default(),
            time: TimestampUnwrapper::default(),
            streaming: None,
            timeout,
        }
    }

    fn send(&mut self, cmd: &str) -> Result<(), ScipError> {
        let port = &mut self.reader.inner;
        port.write_all(cmd.as_bytes())?;
        port.write_all(b"\n")?;
        port.flush()?;
        Ok(())
    }

    /// Sends `cmd` and returns its answer, skipping frames of other commands (scan data still
    /// in flight).
    pub fn command(&mut self, cmd: &str) -> Result<Frame, ScipError> {
        self.send(cmd)?;
        let deadline = Instant::now() + self.timeout;
        loop {
            let frame = read_frame(&mut self.reader, &mut self.stats.resyncs)?;
            if frame.echo == cmd {
                return Ok(frame);
            }
            if Instant::now() > deadline {
                return Err(ScipError::Timeout);
            }
        }
    }

    fn expect_ok(&mut self, cmd: &str, ok: &[&str]) -> Result<Frame, ScipError> {
        let f = self.command(cmd)?;
        if ok.contains(&f.status.as_str()) {
            Ok(f)
        } else {
            Err(ScipError::Status { command: cmd.into(), meaning: status_meaning(cmd, &f.status), status: f.status })
        }
    }

    /// Brings the sensor to a known state and reads its description: stops any stream, switches
    /// a SCIP 1.1 sensor to SCIP 2.0, ends a time-adjust mode left open, then `PP` (required),
    /// `VV` and `II` (what they do not answer is noted in [`SensorInfo::unanswered`]).
    pub fn connect(&mut self) -> Result<&SensorInfo, ScipError> {
        // QT twice: the first may be lost in a stream already running, and its answer tells
        // what state the sensor is in
        match self.command("QT") {
            // SCIP 1.1 knows no QT (firmware before 3.x starts in it)
            Ok(f) if f.status == "E" => {
                let f = self.command("SCIP2.0")?;
                if !matches!(f.status.as_str(), "0" | "00" | "0E") {
                    return Err(ScipError::Status {
                        command: "SCIP2.0".into(),
                        meaning: "the sensor speaks SCIP 1.1 and did not switch to SCIP 2.0 (update its firmware)",
                        status: f.status,
                    });
                }
            }
            // time-adjust mode (TM0 without TM2: a client that died reading the clock)
            // refuses everything but TM
            Ok(f) if f.status == "0E" => {
                let _ = self.command("TM2");
            }
            _ => {}
        }
        self.expect_ok("QT", &["00"])?;
        self.streaming = None;
        let mut info = SensorInfo::default();
        // PP places the beams: it must answer, and every line of it must check
        let f = self.expect_ok("PP", &["00"])?;
        for line in &f.lines {
            let (key, value) = parse_info_line(line)?;
            info.apply(&key, &value);
        }
        // VV and II only describe the sensor: one that does not know them (status 0E), or
        // sends a line that does not parse, is still a sensor to scan with
        for cmd in ["VV", "II"] {
            let f = self.command(cmd)?;
            if f.status != "00" {
                info.unanswered.push(format!("{cmd}: status {} ({})", f.status, status_meaning(cmd, &f.status)));
                continue;
            }
            for line in &f.lines {
                match parse_info_line(line) {
                    Ok((key, value)) => info.apply(&key, &value),
                    Err(e) => info.unanswered.push(format!("{cmd}: {e}")),
                }
            }
        }
        if !info.usable() {
            return Err(ScipError::Malformed(format!("PP did not describe the scan area: {info:?}")));
        }
        self.info = info;
        Ok(&self.info)
    }

    /// The transport, to change what the protocol does not (a serial port's bit rate).
    pub fn port_mut(&mut self) -> &mut T {
        &mut self.reader.inner
    }

    /// Forgets received bytes not yet read as a response: what arrived before a change of
    /// bit rate is garbage after it.
    pub fn discard_input(&mut self) {
        self.reader.clear();
    }

    /// Asks an RS-232 sensor to change its bit rate (`SS`); it answers at the old rate, then
    /// switches. Status 03 (already at that rate) counts as done; a USB sensor accepts and
    /// ignores the change.
    pub fn set_bit_rate(&mut self, bps: u32) -> Result<(), ScipError> {
        self.expect_ok(&format!("SS{bps:06}"), &["00", "03"]).map(|_| ())
    }

    /// Switches the laser on (`BM`).
    pub fn laser_on(&mut self) -> Result<(), ScipError> {
        self.expect_ok("BM", &["00", "02"]).map(|_| ())
    }

    /// Stops scanning and switches the laser off (`QT`).
    pub fn stop(&mut self) -> Result<(), ScipError> {
        self.streaming = None;
        self.expect_ok("QT", &["00"]).map(|_| ())
    }

    /// Resets the sensor's settings (`RS`).
    pub fn reset(&mut self) -> Result<(), ScipError> {
        self.streaming = None;
        self.expect_ok("RS", &["00"]).map(|_| ())
    }

    /// Reads the sensor's clock in time-adjust mode (`TM0`, `TM1`, `TM2`), milliseconds.
    pub fn sensor_time(&mut self) -> Result<u64, ScipError> {
        self.expect_ok("TM0", &["00", "02"])?;
        let f = self.expect_ok("TM1", &["00"]);
        let _ = self.expect_ok("TM2", &["00", "03"]);
        let f = f?;
        let line = f.lines.first().ok_or_else(|| ScipError::Malformed("TM1 without time".into()))?;
        Ok(self.time.unwrap(decode(verified(line)?)?))
    }

    /// Starts continuous scanning (`MD` with three-character readings, `MS` with two) of steps
    /// `first..=last`, grouping `cluster` steps per reading; `scans` 0 means until stopped.
    pub fn start(
        &mut self,
        encoding: Encoding,
        first: u32,
        last: u32,
        cluster: u32,
        scans: u32,
    ) -> Result<(), ScipError> {
        check_request(first, last, cluster, scans)?;
        let code = if encoding == Encoding::Three { "MD" } else { "MS" };
        let cmd = format!("{code}{first:04}{last:04}{cluster:02}0{scans:02}");
        self.expect_ok(&cmd, &["00"])?;
        self.streaming = Some((encoding, first, last, cluster));
        Ok(())
    }

    fn readings(first: u32, last: u32, cluster: u32) -> usize {
        ((last - first + 1) as usize).div_ceil(cluster.max(1) as usize)
    }

    fn decode_scan(
        &mut self,
        f: &Frame,
        encoding: Encoding,
        first: u32,
        last: u32,
        cluster: u32,
    ) -> Result<RawScan, ScipError> {
        let (time, data) =
            f.lines.split_first().ok_or_else(|| ScipError::Malformed("scan without timestamp".into()))?;
        let raw = decode(verified(time)?)?;
        let ranges_mm = data_values(data, encoding.width(), Self::readings(first, last, cluster))?;
        self.stats.scans += 1;
        Ok(RawScan { timestamp_ms: self.time.unwrap(raw), first_step: first, last_step: last, cluster, ranges_mm })
    }

    /// The next scan of the running stream. A scan whose data fails its checksum is dropped
    /// and counted, and the error returned: the stream goes on.
    pub fn next_scan(&mut self) -> Result<RawScan, ScipError> {
        let Some((encoding, first, last, cluster)) = self.streaming else {
            return Err(ScipError::Malformed("next_scan without a running MD/MS".into()));
        };
        loop {
            let f = read_frame(&mut self.reader, &mut self.stats.resyncs)?;
            if !(f.echo.starts_with("MD") || f.echo.starts_with("MS")) {
                continue;
            }
            match f.status.as_str() {
                "99" => {}
                "00" => continue, // the acknowledgement of the request
                s => {
                    return Err(ScipError::Status {
                        command: f.echo.clone(),
                        status: s.into(),
                        meaning: status_meaning(&f.echo, s),
                    })
                }
            }
            return match self.decode_scan(&f, encoding, first, last, cluster) {
                Err(ScipError::Checksum(line)) => {
                    self.stats.checksum_drops += 1;
                    Err(ScipError::Checksum(line))
                }
                other => other,
            };
        }
    }

    /// One scan on request (`GD` three-character, `GS` two-character readings).
    pub fn single_scan(
        &mut self,
        encoding: Encoding,
        first: u32,
        last: u32,
        cluster: u32,
    ) -> Result<RawScan, ScipError> {
        check_request(first, last, cluster, 0)?;
        let code = if encoding == Encoding::Three { "GD" } else { "GS" };
        let cmd = format!("{code}{first:04}{last:04}{cluster:02}");
        let f = self.expect_ok(&cmd, &["00"])?;
        self.decode_scan(&f, encoding, first, last, cluster)
    }
}

/// Refuses what a scan request cannot say in its fixed-width fields (4 digits per step, 2 for
/// the cluster and scan counts) and an empty step range, before anything is sent.
fn check_request(first: u32, last: u32, cluster: u32, scans: u32) -> Result<(), ScipError> {
    if last < first || last > 9999 || cluster > 99 || scans > 99 {
        return Err(ScipError::Malformed(format!(
            "a scan request of steps {first}..={last}, cluster {cluster}, {scans} scans: steps must be \
             increasing and at most 9999, cluster and scans at most 99"
        )));
    }
    Ok(())
}

/// `KEY:value;` followed by its checksum, which covers the bytes before the `;` (some firmware
/// includes the `;`: both are accepted).
///
/// The `;` is found by its place, the byte before the checksum, not by its value: a checksum is
/// any byte from `0` to `o`, `;` among them, and so is every character of an encoded value
/// such as II's `TIME`. Looking for the last `;` refused 2 of 6 connections to the emulated
/// sensor in one trial, whose II answers held such lines: `TIME:00G;;;` (value `00G;`,
/// checksum `;`).
pub fn parse_info_line(line: &[u8]) -> Result<(String, String), ScipError> {
    let text = || String::from_utf8_lossy(line).into_owned();
    let colon =
        line.iter().position(|&b| b == b':').ok_or_else(|| ScipError::Malformed(format!("no ':' in {:?}", text())))?;
    let semi = line.len().saturating_sub(2);
    if line.len() < 2 || line[semi] != b';' || semi < colon {
        return Err(ScipError::Malformed(format!("not KEY:value;sum: {:?}", text())));
    }
    let sum = line[semi + 1];
    if super::codec::checksum(&line[..semi]) != sum && super::codec::checksum(&line[..=semi]) != sum {
        return Err(ScipError::Checksum(text()));
    }
    Ok((
        String::from_utf8_lossy(&line[..colon]).into_owned(),
        String::from_utf8_lossy(&line[colon + 1..semi]).into_owned(),
    ))
}
