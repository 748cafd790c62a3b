//! The supervisor's loop.

use super::child::{stop, StageProcess};
use super::control::{claim_prefix, ControlServer};
use super::monitor::Monitor;
use super::pipeline::{set_arg, Kind, Pipeline, Restart, StageSpec, SupervisorSpec, EMBEDDED};
use super::swap::{Swap, SwapOutcome};
use anyhow::{bail, Context, Result};
use clap::Args;
use messages::iceoryx2::prelude::*;
use messages::{open_control, ready_listener, Inlet, Look, PoseMsg, Topic, MAX_INSTANCE};
use std::collections::HashSet;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

#[derive(Args, Debug, Clone)]
pub struct RunArgs {
    /// Pipeline file (TOML); the embedded default runs the simulator in the bundled office.
    #[arg(long)]
    pub pipeline: Option<PathBuf>,
    /// Scans the sources publish (default: the pipeline's; 300 with the embedded pipeline). 0:
    /// until the sources end (a log's last scan), or for ever (a simulator, a sensor) until
    /// Ctrl-C or --timeout.
    #[arg(long)]
    pub scans: Option<u64>,
    /// Scans per second of the sources, or `max`.
    #[arg(long, value_parser = acquire::node::rate_arg)]
    pub rate: Option<String>,
    /// Service name prefix, so several pipelines can share a machine.
    #[arg(long, default_value = "gema2")]
    pub prefix: String,
    /// Write every pose received as CSV (the columns of `gema2 locate`).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Give up after this many seconds.
    #[arg(long, value_parser = crate::cmd::positive_seconds)]
    pub timeout: Option<f64>,
    /// Record every message to this rerun file through the `viewer` program.
    #[arg(long)]
    pub record: Option<PathBuf>,
    /// With --record: start a new numbered file past this size (e.g. 500M).
    #[arg(long, requires = "record")]
    pub max_size: Option<String>,
}

impl Default for RunArgs {
    /// The embedded default: the simulator in the bundled office, 300 scans at the pipeline's
    /// rate, under the `gema2` prefix.
    fn default() -> Self {
        RunArgs {
            pipeline: None,
            scans: None,
            rate: None,
            prefix: "gema2".into(),
            out: None,
            timeout: None,
            record: None,
            max_size: None,
        }
    }
}

/// Hands out instance numbers 1..=MAX_INSTANCE.
struct Instances(usize);

impl Instances {
    fn next(&mut self) -> usize {
        self.0 = self.0 % MAX_INSTANCE + 1;
        self.0
    }
}

fn wait_ready(
    ready: &messages::iceoryx2::port::listener::Listener<ipc::Service>,
    seen: &mut HashSet<usize>,
    want: usize,
    stage: &mut StageProcess,
    limit: Duration,
) -> Result<()> {
    let deadline = Instant::now() + limit;
    while !seen.contains(&want) {
        if Instant::now() > deadline {
            bail!("stage {} did not become ready within {limit:?}", stage.spec.name);
        }
        if let Some(Ok(Some(status))) = stage.child.as_mut().map(|c| c.try_wait()) {
            bail!("stage {} exited before it was ready: {status}", stage.spec.name);
        }
        let _ = ready.timed_wait(
            |e| {
                seen.insert(e.id.as_value());
            },
            Duration::from_millis(50),
        );
    }
    Ok(())
}

