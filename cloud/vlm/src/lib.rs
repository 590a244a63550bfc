//! # v2t-vlm
//!
//! Scenario abstraction (paper Sec. 3.2.1, Appendix A): a driving video in, checked
//! [`ScenarioSemantics`] out. Frames are taken from the video with `ffmpeg` ([`frames`]: uniform,
//! optionally where the picture changes most, long side ≤ 768 px, JPEG), shown with the versioned
//! chain-of-thought prompt `config/vlm/prompt.md` ([`prompt`]) to a vision-language model behind
//! an OpenAI-compatible chat-completions API ([`client`], over [`transport`]), and the answer is
//! checked against the semantics rules ([`answer`]). The answer's form is asked for with
//! `response_format: json_schema`, or with the schema in the prompt where the server does not
//! support that. A wrong answer is sent back once with its errors; then the error is final.
//!
//! The model is not asked for the post-encroachment time (PET): the operator's label is put in
//! before the check, as the paper prescribes.
//!
//! Every exchange can be recorded into a cassette and replayed offline through the same code
//! ([`cassette`]). `config/vlm/cassettes/` ships three hand-written ones: the paper's cut-in and
//! left turn, and the left turn with the VUT turning:
//!
//! ```
//! use std::path::Path;
//! use v2t_vlm::{Mode, VlmConfig, abstract_video};
//!
//! let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
//! let cassette = root.join("config/vlm/cassettes/cut_in");
//! // A replay needs neither the video nor an endpoint: frames and settings come from the cassette.
//! let result = abstract_video(Path::new("cut_in_4.70.mp4"), 4.70, &VlmConfig::default(), &Mode::Replay(cassette))?;
//! assert_eq!(result.semantics.interacting_bvs[0].interaction_type.as_str(), "cut_in");
//! assert_eq!(result.semantics.pet_label_s, 4.70);
//! assert_eq!((result.requests, result.repairs), (1, 0));
//! # Ok::<(), v2t_vlm::VlmError>(())
//! ```
//!
//! A live run reads the endpoint from `V2T_VLM_BASE_URL`, `V2T_VLM_MODEL` and `V2T_VLM_API_KEY`
//! ([`VlmConfig::from_env`]); the key is never logged nor recorded.

pub mod answer;
pub mod cassette;
pub mod client;
pub mod config;
mod error;
mod files;
pub mod frames;
pub mod prompt;
pub mod request;
pub mod transport;

use std::path::{Path, PathBuf};

use v2t_model::semantics::{ScenarioSemantics, SourceMetadata};

pub use crate::answer::AnswerProblem;
pub use crate::config::{ApiKey, ConfigError, RequestSettings, RetryPolicy, StructuredOutput, Timeouts, VlmConfig};
pub use crate::error::VlmError;
pub use crate::files::check_config_file;
pub use crate::frames::{Frame, FrameError, FrameSettings, VideoInfo};

use crate::cassette::{Cassette, Manifest, RecordedFrame, Recorder, Replayer};
use crate::client::{Conversation, Outcome, converse};
use crate::prompt::Prompt;
use crate::transport::{HttpTransport, Transport};

/// Where the answers come from.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Mode {
    /// From the configured endpoint.
    Live,
    /// From the configured endpoint, every exchange saved into the cassette directory.
    Record(PathBuf),
    /// From the cassette directory, offline.
    Replay(PathBuf),
}

/// A frame that was shown to the model.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FrameUsed {
    /// Timestamp, ms.
    pub timestamp_ms: u64,
    /// Width, px.
    pub width: u32,
    /// Height, px.
    pub height: u32,
    /// JPEG size, bytes.
    pub jpeg_bytes: usize,
}

/// The semantics of a video and how they were obtained.
#[derive(Debug, Clone, PartialEq)]
pub struct Abstraction {
    /// The checked semantics, with the operator's PET label and the provenance.
    pub semantics: ScenarioSemantics,
    /// The video's facts.
    pub video: VideoInfo,
    /// The frames shown, in time order.
    pub frames: Vec<FrameUsed>,
    /// HTTP requests sent (or replayed), retries, fallback and repair included.
    pub requests: u32,
    /// Repair rounds: 0 or 1.
    pub repairs: u32,
    /// What was wrong with the first answer, when it needed repair.
    pub repaired_problem: Option<AnswerProblem>,
    /// Whether the schema was put into the prompt instead of `response_format`.
    pub schema_in_prompt: bool,
    /// The prompt's version.
    pub prompt_version: String,
    /// The model asked for.
    pub model: String,
    /// Where the answer comes from: a live exchange with the endpoint, or the cassette's own
    /// provenance note (`recorded`, or what a hand-written cassette says it is).
    pub provenance: String,
}

