//! What every gema2 process does the same way: name its node, take its place on the machine
//! ([`crate::placement`]), read the clock that message headers use, and clean up after
//! processes that died.

use iceoryx2::prelude::*;
use std::time::Duration;
use thiserror::Error;

/// How often a stage looks at its inputs without having been woken. iceoryx2 0.10's event can
/// lose a wake-up under load: a notification that lands between the listener's state reset and
/// its socket drain leaves the notifiers believing a wake-up is still pending, so they send no
/// more and a stage that only reacts to wake-ups stalls for good. Draining the listener on this
/// timer resets that state, so a lost wake-up delays a message by at most this long.
pub const MISSED_WAKEUP_POLL: Duration = Duration::from_millis(50);

#[derive(Debug, Error)]
pub enum RuntimeError {
    #[error("cannot create the iceoryx2 node {name:?}: {message}")]
    Node { name: String, message: String },
    #[error(transparent)]
    Placement(#[from] crate::placement::PlacementError),
}

/// iceoryx2 warns, the first time its configuration is read, that it runs without a config
/// file: errors only, unless the environment asks for more (IOX2_LOG_LEVEL). Called before
/// every first use of iceoryx2 in a process, as `gema2 run` lists dead nodes before it makes
/// its own.
fn quiet_iceoryx2() {
    set_log_level_from_env_or(LogLevel::Error);
}

/// How many connections to publishers that have gone each subscriber keeps until what it holds
/// from them is returned. iceoryx2's default, 128, costs every subscriber about 470 KB of its
/// own memory (a slot per connection, each about 3.6 KB of names), more than a localizer needs
/// for anything else. A connection is kept here only when its publisher went while this
/// process still held its samples or had been sent some not yet read:
/// - A sample held: a subscriber holds at most [`crate::MODEL_HELD`] (the model) or 2
///   (iceoryx2's default elsewhere) samples, so at most 2 connections hold one; iceoryx2 makes
///   room for those first, so a held sample is never taken away.
/// - A sample sent but unread: a stage reads what it was sent within a scan, so only
///   publishers that go within the same scan count; a third such one at once loses its
///   unread samples, with iceoryx2's warning.
pub const EXPIRED_CONNECTIONS: usize = 2;

/// Creates this process's node. Termination signals (SIGINT, SIGTERM) are left to iceoryx2,
/// which records them for the node; [`crate::run_waitset`] and [`crate::sleep`] then return so
/// the process can finish cleanly (and, unlike iceoryx2's own loops, only then).
pub fn create_node(name: &str) -> Result<Node<ipc::Service>, RuntimeError> {
    quiet_iceoryx2();
    let node_name =
        NodeName::new(name).map_err(|e| RuntimeError::Node { name: name.into(), message: format!("{e:?}") })?;
    let mut config = Config::global_config().clone();
    config.defaults.publish_subscribe.subscriber_expired_connection_buffer = EXPIRED_CONNECTIONS;
    NodeBuilder::new()
        .config(&config)
        .name(&node_name)
        .signal_handling_mode(SignalHandlingMode::HandleTerminationRequests)
        .create::<ipc::Service>()
        .map_err(|e| RuntimeError::Node { name: name.into(), message: format!("{e:?}") })
}

/// The arguments every stage process takes, declared once.
#[derive(clap::Args, Debug, Clone, PartialEq, Eq)]
pub struct StageArgs {
    /// Service name prefix: runs with different prefixes never share services.
    #[arg(long, default_value = "gema2")]
    pub prefix: String,
    /// Pin to this CPU core.
    #[arg(long)]
    pub cpu: Option<usize>,
    /// Run under SCHED_FIFO at this priority (1-99; needs root or CAP_SYS_NICE).
    #[arg(long)]
    pub priority: Option<u8>,
    /// Print the wire contract's version (messages::WIRE_VERSION) and exit: what the
    /// supervisor asks a program before swapping it in.
    #[arg(long)]
    pub wire_version: bool,
}

impl StageArgs {
    /// Answers `--wire-version` (prints it and ends the process), then pins the process to
    /// `--cpu` and sets its `--priority`, when given. Every stage calls it first.
    pub fn place(&self) -> Result<(), RuntimeError> {
        if self.wire_version {
            println!("{}", crate::WIRE_VERSION);
            std::process::exit(0);
        }
        if let Some(cpu) = self.cpu {
            crate::placement::pin_to_cpu(cpu)?;
        }
        if let Some(p) = self.priority {
            crate::placement::set_realtime_priority(p, false)?;
        }
        Ok(())
    }
}

/// Monotonic clock, nanoseconds: the same clock in every process of the machine.
pub fn monotonic_ns() -> u64 {
    let mut ts = libc::timespec { tv_sec: 0, tv_nsec: 0 };
    // SAFETY: clock_gettime writes the struct we pass.
    unsafe { libc::clock_gettime(libc::CLOCK_MONOTONIC, &mut ts) };
    ts.tv_sec as u64 * 1_000_000_000 + ts.tv_nsec as u64
}

/// Removes the shared-memory resources of nodes whose process died; returns how many.
pub fn cleanup_dead_nodes() -> usize {
    let mut removed = 0;
    quiet_iceoryx2();
    let _ = Node::<ipc::Service>::list(Config::global_config(), |state| {
        if let NodeState::Dead(view) = state {
            if view.try_remove_stale_resources().is_ok() {
                removed += 1;
            }
        }
        CallbackProgression::Continue
    });
    removed
}

/// Process ids of the dead nodes on this machine (nothing is removed). A test that stopped its
/// own processes checks that none of them is among these, without tripping over dead nodes
/// that other runs leave for their own supervisors to clean.
pub fn dead_node_pids() -> Vec<u32> {
    use iceoryx2::node::NodeView;
    let mut pids = Vec::new();
    quiet_iceoryx2();
    let _ = Node::<ipc::Service>::list(Config::global_config(), |state| {
        if let NodeState::Dead(view) = state {
            if let Ok(pid) = view.id().pid::<ipc::Service>() {
                pids.push(pid.value() as u32);
            }
        }
        CallbackProgression::Continue
    });
    pids
}

/// Largest instance number the supervisor hands out (`GEMA2_INSTANCE`).
pub const MAX_INSTANCE: usize = 4095;

/// This process's instance number, given by the supervisor in `GEMA2_INSTANCE` (0 if none).
pub fn instance() -> usize {
    std::env::var("GEMA2_INSTANCE").ok().and_then(|v| v.parse().ok()).filter(|&v| v <= MAX_INSTANCE).unwrap_or(0)
}

/// The `<prefix>/ready` event service, through which stages tell the supervisor they are
/// connected.
fn ready_event(
    node: &Node<ipc::Service>,
    prefix: &str,
) -> Result<iceoryx2::service::port_factory::event::PortFactory<ipc::Service>, crate::OpenError> {
    let service = crate::service_name(prefix, "ready");
    let name = ServiceName::new(&service)
        .map_err(|e| crate::OpenError::Name { service: service.clone(), message: format!("{e:?}") })?;
    node.service_builder(&name)
        .event()
        .event_id_max_value(MAX_INSTANCE)
        .max_notifiers(16)
        // the supervisor, and the segment stages, which hand a ready localizer the latest scan
        .max_listeners(8)
        .max_nodes(32)
        .open_or_create_with_attributes(&crate::topic::wire_attributes())
        .map_err(|e| crate::OpenError::Open { service, message: format!("{e:?}") })
}

/// Tells the supervisor (listening on `<prefix>/ready`) that this process's ports exist and it
/// can take data: the event id is the instance number the supervisor gave it. Start-up is over
/// then, and the stack it used is given back (`release_start_up_stack`).
pub fn announce_ready(node: &Node<ipc::Service>, prefix: &str) -> Result<(), crate::OpenError> {
    let port = |e: &dyn std::fmt::Debug| crate::OpenError::Port {
        service: crate::service_name(prefix, "ready"),
        message: format!("{e:?}"),
    };
    let notifier = ready_event(node, prefix)?.notifier_builder().create().map_err(|e| port(&e))?;
    notifier.notify_with_custom_event_id(EventId::new(instance())).map_err(|e| port(&e))?;
    release_start_up_stack();
    Ok(())
}

/// Stack kept below the caller's frame by [`release_start_up_stack`]: room for its own call of
/// `madvise`. What a stage's loop reaches further down comes back zeroed as it is first
/// touched, a few pages once; kept instead, pages the loop never reaches stayed resident (a
/// localizer's loop reaches about 8 KB below, and 16 KB kept had left the other 8 KB in its
/// own memory).
const STACK_KEPT: usize = 4 * 1024;

/// Gives the system back the main thread's stack pages below the caller's frame (less
/// [`STACK_KEPT`]). iceoryx2 reads its configuration and sets up a node in frames of tens of
/// kilobytes, about 250 KB of stack that a stage then never uses again but would keep resident
/// for its life. Nothing lives below the stack pointer, so the pages are free to drop; one
/// touched again comes back zeroed, as new stack does. Elsewhere than on Linux's main thread
/// it does nothing.
pub fn release_start_up_stack() {
    let here = 0u8;
    let sp = std::ptr::addr_of!(here) as usize;
    let Ok(maps) = std::fs::read_to_string("/proc/self/maps") else { return };
    let Some((start, end)) = maps.lines().filter(|l| l.ends_with("[stack]")).find_map(|l| {
        let (range, _) = l.split_once(' ')?;
        let (a, b) = range.split_once('-')?;
        Some((usize::from_str_radix(a, 16).ok()?, usize::from_str_radix(b, 16).ok()?))
    }) else {
        return;
    };
    // SAFETY: sysconf has no preconditions
    let page = usize::try_from(unsafe { libc::sysconf(libc::_SC_PAGESIZE) }).unwrap_or(4096).max(1);
    if !(start..end).contains(&sp) {
        return; // not the main thread
    }
    let top = sp.saturating_sub(STACK_KEPT) / page * page;
    if top > start {
        // SAFETY: [start, top) lies in this process's stack mapping, wholly below the stack
        // pointer less a margin, where no frame lives; MADV_DONTNEED on private anonymous
        // memory only drops pages, which read back as zeros
        unsafe { libc::madvise(start as *mut libc::c_void, top - start, libc::MADV_DONTNEED) };
    }
}

/// The readiness event service the supervisor listens on.
pub fn ready_listener(
    node: &Node<ipc::Service>,
    prefix: &str,
) -> Result<iceoryx2::port::listener::Listener<ipc::Service>, crate::OpenError> {
    ready_event(node, prefix)?.listener_builder().create().map_err(|e| crate::OpenError::Port {
        service: crate::service_name(prefix, "ready"),
        message: format!("{e:?}"),
    })
}

/// Writes `line` and a newline to stderr in one write. A pipeline's stages share their
/// supervisor's stderr, and `eprintln!` writes a formatted line in pieces, between which
/// another stage's line can land (seen under load: a map server's line inside a localizer's).
/// One write of a line shorter than the pipe's buffer is never split. See [`crate::say`].
pub fn say_line(line: std::fmt::Arguments<'_>) {
    let text = format!("{line}\n");
    let _ = std::io::Write::write_all(&mut std::io::stderr().lock(), text.as_bytes());
}

/// `eprintln!` in one write ([`say_line`]): what a stage and its supervisor report with.
#[macro_export]
macro_rules! say {
    ($($arg:tt)*) => {
        $crate::say_line(format_args!($($arg)*))
    };
}

/// Hands the memory this process freed back to the system (glibc's `malloc_trim`): the
/// allocator otherwise keeps every page it ever used resident, so a process's memory is the
/// high-water mark of all it ever held at once rather than what it holds now. Cheap on a small
/// heap (a walk over its free chunks); a no-op where the C library is not glibc.
pub fn return_freed_memory() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: malloc_trim only walks and releases the allocator's own free chunks.
    unsafe {
        libc::malloc_trim(0);
    }
}