pub fn run(a: RunArgs) -> Result<()> {
    let mut pipeline = Pipeline::load(a.pipeline.as_deref())?;
    let origin = a.pipeline.as_deref().unwrap_or(Path::new(EMBEDDED));
    pipeline.check_cores(origin, &messages::placement::allowed_cores()?)?;
    let scans = apply_overrides(&mut pipeline, &a);
    // created before anything runs: a path that cannot be written must not cost the run
    let out = a.out.as_deref().map(create_out).transpose()?;
    // the supervisor's own place: it consumes the poses, and holds the wake-up latency request
    let _placement = Placement::take(&pipeline.supervisor)?;
    let stale = messages::cleanup_dead_nodes();
    if stale > 0 {
        messages::say!("supervisor: removed the resources of {stale} dead processes");
    }
    let node = messages::create_node("supervisor")?;
    let control = open_control(&node, &a.prefix)?;
    let server = claim_prefix(&control, &a.prefix)?;
    let poses = Inlet::<PoseMsg>::open(&node, &a.prefix, Topic::Pose)?;
    let ready = ready_listener(&node, &a.prefix)?;
    let events = Events::open(&node, &a.prefix)?;

    let mut instances = Instances(0);
    let mut seen = HashSet::new();
    let mut stages: Vec<StageProcess> = pipeline.stages.into_iter().map(StageProcess::new).collect();
    start_all(&mut stages, &a.prefix, &ready, &mut seen, &mut instances)?;
    let started = Instant::now();
    messages::say!("supervisor: {} stages running under prefix {}", stages.len(), a.prefix);

    let mut monitor = Monitor::new(out);
    let progress = crate::progress::Progress::scans("poses", scans.filter(|&n| n > 0));
    let mut swap: Option<Swap> = None;
    let mut failure: Option<anyhow::Error> = None;
    let mut last_pose = Instant::now();
    let on_event = |_: &[bool]| {
        // looked at on every wake, the tick too: a wake-up can be lost (MISSED_WAKEUP_POLL);
        // two passes, the listener drained in between (messages::Look)
        let mut look = Look::new([&poses.listener], true);
        while look.next_pass() {
            while let Ok(Some((p, taken))) = look.receive(&poses.subscriber) {
                monitor.record(&p, taken);
                last_pose = Instant::now();
            }
            progress.set(monitor.received, monitor.right, monitor.with_truth);
        }
        let _ = ready.try_wait(|e| {
            seen.insert(e.id.as_value());
        });
        if let Err(e) = reap_and_restart(&mut stages, &a.prefix, &mut instances) {
            failure = Some(e);
            return CallbackProgression::Stop;
        }
        hot_swap(&mut swap, &server, &mut stages, &a.prefix, &seen, &mut instances, &events);
        // done?
        let sources_done = stages.iter().filter(|s| s.spec.kind.is_source()).all(|s| s.finished);
        let all_in = scans.is_some_and(|n| monitor.received >= n);
        let quiet = sources_done && last_pose.elapsed() > Duration::from_secs(2);
        let timed_out = a.timeout.is_some_and(|t| started.elapsed().as_secs_f64() > t);
        if all_in || quiet || timed_out {
            if timed_out {
                messages::say!("supervisor: timed out after {:?}", started.elapsed());
            }
            return CallbackProgression::Stop;
        }
        CallbackProgression::Continue
    };
    let listeners = [(poses.name.as_str(), &poses.listener), ("the stages' readiness", &ready)];
    let waited = messages::run_stage(&node, &listeners, Duration::from_millis(20), on_event);
    progress.finish();
    stop_all(&mut stages);
    drop(swap);
    messages::cleanup_dead_nodes();
    waited?;
    if let Some(e) = failure {
        return Err(e);
    }
    report(monitor, &stages, scans, a.out.as_deref())
}

/// The `--out` CSV.
fn create_out(path: &Path) -> Result<std::io::BufWriter<std::fs::File>> {
    let file = std::fs::File::create(path).with_context(|| format!("creating {}", path.display()))?;
    Ok(std::io::BufWriter::new(file))
}

/// Applies the command line's `--scans`, `--rate` and `--record` to the pipeline; returns the
/// scans the sources publish, when known (not for `--scans 0`, which a source takes as no
/// limit).
fn apply_overrides(pipeline: &mut Pipeline, a: &RunArgs) -> Option<u64> {
    let scans = a.scans.or(if a.pipeline.is_none() { Some(300) } else { None });
    for s in pipeline.stages.iter_mut().filter(|s| s.kind == Kind::Acquire) {
        if let Some(n) = scans {
            set_arg(&mut s.args, "--scans", &n.to_string());
        }
        if let Some(r) = &a.rate {
            set_arg(&mut s.args, "--rate", r);
        }
    }
    if let Some(file) = &a.record {
        let mut args = vec!["--out".to_owned(), file.display().to_string()];
        if let Some(size) = &a.max_size {
            args.extend(["--max-size".to_owned(), size.clone()]);
        }
        // started first whatever its place (Kind::start_rank), so it is subscribed before
        // anything is published; at the front, it is also listed first in the report
        pipeline.stages.insert(
            0,
            StageSpec {
                name: "viewer".into(),
                kind: Kind::Viewer,
                binary: None,
                implementation: None,
                args,
                cpu: None,
                priority: None,
                restart: Restart::OnFailure,
                alternatives: Vec::new(),
            },
        );
    }
    scans.filter(|&n| n > 0)
}