/// Turns a video into scenario semantics. `pet_label_s` is the operator's PET label for the video
/// (from the command line or an annotation file), in the range of a target τ (0.1–30 s).
///
/// In [`Mode::Replay`] the video file is not read: only its file name must be the recorded one.
pub fn abstract_video(video: &Path, pet_label_s: f64, cfg: &VlmConfig, mode: &Mode) -> Result<Abstraction, VlmError> {
    v2t_model::Target::new(pet_label_s, v2t_model::Style::Rush).map_err(VlmError::PetLabel)?;
    let prompt = match &cfg.prompt_file {
        Some(path) => Prompt::load(path)?,
        None => Prompt::builtin()?,
    };
    match mode {
        Mode::Live => {
            cfg.validate()?;
            let (info, frames) = frames::extract_frames(video, &cfg.frames)?;
            let mut transport = HttpTransport::new(&cfg.base_url, cfg.api_key.clone(), cfg.timeouts);
            let provenance = format!("live exchange with {} at {}", cfg.request.model, cfg.base_url);
            let input =
                RunInput { video, info: &info, frames: &frames, pet_label_s, settings: &cfg.request, provenance };
            run(&mut transport, input, cfg, &prompt)
        }
        Mode::Record(dir) => {
            cfg.validate()?;
            let (info, frames) = frames::extract_frames(video, &cfg.frames)?;
            let transport = HttpTransport::new(&cfg.base_url, cfg.api_key.clone(), cfg.timeouts);
            let mut recorder = Recorder::new(transport, cfg.api_key.is_some());
            let provenance = format!("live exchange with {} at {}, recorded", cfg.request.model, cfg.base_url);
            let input =
                RunInput { video, info: &info, frames: &frames, pet_label_s, settings: &cfg.request, provenance };
            let result = run(&mut recorder, input, cfg, &prompt);
            let manifest = Manifest {
                format: cassette::FORMAT.into(),
                provenance: "recorded".into(),
                prompt_version: prompt.version().into(),
                video_file: file_name(video),
                video: info,
                settings: cfg.request.clone(),
                pet_label_s,
                frames: frames
                    .iter()
                    .map(|f| RecordedFrame { timestamp_ms: f.timestamp_ms, width: f.width, height: f.height })
                    .collect(),
                exchanges: Vec::new(),
            };
            let semantics = result.as_ref().ok().map(|a| &a.semantics);
            cassette::write(dir, &manifest, recorder.exchanges(), semantics)?;
            result
        }
        Mode::Replay(dir) => replay(dir, video, pet_label_s, cfg, &prompt, false).map(|(a, _)| a),
    }
}

/// Replays a cassette whose requests were written by hand or by an older prompt, replacing each
/// recorded request by the one the current code builds, and writes it back with the semantics it
/// gives. The responses are kept. Only for hand-written cassettes: a recorded cassette must be
/// recorded again, because its answers belong to the old requests.
pub fn bless_cassette(dir: &Path, cfg: &VlmConfig) -> Result<Abstraction, VlmError> {
    let prompt = match &cfg.prompt_file {
        Some(path) => Prompt::load(path)?,
        None => Prompt::builtin()?,
    };
    let cassette = Cassette::load(dir)?;
    let video = PathBuf::from(&cassette.manifest.video_file);
    let (abstraction, replayer) = replay(dir, &video, cassette.manifest.pet_label_s, cfg, &prompt, true)?;
    let manifest = Manifest { prompt_version: prompt.version().into(), ..cassette.manifest };
    cassette::write(dir, &manifest, replayer.exchanges(), Some(&abstraction.semantics))?;
    Ok(abstraction)
}

fn replay(
    dir: &Path,
    video: &Path,
    pet_label_s: f64,
    cfg: &VlmConfig,
    prompt: &Prompt,
    bless: bool,
) -> Result<(Abstraction, Replayer), VlmError> {
    let cassette = Cassette::load(dir)?;
    let m = &cassette.manifest;
    if file_name(video) != m.video_file {
        return Err(VlmError::Replay(format!(
            "{} holds the exchanges for video `{}`, not `{}`",
            dir.display(),
            m.video_file,
            file_name(video)
        )));
    }
    if !bless && prompt.version() != m.prompt_version {
        return Err(VlmError::Replay(format!(
            "recorded with prompt `{}`, the prompt is now `{}`: record the cassette again",
            m.prompt_version,
            prompt.version()
        )));
    }
    let frames = cassette.frames()?;
    let mut replayer = Replayer::new(&cassette, bless);
    let provenance = format!("replayed cassette {}: {}", dir.display(), m.provenance);
    let input = RunInput { video, info: &m.video, frames: &frames, pet_label_s, settings: &m.settings, provenance };
    let abstraction = run(&mut replayer, input, cfg, prompt)?;
    replayer.finish()?;
    Ok((abstraction, replayer))
}

/// What one run works on.
struct RunInput<'a> {
    video: &'a Path,
    info: &'a VideoInfo,
    frames: &'a [Frame],
    pet_label_s: f64,
    settings: &'a RequestSettings,
    provenance: String,
}

fn run(
    transport: &mut dyn Transport,
    input: RunInput<'_>,
    cfg: &VlmConfig,
    prompt: &Prompt,
) -> Result<Abstraction, VlmError> {
    let RunInput { video, info, frames, pet_label_s, settings, provenance } = input;
    let source = SourceMetadata {
        video: file_name(video),
        dataset: None,
        duration_s: Some(info.duration_s),
        frames_used: u32::try_from(frames.len()).ok(),
        model: None,
        prompt_version: Some(prompt.version().into()),
    };
    let conversation = Conversation {
        prompt,
        settings,
        retry: &cfg.retry,
        frames,
        duration_s: info.duration_s,
        pet_label_s,
        source: &source,
    };
    let Outcome { semantics, requests, repairs, schema_in_prompt, repaired_problem } =
        converse(transport, &conversation)?;
    Ok(Abstraction {
        semantics,
        video: *info,
        frames: frames
            .iter()
            .map(|f| FrameUsed {
                timestamp_ms: f.timestamp_ms,
                width: f.width,
                height: f.height,
                jpeg_bytes: f.jpeg.len(),
            })
            .collect(),
        requests,
        repairs,
        repaired_problem,
        schema_in_prompt,
        prompt_version: prompt.version().into(),
        model: settings.model.clone(),
        provenance,
    })
}

/// The file name of a path, or the whole path if it has none.
fn file_name(path: &Path) -> String {
    path.file_name().map_or_else(|| path.display().to_string(), |n| n.to_string_lossy().into_owned())
}
