//! `v2t-bench`: the onboard figures, measured.
//!
//! ```sh
//! v2t-bench latency --json latency.json   # state-in → CAN-frame-out through the real processes
//! v2t-bench latency --load 2 --config config/edge/bv1_realtime.toml
//!                                         # the same beside 2 busy processes, under SCHED_FIFO
//! v2t-bench game --json game.json         # the regulator's decision latency and allocations
//! v2t-bench netdelay --listen 127.0.0.1:18830 --upstream 127.0.0.1:1883 --delay-ms 50
//!                                         # a delaying TCP proxy (the network of `experiment latency`'s real-process check)
//! ```
//!
//! Both run release builds on this machine; their figures go into `docs/BENCHMARKS.md` with the
//! command. They are never timed assertions in tests.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::Context as _;
use clap::{Parser, Subcommand};
use v2t_edge::config::{Overrides, load_for_process};
use v2t_files::{out, outln};

/// Counts heap allocations, so that `game` can report allocations per decision (this binary only:
/// the onboard runtime uses the system allocator untouched).
#[global_allocator]
static GLOBAL: v2t_test_support::alloc::Counting = v2t_test_support::alloc::Counting;

fn allocations() -> u64 {
    v2t_test_support::alloc::total()
}

/// Video2Track benches of the onboard runtime and the regulator.
#[derive(Debug, Parser)]
#[command(name = "v2t-bench", version)]
struct Cli {
    #[command(subcommand)]
    command: Bench,
}

#[derive(Debug, Subcommand)]
enum Bench {
    /// State-in → CAN-frame-out latency through the real processes (`v2t-edge launch` and
    /// `v2t-sim-ecu`, both beside this binary).
    Latency {
        /// The BV's runtime configuration.
        #[arg(long, default_value = v2t_files::shipped::EDGE)]
        config: PathBuf,
        /// The scenario to drive.
        #[arg(long, default_value = "config/scenarios/left_turn_basic.toml")]
        scenario: PathBuf,
        /// Write the figures (JSON) here.
        #[arg(long)]
        json: Option<PathBuf>,
        /// Busy processes (one CPU each, pinned nowhere) beside the runtime while it is measured.
        #[arg(long, default_value_t = 0, value_parser = clap::value_parser!(u16).range(0..=256))]
        load: u16,
        /// Run the scenario again until the path has this many samples (at most 100 runs).
        #[arg(long, default_value_t = 5_000)]
        min_samples: usize,
    },
    /// Spins on one CPU until the process PARENT is gone (the load of `latency --load`).
    #[command(hide = true)]
    Spin {
        /// The bench that started it.
        #[arg(long)]
        parent: u32,
    },
    /// The regulator's decision latency and allocations (one thread, warm; N = 30 and 50).
    Game {
        /// Write the figures (JSON) here.
        #[arg(long)]
        json: Option<PathBuf>,
    },
    /// A TCP proxy that delays every byte it forwards (put it between a BV and its broker): a
    /// link with this one-way delay each way, order kept, nothing lost. Runs until killed.
    Netdelay {
        /// Where to listen (host:port).
        #[arg(long)]
        listen: std::net::SocketAddr,
        /// Where to forward (the broker, host:port).
        #[arg(long)]
        upstream: std::net::SocketAddr,
        /// One-way delay in each direction, ms (0–10,000).
        #[arg(long, value_parser = clap::value_parser!(u64).range(0..=10_000))]
        delay_ms: u64,
    },
}

fn write_json(path: &Path, value: &impl serde::Serialize) -> anyhow::Result<()> {
    let text = serde_json::to_string_pretty(value)?;
    std::fs::write(path, text).with_context(|| format!("cannot write {}", path.display()))
}

fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Bench::Latency { config, scenario, json, load, min_samples } => {
            use v2t_lab::bench_latency::{LatencyOptions, Load, Programs, latency};
            let cfg = load_for_process(&config, Overrides::default())?;
            // The scenario is the ECU's to read; read it here first, before anything starts.
            v2t_sim::files::load_scenario(&scenario)?;
            let (edge, ecu) = (v2t_lab::demo::beside_me("v2t-edge"), v2t_lab::demo::beside_me("v2t-sim-ecu"));
            let programs = Programs { edge: &edge, ecu: &ecu };
            let me = std::env::current_exe().context("cannot find the v2t-bench executable")?;
            let parent = std::process::id().to_string();
            let load = Load::start(usize::from(load), &me, &["spin", "--parent", &parent])?;
            let opts = LatencyOptions { scenario: &scenario, min_samples, load: &load };
            let report = latency(&cfg, programs, &opts)?;
            drop(load);
            outln!("{}", report.table())?;
            if let Some(path) = json {
                write_json(&path, &report)?;
            }
        }
        Bench::Spin { parent } => v2t_lab::bench_latency::spin(parent),
        Bench::Netdelay { listen, upstream, delay_ms } => {
            let listener = std::net::TcpListener::bind(listen).with_context(|| format!("cannot listen on {listen}"))?;
            outln!("netdelay: {listen} -> {upstream}, {delay_ms} ms each way")?;
            let delay = std::time::Duration::from_millis(delay_ms);
            v2t_lab::netdelay::serve(&listener, upstream, delay, delay)?;
        }
        Bench::Game { json } => {
            let figures = v2t_lab::bench_game::run_bench(allocations).map_err(|e| anyhow::anyhow!("{e}"))?;
            out!("{}", v2t_lab::bench_game::table(&figures))?;
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
        // stdout's reader went away (`| head`): nothing more to say, and nothing failed.
        Err(e) if v2t_files::stdout::closed(e.as_ref()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("v2t-bench: {}", v2t_files::error_chain(e.as_ref()));
            // A configuration or scenario file at fault is bad input (2); the rest failed work (1).
            let bad_input = e.chain().any(|c| {
                c.downcast_ref::<v2t_edge::error::EdgeError>().is_some_and(v2t_edge::error::EdgeError::is_input)
                    || c.is::<v2t_files::InputError>()
                    || c.is::<v2t_sim::files::CardError>()
            });
            ExitCode::from(if bad_input { 2 } else { 1 })
        }
    }
}
