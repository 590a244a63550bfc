//! Guided sampling (Algorithm 1 of the paper, lines 1–10), batched over variants.
//!
//! Start from `U_K ~ N(0, I)`; at every step `k`: `ε̂ = ε_θ(U_k, k, c)`, the predicted clean
//! sample `Û0 = (U_k − √(1 − ᾱ_k) ε̂)/√ᾱ_k` (clipped to ±[`CLEAN_CLIP`] normalized units), the
//! guided correction `Ũ0 = Û0 − η ∇E(Rollout(Û0))` through the rollout adjoint
//! ([`crate::guidance`]), and the next sample: **DDPM**, the guided posterior mean
//! `μ̃(Ũ0, U_k)` plus `σ_k ξ` (no noise on the last step; `noise: false` follows the paper, which
//! adds none); **DDIM** (η = 0) on an evenly spaced sub-sequence of the `K` steps,
//! `U_{k'} = √ᾱ_{k'} Ũ0 + √(1 − ᾱ_{k'}) ε(Ũ0, U_k)`.
//!
//! After the last step, `final_iterations` more guided corrections of `U_0` (each accepted only
//! when it lowers the energy; the step halves otherwise and grows by half after a success) land
//! the anchors precisely: this is our addition to the paper's algorithm and can be switched off
//! (`final_iterations = 0`).
//!
//! Empty agent slots carry fresh noise of the step's level, as in training (their output is not
//! used). Guidance sees only the used slots, in slot order.

use candle_core::{Device, Tensor};
use rand_chacha::ChaCha8Rng;
use rand_chacha::rand_core::SeedableRng;
use rand_distr::{Distribution, StandardNormal};
use v2t_model::kinematics::{Control, State};

use crate::condition::Condition;
use crate::guidance::normalized::{GuidanceStep, guided_posterior_mean, predicted_clean_sample};
use crate::guidance::{EnergyBreakdown, Guidance, GuidanceError, GuidanceWorkspace};
use crate::schedule::NoiseSchedule;
use crate::weights::Model;

/// Clean samples are clipped to this many normalized units.
pub const CLEAN_CLIP: f64 = 6.0;

/// Which reverse process.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Method {
    /// Ancestral DDPM over all `K` steps.
    Ddpm {
        /// Add `σ_k ξ` after each step (the paper does not).
        noise: bool,
    },
    /// Deterministic DDIM over `steps` of the `K` steps.
    Ddim {
        /// Steps taken (1..=K).
        steps: usize,
    },
}

/// Guidance step sizes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GuidanceSchedule {
    /// `η` of every denoising step, normalized units per unit energy.
    pub scale: f64,
    /// Largest L2 norm of one correction, normalized units.
    pub max_step_norm: f64,
    /// Guided corrections of `U_0` after the last step.
    pub final_iterations: usize,
}

impl Default for GuidanceSchedule {
    fn default() -> Self {
        Self { scale: 0.05, max_step_norm: 2.0, final_iterations: 300 }
    }
}

/// Sampler settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SamplerOptions {
    /// Reverse process.
    pub method: Method,
    /// Guidance (used when a [`Guidance`] is given).
    pub guidance: GuidanceSchedule,
}

impl Default for SamplerOptions {
    fn default() -> Self {
        Self { method: Method::Ddpm { noise: true }, guidance: GuidanceSchedule::default() }
    }
}

/// What to sample.
#[derive(Debug, Clone, Copy)]
pub struct Problem<'a> {
    /// The condition (its used slots are the agents).
    pub condition: &'a Condition,
    /// The guidance over the used slots in slot order, or `None` for unguided samples.
    pub guidance: Option<&'a Guidance>,
    /// Initial states of the used slots (guidance rollouts).
    pub x0s: &'a [State],
}

/// One sampled variant.
#[derive(Debug, Clone, PartialEq)]
pub struct Variant {
    /// Controls per used slot, `T` each.
    pub controls: Vec<Vec<Control>>,
    /// Guidance energy of the result (zero without guidance).
    pub energy: EnergyBreakdown,
}

/// What can stop sampling.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SampleError {
    /// Shapes that do not fit the model.
    #[error("sampling: {0}")]
    Shape(String),
    /// The guidance failed.
    #[error(transparent)]
    Guidance(#[from] GuidanceError),
    /// The network produced NaN or infinite numbers.
    #[error("sampling: the network produced non-finite values at step {0}")]
    NonFinite(usize),
    /// The tensor library failed.
    #[error("sampling: {0}")]
    Tensor(String),
}

fn tensor_err(e: candle_core::Error) -> SampleError {
    SampleError::Tensor(e.to_string())
}

