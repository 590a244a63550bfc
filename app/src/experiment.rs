//! `video2track experiment`: the paper's research questions in the simulated proving ground
//! ([`v2t_lab::steer`] for the regulator alone on the scenario cards, [`v2t_lab::methods`] for the
//! four methods on the paper's scenarios).

use std::path::{Path, PathBuf};

use anyhow::Context as _;
use v2t_files::{load_toml, out, outln, shipped};
use v2t_game::regulator::RegulatorParams;
use v2t_lab::methods::{self, Comparison, PaperScenario, Setup};
use v2t_lab::{steer, tradeoff};
use v2t_sim::vut::VutModel;

use crate::{Usage, write_json};

/// `experiment`'s arguments: which experiment, each with the options it reads (an option another
/// experiment reads is refused by the parser, never dropped in silence).
#[derive(Debug, clap::Args)]
pub struct ExperimentArgs {
    #[command(subcommand)]
    which: Experiment,
}

/// Which experiment.
#[derive(Debug, clap::Subcommand)]
enum Experiment {
    /// RQ3: does the achieved PET land on the target τ, in both styles, against every VUT model?
    /// The regulator alone on the scenario cards, or (--methods) the four methods on the paper's
    /// scenarios.
    Steerability(SteerabilityArgs),
    /// RQ1: the four methods at rush, τ = 1.5 s: which gives the smallest PET without collision?
    Adversariality(MethodsArgs),
    /// RQ2: the four methods at the video's style and PET label: PET^min_track against the label.
    Fidelity(MethodsArgs),
    /// The four methods in both styles at the video's PET label: is the order the one asked for?
    Style(MethodsArgs),
    /// The regulator's realism weight w_real swept (0, 0.1, 0.3, 1, 3, 10): steering error per VUT
    /// model against the BV's realism, for TroubleMaker-like and Video2Track.
    Tradeoff(TradeoffArgs),
    /// Test campaigns on the scenario cards: each test repeated --runs times against one VUT, the
    /// regulator learning the VUT's reaction from run to run; error per run index and per VUT.
    Campaign(CampaignArgs),
    /// The regulator onboard against the same regulator in the cloud across a simulated network
    /// (one-way delay 0–300 ms, loss 0 and 5 %, and the presets under config/network): steering
    /// error, collisions, order, minimum distance and fallbacks per VUT model.
    Latency(LatencyArgs),
}

impl Experiment {
    /// The experiment's name on the command line.
    fn name(&self) -> &'static str {
        match self {
            Self::Steerability(_) => "steerability",
            Self::Adversariality(_) => "adversariality",
            Self::Fidelity(_) => "fidelity",
            Self::Style(_) => "style",
            Self::Tradeoff(_) => "tradeoff",
            Self::Campaign(_) => "campaign",
            Self::Latency(_) => "latency",
        }
    }
}

/// Where the results go.
#[derive(Debug, clap::Args)]
struct Output {
    /// Write the per-case results as JSON to this file.
    #[arg(long)]
    json: Option<PathBuf>,
    /// Write the experiment's HTML report here: the tables, every run's PET per case and VUT, the
    /// steering error against τ, the methods side by side, and each case's runs.
    #[arg(long)]
    report: Option<PathBuf>,
}

/// Which seeds run.
#[derive(Debug, clap::Args)]
struct SeedArgs {
    /// Seeded noisy runs per case, seeds --first-seed to --first-seed + N − 1 (default 20; tradeoff
    /// and latency: 5). campaign: the number of campaigns per case (default 15), each with its own
    /// seed.
    #[arg(long, value_parser = clap::value_parser!(u64).range(1..=1_000_000))]
    repeats: Option<u64>,
    /// The first seed (default 1; tradeoff, latency and campaign: 6). Constants are chosen on seeds
    /// 1–5: report seeds 6 onward (`--first-seed 6 --repeats 15`) to keep the reported runs out of
    /// the tuning.
    #[arg(long, value_parser = clap::value_parser!(u64).range(1..=u64::MAX / 2))]
    first_seed: Option<u64>,
}

