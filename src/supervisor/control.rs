//! The supervisor's end of the control service (`<prefix>/control`): what `gema2 swap` asks,
//! and what claims a prefix for one run.

use anyhow::{anyhow, Result};
use messages::iceoryx2::prelude::*;
use messages::iceoryx2::service::port_factory::server::ServerCreateError;
use messages::{ControlReply, ControlRequest};

/// The supervisor's end of the control service, which `gema2 swap` asks.
pub type ControlServer = messages::iceoryx2::port::server::Server<ipc::Service, ControlRequest, (), ControlReply, ()>;
pub type ControlService = messages::iceoryx2::service::port_factory::request_response::PortFactory<
    ipc::Service,
    ControlRequest,
    (),
    ControlReply,
    (),
>;

/// The control service's server. The service takes one: holding it claims the prefix, so a
/// second run under the same prefix stops here instead of mixing its scans and poses with this
/// one's.
pub fn claim_prefix(control: &ControlService, prefix: &str) -> Result<ControlServer> {
    control.server_builder().create().map_err(|e| match e {
        ServerCreateError::ExceedsMaxSupportedServers => {
            anyhow!("prefix {prefix:?} is in use by another `gema2 run`: give this one its own --prefix")
        }
        e => anyhow::Error::from(e).context("control: server"),
    })
}
