//! The noise schedule of the forward process and the reverse-step arithmetic (DDPM and DDIM).
//!
//! Cosine schedule (Nichol & Dhariwal 2021): `ᾱ_k = f(k)/f(0)`, `f(k) = cos²((k/K + s)/(1 + s) · π/2)`,
//! `s = 0.008`, `β_k = 1 − ᾱ_k/ᾱ_{k−1}` clipped to 0.999; `ᾱ_0 = 1`. Indices run `k = 0 … K`, the
//! network sees `k ≥ 1`.

/// `ᾱ_k` and `β_k` for `k = 0 … K`.
#[derive(Debug, Clone, PartialEq)]
pub struct NoiseSchedule {
    alpha_bar: Vec<f64>,
    beta: Vec<f64>,
}

impl NoiseSchedule {
    /// The cosine schedule with `k_max` steps (at least 1).
    pub fn cosine(k_max: usize) -> Self {
        let k_max = k_max.max(1);
        let s = 0.008;
        let f = |k: usize| ((k as f64 / k_max as f64 + s) / (1.0 + s) * std::f64::consts::FRAC_PI_2).cos().powi(2);
        let f0 = f(0);
        let mut alpha_bar = Vec::with_capacity(k_max + 1);
        let mut beta = Vec::with_capacity(k_max + 1);
        alpha_bar.push(1.0);
        beta.push(0.0);
        for k in 1..=k_max {
            let prev = alpha_bar.last().copied().unwrap_or(1.0);
            let b = (1.0 - (f(k) / f0) / prev).clamp(0.0, 0.999);
            beta.push(b);
            alpha_bar.push(prev * (1.0 - b));
        }
        Self { alpha_bar, beta }
    }

    /// `K`.
    pub fn steps(&self) -> usize {
        self.alpha_bar.len() - 1
    }

    /// `ᾱ_k` (1 at `k = 0`; `k` clamped to `K`).
    pub fn alpha_bar(&self, k: usize) -> f64 {
        self.alpha_bar.get(k.min(self.steps())).copied().unwrap_or(1.0)
    }

    /// `β_k` (`k` clamped to `K`).
    pub fn beta(&self, k: usize) -> f64 {
        self.beta.get(k.min(self.steps())).copied().unwrap_or(0.0)
    }

    /// Standard deviation of the DDPM reverse step `k → k − 1`: `σ_k² = β̃_k = (1 − ᾱ_{k−1})/(1 − ᾱ_k) β_k`.
    pub fn ddpm_sigma(&self, k: usize) -> f64 {
        if k == 0 {
            return 0.0;
        }
        let ab = self.alpha_bar(k);
        let ab_prev = self.alpha_bar(k - 1);
        ((1.0 - ab_prev) / (1.0 - ab).max(1e-12) * self.beta(k)).max(0.0).sqrt()
    }

    /// The forward process: `U_k = √ᾱ_k U_0 + √(1 − ᾱ_k) ε`.
    pub fn noised(&self, k: usize, clean: f64, noise: f64) -> f64 {
        let ab = self.alpha_bar(k);
        ab.sqrt() * clean + (1.0 - ab).sqrt() * noise
    }

    /// The DDIM step (η = 0) from `k` to `k_prev < k` given the (guided) clean sample `u0` and the
    /// current `u_k`: the noise implied by the pair is carried to `k_prev`.
    pub fn ddim_step(&self, k: usize, k_prev: usize, u0: f64, uk: f64) -> f64 {
        let ab = self.alpha_bar(k);
        let ab_prev = self.alpha_bar(k_prev);
        let eps = (uk - ab.sqrt() * u0) / (1.0 - ab).max(1e-12).sqrt();
        ab_prev.sqrt() * u0 + (1.0 - ab_prev).sqrt() * eps
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cosine_schedule_is_monotone_and_ends_near_pure_noise() {
        let s = NoiseSchedule::cosine(50);
        assert_eq!(s.steps(), 50);
        assert_eq!(s.alpha_bar(0), 1.0);
        for k in 1..=50 {
            assert!(s.alpha_bar(k) < s.alpha_bar(k - 1));
            assert!(s.beta(k) > 0.0 && s.beta(k) <= 0.999);
        }
        assert!(s.alpha_bar(50) < 1e-3);
        assert!(s.alpha_bar(1) > 0.99);
    }

    #[test]
    fn ddim_step_keeps_the_implied_noise() {
        let s = NoiseSchedule::cosine(50);
        let (u0, eps) = (0.7, -1.3);
        let u30 = s.noised(30, u0, eps);
        let u10 = s.ddim_step(30, 10, u0, u30);
        assert!((u10 - s.noised(10, u0, eps)).abs() < 1e-12);
        assert!((s.ddim_step(30, 0, u0, u30) - u0).abs() < 1e-12);
    }
}
