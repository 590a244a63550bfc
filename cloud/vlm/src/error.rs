//! Why scenario abstraction failed.

use crate::answer::{AnswerProblem, ReplyError};
use crate::config::ConfigError;
use crate::frames::FrameError;
use crate::prompt::PromptError;
use crate::transport::TransportError;

/// Why a video could not be turned into scenario semantics.
#[derive(Debug, thiserror::Error)]
pub enum VlmError {
    /// The configuration is unusable.
    #[error(transparent)]
    Config(#[from] ConfigError),
    /// Frames could not be taken from the video.
    #[error(transparent)]
    Frames(#[from] FrameError),
    /// The prompt file is unusable.
    #[error(transparent)]
    Prompt(#[from] PromptError),
    /// The operator's PET label is out of range (the range of a target τ).
    #[error("PET label: {0}")]
    PetLabel(v2t_model::TargetError),
    /// The server answered with a status that retrying does not fix (400, 401, 404, …).
    #[error("the VLM server answered HTTP {status}: {body}")]
    Http {
        /// Status code.
        status: u16,
        /// The start of the body.
        body: String,
    },
    /// The server rejected `response_format: json_schema` and the configuration forbids the
    /// fallback to the schema in the prompt (`structured_output = json_schema`).
    #[error(
        "the VLM server does not accept response_format json_schema (HTTP {status}: {body}); use structured output `auto` or `in_prompt`"
    )]
    ResponseFormatRejected {
        /// Status code.
        status: u16,
        /// The start of the body.
        body: String,
    },
    /// Every attempt failed with a retryable error.
    #[error("no answer from the VLM server after {attempts} attempts; last: {last}")]
    RetriesExhausted {
        /// Requests sent.
        attempts: u32,
        /// The last failure.
        last: String,
    },
    /// A failure that retrying does not fix.
    #[error("VLM request could not be sent: {0}")]
    Transport(TransportError),
    /// The 2xx response carries no usable answer.
    #[error(transparent)]
    Reply(#[from] ReplyError),
    /// The answer broke the schema or the rules, and so did the repaired one.
    #[error("the model's answer was rejected ({first}), and so was its repaired answer ({second}); answer: {answer}")]
    InvalidAnswer {
        /// What was wrong with the first answer.
        first: AnswerProblem,
        /// What was wrong with the answer to the repair request.
        second: AnswerProblem,
        /// The start of the last answer.
        answer: String,
    },
    /// A replay sent a request the cassette does not hold (the prompt, the settings or the code
    /// changed since it was recorded), or asked for more exchanges than it holds.
    #[error("replay does not match the cassette: {0}")]
    Replay(String),
    /// A cassette could not be read or written.
    #[error("cassette {dir}: {problem}")]
    Cassette {
        /// The cassette's directory.
        dir: std::path::PathBuf,
        /// What is wrong.
        problem: String,
    },
}

/// The first `max` characters of `text`, marked when cut.
pub(crate) fn excerpt(text: &str, max: usize) -> String {
    let mut out: String = text.chars().take(max).collect();
    if text.chars().nth(max).is_some() {
        out.push('…');
    }
    out
}
