//! A stage's output on one topic, and what its subscribers use to take each scan once.
//!
//! iceoryx2 0.10 connects a subscriber to a publisher lazily: the subscriber's side of the link
//! exists only from its first `receive` after the publisher appeared. A message that finds a
//! subscriber not connected yet *and* its buffer full is dropped for that subscriber, even by a
//! publisher that waits for room (`RetryUntilDelivered`), "to prevent a deadlock". A stage that
//! starts, restarts or is swapped in and sends a burst before a busy subscriber has looked at
//! its queue loses messages that way: seen under load as 17-85 scans lost at the 64th.
//! [`Outlet::send`] notices (fewer recipients than subscribers) and sends the message again
//! until every subscriber has it; subscribers skip the copies they already had
//! ([`Freshness`]).
//!
//! A reader that dies (kill -9, a crash) leaves its side of the link in shared memory, still
//! "connected", its buffer full. A publisher that waits for room would wait for it forever, and
//! iceoryx2 ends such a wait with an error: a dead localize once took its segment stage down
//! with it. An outlet that waits for room therefore asks, while it waits, whether the reader's
//! process is alive, and gives up on a dead one's copy of the message; a send that still fails
//! removes the dead nodes' resources and is tried once more. The reader is served again when it
//! is back (a restart subscribes afresh).

use crate::publish::{publish, PublishError, Zeroable};
use crate::topic::{open_topic, OpenError, Topic};
use crate::Header;
use iceoryx2::port::notifier::Notifier;
use iceoryx2::port::publisher::Publisher;
use iceoryx2::port::update_connections::UpdateConnections;
use iceoryx2::port::{BackpressureAction, BackpressureInfo};
use iceoryx2::prelude::*;
use iceoryx2::service::port_factory::publish_subscribe;
use std::fmt::Debug;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use thiserror::Error;

/// Why an outlet could not send a message.
#[derive(Debug, Error)]
#[error("{topic}: {reason}")]
pub struct SendError {
    pub topic: String,
    /// In the message, not chained as a source too: it would print twice ("Caused by").
    pub reason: PublishError,
}

/// The process of each subscriber, by the subscriber's port id: what the backpressure handler
/// asks about while it waits for room.
type Readers = Arc<Mutex<Vec<(u128, i32)>>>;

/// Whether process `pid` is alive (or a zombie not yet reaped).
fn alive(pid: i32) -> bool {
    // SAFETY: kill with signal 0 sends nothing; it only checks that the process exists.
    unsafe { libc::kill(pid, 0) == 0 || std::io::Error::last_os_error().raw_os_error() != Some(libc::ESRCH) }
}

/// While a subscriber's buffer is full: wait while its process lives, give up on its copy once
/// it is dead. A subscriber not yet listed is waited for, as iceoryx2 would.
fn wait_for_live_readers(readers: &Readers) -> impl Fn(&BackpressureInfo) -> BackpressureAction + Send {
    let readers = readers.clone();
    move |info: &BackpressureInfo| {
        let pid = readers.lock().ok().and_then(|r| r.iter().find(|(id, _)| *id == info.receiver_port_id).map(|r| r.1));
        match pid {
            Some(pid) if !alive(pid) => BackpressureAction::DiscardData,
            _ => BackpressureAction::Retry,
        }
    }
}

/// How long, in all, an outlet waits for late subscribers to connect over its lifetime. A
/// subscriber connects within one of its polls ([`crate::MISSED_WAKEUP_POLL`]); one that
/// never does (it died before its first receive) costs this much once, not per message.
pub const CONNECT_PATIENCE: Duration = Duration::from_secs(2);

/// The event id of a warm-up: a wake-up with no message, sent ahead of a periodic scan so that
/// the scan's own wake-ups find a warm path. On this project's 2-core VM a hop took 30-70 us
/// p50 after 100 ms asleep (the kernel's wake-up path gone cold in the caches) and 10-25 us
/// with a warm-up 200 us before (real-time placement, `gema2 bench --pipeline`). A stage that
/// wakes for a warm-up takes nothing, passes the warm-up on to the next stage
/// ([`ListenerDrain::warm_up_to_pass_on`](crate::ListenerDrain::warm_up_to_pass_on),
/// [`Outlet::warm_up`])
/// and waits again. Messages are notified with iceoryx2's default id, 0.
pub const WARM_UP: EventId = EventId::new(1);

/// The event id of a wake-up that says "look at your queue": a topic's history was just
/// handed to a subscriber that connected after its last message ([`Outlet::serve_history`]).
/// History comes with no wake-up of its own, and a reader would otherwise find it only at its
/// next poll ([`crate::MISSED_WAKEUP_POLL`]) or with the next message.
pub const LOOK: EventId = EventId::new(2);

/// Pause before sending again to a subscriber that has not connected yet.
const RESEND_PAUSE: Duration = Duration::from_micros(200);

