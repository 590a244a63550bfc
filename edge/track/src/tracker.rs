//! The tracker: one cycle locates the vehicle on its path, runs the longitudinal PID and the
//! Stanley law, and returns the actuation request with the tracking errors.
//!
//! **Latency.** Between the instant a state describes and the instant a request takes effect lie
//! the localization delay, the transport delay and the actuator lag: about 0.25 s for the steering
//! and 0.45 s for the acceleration of the BV. The tracker predicts the pose over
//! `steer_latency_s` (kinematic bicycle at constant speed through the steering requests of the
//! last `steer_latency_s`, as they were held), the speed and the station over `accel_latency_s`
//! (through the acceleration requests of that window), extrapolates the plan over the same time,
//! and controls the predicted errors. With both latencies 0 it acts on the measured state.
//!
//! **Path memory.** The footprint centre and the front axle are projected with
//! [`ReferencePath::project_near`] around their previous arc lengths (the plan's station on the
//! first cycle), so a vehicle on one branch of a self-approaching path is never snapped onto the
//! other. Call [`Tracker::reset`] when the path changes.

use serde::{Deserialize, Serialize};
use v2t_model::geometry::{Point2, wrap_angle};
use v2t_model::kinematics::State;
use v2t_model::path::{FrenetPoint, ReferencePath};
use v2t_model::validate::{Validate, ValidationError, in_range, positive};
use v2t_model::vehicle::VehicleConfig;

use crate::latency::{Request, RequestHistory};
use crate::lateral::{LateralGains, Stanley, StanleyInput, SteeringModel};
use crate::longitudinal::{LongitudinalGains, LongitudinalInput, LongitudinalLimits, SpeedPid};
use crate::{TrackError, check_dt, check_finite, check_plausible, limit};

/// Speeds beyond this (measured or planned) are faults, m/s.
const MAX_PLAUSIBLE_SPEED_MPS: f64 = 150.0;
/// Planned accelerations beyond this are faults, m/s².
const MAX_PLAUSIBLE_ACCEL_MPS2: f64 = 50.0;
/// Planned stations beyond this are faults, m.
const MAX_PLAUSIBLE_STATION_M: f64 = 1.0e6;

/// Tracker settings, as written in `config/track/*.toml`. The vehicle's geometry and limits are
/// not part of the file: they come from the vehicle file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TrackerConfig {
    /// Time from the instant a state describes until a steering request computed from it takes
    /// effect (localization delay, transport delay, steering lag), s: the pose is predicted over it.
    pub steer_latency_s: f64,
    /// The same for an acceleration request (the longitudinal lag is longer), s: the speed, the
    /// station and the plan are predicted over it.
    pub accel_latency_s: f64,
    /// Longest control cycle accepted, s; a longer one means the loop stalled and is refused.
    pub max_dt_s: f64,
    /// Half-width of the window around the previous arc length in which the path is searched, m
    /// (widened by twice the distance the vehicle covers in a cycle).
    pub projection_window_m: f64,
    /// Farthest the vehicle may be from its path, m: beyond it the BV is not where its plan can
    /// take it (a localization fault, or control lost), and steering it back across the track
    /// would be a manoeuvre nobody planned. The state is refused (no command: the gate's command
    /// timeout brings the minimal-risk stop).
    pub max_cross_track_m: f64,
    /// Speed control.
    pub longitudinal: LongitudinalGains,
    /// Steering control.
    pub lateral: LateralGains,
}

impl Default for TrackerConfig {
    /// The settings of `config/track/default.toml`.
    fn default() -> Self {
        Self {
            steer_latency_s: 0.2,
            accel_latency_s: 0.45,
            max_dt_s: 0.5,
            projection_window_m: 5.0,
            max_cross_track_m: 2.0,
            longitudinal: LongitudinalGains::default(),
            lateral: LateralGains::default(),
        }
    }
}

impl Validate for TrackerConfig {
    fn validate(&self) -> Result<(), ValidationError> {
        in_range("steer_latency_s", self.steer_latency_s, 0.0, 1.0)?;
        in_range("accel_latency_s", self.accel_latency_s, 0.0, 1.0)?;
        in_range("max_dt_s", self.max_dt_s, 0.001, 2.0)?;
        positive("projection_window_m", self.projection_window_m)?;
        in_range("max_cross_track_m", self.max_cross_track_m, 0.1, 1.0e6)?;
        self.longitudinal.validate().map_err(|e| e.within("longitudinal"))?;
        self.lateral.validate().map_err(|e| e.within("lateral"))
    }
}

/// The plan at the instant the state describes.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct PlanSample {
    /// Reference station (arc length of the footprint centre along the path), m.
    pub s_m: f64,
    /// Reference speed, m/s.
    pub v_mps: f64,
    /// Reference acceleration, m/s².
    pub a_mps2: f64,
}

