//! The guided correction of Algorithm 1 without the network.
//!
//! The denoiser works on normalized controls, per channel `z_a = (a − μ_a) / σ_a`,
//! `z_ω = (ω − μ_ω) / σ_ω`, stored flat `[agent][step][channel]` (`2 · N · T` numbers, channel 0
//! the acceleration). Given its predicted clean sample `Ẑ0`, [`Guidance::guide_clean_sample`]
//! denormalizes it, evaluates `E` and `∇_U E` on the rollout, takes the chain rule
//! `∇_Z E = σ ⊙ ∇_U E`, and writes `Z̃0 = Ẑ0 − η ∇_Z E` where the step `η ∇_Z E` is scaled down, if
//! needed, to an L2 norm of at most `max_step_norm` (direction kept). [`guided_posterior_mean`] is
//! the guided reverse-process mean `μ̃` of the paper and [`predicted_clean_sample`] the `Û0` of the
//! noise estimate, so one step of Algorithm 1 (lines 3–9) is: `ε̂ = ε_θ(U_k, k, c)` (stage 2b),
//! [`predicted_clean_sample`], [`Guidance::guide_clean_sample`], [`guided_posterior_mean`] (the
//! result is `U_{k−1}`; the paper adds no noise).

use v2t_model::kinematics::{Control, State};

use super::{EnergyBreakdown, Guidance, GuidanceError, GuidanceWorkspace};

/// Per-channel normalization of the controls.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ControlNormalization {
    /// `μ_a`, m/s².
    pub accel_mean_mps2: f64,
    /// `σ_a`, m/s².
    pub accel_scale_mps2: f64,
    /// `μ_ω`, rad/s.
    pub yaw_rate_mean_radps: f64,
    /// `σ_ω`, rad/s.
    pub yaw_rate_scale_radps: f64,
}

impl Default for ControlNormalization {
    /// Zero means, `σ_a = 1.5 m/s²`, `σ_ω = 0.15 rad/s`: about the spread of the synthetic corpus
    /// (acceleration p1/p99 −4.5/2.0 m/s², yaw rate p99 0.32 rad/s); stage 2b fits them to its data.
    fn default() -> Self {
        Self { accel_mean_mps2: 0.0, accel_scale_mps2: 1.5, yaw_rate_mean_radps: 0.0, yaw_rate_scale_radps: 0.15 }
    }
}

impl ControlNormalization {
    /// Finite means and finite scales above zero (NaN fails), or the error that says so.
    pub fn checked(&self) -> Result<(), GuidanceError> {
        let ok = |v: f64| v.is_finite();
        if ok(self.accel_mean_mps2)
            && ok(self.yaw_rate_mean_radps)
            && self.accel_scale_mps2 > 0.0
            && self.yaw_rate_scale_radps > 0.0
            && ok(self.accel_scale_mps2)
            && ok(self.yaw_rate_scale_radps)
        {
            Ok(())
        } else {
            Err(GuidanceError::InvalidConfig {
                field: "normalization",
                reason: "needs finite means and scales > 0".into(),
            })
        }
    }

    /// Physical control of a normalized pair.
    pub fn denormalize(&self, z: [f64; 2]) -> Control {
        Control {
            accel_mps2: self.accel_mean_mps2 + self.accel_scale_mps2 * z[0],
            yaw_rate_radps: self.yaw_rate_mean_radps + self.yaw_rate_scale_radps * z[1],
        }
    }

    /// Normalized pair of a physical control.
    pub fn normalize(&self, u: Control) -> [f64; 2] {
        [
            (u.accel_mps2 - self.accel_mean_mps2) / self.accel_scale_mps2,
            (u.yaw_rate_radps - self.yaw_rate_mean_radps) / self.yaw_rate_scale_radps,
        ]
    }
}

/// Step size and clipping of the guided correction.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GuidanceStep {
    /// `η_k`, the guidance scale of this diffusion step (normalized units per unit energy).
    pub scale: f64,
    /// Largest L2 norm of the whole correction `η ∇_Z E`, normalized units (`∞` for none).
    pub max_step_norm: f64,
}

/// What one guided correction did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GuidedCorrection {
    /// The energy at `Ẑ0`.
    pub energy: EnergyBreakdown,
    /// L2 norm of `∇_Z E`.
    pub grad_norm: f64,
    /// L2 norm of the correction applied (after clipping).
    pub step_norm: f64,
}

