//! `gema2 inspect FILE.rrd`: what a recording holds. rerun is linked into the `viewer` program
//! only, so this hands the files to `viewer inspect`.

use crate::supervisor::child::viewer_binary;
use anyhow::{bail, Context, Result};
use clap::Args;
use std::path::PathBuf;

#[derive(Args, Debug)]
pub struct InspectArgs {
    /// The recording's files, in order (part 0, then the numbered parts).
    #[arg(required = true)]
    pub files: Vec<PathBuf>,
    /// Also print, per scan, the instances of every per-scan entity (tab-separated).
    #[arg(long)]
    pub per_scan: bool,
}

pub fn run(a: InspectArgs) -> Result<()> {
    let viewer = viewer_binary()?;
    let mut cmd = std::process::Command::new(&viewer);
    cmd.arg("inspect").args(&a.files);
    if a.per_scan {
        cmd.arg("--per-scan");
    }
    let status = cmd.status().with_context(|| format!("running {}", viewer.display()))?;
    match status.code() {
        Some(0) => Ok(()),
        // the viewer said why
        Some(code) => std::process::exit(code),
        None => bail!("{} inspect: {status}", viewer.display()),
    }
}
