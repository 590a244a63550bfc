//! The regulator (`v2t-game`) as a BV controller of the simulated proving ground: the regulator
//! decides the longitudinal motion every control period, pure pursuit keeps the BV on its path.

use std::cell::{Cell, RefCell};
use std::rc::Rc;
use v2t_game::qp::QpError;
use v2t_game::reference::{MAX_REFERENCE_SAMPLES, ReferenceSample};

use v2t_game::regulator::{
    BelowReach, Decision, Limits, PathState, Regulator, RegulatorInput, RegulatorParams, curve_speed_limit,
};
use v2t_model::Target;
use v2t_sim::bv::BvController;
use v2t_sim::control::pure_pursuit;
use v2t_sim::observation::BvObservation;
use v2t_sim::plant::ActuationRequest;
use v2t_sim::scenario::{BvSetup, Conflict};

/// A regulated BV.
#[derive(Debug)]
pub struct RegulatedBv {
    regulator: Regulator,
    target: Target,
    last_accel: f64,
    last: Option<Decision>,
    /// The last "τ out of reach" the regulator reported in this run (shared with whoever asked).
    below_reach: Rc<Cell<Option<BelowReach>>>,
    /// Every decision of the run (shared with whoever asked).
    log: Rc<RefCell<Vec<LoggedDecision>>>,
}

/// One decision of an in-process regulated BV, kept as it was made (no allocation in the control
/// step); [`LoggedDecision::record`] makes the record the onboard runtime publishes of it.
#[derive(Debug, Clone, Copy)]
pub struct LoggedDecision {
    /// Simulated time, s.
    pub t_s: f64,
    /// The BV's arc length the decision started from, m.
    pub s_m: f64,
    /// The BV's speed it started from, m/s.
    pub v_mps: f64,
    /// The decision.
    pub decision: Decision,
    /// How long it took, µs.
    pub solve_us: f64,
}

impl LoggedDecision {
    /// The decision as the onboard runtime's `/plans` record.
    pub fn record(&self) -> v2t_sim::recording::PlanRecord {
        let d = &self.decision;
        v2t_sim::recording::PlanRecord {
            t_s: self.t_s,
            prior_id: 0,
            status: format!("{:?}", d.status),
            s_m: self.s_m,
            v_mps: self.v_mps,
            accel_mps2: d.accel_mps2,
            predicted_pet_s: d.predicted_pet_s,
            below_reach: d.below_reach.map(|b| format!("{:?}", b.cause)),
            pet_bound_s: d.below_reach.and_then(|b| b.pet_bound_s),
            solve_us: self.solve_us,
        }
    }
}

/// Period at which the BV's reference speed profile is sampled for the regulator's realism term, s.
const REFERENCE_PERIOD_S: f64 = 0.1;

impl RegulatedBv {
    /// A regulator with `params` for BV `bv_index` of `scenario`, aiming at the scenario's target,
    /// its realism term around the BV's prior or a card's speed profile re-timed for the target
    /// ([`v2t_sim::scenario::Scenario::realism_reference`]; sampled here, once).
    pub fn new(
        params: RegulatorParams,
        scenario: &v2t_sim::scenario::Scenario,
        bv_index: usize,
    ) -> Result<Self, QpError> {
        let regulator = regulator_for(params, scenario, bv_index)?;
        Ok(Self {
            regulator,
            target: scenario.target,
            last_accel: 0.0,
            last: None,
            below_reach: Rc::default(),
            log: Rc::default(),
        })
    }

    /// This BV aiming at `aim` instead of the scenario's target (a campaign's learned aim, see
    /// [`v2t_game::campaign`]), told what earlier runs showed about reach.
    #[must_use]
    pub fn aiming(mut self, aim: v2t_model::Target, known: Option<BelowReach>) -> Self {
        self.target = aim;
        self.regulator.set_known_below_reach(known);
        self
    }

    /// Where the last "τ out of reach" of the run will be (`None` while nothing said so).
    pub fn below_reach_report(&self) -> Rc<Cell<Option<BelowReach>>> {
        Rc::clone(&self.below_reach)
    }

    /// Where every decision of the run will be (the regulator's status and predicted PET over time).
    pub fn decision_log(&self) -> Rc<RefCell<Vec<LoggedDecision>>> {
        Rc::clone(&self.log)
    }

    /// `settings` with the limits of BV `bv_index` and the VUT of `scenario` (unchanged when the
    /// scenario has no such BV).
    pub fn params_for(
        settings: &RegulatorParams,
        scenario: &v2t_sim::scenario::Scenario,
        bv_index: usize,
    ) -> RegulatorParams {
        match Self::limits_for(scenario, bv_index) {
            Some((bv, vut)) => settings.with_limits(bv, vut),
            None => *settings,
        }
    }

