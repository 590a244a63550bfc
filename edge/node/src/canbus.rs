//! The virtual CAN bus over iceoryx2, for machines whose kernel has no CAN: the gateway and the
//! simulated ECU exchange the same classic frames they would put on SocketCAN, through two
//! services (`can/tx`: gateway → ECU, `can/rx`: ECU → gateway).

use std::time::Duration;

use iceoryx2::port::listener::Listener;
use iceoryx2::port::notifier::Notifier;
use iceoryx2::port::publisher::Publisher;
use iceoryx2::port::subscriber::Subscriber;
use iceoryx2::service::Service;
use v2t_can::codec::CanFrame;
use v2t_can::transport::{CanError, CanTransport};
use v2t_wire::{CanFrameMsg, Header, services};

use crate::clock::now_ns;
use crate::error::EdgeError;
use crate::ports::{Bus, wait_wake};

/// Which end of the virtual bus.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum End {
    /// The BV's gateway: sends on `can/tx`, receives on `can/rx`.
    Gateway,
    /// The drive-by-wire ECU (simulated): the other way round.
    Ecu,
}

/// One end of the virtual bus.
#[derive(Debug)]
pub struct IpcCanBus<S: Service> {
    tx: Publisher<S, CanFrameMsg, ()>,
    tx_wake: Notifier<S>,
    rx: Subscriber<S, CanFrameMsg, ()>,
    rx_wake: Listener<S>,
    header: Header,
}

impl<S: Service> IpcCanBus<S> {
    /// Opens `end` of the bus of `bus`'s namespace.
    pub fn open(bus: &Bus<S>, end: End) -> Result<Self, EdgeError> {
        let (tx, rx, tx_wake, rx_wake) = match end {
            End::Gateway => (services::CAN_TX, services::CAN_RX, services::WAKE_ECU, services::WAKE_GATEWAY),
            End::Ecu => (services::CAN_RX, services::CAN_TX, services::WAKE_GATEWAY, services::WAKE_ECU),
        };
        Ok(Self {
            tx: bus.publisher(tx)?,
            tx_wake: bus.notifier(tx_wake)?,
            rx: bus.subscriber(rx)?,
            rx_wake: bus.listener(rx_wake)?,
            header: Header::default(),
        })
    }
}

fn ipc_error(e: impl std::fmt::Debug) -> CanError {
    CanError::Io(std::io::Error::other(format!("{e:?}")))
}

impl<S: Service> CanTransport for IpcCanBus<S> {
    fn send(&mut self, frame: &CanFrame) -> Result<(), CanError> {
        self.header.seq += 1;
        self.header.stamp_ns = now_ns();
        let msg = CanFrameMsg { header: self.header, id: frame.id, len: frame.len, data: frame.data };
        self.tx.send_copy(msg).map_err(ipc_error)?;
        self.tx_wake.notify().map_err(ipc_error)?;
        Ok(())
    }

    fn recv(&mut self, timeout: Duration) -> Result<Option<CanFrame>, CanError> {
        if let Some(m) = self.rx.receive().map_err(ipc_error)? {
            return Ok(Some(CanFrame { id: m.id, len: m.len, data: m.data }));
        }
        if timeout.is_zero() {
            return Ok(None);
        }
        wait_wake(&self.rx_wake, timeout).map_err(ipc_error)?;
        Ok(self.rx.receive().map_err(ipc_error)?.map(|m| CanFrame { id: m.id, len: m.len, data: m.data }))
    }
}
