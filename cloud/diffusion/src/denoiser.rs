//! The noise-prediction network `ε_θ(U_k, k, c)`: a temporal convolution network over patches of
//! the joint control sequence, conditioned by FiLM on the diffusion step and the scenario.
//!
//! **Layout.** The input is the normalized joint control tensor `[B, 2S, T]` (`S` agent slots, two
//! channels each, `a` then `ω`; absent slots are zero), cut into `T / P` patches of `P` steps
//! (channels-last, `[B, T/P, 2S·P]`). Time-aligned features (a bump at each slot's conflict-anchor
//! time and the patch position) join as extra channels. A 3-tap input convolution lifts this to
//! `H` channels; `blocks` residual blocks (layer norm, SiLU, dilated 3-tap convolution, FiLM from
//! the embedding, layer norm, SiLU, convolution starting at zero; dilations 1, 2, 4, 8, …) follow;
//! a per-patch linear map (starting at zero) goes back to patches, unfolded to `[B, 2S, T]`. The embedding is the sum of an MLP of the
//! sinusoidal step embedding and an MLP of the condition vector.
//!
//! **Why this shape.** Controls are smooth, low-dimensional sequences (6 channels over 80 steps):
//! patching by 4 cuts the work of every convolution by 4 with no visible loss (neighbouring
//! controls are strongly correlated), dilations give the 20 patches a receptive field over the
//! whole horizon in four blocks, and FiLM carries the scenario (routes, anchors, order) to every
//! block. A transformer over agent × time tokens would cost more per sample (attention plus wide
//! MLPs) for the same horizon; measurements are in the crate README.

use candle_core::{D, DType, Device, Module, Tensor};
use candle_nn::{Linear, VarBuilder};
use v2t_model::validate::ValidationError;

use crate::condition::{SLOT_FEATURES, TIME_FEATURES_PER_SLOT, TIME_POSITION_FEATURES};

/// Width of the sinusoidal step embedding.
const STEP_EMBED: usize = 32;

/// Architecture of the denoiser; stored with the weights.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DenoiserConfig {
    /// Agent slots `S` (VUT + up to two BVs).
    pub slots: usize,
    /// Control steps `T` at 0.1 s.
    pub steps: usize,
    /// Steps per patch `P` (`T` a multiple of it).
    pub patch: usize,
    /// Channels `H` of the residual blocks.
    pub hidden: usize,
    /// Residual blocks.
    pub blocks: usize,
    /// Width of the step and condition embedding.
    pub embed: usize,
    /// Diffusion steps `K` the network was trained for.
    pub diffusion_steps: usize,
}

impl Default for DenoiserConfig {
    fn default() -> Self {
        Self { slots: 3, steps: 80, patch: 4, hidden: 64, blocks: 4, embed: 128, diffusion_steps: 50 }
    }
}

/// Number of interaction kinds in the condition (one-hot): cut-in / lane change, left turn /
/// crossing, merge.
pub const INTERACTION_KINDS: usize = 3;

impl DenoiserConfig {
    /// Length of the condition vector.
    pub fn condition_len(&self) -> usize {
        self.slots * SLOT_FEATURES + INTERACTION_KINDS
    }

    /// Number of patches `T / P`.
    pub fn patches(&self) -> usize {
        self.steps / self.patch.max(1)
    }

    /// Time-aligned feature channels.
    pub fn time_channels(&self) -> usize {
        self.slots * TIME_FEATURES_PER_SLOT + TIME_POSITION_FEATURES
    }

    /// Numbers in one normalized joint control sample (`2 S T`).
    pub fn sample_len(&self) -> usize {
        2 * self.slots * self.steps
    }

    /// Checks the shape rules; the error names the field and the rule it breaks.
    pub fn check(&self) -> Result<(), ValidationError> {
        let rules = [
            ("slots", (2..=4).contains(&self.slots), "must lie in 2..=4"),
            ("patch", self.patch >= 1 && self.steps >= self.patch, "must lie in 1..=steps"),
            ("steps", self.patch >= 1 && self.steps.is_multiple_of(self.patch), "must be a multiple of patch"),
            ("steps", self.steps <= 400, "must be at most 400"),
            ("hidden", (4..=512).contains(&self.hidden), "must lie in 4..=512"),
            ("blocks", (1..=12).contains(&self.blocks), "must lie in 1..=12"),
            ("embed", (8..=1024).contains(&self.embed), "must lie in 8..=1024"),
            ("diffusion_steps", (2..=1000).contains(&self.diffusion_steps), "must lie in 2..=1000"),
        ];
        match rules.iter().find(|(_, ok, _)| !ok) {
            Some((field, _, rule)) => Err(ValidationError::new(*field, *rule)),
            None => Ok(()),
        }
    }
}

