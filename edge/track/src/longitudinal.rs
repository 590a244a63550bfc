//! Longitudinal control: a PID on speed with the plan's acceleration as feed-forward and a
//! correction on the station (position along the path) error.
//!
//! ```text
//! a_raw = g_ff·a_ref + Kp·(v_ref − v) + I − Kd·(v̇_filtered − a_ref) + Ks·clamp(s_ref − s)
//! a     = jerk_limit(clamp(a_raw, −max_decel, max_accel))
//! I    += Ki·(v_ref − v)·dt   unless a was cut by a limit in the direction the error pushes
//! ```
//!
//! Anti-windup is conditional integration ("clamping"): while the request is cut by the
//! acceleration or jerk limit and the speed error pushes further into that limit, the integral
//! holds. It never winds up while the vehicle cannot follow, and it never gets pushed past zero
//! either (which back-calculation does when the proportional term alone saturates, and which
//! makes the request undershoot once the error closes).
//!
//! The derivative acts on the measured speed (its rate, low-pass filtered, against the plan's
//! acceleration), so a step in `v_ref` gives no kick. The integral is also kept inside the
//! acceleration range. Whatever finite numbers come in, the output is finite, inside
//! `[−max_decel, max_accel]` and within `max_jerk·dt` of the previous output.

use serde::{Deserialize, Serialize};
use v2t_model::validate::{Validate, ValidationError, in_range, positive};
use v2t_model::vehicle::VehicleLimits;

use crate::{TrackError, check_dt, check_finite, limit};

/// The largest speed error acted on, m/s (keeps intermediates finite for absurd inputs).
const MAX_SPEED_ERROR_MPS: f64 = 100.0;
/// The largest speed rate or plan acceleration taken into account, m/s².
const MAX_ACCEL_INPUT_MPS2: f64 = 100.0;

/// Gains of the longitudinal controller, as written in `[longitudinal]` of `config/track/*.toml`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LongitudinalGains {
    /// Weight of the plan's acceleration (feed-forward), 1 = take it as is.
    pub feedforward_gain: f64,
    /// Proportional gain on the speed error, 1/s (m/s² per m/s).
    pub kp_1ps: f64,
    /// Integral gain on the speed error, 1/s² (m/s² per m of integrated speed error).
    pub ki_1ps2: f64,
    /// Derivative gain on the measured speed rate, dimensionless (m/s² per m/s²).
    pub kd: f64,
    /// Time constant of the low-pass filter on the measured speed rate, s.
    pub derivative_filter_s: f64,
    /// Gain on the station error `s_ref − s`, 1/s² (m/s² per m).
    pub station_gain_1ps2: f64,
    /// The station error is clamped to ± this before it is used, m.
    pub max_station_error_m: f64,
}

impl Validate for LongitudinalGains {
    fn validate(&self) -> Result<(), ValidationError> {
        in_range("feedforward_gain", self.feedforward_gain, 0.0, 2.0)?;
        in_range("kp_1ps", self.kp_1ps, 0.0, 20.0)?;
        in_range("ki_1ps2", self.ki_1ps2, 0.0, 20.0)?;
        in_range("kd", self.kd, 0.0, 5.0)?;
        in_range("derivative_filter_s", self.derivative_filter_s, 0.0, 5.0)?;
        in_range("station_gain_1ps2", self.station_gain_1ps2, 0.0, 20.0)?;
        in_range("max_station_error_m", self.max_station_error_m, 0.0, 100.0)
    }
}

impl Default for LongitudinalGains {
    fn default() -> Self {
        Self {
            feedforward_gain: 1.0,
            kp_1ps: 2.0,
            ki_1ps2: 0.1,
            kd: 0.0,
            derivative_filter_s: 0.3,
            station_gain_1ps2: 0.5,
            max_station_error_m: 5.0,
        }
    }
}

/// The vehicle's longitudinal limits the controller respects.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LongitudinalLimits {
    /// Largest forward acceleration, m/s².
    pub max_accel_mps2: f64,
    /// Largest deceleration (positive number), m/s².
    pub max_decel_mps2: f64,
    /// Largest rate of change of the requested acceleration, m/s³.
    pub max_jerk_mps3: f64,
}

impl From<&VehicleLimits> for LongitudinalLimits {
    fn from(l: &VehicleLimits) -> Self {
        Self { max_accel_mps2: l.max_accel_mps2, max_decel_mps2: l.max_decel_mps2, max_jerk_mps3: l.max_jerk_mps3 }
    }
}

impl Validate for LongitudinalLimits {
    fn validate(&self) -> Result<(), ValidationError> {
        in_range("max_accel_mps2", self.max_accel_mps2, 0.1, 10.0)?;
        in_range("max_decel_mps2", self.max_decel_mps2, 0.1, 12.0)?;
        positive("max_jerk_mps3", self.max_jerk_mps3)
    }
}

