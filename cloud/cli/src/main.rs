//! `video2track`: the operator's command line.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context as _;
use clap::{CommandFactory as _, Parser, Subcommand, ValueEnum as _};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use v2t_game::regulator::RegulatorParams;
use v2t_sim::vut::VutModel;
use v2t_wire::link::{ALL_BVS, CloudBody, key_to_hex};
use video2track::abstract_cmd::{AbstractArgs, AbstractError};
use video2track::experiment;
use video2track::files::{InputError, load_scenario, load_toml};
use video2track::link::{BvEvent, Connection, Signer};
use video2track::render::{RenderError, RenderOptions};
use video2track::serve::ServeOptions;
use video2track::sim::{report, run_reference};

/// Video2Track: real interaction videos → steerable adversarial tests on a closed track.
#[derive(Debug, Parser)]
#[command(name = "video2track", version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

/// Guidance terms of `generate`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
enum GuidanceArg {
    /// Anchors, solid boundaries, clearance, kinematic limits.
    Full,
    /// Anchors only.
    Anchor,
    /// None: the bare denoiser.
    None,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// The whole pipeline on embedded defaults: the paper's two scenarios from their recorded VLM
    /// exchanges, grounded, a prior, a closed loop through the BV's onboard processes; writes
    /// report.html, summary.json, and per scenario the .xosc, the .mcap and the intermediate files.
    Demo {
        /// Output folder.
        #[arg(long, default_value = "demo-out")]
        out: PathBuf,
        /// VUT driver model.
        #[arg(long, default_value = "idm-normal", value_parser = clap::builder::PossibleValuesParser::new(VutModel::names()))]
        vut: String,
        /// Noise seed.
        #[arg(long, default_value_t = 1)]
        seed: u64,
    },
    /// Run one scenario card in the simulated proving ground with reference-following BVs.
    Sim {
        /// Scenario card (TOML), e.g. config/scenarios/left_turn_basic.toml.
        card: PathBuf,
        /// Random seed of sensor noise.
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// VUT driver model (default: the card's).
        #[arg(long, value_parser = clap::builder::PossibleValuesParser::new(VutModel::names()))]
        vut: Option<String>,
        /// Write the results and the full trace as JSON to this file.
        #[arg(long)]
        json: Option<PathBuf>,
        /// Record the run as MCAP (truth, scene, commands, predicted PET) to this file.
        #[arg(long)]
        mcap: Option<PathBuf>,
    },
    /// Measure a recorded run (`sim --mcap`) again from its recorded truth and compare with what
    /// the run reported; exit 1 when they differ.
    Replay {
        /// The recording (.mcap).
        recording: PathBuf,
        /// Write the recomputed result as JSON here.
        #[arg(long)]
        json: Option<PathBuf>,
    },
    /// Draw a simulated run (`sim --json`) as a bird's-eye video with ffmpeg.
    Render {
        /// The run (JSON written by `video2track sim --json`).
        run: PathBuf,
        /// The video to write, e.g. run.mp4.
        #[arg(short, long)]
        out: PathBuf,
        /// Frames per second (poses between the run's 10 Hz samples are interpolated).
        #[arg(long, default_value_t = 10)]
        fps: u32,
        /// Width, px (even); the height is 9/16 of it.
        #[arg(long, default_value_t = 960)]
        width: u32,
        /// The run's scenario card: footprints and routes (default: 4.8 m × 1.85 m, driven paths).
        #[arg(long)]
        card: Option<PathBuf>,
        /// A map (.xodr) whose lanes are drawn underneath.
        #[arg(long)]
        map: Option<PathBuf>,
    },
    /// Reproduce a research question of the paper in the simulated proving ground.
    Experiment {
        /// Which experiment.
        #[arg(value_enum)]
        which: Experiment,
        /// Write the per-case results as JSON to this file.
        #[arg(long)]
        json: Option<PathBuf>,
        /// Seeded noisy runs per case.
        #[arg(long, default_value_t = 20)]
        repeats: usize,
        /// steerability without --methods: scenario cards (default: the bundled left turn and cut-in).
        #[arg(long = "card")]
        cards: Vec<PathBuf>,
        /// Only these VUT models (default: all).
        #[arg(long, value_parser = clap::builder::PossibleValuesParser::new(VutModel::names()))]
        vut: Vec<String>,
        /// steerability: only these targets τ, s (default: 1.5 2 3 4 5; repeat the option for more).
        #[arg(long)]
        tau: Vec<f64>,
        /// Regulator settings (TOML).
        #[arg(long, default_value = "config/regulator/default.toml")]
        regulator: PathBuf,
        /// steerability: compare the four methods on the two recorded scenarios (grounded for each
        /// τ and style) instead of the regulator alone on the scenario cards.
        #[arg(long)]
        methods: bool,
    },
    /// Turn a driving video into scenario semantics with a vision-language model (endpoint from
    /// V2T_VLM_BASE_URL, V2T_VLM_MODEL, V2T_VLM_API_KEY), or replay a recorded cassette offline.
    Abstract {
        /// The video. With --replay only its file name counts: the one the cassette recorded.
        video: PathBuf,
        /// The operator's post-encroachment time label for the video, s, in (0, 30] (default: from
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
    },
    /// Trajectory priors for a grounded scenario from the guided diffusion model.
    Generate {
        /// Grounded scenario (JSON, as `ground --out` writes it).
        grounded: PathBuf,
        /// Variants to generate (seeded, one batch).
        #[arg(long, default_value_t = 1)]
        variants: usize,
        /// Write the best variant (no boundary crossing, within limits, order as asked, smallest
        /// anchor error) as a trajectory prior (JSON) here.
        #[arg(long)]
        out: Option<PathBuf>,
        /// Write every variant as DIR/variant-NNN.json.
        #[arg(long)]
        all: Option<PathBuf>,
        /// Write per-variant metrics and their summary (JSON) here.
        #[arg(long)]
        json_metrics: Option<PathBuf>,
        /// Denoiser weights (safetensors).
        #[arg(long, default_value = video2track::train::SHIPPED_WEIGHTS)]
        weights: PathBuf,
        /// The map the scenario is grounded on.
        #[arg(long, default_value = video2track::ground::DEFAULT_MAP)]
        map: PathBuf,
        /// Seed of the noise.
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// DDIM with this many steps instead of DDPM over all K.
        #[arg(long)]
        ddim: Option<usize>,
        /// Guidance terms (ablation): full, anchor, none.
        #[arg(long, value_enum, default_value_t = GuidanceArg::Full)]
        guidance: GuidanceArg,
        /// Guidance scale η of every denoising step.
        #[arg(long, default_value_t = v2t_diffusion::sample::GuidanceSchedule::default().scale)]
        guidance_scale: f64,
        /// Guided corrections of the final sample (0: the paper's algorithm alone).
        #[arg(long, default_value_t = v2t_diffusion::sample::GuidanceSchedule::default().final_iterations)]
        final_iterations: usize,
        /// Draws per variant: one that crosses a solid boundary, leaves the limits or the order is
        /// drawn again up to this many times in all (1: no redraw, for ablations).
        #[arg(long, default_value_t = v2t_diffusion::generate::GenerateOptions::default().draws)]
        draws: u64,
    },
    /// Realism of trained weights: Wasserstein-1 distances between the controls they generate for
    /// held-out windows of the corpus and the recorded ones, without guidance, with anchors only
    /// and with full guidance.
    Realism {
        /// Denoiser weights (safetensors).
        #[arg(long, default_value = video2track::train::SHIPPED_WEIGHTS)]
        weights: PathBuf,
        #[command(flatten)]
        corpus: video2track::train::CorpusSource,
        /// Held-out windows compared (one per held-out episode).
        #[arg(long, default_value_t = 100)]
        windows: usize,
        /// Sampling seed.
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Write the rows as JSON here.
        #[arg(long)]
        json: Option<PathBuf>,
    },
    /// Train the trajectory-prior denoiser (default: on the synthetic corpus generated on the
    /// proving ground); writes OUT/denoiser.safetensors, OUT/metrics.jsonl, OUT/checkpoints/.
    Train {
        #[command(flatten)]
        corpus: video2track::train::CorpusSource,
        /// Optimizer steps.
        #[arg(long, default_value_t = 5000)]
        steps: usize,
        /// Windows per step.
        #[arg(long, default_value_t = 64)]
        batch: usize,
        /// Peak learning rate.
        #[arg(long, default_value_t = 1e-3)]
        lr: f64,
        /// Seed of initialization, batches and noise.
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Channels of the network.
        #[arg(long, default_value_t = 64)]
        hidden: usize,
        /// Residual blocks.
        #[arg(long, default_value_t = 4)]
        blocks: usize,
        /// Held-out loss (and a metrics line) every this many steps.
        #[arg(long, default_value_t = 250)]
        eval_every: usize,
        /// A checkpoint every this many steps (0: none).
        #[arg(long, default_value_t = 1000)]
        checkpoint_every: usize,
        /// Output directory.
        #[arg(long, default_value = "target/train")]
        out: PathBuf,
    },
    /// Place a video's semantics on the proving ground: rank the map's fragments, ground the VUT,
    /// the BVs and their conflict on the best that fits, write the grounded scenario.
    Ground {
        /// Scenario semantics (JSON, as `abstract` writes it), e.g. config/examples/semantics_cut_in.json.
        semantics: PathBuf,
        /// The proving ground's map (.xodr); its annotations `<map>.toml` apply when they exist.
        #[arg(long, default_value = video2track::ground::DEFAULT_MAP)]
        map: PathBuf,
        /// Hand annotations (TOML; default: the map's name with .toml, when it exists).
        #[arg(long)]
        annotations: Option<PathBuf>,
        /// Write the grounded scenario (JSON) here.
        #[arg(long)]
        out: Option<PathBuf>,
        /// Write the whole grounding (scenario, routes, planned timing, notes, ranking) as JSON here.
        #[arg(long)]
        json: Option<PathBuf>,
        /// Show this many ranked fragments with their scores and reasons.
        #[arg(long, default_value_t = 3)]
        top: usize,
    },
    /// Export a scenario for other tools.
    Export {
        #[command(subcommand)]
        command: ExportCommand,
    },
    /// OpenDRIVE maps and their topology library.
    Map {
        #[command(subcommand)]
        command: MapCommand,
    },
    /// Make the supervisor's Ed25519 key pair: DIR/cloud.key (secret) and DIR/cloud.pub (for every
    /// BV's edge config).
    Keygen {
        /// Where to write the pair.
        #[arg(long, default_value = "keys")]
        out: PathBuf,
    },
    /// The cloud supervisor: embedded MQTT broker (or --broker), live status of every BV, operator
    /// commands on the console, abort all on Ctrl-C or `quit`.
    Serve {
        #[command(flatten)]
        link: LinkArgs,
        /// An external broker (mqtt://host:port or mqtts://…) instead of the embedded one.
        #[arg(long)]
        broker: Option<String>,
        /// Address of the embedded broker.
        #[arg(long, default_value = "127.0.0.1:1883")]
        listen: std::net::SocketAddr,
        /// Log every message received as JSON lines here.
        #[arg(long)]
        log: Option<PathBuf>,
        /// Print the fleet table every this many seconds (0: only on `status`).
        #[arg(long, default_value_t = 2.0)]
        status_period_s: f64,
        /// A prior uploaded from the console stays valid this long, s.
        #[arg(long, default_value_t = 600.0)]
        valid_s: f64,
    },
    /// Sign a prior (TrajectoryPrior JSON, or a GroundedScenario: then constant speed along its
    /// routes) and send it to one BV; wait for the BV's verdict.
    Upload {
        /// The priors file.
        priors: PathBuf,
        /// The BV it is for.
        #[arg(long)]
        bv: String,
        /// The prior's BV agent this BV drives (default: the first BV).
        #[arg(long)]
        agent: Option<String>,
        /// Target PET τ, s (default: the file's).
        #[arg(long)]
        tau: Option<f64>,
        /// Style, rush or yield (default: the file's).
        #[arg(long, value_parser = ["rush", "yield"])]
        style: Option<String>,
        /// Identifier the BV reports back (default: from the clock).
        #[arg(long)]
        prior_id: Option<u64>,
        /// Valid for this long from now, s.
        #[arg(long, default_value_t = 600.0)]
        valid_s: f64,
        #[command(flatten)]
        shot: OneShotArgs,
    },
    /// Send one signed supervision command: arm, start, abort or target (with --tau and --style).
    Send {
        /// What.
        #[arg(value_parser = ["arm", "start", "abort", "target"])]
        action: String,
        /// The BV, or `all`.
        #[arg(long, default_value = "all")]
        bv: String,
        /// New target PET τ, s (target).
        #[arg(long)]
        tau: Option<f64>,
        /// New style (target).
        #[arg(long, value_parser = ["rush", "yield"])]
        style: Option<String>,
        #[command(flatten)]
        shot: OneShotArgs,
    },
}

