//! The actuation safety gate: the last thing between the tracker and the actuators.
//!
//! Pure: [`SafetyGate::step`] takes the time and the newest inputs and returns what to send; it
//! reads no clock and does no IO. Whatever comes in, what goes out lies inside the envelope:
//!
//! - acceleration within `[-max_decel, max_accel]` of the vehicle, changing by at most
//!   `max_jerk · dt` from the previously sent value, never rising above zero at or beyond the
//!   top speed (in either direction);
//! - road-wheel angle within the speed-dependent limit `min(max_steer, atan(L · a_lat / v²))`,
//!   changing by at most `min(max_steer_rate, L · j_lat / v²) · dt` (lateral acceleration and
//!   lateral jerk of the kinematic bicycle, `a_lat = v² tan δ / L`). If the speed rises faster
//!   than the steering may follow, the angle limit wins: the angle is cut to it at once, a move
//!   toward straight ahead. A speed that is not finite counts as the top speed;
//! - nothing that is not finite: a NaN or an infinity in a command stops the vehicle instead.
//!
//! States and transitions:
//!
//! | from | event | to (reason) |
//! | --- | --- | --- |
//! | Disengaged | `Engage` with a fresh, finite command, fresh feedback, DBW manual or auto | Engaged (`EngageRequest`) |
//! | Disengaged | `Engage` otherwise | Disengaged (`EngageRefused`) |
//! | Engaged | `EStop` | MinimalRiskStop at maximum braking (`EStop`) |
//! | Engaged | `Disengage` or `Reset` | Disengaged (`DisengageRequest`) |
//! | Engaged | `MinimalRiskStop` | MinimalRiskStop (`StopRequest`) |
//! | Engaged | command not finite | MinimalRiskStop (`NonFiniteCommand`) |
//! | Engaged | DBW reports override, fault or an unknown mode | MinimalRiskStop (`DbwFault`) |
//! | Engaged | no command, or one older than `command_timeout_s` | MinimalRiskStop (`CommandTimeout`) |
//! | Engaged | no feedback, one older than `feedback_timeout_s`, or a speed not finite | MinimalRiskStop (`FeedbackTimeout`) |
//! | Engaged | [`SafetyGate::bus_error`] | MinimalRiskStop (`BusError`) |
//! | MinimalRiskStop | `EStop` | MinimalRiskStop at maximum braking (`EStop`) |
//! | MinimalRiskStop | `Disengage` or `Reset` | Disengaged (`DisengageRequest`) |
//! | any | configuration invalid at construction | Fault (`Init`), permanently |
//!
//! A DBW that still reports manual while engaged is tolerated (it switches to auto when it sees
//! the engage request); override, fault or an unknown mode code are not.
//! In the minimal-risk stop the gate brakes on its own profile — toward `-stop_decel_mps2` at
//! `stop_jerk_mps3` (an e-stop: toward the vehicle's `-max_decel_mps2` at its `max_jerk_mps3`),
//! never braking less than it already did — holds the steering angle, and keeps braking at
//! standstill until an explicit `Disengage` or `Reset`; commands and `Engage` are ignored.
//! Disengaged and Fault send zeros with `enable = false`, so an engagement ramps up from zero.
//! `MinimalRiskStop` and `EStop` requests while disengaged are ignored: the safety driver drives.

use serde::{Deserialize, Serialize};
use v2t_model::validate::{Validate, ValidationError, in_range};
use v2t_model::vehicle::VehicleConfig;
pub use v2t_wire::{GateReason, GateState};

/// Settings of the gate (`config/can/gate.toml`); the vehicle limits come from the vehicle file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GateConfig {
    /// A tracker command older than this stops the vehicle, s.
    pub command_timeout_s: f64,
    /// Vehicle feedback older than this stops the vehicle, s.
    pub feedback_timeout_s: f64,
    /// Deceleration of the minimal-risk stop (positive), m/s²; at most the vehicle's `max_decel_mps2`.
    pub stop_decel_mps2: f64,
    /// Jerk with which the minimal-risk stop builds up its deceleration, m/s³; at most the
    /// vehicle's `max_jerk_mps3`.
    pub stop_jerk_mps3: f64,
    /// Below this speed the stop is complete (standstill), m/s.
    pub standstill_speed_mps: f64,
    /// Largest lateral acceleration the steering may command, m/s²; at most the vehicle's.
    pub max_lat_accel_mps2: f64,
    /// Largest lateral jerk the steering rate may cause, m/s³.
    pub max_lat_jerk_mps3: f64,
}

