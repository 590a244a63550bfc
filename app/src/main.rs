//! `video2track`: the operator's command line. It parses arguments, calls the crates that do the
//! work (grounding, generation, exports, supervision, the lab) and prints what they return; every
//! command lives in its own module with its arguments.
//!
//! Exit codes: 0 the work is done (or stdout's reader stopped reading, `| head`: the command ends
//! quietly there, see [`v2t_files::stdout`]); 1 the work failed (a server, a tool, a run that did not finish,
//! a replay that differs); 2 bad input or usage (a file that does not read, parse or validate, an
//! option out of range), always with a message naming the file, the field and the bound.

use std::process::ExitCode;

use clap::{Parser, Subcommand};
use v2t_files::outln;

mod abstract_cmd;
mod campaign;
mod corpus;
mod demo;
mod experiment;
mod export;
mod generate;
mod ground;
mod link;
mod map;
mod regulate;
mod sim;
mod train;
mod world;

/// Video2Track: real interaction videos → steerable adversarial tests on a closed track.
#[derive(Debug, Parser)]
#[command(name = "video2track", version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// The whole pipeline on what ships with the repository: the paper's two scenarios from their
    /// hand-written VLM exchanges, grounded, a prior, a closed loop through the BV's onboard
    /// processes and the simulated proving ground; writes report.html, summary.json, and per
    /// scenario the .xosc, the .mcap and the intermediate files.
    Demo(demo::DemoArgs),
    /// Run one scenario card in the simulated proving ground with reference-following BVs (or,
    /// with --regulated, the BVs' regulator; with --campaign, as one run of a test campaign).
    Sim(sim::SimArgs),
    /// Measure a recorded run (`sim --mcap`) again from its recorded truth and compare with what
    /// the run reported; exit 1 when they differ.
    Replay(sim::ReplayArgs),
    /// Draw a simulated run (`sim --json`) as a bird's-eye video with ffmpeg.
    Render(sim::RenderArgs),
    /// Reproduce a research question of the paper in the simulated proving ground.
    Experiment(experiment::ExperimentArgs),
    /// A test campaign's memory of one VUT on the track: the next run's aim, a run's measured
    /// outcome recorded, what was learned.
    Campaign {
        #[command(subcommand)]
        command: campaign::CampaignCommand,
    },
    /// Turn a driving video into scenario semantics with a vision-language model (endpoint from
    /// V2T_VLM_BASE_URL, V2T_VLM_MODEL, V2T_VLM_API_KEY), or replay a cassette offline.
    Abstract(abstract_cmd::AbstractCmd),
    /// Trajectory priors for a grounded scenario from the guided diffusion model.
    Generate(generate::GenerateArgs),
    /// Realism of trained weights: Wasserstein-1 distances between the controls they generate for
    /// held-out windows of the corpus and the recorded ones, without guidance, with anchors only
    /// and with full guidance.
    Realism(train::RealismCmd),
    /// Recorded human driving for training and realism: import recordings (CommonRoad XML, CSV)
    /// into a corpus, print a corpus's counts.
    Corpus {
        #[command(subcommand)]
        command: corpus::CorpusCommand,
    },
    /// Train the trajectory-prior denoiser (default: on the synthetic corpus generated on the
    /// proving ground); writes OUT/denoiser.safetensors, OUT/metrics.jsonl, OUT/checkpoints/.
    Train(train::TrainCmd),
    /// Place a video's semantics on the proving ground: rank the map's fragments, ground the VUT,
    /// the BVs and their conflict on the best that fits, write the grounded scenario.
    Ground(ground::GroundArgs),
    /// Export a scenario for other tools.
    Export {
        #[command(subcommand)]
        command: export::ExportCommand,
    },
    /// OpenDRIVE maps and their topology library.
    Map {
        #[command(subcommand)]
        command: map::MapCommand,
    },
    /// Make the supervisor's Ed25519 key pair: DIR/cloud.key (secret) and DIR/cloud.pub (for every
    /// BV's edge config).
    Keygen(link::KeygenArgs),
    /// The cloud supervisor: embedded MQTT broker (or --broker), live status of every BV, operator
    /// commands on the console, abort all on Ctrl-C or `quit`.
    Serve(link::ServeArgs),
    /// Sign a prior (TrajectoryPrior JSON, or a GroundedScenario: then constant speed along its
    /// routes) and send it to one BV; wait for the BV's verdict.
    Upload(link::UploadArgs),
    /// Send one signed supervision command: arm, start, abort or target (with --tau and --style).
    Send(link::SendArgs),
    /// The regulator of one BV in the cloud, as the paper and TroubleMaker deploy it: plans on the
    /// BV's states as they arrive through the broker, signed plans back (the BV side is `sim
    /// --regulated --cloud-broker`).
    Regulate(regulate::RegulateArgs),
}

