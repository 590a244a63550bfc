//! Training the denoiser on synthetic and recorded corpora: windows of `T` steps around each
//! episode's interaction, a held-out split by episode (synthetic) or by recording (recorded),
//! ε-prediction with AdamW, from scratch or on from saved weights.
//!
//! **Windows.** Slot 0 is the episode's actor, slot 1 the other vehicle of its mined interaction,
//! slot 2 a third vehicle if any. Each agent passes the conflict point at the time its trajectory
//! comes closest to it; a window (start every `stride` steps) is kept when both passage times lie
//! at least 0.5 s inside it. Its condition is built from the states at the window's start, the
//! agents' routes (the topology library's maneuvers they drove) and the conflict point with the
//! passage times and order.
//!
//! **Recorded windows.** Recordings seldom hold two vehicles for the whole horizon (NGSIM's
//! CommonRoad excerpts are 4–10 s long). A recorded window starts where both conflict vehicles are
//! recorded, holds at least [`MIN_WINDOW_STEPS`] steps of each, and masks the steps after a
//! vehicle's data ends out of the loss; its routes are the lanes the vehicles ended in. Recorded
//! windows start at every step (synthetic ones every `stride` steps).
//!
//! **Split.** Synthetic episodes whose index is a multiple of 10 are held out (10 %), so no
//! held-out window shares an episode with a training window; a recorded corpus is held out whole
//! or not at all (its files are the recordings: the split is by recording).
//!
//! **Loss.** `‖ε − ε_θ(√ᾱ_k U_0 + √(1 − ᾱ_k) ε, k, c)‖²` over the used slots, `k` uniform in
//! `1..=K`; AdamW (weight decay 1e-4), learning rate warmed up over 100 steps then cosine-decayed to
//! a tenth. The held-out loss is measured on fixed `(window, k, ε)` triples.

use std::collections::HashMap;

use candle_core::{DType, Device, Tensor};
use candle_nn::{Optimizer, VarBuilder, VarMap};
use rand_chacha::ChaCha8Rng;
use rand_chacha::rand_core::{Rng, SeedableRng};
use rand_distr::{Distribution, StandardNormal};
use v2t_map::library::TopologyLibrary;
use v2t_model::geometry::Point2;
use v2t_model::kinematics::{Control, State};
use v2t_model::path::ReferencePath;

use crate::condition::{Condition, KindClass, PassingOrder, SlotCondition, route_ahead};
use crate::denoiser::{Denoiser, DenoiserConfig};
use crate::guidance::normalized::ControlNormalization;
use crate::schedule::NoiseSchedule;
use crate::synth::SyntheticEpisode;
use crate::weights::{ModelMeta, TrainingRecord};

/// Passage times must lie this far inside a window, s.
const WINDOW_MARGIN_S: f64 = 0.5;

/// One training sample.
#[derive(Debug, Clone, PartialEq)]
pub struct Window {
    /// Index of its episode in the corpus.
    pub episode: usize,
    /// Episode step it starts at.
    pub start_step: usize,
    /// Normalized controls `[slot][channel][step]`, zero for empty slots.
    pub z0: Vec<f32>,
    /// 1 where `z0` is data, 0 for empty slots.
    pub mask: Vec<f32>,
    /// Condition vector.
    pub cond: Vec<f32>,
    /// Time-aligned features `[channel][patch]`.
    pub time: Vec<f32>,
    /// The condition the features encode.
    pub condition: Condition,
    /// The recorded controls of the used slots, in slot order.
    pub controls: Vec<Vec<Control>>,
    /// Where each used slot is at the end of its data.
    pub end_positions: Vec<Point2>,
    /// Steps of data of each used slot (the horizon, or fewer for a recording that ends early).
    pub data_steps: Vec<usize>,
}

/// What can go wrong preparing data or training.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum TrainError {
    /// The corpus gave no usable window.
    #[error("no training windows: {0}")]
    NoData(String),
    /// A setting out of range.
    #[error("training option {field}: {reason}")]
    Option {
        /// Which option.
        field: &'static str,
        /// Why.
        reason: String,
    },
    /// The loss became NaN or infinite.
    #[error("training diverged at step {step} (loss {loss})")]
    Diverged {
        /// Optimizer step.
        step: usize,
        /// The loss.
        loss: f64,
    },
    /// The tensor library failed.
    #[error("tensor: {0}")]
    Tensor(String),
}

