//! The same regulator (`v2t-game`) in the cloud, as the paper and TroubleMaker run it: the BV
//! reports its state and the VUT's over the link (real `v2t-wire::link` telemetry frames), the
//! cloud ([`CloudRegulator`]) regulates on what arrives and sends back a signed plan (the
//! accelerations over its horizon from the instant it starts), and the BV applies the last plan it
//! accepted at its own clock (the tracker's longitudinal loop, its limits, feed-forward only) while
//! pure pursuit keeps it on its path, as [`super::RegulatedBv`] does. The link is a [`CloudLink`]:
//! a simulated network with the cloud in the same process ([`SimulatedNetwork`],
//! [`v2t_sim::network`]), or a real broker and a cloud process (`crate::cloud_mqtt`).
//!
//! **What differs from onboard, and only that.** The VUT's state reaches the BV as it does for the
//! onboard regulator (the simulator's V2X delay); the BV forwards both states to the cloud. So at
//! zero network delay the two methods see the same measurements, and what the comparison shows is
//! the network inside the loop (and the BV tracking a plan instead of applying the decision).
//!
//! **When plans stop arriving** the BV falls back by the onboard rules: it starts on its prior (the
//! plan it holds when the test starts); a plan (or that prior) more than `plan_timeout_s` after its
//! arrival, or one the BV has driven past the end of, is not followed, and the BV brakes at the
//! regulator's `fallback_decel_mps2` (the minimal-risk profile). The cloud
//! regulator judges its inputs by the onboard rule too: a state older than `max_input_age_s` when
//! it decides is stale (its plan is the minimal-risk profile).

use std::cell::Cell;
use std::rc::Rc;

use v2t_game::regulation::{Measurement, Regulation};
use v2t_game::regulator::RegulatorParams;
use v2t_sim::bv::BvController;
use v2t_sim::control::pure_pursuit;
use v2t_sim::network::{Channel, NetworkSettings};
use v2t_sim::observation::{BvObservation, Perceived};
use v2t_sim::plant::ActuationRequest;
use v2t_sim::scenario::Scenario;
use v2t_track::{LongitudinalGains, LongitudinalInput, LongitudinalLimits, PlanSample, SpeedPid};
use v2t_wire::Code as _;
use v2t_wire::link::{
    self, Arrival, CloudBody, CloudMessage, CloudPlan, EdgeReport, Receiver, SigningKey, Telemetry, VerifyingKey,
    Window,
};

/// The plan timeout of the onboard runtime's shipped configurations (`plan_timeout_s` of
/// `config/edge/*.toml`), s.
pub const PLAN_TIMEOUT_S: f64 = 0.4;

/// The id the VUT's state is forwarded under (on the BV's telemetry topic).
pub const VUT_ID: &str = "vut";
/// The simulated link's fleet and BV.
const SIM_FLEET: &str = "sim";
const SIM_BV: &str = "bv1";
/// The simulated link's clock at the simulation's time 0, Unix ms (any value: both ends share it).
const SIM_EPOCH_MS: u64 = 1_000_000_000;

/// What the link did in one run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct CloudLinkStats {
    /// BV control cycles.
    pub cycles: u64,
    /// Cycles the BV braked on the minimal-risk profile (no plan to follow, or the plan was one).
    pub fallback_cycles: u64,
    /// Cloud decisions.
    pub decisions: u64,
    /// Cloud decisions on stale states.
    pub stale_decisions: u64,
    /// Plans the BV accepted.
    pub plans_accepted: u64,
    /// Plans the BV refused (overtaken by a newer one, or broken).
    pub plans_refused: u64,
    /// State reports lost on the way up.
    pub up_lost: u64,
    /// Plans lost on the way down.
    pub down_lost: u64,
}

/// The network between a BV and its cloud regulator, as the BV sees it: what the BV reports goes
/// in, the plans that reached it come out. [`SimulatedNetwork`] has the cloud in the same process
/// behind a simulated network; `v2t_lab::cloud_mqtt` reaches a cloud process through a broker.
pub trait CloudLink: std::fmt::Debug {
    /// The link's clock at simulation time 0, Unix ms (stamps, plans and arrivals are on it).
    fn epoch_ms(&self) -> u64;

