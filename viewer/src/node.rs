//! The recorder process: subscribes to every topic of [`messages::ALL_TOPICS`] and records what
//! arrives. It blocks in a WaitSet; on SIGINT or SIGTERM it takes what is still queued, flushes
//! and closes the file, so nothing already received is lost.

use crate::output::{Output, OutputSpec};
use crate::record::{Counts, Recorder};
use anyhow::{anyhow, Context, Result};
use clap::Args;
use messages::iceoryx2::port::listener::Listener;
use messages::iceoryx2::port::subscriber::Subscriber;
use messages::iceoryx2::prelude::*;
use messages::{CornersMsg, LinesMsg, MapMsg, PoseMsg, ScanMsg, Topic};
use rerun::components::TextLogLevel;
use std::fmt::Debug;
use std::path::PathBuf;
use std::time::Duration;

#[derive(Args, Debug, Clone)]
pub struct RecordArgs {
    /// The .rrd file to write (later parts, with --max-size, are numbered beside it).
    #[arg(long, short)]
    pub out: Option<PathBuf>,
    /// Start a new numbered file once the current one holds this many bytes (suffixes k, M, G).
    #[arg(long, value_parser = parse_size)]
    pub max_size: Option<u64>,
    /// Spawn a rerun viewer (the `rerun` program on PATH) and stream to it as well.
    #[arg(long)]
    pub spawn: bool,
    /// Stream to a running rerun viewer as well: HOST:PORT or rerun+http://HOST:PORT/proxy.
    #[arg(long)]
    pub connect: Option<String>,
    #[command(flatten)]
    pub stage: messages::StageArgs,
}

/// `512k`, `64M`, `2G` or plain bytes.
pub fn parse_size(s: &str) -> Result<u64, String> {
    let s = s.trim();
    let (digits, unit) = match s.char_indices().find(|(_, c)| !c.is_ascii_digit()) {
        Some((k, _)) => (&s[..k], s[k..].trim()),
        None => (s, ""),
    };
    let n: u64 = digits.parse().map_err(|_| format!("{s:?}: not a size (e.g. 500M)"))?;
    let scale: u64 = match unit.to_ascii_lowercase().as_str() {
        "" | "b" => 1,
        "k" | "kb" | "kib" => 1 << 10,
        "m" | "mb" | "mib" => 1 << 20,
        "g" | "gb" | "gib" => 1 << 30,
        _ => return Err(format!("{s:?}: unknown unit {unit:?} (k, M or G)")),
    };
    n.checked_mul(scale).filter(|&b| b > 0).ok_or_else(|| format!("{s:?}: out of range"))
}

/// One topic's subscription: the data port and the listener that wakes on it.
pub struct TopicSubscription<T: Debug + ZeroCopySend + 'static> {
    pub name: String,
    pub data: Subscriber<ipc::Service, T, ()>,
    pub wake: Listener<ipc::Service>,
}

fn subscribe<T: Debug + ZeroCopySend + 'static>(
    node: &Node<ipc::Service>,
    prefix: &str,
    topic: Topic,
) -> Result<TopicSubscription<T>> {
    let inlet = messages::Inlet::<T>::open(node, prefix, topic)?;
    Ok(TopicSubscription { name: inlet.name, data: inlet.subscriber, wake: inlet.listener })
}

/// A subscription to every topic. Built by matching on each [`Topic`], so a new topic does not
/// compile until it has a recorder; [`Subscriptions::topics`] lists what is subscribed, checked
/// against [`messages::ALL_TOPICS`] by a test.
pub struct Subscriptions {
    pub scan: TopicSubscription<ScanMsg>,
    pub lines: TopicSubscription<LinesMsg>,
    pub corners: TopicSubscription<CornersMsg>,
    pub pose: TopicSubscription<PoseMsg>,
    pub map: TopicSubscription<MapMsg>,
    /// The supervisor's events (swaps), beside the data topics.
    pub events: TopicSubscription<messages::EventMsg>,
}

impl Subscriptions {
    /// Subscribes to every topic of [`messages::ALL_TOPICS`]; a topic missing from that list is
    /// an error naming it.
    pub fn open(node: &Node<ipc::Service>, prefix: &str) -> Result<Self> {
        let (mut scan, mut lines, mut corners, mut pose, mut map) = (None, None, None, None, None);
        for topic in messages::ALL_TOPICS {
            match topic {
                Topic::Scan => scan = Some(subscribe(node, prefix, topic)?),
                Topic::Lines => lines = Some(subscribe(node, prefix, topic)?),
                Topic::Corners => corners = Some(subscribe(node, prefix, topic)?),
                Topic::Pose => pose = Some(subscribe(node, prefix, topic)?),
                Topic::Map => map = Some(subscribe(node, prefix, topic)?),
            }
        }
        let missing = |t: Topic| anyhow!("topic {t:?} is not in messages::ALL_TOPICS, so it would not be recorded");
        let events = {
            let ports = messages::open_events(node, prefix)?;
            let data =
                ports.data.subscriber_builder().create().with_context(|| format!("{}: subscriber", ports.name))?;
            let wake = ports.event.listener_builder().create().with_context(|| format!("{}: listener", ports.name))?;
            TopicSubscription { name: ports.name, data, wake }
        };
        Ok(Subscriptions {
            events,
            scan: scan.ok_or_else(|| missing(Topic::Scan))?,
            lines: lines.ok_or_else(|| missing(Topic::Lines))?,
            corners: corners.ok_or_else(|| missing(Topic::Corners))?,
            pose: pose.ok_or_else(|| missing(Topic::Pose))?,
            map: map.ok_or_else(|| missing(Topic::Map))?,
        })
    }

