//! `v2t-sim-ecu`: the simulated drive-by-wire ECU. It plays the BV's actuators and sensors in the
//! simulated proving ground behind the same CAN frames a real vehicle takes, so that the onboard
//! runtime (`v2t-edge launch`) runs unchanged without a vehicle.
//!
//! ```sh
//! v2t-edge launch --config config/edge/bv1.toml &
//! v2t-sim-ecu --config config/edge/bv1.toml --scenario config/scenarios/left_turn_basic.toml
//! v2t-sim-ecu --config config/edge/bv1.toml --prior prior.json --mcap run.mcap --out run.json
//! ```

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context as _;
use clap::Parser;
use iceoryx2::prelude::ipc;
use v2t_edge::config::{Overrides, load_for_process};
use v2t_files::{out, outln};
use v2t_lab::ecu::{EcuError, EcuOptions, EcuSource};
use v2t_model::Style;
use v2t_sim::vut::VutModel;

/// Video2Track simulated drive-by-wire ECU: the simulated proving ground behind the BV's CAN frames.
#[derive(Debug, Parser)]
#[command(name = "v2t-sim-ecu", version)]
struct Cli {
    /// The BV's runtime configuration (the same file `v2t-edge launch` runs).
    #[arg(long, default_value = v2t_files::shipped::EDGE)]
    config: PathBuf,
    /// Override the service namespace of the configuration.
    #[arg(long)]
    namespace: Option<String>,
    /// Use this SocketCAN interface (`can0`, `vcan0`) instead of the configured CAN transport.
    #[arg(long)]
    can_iface: Option<String>,
    /// A scenario card (its prior is published as the stand-in for a cloud upload).
    #[arg(long, required_unless_present_any = ["from_uplink", "prior"], conflicts_with_all = ["from_uplink", "prior"])]
    scenario: Option<PathBuf>,
    /// A trajectory prior (JSON) instead of a card: accepted like an upload, published, and the
    /// world built from it.
    #[arg(long, conflicts_with = "from_uplink")]
    prior: Option<PathBuf>,
    /// The prior's BV agent this BV drives (default: the first BV).
    #[arg(long, requires = "prior")]
    agent: Option<String>,
    /// Build the world from the prior the uplink node accepts from the cloud.
    #[arg(long)]
    from_uplink: bool,
    /// Simulation settings for --prior and --from-uplink.
    #[arg(long, default_value = v2t_files::shipped::SIM)]
    sim_settings: PathBuf,
    /// Longest wait for the uplinked prior, s.
    #[arg(long, default_value_t = 60.0)]
    prior_wait_s: f64,
    /// VUT driver model (default: the card's; IDM normal for a prior).
    #[arg(long)]
    vut: Option<VutModel>,
    /// Which world drives the VUT: builtin (this project's driver models) or sumo (Eclipse SUMO on
    /// the network converted from --map; needs scripts/install-sumo).
    #[arg(long, default_value = "builtin", value_parser = clap::builder::PossibleValuesParser::new(["builtin", "sumo"]))]
    world: String,
    /// With --world sumo: the SUMO driver (default: config/vut/sumo/krauss.toml).
    #[arg(long)]
    sumo_driver: Option<PathBuf>,
    /// With --world sumo: the map SUMO drives on (OpenDRIVE).
    #[arg(long, default_value = v2t_files::shipped::MAP)]
    map: PathBuf,
    /// Noise seed.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Record the run as MCAP here.
    #[arg(long)]
    mcap: Option<PathBuf>,
    /// Write the measured run (JSON) here.
    #[arg(long)]
    out: Option<PathBuf>,
    /// Longest wait for the gateway to engage, s.
    #[arg(long, default_value_t = 10.0)]
    engage_timeout_s: f64,
    /// Target PET instead of the card's, s.
    #[arg(long, value_parser = v2t_model::Target::parse_tau, allow_negative_numbers = true)]
    tau: Option<f64>,
    /// Style instead of the card's (rush or yield).
    #[arg(long)]
    style: Option<Style>,
    /// Recorded human driving per manoeuvre class, the reference of the run's realism (default:
    /// the shipped config/realism/human_reference.json when run from the repository).
    #[arg(long)]
    human_reference: Option<PathBuf>,
    /// Write the run's HTML report here, drawn on the map of --map (the bundled cards run on the
    /// proving ground's lanes, as do priors grounded on it).
    #[arg(long)]
    report: Option<PathBuf>,
}

