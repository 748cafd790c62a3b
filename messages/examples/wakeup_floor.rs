//! The floor under every pipeline hop on this machine: how long a bare iceoryx2 listener takes
//! to wake up and receive a scan message, with nothing of gema2 around it.
//!
//! ```sh
//! cargo build --release -p messages --example wakeup_floor
//! E=target/release/examples/wakeup_floor
//! taskset -c 1 $E listen block & sleep 0.3; taskset -c 0 $E send; wait   # cross-core
//! taskset -c 0 $E listen block & sleep 0.3; taskset -c 0 $E send; wait   # same core
//! ```
//!
//! `listen` takes `block` (the listener's own blocking wait) or `waitset` (a WaitSet with the
//! 50 ms poll, as the stages wait). The sender sends 400 scans at 100 Hz; the listener prints
//! p50/p90/p99 of send-to-receive in microseconds. Compare with `gema2 bench --pipeline`'s
//! hops.

use anyhow::{anyhow, bail, Result};
use iceoryx2::prelude::*;
use messages::*;
use std::time::Duration;

const PREFIX: &str = "wakeup_floor";
const SCANS: usize = 400;

fn main() -> Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let node = create_node("wakeup_floor")?;
    match args.first().map(String::as_str) {
        Some("send") => send(&node),
        Some("listen") => listen(&node, args.get(1).map(String::as_str).unwrap_or("block")),
        _ => bail!("usage: wakeup_floor send | listen [block|waitset]"),
    }
}

fn send(node: &Node<ipc::Service>) -> Result<()> {
    let mut out = Outlet::<ScanMsg>::open(node, PREFIX, Topic::Scan, BackpressureStrategy::RetryUntilDelivered)?;
    for seq in 0..SCANS as u64 {
        if node.wait(Duration::from_millis(10)).is_err() {
            break;
        }
        out.send(|m: &mut ScanMsg| {
            m.header = Header::new(seq, monotonic_ns());
            m.header.span(Stage::Acquire).leave_ns = monotonic_ns();
        })
        .map_err(|e| anyhow!("{}: {e}", out.name()))?;
    }
    Ok(())
}

fn listen(node: &Node<ipc::Service>, how: &str) -> Result<()> {
    let topic = open_topic::<ScanMsg>(node, PREFIX, Topic::Scan)?;
    let sub = topic.data.subscriber_builder().create().map_err(|e| anyhow!("subscriber: {e:?}"))?;
    let listener = topic.event.listener_builder().create().map_err(|e| anyhow!("listener: {e:?}"))?;
    let mut micros = Vec::with_capacity(SCANS);
    let take = |micros: &mut Vec<f64>| {
        while let Ok(Some(s)) = sub.receive() {
            let sent = s.header.stages[Stage::Acquire as usize].leave_ns;
            micros.push(monotonic_ns().saturating_sub(sent) as f64 / 1e3);
        }
    };
    match how {
        "block" => {
            while micros.len() < SCANS {
                listener.blocking_wait(|_| {}).map_err(|e| anyhow!("wait: {e:?}"))?;
                take(&mut micros);
            }
        }
        "waitset" => {
            let waitset = WaitSetBuilder::new().create::<ipc::Service>().map_err(|e| anyhow!("waitset: {e:?}"))?;
            let _woken = waitset.attach_notification(&listener).map_err(|e| anyhow!("waitset: {e:?}"))?;
            let _poll = waitset.attach_interval(MISSED_WAKEUP_POLL).map_err(|e| anyhow!("waitset: {e:?}"))?;
            waitset
                .wait_and_process(|_| {
                    let _ = listener.try_wait(|_| {});
                    take(&mut micros);
                    if micros.len() >= SCANS {
                        CallbackProgression::Stop
                    } else {
                        CallbackProgression::Continue
                    }
                })
                .map_err(|e| anyhow!("waitset: {e:?}"))?;
        }
        other => bail!("listen {other:?}: block or waitset"),
    }
    micros.sort_by(f64::total_cmp);
    let q = |f: f64| micros[((micros.len() - 1) as f64 * f).round() as usize];
    println!(
        "{how}: {} scans, send to receive p50 {:.1} us, p90 {:.1}, p99 {:.1}",
        micros.len(),
        q(0.5),
        q(0.9),
        q(0.99)
    );
    Ok(())
}
