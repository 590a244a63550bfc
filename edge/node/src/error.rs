//! Errors of the onboard runtime.

use std::path::PathBuf;

/// Why a node could not start or had to stop.
#[derive(Debug, thiserror::Error)]
pub enum EdgeError {
    /// The runtime's configuration file is unreadable, malformed or out of range (the error names
    /// the file, the field and the bound).
    #[error(transparent)]
    File(#[from] v2t_files::InputError),
    /// A configuration file is malformed or out of range.
    #[error("{path}: {message}")]
    Config {
        /// The file.
        path: PathBuf,
        /// What is wrong, and where.
        message: String,
    },
    /// An iceoryx2 operation failed.
    #[error("iceoryx2 {what} `{service}`: {detail}")]
    Ipc {
        /// The operation.
        what: &'static str,
        /// The service or node concerned.
        service: String,
        /// iceoryx2's error.
        detail: String,
    },
    /// The SocketCAN interface failed.
    #[error("CAN: {0}")]
    Can(#[from] v2t_can::transport::CanError),
    /// A frame could not be encoded.
    #[error("CAN frame: {0}")]
    Codec(#[from] v2t_can::codec::CodecError),
    /// A prior could not be accepted or decoded.
    #[error("prior: {0}")]
    Prior(#[from] crate::prior::PriorError),
    /// The regulator could not be built.
    #[error("regulator: {0}")]
    Regulator(#[from] v2t_game::qp::QpError),
    /// The MQTT client could not start.
    #[error("uplink: {0}")]
    Mqtt(#[from] v2t_wire::mqtt::MqttError),
}

impl EdgeError {
    /// Whether the operator's input is at fault (a configuration file unreadable, malformed or out
    /// of range: exit code 2), not the runtime's work.
    pub fn is_input(&self) -> bool {
        matches!(self, Self::File(_) | Self::Config { .. })
    }

    /// An iceoryx2 failure of `what` on `service`.
    pub fn ipc(what: &'static str, service: &str, detail: impl std::fmt::Debug) -> Self {
        Self::Ipc { what, service: service.to_owned(), detail: format!("{detail:?}") }
    }
}