    /// The topics subscribed, by their service names' last part.
    pub fn topics(&self) -> Vec<Topic> {
        let names = [&self.scan.name, &self.lines.name, &self.corners.name, &self.pose.name, &self.map.name];
        messages::ALL_TOPICS
            .into_iter()
            .filter(|t| names.iter().any(|n| n.ends_with(&format!("/{}", t.suffix()))))
            .collect()
    }

    fn listeners(&self) -> [(&str, &Listener<ipc::Service>); 6] {
        [
            (&self.events.name, &self.events.wake),
            (&self.scan.name, &self.scan.wake),
            (&self.lines.name, &self.lines.wake),
            (&self.corners.name, &self.corners.wake),
            (&self.pose.name, &self.pose.wake),
            (&self.map.name, &self.map.wake),
        ]
    }

    /// Records everything queued, in pipeline order (map, scans, lines, corners, poses), so a
    /// pose always finds its scan. The stages run meanwhile: a pose taken here can have been
    /// published after this look drained the corners, its own among them, so before each pose
    /// the earlier topics are drained again (cheap when empty). Errors of the recording itself
    /// end the run.
    pub fn drain(&self, recorder: &mut Recorder) -> Result<()> {
        for (_, l) in self.listeners() {
            let _ = l.try_wait(|_| {});
        }
        fn each<T: Debug + ZeroCopySend>(
            s: &TopicSubscription<T>,
            mut f: impl FnMut(&T) -> Result<(), crate::output::OutputError>,
        ) -> Result<()> {
            loop {
                match s.data.receive() {
                    Ok(Some(sample)) => f(&sample).with_context(|| format!("recording {}", s.name))?,
                    Ok(None) => return Ok(()),
                    Err(e) => return Err(anyhow!("{}: receive: {e}", s.name)),
                }
            }
        }
        let upstream = |recorder: &mut Recorder| -> Result<()> {
            each(&self.scan, |m| recorder.scan(m))?;
            each(&self.lines, |m| recorder.lines(m))?;
            each(&self.corners, |m| recorder.corners(m))
        };
        each(&self.events, |m| recorder.event(m))?;
        each(&self.map, |m| recorder.map(m))?;
        upstream(recorder)?;
        loop {
            match self.pose.data.receive() {
                Ok(Some(pose)) => {
                    upstream(recorder)?;
                    recorder.pose(&pose).with_context(|| format!("recording {}", self.pose.name))?;
                }
                Ok(None) => return Ok(()),
                Err(e) => return Err(anyhow!("{}: receive: {e}", self.pose.name)),
            }
        }
    }
}

/// How long `--connect` waits for a live viewer to answer before warning that none does.
const LIVE_WAIT: Duration = Duration::from_secs(2);

/// Runs the recorder until SIGINT or SIGTERM; prints what it recorded.
pub fn run(a: RecordArgs) -> Result<Counts> {
    a.stage.place()?;
    let output = Output::open(OutputSpec {
        file: a.out.clone(),
        max_size: a.max_size,
        spawn: a.spawn,
        connect: a.connect.clone(),
        recording_id: None,
    })?;
    let mut recorder = Recorder::new(output);
    let node = messages::create_node("viewer")?;
    let subs = Subscriptions::open(&node, &a.stage.prefix)?;
    messages::announce_ready(&node, &a.stage.prefix)?;
    messages::say!("viewer: recording {} to {}", a.stage.prefix, describe(&a));
    if let Some(c) = a.connect.as_deref() {
        if let Some(why) = crate::output::unanswered(&crate::output::connect_url(c), LIVE_WAIT) {
            messages::say!(
                "viewer: warning: no rerun viewer answers at {c} ({why}); one started later shows what \
                 comes after it connects, and the recording ends in an error"
            );
        }
    }
    let mut failure = None;
    // the map waits in history without an event; late samples are picked up on the tick too
    let waited = messages::run_stage(&node, &subs.listeners(), Duration::from_millis(200), |_| {
        match subs.drain(&mut recorder) {
            Ok(()) => CallbackProgression::Continue,
            Err(e) => {
                failure = Some(e);
                CallbackProgression::Stop
            }
        }
    });
    // stopped (signal or error): keep what is still queued, then close the file
    let last = subs.drain(&mut recorder);
    if let Err(e) = &waited {
        let _ = recorder.note(TextLogLevel::ERROR, format!("viewer: {e}"));
    }
    let (counts, parts, closed) = recorder.finish_keeping();
    messages::say!("viewer: stopped\n{}", counts.render());
    for p in &parts {
        messages::say!("viewer: wrote {}", p.display());
    }
    closed?;
    waited?;
    if let Some(e) = failure {
        return Err(e);
    }
    last?;
    Ok(counts)
}

fn describe(a: &RecordArgs) -> String {
    let mut to = Vec::new();
    if let Some(f) = &a.out {
        to.push(f.display().to_string());
    }
    if a.spawn {
        to.push("a spawned rerun viewer".into());
    }
    if let Some(c) = &a.connect {
        to.push(c.clone());
    }
    to.join(" and ")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_parse() {
        assert_eq!(parse_size("512k"), Ok(512 * 1024));
        assert_eq!(parse_size("64M"), Ok(64 << 20));
        assert_eq!(parse_size("1000"), Ok(1000));
        assert!(parse_size("0").is_err());
        assert!(parse_size("12parsecs").is_err());
        assert!(parse_size("M").is_err());
    }

    #[test]
    fn every_topic_is_subscribed_and_recorded() {
        let node = messages::create_node("viewer-test").unwrap();
        let prefix = format!("gema2-viewer-test-{}", std::process::id());
        let subs = Subscriptions::open(&node, &prefix).unwrap();
        assert_eq!(subs.topics(), messages::ALL_TOPICS.to_vec());
    }
}