/// The supervisor's own placement while the pipeline runs (its `[supervisor]` table): put
/// back when dropped, because `gema2 bench` runs several pipelines from one thread.
struct Placement {
    _saved: Option<messages::placement::SavedPlacement>,
    _wake_latency: Option<messages::placement::WakeLatencyRequest>,
}

impl Placement {
    fn take(placement: &SupervisorSpec) -> Result<Placement> {
        let wake_latency = match placement.wake_latency_us {
            Some(us) => {
                let r = messages::placement::WakeLatencyRequest::hold(us).context("[supervisor] wake_latency_us")?;
                messages::say!("supervisor: idle cores wake within {} us while the pipeline runs (PM QoS)", r.micros);
                Some(r)
            }
            None => None,
        };
        let saved = (placement.cpu.is_some() || placement.priority.is_some())
            .then(messages::placement::SavedPlacement::save)
            .transpose()?;
        if let (Some(cpu), Some(saved)) = (placement.cpu, &saved) {
            super::child::remember_affinity(saved.affinity());
            messages::pin_to_cpu(cpu).context("[supervisor] cpu")?;
        }
        if let Some(p) = placement.priority {
            messages::placement::set_realtime_priority(p, true).context("[supervisor] priority")?;
        }
        Ok(Placement { _saved: saved, _wake_latency: wake_latency })
    }
}

/// Starts every stage in [`Kind::start_rank`] order (the file's order among stages of a kind):
/// all but the sources each connected before the next starts, so that no scan is published
/// before its consumers listen, then the sources.
fn start_all(
    stages: &mut [StageProcess],
    prefix: &str,
    ready: &messages::iceoryx2::port::listener::Listener<ipc::Service>,
    seen: &mut HashSet<usize>,
    instances: &mut Instances,
) -> Result<()> {
    let mut order: Vec<usize> = (0..stages.len()).collect();
    order.sort_by_key(|&i| stages[i].spec.kind.start_rank());
    let (sources, others): (Vec<usize>, Vec<usize>) = order.into_iter().partition(|&i| stages[i].spec.kind.is_source());
    let has_mapserver = stages.iter().any(|s| s.spec.kind == Kind::Mapserver);
    for i in others {
        let (k, st) = (instances.next(), &mut stages[i]);
        st.start(prefix, None, k)?;
        let started = wait_ready(ready, seen, k, st, Duration::from_secs(30));
        if st.spec.kind == Kind::Localize && !has_mapserver {
            started.with_context(|| {
                format!(
                    "stage {:?} got no map: the pipeline has no mapserver stage, and none runs under prefix {prefix:?}",
                    st.spec.name
                )
            })?;
        } else {
            started?;
        }
    }
    for i in sources {
        stages[i].start(prefix, None, instances.next())?;
    }
    Ok(())
}

/// Reaps the stages that ended, schedules the restart of those whose policy asks for one
/// (with backoff, their dead nodes cleaned up), and starts those that are due. An error when
/// a stage cannot be started again.
fn reap_and_restart(stages: &mut [StageProcess], prefix: &str, instances: &mut Instances) -> Result<()> {
    for st in stages.iter_mut() {
        let exited = st.child.as_mut().and_then(|c| c.try_wait().ok().flatten());
        if let Some(status) = exited {
            st.child = None;
            if st.should_restart(&status) {
                let removed = messages::cleanup_dead_nodes();
                messages::say!(
                    "supervisor: stage {} ended ({status}); restarting in {:?} ({removed} dead nodes cleaned)",
                    st.spec.name,
                    st.backoff()
                );
                st.restart_at = Some(Instant::now() + st.backoff());
                st.restarts += 1;
            } else {
                st.finished = true;
                if !status.success() {
                    messages::say!("supervisor: stage {} ended ({status}), not restarted", st.spec.name);
                    st.failed = Some(status);
                }
            }
        }
        if st.restart_at.is_some_and(|t| Instant::now() >= t) {
            let implementation = st.spec.implementation.clone();
            st.start(prefix, implementation.as_deref(), instances.next())?;
        }
    }
    Ok(())
}

