//! Cassettes: every request/response exchange of one abstraction, saved as JSON files in a
//! directory, and served back offline.
//!
//! A cassette directory holds `cassette.json` (the video's facts, the request settings, the prompt
//! version, the PET label and the frames' timestamps), one `exchange_NN.json` per HTTP exchange
//! (the request's path and exact JSON body, its non-secret headers with the key shown as
//! `<redacted>`, and the response's status, `Retry-After` and body, or the transport error) and,
//! when the run succeeded, `semantics.json`, the document it produced.
//!
//! A replay takes the frames (from the first request's `image_url` parts) and the settings from
//! the cassette, runs the same conversation code as a live run, and checks that each request it
//! builds is exactly the recorded one before it serves the recorded response. A changed prompt, a
//! changed schema or changed request code therefore fails the replay, saying where the request
//! differs, instead of silently serving stale answers.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Duration;

use base64::Engine as _;
use serde::{Deserialize, Serialize};
use serde_json::Value;
use v2t_model::semantics::ScenarioSemantics;

use crate::config::RequestSettings;
use crate::error::VlmError;
use crate::frames::{Frame, VideoInfo};
use crate::request::images_in;
use crate::transport::{HttpRequest, HttpResponse, Transport, TransportError, TransportErrorKind};

/// Format tag of `cassette.json`.
pub const FORMAT: &str = "v2t-vlm-cassette-1";
/// The manifest's file name.
pub const MANIFEST_FILE: &str = "cassette.json";
/// The produced semantics' file name.
pub const SEMANTICS_FILE: &str = "semantics.json";
/// What the `authorization` header is recorded as.
pub const REDACTED: &str = "Bearer <redacted>";

/// `cassette.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Manifest {
    /// [`FORMAT`].
    pub format: String,
    /// Where the exchanges come from: `recorded` for a live run, or a note for hand-written ones.
    pub provenance: String,
    /// Version of the prompt the requests were built with.
    pub prompt_version: String,
    /// The video's file name (no directories).
    pub video_file: String,
    /// What `ffprobe` said about the video.
    pub video: VideoInfo,
    /// The request settings.
    pub settings: RequestSettings,
    /// The PET label given when recording, s.
    pub pet_label_s: f64,
    /// The frames' timestamps and sizes; their images are in the first request.
    pub frames: Vec<RecordedFrame>,
    /// The exchange files, in order.
    pub exchanges: Vec<String>,
}

/// One frame's facts.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RecordedFrame {
    /// Timestamp, ms.
    pub timestamp_ms: u64,
    /// Width, px.
    pub width: u32,
    /// Height, px.
    pub height: u32,
}

/// One exchange: a request and its response or transport error.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Exchange {
    /// The request.
    pub request: RecordedRequest,
    /// The response, if one came.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub response: Option<RecordedResponse>,
    /// The failure, if none came.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub error: Option<TransportError>,
}

/// A request as sent.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RecordedRequest {
    /// Always `POST`.
    pub method: String,
    /// Path under the base URL.
    pub path: String,
    /// Headers the transport adds, the key redacted.
    pub headers: BTreeMap<String, String>,
    /// The exact JSON body.
    pub body: Value,
}

/// A response as received.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RecordedResponse {
    /// Status code.
    pub status: u16,
    /// `Retry-After`, if any.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub retry_after: Option<String>,
    /// The body, when it is JSON (kept as a value so the file stays readable).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub body_json: Option<Value>,
    /// The body, when it is not JSON.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub body_text: Option<String>,
}

impl RecordedResponse {
    fn from_response(r: &HttpResponse) -> Self {
        let json = serde_json::from_str::<Value>(&r.body).ok();
        let text = json.is_none().then(|| r.body.clone());
        Self { status: r.status, retry_after: r.retry_after.clone(), body_json: json, body_text: text }
    }

    fn to_response(&self) -> HttpResponse {
        let body = match (&self.body_json, &self.body_text) {
            (Some(v), _) => v.to_string(),
            (None, Some(t)) => t.clone(),
            (None, None) => String::new(),
        };
        HttpResponse { status: self.status, retry_after: self.retry_after.clone(), body }
    }
}

fn headers(with_key: bool) -> BTreeMap<String, String> {
    let mut h = BTreeMap::from([("content-type".to_owned(), "application/json".to_owned())]);
    if with_key {
        h.insert("authorization".into(), REDACTED.into());
    }
    h
}

fn cassette_error(dir: &Path, problem: impl Into<String>) -> VlmError {
    VlmError::Cassette { dir: dir.to_owned(), problem: problem.into() }
}

/// Wraps a transport and keeps every exchange.
#[derive(Debug)]
pub struct Recorder<T> {
    inner: T,
    with_key: bool,
    exchanges: Vec<Exchange>,
}

impl<T: Transport> Recorder<T> {
    /// Records what `inner` sends; `with_key`: whether it sends an `Authorization` header.
    pub fn new(inner: T, with_key: bool) -> Self {
        Self { inner, with_key, exchanges: Vec::new() }
    }

    /// The exchanges so far.
    pub fn exchanges(&self) -> &[Exchange] {
        &self.exchanges
    }
}

