//! `gema2 map corners`: asks a running map server for the corners of its map near an inner
//! angle (and a place), over its corner-query service (`<prefix>/map/corners`). The map server
//! holds the map's corners sorted by inner angle (paper section 5); this is how a tool or a
//! user's program reads them without loading the map itself.

use anyhow::{bail, Context, Result};
use clap::Args;
use messages::{await_response, open_corner_queries, Awaited, CornerQuery};
use std::time::Duration;

#[derive(Args, Debug)]
pub struct CornersArgs {
    /// Inner angle of the corners wanted, degrees (90: a convex right-angled corner seen from
    /// the free side; 270: a concave one).
    #[arg(long, allow_negative_numbers = true)]
    pub angle: f64,
    /// How far the inner angle may be from --angle, degrees.
    #[arg(long, default_value_t = 5.0)]
    pub tolerance: f64,
    /// Only corners within R metres of (X, Y).
    #[arg(long, num_args = 3, value_names = ["X", "Y", "R"], allow_negative_numbers = true)]
    pub near: Vec<f64>,
    /// The running pipeline's service prefix (its `gema2 run --prefix`).
    #[arg(long, default_value = "gema2")]
    pub prefix: String,
    /// Seconds to wait for the map server's answer.
    #[arg(long, default_value_t = 5.0, value_parser = super::positive_seconds)]
    pub timeout: f64,
}

/// The query `a` asks.
fn query(a: &CornersArgs) -> Result<CornerQuery> {
    if !(a.angle.is_finite() && a.tolerance.is_finite() && a.tolerance >= 0.0) {
        bail!("--angle {} --tolerance {}: an angle and a tolerance of at least 0, in degrees", a.angle, a.tolerance);
    }
    let mut q = CornerQuery {
        inner_angle: a.angle.rem_euclid(360.0).to_radians(),
        tolerance: a.tolerance.to_radians(),
        ..CornerQuery::default()
    };
    if let [x, y, r] = a.near[..] {
        if !(x.is_finite() && y.is_finite() && r.is_finite() && r >= 0.0) {
            bail!("--near {x} {y} {r}: a place in metres and a radius of at least 0");
        }
        (q.has_region, q.x, q.y, q.radius) = (1, x, y, r);
    }
    Ok(q)
}

pub fn run(a: CornersArgs) -> Result<()> {
    let q = query(&a)?;
    let node = messages::create_node("corners")?;
    let service = open_corner_queries(&node, &a.prefix)?;
    let client = service.client_builder().create().context("corner queries: client")?;
    let pending = client.send_copy(q).context("corner queries: send")?;
    let reply = match await_response(&node, &pending, Duration::from_secs_f64(a.timeout)).context("corner queries")? {
        Awaited::Answer(reply) => reply,
        Awaited::NoServer => {
            bail!("no map server is serving {}/map/corners (is `gema2 run --prefix {}` running?)", a.prefix, a.prefix)
        }
        Awaited::TimedOut => bail!("no answer from the map server within {} s", a.timeout),
        Awaited::Interrupted => bail!("interrupted while waiting for the map server"),
    };
    let n = (reply.count as usize).min(reply.corners.len());
    println!("# map version {}: {} corners match, {n} listed", reply.map_version, reply.total);
    println!("x\ty\tinner_angle_deg\torientation_deg");
    for c in &reply.corners[..n] {
        println!(
            "{:.3}\t{:.3}\t{:.2}\t{:.2}",
            c.position[0],
            c.position[1],
            c.inner_angle.to_degrees(),
            c.orientation.to_degrees()
        );
    }
    Ok(())
}
