//! Where and how a process runs: its CPU core, its real-time priority, and how fast idle cores
//! wake up. These decide most of what an IPC hop costs. A message's own transport is a few
//! microseconds; the rest is the kernel waking the receiver, and a receiver that is not on the
//! sender's core, or that shares it at a lower priority, or whose core sleeps deeply, waits.
//!
//! - [`pin_to_cpu`]: one core per stage, so a stage is never moved away from its warm caches.
//! - [`set_realtime_priority`]: `SCHED_FIFO`. A stage that wakes at a higher priority than the
//!   one that woke it runs at once instead of when the sender next blocks; priorities rising
//!   downstream drain the pipeline before it takes the next scan.
//! - [`WakeLatencyRequest`]: Linux's PM QoS request on `/dev/cpu_dma_latency`. While it is held,
//!   idle cores stay in states they leave within that many microseconds; at 0 they poll
//!   instead of halting. On this project's 2-core VM (a `haltpoll` guest that never polls
//!   before halting) that took a cross-core wake-up from 96 to 22 us p50. The price is idle
//!   cores that spin: power on a robot, CPU time taken from neighbours on a shared host.
//!
//! All three are opt-in (`cpu`, `priority` and `[supervisor] wake_latency_us` in the pipeline
//! file). Each fails with an error when the system refuses it, never silently: a pipeline that
//! was asked to be real-time and quietly is not would mislead whoever measures it.

use std::fs::File;
use std::io::Write;
use thiserror::Error;

#[derive(Debug, Error)]
pub enum PlacementError {
    #[error("cannot pin to CPU {cpu}: {message}")]
    Pin { cpu: usize, message: String },
    #[error("cannot read the CPU affinity or scheduling: {0}")]
    Affinity(String),
    #[error(
        "cannot run at SCHED_FIFO priority {priority}: {message} (real-time priorities need root, \
         CAP_SYS_NICE or an rtprio limit)"
    )]
    Priority { priority: u8, message: String },
    #[error("cannot request a CPU wake-up latency of {micros} us on {path}: {message} (it needs root)")]
    WakeLatency { micros: u32, path: &'static str, message: String },
}

/// Lowest and highest `SCHED_FIFO` priority Linux accepts.
pub const REALTIME_PRIORITIES: std::ops::RangeInclusive<u8> = 1..=99;

/// Pins the calling thread (and what it forks from now on) to one CPU core. When the kernel
/// refuses, the error names the cores it would accept ([`allowed_cores`]).
pub fn pin_to_cpu(cpu: usize) -> Result<(), PlacementError> {
    if set_affinity_to(cpu) {
        return Ok(());
    }
    let error = std::io::Error::last_os_error();
    let allowed = allowed_cores()?;
    Err(PlacementError::Pin { cpu, message: format!("{error}; this process may run on cores {}", ranges(&allowed)) })
}

/// Sets the calling thread's affinity to `cpu` alone; whether the kernel accepted it (a core
/// beyond the set's size never is).
fn set_affinity_to(cpu: usize) -> bool {
    if cpu >= libc::CPU_SETSIZE as usize {
        return false;
    }
    // SAFETY: `set` is a plain bit set on the stack and `cpu` lies within it; sched_setaffinity
    // reads it.
    unsafe {
        let mut set: libc::cpu_set_t = std::mem::zeroed();
        libc::CPU_SET(cpu, &mut set);
        libc::sched_setaffinity(0, std::mem::size_of::<libc::cpu_set_t>(), &set) == 0
    }
}

/// The cores the kernel lets the calling thread be pinned to, lowest first: asked of the kernel
/// core by core, the thread's affinity put back after. That is wider than the current
/// affinity (`taskset -c 0` still lets a process pin itself to core 1) and narrower than the
/// machine's cores (a cpuset, a container's `--cpuset-cpus`).
pub fn allowed_cores() -> Result<Vec<usize>, PlacementError> {
    let saved = Affinity::current()?;
    // no core is numbered beyond those the system has configured
    // SAFETY: sysconf only reads a system value.
    let configured = usize::try_from(unsafe { libc::sysconf(libc::_SC_NPROCESSORS_CONF) }).unwrap_or(0);
    let cores = if configured > 0 { configured.min(libc::CPU_SETSIZE as usize) } else { libc::CPU_SETSIZE as usize };
    let allowed = (0..cores).filter(|&c| set_affinity_to(c)).collect();
    restore_affinity(&saved).map_err(|e| PlacementError::Affinity(e.to_string()))?;
    Ok(allowed)
}

/// The calling thread's CPU affinity, to hand back to processes it starts after pinning itself
/// (see [`restore_affinity`]).
#[derive(Clone, Copy)]
pub struct Affinity(libc::cpu_set_t);

