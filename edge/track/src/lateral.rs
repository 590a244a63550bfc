//! Lateral control: the Stanley law at the front axle, with a curvature feed-forward that can look
//! ahead, optional yaw-rate damping, and the kinematic offset that keeps the footprint centre (the
//! reference point of every state) on the path in a turn.
//!
//! Signs: `cross_track_m` is the front axle's lateral offset from the path, positive to the left;
//! `heading_error_rad` is the vehicle's heading minus the path's, positive when the vehicle points
//! to the left of the path; the steering angle is positive to the left. A vehicle left of its path,
//! or pointing left of it, steers right.
//!
//! ```text
//! δ = δ_ss(κ_preview) + k_ψ·(−ψ_e − δ_ss(κ)) − atan2(k·(e − e_ss(κ)), k_soft + v) − k_r·(r − v·κ)
//! δ_ss(κ) = atan(L·κ / √(1 − c²κ²))                  (≈ atan(L·κ), the curvature feed-forward)
//! e_ss(κ) = −κ·(L² − c²) / (1 + √(1 + κ²·(L² − c²)))   (front-axle offset when the centre is on the path)
//! ```
//!
//! with `L` the wheelbase and `c` the distance from the footprint centre back to the rear axle. In
//! a steady turn of the kinematic bicycle with the centre on the path, the front wheels point along
//! the path tangent at the front axle's foot point, so the plain heading error already equals the
//! steady steering angle: the heading term is measured against `δ_ss(κ)` so that the feed-forward
//! is not counted twice, and with `k_ψ = 1` and no preview the law is the classic Stanley law
//! (plus the centre offset). The result is clamped to `±max_steer` and moves at most
//! `max_steer_rate·dt` per cycle.

use serde::{Deserialize, Serialize};
use v2t_model::geometry::wrap_angle;
use v2t_model::validate::{Validate, ValidationError, in_range, positive};
use v2t_model::vehicle::{VehicleGeometry, VehicleLimits};

use crate::{TrackError, check_dt, check_finite, limit};

/// The largest cross-track error acted on, m (the steering saturates long before).
const MAX_CROSS_TRACK_M: f64 = 100.0;
/// The largest speed taken into account, m/s.
const MAX_SPEED_MPS: f64 = 100.0;
/// The largest |curvature| taken into account, 1/m.
const MAX_CURVATURE_1PM: f64 = 10.0;
/// The largest yaw rate taken into account, rad/s.
const MAX_YAW_RATE_RADPS: f64 = 10.0;

/// Gains of the lateral controller, as written in `[lateral]` of `config/track/*.toml`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LateralGains {
    /// Stanley gain `k` on the cross-track error, 1/s.
    pub cross_track_gain_1ps: f64,
    /// Softening speed `k_soft` in the Stanley denominator, m/s (keeps the gain finite at standstill).
    pub softening_speed_mps: f64,
    /// Gain `k_ψ` on the heading error (1 = classic Stanley).
    pub heading_gain: f64,
    /// How far ahead the curvature feed-forward reads the path, s (times the speed).
    pub feedforward_preview_s: f64,
    /// Yaw-rate damping `k_r`, rad of steering per rad/s of yaw-rate error (0 = off).
    pub yaw_damping_s: f64,
    /// Time constant of the low-pass filter on the yaw rate estimated from the headings, s.
    pub yaw_rate_filter_s: f64,
}

impl Validate for LateralGains {
    fn validate(&self) -> Result<(), ValidationError> {
        in_range("cross_track_gain_1ps", self.cross_track_gain_1ps, 0.0, 20.0)?;
        positive("softening_speed_mps", self.softening_speed_mps)?;
        in_range("heading_gain", self.heading_gain, 0.0, 5.0)?;
        in_range("feedforward_preview_s", self.feedforward_preview_s, 0.0, 2.0)?;
        in_range("yaw_damping_s", self.yaw_damping_s, 0.0, 2.0)?;
        in_range("yaw_rate_filter_s", self.yaw_rate_filter_s, 0.0, 5.0)
    }
}

impl Default for LateralGains {
    fn default() -> Self {
        Self {
            cross_track_gain_1ps: 3.0,
            softening_speed_mps: 1.0,
            heading_gain: 1.0,
            feedforward_preview_s: 0.0,
            yaw_damping_s: 0.05,
            yaw_rate_filter_s: 0.2,
        }
    }
}

/// The vehicle's steering geometry and limits the controller respects.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SteeringModel {
    /// Wheelbase `L`, m.
    pub wheelbase_m: f64,
    /// Distance `c` from the reference point (footprint centre) back to the rear axle, m.
    pub center_to_rear_axle_m: f64,
    /// Largest road-wheel angle, rad.
    pub max_steer_rad: f64,
    /// Largest steering rate, rad/s.
    pub max_steer_rate_radps: f64,
}