impl<T: Transport> Transport for Recorder<T> {
    fn send(&mut self, request: &HttpRequest) -> Result<HttpResponse, TransportError> {
        let result = self.inner.send(request);
        let (response, error) = match &result {
            Ok(r) => (Some(RecordedResponse::from_response(r)), None),
            Err(e) => (None, Some(e.clone())),
        };
        let request = RecordedRequest {
            method: "POST".into(),
            path: request.path.clone(),
            headers: headers(self.with_key),
            body: request.body.clone(),
        };
        self.exchanges.push(Exchange { request, response, error });
        result
    }

    fn pause(&mut self, wait: Duration) {
        self.inner.pause(wait);
    }
}

/// Writes a cassette (replacing the files of an earlier one in `dir`).
pub fn write(
    dir: &Path,
    manifest: &Manifest,
    exchanges: &[Exchange],
    semantics: Option<&ScenarioSemantics>,
) -> Result<(), VlmError> {
    let io = |what: &str, e: std::io::Error| cassette_error(dir, format!("{what}: {e}"));
    std::fs::create_dir_all(dir).map_err(|e| io("create", e))?;
    for entry in std::fs::read_dir(dir).map_err(|e| io("list", e))? {
        let path = entry.map_err(|e| io("list", e))?.path();
        let name = path.file_name().and_then(|n| n.to_str()).unwrap_or_default();
        if (name.starts_with("exchange_") && name.ends_with(".json")) || name == SEMANTICS_FILE {
            std::fs::remove_file(&path).map_err(|e| io("remove old file", e))?;
        }
    }
    let names: Vec<String> = (1..=exchanges.len()).map(|i| format!("exchange_{i:02}.json")).collect();
    for (name, exchange) in names.iter().zip(exchanges) {
        write_json(dir, name, exchange)?;
    }
    write_json(dir, MANIFEST_FILE, &Manifest { exchanges: names, ..manifest.clone() })?;
    if let Some(s) = semantics {
        write_json(dir, SEMANTICS_FILE, s)?;
    }
    Ok(())
}

/// The text a semantics document is written as (`semantics.json`, the CLI's output): pretty JSON
/// with a final newline.
pub fn semantics_text(semantics: &ScenarioSemantics) -> Result<String, serde_json::Error> {
    serde_json::to_string_pretty(semantics).map(|t| t + "\n")
}

fn write_json<T: Serialize>(dir: &Path, name: &str, value: &T) -> Result<(), VlmError> {
    let text = serde_json::to_string_pretty(value).map_err(|e| cassette_error(dir, format!("{name}: {e}")))? + "\n";
    std::fs::write(dir.join(name), text).map_err(|e| cassette_error(dir, format!("write {name}: {e}")))
}

fn read_json<T: for<'de> Deserialize<'de>>(dir: &Path, name: &str) -> Result<T, VlmError> {
    let text = v2t_files::bounds::read_text_within(&dir.join(name), v2t_files::bounds::VLM_FILE)
        .map_err(|e| cassette_error(dir, format!("read {name}: {e}")))?;
    serde_json::from_str(&text).map_err(|e| cassette_error(dir, format!("{name}: {e}")))
}

/// A cassette read back.
#[derive(Debug, Clone, PartialEq)]
pub struct Cassette {
    /// Its directory.
    pub dir: PathBuf,
    /// `cassette.json`.
    pub manifest: Manifest,
    /// The exchanges, in order.
    pub exchanges: Vec<Exchange>,
}

impl Cassette {
    /// Reads a cassette directory.
    pub fn load(dir: &Path) -> Result<Self, VlmError> {
        let manifest: Manifest = read_json(dir, MANIFEST_FILE)?;
        if manifest.format != FORMAT {
            return Err(cassette_error(dir, format!("format `{}`, expected `{FORMAT}`", manifest.format)));
        }
        let mut exchanges = Vec::with_capacity(manifest.exchanges.len());
        for name in &manifest.exchanges {
            let exchange: Exchange = read_json(dir, name)?;
            if exchange.response.is_some() == exchange.error.is_some() {
                return Err(cassette_error(dir, format!("{name}: needs exactly one of `response` and `error`")));
            }
            exchanges.push(exchange);
        }
        Ok(Self { dir: dir.to_owned(), manifest, exchanges })
    }

    /// The frames, with their images taken from the first request.
    pub fn frames(&self) -> Result<Vec<Frame>, VlmError> {
        let first = self.exchanges.first().ok_or_else(|| cassette_error(&self.dir, "holds no exchange"))?;
        let images = images_in(&first.request.body);
        if images.len() != self.manifest.frames.len() {
            return Err(cassette_error(
                &self.dir,
                format!(
                    "lists {} frames but its first request carries {} images",
                    self.manifest.frames.len(),
                    images.len()
                ),
            ));
        }
        let engine = base64::engine::general_purpose::STANDARD;
        images
            .iter()
            .zip(&self.manifest.frames)
            .enumerate()
            .map(|(i, (url, f))| {
                let data = url.strip_prefix("data:image/jpeg;base64,").ok_or_else(|| {
                    cassette_error(&self.dir, format!("image {i} is not a data:image/jpeg;base64 URL"))
                })?;
                let jpeg = engine.decode(data).map_err(|e| cassette_error(&self.dir, format!("image {i}: {e}")))?;
                Ok(Frame { timestamp_ms: f.timestamp_ms, width: f.width, height: f.height, jpeg })
            })
            .collect()
    }
}