impl Affinity {
    pub fn current() -> Result<Self, PlacementError> {
        // SAFETY: sched_getaffinity writes the set we pass.
        unsafe {
            let mut set: libc::cpu_set_t = std::mem::zeroed();
            if libc::sched_getaffinity(0, std::mem::size_of::<libc::cpu_set_t>(), &mut set) != 0 {
                return Err(PlacementError::Affinity(std::io::Error::last_os_error().to_string()));
            }
            Ok(Affinity(set))
        }
    }
}

/// `cores` (ascending) as ranges: "0-3, 6".
pub fn ranges(cores: &[usize]) -> String {
    let mut out: Vec<String> = Vec::new();
    let mut k = 0;
    while k < cores.len() {
        let start = cores[k];
        while k + 1 < cores.len() && cores[k + 1] == cores[k] + 1 {
            k += 1;
        }
        out.push(if cores[k] == start { start.to_string() } else { format!("{start}-{}", cores[k]) });
        k += 1;
    }
    if out.is_empty() {
        "none".to_owned()
    } else {
        out.join(", ")
    }
}

/// Sets the calling thread's affinity to `a`. Only a system call: safe between `fork` and
/// `exec`.
pub fn restore_affinity(a: &Affinity) -> std::io::Result<()> {
    // SAFETY: sched_setaffinity reads the set; it is async-signal-safe.
    let rc = unsafe { libc::sched_setaffinity(0, std::mem::size_of::<libc::cpu_set_t>(), &a.0) };
    if rc != 0 {
        return Err(std::io::Error::last_os_error());
    }
    Ok(())
}

/// Runs the calling process under `SCHED_FIFO` at `priority` (1-99). With `reset_on_fork`,
/// processes it starts begin as ordinary ones (they set their own priorities).
pub fn set_realtime_priority(priority: u8, reset_on_fork: bool) -> Result<(), PlacementError> {
    if !REALTIME_PRIORITIES.contains(&priority) {
        return Err(PlacementError::Priority { priority, message: "priorities run from 1 to 99".into() });
    }
    let policy = libc::SCHED_FIFO | if reset_on_fork { libc::SCHED_RESET_ON_FORK } else { 0 };
    let param = libc::sched_param { sched_priority: priority as i32 };
    // SAFETY: sched_setscheduler reads the parameter struct we pass.
    if unsafe { libc::sched_setscheduler(0, policy, &param) } != 0 {
        return Err(PlacementError::Priority { priority, message: std::io::Error::last_os_error().to_string() });
    }
    Ok(())
}

/// The calling thread's CPU affinity, scheduling policy and priority as they were when saved,
/// put back when this is dropped: a program that runs a pipeline and goes on (`gema2 bench`
/// runs several) leaves it as it found it.
pub struct SavedPlacement {
    affinity: Affinity,
    policy: libc::c_int,
    param: libc::sched_param,
}

impl SavedPlacement {
    pub fn save() -> Result<Self, PlacementError> {
        let affinity = Affinity::current()?;
        let mut param = libc::sched_param { sched_priority: 0 };
        // SAFETY: plain queries of the calling thread's scheduling into a struct we own.
        let policy = unsafe { libc::sched_getscheduler(0) };
        if policy < 0 || unsafe { libc::sched_getparam(0, &mut param) } != 0 {
            return Err(PlacementError::Affinity(format!(
                "reading the scheduling policy: {}",
                std::io::Error::last_os_error()
            )));
        }
        Ok(SavedPlacement { affinity, policy, param })
    }

    /// The affinity as it was saved.
    pub fn affinity(&self) -> Affinity {
        self.affinity
    }
}

impl Drop for SavedPlacement {
    fn drop(&mut self) {
        // SAFETY: sets the calling thread's policy from values read from it before.
        unsafe { libc::sched_setscheduler(0, self.policy, &self.param) };
        let _ = restore_affinity(&self.affinity);
    }
}

/// A PM QoS request that bounds how long idle cores take to wake up, held while this value
/// lives (the kernel drops the request when the file is closed, also when the process dies).
pub struct WakeLatencyRequest {
    _file: File,
    pub micros: u32,
}

impl WakeLatencyRequest {
    const PATH: &'static str = "/dev/cpu_dma_latency";