/// A publisher and its notifier on one topic.
pub struct Outlet<T: Debug + ZeroCopySend + Zeroable + 'static> {
    name: String,
    data: publish_subscribe::PortFactory<ipc::Service, T, ()>,
    publisher: Publisher<ipc::Service, T, ()>,
    notifier: Notifier<ipc::Service>,
    waits_for_room: bool,
    patience: Duration,
    /// Messages sent again because a subscriber had not connected yet.
    pub resent: u64,
    /// Messages that some subscriber never got (patience ran out, or the outlet drops by
    /// design when a buffer is full).
    pub missed: u64,
    readers: Readers,
}

impl<T: Debug + ZeroCopySend + Zeroable + 'static> Outlet<T> {
    /// Opens `topic` under `prefix` and creates its publisher and notifier. With
    /// `BackpressureStrategy::RetryUntilDelivered` sending waits for room and nothing is lost;
    /// with `DiscardData` a subscriber whose buffer is full misses the message.
    pub fn open(
        node: &Node<ipc::Service>,
        prefix: &str,
        topic: Topic,
        strategy: BackpressureStrategy,
    ) -> Result<Self, OpenError> {
        let ports = open_topic::<T>(node, prefix, topic)?;
        let port = |e: &dyn Debug| OpenError::Port { service: ports.name.clone(), message: format!("{e:?}") };
        let readers = Readers::default();
        let waits_for_room = matches!(strategy, BackpressureStrategy::RetryUntilDelivered);
        let mut builder = ports.data.publisher_builder().backpressure_strategy(strategy);
        if waits_for_room {
            builder = builder.set_backpressure_handler(wait_for_live_readers(&readers));
        }
        let publisher = builder.create().map_err(|e| port(&e))?;
        let notifier = ports.event.notifier_builder().create().map_err(|e| port(&e))?;
        Ok(Outlet {
            waits_for_room,
            readers,
            name: ports.name,
            data: ports.data,
            publisher,
            notifier,
            patience: CONNECT_PATIENCE,
            resent: 0,
            missed: 0,
        })
    }

    /// The service name.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// Loans a message, lets `fill` write it (again, for each resend), sends it and wakes the
    /// subscribers. Returns how many subscribers received it.
    pub fn send(&mut self, mut fill: impl FnMut(&mut T)) -> Result<usize, SendError> {
        let mut delivered = self.publish_once(&mut fill)?;
        let mut subscribers = self.subscribers();
        while self.waits_for_room && delivered < subscribers && !self.patience.is_zero() {
            let start = Instant::now();
            std::thread::sleep(RESEND_PAUSE);
            delivered = self.publish_once(&mut fill)?;
            subscribers = self.subscribers();
            self.resent += 1;
            self.patience = self.patience.saturating_sub(start.elapsed());
        }
        if delivered < subscribers {
            self.missed += 1;
        }
        Ok(delivered)
    }

    /// One publication. A delivery that fails (a dead reader's link) clears the dead nodes'
    /// resources and is tried once more; the second failure is the caller's.
    fn publish_once(&mut self, fill: &mut impl FnMut(&mut T)) -> Result<usize, SendError> {
        self.list_readers();
        match publish(&self.publisher, &self.notifier, &mut *fill) {
            Err(PublishError::Send(_)) => {
                crate::cleanup_dead_nodes();
                self.list_readers();
                self.missed += 1;
                publish(&self.publisher, &self.notifier, fill)
            }
            other => other,
        }
        .map_err(|reason| SendError { topic: self.name.clone(), reason })
    }

    /// Lists the subscribers' processes for the backpressure handler, before each publication:
    /// a reader that died and one that took its place between two messages must both be known
    /// (a few entries of shared memory, read in place).
    fn list_readers(&mut self) {
        if !self.waits_for_room {
            return;
        }
        let Ok(mut readers) = self.readers.lock() else { return };
        readers.clear();
        self.data.dynamic_config().list_subscribers(|s| {
            if let Ok(pid) = s.node_id.pid::<ipc::Service>() {
                readers.push((s.subscriber_id.value(), pid.value()));
            }
            CallbackProgression::Continue
        });
    }

    /// Hands the topic's history ([`Topic::settings`](crate::Topic::settings)) to subscribers
    /// that connected since the last message, and wakes them to look at it ([`LOOK`]). A
    /// publisher hands history out only when it sends or is asked to: a stage calls this when
    /// another stage announces itself ready ([`crate::announce_ready`]), so that a restarted or
    /// swapped-in reader has the latest message at once instead of at the next one.
    pub fn serve_history(&self) -> Result<(), SendError> {
        let failed = |reason| SendError { topic: self.name.clone(), reason };
        self.publisher.update_connections().map_err(|e| failed(PublishError::Connect(e)))?;
        self.notifier.notify_with_custom_event_id(LOOK).map(|_| ()).map_err(|e| failed(PublishError::Notify(e)))
    }

    /// Wakes the subscribers without a message ([`WARM_UP`]).
    pub fn warm_up(&self) -> Result<(), SendError> {
        self.notifier
            .notify_with_custom_event_id(WARM_UP)
            .map(|_| ())
            .map_err(|e| SendError { topic: self.name.clone(), reason: PublishError::Notify(e) })
    }

    fn subscribers(&self) -> usize {
        self.data.dynamic_config().number_of_subscribers()
    }

    /// Publishers of the topic other than this one: a source being replaced, while both run.
    pub fn other_publishers(&self) -> usize {
        self.data.dynamic_config().number_of_publishers().saturating_sub(1)
    }

    /// What was resent or missed, for a stage's closing report; `None` when nothing was.
    pub fn report(&self) -> Option<String> {
        (self.resent > 0 || self.missed > 0).then(|| {
            format!(
                "{}: {} messages sent again to a subscriber not yet connected, {} missed by some subscriber",
                self.name, self.resent, self.missed
            )
        })
    }
}