/// Options that contradict each other or lie out of range: bad input (exit 2).
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub(crate) struct Usage(pub(crate) String);

/// An input file the user named is unreadable or not what it should be (a directory, missing,
/// damaged): bad input (exit 2), whatever error type the reader that found it uses.
#[derive(Debug, thiserror::Error)]
#[error(transparent)]
pub(crate) struct BadFile(pub(crate) Box<dyn std::error::Error + Send + Sync + 'static>);

impl BadFile {
    /// Marks a reader's error as the user's input at fault.
    pub(crate) fn of(e: impl std::error::Error + Send + Sync + 'static) -> Self {
        Self(Box::new(e))
    }
}

/// A reader's error about the file at `path`, as bad input: the path first, once (some readers
/// name it themselves).
pub(crate) fn named(path: &std::path::Path, e: impl std::fmt::Display) -> Usage {
    let (path, e) = (path.display().to_string(), e.to_string());
    Usage(if e.starts_with(&path) { e } else { format!("{path}: {e}") })
}

fn execute(command: Command) -> anyhow::Result<()> {
    match command {
        Command::Demo(a) => demo::run(a),
        Command::Sim(a) => sim::run(a),
        Command::Replay(a) => sim::replay(a),
        Command::Render(a) => sim::render(a),
        Command::Experiment(a) => experiment::run(a),
        Command::Campaign { command } => campaign::run(command),
        Command::Abstract(a) => abstract_cmd::run(a),
        Command::Generate(a) => generate::run(a),
        Command::Realism(a) => train::realism(a),
        Command::Train(a) => train::train(a),
        Command::Corpus { command } => corpus::run(command),
        Command::Ground(a) => ground::run(a),
        Command::Export { command } => export::run(command),
        Command::Map { command } => map::run(command),
        Command::Keygen(a) => link::keygen(a),
        Command::Serve(a) => link::serve(a),
        Command::Upload(a) => link::upload(a),
        Command::Send(a) => link::send(a),
        Command::Regulate(a) => regulate::run(a),
    }
}

/// Whether an error is the user's input at fault (exit 2) rather than the work (exit 1).
fn bad_input(err: &anyhow::Error) -> bool {
    use v2t_supervisor::link::LinkError;
    err.chain().any(|e| {
        e.is::<Usage>()
            || e.is::<BadFile>()
            || e.is::<v2t_files::InputError>()
            || e.is::<v2t_sim::files::CardError>()
            || e.is::<v2t_map::MapError>()
            || e.is::<v2t_model::TargetError>()
            || e.downcast_ref::<abstract_cmd::AbstractError>().is_some_and(abstract_cmd::AbstractError::is_input)
            || e.downcast_ref::<v2t_export::video::RenderError>().is_some_and(v2t_export::video::RenderError::is_input)
            || e.downcast_ref::<v2t_export::file::ExportError>().is_some_and(v2t_export::file::ExportError::is_input)
            || matches!(
                e.downcast_ref::<LinkError>(),
                Some(
                    LinkError::Prior(_)
                        | LinkError::Agent { .. }
                        | LinkError::Usage(_)
                        | LinkError::Url(_)
                        | LinkError::Target(_)
                )
            )
            || matches!(
                e.downcast_ref::<v2t_sim::recording::RecordingError>(),
                Some(
                    v2t_sim::recording::RecordingError::Mcap { .. }
                        | v2t_sim::recording::RecordingError::Content { .. }
                )
            )
    })
}

fn main() -> ExitCode {
    match execute(Cli::parse().command) {
        Ok(()) => ExitCode::SUCCESS,
        // The reader of stdout went away (`| head`): nothing more to say, and nothing failed.
        Err(err) if v2t_files::stdout::closed(err.as_ref()) => ExitCode::SUCCESS,
        Err(err) => {
            eprintln!("error: {}", v2t_files::error_chain(err.as_ref()));
            ExitCode::from(if bad_input(&err) { 2 } else { 1 })
        }
    }
}

/// Writes `value` as pretty JSON with a final newline and says so.
pub(crate) fn write_json(path: &std::path::Path, value: &impl serde::Serialize) -> anyhow::Result<()> {
    use anyhow::Context as _;
    let text = serde_json::to_string_pretty(value).context("serializing")?;
    std::fs::write(path, text + "\n").with_context(|| format!("writing {}", path.display()))?;
    outln!("wrote {}", path.display())?;
    Ok(())
}

/// The VUT driver models named on the command line (all when none).
pub(crate) fn vut_models(names: &[String]) -> anyhow::Result<Vec<v2t_sim::vut::VutModel>> {
    if names.is_empty() {
        return Ok(v2t_sim::vut::VutModel::ALL.to_vec());
    }
    names.iter().map(|v| v.parse().map_err(|e: String| Usage(e).into())).collect()
}
