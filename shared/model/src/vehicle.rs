//! Vehicle description: footprint, wheelbase, motion limits, actuator response and localization
//! quality. One TOML file per vehicle under `config/vehicles/`; every consumer (plant, regulator,
//! tracker, safety gate, diffusion guidance) reads its limits from here.

use serde::{Deserialize, Serialize};

use crate::geometry::OrientedBox;
use crate::kinematics::State;
use crate::validate::{Validate, ValidationError, in_range, non_negative, positive};

/// A vehicle as configured.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct VehicleConfig {
    /// Human-readable name.
    pub name: String,
    /// Dimensions.
    pub geometry: VehicleGeometry,
    /// Motion limits.
    pub limits: VehicleLimits,
    /// Actuator response.
    pub actuator: ActuatorResponse,
    /// Localization quality of this vehicle's positioning system.
    pub localization: LocalizationNoise,
}

/// Footprint and wheelbase. The reference point of every state is the footprint centre.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct VehicleGeometry {
    /// Overall length, m.
    pub length_m: f64,
    /// Overall width, m.
    pub width_m: f64,
    /// Wheelbase, m.
    pub wheelbase_m: f64,
    /// Distance from the reference point (footprint centre) back to the rear axle, m.
    pub center_to_rear_axle_m: f64,
}

/// Hard motion limits.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct VehicleLimits {
    /// Top speed, m/s.
    pub max_speed_mps: f64,
    /// Largest forward acceleration, m/s².
    pub max_accel_mps2: f64,
    /// Largest deceleration (positive number), m/s².
    pub max_decel_mps2: f64,
    /// Largest rate of change of acceleration, m/s³.
    pub max_jerk_mps3: f64,
    /// Largest road-wheel steering angle, rad.
    pub max_steer_rad: f64,
    /// Largest steering rate, rad/s.
    pub max_steer_rate_radps: f64,
    /// Largest lateral acceleration, m/s².
    pub max_lat_accel_mps2: f64,
}

/// First-order actuator lags and a pure transport delay.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ActuatorResponse {
    /// Time constant of the longitudinal response, s.
    pub accel_time_constant_s: f64,
    /// Time constant of the steering response, s.
    pub steer_time_constant_s: f64,
    /// Transport delay between a request and its effect, s.
    pub delay_s: f64,
}

/// How localization errors evolve in time.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum NoiseModel {
    /// Independent Gaussian errors at every sample.
    Gaussian,
    /// Ornstein–Uhlenbeck (first-order Gauss–Markov): correlated drift with the given stationary std.
    OrnsteinUhlenbeck,
}

/// Localization error model and delay.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LocalizationNoise {
    /// Temporal model of the errors.
    pub model: NoiseModel,
    /// Standard deviation of each position coordinate, m.
    pub position_std_m: f64,
    /// Standard deviation of the heading, rad.
    pub heading_std_rad: f64,
    /// Standard deviation of the speed, m/s.
    pub speed_std_mps: f64,
    /// Correlation time of the Ornstein–Uhlenbeck model, s (ignored for Gaussian).
    pub correlation_time_s: f64,
    /// Age of a localization sample when it becomes available, s.
    pub delay_s: f64,
}

impl VehicleConfig {
    /// Footprint of this vehicle at `state`.
    pub fn footprint(&self, state: &State) -> OrientedBox {
        OrientedBox {
            center: state.position(),
            heading_rad: state.theta_rad,
            length_m: self.geometry.length_m,
            width_m: self.geometry.width_m,
        }
    }
}

impl Validate for VehicleConfig {
    fn validate(&self) -> Result<(), ValidationError> {
        if self.name.trim().is_empty() {
            return Err(ValidationError::new("name", "must not be empty"));
        }
        self.geometry.validate().map_err(|e| e.within("geometry"))?;
        self.limits.validate().map_err(|e| e.within("limits"))?;
        self.actuator.validate().map_err(|e| e.within("actuator"))?;
        self.localization.validate().map_err(|e| e.within("localization"))
    }
}

impl Validate for VehicleGeometry {
    fn validate(&self) -> Result<(), ValidationError> {
        in_range("length_m", self.length_m, 1.0, 20.0)?;
        in_range("width_m", self.width_m, 0.5, 3.0)?;
        in_range("wheelbase_m", self.wheelbase_m, 0.5, self.length_m)?;
        in_range("center_to_rear_axle_m", self.center_to_rear_axle_m, 0.0, self.wheelbase_m)
    }
}

impl Validate for VehicleLimits {
    fn validate(&self) -> Result<(), ValidationError> {
        in_range("max_speed_mps", self.max_speed_mps, 0.1, 70.0)?;
        in_range("max_accel_mps2", self.max_accel_mps2, 0.1, 10.0)?;
        in_range("max_decel_mps2", self.max_decel_mps2, 0.1, 12.0)?;
        positive("max_jerk_mps3", self.max_jerk_mps3)?;
        in_range("max_steer_rad", self.max_steer_rad, 0.01, 1.2)?;
        positive("max_steer_rate_radps", self.max_steer_rate_radps)?;
        in_range("max_lat_accel_mps2", self.max_lat_accel_mps2, 0.1, 12.0)
    }
}

impl Validate for ActuatorResponse {
    fn validate(&self) -> Result<(), ValidationError> {
        in_range("accel_time_constant_s", self.accel_time_constant_s, 0.0, 5.0)?;
        in_range("steer_time_constant_s", self.steer_time_constant_s, 0.0, 5.0)?;
        in_range("delay_s", self.delay_s, 0.0, 2.0)
    }
}

impl Validate for LocalizationNoise {
    fn validate(&self) -> Result<(), ValidationError> {
        non_negative("position_std_m", self.position_std_m)?;
        non_negative("heading_std_rad", self.heading_std_rad)?;
        non_negative("speed_std_mps", self.speed_std_mps)?;
        if self.model == NoiseModel::OrnsteinUhlenbeck {
            positive("correlation_time_s", self.correlation_time_s)?;
        } else {
            non_negative("correlation_time_s", self.correlation_time_s)?;
        }
        in_range("delay_s", self.delay_s, 0.0, 2.0)
    }
}
