//! What the supervisor learns from the poses it receives: latency per stage and per IPC hop
//! (from the per-stage enter/leave times every header carries), throughput, accuracy.

use crate::report::{SUCCESS_HEADING_DEG, SUCCESS_POSITION};
use messages::{latency, Freshness, PoseMsg, Stage, STATUS_FAILED};
use std::io::Write;

/// The figures every reader of a pose reports ([`messages::latency::FIGURES`]), then the two
/// only the supervisor can, as the pose's consumer.
pub const CONSUMER_FIGURES: [&str; 2] = ["hop localize -> supervisor", "end to end (acquisition -> pose received)"];

/// The latest poses whose latency figures the report reads: about 27 minutes at 40 Hz, 4 MB.
/// A run of days keeps no more.
pub const FIGURES_KEPT: usize = 1 << 16;

/// What the supervisor keeps of the poses: counts, the latest [`FIGURES_KEPT`] poses' latency
/// figures, and, with `--out`, each pose's CSV row written as it comes. Nothing grows with the
/// length of the run: a pipeline deployed on a robot runs for days.
pub struct Monitor<W: Write> {
    /// Per pose: [`messages::latency::of_pose`], then [`CONSUMER_FIGURES`]; the latest
    /// [`FIGURES_KEPT`].
    figures: latency::Latest<[f64; 8]>,
    pub received: u64,
    pub right: u64,
    pub with_truth: u64,
    pub first_ns: Option<u64>,
    pub last_ns: u64,
    /// Where the rows go, and the first error writing them (the rest are not tried).
    csv: Option<W>,
    csv_error: Option<std::io::Error>,
    /// Skips copies of a pose (a resend to a late-connecting subscriber).
    fresh: Freshness,
}

impl<W: Write> Monitor<W> {
    /// A monitor writing the poses' rows to `csv` (its header first) when given.
    pub fn new(csv: Option<W>) -> Self {
        let mut m = Monitor {
            figures: latency::Latest::new(FIGURES_KEPT),
            received: 0,
            right: 0,
            with_truth: 0,
            first_ns: None,
            last_ns: 0,
            csv,
            csv_error: None,
            fresh: Freshness::default(),
        };
        m.write_row(crate::report::CSV_HEADER);
        m
    }

    fn write_row(&mut self, row: &str) {
        if self.csv_error.is_some() {
            return;
        }
        if let Some(w) = self.csv.as_mut() {
            if let Err(e) = writeln!(w, "{row}") {
                self.csv_error = Some(e);
            }
        }
    }

    /// The rows' writer, flushed, or the first error writing to it.
    pub fn finish_csv(mut self) -> Result<Option<W>, std::io::Error> {
        if let Some(e) = self.csv_error.take() {
            return Err(e);
        }
        match self.csv.take() {
            Some(mut w) => w.flush().map(|()| Some(w)),
            None => Ok(None),
        }
    }

    pub fn record(&mut self, p: &PoseMsg, received_ns: u64) {
        if !self.fresh.admit(&p.header) {
            return;
        }
        let h = &p.header;
        let l = h.stages[Stage::Localize as usize];
        let [a, hop_scan, s, hop_corners, localize, published] = latency::of_pose(h);
        let consumer = [latency::between_us(l.leave_ns, received_ns), latency::between_us(h.stamp_ns, received_ns)];
        self.figures.push([a, hop_scan, s, hop_corners, localize, published, consumer[0], consumer[1]]);
        self.received += 1;
        self.first_ns.get_or_insert(received_ns);
        self.last_ns = received_ns;
        let best = (p.status != STATUS_FAILED && p.count > 0).then(|| p.hypotheses[0]);
        if p.has_truth != 0 {
            self.with_truth += 1;
            if let Some(b) = best {
                let t = p.truth;
                let d = (b.pose.x - t.x).hypot(b.pose.y - t.y);
                let a = laser::angle_diff(b.pose.theta, t.theta).abs().to_degrees();
                if d <= SUCCESS_POSITION && a <= SUCCESS_HEADING_DEG {
                    self.right += 1;
                }
            }
        }
        if self.csv.is_none() {
            return;
        }
        // a code no localizer sends counts as no answer
        let status = match messages::status_name(p.status) {
            "unknown" => "failed",
            name => name,
        };
        let micros = localize + s;
        let row = crate::report::csv_row(
            h.seq as usize,
            best.map(|b| (b.pose.x, b.pose.y, b.pose.theta, b.cost, b.inliers, b.through)),
            status,
            micros,
            p.count as usize,
            p.candidates as usize,
            if best.is_some() { p.scans.max(1) } else { 0 },
        );
        self.write_row(&row);
    }

