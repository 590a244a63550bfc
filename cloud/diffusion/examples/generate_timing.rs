//! Timing of guided generation for the reference case: 16 variants of 3 agents × 8 s
//! (T = 80), K = 50 DDPM steps, full guidance (anchors, solid boundaries, clearance, kinematic
//! limits, 300 final corrections), on held-out 3-agent windows of the synthetic corpus.
//!
//! `RAYON_NUM_THREADS=1 cargo run --release -p v2t-diffusion --example generate_timing -- config/diffusion/denoiser.safetensors config/maps/proving_ground.xodr`
use std::time::Instant;

use v2t_diffusion::guidance::{Anchor, Guidance, GuidanceConfig, GuidanceContext, GuidanceWeights};
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
        let x0s: Vec<_> = w.condition.slots.iter().flatten().map(|s| s.start).collect();
        let mut anchors: Vec<Anchor> = w
            .condition
            .slots
            .iter()
            .flatten()
            .enumerate()
            .filter_map(|(agent, s)| s.anchor.map(|(position, time_s)| Anchor { agent, position, time_s }))
            .collect();
        anchors.extend(w.end_positions.iter().enumerate().map(|(agent, p)| Anchor {
            agent,
            position: *p,
            time_s: 8.0,
        }));
        let near: Vec<_> = x0s.iter().map(|x| x.position()).chain(w.end_positions.iter().copied()).collect();
        let context = GuidanceContext {
            anchors,
            boundaries: v2t_map::boundaries::solid_boundaries(&map, &near, 40.0, 0.05),
            ..GuidanceContext::default()
        };
        let config = GuidanceConfig {
            agents: 3,
            steps,
            weights: GuidanceWeights { kinematic: 4.0, ..GuidanceWeights::default() },
            ..GuidanceConfig::default()
        };
        let guidance = Guidance::new(config, context)?;
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