/// Serves a cassette's responses to requests that must equal the recorded ones.
#[derive(Debug)]
pub struct Replayer {
    exchanges: Vec<Exchange>,
    next: usize,
    bless: bool,
}

impl Replayer {
    /// Replays `cassette`. With `bless`, a request that differs replaces the recorded one instead
    /// of failing (for hand-written cassettes after a prompt change: see the crate's README).
    pub fn new(cassette: &Cassette, bless: bool) -> Self {
        Self { exchanges: cassette.exchanges.clone(), next: 0, bless }
    }

    /// Fails if exchanges are left over.
    pub fn finish(&self) -> Result<(), VlmError> {
        let left = self.exchanges.len().saturating_sub(self.next);
        if left > 0 {
            return Err(VlmError::Replay(format!(
                "the run ended after {} exchanges but the cassette holds {}",
                self.next,
                self.exchanges.len()
            )));
        }
        Ok(())
    }

    /// The exchanges, with blessed requests.
    pub fn exchanges(&self) -> &[Exchange] {
        &self.exchanges
    }
}

impl Transport for Replayer {
    fn send(&mut self, request: &HttpRequest) -> Result<HttpResponse, TransportError> {
        let n = self.next;
        let replay_error = |message: String| TransportError { kind: TransportErrorKind::Replay, message };
        let count = self.exchanges.len();
        let exchange = self.exchanges.get_mut(n).ok_or_else(|| {
            replay_error(format!("request {} asked for, but the cassette holds only {count} exchanges", n + 1))
        })?;
        self.next += 1;
        let recorded = &mut exchange.request;
        if recorded.path != request.path {
            return Err(replay_error(format!(
                "exchange {}: path `{}`, recorded `{}`",
                n + 1,
                request.path,
                recorded.path
            )));
        }
        if let Some(at) = first_difference(&recorded.body, &request.body, String::new()) {
            if !self.bless {
                return Err(replay_error(format!(
                    "exchange {}: the request body differs from the recording at `{at}` (prompt, settings or request code changed: record the cassette again)",
                    n + 1
                )));
            }
            recorded.body = request.body.clone();
        }
        match (&exchange.response, &exchange.error) {
            (Some(r), _) => Ok(r.to_response()),
            (None, Some(e)) => Err(e.clone()),
            (None, None) => Err(replay_error(format!("exchange {} has neither response nor error", n + 1))),
        }
    }

    fn pause(&mut self, _wait: Duration) {}
}

/// The JSON pointer of the first place where `a` and `b` differ.
fn first_difference(a: &Value, b: &Value, at: String) -> Option<String> {
    match (a, b) {
        (Value::Object(x), Value::Object(y)) => {
            for key in x.keys().chain(y.keys().filter(|k| !x.contains_key(*k))) {
                let here = format!("{at}/{key}");
                match (x.get(key), y.get(key)) {
                    (Some(p), Some(q)) => {
                        if let Some(d) = first_difference(p, q, here) {
                            return Some(d);
                        }
                    }
                    _ => return Some(here),
                }
            }
            None
        }
        (Value::Array(x), Value::Array(y)) => {
            for (i, (p, q)) in x.iter().zip(y).enumerate() {
                if let Some(d) = first_difference(p, q, format!("{at}/{i}")) {
                    return Some(d);
                }
            }
            (x.len() != y.len()).then(|| format!("{at}/{}", x.len().min(y.len())))
        }
        _ => (a != b).then(|| if at.is_empty() { "/".into() } else { at }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn first_difference_points_at_the_change() {
        let a = json!({"m": [{"t": "x"}, {"t": "y"}], "k": 1});
        assert_eq!(first_difference(&a, &a, String::new()), None);
        let b = json!({"m": [{"t": "x"}, {"t": "z"}], "k": 1});
        assert_eq!(first_difference(&a, &b, String::new()).as_deref(), Some("/m/1/t"));
        let c = json!({"m": [{"t": "x"}], "k": 1, "n": 2});
        assert_eq!(first_difference(&a, &c, String::new()).as_deref(), Some("/m/1"));
        assert_eq!(first_difference(&json!(1), &json!(2), String::new()).as_deref(), Some("/"));
    }

    #[test]
    fn responses_keep_json_as_values_and_text_as_text() {
        let json_body = HttpResponse { status: 200, retry_after: None, body: "{\"a\":[1,2.5]}".into() };
        let r = RecordedResponse::from_response(&json_body);
        assert!(r.body_json.is_some() && r.body_text.is_none());
        assert_eq!(r.to_response(), json_body);
        let text = HttpResponse { status: 502, retry_after: Some("1".into()), body: "<html>bad gateway".into() };
        assert_eq!(RecordedResponse::from_response(&text).to_response(), text);
    }
}
