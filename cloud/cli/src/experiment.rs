//! `video2track experiment`: the paper's research questions in the simulated proving ground
//! ([`v2t_lab::steer`] for the regulator alone on the scenario cards, [`v2t_lab::methods`] for the
//! four methods on the paper's two scenarios).

use std::path::{Path, PathBuf};

use clap::ValueEnum as _;
use v2t_files::{load_toml, shipped};
use v2t_game::regulator::RegulatorParams;
use v2t_lab::methods::{self, Comparison, PaperScenario, Setup};
use v2t_lab::steer;
use v2t_sim::vut::VutModel;

use crate::{Usage, write_json};

/// Which experiment.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Experiment {
    /// RQ3: does the achieved PET land on the target τ, in both styles, against every VUT model?
    Steerability,
    /// RQ1: the four methods at rush, τ = 1.5 s: which gives the smallest PET without collision?
    Adversariality,
    /// RQ2: the four methods at the video's style and PET label: PET^min_track against the label.
    Fidelity,
    /// The four methods in both styles at the video's PET label: is the order the one asked for?
    Style,
}

/// `experiment`'s arguments.
#[derive(Debug, clap::Args)]
pub struct ExperimentArgs {
    /// Which experiment.
    #[arg(value_enum)]
    which: Experiment,
    /// Write the per-case results as JSON to this file.
    #[arg(long)]
    json: Option<PathBuf>,
    /// Seeded noisy runs per case (seeds 1 to N).
    #[arg(long, default_value_t = 20)]
    repeats: usize,
    /// steerability without --methods: scenario cards (default: the bundled left turn and cut-in).
    #[arg(long = "card")]
    cards: Vec<PathBuf>,
    /// Only these VUT models (default: all).
    #[arg(long, value_parser = clap::builder::PossibleValuesParser::new(VutModel::names()))]
    vut: Vec<String>,
    /// steerability: only these targets τ, s (default: 1.5 2 3 4 5; repeat the option for more).
    #[arg(long, value_parser = v2t_model::Target::parse_tau, allow_negative_numbers = true)]
    tau: Vec<f64>,
    /// Regulator settings (TOML).
    #[arg(long, default_value = shipped::REGULATOR)]
    regulator: PathBuf,
    /// steerability: compare the four methods on the paper's two scenarios (grounded for each τ
    /// and style) instead of the regulator alone on the scenario cards.
    #[arg(long)]
    methods: bool,
}

impl ExperimentArgs {
    /// An option given where this experiment does not read it (it would be dropped silently).
    fn unused_option(&self) -> Option<String> {
        let steerability = self.which == Experiment::Steerability;
        if !self.cards.is_empty() && (self.methods || !steerability) {
            return Some(
                "--card applies to `experiment steerability` (the regulator on scenario cards); the four \
                 methods run on the paper's two scenarios"
                    .to_owned(),
            );
        }
        if !self.tau.is_empty() && !steerability {
            let name = self.which.to_possible_value().map_or_else(String::new, |v| v.get_name().to_owned());
            return Some(format!(
                "--tau applies to `experiment steerability` only; `experiment {name}` sets its own targets"
            ));
        }
        if self.repeats == 0 {
            return Some("--repeats must be at least 1".to_owned());
        }
        None
    }
}

/// Runs the experiment and prints its tables.
pub fn run(a: ExperimentArgs) -> anyhow::Result<()> {
    if let Some(msg) = a.unused_option() {
        return Err(Usage(msg).into());
    }
    if a.methods || a.which != Experiment::Steerability { four_methods(a) } else { regulator_on_cards(a) }
}

/// The four methods on the paper's two scenarios.
fn four_methods(a: ExperimentArgs) -> anyhow::Result<()> {
    let models = crate::vut_models(&a.vut)?;
    let inspection = v2t_map::inspect(Path::new(shipped::MAP), None)?;
    let model = v2t_diffusion::weights::load(Path::new(shipped::WEIGHTS))?;
    let setup = Setup {
        inspection: &inspection,
        model: &model,
        regulator: load_toml(&a.regulator)?,
        sim: load_toml(Path::new(shipped::SIM))?,
        vut_vehicle: load_toml(Path::new(shipped::VUT_VEHICLE))?,
        bv_vehicle: load_toml(Path::new(shipped::BV_VEHICLE))?,
    };
    let mut scenarios = Vec::new();
    for sc in v2t_lab::demo::SCENARIOS {
        scenarios.push(PaperScenario { name: sc.name.to_owned(), semantics: sc.replayed_semantics()? });
    }
    let taus = if a.tau.is_empty() { steer::STEER_TAUS_S.to_vec() } else { a.tau };
    let comparison = match a.which {
        Experiment::Adversariality => Comparison::Adversariality,
        Experiment::Fidelity => Comparison::Fidelity,
        Experiment::Style => Comparison::Style,
        Experiment::Steerability => Comparison::Steerability(steer::both_styles(&taus)),
    };
    let cases = methods::run_all(&setup, &scenarios, &comparison, &models, a.repeats)?;
    let summary = methods::summarize(&cases);
    // The fidelity error is against the video's PET label: only where τ is that label.
    let labels: Vec<(String, f64)> = match a.which {
        Experiment::Adversariality | Experiment::Steerability => Vec::new(),
        _ => scenarios.iter().map(|r| (r.name.clone(), r.semantics.pet_label_s)).collect(),
    };
    println!(
        "simulated proving ground; VUT driver models written by this project; the paper's two scenarios, \
         semantics replayed from hand-written cassettes (no model's answer); Diffusion-only and Video2Track on the {}; seeds 1–{}",
        v2t_lab::demo::prior_kind(Path::new(shipped::WEIGHTS), &model),
        a.repeats
    );
    print!("{}", methods::markdown(&summary, &labels));
    let steering = methods::steering_errors(&summary);
    if a.which == Experiment::Steerability {
        print!("{}", methods::steering_markdown(&steering));
    }
    if let Some(path) = a.json {
        write_json(&path, &serde_json::json!({ "cases": cases, "summary": summary, "steering": steering }))?;
    }
    Ok(())
}

/// The regulator alone on the scenario cards.
fn regulator_on_cards(a: ExperimentArgs) -> anyhow::Result<()> {
    let settings: RegulatorParams = load_toml(&a.regulator)?;
    let cards = if a.cards.is_empty() { shipped::CARDS.iter().map(PathBuf::from).collect() } else { a.cards };
    let scenarios = cards.iter().map(|c| v2t_sim::files::load_scenario(c)).collect::<Result<Vec<_>, _>>()?;
    let models = crate::vut_models(&a.vut)?;
    let taus = if a.tau.is_empty() { steer::STEER_TAUS_S.to_vec() } else { a.tau };
    let report = steer::steerability(&settings, &scenarios, &steer::both_styles(&taus), &models, a.repeats);
    println!(
        "simulated proving ground; VUT driver models written by this project; scenario cards \
         written by this project; seeds 1–{}",
        a.repeats
    );
    print!("{}", steer::steer_markdown(&report));
    if let Some(path) = a.json {
        write_json(&path, &report)?;
    }
    Ok(())
}
