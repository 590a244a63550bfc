//! Moving [`CanFrame`]s: the [`CanTransport`] trait, and its SocketCAN implementation
//! [`SocketCanBus`] (a classic `CAN_RAW` socket on `can0`, `vcan0`, …).
//!
//! The protocol of `config/can/bv.dbc` uses classic data frames with 11-bit ids only. Anything
//! else that arrives — an extended id, a remote (RTR) frame, a CAN FD frame — is rejected with
//! [`CanError::Unsupported`] and never becomes a [`CanFrame`]. The socket also subscribes to the
//! kernel's error frames: bus-off, error-passive, controller problems (overflows, warnings),
//! protocol and transceiver errors, missing ACKs and controller restarts come back from
//! [`CanTransport::recv`] as typed errors instead of being dropped. Lost arbitration (normal bus
//! operation, the frame is retransmitted) and the "back to error-active" notice are not errors.

use std::io;
use std::time::{Duration, Instant};

use socketcan as sc;
use socketcan::errors::{
    CAN_ERR_ACK, CAN_ERR_BUSERROR, CAN_ERR_BUSOFF, CAN_ERR_CRTL, CAN_ERR_PROT, CAN_ERR_RESTARTED, CAN_ERR_TRX,
    CAN_ERR_TX_TIMEOUT,
};
use socketcan::errors::{ControllerProblems, ErrorCause};
use socketcan::{EmbeddedFrame, Id, Socket, SocketOptions, StandardId};

use crate::codec::CanFrame;

/// What kind of frame was not supported.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FrameKind {
    /// A 29-bit (extended) identifier.
    Extended,
    /// A remote transmission request.
    Remote,
    /// A CAN FD frame.
    Fd,
    /// A classic frame claiming more than 8 data bytes.
    TooLong(u8),
}

impl std::fmt::Display for FrameKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Extended => write!(f, "extended (29-bit) identifier"),
            Self::Remote => write!(f, "remote (RTR) frame"),
            Self::Fd => write!(f, "CAN FD frame"),
            Self::TooLong(len) => write!(f, "{len} data bytes (at most 8)"),
        }
    }
}

/// A failure of the CAN link.
#[derive(Debug, thiserror::Error)]
pub enum CanError {
    /// The interface could not be opened (missing, down, no CAN in the kernel).
    #[error("cannot open CAN interface `{iface}`: {source}")]
    Open {
        /// Interface name.
        iface: String,
        /// The socket error.
        #[source]
        source: io::Error,
    },
    /// A socket read or write failed (including a full transmit queue).
    #[error("CAN socket: {0}")]
    Io(#[from] io::Error),
    /// The controller is bus-off: it no longer takes part in bus traffic.
    #[error("CAN controller is bus-off")]
    BusOff,
    /// The controller reached error-passive (error counter ≥ 128).
    #[error("CAN controller is error-passive ({detail})")]
    ErrorPassive {
        /// Which counters (rx, tx).
        detail: String,
    },
    /// Another controller problem: receive or transmit overflow (frames lost), error warning
    /// level, or an unspecified problem.
    #[error("CAN controller problem: {detail}")]
    Controller {
        /// The problems.
        detail: String,
    },
    /// A bus-level error: protocol violation, transceiver fault, no ACK, transmit timeout.
    #[error("CAN bus error: {detail}")]
    Bus {
        /// What the error frame said.
        detail: String,
    },
    /// The controller was restarted after bus-off; frames may have been lost.
    #[error("CAN controller restarted (frames may have been lost)")]
    Restarted,
    /// A frame this protocol does not use (only classic data frames with 11-bit ids).
    #[error("unsupported CAN frame {id:#x}: {kind}; the protocol uses classic data frames with 11-bit ids")]
    Unsupported {
        /// Its identifier (without flags).
        id: u32,
        /// What it was.
        kind: FrameKind,
    },
}

impl CanError {
    /// Whether the error says the bus or the controller is unhealthy (everything but a single
    /// unsupported frame). A gateway should start its minimal-risk stop on these.
    pub fn is_bus_fault(&self) -> bool {
        !matches!(self, Self::Unsupported { .. })
    }

