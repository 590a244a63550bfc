//! `video2track abstract`: a driving video and the operator's PET label in, checked scenario
//! semantics out, through [`v2t_vlm`]: frames with `ffmpeg`, the versioned prompt, an
//! OpenAI-compatible vision-language model (endpoint from the `V2T_VLM_*` variables), or a recorded
//! cassette offline.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use v2t_files::{out, outln};
use v2t_model::semantics::ScenarioSemantics;
use v2t_vlm::config::{ENV_API_KEY, ENV_BASE_URL, ENV_MODEL};
use v2t_vlm::frames::MAX_FRAMES;
use v2t_vlm::{Abstraction, ConfigError, FrameError, Mode, VlmConfig, VlmError};

/// `abstract`'s arguments.
#[derive(Debug, clap::Args)]
pub struct AbstractCmd {
    /// The video. With --replay only its file name counts: the one the cassette recorded.
    video: PathBuf,
    /// The operator's post-encroachment time label for the video, s, in [0.1, 30] (default: from
    /// the annotation file).
    #[arg(long, value_name = "SECONDS", allow_negative_numbers = true)]
    pet_label: Option<f64>,
    /// Annotation file with `pet_label_s` (TOML; default: the video's name with `.labels.toml`).
    #[arg(long, value_name = "FILE", conflicts_with = "pet_label")]
    labels: Option<PathBuf>,
    /// Write the scenario semantics (JSON) here.
    #[arg(long)]
    out: Option<PathBuf>,
    /// Save every exchange with the model into this cassette directory.
    #[arg(long, value_name = "DIR", conflicts_with = "replay")]
    record: Option<PathBuf>,
    /// Replay this cassette directory instead of asking a model (no endpoint, no video needed).
    #[arg(long, value_name = "DIR")]
    replay: Option<PathBuf>,
    /// Frames shown to the model (default 16, at most 64).
    #[arg(long)]
    frames: Option<u32>,
    /// Where the frames are taken: uniform, or half of them where the picture changes most.
    #[arg(long, value_enum)]
    sampling: Option<Sampling>,
}

/// Runs `abstract`: semantics from the video (or the cassette), the report, the file.
pub fn run(a: AbstractCmd) -> anyhow::Result<()> {
    let pet_label_s = pet_label(&a.video, a.pet_label, a.labels.as_deref())?;
    let args = AbstractArgs {
        video: a.video,
        pet_label_s,
        record: a.record,
        replay: a.replay,
        frames: a.frames,
        sampling: a.sampling,
    };
    let result = abstract_video(&args, |name| std::env::var(name).ok())?;
    out!("{}", report(&result))?;
    if let Some(dir) = &args.record {
        outln!("recorded {}", dir.display())?;
    }
    if let Some(path) = a.out {
        write_semantics(&path, &result.semantics)?;
        outln!("wrote {}", path.display())?;
    }
    Ok(())
}

/// Where the frames shown to the model are taken.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, clap::ValueEnum)]
pub enum Sampling {
    /// In the middle of equal slices of the video.
    #[default]
    Uniform,
    /// Half of them uniformly, half where the picture changes most.
    Motion,
}

/// What `abstract` is asked to do.
#[derive(Debug, Clone, PartialEq)]
pub struct AbstractArgs {
    /// The video. In a replay only its file name is used: it must be the one the cassette recorded.
    pub video: PathBuf,
    /// The operator's PET label, s, in [0.1, 30].
    pub pet_label_s: f64,
    /// Save every exchange of the live run into this cassette directory.
    pub record: Option<PathBuf>,
    /// Replay this cassette directory instead of asking a model.
    pub replay: Option<PathBuf>,
    /// Frames shown to the model (default 16, at most 64); not with a replay.
    pub frames: Option<u32>,
    /// Where the frames are taken (default uniform); not with a replay.
    pub sampling: Option<Sampling>,
}

