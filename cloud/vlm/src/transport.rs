//! How a request reaches a server: HTTP with `ureq` (rustls), or a cassette
//! ([`crate::cassette`]). The client builds requests and reads responses the same way whatever the
//! transport, so a replay exercises the same code as a live run.

use std::time::Duration;

use serde::{Deserialize, Serialize};
use serde_json::Value;

use crate::config::{ApiKey, Timeouts};

/// Largest response body read, bytes.
const MAX_RESPONSE_BYTES: u64 = 32 * 1024 * 1024;

/// A request: a JSON body POSTed to a path under the base URL. It holds no credentials: the
/// transport adds them, so nothing that records requests can see the key.
#[derive(Debug, Clone, PartialEq)]
pub struct HttpRequest {
    /// Path under the base URL, e.g. `/chat/completions`.
    pub path: String,
    /// The JSON body.
    pub body: Value,
}

/// A response.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct HttpResponse {
    /// HTTP status code.
    pub status: u16,
    /// The `Retry-After` header, if any.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub retry_after: Option<String>,
    /// The body as text.
    pub body: String,
}

/// What kind of failure happened before a response came.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TransportErrorKind {
    /// A time limit passed.
    Timeout,
    /// Connecting failed (refused, reset, DNS).
    Connection,
    /// Another I/O or protocol failure.
    Io,
    /// The request cannot be sent at all (bad URL, TLS setup); retrying will not help.
    Fatal,
    /// A replay does not match the cassette; retrying will not help.
    Replay,
}

/// A failure before a response came.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize, thiserror::Error)]
#[error("{kind:?}: {message}")]
pub struct TransportError {
    /// The kind.
    pub kind: TransportErrorKind,
    /// What happened.
    pub message: String,
}

impl TransportError {
    /// Whether trying again may help.
    pub fn is_retryable(&self) -> bool {
        matches!(self.kind, TransportErrorKind::Timeout | TransportErrorKind::Connection | TransportErrorKind::Io)
    }
}

/// Sends requests.
pub trait Transport {
    /// Sends one request and returns the response, whatever its status.
    fn send(&mut self, request: &HttpRequest) -> Result<HttpResponse, TransportError>;

    /// Waits before a retry. Replays skip the wait.
    fn pause(&mut self, wait: Duration) {
        std::thread::sleep(wait);
    }
}

/// HTTP(S) with `ureq` and rustls.
pub struct HttpTransport {
    agent: ureq::Agent,
    base_url: String,
    api_key: Option<ApiKey>,
}

impl std::fmt::Debug for HttpTransport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("HttpTransport").field("base_url", &self.base_url).field("api_key", &self.api_key).finish()
    }
}

impl HttpTransport {
    /// A transport to `base_url` with the given key and time limits.
    pub fn new(base_url: &str, api_key: Option<ApiKey>, timeouts: Timeouts) -> Self {
        let config = ureq::Agent::config_builder()
            .http_status_as_error(false)
            .timeout_global(Some(timeouts.request))
            .timeout_connect(Some(timeouts.connect))
            .user_agent(concat!("video2track-vlm/", env!("CARGO_PKG_VERSION")))
            .build();
        Self { agent: config.into(), base_url: base_url.trim().trim_end_matches('/').to_owned(), api_key }
    }
}

impl Transport for HttpTransport {
    fn send(&mut self, request: &HttpRequest) -> Result<HttpResponse, TransportError> {
        let url = format!("{}{}", self.base_url, request.path);
        let body = serde_json::to_vec(&request.body)
            .map_err(|e| TransportError { kind: TransportErrorKind::Fatal, message: e.to_string() })?;
        let mut builder = self.agent.post(&url).header("Content-Type", "application/json");
        if let Some(key) = &self.api_key {
            builder = builder.header("Authorization", format!("Bearer {}", key.expose()));
        }
        let mut response = builder.send(&body[..]).map_err(from_ureq)?;
        let status = response.status().as_u16();
        let retry_after =
            response.headers().get("retry-after").and_then(|v| v.to_str().ok()).map(|v| v.trim().to_owned());
        let body = response.body_mut().with_config().limit(MAX_RESPONSE_BYTES).read_to_string().map_err(from_ureq)?;
        Ok(HttpResponse { status, retry_after, body })
    }
}

fn from_ureq(e: ureq::Error) -> TransportError {
    use ureq::Error as E;
    let kind = match &e {
        E::Timeout(_) => TransportErrorKind::Timeout,
        E::ConnectionFailed | E::HostNotFound => TransportErrorKind::Connection,
        E::Io(io) if io.kind() == std::io::ErrorKind::TimedOut => TransportErrorKind::Timeout,
        E::Io(_) | E::Protocol(_) | E::BodyExceedsLimit(_) => TransportErrorKind::Io,
        _ => TransportErrorKind::Fatal,
    };
    TransportError { kind, message: e.to_string() }
}