/// One cycle's measurement and reference, all at the same instant.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct LongitudinalInput {
    /// Measured speed, m/s.
    pub speed_mps: f64,
    /// Measured station (arc length along the path), m.
    pub station_m: f64,
    /// Reference speed, m/s.
    pub ref_speed_mps: f64,
    /// Reference station, m.
    pub ref_station_m: f64,
    /// Reference acceleration (feed-forward), m/s².
    pub ref_accel_mps2: f64,
}

/// One cycle's result.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LongitudinalOutput {
    /// Requested acceleration, m/s² (negative brakes).
    pub accel_mps2: f64,
    /// `v_ref − v`, m/s.
    pub speed_error_mps: f64,
    /// `s_ref − s`, m (before clamping).
    pub station_error_m: f64,
    /// The request was cut by the acceleration or jerk limit.
    pub saturated: bool,
}

/// The longitudinal PID. `Copy`: a cycle can be computed on a copy and committed when it succeeds.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SpeedPid {
    gains: LongitudinalGains,
    limits: LongitudinalLimits,
    /// Integral term, already in m/s².
    integral_mps2: f64,
    /// Filtered rate of the measured speed, m/s².
    speed_rate_mps2: f64,
    last_speed_mps: Option<f64>,
    last_accel_mps2: f64,
}

impl SpeedPid {
    /// A controller at rest (no integral, previous request 0 m/s²), after checking gains and limits.
    pub fn new(gains: LongitudinalGains, limits: LongitudinalLimits) -> Result<Self, TrackError> {
        gains.validate().map_err(|e| e.within("longitudinal"))?;
        limits.validate().map_err(|e| e.within("limits"))?;
        Ok(Self::new_unchecked(gains, limits))
    }

    pub(crate) fn new_unchecked(gains: LongitudinalGains, limits: LongitudinalLimits) -> Self {
        Self { gains, limits, integral_mps2: 0.0, speed_rate_mps2: 0.0, last_speed_mps: None, last_accel_mps2: 0.0 }
    }

    /// Forgets the integral and the speed history; the jerk limit starts again from 0 m/s².
    pub fn reset(&mut self) {
        self.reset_to(0.0);
    }

    /// [`Self::reset`], with the jerk limit starting from `accel_mps2` (the acceleration the
    /// actuators deliver now, for a bumpless take-over; a non-finite value counts as 0).
    pub fn reset_to(&mut self, accel_mps2: f64) {
        let a = if accel_mps2.is_finite() { accel_mps2 } else { 0.0 };
        self.integral_mps2 = 0.0;
        self.speed_rate_mps2 = 0.0;
        self.last_speed_mps = None;
        self.last_accel_mps2 = limit(a, -self.limits.max_decel_mps2, self.limits.max_accel_mps2);
    }

    /// The integral term, m/s².
    pub fn integral_mps2(&self) -> f64 {
        self.integral_mps2
    }

    /// The last request, m/s².
    pub fn last_accel_mps2(&self) -> f64 {
        self.last_accel_mps2
    }

    /// The gains.
    pub fn gains(&self) -> &LongitudinalGains {
        &self.gains
    }

