//! The regulator node: every `timing.regulator_period_s` it turns the newest BV and VUT states and
//! the active prior into a [`RegulatedPlan`] with the Stackelberg regulator of `v2t-game`.
//!
//! Its deadline is watched: a decision (inputs read, decided, published) that takes longer than
//! `timing.regulator_budget_s` (default: the period) is counted in the regulator's heartbeat
//! (`deadline_misses`, with `max_cycle_ns`), which the monitor reports; every plan carries its
//! `solve_ns`. An overrun is not a fault by itself: a late plan is caught by `plan_timeout_s`.

use std::time::Duration;

use iceoryx2::service::Service;
use v2t_game::regulation::Measurement;
use v2t_game::regulator::{RegulatorParams, RegulatorStatus};
use v2t_wire::{
    ActivePrior, BvState, CampaignKnowledge, Code, Header, NodeKind, PlanStatus, RegulatedPlan, RunLearnedMsg,
    VutState, services,
};

use crate::campaign::{Learned, below_reach_code};
use crate::clock::{now_ns, secs_between};
use crate::config::Loaded;
use crate::error::EdgeError;
use crate::heart::Heart;
use crate::ports::{Bus, latest, send};
use crate::prior::PriorContext;

/// The regulator with the prior it regulates around: [`v2t_game::regulation::Regulation`] (the
/// one adapter the lab runs too) between the bus's states and plans. Pure: time comes in as
/// arguments.
#[derive(Debug)]
pub struct Regulation {
    inner: v2t_game::regulation::Regulation,
    prior_id: Option<u64>,
    /// The header sequence of the active prior as last taken.
    prior_seq: u64,
    /// What the campaign learned, as given to the regulator, and the cloud message it came with.
    learned: Learned,
    campaign_seq: u64,
    /// The run of the active prior ([`ActivePrior::run`]).
    run: u64,
    /// Lessons given.
    lessons: u64,
    header: Header,
}

/// The wire code of a regulator status.
pub fn status_code(s: RegulatorStatus) -> PlanStatus {
    match s {
        RegulatorStatus::Regulating => PlanStatus::Regulating,
        RegulatorStatus::Degraded => PlanStatus::Degraded,
        RegulatorStatus::SafetyYield => PlanStatus::SafetyYield,
        RegulatorStatus::Waiting => PlanStatus::Waiting,
        RegulatorStatus::Passed => PlanStatus::Passed,
        RegulatorStatus::Stale => PlanStatus::Stale,
        RegulatorStatus::Fallback => PlanStatus::Fallback,
    }
}

/// A state on the bus as the regulator measures it at `now_ns`.
fn measured(px_m: f64, py_m: f64, speed_mps: f64, stamp_ns: u64, now_ns: u64) -> Measurement {
    Measurement { x_m: px_m, y_m: py_m, speed_mps, age_s: secs_between(stamp_ns, now_ns) }
}

impl Regulation {
    /// A regulator with `params` and no prior yet, for a BV whose lateral acceleration is limited
    /// to `lat_accel_mps2` (its plans slow down for the curves of the path ahead).
    pub fn new(params: RegulatorParams, lat_accel_mps2: f64) -> Result<Self, EdgeError> {
        let inner = v2t_game::regulation::Regulation::new(params, lat_accel_mps2)?;
        Ok(Self {
            inner,
            prior_id: None,
            prior_seq: 0,
            learned: Learned::default(),
            campaign_seq: 0,
            run: 0,
            lessons: 0,
            header: Header::default(),
        })
    }