impl SteeringModel {
    /// From a vehicle's geometry and limits.
    pub fn new(geometry: &VehicleGeometry, limits: &VehicleLimits) -> Self {
        Self {
            wheelbase_m: geometry.wheelbase_m,
            center_to_rear_axle_m: geometry.center_to_rear_axle_m,
            max_steer_rad: limits.max_steer_rad,
            max_steer_rate_radps: limits.max_steer_rate_radps,
        }
    }

    /// Distance from the reference point forward to the front axle, m.
    pub fn center_to_front_axle_m(&self) -> f64 {
        self.wheelbase_m - self.center_to_rear_axle_m
    }

    /// Road-wheel angle that holds the reference point on a circle of curvature `kappa_1pm`
    /// (kinematic bicycle, no slip): `atan(L·κ / √(1 − c²κ²))`.
    pub fn steady_steer_rad(&self, kappa_1pm: f64) -> f64 {
        let k = limit(kappa_1pm, -MAX_CURVATURE_1PM, MAX_CURVATURE_1PM);
        let ck = self.center_to_rear_axle_m * k;
        let cos_beta = (1.0 - ck * ck).max(1e-6).sqrt();
        (self.wheelbase_m * k / cos_beta).atan()
    }

    /// Lateral offset of the front axle from a path of curvature `kappa_1pm` when the reference
    /// point is on it in a steady turn, m (negative, i.e. outside, in a left turn).
    pub fn steady_front_offset_m(&self, kappa_1pm: f64) -> f64 {
        let k = limit(kappa_1pm, -MAX_CURVATURE_1PM, MAX_CURVATURE_1PM);
        let d2 = self.wheelbase_m * self.wheelbase_m - self.center_to_rear_axle_m * self.center_to_rear_axle_m;
        -k * d2 / (1.0 + (1.0 + k * k * d2).max(0.0).sqrt())
    }
}

impl Validate for SteeringModel {
    fn validate(&self) -> Result<(), ValidationError> {
        in_range("wheelbase_m", self.wheelbase_m, 0.5, 20.0)?;
        in_range("center_to_rear_axle_m", self.center_to_rear_axle_m, 0.0, self.wheelbase_m)?;
        in_range("max_steer_rad", self.max_steer_rad, 0.01, 1.2)?;
        positive("max_steer_rate_radps", self.max_steer_rate_radps)
    }
}

/// What the Stanley law needs from one cycle.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct StanleyInput {
    /// Lateral offset of the front axle from the path, m, positive left.
    pub cross_track_m: f64,
    /// Vehicle heading minus path heading at the front axle's foot point, rad, positive when the
    /// vehicle points left of the path.
    pub heading_error_rad: f64,
    /// Speed, m/s.
    pub speed_mps: f64,
    /// Path curvature at the front axle's foot point, 1/m (positive turning left).
    pub curvature_1pm: f64,
    /// Path curvature at the feed-forward preview point, 1/m.
    pub preview_curvature_1pm: f64,
    /// Measured heading, rad (for the yaw-rate estimate of the damping term).
    pub heading_rad: f64,
}

/// The Stanley controller with its steering memory. `Copy`: a cycle can be computed on a copy and
/// committed when it succeeds.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Stanley {
    gains: LateralGains,
    model: SteeringModel,
    last_steer_rad: f64,
    last_heading_rad: Option<f64>,
    yaw_rate_radps: f64,
}

impl Stanley {
    /// A controller with the wheels straight, after checking gains and model.
    pub fn new(gains: LateralGains, model: SteeringModel) -> Result<Self, TrackError> {
        gains.validate().map_err(|e| e.within("lateral"))?;
        model.validate().map_err(|e| e.within("vehicle"))?;
        Ok(Self::new_unchecked(gains, model))
    }

    pub(crate) fn new_unchecked(gains: LateralGains, model: SteeringModel) -> Self {
        Self { gains, model, last_steer_rad: 0.0, last_heading_rad: None, yaw_rate_radps: 0.0 }
    }

    /// Forgets the yaw-rate history; the rate limit starts again from straight wheels.
    pub fn reset(&mut self) {
        self.reset_to(0.0);
    }

    /// [`Self::reset`], with the rate limit starting from `steer_rad` (the road-wheel angle now;
    /// a non-finite value counts as 0).
    pub fn reset_to(&mut self, steer_rad: f64) {
        let d = if steer_rad.is_finite() { steer_rad } else { 0.0 };
        self.last_steer_rad = limit(d, -self.model.max_steer_rad, self.model.max_steer_rad);
        self.last_heading_rad = None;
        self.yaw_rate_radps = 0.0;
    }

