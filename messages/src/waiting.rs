//! Waiting that only a stop request ends.
//!
//! iceoryx2 0.10 reports *any* interrupted wait as an interrupt: `WaitSet::wait_and_process`
//! returns `WaitSetRunResult::Interrupt` and `Node::wait` fails with `NodeWaitFailure::Interrupt`
//! whenever the system call returns EINTR. That happens for SIGINT, but also when the process
//! is stopped and continued (Ctrl-Z then `fg`, SIGSTOP/SIGCONT), when a debugger or `strace`
//! attaches, or on any other handled signal. A stage that took that for a stop request would
//! quietly end mid-run (exit status 0, so not restarted either). The functions here ask the
//! node whether SIGINT or SIGTERM really arrived, and otherwise wait again.

use iceoryx2::node::NodeWaitFailure;
use iceoryx2::port::listener::Listener;
use iceoryx2::port::subscriber::Subscriber;
use iceoryx2::port::ReceiveError;
use iceoryx2::prelude::*;
use iceoryx2::sample::Sample;
use iceoryx2::waitset::{WaitSetRunError, WaitSetRunResult};
use std::time::{Duration, Instant};

/// True when SIGINT or SIGTERM arrived. iceoryx2's handler records them for nodes created
/// with `SignalHandlingMode::HandleTerminationRequests` ([`crate::create_node`]); asking
/// consumes the record, so call this only to decide to stop.
pub fn termination_requested(node: &Node<ipc::Service>) -> bool {
    node.wait(Duration::ZERO).is_err()
}

/// Runs `waitset` until `on_event` returns `CallbackProgression::Stop` or SIGINT/SIGTERM
/// arrives; waits that another signal cut short are resumed.
pub fn run_waitset<F>(
    node: &Node<ipc::Service>,
    waitset: &WaitSet<ipc::Service>,
    mut on_event: F,
) -> Result<WaitSetRunResult, WaitSetRunError>
where
    F: FnMut(WaitSetAttachmentId<ipc::Service>) -> CallbackProgression,
{
    loop {
        match waitset.wait_and_process_once(&mut on_event)? {
            WaitSetRunResult::AllEventsHandled => {}
            WaitSetRunResult::Interrupt if !termination_requested(node) => {}
            stopped => return Ok(stopped),
        }
    }
}

/// How a wait for the answer to a request ended.
pub enum Awaited<R> {
    Answer(R),
    /// The request reached no server.
    NoServer,
    TimedOut,
    /// SIGINT or SIGTERM arrived first.
    Interrupted,
}

/// Waits up to `timeout` for the answer to the request `pending` stands for, looking every 5 ms:
/// what a command-line client of a running process (`gema2 swap`, `gema2 map corners`) does.
pub fn await_response<Req, Res>(
    node: &Node<ipc::Service>,
    pending: &iceoryx2::pending_response::PendingResponse<ipc::Service, Req, (), Res, ()>,
    timeout: Duration,
) -> Result<Awaited<iceoryx2::response::Response<ipc::Service, Res, ()>>, ReceiveError>
where
    Req: std::fmt::Debug + ZeroCopySend,
    Res: std::fmt::Debug + ZeroCopySend,
{
    if pending.number_of_server_connections() == 0 {
        return Ok(Awaited::NoServer);
    }
    let deadline = Instant::now() + timeout;
    loop {
        if let Some(r) = pending.receive()? {
            return Ok(Awaited::Answer(r));
        }
        if Instant::now() > deadline {
            return Ok(Awaited::TimedOut);
        }
        if !sleep(node, Duration::from_millis(5)) {
            return Ok(Awaited::Interrupted);
        }
    }
}

/// Sleeps until `deadline` (resuming after unrelated signals); false when SIGINT or SIGTERM
/// arrived first.
pub fn sleep_until(node: &Node<ipc::Service>, deadline: Instant) -> bool {
    loop {
        match node.wait(deadline.saturating_duration_since(Instant::now())) {
            Ok(()) => return true,
            Err(NodeWaitFailure::TerminationRequest) => return false,
            Err(NodeWaitFailure::Interrupt) if termination_requested(node) => return false,
            Err(NodeWaitFailure::Interrupt) => {}
        }
    }
}

/// Drains a stage's listeners once per look at its queues. iceoryx2's listener must be drained on
/// every wake (see [`crate::MISSED_WAKEUP_POLL`]), but its system calls are best made after the
/// scan that woke the stage is taken and stamped, so they count in the stage and in neither
/// hop. A look therefore reads the queues twice: [`once`](Self::once) after stamping the first
/// message, and before the second pass if no message came in the first; a message whose
/// notification the drain took is taken in the second pass, any later one wakes the stage.
pub struct ListenerDrain<'a, const N: usize> {
    listeners: [&'a Listener<ipc::Service>; N],
    done: bool,
    warm_up: bool,
    took: bool,
}