impl Validate for GateConfig {
    fn validate(&self) -> Result<(), ValidationError> {
        in_range("command_timeout_s", self.command_timeout_s, 0.001, 5.0)?;
        in_range("feedback_timeout_s", self.feedback_timeout_s, 0.001, 5.0)?;
        in_range("stop_decel_mps2", self.stop_decel_mps2, 0.5, 12.0)?;
        in_range("stop_jerk_mps3", self.stop_jerk_mps3, 0.5, 100.0)?;
        in_range("standstill_speed_mps", self.standstill_speed_mps, 0.0, 1.0)?;
        in_range("max_lat_accel_mps2", self.max_lat_accel_mps2, 0.1, 12.0)?;
        in_range("max_lat_jerk_mps3", self.max_lat_jerk_mps3, 0.1, 100.0)
    }
}

impl GateConfig {
    /// Validates these settings, `vehicle`, and the settings against the vehicle's limits.
    pub fn validate_for(&self, vehicle: &VehicleConfig) -> Result<(), ValidationError> {
        self.validate()?;
        vehicle.validate().map_err(|e| e.within("vehicle"))?;
        let l = &vehicle.limits;
        let at_most = |field: &str, value: f64, limit: f64, name: &str| {
            if value <= limit {
                Ok(())
            } else {
                Err(ValidationError::new(field, format!("{value} exceeds the vehicle's {name} {limit}")))
            }
        };
        at_most("stop_decel_mps2", self.stop_decel_mps2, l.max_decel_mps2, "max_decel_mps2")?;
        at_most("stop_jerk_mps3", self.stop_jerk_mps3, l.max_jerk_mps3, "max_jerk_mps3")?;
        at_most("max_lat_accel_mps2", self.max_lat_accel_mps2, l.max_lat_accel_mps2, "max_lat_accel_mps2")
    }
}

/// `lo ≤ x ≤ hi` without `f64::clamp`'s panics; a NaN `x` becomes `lo`.
fn clamp_to(x: f64, lo: f64, hi: f64) -> f64 {
    x.max(lo).min(hi)
}

/// The limits every output of the gate satisfies.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Envelope {
    /// Largest acceleration, m/s².
    pub max_accel_mps2: f64,
    /// Largest deceleration (positive), m/s².
    pub max_decel_mps2: f64,
    /// Largest change of the acceleration, m/s³.
    pub max_jerk_mps3: f64,
    /// Top speed: no positive acceleration at or above it, m/s.
    pub max_speed_mps: f64,
    /// Largest road-wheel angle at standstill, rad.
    pub max_steer_rad: f64,
    /// Largest steering rate at standstill, rad/s.
    pub max_steer_rate_radps: f64,
    /// Wheelbase, m.
    pub wheelbase_m: f64,
    /// Largest lateral acceleration, m/s².
    pub max_lat_accel_mps2: f64,
    /// Largest lateral jerk, m/s³.
    pub max_lat_jerk_mps3: f64,
}

impl Envelope {
    /// The envelope of `vehicle` narrowed by `cfg`.
    pub fn new(cfg: &GateConfig, vehicle: &VehicleConfig) -> Self {
        let l = &vehicle.limits;
        Self {
            max_accel_mps2: l.max_accel_mps2,
            max_decel_mps2: l.max_decel_mps2,
            max_jerk_mps3: l.max_jerk_mps3,
            max_speed_mps: l.max_speed_mps,
            max_steer_rad: l.max_steer_rad,
            max_steer_rate_radps: l.max_steer_rate_radps,
            wheelbase_m: vehicle.geometry.wheelbase_m,
            max_lat_accel_mps2: cfg.max_lat_accel_mps2.min(l.max_lat_accel_mps2),
            max_lat_jerk_mps3: cfg.max_lat_jerk_mps3,
        }
    }

    /// The speed the steering limits assume: `|speed|`, or the top speed when it is not finite.
    pub fn limit_speed_mps(&self, speed_mps: f64) -> f64 {
        if speed_mps.is_finite() { speed_mps.abs() } else { self.max_speed_mps }
    }

