//! SCIP 2.0 framing: a response is an echo of the command, a status line (two characters and a
//! checksum), data lines, and an empty line. The reader caps line length and, on anything that
//! is not a response, skips to the next empty line (resynchronisation), counting what it
//! threw away.

use super::codec::verified;
use super::ScipError;
use std::io::{ErrorKind, Read};

/// Longest line accepted; longer means garbage.
pub const MAX_LINE: usize = 256;

/// Reads LF-terminated lines from a byte stream.
pub struct LineReader<R: Read> {
    pub inner: R,
    buf: Vec<u8>,
    start: usize,
}

impl<R: Read> LineReader<R> {
    pub fn new(inner: R) -> Self {
        LineReader { inner, buf: Vec::with_capacity(4096), start: 0 }
    }

    /// Forgets what was read but not yet returned (bytes received at a wrong bit rate).
    pub fn clear(&mut self) {
        self.buf.clear();
        self.start = 0;
    }

    /// The next line without its LF (CR before LF is dropped too).
    pub fn read_line(&mut self) -> Result<Vec<u8>, ScipError> {
        loop {
            if let Some(k) = self.buf[self.start..].iter().position(|&b| b == b'\n') {
                let mut line = self.buf[self.start..self.start + k].to_vec();
                self.start += k + 1;
                if line.last() == Some(&b'\r') {
                    line.pop();
                }
                if line.len() > MAX_LINE {
                    return Err(ScipError::Malformed(format!("a line of {} bytes", line.len())));
                }
                return Ok(line);
            }
            if self.buf.len() - self.start > MAX_LINE {
                // no LF in sight: drop what we have and report garbage
                self.buf.clear();
                self.start = 0;
                return Err(ScipError::Malformed(format!("more than {MAX_LINE} bytes without a line end")));
            }
            if self.start > 0 {
                self.buf.drain(..self.start);
                self.start = 0;
            }
            let mut chunk = [0u8; 1024];
            match self.inner.read(&mut chunk) {
                Ok(0) => return Err(ScipError::Closed),
                Ok(n) => self.buf.extend_from_slice(&chunk[..n]),
                Err(e) if e.kind() == ErrorKind::Interrupted => {}
                Err(e) if e.kind() == ErrorKind::TimedOut || e.kind() == ErrorKind::WouldBlock => {
                    return Err(ScipError::Timeout)
                }
                Err(e) => return Err(ScipError::Io(e)),
            }
        }
    }
}

/// One response.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Frame {
    /// The echoed command, e.g. `MD0044072501000`.
    pub echo: String,
    /// The two status characters, e.g. `00` or `99`.
    pub status: String,
    /// Data lines, each still ending in its checksum character.
    pub lines: Vec<Vec<u8>>,
}

/// Whether a line can be the echo of a command: two upper-case letters, then printable ASCII.
fn is_echo(line: &[u8]) -> bool {
    line.len() >= 2
        && line[..2].iter().all(u8::is_ascii_uppercase)
        && line.iter().all(|b| b.is_ascii_graphic() || *b == b' ')
}

/// Reads the next well-formed response; lines that are not one are skipped (up to the next
/// empty line) and counted in `resyncs`. Status checksum failures are errors.
pub fn read_frame<R: Read>(r: &mut LineReader<R>, resyncs: &mut u64) -> Result<Frame, ScipError> {
    let mut skipped = 0usize;
    loop {
        match try_frame(r, resyncs, &mut skipped) {
            // a malformed line inside a frame: drop the frame, look for the next one
            Err(ScipError::Malformed(m)) if skipped <= 10_000 && !m.starts_with("no SCIP response") => {
                *resyncs += 1;
                skipped += 1;
            }
            other => return other,
        }
    }
}

fn try_frame<R: Read>(r: &mut LineReader<R>, resyncs: &mut u64, skipped: &mut usize) -> Result<Frame, ScipError> {
    loop {
        let echo = match r.read_line() {
            Ok(l) => l,
            Err(ScipError::Malformed(_)) => {
                *resyncs += 1;
                continue;
            }
            Err(e) => return Err(e),
        };
        if echo.is_empty() {
            continue; // a stray terminator
        }
        if !is_echo(&echo) {
            *resyncs += 1;
            *skipped += 1;
            if *skipped > 10_000 {
                return Err(ScipError::Malformed("no SCIP response in 10000 lines".into()));
            }
            continue;
        }
        let status_line = r.read_line()?;
        if status_line.is_empty() {
            // SCIP 1.1 style or a garbled frame: no status
            *resyncs += 1;
            continue;
        }
        let status = match status_line.len() {
            // status + checksum
            3 => verified(&status_line)?,
            // some firmware sends a bare status for some commands, and a sensor still speaking
            // SCIP 1.1 a one-character one (`E` for a command it does not know)
            1 | 2 => &status_line[..],
            _ => {
                *resyncs += 1;
                skip_to_end(r)?;
                continue;
            }
        };
        let status = String::from_utf8_lossy(status).into_owned();
        let mut lines = Vec::new();
        loop {
            let line = r.read_line()?;
            if line.is_empty() {
                break;
            }
            lines.push(line);
            if lines.len() > 200 {
                return Err(ScipError::Malformed("a response of more than 200 lines".into()));
            }
        }
        return Ok(Frame { echo: String::from_utf8_lossy(&echo).into_owned(), status, lines });
    }
}

fn skip_to_end<R: Read>(r: &mut LineReader<R>) -> Result<(), ScipError> {
    loop {
        if r.read_line()?.is_empty() {
            return Ok(());
        }
    }
}