fn tensor_err(e: candle_core::Error) -> TrainError {
    TrainError::Tensor(e.to_string())
}

/// The time an agent's trajectory comes closest to `p`, s from its first state.
pub fn passage_time_s(states: &[State], p: Point2, dt_s: f64) -> Option<f64> {
    let mut best: Option<(f64, f64)> = None;
    for (k, w) in states.windows(2).enumerate() {
        let [a, b] = w else { continue };
        let (pa, pb) = (a.position(), b.position());
        let d = pb.sub(pa);
        let len2 = d.dot(d);
        let f = if len2 > 0.0 { (p.sub(pa).dot(d) / len2).clamp(0.0, 1.0) } else { 0.0 };
        let dist = pa.lerp(pb, f).dist(p);
        if best.is_none_or(|(bd, _)| dist < bd) {
            best = Some((dist, (k as f64 + f) * dt_s));
        }
    }
    best.map(|(_, t)| t)
}

/// Per-channel mean and standard deviation of the controls of `episodes`.
pub fn fit_normalization<'a>(controls: impl Iterator<Item = &'a Control>) -> ControlNormalization {
    let (mut n, mut sa, mut sw, mut qa, mut qw) = (0.0f64, 0.0, 0.0, 0.0, 0.0);
    for u in controls {
        n += 1.0;
        sa += u.accel_mps2;
        sw += u.yaw_rate_radps;
        qa += u.accel_mps2 * u.accel_mps2;
        qw += u.yaw_rate_radps * u.yaw_rate_radps;
    }
    if n < 2.0 {
        return ControlNormalization::default();
    }
    let (ma, mw) = (sa / n, sw / n);
    let std = |q: f64, m: f64, floor: f64| ((q / n - m * m).max(0.0)).sqrt().max(floor);
    ControlNormalization {
        accel_mean_mps2: ma,
        accel_scale_mps2: std(qa, ma, 0.05),
        yaw_rate_mean_radps: mw,
        yaw_rate_scale_radps: std(qw, mw, 0.005),
    }
}

/// Flat normalized controls `[slot][channel][step]` of one slot's controls into `out`.
pub fn write_slot(out: &mut [f32], slot: usize, steps: usize, controls: &[Control], norm: &ControlNormalization) {
    for (t, u) in controls.iter().take(steps).enumerate() {
        let [za, zw] = norm.normalize(*u);
        if let Some(v) = out.get_mut(2 * slot * steps + t) {
            *v = za as f32;
        }
        if let Some(v) = out.get_mut((2 * slot + 1) * steps + t) {
            *v = zw as f32;
        }
    }
}

/// One vehicle of a training episode, borrowed from a synthetic or a recorded corpus.
#[derive(Debug, Clone)]
pub struct TrainingAgent<'a> {
    /// Its id.
    pub id: &'a str,
    /// Episode step of `states[0]`.
    pub start_step: usize,
    /// States, one more than controls.
    pub states: &'a [State],
    /// Controls.
    pub controls: &'a [Control],
    /// Its route (`None`: the agent cannot fill a slot).
    pub route: Option<ReferencePath>,
}

/// One episode as training sees it: an interaction, its vehicles, its split.
#[derive(Debug, Clone)]
pub struct TrainingEpisode<'a> {
    /// Synthetic episode id or recording id (the held-out split keeps groups whole).
    pub group: String,
    /// Whether it belongs to the held-out split.
    pub heldout: bool,
    /// Time step, s.
    pub dt_s: f64,
    /// The interaction.
    pub mined: &'a crate::mining::Interaction,
    /// The vehicles.
    pub agents: Vec<TrainingAgent<'a>>,
    /// Whether every window must hold every agent for the whole horizon (the synthetic corpus);
    /// otherwise a window may end an agent's data early ([`MIN_WINDOW_STEPS`] at least for the two
    /// conflict vehicles) and the rest of its steps are masked out of the loss.
    pub full_windows_only: bool,
}

