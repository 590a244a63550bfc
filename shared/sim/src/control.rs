//! Small path-following helpers shared by the simulated drivers: route tracking in the Frenet
//! frame, pure-pursuit steering and speed keeping.

use v2t_model::geometry::{Point2, wrap_angle};
use v2t_model::kinematics::State;
use v2t_model::path::ReferencePath;
use v2t_model::vehicle::VehicleConfig;

/// Pure-pursuit road-wheel angle that steers a vehicle at `state` (arc length `s_m` on `route`)
/// toward the route point one look-ahead distance ahead.
pub fn pure_pursuit(route: &ReferencePath, state: &State, s_m: f64, vehicle: &VehicleConfig) -> f64 {
    let geo = &vehicle.geometry;
    let lookahead = (0.6 * state.speed_mps + 3.0).max(geo.wheelbase_m);
    let target = route.point_at(s_m + lookahead);
    // Steer the rear axle, the point about which the bicycle turns.
    let rear = state.position().sub(Point2::from_heading(state.theta_rad).scale(geo.center_to_rear_axle_m));
    let to_target = target.sub(rear);
    let alpha = wrap_angle(to_target.y.atan2(to_target.x) - state.theta_rad);
    let ld = to_target.norm().max(1e-3);
    let delta = (2.0 * geo.wheelbase_m * alpha.sin() / ld).atan();
    delta.clamp(-vehicle.limits.max_steer_rad, vehicle.limits.max_steer_rad)
}

/// Acceleration that brings `speed_mps` to `target_mps` with a first-order response of time
/// constant `tau_s`, within the vehicle's limits.
pub fn speed_keeping(speed_mps: f64, target_mps: f64, tau_s: f64, vehicle: &VehicleConfig) -> f64 {
    ((target_mps - speed_mps) / tau_s.max(1e-3)).clamp(-vehicle.limits.max_decel_mps2, vehicle.limits.max_accel_mps2)
}

/// Highest speed at which the route's curvature near `s_m` keeps lateral acceleration in limits.
pub fn curve_speed_limit(route: &ReferencePath, s_m: f64, horizon_m: f64, vehicle: &VehicleConfig) -> f64 {
    let n = 10;
    let k_max =
        (0..=n).map(|i| route.curvature_at(s_m + horizon_m * i as f64 / n as f64).abs()).fold(0.0_f64, f64::max);
    if k_max < 1e-6 { vehicle.limits.max_speed_mps } else { (vehicle.limits.max_lat_accel_mps2 / k_max).sqrt() }
}
