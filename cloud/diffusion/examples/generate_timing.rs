//! Timing of guided generation for the reference case: 16 variants of 3 agents × 8 s
//! (T = 80), K = 50 DDPM steps, full guidance (anchors, solid boundaries, clearance, kinematic
//! limits, 300 final corrections), on held-out 3-agent windows of the synthetic corpus.
//!
//! `RAYON_NUM_THREADS=1 cargo run --release -p v2t-diffusion --example generate_timing -- config/diffusion/denoiser.safetensors config/maps/proving_ground.xodr`
use std::time::Instant;

use v2t_diffusion::generate::FULL_GUIDANCE;
use v2t_diffusion::realism::window_guidance;
use v2t_diffusion::sample::{Problem, SamplerOptions, sample};
use v2t_diffusion::synth::generate_corpus;
use v2t_diffusion::train::Dataset;

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let weights = args.get(1).map_or("config/diffusion/denoiser.safetensors", String::as_str);
    let map_path = args.get(2).map_or("config/maps/proving_ground.xodr", String::as_str);
    let model = v2t_diffusion::weights::load(std::path::Path::new(weights))?;
    let map = v2t_map::Map::load(std::path::Path::new(map_path))?;
    let library = v2t_map::library::TopologyLibrary::build(&map);
    let corpus = generate_corpus(&map, 200, 1)?;
    let data = Dataset::build(&corpus.episodes, &library, model.meta.config, 5)?;
    let windows: Vec<_> = data.heldout.iter().filter(|w| w.controls.len() == 3).take(5).collect();
    println!("{} held-out 3-agent windows", windows.len());
    let steps = model.meta.config.steps;
    let mut times = Vec::new();
    for w in windows {
        let (guidance, x0s) = window_guidance(w, FULL_GUIDANCE, Some(&map), steps)?;
        let problem = Problem { condition: &w.condition, guidance: Some(&guidance), x0s: &x0s };
        let t = Instant::now();
        let v = sample(&model, &problem, 16, 1, &SamplerOptions::default())?;
        let dt = t.elapsed().as_secs_f64();
        times.push(dt);
        println!(
            "16 variants × 3 agents in {:.3} s ({} boundary segments)",
            dt,
            guidance.context().boundaries.iter().map(|b| b.len().saturating_sub(1)).sum::<usize>()
        );
        assert_eq!(v.len(), 16);
    }
    times.sort_by(f64::total_cmp);
    let at = |k: usize| times.get(k).copied().unwrap_or(f64::NAN);
    println!("median {:.3} s, max {:.3} s", at(times.len() / 2), at(times.len().saturating_sub(1)));
    Ok(())
}