/// Recorded data shorter than the horizon: the two conflict vehicles need at least this many steps
/// in a window.
pub const MIN_WINDOW_STEPS: usize = 30;

/// The synthetic episodes as training episodes (routes from `library`); with `hold_out` those
/// whose index is a multiple of 10 are held out ([`is_heldout`]), else all train.
pub fn synthetic_episodes<'a>(
    episodes: &'a [SyntheticEpisode],
    library: &TopologyLibrary,
    hold_out: bool,
) -> Vec<TrainingEpisode<'a>> {
    let routes = routes_of(library);
    episodes
        .iter()
        .enumerate()
        .map(|(i, e)| TrainingEpisode {
            group: e.id.clone(),
            heldout: hold_out && is_heldout(i),
            dt_s: e.dt_s,
            mined: &e.mined,
            agents: e
                .agents
                .iter()
                .map(|a| TrainingAgent {
                    id: &a.id,
                    start_step: 0,
                    states: &a.states,
                    controls: &a.controls,
                    route: routes.get(&a.route_id).cloned(),
                })
                .collect(),
            full_windows_only: true,
        })
        .collect()
}

/// The recorded episodes sampled at [`crate::synth::DT_S`] as training episodes, all in the split
/// `heldout`; the others (another sampling period) are counted in the second number.
pub fn recorded_episodes(
    episodes: &[crate::recorded::RecordedEpisode],
    heldout: bool,
) -> (Vec<TrainingEpisode<'_>>, usize) {
    let mut out = Vec::new();
    let mut skipped = 0;
    for e in episodes {
        if (e.dt_s - crate::synth::DT_S).abs() > 1e-9 {
            skipped += 1;
            continue;
        }
        let t0 = e.agents.iter().map(|a| a.start_s).fold(f64::INFINITY, f64::min);
        let agents = e
            .agents
            .iter()
            .map(|a| TrainingAgent {
                id: &a.id,
                start_step: ((a.start_s - t0) / e.dt_s).round().max(0.0) as usize,
                states: &a.states,
                controls: &a.controls,
                route: ReferencePath::from_points(&a.route).ok(),
            })
            .collect();
        // The interaction's times are recording times: windows count from the episode's start.
        out.push(TrainingEpisode {
            group: e.recording.clone(),
            heldout,
            dt_s: e.dt_s,
            mined: &e.mined,
            agents,
            full_windows_only: false,
        });
    }
    (out, skipped)
}

