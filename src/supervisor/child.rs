//! Stage processes: started from the pipeline spec, reaped, stopped cleanly.

use super::pipeline::{Kind, Restart, StageSpec};
use anyhow::{Context, Result};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::time::{Duration, Instant};

/// A running (or restarting) stage.
pub struct StageProcess {
    pub spec: StageSpec,
    pub child: Option<Child>,
    pub restarts: u32,
    /// When a dead stage is due to be started again.
    pub restart_at: Option<Instant>,
    pub finished: bool,
    /// How the stage ended when it failed and was not started again: the run then fails too.
    pub failed: Option<std::process::ExitStatus>,
}

impl StageProcess {
    pub fn new(spec: StageSpec) -> Self {
        StageProcess { spec, child: None, restarts: 0, restart_at: None, finished: false, failed: None }
    }

    /// Starts the stage with its implementation, CPU and prefix, as instance `instance` (the
    /// number it announces readiness with).
    pub fn start(&mut self, prefix: &str, implementation: Option<&str>, instance: usize) -> Result<()> {
        self.child = Some(spawn(&self.spec, prefix, implementation, instance)?);
        self.restart_at = None;
        Ok(())
    }

    /// Whether the policy restarts a stage that ended with `status`.
    pub fn should_restart(&self, status: &ExitStatus) -> bool {
        match self.spec.restart {
            Restart::Always => true,
            Restart::OnFailure => !status.success(),
            Restart::Never => false,
        }
    }

    /// Backoff before the next restart: 100 ms doubling up to 5 s.
    pub fn backoff(&self) -> Duration {
        Duration::from_millis(100u64 << self.restarts.min(6)).min(Duration::from_secs(5))
    }
}

/// Starts one stage process.
pub fn spawn(spec: &StageSpec, prefix: &str, implementation: Option<&str>, instance: usize) -> Result<Child> {
    let mut cmd = match &spec.binary {
        Some(b) => Command::new(b),
        None if spec.kind == Kind::Viewer => Command::new(viewer_binary()?),
        None => {
            let mut c = Command::new(std::env::current_exe().context("locating the gema2 binary")?);
            c.arg("stage").arg(spec.kind.as_str());
            c
        }
    };
    cmd.args(&spec.args).arg("--prefix").arg(prefix);
    if let Some(cpu) = spec.cpu {
        cmd.arg("--cpu").arg(cpu.to_string());
    }
    if let Some(p) = spec.priority {
        cmd.arg("--priority").arg(p.to_string());
    }
    if let Some(i) = implementation.or(spec.implementation.as_deref()) {
        if matches!(spec.kind, Kind::Segment | Kind::Localize) {
            cmd.arg("--impl").arg(i);
        }
    }
    cmd.env("GEMA2_INSTANCE", instance.to_string());
    cmd.stdin(Stdio::null());
    stop_with_supervisor(&mut cmd);
    give_back_cores(&mut cmd);
    let program = cmd.get_program().to_string_lossy().into_owned();
    cmd.spawn().with_context(|| format!("starting stage {} ({program})", spec.name))
}

/// Makes the stage receive SIGTERM when the supervisor dies, however it dies (SIGKILL, a
/// crash): it then stops as on Ctrl-C instead of living on as an orphan that still publishes
/// under the prefix. Stages are started from the supervisor's main thread, whose end the
/// signal follows, so it comes only when the supervisor process ends.
fn stop_with_supervisor(cmd: &mut Command) {
    use std::os::unix::process::CommandExt;
    // SAFETY: getpid is async-signal-safe and called before the fork.
    let supervisor = unsafe { libc::getpid() };
    // SAFETY: prctl and getppid are async-signal-safe, as code between fork and exec must be.
    unsafe {
        cmd.pre_exec(move || {
            if libc::prctl(libc::PR_SET_PDEATHSIG, libc::SIGTERM) != 0 {
                return Err(std::io::Error::last_os_error());
            }
            // the supervisor died before the prctl took effect. The error is an errno, not a
            // message: building one allocates, which a forked child of a threaded process must not
            if libc::getppid() != supervisor {
                return Err(std::io::Error::from_raw_os_error(libc::ESRCH));
            }
            Ok(())
        });
    }
}

/// The CPU affinity the supervisor had before it pinned itself ([`super::pipeline::SupervisorSpec`]).
static STARTED_WITH: std::sync::OnceLock<messages::placement::Affinity> = std::sync::OnceLock::new();

/// Records the supervisor's affinity before it pins itself, for [`give_back_cores`].
pub fn remember_affinity(a: messages::placement::Affinity) {
    let _ = STARTED_WITH.set(a);
}

/// A stage inherits the affinity of the thread that starts it: once the supervisor has pinned
/// itself, a stage with no `cpu` of its own would share the supervisor's one core. It gets
/// the cores the supervisor started with instead (a stage with a `cpu` pins itself anyway).
fn give_back_cores(cmd: &mut Command) {
    use std::os::unix::process::CommandExt;
    if let Some(affinity) = STARTED_WITH.get().copied() {
        // SAFETY: restore_affinity is one system call, async-signal-safe as code between fork
        // and exec must be.
        unsafe { cmd.pre_exec(move || messages::placement::restore_affinity(&affinity)) };
    }
}

/// The recorder's program: `GEMA2_VIEWER` if set, else `viewer` beside the gema2 binary (where
/// cargo builds it), else `viewer` on PATH. rerun is compiled into that program only.
pub fn viewer_binary() -> Result<std::path::PathBuf> {
    if let Some(p) = std::env::var_os("GEMA2_VIEWER") {
        return Ok(p.into());
    }
    let exe = std::env::current_exe().context("locating the gema2 binary")?;
    let beside = exe.with_file_name("viewer");
    if beside.is_file() {
        return Ok(beside);
    }
    let on_path = std::env::var_os("PATH")
        .map(|p| std::env::split_paths(&p).map(|d| d.join("viewer")).find(|c| c.is_file()))
        .unwrap_or_default();
    on_path.with_context(|| {
        format!(
            "no viewer program: not beside {} nor on PATH; build it with `cargo build --release -p viewer` \
             or set GEMA2_VIEWER",
            exe.display()
        )
    })
}

/// Sends SIGTERM, waits up to `grace`, then SIGKILL; always reaps.
pub fn stop(child: &mut Child, grace: Duration) -> Option<ExitStatus> {
    // SAFETY: kill(2) on our own child's pid.
    unsafe { libc::kill(child.id() as i32, libc::SIGTERM) };
    let deadline = Instant::now() + grace;
    while Instant::now() < deadline {
        if let Ok(Some(status)) = child.try_wait() {
            return Some(status);
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    let _ = child.kill();
    child.wait().ok()
}
