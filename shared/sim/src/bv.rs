//! BV controllers. The regulator of `edge/game` plugs in here; this module has the plain one:
//! follow the reference path at the reference timing.

use crate::control::{pure_pursuit, speed_keeping};
use crate::observation::BvObservation;
use crate::plant::ActuationRequest;

/// Decides the BV's actuation every control period.
pub trait BvController {
    /// Short name for reports.
    fn name(&self) -> &str;
    /// The request for this control period.
    fn control(&mut self, obs: &BvObservation<'_>) -> ActuationRequest;
}

/// Follows the BV's reference: the path, and the position and speed the speed profile sets for
/// every instant (feed-forward acceleration plus speed and station feedback). It ignores the VUT.
#[derive(Debug, Clone)]
pub struct ReferenceFollower {
    /// Gain on the speed error, 1/s.
    pub speed_gain_1ps: f64,
    /// Gain on the station (position along the path) error, 1/s².
    pub station_gain_1ps2: f64,
}

impl Default for ReferenceFollower {
    fn default() -> Self {
        Self { speed_gain_1ps: 1.0, station_gain_1ps2: 0.25 }
    }
}

impl BvController for ReferenceFollower {
    fn name(&self) -> &str {
        "reference"
    }

    fn control(&mut self, obs: &BvObservation<'_>) -> ActuationRequest {
        let Some(bv) = obs.scenario.bvs.get(obs.bv_index) else {
            // Not a BV of this scenario: stop.
            return ActuationRequest { accel_mps2: -3.0, steer_rad: 0.0 };
        };
        let vehicle = &bv.agent.vehicle;
        // Compensate the measurement's age: where the reference is "now" for the state we see.
        let t_ref = obs.t_s - obs.own.age_s;
        let s_ref = bv.reference.distance_at(t_ref);
        let v_ref = bv.reference.speed_at(t_ref);
        let a_ff = bv.reference.accel_at(t_ref);
        let v = obs.own.state.speed_mps;
        let target = v_ref + self.station_gain_1ps2 / self.speed_gain_1ps * (s_ref - obs.own.s_m);
        let accel = a_ff + speed_keeping(v, target.max(0.0), 1.0 / self.speed_gain_1ps, vehicle);
        ActuationRequest {
            accel_mps2: accel.clamp(-vehicle.limits.max_decel_mps2, vehicle.limits.max_accel_mps2),
            steer_rad: pure_pursuit(&bv.agent.route, &obs.own.state, obs.own.s_m, vehicle),
        }
    }
}