/// The windows of one episode (see the module doc).
pub fn episode_windows(
    index: usize,
    episode: &TrainingEpisode<'_>,
    cfg: &DenoiserConfig,
    norm: &ControlNormalization,
    stride: usize,
) -> Vec<Window> {
    let dt = episode.dt_s;
    let mined = episode.mined;
    let find = |id: &str| episode.agents.iter().position(|a| a.id == id);
    let (Some(actor), Some(other)) = (find(&mined.actor), find(&mined.other)) else { return Vec::new() };
    let mut order = vec![actor, other];
    order.extend((0..episode.agents.len()).filter(|i| *i != actor && *i != other));
    order.truncate(cfg.slots);
    // Each agent's data: episode steps [start, end) of controls.
    let span = |i: usize| episode.agents.get(i).map(|a| (a.start_step, a.start_step + a.controls.len()));
    let (Some(span0), Some(span1)) = (span(actor), span(other)) else { return Vec::new() };
    let first = span0.0.max(span1.0);
    let last_end = if episode.full_windows_only {
        order.iter().filter_map(|&i| span(i)).map(|s| s.1).min().unwrap_or(0)
    } else {
        span0.1.min(span1.1)
    };
    let min_steps = if episode.full_windows_only { cfg.steps } else { MIN_WINDOW_STEPS.min(cfg.steps) };
    // Passage times in episode seconds.
    let pass: Vec<Option<f64>> = order
        .iter()
        .take(2)
        .map(|&i| {
            let a = episode.agents.get(i)?;
            passage_time_s(a.states, mined.conflict_point, dt).map(|t| t + a.start_step as f64 * dt)
        })
        .collect();
    let mut out = Vec::new();
    let mut w0 = first;
    while w0 + min_steps <= last_end {
        let t0 = w0 as f64 * dt;
        // Steps of data per slot in this window.
        let lengths: Vec<Option<usize>> = order
            .iter()
            .map(|&i| {
                let (a, b) = span(i)?;
                (a <= w0 && w0 < b).then(|| (b - w0).min(cfg.steps)).filter(|n| *n >= min_steps)
            })
            .collect();
        let inside = pass.iter().zip(&lengths).all(|(p, n)| {
            let data_s = n.map_or(0.0, |n| n as f64 * dt);
            p.is_some_and(|t| t - t0 >= WINDOW_MARGIN_S && t - t0 <= data_s - WINDOW_MARGIN_S)
        });
        if inside {
            let mut z0 = vec![0.0f32; cfg.sample_len()];
            let mut mask = vec![0.0f32; cfg.sample_len()];
            let mut slots = vec![None; cfg.slots];
            let mut recorded = Vec::new();
            let mut end_positions = Vec::new();
            let mut data_steps = Vec::new();
            for (slot, (&i, n)) in order.iter().zip(&lengths).enumerate() {
                let (Some(agent), Some(n)) = (episode.agents.get(i), n) else { continue };
                let local = w0 - agent.start_step;
                let (Some(start), Some(controls)) = (agent.states.get(local), agent.controls.get(local..local + n))
                else {
                    continue;
                };
                let Some(route) = &agent.route else { continue };
                write_slot(&mut z0, slot, cfg.steps, controls, norm);
                recorded.push(controls.to_vec());
                end_positions.push(agent.states.get(local + n).map_or(start.position(), State::position));
                data_steps.push(*n);
                for ch in 0..2 {
                    for v in mask.iter_mut().skip((2 * slot + ch) * cfg.steps).take(*n) {
                        *v = 1.0;
                    }
                }
                let anchor = pass.get(slot).copied().flatten().map(|t| (mined.conflict_point, t - t0));
                let order = (slot < 2)
                    .then(|| if agent.id == mined.first { PassingOrder::First } else { PassingOrder::Second });
                if let Some(s) = slots.get_mut(slot) {
                    *s = Some(SlotCondition { start: *start, route_local: route_ahead(route, start), anchor, order });
                }
            }
            // Both conflict vehicles must fill their slots.
            if slots.first().is_some_and(Option::is_some) && slots.get(1).is_some_and(Option::is_some) {
                let condition = Condition { slots, kind: KindClass::of_mined(mined.kind) };
                out.push(Window {
                    episode: index,
                    start_step: w0,
                    z0,
                    mask,
                    cond: condition.features(cfg),
                    time: condition.time_features(cfg),
                    condition,
                    controls: recorded,
                    end_positions,
                    data_steps,
                });
            }
        }
        // Recorded data are scarce: their windows start at every step.
        w0 += if episode.full_windows_only { stride.max(1) } else { 1 };
    }
    out
}

/// Training and held-out windows of a corpus, and the normalization fitted on the training part.
#[derive(Debug, Clone)]
pub struct Dataset {
    /// Architecture the windows are shaped for.
    pub config: DenoiserConfig,
    /// Fitted on the training episodes (or taken from the weights training starts from).
    pub normalization: ControlNormalization,
    /// Training windows.
    pub train: Vec<Window>,
    /// Held-out windows.
    pub heldout: Vec<Window>,
    /// Held-out episode indices.
    pub heldout_episodes: Vec<usize>,
}

/// Whether a synthetic episode belongs to the held-out split (index a multiple of 10).
pub fn is_heldout(index: usize) -> bool {
    index.is_multiple_of(10)
}