    /// The last request, rad.
    pub fn last_steer_rad(&self) -> f64 {
        self.last_steer_rad
    }

    /// The steering model.
    pub fn model(&self) -> &SteeringModel {
        &self.model
    }

    /// The gains.
    pub fn gains(&self) -> &LateralGains {
        &self.gains
    }

    /// One control cycle of length `dt_s`: the road-wheel angle to request, rad. Rejects a
    /// non-positive or non-finite `dt_s` and non-finite inputs without changing the controller.
    pub fn update(&mut self, input: &StanleyInput, dt_s: f64) -> Result<f64, TrackError> {
        check_dt(dt_s, f64::INFINITY)?;
        check_finite("cross_track_m", input.cross_track_m)?;
        check_finite("heading_error_rad", input.heading_error_rad)?;
        check_finite("speed_mps", input.speed_mps)?;
        check_finite("curvature_1pm", input.curvature_1pm)?;
        check_finite("preview_curvature_1pm", input.preview_curvature_1pm)?;
        check_finite("heading_rad", input.heading_rad)?;
        let g = &self.gains;
        let m = &self.model;
        let v = limit(input.speed_mps, 0.0, MAX_SPEED_MPS);
        let kappa = limit(input.curvature_1pm, -MAX_CURVATURE_1PM, MAX_CURVATURE_1PM);
        let e = limit(input.cross_track_m - m.steady_front_offset_m(kappa), -MAX_CROSS_TRACK_M, MAX_CROSS_TRACK_M);
        let psi = wrap_angle(input.heading_error_rad);

        let yaw_rate = match self.last_heading_rad {
            Some(prev) => {
                let raw = limit(wrap_angle(input.heading_rad - prev) / dt_s, -MAX_YAW_RATE_RADPS, MAX_YAW_RATE_RADPS);
                self.yaw_rate_radps + (raw - self.yaw_rate_radps) * dt_s / (g.yaw_rate_filter_s + dt_s)
            }
            None => v * kappa,
        };

        let feedforward = m.steady_steer_rad(input.preview_curvature_1pm);
        let heading_term = g.heading_gain * wrap_angle(-psi - m.steady_steer_rad(kappa));
        let cross_term = (g.cross_track_gain_1ps * e).atan2(g.softening_speed_mps + v);
        let damping = g.yaw_damping_s * (yaw_rate - v * kappa);
        let raw = feedforward + heading_term - cross_term - damping;

        let max_step = m.max_steer_rate_radps * dt_s;
        let steer = limit(raw, -m.max_steer_rad, m.max_steer_rad);
        let steer = limit(steer, self.last_steer_rad - max_step, self.last_steer_rad + max_step);
        let steer = limit(steer, -m.max_steer_rad, m.max_steer_rad);
        if !steer.is_finite() {
            return Err(TrackError::NotFinite { field: "steer_rad (internal)", value: steer });
        }
        self.last_steer_rad = steer;
        self.last_heading_rad = Some(wrap_angle(input.heading_rad));
        self.yaw_rate_radps = yaw_rate;
        Ok(steer)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn model() -> SteeringModel {
        SteeringModel { wheelbase_m: 2.85, center_to_rear_axle_m: 1.45, max_steer_rad: 0.55, max_steer_rate_radps: 0.6 }
    }

    fn stanley(gains: LateralGains) -> Stanley {
        let mut s = Stanley::new(gains, model()).unwrap();
        // Start from any angle: these tests look at the law, not the rate limit.
        s.model.max_steer_rate_radps = 100.0;
        s
    }

    fn straight(cross_track_m: f64, heading_error_rad: f64) -> StanleyInput {
        StanleyInput { cross_track_m, heading_error_rad, speed_mps: 10.0, ..StanleyInput::default() }
    }

    #[test]
    fn left_of_the_path_steers_right_and_right_of_it_steers_left() {
        let mut s = stanley(LateralGains::default());
        assert!(s.update(&straight(0.5, 0.0), 0.1).unwrap() < 0.0);
        s.reset();
        assert!(s.update(&straight(-0.5, 0.0), 0.1).unwrap() > 0.0);
        s.reset();
        assert_eq!(s.update(&straight(0.0, 0.0), 0.1).unwrap(), 0.0);
    }

    #[test]
    fn pointing_left_of_the_path_steers_right() {
        let mut s = stanley(LateralGains::default());
        assert!((s.update(&straight(0.0, 0.1), 0.1).unwrap() + 0.1).abs() < 1e-12);
        s.reset();
        assert!((s.update(&straight(0.0, -0.1), 0.1).unwrap() - 0.1).abs() < 1e-12);
    }

    #[test]
    fn the_cross_track_term_is_the_stanley_arctangent() {
        let gains = LateralGains { heading_gain: 0.0, feedforward_preview_s: 0.0, ..LateralGains::default() };
        let mut s = stanley(gains);
        let d = s.update(&straight(-0.2, 0.0), 0.1).unwrap();
        let expected = (gains.cross_track_gain_1ps * 0.2).atan2(gains.softening_speed_mps + 10.0);
        assert!((d - expected).abs() < 1e-12, "{d} vs {expected}");
    }

    #[test]
    fn a_steady_turn_with_the_centre_on_the_path_needs_no_correction() {
        // Centre on a left circle of radius 25 m: the front axle is outside by e_ss, the heading
        // error is −δ_ss (the vehicle points right of the tangent at the front's foot point).
        let m = model();
        let kappa = 1.0 / 25.0;
        let d_ss = m.steady_steer_rad(kappa);
        let input = StanleyInput {
            cross_track_m: m.steady_front_offset_m(kappa),
            heading_error_rad: -d_ss,
            speed_mps: 10.0,
            curvature_1pm: kappa,
            preview_curvature_1pm: kappa,
            heading_rad: 0.0,
        };
        for heading_gain in [0.5, 1.0, 1.5] {
            let mut s = stanley(LateralGains { heading_gain, ..LateralGains::default() });
            assert!((s.update(&input, 0.1).unwrap() - d_ss).abs() < 1e-12);
        }
        // The steady angle and offset agree with the bicycle geometry: the rear axle on radius
        // √(R² − c²), the front axle on √(R² − c² + L²).
        let r: f64 = 25.0;
        let rear = (r * r - 1.45 * 1.45).sqrt();
        assert!((d_ss - (2.85 / rear).atan()).abs() < 1e-12);
        assert!((m.steady_front_offset_m(kappa) + ((rear * rear + 2.85 * 2.85).sqrt() - r)).abs() < 1e-12);
        // Right turns mirror.
        assert!((m.steady_steer_rad(-kappa) + d_ss).abs() < 1e-15);
        assert!(m.steady_front_offset_m(-kappa) > 0.0);
    }

    #[test]
    fn the_feedforward_reads_the_preview_curvature() {
        let mut s = stanley(LateralGains::default());
        let entering = StanleyInput { preview_curvature_1pm: 0.04, ..straight(0.0, 0.0) };
        let d = s.update(&entering, 0.1).unwrap();
        assert!((d - model().steady_steer_rad(0.04)).abs() < 1e-12, "{d}");
    }

    #[test]
    fn yaw_rate_damping_opposes_a_yaw_rate_the_path_does_not_ask_for() {
        let gains = LateralGains { yaw_damping_s: 0.2, yaw_rate_filter_s: 0.0, ..LateralGains::default() };
        let mut s = stanley(gains);
        s.update(&straight(0.0, 0.0), 0.1).unwrap();
        // Turning left at 0.5 rad/s on a straight path.
        let d = s.update(&StanleyInput { heading_rad: 0.05, ..straight(0.0, 0.0) }, 0.1).unwrap();
        assert!((d + 0.2 * 0.5).abs() < 1e-9, "{d}");
    }

    #[test]
    fn the_request_is_clamped_and_rate_limited() {
        let mut s = Stanley::new(LateralGains::default(), model()).unwrap();
        let mut prev = 0.0;
        for k in 0..40 {
            let e = if (k / 10) % 2 == 0 { -20.0 } else { 20.0 };
            let d = s.update(&straight(e, 0.0), 0.1).unwrap();
            assert!(d.abs() <= 0.55, "{d}");
            assert!((d - prev).abs() <= 0.6 * 0.1 + 1e-12, "step {k}: {prev} -> {d}");
            prev = d;
        }
        // Held long enough, it reaches the clamp.
        for _ in 0..20 {
            prev = s.update(&straight(20.0, 0.0), 0.1).unwrap();
        }
        assert_eq!(prev, -0.55);
    }

    #[test]
    fn a_bad_cycle_is_an_error_and_changes_nothing() {
        let mut s = stanley(LateralGains::default());
        s.update(&straight(0.3, 0.0), 0.1).unwrap();
        let before = s;
        assert!(matches!(s.update(&straight(0.3, 0.0), 0.0), Err(TrackError::TimeStep { .. })));
        assert!(matches!(
            s.update(&straight(f64::NAN, 0.0), 0.1),
            Err(TrackError::NotFinite { field: "cross_track_m", .. })
        ));
        assert_eq!(s, before);
    }
}