/// Copies the used slots of one network-layout sample (`[slot][channel][t]`) into guidance layout
/// (`[agent][t][channel]`), or back.
fn to_guidance(net: &[f64], used: &[usize], steps: usize, out: &mut [f64]) {
    for (agent, &slot) in used.iter().enumerate() {
        for t in 0..steps {
            for c in 0..2 {
                if let (Some(o), Some(v)) =
                    (out.get_mut((agent * steps + t) * 2 + c), net.get((2 * slot + c) * steps + t))
                {
                    *o = *v;
                }
            }
        }
    }
}

fn from_guidance(g: &[f64], used: &[usize], steps: usize, net: &mut [f64]) {
    for (agent, &slot) in used.iter().enumerate() {
        for t in 0..steps {
            for c in 0..2 {
                if let (Some(o), Some(v)) =
                    (net.get_mut((2 * slot + c) * steps + t), g.get((agent * steps + t) * 2 + c))
                {
                    *o = *v;
                }
            }
        }
    }
}

/// The reverse steps to take, from `K` down to 1.
fn step_sequence(method: Method, k_max: usize) -> Vec<usize> {
    match method {
        Method::Ddpm { .. } => (1..=k_max).rev().collect(),
        Method::Ddim { steps } => {
            let n = steps.clamp(1, k_max);
            let mut seq: Vec<usize> = (0..n).map(|i| k_max - (i * k_max) / n).collect();
            seq.dedup();
            seq
        }
    }
}

/// Samples `variants` joint control sequences for `problem`, seeded by `seed`.
pub fn sample(
    model: &Model,
    problem: &Problem<'_>,
    variants: usize,
    seed: u64,
    options: &SamplerOptions,
) -> Result<Vec<Variant>, SampleError> {
    let cfg = *model.denoiser.config();
    let used: Vec<usize> =
        (0..cfg.slots).filter(|s| problem.condition.slots.get(*s).is_some_and(Option::is_some)).collect();
    if used.is_empty() {
        return Err(SampleError::Shape("the condition has no agent".into()));
    }
    if problem.condition.slots.len() > cfg.slots {
        return Err(SampleError::Shape(format!(
            "{} agents, the model has {} slots",
            problem.condition.slots.len(),
            cfg.slots
        )));
    }
    if let Some(g) = problem.guidance {
        let gc = g.config();
        if gc.agents != used.len() || gc.steps != cfg.steps || problem.x0s.len() != used.len() {
            return Err(SampleError::Shape(format!(
                "guidance for {} agents × {} steps with {} initial states; the sample has {} agents × {} steps",
                gc.agents,
                gc.steps,
                problem.x0s.len(),
                used.len(),
                cfg.steps
            )));
        }
    }
    let b = variants.max(1);
    let per = cfg.sample_len();
    let schedule = NoiseSchedule::cosine(cfg.diffusion_steps);
    let norm = model.meta.normalization;
    let dev = Device::Cpu;
    let cond_one = problem.condition.features(&cfg);
    let time_one = problem.condition.time_features(&cfg);
    let cond = Tensor::from_vec(cond_one.repeat(b), (b, cfg.condition_len()), &dev).map_err(tensor_err)?;
    let time =
        Tensor::from_vec(time_one.repeat(b), (b, cfg.time_channels(), cfg.patches()), &dev).map_err(tensor_err)?;
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut normal = move || -> f64 { StandardNormal.sample(&mut rng) };
    let mut u: Vec<f64> = (0..b * per).map(|_| normal()).collect();
    let mut eps = vec![0.0; per];
    let mut u0 = vec![0.0; per];
    let glen = 2 * used.len() * cfg.steps;
    let (mut g_in, mut g_out) = (vec![0.0; glen], vec![0.0; glen]);
    let mut ws = problem.guidance.map(GuidanceWorkspace::new);
    let mut next = vec![0.0; per];
    let used_mask: Vec<bool> = (0..per).map(|i| used.contains(&(i / (2 * cfg.steps)))).collect();
    let seq = step_sequence(options.method, schedule.steps());
    let step = GuidanceStep { scale: options.guidance.scale, max_step_norm: options.guidance.max_step_norm };
    let mut u0_all = vec![0.0; b * per];
    for (i, &k) in seq.iter().enumerate() {
        let k_prev = seq.get(i + 1).copied().unwrap_or(0);
        // Empty slots: noise of this step's level, as the network saw in training.
        let level = (1.0 - schedule.alpha_bar(k)).sqrt();
        for (v, used) in u.iter_mut().zip(used_mask.iter().cycle()) {
            if !used {
                *v = level * normal();
            }
        }
        let input =
            Tensor::from_vec(u.iter().map(|v| *v as f32).collect::<Vec<f32>>(), (b, 2 * cfg.slots, cfg.steps), &dev)
                .map_err(tensor_err)?;
        let out = model.denoiser.forward(&input, &vec![k; b], &cond, &time).map_err(tensor_err)?;
        let out: Vec<f32> = out.flatten_all().and_then(|t| t.to_vec1()).map_err(tensor_err)?;
        if out.iter().any(|v| !v.is_finite()) {
            return Err(SampleError::NonFinite(k));
        }
        for v in 0..b {
            let (Some(uk), Some(e), Some(u0v)) = (
                u.get(v * per..(v + 1) * per),
                out.get(v * per..(v + 1) * per),
                u0_all.get_mut(v * per..(v + 1) * per),
            ) else {
                continue;
            };
            for (d, s) in eps.iter_mut().zip(e) {
                *d = f64::from(*s);
            }
            predicted_clean_sample(schedule.alpha_bar(k), uk, &eps, &mut u0)?;
            for z in &mut u0 {
                *z = z.clamp(-CLEAN_CLIP, CLEAN_CLIP);
            }
            if let (Some(g), Some(ws)) = (problem.guidance, ws.as_mut()) {
                to_guidance(&u0, &used, cfg.steps, &mut g_in);
                g.guide_clean_sample(ws, &norm, &step, problem.x0s, &g_in, &mut g_out)?;
                from_guidance(&g_out, &used, cfg.steps, &mut u0);
            }
            u0v.copy_from_slice(&u0);
            match options.method {
                Method::Ddpm { noise } => {
                    guided_posterior_mean(
                        schedule.alpha_bar(k),
                        schedule.alpha_bar(k - 1),
                        schedule.beta(k),
                        &u0,
                        uk,
                        &mut next,
                    )?;
                    if noise && k > 1 {
                        let sigma = schedule.ddpm_sigma(k);
                        for x in &mut next {
                            *x += sigma * normal();
                        }
                    }
                }
                Method::Ddim { .. } => {
                    for ((x, a), c) in next.iter_mut().zip(&u0).zip(uk) {
                        *x = schedule.ddim_step(k, k_prev, *a, *c);
                    }
                }
            }
            if let Some(dst) = u.get_mut(v * per..(v + 1) * per) {
                dst.copy_from_slice(&next);
            }
        }
    }
    let mut variants_out = Vec::with_capacity(b);
    for v in 0..b {
        let Some(z) = u0_all.get(v * per..(v + 1) * per) else { continue };
        to_guidance(z, &used, cfg.steps, &mut g_in);
        let energy = match (problem.guidance, ws.as_mut()) {
            (Some(g), Some(ws)) => refine(g, ws, &norm, &options.guidance, problem.x0s, &mut g_in, &mut g_out)?,
            _ => EnergyBreakdown::default(),
        };
        let controls = (0..used.len())
            .map(|a| {
                (0..cfg.steps)
                    .map(|t| {
                        let i = (a * cfg.steps + t) * 2;
                        norm.denormalize([g_in.get(i).copied().unwrap_or(0.0), g_in.get(i + 1).copied().unwrap_or(0.0)])
                    })
                    .collect()
            })
            .collect();
        variants_out.push(Variant { controls, energy });
    }
    Ok(variants_out)
}

