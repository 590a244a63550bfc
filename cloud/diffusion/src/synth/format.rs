//! The synthetic corpus on disk: JSON lines. The first line is a [`CorpusHeader`] with the format
//! name, its version and `"synthetic": true`; every following line is one
//! [`SyntheticEpisode`]. Reading checks the format, the version and the episode count, and
//! names the line of any error.

use serde::{Deserialize, Serialize};

use super::corpus::{Rejections, SyntheticCorpus, SyntheticEpisode};

/// Format name in the header.
pub const FORMAT: &str = "v2t-synthetic-corpus";
/// Format version written and read.
pub const VERSION: u32 = 1;

/// First line of a corpus file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CorpusHeader {
    /// [`FORMAT`].
    pub format: String,
    /// [`VERSION`].
    pub version: u32,
    /// Always true: the episodes are simulated, not recorded.
    pub synthetic: bool,
    /// Map name.
    pub map: String,
    /// Corpus seed.
    pub seed: u64,
    /// Number of episode lines that follow.
    pub episodes: usize,
    /// Draws rejected while generating.
    pub rejections: Rejections,
}

/// What can go wrong reading a corpus file.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CorpusIoError {
    /// No header line.
    #[error("empty corpus file")]
    Empty,
    /// A line that is not the expected JSON.
    #[error("line {line}: {message}")]
    Json {
        /// Line (1-based).
        line: usize,
        /// What serde said.
        message: String,
    },
    /// Not a synthetic corpus.
    #[error("line 1: format `{found}` (synthetic {synthetic}), expected `{FORMAT}` (synthetic true)")]
    Format {
        /// Format in the header.
        found: String,
        /// Its synthetic flag.
        synthetic: bool,
    },
    /// A version this reader does not know.
    #[error("line 1: version {found}, this reader knows {VERSION}")]
    Version {
        /// Version in the header.
        found: u32,
    },
    /// The header's count disagrees with the lines.
    #[error("header announces {announced} episodes, the file has {found}")]
    Count {
        /// From the header.
        announced: usize,
        /// Lines found.
        found: usize,
    },
    /// The file could not be read.
    #[error("{path}: {message}")]
    Io {
        /// The file.
        path: String,
        /// What the OS said.
        message: String,
    },
}

/// The corpus as JSON lines.
pub fn to_jsonl(corpus: &SyntheticCorpus) -> Result<String, serde_json::Error> {
    let header = CorpusHeader {
        format: FORMAT.to_owned(),
        version: VERSION,
        synthetic: true,
        map: corpus.map.clone(),
        seed: corpus.seed,
        episodes: corpus.episodes.len(),
        rejections: corpus.rejections,
    };
    let mut out = serde_json::to_string(&header)?;
    out.push('\n');
    for e in &corpus.episodes {
        out.push_str(&serde_json::to_string(e)?);
        out.push('\n');
    }
    Ok(out)
}

/// Reads a corpus from JSON lines.
pub fn from_jsonl(text: &str) -> Result<SyntheticCorpus, CorpusIoError> {
    let mut lines = text.lines().enumerate().filter(|(_, l)| !l.trim().is_empty());
    let (_, first) = lines.next().ok_or(CorpusIoError::Empty)?;
    // The format and version are checked before the rest of the header so that a newer file says so.
    let raw: serde_json::Value =
        serde_json::from_str(first).map_err(|e| CorpusIoError::Json { line: 1, message: e.to_string() })?;
    let format = raw.get("format").and_then(|v| v.as_str()).unwrap_or("").to_owned();
    let synthetic = raw.get("synthetic").and_then(serde_json::Value::as_bool).unwrap_or(false);
    if format != FORMAT || !synthetic {
        return Err(CorpusIoError::Format { found: format, synthetic });
    }
    let version = raw.get("version").and_then(serde_json::Value::as_u64).unwrap_or(0);
    if version != u64::from(VERSION) {
        return Err(CorpusIoError::Version { found: u32::try_from(version).unwrap_or(u32::MAX) });
    }
    let header: CorpusHeader =
        serde_json::from_value(raw).map_err(|e| CorpusIoError::Json { line: 1, message: e.to_string() })?;
    let mut episodes = Vec::with_capacity(header.episodes);
    for (i, line) in lines {
        let e: SyntheticEpisode =
            serde_json::from_str(line).map_err(|e| CorpusIoError::Json { line: i + 1, message: e.to_string() })?;
        episodes.push(e);
    }
    if episodes.len() != header.episodes {
        return Err(CorpusIoError::Count { announced: header.episodes, found: episodes.len() });
    }
    Ok(SyntheticCorpus { map: header.map, seed: header.seed, episodes, rejections: header.rejections })
}

/// Reads a corpus file.
pub fn read_jsonl_file(path: &std::path::Path) -> Result<SyntheticCorpus, CorpusIoError> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| CorpusIoError::Io { path: path.display().to_string(), message: e.to_string() })?;
    from_jsonl(&text)
}
