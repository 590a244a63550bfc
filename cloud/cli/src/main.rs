//! `video2track`: the operator's command line.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context as _;
use clap::{Parser, Subcommand};
use v2t_sim::vut::VutModel;
use video2track::files::{InputError, load_scenario};
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
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    match execute(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(err) => {
            eprintln!("error: {err:#}");
            if err.chain().any(|e| e.is::<InputError>()) { ExitCode::from(2) } else { ExitCode::FAILURE }
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
    }
}
