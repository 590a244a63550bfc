//! The regulator (`v2t-game`) as a BV controller of the simulated proving ground: the adapter the
//! vehicle runs ([`v2t_game::regulation::Regulation`]) decides the longitudinal motion every
//! control period from the prior the BV would have received ([`crate::world::prior_of_card`],
//! decoded as the BV decodes it), pure pursuit keeps the BV on its path.

use std::cell::{Cell, RefCell};
use std::rc::Rc;
use v2t_edge::prior::{PriorContext, PriorError};
use v2t_game::qp::QpError;
use v2t_game::regulation::{Measurement, Regulation};
use v2t_game::regulator::{BelowReach, Decision, Limits, RegulatorParams};
use v2t_sim::bv::BvController;
use v2t_sim::control::pure_pursuit;
use v2t_sim::observation::{BvObservation, Perceived};
use v2t_sim::plant::ActuationRequest;
use v2t_sim::scenario::Scenario;

use crate::world::WorldError;

/// A regulated BV.
#[derive(Debug)]
pub struct RegulatedBv {
    regulation: Regulation,
    last: Option<Decision>,
    /// The last "τ out of reach" the regulator reported in this run (shared with whoever asked).
    below_reach: Rc<Cell<Option<BelowReach>>>,
    /// Every decision of the run (shared with whoever asked).
    log: Rc<RefCell<Vec<LoggedDecision>>>,
    /// The identification of the VUT's reaction as of the last decision (shared with whoever asked).
    reaction: Rc<Cell<Option<v2t_game::reaction::BeliefSnapshot>>>,
    /// Whether the regulator started from earlier runs' identification.
    reaction_prior: bool,
    /// What the run taught the regulator, once the VUT has left its zone (shared with whoever
    /// asked; [`v2t_game::regulation::Regulation::lesson`], what the onboard node reports).
    lesson: Rc<RefCell<Option<v2t_game::regulation::Lesson>>>,
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
            vut_reacts_p: d.reaction.map(|r| r.reacts_probability),
            vut_gap_s: d.reaction.map(|r| r.gap_mean_s),
            vut_gap_sd_s: d.reaction.map(|r| r.gap_sd_s),
            solve_us: self.solve_us,
        }
    }
}

