//! `gema2 lines`: segmentation alone over a log, with lines and corners per scan and time per
//! scan: how the paper's line inference fares on real readings.

use super::Malformed;
use crate::report::quantile;
use acquire::urg_log::UrgLogReader;
use acquire::CarmenReader;
use anyhow::{anyhow, bail, Result};
use clap::Args;
use laser::LaserScan;
use segment::{segmenter_by_name, SegmenterConfig, SEGMENTERS};
use std::path::PathBuf;
use std::time::Instant;

#[derive(Args)]
pub struct LinesArgs {
    /// A URG-04LX log (datasets/urg04lx format).
    #[arg(long)]
    pub urg_log: Option<PathBuf>,
    /// A CARMEN log.
    #[arg(long)]
    pub log: Option<PathBuf>,
    #[command(flatten)]
    pub flaser: acquire::FlaserArgs,
    /// Segmenter: line-visibility or split-and-merge.
    #[arg(long = "impl", default_value = "line-visibility")]
    pub implementation: String,
    /// Print the lines and corners of scan N.
    #[arg(long)]
    pub show: Option<usize>,
}

pub fn run(a: LinesArgs) -> Result<()> {
    let scans: Box<dyn Iterator<Item = Result<LaserScan, acquire::LogError>>> = match (&a.urg_log, &a.log) {
        (Some(p), None) => Box::new(UrgLogReader::open(p)?),
        (None, Some(p)) => Box::new(CarmenReader::open(p, a.flaser.layout()?)?.map(|r| r.map(|s| s.scan))),
        _ => bail!("give exactly one of --urg-log and --log"),
    };
    let mut seg = segmenter_by_name(&a.implementation, SegmenterConfig::default())
        .ok_or_else(|| anyhow!("unknown implementation {:?}: {SEGMENTERS:?}", a.implementation))?;
    let (mut lines, mut corners, mut micros, mut valid) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    let mut malformed = Malformed::default();
    // laser lines read, malformed or not: `--show` counts them all, as `locate` numbers scans
    let mut read = 0;
    for (k, scan) in scans.enumerate() {
        read = k + 1;
        // a bad line loses its own scan only, as in `locate`
        let Some(scan) = malformed.take(scan)? else { continue };
        let start = Instant::now();
        let out = seg.segment(&scan.view());
        if a.show == Some(k) {
            println!("scan {k}: {} samples, {} raw lines", out.samples.len(), out.raw_lines.len());
            for l in &out.lines {
                println!(
                    "  line ({:6.3},{:6.3})-({:6.3},{:6.3}) len {:.2} n {} rms {:.4} sigma {:.2} deg",
                    l.start.x,
                    l.start.y,
                    l.end.x,
                    l.end.y,
                    l.length(),
                    l.samples,
                    l.fit.rms(),
                    l.direction_sigma.to_degrees()
                );
            }
            for c in &out.corners {
                println!(
                    "  corner ({:6.3},{:6.3}) beta {:.1} q {:.2}",
                    c.position.x,
                    c.position.y,
                    c.inner_angle.to_degrees(),
                    c.quality
                );
            }
        }
        micros.push(start.elapsed().as_secs_f64() * 1e6);
        lines.push(out.lines.len() as f64);
        corners.push(out.corners.len() as f64);
        valid.push(scan.view().valid_count() as f64);
    }
    let n = lines.len();
    if n == 0 {
        bail!(
            "{}: no laser scan to segment",
            a.urg_log.as_ref().or(a.log.as_ref()).map_or("".into(), |p| p.display().to_string())
        );
    }
    let row = |name: &str, v: &mut Vec<f64>| {
        let (p10, p50, p90) = (quantile(v, 0.1), quantile(v, 0.5), quantile(v, 0.9));
        println!("  {name:24} p10 {p10:8.1}  median {p50:8.1}  p90 {p90:8.1}");
    };
    println!("{n} scans segmented by {}", a.implementation);
    row("valid readings", &mut valid);
    row("lines (after filtering)", &mut lines);
    row("corners", &mut corners);
    row("time per scan (us)", &mut micros);
    if let Some(k) = a.show.filter(|&k| k >= read) {
        bail!("--show {k}: the log holds {read} scans (0 to {})", read - 1);
    }
    malformed.into_result("skipped")?;
    Ok(())
}