impl Guidance {
    /// `Z̃0 = Ẑ0 − clip(η ∇_Z E(Rollout(x0s, denorm(Ẑ0))))` into `out` (same layout as `z0_hat`,
    /// `2 · N · T` numbers). No allocation (uses `ws`).
    pub fn guide_clean_sample(
        &self,
        ws: &mut GuidanceWorkspace,
        norm: &ControlNormalization,
        step: &GuidanceStep,
        x0s: &[State],
        z0_hat: &[f64],
        out: &mut [f64],
    ) -> Result<GuidedCorrection, GuidanceError> {
        norm.checked()?;
        if !(step.scale >= 0.0 && step.scale.is_finite() && step.max_step_norm >= 0.0) {
            return Err(GuidanceError::InvalidConfig {
                field: "step",
                reason: "needs 0 ≤ η < ∞ and max_step_norm ≥ 0".into(),
            });
        }
        let len = 2 * self.len();
        for (what, got) in [("z0_hat", z0_hat.len()), ("out", out.len())] {
            if got != len {
                return Err(GuidanceError::Shape { what, expected: len, got });
            }
        }
        if let Some(index) = z0_hat.iter().position(|z| !z.is_finite()) {
            return Err(GuidanceError::NonFiniteInput { what: "z0_hat", index });
        }
        let mut controls = std::mem::take(&mut ws.controls);
        let mut grad = std::mem::take(&mut ws.grad);
        for (u, z) in controls.iter_mut().zip(z0_hat.chunks_exact(2)) {
            if let (Some(&za), Some(&zw)) = (z.first(), z.get(1)) {
                *u = norm.denormalize([za, zw]);
            }
        }
        let result = self.energy_and_grad(ws, x0s, &controls, &mut grad);
        ws.controls = controls;
        ws.grad = grad;
        let energy = result?;
        let gz = |g: &Control| [g.accel_mps2 * norm.accel_scale_mps2, g.yaw_rate_radps * norm.yaw_rate_scale_radps];
        let grad_norm = ws.grad.iter().map(|g| gz(g).iter().map(|v| v * v).sum::<f64>()).sum::<f64>().sqrt();
        let raw = step.scale * grad_norm;
        let k = if raw > step.max_step_norm && raw > 0.0 { step.scale * step.max_step_norm / raw } else { step.scale };
        if !(k.is_finite() && grad_norm.is_finite()) {
            return Err(GuidanceError::NonFiniteResult);
        }
        for ((o, z), g) in out.chunks_exact_mut(2).zip(z0_hat.chunks_exact(2)).zip(&ws.grad) {
            for ((oc, zc), gc) in o.iter_mut().zip(z).zip(gz(g)) {
                *oc = zc - k * gc;
            }
        }
        Ok(GuidedCorrection { energy, grad_norm, step_norm: k * grad_norm })
    }
}

/// The guided reverse-process mean of the paper,
/// `μ̃ = √ᾱ_{k−1} β_k / (1 − ᾱ_k) · Ũ0 + √α_k (1 − ᾱ_{k−1}) / (1 − ᾱ_k) · U_k`,
/// with `α_k = 1 − β_k`, written into `out` (all three slices the same length). Needs
/// `0 < β_k < 1`, `0 ≤ ᾱ_k < 1`, `0 < ᾱ_{k−1} ≤ 1`.
pub fn guided_posterior_mean(
    alpha_bar_k: f64,
    alpha_bar_prev: f64,
    beta_k: f64,
    u0_tilde: &[f64],
    u_k: &[f64],
    out: &mut [f64],
) -> Result<(), GuidanceError> {
    let ok = beta_k > 0.0
        && beta_k < 1.0
        && (0.0..1.0).contains(&alpha_bar_k)
        && alpha_bar_prev > 0.0
        && alpha_bar_prev <= 1.0;
    if !ok {
        return Err(GuidanceError::InvalidConfig {
            field: "schedule",
            reason: format!("ᾱ_k {alpha_bar_k}, ᾱ_(k-1) {alpha_bar_prev}, β_k {beta_k}"),
        });
    }
    for (what, got) in [("u_k", u_k.len()), ("out", out.len())] {
        if got != u0_tilde.len() {
            return Err(GuidanceError::Shape { what, expected: u0_tilde.len(), got });
        }
    }
    let c0 = alpha_bar_prev.sqrt() * beta_k / (1.0 - alpha_bar_k);
    let ck = (1.0 - beta_k).sqrt() * (1.0 - alpha_bar_prev) / (1.0 - alpha_bar_k);
    for ((o, a), b) in out.iter_mut().zip(u0_tilde).zip(u_k) {
        *o = c0 * a + ck * b;
    }
    if out.iter().all(|v| v.is_finite()) { Ok(()) } else { Err(GuidanceError::NonFiniteResult) }
}

/// The clean sample predicted from the noise estimate (Algorithm 1, line 3),
/// `Û0 = (U_k − √(1 − ᾱ_k) ε̂) / √ᾱ_k`, written into `out` (all three slices the same length).
/// Needs `0 < ᾱ_k ≤ 1`.
pub fn predicted_clean_sample(
    alpha_bar_k: f64,
    u_k: &[f64],
    eps_hat: &[f64],
    out: &mut [f64],
) -> Result<(), GuidanceError> {
    if !(alpha_bar_k > 0.0 && alpha_bar_k <= 1.0) {
        return Err(GuidanceError::InvalidConfig {
            field: "schedule",
            reason: format!("ᾱ_k {alpha_bar_k} outside (0, 1]"),
        });
    }
    for (what, got) in [("eps_hat", eps_hat.len()), ("out", out.len())] {
        if got != u_k.len() {
            return Err(GuidanceError::Shape { what, expected: u_k.len(), got });
        }
    }
    let (a, s) = (alpha_bar_k.sqrt(), (1.0 - alpha_bar_k).sqrt());
    for ((o, u), e) in out.iter_mut().zip(u_k).zip(eps_hat) {
        *o = (u - s * e) / a;
    }
    if out.iter().all(|v| v.is_finite()) { Ok(()) } else { Err(GuidanceError::NonFiniteResult) }
}