    /// Hands this cycle's reports (telemetry frames) to the network at simulation time `t_s` and
    /// returns the plan frames that reached the BV by then, with their arrival times (simulation
    /// time), in order of arrival. `stats` takes what the link knows of the cloud and the losses.
    fn exchange(&mut self, t_s: f64, reports: Vec<Vec<u8>>, stats: &mut CloudLinkStats) -> Vec<(f64, Vec<u8>)>;
}

/// The cloud in the same process, behind a simulated network ([`v2t_sim::network`]): every report
/// crosses the uplink, the cloud decides on the newest BV state at its arrival, the plan crosses
/// the downlink.
#[derive(Debug)]
pub struct SimulatedNetwork {
    cloud: CloudRegulator,
    up: Channel<Vec<u8>>,
    down: Channel<Vec<u8>>,
    processing_s: f64,
}

impl CloudLink for SimulatedNetwork {
    fn epoch_ms(&self) -> u64 {
        SIM_EPOCH_MS
    }

    fn exchange(&mut self, t_s: f64, reports: Vec<Vec<u8>>, stats: &mut CloudLinkStats) -> Vec<(f64, Vec<u8>)> {
        for r in reports {
            self.up.send(t_s, r);
        }
        let mut decide_at = None;
        for (at, frame) in self.up.deliver(t_s) {
            if self.cloud.hear(&frame) {
                decide_at = Some(at);
            }
        }
        if let Some(at) = decide_at
            && let Some(frame) = self.cloud.decide(at, SIM_EPOCH_MS)
        {
            self.down.send(at + self.processing_s, frame);
        }
        stats.decisions = self.cloud.decisions;
        stats.stale_decisions = self.cloud.stale_decisions;
        stats.up_lost = self.up.lost();
        stats.down_lost = self.down.lost();
        self.down.deliver(t_s)
    }
}

/// A BV regulated in the cloud: it reports, follows the plans that reach it, falls back when they
/// stop.
#[derive(Debug)]
pub struct CloudRegulatedBv {
    link: Box<dyn CloudLink>,
    rx: Receiver,
    bv_id: String,
    /// The plan followed and when it arrived, s.
    plan: Option<(CloudPlan, f64)>,
    pid: SpeedPid,
    seq: u64,
    fallback_decel_mps2: f64,
    plan_timeout_s: f64,
    /// When the test started (the first cycle), s.
    started_s: f64,
    stats: CloudLinkStats,
    report: Rc<Cell<CloudLinkStats>>,
}

/// The cloud's side: the regulator of one BV, what it last heard, and the key it signs with.
#[derive(Debug)]
pub struct CloudRegulator {
    /// The adapter the vehicle runs, in the cloud.
    regulation: Regulation,
    key: SigningKey,
    fleet: String,
    bv_id: String,
    seq: u64,
    bv: Option<Telemetry>,
    vut: Option<Telemetry>,
    decisions: u64,
    stale_decisions: u64,
}

impl CloudRegulatedBv {
    /// A BV of `scenario` (index `bv_index`) regulated in the cloud with `params` across the
    /// simulated `network`; `seed` draws the network's delays and losses (its own streams: the
    /// run's other draws do not change with the network).
    pub fn new(
        params: RegulatorParams,
        scenario: &Scenario,
        bv_index: usize,
        network: &NetworkSettings,
        seed: u64,
    ) -> Result<Self, CloudBvError> {
        let key = SigningKey::from_bytes(&[0x5c; 32]);
        let public = key.verifying_key();
        let cloud = CloudRegulator::new(params, scenario, bv_index, key, SIM_FLEET, SIM_BV)?;
        let link = SimulatedNetwork {
            cloud,
            up: Channel::new(network.uplink, network.in_order, seed, 0x75),
            down: Channel::new(network.downlink, network.in_order, seed, 0x64),
            processing_s: network.processing_ms / 1000.0,
        };
        Self::with_link(params, scenario, bv_index, Box::new(link), public, SIM_FLEET, SIM_BV)
    }