    /// One control cycle of length `dt_s`. Rejects a non-positive or non-finite `dt_s` and
    /// non-finite inputs without changing the controller.
    pub fn update(&mut self, input: &LongitudinalInput, dt_s: f64) -> Result<LongitudinalOutput, TrackError> {
        check_dt(dt_s, f64::INFINITY)?;
        check_finite("speed_mps", input.speed_mps)?;
        check_finite("station_m", input.station_m)?;
        check_finite("plan.v_mps", input.ref_speed_mps)?;
        check_finite("plan.s_m", input.ref_station_m)?;
        check_finite("plan.a_mps2", input.ref_accel_mps2)?;
        let g = &self.gains;
        let (lo, hi) = (-self.limits.max_decel_mps2, self.limits.max_accel_mps2);
        let a_ref = limit(input.ref_accel_mps2, -MAX_ACCEL_INPUT_MPS2, MAX_ACCEL_INPUT_MPS2);
        let speed_error = input.ref_speed_mps - input.speed_mps;
        let e_v = limit(speed_error, -MAX_SPEED_ERROR_MPS, MAX_SPEED_ERROR_MPS);
        let station_error = input.ref_station_m - input.station_m;
        let e_s = limit(station_error, -g.max_station_error_m, g.max_station_error_m);

        // Derivative on the measurement: the filtered rate of the measured speed against a_ref.
        let rate = match self.last_speed_mps {
            Some(prev) => {
                let raw = limit((input.speed_mps - prev) / dt_s, -MAX_ACCEL_INPUT_MPS2, MAX_ACCEL_INPUT_MPS2);
                self.speed_rate_mps2 + (raw - self.speed_rate_mps2) * dt_s / (g.derivative_filter_s + dt_s)
            }
            None => a_ref,
        };
        let derivative = -g.kd * (rate - a_ref);

        let raw =
            g.feedforward_gain * a_ref + g.kp_1ps * e_v + self.integral_mps2 + derivative + g.station_gain_1ps2 * e_s;
        let saturated_value = limit(raw, lo, hi);
        let max_step = self.limits.max_jerk_mps3 * dt_s;
        let accel = limit(saturated_value, self.last_accel_mps2 - max_step, self.last_accel_mps2 + max_step);
        let accel = limit(accel, lo, hi);
        if !accel.is_finite() {
            return Err(TrackError::NotFinite { field: "accel_mps2 (internal)", value: accel });
        }
        // Conditional integration: hold while a limit cuts the request in the error's direction.
        let cut_above = accel < raw - 1e-9;
        let cut_below = accel > raw + 1e-9;
        let winding = (cut_above && e_v > 0.0) || (cut_below && e_v < 0.0);
        if !winding {
            let integral = self.integral_mps2 + g.ki_1ps2 * e_v * dt_s;
            self.integral_mps2 = if integral.is_finite() { limit(integral, lo, hi) } else { 0.0 };
        }
        self.speed_rate_mps2 = rate;
        self.last_speed_mps = Some(input.speed_mps);
        self.last_accel_mps2 = accel;
        Ok(LongitudinalOutput {
            accel_mps2: accel,
            speed_error_mps: speed_error,
            station_error_m: station_error,
            saturated: cut_above || cut_below,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn limits() -> LongitudinalLimits {
        LongitudinalLimits { max_accel_mps2: 3.0, max_decel_mps2: 6.0, max_jerk_mps3: 8.0 }
    }

    fn pid(gains: LongitudinalGains) -> SpeedPid {
        SpeedPid::new(gains, limits()).unwrap()
    }

    fn at(v: f64, v_ref: f64) -> LongitudinalInput {
        LongitudinalInput {
            speed_mps: v,
            station_m: 0.0,
            ref_speed_mps: v_ref,
            ref_station_m: 0.0,
            ref_accel_mps2: 0.0,
        }
    }

    #[test]
    fn proportional_feedforward_and_station_terms_add_up() {
        let gains = LongitudinalGains {
            feedforward_gain: 1.0,
            kp_1ps: 0.5,
            ki_1ps2: 0.0,
            kd: 0.0,
            derivative_filter_s: 0.1,
            station_gain_1ps2: 0.2,
            max_station_error_m: 5.0,
        };
        let mut c = pid(gains);
        c.reset_to(1.0);
        let input = LongitudinalInput {
            speed_mps: 9.0,
            station_m: 10.0,
            ref_speed_mps: 10.0,
            ref_station_m: 11.0,
            ref_accel_mps2: 0.3,
        };
        let out = c.update(&input, 0.1).unwrap();
        assert!((out.accel_mps2 - (0.3 + 0.5 + 0.2)).abs() < 1e-12, "{out:?}");
        assert!(!out.saturated);
        assert_eq!((out.speed_error_mps, out.station_error_m), (1.0, 1.0));
        // The station error is clamped: 100 m behind pulls like 5 m.
        let mut c = pid(gains);
        c.reset_to(2.0);
        let far = LongitudinalInput { ref_station_m: 110.0, ..input };
        assert!((c.update(&far, 0.1).unwrap().accel_mps2 - (0.3 + 0.5 + 1.0)).abs() < 1e-12);
    }

    #[test]
    fn output_saturates_at_the_vehicle_limits() {
        let mut c = pid(LongitudinalGains::default());
        c.reset_to(3.0);
        let out = c.update(&at(0.0, 30.0), 0.1).unwrap();
        assert_eq!(out.accel_mps2, 3.0);
        assert!(out.saturated);
        c.reset_to(-6.0);
        assert_eq!(c.update(&at(30.0, 0.0), 0.1).unwrap().accel_mps2, -6.0);
    }

    #[test]
    fn anti_windup_keeps_the_integral_bounded_and_recovery_fast() {
        let gains = LongitudinalGains { ki_1ps2: 2.0, ..LongitudinalGains::default() };
        // A long saturated phase: 20 m/s too slow for 30 s (a plant that cannot accelerate).
        let mut c = pid(gains);
        for _ in 0..300 {
            let out = c.update(&at(0.0, 20.0), 0.1).unwrap();
            assert!(out.accel_mps2 <= 3.0);
        }
        // A naive integrator would hold ∫e = 600 m·s, i.e. 1200 m/s² of pull; this one held
        // (it only integrated during the first jerk-limited cycles).
        assert!(c.integral_mps2() >= 0.0 && c.integral_mps2() < 1.5, "{}", c.integral_mps2());
        // Once the speed is reached, the request leaves full throttle at the jerk limit instead of
        // staying pinned there while a wound-up integral drains.
        let mut cycles = 0;
        while c.update(&at(20.0, 20.0), 0.1).unwrap().accel_mps2 > c.integral_mps2() + 1e-9 {
            cycles += 1;
            assert!(cycles <= 4, "still pulling after {cycles} cycles: integral {}", c.integral_mps2());
        }
    }

    #[test]
    fn the_integral_holds_while_braking_is_saturated() {
        let gains = LongitudinalGains { ki_1ps2: 1.0, ..LongitudinalGains::default() };
        let mut c = pid(gains);
        c.reset_to(-6.0);
        for _ in 0..100 {
            let out = c.update(&at(25.0, 0.0), 0.1).unwrap();
            assert_eq!(out.accel_mps2, -6.0);
            assert!(out.saturated);
        }
        assert_eq!(c.integral_mps2(), 0.0);
    }

    #[test]
    fn the_integral_removes_a_steady_disturbance() {
        // A plant with a constant 0.5 m/s² drag: v' = a − 0.5 (first order, no lag).
        let gains = LongitudinalGains { station_gain_1ps2: 0.0, ..LongitudinalGains::default() };
        let mut c = pid(gains);
        let mut v = 10.0;
        for _ in 0..2000 {
            let a = c.update(&at(v, 10.0), 0.1).unwrap().accel_mps2;
            v += (a - 0.5) * 0.1;
        }
        assert!((v - 10.0).abs() < 0.01, "{v}");
        assert!((c.integral_mps2() - 0.5).abs() < 0.02, "{}", c.integral_mps2());
    }

    #[test]
    fn the_request_changes_no_faster_than_the_jerk_limit() {
        let mut c = pid(LongitudinalGains::default());
        let mut prev = 0.0;
        for k in 0..40 {
            let v_ref = if (k / 10) % 2 == 0 { 30.0 } else { 0.0 };
            let a = c.update(&at(10.0, v_ref), 0.05).unwrap().accel_mps2;
            assert!((a - prev).abs() <= 8.0 * 0.05 + 1e-12, "step {k}: {prev} -> {a}");
            prev = a;
        }
    }

    #[test]
    fn a_step_in_the_reference_speed_gives_no_derivative_kick() {
        let gains = LongitudinalGains { kp_1ps: 0.0, ki_1ps2: 0.0, kd: 2.0, ..LongitudinalGains::default() };
        let mut c = pid(gains);
        c.update(&at(10.0, 10.0), 0.1).unwrap();
        assert_eq!(c.update(&at(10.0, 15.0), 0.1).unwrap().accel_mps2, 0.0);
        // A measured speed rising while the plan holds its speed is damped.
        assert!(c.update(&at(10.5, 15.0), 0.1).unwrap().accel_mps2 < 0.0);
    }

    #[test]
    fn bad_time_steps_and_nan_inputs_are_errors_and_change_nothing() {
        let mut c = pid(LongitudinalGains::default());
        c.update(&at(10.0, 12.0), 0.1).unwrap();
        let before = c;
        for dt in [0.0, -0.1, f64::NAN, f64::INFINITY] {
            assert!(matches!(c.update(&at(10.0, 12.0), dt), Err(TrackError::TimeStep { .. })), "{dt}");
        }
        let nan = LongitudinalInput { ref_accel_mps2: f64::NAN, ..at(10.0, 12.0) };
        assert!(matches!(c.update(&nan, 0.1), Err(TrackError::NotFinite { field: "plan.a_mps2", .. })));
        assert!(c.update(&at(f64::NAN, 12.0), 0.1).is_err());
        assert_eq!(c, before);
    }

    #[test]
    fn invalid_gains_are_refused_with_the_field_name() {
        let gains = LongitudinalGains { kp_1ps: f64::NAN, ..LongitudinalGains::default() };
        let err = SpeedPid::new(gains, limits()).unwrap_err();
        assert!(err.to_string().contains("longitudinal.kp_1ps"), "{err}");
        let bad = LongitudinalLimits { max_jerk_mps3: -1.0, ..limits() };
        assert!(SpeedPid::new(LongitudinalGains::default(), bad).unwrap_err().to_string().contains("max_jerk_mps3"));
    }
}