/// Admits each scan's message once. Copies carry the acquisition stamp of a scan already
/// seen: a resend by an [`Outlet`], or the same scan from two segmenters during a hot swap.
/// Stamps come from one monotonic clock, so a restarted source (which numbers its scans from
/// the start again) is still admitted.
///
/// A stamp ahead of that clock (by more than [`AHEAD_SLACK_NS`]) is no stamp of it: a damaged
/// message, or a publisher stamping with another clock (wall time, a ROS time). It is refused
/// and not remembered; remembered, it would make every later message look old, and one bad
/// message would stop a stage for good.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Freshness {
    last_stamp_ns: Option<u64>,
}

/// How far ahead of the reader's clock a stamp may lie and still be taken as one of the
/// machine's monotonic clock. Every process reads the same clock and stamps before it
/// publishes, so an honest stamp is never ahead; the margin only guards against the clock's
/// own rounding. A hostile stamp within it costs the scans of the next 10 ms at most.
pub const AHEAD_SLACK_NS: u64 = 10_000_000;

/// Why [`Freshness`] did not admit a message.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Refused {
    /// Stamped no later than a message admitted before: a copy, or an older scan.
    Seen,
    /// Stamped this far ahead of the reader's monotonic clock.
    Ahead { by_ns: u64 },
}

impl std::fmt::Display for Refused {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Refused::Seen => write!(f, "stamped no later than a message taken before"),
            Refused::Ahead { by_ns } => write!(
                f,
                "stamped {:.3} s ahead of this machine's monotonic clock, which every stage stamps with",
                *by_ns as f64 / 1e9
            ),
        }
    }
}

impl Freshness {
    /// True for a message newer than every message admitted before and not ahead of the
    /// monotonic clock; remembers it.
    pub fn admit(&mut self, header: &Header) -> bool {
        self.check(header, crate::monotonic_ns()).is_ok()
    }

    /// [`admit`](Self::admit) with the clock read as `now_ns`, and why a message is refused.
    pub fn check(&mut self, header: &Header, now_ns: u64) -> Result<(), Refused> {
        if header.stamp_ns > now_ns.saturating_add(AHEAD_SLACK_NS) {
            return Err(Refused::Ahead { by_ns: header.stamp_ns - now_ns });
        }
        if self.last_stamp_ns.is_some_and(|last| header.stamp_ns <= last) {
            return Err(Refused::Seen);
        }
        self.last_stamp_ns = Some(header.stamp_ns);
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn freshness_admits_each_stamp_once_and_a_restarted_source() {
        let mut f = Freshness::default();
        assert!(f.admit(&Header::new(0, 100)));
        assert!(!f.admit(&Header::new(0, 100)), "a copy");
        assert!(f.admit(&Header::new(1, 200)));
        assert!(!f.admit(&Header::new(0, 150)), "older than the last one");
        // a restarted source numbers from 0 again, later on the same clock
        assert!(f.admit(&Header::new(0, 300)));
    }

    /// One message stamped ahead of the clock is refused, and does not make the next ones look
    /// old.
    #[test]
    fn a_stamp_ahead_of_the_clock_is_refused_and_forgotten() {
        let mut f = Freshness::default();
        let now = 5_000_000_000;
        assert_eq!(f.check(&Header::new(0, now - 10), now), Ok(()));
        assert_eq!(f.check(&Header::new(1, u64::MAX), now), Err(Refused::Ahead { by_ns: u64::MAX - now }));
        assert_eq!(
            f.check(&Header::new(2, now + 2 * AHEAD_SLACK_NS), now),
            Err(Refused::Ahead { by_ns: 2 * AHEAD_SLACK_NS })
        );
        assert_eq!(f.check(&Header::new(3, now - 5), now), Ok(()), "a scan after them");
        // within the slack: taken as the machine's clock
        assert_eq!(f.check(&Header::new(4, now + AHEAD_SLACK_NS / 2), now), Ok(()));
        assert_eq!(f.check(&Header::new(4, now - 1), now), Err(Refused::Seen));
    }
}