/// The routes (maneuver paths) of a topology library by maneuver id.
pub fn routes_of(library: &TopologyLibrary) -> HashMap<String, ReferencePath> {
    let mut out = HashMap::new();
    for f in &library.fragments {
        for m in &f.maneuvers {
            if let Ok(p) = ReferencePath::from_points(&m.path) {
                out.insert(m.id.clone(), p);
            }
        }
    }
    out
}

impl Dataset {
    /// Windows of every synthetic episode (start every `stride` steps); routes from `library`.
    pub fn build(
        episodes: &[SyntheticEpisode],
        library: &TopologyLibrary,
        config: DenoiserConfig,
        stride: usize,
    ) -> Result<Self, TrainError> {
        Self::build_from(&synthetic_episodes(episodes, library, true), config, stride, None)
    }

    /// Windows of training episodes of any source (start every `stride` steps); the normalization
    /// is fitted on the training split's controls unless given.
    pub fn build_from(
        episodes: &[TrainingEpisode<'_>],
        config: DenoiserConfig,
        stride: usize,
        normalization: Option<ControlNormalization>,
    ) -> Result<Self, TrainError> {
        config.check().map_err(|e| TrainError::Option { field: "config", reason: e.to_string() })?;
        let normalization = normalization.unwrap_or_else(|| {
            fit_normalization(
                episodes.iter().filter(|e| !e.heldout).flat_map(|e| e.agents.iter().flat_map(|a| a.controls.iter())),
            )
        });
        let (mut train, mut heldout, mut heldout_episodes) = (Vec::new(), Vec::new(), Vec::new());
        for (i, e) in episodes.iter().enumerate() {
            let w = episode_windows(i, e, &config, &normalization, stride);
            if e.heldout {
                heldout_episodes.push(i);
                heldout.extend(w);
            } else {
                train.extend(w);
            }
        }
        if train.is_empty() || heldout.is_empty() {
            return Err(TrainError::NoData(format!(
                "{} training and {} held-out windows of {} steps from {} episodes",
                train.len(),
                heldout.len(),
                config.steps,
                episodes.len()
            )));
        }
        Ok(Self { config, normalization, train, heldout, heldout_episodes })
    }
}

/// Training settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrainOptions {
    /// Optimizer steps.
    pub steps: usize,
    /// Windows per step.
    pub batch: usize,
    /// Peak learning rate.
    pub learning_rate: f64,
    /// Seed of initialization, batches and noise.
    pub seed: u64,
    /// Held-out loss every this many steps (and at the end).
    pub eval_every: usize,
    /// Fixed held-out triples evaluated.
    pub eval_samples: usize,
}

impl Default for TrainOptions {
    fn default() -> Self {
        Self { steps: 5000, batch: 64, learning_rate: 1e-3, seed: 1, eval_every: 250, eval_samples: 512 }
    }
}

/// One line of the metrics file.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct TrainMetrics {
    /// Optimizer steps done.
    pub step: usize,
    /// Mean training loss since the last line.
    pub train_loss: f64,
    /// Held-out loss, when measured at this step.
    pub heldout_loss: Option<f64>,
    /// Learning rate at this step.
    pub learning_rate: f64,
    /// Seconds since training started.
    pub elapsed_s: f64,
}

/// A trainer: the variables, the network and the optimizer.
pub struct Trainer {
    varmap: VarMap,
    denoiser: Denoiser,
    optimizer: candle_nn::AdamW,
    schedule: NoiseSchedule,
    rng: ChaCha8Rng,
    options: TrainOptions,
    step: usize,
    eval_set: Vec<(usize, usize, u64)>,
}

impl std::fmt::Debug for Trainer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Trainer").field("step", &self.step).field("options", &self.options).finish_non_exhaustive()
    }
}

