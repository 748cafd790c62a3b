//! Hot swap: `gema2 swap STAGE` asks the supervisor, over the control service, to replace a
//! running stage with another implementation (`--impl`), another program of the same stage
//! kind (`--binary`, a new build), or the same with other arguments (`--args`, `--set`). The
//! supervisor starts the new process beside the old one under the same service names, waits
//! until it announces that it is ready (ports connected; a localizer has read the map model),
//! then stops the old one; nothing else restarts, and the stage's new program and arguments
//! are what a later restart runs. While both run, downstream skips duplicate scans.
//!
//! A program is swapped in only when it answers `--wire-version` with this pipeline's
//! [`messages::WIRE_VERSION`]; one that does not start, or exits before it is ready, leaves the
//! old stage running, and the swap ends with an error that says why. `gema2 swap` with no stage
//! lists what each stage runs and what it can be swapped to.
//!
//! Segment and localize stages swap this way. An acquire stage (the source) is handed over at a
//! scan boundary: the new one starts with `--handover`, announces readiness, and publishes only
//! once the old one is gone, numbering on from the old one's last scan. A new map server
//! publishes its map as the version after the running one's, so the localizers take it up
//! between two scans. The ros2 bridge and the recorder do not swap yet.

use super::child::{spawn, stop, StageProcess};
use super::control::ControlServer;
use super::pipeline::{Kind, StageSpec};
use anyhow::{anyhow, bail, Context, Result};
use clap::Args;
use localize::LOCALIZERS;
use messages::iceoryx2::active_request::ActiveRequest;
use messages::iceoryx2::prelude::*;
use messages::{
    cut_padded, name_bytes, name_str, open_control, pack_args, padded, unpack_args, unpadded, Awaited, ControlReply,
    ControlRequest, CONTROL_LIST, CONTROL_SWAP, REPLY_LEN,
};
use segment::SEGMENTERS;
use std::collections::HashSet;
use std::path::{Path, PathBuf};
use std::process::Child;
use std::time::{Duration, Instant};

type Request = ActiveRequest<ipc::Service, ControlRequest, (), ControlReply, ()>;

/// A swap in progress.
pub struct Swap {
    request: Request,
    stage: usize,
    /// What the stage becomes.
    spec: StageSpec,
    what: String,
    instance: usize,
    new: Option<Child>,
    deadline: Instant,
}

pub enum SwapOutcome {
    Pending,
    Done(String),
    Failed(String),
}

fn reply(request: &Request, ok: bool, message: &str) {
    let m = ControlReply { ok: ok as u32, message: cut_padded::<REPLY_LEN>(message) };
    if let Ok(r) = request.loan_uninit() {
        let _ = r.write_payload(m).send();
    }
}

/// What a swap asks for, read from the request.
struct Asked {
    stage: String,
    alternative: Option<String>,
    implementation: Option<String>,
    binary: Option<PathBuf>,
    args: Vec<String>,
    replace_args: bool,
}

impl Asked {
    fn of(r: &ControlRequest) -> Self {
        let text = |b: &[u8]| Some(unpadded(b)).filter(|s| !s.is_empty());
        Asked {
            stage: name_str(&r.stage).to_owned(),
            alternative: text(&r.alternative),
            implementation: text(&r.implementation),
            binary: text(&r.binary).map(PathBuf::from),
            args: unpack_args(&r.args),
            replace_args: r.replace_args == 1,
        }
    }
}

/// How long a program has to say its wire version.
const VERSION_PATIENCE: Duration = Duration::from_secs(10);

