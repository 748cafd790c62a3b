//! Every topic: its service name, payload type and settings, and the one way to open it.

use iceoryx2::prelude::*;
use iceoryx2::service::builder::publish_subscribe::{PublishSubscribeOpenError, PublishSubscribeOpenOrCreateError};
use iceoryx2::service::port_factory::{event, publish_subscribe, request_response};
use std::fmt::Debug;
use thiserror::Error;

/// The published topics, in pipeline order.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Topic {
    /// [`crate::ScanMsg`] from `acquire`.
    Scan,
    /// [`crate::LinesMsg`] from `segment`.
    Lines,
    /// [`crate::CornersMsg`] from `segment`, with the latest kept: a localizer that starts
    /// (or restarts, or is swapped in) locates it at once.
    Corners,
    /// [`crate::PoseMsg`] from `localize`.
    Pose,
    /// [`crate::MapMsg`] from `mapserver`, with history.
    Map,
}

/// Every topic: a recorder that must see everything iterates over this.
pub const ALL_TOPICS: [Topic; 5] = [Topic::Scan, Topic::Lines, Topic::Corners, Topic::Pose, Topic::Map];

/// Settings fixed by whoever creates a topic's service.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TopicSettings {
    /// Samples kept for subscribers that connect later.
    pub history: usize,
    /// Samples a subscriber can hold unread.
    pub buffer: usize,
    /// Two publishers at once: a stage and its replacement during a hot swap.
    pub max_publishers: usize,
    pub max_subscribers: usize,
    /// Whether a full subscriber buffer overwrites its oldest sample. Off for the data topics:
    /// their publishers then wait or drop by their own strategy, and nothing is lost silently.
    pub safe_overflow: bool,
}

impl Topic {
    /// The service name's last part: `gema2/<topic>` or `<prefix>/<topic>`.
    pub fn suffix(self) -> &'static str {
        match self {
            Topic::Scan => "scan",
            Topic::Lines => "lines",
            Topic::Corners => "corners",
            Topic::Pose => "pose",
            Topic::Map => "map",
        }
    }

    /// The Rust type of the payload.
    pub fn payload_type(self) -> &'static str {
        match self {
            Topic::Scan => std::any::type_name::<crate::ScanMsg>(),
            Topic::Lines => std::any::type_name::<crate::LinesMsg>(),
            Topic::Corners => std::any::type_name::<crate::CornersMsg>(),
            Topic::Pose => std::any::type_name::<crate::PoseMsg>(),
            Topic::Map => std::any::type_name::<crate::MapMsg>(),
        }
    }

    pub fn settings(self) -> TopicSettings {
        let base =
            TopicSettings { history: 0, buffer: 64, max_publishers: 3, max_subscribers: 8, safe_overflow: false };
        match self {
            Topic::Map => TopicSettings { history: 1, buffer: 2, safe_overflow: true, ..base },
            Topic::Corners => TopicSettings { history: 1, ..base },
            _ => base,
        }
    }
}

/// Why a service could not be opened; always names the service.
#[derive(Debug, Error)]
pub enum OpenError {
    #[error("service {service}: invalid name: {message}")]
    Name { service: String, message: String },
    #[error("service {service}: carries {expected}, cannot be opened as {requested}")]
    WrongType { service: String, expected: &'static str, requested: &'static str },
    #[error("service {service}: {message}")]
    Open { service: String, message: String },
    #[error("service {service}: cannot create a port: {message}")]
    Port { service: String, message: String },
}

/// What every service of the pipeline carries, and every process requires when it opens one:
/// the wire contract's version ([`crate::WIRE_VERSION`]). A process of another version is
/// refused at connect time, naming the service, instead of misreading its messages.
pub fn wire_attributes() -> AttributeVerifier {
    let verifier = (|| {
        let key = "gema2.wire_version".try_into().ok()?;
        let value = crate::WIRE_VERSION.to_string().as_str().try_into().ok()?;
        AttributeVerifier::new().require(&key, &value).ok()
    })();
    // a fixed key and a short number always fit
    verifier.unwrap_or_default()
}

/// The full service name of `topic` under `prefix` (`gema2` by default).
pub fn service_name(prefix: &str, topic: &str) -> String {
    format!("{}/{}", prefix.trim_end_matches('/'), topic)
}

/// A topic's two services: the data and the event that wakes its subscribers.
pub struct TopicPorts<T: Debug + ZeroCopySend + 'static> {
    pub name: String,
    pub data: publish_subscribe::PortFactory<ipc::Service, T, ()>,
    pub event: event::PortFactory<ipc::Service>,
}

pub(crate) fn parse_name(service: &str) -> Result<ServiceName, OpenError> {
    ServiceName::new(service).map_err(|e| OpenError::Name { service: service.into(), message: format!("{e:?}") })
}