/// The regulator's settings and the human driving the realism is measured against.
#[derive(Debug, clap::Args)]
struct Shared {
    /// Regulator settings (TOML).
    #[arg(long, default_value = shipped::REGULATOR)]
    regulator: PathBuf,
    /// Recorded human driving per manoeuvre class, the reference of the realism columns.
    #[arg(long, default_value = shipped::HUMAN_REFERENCE)]
    human_reference: PathBuf,
    /// Only these builtin VUT models (default: all; repeat the option).
    #[arg(long, value_parser = clap::builder::PossibleValuesParser::new(VutModel::names()))]
    vut: Vec<String>,
}

/// What every experiment reads: the regulator and VUTs, the seeds, where the results go.
#[derive(Debug, clap::Args)]
struct RunArgs {
    #[command(flatten)]
    shared: Shared,
    #[command(flatten)]
    seeds: SeedArgs,
    #[command(flatten)]
    out: Output,
}

/// The paper's scenarios to run (the four methods, tradeoff, latency).
#[derive(Debug, clap::Args)]
struct PaperArgs {
    /// Only these of the paper's scenarios (cut_in, left_turn, left_turn_vut; default: all; repeat
    /// the option).
    #[arg(long = "scenario", value_parser = clap::builder::PossibleValuesParser::new(v2t_lab::demo::SCENARIOS.map(|s| s.name)))]
    scenarios: Vec<String>,
}

/// The regulator on the scenario cards (steerability, campaign).
#[derive(Debug, clap::Args)]
struct CardArgs {
    /// Scenario cards (default: the bundled cards — the left turn with the BV turning, the left
    /// turn with the VUT turning, the cut-in; repeat the option).
    #[arg(long = "card")]
    cards: Vec<PathBuf>,
    #[command(flatten)]
    world: crate::world::WorldArgs,
    /// Skip the open-loop grid that measures which targets any BV can reach against each VUT (250
    /// runs per scenario and VUT, on the first seed).
    #[arg(long)]
    no_reach: bool,
}

/// The targets τ of an experiment that takes them.
#[derive(Debug, clap::Args)]
struct TauArgs {
    /// Only these targets τ, s (default: 1.5 2 3 4 5; tradeoff: its own; repeat the option).
    #[arg(long, value_parser = v2t_model::Target::parse_tau, allow_negative_numbers = true)]
    tau: Vec<f64>,
}

/// `experiment steerability`.
#[derive(Debug, clap::Args)]
struct SteerabilityArgs {
    /// Compare the four methods on the paper's scenarios (grounded for each τ and style) instead of
    /// the regulator alone on the scenario cards.
    #[arg(long, conflicts_with_all = ["cards", "no_reach", "world", "sumo_drivers"])]
    methods: bool,
    /// With --methods: only these of the paper's scenarios (cut_in, left_turn, left_turn_vut;
    /// default: all; repeat the option).
    #[arg(long = "scenario", requires = "methods", value_parser = clap::builder::PossibleValuesParser::new(v2t_lab::demo::SCENARIOS.map(|s| s.name)))]
    scenarios: Vec<String>,
    /// Prepare every regulated run by a free drive: the VUT drives the test once alone (every BV
    /// parked where it starts, another seed), and the regulator knows how it drove its route, as
    /// after a first run of a campaign.
    #[arg(long, conflicts_with = "methods")]
    free_drive: bool,
    #[command(flatten)]
    cards: CardArgs,
    #[command(flatten)]
    tau: TauArgs,
    #[command(flatten)]
    run: RunArgs,
}

/// `experiment adversariality|fidelity|style`.
#[derive(Debug, clap::Args)]
struct MethodsArgs {
    #[command(flatten)]
    paper: PaperArgs,
    #[command(flatten)]
    run: RunArgs,
}

