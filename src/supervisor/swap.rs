//! Hot swap: `gema2 swap STAGE --impl NAME` asks the supervisor, over the control service, to
//! replace a stage's implementation. The supervisor starts the new process under the same
//! service names, waits until it announces that it is ready (ports connected; a localizer has
//! read the map model), then stops the old one; nothing else restarts. While both run,
//! downstream skips duplicate scans. A segment stage swaps between its segmenters; a localize
//! stage to a fresh process of its one implementation (a new build, once installed), which
//! reads the map server's model in place and so locates from its first scan.

use super::child::{spawn, stop, StageProcess};
use super::control::ControlServer;
use super::pipeline::Kind;
use anyhow::{anyhow, Context, Result};
use clap::Args;
use localize::LOCALIZERS;
use messages::iceoryx2::active_request::ActiveRequest;
use messages::iceoryx2::prelude::*;
use messages::{name_bytes, name_str, open_control, Awaited, ControlReply, ControlRequest};
use segment::SEGMENTERS;
use std::collections::HashSet;
use std::process::Child;
use std::time::{Duration, Instant};

type Request = ActiveRequest<ipc::Service, ControlRequest, (), ControlReply, ()>;

/// A swap in progress.
pub struct Swap {
    request: Request,
    stage: usize,
    implementation: String,
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
    let mut m = ControlReply { ok: ok as u32, message: [0; 256] };
    let bytes = message.as_bytes();
    let n = bytes.len().min(255);
    m.message[..n].copy_from_slice(&bytes[..n]);
    if let Ok(r) = request.loan_uninit() {
        let _ = r.write_payload(m).send();
    }
}

impl Swap {
    /// Takes the next control request, if any, and starts the replacement.
    pub fn accept(
        server: &ControlServer,
        stages: &mut [StageProcess],
        prefix: &str,
        instance: impl FnOnce() -> usize,
    ) -> Result<Option<Swap>> {
        let Some(request) = server.receive().context("control")? else { return Ok(None) };
        let (name, implementation) =
            (name_str(&request.stage).to_owned(), name_str(&request.implementation).to_owned());
        let refuse = |why: String| -> Result<Option<Swap>> {
            reply(&request, false, &why);
            Err(anyhow!("swap refused: {why}"))
        };
        let Some(stage) = stages.iter().position(|s| s.spec.name == name) else {
            return refuse(format!("no stage called {name:?}"));
        };
        let kind = stages[stage].spec.kind;
        let implementations = implementations(kind);
        if implementations.is_empty() {
            return refuse(format!(
                "stage {name:?} is a {} stage, which cannot be swapped: a segment stage can (to one of \
                 {SEGMENTERS:?}), and a localize stage (to {LOCALIZERS:?})",
                kind.as_str()
            ));
        }
        if !implementations.contains(&implementation.as_str()) {
            return refuse(format!(
                "stage {name:?} has no implementation {implementation:?}: one of {implementations:?}"
            ));
        }
        let instance = instance();
        let new = match spawn(&stages[stage].spec, prefix, Some(&implementation), instance) {
            Ok(c) => c,
            Err(e) => return refuse(format!("{e:#}")),
        };
        eprintln!("supervisor: swapping {name} to {implementation}");
        Ok(Some(Swap {
            request,
            stage,
            implementation,
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
            let m = format!("swap of {name} failed: the new implementation exited ({status})");
            reply(&self.request, false, &m);
            return SwapOutcome::Failed(m);
        }
        if ready.contains(&self.instance) {
            if let Some(mut old) = st.child.take() {
                stop(&mut old, Duration::from_secs(3));
            }
            st.child = self.new.take();
            st.spec.implementation = Some(self.implementation.clone());
            let m = format!("swapped {name} to {}", self.implementation);
            reply(&self.request, true, &m);
            return SwapOutcome::Done(m);
        }
        if Instant::now() > self.deadline {
            if let Some(mut n) = self.new.take() {
                stop(&mut n, Duration::from_secs(1));
            }
            let m = format!("swap of {name} failed: the new implementation did not connect in time");
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

#[derive(Args, Debug)]
pub struct SwapArgs {
    /// The stage to replace, by its name in the pipeline.
    pub stage: String,
    /// The implementation to run instead.
    #[arg(long = "impl")]
    pub implementation: String,
    /// The running pipeline's service prefix (its `gema2 run --prefix`).
    #[arg(long, default_value = "gema2")]
    pub prefix: String,
}

/// The client side: asks a running `gema2 run` to swap, and waits for its answer.
pub fn request(a: SwapArgs) -> Result<()> {
    let node = messages::create_node("swap")?;
    let control = open_control(&node, &a.prefix)?;
    let client = control.client_builder().create().context("control")?;
    let req = ControlRequest { stage: name_bytes(&a.stage), implementation: name_bytes(&a.implementation) };
    let pending = client.send_copy(req).context("control: send")?;
    match messages::await_response(&node, &pending, Duration::from_secs(30)).context("control")? {
        Awaited::Answer(r) => {
            let message = String::from_utf8_lossy(r.message.split(|&b| b == 0).next().unwrap_or(&[])).into_owned();
            if r.ok == 1 {
                println!("{message}");
                return Ok(());
            }
            anyhow::bail!("{message}");
        }
        Awaited::NoServer => anyhow::bail!("no gema2 run is serving {}/control", a.prefix),
        Awaited::TimedOut => anyhow::bail!("no answer from the supervisor within 30 s"),
        Awaited::Interrupted => anyhow::bail!("interrupted while waiting for the supervisor"),
    }
}
