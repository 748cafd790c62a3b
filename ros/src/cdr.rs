//! CDR (OMG Common Data Representation, XCDR1), as ROS 2 serializes its messages: a 4-byte
//! encapsulation header (`00 01` little-endian, `00 00` big-endian, then two option bytes),
//! then each primitive aligned to its own size from the end of that header; strings and
//! sequences as a `u32` length first (a string's counting its closing NUL).
//!
//! The reader checks every length against what is left: a hostile or cut message is an error,
//! never a panic or a huge allocation.
//!
//! The same reader reads ROS 1's serialization ([`Encoding::Ros1`], as in a ROS 1 bag): no
//! encapsulation header, little-endian, nothing aligned, strings without a closing NUL; and
//! a `std_msgs/Header` opens with a `seq` ([`CdrReader::is_ros1`]).

use thiserror::Error;

#[derive(Debug, Error, PartialEq, Eq)]
pub enum CdrError {
    #[error("the message ends at byte {len}, reading {what} needs {need} more")]
    Truncated { what: &'static str, need: usize, len: usize },
    #[error("unknown CDR encapsulation {0:#06x} (ROS 2 writes 0x0000 or 0x0001)")]
    Encapsulation(u16),
    #[error("a string that is not UTF-8, or in CDR not NUL-terminated")]
    BadString,
}

/// How a message's bytes are laid out.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Encoding {
    /// CDR, as ROS 2 writes (on the wire, in rosbag2 bags).
    #[default]
    Cdr,
    /// ROS 1's serialization (in ROS 1 bags).
    Ros1,
}

/// Reads one CDR (or ROS 1) message.
pub struct CdrReader<'a> {
    bytes: &'a [u8],
    /// Position in `bytes`; alignment counts from `origin`.
    pos: usize,
    little: bool,
    /// Where alignment counts from ([`HEADER`] in CDR); `None`: nothing is aligned (ROS 1).
    origin: Option<usize>,
}

/// Bytes of the encapsulation header.
pub const HEADER: usize = 4;

impl<'a> CdrReader<'a> {
    /// A reader of `bytes`, which start with the encapsulation header.
    pub fn new(bytes: &'a [u8]) -> Result<Self, CdrError> {
        let head =
            bytes.get(..HEADER).ok_or(CdrError::Truncated { what: "the header", need: HEADER, len: bytes.len() })?;
        let kind = u16::from_be_bytes([head[0], head[1]]);
        let little = match kind {
            0x0000 | 0x0002 => false, // CDR_BE, PL_CDR_BE
            0x0001 | 0x0003 => true,  // CDR_LE, PL_CDR_LE
            other => return Err(CdrError::Encapsulation(other)),
        };
        Ok(CdrReader { bytes, pos: HEADER, little, origin: Some(HEADER) })
    }

    /// A reader of `bytes` in ROS 1's serialization.
    pub fn ros1(bytes: &'a [u8]) -> Self {
        CdrReader { bytes, pos: 0, little: true, origin: None }
    }

    /// A reader of `bytes` laid out as `encoding` says.
    pub fn of(encoding: Encoding, bytes: &'a [u8]) -> Result<Self, CdrError> {
        match encoding {
            Encoding::Cdr => Self::new(bytes),
            Encoding::Ros1 => Ok(Self::ros1(bytes)),
        }
    }

    /// Whether this reads ROS 1's serialization, whose `std_msgs/Header` has a `seq`.
    pub fn is_ros1(&self) -> bool {
        self.origin.is_none()
    }

    fn take(&mut self, n: usize, align: usize, what: &'static str) -> Result<&'a [u8], CdrError> {
        let start = match self.origin {
            Some(origin) => self.pos + (align - (self.pos - origin) % align) % align,
            None => self.pos,
        };
        let end = start.checked_add(n).filter(|&e| e <= self.bytes.len()).ok_or(CdrError::Truncated {
            what,
            need: start.saturating_add(n).saturating_sub(self.bytes.len()),
            len: self.bytes.len(),
        })?;
        self.pos = end;
        Ok(&self.bytes[start..end])
    }

    fn array<const N: usize>(&mut self, what: &'static str) -> Result<[u8; N], CdrError> {
        let b = self.take(N, N, what)?;
        let mut a = [0u8; N];
        a.copy_from_slice(b);
        if !self.little {
            a.reverse();
        }
        Ok(a)
    }

    pub fn u8(&mut self) -> Result<u8, CdrError> {
        Ok(self.take(1, 1, "a byte")?[0])
    }

    pub fn u32(&mut self) -> Result<u32, CdrError> {
        self.array::<4>("a u32").map(u32::from_le_bytes)
    }

    pub fn i32(&mut self) -> Result<i32, CdrError> {
        self.array::<4>("an i32").map(i32::from_le_bytes)
    }

    pub fn f32(&mut self) -> Result<f32, CdrError> {
        self.array::<4>("an f32").map(f32::from_le_bytes)
    }

    pub fn f64(&mut self) -> Result<f64, CdrError> {
        self.array::<8>("an f64").map(f64::from_le_bytes)
    }

    /// A sequence's length, checked against the bytes left at `size` bytes an element.
    pub fn len(&mut self, size: usize, what: &'static str) -> Result<usize, CdrError> {
        let n = self.u32()? as usize;
        let left = self.bytes.len() - self.pos;
        if n.saturating_mul(size) > left {
            return Err(CdrError::Truncated { what, need: n.saturating_mul(size) - left, len: self.bytes.len() });
        }
        Ok(n)
    }

    pub fn string(&mut self) -> Result<String, CdrError> {
        let n = self.len(1, "a string")?;
        if n == 0 {
            // some writers send an empty string as length 0, no NUL
            return Ok(String::new());
        }
        let b = self.take(n, 1, "a string")?;
        let text = if self.is_ros1() {
            b
        } else {
            let (&nul, text) = b.split_last().ok_or(CdrError::BadString)?;
            if nul != 0 {
                return Err(CdrError::BadString);
            }
            text
        };
        std::str::from_utf8(text).map(str::to_owned).map_err(|_| CdrError::BadString)
    }

    pub fn f32_seq(&mut self) -> Result<Vec<f32>, CdrError> {
        let n = self.len(4, "a float32[]")?;
        (0..n).map(|_| self.f32()).collect()
    }

    pub fn f64_seq(&mut self) -> Result<Vec<f64>, CdrError> {
        let n = self.len(8, "a float64[]")?;
        (0..n).map(|_| self.f64()).collect()
    }

    pub fn bytes_seq(&mut self) -> Result<&'a [u8], CdrError> {
        let n = self.len(1, "a byte[]")?;
        self.take(n, 1, "a byte[]")
    }