/// `experiment tradeoff`.
#[derive(Debug, clap::Args)]
struct TradeoffArgs {
    /// Only these realism weights (default: 0 0.1 0.3 1 3 10; repeat the option).
    #[arg(long = "w-real", allow_negative_numbers = true, value_parser = parse_w_real)]
    w_real: Vec<f64>,
    /// Write the fronts as SVG plots into this directory (one per scenario whose BV has a human
    /// reference).
    #[arg(long)]
    svg_dir: Option<PathBuf>,
    #[command(flatten)]
    paper: PaperArgs,
    #[command(flatten)]
    tau: TauArgs,
    #[command(flatten)]
    run: RunArgs,
}

/// `experiment campaign`.
#[derive(Debug, clap::Args)]
struct CampaignArgs {
    /// Runs per campaign (default 10).
    #[arg(long, value_parser = clap::value_parser!(u64).range(1..=v2t_lab::campaign::MAX_RUNS as u64))]
    runs: Option<u64>,
    /// Write what each campaign learned, one memory file per VUT and campaign
    /// (`DIR/<vut>/campaign-<seed>.json`, the file `video2track sim --campaign` reads).
    #[arg(long)]
    memory_dir: Option<PathBuf>,
    #[command(flatten)]
    cards: CardArgs,
    #[command(flatten)]
    tau: TauArgs,
    #[command(flatten)]
    run: RunArgs,
}

/// `experiment latency`: the regulator at its own targets (rush and yield, τ 2, 3, 4 s).
#[derive(Debug, clap::Args)]
struct LatencyArgs {
    /// Network settings (TOML, as in config/network) besides the sweep of constant delays
    /// (default: the shipped presets — 5G SA, LTE, a congested cell; repeat the option).
    #[arg(long = "network")]
    networks: Vec<PathBuf>,
    /// Write the plot of the steering error against the delay (SVG) to this file.
    #[arg(long)]
    svg: Option<PathBuf>,
    #[command(flatten)]
    paper: PaperArgs,
    #[command(flatten)]
    run: RunArgs,
}

/// A realism weight in [0, 1e6].
fn parse_w_real(s: &str) -> Result<f64, String> {
    let w: f64 = s.trim().parse().map_err(|_| format!("`{s}` is not a number"))?;
    if w.is_finite() && (0.0..=1e6).contains(&w) { Ok(w) } else { Err(format!("must lie in [0, 1e6], got {s}")) }
}

impl CardArgs {
    /// `--vut` names builtin models: with `--world sumo` the drivers are `--sumo-driver`.
    fn check(&self, shared: &Shared) -> Result<(), Usage> {
        if self.world.world == "sumo" && !shared.vut.is_empty() {
            return Err(Usage("--vut names builtin driver models; with --world sumo use --sumo-driver".to_owned()));
        }
        Ok(())
    }
}

/// Writes the experiment's report when `--report` asks for one.
fn write_report(out: &Output, name: &str, provenance: &[String], body: &str) -> anyhow::Result<()> {
    let Some(path) = &out.report else { return Ok(()) };
    let mut page = v2t_lab::report::Page::new(&format!("Video2Track experiment: {name}"));
    page.provenance = provenance.to_vec();
    page.provenance.push(format!("Command: video2track {}", std::env::args().skip(1).collect::<Vec<_>>().join(" ")));
    page.body = body.to_owned();
    std::fs::write(path, page.html()).with_context(|| format!("writing {}", path.display()))?;
    outln!("wrote {}", path.display())?;
    Ok(())
}

/// Runs the experiment and prints its tables.
pub fn run(a: ExperimentArgs) -> anyhow::Result<()> {
    let name = a.which.name();
    match a.which {
        Experiment::Tradeoff(t) => tradeoff(&t),
        Experiment::Campaign(c) => campaign(&c),
        Experiment::Latency(l) => latency(&l),
        Experiment::Steerability(s) if !s.methods => regulator_on_cards(&s),
        Experiment::Steerability(s) => {
            let taus = if s.tau.tau.is_empty() { steer::STEER_TAUS_S.to_vec() } else { s.tau.tau.clone() };
            let methods = MethodsArgs { paper: PaperArgs { scenarios: s.scenarios }, run: s.run };
            four_methods(name, &methods, Comparison::Steerability(steer::both_styles(&taus)))
        }
        Experiment::Adversariality(m) => four_methods(name, &m, Comparison::Adversariality),
        Experiment::Fidelity(m) => four_methods(name, &m, Comparison::Fidelity),
        Experiment::Style(m) => four_methods(name, &m, Comparison::Style),
    }
}