/// Opens (or creates, with [`Topic::settings`]) `topic` under `prefix`, with payload type `T`.
/// A `T` that is not the topic's payload is refused before iceoryx2 is asked; a service created
/// elsewhere with another type fails with iceoryx2's own complaint, both naming the service.
pub fn open_topic<T: Debug + ZeroCopySend + 'static>(
    node: &Node<ipc::Service>,
    prefix: &str,
    topic: Topic,
) -> Result<TopicPorts<T>, OpenError> {
    let service = service_name(prefix, topic.suffix());
    let requested = std::any::type_name::<T>();
    if requested != topic.payload_type() {
        return Err(OpenError::WrongType { service, expected: topic.payload_type(), requested });
    }
    open_pubsub::<T>(node, &service, topic.settings())
}

/// Opens any publish-subscribe service with the given settings (and its event service).
pub fn open_pubsub<T: Debug + ZeroCopySend + 'static>(
    node: &Node<ipc::Service>,
    service: &str,
    s: TopicSettings,
) -> Result<TopicPorts<T>, OpenError> {
    let name = parse_name(service)?;
    let data = node
        .service_builder(&name)
        .publish_subscribe::<T>()
        .history_size(s.history)
        .enable_safe_overflow(s.safe_overflow)
        .subscriber_max_buffer_size(s.buffer.max(s.history))
        .max_publishers(s.max_publishers)
        .max_subscribers(s.max_subscribers)
        .max_nodes(32)
        .open_or_create_with_attributes(&crate::topic::wire_attributes())
        .map_err(|e| {
            let payload = std::any::type_name::<T>();
            let hint = match e {
                PublishSubscribeOpenOrCreateError::PublishSubscribeOpenError(
                    PublishSubscribeOpenError::IncompatibleTypes,
                ) => {
                    // what it usually means in practice: one binary is older than the others
                    "; another process created it with a different payload layout: are all the \
                     processes (a `viewer` too) built from the same sources?"
                }
                PublishSubscribeOpenOrCreateError::PublishSubscribeOpenError(
                    PublishSubscribeOpenError::IncompatibleAttributes,
                ) => "; another process created it with another wire version (messages::WIRE_VERSION)",
                _ => "",
            };
            OpenError::Open { service: service.into(), message: format!("{e:?} (payload {payload}){hint}") }
        })?;
    let event = open_event(node, &name, service, s.max_subscribers)?;
    Ok(TopicPorts { name: service.into(), data, event })
}

/// Opens (or creates) the event service paired with the data service `name` (`service`):
/// what wakes its subscribers. Each subscriber listens once, so the listeners are at most
/// the subscribers, `max_listeners`: every notifier (each publisher has one) keeps a slot per
/// listener, about 1.2 KB each of the publishing process's own memory.
pub(crate) fn open_event(
    node: &Node<ipc::Service>,
    name: &ServiceName,
    service: &str,
    max_listeners: usize,
) -> Result<event::PortFactory<ipc::Service>, OpenError> {
    node.service_builder(name)
        .event()
        .max_notifiers(16)
        .max_listeners(max_listeners)
        .max_nodes(32)
        .open_or_create_with_attributes(&crate::topic::wire_attributes())
        .map_err(|e| OpenError::Open { service: service.into(), message: format!("event: {e:?}") })
}

/// The supervisor's events, `<prefix>/events`: a few kept for a recorder that connects late;
/// a full reader loses the oldest, so the supervisor never waits on one.
pub fn open_events(node: &Node<ipc::Service>, prefix: &str) -> Result<TopicPorts<crate::EventMsg>, OpenError> {
    let settings =
        TopicSettings { history: 16, buffer: 16, max_publishers: 2, max_subscribers: 8, safe_overflow: true };
    open_pubsub::<crate::EventMsg>(node, &service_name(prefix, "events"), settings)
}

/// The map server's corner query service, `<prefix>/map/corners`.
pub fn open_corner_queries(
    node: &Node<ipc::Service>,
    prefix: &str,
) -> Result<request_response::PortFactory<ipc::Service, crate::CornerQuery, (), crate::CornerReply, ()>, OpenError> {
    // two servers: a restarted map server's may overlap its predecessor's for a moment
    open_request_response(node, &service_name(prefix, "map/corners"), 2)
}

/// The supervisor's control service, `<prefix>/control`.
pub fn open_control(
    node: &Node<ipc::Service>,
    prefix: &str,
) -> Result<request_response::PortFactory<ipc::Service, crate::ControlRequest, (), crate::ControlReply, ()>, OpenError>
{
    // one server: the supervisor that owns the prefix (see `gema2 run`)
    open_request_response(node, &service_name(prefix, "control"), 1)
}

fn open_request_response<Q: Debug + ZeroCopySend + 'static, R: Debug + ZeroCopySend + 'static>(
    node: &Node<ipc::Service>,
    service: &str,
    max_servers: usize,
) -> Result<request_response::PortFactory<ipc::Service, Q, (), R, ()>, OpenError> {
    let name = parse_name(service)?;
    node.service_builder(&name)
        .request_response::<Q, R>()
        .max_clients(8)
        .max_servers(max_servers)
        .open_or_create_with_attributes(&crate::topic::wire_attributes())
        .map_err(|e| OpenError::Open { service: service.into(), message: format!("{e:?}") })
}