    /// Regulator limits from the scenario's vehicles.
    pub fn limits_for(scenario: &v2t_sim::scenario::Scenario, bv_index: usize) -> Option<(Limits, Limits)> {
        let lim = |l: &v2t_model::vehicle::VehicleLimits| Limits {
            max_speed_mps: l.max_speed_mps,
            max_accel_mps2: l.max_accel_mps2,
            max_decel_mps2: l.max_decel_mps2,
        };
        Some((lim(&scenario.bvs.get(bv_index)?.agent.vehicle.limits), lim(&scenario.vut.agent.vehicle.limits)))
    }

    /// The last decision.
    pub fn last_decision(&self) -> Option<&Decision> {
        self.last.as_ref()
    }
}

/// A regulator with `params` for BV `bv_index` of `scenario`, its realism term around the BV's
/// prior or a card's speed profile re-timed for the target
/// ([`v2t_sim::scenario::Scenario::realism_reference`]; sampled here, once).
pub(crate) fn regulator_for(
    params: RegulatorParams,
    scenario: &v2t_sim::scenario::Scenario,
    bv_index: usize,
) -> Result<Regulator, QpError> {
    let mut regulator = Regulator::new(params)?;
    if let Some(profile) = scenario.realism_reference(bv_index) {
        let period = REFERENCE_PERIOD_S.max(scenario.duration_s / (MAX_REFERENCE_SAMPLES - 1) as f64);
        let samples = profile
            .samples(scenario.duration_s, period, MAX_REFERENCE_SAMPLES)
            .map(|[t_s, s_m, v]| ReferenceSample { t_s, s_m, v_mps: v.max(0.0) });
        // A reference the regulator refuses leaves it without the realism term: it still regulates.
        let _ = regulator.set_reference(samples);
    }
    Ok(regulator)
}

/// A vehicle as measured along its own path: arc length, speed and the measurement's age.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Measured {
    pub s_m: f64,
    pub v_mps: f64,
    pub age_s: f64,
}

impl Measured {
    /// Arc length brought to now, at constant speed.
    pub fn s_now_m(&self) -> f64 {
        self.s_m + self.v_mps * self.age_s
    }
}

/// One decision of `regulator` for BV `bv` in `conflict` at time `t_s`: both measurements brought
/// to `t_s` at constant speed, the BV's curves capping its plan. The one recipe of the onboard
/// BV and the cloud's.
#[allow(clippy::too_many_arguments)]
pub(crate) fn decide(
    regulator: &mut Regulator,
    bv: &BvSetup,
    conflict: &Conflict,
    target: Target,
    t_s: f64,
    own: Measured,
    vut: Measured,
    bv_accel_mps2: f64,
) -> Decision {
    let now = |m: Measured| PathState { s_m: m.s_now_m(), v_mps: m.v_mps, age_s: m.age_s };
    let input = RegulatorInput {
        t_s,
        bv: now(own),
        vut: now(vut),
        bv_accel_mps2,
        zone_bv: conflict.zone.bv,
        zone_vut: conflict.zone.vut,
        zone_kind: conflict.zone.kind,
        target,
        reference_speed_mps: bv.reference.speed_at(t_s),
    };
    let lat = bv.agent.vehicle.limits.max_lat_accel_mps2;
    regulator.decide_on_path(&input, &|s| curve_speed_limit(&bv.agent.route, s, lat))
}

impl BvController for RegulatedBv {
    fn name(&self) -> &str {
        "regulator"
    }

    fn control(&mut self, obs: &BvObservation<'_>) -> ActuationRequest {
        let sc = obs.scenario;
        let (Some(bv), Some(conflict)) = (sc.bvs.get(obs.bv_index), sc.conflict_of(obs.bv_index)) else {
            return ActuationRequest { accel_mps2: -2.0, steer_rad: 0.0 };
        };
        let vehicle = &bv.agent.vehicle;
        let own = Measured { s_m: obs.own.s_m, v_mps: obs.own.state.speed_mps, age_s: obs.own.age_s };
        let vut = Measured { s_m: obs.vut.s_m, v_mps: obs.vut.state.speed_mps, age_s: obs.vut.age_s };
        let started = std::time::Instant::now();
        let d = decide(&mut self.regulator, bv, conflict, self.target, obs.t_s, own, vut, self.last_accel);
        self.log.borrow_mut().push(LoggedDecision {
            t_s: obs.t_s,
            s_m: own.s_m,
            v_mps: own.v_mps,
            decision: d,
            solve_us: started.elapsed().as_secs_f64() * 1e6,
        });
        self.last_accel = d.accel_mps2;
        self.last = Some(d);
        if d.below_reach.is_some() {
            self.below_reach.set(d.below_reach);
        }
        ActuationRequest {
            accel_mps2: d.accel_mps2,
            steer_rad: pure_pursuit(&bv.agent.route, &obs.own.state, obs.own.s_m, vehicle),
        }
    }
}