/// Why `abstract` failed.
#[derive(Debug, thiserror::Error)]
pub enum AbstractError {
    /// The options contradict each other or are out of range.
    #[error("{0}")]
    Usage(String),
    /// The video cannot be read (live and record mode).
    #[error("video {path}: {error}")]
    Video {
        /// The path given.
        path: PathBuf,
        /// What the file system said.
        error: std::io::Error,
    },
    /// No usable endpoint in the environment.
    #[error(
        "no VLM endpoint configured ({problem}): set {ENV_BASE_URL} (e.g. https://api.openai.com/v1) and {ENV_MODEL}, and {ENV_API_KEY} if the server needs a key; or replay a cassette with --replay DIR"
    )]
    Endpoint {
        /// What is missing or wrong.
        problem: String,
    },
    /// Scenario abstraction failed.
    #[error(transparent)]
    Vlm(#[from] VlmError),
    /// The semantics could not be written.
    #[error("writing {path}: {problem}")]
    Write {
        /// The file.
        path: PathBuf,
        /// Why.
        problem: String,
    },
}

impl AbstractError {
    /// Whether the user's input is at fault (options, video, label, endpoint settings, cassette),
    /// as opposed to the tools, the network or the model.
    pub fn is_input(&self) -> bool {
        match self {
            Self::Usage(_) | Self::Video { .. } | Self::Endpoint { .. } => true,
            Self::Write { .. } => false,
            Self::Vlm(e) => match e {
                VlmError::Config(_)
                | VlmError::PetLabel { .. }
                | VlmError::Prompt(_)
                | VlmError::Replay(_)
                | VlmError::Cassette { .. } => true,
                VlmError::Frames(f) => matches!(
                    f,
                    FrameError::Video { .. }
                        | FrameError::Probe { .. }
                        | FrameError::TooLong { .. }
                        | FrameError::Settings(_)
                ),
                VlmError::Http { .. }
                | VlmError::ResponseFormatRejected { .. }
                | VlmError::RetriesExhausted { .. }
                | VlmError::Transport(_)
                | VlmError::Reply(_)
                | VlmError::InvalidAnswer { .. } => false,
            },
        }
    }
}

/// The operator's annotation beside a video (`<video stem>.labels.toml`): what the model is never
/// asked for.
#[derive(Debug, Clone, PartialEq, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Labels {
    /// Post-encroachment time of the interaction in the video, s, as measured by the operator.
    pub pet_label_s: f64,
    /// Free text: how and by whom it was measured.
    #[serde(default)]
    pub note: Option<String>,
}

/// The annotation file `abstract` reads when no `--pet-label` is given: the video's name with
/// `.labels.toml` for its extension (`cut_in.mp4` → `cut_in.labels.toml`).
pub fn default_labels_path(video: &Path) -> PathBuf {
    video.with_extension("labels.toml")
}

/// The PET label: `--pet-label` when given, else the annotation file (`labels`, or the default one
/// beside the video). Neither is an error that says how to give one.
pub fn pet_label(video: &Path, pet_label_s: Option<f64>, labels: Option<&Path>) -> Result<f64, AbstractError> {
    if let Some(p) = pet_label_s {
        return Ok(p);
    }
    let path = labels.map_or_else(|| default_labels_path(video), Path::to_owned);
    let text = v2t_files::bounds::read_text_within(&path, v2t_files::bounds::CONFIG).map_err(|e| {
        AbstractError::Usage(format!(
            "no PET label: give --pet-label SECONDS, or write `pet_label_s = …` into {} ({e})",
            path.display()
        ))
    })?;
    let l: Labels =
        toml::from_str(&text).map_err(|e| AbstractError::Usage(format!("{}: {}", path.display(), e.message())))?;
    Ok(l.pet_label_s)
}

