//! How human the motion of a run was: each vehicle's driven trajectory (the true states of the
//! recorded trace, from its start until it reaches the end of its route) against recorded human
//! driving in the same manoeuvre class ([`v2t_model::realism`]): W₁ of longitudinal acceleration,
//! jerk and yaw rate, jerk RMS and speed reversals. The one measure that `sim`, `sim-ecu`, the demo
//! and the experiments report.

use serde::{Deserialize, Serialize};
use v2t_model::kinematics::State;
use v2t_model::realism::{HumanReference, ManoeuvreClass, MotionRealism};

use crate::runner::RunOutcome;
use crate::scenario::Scenario;

/// A vehicle counts as at the end of its route this close to it, m (what follows is standing).
const END_MARGIN_M: f64 = 1.0;
/// Spacing at which a route is walked to classify its manoeuvre, m.
const CLASS_STEP_M: f64 = 1.0;

/// The manoeuvre a route asks for ([`ManoeuvreClass::of_states`] along its geometry): a run is
/// measured in the class of what the vehicle is meant to do, even when it ends before the
/// vehicle has done all of it.
pub fn route_class(route: &v2t_model::path::ReferencePath) -> ManoeuvreClass {
    let n = (route.length() / CLASS_STEP_M).ceil().clamp(1.0, 100_000.0) as usize;
    let states: Vec<State> = (0..=n)
        .map(|k| {
            let s = route.length() * k as f64 / n as f64;
            let p = route.point_at(s);
            State { px: p.x, py: p.y, theta_rad: route.heading_at(s), speed_mps: 1.0 }
        })
        .collect();
    ManoeuvreClass::of_states(&states)
}

/// One vehicle's realism in a run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct VehicleRealism {
    /// Its id (`vut`, `bv1`, …).
    pub id: String,
    /// Its manoeuvre class, from its route ([`route_class`]).
    pub class: ManoeuvreClass,
    /// The measure; `None` when the reference has no human driving of this class, or the
    /// trajectory is shorter than three samples.
    pub realism: Option<MotionRealism>,
}

/// Every vehicle of a run: the VUT first, then the BVs in scenario order.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RunRealism {
    /// One per vehicle.
    pub vehicles: Vec<VehicleRealism>,
}

impl RunRealism {
    /// The VUT's.
    pub fn vut(&self) -> Option<&VehicleRealism> {
        self.vehicles.first()
    }

    /// BV `i`'s.
    pub fn bv(&self, i: usize) -> Option<&VehicleRealism> {
        self.vehicles.get(i + 1)
    }
}

/// Why a run cannot be measured against a reference.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum RealismError {
    /// The trace is not sampled at a divisor of the reference's period.
    #[error(
        "record_period_s: the trace is recorded every {record_s} s, the human reference every {reference_s} s; \
         the reference's period must be a whole multiple of the record period"
    )]
    Period {
        /// The trace's period, s.
        record_s: f64,
        /// The reference's period, s.
        reference_s: f64,
    },
}

/// The realism of every vehicle of `outcome` (a run of `scenario`) against `reference`.
pub fn measure_run(
    scenario: &Scenario,
    outcome: &RunOutcome,
    reference: &HumanReference,
) -> Result<RunRealism, RealismError> {
    let record_s = scenario.settings.record_period_s;
    let ratio = reference.dt_s / record_s;
    let every = ratio.round();
    if every < 1.0 || (ratio - every).abs() > 1e-6 {
        return Err(RealismError::Period { record_s, reference_s: reference.dt_s });
    }
    let every = every as usize;
    let routes = std::iter::once(&scenario.vut.agent).chain(scenario.bvs.iter().map(|b| &b.agent));
    let vehicles = routes
        .enumerate()
        .map(|(i, agent)| {
            let end = agent.route.length() - END_MARGIN_M;
            let states: Vec<State> = outcome
                .trace
                .iter()
                .step_by(every)
                .filter_map(|t| t.agents.get(i))
                .take_while(|a| a.s_m < end)
                .map(|a| a.state)
                .collect();
            let class = route_class(&agent.route);
            VehicleRealism {
                id: agent.id.clone(),
                class,
                realism: reference.measure_as(class, &states, reference.dt_s),
            }
        })
        .collect();
    Ok(RunRealism { vehicles })
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use crate::bv::{BvController, ReferenceFollower};
    use crate::vut::VutModel;

    fn root() -> std::path::PathBuf {
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
    }

    /// A shipped card run once with a reference-following BV, and the shipped human reference.
    fn run_card(card: &str) -> (Scenario, RunOutcome, HumanReference) {
        let sc = crate::files::load_scenario(&root().join("config/scenarios").join(card)).unwrap();
        let reference = v2t_files::read_human_reference(&root().join(v2t_files::shipped::HUMAN_REFERENCE)).unwrap();
        let mut bvs: Vec<Box<dyn BvController>> = vec![Box::new(ReferenceFollower::default())];
        let out = crate::runner::run(&sc, &mut bvs, VutModel::IdmNormal.driver().as_mut(), 1).unwrap();
        (sc, out, reference)
    }

    #[test]
    fn a_cut_in_run_is_measured_per_vehicle_in_its_class() {
        let (sc, out, reference) = run_card("cut_in_basic.toml");
        let r = measure_run(&sc, &out, &reference).unwrap();
        assert_eq!(r.vehicles.len(), 2);
        let (vut, bv) = (r.vut().unwrap(), r.bv(0).unwrap());
        assert_eq!((vut.id.as_str(), vut.class), ("vut", ManoeuvreClass::Straight));
        assert_eq!((bv.id.as_str(), bv.class), ("bv1", ManoeuvreClass::LaneChange));
        let m = bv.realism.unwrap();
        assert!(m.w1_accel_mps2.is_finite() && m.w1_accel_mps2 > 0.0, "{m:?}");
        assert!(m.w1_jerk_mps3 > 0.0 && m.jerk_rms_mps3 > 0.0);
        // A reference at a period that is not a multiple of the trace's is refused.
        let mut odd = reference.clone();
        odd.dt_s = 0.15;
        assert!(matches!(measure_run(&sc, &out, &odd), Err(RealismError::Period { .. })));
    }

    #[test]
    fn a_left_turn_is_measured_against_left_turns_and_a_reference_without_them_says_so() {
        let (sc, out, reference) = run_card("left_turn_basic.toml");
        let r = measure_run(&sc, &out, &reference).unwrap();
        let bv = r.bv(0).unwrap();
        assert_eq!(bv.class, ManoeuvreClass::LeftTurn);
        assert!(reference.class(ManoeuvreClass::LeftTurn).is_some(), "the shipped reference has left turns");
        assert!(bv.realism.is_some_and(|m| m.w1_yaw_rate_radps.is_finite()), "{bv:?}");
        // A reference without the class: no figure, never another class's.
        let mut without = reference.clone();
        without.classes.retain(|c| c.class != ManoeuvreClass::LeftTurn);
        let r = measure_run(&sc, &out, &without).unwrap();
        assert!(r.bv(0).unwrap().realism.is_none());
        assert!(r.vut().unwrap().realism.is_some(), "the VUT goes straight: measured");
    }
}
