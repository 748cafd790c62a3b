//! The gema2 wire contract: every payload that crosses a process boundary, every service name,
//! and the one function each process opens services through.
//!
//! Payloads are fixed-size `#[repr(C)]` plain data with documented maxima, loaned from shared
//! memory and written in place: nothing is serialized on the hot path. Each topic is a
//! publish-subscribe service paired with an event service of the same name, so a subscriber
//! blocks in a `WaitSet` instead of polling. Whoever creates a service fixes its settings, so
//! they are defined here once ([`Topic::settings`]) and every process opens through
//! [`open_topic`].
//!
//! One job: the wire contract. Depends on iceoryx2, serde and nothing of the algorithm; every
//! process depends on it, and no library algorithm does.

mod inlet;
pub mod latency;
mod model;
mod outlet;
mod payload;
pub mod placement;
mod publish;
mod runtime;
mod topic;
mod waiting;

/// The wire contract's version: raised with any change to a payload's layout, a topic's name
/// or settings, or what a message means. A stage program answers it to `--wire-version`, and
/// the supervisor swaps in only a program that answers its own.
pub const WIRE_VERSION: u32 = 4;

pub use inlet::{run_stage, Inlet, WaitError, MAX_LISTENERS};
pub use model::{open_model_topic, ModelHeader, ModelOutlet, ModelPorts, MODEL_ALIGN, MODEL_HELD};
pub use outlet::{Freshness, Outlet, Refused, SendError, AHEAD_SLACK_NS, CONNECT_PATIENCE, LOOK, WARM_UP};
pub use payload::*;
pub use placement::pin_to_cpu;
pub use publish::{publish, zeroed_box, PublishError, Zeroable};
pub use runtime::{
    announce_ready, cleanup_dead_nodes, create_node, dead_node_pids, instance, monotonic_ns, ready_listener,
    return_freed_memory, say_line, RuntimeError, StageArgs, EXPIRED_CONNECTIONS, MAX_INSTANCE, MISSED_WAKEUP_POLL,
};
pub use topic::{
    open_control, open_corner_queries, open_events, open_pubsub, open_topic, service_name, OpenError, Topic,
    TopicPorts, TopicSettings, ALL_TOPICS,
};

pub use waiting::{
    await_response, run_waitset, sleep, sleep_until, termination_requested, Awaited, ListenerDrain, Look,
};

pub use iceoryx2;
