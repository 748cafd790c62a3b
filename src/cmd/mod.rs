//! One module per subcommand.

pub mod amcl;
pub mod bench;
pub mod bench_memory;
pub mod build_map;
pub mod corners;
pub mod demo;
pub mod emulate;
pub mod evaluate;
pub mod inspect;
pub mod lines;
pub mod locate;
pub mod map;
pub mod odometry;
pub mod scans;
pub mod settings;
pub mod sim;

/// A scratch folder of this run, `<temp>/gema2-<what>-<pid>`, removed when dropped, however
/// the command ends.
pub struct ScratchDir(std::path::PathBuf);

impl ScratchDir {
    pub fn new(what: &str) -> anyhow::Result<Self> {
        use anyhow::Context;
        let dir = std::env::temp_dir().join(format!("gema2-{what}-{}", std::process::id()));
        std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
        Ok(ScratchDir(dir))
    }

    pub fn path(&self) -> &std::path::Path {
        &self.0
    }
}

impl Drop for ScratchDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// A child process killed (and reaped) when dropped, however the command that started it ends.
pub struct KilledOnDrop(pub std::process::Child);

impl Drop for KilledOnDrop {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// Parses a count that must be at least 1: `--every` (every 0th scan selects nothing),
/// `sim --scans` (an empty log is no test of anything).
pub fn positive_count(s: &str) -> Result<usize, String> {
    match s.parse::<usize>() {
        Ok(0) => Err("must be at least 1".to_owned()),
        Ok(n) => Ok(n),
        Err(e) => Err(e.to_string()),
    }
}

/// Parses a beam count of a simulated scan: at least 2, so that there are beams to space.
pub fn beam_count(s: &str) -> Result<usize, String> {
    match s.parse::<usize>() {
        Ok(n) if n < 2 => Err("a scan needs at least 2 beams".to_owned()),
        Ok(n) => Ok(n),
        Err(e) => Err(e.to_string()),
    }
}

/// Parses a duration in seconds: a finite number above 0.
pub fn positive_seconds(s: &str) -> Result<f64, String> {
    match s.parse::<f64>() {
        Ok(v) if v.is_finite() && v > 0.0 => Ok(v),
        Ok(_) => Err("must be a number of seconds above 0".to_owned()),
        Err(e) => Err(e.to_string()),
    }
}

/// Whether laser line `index` (from 0) is one of every `every`-th from `offset` on
/// (`--every`, `--offset`); `every` is at least 1 (see [`positive_count`]).
pub fn selected(index: usize, every: usize, offset: usize) -> bool {
    index >= offset && (index - offset).is_multiple_of(every.max(1))
}

/// The malformed laser lines a run skipped: each is reported as it is met, up to
/// [`Malformed::REPORTED`] of them, and all are counted.
#[derive(Default)]
pub struct Malformed {
    count: usize,
    first: Option<String>,
    /// Counts without reporting ([`Malformed::silent`]).
    silent: bool,
    /// What a scan is in the source: "laser line" when not said.
    unit: Option<&'static str>,
}

impl Malformed {
    const REPORTED: usize = 10;

    /// One that calls the scans `unit` ("LaserScan message").
    pub fn of(unit: &'static str) -> Self {
        Malformed { unit: Some(unit), ..Malformed::default() }
    }

    /// One that counts the lines without reporting them: for another pass over a log whose
    /// malformed lines were reported already.
    pub fn silent() -> Self {
        Malformed { silent: true, ..Malformed::default() }
    }

    pub fn add(&mut self, e: impl std::fmt::Display) {
        self.count += 1;
        if !self.silent {
            if self.count <= Self::REPORTED {
                eprintln!("skipped {e}");
            } else if self.count == Self::REPORTED + 1 {
                eprintln!("(more malformed {}s: counted, not shown)", self.unit());
            }
        }
        self.first.get_or_insert_with(|| e.to_string());
    }

    /// A reader's item as the run takes it: the scan, or `None` for a malformed line, added
    /// here; a log that cannot be read on stays an error.
    pub fn take<T>(&mut self, item: Result<T, acquire::LogError>) -> Result<Option<T>, acquire::LogError> {
        match item {
            Ok(item) => Ok(Some(item)),
            Err(e @ acquire::LogError::Line { .. }) => {
                self.add(e);
                Ok(None)
            }
            Err(e) => Err(e),
        }
    }

    fn unit(&self) -> &'static str {
        self.unit.unwrap_or("laser line")
    }

    /// An error when any line was skipped, saying how many and naming the first; what was
    /// done with them is `done` ("skipped").
    pub fn into_result(self, done: &str) -> anyhow::Result<()> {
        match &self.first {
            Some(first) => {
                let n = self.count;
                anyhow::bail!(
                    "{n} malformed {}{} {done}, the first {first}",
                    self.unit(),
                    if n == 1 { "" } else { "s" }
                )
            }
            None => Ok(()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts_and_durations_that_measure_nothing_are_refused() {
        assert_eq!(positive_count("3"), Ok(3));
        assert!(positive_count("0").unwrap_err().contains("at least 1"));
        assert!(positive_count("-1").is_err());
        assert_eq!(beam_count("2"), Ok(2));
        assert!(beam_count("1").is_err() && beam_count("0").is_err());
        assert_eq!(positive_seconds("0.5"), Ok(0.5));
        for bad in ["0", "-2", "inf", "NaN", "x"] {
            assert!(positive_seconds(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn every_and_offset_select_from_the_offset_on() {
        let picked = |every, offset| (0..10).filter(|&k| selected(k, every, offset)).collect::<Vec<_>>();
        assert_eq!(picked(1, 0), (0..10).collect::<Vec<_>>());
        assert_eq!(picked(2, 1), [1, 3, 5, 7, 9]);
        assert_eq!(picked(3, 4), [4, 7]);
        // an offset past the last line selects nothing, not the offset's residue
        assert!(picked(1, 10).is_empty());
        assert_eq!(picked(2, 5), [5, 7, 9]);
    }
}
