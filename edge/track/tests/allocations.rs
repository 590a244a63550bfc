//! The tracker allocates nothing per cycle.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic, clippy::indexing_slicing)] // test code

use v2t_model::kinematics::State;
use v2t_model::path::PathBuilder;
use v2t_model::vehicle::VehicleConfig;
use v2t_track::{PlanSample, Tracker, TrackerConfig};

#[global_allocator]
static GLOBAL: v2t_test_support::alloc::Counting = v2t_test_support::alloc::Counting;

#[test]
fn a_tracking_cycle_allocates_nothing() {
    let vehicle: VehicleConfig = toml::from_str(include_str!("../../../config/vehicles/bv_sedan.toml")).unwrap();
    let config: TrackerConfig = toml::from_str(include_str!("../../../config/track/default.toml")).unwrap();
    let mut tracker = Tracker::try_new(config, &vehicle).unwrap();
    let path = PathBuilder::new(0.0, 0.0, 0.0).line(30.0).arc(25.0, 1.5).line(30.0).build(0.5).unwrap();
    let mut state = State { px: 0.0, py: 0.4, theta_rad: 0.05, speed_mps: 9.0 };
    let before = v2t_test_support::alloc::on_this_thread();
    for k in 0..200 {
        let t = k as f64 * 0.1;
        let plan = PlanSample { s_m: 10.0 * t, v_mps: 10.0, a_mps2: 0.0 };
        let out = tracker.step(&state, &path, &plan, 0.1).unwrap();
        // A crude plant: enough to move along the path.
        state.theta_rad += state.speed_mps / 2.85 * out.steer_rad.tan() * 0.1;
        state.px += state.speed_mps * state.theta_rad.cos() * 0.1;
        state.py += state.speed_mps * state.theta_rad.sin() * 0.1;
        state.speed_mps += out.accel_mps2 * 0.1;
    }
    assert_eq!(v2t_test_support::alloc::on_this_thread() - before, 0);
}
