//! `video2track demo`: the lab's end-to-end pipeline ([`v2t_lab::demo`]) on the shipped files.

use std::path::PathBuf;

use v2t_files::{outln, shipped};
use v2t_sim::vut::VutModel;

/// `demo`'s arguments.
#[derive(Debug, clap::Args)]
pub struct DemoArgs {
    /// Output folder.
    #[arg(long, default_value = "demo-out")]
    out: PathBuf,
    /// VUT driver model.
    #[arg(long, default_value = "idm-normal", value_parser = clap::builder::PossibleValuesParser::new(VutModel::names()))]
    vut: String,
    /// Noise seed.
    #[arg(long, default_value_t = 1)]
    seed: u64,
}

/// Runs the demo and says where its report is.
pub fn run(a: DemoArgs) -> anyhow::Result<()> {
    let opts = v2t_lab::demo::DemoOptions {
        out: a.out.clone(),
        map: PathBuf::from(shipped::MAP),
        edge_config: PathBuf::from(shipped::EDGE),
        edge_bin: v2t_lab::demo::beside_me("v2t-edge"),
        ecu_bin: v2t_lab::demo::beside_me("v2t-sim-ecu"),
        vut: a.vut,
        seed: a.seed,
        weights: PathBuf::from(shipped::WEIGHTS),
    };
    let summary = v2t_lab::demo::run(&opts)?;
    outln!("wrote {0}/report.html and {0}/summary.json in {1:.1} s", a.out.display(), summary.wall_s)?;
    Ok(())
}
