//! Publishing in place: a payload is loaned from shared memory, zeroed there and filled by the
//! caller, so even an 80 KB message never exists on the stack.

use crate::payload::*;
use iceoryx2::port::notifier::Notifier;
use iceoryx2::port::publisher::Publisher;
use iceoryx2::prelude::*;
use std::fmt::Debug;

/// Payloads for which all-zero bytes are a valid value (numbers and arrays of numbers only).
///
/// # Safety
/// Implement only for `#[repr(C)]` types whose every field is an integer, a float or an array
/// or struct of such.
pub unsafe trait Zeroable {}

// SAFETY: every field of these types is an integer, a float, or an array or struct of those.
unsafe impl Zeroable for ScanMsg {}
unsafe impl Zeroable for LinesMsg {}
unsafe impl Zeroable for CornersMsg {}
unsafe impl Zeroable for PoseMsg {}
unsafe impl Zeroable for MapMsg {}
unsafe impl Zeroable for CornerReply {}
unsafe impl Zeroable for ControlReply {}

/// Loans a sample, zeroes it in place, lets `fill` write it, sends it and wakes the topic's
/// listeners. Returns how many subscribers received it.
pub fn publish<T: Debug + ZeroCopySend + Zeroable>(
    publisher: &Publisher<ipc::Service, T, ()>,
    notifier: &Notifier<ipc::Service>,
    fill: impl FnOnce(&mut T),
) -> Result<usize, String> {
    let mut sample = publisher.loan_uninit().map_err(|e| format!("loan: {e:?}"))?;
    // SAFETY: all-zero bytes are a valid T (Zeroable), so after write_bytes the payload is
    // initialised.
    let mut sample = unsafe {
        sample.payload_mut().as_mut_ptr().write_bytes(0, 1);
        sample.assume_init()
    };
    fill(sample.payload_mut());
    let delivered = sample.send().map_err(|e| format!("send: {e:?}"))?;
    notifier.notify().map_err(|e| format!("notify: {e:?}"))?;
    Ok(delivered)
}