    pub fn f64_array<const N: usize>(&mut self) -> Result<[f64; N], CdrError> {
        let mut a = [0.0; N];
        for v in &mut a {
            *v = self.f64()?;
        }
        Ok(a)
    }
}

/// Writes one CDR message, little-endian.
pub struct CdrWriter {
    bytes: Vec<u8>,
}

impl Default for CdrWriter {
    fn default() -> Self {
        Self::new()
    }
}

impl CdrWriter {
    pub fn new() -> Self {
        CdrWriter { bytes: vec![0x00, 0x01, 0x00, 0x00] }
    }

    fn align(&mut self, n: usize) {
        while !(self.bytes.len() - HEADER).is_multiple_of(n) {
            self.bytes.push(0);
        }
    }

    pub fn u8(&mut self, v: u8) {
        self.bytes.push(v);
    }

    pub fn u32(&mut self, v: u32) {
        self.align(4);
        self.bytes.extend_from_slice(&v.to_le_bytes());
    }

    pub fn i32(&mut self, v: i32) {
        self.align(4);
        self.bytes.extend_from_slice(&v.to_le_bytes());
    }

    pub fn f32(&mut self, v: f32) {
        self.align(4);
        self.bytes.extend_from_slice(&v.to_le_bytes());
    }

    pub fn f64(&mut self, v: f64) {
        self.align(8);
        self.bytes.extend_from_slice(&v.to_le_bytes());
    }

    pub fn string(&mut self, s: &str) {
        self.u32(s.len() as u32 + 1);
        self.bytes.extend_from_slice(s.as_bytes());
        self.bytes.push(0);
    }

    pub fn f32_seq(&mut self, v: &[f32]) {
        self.u32(v.len() as u32);
        v.iter().for_each(|&x| self.f32(x));
    }

    pub fn f64_seq(&mut self, v: &[f64]) {
        self.u32(v.len() as u32);
        v.iter().for_each(|&x| self.f64(x));
    }

    pub fn bytes_seq(&mut self, v: &[u8]) {
        self.u32(v.len() as u32);
        self.bytes.extend_from_slice(v);
    }

    pub fn finish(self) -> Vec<u8> {
        self.bytes
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn primitives_are_aligned_from_the_end_of_the_header() {
        let mut w = CdrWriter::new();
        w.u8(7);
        w.f64(1.5);
        w.string("laser");
        w.f32_seq(&[1.0, f32::NAN]);
        let b = w.finish();
        // u8 at 0, f64 padded to 8, string length at 16, "laser\0" at 20..26, seq length at 28
        assert_eq!(b.len(), HEADER + 28 + 4 + 8);
        let mut r = CdrReader::new(&b).unwrap();
        assert_eq!(r.u8().unwrap(), 7);
        assert_eq!(r.f64().unwrap(), 1.5);
        assert_eq!(r.string().unwrap(), "laser");
        let s = r.f32_seq().unwrap();
        assert_eq!(s[0], 1.0);
        assert!(s[1].is_nan());
    }

    #[test]
    fn big_endian_messages_read_the_same() {
        let mut b = vec![0x00, 0x00, 0x00, 0x00];
        b.extend_from_slice(&7u32.to_be_bytes());
        b.extend_from_slice(&[0; 4]);
        b.extend_from_slice(&2.5f64.to_be_bytes());
        let mut r = CdrReader::new(&b).unwrap();
        assert_eq!((r.u32().unwrap(), r.f64().unwrap()), (7, 2.5));
    }

    #[test]
    fn a_length_beyond_the_message_is_an_error_not_an_allocation() {
        let mut w = CdrWriter::new();
        w.u32(u32::MAX);
        let b = w.finish();
        assert!(matches!(CdrReader::new(&b).unwrap().f32_seq(), Err(CdrError::Truncated { .. })));
        assert!(matches!(CdrReader::new(&b).unwrap().string(), Err(CdrError::Truncated { .. })));
        assert!(matches!(CdrReader::new(&[0, 9, 0, 0]), Err(CdrError::Encapsulation(9))));
        assert!(CdrReader::new(&[0, 1]).is_err());
    }
}
