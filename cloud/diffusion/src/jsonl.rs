//! Corpus files as JSON lines, for the synthetic and the recorded corpus alike: the first line is
//! a header naming the format and its version and announcing how many records follow; every
//! following line is one record. Reading checks the format and version before the rest of the
//! header (so that a newer file says so), then every line and the count, and names the line of any
//! error; writing goes to a temporary file renamed into place, so an error leaves no half file.

use serde::Serialize;
use serde::de::DeserializeOwned;

/// What can go wrong reading or writing a corpus file.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum JsonlError {
    /// No header line.
    #[error("empty corpus file")]
    Empty,
    /// A line that is not the expected JSON.
    #[error("line {line}: {message}")]
    Json {
        /// Line (1-based; 0 when writing).
        line: usize,
        /// What serde said.
        message: String,
    },
    /// Another kind of file.
    #[error("line 1: format `{found}`, expected `{expected}`")]
    Format {
        /// Format (and kind) in the header.
        found: String,
        /// What this reader reads.
        expected: String,
    },
    /// A version this reader does not know.
    #[error("line 1: version {found}, this reader knows {known}")]
    Version {
        /// Version in the header.
        found: u32,
        /// The version read.
        known: u32,
    },
    /// The header's count disagrees with the lines.
    #[error("header announces {announced} records, the file has {found}")]
    Count {
        /// From the header.
        announced: usize,
        /// Lines found.
        found: usize,
    },
    /// The file could not be read or written.
    #[error("{path}: {message}")]
    Io {
        /// The file.
        path: String,
        /// What the OS said.
        message: String,
    },
}

/// The header and the records as JSON lines.
pub fn to_string<H: Serialize, R: Serialize>(header: &H, records: &[R]) -> Result<String, serde_json::Error> {
    let mut out = serde_json::to_string(header)?;
    out.push('\n');
    for r in records {
        out.push_str(&serde_json::to_string(r)?);
        out.push('\n');
    }
    Ok(out)
}

/// The header and the records of a JSON-lines text whose header has `"format": format` (and
/// passes `kind`, e.g. its synthetic flag; `expected` says what was wanted) and `"version":
/// version`; `count` is the number of records the header announces.
pub fn parse<H: DeserializeOwned, R: DeserializeOwned>(
    text: &str,
    format: &str,
    version: u32,
    kind: impl Fn(&serde_json::Value) -> bool,
    expected: &str,
    count: impl Fn(&H) -> usize,
) -> Result<(H, Vec<R>), JsonlError> {
    let mut lines = text.lines().enumerate().filter(|(_, l)| !l.trim().is_empty());
    let (_, first) = lines.next().ok_or(JsonlError::Empty)?;
    let raw: serde_json::Value =
        serde_json::from_str(first).map_err(|e| JsonlError::Json { line: 1, message: e.to_string() })?;
    let found = raw.get("format").and_then(|v| v.as_str()).unwrap_or("").to_owned();
    if found != format || !kind(&raw) {
        return Err(JsonlError::Format { found, expected: expected.to_owned() });
    }
    let v = raw.get("version").and_then(serde_json::Value::as_u64).unwrap_or(0);
    if v != u64::from(version) {
        return Err(JsonlError::Version { found: u32::try_from(v).unwrap_or(u32::MAX), known: version });
    }
    let header: H = serde_json::from_value(raw).map_err(|e| JsonlError::Json { line: 1, message: e.to_string() })?;
    let announced = count(&header);
    let mut records = Vec::with_capacity(announced.min(1 << 16));
    for (i, line) in lines {
        records.push(serde_json::from_str(line).map_err(|e| JsonlError::Json { line: i + 1, message: e.to_string() })?);
    }
    if records.len() != announced {
        return Err(JsonlError::Count { announced, found: records.len() });
    }
    Ok((header, records))
}

/// The text of a file.
pub fn read_text(path: &std::path::Path) -> Result<String, JsonlError> {
    v2t_files::bounds::read_text_within(path, v2t_files::bounds::DRIVING_DATA)
        .map_err(|e| JsonlError::Io { path: path.display().to_string(), message: e.to_string() })
}

/// Writes `text` to `<path>.partial`, then renames it to `path`.
pub fn write_atomic(path: &std::path::Path, text: &str) -> Result<(), JsonlError> {
    let io = |e: std::io::Error| JsonlError::Io { path: path.display().to_string(), message: e.to_string() };
    let mut partial = path.as_os_str().to_owned();
    partial.push(".partial");
    let partial = std::path::PathBuf::from(partial);
    std::fs::write(&partial, text).map_err(io)?;
    std::fs::rename(&partial, path).map_err(io)
}