    /// Takes `prior` if it is news and well formed. A new prior (another id), the active one
    /// with new campaign knowledge (the uplink takes it only before `start`: it prepares the next
    /// run, [`crate::campaign`]), or the active one as its next run (the BV armed again,
    /// [`ActivePrior::run`]) starts a run around it with what its campaign block says (a prior as
    /// uploaded says nothing, so nothing of an earlier test stays; nothing of an earlier run does
    /// either: which vehicle left the zone when, what it identified). The active prior
    /// published again otherwise (the uplink does so when the cloud re-targets the running
    /// interaction, `send target`) aims the run at its τ and style without starting it over. A
    /// broken one (its timing or its block included) leaves the active prior, its aim and what
    /// was learned in place. `Ok(false)`: nothing new.
    pub fn set_prior(&mut self, prior: &ActivePrior) -> Result<bool, EdgeError> {
        let invalid = crate::prior::PriorError::Invalid;
        let same = self.prior_id == Some(prior.prior_id);
        if same && self.prior_seq == prior.header.seq {
            return Ok(false);
        }
        if same && prior.campaign.seq == self.campaign_seq && prior.run == self.run {
            let target = prior.target().map_err(crate::prior::PriorError::from)?;
            self.inner.aim(target, self.learned.known);
            self.prior_seq = prior.header.seq;
            return Ok(true);
        }
        let ctx = PriorContext::new(prior)?;
        let target = ctx.context.target;
        let learned = Learned::from_knowledge(&prior.campaign).map_err(invalid)?;
        self.inner.set_context(ctx.context).map_err(invalid)?;
        learned.apply(&mut self.inner, target).map_err(invalid)?;
        self.learned = learned;
        self.campaign_seq = prior.campaign.seq;
        self.run = prior.run;
        self.prior_id = Some(prior.prior_id);
        self.prior_seq = prior.header.seq;
        Ok(true)
    }

    /// What this run taught the regulator about the VUT ([`v2t_game::regulation::Regulation::lesson`]:
    /// once per run, when the VUT has left its zone), as the bus carries it to the uplink.
    pub fn run_learned(&mut self, stamp_ns: u64) -> Option<RunLearnedMsg> {
        let lesson = self.inner.lesson()?;
        let ctx = self.inner.context()?;
        let learned = Learned { known: None, route: lesson.route, reaction: lesson.reaction };
        let target = ctx.target;
        // A posterior or a route the wire refuses is not reported (the regulator made neither).
        let knowledge = CampaignKnowledge::from_upload(&learned.upload(0, target), 0).ok()?;
        self.lessons += 1;
        Some(RunLearnedMsg {
            header: Header { seq: self.lessons, stamp_ns },
            prior_id: self.prior_id.unwrap_or(0),
            tau_s: target.tau_s(),
            style: v2t_wire::StyleCode::from(target.style()).code(),
            started_with_route: u8::from(self.learned.route.is_some()),
            started_with_reaction: u8::from(self.learned.reaction.is_some()),
            learned: knowledge,
        })
    }

    /// What the campaign has learned of the VUT for this run (nothing unless the cloud sent it).
    pub fn learned(&self) -> &Learned {
        &self.learned
    }

    /// The active prior's context.
    pub fn context(&self) -> Option<&v2t_game::regulation::Context> {
        self.inner.context()
    }

    /// One decision at `now_ns` from the BV's state and the VUT's (if any has arrived).
    pub fn decide(&mut self, bv: &BvState, vut: Option<&VutState>, now_ns: u64) -> RegulatedPlan {
        let fallback = self.inner.params().fallback_decel_mps2;
        let mut plan = RegulatedPlan {
            header: Header { seq: self.header.seq + 1, stamp_ns: bv.header.stamp_ns },
            state_seq: bv.header.seq,
            prior_id: 0,
            status: PlanStatus::NoPrior.code(),
            has_predicted_pet: 0,
            below_reach: 0,
            has_pet_bound: 0,
            has_reaction: 0,
            s0_m: 0.0,
            v0_mps: bv.speed_mps.max(0.0),
            accel_mps2: -fallback,
            predicted_pet_s: 0.0,
            pet_bound_s: 0.0,
            vut_reacts_p: 0.0,
            vut_gap_s: 0.0,
            vut_gap_sd_s: 0.0,
            solve_ns: 0,
        };
        self.header = plan.header;
        let Some(prior_id) = self.prior_id else { return plan };
        plan.prior_id = prior_id;
        if !bv.is_finite() {
            plan.status = PlanStatus::Fallback.code();
            return plan;
        }
        let own = measured(bv.px_m, bv.py_m, bv.speed_mps, bv.header.stamp_ns, now_ns);
        let vut =
            vut.filter(|v| v.is_finite()).map(|v| measured(v.px_m, v.py_m, v.speed_mps, v.header.stamp_ns, now_ns));
        let Some(step) = self.inner.decide(now_ns as f64 * 1e-9, &own, vut.as_ref()) else { return plan };
        let d = step.decision;
        plan.s0_m = step.bv_s_m.unwrap_or(0.0);
        plan.status = status_code(d.status).code();
        plan.accel_mps2 = d.accel_mps2;
        if let Some(pet) = d.predicted_pet_s {
            plan.has_predicted_pet = 1;
            plan.predicted_pet_s = pet;
        }
        if let Some(r) = d.reaction {
            plan.has_reaction = 1;
            plan.vut_reacts_p = r.reacts_probability;
            plan.vut_gap_s = r.gap_mean_s;
            plan.vut_gap_sd_s = r.gap_sd_s;
        }
        if let Some(b) = d.below_reach {
            plan.below_reach = below_reach_code(b.cause).code();
            if let Some(bound) = b.pet_bound_s {
                plan.has_pet_bound = 1;
                plan.pet_bound_s = bound;
            }
        }
        plan
    }
}