impl SeedArgs {
    /// The seeds of the runs: `repeats` from `first` unless the options say otherwise (tradeoff
    /// and latency 6–10, campaigns 6–20: out of the tuning seeds 1–5; the others 1–20).
    fn range(&self, first: u64, repeats: u64) -> std::ops::RangeInclusive<u64> {
        let first = self.first_seed.unwrap_or(first);
        first..=first + self.repeats.unwrap_or(repeats) - 1
    }
}

/// The paper's scenarios (the cut-in, the left turn with the BV turning and with the VUT turning),
/// their semantics replayed from the shipped hand-written cassettes.
fn paper_scenarios(only: &[String]) -> anyhow::Result<Vec<PaperScenario>> {
    let mut scenarios = Vec::new();
    for sc in v2t_lab::demo::SCENARIOS.iter().filter(|s| only.is_empty() || only.iter().any(|n| n == s.name)) {
        scenarios.push(PaperScenario { name: sc.name.to_owned(), semantics: sc.replayed_semantics()? });
    }
    Ok(scenarios)
}

/// What the four-method figures depend on, said once above every table.
fn provenance(
    model: &v2t_diffusion::weights::Model,
    human: &v2t_model::realism::HumanReference,
    seeds: &std::ops::RangeInclusive<u64>,
) -> String {
    format!(
        "simulated proving ground; VUT driver models written by this project; the paper's scenarios, \
         semantics replayed from hand-written cassettes (no model's answer); Diffusion-only and Video2Track on the {}; \
         BV realism against {}; {}",
        v2t_lab::demo::prior_kind(Path::new(shipped::WEIGHTS), model),
        human.provenance.split("; made by").next().unwrap_or_default(),
        seed_split(seeds)
    )
}

/// The seeds, and whether the figures over them are in-sample: the regulator's constants (and the
/// campaign memory's) were chosen on seeds 1–5 of these cards, scenarios and VUT models.
fn seed_split(seeds: &std::ops::RangeInclusive<u64>) -> String {
    let (a, b) = (*seeds.start(), *seeds.end());
    if b <= 5 {
        format!("seeds {a}–{b}: tuning seeds, figures in-sample")
    } else if a <= 5 {
        format!(
            "seeds {a}–{b}: seeds {a}–5 are tuning seeds, figures partly in-sample (report seeds 6 on: --first-seed 6)"
        )
    } else {
        format!("seeds {a}–{b}: held out from the tuning seeds 1–5")
    }
}

/// What the four-method experiments load from the shipped files.
struct World {
    inspection: v2t_map::Inspection,
    model: v2t_diffusion::weights::Model,
    human: v2t_model::realism::HumanReference,
    regulator: RegulatorParams,
    sim: v2t_sim::config::SimSettings,
    vut_vehicle: v2t_model::vehicle::VehicleConfig,
    bv_vehicle: v2t_model::vehicle::VehicleConfig,
    baseline_network: v2t_sim::network::NetworkSettings,
}

impl World {
    fn load(a: &Shared) -> anyhow::Result<Self> {
        Ok(Self {
            inspection: v2t_map::inspect(Path::new(shipped::MAP), None)?,
            model: v2t_diffusion::weights::load(Path::new(shipped::WEIGHTS))?,
            human: v2t_files::read_human_reference(&a.human_reference)?,
            regulator: load_toml(&a.regulator)?,
            sim: load_toml(Path::new(shipped::SIM))?,
            vut_vehicle: load_toml(Path::new(shipped::VUT_VEHICLE))?,
            bv_vehicle: load_toml(Path::new(shipped::BV_VEHICLE))?,
            baseline_network: load_toml(Path::new(shipped::BASELINE_NETWORK))?,
        })
    }

