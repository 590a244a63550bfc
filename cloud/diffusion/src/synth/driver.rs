//! Heterogeneous human driver models for the synthetic corpus: sampled IDM and gap-acceptance
//! parameters, reaction delays, actuation lag, process noise, minimum-jerk lane changes, and the
//! pure-pursuit steering that turns a reference path into a yaw rate.

use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal, StandardUniform};
use serde::{Deserialize, Serialize};
use v2t_model::geometry::{Point2, wrap_angle};
use v2t_model::kinematics::State;
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

    /// IDM acceleration at speed `v` toward `v0`, against an obstacle `(gap, its speed)`.
    pub fn idm_accel(&self, v: f64, v0: f64, obstacle: Option<(f64, f64)>) -> f64 {
        let free = 1.0 - (v.max(0.0) / v0.max(0.5)).powi(4);
        let interaction = obstacle.map_or(0.0, |(gap, lead_v)| {
            let sqrt_ab = (self.max_accel_mps2 * self.comfort_decel_mps2).sqrt();
            let s_star = self.min_gap_m + (v * self.time_headway_s + v * (v - lead_v) / (2.0 * sqrt_ab)).max(0.0);
            (s_star / gap.max(0.1)).powi(2)
        });
        self.max_accel_mps2 * (free - interaction)
    }

    /// Enhanced-IDM acceleration behind a vehicle at `gap` driving at `lead_v` (Kesting, Treiber &
    /// Helbing 2010, coolness 0.99, the leader's acceleration taken as 0): where the IDM brakes
    /// harder than the constant-acceleration heuristic needs — typically right after a cut-in with
    /// a short gap but no closing speed — the braking is softened toward the heuristic, as human
    /// drivers do.
    pub fn eidm_accel(&self, v: f64, v0: f64, gap: f64, lead_v: f64) -> f64 {
        const COOLNESS: f64 = 0.99;
        let idm = self.idm_accel(v, v0, Some((gap, lead_v)));
        let cah = if v <= lead_v { 0.0 } else { -(v - lead_v).powi(2) / (2.0 * gap.max(0.1)) };
        if idm >= cah {
            return idm;
        }
        let b = self.comfort_decel_mps2.max(0.1);
        (1.0 - COOLNESS) * idm + COOLNESS * (cah + b * ((idm - cah) / b).tanh())
    }

    /// Desired speed at arc length `s` on `path`: `v0` capped by the curve speed
    /// `√(a_lat / |κ|)` over the stretch the driver can still brake for comfortably.
    pub fn curve_capped_speed(&self, path: &ReferencePath, s: f64, v: f64) -> f64 {
        let mut cap = self.desired_speed_mps;
        let reach = (v * v / (2.0 * self.comfort_decel_mps2) + 10.0).min(80.0);
        let mut d = 0.0;
        while d <= reach {
            let k = path.curvature_at(s + d).abs();
            if k > 1e-4 {
                // Speed allowed now so that braking at b reaches the curve speed at distance d.
                let vc = (self.max_lateral_accel_mps2 / k).sqrt();
                cap = cap.min((vc * vc + 2.0 * self.comfort_decel_mps2 * d).sqrt());
            }
            d += 2.0;
        }
        cap
    }
}

/// Lateral offset of a minimum-jerk lane change from `from_m` to `to_m` lasting `duration_s`,
/// `elapsed_s` after it began: `from + (to − from)(10τ³ − 15τ⁴ + 6τ⁵)`, τ clamped to [0, 1].
pub fn min_jerk_offset(from_m: f64, to_m: f64, duration_s: f64, elapsed_s: f64) -> f64 {
    let tau = if duration_s > 0.0 { (elapsed_s / duration_s).clamp(0.0, 1.0) } else { 1.0 };
    from_m + (to_m - from_m) * tau * tau * tau * (10.0 - 15.0 * tau + 6.0 * tau * tau)
}

/// Pure-pursuit yaw rate toward `target`: `ω = v · 2 sin α / L`, with α the bearing of the target
/// from the heading and `L` the distance to it.
pub fn pursuit_yaw_rate(x: &State, target: Point2) -> f64 {
    let d = target.sub(x.position());
    let dist = d.norm().max(1e-3);
    let alpha = wrap_angle(d.y.atan2(d.x) - x.theta_rad);
    x.speed_mps.max(0.0) * 2.0 * alpha.sin() / dist
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
    fn idm_is_free_at_low_speed_and_brakes_when_close() {
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        let d = DriverParams::sample(&mut rng, 12.0);
        assert!(d.idm_accel(0.0, 12.0, None) > 0.0);
        assert!(d.idm_accel(d.desired_speed_mps, d.desired_speed_mps, None).abs() < 1e-9);
        assert!(d.idm_accel(10.0, 12.0, Some((5.0, 0.0))) < -d.comfort_decel_mps2);
    }

    #[test]
    fn enhanced_idm_softens_a_close_cut_in_without_closing_speed() {
        let d = DriverParams::sample(&mut ChaCha8Rng::seed_from_u64(2), 15.0);
        // A vehicle cut in 6 m ahead at the same speed: the IDM brakes hard, the enhanced IDM gently.
        let (idm, eidm) = (d.idm_accel(15.0, 15.0, Some((6.0, 15.0))), d.eidm_accel(15.0, 15.0, 6.0, 15.0));
        assert!(
            idm < -d.comfort_decel_mps2 && eidm > idm && eidm >= -d.comfort_decel_mps2 + 0.01 * idm - 1e-9,
            "{idm} {eidm}"
        );
        // Closing fast on a near obstacle it still brakes at least as the kinematics need.
        let need = -(10.0f64 * 10.0) / (2.0 * 20.0);
        assert!(d.eidm_accel(10.0, 15.0, 20.0, 0.0) <= need + 0.5);
        // Free of interaction where the IDM is not braking.
        assert_eq!(d.eidm_accel(5.0, 15.0, 200.0, 15.0), d.idm_accel(5.0, 15.0, Some((200.0, 15.0))));
    }

    #[test]
    fn sampled_drivers_differ_and_repeat() {
        let a = DriverParams::sample(&mut ChaCha8Rng::seed_from_u64(3), 10.0);
        let b = DriverParams::sample(&mut ChaCha8Rng::seed_from_u64(3), 10.0);
        let c = DriverParams::sample(&mut ChaCha8Rng::seed_from_u64(4), 10.0);
        assert_eq!(a, b);
        assert_ne!(a, c);
    }

    #[test]
    fn pursuit_turns_toward_the_target() {
        let x = State { px: 0.0, py: 0.0, theta_rad: 0.0, speed_mps: 10.0 };
        assert!(pursuit_yaw_rate(&x, Point2::new(10.0, 1.0)) > 0.0);
        assert!(pursuit_yaw_rate(&x, Point2::new(10.0, -1.0)) < 0.0);
        assert!(pursuit_yaw_rate(&x, Point2::new(10.0, 0.0)).abs() < 1e-12);
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