/// candle's CPU generator cannot be seeded: every variable is drawn again from a seeded normal
/// with the mean and spread of candle's initialization (constants such as norm gains stay).
fn reseed(varmap: &VarMap, seed: u64) -> candle_core::Result<()> {
    let data = varmap.data().lock().map_err(|_| candle_core::Error::Msg("variable map lock poisoned".into()))?;
    let mut names: Vec<&String> = data.keys().collect();
    names.sort();
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    for name in names {
        let Some(var) = data.get(name) else { continue };
        let values = var.as_tensor().flatten_all()?.to_vec1::<f32>()?;
        let n = values.len().max(1) as f64;
        let mean = values.iter().map(|v| f64::from(*v)).sum::<f64>() / n;
        let std = (values.iter().map(|v| (f64::from(*v) - mean).powi(2)).sum::<f64>() / n).sqrt();
        if std == 0.0 {
            continue;
        }
        let drawn: Vec<f32> = values
            .iter()
            .map(|_| {
                let z: f64 = StandardNormal.sample(&mut rng);
                (mean + std * z) as f32
            })
            .collect::<Vec<f32>>();
        var.set(&Tensor::from_vec(drawn, var.as_tensor().dims(), &Device::Cpu)?)?;
    }
    Ok(())
}

/// A batch of windows as tensors: `(z0, mask, cond, time)`.
fn batch_tensors(windows: &[&Window], cfg: &DenoiserConfig) -> candle_core::Result<(Tensor, Tensor, Tensor, Tensor)> {
    let b = windows.len();
    let dev = Device::Cpu;
    let cat = |f: &dyn Fn(&Window) -> &[f32]| windows.iter().flat_map(|w| f(w).iter().copied()).collect::<Vec<f32>>();
    let z0 = Tensor::from_vec(cat(&|w| &w.z0), (b, 2 * cfg.slots, cfg.steps), &dev)?;
    let mask = Tensor::from_vec(cat(&|w| &w.mask), (b, 2 * cfg.slots, cfg.steps), &dev)?;
    let cond = Tensor::from_vec(cat(&|w| &w.cond), (b, cfg.condition_len()), &dev)?;
    let time = Tensor::from_vec(cat(&|w| &w.time), (b, cfg.time_channels(), cfg.patches()), &dev)?;
    Ok((z0, mask, cond, time))
}

impl Trainer {
    /// A fresh network for `config`.
    pub fn new(config: DenoiserConfig, options: TrainOptions) -> Result<Self, TrainError> {
        Self::check(&options)?;
        let varmap = VarMap::new();
        let vb = VarBuilder::from_varmap(&varmap, DType::F32, &Device::Cpu);
        let denoiser = Denoiser::new(config, vb).map_err(tensor_err)?;
        reseed(&varmap, options.seed).map_err(tensor_err)?;
        Self::with(varmap, denoiser, options)
    }

    /// A trainer that goes on from the weights in `bytes` (a weights file): their architecture, and
    /// their normalization, which the training data must then use (returned).
    pub fn from_weights(bytes: &[u8], options: TrainOptions) -> Result<(Self, ControlNormalization), TrainError> {
        Self::check(&options)?;
        let (model, varmap) = crate::weights::from_bytes_with_variables(bytes)
            .map_err(|e| TrainError::Option { field: "init", reason: e.to_string() })?;
        let normalization = model.meta.normalization;
        Ok((Self::with(varmap, model.denoiser, options)?, normalization))
    }

    fn check(options: &TrainOptions) -> Result<(), TrainError> {
        if options.steps == 0 || options.batch == 0 || options.eval_every == 0 {
            return Err(TrainError::Option { field: "steps/batch/eval_every", reason: "must be > 0".into() });
        }
        if !(options.learning_rate > 0.0 && options.learning_rate < 1.0) {
            return Err(TrainError::Option { field: "learning_rate", reason: "must lie in (0, 1)".into() });
        }
        Ok(())
    }

    fn with(varmap: VarMap, denoiser: Denoiser, options: TrainOptions) -> Result<Self, TrainError> {
        let config = *denoiser.config();
        let params = candle_nn::ParamsAdamW { lr: options.learning_rate, weight_decay: 1e-4, ..Default::default() };
        let optimizer = candle_nn::AdamW::new(varmap.all_vars(), params).map_err(tensor_err)?;
        Ok(Self {
            varmap,
            denoiser,
            optimizer,
            schedule: NoiseSchedule::cosine(config.diffusion_steps),
            rng: ChaCha8Rng::seed_from_u64(options.seed),
            options,
            step: 0,
            eval_set: Vec::new(),
        })
    }