/// Runs the regulator node until termination.
pub fn run<S: Service>(cfg: &Loaded) -> Result<(), EdgeError> {
    let bus = Bus::<S>::new("regulator", &cfg.edge.namespace)?;
    let states = bus.subscriber::<BvState>(services::STATE)?;
    let vuts = bus.subscriber::<VutState>(services::VUT)?;
    let priors = bus.subscriber::<ActivePrior>(services::PRIOR)?;
    let out = bus.publisher::<RegulatedPlan>(services::PLAN)?;
    let lessons = bus.publisher::<RunLearnedMsg>(services::LEARNED)?;
    let t = cfg.edge.timing;
    let mut heart = Heart::new(&bus, NodeKind::Regulator, t.heartbeat_period_s)?;
    let mut reg = Regulation::new(cfg.regulator, cfg.vehicle.limits.max_lat_accel_mps2)?;
    let (mut bv, mut vut): (Option<BvState>, Option<VutState>) = (None, None);
    let period_ns = (t.regulator_period_s * 1e9) as u64;
    let budget_ns = t.regulator_budget_ns();
    let mut next_ns = now_ns();
    let mut last_status = 0;
    loop {
        let now = now_ns();
        if now >= next_ns {
            next_ns += period_ns;
            if next_ns < now {
                next_ns = now + period_ns;
            }
            while let Some(p) = priors.receive().map_err(|e| EdgeError::ipc("receive", services::PRIOR, e))? {
                match reg.set_prior(&p) {
                    Ok(true) => {
                        let aim = reg.context().map(|c| c.target.to_string()).unwrap_or_default();
                        eprintln!("regulator: prior {}: aim {aim}; {}", p.prior_id, reg.learned().summary());
                    }
                    Ok(false) => {}
                    Err(e) => eprintln!("regulator: prior {} refused: {e}", p.prior_id),
                }
            }
            bv = latest(&states)?.or(bv);
            vut = latest(&vuts)?.or(vut);
            if let Some(state) = bv.filter(|s| secs_between(s.header.stamp_ns, now) <= t.state_timeout_s) {
                let vut_fresh = vut.filter(|v| secs_between(v.header.stamp_ns, now) <= t.vut_timeout_s);
                let mut plan = reg.decide(&state, vut_fresh.as_ref(), now);
                let done = now_ns();
                if plan.status != last_status {
                    last_status = plan.status;
                    let status = PlanStatus::from_code(plan.status).map(|s| format!("{s:?}")).unwrap_or_default();
                    eprintln!(
                        "regulator: {status} (s {:.1} m, v {:.1} m/s, a {:.2} m/s²)",
                        plan.s0_m, plan.v0_mps, plan.accel_mps2
                    );
                }
                if std::env::var_os("V2T_TRACE_PLANS").is_some() {
                    eprintln!(
                        "plan {:.3} s={:.2} v={:.2} a={:.2} pet={:.2} {}",
                        now as f64 * 1e-9,
                        plan.s0_m,
                        plan.v0_mps,
                        plan.accel_mps2,
                        plan.predicted_pet_s,
                        plan.status
                    );
                }
                plan.solve_ns = done - now;
                send(&out, None, plan)?;
                if let Some(lesson) = reg.run_learned(done) {
                    eprintln!(
                        "regulator: prior {}: the VUT has left its zone, what the run learned is out",
                        lesson.prior_id
                    );
                    lessons.send_copy(lesson).map_err(|e| EdgeError::ipc("send", services::LEARNED, e))?;
                }
                heart.cycle(done - now, budget_ns);
            }
        }
        let inputs_ok = bv.is_some_and(|s| secs_between(s.header.stamp_ns, now) <= t.state_timeout_s);
        heart.tick(now_ns(), inputs_ok)?;
        let sleep = next_ns.saturating_sub(now_ns()).min(heart.due_in_ns(now_ns())).max(200_000);
        if !bus.wait(Duration::from_nanos(sleep)) {
            return Ok(());
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use v2t_wire::Vector as _;

    fn setup() -> (Regulation, ActivePrior) {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config");
        let cfg = crate::config::load(&dir.join("edge/bv1.toml")).unwrap();
        (Regulation::new(cfg.regulator, 4.5).unwrap(), crate::prior::fixtures::left_turn(1))
    }

    fn bv_at(prior: &ActivePrior, i: usize, stamp_ns: u64) -> BvState {
        let p = prior.bv_path[i];
        BvState { header: Header { seq: 1, stamp_ns }, px_m: p.x_m, py_m: p.y_m, speed_mps: 8.0, ..BvState::default() }
    }

    /// The VUT at route point `q`, at 8 m/s.
    fn vut_at(q: v2t_wire::Vec2, seq: u64, stamp_ns: u64) -> VutState {
        VutState { header: Header { seq, stamp_ns }, px_m: q.x_m, py_m: q.y_m, speed_mps: 8.0, ..VutState::default() }
    }

    #[test]
    fn a_decision_over_its_budget_is_counted_in_the_heartbeat() {
        use iceoryx2::prelude::local;
        let mut timing =
            crate::config::load(&std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config/edge/bv1.toml"))
                .unwrap()
                .edge
                .timing;
        assert_eq!(timing.regulator_budget_ns(), 100_000_000, "default: the period");
        timing.regulator_budget_s = Some(0.02);
        let budget_ns = timing.regulator_budget_ns();
        assert_eq!(budget_ns, 20_000_000);
        let bus = Bus::<local::Service>::new("regulator", "test/deadline").unwrap();
        let beats = bus.subscriber::<v2t_wire::Heartbeat>(services::HEARTBEAT).unwrap();
        let mut heart = Heart::new(&bus, NodeKind::Regulator, 0.02).unwrap();
        // Start and end stamps of three decisions: on budget, 1 ns over, far over.
        for (start, done) in [(0, budget_ns), (1_000, 1_001 + budget_ns), (5_000, 5_000 + 3 * budget_ns)] {
            heart.cycle(done - start, budget_ns);
        }
        heart.tick(1_000_000_000, true).unwrap();
        let beat = latest(&beats).unwrap().unwrap();
        assert_eq!((beat.cycles, beat.deadline_misses, beat.max_cycle_ns), (3, 2, 3 * budget_ns));
    }

    #[test]
    fn without_a_prior_or_a_vut_the_plan_brakes() {
        let (mut reg, prior) = setup();
        let bv = bv_at(&prior, 0, 1_000);
        let plan = reg.decide(&bv, None, 2_000);
        assert_eq!(plan.status, PlanStatus::NoPrior.code());
        assert!(plan.accel_mps2 < 0.0);
        assert!(reg.set_prior(&prior).unwrap());
        assert!(!reg.set_prior(&prior).unwrap(), "the same prior again is not new");
        let plan = reg.decide(&bv, None, 2_000);
        assert_eq!(plan.status, PlanStatus::Stale.code());
        assert!(plan.accel_mps2 < 0.0);
    }

    #[test]
    fn a_new_target_for_the_active_prior_reaches_the_regulator() {
        // `send target` re-targets the running interaction: the uplink publishes the active prior
        // again, the same prior id with the new τ and style and the next header sequence.
        let (mut reg, prior) = setup();
        assert!(reg.set_prior(&prior).unwrap());
        let mut retarget = prior.clone();
        let new = v2t_model::Target::new(3.5, v2t_model::Style::Yield).unwrap();
        retarget.set_target(new);
        retarget.header.seq += 1;
        assert!(reg.set_prior(&retarget).unwrap(), "a new target is news");
        assert_eq!(reg.context().unwrap().target, new);
        assert!(!reg.set_prior(&retarget).unwrap(), "the same message again is not");
        // A retarget whose τ does not decode leaves the aim as it was.
        let mut bad = retarget.clone();
        bad.tau_s = 99.0;
        bad.header.seq += 1;
        assert!(reg.set_prior(&bad).is_err());
        assert_eq!(reg.context().unwrap().target, new);
    }

    #[test]
    fn campaign_knowledge_reaches_the_regulator_and_a_new_prior_starts_from_nothing() {
        use crate::campaign::Learned;
        use v2t_game::regulator::{BelowReach, BelowReachCause};
        use v2t_game::route_speed::RouteSpeed;
        let (mut reg, prior) = setup();
        reg.set_prior(&prior).unwrap();
        assert_eq!(reg.learned(), &Learned::default());
        let learned = Learned {
            known: Some(BelowReach { cause: BelowReachCause::Campaign, pet_bound_s: Some(2.2) }),
            route: Some(RouteSpeed { step_m: 2.0, speeds_mps: vec![8.0, 7.0, 5.0, 4.0], runs: 3 }),
            reaction: None,
        };
        let aim = v2t_model::Target::new(1.8, v2t_model::Style::Rush).unwrap();
        // As the uplink publishes it: the same prior, its block, the aim, the next sequence.
        let (with, _) = crate::uplink::with_campaign(&prior, &learned.upload(prior.prior_id, aim), 9, 5).unwrap();
        assert!(reg.set_prior(&with).unwrap());
        assert_eq!(reg.learned(), &learned);
        assert_eq!(reg.context().unwrap().target, aim);
        assert_eq!(reg.inner.route_speed(), learned.route.as_ref());
        // A retarget keeps what was learned.
        let mut retarget = with.clone();
        let yield_3 = v2t_model::Target::new(3.0, v2t_model::Style::Yield).unwrap();
        retarget.set_target(yield_3);
        retarget.header.seq += 1;
        assert!(reg.set_prior(&retarget).unwrap());
        assert_eq!((reg.learned(), reg.context().unwrap().target), (&learned, yield_3));
        // A block the regulator refuses leaves what it had.
        let mut bad = retarget.clone();
        bad.campaign.route_step_m = 0.1;
        bad.campaign.seq += 1;
        bad.header.seq += 1;
        let e = reg.set_prior(&bad).unwrap_err().to_string();
        assert!(e.contains("campaign.route.step_m"), "{e}");
        assert_eq!(reg.learned(), &learned);
        // Another test's prior knows nothing of this one's.
        let other = crate::prior::fixtures::left_turn(2);
        assert!(reg.set_prior(&other).unwrap());
        assert_eq!(reg.learned(), &Learned::default());
        assert_eq!(reg.inner.route_speed(), None);
    }

    #[test]
    fn a_run_gives_what_it_learned_once_when_the_vut_has_left_its_zone() {
        let (mut reg, prior) = setup();
        reg.set_prior(&prior).unwrap();
        let exit = prior.vut_zone_exit_s_m;
        let path = prior.vut_path.as_slice();
        // The VUT drives its route point by point (a point every ~0.2–1 m) at 8 m/s, the BV waits.
        let mut lesson = None;
        let mut before_exit = 0;
        for (k, q) in path.iter().enumerate() {
            let now = 1_000_000_000 + k as u64 * 50_000_000;
            let _ = reg.decide(&bv_at(&prior, 0, now), Some(&vut_at(*q, k as u64 + 1, now)), now + 1_000_000);
            if let Some(l) = reg.run_learned(now) {
                assert!(lesson.is_none(), "once per run");
                lesson = Some(l);
            } else if lesson.is_none() {
                before_exit += 1;
            }
        }
        assert!(before_exit > 10, "not before the VUT has left its zone");
        let l = lesson.expect("the VUT left its zone");
        assert_eq!((l.prior_id, l.tau_s, l.started_with_route, l.started_with_reaction), (1, prior.tau_s, 0, 0));
        let learned = Learned::from_knowledge(&l.learned).unwrap();
        let route = learned.route.expect("the route up to the zone's exit");
        assert!(route.speeds_mps.iter().all(|v| (v - 8.0).abs() < 1e-9), "{:?}", route.speeds_mps);
        assert!((route.speeds_mps.len() - 1) as f64 * route.step_m >= exit - route.step_m, "{route:?} to {exit}");
        assert!(learned.reaction.is_some(), "the shipped follower identifies the reaction");
        assert!(reg.run_learned(10_000_000_000).is_none());
        // The BV armed again with the same prior (the uplink publishes it as its next run): the
        // run starts over, the VUT's exit of the run before forgotten, and learns afresh.
        let mut again = prior.clone();
        again.run += 1;
        again.header.seq += 1;
        assert!(reg.set_prior(&again).unwrap(), "the next run is news");
        let now = 20_000_000_000;
        let _ = reg.decide(&bv_at(&prior, 0, now), Some(&vut_at(path[0], 1, now)), now + 1_000_000);
        assert!(reg.run_learned(now).is_none(), "nothing seen yet in this run");
        for (k, q) in path.iter().enumerate().skip(1) {
            let now = 20_000_000_000 + k as u64 * 50_000_000;
            let _ = reg.decide(&bv_at(&prior, 0, now), Some(&vut_at(*q, k as u64 + 1, now)), now + 1_000_000);
        }
        let l = reg.run_learned(30_000_000_000).expect("the second run's lesson");
        assert_eq!(l.header.seq, 2, "the second lesson");
        // A new run (another prior) learns afresh.
        reg.set_prior(&crate::prior::fixtures::left_turn(2)).unwrap();
        assert!(reg.run_learned(10_000_000_000).is_none(), "nothing seen yet");
    }

    #[test]
    fn a_fresh_pair_of_states_is_regulated_and_a_nan_state_falls_back() {
        let (mut reg, prior) = setup();
        reg.set_prior(&prior).unwrap();
        let bv = bv_at(&prior, 0, 1_000_000_000);
        let q = prior.vut_path[0];
        let vut = VutState {
            header: Header { seq: 1, stamp_ns: 1_000_000_000 },
            px_m: q.x_m,
            py_m: q.y_m,
            speed_mps: 10.0,
            ..VutState::default()
        };
        let plan = reg.decide(&bv, Some(&vut), 1_020_000_000);
        let status = PlanStatus::from_code(plan.status).unwrap();
        assert!(matches!(status, PlanStatus::Regulating | PlanStatus::Degraded), "{status:?}");
        assert!(plan.accel_mps2.is_finite() && plan.s0_m.abs() < 0.5);
        // The plan says how the VUT is identified to react (the shipped follower reacts); at the
        // first decision, the prior: a VUT that does not react is the most probable.
        assert_eq!(plan.has_reaction, 1);
        assert!((0.0..=1.0).contains(&plan.vut_reacts_p) && plan.vut_gap_s > 0.0 && plan.vut_gap_sd_s >= 0.0);
        let mut nan = bv;
        nan.px_m = f64::NAN;
        let plan = reg.decide(&nan, Some(&vut), 1_020_000_000);
        assert_eq!(plan.status, PlanStatus::Fallback.code());
        assert!(plan.accel_mps2 < 0.0);
    }

    #[test]
    fn a_vut_standing_before_the_zone_in_yield_is_reported_below_reach_on_the_plan() {
        let (mut reg, mut prior) = setup();
        prior.set_target(v2t_model::Target::new(2.0, v2t_model::Style::Yield).unwrap());
        reg.set_prior(&prior).unwrap();
        let q = prior.vut_path[0];
        let mut last = RegulatedPlan::default();
        for k in 0..45_u64 {
            let now = 1_000_000_000 + k * 100_000_000;
            let bv = bv_at(&prior, 0, now);
            let vut = VutState {
                header: Header { seq: k + 1, stamp_ns: now },
                px_m: q.x_m,
                py_m: q.y_m,
                ..VutState::default()
            };
            last = reg.decide(&bv, Some(&vut), now + 10_000_000);
            if k < 25 {
                assert_eq!(last.below_reach, 0, "not before {} s of waiting", v2t_game::regulator::WAIT_BELOW_REACH_S);
            }
        }
        assert_eq!(v2t_wire::BelowReachCode::from_code(last.below_reach), Ok(v2t_wire::BelowReachCode::VutWaits));
        assert_eq!(last.has_pet_bound, 0, "no PET in the asked order: no bound");
    }
}