/// Why a regulated BV cannot be built.
#[derive(Debug, thiserror::Error)]
pub enum RegulatedBvError {
    /// The regulator refused its settings.
    #[error("regulator: {0}")]
    Regulator(#[from] QpError),
    /// The scenario gives this BV no prior the BV would accept (its timing included).
    #[error("prior: {0}")]
    Prior(#[from] WorldError),
    /// What a campaign learned does not pass the BV's checks.
    #[error("{0}")]
    Campaign(#[from] v2t_model::validate::ValidationError),
}

impl RegulatedBv {
    /// A regulator with `params` for BV `bv_index` of `scenario`, aiming at the scenario's target,
    /// around the prior the BV would have received (`regulation_for`).
    pub fn new(params: RegulatorParams, scenario: &Scenario, bv_index: usize) -> Result<Self, RegulatedBvError> {
        Ok(Self {
            regulation: regulation_for(params, scenario, bv_index)?,
            last: None,
            below_reach: Rc::default(),
            log: Rc::default(),
            reaction: Rc::default(),
            reaction_prior: false,
            lesson: Rc::default(),
        })
    }

    /// This BV given what a test campaign has learned of the VUT (its aim, reach, route and
    /// reaction, [`v2t_edge::campaign`]) as the vehicle takes it: the upload the cloud sends,
    /// through the block the BV keeps with its prior, checked and given to the regulator by the
    /// onboard node's own functions. What the regulator refuses is the error.
    pub fn with_campaign(mut self, up: &v2t_wire::link::CampaignUpload) -> Result<Self, RegulatedBvError> {
        let learned = v2t_edge::campaign::Learned::from_upload(up)?;
        learned.apply(&mut self.regulation, up.aim)?;
        self.reaction_prior = learned.reaction.is_some();
        Ok(self)
    }

    /// Whether the regulator started from earlier runs' identification of the VUT's reaction.
    pub fn has_reaction_prior(&self) -> bool {
        self.reaction_prior
    }

    /// Where the regulator's identification of the VUT's reaction will be, as of its last
    /// decision (`None` while it made none, or when its follower does not react).
    pub fn reaction_report(&self) -> Rc<Cell<Option<v2t_game::reaction::BeliefSnapshot>>> {
        Rc::clone(&self.reaction)
    }

    /// Where what the run taught the regulator will be once the VUT has left its zone (`None`
    /// before, and for a run in which it never did).
    pub fn lesson_report(&self) -> Rc<RefCell<Option<v2t_game::regulation::Lesson>>> {
        Rc::clone(&self.lesson)
    }

    /// Whether the follower predicts the VUT's free motion from a learned route speed.
    pub fn knows_route(&self) -> bool {
        self.regulation.route_speed().is_some()
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
    pub fn params_for(settings: &RegulatorParams, scenario: &Scenario, bv_index: usize) -> RegulatorParams {
        match Self::limits_for(scenario, bv_index) {
            Some((bv, vut)) => settings.with_limits(bv, vut),
            None => *settings,
        }
    }

    /// Regulator limits from the scenario's vehicles.
    pub fn limits_for(scenario: &Scenario, bv_index: usize) -> Option<(Limits, Limits)> {
        let bv = &scenario.bvs.get(bv_index)?.agent.vehicle.limits;
        Some((bv.into(), (&scenario.vut.agent.vehicle.limits).into()))
    }

    /// The last decision.
    pub fn last_decision(&self) -> Option<&Decision> {
        self.last.as_ref()
    }
}

/// The adapter the vehicle runs, with `params`, for BV `bv_index` of `scenario`: around the prior
/// that BV would have received from the cloud ([`crate::world::prior_of_card`]: its path, the
/// card's speed profile re-timed for the target, the VUT's route, their zone), decoded as the BV
/// decodes it ([`PriorContext`]). A timing the regulator refuses is an error, not a regulator
/// without its realism term.
pub(crate) fn regulation_for(
    params: RegulatorParams,
    scenario: &Scenario,
    bv_index: usize,
) -> Result<Regulation, RegulatedBvError> {
    let bv = scenario.bvs.get(bv_index).ok_or(WorldError::NoBv(bv_index))?;
    let prior = crate::world::prior_of_card(scenario, bv_index, crate::world::CARD_PRIOR_ID, 0)?;
    let ctx = PriorContext::new(&prior).map_err(WorldError::from)?;
    let mut regulation = Regulation::new(params, bv.agent.vehicle.limits.max_lat_accel_mps2)?;
    regulation.set_context(ctx.context).map_err(|e| WorldError::from(PriorError::Invalid(e)))?;
    Ok(regulation)
}

/// What the simulator perceived of a vehicle, as the regulator measures it.
pub(crate) fn measurement(p: &Perceived) -> Measurement {
    Measurement { x_m: p.state.px, y_m: p.state.py, speed_mps: p.state.speed_mps, age_s: p.age_s }
}

impl BvController for RegulatedBv {
    fn name(&self) -> &str {
        "regulator"
    }

    fn control(&mut self, obs: &BvObservation<'_>) -> ActuationRequest {
        let sc = obs.scenario;
        let fallback = ActuationRequest { accel_mps2: -self.regulation.params().fallback_decel_mps2, steer_rad: 0.0 };
        let Some(bv) = sc.bvs.get(obs.bv_index) else { return fallback };
        let started = std::time::Instant::now();
        let own = measurement(&obs.own);
        let Some(step) = self.regulation.decide(obs.t_s, &own, Some(&measurement(&obs.vut))) else { return fallback };
        let d = step.decision;
        self.log.borrow_mut().push(LoggedDecision {
            t_s: obs.t_s,
            s_m: step.bv_s_m.unwrap_or(obs.own.s_m),
            v_mps: own.speed_mps,
            decision: d,
            solve_us: started.elapsed().as_secs_f64() * 1e6,
        });
        self.last = Some(d);
        if d.below_reach.is_some() {
            self.below_reach.set(d.below_reach);
        }
        if self.regulation.params().reacting_follower {
            self.reaction.set(Some(self.regulation.reaction_belief().snapshot()));
        }
        if let Some(lesson) = self.regulation.lesson() {
            *self.lesson.borrow_mut() = Some(lesson);
        }
        ActuationRequest {
            accel_mps2: d.accel_mps2,
            steer_rad: pure_pursuit(&bv.agent.route, &obs.own.state, obs.own.s_m, &bv.agent.vehicle),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use v2t_edge::regulate::{Regulation as OnboardRegulation, status_code};
    use v2t_model::{Style, Target};
    use v2t_sim::vut::VutModel;
    use v2t_wire::{BvState, Code as _, Header, VutState};

    /// The in-process BV and, beside it on the same inputs, the onboard node's code path: every
    /// decision of a closed-loop run compared bit for bit.
    #[derive(Debug)]
    struct Twin {
        lab: RegulatedBv,
        onboard: OnboardRegulation,
        /// Decisions compared, and every one that differed.
        tally: Rc<RefCell<(usize, Vec<String>)>>,
    }

    impl BvController for Twin {
        fn name(&self) -> &str {
            "twin"
        }

        fn control(&mut self, obs: &BvObservation<'_>) -> ActuationRequest {
            // The onboard clock counts nanoseconds (from 10 s before the run here, so that no stamp
            // is negative): both sides get the instants it can express.
            let now_ns = 10_000_000_000 + (obs.t_s * 1e9).round() as u64;
            let stamp = |p: &Perceived| now_ns - (p.age_s * 1e9).round() as u64;
            let (bv_ns, vut_ns) = (stamp(&obs.own), stamp(&obs.vut));
            let secs = |stamp_ns: u64| (now_ns - stamp_ns) as f64 * 1e-9;
            let mut same = *obs;
            same.t_s = now_ns as f64 * 1e-9;
            same.own.age_s = secs(bv_ns);
            same.vut.age_s = secs(vut_ns);
            let lab = self.lab.control(&same);
            let (o, v) = (&obs.own.state, &obs.vut.state);
            let bv = BvState {
                header: Header { seq: 1, stamp_ns: bv_ns },
                px_m: o.px,
                py_m: o.py,
                theta_rad: o.theta_rad,
                speed_mps: o.speed_mps,
                ..BvState::default()
            };
            let vut = VutState {
                header: Header { seq: 1, stamp_ns: vut_ns },
                px_m: v.px,
                py_m: v.py,
                theta_rad: v.theta_rad,
                speed_mps: v.speed_mps,
            };
            let plan = self.onboard.decide(&bv, Some(&vut), now_ns);
            let d = self.lab.last_decision().copied();
            let lab_status = d.map(|d| status_code(d.status).code());
            let differ = d.map(|d| d.accel_mps2.to_bits()) != Some(plan.accel_mps2.to_bits())
                || lab_status != Some(plan.status)
                || d.and_then(|d| d.predicted_pet_s).map(f64::to_bits)
                    != (plan.has_predicted_pet == 1).then_some(plan.predicted_pet_s.to_bits());
            let mut tally = self.tally.borrow_mut();
            if differ {
                tally.1.push(format!("t {:.3}: lab {d:?}, onboard {plan:?}", obs.t_s));
            }
            tally.0 += 1;
            lab
        }
    }

    fn card(name: &str, target: Target) -> Scenario {
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
        let mut sc = v2t_sim::files::load_scenario(&root.join("config/scenarios").join(name)).unwrap();
        sc.target = target;
        sc
    }

    #[test]
    fn the_lab_and_the_onboard_node_decide_bit_identically_on_the_same_inputs() {
        let cases = [
            ("left_turn_basic.toml", Target::new(2.0, Style::Rush).unwrap()),
            ("left_turn_basic.toml", Target::new(2.5, Style::Yield).unwrap()),
            ("left_turn_vut.toml", Target::new(2.0, Style::Yield).unwrap()),
            ("cut_in_basic.toml", Target::new(3.0, Style::Rush).unwrap()),
        ];
        for (name, target) in cases {
            let sc = card(name, target);
            let params = RegulatedBv::params_for(&RegulatorParams::default(), &sc, 0);
            let lat = sc.bvs[0].agent.vehicle.limits.max_lat_accel_mps2;
            let mut onboard = OnboardRegulation::new(params, lat).unwrap();
            // What the cloud would send this BV: the prior the lab's BV regulates around.
            onboard.set_prior(&crate::world::prior_of_card(&sc, 0, 7, 0).unwrap()).unwrap();
            let tally = Rc::default();
            let twin = Twin { lab: RegulatedBv::new(params, &sc, 0).unwrap(), onboard, tally: Rc::clone(&tally) };
            let mut bvs: Vec<Box<dyn BvController>> = vec![Box::new(twin)];
            let out = v2t_sim::runner::run(&sc, &mut bvs, VutModel::IdmNormal.driver().as_mut(), 6).unwrap();
            assert!(out.result.collision.is_none(), "{name}");
            let (compared, mismatches) = &*tally.borrow();
            assert!(
                mismatches.is_empty(),
                "{name} {target:?}: {} of {compared} differ: {mismatches:?}",
                mismatches.len()
            );
            assert!(*compared > 100, "{name}: only {compared} decisions compared");
        }
    }

    /// What a campaign learned reaches the onboard node as the cloud sends it (the uplink's
    /// [`v2t_edge::uplink::with_campaign`], the active prior published again) and the lab's BV
    /// as its campaigns give it: the same decisions, bit for bit.
    #[test]
    fn campaign_knowledge_steers_the_lab_and_the_onboard_node_alike() {
        use v2t_game::reaction::{HYPOTHESES, ReactionPosterior};
        use v2t_game::regulator::{BelowReach, BelowReachCause};
        use v2t_game::route_speed::RouteSpeed;
        let sc = card("left_turn_vut.toml", Target::new(2.5, Style::Rush).unwrap());
        // A VUT that slows from 8 to 4.5 m/s 40–60 m along its route, mostly known to react.
        let speeds = (0..60).map(|i| if (20..30).contains(&i) { 4.5 } else { 8.0 }).collect();
        let mut probabilities = vec![0.8 / (HYPOTHESES - 1) as f64; HYPOTHESES];
        probabilities[0] = 0.2;
        let learned = v2t_edge::campaign::Learned {
            known: Some(BelowReach { cause: BelowReachCause::Campaign, pet_bound_s: Some(2.1) }),
            route: Some(RouteSpeed { step_m: 2.0, speeds_mps: speeds, runs: 4 }),
            reaction: Some(ReactionPosterior { probabilities, informative_cycles: 300 }),
        };
        let aim = Target::new(2.2, Style::Rush).unwrap();
        let params = RegulatedBv::params_for(&RegulatorParams::default(), &sc, 0);
        let lat = sc.bvs[0].agent.vehicle.limits.max_lat_accel_mps2;
        let mut onboard = OnboardRegulation::new(params, lat).unwrap();
        let prior = crate::world::prior_of_card(&sc, 0, 7, 0).unwrap();
        onboard.set_prior(&prior).unwrap();
        let (with, _) = v2t_edge::uplink::with_campaign(&prior, &learned.upload(7, aim), 12, 1).unwrap();
        assert!(onboard.set_prior(&with).unwrap());
        assert_eq!(onboard.learned(), &learned);
        let lab = RegulatedBv::new(params, &sc, 0).unwrap().with_campaign(&learned.upload(7, aim)).unwrap();
        assert!(lab.knows_route() && lab.has_reaction_prior());
        let tally = Rc::default();
        let twin = Twin { lab, onboard, tally: Rc::clone(&tally) };
        let mut bvs: Vec<Box<dyn BvController>> = vec![Box::new(twin)];
        let out = v2t_sim::runner::run(&sc, &mut bvs, VutModel::IdmCautious.driver().as_mut(), 3).unwrap();
        assert!(out.result.collision.is_none());
        let (compared, mismatches) = &*tally.borrow();
        assert!(mismatches.is_empty(), "{} of {compared} differ: {mismatches:?}", mismatches.len());
        assert!(*compared > 100, "only {compared} decisions compared");
        // The campaign's aim, not the card's τ, is what both steered at.
        assert_eq!(with.target().unwrap(), aim);
    }
}
