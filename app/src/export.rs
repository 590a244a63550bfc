//! `video2track export xosc`: an OpenSCENARIO 1.2 file of a prior, a grounded scenario or a run
//! ([`v2t_export::file`]).

use std::path::PathBuf;

use v2t_files::{outln, shipped};

/// `export`'s commands.
#[derive(Debug, clap::Subcommand)]
pub enum ExportCommand {
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
        #[arg(long, default_value = shipped::MAP)]
        map: PathBuf,
        /// The VUT's vehicle file (TOML).
        #[arg(long, default_value = shipped::VUT_VEHICLE)]
        vut_vehicle: PathBuf,
        /// Every BV's vehicle file (TOML).
        #[arg(long, default_value = shipped::BV_VEHICLE)]
        bv_vehicle: PathBuf,
    },
}

/// Runs an `export` command.
pub fn run(command: ExportCommand) -> anyhow::Result<()> {
    let ExportCommand::Xosc { input, out, map, vut_vehicle, bv_vehicle } = command;
    let args = v2t_export::file::XoscArgs {
        input: &input,
        out: &out,
        map: &map,
        vut_vehicle: &vut_vehicle,
        bv_vehicle: &bv_vehicle,
    };
    let done = v2t_export::file::export_xosc(&args)?;
    let s = &done.scenario;
    let bvs = s.agents.iter().filter(|a| a.role == v2t_model::grounded::AgentRole::Bv).count();
    outln!(
        "{} `{}`: {} agents ({bvs} following trajectories), {:.1} s, τ {} s, {}; map {}",
        s.kind.describe(),
        s.name,
        s.agents.len(),
        s.end_time_s(),
        s.tau_s,
        s.style,
        done.map_path
    )?;
    outln!("wrote {}", out.display())?;
    Ok(())
}