    fn setup(&self) -> Setup<'_> {
        Setup {
            inspection: &self.inspection,
            model: &self.model,
            regulator: self.regulator,
            sim: self.sim.clone(),
            vut_vehicle: self.vut_vehicle.clone(),
            bv_vehicle: self.bv_vehicle.clone(),
            human: Some(&self.human),
            baseline_network: Some(self.baseline_network.clone()),
        }
    }
}

/// The sweep of the realism weight.
fn tradeoff(a: &TradeoffArgs) -> anyhow::Result<()> {
    let models = crate::vut_models(&a.run.shared.vut)?;
    let world = World::load(&a.run.shared)?;
    let (model, human, setup) = (&world.model, &world.human, world.setup());
    let scenarios = paper_scenarios(&a.paper.scenarios)?;
    let taus = if a.tau.tau.is_empty() { tradeoff::TAUS_S.to_vec() } else { a.tau.tau.clone() };
    let weights = if a.w_real.is_empty() { tradeoff::WEIGHTS.to_vec() } else { a.w_real.clone() };
    let seeds = a.run.seeds.range(6, 5);
    let provenance = provenance(model, human, &seeds);
    let report = tradeoff::sweep(&setup, &scenarios, &taus, &weights, &models, seeds, provenance)?;
    outln!("{}", report.provenance)?;
    let md = tradeoff::markdown(&report);
    out!("{md}")?;
    if a.run.out.report.is_some() {
        let mut body = v2t_lab::report::experiment::body(&md, &report);
        for rec in &scenarios {
            if let Some(figure) = tradeoff::figure(&report, &rec.name) {
                body.push_str(&format!(
                    "<h2>Trade-off front, {}</h2>{}",
                    v2t_lab::report::esc(&rec.name),
                    figure.svg()
                ));
            }
        }
        write_report(&a.run.out, "tradeoff", std::slice::from_ref(&report.provenance), &body)?;
    }
    if let Some(dir) = &a.svg_dir {
        std::fs::create_dir_all(dir).map_err(|e| anyhow::anyhow!("{}: {e}", dir.display()))?;
        for rec in &scenarios {
            if let Some(svg) = tradeoff::svg(&report, &rec.name) {
                let path =
                    dir.join(format!("tradeoff_{}.svg", rec.name.replace(|c: char| !c.is_ascii_alphanumeric(), "_")));
                std::fs::write(&path, svg).map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
                outln!("wrote {}", path.display())?;
            }
        }
    }
    if let Some(path) = &a.run.out.json {
        write_json(path, &report)?;
    }
    Ok(())
}

/// The four methods on the paper's scenarios.
fn four_methods(name: &str, a: &MethodsArgs, comparison: Comparison) -> anyhow::Result<()> {
    let models = crate::vut_models(&a.run.shared.vut)?;
    let world = World::load(&a.run.shared)?;
    let (model, human, setup) = (&world.model, &world.human, world.setup());
    let scenarios = paper_scenarios(&a.paper.scenarios)?;
    let seeds = a.run.seeds.range(1, 20);
    let cases = methods::run_all(&setup, &scenarios, &comparison, &models, seeds.clone())?;
    let summary = methods::summarize(&cases);
    // The fidelity error is against the video's PET label: only where τ is that label.
    let labels: Vec<(String, f64)> = match comparison {
        Comparison::Adversariality | Comparison::Steerability(_) => Vec::new(),
        _ => scenarios.iter().map(|r| (r.name.clone(), r.semantics.pet_label_s)).collect(),
    };
    outln!(
        "{}; TroubleMaker-like regulates in the cloud across the simulated \"{}\" network ({})\n",
        provenance(model, human, &seeds),
        world.baseline_network.name,
        world.baseline_network.source
    )?;
    let mut md = methods::markdown(&summary, &labels);
    let steering = methods::steering_errors(&cases);
    if matches!(comparison, Comparison::Steerability(_)) {
        md.push_str(&methods::steering_markdown(&steering));
    }
    out!("{md}")?;
    let provenance_line = format!(
        "{}; TroubleMaker-like regulates in the cloud across the simulated \"{}\" network ({})",
        provenance(model, human, &seeds),
        world.baseline_network.name,
        world.baseline_network.source
    );
    write_report(&a.run.out, name, &[provenance_line], &v2t_lab::report::experiment::body(&md, &cases))?;
    if let Some(path) = &a.run.out.json {
        write_json(path, &serde_json::json!({ "cases": cases, "summary": summary, "steering": steering }))?;
    }
    Ok(())
}

