//! The floor under every pipeline hop on this machine: how long a bare iceoryx2 listener takes
//! to wake up and receive a scan message, with nothing of gema2 around it.
//!
//! ```sh
//! cargo build --release -p messages --example wakeup_floor
//! E=target/release/examples/wakeup_floor
//! taskset -c 1 $E listen block & sleep 0.3; taskset -c 0 $E send; wait   # cross-core
//! taskset -c 0 $E listen block & sleep 0.3; taskset -c 0 $E send; wait   # same core
//! $E raw 1 0; $E raw 0 0                                                  # the kernel alone
//! ```
//!
//! `listen` takes `block` (the listener's own blocking wait) or `waitset` (a WaitSet with the
//! 50 ms poll, as the stages wait). The sender sends 400 scans at 100 Hz; the listener prints
//! p50/p90/p99 of send-to-receive in microseconds. Compare with `gema2 bench --pipeline`'s
//! hops.
//!
//! `raw RECEIVER_CPU SENDER_CPU [PERIOD_MS [LEAD_US]]` measures the kernel alone, without
//! iceoryx2: a forked receiver blocks on an eventfd (what a futex or pipe costs too) and then on
//! a Unix datagram socket pair (the trigger iceoryx2 0.10's `ipc::Service` events use), woken
//! 400 times every PERIOD_MS (default 10). It prints the wake-up (write to the receiver
//! running) and the writer's own system call time. With LEAD_US the receiver is also woken
//! that long before each measured wake-up, as the pipeline's warm-up does (`acquire
//! --warm-up-us`): `$E raw 1 0 100` against `$E raw 1 0 100 200`.

use anyhow::{anyhow, bail, Context, Result};
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
        Some("raw") => {
            let cpu = |i: usize| {
                args.get(i).and_then(|a| a.parse().ok()).ok_or_else(|| anyhow!("raw RECEIVER_CPU SENDER_CPU"))
            };
            let (receiver, sender) = (cpu(1)?, cpu(2)?);
            let number = |i: usize, default: u64| args.get(i).map_or(Ok(default), |a| a.parse::<u64>());
            let period = Duration::from_millis(number(3, 10)?);
            let lead = Duration::from_micros(number(4, 0)?).min(period);
            raw("eventfd", receiver, sender, period, lead)?;
            raw("unix datagram", receiver, sender, period, lead)
        }
        _ => bail!(
            "usage: wakeup_floor send | listen [block|waitset] | raw RECEIVER_CPU SENDER_CPU [PERIOD_MS [LEAD_US]]"
        ),
    }
}

/// One kernel wake-up mechanism between two processes: (receiver's fd, sender's fd).
fn raw_channel(kind: &str) -> Result<(i32, i32)> {
    // SAFETY: plain system calls creating file descriptors this process owns.
    unsafe {
        if kind == "eventfd" {
            let fd = libc::eventfd(0, 0);
            return if fd < 0 { Err(std::io::Error::last_os_error().into()) } else { Ok((fd, fd)) };
        }
        let mut fds = [0; 2];
        if libc::socketpair(libc::AF_UNIX, libc::SOCK_DGRAM, 0, fds.as_mut_ptr()) != 0 {
            return Err(std::io::Error::last_os_error().into());
        }
        Ok((fds[0], fds[1]))
    }
}

/// What the sender writes: a measured wake-up, or (in the high half, so that an eventfd's sum
/// still tells them apart) a warm-up ahead of one.
const MEASURED: u64 = 1;
const WARM_UP: u64 = 1 << 32;

fn raw(kind: &str, receiver_cpu: usize, sender_cpu: usize, period: Duration, lead: Duration) -> Result<()> {
    let (rx, tx) = raw_channel(kind)?;
    // the send time travels through a pipe the receiver reads after it woke
    let mut stamps = [0; 2];
    // SAFETY: creates a pipe into an array of two fds.
    if unsafe { libc::pipe(stamps.as_mut_ptr()) } != 0 {
        return Err(std::io::Error::last_os_error().into());
    }
    // SAFETY: the child only makes system calls, computes and prints, then exits.
    let child = unsafe { libc::fork() };
    if child == 0 {
        pin_to_cpu(receiver_cpu)?;
        let mut micros = Vec::with_capacity(SCANS);
        while micros.len() < SCANS {
            let (mut token, mut sent) = (0u64, 0u64);
            // SAFETY: reads 8 bytes into a u64.
            unsafe {
                libc::read(rx, (&mut token as *mut u64).cast(), 8);
                let woke = monotonic_ns();
                if token & MEASURED == 0 {
                    continue; // a warm-up alone
                }
                libc::read(stamps[0], (&mut sent as *mut u64).cast(), 8);
                micros.push(woke.saturating_sub(sent) as f64 / 1e3);
            }
        }
        println!("{kind}: wake-up {}", percentiles(&mut micros));
        std::process::exit(0);
    }
    pin_to_cpu(sender_cpu)?;
    let mut micros = Vec::with_capacity(SCANS);
    for _ in 0..SCANS {
        std::thread::sleep(period - lead);
        if !lead.is_zero() {
            // SAFETY: writes 8 bytes from a u64.
            unsafe { libc::write(tx, (&WARM_UP as *const u64).cast(), 8) };
            std::thread::sleep(lead);
        }
        let sent = monotonic_ns();
        // SAFETY: writes 8 bytes from a u64.
        unsafe {
            libc::write(tx, (&MEASURED as *const u64).cast(), 8);
            micros.push((monotonic_ns() - sent) as f64 / 1e3);
            libc::write(stamps[1], (&sent as *const u64).cast(), 8);
        }
    }
    // SAFETY: waits for the child forked above.
    unsafe { libc::waitpid(child, std::ptr::null_mut(), 0) };
    println!("{kind}: the writer's system call {}", percentiles(&mut micros));
    Ok(())
}

fn percentiles(micros: &mut [f64]) -> String {
    micros.sort_by(f64::total_cmp);
    let q = |f: f64| micros[((micros.len() - 1) as f64 * f).round() as usize];
    format!("p50 {:.1} us, p90 {:.1}, p99 {:.1}", q(0.5), q(0.9), q(0.99))
}

fn send(node: &Node<ipc::Service>) -> Result<()> {
    let mut out = Outlet::<ScanMsg>::open(node, PREFIX, Topic::Scan, BackpressureStrategy::RetryUntilDelivered)?;
    for seq in 0..SCANS as u64 {
        if !messages::sleep(node, Duration::from_millis(10)) {
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
    let sub = topic.data.subscriber_builder().create().context("subscriber")?;
    let listener = topic.event.listener_builder().create().context("listener")?;
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
                listener.blocking_wait(|_| {}).context("wait")?;
                take(&mut micros);
            }
        }
        "waitset" => {
            let waitset = WaitSetBuilder::new().create::<ipc::Service>().context("waitset")?;
            let _woken = waitset.attach_notification(&listener).context("waitset")?;
            let _poll = waitset.attach_interval(MISSED_WAKEUP_POLL).context("waitset")?;
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
                .context("waitset")?;
        }
        other => bail!("listen {other:?}: block or waitset"),
    }
    println!("{how}: {} scans, send to receive {}", micros.len(), percentiles(&mut micros));
    Ok(())
}
