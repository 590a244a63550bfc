//! Generates a synthetic corpus on a map and prints how long it took and what it holds.
//!
//! ```text
//! cargo run --release -p v2t-diffusion --example synthetic_corpus -- [MAP.xodr] [EPISODES] [SEED] [OUT.jsonl]
//! ```

use std::collections::BTreeMap;
use std::time::Instant;

use anyhow::Context;
use v2t_diffusion::synth::{generate_corpus, to_jsonl};

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let map_path = args.first().map_or_else(|| root.join("config/maps/proving_ground.xodr"), std::path::PathBuf::from);
    let n: usize = args.get(1).map_or(Ok(1000), |s| s.parse()).context("EPISODES")?;
    let seed: u64 = args.get(2).map_or(Ok(1), |s| s.parse()).context("SEED")?;
    let map = v2t_map::Map::load(&map_path)?;
    let start = Instant::now();
    let corpus = generate_corpus(&map, n, seed)?;
    let elapsed = start.elapsed().as_secs_f64();
    let steps: usize = corpus.episodes.iter().flat_map(|e| e.agents.iter().map(|a| a.controls.len())).sum();
    println!(
        "{n} synthetic episodes on `{}` (seed {seed}) in {elapsed:.2} s ({:.2} ms/episode), {steps} agent steps, {} draws rejected {:?}",
        corpus.map,
        1e3 * elapsed / n.max(1) as f64,
        corpus.rejections.total(),
        corpus.rejections
    );
    let mut by_kind: BTreeMap<String, (usize, Vec<f64>)> = BTreeMap::new();
    let samples = corpus.control_samples();
    let mut worst_gap: f64 = 0.0;
    let three = corpus.episodes.iter().filter(|e| e.agents.len() == 3).count();
    println!("  {three} episodes with a third vehicle");
    for e in &corpus.episodes {
        let entry = by_kind.entry(format!("{:?}/{:?}", e.interaction, e.mined.kind)).or_default();
        entry.0 += 1;
        entry.1.push(e.pet_s());
        for t in e.trajectories() {
            worst_gap = worst_gap.max(t.rollout_gap_m(e.dt_s));
        }
    }
    for (k, (count, mut pets)) in by_kind {
        pets.sort_by(f64::total_cmp);
        let q = |f: f64| pets.get(((pets.len() as f64 - 1.0) * f).round() as usize).copied().unwrap_or(f64::NAN);
        println!("  {k}: {count} episodes, PET min {:.2} / median {:.2} / max {:.2} s", q(0.0), q(0.5), q(1.0));
    }
    let q = |v: &[f64], f: f64| {
        let mut v = v.to_vec();
        v.sort_by(f64::total_cmp);
        v.get(((v.len() as f64 - 1.0) * f).round() as usize).copied().unwrap_or(f64::NAN)
    };
    println!(
        "  accel p1/p50/p99 {:.2}/{:.2}/{:.2} m/s², jerk p1/p99 {:.2}/{:.2} m/s³, yaw rate p1/p99 {:.3}/{:.3} rad/s",
        q(&samples.accel_mps2, 0.01),
        q(&samples.accel_mps2, 0.5),
        q(&samples.accel_mps2, 0.99),
        q(&samples.jerk_mps3, 0.01),
        q(&samples.jerk_mps3, 0.99),
        q(&samples.yaw_rate_radps, 0.01),
        q(&samples.yaw_rate_radps, 0.99)
    );
    println!("  largest rollout gap of the stored controls: {worst_gap:.2e} m");
    if let Some(out) = args.get(3) {
        let text = to_jsonl(&corpus)?;
        std::fs::write(out, &text).with_context(|| out.clone())?;
        let start = Instant::now();
        let back = v2t_diffusion::synth::read_jsonl_file(std::path::Path::new(out))?;
        println!(
            "  wrote {out} ({} bytes); read back in {:.2} s, identical: {}",
            text.len(),
            start.elapsed().as_secs_f64(),
            back == corpus
        );
    }
    Ok(())
}