/// The regulator onboard and in the cloud across the networks.
fn latency(a: &LatencyArgs) -> anyhow::Result<()> {
    let models = crate::vut_models(&a.run.shared.vut)?;
    let world = World::load(&a.run.shared)?;
    let (model, human, setup) = (&world.model, &world.human, world.setup());
    let scenarios = paper_scenarios(&a.paper.scenarios)?;
    let files: Vec<PathBuf> =
        if a.networks.is_empty() { shipped::NETWORKS.iter().map(PathBuf::from).collect() } else { a.networks.clone() };
    let mut networks = v2t_lab::latency::sweep();
    for f in &files {
        networks.push(load_toml(f)?);
    }
    let seeds = a.run.seeds.range(6, 5);
    let cases = v2t_lab::latency::run_all(&setup, &scenarios, &networks, &models, seeds.clone())?;
    let rows = v2t_lab::latency::summarize(&cases, &networks);
    outln!("{}; networks simulated (presets named below)\n", provenance(model, human, &seeds))?;
    let md = v2t_lab::latency::markdown(&rows, &cases, &networks);
    out!("{md}")?;
    let mut body = v2t_lab::report::experiment::body(&md, &cases);
    body.push_str(&format!(
        "<h2>Steering error against the delay</h2>{}",
        v2t_lab::latency::figure(&rows, &networks, &seeds).svg()
    ));
    write_report(&a.run.out, "latency", &[format!("{}; networks simulated", provenance(model, human, &seeds))], &body)?;
    if let Some(path) = &a.svg {
        std::fs::write(path, v2t_lab::latency::svg(&rows, &networks, &seeds))
            .with_context(|| format!("writing {}", path.display()))?;
        outln!("\nwrote {}", path.display())?;
    }
    if let Some(path) = &a.run.out.json {
        write_json(path, &serde_json::json!({ "networks": networks, "cases": cases, "summary": rows }))?;
    }
    Ok(())
}

/// What the experiments of the regulator on the scenario cards load: its settings, the cards, the
/// targets in both styles, and the SUMO world when asked.
struct Cards {
    settings: RegulatorParams,
    scenarios: Vec<v2t_sim::scenario::Scenario>,
    targets: Vec<v2t_model::Target>,
    sumo: Option<crate::world::Sumo>,
}

impl Cards {
    fn load(a: &CardArgs, tau: &TauArgs, shared: &Shared) -> anyhow::Result<Self> {
        a.check(shared)?;
        let settings: RegulatorParams = load_toml(&shared.regulator)?;
        let cards =
            if a.cards.is_empty() { shipped::CARDS.iter().map(PathBuf::from).collect() } else { a.cards.clone() };
        let scenarios = cards.iter().map(|c| v2t_sim::files::load_scenario(c)).collect::<Result<Vec<_>, _>>()?;
        let taus = if tau.tau.is_empty() { steer::STEER_TAUS_S.to_vec() } else { tau.tau.clone() };
        Ok(Self { settings, scenarios, targets: steer::both_styles(&taus), sumo: a.world.sumo(true)? })
    }