    /// A BV of `scenario` whose plans come across `link`, signed with the key `cloud_key` verifies,
    /// for BV `bv_id` of `fleet`.
    pub fn with_link(
        params: RegulatorParams,
        scenario: &Scenario,
        bv_index: usize,
        link: Box<dyn CloudLink>,
        cloud_key: VerifyingKey,
        fleet: &str,
        bv_id: &str,
    ) -> Result<Self, CloudBvError> {
        let vehicle = &scenario.bvs.get(bv_index).ok_or(CloudBvError::NoBv(bv_index))?.agent.vehicle;
        // The onboard tracker's longitudinal loop with the BV's limits, on the plan's acceleration
        // alone (as the onboard BV applies its regulator's): the cloud closes the loop with every
        // plan. Feedback on a delayed plan's station or speed made a BV that holds just before its
        // zone creep over the line (chosen on seeds 1–3 of the left-turn card, yield τ 2 s, 0–300
        // ms: with the default speed and station gains the BV crossed its entry in 7 of 9 runs).
        let gains =
            LongitudinalGains { station_gain_1ps2: 0.0, kp_1ps: 0.0, ki_1ps2: 0.0, ..LongitudinalGains::default() };
        let pid = SpeedPid::new(gains, LongitudinalLimits::from(&vehicle.limits))?;
        Ok(Self {
            link,
            rx: Receiver::new(cloud_key, fleet, bv_id, Window::default()),
            bv_id: bv_id.to_owned(),
            plan: None,
            pid,
            seq: 0,
            fallback_decel_mps2: params.fallback_decel_mps2,
            plan_timeout_s: PLAN_TIMEOUT_S,
            started_s: f64::NAN,
            stats: CloudLinkStats::default(),
            report: Rc::default(),
        })
    }

    /// Where the run's link statistics will be (updated every cycle).
    pub fn link_report(&self) -> Rc<Cell<CloudLinkStats>> {
        Rc::clone(&self.report)
    }

    /// The acceleration to apply now: the BV starts on its prior (the plan it holds when the test
    /// starts), then follows the last plan; either only while it is fresh (`plan_timeout_s` since
    /// it arrived, the prior counting as arrived at the start). `None`: the minimal-risk profile.
    fn followed(&self, bv: &v2t_sim::scenario::BvSetup, t_s: f64) -> Option<f64> {
        let arrived = self.plan.as_ref().map_or(self.started_s, |(_, at)| *at);
        if t_s - arrived > self.plan_timeout_s {
            return None;
        }
        match self.plan.as_ref() {
            None => Some(bv.reference.accel_at(t_s)),
            Some((plan, _)) if plan.accel_mps2.is_empty() => None,
            Some((plan, _)) => plan_at(plan, clock_ms(self.link.epoch_ms(), t_s)).map(|p| p.a_mps2),
        }
    }
}

/// A telemetry report of `p` (measured `p.age_s` before `t_s`) under `id`, on the link's clock.
fn report(id: &str, seq: u64, epoch_ms: u64, p: &Perceived, t_s: f64) -> Telemetry {
    Telemetry {
        bv_id: id.to_owned(),
        seq,
        stamp_ms: clock_ms(epoch_ms, t_s - p.age_s),
        prior_id: 0,
        px_m: p.state.px,
        py_m: p.state.py,
        theta_rad: p.state.theta_rad,
        speed_mps: p.state.speed_mps,
        plan_status: 0,
        predicted_pet_s: None,
        below_reach: 0,
        pet_bound_s: None,
        gate_state: 0,
        gate_reason: 0,
        vut_reaction: None,
    }
}

/// What `plan` sets at `t_ms` on its clock (before its start: its start), step by step at each
/// step's acceleration as the tracker advances a plan ([`PlanSample::advanced`]: a braking step
/// stops and stays). `None` past its last step.
pub fn plan_at(plan: &CloudPlan, t_ms: u64) -> Option<PlanSample> {
    let mut t = t_ms.saturating_sub(plan.t0_ms) as f64 / 1000.0;
    let mut p = PlanSample { s_m: plan.s0_m, v_mps: plan.v0_mps.max(0.0), a_mps2: 0.0 };
    for &a in &plan.accel_mps2 {
        let step = PlanSample { a_mps2: a, ..p };
        if t < plan.dt_s {
            return Some(step.advanced(t));
        }
        p = step.advanced(plan.dt_s);
        t -= plan.dt_s;
    }
    None
}

