//! `video2track`: the operator's command line.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context as _;
use clap::{Parser, Subcommand};
use v2t_game::regulator::RegulatorParams;
use v2t_sim::vut::VutModel;
use video2track::experiment;
use video2track::files::{InputError, load_scenario, load_toml};
use video2track::sim::{report, run_reference};

/// Video2Track: real interaction videos → steerable adversarial tests on a closed track.
#[derive(Debug, Parser)]
#[command(name = "video2track", version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
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
        /// Scenario cards (default: the bundled left turn and cut-in).
        #[arg(long = "card")]
        cards: Vec<PathBuf>,
        /// Only these VUT models (default: all).
        #[arg(long, value_parser = clap::builder::PossibleValuesParser::new(VutModel::names()))]
        vut: Vec<String>,
        /// Only these targets τ, s (default: 1.5 2 3 4 5).
        #[arg(long)]
        tau: Vec<f64>,
        /// Regulator settings (TOML).
        #[arg(long, default_value = "config/regulator/default.toml")]
        regulator: PathBuf,
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
    /// OpenDRIVE maps and their topology library.
    Map {
        #[command(subcommand)]
        command: MapCommand,
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
enum Experiment {
    /// RQ3: does the achieved PET land on the target τ, in both styles, against every VUT model?
    Steerability,
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    match execute(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(err) => {
            eprintln!("error: {err:#}");
            let bad_input = err.chain().any(|e| {
                e.is::<InputError>() || e.is::<v2t_map::MapError>() || e.is::<video2track::ground::SemanticsFileError>()
            });
            if bad_input { ExitCode::from(2) } else { ExitCode::FAILURE }
        }
    }
}

fn execute(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Sim { card, seed, vut, json } => {
            let scenario = load_scenario(&card)?;
            let model = vut.map(|v| v.parse::<VutModel>()).transpose().map_err(anyhow::Error::msg)?;
            let outcome = run_reference(&scenario, model, seed)?;
            print!("{}", report(&outcome));
            if let Some(path) = json {
                let text = serde_json::to_string_pretty(&outcome).context("serializing the run")?;
                std::fs::write(&path, text + "\n").with_context(|| format!("writing {}", path.display()))?;
                println!("wrote {}", path.display());
            }
            Ok(())
        }
        Command::Experiment { which: Experiment::Steerability, json, repeats, cards, vut, tau, regulator } => {
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
