//! The URG-04LX log format of `../shared/datasets/urg04lx` (BreezySLAM's `exp1.dat`): one scan
//! a line; token 0 is a timestamp in microseconds, tokens 24 onwards are 682 ranges in mm for
//! steps 44..=725 (0: no return). Errors name the file and line.

use crate::carmen::{next_line, open_log, LineBuf, LogError};
use laser::{LaserScan, ScanGeometry};
use std::io::BufRead;
use std::path::{Path, PathBuf};

/// Readings per line.
pub const READINGS: usize = 682;
/// Index of the first reading among a line's tokens.
pub const FIRST_READING: usize = 24;

pub struct UrgLogReader {
    reader: Box<dyn BufRead + Send>,
    path: PathBuf,
    line: usize,
    buf: LineBuf,
}

impl UrgLogReader {
    pub fn open(path: &Path) -> Result<Self, LogError> {
        Ok(Self::from_reader(open_log(path)?, path))
    }

    /// Reads lines from `reader`; `path` names it in errors.
    pub fn from_reader(reader: Box<dyn BufRead + Send>, path: &Path) -> Self {
        UrgLogReader { reader, path: path.to_owned(), line: 0, buf: LineBuf::default() }
    }

    fn parse(&self) -> Result<LaserScan, String> {
        let tokens: Vec<&str> = self.buf.text.split_ascii_whitespace().collect();
        if tokens.len() < FIRST_READING + READINGS {
            return Err(format!("{} tokens, a scan needs {}", tokens.len(), FIRST_READING + READINGS));
        }
        let micros: f64 = tokens[0].parse().map_err(|_| format!("timestamp {:?} is not a number", tokens[0]))?;
        let geometry = ScanGeometry::urg04lx();
        let ranges = tokens[FIRST_READING..FIRST_READING + READINGS]
            .iter()
            .map(|t| match t.parse::<u32>() {
                Ok(0) => Ok(geometry.range_max as f32),
                Ok(mm) if mm < 20 => Ok(0.0),
                Ok(mm) => Ok(mm as f32 / 1000.0),
                Err(_) => Err(format!("range {t:?} is not a whole number of mm")),
            })
            .collect::<Result<Vec<f32>, String>>()?;
        Ok(LaserScan { geometry, ranges, stamp: micros / 1e6, truth: None })
    }
}

impl Iterator for UrgLogReader {
    type Item = Result<LaserScan, LogError>;

    fn next(&mut self) -> Option<Self::Item> {
        loop {
            if let Err(e) = next_line(&mut self.reader, &mut self.buf, &mut self.line, &self.path)? {
                return Some(Err(e));
            }
            if self.buf.text.trim().is_empty() {
                continue;
            }
            return Some(self.parse().map_err(|message| LogError::Line {
                path: self.path.clone(),
                line: self.line,
                message,
            }));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lines_become_urg_scans_and_bad_ones_name_the_line() {
        let dir = std::env::temp_dir().join(format!("urglog{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("x.dat");
        let mut good = vec!["1500000".to_owned()];
        good.extend((1..24).map(|k| k.to_string()));
        good.extend((0..READINGS).map(|k| {
            if k == 0 {
                "0".into()
            } else if k == 1 {
                "7".into()
            } else {
                "1234".into()
            }
        }));
        std::fs::write(&path, format!("{}\n\n1 2 3\n", good.join(" "))).unwrap();
        let mut r = UrgLogReader::open(&path).unwrap();
        let s = r.next().unwrap().unwrap();
        assert_eq!(s.ranges.len(), READINGS);
        assert_eq!((s.ranges[0], s.ranges[1], s.ranges[2]), (5.6, 0.0, 1.234));
        assert!((s.stamp - 1.5).abs() < 1e-12);
        let err = r.next().unwrap().unwrap_err().to_string();
        assert!(err.contains("x.dat:3"), "{err}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