impl<'a, const N: usize> ListenerDrain<'a, N> {
    pub fn new(listeners: [&'a Listener<ipc::Service>; N]) -> Self {
        ListenerDrain { listeners, done: false, warm_up: false, took: false }
    }

    /// Drains every listener, the first time it is called in this look.
    pub fn once(&mut self) {
        if !self.done {
            for l in self.listeners {
                let _ = l.try_wait(|e| self.warm_up |= e.id == crate::WARM_UP);
            }
            self.done = true;
        }
    }

    /// A message was taken in this look: drains (see [`once`](Self::once)) and remembers it.
    pub fn took_message(&mut self) {
        self.once();
        self.took = true;
    }

    /// Whether the drain took a [`crate::WARM_UP`] in a look that took no message: the stage
    /// passes it on to the next one (a message would wake that one anyway).
    pub fn warm_up_to_pass_on(&self) -> bool {
        self.warm_up && !self.took
    }
}

/// A message as a [`Look`] takes it: the sample, and when it was taken ([`crate::monotonic_ns`]).
pub type Taken<T> = (Sample<ipc::Service, T, ()>, u64);

/// One look at a stage's input, as a call of its [`run_waitset`] callback makes it: the two
/// passes of [`ListenerDrain`], each message stamped as it is taken, and whether the look
/// found scans that no wake-up announced.
///
/// ```text
/// let mut look = Look::new([&listener], id.has_event_from(&woken_by_scans));
/// while look.next_pass() {
///     while let Some((sample, enter)) = look.receive(&subscriber)? { ... }
/// }
/// ```
pub struct Look<'a, const N: usize> {
    drain: ListenerDrain<'a, N>,
    passes: u8,
    woken: bool,
    counted: bool,
}

impl<'a, const N: usize> Look<'a, N> {
    /// A look at the queues whose notifications come to `listeners`; `woken` when a wake-up of
    /// the stage's scans started it (not its poll, nor another input).
    pub fn new(listeners: [&'a Listener<ipc::Service>; N], woken: bool) -> Self {
        Look { drain: ListenerDrain::new(listeners), passes: 0, woken, counted: false }
    }

    /// Starts the next pass over the queues: true twice, the listeners drained before the
    /// second if no message has drained them yet.
    pub fn next_pass(&mut self) -> bool {
        if self.passes == 1 {
            self.drain.once();
        }
        self.passes += 1;
        self.passes <= 2
    }

    /// The next message of `subscriber`, with the time it was taken ([`crate::monotonic_ns`]);
    /// the listeners are drained after the first one (see [`ListenerDrain`]).
    pub fn receive<T: IceoryxSend + std::fmt::Debug>(
        &mut self,
        subscriber: &Subscriber<ipc::Service, T, ()>,
    ) -> Result<Option<Taken<T>>, ReceiveError> {
        let Some(sample) = subscriber.receive()? else {
            return Ok(None);
        };
        let enter = crate::monotonic_ns();
        self.drain.took_message();
        Ok(Some((sample, enter)))
    }

    /// Call for each scan the stage takes on: true for the first in a look that no wake-up of
    /// the scans started, which found it by the poll ([`crate::MISSED_WAKEUP_POLL`]). Counted
    /// once per look, since a busy stage keeps taking scans in one look, wake-up or not.
    pub fn found_by_poll(&mut self) -> bool {
        let first = !self.woken && !self.counted;
        self.counted = true;
        first
    }

    /// See [`ListenerDrain::warm_up_to_pass_on`].
    pub fn warm_up_to_pass_on(&self) -> bool {
        self.drain.warm_up_to_pass_on()
    }
}

/// [`sleep_until`] `now + d`.
pub fn sleep(node: &Node<ipc::Service>, d: Duration) -> bool {
    sleep_until(node, Instant::now() + d)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::atomic::{AtomicBool, Ordering};

    static HANDLED: AtomicBool = AtomicBool::new(false);
    extern "C" fn on_usr2(_: libc::c_int) {
        HANDLED.store(true, Ordering::Relaxed);
    }

    /// A handled signal that is not a stop request (SIGUSR2 here, installed without SA_RESTART)
    /// interrupts the sleep, which must still last its whole time.
    #[test]
    fn a_sleep_cut_short_by_another_signal_sleeps_on() {
        let node = crate::create_node("waiting_test").unwrap();
        // iceoryx2 installs its handlers for most signals on first use: let it, then take SIGUSR2
        assert!(!termination_requested(&node));
        // SAFETY: the handler only stores to an atomic; sigaction without SA_RESTART makes the
        // sleep return EINTR.
        unsafe {
            let mut act: libc::sigaction = std::mem::zeroed();
            act.sa_sigaction = on_usr2 as *const () as usize;
            libc::sigaction(libc::SIGUSR2, &act, std::ptr::null_mut());
        }
        let me = unsafe { libc::pthread_self() };
        let poker = std::thread::spawn(move || {
            std::thread::sleep(Duration::from_millis(50));
            // SAFETY: signals the test's thread, which is alive until this thread is joined.
            unsafe { libc::pthread_kill(me, libc::SIGUSR2) };
        });
        let start = Instant::now();
        assert!(sleep(&node, Duration::from_millis(300)), "an unrelated signal was taken for a stop");
        poker.join().unwrap();
        assert!(HANDLED.load(Ordering::Relaxed), "the signal did not arrive during the sleep");
        assert!(start.elapsed() >= Duration::from_millis(300));
    }
}
