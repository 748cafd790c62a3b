//! The map model topic, `<prefix>/map/model`: the map server's model of the map, built once per
//! map version and read in place by every localizer.
//!
//! The payload is one block of bytes, a dynamic-size `[u8]` slice, 16-byte aligned, whose
//! layout the map library defines and versions (`map::flat`, `map::model::MODEL_LAYOUT`); the
//! [`ModelHeader`] says which map version and layout it holds and how long it is. The service
//! keeps the newest block as history, so a localizer that starts, restarts or is swapped in
//! later gets the current model at once. A subscriber may hold two blocks: the one it locates
//! with and a newer one it switches to between two scans. Publishing a new version never
//! overwrites a block a localizer still holds: the publisher takes a fresh chunk, and a chunk
//! returns to it only when every reader has released it.

use crate::topic::{open_event, parse_name, service_name, OpenError};
use bytemuck::Zeroable;
use iceoryx2::port::publisher::Publisher;
use iceoryx2::port::subscriber::Subscriber;
use iceoryx2::port::update_connections::UpdateConnections;
use iceoryx2::prelude::*;
use iceoryx2::service::port_factory::{event, publish_subscribe};

/// What a model block is, in front of it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, ZeroCopySend, Zeroable)]
#[repr(C)]
pub struct ModelHeader {
    /// The map version the model was built from: that of the `gema2/map` message of the same
    /// map.
    pub map_version: u32,
    pub _pad: u32,
    /// The block's layout version (`map::model::MODEL_LAYOUT`).
    pub layout: u64,
    /// The block's length, bytes.
    pub block_len: u64,
}

/// The alignment of a model block, bytes (`map::flat::ALIGN`).
pub const MODEL_ALIGN: usize = 16;

/// Blocks a model reader may hold at once: the one it reads and a newer one.
pub const MODEL_HELD: usize = 2;

/// Readers of the model at once: localizers, their replacements during a swap, and tools.
const MODEL_READERS: usize = 16;

/// The model topic's data and wake-up services.
pub struct ModelPorts {
    pub name: String,
    pub data: publish_subscribe::PortFactory<ipc::Service, [u8], ModelHeader>,
    pub event: event::PortFactory<ipc::Service>,
}

/// Opens (or creates) `<prefix>/map/model`.
pub fn open_model_topic(node: &Node<ipc::Service>, prefix: &str) -> Result<ModelPorts, OpenError> {
    let service = service_name(prefix, "map/model");
    let name = parse_name(&service)?;
    let alignment = Alignment::new(MODEL_ALIGN)
        .ok_or_else(|| OpenError::Open { service: service.clone(), message: "alignment".into() })?;
    let open = |e: &dyn std::fmt::Debug| OpenError::Open { service: service.clone(), message: format!("{e:?}") };
    let data = node
        .service_builder(&name)
        .publish_subscribe::<[u8]>()
        .user_header::<ModelHeader>()
        .payload_alignment(alignment)
        .history_size(1)
        .subscriber_max_buffer_size(1)
        .subscriber_max_borrowed_samples(MODEL_HELD)
        .enable_safe_overflow(true)
        // a map server and its replacement
        .max_publishers(2)
        .max_subscribers(MODEL_READERS)
        .max_nodes(32)
        .open_or_create_with_attributes(&crate::topic::wire_attributes())
        .map_err(|e| open(&e))?;
    let event = open_event(node, &name, &service, MODEL_READERS)?;
    Ok(ModelPorts { name: service, data, event })
}

impl ModelPorts {
    pub fn subscriber(&self) -> Result<Subscriber<ipc::Service, [u8], ModelHeader>, OpenError> {
        self.data
            .subscriber_builder()
            .create()
            .map_err(|e| OpenError::Port { service: self.name.clone(), message: format!("subscriber: {e:?}") })
    }
}

/// The map server's side of the model topic: a publisher whose chunks hold the largest block
/// sent so far, made anew (the old one first let go) when a later version's block is larger.
///
/// Its chunks lie in one fixed-size segment (iceoryx2's static allocation). A segment that
/// grows instead costs every reader a table of all the segments it may grow to, about 290 KB
/// of the reader's own memory, more than a tenth of a small map's model. A reader still
/// holding a block of the publisher let go keeps it: it holds the expired connection
/// ([`crate::EXPIRED_CONNECTIONS`]) until it releases the block.
pub struct ModelOutlet {
    publisher: Option<Publisher<ipc::Service, [u8], ModelHeader>>,
    /// The bytes a chunk of `publisher` holds.
    capacity: usize,
}

impl ModelOutlet {
    /// An outlet whose chunks hold `block_len` bytes.
    pub fn new(ports: &ModelPorts, block_len: usize) -> Result<Self, OpenError> {
        let publisher = Self::publisher(ports, block_len)?;
        Ok(ModelOutlet { publisher: Some(publisher), capacity: block_len.max(1) })
    }

    fn publisher(
        ports: &ModelPorts,
        block_len: usize,
    ) -> Result<Publisher<ipc::Service, [u8], ModelHeader>, OpenError> {
        ports
            .data
            .publisher_builder()
            .initial_max_slice_len(block_len.max(1))
            .allocation_strategy(AllocationStrategy::Static)
            .max_loaned_samples(1)
            .create()
            .map_err(|e| OpenError::Port { service: ports.name.clone(), message: format!("publisher: {e:?}") })
    }

    /// Hands a reader that joined the history (the newest block).
    pub fn update_connections(&self, ports: &ModelPorts) -> Result<(), OpenError> {
        match &self.publisher {
            Some(p) => p
                .update_connections()
                .map_err(|e| OpenError::Port { service: ports.name.clone(), message: format!("{e:?}") }),
            None => Ok(()),
        }
    }

    /// Publishes the model block `block` as `map_version` (its layout `layout`) and wakes the
    /// readers. The block is copied once, into the loaned chunk; readers read it there. A block
    /// larger than the chunks takes a new publisher, made after the old one is let go (the
    /// service allows a map server and its replacement, one publisher each).
    pub fn publish(
        &mut self,
        ports: &ModelPorts,
        notifier: &iceoryx2::port::notifier::Notifier<ipc::Service>,
        map_version: u32,
        layout: u64,
        block: &[u8],
    ) -> Result<(), OpenError> {
        let fail = |what: &str, e: &dyn std::fmt::Debug| OpenError::Port {
            service: ports.name.clone(),
            message: format!("{what} {} bytes: {e:?}", block.len()),
        };
        if block.len() > self.capacity {
            self.publisher = None;
        }
        let publisher = match &mut self.publisher {
            Some(p) => p,
            // none after a failed remake too: the next version tries again
            none => {
                let p = none.insert(Self::publisher(ports, block.len())?);
                self.capacity = block.len().max(1);
                p
            }
        };
        let mut sample = publisher.loan_slice_uninit(block.len()).map_err(|e| fail("loan", &e))?;
        *sample.user_header_mut() = ModelHeader { map_version, _pad: 0, layout, block_len: block.len() as u64 };
        let sample = sample.write_from_slice(block);
        sample.send().map_err(|e| fail("send", &e))?;
        notifier.notify().map_err(|e| fail("notify", &e))?;
        Ok(())
    }
}
