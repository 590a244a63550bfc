//! # v2t-track — the BV's path tracker
//!
//! The regulator (`v2t-game`) decides where the BV should be along its reference path and how fast
//! it should go; this crate turns that plan into the actuation request the drive-by-wire ECU takes:
//! an acceleration from a longitudinal PID on speed (the plan's acceleration as feed-forward, a
//! station-error correction, conditional-integration anti-windup, the vehicle's acceleration and
//! jerk limits; see [`longitudinal`]) and a road-wheel angle from the Stanley law at the front axle
//! (curvature feed-forward with preview, optional yaw-rate damping, the vehicle's steering angle and
//! rate limits; see [`lateral`]). [`Tracker`] combines both, compensates the loop's latency and
//! remembers where the vehicle is on its path.
//!
//! Pure: no IO, no clock, no threads, no allocation per cycle; the cycle length comes in as an
//! argument. Bad input (NaN, a non-positive or stalled cycle, a vehicle that cannot be located on
//! the path) is a [`TrackError`], never a NaN request. The lab (`v2t-lab`) drives a BV of the
//! simulated proving ground with it to measure it against the plant, noise and actuator lag.
//!
//! ```
//! use v2t_model::kinematics::State;
//! use v2t_model::path::PathBuilder;
//! use v2t_model::vehicle::VehicleConfig;
//! use v2t_track::{PlanSample, Tracker, TrackerConfig};
//!
//! # fn main() -> Result<(), Box<dyn std::error::Error>> {
//! let vehicle: VehicleConfig = toml::from_str(include_str!("../../../config/vehicles/bv_sedan.toml"))?;
//! let config: TrackerConfig = toml::from_str(include_str!("../../../config/track/default.toml"))?;
//! let mut tracker = Tracker::try_new(config, &vehicle)?;
//!
//! // 50 m east, then a left turn of radius 25 m.
//! let path = PathBuilder::new(0.0, 0.0, 0.0).line(50.0).arc(25.0, std::f64::consts::FRAC_PI_2).build(0.5)?;
//! // The BV is 0.3 m left of its path and 1 m/s slower than its plan.
//! let state = State { px: 10.0, py: 0.3, theta_rad: 0.0, speed_mps: 9.0 };
//! let plan = PlanSample { s_m: 10.0, v_mps: 10.0, a_mps2: 0.0 };
//! let out = tracker.step(&state, &path, &plan, 0.1)?;
//! assert!(out.steer_rad < 0.0, "steers right, back toward the path");
//! assert!(out.accel_mps2 > 0.0, "speeds up");
//! assert!(out.cross_track_m > 0.29 && out.speed_error_mps == 1.0);
//! assert!((out.s_m - 10.0).abs() < 1e-9 && out.station_error_m.abs() < 1e-9);
//!
//! // NaN never reaches the actuators.
//! let broken = State { speed_mps: f64::NAN, ..state };
//! assert!(tracker.step(&broken, &path, &plan, 0.1).is_err());
//! # Ok(())
//! # }
//! ```

mod latency;
pub mod lateral;
pub mod longitudinal;
mod tracker;

pub use lateral::{LateralGains, Stanley, StanleyInput, SteeringModel};
pub use longitudinal::{LongitudinalGains, LongitudinalInput, LongitudinalLimits, LongitudinalOutput, SpeedPid};
pub use tracker::{PlanSample, Tracker, TrackerConfig, TrackerOutput};

use v2t_model::validate::ValidationError;

/// Why a tracker could not be built or a cycle was refused. A refused cycle leaves the tracker as
/// it was.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum TrackError {
    /// The configuration or the vehicle is out of range.
    #[error("tracker configuration: {0}")]
    Config(#[from] ValidationError),
    /// The cycle length is not a finite number in `(0, max]`.
    #[error("cycle length must lie in (0, {max_s}] s, got {dt_s}")]
    TimeStep {
        /// The cycle length given, s.
        dt_s: f64,
        /// The longest accepted, s.
        max_s: f64,
    },
    /// An input is NaN or infinite.
    #[error("`{field}` must be a finite number, got {value}")]
    NotFinite {
        /// Which input.
        field: &'static str,
        /// Its value.
        value: f64,
    },
    /// An input is finite but beyond what a vehicle on a track can measure or be asked for (a
    /// sensor or plan fault); taken at face value it would overflow the controllers.
    #[error("`{field}` = {value} is beyond the plausible ±{bound}")]
    Implausible {
        /// Which input.
        field: &'static str,
        /// Its value.
        value: f64,
        /// The largest magnitude accepted.
        bound: f64,
    },
    /// The vehicle is farther from its path than the configuration allows.
    #[error("the vehicle is {cross_track_m:.2} m from its path (at most {limit_m} m)")]
    FarFromPath {
        /// Its signed distance from the path (left positive), m.
        cross_track_m: f64,
        /// The largest accepted, m.
        limit_m: f64,
    },
    /// The vehicle could not be located on the path.
    #[error("the vehicle at ({x}, {y}) cannot be located on the path")]
    OffPath {
        /// Its x, m.
        x: f64,
        /// Its y, m.
        y: f64,
    },
}

/// `dt_s` must be finite, `> 0` and `<= max_s`.
fn check_dt(dt_s: f64, max_s: f64) -> Result<(), TrackError> {
    if dt_s.is_finite() && dt_s > 0.0 && dt_s <= max_s { Ok(()) } else { Err(TrackError::TimeStep { dt_s, max_s }) }
}

/// `value` must be finite.
fn check_finite(field: &'static str, value: f64) -> Result<(), TrackError> {
    if value.is_finite() { Ok(()) } else { Err(TrackError::NotFinite { field, value }) }
}

/// `value` must be finite with `|value| <= bound`.
fn check_plausible(field: &'static str, value: f64, bound: f64) -> Result<(), TrackError> {
    check_finite(field, value)?;
    if value.abs() <= bound { Ok(()) } else { Err(TrackError::Implausible { field, value, bound }) }
}

/// `x` limited to `[lo, hi]`; never panics (unlike `f64::clamp` with NaN or crossed bounds): NaN
/// bounds are ignored, and `lo` wins over `hi` if they cross.
fn limit(x: f64, lo: f64, hi: f64) -> f64 {
    let y = if x > hi { hi } else { x };
    if y < lo { lo } else { y }
}
