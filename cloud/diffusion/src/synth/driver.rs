//! Heterogeneous human driver models for the synthetic corpus: sampled IDM and gap-acceptance
//! parameters, reaction delays, actuation lag, process noise and minimum-jerk lane changes. The
//! IDM, the curve speed and pure pursuit are `v2t_model::driving`'s, the same the simulated VUTs
//! drive with.

use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal, StandardUniform};
use serde::{Deserialize, Serialize};
use v2t_model::driving::{CurvePreview, Idm, curve_speed_ahead};
use v2t_model::path::ReferencePath;

/// One driver's parameters, sampled per agent and stored with every synthetic episode.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DriverParams {
    /// IDM desired speed `v0`, m/s.
    pub desired_speed_mps: f64,
    /// IDM desired time headway `T`, s.
    pub time_headway_s: f64,
    /// IDM maximum acceleration `a`, m/s².
    pub max_accel_mps2: f64,
    /// IDM comfortable deceleration `b`, m/s².
    pub comfort_decel_mps2: f64,
    /// IDM standstill gap `s0`, m.
    pub min_gap_m: f64,
    /// Gap acceptance: the driver goes first only if it clears the conflict at least this long
    /// before the other vehicle arrives (crossings, merges), or — for a lane change — if the
    /// vehicle behind in the target lane is at least this time headway away, s.
    pub critical_gap_s: f64,
    /// Perception delay: other vehicles are seen as they were this long ago, s.
    pub reaction_delay_s: f64,
    /// Time constant of the first-order lag between wanted and applied acceleration, s.
    pub accel_lag_s: f64,
    /// Lateral acceleration accepted in curves (sets the curve speed), m/s².
    pub max_lateral_accel_mps2: f64,
    /// Duration of a minimum-jerk lane change, s.
    pub lane_change_duration_s: f64,
    /// Standard deviation of the acceleration process noise (Ornstein–Uhlenbeck, 1 s), m/s².
    pub accel_noise_mps2: f64,
    /// Standard deviation of the yaw-rate process noise (Ornstein–Uhlenbeck, 1 s), rad/s.
    pub yaw_noise_radps: f64,
}

/// Uniform sample in `[lo, hi)`.
pub(crate) fn uniform(rng: &mut ChaCha8Rng, lo: f64, hi: f64) -> f64 {
    let u: f64 = StandardUniform.sample(rng);
    lo + (hi - lo) * u
}

/// Standard normal sample.
pub(crate) fn normal(rng: &mut ChaCha8Rng) -> f64 {
    StandardNormal.sample(rng)
}

impl DriverParams {
    /// Samples a driver. Ranges (uniform): `v0` 0.85–1.25 × `nominal_speed_mps`, `T` 0.8–2.2 s,
    /// `a` 0.8–2.5 m/s², `b` 1.2–3.0 m/s², `s0` 1.5–3.5 m, critical gap 0.8–3.0 s, reaction delay
    /// 0.3–1.2 s, actuation lag 0.2–0.6 s, lateral acceleration 1.5–3.0 m/s², lane change 3–7 s,
    /// noise 0.03–0.25 m/s² and 0.002–0.01 rad/s. Faster drivers are not made bolder: the
    /// parameters are independent, so the corpus covers unusual combinations too.
    pub fn sample(rng: &mut ChaCha8Rng, nominal_speed_mps: f64) -> Self {
        Self {
            desired_speed_mps: nominal_speed_mps * uniform(rng, 0.85, 1.25),
            time_headway_s: uniform(rng, 0.8, 2.2),
            max_accel_mps2: uniform(rng, 0.8, 2.5),
            comfort_decel_mps2: uniform(rng, 1.2, 3.0),
            min_gap_m: uniform(rng, 1.5, 3.5),
            critical_gap_s: uniform(rng, 0.8, 3.0),
            reaction_delay_s: uniform(rng, 0.3, 1.2),
            accel_lag_s: uniform(rng, 0.2, 0.6),
            max_lateral_accel_mps2: uniform(rng, 1.5, 3.0),
            lane_change_duration_s: uniform(rng, 3.0, 7.0),
            accel_noise_mps2: uniform(rng, 0.03, 0.25),
            yaw_noise_radps: uniform(rng, 0.002, 0.01),
        }
    }

