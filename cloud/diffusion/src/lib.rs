//! # v2t-diffusion — the data side
//!
//! The guided diffusion model of the paper (Section 3.3.1) denoises *joint control sequences*
//! `(a, ω)` of the kinematic model of `v2t-model`; it learns human driving priors from data. This
//! crate prepares that data, with no ML dependency:
//!
//! - [`tracks`]: recorded tracks and episodes;
//! - [`import`]: INTERACTION/highD-style CSV and CommonRoad XML importers;
//! - [`inverse`]: positions → controls by a jerk-penalised least-squares smoother and exact
//!   inversion of the discrete model, with the rollout gap measured;
//! - [`mining`]: cut-ins, left turns / crossings and merges found in an episode, with PET;
//! - [`synth`]: a **synthetic** human-driving corpus simulated on the topology library's fragments
//!   with heterogeneous driver models, and its JSON-lines format;
//! - [`stats`]: histograms and Wasserstein-1 distances for realism checks;
//! - [`guidance`]: stage 2a, the guidance energies (anchors, solid boundaries, clearance, kinematic
//!   limits) on rolled-out joint controls with their gradients through the rollout adjoint, and the
//!   guided correction of Algorithm 1 in the denoiser's normalized space.
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
pub mod denoiser;
pub mod generate;
pub mod guidance;
pub mod import;
pub mod inverse;
pub mod mining;
pub mod realism;
pub mod sample;
pub mod schedule;
pub mod stats;
pub mod synth;
pub mod tracks;
pub mod train;
pub mod weights;