    pub fn render(&self, published: Option<u64>) -> String {
        let title = match self.received > self.figures.len() as u64 {
            true => format!("latency (us), the last {} poses", self.figures.len()),
            false => "latency (us)".to_owned(),
        };
        let mut s = format!("{title:47}p50       p99\n");
        let labels = latency::FIGURES.iter().map(|f| f.label).chain(CONSUMER_FIGURES);
        for (k, name) in labels.enumerate() {
            let v: Vec<f64> = self.figures.iter().map(|f| f[k]).collect();
            let (p50, p99) = latency::p50_p99(&v);
            s += &format!("  {name:42} {p50:8.1}  {p99:8.1}\n");
        }
        let secs = (self.last_ns.saturating_sub(self.first_ns.unwrap_or(self.last_ns))) as f64 / 1e9;
        let rate = if secs > 0.0 { (self.received.saturating_sub(1)) as f64 / secs } else { f64::NAN };
        s += &format!("poses received {}", self.received);
        if let Some(n) = published {
            s += &format!(" of {n} scans published");
        }
        s += &format!(", throughput {rate:.1} scans/s\n");
        if self.with_truth > 0 {
            s += &format!(
                "success {:.1} % (within {SUCCESS_POSITION} m and {SUCCESS_HEADING_DEG} deg)\n",
                100.0 * self.right as f64 / self.with_truth as f64
            );
        }
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use messages::Zeroable;

    /// However long a run, the monitor keeps the latest [`FIGURES_KEPT`] poses' figures and no
    /// rows: each pose's row is written as it comes, and the report says which poses its
    /// latency is over.
    #[test]
    fn a_long_run_keeps_a_bounded_window_and_writes_every_row() {
        let poses = FIGURES_KEPT as u64 + 10;
        let mut monitor = Monitor::new(Some(Vec::new()));
        let start = messages::monotonic_ns().saturating_sub(10 * poses);
        for seq in 0..poses {
            let mut p = PoseMsg::zeroed();
            p.header = messages::Header::new(seq, start + seq);
            monitor.record(&p, start + seq + 1);
        }
        assert_eq!((monitor.received, monitor.figures.len()), (poses, FIGURES_KEPT));
        assert!(monitor.render(None).starts_with(&format!("latency (us), the last {FIGURES_KEPT} poses")));
        let csv = monitor.finish_csv().expect("written").expect("a writer");
        let text = String::from_utf8(csv).expect("UTF-8");
        assert_eq!(text.lines().count() as u64, poses + 1, "a header and a row a pose");
        assert!(text.starts_with(crate::report::CSV_HEADER));
    }

    /// Without `--out` no row is kept or made.
    #[test]
    fn without_an_output_no_row_is_kept() {
        let mut monitor: Monitor<Vec<u8>> = Monitor::new(None);
        let now = messages::monotonic_ns();
        let mut p = PoseMsg::zeroed();
        p.header = messages::Header::new(0, now.saturating_sub(1000));
        monitor.record(&p, now);
        assert_eq!(monitor.received, 1);
        assert!(monitor.render(None).starts_with("latency (us)  "));
        assert!(monitor.finish_csv().expect("nothing to write").is_none());
    }
}