    pub fn hold(micros: u32) -> Result<Self, PlacementError> {
        let error =
            |e: std::io::Error| PlacementError::WakeLatency { micros, path: Self::PATH, message: e.to_string() };
        let mut file = std::fs::OpenOptions::new().write(true).open(Self::PATH).map_err(error)?;
        // the kernel reads a binary 32-bit value (microseconds)
        let value = i32::try_from(micros).unwrap_or(i32::MAX);
        file.write_all(&value.to_ne_bytes()).map_err(error)?;
        Ok(WakeLatencyRequest { _file: file, micros })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bad_requests_are_refused_with_the_reason() {
        let e = pin_to_cpu(100_000).unwrap_err().to_string();
        assert!(e.contains("CPU 100000") && e.contains("cores"), "{e}");
        // a core within the set's range that the kernel refuses: the error names the cores it
        // would accept
        let allowed = allowed_cores().unwrap();
        let outside = allowed.last().unwrap() + 1;
        if outside < libc::CPU_SETSIZE as usize {
            let e = pin_to_cpu(outside).unwrap_err().to_string();
            assert!(e.contains(&format!("CPU {outside}")) && e.contains(&ranges(&allowed)), "{e}");
        }
        for p in [0, 100] {
            let e = set_realtime_priority(p, true).unwrap_err().to_string();
            assert!(e.contains(&format!("priority {p}")) && e.contains("1 to 99"), "{e}");
        }
    }

    #[test]
    fn core_lists_read_as_ranges() {
        assert_eq!(ranges(&[0, 1, 2, 3, 6, 8, 9]), "0-3, 6, 8-9");
        assert_eq!(ranges(&[5]), "5");
        assert_eq!(ranges(&[]), "none");
    }

    /// The cores the kernel accepts include those the thread runs on, and asking leaves its
    /// affinity as it was.
    #[test]
    fn allowed_cores_are_asked_of_the_kernel_and_leave_the_affinity_alone() {
        std::thread::spawn(|| {
            let before = Affinity::current().unwrap();
            let allowed = allowed_cores().unwrap();
            assert!(!allowed.is_empty());
            // SAFETY: CPU_ISSET reads bits below CPU_SETSIZE of a set we own.
            let running: Vec<usize> =
                (0..libc::CPU_SETSIZE as usize).filter(|&c| unsafe { libc::CPU_ISSET(c, &before.0) }).collect();
            assert!(running.iter().all(|c| allowed.contains(c)), "{running:?} {allowed:?}");
            // pinned to one core, the others it could run on are still allowed
            pin_to_cpu(running[0]).unwrap();
            assert_eq!(allowed_cores().unwrap(), allowed);
            restore_affinity(&before).unwrap();
            let after = Affinity::current().unwrap();
            // SAFETY: CPU_EQUAL compares two bit sets we own.
            assert!(unsafe { libc::CPU_EQUAL(&before.0, &after.0) });
        })
        .join()
        .unwrap();
    }

    /// Where the system allows it (root), a real-time priority takes effect and, with
    /// reset-on-fork, is not inherited; elsewhere the refusal names what is missing.
    #[test]
    fn a_realtime_priority_takes_effect_or_says_why_not() {
        // a thread of its own, so the test harness's other threads keep their policy
        std::thread::spawn(|| match set_realtime_priority(3, true) {
            Ok(()) => {
                // SAFETY: plain queries of the calling thread's scheduling.
                let policy = unsafe { libc::sched_getscheduler(0) };
                assert_eq!(policy & !libc::SCHED_RESET_ON_FORK, libc::SCHED_FIFO);
                let mut param = libc::sched_param { sched_priority: 0 };
                assert_eq!(unsafe { libc::sched_getparam(0, &mut param) }, 0);
                assert_eq!(param.sched_priority, 3);
            }
            Err(e) => assert!(e.to_string().contains("CAP_SYS_NICE"), "{e}"),
        })
        .join()
        .unwrap();
    }

    /// What a saved placement saw comes back when it is dropped, whatever was set meanwhile.
    #[test]
    fn a_saved_placement_is_put_back() {
        std::thread::spawn(|| {
            let before = Affinity::current().unwrap();
            // SAFETY: a plain query of the calling thread's policy.
            let policy = || unsafe { libc::sched_getscheduler(0) } & !libc::SCHED_RESET_ON_FORK;
            let original = policy();
            {
                let _saved = SavedPlacement::save().unwrap();
                pin_to_cpu(0).unwrap();
                if set_realtime_priority(5, true).is_ok() {
                    assert_eq!(policy(), libc::SCHED_FIFO);
                }
            }
            assert_eq!(policy(), original);
            let after = Affinity::current().unwrap();
            // SAFETY: CPU_EQUAL compares two bit sets we own.
            assert!(unsafe { libc::CPU_EQUAL(&before.0, &after.0) });
        })
        .join()
        .unwrap();
    }

    /// The kernel's effective wake-up latency (reading the device gives it) is at most what a
    /// held request asks; without permission the error names the device. (That it returns
    /// when the request is dropped cannot be checked here: another program may hold one too.)
    #[test]
    fn a_wake_latency_request_holds_while_it_lives() {
        use std::io::Read;
        let effective = || {
            let mut v = [0u8; 4];
            File::open(WakeLatencyRequest::PATH).and_then(|mut f| f.read_exact(&mut v)).map(|_| i32::from_ne_bytes(v))
        };
        match WakeLatencyRequest::hold(7) {
            Ok(request) => {
                let value = effective().unwrap();
                assert!(value <= 7, "the kernel reports {value} us while {} us is held", request.micros);
            }
            Err(e) => assert!(e.to_string().contains("/dev/cpu_dma_latency"), "{e}"),
        }
    }
}