    /// The IDM this driver follows with (`δ` = 4, the original model's).
    pub fn idm(&self) -> Idm {
        Idm {
            time_gap_s: self.time_headway_s,
            min_gap_m: self.min_gap_m,
            max_accel_mps2: self.max_accel_mps2,
            comfort_decel_mps2: self.comfort_decel_mps2,
            accel_exponent: 4.0,
        }
    }

    /// Desired speed at arc length `s` on `path` at speed `v`: `v0` capped by the curves the
    /// driver can still brake for comfortably ([`curve_speed_ahead`] at its lateral acceleration
    /// and `b`, the [`CurvePreview::DRIVER`] preview).
    pub fn curve_capped_speed(&self, path: &ReferencePath, s: f64, v: f64) -> f64 {
        let cap =
            curve_speed_ahead(path, s, v, self.max_lateral_accel_mps2, self.comfort_decel_mps2, &CurvePreview::DRIVER);
        self.desired_speed_mps.min(cap)
    }
}

/// Lateral offset of a minimum-jerk lane change from `from_m` to `to_m` lasting `duration_s`,
/// `elapsed_s` after it began: `from + (to − from)(10τ³ − 15τ⁴ + 6τ⁵)`, τ clamped to [0, 1].
pub fn min_jerk_offset(from_m: f64, to_m: f64, duration_s: f64, elapsed_s: f64) -> f64 {
    let tau = if duration_s > 0.0 { (elapsed_s / duration_s).clamp(0.0, 1.0) } else { 1.0 };
    from_m + (to_m - from_m) * tau * tau * tau * (10.0 - 15.0 * tau + 6.0 * tau * tau)
}

/// A first-order Ornstein–Uhlenbeck process with unit time constant, stationary standard
/// deviation `sigma`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OuNoise {
    /// Current value.
    pub value: f64,
    /// Stationary standard deviation.
    pub sigma: f64,
}

impl OuNoise {
    /// Advances by `dt_s` with standard normal draw `z`.
    pub fn step(&mut self, dt_s: f64, z: f64) -> f64 {
        let decay = (-dt_s).exp();
        self.value = self.value * decay + self.sigma * (1.0 - decay * decay).sqrt() * z;
        self.value
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use rand_chacha::rand_core::SeedableRng;

    #[test]
    fn sampled_drivers_differ_and_repeat() {
        let a = DriverParams::sample(&mut ChaCha8Rng::seed_from_u64(3), 10.0);
        let b = DriverParams::sample(&mut ChaCha8Rng::seed_from_u64(3), 10.0);
        let c = DriverParams::sample(&mut ChaCha8Rng::seed_from_u64(4), 10.0);
        assert_eq!(a, b);
        assert_ne!(a, c);
    }

    proptest! {
        #[test]
        fn min_jerk_profile_is_monotone_with_flat_ends(from in -5.0f64..5.0, to in -5.0f64..5.0, dur in 1.0f64..8.0) {
            prop_assert!((min_jerk_offset(from, to, dur, 0.0) - from).abs() < 1e-12);
            prop_assert!((min_jerk_offset(from, to, dur, dur) - to).abs() < 1e-12);
            prop_assert!((min_jerk_offset(from, to, dur, 0.5 * dur) - 0.5 * (from + to)).abs() < 1e-9);
            let mut prev = from;
            for k in 1..=50 {
                let y = min_jerk_offset(from, to, dur, dur * k as f64 / 50.0);
                prop_assert!((y - prev) * (to - from) >= -1e-12);
                prev = y;
            }
            // Zero lateral speed at both ends.
            let h = 1e-4;
            prop_assert!((min_jerk_offset(from, to, dur, h) - from).abs() < 1e-6);
            prop_assert!((min_jerk_offset(from, to, dur, dur - h) - to).abs() < 1e-6);
        }
    }
}