impl PlanSample {
    /// The plan `dt_s` later at its constant acceleration; a braking plan stops and stays.
    pub fn advanced(&self, dt_s: f64) -> Self {
        let (v0, a) = (self.v_mps, self.a_mps2);
        let t_move = if a < 0.0 && v0 >= 0.0 { (v0 / -a).min(dt_s) } else { dt_s };
        let stopped = t_move < dt_s;
        let v = if stopped { 0.0 } else { v0 + a * t_move };
        let v = if v0 >= 0.0 { v.max(0.0) } else { v };
        Self {
            s_m: self.s_m + v0 * t_move + 0.5 * a * t_move * t_move,
            v_mps: v,
            a_mps2: if stopped { 0.0 } else { a },
        }
    }
}

/// One cycle's request and the tracking errors of the measured state against the plan (both at the
/// instant the state describes; the request itself acts on the predicted errors).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct TrackerOutput {
    /// Requested acceleration, m/s² (negative brakes), within the vehicle's limits.
    pub accel_mps2: f64,
    /// Requested road-wheel angle, rad, positive left, within the vehicle's limits.
    pub steer_rad: f64,
    /// Lateral offset of the footprint centre from the path, m, positive left.
    pub cross_track_m: f64,
    /// Vehicle heading minus path heading at the centre's foot point, rad, positive when the
    /// vehicle points left of the path.
    pub heading_error_rad: f64,
    /// Plan station minus vehicle station, m (positive: the vehicle is behind its plan).
    pub station_error_m: f64,
    /// Plan speed minus vehicle speed, m/s (positive: the vehicle is too slow).
    pub speed_error_mps: f64,
    /// Arc length of the footprint centre's foot point on the path, m (the station the errors
    /// are measured at).
    pub s_m: f64,
}

/// Longitudinal PID + lateral Stanley for one vehicle.
#[derive(Debug, Clone)]
pub struct Tracker {
    config: TrackerConfig,
    pid: SpeedPid,
    stanley: Stanley,
    /// Arc lengths of the centre and the front axle at the last cycle.
    last_s: Option<(f64, f64)>,
    /// Recent requests, for the latency prediction.
    history: RequestHistory,
    /// Why the configuration was refused, if it was: every cycle then returns it.
    refused: Option<ValidationError>,
}

impl Tracker {
    /// A tracker for `vehicle` with `config`, checking both. Prefer this where the configuration
    /// has not been validated already.
    pub fn try_new(config: TrackerConfig, vehicle: &VehicleConfig) -> Result<Self, TrackError> {
        let tracker = Self::new(config, vehicle);
        match tracker.refused {
            Some(e) => Err(TrackError::Config(e)),
            None => Ok(tracker),
        }
    }

    /// A tracker for `vehicle` with `config`, at rest (no integral, wheels straight, no path memory).
    /// An invalid configuration or vehicle never panics and never drives: every cycle of such a
    /// tracker returns the validation error ([`Self::try_new`] reports it at once).
    pub fn new(config: TrackerConfig, vehicle: &VehicleConfig) -> Self {
        let lon_limits = LongitudinalLimits::from(&vehicle.limits);
        let model = SteeringModel::new(&vehicle.geometry, &vehicle.limits);
        let refused = config
            .validate()
            .and_then(|()| vehicle.geometry.validate().map_err(|e| e.within("vehicle.geometry")))
            .and_then(|()| vehicle.limits.validate().map_err(|e| e.within("vehicle.limits")))
            .err();
        let pid = SpeedPid::new_unchecked(config.longitudinal, lon_limits);
        let stanley = Stanley::new_unchecked(config.lateral, model);
        Self { config, pid, stanley, last_s: None, history: RequestHistory::new(Request::default()), refused }
    }

    /// The settings.
    pub fn config(&self) -> &TrackerConfig {
        &self.config
    }

    /// The longitudinal controller.
    pub fn longitudinal(&self) -> &SpeedPid {
        &self.pid
    }

    /// The lateral controller.
    pub fn lateral(&self) -> &Stanley {
        &self.stanley
    }

    /// Arc length of the footprint centre at the last cycle, m.
    pub fn station_m(&self) -> Option<f64> {
        self.last_s.map(|(s, _)| s)
    }

    /// Forgets the integral, the filters and the path memory (call it when the path changes); the
    /// jerk and steering-rate limits start again from 0.
    pub fn reset(&mut self) {
        self.reset_to(0.0, 0.0);
    }

    /// [`Self::reset`], with the rate limits starting from the actuators' state now (bumpless
    /// take-over from another controller).
    pub fn reset_to(&mut self, accel_mps2: f64, steer_rad: f64) {
        self.pid.reset_to(accel_mps2);
        self.stanley.reset_to(steer_rad);
        let now = Request { accel_mps2: self.pid.last_accel_mps2(), steer_rad: self.stanley.last_steer_rad() };
        self.history = RequestHistory::new(now);
        self.last_s = None;
    }