    fn severity(&self) -> u8 {
        match self {
            Self::BusOff => 6,
            Self::ErrorPassive { .. } => 5,
            Self::Restarted => 4,
            Self::Controller { .. } => 3,
            Self::Bus { .. } => 2,
            Self::Open { .. } | Self::Io(_) | Self::Unsupported { .. } => 1,
        }
    }
}

/// A link that moves classic CAN frames. Object-safe: the gateway holds a `Box<dyn CanTransport>`
/// (SocketCAN, or the iceoryx2 virtual bus of `v2t-edge`).
pub trait CanTransport {
    /// Sends one frame.
    fn send(&mut self, frame: &CanFrame) -> Result<(), CanError>;
    /// The next frame, waiting at most `timeout` (zero: do not wait); `Ok(None)` if none came.
    fn recv(&mut self, timeout: Duration) -> Result<Option<CanFrame>, CanError>;
}

/// Error classes the socket subscribes to: everything except lost arbitration and the bare
/// error-counter reports.
pub const ERROR_MASK: u32 = CAN_ERR_TX_TIMEOUT
    | CAN_ERR_CRTL
    | CAN_ERR_PROT
    | CAN_ERR_TRX
    | CAN_ERR_ACK
    | CAN_ERR_BUSOFF
    | CAN_ERR_BUSERROR
    | CAN_ERR_RESTARTED;

/// The error of a controller-problem set, `None` for the bare "back to error-active" notice.
fn controller_error(p: ControllerProblems) -> Option<CanError> {
    let passive = ControllerProblems::RX_PASSIVE | ControllerProblems::TX_PASSIVE;
    if p.intersects(passive) {
        return Some(CanError::ErrorPassive { detail: (p & passive).to_string() });
    }
    let problems = p - ControllerProblems::ACTIVE;
    if p.contains(ControllerProblems::ACTIVE) && problems.is_empty() {
        return None;
    }
    // An empty set is the kernel's "unspecified controller problem".
    Some(CanError::Controller { detail: problems.to_string() })
}

/// The error an error frame reports (its most severe cause), or `None` if it reports nothing
/// that is an error (lost arbitration, error counters, recovery to error-active).
pub fn error_of(frame: sc::CanErrorFrame) -> Option<CanError> {
    let err = frame.into_error();
    let mut worst: Option<CanError> = None;
    for cause in err.causes() {
        let this = match cause {
            ErrorCause::BusOff => Some(CanError::BusOff),
            ErrorCause::Controller(p) => controller_error(*p),
            ErrorCause::Restarted => Some(CanError::Restarted),
            ErrorCause::LostArbitration(_) | ErrorCause::Counters { .. } => None,
            other => Some(CanError::Bus { detail: other.to_string() }),
        };
        if let Some(e) = this
            && worst.as_ref().is_none_or(|w| e.severity() > w.severity())
        {
            worst = Some(e);
        }
    }
    worst
}

fn raw_id(id: Id) -> u32 {
    match id {
        Id::Standard(s) => u32::from(s.as_raw()),
        Id::Extended(e) => e.as_raw(),
    }
}

/// The [`CanFrame`] of a received socketcan frame: `Ok(Some)` for a classic data frame with an
/// 11-bit id, `Ok(None)` for an error frame that reports no error, an error otherwise.
pub fn from_socketcan(frame: sc::CanFrame) -> Result<Option<CanFrame>, CanError> {
    match frame {
        sc::CanFrame::Data(d) => {
            let id = raw_id(d.id());
            if d.is_extended() {
                return Err(CanError::Unsupported { id, kind: FrameKind::Extended });
            }
            let bytes = d.data();
            let len = u8::try_from(bytes.len()).unwrap_or(u8::MAX);
            let mut data = [0u8; 8];
            match data.get_mut(..bytes.len()) {
                Some(dst) => dst.copy_from_slice(bytes),
                None => return Err(CanError::Unsupported { id, kind: FrameKind::TooLong(len) }),
            }
            Ok(Some(CanFrame { id, len, data }))
        }
        sc::CanFrame::Remote(r) => Err(CanError::Unsupported { id: raw_id(r.id()), kind: FrameKind::Remote }),
        sc::CanFrame::Error(e) => error_of(e).map_or(Ok(None), Err),
    }
}

/// As [`from_socketcan`], for a frame read from an FD-capable socket: CAN FD frames are rejected.
pub fn from_any(frame: sc::CanAnyFrame) -> Result<Option<CanFrame>, CanError> {
    match frame {
        sc::CanAnyFrame::Normal(d) => from_socketcan(sc::CanFrame::Data(d)),
        sc::CanAnyFrame::Remote(r) => from_socketcan(sc::CanFrame::Remote(r)),
        sc::CanAnyFrame::Error(e) => from_socketcan(sc::CanFrame::Error(e)),
        sc::CanAnyFrame::Fd(fd) => Err(CanError::Unsupported { id: raw_id(fd.id()), kind: FrameKind::Fd }),
    }
}

/// The socketcan data frame of `frame`: an 11-bit id and at most 8 bytes, else an error.
pub fn to_socketcan(frame: &CanFrame) -> Result<sc::CanFrame, CanError> {
    let kind = if frame.len > 8 {
        Some(FrameKind::TooLong(frame.len))
    } else if frame.id > CanFrame::MAX_STANDARD_ID {
        Some(FrameKind::Extended)
    } else {
        None
    };
    if let Some(kind) = kind {
        return Err(CanError::Unsupported { id: frame.id, kind });
    }
    let std_id = u16::try_from(frame.id).ok().and_then(StandardId::new);
    std_id
        .and_then(|id| sc::CanDataFrame::new(id, frame.payload()))
        .map(sc::CanFrame::Data)
        .ok_or(CanError::Unsupported { id: frame.id, kind: FrameKind::Extended })
}

/// A SocketCAN `CAN_RAW` socket bound to one interface.
#[derive(Debug)]
pub struct SocketCanBus {
    socket: sc::CanSocket,
    iface: String,
}

impl SocketCanBus {
    /// How long a send may wait for room in the transmit queue.
    pub const WRITE_TIMEOUT: Duration = Duration::from_millis(10);

