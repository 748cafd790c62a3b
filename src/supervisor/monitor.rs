//! What the supervisor learns from the poses it receives: latency per stage and per IPC hop
//! (from the per-stage enter/leave times every header carries), throughput, accuracy.

use crate::report::{SUCCESS_HEADING_DEG, SUCCESS_POSITION};
use messages::{latency, Freshness, PoseMsg, Stage, STATUS_FAILED};
use std::io::Write;

/// The figures every reader of a pose reports ([`messages::latency::FIGURES`]), then the two
/// only the supervisor can, as the pose's consumer.
pub const CONSUMER_FIGURES: [&str; 2] = ["hop localize -> supervisor", "end to end (acquisition -> pose received)"];

#[derive(Default)]
pub struct Monitor {
    /// Per pose: [`messages::latency::of_pose`], then [`CONSUMER_FIGURES`].
    pub figures: Vec<[f64; 8]>,
    pub received: u64,
    pub right: u64,
    pub with_truth: u64,
    pub first_ns: Option<u64>,
    pub last_ns: u64,
    pub seqs: Vec<u64>,
    pub rows: Vec<String>,
    /// Skips copies of a pose (a resend to a late-connecting subscriber).
    fresh: Freshness,
}

impl Monitor {
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
        self.seqs.push(h.seq);
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
        // a code no localizer sends counts as no answer
        let status = match messages::status_name(p.status) {
            "unknown" => "failed",
            name => name,
        };
        let micros = localize + s;
        self.rows.push(crate::report::csv_row(
            h.seq as usize,
            best.map(|b| (b.pose.x, b.pose.y, b.pose.theta, b.cost, b.inliers, b.through)),
            status,
            micros,
            p.count as usize,
            p.candidates as usize,
            if best.is_some() { p.scans.max(1) } else { 0 },
        ));
    }

    pub fn write_csv(&self, w: &mut impl Write) -> std::io::Result<()> {
        writeln!(w, "{}", crate::report::CSV_HEADER)?;
        for r in &self.rows {
            writeln!(w, "{r}")?;
        }
        Ok(())
    }

    pub fn render(&self, published: Option<u64>) -> String {
        let mut s = String::from("latency (us)                                   p50       p99\n");
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