/// One signed frame sent to a broker, waiting for the BV's verdict (`upload`, `send`).
#[derive(Debug, clap::Args)]
struct OneShotArgs {
    #[command(flatten)]
    link: LinkArgs,
    /// The broker.
    #[arg(long, default_value = "mqtt://127.0.0.1:1883")]
    broker: String,
    /// Wait this long for the BV's verdict, s (0, or `--bv all`: do not wait).
    #[arg(long, default_value_t = 3.0)]
    wait_s: f64,
}

impl OneShotArgs {
    /// Signs `body` for `bv`, sends it and reports the BV's verdict.
    fn send(&self, bv: &str, body: CloudBody) -> anyhow::Result<()> {
        let mut signer = self.link.signer()?;
        let wait = wait_duration(self.wait_s)?;
        let answer = video2track::link::send_once(&self.link.connection(&self.broker)?, &mut signer, bv, body, wait)?;
        verdict(bv, answer)
    }
}

/// Who signs, for which fleet, and how to log in to the broker.
#[derive(Debug, clap::Args)]
struct LinkArgs {
    /// Fleet (test session) id: part of every topic.
    #[arg(long, default_value = "demo")]
    fleet: String,
    /// The supervisor's secret key (`video2track keygen`). The default is the committed demo key,
    /// for simulated BVs only.
    #[arg(long, default_value = "config/keys/demo_cloud.key")]
    key: PathBuf,
    /// MQTT user name.
    #[arg(long)]
    username: Option<String>,
    /// Environment variable holding the MQTT password.
    #[arg(long)]
    password_env: Option<String>,
    /// CA certificate (PEM) of an mqtts:// broker.
    #[arg(long)]
    ca_file: Option<PathBuf>,
    /// Client certificate (PEM) for brokers that require one.
    #[arg(long, requires = "client_key")]
    client_cert: Option<PathBuf>,
    /// Its key (PEM).
    #[arg(long, requires = "client_cert")]
    client_key: Option<PathBuf>,
}