    /// Largest road-wheel angle at `speed_mps`, rad.
    pub fn steer_limit_rad(&self, speed_mps: f64) -> f64 {
        let v = self.limit_speed_mps(speed_mps);
        let v2 = v * v;
        if v2 > 0.0 {
            self.max_steer_rad.min((self.wheelbase_m * self.max_lat_accel_mps2 / v2).atan())
        } else {
            self.max_steer_rad
        }
    }

    /// Largest steering rate at `speed_mps`, rad/s.
    pub fn steer_rate_limit_radps(&self, speed_mps: f64) -> f64 {
        let v = self.limit_speed_mps(speed_mps);
        let v2 = v * v;
        if v2 > 0.0 {
            self.max_steer_rate_radps.min(self.wheelbase_m * self.max_lat_jerk_mps3 / v2)
        } else {
            self.max_steer_rate_radps
        }
    }
}

/// DBW mode codes of `DBW_Feedback.Mode` (as `v2t_wire::DbwMode`).
pub mod dbw_mode {
    /// The driver drives; the DBW is ready to be engaged.
    pub const MANUAL: u8 = 0;
    /// The DBW executes commands.
    pub const AUTO: u8 = 1;
    /// The safety driver overrode the commands.
    pub const OVERRIDE: u8 = 2;
    /// The DBW has a fault.
    pub const FAULT: u8 = 3;
}

/// A request from the monitor or the operator.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Request {
    /// Engage (pass commands to the actuators).
    Engage,
    /// Disengage (hand back to the safety driver).
    Disengage,
    /// Stop on the minimal-risk profile.
    MinimalRiskStop,
    /// Emergency stop: maximum permitted braking.
    EStop,
    /// Leave a minimal-risk stop (as `Disengage`).
    Reset,
}

/// The tracker's newest command.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Command {
    /// Requested acceleration, m/s².
    pub accel_mps2: f64,
    /// Requested road-wheel angle, rad.
    pub steer_rad: f64,
    /// When the command was made, s (same clock as `now_s`).
    pub stamp_s: f64,
}

/// Everything the gate looks at in one step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GateInput {
    /// The newest tracker command, if any.
    pub command: Option<Command>,
    /// A request that arrived since the last step, if any.
    pub request: Option<Request>,
    /// Measured speed, m/s.
    pub speed_mps: f64,
    /// DBW mode code (see [`dbw_mode`]).
    pub dbw_mode: u8,
    /// When the newest vehicle feedback arrived, s; `None` before the first.
    pub feedback_stamp_s: Option<f64>,
}

/// What to send.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GateOutput {
    /// Acceleration request, m/s².
    pub accel_mps2: f64,
    /// Road-wheel angle request, rad.
    pub steer_rad: f64,
    /// Whether the DBW shall execute the requests.
    pub enable: bool,
    /// State after this step.
    pub state: GateState,
    /// Reason of the last transition.
    pub reason: GateReason,
}

/// Braking profile of a minimal-risk stop.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum StopProfile {
    /// `stop_decel_mps2` at `stop_jerk_mps3`.
    Configured,
    /// The vehicle's `max_decel_mps2` at `max_jerk_mps3`.
    Emergency,
}

/// The safety gate. See the module documentation.
#[derive(Debug, Clone)]
pub struct SafetyGate {
    cfg: GateConfig,
    env: Envelope,
    state: GateState,
    reason: GateReason,
    profile: StopProfile,
    last_now_s: Option<f64>,
    accel_mps2: f64,
    steer_rad: f64,
}

fn is_fresh(now_s: f64, stamp_s: f64, timeout_s: f64) -> bool {
    let age = now_s - stamp_s;
    // Written so that NaN fails; a stamp far in the future is as wrong as an old one.
    age <= timeout_s && age >= -timeout_s
}

impl SafetyGate {
    /// A disengaged gate, or — if `cfg` does not validate against `vehicle` — a gate latched in
    /// [`GateState::Fault`] that never engages.
    pub fn new(cfg: GateConfig, vehicle: &VehicleConfig) -> Self {
        let ok = cfg.validate_for(vehicle).is_ok();
        let mut gate = Self::build(cfg, vehicle);
        if !ok {
            gate.state = GateState::Fault;
        }
        gate
    }

    /// A disengaged gate; an error if `cfg` does not validate against `vehicle`.
    pub fn try_new(cfg: GateConfig, vehicle: &VehicleConfig) -> Result<Self, ValidationError> {
        cfg.validate_for(vehicle)?;
        Ok(Self::build(cfg, vehicle))
    }