    /// Number of trainable numbers.
    pub fn parameters(&self) -> usize {
        self.varmap.all_vars().iter().map(|v| v.as_tensor().elem_count()).sum()
    }

    /// The variables (for saving).
    pub fn varmap(&self) -> &VarMap {
        &self.varmap
    }

    /// The network being trained.
    pub fn denoiser(&self) -> &Denoiser {
        &self.denoiser
    }

    /// Steps done.
    pub fn step(&self) -> usize {
        self.step
    }

    fn learning_rate(&self) -> f64 {
        let warm = 100.0;
        let s = self.step as f64;
        let total = self.options.steps as f64;
        let peak = self.options.learning_rate;
        if s < warm {
            peak * (s + 1.0) / warm
        } else {
            let f = ((s - warm) / (total - warm).max(1.0)).clamp(0.0, 1.0);
            peak * (0.1 + 0.9 * 0.5 * (1.0 + (std::f64::consts::PI * f).cos()))
        }
    }

    /// The noised batch, the steps and the noise for `windows` with noise from `rng`.
    fn noised(&self, z0: &Tensor, steps: &[usize], rng: &mut ChaCha8Rng) -> candle_core::Result<(Tensor, Tensor)> {
        let dims = z0.dims3()?;
        let per = dims.1 * dims.2;
        let noise: Vec<f32> = (0..dims.0 * per).map(|_| StandardNormal.sample(rng)).collect();
        let eps = Tensor::from_vec(noise, dims, &Device::Cpu)?;
        let a: Vec<f32> = steps.iter().map(|&k| self.schedule.alpha_bar(k).sqrt() as f32).collect();
        let s: Vec<f32> = steps.iter().map(|&k| (1.0 - self.schedule.alpha_bar(k)).sqrt() as f32).collect();
        let a = Tensor::from_vec(a, (dims.0, 1, 1), &Device::Cpu)?;
        let s = Tensor::from_vec(s, (dims.0, 1, 1), &Device::Cpu)?;
        let zk = (z0.broadcast_mul(&a)? + eps.broadcast_mul(&s)?)?;
        Ok((zk, eps))
    }

    fn loss(&self, windows: &[&Window], steps: &[usize], rng: &mut ChaCha8Rng) -> candle_core::Result<Tensor> {
        let cfg = self.denoiser.config();
        let (z0, mask, cond, time) = batch_tensors(windows, cfg)?;
        let (zk, eps) = self.noised(&z0, steps, rng)?;
        let pred = self.denoiser.forward(&zk, steps, &cond, &time)?;
        let err = ((pred - eps)?.sqr()? * &mask)?.sum_all()?;
        err / f64::from(mask.sum_all()?.to_scalar::<f32>()?.max(1.0))
    }

    /// One optimizer step on a random batch of `data.train`; returns the batch loss.
    pub fn train_step(&mut self, data: &Dataset) -> Result<f64, TrainError> {
        let n = data.train.len();
        let k_max = self.schedule.steps();
        let mut picks = Vec::with_capacity(self.options.batch);
        let mut steps = Vec::with_capacity(self.options.batch);
        for _ in 0..self.options.batch {
            let i = (self.rng.next_u64() % n as u64) as usize;
            if let Some(w) = data.train.get(i) {
                picks.push(w);
                steps.push(1 + (self.rng.next_u64() % k_max as u64) as usize);
            }
        }
        let mut rng = ChaCha8Rng::seed_from_u64(self.rng.next_u64());
        let loss = self.loss(&picks, &steps, &mut rng).map_err(tensor_err)?;
        let value = f64::from(loss.to_scalar::<f32>().map_err(tensor_err)?);
        if !value.is_finite() {
            return Err(TrainError::Diverged { step: self.step, loss: value });
        }
        let mut params = self.optimizer.params().clone();
        params.lr = self.learning_rate();
        self.optimizer.set_params(params);
        self.optimizer.backward_step(&loss).map_err(tensor_err)?;
        self.step += 1;
        Ok(value)
    }