impl LinkArgs {
    fn signer(&self) -> anyhow::Result<Signer> {
        let key = video2track::link::load_signing_key(&self.key)?;
        if video2track::link::is_demo_key(&key) {
            eprintln!(
                "warning: signing with the public demo key {}: for simulated BVs only; make your own with `video2track keygen`",
                self.key.display()
            );
        }
        Ok(Signer::new(key, &self.fleet)?)
    }

    fn connection(&self, broker: &str) -> anyhow::Result<Connection> {
        let tls = video2track::link::TlsFiles {
            ca: self.ca_file.as_deref(),
            client_cert: self.client_cert.as_deref(),
            client_key: self.client_key.as_deref(),
        };
        Ok(Connection::new(broker, self.username.as_deref(), self.password_env.as_deref(), tls)?)
    }
}

fn verdict(bv: &str, answer: Option<BvEvent>) -> anyhow::Result<()> {
    match answer {
        Some(e) if e.verdict == "accepted" => {
            println!("{bv}: accepted {}", e.detail);
            Ok(())
        }
        Some(e) => Err(anyhow::anyhow!("{bv} refused it: {}", e.detail)),
        None => {
            println!("sent");
            Ok(())
        }
    }
}

#[derive(Debug, Subcommand)]
enum ExportCommand {
    /// Write a trajectory prior, a grounded scenario (constant speed along its routes) or a run
    /// (`sim --json`) as an OpenSCENARIO 1.2 file: the BVs follow their trajectories, the VUT gets
    /// its start and its route.
    Xosc {
        /// The input (JSON): TrajectoryPrior, GroundedScenario or `video2track sim --json` run.
        input: PathBuf,
        /// The .xosc to write.
        #[arg(short, long)]
        out: PathBuf,
        /// The map (.xodr) the file names as its road network (relative to the output file).
        #[arg(long, default_value = video2track::ground::DEFAULT_MAP)]
        map: PathBuf,
        /// The VUT's vehicle file (TOML).
        #[arg(long, default_value = "config/vehicles/vut_sedan.toml")]
        vut_vehicle: PathBuf,
        /// Every BV's vehicle file (TOML).
        #[arg(long, default_value = "config/vehicles/bv_sedan.toml")]
        bv_vehicle: PathBuf,
    },
}