/// The wire version `binary` answers to `--wire-version`, or why it answers none.
fn wire_version_of(binary: &Path, kind: Kind) -> Result<u32> {
    let mut child = std::process::Command::new(binary)
        .args(["--wire-version"])
        .stdin(std::process::Stdio::null())
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .with_context(|| format!("{} cannot be started", binary.display()))?;
    let deadline = Instant::now() + VERSION_PATIENCE;
    while child.try_wait()?.is_none() {
        if Instant::now() > deadline {
            let _ = child.kill();
            let _ = child.wait();
            bail!("{} did not answer --wire-version within {VERSION_PATIENCE:?}", binary.display());
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    let out = child.wait_with_output()?;
    let said = String::from_utf8_lossy(&out.stdout);
    match (out.status.success(), said.trim().parse::<u32>()) {
        (true, Ok(v)) => Ok(v),
        _ => bail!(
            "{} does not say its wire version (--wire-version): not a gema2 {} stage program of this release",
            binary.display(),
            kind.as_str()
        ),
    }
}

/// The map-corner settings a localizer swap cannot change: the map server built the model
/// with them.
fn refuse_model_settings(args: &[String]) -> Result<()> {
    for kv in args.windows(2).filter(|w| w[0] == "--set").map(|w| &w[1]) {
        let key = kv.split_once('=').map_or(kv.as_str(), |(k, _)| k.trim());
        if localize::Gema2Config::MAP_SETTINGS.iter().any(|s| s.key == key) {
            bail!(
                "{key} shapes the map model the map server built: a localizer cannot differ from it (set it in \
                 the pipeline's settings, for every stage)"
            );
        }
    }
    Ok(())
}

/// `spec` as `asked` would change it, checked: a known implementation, a program that speaks
/// this wire version, settings the stage takes.
fn changed(spec: &StageSpec, asked: &Asked) -> Result<(StageSpec, String)> {
    let kind = spec.kind;
    let implementations = implementations(kind);
    let by_arguments = matches!(kind, Kind::Acquire | Kind::Mapserver);
    if by_arguments && asked.implementation.is_some() {
        bail!("a {} stage has no implementations to choose from: give it other --args (or --binary)", kind.as_str());
    }
    if implementations.is_empty() && !by_arguments {
        bail!(
            "stage {:?} is a {} stage, which cannot be swapped yet: segment stages (to one of {SEGMENTERS:?}), \
             localize stages ({LOCALIZERS:?}), acquire and mapserver stages can, to another --binary or with \
             other --args / --set",
            spec.name,
            kind.as_str()
        );
    }
    let mut new = spec.clone();
    let mut what = Vec::new();
    if let Some(i) = &asked.implementation {
        if !implementations.contains(&i.as_str()) {
            bail!("stage {:?} has no implementation {i:?}: one of {implementations:?}", spec.name);
        }
        new.implementation = Some(i.clone());
        what.push(i.clone());
    }
    if let Some(b) = &asked.binary {
        let version = wire_version_of(b, kind)?;
        if version != messages::WIRE_VERSION {
            bail!(
                "{} speaks wire version {version}, this pipeline {}: it cannot share the pipeline's services",
                b.display(),
                messages::WIRE_VERSION
            );
        }
        new.binary = Some(b.clone());
        what.push(b.display().to_string());
    }
    if asked.replace_args {
        new.args = asked.args.clone();
    } else {
        new.args.extend(asked.args.iter().cloned());
    }
    if !asked.args.is_empty() || asked.replace_args {
        what.push(format!("arguments {:?}", new.args));
    }
    let sets: Vec<String> = new.args.windows(2).filter(|w| w[0] == "--set").map(|w| w[1].clone()).collect();
    match kind {
        Kind::Segment => segment::SegmenterConfig::default().apply(&sets).context("--set")?,
        Kind::Localize => {
            refuse_model_settings(&asked.args)?;
            localize::Gema2Config::default().apply(&sets).context("--set")?
        }
        // the localizers hold the corner settings too: the model must agree with them
        Kind::Mapserver if asked.args.iter().any(|a| a == "--set") => bail!(
            "the map server's corner settings are every localizer's too: change them in the pipeline's settings and \
             start it again"
        ),
        _ => {}
    }
    if what.is_empty() {
        what.push("a fresh process".into());
    }
    Ok((new, what.join(", ")))
}

impl Swap {
    /// Takes the next control request, if any: answers a listing at once, starts the
    /// replacement of a swap.
    pub fn accept(
        server: &ControlServer,
        stages: &mut [StageProcess],
        prefix: &str,
        instance: impl FnOnce() -> usize,
    ) -> Result<Option<Swap>> {
        let Some(request) = server.receive().context("control")? else { return Ok(None) };
        if request.what == CONTROL_LIST {
            reply(&request, true, &listing(stages));
            return Ok(None);
        }
        if request.what != CONTROL_SWAP {
            reply(&request, false, &format!("unknown control request {}", request.what));
            return Ok(None);
        }
        let asked = Asked::of(&request);
        let refuse = |why: String| -> Result<Option<Swap>> {
            reply(&request, false, &why);
            Err(anyhow!("swap refused: {why}"))
        };
        let Some(stage) = stages.iter().position(|s| s.spec.name == asked.stage) else {
            let names: Vec<&str> = stages.iter().map(|s| s.spec.name.as_str()).collect();
            return refuse(format!("no stage called {:?}: the stages are {names:?}", asked.stage));
        };
        let mut asked = asked;
        if let Some(to) = asked.alternative.clone() {
            let spec = &stages[stage].spec;
            let Some(alt) = spec.alternatives.iter().find(|a| a.name == to) else {
                let named: Vec<&str> = spec.alternatives.iter().map(|a| a.name.as_str()).collect();
                return refuse(format!("stage {:?} names no alternative {to:?}: it names {named:?}", spec.name));
            };
            asked.implementation = alt.implementation.clone();
            asked.binary = alt.binary.clone();
            asked.replace_args = alt.args.is_some();
            asked.args = alt.args.clone().unwrap_or_default();
        }
        let (spec, what) = match changed(&stages[stage].spec, &asked) {
            Ok(c) => c,
            Err(e) => return refuse(format!("{e:#}")),
        };
        let instance = instance();
        // a source takes over at a scan boundary (not kept for a restart: that starts afresh)
        let mut starting = spec.clone();
        if starting.kind == Kind::Acquire {
            starting.args.push("--handover".into());
        }
        let new = match spawn(&starting, prefix, None, instance) {
            Ok(c) => c,
            Err(e) => return refuse(format!("{e:#}")),
        };
        messages::say!("supervisor: swapping {} to {what}", spec.name);
        Ok(Some(Swap {
            request,
            stage,
            spec,
            what,
            instance,
            new: Some(new),
            deadline: Instant::now() + Duration::from_secs(20),
        }))
    }

    /// Advances the swap: once the new process is connected, stops the old one.
    pub fn progress(&mut self, ready: &HashSet<usize>, stages: &mut [StageProcess]) -> SwapOutcome {
        let st = &mut stages[self.stage];
        let name = st.spec.name.clone();
        let new = match self.new.as_mut() {
            Some(n) => n,
            None => return SwapOutcome::Failed(format!("swap of {name}: lost the new process")),
        };
        if let Ok(Some(status)) = new.try_wait() {
            self.new = None;
            let m = format!(
                "swap of {name} failed: the new process exited before it was ready ({status}; its error is on the \
                 supervisor's output); the old one runs on"
            );
            reply(&self.request, false, &m);
            return SwapOutcome::Failed(m);
        }
        if ready.contains(&self.instance) {
            if let Some(mut old) = st.child.take() {
                stop(&mut old, Duration::from_secs(3));
            }
            st.child = self.new.take();
            st.spec = self.spec.clone();
            let m = format!("swapped {name} to {}", self.what);
            reply(&self.request, true, &m);
            return SwapOutcome::Done(m);
        }
        if Instant::now() > self.deadline {
            if let Some(mut n) = self.new.take() {
                stop(&mut n, Duration::from_secs(1));
            }
            let m = format!("swap of {name} failed: the new process was not ready in time; the old one runs on");
            reply(&self.request, false, &m);
            return SwapOutcome::Failed(m);
        }
        SwapOutcome::Pending
    }
}

impl Drop for Swap {
    fn drop(&mut self) {
        if let Some(mut n) = self.new.take() {
            stop(&mut n, Duration::from_secs(1));
        }
    }
}

/// What a stage of `kind` can be swapped to; none for a stage that cannot be.
fn implementations(kind: Kind) -> &'static [&'static str] {
    match kind {
        Kind::Segment => &SEGMENTERS,
        Kind::Localize => &LOCALIZERS,
        _ => &[],
    }
}

/// Each stage: what it runs, and what it can be swapped to.
fn listing(stages: &[StageProcess]) -> String {
    let mut out = String::new();
    for st in stages {
        let s = &st.spec;
        let program =
            s.binary.as_ref().map_or_else(|| format!("gema2 stage {}", s.kind.as_str()), |b| b.display().to_string());
        let running = match (&s.implementation, s.kind) {
            (Some(i), _) => format!("{program} --impl {i}"),
            (None, Kind::Segment) => format!("{program} --impl line-visibility"),
            (None, _) => program,
        };
        let args = if s.args.is_empty() { String::new() } else { format!(" {}", s.args.join(" ")) };
        let to = match implementations(s.kind) {
            [] if s.kind == Kind::Acquire => {
                "can be swapped to another --binary or other --args, handed over at a scan boundary".to_owned()
            }
            [] if s.kind == Kind::Mapserver => {
                "can be swapped to another --binary or other --args (another --map), served as a new map version"
                    .to_owned()
            }
            [] => "cannot be swapped yet".to_owned(),
            i => format!("can be swapped to --impl {}, another --binary, other --args or --set", i.join(" | ")),
        };
        out += &format!("{} ({}): {running}{args}\n    {to}\n", s.name, s.kind.as_str());
        for a in &s.alternatives {
            let mut what = Vec::new();
            if let Some(i) = &a.implementation {
                what.push(format!("--impl {i}"));
            }
            if let Some(b) = &a.binary {
                what.push(format!("--binary {}", b.display()));
            }
            if let Some(args) = &a.args {
                what.push(format!("--args {}", args.join(" ")));
            }
            out += &format!("    --to {}: {}\n", a.name, what.join(" "));
        }
    }
    out
}

#[derive(Args, Debug)]
pub struct SwapArgs {
    /// The stage to replace, by its name in the pipeline; without it, list the stages and what
    /// each can be swapped to.
    pub stage: Option<String>,
    /// A replacement the pipeline file names for the stage ([[stage.alternative]]).
    #[arg(long, conflicts_with_all = ["implementation", "binary", "set", "args"])]
    pub to: Option<String>,
    /// The implementation to run instead.
    #[arg(long = "impl")]
    pub implementation: Option<String>,
    /// A separately built program of the same stage kind to run instead (it must answer
    /// --wire-version with this pipeline's).
    #[arg(long)]
    pub binary: Option<PathBuf>,
    /// A parameter for the new process, KEY=VALUE (repeatable), after the stage's arguments.
    #[arg(long = "set", value_name = "KEY=VALUE")]
    pub set: Vec<String>,
    /// The new process's arguments, instead of the stage's (everything after --args).
    #[arg(long, num_args = 0.., allow_hyphen_values = true)]
    pub args: Option<Vec<String>>,
    /// The running pipeline's service prefix (its `gema2 run --prefix`).
    #[arg(long, default_value = "gema2")]
    pub prefix: String,
}

/// The client side: asks a running `gema2 run` to swap (or list), and waits for its answer.
pub fn request(a: SwapArgs) -> Result<()> {
    let mut args = a.args.clone().unwrap_or_default();
    for kv in &a.set {
        args.extend(["--set".to_owned(), kv.clone()]);
    }
    let binary = match &a.binary {
        // the supervisor runs in its own directory: a relative path is made whole here
        Some(b) => std::path::absolute(b).with_context(|| b.display().to_string())?.display().to_string(),
        None => String::new(),
    };
    let req = ControlRequest {
        what: if a.stage.is_some() { CONTROL_SWAP } else { CONTROL_LIST },
        replace_args: u32::from(a.args.is_some()),
        stage: name_bytes(a.stage.as_deref().unwrap_or("")),
        implementation: name_bytes(a.implementation.as_deref().unwrap_or("")),
        alternative: name_bytes(a.to.as_deref().unwrap_or("")),
        binary: padded(&binary).ok_or_else(|| anyhow!("--binary: a path of at most {} bytes", messages::PATH_LEN))?,
        args: pack_args(&args).ok_or_else(|| anyhow!("the arguments take more than {} bytes", messages::ARGS_LEN))?,
    };
    if a.stage.as_ref().is_some_and(|s| s.len() > messages::NAME_LEN) {
        bail!("a stage's name is at most {} bytes", messages::NAME_LEN);
    }
    let node = messages::create_node("swap")?;
    let control = open_control(&node, &a.prefix)?;
    let client = control.client_builder().create().context("control")?;
    let pending = client.send_copy(req).context("control: send")?;
    match messages::await_response(&node, &pending, Duration::from_secs(40)).context("control")? {
        Awaited::Answer(r) => {
            let message = unpadded(&r.message);
            if r.ok == 1 {
                print!("{message}{}", if message.ends_with('\n') { "" } else { "\n" });
                return Ok(());
            }
            bail!("{message}");
        }
        Awaited::NoServer => bail!("no gema2 run is serving {}/control", a.prefix),
        Awaited::TimedOut => bail!("no answer from the supervisor within 40 s"),
        Awaited::Interrupted => bail!("interrupted while waiting for the supervisor"),
    }
}