/// Runs scenario abstraction as `args` asks. `env` looks up the `V2T_VLM_*` variables (live and
/// record mode only). The label, the options and the video are checked before the endpoint.
pub fn abstract_video(args: &AbstractArgs, env: impl Fn(&str) -> Option<String>) -> Result<Abstraction, AbstractError> {
    let pet = args.pet_label_s;
    v2t_model::Target::new(pet, v2t_model::Style::Rush).map_err(VlmError::PetLabel)?;
    if let Some(n) = args.frames
        && !(1..=MAX_FRAMES).contains(&n)
    {
        return Err(AbstractError::Usage(format!("--frames must lie in 1..={MAX_FRAMES}, got {n}")));
    }
    let mode = match (&args.record, &args.replay) {
        (Some(_), Some(_)) => return Err(AbstractError::Usage("--record and --replay exclude each other".into())),
        (None, Some(dir)) => {
            if args.frames.is_some() || args.sampling.is_some() {
                return Err(AbstractError::Usage(
                    "--frames and --sampling do not apply to --replay: the frames come from the cassette".into(),
                ));
            }
            return Ok(v2t_vlm::abstract_video(&args.video, pet, &VlmConfig::default(), &Mode::Replay(dir.clone()))?);
        }
        (Some(dir), None) => Mode::Record(dir.clone()),
        (None, None) => Mode::Live,
    };
    std::fs::File::open(&args.video).map_err(|error| AbstractError::Video { path: args.video.clone(), error })?;
    let mut cfg = VlmConfig::from_lookup(env).map_err(|e| AbstractError::Endpoint {
        problem: match e {
            ConfigError::MissingEnv(name) => format!("{name} is not set"),
            other => other.to_string(),
        },
    })?;
    if let Some(n) = args.frames {
        cfg.frames.count = n;
    }
    cfg.frames.motion_frames = match args.sampling.unwrap_or_default() {
        Sampling::Uniform => 0,
        Sampling::Motion => cfg.frames.count / 2,
    };
    Ok(v2t_vlm::abstract_video(&args.video, pet, &cfg, &mode)?)
}

/// Writes the semantics as `semantics.json` of a cassette holds them (pretty JSON, one final
/// newline), so that a replay's output equals the recorded document byte for byte.
pub fn write_semantics(path: &Path, semantics: &ScenarioSemantics) -> Result<(), AbstractError> {
    let write_error = |problem: String| AbstractError::Write { path: path.to_owned(), problem };
    let text = v2t_vlm::cassette::semantics_text(semantics).map_err(|e| write_error(e.to_string()))?;
    std::fs::write(path, text).map_err(|e| write_error(e.to_string()))
}

/// A short report: the frames used with their timestamps, the model, the prompt version, requests
/// and repairs, and what the semantics say.
pub fn report(a: &Abstraction) -> String {
    let mut out = String::new();
    let v = &a.video;
    let _ = writeln!(
        out,
        "video {}  |  {:.1} s, {}x{}, {:.0} fps",
        a.semantics.source.video, v.duration_s, v.width, v.height, v.fps
    );
    let times: Vec<String> = a.frames.iter().map(|f| format!("{:.2}", f.timestamp_ms as f64 / 1000.0)).collect();
    let size = a.frames.first().map_or_else(String::new, |f| format!(", {}x{}", f.width, f.height));
    let _ = writeln!(out, "frames {}{size} at {} s", a.frames.len(), times.join(" "));
    let _ = writeln!(
        out,
        "model {}  |  prompt {}  |  {} request(s), {} repair(s){}",
        a.model,
        a.prompt_version,
        a.requests,
        a.repairs,
        if a.schema_in_prompt { "  |  schema in the prompt" } else { "" }
    );
    let _ = writeln!(out, "provenance {}", a.provenance);
    if let Some(problem) = &a.repaired_problem {
        let _ = writeln!(out, "  first answer repaired: {problem}");
    }
    let s = &a.semantics;
    let r = &s.road_topology;
    let _ = writeln!(
        out,
        "road {}, {} lane(s) per direction, {}  |  ego {} at {:.1} m/s  |  PET label {:.2} s",
        r.road_type, r.lanes_per_direction, r.signal_control, s.ego.maneuver, s.ego.speed_estimate_mps, s.pet_label_s
    );
    for bv in &s.interacting_bvs {
        let _ = writeln!(
            out,
            "  {}: {} from {}, {} at {:.1} m/s, {}",
            bv.id,
            bv.interaction_type,
            bv.relative_start,
            bv.behavior.maneuver,
            bv.behavior.speed_estimate_mps,
            bv.style
        );
    }
    let _ = writeln!(out, "  {}", s.event_description);
    out
}