/// Takes a hot-swap request when none is in progress, and advances the one that is.
fn hot_swap(
    swap: &mut Option<Swap>,
    server: &ControlServer,
    stages: &mut [StageProcess],
    prefix: &str,
    seen: &HashSet<usize>,
    instances: &mut Instances,
    events: &Events,
) {
    if swap.is_none() {
        match Swap::accept(server, stages, prefix, || instances.next()) {
            Ok(s) => *swap = s,
            Err(e) => {
                messages::say!("supervisor: {e:#}");
                events.say(false, &format!("{e:#}"));
            }
        }
    }
    if let Some(s) = swap.as_mut() {
        let (ok, message) = match s.progress(seen, stages) {
            SwapOutcome::Pending => return,
            SwapOutcome::Done(message) => (true, message),
            SwapOutcome::Failed(message) => (false, message),
        };
        messages::say!("supervisor: {message}");
        events.say(ok, &message);
        *swap = None;
    }
}

/// The supervisor's end of `<prefix>/events`: what it did, for the recording.
struct Events {
    publisher: messages::iceoryx2::port::publisher::Publisher<ipc::Service, messages::EventMsg, ()>,
    notifier: messages::iceoryx2::port::notifier::Notifier<ipc::Service>,
}

impl Events {
    fn open(node: &Node<ipc::Service>, prefix: &str) -> Result<Self> {
        let ports = messages::open_events(node, prefix)?;
        let publisher =
            ports.data.publisher_builder().create().with_context(|| format!("{}: publisher", ports.name))?;
        let notifier = ports.event.notifier_builder().create().with_context(|| format!("{}: notifier", ports.name))?;
        Ok(Events { publisher, notifier })
    }

    /// Publishes `text` (cut to fit); a failure to is said, never fatal.
    fn say(&self, ok: bool, text: &str) {
        let text = messages::cut_padded::<{ messages::EVENT_LEN }>(text);
        let m = messages::EventMsg { stamp_ns: messages::monotonic_ns(), ok: u32::from(ok), _pad: 0, text };
        if let Err(e) = messages::publish(&self.publisher, &self.notifier, |slot: &mut messages::EventMsg| *slot = m) {
            messages::say!("supervisor: events: {e}");
        }
    }
}

/// Stops every stage: SIGTERM, a grace period, then SIGKILL. The recorder goes last, so it
/// records everything the others sent; it flushes on SIGTERM.
fn stop_all(stages: &mut [StageProcess]) {
    for st in stages.iter_mut().filter(|s| s.spec.kind != Kind::Viewer) {
        if let Some(mut c) = st.child.take() {
            stop(&mut c, Duration::from_secs(3));
        }
    }
    for st in stages.iter_mut().filter(|s| s.spec.kind == Kind::Viewer) {
        if let Some(mut c) = st.child.take() {
            stop(&mut c, Duration::from_secs(30));
        }
    }
}

/// What a run's report ends with: where to go from here.
const NEXT: &str = "next:
  gema2 run --record run.rrd && gema2 inspect run.rrd   record every message, then read the recording
  gema2 locate --map MAP --log LOG.log                  locate a CARMEN log of your own, offline
  gema2 swap segment --impl split-and-merge             swap a stage while a run runs (another terminal)
  gema2 evaluate                                        the accuracy suite (docs/results.md)
  gema2 --help                                          everything else";

/// Prints the latency and accuracy figures and the restarts, and finishes the CSV of the
/// poses received at `out` (written as they came). A run asked for scans that got no pose
/// back is an error.
fn report(
    monitor: Monitor<std::io::BufWriter<std::fs::File>>,
    stages: &[StageProcess],
    scans: Option<u64>,
    out: Option<&Path>,
) -> Result<()> {
    println!("{}", monitor.render(scans));
    for st in stages.iter().filter(|s| s.restarts > 0) {
        println!("stage {} restarted {} times", st.spec.name, st.restarts);
    }
    println!("{NEXT}");
    let received = monitor.received;
    monitor.finish_csv().with_context(|| format!("writing {}", out.map_or(Path::new("-"), |p| p).display()))?;
    if let Some(n) = scans.filter(|_| received == 0) {
        bail!("no pose came back of the {n} scans asked for: see the stages' messages above");
    }
    if let Some((st, how)) = stages.iter().find_map(|s| s.failed.map(|how| (s, how))) {
        bail!(
            "stage {} ended ({how}) and was not restarted (restart = \"{}\"): the report above is of a \
             broken pipeline",
            st.spec.name,
            st.spec.restart.as_str()
        );
    }
    Ok(())
}
