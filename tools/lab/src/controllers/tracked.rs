//! The tracker (`v2t-track`) as a BV controller of the simulated proving ground: the BV follows its reference
//! path at the timing of its reference speed profile (the plan a regulator would hand over), with
//! PID + Stanley instead of the simulator's own pure pursuit, so that the tracker can be measured
//! against the real plant, localization noise and actuator lag.

use v2t_model::vehicle::VehicleConfig;
use v2t_sim::bv::BvController;
use v2t_sim::observation::BvObservation;
use v2t_sim::plant::ActuationRequest;
use v2t_sim::scenario::BvSetup;

use v2t_track::{PlanSample, TrackError, Tracker, TrackerConfig, TrackerOutput};

/// Deceleration requested when a cycle is refused (the wheel holds its last angle), m/s².
const FALLBACK_DECEL_MPS2: f64 = 3.0;

/// A BV that tracks its reference with [`Tracker`].
#[derive(Debug, Clone)]
pub struct TrackedBv {
    tracker: Tracker,
    last: Option<TrackerOutput>,
    last_error: Option<TrackError>,
    refused_cycles: usize,
}

impl TrackedBv {
    /// A tracked BV driving `vehicle` with `config`.
    pub fn new(config: TrackerConfig, vehicle: &VehicleConfig) -> Result<Self, TrackError> {
        Ok(Self { tracker: Tracker::try_new(config, vehicle)?, last: None, last_error: None, refused_cycles: 0 })
    }

    /// The plan a BV's reference sets for time `t_s`.
    pub fn reference_plan(bv: &BvSetup, t_s: f64) -> PlanSample {
        PlanSample {
            s_m: bv.reference.distance_at(t_s),
            v_mps: bv.reference.speed_at(t_s),
            a_mps2: bv.reference.accel_at(t_s),
        }
    }

    /// The tracker.
    pub fn tracker(&self) -> &Tracker {
        &self.tracker
    }

    /// The last cycle's output, if it succeeded.
    pub fn last_output(&self) -> Option<&TrackerOutput> {
        self.last.as_ref()
    }

    /// The last refused cycle's error.
    pub fn last_error(&self) -> Option<&TrackError> {
        self.last_error.as_ref()
    }

    /// How many cycles were refused.
    pub fn refused_cycles(&self) -> usize {
        self.refused_cycles
    }
}

impl BvController for TrackedBv {
    fn name(&self) -> &str {
        "tracker"
    }

    fn control(&mut self, obs: &BvObservation<'_>) -> ActuationRequest {
        let steer_held = self.tracker.lateral().last_steer_rad();
        let fallback = ActuationRequest { accel_mps2: -FALLBACK_DECEL_MPS2, steer_rad: steer_held };
        let Some(bv) = obs.scenario.bvs.get(obs.bv_index) else {
            return fallback;
        };
        // The plan at the instant the measurement describes.
        let plan = Self::reference_plan(bv, obs.t_s - obs.own.age_s);
        match self.tracker.step(&obs.own.state, &bv.agent.route, &plan, obs.dt_s) {
            Ok(out) => {
                self.last = Some(out);
                ActuationRequest { accel_mps2: out.accel_mps2, steer_rad: out.steer_rad }
            }
            Err(e) => {
                self.last = None;
                self.last_error = Some(e);
                self.refused_cycles += 1;
                fallback
            }
        }
    }
}
