//! Operator requests to the gateway (engage, stop, disengage, e-stop) from the command line.

use std::time::Duration;

use iceoryx2::service::Service;
use v2t_wire::{Code, Header, SafetyAction, SafetyCommand, services};

use crate::clock::now_ns;
use crate::config::Loaded;
use crate::error::EdgeError;
use crate::ports::{Bus, send};

/// Sends `action` to the gateway of `cfg`'s BV.
pub fn request<S: Service>(cfg: &Loaded, action: SafetyAction) -> Result<(), EdgeError> {
    let bus = Bus::<S>::new("operator", &cfg.edge.namespace)?;
    let out = bus.publisher::<SafetyCommand>(services::SAFETY)?;
    let wake = bus.notifier(services::WAKE_GATEWAY)?;
    // Let the gateway's subscriber connect to the new publisher before the request goes out.
    bus.wait(Duration::from_millis(50));
    let cmd = SafetyCommand { header: Header { seq: 1, stamp_ns: now_ns() }, action: action.code(), culprit: 0 };
    send(&out, Some(&wake), cmd)?;
    // Keep the publisher (and its history) alive a moment so a gateway between cycles still reads it.
    bus.wait(Duration::from_millis(100));
    Ok(())
}