fn run(cli: Cli) -> anyhow::Result<()> {
    let human = v2t_files::human_reference_or_shipped(cli.human_reference.as_deref()).map_err(EcuError::from)?;
    let overrides = Overrides { namespace: cli.namespace.as_deref(), can_iface: cli.can_iface.as_deref() };
    let cfg = load_for_process(&cli.config, overrides).map_err(EcuError::from)?;
    // The map a report draws a prior's run on, read before anything starts.
    let report_map = cli.map.clone();
    let map = match &cli.report {
        Some(_) => Some(v2t_map::Map::load(&report_map).map_err(|e| {
            // The origin names the file; the map's error names it too.
            let message = match e {
                v2t_map::MapError::File { error, .. } => error.to_string(),
                e => e.to_string(),
            };
            EcuError::Input(v2t_files::InputError::Config(v2t_files::ConfigError::Parse {
                origin: report_map.display().to_string(),
                message,
            }))
        })?),
        _ => None,
    };
    let source = match (cli.scenario, cli.prior) {
        (Some(card), _) => EcuSource::Card(card),
        (None, Some(path)) => EcuSource::Prior { path, agent: cli.agent, sim_settings: cli.sim_settings },
        (None, None) => EcuSource::Uplink { sim_settings: cli.sim_settings, wait_s: cli.prior_wait_s },
    };
    let sumo = match (cli.world.as_str(), cli.sumo_driver) {
        ("sumo", driver) => {
            if cli.vut.is_some() {
                return Err(EcuError::Input(v2t_files::InputError::Config(v2t_files::ConfigError::Parse {
                    origin: "--vut".to_owned(),
                    message: "names a builtin driver model; with --world sumo use --sumo-driver".to_owned(),
                }))
                .into());
            }
            let path = driver.unwrap_or_else(|| PathBuf::from(v2t_lab::sumo::DEFAULT_DRIVER));
            Some((cli.map, v2t_lab::sumo::SumoDriver::load(&path).map_err(EcuError::from)?))
        }
        (_, Some(_)) => {
            return Err(EcuError::Input(v2t_files::InputError::Config(v2t_files::ConfigError::Parse {
                origin: "--sumo-driver".to_owned(),
                message: "applies with --world sumo".to_owned(),
            }))
            .into());
        }
        _ => None,
    };
    let world = if sumo.is_some() { v2t_lab::vut::World::Sumo } else { v2t_lab::vut::World::Builtin };
    let opts = EcuOptions {
        sumo,
        source,
        vut: cli.vut,
        seed: cli.seed,
        engage_timeout_s: cli.engage_timeout_s,
        tau_s: cli.tau,
        style: cli.style,
        human,
    };
    let run = v2t_lab::ecu::run::<ipc::Service>(&cfg, &opts)?;
    let (r, stats) = (&run.outcome.result, &run.stats);
    let pet = r.pet_min_s.map_or_else(|| "none".to_owned(), |p| format!("{p:.2} s"));
    outln!(
        "{}: VUT {}, PET_min {pet} (τ {:.2} s, {}), completed {}, collision {}, frames ok {} rejected {}, ECU timeout steps {}, late steps {} ({})",
        r.scenario,
        r.vut_model,
        r.target.tau_s(),
        r.target.style(),
        r.completed,
        r.collision.is_some(),
        stats.frames_ok,
        stats.frames_rejected,
        stats.timeout_steps,
        stats.late_steps,
        world.place()
    )?;
    if let (Some(r), Some(h)) = (&run.realism, &opts.human) {
        out!("{}", v2t_lab::sim::realism_report(r, h))?;
    }
    if let Some(path) = &cli.mcap {
        v2t_sim::recording::write_with_plans(&run.outcome, &run.plans, path)?;
    }
    if cli.out.is_none() && cli.report.is_none() {
        return Ok(());
    }
    let file = run.file();
    if let Some(path) = &cli.out {
        let text = serde_json::to_string_pretty(&file).context("serializing the run")?;
        std::fs::write(path, text).with_context(|| format!("cannot write {}", path.display()))?;
    }
    if let Some(path) = &cli.report {
        let page = v2t_lab::report::run::page(
            &file,
            map.as_ref(),
            &report_map,
            world.provenance(),
            path,
            &[("run (JSON)", cli.out.as_deref()), ("recording (MCAP)", cli.mcap.as_deref())],
        );
        std::fs::write(path, page).with_context(|| format!("cannot write {}", path.display()))?;
    }
    Ok(())
}

fn main() -> ExitCode {
    match run(Cli::parse()) {
        Ok(()) => ExitCode::SUCCESS,
        // stdout's reader went away (`| head`): nothing more to say, and nothing failed.
        Err(e) if v2t_files::stdout::closed(e.as_ref()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("v2t-sim-ecu: {}", v2t_files::error_chain(e.as_ref()));
            let bad_input = e.chain().any(|c| c.downcast_ref::<EcuError>().is_some_and(EcuError::is_input));
            ExitCode::from(if bad_input { 2 } else { 1 })
        }
    }
}