    /// The VUTs: every SUMO driver asked for, or the builtin models named (all by default).
    fn vuts(&self, shared: &Shared) -> anyhow::Result<Vec<v2t_lab::vut::Vut<'_>>> {
        Ok(match &self.sumo {
            Some(s) => s.drivers.iter().map(|driver| v2t_lab::vut::Vut::Sumo { world: &s.world, driver }).collect(),
            None => crate::vut_models(&shared.vut)?.into_iter().map(v2t_lab::vut::Vut::Builtin).collect(),
        })
    }

    /// The first line of the output: where the figures come from, the seeds, `tuned` what was
    /// chosen in the builtin world.
    fn provenance(&self, a: &CardArgs, seeds: &std::ops::RangeInclusive<u64>, what: &str) -> anyhow::Result<String> {
        let world = a.world.world()?;
        let sumo_version = self.sumo.as_ref().map_or_else(String::new, |s| format!(" ({})", s.world.version()));
        let tuned = if world == v2t_lab::vut::World::Sumo {
            format!("; {what} as chosen in the builtin world (nothing tuned on SUMO)")
        } else {
            String::new()
        };
        Ok(format!(
            "{}{sumo_version}; scenario cards written by this project; {}{tuned}",
            world.provenance(),
            seed_split(seeds)
        ))
    }
}

/// Test campaigns on the scenario cards.
fn campaign(a: &CampaignArgs) -> anyhow::Result<()> {
    let cards = Cards::load(&a.cards, &a.tau, &a.run.shared)?;
    let vuts = cards.vuts(&a.run.shared)?;
    let seeds = a.run.seeds.range(6, 15);
    let runs = a.runs.map_or(v2t_lab::campaign::DEFAULT_RUNS, |r| r as usize);
    let reach_seed = (!a.cards.no_reach).then_some(*seeds.start());
    let (report, memories) = v2t_lab::campaign::campaigns(
        &cards.settings,
        &cards.scenarios,
        &cards.targets,
        &vuts,
        seeds.clone(),
        runs,
        reach_seed,
    );
    let provenance_line = cards
        .provenance(&a.cards, &seeds, "the regulator's and the campaign memory's constants")?
        .replace("; seeds", "; campaigns: seeds");
    outln!("{provenance_line}")?;
    let md = v2t_lab::campaign::markdown(&report);
    out!("{md}")?;
    if a.run.out.report.is_some() {
        let body = v2t_lab::report::experiment::body(&md, &report);
        write_report(&a.run.out, "campaign", &[provenance_line, format!("{runs} runs per campaign")], &body)?;
    }
    if let Some(dir) = &a.memory_dir {
        for (vut, seed, memory) in &memories {
            let sub = dir.join(vut);
            std::fs::create_dir_all(&sub).with_context(|| format!("creating {}", sub.display()))?;
            let path = sub.join(format!("campaign-{seed}.json"));
            let text = v2t_lab::campaign::memory_json(memory)?;
            std::fs::write(&path, text).with_context(|| format!("writing {}", path.display()))?;
        }
        outln!("\nwrote {} memory files under {}", memories.len(), dir.display())?;
    }
    if let Some(path) = &a.run.out.json {
        write_json(path, &report)?;
    }
    Ok(())
}

/// The regulator alone on the scenario cards.
fn regulator_on_cards(a: &SteerabilityArgs) -> anyhow::Result<()> {
    let cards = Cards::load(&a.cards, &a.tau, &a.run.shared)?;
    let vuts = cards.vuts(&a.run.shared)?;
    let seeds = a.run.seeds.range(1, 20);
    let reach_seed = (!a.cards.no_reach).then_some(*seeds.start());
    let report = steer::steerability(
        &cards.settings,
        &cards.scenarios,
        &cards.targets,
        &vuts,
        seeds.clone(),
        reach_seed,
        a.free_drive,
    );
    let mut provenance_line = cards.provenance(&a.cards, &seeds, "the regulator's settings")?;
    if a.free_drive {
        provenance_line.push_str("; every run prepared by a free drive of the VUT (BVs parked)");
    }
    outln!("{provenance_line}")?;
    let md = steer::steer_markdown(&report);
    out!("{md}")?;
    write_report(&a.run.out, "steerability", &[provenance_line], &v2t_lab::report::experiment::body(&md, &report))?;
    if let Some(path) = &a.run.out.json {
        write_json(path, &report)?;
    }
    Ok(())
}