/// A temporal convolution in channels-last layout `[B, L, C]`: the input is zero-padded in time,
/// its `k` shifted copies (`dilation` apart) are stacked along the channels and one linear layer
/// maps them. (Written with `narrow` and `matmul` rather than candle's `conv1d`, whose weight
/// gradient in candle 0.9.1 on the CPU is wrong for batches larger than one; the test
/// `gradients_match_finite_differences` guards this network against such errors.)
struct TemporalConv {
    linear: Linear,
    kernel: usize,
    dilation: usize,
}

impl TemporalConv {
    fn new(
        cin: usize,
        cout: usize,
        kernel: usize,
        dilation: usize,
        zero: bool,
        vb: VarBuilder,
    ) -> candle_core::Result<Self> {
        let linear = if zero {
            let w = vb.get_with_hints((cout, kernel * cin), "weight", candle_nn::Init::Const(0.0))?;
            let b = vb.get_with_hints(cout, "bias", candle_nn::Init::Const(0.0))?;
            Linear::new(w, Some(b))
        } else {
            candle_nn::linear(kernel * cin, cout, vb)?
        };
        Ok(Self { linear, kernel, dilation })
    }

    fn forward(&self, x: &Tensor) -> candle_core::Result<Tensor> {
        if self.kernel == 1 {
            return self.linear.forward(x);
        }
        let l = x.dim(1)?;
        let pad = self.dilation * (self.kernel - 1) / 2;
        let padded = x.pad_with_zeros(1, pad, pad)?;
        let taps = (0..self.kernel)
            .map(|j| padded.narrow(1, j * self.dilation, l))
            .collect::<candle_core::Result<Vec<_>>>()?;
        self.linear.forward(&Tensor::cat(&taps, 2)?)
    }
}

/// Layer norm over the channels (last dimension), written with differentiable tensor operations.
struct ChannelNorm {
    weight: Tensor,
    bias: Tensor,
}

impl ChannelNorm {
    fn new(channels: usize, vb: VarBuilder) -> candle_core::Result<Self> {
        Ok(Self {
            weight: vb.get_with_hints(channels, "weight", candle_nn::Init::Const(1.0))?,
            bias: vb.get_with_hints(channels, "bias", candle_nn::Init::Const(0.0))?,
        })
    }

    fn forward(&self, x: &Tensor) -> candle_core::Result<Tensor> {
        let centred = x.broadcast_sub(&x.mean_keepdim(D::Minus1)?)?;
        let var = centred.sqr()?.mean_keepdim(D::Minus1)?;
        centred.broadcast_div(&(var + 1e-5)?.sqrt()?)?.broadcast_mul(&self.weight)?.broadcast_add(&self.bias)
    }
}

struct Block {
    norm1: ChannelNorm,
    conv1: TemporalConv,
    film: Linear,
    norm2: ChannelNorm,
    conv2: TemporalConv,
}

impl Block {
    fn new(cfg: &DenoiserConfig, dilation: usize, vb: VarBuilder) -> candle_core::Result<Self> {
        Ok(Self {
            norm1: ChannelNorm::new(cfg.hidden, vb.pp("norm1"))?,
            conv1: TemporalConv::new(cfg.hidden, cfg.hidden, 3, dilation, false, vb.pp("conv1"))?,
            film: candle_nn::linear(cfg.embed, 2 * cfg.hidden, vb.pp("film"))?,
            norm2: ChannelNorm::new(cfg.hidden, vb.pp("norm2"))?,
            conv2: TemporalConv::new(cfg.hidden, cfg.hidden, 3, dilation, true, vb.pp("conv2"))?,
        })
    }

    /// `h` `[B, L, H]`, `emb` `[B, E]`.
    fn forward(&self, h: &Tensor, emb: &Tensor) -> candle_core::Result<Tensor> {
        let x = self.conv1.forward(&candle_nn::ops::silu(&self.norm1.forward(h)?)?)?;
        let film = self.film.forward(emb)?.unsqueeze(1)?;
        let hidden = x.dim(2)?;
        let scale = film.narrow(2, 0, hidden)?;
        let shift = film.narrow(2, hidden, hidden)?;
        let x = self.norm2.forward(&x)?.broadcast_mul(&(scale + 1.0)?)?.broadcast_add(&shift)?;
        let x = self.conv2.forward(&candle_nn::ops::silu(&x)?)?;
        h + x
    }
}