    /// Opens `iface`, subscribes to its error frames ([`ERROR_MASK`]) and sets the write timeout.
    pub fn open(iface: &str) -> Result<Self, CanError> {
        let open_error = |source| CanError::Open { iface: iface.to_owned(), source };
        let socket = sc::CanSocket::open(iface).map_err(open_error)?;
        socket.set_error_filter(ERROR_MASK).map_err(open_error)?;
        socket.set_write_timeout(Self::WRITE_TIMEOUT).map_err(open_error)?;
        Ok(Self { socket, iface: iface.to_owned() })
    }

    /// The interface name.
    pub fn iface(&self) -> &str {
        &self.iface
    }

    /// Changes how long a send may wait for room in the transmit queue.
    pub fn set_write_timeout(&self, timeout: Duration) -> Result<(), CanError> {
        Ok(self.socket.set_write_timeout(timeout)?)
    }
}

impl CanTransport for SocketCanBus {
    fn send(&mut self, frame: &CanFrame) -> Result<(), CanError> {
        let sc_frame = to_socketcan(frame)?;
        Ok(self.socket.write_frame(&sc_frame)?)
    }

    fn recv(&mut self, timeout: Duration) -> Result<Option<CanFrame>, CanError> {
        let start = Instant::now();
        loop {
            let remaining = timeout.saturating_sub(start.elapsed());
            let frame = match self.socket.read_frame_timeout(remaining) {
                Ok(f) => f,
                Err(e) if matches!(e.kind(), io::ErrorKind::TimedOut | io::ErrorKind::WouldBlock) => return Ok(None),
                Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
                Err(e) => return Err(CanError::Io(e)),
            };
            // An error frame that reports no error is consumed; read on (the next read returns at
            // once when the queue is empty and the time is up).
            if let Some(f) = from_socketcan(frame)? {
                return Ok(Some(f));
            }
        }
    }
}

#[cfg(test)]
#[path = "transport_tests.rs"]
mod tests;
