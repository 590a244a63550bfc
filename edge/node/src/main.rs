//! `v2t-edge`: the BV's onboard runtime.
//!
//! ```sh
//! v2t-edge launch --config config/edge/bv1.toml          # start and supervise every node
//! v2t-edge node regulator --config config/edge/bv1.toml  # one node (what the launcher runs)
//! v2t-edge sim-ecu --config config/edge/bv1.toml --scenario config/scenarios/left_turn_basic.toml
//! v2t-edge reset|engage|stop|disengage|estop --config config/edge/bv1.toml
//! v2t-edge bench-latency --json latency.json
//! v2t-edge bench-game --json game.json
//! ```

use std::alloc::{GlobalAlloc, Layout, System};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::atomic::{AtomicU64, Ordering};

use anyhow::Context;
use clap::{Parser, Subcommand};
use iceoryx2::prelude::ipc;
use v2t_edge::NodeRole;
use v2t_edge::config::{Loaded, load};
use v2t_edge::ecu::{EcuOptions, EcuSource};
use v2t_model::validate::Validate;
use v2t_wire::SafetyAction;

/// Counts heap allocations, so the benches can report allocations per decision.
struct Counting;
static ALLOCATIONS: AtomicU64 = AtomicU64::new(0);

// SAFETY: forwards every call to the system allocator unchanged and only counts.
#[allow(unsafe_code)]
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, l: Layout) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        // SAFETY: same contract as the caller's.
        unsafe { System.alloc(l) }
    }
    unsafe fn dealloc(&self, p: *mut u8, l: Layout) {
        // SAFETY: same contract as the caller's.
        unsafe { System.dealloc(p, l) }
    }
    unsafe fn realloc(&self, p: *mut u8, l: Layout, n: usize) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        // SAFETY: same contract as the caller's.
        unsafe { System.realloc(p, l, n) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

fn allocations() -> u64 {
    ALLOCATIONS.load(Ordering::Relaxed)
}

#[derive(Debug, Parser)]
#[command(name = "v2t-edge", version, about = "Video2Track BV onboard runtime")]
struct Cli {
    #[command(subcommand)]
    command: Cmd,
}

#[derive(Debug, clap::Args)]
struct Common {
    /// The BV's runtime configuration.
    #[arg(long, default_value = "config/edge/bv1.toml")]
    config: PathBuf,
    /// Override the service namespace of the configuration.
    #[arg(long)]
    namespace: Option<String>,
    /// Use this SocketCAN interface (`can0`, `vcan0`) instead of the configured CAN transport.
    #[arg(long)]
    can_iface: Option<String>,
}

#[derive(Debug, Subcommand)]
enum Cmd {
    /// Start every configured node as its own process, restart failed ones, stop all on SIGINT/SIGTERM.
    Launch(Common),
    /// Run one node in this process.
    Node {
        /// Which node.
        role: NodeRole,
        #[command(flatten)]
        common: Common,
    },
    /// Run a scenario against the onboard stack with the simulated drive-by-wire ECU.
    SimEcu {
        #[command(flatten)]
        common: Common,
        /// The scenario card (its prior is published as the stand-in for a cloud upload).
        #[arg(long, required_unless_present_any = ["from_uplink", "prior"], conflicts_with_all = ["from_uplink", "prior"])]
        scenario: Option<PathBuf>,
        /// A trajectory prior (JSON) instead of a card: checked like an upload, published, and the
        /// world built from it.
        #[arg(long, conflicts_with = "from_uplink")]
        prior: Option<PathBuf>,
        /// The prior's BV agent this BV drives (default: the first BV).
        #[arg(long, requires = "prior")]
        agent: Option<String>,
        /// Record the run as MCAP here.
        #[arg(long)]
        mcap: Option<PathBuf>,
        /// Build the world from the prior the uplink node accepts from the cloud instead of a card.
        #[arg(long)]
        from_uplink: bool,
        /// Simulation settings for --from-uplink.
        #[arg(long, default_value = "config/sim/default.toml")]
        sim_settings: PathBuf,
        /// Longest wait for the uplinked prior, s.
        #[arg(long, default_value_t = 60.0)]
        prior_wait_s: f64,
        /// VUT driver model (default: the card's).
        #[arg(long)]
        vut: Option<v2t_sim::vut::VutModel>,
        /// Noise seed.
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Write the measured run (JSON) here.
        #[arg(long)]
        out: Option<PathBuf>,
        /// Longest wait for the gateway to engage, s.
        #[arg(long, default_value_t = 10.0)]
        engage_timeout_s: f64,
        /// Target PET instead of the card's, s.
        #[arg(long)]
        tau: Option<f64>,
        /// Style instead of the card's (rush or yield).
        #[arg(long, value_parser = parse_style)]
        style: Option<v2t_model::Style>,
    },
    /// Ask the gateway to engage (after a stop, engaging takes this explicit request).
    Engage(Common),
    /// Leave a stop: the gate goes back to disengaged (engaging again is `engage`).
    Reset(Common),
    /// Ask the gateway for the minimal-risk stop.
    Stop(Common),
    /// Ask the gateway to disengage.
    Disengage(Common),
    /// Emergency stop.
    Estop(Common),
    /// Measure state-in → CAN-frame-out latency through the real processes.
    BenchLatency {
        #[command(flatten)]
        common: Common,
        /// The scenario to drive.
        #[arg(long, default_value = "config/scenarios/left_turn_basic.toml")]
        scenario: PathBuf,
        /// Write the figures (JSON) here.
        #[arg(long)]
        json: Option<PathBuf>,
    },
    /// Measure the regulator's decision latency and allocations (one thread, warm; N = 30 and 50).
    BenchGame {
        /// Write the figures (JSON) here.
        #[arg(long)]
        json: Option<PathBuf>,
    },
}

fn parse_style(s: &str) -> Result<v2t_model::Style, String> {
    match s {
        "rush" => Ok(v2t_model::Style::Rush),
        "yield" => Ok(v2t_model::Style::Yield),
        other => Err(format!("unknown style {other:?}: rush or yield")),
    }
}

fn loaded(c: &Common) -> anyhow::Result<Loaded> {
    let mut cfg = load(&c.config)?;
    if let Some(ns) = &c.namespace {
        cfg.edge.namespace.clone_from(ns);
    }
    if let Some(interface) = &c.can_iface {
        cfg.edge.can = v2t_edge::config::CanLink::Socketcan { interface: interface.clone() };
        cfg.edge.validate().with_context(|| format!("--can-iface {interface}"))?;
    }
    v2t_edge::ports::use_iceoryx2_config(&cfg.iceoryx2)?;
    Ok(cfg)
}

fn write_json(path: &Path, value: &impl serde::Serialize) -> anyhow::Result<()> {
    let text = serde_json::to_string_pretty(value)?;
    std::fs::write(path, text).with_context(|| format!("cannot write {}", path.display()))
}

fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Cmd::Launch(c) => {
            let exe = std::env::current_exe().context("cannot find the v2t-edge executable")?;
            v2t_edge::launch::run::<ipc::Service>(&loaded(&c)?, &exe)?;
        }
        Cmd::Node { role, common } => {
            let cfg = loaded(&common)?;
            match role {
                NodeRole::State => v2t_edge::state::run::<ipc::Service>(&cfg)?,
                NodeRole::Regulator => v2t_edge::regulate::run::<ipc::Service>(&cfg)?,
                NodeRole::Tracker => v2t_edge::track::run::<ipc::Service>(&cfg)?,
                NodeRole::Gateway => v2t_edge::gateway::run::<ipc::Service>(&cfg)?,
                NodeRole::Monitor => v2t_edge::monitor::run::<ipc::Service>(&cfg)?,
                NodeRole::Uplink => v2t_edge::uplink::run::<ipc::Service>(&cfg)?,
            }
        }
        Cmd::SimEcu {
            common,
            scenario,
            prior,
            agent,
            mcap,
            from_uplink: _,
            sim_settings,
            prior_wait_s,
            vut,
            seed,
            out,
            engage_timeout_s,
            tau,
            style,
        } => {
            let cfg = loaded(&common)?;
            let source = match (scenario, prior) {
                (Some(card), _) => EcuSource::Card(card),
                (None, Some(path)) => EcuSource::Prior { path, agent, sim_settings },
                (None, None) => EcuSource::Uplink { sim_settings, wait_s: prior_wait_s },
            };
            let opts = EcuOptions { source, vut, seed, engage_timeout_s, tau_s: tau, style };
            let (outcome, stats, plans) = v2t_edge::ecu::run::<ipc::Service>(&cfg, &opts)?;
            let r = &outcome.result;
            let pet = r.pet_min_s.map_or_else(|| "none".to_owned(), |p| format!("{p:.2} s"));
            println!(
                "{}: PET_min {pet} (τ {:.2} s, {}), completed {}, collision {}, frames ok {} rejected {}, ECU timeout steps {}, late steps {}",
                r.scenario,
                r.tau_s,
                r.style,
                r.completed,
                r.collision.is_some(),
                stats.frames_ok,
                stats.frames_rejected,
                stats.timeout_steps,
                stats.late_steps
            );
            if let Some(path) = mcap {
                v2t_sim::recording::write_with_plans(&outcome, &plans, &path)?;
            }
            if let Some(path) = out {
                let mut doc = serde_json::to_value(&outcome).context("serializing the run")?;
                if let Some(obj) = doc.as_object_mut() {
                    obj.insert("ecu".into(), serde_json::to_value(stats).context("serializing the ECU statistics")?);
                }
                write_json(&path, &doc)?;
            }
        }
        Cmd::Engage(c) => v2t_edge::operator::request::<ipc::Service>(&loaded(&c)?, SafetyAction::Engage)?,
        Cmd::Reset(c) => v2t_edge::operator::request::<ipc::Service>(&loaded(&c)?, SafetyAction::Reset)?,
        Cmd::Stop(c) => v2t_edge::operator::request::<ipc::Service>(&loaded(&c)?, SafetyAction::MinimalRiskStop)?,
        Cmd::Disengage(c) => v2t_edge::operator::request::<ipc::Service>(&loaded(&c)?, SafetyAction::Disengage)?,
        Cmd::Estop(c) => v2t_edge::operator::request::<ipc::Service>(&loaded(&c)?, SafetyAction::EStop)?,
        Cmd::BenchLatency { common, scenario, json } => {
            let exe = std::env::current_exe().context("cannot find the v2t-edge executable")?;
            let report = v2t_edge::bench::latency(&loaded(&common)?, &exe, &scenario)?;
            println!("{}", report.table());
            if let Some(path) = json {
                write_json(&path, &report)?;
            }
        }
        Cmd::BenchGame { json } => {
            let figures = v2t_game::bench::run_bench(allocations).map_err(|e| anyhow::anyhow!("{e}"))?;
            println!(
                "| N | closed-loop decisions | p50 | p99 | max | approaches+random p50 | p99 | max | allocations/decision | non-finite |"
            );
            println!("|---|---|---|---|---|---|---|---|---|---|");
            for f in &figures {
                println!(
                    "| {} | {} | {:.0} µs | {:.0} µs | {:.0} µs | {:.0} µs | {:.0} µs | {:.0} µs | {:.2} | {} |",
                    f.horizon,
                    f.sim_decisions,
                    f.sim_p50_us,
                    f.sim_p99_us,
                    f.sim_max_us,
                    f.p50_us,
                    f.p99_us,
                    f.max_us,
                    f.allocs_per_decision,
                    f.non_finite
                );
                println!("statuses (N = {}): {:?}", f.horizon, f.statuses);
            }
            if let Some(path) = json {
                write_json(&path, &figures)?;
            }
        }
    }
    Ok(())
}

fn main() -> ExitCode {
    match run(Cli::parse()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("v2t-edge: {e:#}");
            ExitCode::from(1)
        }
    }
}