/// The network. Build it with [`Denoiser::new`] on a `VarBuilder` (fresh variables for training,
/// or loaded weights, see [`crate::weights`]).
pub struct Denoiser {
    cfg: DenoiserConfig,
    input: TemporalConv,
    step1: Linear,
    step2: Linear,
    cond1: Linear,
    cond2: Linear,
    blocks: Vec<Block>,
    out: TemporalConv,
}

impl std::fmt::Debug for Denoiser {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Denoiser").field("cfg", &self.cfg).finish_non_exhaustive()
    }
}

impl Denoiser {
    /// The network of `cfg` with its variables from `vb`.
    pub fn new(cfg: DenoiserConfig, vb: VarBuilder) -> candle_core::Result<Self> {
        cfg.check().map_err(|e| candle_core::Error::Msg(e.to_string()))?;
        let patch_channels = 2 * cfg.slots * cfg.patch;
        let input = TemporalConv::new(patch_channels + cfg.time_channels(), cfg.hidden, 3, 1, false, vb.pp("input"))?;
        let blocks = (0..cfg.blocks)
            .map(|b| Block::new(&cfg, 1 << (b % 4), vb.pp(format!("block{b}"))))
            .collect::<candle_core::Result<Vec<_>>>()?;
        Ok(Self {
            cfg,
            input,
            step1: candle_nn::linear(STEP_EMBED, cfg.embed, vb.pp("step1"))?,
            step2: candle_nn::linear(cfg.embed, cfg.embed, vb.pp("step2"))?,
            cond1: candle_nn::linear(cfg.condition_len(), cfg.embed, vb.pp("cond1"))?,
            cond2: candle_nn::linear(cfg.embed, cfg.embed, vb.pp("cond2"))?,
            blocks,
            out: TemporalConv::new(cfg.hidden, patch_channels, 1, 1, true, vb.pp("out"))?,
        })
    }

    /// Its architecture.
    pub fn config(&self) -> &DenoiserConfig {
        &self.cfg
    }

    /// `ε̂` for a batch: `z` `[B, 2S, T]`, `steps` the diffusion step of each sample (1..=K),
    /// `cond` `[B, C]`, `time_features` `[B, F, T/P]`. Returns `[B, 2S, T]`.
    pub fn forward(
        &self,
        z: &Tensor,
        steps: &[usize],
        cond: &Tensor,
        time_features: &Tensor,
    ) -> candle_core::Result<Tensor> {
        let (b, ch, t) = z.dims3()?;
        let p = self.cfg.patch;
        let l = t / p;
        // Channels-last patches: [B, L, 2S·P], the P steps of each channel together.
        let patches = z.reshape((b, ch, l, p))?.permute((0, 2, 1, 3))?.reshape((b, l, ch * p))?;
        let x = Tensor::cat(&[&patches, &time_features.transpose(1, 2)?], 2)?;
        let mut h = self.input.forward(&x)?;
        let step_emb = step_embedding(steps, z.device())?.to_dtype(z.dtype())?;
        let emb = self.step2.forward(&candle_nn::ops::silu(&self.step1.forward(&step_emb)?)?)?
            + self.cond2.forward(&candle_nn::ops::silu(&self.cond1.forward(cond)?)?)?;
        let emb = candle_nn::ops::silu(&emb?)?;
        for block in &self.blocks {
            h = block.forward(&h, &emb)?;
        }
        let out = self.out.forward(&h)?;
        out.reshape((b, l, ch, p))?.permute((0, 2, 1, 3))?.reshape((b, ch, t))
    }
}

/// Sinusoidal embedding of the diffusion steps, `[B, 32]`.
fn step_embedding(steps: &[usize], device: &Device) -> candle_core::Result<Tensor> {
    let half = STEP_EMBED / 2;
    let mut data = Vec::with_capacity(steps.len() * STEP_EMBED);
    for &k in steps {
        for j in 0..half {
            let freq = (-(j as f64) / half as f64 * 1000f64.ln()).exp();
            data.push((k as f64 * freq).sin() as f32);
        }
        for j in 0..half {
            let freq = (-(j as f64) / half as f64 * 1000f64.ln()).exp();
            data.push((k as f64 * freq).cos() as f32);
        }
    }
    Tensor::from_vec(data, (steps.len(), STEP_EMBED), device)?.to_dtype(DType::F32)
}

#[cfg(test)]
mod tests {
    use candle_nn::VarMap;

    use super::*;

