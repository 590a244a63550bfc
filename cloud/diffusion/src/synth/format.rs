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

/// What can go wrong reading a corpus file (shared with the recorded corpus).
pub type CorpusIoError = crate::jsonl::JsonlError;

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
    crate::jsonl::to_string(&header, &corpus.episodes)
}

/// Reads a corpus from JSON lines.
pub fn from_jsonl(text: &str) -> Result<SyntheticCorpus, CorpusIoError> {
    let synthetic = |raw: &serde_json::Value| raw.get("synthetic").and_then(serde_json::Value::as_bool) == Some(true);
    let (header, episodes): (CorpusHeader, Vec<SyntheticEpisode>) = crate::jsonl::parse(
        text,
        FORMAT,
        VERSION,
        synthetic,
        &format!("{FORMAT} (synthetic true)"),
        |h: &CorpusHeader| h.episodes,
    )?;
    Ok(SyntheticCorpus { map: header.map, seed: header.seed, episodes, rejections: header.rejections })
}

/// Reads a corpus file.
pub fn read_jsonl_file(path: &std::path::Path) -> Result<SyntheticCorpus, CorpusIoError> {
    from_jsonl(&crate::jsonl::read_text(path)?)
}
