//! The vehicle plant: a kinematic bicycle about the footprint centre, driven through a transport
//! delay and first-order actuator lags with jerk, rate and magnitude limits.

use std::collections::VecDeque;

use v2t_model::geometry::wrap_angle;
use v2t_model::kinematics::State;
use v2t_model::vehicle::VehicleConfig;

/// What a controller asks of the vehicle: a longitudinal acceleration and a road-wheel steering angle.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize, serde::Deserialize)]
pub struct ActuationRequest {
    /// Requested acceleration, m/s² (negative brakes).
    pub accel_mps2: f64,
    /// Requested road-wheel angle, rad, positive left.
    pub steer_rad: f64,
}

impl ActuationRequest {
    /// Both components finite.
    pub fn is_finite(&self) -> bool {
        self.accel_mps2.is_finite() && self.steer_rad.is_finite()
    }
}

/// A simulated vehicle.
#[derive(Debug, Clone)]
pub struct Plant {
    config: VehicleConfig,
    state: State,
    accel_mps2: f64,
    steer_rad: f64,
    /// Requests waiting out the transport delay, with the time they take effect.
    pending: VecDeque<(f64, ActuationRequest)>,
    active: ActuationRequest,
}

impl Plant {
    /// A vehicle at `state`, at rest in its actuators.
    pub fn new(config: VehicleConfig, state: State) -> Self {
        Self {
            config,
            state,
            accel_mps2: 0.0,
            steer_rad: 0.0,
            pending: VecDeque::new(),
            active: ActuationRequest::default(),
        }
    }

    /// True state.
    pub fn state(&self) -> State {
        self.state
    }

    /// Acceleration the actuators deliver now, m/s².
    pub fn accel_mps2(&self) -> f64 {
        self.accel_mps2
    }

    /// Road-wheel angle now, rad.
    pub fn steer_rad(&self) -> f64 {
        self.steer_rad
    }

    /// The vehicle's configuration.
    pub fn config(&self) -> &VehicleConfig {
        &self.config
    }

    /// Hands a request to the actuators at time `t_s`; it takes effect after the transport delay.
    /// A non-finite request is replaced by full braking with the wheel held (the plant never
    /// integrates NaN).
    pub fn request(&mut self, t_s: f64, req: ActuationRequest) {
        let req = if req.is_finite() {
            req
        } else {
            ActuationRequest { accel_mps2: -self.config.limits.max_decel_mps2, steer_rad: self.steer_rad }
        };
        self.pending.push_back((t_s + self.config.actuator.delay_s, req));
    }

    /// Puts the vehicle where another simulator says it is (a VUT driven by SUMO): its state, the
    /// acceleration it realises and its road-wheel angle. Pending requests are dropped.
    pub fn set_external(&mut self, state: State, accel_mps2: f64, steer_rad: f64) {
        self.state = state;
        self.accel_mps2 = accel_mps2;
        self.steer_rad = steer_rad;
        self.pending.clear();
    }