/// Why a cloud-regulated BV cannot be built.
#[derive(Debug, thiserror::Error)]
pub enum CloudBvError {
    /// The regulator: its QPs, or the prior it regulates around.
    #[error(transparent)]
    Regulated(#[from] super::regulated::RegulatedBvError),
    /// The tracker's longitudinal loop (the BV's limits).
    #[error("tracker: {0}")]
    Tracker(#[from] v2t_track::TrackError),
    /// The scenario has no such BV.
    #[error("the scenario has no BV {0}")]
    NoBv(usize),
}

/// The link clock's reading at simulation time `t_s`, ms.
pub fn clock_ms(epoch_ms: u64, t_s: f64) -> u64 {
    let ms = (t_s * 1000.0).round();
    if ms >= 0.0 { epoch_ms.saturating_add(ms as u64) } else { epoch_ms.saturating_sub((-ms) as u64) }
}

impl CloudRegulator {
    /// The regulator of BV `bv_index` of `scenario` with `params`, signing its plans for BV `bv_id`
    /// of `fleet` with `key`.
    pub fn new(
        params: RegulatorParams,
        scenario: &Scenario,
        bv_index: usize,
        key: SigningKey,
        fleet: &str,
        bv_id: &str,
    ) -> Result<Self, CloudBvError> {
        if scenario.bvs.get(bv_index).is_none() {
            return Err(CloudBvError::NoBv(bv_index));
        }
        Ok(Self {
            regulation: super::regulated::regulation_for(params, scenario, bv_index)?,
            key,
            fleet: fleet.to_owned(),
            bv_id: bv_id.to_owned(),
            seq: 0,
            bv: None,
            vut: None,
            decisions: 0,
            stale_decisions: 0,
        })
    }

    /// Decisions so far, and how many of them on stale states.
    pub fn decisions(&self) -> (u64, u64) {
        (self.decisions, self.stale_decisions)
    }

    /// Takes a report that arrived; returns whether it was a newer BV state (then the cloud decides).
    pub fn hear(&mut self, frame: &[u8]) -> bool {
        let Ok(EdgeReport::Telemetry(t)) = link::read_report(frame) else { return false };
        let newer = |old: &Option<Telemetry>| old.as_ref().is_none_or(|o| o.seq < t.seq);
        if t.bv_id == self.bv_id && newer(&self.bv) {
            self.bv = Some(t);
            true
        } else {
            if t.bv_id == VUT_ID && newer(&self.vut) {
                self.vut = Some(t);
            }
            false
        }
    }

    /// One decision at simulation time `now_s` (the link's clock reads `epoch_ms` at time 0) on
    /// the latest states: the sealed plan frame.
    pub fn decide(&mut self, now_s: f64, epoch_ms: u64) -> Option<Vec<u8>> {
        let (bv, vut) = (self.bv.as_ref()?, self.vut.as_ref()?);
        let now_ms = clock_ms(epoch_ms, now_s);
        let measured = |t: &Telemetry| Measurement {
            x_m: t.px_m,
            y_m: t.py_m,
            speed_mps: t.speed_mps,
            age_s: now_ms.saturating_sub(t.stamp_ms) as f64 / 1000.0,
        };
        let step = self.regulation.decide(now_s, &measured(bv), Some(&measured(vut)))?;
        let d = step.decision;
        // Where the plan starts: the BV brought to now, as the decision took it.
        let bv_now = step.input.map_or(step.bv_s_m.unwrap_or(0.0), |i| i.bv.s_m);
        self.decisions += 1;
        if d.status == v2t_game::regulator::RegulatorStatus::Stale {
            self.stale_decisions += 1;
        }
        let accel = self.regulation.planned_accels(&d).map(<[f64]>::to_vec).unwrap_or_default();
        self.seq += 1;
        let plan = CloudPlan {
            state_seq: bv.seq,
            t0_ms: now_ms,
            s0_m: bv_now,
            v0_mps: bv.speed_mps.clamp(0.0, 150.0),
            dt_s: self.regulation.params().dt_s,
            accel_mps2: accel,
            status: v2t_edge::regulate::status_code(d.status).code(),
            predicted_pet_s: d.predicted_pet_s,
        };
        let msg = CloudMessage {
            fleet: self.fleet.clone(),
            bv_id: self.bv_id.clone(),
            seq: self.seq,
            issued_ms: now_ms,
            body: CloudBody::Plan(plan),
        };
        link::seal(&msg, &self.key).ok()
    }
}

impl BvController for CloudRegulatedBv {
    fn name(&self) -> &str {
        "cloud regulator"
    }

    fn control(&mut self, obs: &BvObservation<'_>) -> ActuationRequest {
        let sc = obs.scenario;
        let t = obs.t_s;
        if self.stats.cycles == 0 {
            self.started_s = t;
        }
        self.stats.cycles += 1;
        // Up: this cycle's VUT and BV states, the VUT's first (the cloud decides when the BV's
        // arrives, on the newest of both); down: the plans that arrived.
        let epoch = self.link.epoch_ms();
        let mut reports = Vec::with_capacity(2);
        for (id, p) in [(VUT_ID, &obs.vut), (self.bv_id.as_str(), &obs.own)] {
            self.seq += 1;
            if let Ok(frame) = link::telemetry_frame(&report(id, self.seq, epoch, p, t)) {
                reports.push(frame);
            }
        }
        for (at, frame) in self.link.exchange(t, reports, &mut self.stats) {
            match self.rx.open(&frame, Arrival::Plan, clock_ms(epoch, at)) {
                Ok(CloudMessage { body: CloudBody::Plan(plan), .. }) => {
                    self.stats.plans_accepted += 1;
                    self.plan = Some((plan, at));
                }
                _ => self.stats.plans_refused += 1,
            }
        }

        let Some(bv) = sc.bvs.get(obs.bv_index) else {
            return ActuationRequest { accel_mps2: -self.fallback_decel_mps2, steer_rad: 0.0 };
        };
        let steer_rad = pure_pursuit(&bv.agent.route, &obs.own.state, obs.own.s_m, &bv.agent.vehicle);
        // Feed-forward only: the loop's limits and jerk bound on the plan's acceleration.
        let tracked = self.followed(bv, t).and_then(|a_ref| {
            let mut pid = self.pid;
            let out = pid
                .update(
                    &LongitudinalInput {
                        speed_mps: obs.own.state.speed_mps,
                        station_m: obs.own.s_m,
                        ref_speed_mps: obs.own.state.speed_mps,
                        ref_station_m: obs.own.s_m,
                        ref_accel_mps2: a_ref,
                    },
                    obs.dt_s,
                )
                .ok()?;
            self.pid = pid;
            Some(out.accel_mps2)
        });
        let accel_mps2 = match tracked {
            Some(a) => a,
            None => {
                self.stats.fallback_cycles += 1;
                self.pid.reset();
                let v = obs.own.state.speed_mps.max(0.0);
                -self.fallback_decel_mps2.min(v / obs.dt_s.max(1e-3))
            }
        };
        self.report.set(self.stats);
        ActuationRequest { accel_mps2, steer_rad }
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing)]

    use super::*;
    use crate::controllers::RegulatedBv;
    use v2t_sim::runner::run;
    use v2t_sim::vut::VutModel;

    /// The card `name` at rush τ = 3 s.
    fn card(name: &str) -> Scenario {
        let cfg = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config");
        let card: v2t_sim::config::ScenarioCard =
            v2t_files::load_toml(&cfg.join(format!("scenarios/{name}.toml"))).unwrap();
        let vehicle = |f: &str| v2t_files::load_toml(&cfg.join("vehicles").join(f)).unwrap();
        let sim = v2t_files::load_toml(&cfg.join("sim/default.toml")).unwrap();
        let mut sc =
            Scenario::from_card(&card, sim, vehicle("vut_sedan.toml"), vec![vehicle("bv_sedan.toml")]).unwrap();
        sc.target = v2t_model::Target::new(3.0, v2t_model::Style::Rush).unwrap();
        sc
    }

    fn pet(sc: &Scenario, ctrl: Box<dyn BvController>, seed: u64) -> Option<f64> {
        let mut bvs = vec![ctrl];
        let out = run(sc, &mut bvs, VutModel::IdmNormal.driver().as_mut(), seed).unwrap();
        assert!(out.result.collision.is_none());
        out.result.pet_min_s
    }

    /// A plan is read at the BV's instant, step by step, a braking step stops and stays, and past
    /// its last step it says nothing.
    #[test]
    fn a_plan_is_read_at_the_bvs_instant_and_ends_with_its_last_step() {
        let p = CloudPlan {
            state_seq: 3,
            t0_ms: 10_000,
            s0_m: 20.0,
            v0_mps: 4.0,
            dt_s: 0.1,
            accel_mps2: vec![1.0, 1.0, -50.0, 0.0],
            status: 1,
            predicted_pet_s: Some(2.0),
        };
        let at = |t_ms| plan_at(&p, t_ms).map(|q| (q.s_m, q.v_mps, q.a_mps2));
        let (s, v, a) = at(10_150).unwrap();
        // 0.1 s at 1 m/s² from 4 m/s, then 0.05 s more.
        let s1 = 20.0 + 0.4 + 0.005;
        assert!((s - (s1 + 4.1 * 0.05 + 0.5 * 0.05 * 0.05)).abs() < 1e-9 && (v - 4.15).abs() < 1e-9 && a == 1.0);
        // Before its start: its start.
        assert_eq!(at(9_000), Some((20.0, 4.0, 1.0)));
        // The braking step stops at 0 and stays.
        let (_, v, a) = at(10_290).unwrap();
        assert_eq!((v, a), (0.0, 0.0));
        assert_eq!(at(10_400), None, "past its last step the plan says nothing");
    }

    /// With no network the cloud regulator lands where the onboard one does; with a network that
    /// never delivers, the BV never gets a plan and brakes every cycle.
    #[test]
    fn the_cloud_regulator_matches_onboard_without_a_network_and_falls_back_without_plans() {
        let sc = card("left_turn_basic");
        let params = RegulatedBv::params_for(&RegulatorParams::default(), &sc, 0);
        let onboard = pet(&sc, Box::new(RegulatedBv::new(params, &sc, 0).unwrap()), 6).unwrap();
        let ideal = NetworkSettings::constant(0.0, 0.0);
        let cloud = CloudRegulatedBv::new(params, &sc, 0, &ideal, 6).unwrap();
        let report = cloud.link_report();
        let cloud_pet = pet(&sc, Box::new(cloud), 6).unwrap();
        assert!((cloud_pet - onboard).abs() < 0.25, "onboard {onboard:.2} s, cloud {cloud_pet:.2} s");
        let r = report.get();
        assert_eq!((r.up_lost, r.down_lost, r.plans_refused), (0, 0, 0));
        assert!(r.fallback_cycles <= 1, "{r:?}");
        // Every plan arrives, but the last one may still be on its way (2 ms of processing) when
        // the run ends.
        assert!(r.decisions - r.plans_accepted <= 1, "{r:?}");

        let dead = NetworkSettings::constant(0.0, 0.99);
        let cloud = CloudRegulatedBv::new(params, &sc, 0, &dead, 6).unwrap();
        let report = cloud.link_report();
        let mut bvs: Vec<Box<dyn BvController>> = vec![Box::new(cloud)];
        let _ = run(&sc, &mut bvs, VutModel::IdmNormal.driver().as_mut(), 6).unwrap();
        let r = report.get();
        assert!(r.fallback_cycles as f64 > 0.9 * r.cycles as f64, "{r:?}");
    }

    /// A plan that arrives late is read at the BV's own instant; the cloud's age rule makes a
    /// decision on states older than `max_input_age_s` the minimal-risk profile.
    #[test]
    fn a_long_delay_makes_the_clouds_states_stale_and_the_bv_brake() {
        let sc = card("left_turn_basic");
        let params = RegulatedBv::params_for(&RegulatorParams::default(), &sc, 0);
        let slow = NetworkSettings::constant(600.0, 0.0);
        let cloud = CloudRegulatedBv::new(params, &sc, 0, &slow, 6).unwrap();
        let report = cloud.link_report();
        let mut bvs: Vec<Box<dyn BvController>> = vec![Box::new(cloud)];
        let _ = run(&sc, &mut bvs, VutModel::IdmNormal.driver().as_mut(), 6).unwrap();
        let r = report.get();
        assert_eq!(r.stale_decisions, r.decisions, "{r:?}");
        assert!(r.fallback_cycles as f64 > 0.9 * r.cycles as f64, "{r:?}");
    }
}
