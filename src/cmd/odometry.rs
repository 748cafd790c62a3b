//! `gema2 odometry`: how far a log's odometry strays from its true poses, as the four alphas of
//! the odometry motion model (AMCL's), which the sequential localizer takes as `odom_alpha1`
//! to `odom_alpha4` ([`laser::motion::OdometryNoise::fit`]).

use super::scans::{ScanArgs, SourceError};
use anyhow::{bail, Result};
use clap::Args;
use laser::motion::OdometryNoise;
use laser::Pose;

#[derive(Args, Debug)]
pub struct OdometryArgs {
    /// A log whose scans carry the true pose (SLAM-corrected or simulated) and odometry (ODOM
    /// lines, FLASER's odometry, ROBOTLASER1's robot pose), or a bag with its --truth-topic and
    /// --odom-topic; the motions between every K-th scan (`--every`).
    #[command(flatten)]
    pub scans: ScanArgs,
}

/// The margin the sequential localizer's defaults keep over the noise they are measured with
/// (0.1, 0.02, 0.1, 0.02 against 0.05, 0.01, 0.05, 0.01): the settings suggested.
const MARGIN: f64 = 2.0;

pub fn run(a: OdometryArgs) -> Result<()> {
    let source = a.scans.open()?;
    // (truth, odometry) of the selected scans that have both
    let mut poses: Vec<Option<(Pose, Pose)>> = Vec::new();
    let (mut unread, mut without) = (0usize, 0usize);
    for (index, item) in source.scans.enumerate() {
        if !a.scans.takes(index) {
            continue;
        }
        match item {
            Ok(s) => {
                let both = s.scan.truth.zip(s.odometry);
                without += usize::from(both.is_none());
                poses.push(both);
            }
            Err(SourceError::Skip(_)) => {
                unread += 1;
                poses.push(None);
            }
            Err(SourceError::Stop(e)) => return Err(e),
        }
    }
    let motions: Vec<_> = poses
        .windows(2)
        .filter_map(|w| match (w[0], w[1]) {
            (Some((ta, oa)), Some((tb, ob))) => Some((ta, tb, oa, ob)),
            _ => None,
        })
        .collect();
    let Some(fit) = OdometryNoise::fit(&motions) else {
        bail!(
            "{}: {} motions between scans with both a true pose and odometry ({without} scans lack one, {unread} \
             could not be read): too few to fit",
            source.path.display(),
            motions.len()
        );
    };
    let [a1, a2, a3, a4] = fit.noise.alphas;
    println!(
        "{}: odometry against the true poses over {} motions between every {} scan(s) ({} left out: drives \
         taken for turns or the other way, or errors beyond four standard deviations)",
        source.path.display(),
        fit.used,
        a.scans.every,
        fit.left_out
    );
    println!("alphas (AMCL's): a1 {a1:.4}  a2 {a2:.4}  a3 {a3:.4}  a4 {a4:.4}");
    let set = |k: usize, v: f64| format!("--set odom_alpha{k}={:.4}", v * MARGIN);
    println!(
        "for the sequential localizer, with its margin of {MARGIN}x: {} {} {} {}",
        set(1, a1),
        set(2, a2),
        set(3, a3),
        set(4, a4)
    );
    if without > 0 || unread > 0 {
        println!(
            "({without} scans lack a true pose or odometry, {unread} could not be read: their motions are not counted)"
        );
    }
    Ok(())
}