    fn tiny() -> DenoiserConfig {
        DenoiserConfig { slots: 2, steps: 8, patch: 2, hidden: 8, blocks: 2, embed: 8, diffusion_steps: 10 }
    }

    #[test]
    fn gradients_match_finite_differences() {
        let cfg = tiny();
        let dev = Device::Cpu;
        let varmap = VarMap::new();
        let net = Denoiser::new(cfg, VarBuilder::from_varmap(&varmap, DType::F64, &dev)).unwrap();
        // Every variable random (the zero-initialised layers too), so every path carries gradient.
        for v in varmap.all_vars() {
            v.set(&Tensor::randn(0f64, 0.5, v.as_tensor().dims(), &dev).unwrap()).unwrap();
        }
        let b = 3;
        let z = Tensor::randn(0f64, 1.0, (b, 2 * cfg.slots, cfg.steps), &dev).unwrap();
        let cond = Tensor::randn(0f64, 1.0, (b, cfg.condition_len()), &dev).unwrap();
        let time = Tensor::randn(0f64, 1.0, (b, cfg.time_channels(), cfg.patches()), &dev).unwrap();
        let target = Tensor::randn(0f64, 1.0, (b, 2 * cfg.slots, cfg.steps), &dev).unwrap();
        let steps = [1, 4, 9];
        let loss_of = || -> f64 {
            let out = net.forward(&z.to_dtype(DType::F64).unwrap(), &steps, &cond, &time).unwrap();
            (out - &target).unwrap().sqr().unwrap().sum_all().unwrap().to_scalar::<f64>().unwrap()
        };
        let out = net.forward(&z, &steps, &cond, &time).unwrap();
        let loss = (out - &target).unwrap().sqr().unwrap().sum_all().unwrap();
        let grads = loss.backward().unwrap();
        let data = varmap.data().lock().unwrap();
        let mut names: Vec<&String> = data.keys().collect();
        names.sort();
        let mut checked = 0;
        for name in names {
            let var = &data[name];
            let g = grads.get(var.as_tensor()).unwrap().flatten_all().unwrap().to_vec1::<f64>().unwrap();
            let w0 = var.as_tensor().flatten_all().unwrap().to_vec1::<f64>().unwrap();
            for i in [0, w0.len() / 2, w0.len() - 1] {
                let h = 1e-5;
                let mut wp = w0.clone();
                wp[i] += h;
                var.set(&Tensor::from_vec(wp, var.as_tensor().dims(), &dev).unwrap()).unwrap();
                let lp = loss_of();
                let mut wm = w0.clone();
                wm[i] -= h;
                var.set(&Tensor::from_vec(wm, var.as_tensor().dims(), &dev).unwrap()).unwrap();
                let lm = loss_of();
                var.set(&Tensor::from_vec(w0.clone(), var.as_tensor().dims(), &dev).unwrap()).unwrap();
                let num = (lp - lm) / (2.0 * h);
                assert!((num - g[i]).abs() <= 1e-4 * (1.0 + num.abs()), "{name}[{i}]: autograd {} numeric {num}", g[i]);
                checked += 1;
            }
        }
        assert!(checked > 40, "{checked}");
    }

    #[test]
    fn untrained_network_predicts_zero_noise() {
        let cfg = DenoiserConfig::default();
        let dev = Device::Cpu;
        let varmap = VarMap::new();
        let net = Denoiser::new(cfg, VarBuilder::from_varmap(&varmap, DType::F32, &dev)).unwrap();
        let z = Tensor::randn(0f32, 1.0, (2, 2 * cfg.slots, cfg.steps), &dev).unwrap();
        let cond = Tensor::zeros((2, cfg.condition_len()), DType::F32, &dev).unwrap();
        let time = Tensor::zeros((2, cfg.time_channels(), cfg.patches()), DType::F32, &dev).unwrap();
        let out = net.forward(&z, &[3, 40], &cond, &time).unwrap();
        assert_eq!(out.dims(), &[2, 2 * cfg.slots, cfg.steps]);
        assert_eq!(out.abs().unwrap().sum_all().unwrap().to_scalar::<f32>().unwrap(), 0.0);
    }

    #[test]
    fn config_rules() {
        assert!(DenoiserConfig::default().check().is_ok());
        let bad = DenoiserConfig { steps: 81, ..DenoiserConfig::default() };
        assert!(bad.check().unwrap_err().to_string().contains("multiple"));
        let bad = DenoiserConfig { slots: 1, ..DenoiserConfig::default() };
        assert!(bad.check().is_err());
    }
}
