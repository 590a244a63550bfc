//! Small path-following helpers shared by the simulated drivers: pure-pursuit steering and speed
//! keeping. The formulas are `v2t_model::driving`'s; here they meet the simulated vehicles.

use v2t_model::driving;
use v2t_model::geometry::Point2;
use v2t_model::kinematics::State;
use v2t_model::path::ReferencePath;
use v2t_model::vehicle::VehicleConfig;

/// Pure-pursuit road-wheel angle ([`driving::pure_pursuit`] from the rear axle, the point about
/// which the bicycle turns) that steers a vehicle at `state` (arc length `s_m` on `route`) toward
/// the route point `0.6 v + 3` m (at least a wheelbase) ahead, within the steering limit.
pub fn pure_pursuit(route: &ReferencePath, state: &State, s_m: f64, vehicle: &VehicleConfig) -> f64 {
    let geo = &vehicle.geometry;
    let lookahead = (0.6 * state.speed_mps + 3.0).max(geo.wheelbase_m);
    let target = route.point_at(s_m + lookahead);
    let rear = state.position().sub(Point2::from_heading(state.theta_rad).scale(geo.center_to_rear_axle_m));
    let delta = driving::pure_pursuit(rear, state.theta_rad, target, geo.wheelbase_m).atan();
    delta.clamp(-vehicle.limits.max_steer_rad, vehicle.limits.max_steer_rad)
}

/// Acceleration that brings `speed_mps` to `target_mps` with a first-order response of time
/// constant `tau_s`, within the vehicle's limits.
pub fn speed_keeping(speed_mps: f64, target_mps: f64, tau_s: f64, vehicle: &VehicleConfig) -> f64 {
    ((target_mps - speed_mps) / tau_s.max(1e-3)).clamp(-vehicle.limits.max_decel_mps2, vehicle.limits.max_accel_mps2)
}
