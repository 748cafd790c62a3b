//! Publishing in place: a payload is loaned from shared memory, zeroed there and filled by the
//! caller, so even an 80 KB message never exists on the stack.

use iceoryx2::port::notifier::Notifier;
use iceoryx2::port::publisher::Publisher;
use iceoryx2::prelude::*;
use std::fmt::Debug;
use thiserror::Error;

/// Why a message was not published. Each cause is in the message, not chained as a source
/// too, where it would print twice.
#[derive(Debug, Error)]
pub enum PublishError {
    /// No shared memory for the payload: every sample is held by slow or dead readers.
    #[error("loan: {0}")]
    Loan(iceoryx2::port::LoanError),
    /// The message reached only some subscribers (an interrupted wait, a corrupted
    /// connection).
    #[error("send: {0}")]
    Send(iceoryx2::port::SendError),
    /// The message was sent but its wake-up was not.
    #[error("notify: {0:?}")]
    Notify(iceoryx2::port::notifier::NotifierNotifyError),
    /// A subscriber that connected late could not be handed the topic's history.
    #[error("connecting a late subscriber: {0:?}")]
    Connect(iceoryx2::port::update_connections::ConnectionFailure),
}

/// Payloads for which all-zero bytes are a valid value: derived (`#[derive(Zeroable)]`), so
/// the compiler checks that every field is a number or an array or struct of numbers.
pub use bytemuck::Zeroable;

/// A payload of all zeros on the heap, never on the stack (a map message is 600 KB).
pub fn zeroed_box<T: Zeroable>() -> Box<T> {
    bytemuck::zeroed_box()
}

/// Loans a sample, zeroes it in place, lets `fill` write it, sends it and wakes the topic's
/// listeners. Returns how many subscribers received it.
pub fn publish<T: Debug + ZeroCopySend + Zeroable>(
    publisher: &Publisher<ipc::Service, T, ()>,
    notifier: &Notifier<ipc::Service>,
    fill: impl FnOnce(&mut T),
) -> Result<usize, PublishError> {
    let mut sample = publisher.loan_uninit().map_err(PublishError::Loan)?;
    // SAFETY: all-zero bytes are a valid T (Zeroable), so after write_bytes the payload is
    // initialised.
    let mut sample = unsafe {
        sample.payload_mut().as_mut_ptr().write_bytes(0, 1);
        sample.assume_init()
    };
    fill(sample.payload_mut());
    let delivered = sample.send().map_err(PublishError::Send)?;
    notifier.notify().map_err(PublishError::Notify)?;
    Ok(delivered)
}
