//! `v2t-edge`: the BV's onboard runtime.
//!
//! ```sh
//! v2t-edge launch --config config/edge/bv1.toml          # start and supervise every node
//! v2t-edge node regulator --config config/edge/bv1.toml  # one node (what the launcher runs)
//! v2t-edge reset|engage|stop|disengage|estop --config config/edge/bv1.toml
//! v2t-edge check --config config/edge/bv1.toml           # before a test day: every check, exit 2 on a FAIL
//! ```
//!
//! Without a vehicle, the lab's simulated drive-by-wire ECU closes the loop (`v2t-sim-ecu`).

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context;
use clap::{Parser, Subcommand};
use iceoryx2::prelude::ipc;
use v2t_edge::NodeRole;
use v2t_edge::config::{Loaded, Overrides, load_for_process};
use v2t_edge::error::EdgeError;
use v2t_files::{out, outln};
use v2t_wire::SafetyAction;

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
    /// Ask the gateway to engage (after a stop, engaging takes this explicit request).
    Engage(Common),
    /// Leave a stop: the gate goes back to disengaged (engaging again is `engage`).
    Reset(Common),
    /// Ask the gateway for the minimal-risk stop.
    Stop {
        #[command(flatten)]
        common: Common,
        /// Wait up to this long (s, 0 to 600) until the BV stands with its gate stopped; exit 1 if
        /// it still moves then. 0: do not wait.
        #[arg(long, default_value_t = 0.0, value_parser = wait_seconds)]
        wait_s: f64,
    },
    /// Ask the gateway to disengage.
    Disengage(Common),
    /// Emergency stop.
    Estop(Common),
    /// Check the configuration, every file it names and how it fits this machine (CAN interface,
    /// real-time allowances), one line per check; exit 2 if any fails. Starts nothing.
    Check(Common),
}

fn overrides(c: &Common) -> Overrides<'_> {
    Overrides { namespace: c.namespace.as_deref(), can_iface: c.can_iface.as_deref() }
}

/// `--wait-s`: 0 to 600 s.
fn wait_seconds(text: &str) -> Result<f64, String> {
    match text.parse::<f64>() {
        Ok(s) if (0.0..=600.0).contains(&s) => Ok(s),
        _ => Err(format!("must be a number of seconds in [0, 600], got {text}")),
    }
}

fn loaded(c: &Common) -> anyhow::Result<Loaded> {
    Ok(load_for_process(&c.config, overrides(c))?)
}

fn run(cli: Cli) -> anyhow::Result<ExitCode> {
    match cli.command {
        Cmd::Launch(c) => {
            let exe = std::env::current_exe().context("cannot find the v2t-edge executable")?;
            v2t_edge::launch::run::<ipc::Service>(&loaded(&c)?, &exe)?;
        }
        Cmd::Node { role, common } => {
            let cfg = loaded(&common)?;
            v2t_edge::realtime::apply_configured(&cfg, v2t_edge::realtime::Process::Node(role))?;
            match role {
                NodeRole::State => v2t_edge::state::run::<ipc::Service>(&cfg)?,
                NodeRole::Regulator => v2t_edge::regulate::run::<ipc::Service>(&cfg)?,
                NodeRole::Tracker => v2t_edge::track::run::<ipc::Service>(&cfg)?,
                NodeRole::Gateway => v2t_edge::gateway::run::<ipc::Service>(&cfg)?,
                NodeRole::Monitor => v2t_edge::monitor::run::<ipc::Service>(&cfg)?,
                NodeRole::Uplink => v2t_edge::uplink::run::<ipc::Service>(&cfg)?,
            }
        }
        Cmd::Engage(c) => v2t_edge::operator::request::<ipc::Service>(&loaded(&c)?, SafetyAction::Engage)?,
        Cmd::Reset(c) => v2t_edge::operator::request::<ipc::Service>(&loaded(&c)?, SafetyAction::Reset)?,
        Cmd::Stop { common, wait_s } if wait_s > 0.0 => {
            use v2t_edge::operator::{StopWait, stop_and_wait};
            match stop_and_wait::<ipc::Service>(&loaded(&common)?, std::time::Duration::from_secs_f64(wait_s))? {
                StopWait::Stopped { after_s } => {
                    outln!("stopped: the BV stands, its gate stopped, {after_s:.1} s after the request")?
                }
                StopWait::NoRuntime => {
                    outln!("no BV state within 1 s: no runtime is running here, nothing to wait for")?
                }
                StopWait::TimedOut { speed_mps, gate } => anyhow::bail!(
                    "the BV still moves at {speed_mps:.2} m/s (gate {gate:?}) {wait_s} s after the minimal-risk stop was requested"
                ),
            }
        }
        Cmd::Stop { common, .. } => {
            v2t_edge::operator::request::<ipc::Service>(&loaded(&common)?, SafetyAction::MinimalRiskStop)?;
        }
        Cmd::Disengage(c) => v2t_edge::operator::request::<ipc::Service>(&loaded(&c)?, SafetyAction::Disengage)?,
        Cmd::Estop(c) => v2t_edge::operator::request::<ipc::Service>(&loaded(&c)?, SafetyAction::EStop)?,
        Cmd::Check(c) => {
            let report = v2t_edge::check::run(&c.config, overrides(&c), &v2t_edge::check::Machine::this_one());
            let printed = out!("{report}");
            // A failed check is bad input, like a configuration the runtime refuses (2), even when
            // stdout's reader went away before the report's end.
            if report.failed() {
                return Ok(ExitCode::from(2));
            }
            printed?;
        }
    }
    Ok(ExitCode::SUCCESS)
}

fn main() -> ExitCode {
    match run(Cli::parse()) {
        Ok(code) => code,
        // stdout's reader went away (`| head`): nothing more to say, and nothing failed.
        Err(e) if v2t_files::stdout::closed(e.as_ref()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("v2t-edge: {}", v2t_files::error_chain(e.as_ref()));
            // Bad configuration is bad input (2); anything else is a failure of the work (1).
            let bad_input = e.chain().any(|c| {
                c.downcast_ref::<EdgeError>().is_some_and(EdgeError::is_input)
                    || c.is::<v2t_model::validate::ValidationError>()
            });
            ExitCode::from(if bad_input { 2 } else { 1 })
        }
    }
}