/// The final guided corrections of `z` (guidance layout), in place; returns the final energy.
fn refine(
    g: &Guidance,
    ws: &mut GuidanceWorkspace,
    norm: &crate::guidance::normalized::ControlNormalization,
    schedule: &GuidanceSchedule,
    x0s: &[State],
    z: &mut [f64],
    scratch: &mut [f64],
) -> Result<EnergyBreakdown, SampleError> {
    let mut scale = schedule.scale;
    // `current` is the energy at `z`; `scratch` holds the candidate `z − step` for the present scale.
    let mut current = g.guide_clean_sample(
        ws,
        norm,
        &GuidanceStep { scale, max_step_norm: schedule.max_step_norm },
        x0s,
        z,
        scratch,
    )?;
    let mut trial = vec![0.0; z.len()];
    for _ in 0..schedule.final_iterations {
        if current.energy.total <= 1e-9 {
            break;
        }
        let step = GuidanceStep { scale, max_step_norm: schedule.max_step_norm };
        let next = g.guide_clean_sample(ws, norm, &step, x0s, scratch, &mut trial)?;
        if next.energy.total < current.energy.total {
            z.copy_from_slice(scratch);
            scratch.copy_from_slice(&trial);
            current = next;
            scale *= 1.5;
        } else {
            scale *= 0.5;
            let step = GuidanceStep { scale, max_step_norm: schedule.max_step_norm };
            g.guide_clean_sample(ws, norm, &step, x0s, z, scratch)?;
        }
    }
    Ok(current.energy)
}