    fn build(cfg: GateConfig, vehicle: &VehicleConfig) -> Self {
        Self {
            env: Envelope::new(&cfg, vehicle),
            cfg,
            state: GateState::Disengaged,
            reason: GateReason::Init,
            profile: StopProfile::Configured,
            last_now_s: None,
            accel_mps2: 0.0,
            steer_rad: 0.0,
        }
    }

    /// The settings.
    pub fn config(&self) -> &GateConfig {
        &self.cfg
    }

    /// The envelope every output lies in.
    pub fn envelope(&self) -> &Envelope {
        &self.env
    }

    /// Current state.
    pub fn state(&self) -> GateState {
        self.state
    }

    /// Reason of the last transition.
    pub fn reason(&self) -> GateReason {
        self.reason
    }

    /// A CAN bus error (send or receive failed, bus-off, error-passive): an engaged gate starts
    /// its minimal-risk stop; the next [`SafetyGate::step`] sends it.
    pub fn bus_error(&mut self) {
        if self.state == GateState::Engaged {
            self.enter_stop(StopProfile::Configured, GateReason::BusError);
        }
    }

    /// One step at time `now_s` (s, the caller's clock): transitions, then the output.
    pub fn step(&mut self, now_s: f64, input: &GateInput) -> GateOutput {
        let dt = self.advance_clock(now_s);
        self.transition(now_s, input);
        self.actuate(dt, input)
    }

    /// Time since the last step; 0 on the first step, when time did not advance, or when `now_s`
    /// is not finite.
    fn advance_clock(&mut self, now_s: f64) -> f64 {
        if !now_s.is_finite() {
            return 0.0;
        }
        match self.last_now_s {
            Some(last) if now_s > last => {
                self.last_now_s = Some(now_s);
                now_s - last
            }
            Some(_) => 0.0,
            None => {
                self.last_now_s = Some(now_s);
                0.0
            }
        }
    }

    fn enter_stop(&mut self, profile: StopProfile, reason: GateReason) {
        self.state = GateState::MinimalRiskStop;
        self.profile = profile;
        self.reason = reason;
    }

    fn disengage(&mut self) {
        self.state = GateState::Disengaged;
        self.reason = GateReason::DisengageRequest;
    }

    fn command_finite(c: &Command) -> bool {
        c.accel_mps2.is_finite() && c.steer_rad.is_finite() && c.stamp_s.is_finite()
    }

    fn command_fresh(&self, now_s: f64, input: &GateInput) -> bool {
        input.command.is_some_and(|c| is_fresh(now_s, c.stamp_s, self.cfg.command_timeout_s))
    }

    fn feedback_fresh(&self, now_s: f64, input: &GateInput) -> bool {
        input.speed_mps.is_finite()
            && input.feedback_stamp_s.is_some_and(|t| is_fresh(now_s, t, self.cfg.feedback_timeout_s))
    }

    /// Whether an engage request may be granted.
    fn ready(&self, now_s: f64, input: &GateInput) -> bool {
        let mode_ready = matches!(input.dbw_mode, dbw_mode::MANUAL | dbw_mode::AUTO);
        input.command.is_some_and(|c| Self::command_finite(&c))
            && self.command_fresh(now_s, input)
            && self.feedback_fresh(now_s, input)
            && mode_ready
    }

    /// Why an engaged gate must leave `Engaged`, if it must.
    fn engaged_exit(&self, now_s: f64, input: &GateInput) -> Option<(GateState, StopProfile, GateReason)> {
        use GateReason as R;
        let stop = |reason| Some((GateState::MinimalRiskStop, StopProfile::Configured, reason));
        match input.request {
            Some(Request::EStop) => return Some((GateState::MinimalRiskStop, StopProfile::Emergency, R::EStop)),
            Some(Request::Disengage | Request::Reset) => {
                return Some((GateState::Disengaged, StopProfile::Configured, R::DisengageRequest));
            }
            Some(Request::MinimalRiskStop) => return stop(R::StopRequest),
            Some(Request::Engage) | None => {}
        }
        if input.command.is_some_and(|c| !Self::command_finite(&c)) {
            return stop(R::NonFiniteCommand);
        }
        if !matches!(input.dbw_mode, dbw_mode::MANUAL | dbw_mode::AUTO) {
            return stop(R::DbwFault);
        }
        if !self.command_fresh(now_s, input) {
            return stop(R::CommandTimeout);
        }
        if !self.feedback_fresh(now_s, input) {
            return stop(R::FeedbackTimeout);
        }
        None
    }

