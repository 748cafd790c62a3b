//! Progress of long commands on a terminal: scans done, their rate, and success so far. It is
//! drawn on stderr only when stderr is a terminal, so logs, pipes and CI get none of it, and
//! results (on stdout) are never mixed with it.

use crate::report::Outcome;
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use std::io::IsTerminal;
use std::path::Path;
use std::time::Duration;

/// A progress line (nothing when stderr is not a terminal), and the outcomes it has been
/// told of through [`add`](Self::add).
pub struct Progress {
    bar: Option<ProgressBar>,
    /// Scans added, those right, and those with a true pose to judge them by.
    tally: (u64, u64, u64),
}

impl Progress {
    /// Counts scans of `what` (a log's name, "poses"), out of `total` when it is known.
    pub fn scans(what: &str, total: Option<u64>) -> Self {
        Self::new(what, total, std::io::stderr().is_terminal())
    }

    /// Counts the scans of the log at `path`, named by its file name after `doing` ("" or
    /// "surveying ").
    pub fn of_log(doing: &str, path: &Path, total: Option<u64>) -> Self {
        let name = path.file_name().map_or_else(|| path.display().to_string(), |n| n.to_string_lossy().into_owned());
        Self::scans(&format!("{doing}{name}"), total)
    }

    fn new(what: &str, total: Option<u64>, on_terminal: bool) -> Self {
        if !on_terminal {
            return Progress { bar: None, tally: (0, 0, 0) };
        }
        let bar = ProgressBar::with_draw_target(total, ProgressDrawTarget::stderr());
        let template = match total {
            Some(_) => "{prefix} [{bar:30}] {pos}/{len} scans{msg} ({elapsed}, {eta} left)",
            None => "{spinner} {prefix} {pos} scans{msg} ({elapsed})",
        };
        if let Ok(style) = ProgressStyle::with_template(template) {
            bar.set_style(style.progress_chars("=> "));
        }
        bar.set_prefix(what.to_owned());
        bar.enable_steady_tick(Duration::from_millis(200));
        Progress { bar: Some(bar), tally: (0, 0, 0) }
    }

    /// One more scan, judged as `gema2 locate` judges it.
    pub fn add(&mut self, o: &Outcome) {
        let (done, right, judged) = &mut self.tally;
        (*done, *right, *judged) = (*done + 1, *right + u64::from(o.success()), *judged + u64::from(o.has_truth));
        let (done, right, judged) = self.tally;
        self.set(done, right, judged);
    }

    /// `done` scans, `right` of the `judged` that had a true pose.
    pub fn set(&self, done: u64, right: u64, judged: u64) {
        if let Some(bar) = &self.bar {
            bar.set_position(done);
            let seconds = bar.elapsed().as_secs_f64();
            let mut msg =
                if seconds > 0.0 { format!(", {:.0} a second", done as f64 / seconds) } else { String::new() };
            if judged > 0 {
                msg += &format!(", success so far {:.1} %", 100.0 * right as f64 / judged as f64);
            }
            bar.set_message(msg);
        }
    }

    /// Removes the progress line.
    pub fn finish(&self) {
        if let Some(bar) = &self.bar {
            bar.finish_and_clear();
        }
    }
}

impl Drop for Progress {
    fn drop(&mut self) {
        self.finish();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nothing_is_drawn_off_a_terminal() {
        let p = Progress::new("log", Some(10), false);
        assert!(p.bar.is_none());
        p.set(3, 2, 3);
        let p = Progress::new("log", None, true);
        assert!(p.bar.is_some());
        p.set(3, 2, 3);
        p.finish();
    }
}