#[derive(Debug, Subcommand)]
enum MapCommand {
    /// Parse an OpenDRIVE map, build its topology library and report fragments, anchors and timings.
    Inspect {
        /// The map (.xodr).
        map: PathBuf,
        /// Write the topology library (fragments, anchors, maneuver paths) as JSON here.
        #[arg(long)]
        json: Option<PathBuf>,
        /// Draw lanes, marks, fragments and anchors as SVG here.
        #[arg(long)]
        svg: Option<PathBuf>,
        /// Hand annotations (TOML; default: the map's name with .toml, when it exists).
        #[arg(long)]
        annotations: Option<PathBuf>,
    },
}

#[derive(Debug, Clone, Copy, clap::ValueEnum)]
enum Sampling {
    /// In the middle of equal slices of the video.
    Uniform,
    /// Half uniform, half where the picture changes most.
    Motion,
}

#[derive(Debug, Clone, Copy, clap::ValueEnum)]
enum Experiment {
    /// RQ3: does the achieved PET land on the target τ, in both styles, against every VUT model?
    Steerability,
    /// RQ1: the four methods at rush, τ = 1.5 s: which gives the smallest PET without collision?
    Adversariality,
    /// RQ2: the four methods at the video's style and PET label: PET^min_track against the label.
    Fidelity,
    /// The four methods in both styles at the video's PET label: is the order the one asked for?
    Style,
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    if let Some(msg) = unused_experiment_options(&cli) {
        Cli::command().error(clap::error::ErrorKind::ArgumentConflict, msg).exit();
    }
    match execute(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(err) => {
            eprintln!("error: {err:#}");
            let bad_input = err.chain().any(|e| {
                e.is::<InputError>()
                    || e.is::<v2t_map::MapError>()
                    || e.is::<video2track::ground::SemanticsFileError>()
                    || e.downcast_ref::<AbstractError>().is_some_and(AbstractError::is_input)
                    || e.downcast_ref::<RenderError>().is_some_and(RenderError::is_input)
                    || e.downcast_ref::<video2track::export::ExportError>()
                        .is_some_and(video2track::export::ExportError::is_input)
                    || matches!(
                        e.downcast_ref::<video2track::link::LinkError>(),
                        Some(video2track::link::LinkError::Prior { .. } | video2track::link::LinkError::Usage(_))
                    )
                    || matches!(
                        e.downcast_ref::<video2track::recording::RecordingError>(),
                        Some(
                            video2track::recording::RecordingError::Mcap { .. }
                                | video2track::recording::RecordingError::Content { .. }
                        )
                    )
            });
            if bad_input { ExitCode::from(2) } else { ExitCode::FAILURE }
        }
    }
}