    fn transition(&mut self, now_s: f64, input: &GateInput) {
        match self.state {
            GateState::Fault => {}
            GateState::Disengaged => {
                if input.request == Some(Request::Engage) {
                    if self.ready(now_s, input) {
                        self.state = GateState::Engaged;
                        self.reason = GateReason::EngageRequest;
                    } else {
                        self.reason = GateReason::EngageRefused;
                    }
                }
            }
            GateState::Engaged => match self.engaged_exit(now_s, input) {
                Some((GateState::Disengaged, _, _)) => self.disengage(),
                Some((_, profile, reason)) => self.enter_stop(profile, reason),
                None => {}
            },
            GateState::MinimalRiskStop => match input.request {
                Some(Request::EStop) => self.enter_stop(StopProfile::Emergency, GateReason::EStop),
                Some(Request::Disengage | Request::Reset) => self.disengage(),
                Some(Request::Engage | Request::MinimalRiskStop) | None => {}
            },
        }
    }

    /// The acceleration after one jerk-limited move from the last one toward `target`.
    fn ramp_accel(&self, target: f64, jerk_mps3: f64, dt: f64) -> f64 {
        let env = &self.env;
        let step = jerk_mps3.min(env.max_jerk_mps3) * dt;
        let next = self.accel_mps2 + clamp_to(target - self.accel_mps2, -step, step);
        clamp_to(next, -env.max_decel_mps2, env.max_accel_mps2)
    }

    /// The angle after one rate-limited move from the last one toward `target`, then cut to the
    /// angle limit at `speed_mps`.
    fn ramp_steer(&self, target: f64, speed_mps: f64, dt: f64) -> f64 {
        let limit = self.env.steer_limit_rad(speed_mps);
        let step = self.env.steer_rate_limit_radps(speed_mps) * dt;
        let target = clamp_to(target, -limit, limit);
        let next = self.steer_rad + clamp_to(target - self.steer_rad, -step, step);
        clamp_to(next, -limit, limit)
    }

    fn actuate(&mut self, dt: f64, input: &GateInput) -> GateOutput {
        let env = self.env;
        let (accel, steer, enable) = match (self.state, input.command) {
            (GateState::Engaged, Some(cmd)) => {
                let mut target = clamp_to(cmd.accel_mps2, -env.max_decel_mps2, env.max_accel_mps2);
                let below_top_speed = env.limit_speed_mps(input.speed_mps) < env.max_speed_mps;
                if !below_top_speed {
                    target = target.min(0.0);
                }
                (
                    self.ramp_accel(target, env.max_jerk_mps3, dt),
                    self.ramp_steer(cmd.steer_rad, input.speed_mps, dt),
                    true,
                )
            }
            (GateState::Engaged, None) | (GateState::MinimalRiskStop, _) => {
                let (decel, jerk) = match self.profile {
                    StopProfile::Configured => {
                        (self.cfg.stop_decel_mps2.min(env.max_decel_mps2), self.cfg.stop_jerk_mps3)
                    }
                    StopProfile::Emergency => (env.max_decel_mps2, env.max_jerk_mps3),
                };
                // Never brake less than already braking.
                let target = (-decel).min(self.accel_mps2);
                (self.ramp_accel(target, jerk, dt), self.ramp_steer(self.steer_rad, input.speed_mps, dt), true)
            }
            (GateState::Disengaged | GateState::Fault, _) => (0.0, 0.0, false),
        };
        // Unreachable by construction (every operand is finite); kept so that a NaN can never
        // leave: the gate would latch its fault instead.
        debug_assert!(accel.is_finite() && steer.is_finite());
        let (accel, steer, enable) = if accel.is_finite() && steer.is_finite() {
            (accel, steer, enable)
        } else {
            self.state = GateState::Fault;
            (0.0, 0.0, false)
        };
        self.accel_mps2 = accel;
        self.steer_rad = steer;
        GateOutput { accel_mps2: accel, steer_rad: steer, enable, state: self.state, reason: self.reason }
    }

    /// Whether a minimal-risk stop has reached standstill at `speed_mps`.
    pub fn at_standstill(&self, speed_mps: f64) -> bool {
        self.state == GateState::MinimalRiskStop && speed_mps.abs() <= self.cfg.standstill_speed_mps
    }
}

#[cfg(test)]
#[path = "gate_tests.rs"]
mod tests;