    /// One control cycle: the measured `state` (reference point: footprint centre), the `path` to
    /// follow, the `plan` at the instant the state describes, and the cycle length `dt_s`.
    ///
    /// Non-finite inputs, a cycle length outside `(0, max_dt_s]` and a state that cannot be
    /// located on the path are errors, and leave the tracker as it was.
    pub fn step(
        &mut self,
        state: &State,
        path: &ReferencePath,
        plan: &PlanSample,
        dt_s: f64,
    ) -> Result<TrackerOutput, TrackError> {
        if let Some(e) = &self.refused {
            return Err(TrackError::Config(e.clone()));
        }
        check_dt(dt_s, self.config.max_dt_s)?;
        check_finite("state.px", state.px)?;
        check_finite("state.py", state.py)?;
        check_finite("state.theta_rad", state.theta_rad)?;
        check_plausible("state.speed_mps", state.speed_mps, MAX_PLAUSIBLE_SPEED_MPS)?;
        check_plausible("plan.s_m", plan.s_m, MAX_PLAUSIBLE_STATION_M)?;
        check_plausible("plan.v_mps", plan.v_mps, MAX_PLAUSIBLE_SPEED_MPS)?;
        check_plausible("plan.a_mps2", plan.a_mps2, MAX_PLAUSIBLE_ACCEL_MPS2)?;

        let cfg = &self.config;
        let model = *self.stanley.model();
        let pose = self.history.predict_pose(state, &model, cfg.steer_latency_s, dt_s);
        let (speed_ahead, travelled) = self.history.predict_speed(state.speed_mps, cfg.accel_latency_s, dt_s);
        let (center, front) = self.locate(path, state, &pose, plan, dt_s)?;
        if center.l_m.abs() > cfg.max_cross_track_m {
            return Err(TrackError::FarFromPath { cross_track_m: center.l_m, limit_m: cfg.max_cross_track_m });
        }

        let target = plan.advanced(cfg.accel_latency_s);
        let mut pid = self.pid;
        let lon = pid.update(
            &LongitudinalInput {
                speed_mps: speed_ahead,
                station_m: center.s_m + travelled,
                ref_speed_mps: target.v_mps,
                ref_station_m: target.s_m,
                ref_accel_mps2: target.a_mps2,
            },
            dt_s,
        )?;

        let speed = limit(pose.speed_mps, 0.0, f64::MAX);
        let preview_m = speed * cfg.lateral.feedforward_preview_s;
        let mut stanley = self.stanley;
        let steer = stanley.update(
            &StanleyInput {
                cross_track_m: front.l_m,
                heading_error_rad: wrap_angle(pose.theta_rad - path.heading_at(front.s_m)),
                speed_mps: speed,
                curvature_1pm: path.curvature_at(front.s_m),
                preview_curvature_1pm: path.curvature_at(front.s_m + preview_m),
                heading_rad: state.theta_rad,
            },
            dt_s,
        )?;

        self.pid = pid;
        self.stanley = stanley;
        self.history.push(Request { accel_mps2: lon.accel_mps2, steer_rad: steer }, dt_s);
        self.last_s = Some((center.s_m, front.s_m));
        Ok(TrackerOutput {
            accel_mps2: lon.accel_mps2,
            steer_rad: steer,
            cross_track_m: center.l_m,
            heading_error_rad: wrap_angle(state.theta_rad - path.heading_at(center.s_m)),
            station_error_m: plan.s_m - center.s_m,
            speed_error_mps: plan.v_mps - state.speed_mps,
            s_m: center.s_m,
        })
    }

    /// Frenet coordinates of the measured footprint centre and of the predicted front axle.
    fn locate(
        &self,
        path: &ReferencePath,
        measured: &State,
        predicted: &State,
        plan: &PlanSample,
        dt_s: f64,
    ) -> Result<(FrenetPoint, FrenetPoint), TrackError> {
        let ahead = self.stanley.model().center_to_front_axle_m();
        let center = measured.position();
        let front = predicted.position().add(Point2::from_heading(predicted.theta_rad).scale(ahead));
        let reach = limit(measured.speed_mps.abs() * (dt_s + self.config.steer_latency_s), 0.0, 1e6);
        let (hint_center, hint_front) = self.last_s.unwrap_or((plan.s_m, plan.s_m + ahead + reach));
        let window = self.config.projection_window_m + 2.0 * reach;
        let off_path = || TrackError::OffPath { x: measured.px, y: measured.py };
        let on_path = |f: &FrenetPoint| f.s_m.is_finite() && f.l_m.is_finite();
        let c = path.project_near(center, hint_center, window).filter(on_path).ok_or_else(off_path)?;
        let f = path.project_near(front, hint_front, window).filter(on_path).ok_or_else(off_path)?;
        Ok((c, f))
    }
}

#[cfg(test)]
mod tests;