/// An `experiment` option given where that experiment does not read it (it would be silently
/// ignored): what to say.
fn unused_experiment_options(cli: &Cli) -> Option<String> {
    let Command::Experiment { which, cards, tau, methods, .. } = &cli.command else { return None };
    let steerability = matches!(which, Experiment::Steerability);
    if !cards.is_empty() && (*methods || !steerability) {
        return Some(
            "--card applies to `experiment steerability` (the regulator on scenario cards); the four \
             methods run on the two recorded scenarios"
                .to_owned(),
        );
    }
    if !tau.is_empty() && !steerability {
        return Some(format!(
            "--tau applies to `experiment steerability` only; `experiment {}` sets its own targets",
            which.to_possible_value().map_or_else(String::new, |v| v.get_name().to_owned())
        ));
    }
    None
}

fn wait_duration(s: f64) -> anyhow::Result<std::time::Duration> {
    if !(0.0..=600.0).contains(&s) {
        anyhow::bail!("--wait-s must lie in [0, 600], got {s}");
    }
    Ok(std::time::Duration::from_secs_f64(s))
}

fn execute(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Demo { out, vut, seed } => {
            let opts = video2track::demo::DemoOptions {
                out: out.clone(),
                map: PathBuf::from(video2track::ground::DEFAULT_MAP),
                edge_config: PathBuf::from("config/edge/bv1.toml"),
                edge_bin: video2track::demo::edge_beside_me(),
                vut,
                seed,
                weights: PathBuf::from(video2track::train::SHIPPED_WEIGHTS),
            };
            let summary = video2track::demo::run(&opts)?;
            println!(
                "wrote {}/report.html and {}/summary.json in {:.1} s",
                out.display(),
                out.display(),
                summary.wall_s
            );
            Ok(())
        }
        Command::Replay { recording, json } => {
            let r = video2track::recording::replay(&recording)?;
            print!("{}", video2track::recording::report(&recording, &r));
            if let Some(path) = json {
                let text = serde_json::to_string_pretty(&r.recomputed).context("serializing the result")?;
                std::fs::write(&path, text + "\n").with_context(|| format!("writing {}", path.display()))?;
                println!("wrote {}", path.display());
            }
            if r.matches() { Ok(()) } else { anyhow::bail!("the recomputed metrics differ from the recorded ones") }
        }
        Command::Sim { card, seed, vut, json, mcap } => {
            let scenario = load_scenario(&card)?;
            let model = vut.map(|v| v.parse::<VutModel>()).transpose().map_err(anyhow::Error::msg)?;
            let outcome = run_reference(&scenario, model, seed)?;
            print!("{}", report(&outcome));
            if let Some(path) = mcap {
                video2track::recording::write(&outcome, &path)?;
                println!("wrote {}", path.display());
            }
            if let Some(path) = json {
                let text = serde_json::to_string_pretty(&outcome).context("serializing the run")?;
                std::fs::write(&path, text + "\n").with_context(|| format!("writing {}", path.display()))?;
                println!("wrote {}", path.display());
            }
            Ok(())
        }
        Command::Generate {
            grounded,
            variants,
            out,
            all,
            json_metrics,
            weights,
            map,
            seed,
            ddim,
            guidance,
            guidance_scale,
            final_iterations,
            draws,
        } => {
            use video2track::generate as g;
            let scenario = g::read_grounded(&grounded)?;
            let model = g::load_model(&weights)?;
            let map_data = v2t_map::Map::load(&map)?;
            let mode = match guidance {
                GuidanceArg::Full => g::GuidanceMode::Full,
                GuidanceArg::Anchor => g::GuidanceMode::AnchorOnly,
                GuidanceArg::None => g::GuidanceMode::None,
            };
            let method = match ddim {
                Some(steps) => v2t_diffusion::sample::Method::Ddim { steps },
                None => v2t_diffusion::sample::Method::Ddpm { noise: true },
            };
            let schedule = v2t_diffusion::sample::GuidanceSchedule {
                scale: guidance_scale,
                final_iterations,
                ..v2t_diffusion::sample::GuidanceSchedule::default()
            };
            let options = v2t_diffusion::generate::GenerateOptions {
                variants,
                seed,
                sampler: v2t_diffusion::sample::SamplerOptions { method, guidance: schedule },
                weights: mode.weights(),
                draws,
                ..v2t_diffusion::generate::GenerateOptions::default()
            };
            let (generated, summary) = g::run(&model, &map_data, &scenario, &options)?;
            print!("{}{}", g::REPORT_HEADER, g::report(&summary, mode));
            if let Some(dir) = &all {
                std::fs::create_dir_all(dir)?;
                for (i, v) in generated.iter().enumerate() {
                    g::write_prior(&dir.join(format!("variant-{i:03}.json")), &v.prior)?;
                }
                println!("wrote {} variants to {}", generated.len(), dir.display());
            }
            if let Some(path) = &out {
                let chosen = g::best(&generated).ok_or_else(|| anyhow::anyhow!("no variant generated"))?;
                g::write_prior(path, &chosen.prior)?;
                println!("wrote {}", path.display());
            }
            if let Some(path) = &json_metrics {
                let file = g::MetricsFile {
                    fragment_id: scenario.fragment_id.clone(),
                    guidance: mode.name().to_owned(),
                    sampler: format!("{method:?}"),
                    weights: format!("{} ({})", weights.display(), model.meta.training.command),
                    summary,
                    variants: generated.iter().map(|v| v.metrics.clone()).collect(),
                };
                std::fs::write(path, serde_json::to_string_pretty(&file)?)?;
                println!("wrote {}", path.display());
            }
            Ok(())
        }
        Command::Realism { weights, corpus, windows, seed, json } => {
            let args = video2track::train::RealismArgs { weights, corpus, windows, seed };
            let rows = video2track::train::realism(&args)?;
            print!("{}", video2track::train::realism_table(&rows));
            if let Some(path) = json {
                std::fs::write(&path, serde_json::to_string_pretty(&rows)?)?;
                println!("wrote {}", path.display());
            }
            Ok(())
        }
        Command::Train { corpus, steps, batch, lr, seed, hidden, blocks, eval_every, checkpoint_every, out } => {
            let command = std::env::args().collect::<Vec<_>>().join(" ");
            let args = video2track::train::TrainArgs {
                corpus,
                options: v2t_diffusion::train::TrainOptions {
                    steps,
                    batch,
                    learning_rate: lr,
                    seed,
                    eval_every,
                    ..v2t_diffusion::train::TrainOptions::default()
                },
                config: v2t_diffusion::denoiser::DenoiserConfig {
                    hidden,
                    blocks,
                    ..v2t_diffusion::denoiser::DenoiserConfig::default()
                },
                stride: 5,
                out,
                checkpoint_every,
                command,
            };
            let done = video2track::train::train(&args)?;
            println!(
                "trained {} parameters in {:.0} s, held-out loss {:.4}; wrote {} and {}",
                done.parameters,
                done.elapsed_s,
                done.heldout_loss,
                done.weights.display(),
                done.metrics.display()
            );
            Ok(())
        }
        Command::Abstract { video, pet_label, labels, out, record, replay, frames, sampling } => {
            let pet_label = video2track::abstract_cmd::pet_label(&video, pet_label, labels.as_deref())?;
            let args = AbstractArgs {
                video,
                pet_label_s: pet_label,
                record,
                replay,
                frames,
                sampling: sampling.map(|s| match s {
                    Sampling::Uniform => video2track::abstract_cmd::Sampling::Uniform,
                    Sampling::Motion => video2track::abstract_cmd::Sampling::Motion,
                }),
            };
            let result = video2track::abstract_cmd::abstract_video(&args, |name| std::env::var(name).ok())?;
            print!("{}", video2track::abstract_cmd::report(&result));
            if let Some(dir) = &args.record {
                println!("recorded {}", dir.display());
            }
            if let Some(path) = out {
                video2track::abstract_cmd::write_semantics(&path, &result.semantics)?;
                println!("wrote {}", path.display());
            }
            Ok(())
        }
        Command::Render { run, out, fps, width, card, map } => {
            let opts = RenderOptions { fps, width };
            opts.validate()?;
            let scene = video2track::render::load_scene(&run, card.as_deref(), map.as_deref())?;
            let done = video2track::render::encode(&scene, &opts, &out, std::path::Path::new("ffmpeg"))?;
            let (t0, t1) = scene.time_span();
            println!(
                "{}: {} vehicles, {:.1} s  |  {} frames at {} fps, {}x{}, {}",
                scene.name,
                scene.vehicles.len(),
                t1 - t0,
                done.frames,
                fps,
                done.width,
                done.height,
                done.encoder
            );
            println!("wrote {}", out.display());
            Ok(())
        }
        Command::Experiment { which, json, repeats, vut, regulator, methods: four, tau, .. }
            if four || !matches!(which, Experiment::Steerability) =>
        {
            use video2track::methods;
            let models: Vec<VutModel> = if vut.is_empty() {
                VutModel::ALL.to_vec()
            } else {
                vut.iter().map(|v| v.parse::<VutModel>()).collect::<Result<_, _>>().map_err(anyhow::Error::msg)?
            };
            let inspection = video2track::map::inspect(std::path::Path::new(video2track::ground::DEFAULT_MAP), None)?;
            let model = video2track::generate::load_model(std::path::Path::new(video2track::train::SHIPPED_WEIGHTS))?;
            let setup = methods::Setup {
                inspection: &inspection,
                model: &model,
                regulator: load_toml(&regulator)?,
                sim: load_toml(std::path::Path::new("config/sim/default.toml"))?,
                vut_vehicle: load_toml(std::path::Path::new("config/vehicles/vut_sedan.toml"))?,
                bv_vehicle: load_toml(std::path::Path::new("config/vehicles/bv_sedan.toml"))?,
            };
            let mut recorded = Vec::new();
            for sc in video2track::demo::SCENARIOS {
                let semantics = sc.replayed_semantics()?;
                recorded.push(methods::Recorded { name: sc.name.to_owned(), semantics });
            }
            let taus = if tau.is_empty() { experiment::STEER_TAUS_S.to_vec() } else { tau };
            let comparison = match which {
                Experiment::Adversariality => methods::Comparison::Adversariality,
                Experiment::Fidelity => methods::Comparison::Fidelity,
                Experiment::Style => methods::Comparison::Style,
                Experiment::Steerability => methods::Comparison::Steerability(taus),
            };
            let cases =
                methods::run_all(&setup, &recorded, &comparison, &models, repeats).map_err(anyhow::Error::msg)?;
            let summary = methods::summarize(&cases);
            // The fidelity error is against the video's PET label: only where τ is that label.
            let labels: Vec<(String, f64)> = match which {
                Experiment::Adversariality | Experiment::Steerability => Vec::new(),
                _ => recorded.iter().map(|r| (r.name.clone(), r.semantics.pet_label_s)).collect(),
            };
            print!("{}", methods::markdown(&summary, &labels));
            let steering = methods::steering_errors(&summary);
            if matches!(which, Experiment::Steerability) {
                print!("{}", methods::steering_markdown(&steering));
            }
            if let Some(path) = json {
                let doc = serde_json::json!({ "cases": cases, "summary": summary, "steering": steering });
                let text = serde_json::to_string_pretty(&doc).context("serializing the report")?;
                std::fs::write(&path, text + "\n").with_context(|| format!("writing {}", path.display()))?;
                println!("wrote {}", path.display());
            }
            Ok(())
        }
        // Steerability of the regulator alone on the scenario cards (the other experiments and
        // `--methods` are the arm above).
        Command::Experiment { json, repeats, cards, vut, tau, regulator, .. } => {
            let settings: RegulatorParams = load_toml(&regulator)?;
            let cards = if cards.is_empty() {
                vec![
                    PathBuf::from("config/scenarios/left_turn_basic.toml"),
                    PathBuf::from("config/scenarios/cut_in_basic.toml"),
                ]
            } else {
                cards
            };
            let scenarios = cards.iter().map(|c| load_scenario(c)).collect::<Result<Vec<_>, _>>()?;
            let models: Vec<VutModel> = if vut.is_empty() {
                VutModel::ALL.to_vec()
            } else {
                vut.iter().map(|v| v.parse::<VutModel>()).collect::<Result<_, _>>().map_err(anyhow::Error::msg)?
            };
            let taus = if tau.is_empty() { experiment::STEER_TAUS_S.to_vec() } else { tau };
            let report = experiment::steerability(&settings, &scenarios, &taus, &models, repeats);
            print!("{}", experiment::steer_markdown(&report));
            if let Some(path) = json {
                let text = serde_json::to_string_pretty(&report).context("serializing the report")?;
                std::fs::write(&path, text + "\n").with_context(|| format!("writing {}", path.display()))?;
                println!("wrote {}", path.display());
            }
            Ok(())
        }
        Command::Ground { semantics, map, annotations, out, json, top } => {
            let sem = video2track::ground::load_semantics(&semantics)?;
            let inspection = video2track::map::inspect(&map, annotations.as_deref())?;
            for w in &inspection.map.warnings {
                eprintln!("warning: {}: {w}", map.display());
            }
            let ranking = v2t_ground::rank(&inspection.library, &sem);
            print!("{}", video2track::ground::ranking_report(&ranking, top));
            let grounding = v2t_ground::ground(&inspection.map, &inspection.library, &sem)
                .with_context(|| format!("grounding {} on {}", semantics.display(), map.display()))?;
            print!("{}", video2track::ground::report(&grounding));
            if let Some(path) = out {
                let text = serde_json::to_string_pretty(&grounding.scenario).context("serializing the scenario")?;
                std::fs::write(&path, text + "\n").with_context(|| format!("writing {}", path.display()))?;
                println!("wrote {}", path.display());
            }
            if let Some(path) = json {
                let doc = video2track::ground::GroundJson {
                    semantics: semantics.display().to_string(),
                    map: map.display().to_string(),
                    grounding: &grounding,
                };
                let text = serde_json::to_string_pretty(&doc).context("serializing the grounding")?;
                std::fs::write(&path, text + "\n").with_context(|| format!("writing {}", path.display()))?;
                println!("wrote {}", path.display());
            }
            Ok(())
        }
        Command::Keygen { out } => {
            let vk = video2track::link::keygen(&out)?;
            println!("wrote {0}/cloud.key (secret, mode 600) and {0}/cloud.pub", out.display());
            println!(
                "public key {}: name cloud.pub as `cloud_key` in every BV's [uplink] section",
                key_to_hex(vk.as_bytes())
            );
            Ok(())
        }
        Command::Serve { link, broker, listen, log, status_period_s, valid_s } => {
            if !(0.0..=3600.0).contains(&status_period_s) {
                anyhow::bail!("--status-period-s must lie in [0, 3600], got {status_period_s}");
            }
            let signer = link.signer()?;
            let (url, embedded) = match broker {
                Some(b) => (b, None),
                None => (format!("mqtt://{listen}"), Some(listen)),
            };
            let stop = Arc::new(AtomicBool::new(false));
            let flag = Arc::clone(&stop);
            ctrlc::set_handler(move || flag.store(true, Ordering::SeqCst)).context("installing the Ctrl-C handler")?;
            let opts = ServeOptions {
                connection: link.connection(&url)?,
                embedded,
                signer,
                log,
                status_period: std::time::Duration::from_secs_f64(status_period_s),
                prior_valid_s: valid_s,
            };
            Ok(video2track::serve::serve(opts, &stop)?)
        }
        Command::Upload { priors, bv, agent, tau, style, prior_id, valid_s, shot } => {
            let style = style.as_deref().map(video2track::link::parse_style).transpose()?;
            let id = prior_id.unwrap_or_else(|| (video2track::link::unix_ms() % 1_000_000_000).max(1));
            let up = video2track::link::prior_from_file(&priors, agent.as_deref(), (tau, style), valid_s, id)?;
            println!(
                "prior {id}: {} agents, {:.1} s, τ {} s, {:?}, {} drives {}",
                up.prior.agents.len(),
                up.prior.duration_s(),
                up.prior.tau_s,
                up.prior.style,
                bv,
                up.bv_agent
            );
            shot.send(&bv, CloudBody::Prior(up))
        }
        Command::Send { action, bv, tau, style, shot } => {
            let style = style.as_deref().map(video2track::link::parse_style).transpose()?;
            let cmd = video2track::link::command(&action, tau, style)?;
            let bv = if bv == "all" { ALL_BVS.to_owned() } else { bv };
            shot.send(&bv, CloudBody::Command(cmd))
        }
        Command::Export { command: ExportCommand::Xosc { input, out, map, vut_vehicle, bv_vehicle } } => {
            let args = video2track::export::XoscArgs {
                input: &input,
                out: &out,
                map: &map,
                vut_vehicle: &vut_vehicle,
                bv_vehicle: &bv_vehicle,
            };
            let done = video2track::export::export_xosc(&args)?;
            let s = &done.scenario;
            let bvs = s.agents.iter().filter(|a| a.role == v2t_model::grounded::AgentRole::Bv).count();
            println!(
                "{} `{}`: {} agents ({bvs} following trajectories), {:.1} s, τ {} s, {}; map {}",
                s.kind.describe(),
                s.name,
                s.agents.len(),
                s.end_time_s(),
                s.tau_s,
                s.style,
                done.map_path
            );
            println!("wrote {}", out.display());
            Ok(())
        }
        Command::Map { command: MapCommand::Inspect { map, json, svg, annotations } } => {
            let inspection = video2track::map::inspect(&map, annotations.as_deref())?;
            print!("{}", video2track::map::report(&map, &inspection));
            if let Some(path) = json {
                let doc = video2track::map::json(&map, &inspection);
                let text = serde_json::to_string_pretty(&doc).context("serializing the library")?;
                std::fs::write(&path, text + "\n").with_context(|| format!("writing {}", path.display()))?;
                println!("wrote {}", path.display());
            }
            if let Some(path) = svg {
                let text = v2t_map::svg::render(&inspection.map, &inspection.library);
                std::fs::write(&path, text).with_context(|| format!("writing {}", path.display()))?;
                println!("wrote {}", path.display());
            }
            Ok(())
        }
    }
}