    /// Advances the plant from `t_s` by `dt_s`.
    pub fn step(&mut self, t_s: f64, dt_s: f64) {
        while let Some((due, req)) = self.pending.front().copied() {
            if due > t_s + 1e-12 {
                break;
            }
            self.active = req;
            self.pending.pop_front();
        }
        let lim = &self.config.limits;
        let act = &self.config.actuator;
        // Longitudinal: saturate, first-order lag, jerk limit.
        let a_cmd = self.active.accel_mps2.clamp(-lim.max_decel_mps2, lim.max_accel_mps2);
        let da = if act.accel_time_constant_s > 0.0 {
            (a_cmd - self.accel_mps2) * (dt_s / act.accel_time_constant_s).min(1.0)
        } else {
            a_cmd - self.accel_mps2
        };
        let max_da = lim.max_jerk_mps3 * dt_s;
        self.accel_mps2 += da.clamp(-max_da, max_da);
        // Steering: saturate, first-order lag, rate limit.
        let d_cmd = self.active.steer_rad.clamp(-lim.max_steer_rad, lim.max_steer_rad);
        let dd = if act.steer_time_constant_s > 0.0 {
            (d_cmd - self.steer_rad) * (dt_s / act.steer_time_constant_s).min(1.0)
        } else {
            d_cmd - self.steer_rad
        };
        let max_dd = lim.max_steer_rate_radps * dt_s;
        self.steer_rad = (self.steer_rad + dd.clamp(-max_dd, max_dd)).clamp(-lim.max_steer_rad, lim.max_steer_rad);
        // Kinematic bicycle about the footprint centre (midpoint integration of the heading).
        let geo = &self.config.geometry;
        let beta = (geo.center_to_rear_axle_m / geo.wheelbase_m * self.steer_rad.tan()).atan();
        let v = self.state.speed_mps;
        let yaw_rate = v / geo.wheelbase_m * beta.cos() * self.steer_rad.tan();
        let theta_mid = self.state.theta_rad + 0.5 * yaw_rate * dt_s;
        let mut v_next = v + self.accel_mps2 * dt_s;
        if v_next < 0.0 {
            // The vehicle stops; it does not reverse.
            v_next = 0.0;
            self.accel_mps2 = self.accel_mps2.max(0.0);
        }
        if v_next > lim.max_speed_mps {
            v_next = lim.max_speed_mps;
            self.accel_mps2 = self.accel_mps2.min(0.0);
        }
        let v_mid = 0.5 * (v + v_next);
        self.state = State {
            px: self.state.px + v_mid * (theta_mid + beta).cos() * dt_s,
            py: self.state.py + v_mid * (theta_mid + beta).sin() * dt_s,
            theta_rad: wrap_angle(self.state.theta_rad + yaw_rate * dt_s),
            speed_mps: v_next,
        };
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use v2t_model::vehicle::{ActuatorResponse, LocalizationNoise, NoiseModel, VehicleGeometry, VehicleLimits};

    pub(crate) fn sedan() -> VehicleConfig {
        VehicleConfig {
            name: "test sedan".into(),
            geometry: VehicleGeometry { length_m: 4.6, width_m: 1.85, wheelbase_m: 2.8, center_to_rear_axle_m: 1.4 },
            limits: VehicleLimits {
                max_speed_mps: 25.0,
                max_accel_mps2: 3.0,
                max_decel_mps2: 7.0,
                max_jerk_mps3: 10.0,
                max_steer_rad: 0.55,
                max_steer_rate_radps: 0.7,
                max_lat_accel_mps2: 5.0,
            },
            actuator: ActuatorResponse { accel_time_constant_s: 0.3, steer_time_constant_s: 0.1, delay_s: 0.05 },
            localization: LocalizationNoise {
                model: NoiseModel::Gaussian,
                position_std_m: 0.03,
                heading_std_rad: 0.005,
                speed_std_mps: 0.05,
                correlation_time_s: 0.0,
                delay_s: 0.05,
            },
        }
    }

    #[test]
    fn braking_stops_without_reversing_and_respects_limits() {
        let mut p = Plant::new(sedan(), State { px: 0.0, py: 0.0, theta_rad: 0.0, speed_mps: 10.0 });
        p.request(0.0, ActuationRequest { accel_mps2: -50.0, steer_rad: 0.0 });
        let mut t = 0.0;
        let mut prev_a = 0.0;
        for _ in 0..1000 {
            p.step(t, 0.01);
            t += 0.01;
            assert!(p.accel_mps2() >= -7.0 - 1e-9);
            // The jerk limit holds while moving; at standstill the brake force simply vanishes.
            if p.state().speed_mps > 0.0 {
                assert!((p.accel_mps2() - prev_a).abs() <= 10.0 * 0.01 + 1e-9, "jerk limit");
            }
            prev_a = p.accel_mps2();
        }
        assert_eq!(p.state().speed_mps, 0.0);
        // Stopping from 10 m/s at ≤ 7 m/s² takes at least 10²/(2·7) ≈ 7.1 m.
        assert!(p.state().px > 7.1);
    }

    #[test]
    fn steady_steering_drives_the_bicycle_circle() {
        let mut p = Plant::new(sedan(), State { px: 0.0, py: 0.0, theta_rad: 0.0, speed_mps: 5.0 });
        let delta: f64 = 0.2;
        p.request(0.0, ActuationRequest { accel_mps2: 0.0, steer_rad: delta });
        let mut t = 0.0;
        for _ in 0..300 {
            p.step(t, 0.01);
            t += 0.01;
        }
        let beta = (0.5 * delta.tan()).atan();
        let expected_rate = 5.0 / 2.8 * beta.cos() * delta.tan();
        let (th0, t0) = (p.state().theta_rad, t);
        for _ in 0..100 {
            p.step(t, 0.01);
            t += 0.01;
        }
        let rate = wrap_angle(p.state().theta_rad - th0) / (t - t0);
        assert!((rate - expected_rate).abs() < 1e-6, "{rate} vs {expected_rate}");
    }

    #[test]
    fn nan_requests_brake_instead_of_poisoning_the_state() {
        let mut p = Plant::new(sedan(), State { px: 0.0, py: 0.0, theta_rad: 0.0, speed_mps: 10.0 });
        p.request(0.0, ActuationRequest { accel_mps2: f64::NAN, steer_rad: 0.0 });
        let mut t = 0.0;
        for _ in 0..100 {
            p.step(t, 0.01);
            t += 0.01;
        }
        assert!(p.state().is_finite());
        assert!(p.state().speed_mps < 10.0);
    }
}
