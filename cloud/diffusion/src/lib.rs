//! # v2t-diffusion — guided diffusion over joint controls
//!
//! The guided diffusion model of the paper (Section 3.3.1, Algorithm 1): it denoises *joint
//! control sequences* `(a, ω)` of the kinematic model of `v2t-model` for the VUT and 1–2 BVs,
//! guided at every step through the differentiable rollout, and learns human driving priors from
//! data (here a **synthetic** corpus):
//!
//! - [`denoiser`]: `ε_θ(U_k, k, c)` on `candle`, a patched temporal convolution network with FiLM;
//!   [`condition`]: what `c` holds; [`schedule`]: the noise schedule;
//! - [`sample`]: Algorithm 1 batched over variants (DDPM or DDIM) with [`guidance`]: the energies
//!   (anchors, solid boundaries, clearance, kinematic limits) on rolled-out controls, their
//!   gradients through the rollout adjoint, the guided correction;
//! - [`generate`]: a grounded scenario → trajectory priors and their metrics;
//! - [`train`], [`weights`], [`realism`]: training windows and the trainer, versioned safetensors,
//!   Wasserstein-1 distances to held-out data;
//! - the data side: [`tracks`], [`import`] (INTERACTION/highD-style CSV, CommonRoad XML),
//!   [`inverse`] (positions → controls), [`mining`] (cut-ins, left turns, merges with PET),
//!   [`synth`] (the synthetic corpus), [`stats`] (histograms, W₁).
//!
//! ```
//! use v2t_diffusion::import::csv::{parse, CsvOptions};
//! use v2t_diffusion::inverse::{to_controls, InverseOptions};
//! let mut text = String::from("track_id,frame_id,timestamp_ms,x,y\n");
//! for k in 0..30 {
//!     text.push_str(&format!("1,{k},{},{},0\n", 100 * k, 1.0 * k as f64));
//! }
//! let csv = parse(&text, "demo", &CsvOptions::default()).unwrap();
//! let inv = to_controls(&csv.episode.tracks[0], &InverseOptions::default()).unwrap();
//! assert!((inv.trajectory.states[5].speed_mps - 10.0).abs() < 1e-6);
//! assert!(inv.rollout_gap_m < 1e-9);
//! ```

pub mod condition;
pub mod dedup;
pub mod denoiser;
pub mod generate;
pub mod guidance;
pub mod import;
pub mod inverse;
pub mod jsonl;
pub mod lanes;
pub mod mining;
pub mod realism;
pub mod recorded;
pub mod sample;
pub mod schedule;
pub mod stats;
pub mod synth;
pub mod tracks;
pub mod train;
pub mod weights;