    /// Loss on fixed held-out `(window, k, noise seed)` triples (the same every call).
    pub fn heldout_loss(&mut self, data: &Dataset) -> Result<f64, TrainError> {
        if self.eval_set.is_empty() {
            let mut rng = ChaCha8Rng::seed_from_u64(0x5eed_e7a1);
            let k_max = self.schedule.steps();
            let count = self.options.eval_samples.min(data.heldout.len() * 4).max(1);
            self.eval_set = (0..count)
                .map(|j| {
                    let w = (rng.next_u64() % data.heldout.len().max(1) as u64) as usize;
                    (w, 1 + j % k_max, rng.next_u64())
                })
                .collect();
        }
        let mut total = 0.0;
        let mut count = 0.0;
        for chunk in self.eval_set.chunks(128) {
            let windows: Vec<&Window> = chunk.iter().filter_map(|(w, _, _)| data.heldout.get(*w)).collect();
            let steps: Vec<usize> = chunk.iter().map(|(_, k, _)| *k).collect();
            let seed = chunk.first().map_or(0, |c| c.2);
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            let loss = self.loss(&windows, &steps, &mut rng).map_err(tensor_err)?;
            total += f64::from(loss.to_scalar::<f32>().map_err(tensor_err)?) * windows.len() as f64;
            count += windows.len() as f64;
        }
        Ok(total / count.max(1.0))
    }

    /// Trains for the configured steps; `report` gets a metrics line every `eval_every` steps
    /// (with the held-out loss) and may save a checkpoint. Returns the last held-out loss.
    pub fn run(&mut self, data: &Dataset, mut report: impl FnMut(&Trainer, &TrainMetrics)) -> Result<f64, TrainError> {
        let started = std::time::Instant::now();
        let mut sum = 0.0;
        let mut count = 0usize;
        let mut last = f64::NAN;
        while self.step < self.options.steps {
            sum += self.train_step(data)?;
            count += 1;
            let at_eval = self.step.is_multiple_of(self.options.eval_every) || self.step == self.options.steps;
            if at_eval {
                last = self.heldout_loss(data)?;
                let m = TrainMetrics {
                    step: self.step,
                    train_loss: sum / count.max(1) as f64,
                    heldout_loss: Some(last),
                    learning_rate: self.learning_rate(),
                    elapsed_s: started.elapsed().as_secs_f64(),
                };
                report(self, &m);
                sum = 0.0;
                count = 0;
            }
        }
        Ok(last)
    }

    /// The metadata to save with these weights.
    /// `synthetic`: whether every training window came from simulated data.
    pub fn meta(
        &self,
        data: &Dataset,
        command: String,
        source: String,
        synthetic: bool,
        heldout_loss: f64,
    ) -> ModelMeta {
        ModelMeta {
            config: *self.denoiser.config(),
            normalization: data.normalization,
            training: TrainingRecord {
                command,
                data: source,
                synthetic,
                train_windows: data.train.len(),
                heldout_windows: data.heldout.len(),
                steps: self.step,
                batch: self.options.batch,
                seed: self.options.seed,
                heldout_loss,
            },
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn init_output_has_unit_scale() {
        let cfg = DenoiserConfig::default();
        let trainer = Trainer::new(cfg, TrainOptions::default()).unwrap();
        let b = 4;
        let dev = Device::Cpu;
        let z = Tensor::randn(0f32, 1f32, (b, 2 * cfg.slots, cfg.steps), &dev).unwrap();
        let cond = Tensor::zeros((b, cfg.condition_len()), DType::F32, &dev).unwrap();
        let time = Tensor::zeros((b, cfg.time_channels(), cfg.patches()), DType::F32, &dev).unwrap();
        let out = trainer.denoiser().forward(&z, &[1, 10, 20, 50], &cond, &time).unwrap();
        let v: Vec<f32> = out.flatten_all().unwrap().to_vec1().unwrap();
        let rms = (v.iter().map(|x| x * x).sum::<f32>() / v.len() as f32).sqrt();
        eprintln!("rms {rms}");
        assert!(rms < 5.0, "rms {rms}");
    }
}
