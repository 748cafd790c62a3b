//! A stage's input on one topic, and the wait loop every stage runs over its inputs.
//!
//! Each stage that reads topics (segment, localize, the recorder, the supervisor's pose reader)
//! opens a subscriber and the listener that wakes it for each topic, then waits on all its
//! listeners and on the missed-wake-up poll ([`crate::MISSED_WAKEUP_POLL`]) until asked to
//! stop. That set-up is written once here, with errors that name what failed.

use crate::topic::{open_topic, OpenError, Topic};
use crate::waiting::{run_waitset, termination_requested};
use iceoryx2::port::listener::Listener;
use iceoryx2::port::subscriber::Subscriber;
use iceoryx2::prelude::*;
use std::fmt::Debug;
use std::time::Duration;
use thiserror::Error;

/// A subscriber and the listener its publisher wakes, on one topic.
pub struct Inlet<T: Debug + ZeroCopySend + 'static> {
    pub name: String,
    pub subscriber: Subscriber<ipc::Service, T, ()>,
    pub listener: Listener<ipc::Service>,
}

impl<T: Debug + ZeroCopySend + 'static> Inlet<T> {
    /// Opens `topic` under `prefix` and creates its subscriber and listener.
    pub fn open(node: &Node<ipc::Service>, prefix: &str, topic: Topic) -> Result<Self, OpenError> {
        let ports = open_topic::<T>(node, prefix, topic)?;
        let port = |what: &str, e: &dyn Debug| OpenError::Port {
            service: ports.name.clone(),
            message: format!("{what}: {e:?}"),
        };
        let subscriber = ports.data.subscriber_builder().create().map_err(|e| port("subscriber", &e))?;
        let listener = ports.event.listener_builder().create().map_err(|e| port("listener", &e))?;
        Ok(Inlet { name: ports.name, subscriber, listener })
    }
}

/// Why a stage's wait loop could not run.
#[derive(Debug, Error)]
pub enum WaitError {
    #[error("waitset: creating it: {0:?}")]
    Create(iceoryx2::waitset::WaitSetCreateError),
    #[error("waitset: attaching {what}: {message}")]
    Attach { what: String, message: String },
    #[error("waitset: waiting: {0:?}")]
    Run(iceoryx2::waitset::WaitSetRunError),
}

/// The most listeners a stage waits on.
pub const MAX_LISTENERS: usize = 8;

/// Waits on `listeners` and on a poll every `poll`, calling `on_event` with which listeners
/// woke the stage (`woken[k]` for `listeners[k]`), until it returns
/// `CallbackProgression::Stop` or SIGINT/SIGTERM arrives ([`run_waitset`]).
pub fn run_stage<F>(
    node: &Node<ipc::Service>,
    listeners: &[(&str, &Listener<ipc::Service>)],
    poll: Duration,
    mut on_event: F,
) -> Result<(), WaitError>
where
    F: FnMut(&[bool]) -> CallbackProgression,
{
    assert!(listeners.len() <= MAX_LISTENERS, "a stage waits on at most {MAX_LISTENERS} listeners");
    let waitset = WaitSetBuilder::new().create::<ipc::Service>().map_err(WaitError::Create)?;
    let attach = |what: &str, e: &dyn Debug| WaitError::Attach { what: what.into(), message: format!("{e:?}") };
    let guards = listeners
        .iter()
        .map(|(name, l)| waitset.attach_notification(*l).map_err(|e| attach(name, &e)))
        .collect::<Result<Vec<_>, _>>()?;
    let _poll = waitset.attach_interval(poll).map_err(|e| attach("the poll", &e))?;
    let mut woken = [false; MAX_LISTENERS];
    // a look before the first wait: what a service's history holds (the map model) came with
    // no wake-up, and would otherwise wait for the first poll. Asking about termination first
    // installs iceoryx2's handlers, which it otherwise does at the first wait: a SIGTERM during
    // this look would kill the stage instead of stopping it
    if termination_requested(node) || on_event(&woken[..guards.len()]) == CallbackProgression::Stop {
        return Ok(());
    }
    run_waitset(node, &waitset, |id| {
        for (w, g) in woken.iter_mut().zip(&guards) {
            *w = id.has_event_from(g);
        }
        on_event(&woken[..guards.len()])
    })
    .map(|_| ())
    .map_err(WaitError::Run)
}
