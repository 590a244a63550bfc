//! Probe: training throughput and loss of the denoiser on a synthetic corpus.
//! `cargo run --release -p v2t-diffusion --example train_probe -- MAP EPISODES STEPS BATCH HIDDEN`
use std::time::Instant;

use v2t_diffusion::denoiser::DenoiserConfig;
use v2t_diffusion::synth::generate_corpus;
use v2t_diffusion::train::{Dataset, TrainOptions, Trainer};

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let map_path = args.get(1).map_or("config/maps/proving_ground.xodr", String::as_str);
    let episodes: usize = args.get(2).map_or(Ok(200), |s| s.parse())?;
    let steps: usize = args.get(3).map_or(Ok(200), |s| s.parse())?;
    let batch: usize = args.get(4).map_or(Ok(64), |s| s.parse())?;
    let hidden: usize = args.get(5).map_or(Ok(64), |s| s.parse())?;
    let map = v2t_map::Map::load(std::path::Path::new(map_path))?;
    let t = Instant::now();
    let corpus = generate_corpus(&map, episodes, 1)?;
    println!("corpus {} episodes in {:.1} s", corpus.episodes.len(), t.elapsed().as_secs_f64());
    let lib = v2t_map::library::TopologyLibrary::build(&map);
    let cfg = DenoiserConfig { hidden, ..DenoiserConfig::default() };
    let t = Instant::now();
    let data = Dataset::build(&corpus.episodes, &lib, cfg, 5)?;
    println!(
        "dataset: {} train / {} heldout windows in {:.1} s, normalization {:?}",
        data.train.len(),
        data.heldout.len(),
        t.elapsed().as_secs_f64(),
        data.normalization
    );
    let opts = TrainOptions { steps, batch, eval_every: (steps / 5).max(1), ..TrainOptions::default() };
    let mut trainer = Trainer::new(cfg, opts)?;
    println!("parameters: {}", trainer.parameters());
    let loss = trainer.run(&data, |_, m| println!("{m:?}"))?;
    println!("final heldout {loss:.4}");
    Ok(())
}
