//! `video2track experiment campaign`: one test repeated as a proving ground repeats it, the BV's
//! regulator learning this VUT's reaction from run to run ([`v2t_game::campaign`]).
//!
//! For every scenario, style, target τ and VUT, `campaigns` independent campaigns of `runs` runs
//! each. Campaign `c` (its seed) runs its run `k` (1-based) with the simulation seed
//! [`run_seed`]`(c, k)`; each campaign starts from an empty memory (run 1 is uncalibrated) and
//! carries its memory from one run to the next, exactly as a memory file would between two
//! invocations of `video2track sim --campaign FILE`. Nothing is shared between VUTs, nor between
//! campaigns.
//!
//! Scoring, per case and per run index `k`: the mean over the campaigns of run `k`'s PET against τ
//! (`|meanPET_k − τ| / τ`). Where the open-loop grid of [`crate::reach`] shows that no BV reaches τ
//! against this VUT, the case is marked *below reach* and scored against the reached PET nearest
//! to τ instead (its *bound*); where no BV passes in the asked order at all, it has no error. The
//! grid is an oracle for scoring only: neither the regulator nor the memory reads it. Errors are
//! given per VUT, never pooled across VUTs.

use std::cell::Cell;
use std::rc::Rc;

mod view;

use serde::Serialize;
use v2t_game::campaign::{CampaignMemory, CaseMemory, RunRecord};
use v2t_game::reaction::ReactionPosterior;
use v2t_game::regulator::{BelowReach, BelowReachCause, RegulatorParams};
use v2t_game::route_speed::RouteSpeed;
use v2t_model::{Style, Target};
use v2t_sim::bv::BvController;
use v2t_sim::runner::{RunError, RunOutcome, RunResult};
use v2t_sim::scenario::Scenario;

use crate::controllers::RegulatedBv;
use crate::reach::{Reach, reach};
use crate::vut::{Vut, World};

/// Runs of one campaign when not told otherwise (the proving-ground campaign).
pub const DEFAULT_RUNS: usize = 10;
/// The largest campaign length.
pub const MAX_RUNS: usize = 1000;
/// Run indices from this one on are the calibrated ones the summary scores apart from run 1.
pub const CALIBRATED_FROM: usize = 3;

/// The simulation seed of run `k` (1-based) of campaign `campaign`: `1000 · campaign + k`, so the
/// runs of campaigns 1–5 (tuning) and 6–20 (reported) never share a seed.
pub fn run_seed(campaign: u64, k: usize) -> u64 {
    campaign.saturating_mul(1000).saturating_add(k as u64)
}

/// One run of one campaign.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CampaignRun {
    /// The campaign (its seed).
    pub campaign: u64,
    /// Run index, 1-based.
    pub run: usize,
    /// The simulation seed.
    pub seed: u64,
    /// The τ the regulator was given (the learned aim), s.
    pub aim_s: f64,
    /// `PET_min` measured, s.
    pub pet_s: Option<f64>,
    /// Every conflict passed in the asked order.
    pub order_ok: bool,
    /// A collision.
    pub collision: bool,
    /// The vehicles were in the zone together.
    pub zone_overlap: bool,
    /// The last "τ out of reach" the regulator reported during the run (`None`: none).
    pub below_reach: Option<BelowReach>,
    /// The world could not run it.
    pub failed: bool,
    /// Where the VUT went first at a crossing with a stop line: whether the first BV gave way as
    /// the regulator's BV must ([`crate::reach::YieldRule`]); `None` elsewhere.
    pub yield_kept: Option<bool>,
    /// The first BV's largest lateral acceleration in the run ([`crate::stats::peak_lateral_mps2`]),
    /// m/s² (`None`: the world could not run it).
    pub bv_lateral_mps2: Option<f64>,
    /// That BV's limit (its vehicle file's `max_lat_accel_mps2`), m/s².
    pub bv_lateral_limit_mps2: f64,
}

/// What run index `k` gave over the campaigns of one case.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RunIndexStats {
    /// Run index, 1-based.
    pub run: usize,
    /// Mean of the measured PETs, s.
    pub mean_pet_s: Option<f64>,
    /// Mean aim, s.
    pub mean_aim_s: f64,
    /// `|meanPET − τ| / τ` (a run index without a measured PET counts as 1).
    pub error_rel: f64,
    /// Against the case's bound when it is below reach, `|meanPET − bound| / bound`.
    pub error_vs_bound_rel: Option<f64>,
    /// Runs without a measured PET.
    pub unmeasured: usize,
    /// Collisions.
    pub collisions: usize,
    /// Zone overlaps.
    pub zone_overlaps: usize,
    /// Share of the runs in the asked order.
    pub order_ok_frac: f64,
    /// Share of the runs in which the regulator reported τ out of reach.
    pub below_reach_frac: f64,
    /// Runs whose BV did not give way as the rule asks ([`CampaignRun::yield_kept`]).
    pub yields_not_kept: usize,
}

/// One case: a test against one VUT, every campaign.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CampaignCase {
    /// Scenario name.
    pub scenario: String,
    /// Style.
    pub style: Style,
    /// The VUT's driver.
    pub vut: String,
    /// The VUT's world.
    pub world: World,
    /// Target PET, s.
    pub tau_s: f64,
    /// Whether some BV reaches τ against this VUT (`None`: the grid was not run).
    pub reachable: Option<bool>,
    /// Below reach: the reached PET nearest to τ in the asked order, s (`None` when reachable, not
    /// measured, or no BV passed in that order at all).
    pub bound_s: Option<f64>,
    /// Per run index.
    pub per_run: Vec<RunIndexStats>,
    /// Whether the regulator reported τ out of reach in most calibrated runs (index ≥
    /// [`CALIBRATED_FROM`]).
    pub detected_below_reach: bool,
    /// Every run, campaign by campaign.
    pub runs: Vec<CampaignRun>,
}

/// Errors of one VUT over its cases.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct VutSummary {
    /// The VUT.
    pub vut: String,
    /// Reachable cases (or every case when reach was not measured).
    pub reachable_cases: usize,
    /// Run 1 (uncalibrated), reachable cases: mean and largest error.
    pub run1: (f64, f64),
    /// Runs [`CALIBRATED_FROM`] on, reachable cases: mean over cases and run indices, and the
    /// largest per-case per-run-index error (each the error of the mean PET over the campaigns).
    pub calibrated: (f64, f64),
    /// Runs [`CALIBRATED_FROM`] on, reachable cases, every run scored on its own: the mean error
    /// and the share within ±10 % of τ (no PET: error 1, outside).
    pub calibrated_single: crate::stats::SingleRuns,
    /// Reachable cases within 10 % at every calibrated run index.
    pub calibrated_within_10: usize,
    /// Below-reach cases, and how many of them the regulator reported.
    pub below_reach: (usize, usize),
    /// Reachable cases the regulator reported out of reach.
    pub false_below_reach: usize,
    /// Below-reach cases with a bound: mean error against it over the calibrated runs.
    pub calibrated_vs_bound: Option<f64>,
    /// Runs, collisions, runs out of the asked order, runs without a PET.
    pub runs: (usize, usize, usize, usize),
    /// Runs whose BV did not give way as the rule asks ([`CampaignRun::yield_kept`]).
    pub yields_not_kept: usize,
    /// The first BV's lateral acceleration over every run: the runs over its limit and the
    /// largest (the limit: the lowest of the cases').
    pub bv_lateral: crate::steer::BvLateral,
}

/// The whole experiment.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CampaignReport {
    /// Runs per campaign.
    pub runs_per_campaign: usize,
    /// The campaigns (their seeds).
    pub campaigns: Vec<u64>,
    /// Every case.
    pub cases: Vec<CampaignCase>,
    /// Per VUT.
    pub per_vut: Vec<VutSummary>,
    /// What the open-loop grid reached (when measured).
    pub reach: Vec<Reach>,
}

/// Runs one campaign of `runs` runs of `scenario` aiming at `target` against `vut`, learning in
/// `memory` (the memory of this VUT; the test's entry is made when missing).
pub fn run_campaign(
    settings: &RegulatorParams,
    scenario: &Scenario,
    target: Target,
    vut: &Vut<'_>,
    campaign: u64,
    runs: usize,
    memory: &mut CampaignMemory,
) -> Vec<CampaignRun> {
    (1..=runs).map(|k| run_once(settings, scenario, target, vut, campaign, k, memory)).collect()
}

/// One run with regulated BVs, each aiming where `memory` says for its test (the scenario's target
/// without a memory, or for a test it never saw).
#[derive(Debug)]
pub struct RegulatedRun {
    /// The run.
    pub outcome: RunOutcome,
    /// Each BV's aim.
    pub aims: Vec<Target>,
    /// Each BV's last "τ out of reach" report of the run.
    pub below_reach: Vec<Option<BelowReach>>,
    /// Each BV's decisions over the run (status, predicted PET).
    pub decisions: Vec<Vec<crate::controllers::LoggedDecision>>,
    /// Whether each BV's follower knew how the VUT drives its route (a learned route speed).
    pub learned_routes: Vec<bool>,
    /// Whether each BV's regulator started from how earlier runs identified the VUT's reaction.
    pub reaction_priors: Vec<bool>,
    /// How each BV's regulator identified the VUT's reaction by the end of the run (`None`: its
    /// follower does not react).
    pub reactions: Vec<Option<ReactionPosterior>>,
    /// What the run taught each BV's regulator once the VUT had left its zone (what the onboard
    /// node reports, `campaign record --learned`): what the campaign memory learns.
    pub lessons: Vec<Option<v2t_game::regulation::Lesson>>,
}

impl RegulatedRun {
    /// Each BV's decisions as the onboard runtime's `/plans` records.
    pub fn plans(&self) -> Vec<Vec<v2t_sim::recording::PlanRecord>> {
        self.decisions.iter().map(|bv| bv.iter().map(|d| d.record()).collect()).collect()
    }
}

/// Why a regulated run did not run.
#[derive(Debug, thiserror::Error)]
pub enum RegulatedRunError {
    /// The regulated BV could not be built (its settings, or the prior it regulates around).
    #[error(transparent)]
    Regulated(#[from] crate::controllers::RegulatedBvError),
    /// The world could not run it.
    #[error(transparent)]
    Run(#[from] RunError),
}

/// Runs `scenario` once against `vut` with regulated BVs aiming as `memory` says.
pub fn regulated_run(
    settings: &RegulatorParams,
    scenario: &Scenario,
    vut: &Vut<'_>,
    seed: u64,
    memory: Option<&CampaignMemory>,
) -> Result<RegulatedRun, RegulatedRunError> {
    let target = scenario.target;
    let mut reports: Vec<Rc<Cell<Option<BelowReach>>>> = Vec::new();
    let mut logs = Vec::new();
    let mut aims = Vec::with_capacity(scenario.bvs.len());
    let mut learned_routes = Vec::with_capacity(scenario.bvs.len());
    let mut reaction_priors = Vec::with_capacity(scenario.bvs.len());
    let mut reaction_reports = Vec::with_capacity(scenario.bvs.len());
    let mut lesson_reports = Vec::with_capacity(scenario.bvs.len());
    let mut bvs: Vec<Box<dyn BvController>> = Vec::with_capacity(scenario.bvs.len());
    for i in 0..scenario.bvs.len() {
        let case = memory.and_then(|m| m.case(&scenario.name, i, target));
        let aim = case.map_or(target, |c| c.aim(target));
        let learned = case.map(learned_of).unwrap_or_default();
        let r = RegulatedBv::new(RegulatedBv::params_for(settings, scenario, i), scenario, i)?
            .with_campaign(&learned.upload(crate::world::CARD_PRIOR_ID, aim))?;
        reports.push(r.below_reach_report());
        logs.push(r.decision_log());
        aims.push(aim);
        learned_routes.push(r.knows_route());
        reaction_priors.push(r.has_reaction_prior());
        reaction_reports.push(r.reaction_report());
        lesson_reports.push(r.lesson_report());
        bvs.push(Box::new(r));
    }
    let outcome = vut.run(scenario, &mut bvs, seed)?;
    drop(bvs);
    Ok(RegulatedRun {
        outcome,
        aims,
        below_reach: reports.iter().map(|r| r.get()).collect(),
        decisions: logs.iter().map(|l| l.take()).collect(),
        learned_routes,
        reaction_priors,
        reactions: reaction_reports.iter().map(|r| r.get().map(ReactionPosterior::from)).collect(),
        lessons: lesson_reports.iter().map(|l| l.take()).collect(),
    })
}

/// What `case` has learned of the VUT, as the cloud sends it to the BV of the test's next run
/// (`video2track campaign send`; the lab's campaigns give it to their BVs the same way).
pub fn learned_of(case: &CaseMemory) -> v2t_edge::campaign::Learned {
    v2t_edge::campaign::Learned {
        known: case.below_reach,
        route: case.route_speed.clone(),
        reaction: case.reaction.clone(),
    }
}

/// Records a regulated run of `scenario` (its target is the test's) in `memory`, BV by BV: its
/// outcome, and what the run taught that BV's regulator (the VUT's route as the regulator measured
/// it, its reaction as identified once the VUT had left its zone: [`RegulatedRun::lessons`]), as
/// the memory learns it on the track from the BV's report.
pub fn record_run(memory: &mut CampaignMemory, scenario: &Scenario, run: &RegulatedRun) {
    let target = scenario.target;
    for (i, aim) in run.aims.iter().enumerate() {
        let id = scenario.bvs.get(i).map(|b| b.agent.id.as_str());
        let case = memory.case_mut(&scenario.name, i, target);
        let learned_route = run.learned_routes.get(i).copied().unwrap_or(false);
        let reaction_prior = run.reaction_priors.get(i).copied().unwrap_or(false);
        case.record(
            target,
            RunRecord { learned_route, reaction_prior, ..bv_record(&run.outcome.result, id, aim.tau_s()) },
        );
        if let Some(Some(lesson)) = run.lessons.get(i) {
            if let Some(route) = &lesson.route {
                case.learn_route(target, route);
            }
            if let Some(reaction) = &lesson.reaction {
                case.learn_reaction(target, reaction);
            }
        }
    }
}

/// How the VUT drove its route in `outcome` as the simulator traced it (the truth, not what a BV
/// measured: the free drive and the campaigns learn what the BV's regulator measured; this is
/// for checking that against), up to the exit of its zone with BV `bv_index` (the follower looks
/// no farther): its speed on the route's grid where it first passed each point, up to where it
/// first stood ([`RouteSpeed::from_samples`]). `None` without that zone or trace.
pub fn vut_route_speed(outcome: &RunOutcome, bv_index: usize) -> Option<RouteSpeed> {
    let zone = outcome.layout.zones.iter().find(|z| z.bv_index == bv_index)?;
    let samples = outcome.trace.iter().filter_map(|t| t.agents.first()).map(|a| (a.s_m, a.state.speed_mps));
    RouteSpeed::from_samples(samples, zone.zone.vut.exit_s_m)
}

/// A free drive's seed is the regulated run's plus this: another drive of the same VUT, not the
/// run it prepares (a noisy VUT model drives it differently).
pub const FREE_DRIVE_SEED_OFFSET: u64 = 1_000_000;

/// A BV that stands where it starts: every control period it brakes as hard as it can, wheels
/// straight.
#[derive(Debug, Clone, Copy, Default)]
struct Parked;

impl BvController for Parked {
    fn name(&self) -> &str {
        "parked"
    }

    fn control(&mut self, obs: &v2t_sim::observation::BvObservation<'_>) -> v2t_sim::plant::ActuationRequest {
        let decel = obs.scenario.bvs.get(obs.bv_index).map_or(3.0, |b| b.agent.vehicle.limits.max_decel_mps2);
        v2t_sim::plant::ActuationRequest { accel_mps2: -decel, steer_rad: 0.0 }
    }
}

/// A BV parked as [`Parked`] whose regulator still runs on every observation, as on the track in a
/// free drive: uploaded the test's prior and never started, the regulator decides (and measures
/// the VUT) while the gateway does not actuate. What it measured of the VUT's route is its
/// [`RegulatedBv::lesson_report`].
struct ParkedRegulated(RegulatedBv);

impl BvController for ParkedRegulated {
    fn name(&self) -> &str {
        "parked"
    }

    fn control(&mut self, obs: &v2t_sim::observation::BvObservation<'_>) -> v2t_sim::plant::ActuationRequest {
        let _ = self.0.control(obs);
        Parked.control(obs)
    }
}

/// A free drive's run and what each BV measured in it.
#[derive(Debug)]
pub struct FreeDrive {
    /// The run.
    pub outcome: RunOutcome,
    /// Per BV, how the VUT drove its route up to that BV's zone as the BV's regulator measured it
    /// (its run's [`v2t_game::regulation::Lesson`] route: what the onboard node reports after a
    /// free drive on the track). `None`: the VUT never left that zone, or too little was seen.
    pub routes: Vec<Option<RouteSpeed>>,
}

/// A *free drive*: `scenario` run once with every BV parked where it starts (braking at its limit
/// from a standstill), the VUT driving its route on its own, as a test engineer drives the ADS
/// through the test alone before the test. Each BV's regulator (with `settings`) runs as on the
/// track, deciding without actuating, and what it measured of the VUT's route is what the free
/// drive shows ([`FreeDrive::routes`]): what the campaign memory would have learned from a first
/// run, without a first regulated run.
pub fn free_drive_run(
    settings: &RegulatorParams,
    scenario: &Scenario,
    vut: &Vut<'_>,
    seed: u64,
) -> Result<FreeDrive, RegulatedRunError> {
    let mut sc = scenario.clone();
    for bv in &mut sc.bvs {
        bv.agent.initial_speed_mps = 0.0;
    }
    let mut lessons = Vec::with_capacity(sc.bvs.len());
    let mut bvs: Vec<Box<dyn BvController>> = Vec::with_capacity(sc.bvs.len());
    for i in 0..sc.bvs.len() {
        let r = RegulatedBv::new(RegulatedBv::params_for(settings, &sc, i), &sc, i)?;
        lessons.push(r.lesson_report());
        bvs.push(Box::new(ParkedRegulated(r)));
    }
    let outcome = vut.run(&sc, &mut bvs, seed)?;
    drop(bvs);
    let routes = lessons.iter().map(|l| l.take().and_then(|lesson| lesson.route)).collect();
    Ok(FreeDrive { outcome, routes })
}

/// The free drives ([`free_drive_run`]) of one scenario against one VUT, one per seed of the runs
/// they prepare (each on its seed plus [`FREE_DRIVE_SEED_OFFSET`]): what a free drive shows does
/// not depend on the test's target, so one drive prepares that seed's run of every target. A drive
/// the world could not run is kept as `None`.
#[derive(Debug, Clone, Default)]
pub struct FreeDrives {
    drives: Vec<(u64, Option<Vec<Option<RouteSpeed>>>)>,
}

impl FreeDrives {
    /// Drives `scenario` freely once for every seed of `seeds`, the BVs' regulators with `settings`.
    pub fn drive(
        settings: &RegulatorParams,
        scenario: &Scenario,
        vut: &Vut<'_>,
        seeds: std::ops::RangeInclusive<u64>,
    ) -> Self {
        let drives = seeds
            .map(|seed| {
                let drive = free_drive_run(settings, scenario, vut, seed + FREE_DRIVE_SEED_OFFSET);
                (seed, drive.ok().map(|d| d.routes))
            })
            .collect();
        Self { drives }
    }

    /// What the free drive for the run of `seed` showed, per BV; `None` when it was not driven or
    /// failed.
    pub fn routes(&self, seed: u64) -> Option<&[Option<RouteSpeed>]> {
        self.drives.iter().find(|(s, _)| *s == seed).and_then(|(_, r)| r.as_deref())
    }
}

/// One run of a campaign: the aim and what is known from the memory, the run, the memory updated.
pub fn run_once(
    settings: &RegulatorParams,
    scenario: &Scenario,
    target: Target,
    vut: &Vut<'_>,
    campaign: u64,
    k: usize,
    memory: &mut CampaignMemory,
) -> CampaignRun {
    let mut sc = scenario.clone();
    sc.target = target;
    let seed = run_seed(campaign, k);
    let bv_lateral_limit_mps2 = sc.bvs.first().map_or(f64::INFINITY, |b| b.agent.vehicle.limits.max_lat_accel_mps2);
    let Ok(run) = regulated_run(settings, &sc, vut, seed, Some(memory)) else {
        return CampaignRun {
            campaign,
            run: k,
            seed,
            aim_s: memory.aim(&sc.name, 0, target).tau_s(),
            pet_s: None,
            order_ok: false,
            collision: false,
            zone_overlap: false,
            below_reach: None,
            failed: true,
            yield_kept: None,
            bv_lateral_mps2: None,
            bv_lateral_limit_mps2,
        };
    };
    record_run(memory, &sc, &run);
    let below_reach = run.below_reach.first().copied().flatten();
    let r = &run.outcome.result;
    CampaignRun {
        campaign,
        run: k,
        seed,
        aim_s: run.aims.first().map_or(target.tau_s(), |a| a.tau_s()),
        pet_s: r.pet_min_s,
        order_ok: r.conflicts.iter().all(|c| c.order_matches_style == Some(true)),
        collision: r.collision.is_some(),
        zone_overlap: r.zone_overlap,
        below_reach,
        failed: false,
        yield_kept: crate::reach::YieldRule::kept_in(&sc, 0, &run.outcome),
        bv_lateral_mps2: Some(crate::stats::peak_lateral_mps2(&run.outcome, 1)),
        bv_lateral_limit_mps2,
    }
}

/// What the memory keeps of one run for the BV `bv_id`: its own conflict's PET and order (the
/// run's `PET_min` and overall order when the run names no conflict of that BV).
pub fn bv_record(r: &RunResult, bv_id: Option<&str>, aim_s: f64) -> RunRecord {
    let own = r.conflicts.iter().find(|c| Some(c.bv_id.as_str()) == bv_id);
    RunRecord {
        aim_s,
        pet_s: own.map_or(r.pet_min_s, |c| c.pet.pet_s()),
        order_ok: own.map_or_else(
            || r.conflicts.iter().all(|c| c.order_matches_style == Some(true)),
            |c| c.order_matches_style == Some(true),
        ),
        collision: r.collision.is_some(),
        learned_route: false,
        reaction_prior: false,
    }
}

/// The statistics of run index `k` over `runs`.
fn index_stats(k: usize, tau: f64, bound: Option<f64>, runs: &[&CampaignRun]) -> RunIndexStats {
    let n = runs.len().max(1) as f64;
    let pets: Vec<f64> = runs.iter().filter_map(|r| r.pet_s).collect();
    let mean_pet_s = (!pets.is_empty()).then(|| pets.iter().sum::<f64>() / pets.len() as f64);
    RunIndexStats {
        run: k,
        mean_pet_s,
        mean_aim_s: runs.iter().map(|r| r.aim_s).sum::<f64>() / n,
        error_rel: mean_pet_s.map_or(1.0, |m| (m - tau).abs() / tau),
        error_vs_bound_rel: bound.zip(mean_pet_s).map(|(b, m)| (m - b).abs() / b),
        unmeasured: runs.len() - pets.len(),
        collisions: runs.iter().filter(|r| r.collision).count(),
        zone_overlaps: runs.iter().filter(|r| r.zone_overlap).count(),
        order_ok_frac: runs.iter().filter(|r| r.order_ok).count() as f64 / n,
        below_reach_frac: runs.iter().filter(|r| r.below_reach.is_some()).count() as f64 / n,
        yields_not_kept: runs.iter().filter(|r| r.yield_kept == Some(false)).count(),
    }
}

/// The reached PET nearest to τ in `style`'s order (`None`: none in that order).
pub fn nearest_reached(reach: &Reach, target: Target) -> Option<f64> {
    let tau = target.tau_s();
    reach.pets(target.style()).iter().copied().min_by(|a, b| (a - tau).abs().total_cmp(&(b - tau).abs()))
}

/// Runs every case (scenario × target × VUT) and every campaign, on the available cores. With
/// `reach_seed`, first runs the open-loop grid for every scenario and VUT on that seed.
pub fn campaigns(
    settings: &RegulatorParams,
    scenarios: &[Scenario],
    targets: &[Target],
    vuts: &[Vut<'_>],
    campaigns: std::ops::RangeInclusive<u64>,
    runs: usize,
    reach_seed: Option<u64>,
) -> (CampaignReport, Vec<(String, u64, CampaignMemory)>) {
    let mut reaches = Vec::new();
    if let Some(seed) = reach_seed {
        let pairs: Vec<(&Scenario, &Vut<'_>)> =
            scenarios.iter().flat_map(|sc| vuts.iter().map(move |v| (sc, v))).collect();
        reaches = crate::parallel_map(&pairs, |(sc, v)| reach(sc, v, seed));
    }
    // One job per (VUT, campaign, scenario, target): each carries its own memory of that VUT.
    let mut jobs = Vec::new();
    for v in vuts {
        for c in campaigns.clone() {
            for sc in scenarios {
                for &target in targets {
                    jobs.push((v, c, sc, target));
                }
            }
        }
    }
    let done = crate::parallel_map(&jobs, |(v, c, sc, target)| {
        let mut memory = CampaignMemory::new(v.name(), v.world().as_str());
        let runs = run_campaign(settings, sc, *target, v, *c, runs, &mut memory);
        (v.name(), *c, memory, sc.name.clone(), *target, v.world(), runs)
    });
    // Memories per VUT and campaign (every test of that campaign in one file).
    let mut memories: Vec<(String, u64, CampaignMemory)> = Vec::new();
    let mut cases: Vec<CampaignCase> = Vec::new();
    for (vut, c, memory, scenario, target, world, runs) in done {
        match memories.iter_mut().find(|(v, cc, _)| *v == vut && *cc == c) {
            Some((_, _, m)) => m.cases.extend(memory.cases),
            None => memories.push((vut.clone(), c, memory)),
        }
        let i = match cases.iter().position(|x| {
            x.scenario == scenario && x.vut == vut && x.style == target.style() && x.tau_s == target.tau_s()
        }) {
            Some(i) => i,
            None => {
                cases.push(CampaignCase {
                    scenario,
                    style: target.style(),
                    vut,
                    world,
                    tau_s: target.tau_s(),
                    reachable: None,
                    bound_s: None,
                    per_run: Vec::new(),
                    detected_below_reach: false,
                    runs: Vec::new(),
                });
                cases.len() - 1
            }
        };
        if let Some(case) = cases.get_mut(i) {
            case.runs.extend(runs);
        }
    }
    for case in &mut cases {
        let Ok(target) = Target::new(case.tau_s, case.style) else { continue };
        let reached = reaches.iter().find(|r| r.scenario == case.scenario && r.vut == case.vut);
        let per_run = |bound: Option<f64>| -> Vec<RunIndexStats> {
            (1..=runs)
                .map(|k| {
                    let at: Vec<&CampaignRun> = case.runs.iter().filter(|r| r.run == k).collect();
                    index_stats(k, case.tau_s, bound, &at)
                })
                .collect()
        };
        // Reachable: the grid reached τ, or the regulated runs themselves landed safely on it at
        // some run index (they are a BV too).
        let stats = per_run(None);
        let landed = stats.iter().any(|s| {
            s.error_rel <= 0.10
                && s.yields_not_kept == 0
                && s.collisions == 0
                && s.zone_overlaps == 0
                && s.unmeasured == 0
                && s.order_ok_frac >= 1.0
        });
        case.reachable = reached.map(|r| r.reachable(target) || landed);
        case.bound_s = match case.reachable {
            Some(false) => reached.and_then(|r| nearest_reached(r, target)),
            _ => None,
        };
        case.per_run = per_run(case.bound_s);
        let calibrated: Vec<&CampaignRun> = case.runs.iter().filter(|r| r.run >= CALIBRATED_FROM).collect();
        case.detected_below_reach = !calibrated.is_empty()
            && 2 * calibrated.iter().filter(|r| r.below_reach.is_some()).count() > calibrated.len();
        case.runs.sort_by_key(|r| (r.campaign, r.run));
    }
    cases.sort_by(|a, b| {
        (&a.vut, &a.scenario, a.style as u8, a.tau_s.to_bits()).cmp(&(
            &b.vut,
            &b.scenario,
            b.style as u8,
            b.tau_s.to_bits(),
        ))
    });
    let per_vut = summarize(&cases, runs);
    memories.sort_by(|a, b| (&a.0, a.1).cmp(&(&b.0, b.1)));
    let report =
        CampaignReport { runs_per_campaign: runs, campaigns: campaigns.collect(), cases, per_vut, reach: reaches };
    (report, memories)
}

fn mean(xs: &[f64]) -> f64 {
    if xs.is_empty() { 0.0 } else { xs.iter().sum::<f64>() / xs.len() as f64 }
}

fn max(xs: &[f64]) -> f64 {
    xs.iter().copied().fold(0.0, f64::max)
}

/// Per VUT, in the order of the cases.
fn summarize(cases: &[CampaignCase], runs: usize) -> Vec<VutSummary> {
    let mut vuts: Vec<&str> = cases.iter().map(|c| c.vut.as_str()).collect();
    vuts.dedup();
    vuts.iter()
        .map(|&vut| {
            let mine: Vec<&CampaignCase> = cases.iter().filter(|c| c.vut == vut).collect();
            let reachable: Vec<&&CampaignCase> = mine.iter().filter(|c| c.reachable != Some(false)).collect();
            let below: Vec<&&CampaignCase> = mine.iter().filter(|c| c.reachable == Some(false)).collect();
            let run1: Vec<f64> = reachable.iter().filter_map(|c| c.per_run.first()).map(|s| s.error_rel).collect();
            let cal = |c: &CampaignCase| -> Vec<f64> {
                c.per_run.iter().filter(|s| s.run >= CALIBRATED_FROM).map(|s| s.error_rel).collect()
            };
            let cal_all: Vec<f64> = reachable.iter().flat_map(|c| cal(c)).collect();
            let vs_bound: Vec<f64> = below
                .iter()
                .flat_map(|c| {
                    c.per_run.iter().filter(|s| s.run >= CALIBRATED_FROM).filter_map(|s| s.error_vs_bound_rel)
                })
                .collect();
            let all_runs: Vec<&CampaignRun> = mine.iter().flat_map(|c| c.runs.iter()).collect();
            VutSummary {
                vut: vut.to_owned(),
                reachable_cases: reachable.len(),
                run1: (mean(&run1), max(&run1)),
                calibrated: (mean(&cal_all), max(&cal_all)),
                calibrated_single: pooled_single_runs(&reachable),
                calibrated_within_10: reachable
                    .iter()
                    .filter(|c| runs >= CALIBRATED_FROM && max(&cal(c)) <= 0.10)
                    .count(),
                below_reach: (below.len(), below.iter().filter(|c| c.detected_below_reach).count()),
                false_below_reach: reachable.iter().filter(|c| c.detected_below_reach).count(),
                calibrated_vs_bound: (!vs_bound.is_empty()).then(|| mean(&vs_bound)),
                runs: (
                    all_runs.len(),
                    all_runs.iter().filter(|r| r.collision).count(),
                    all_runs.iter().filter(|r| !r.order_ok && r.pet_s.is_some()).count(),
                    all_runs.iter().filter(|r| r.pet_s.is_none()).count(),
                ),
                yields_not_kept: all_runs.iter().filter(|r| r.yield_kept == Some(false)).count(),
                bv_lateral: lateral_of(&all_runs),
            }
        })
        .collect()
}

/// The first BV's lateral acceleration over `runs`, each run against its own BV's limit.
fn lateral_of(runs: &[&CampaignRun]) -> crate::steer::BvLateral {
    let limit_mps2 = runs.iter().map(|r| r.bv_lateral_limit_mps2).fold(f64::INFINITY, f64::min);
    let mut lateral = crate::steer::BvLateral { limit_mps2, ..Default::default() };
    for r in runs {
        if let Some(peak) = r.bv_lateral_mps2 {
            lateral.add_against(peak, r.bv_lateral_limit_mps2);
        }
    }
    lateral
}

/// The calibrated runs of `cases` scored one by one, each against its case's τ, pooled.
fn pooled_single_runs(cases: &[&&CampaignCase]) -> crate::stats::SingleRuns {
    crate::stats::SingleRuns::pool(cases.iter().filter_map(|c| {
        let calibrated = || c.runs.iter().filter(|r| r.run >= CALIBRATED_FROM);
        Some((crate::stats::SingleRuns::of(calibrated().map(|r| r.pet_s), c.tau_s)?, calibrated().count()))
    }))
}

/// The cause as a table word.
fn cause(b: &BelowReach) -> &'static str {
    match b.cause {
        BelowReachCause::VutWaits => "VUT waits",
        BelowReachCause::Campaign => "campaign",
        BelowReachCause::OrderRefused => "order refused",
    }
}

/// Markdown: per VUT the summary, then per case run 1, run 2 and the calibrated runs.
pub fn markdown(r: &CampaignReport) -> String {
    let pct = |x: f64| format!("{:.1} %", 100.0 * x);
    let mut out = format!(
        "Campaigns of {} runs, campaigns (seeds) {}; run k of campaign c uses simulation seed 1000·c + k. Errors per VUT, never pooled; \"calibrated\" = runs {CALIBRATED_FROM}–{}.\n\n",
        r.runs_per_campaign,
        match (r.campaigns.first(), r.campaigns.last()) {
            (Some(a), Some(b)) => format!("{a}–{b}"),
            _ => "none".to_owned(),
        },
        r.runs_per_campaign
    );
    out.push_str("Errors \"of the mean\" are those of the mean PET over the campaigns at one run index (overshoot and undershoot of single runs cancel in them); \"single runs\" scores every calibrated run on its own.\n\n");
    out.push_str("| VUT | reachable cases | run 1 mean / max (of the mean) | calibrated mean / max (of the mean) | calibrated single runs: mean error / within 10 % | reachable within 10 % at every calibrated run | below reach: cases / reported | reachable reported below reach | below reach: calibrated error vs bound | runs | collisions | out of order | no PET | yields not kept | BV over its lateral limit: runs (largest, m/s²) |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
    for v in &r.per_vut {
        out.push_str(&format!(
            "| {} | {} | {} / {} | {} / {} | {} / {:.0} % | {} / {} | {} / {} | {} | {} | {} | {} | {} | {} | {} | {} ({:.2}; its limit {:.1}) |\n",
            v.vut,
            v.reachable_cases,
            pct(v.run1.0),
            pct(v.run1.1),
            pct(v.calibrated.0),
            pct(v.calibrated.1),
            pct(v.calibrated_single.mean_error_rel),
            100.0 * v.calibrated_single.within_10_frac,
            v.calibrated_within_10,
            v.reachable_cases,
            v.below_reach.0,
            v.below_reach.1,
            v.false_below_reach,
            v.calibrated_vs_bound.map_or_else(|| "—".to_owned(), pct),
            v.runs.0,
            v.runs.1,
            v.runs.2,
            v.runs.3,
            v.yields_not_kept,
            v.bv_lateral.over_limit_runs,
            v.bv_lateral.peak_mps2,
            v.bv_lateral.limit_mps2
        ));
    }
    out.push_str("\n| VUT | scenario | style | τ (s) | τ reachable | run 1 PET (error) | run 2 PET (error) | calibrated mean PET | calibrated mean / max error | mean aim, last run (s) | reported below reach (calibrated runs) |\n|---|---|---|---|---|---|---|---|---|---|---|\n");
    for c in &r.cases {
        let reach = match (c.reachable, c.bound_s) {
            (Some(true), _) => "yes".to_owned(),
            (Some(false), Some(b)) => format!("**below reach**: nearest reached {b:.2} s"),
            (Some(false), None) => "**below reach**: no BV passes in this order".to_owned(),
            (None, _) => "not measured".to_owned(),
        };
        let at = |k: usize| {
            c.per_run.get(k).map_or_else(
                || "—".to_owned(),
                |s| s.mean_pet_s.map_or_else(|| "no PET".to_owned(), |p| format!("{p:.2} ({})", pct(s.error_rel))),
            )
        };
        let cal: Vec<&RunIndexStats> = c.per_run.iter().filter(|s| s.run >= CALIBRATED_FROM).collect();
        let cal_pets: Vec<f64> = cal.iter().filter_map(|s| s.mean_pet_s).collect();
        let cal_err: Vec<f64> = cal.iter().map(|s| s.error_rel).collect();
        let reported = c.runs.iter().filter(|r| r.run >= CALIBRATED_FROM);
        let n = reported.clone().count();
        let flagged: Vec<&CampaignRun> = reported.filter(|r| r.below_reach.is_some()).collect();
        let why = flagged.first().and_then(|r| r.below_reach).map_or_else(String::new, |b| {
            format!(" ({}{})", cause(&b), b.pet_bound_s.map_or_else(String::new, |x| format!(", bound {x:.2} s")))
        });
        out.push_str(&format!(
            "| {} | {} | {} | {:.1} | {reach} | {} | {} | {} | {} / {} | {:.2} | {}/{n}{why} |\n",
            c.vut,
            c.scenario,
            c.style,
            c.tau_s,
            at(0),
            at(1),
            if cal_pets.is_empty() { "—".to_owned() } else { format!("{:.2}", mean(&cal_pets)) },
            if cal_err.is_empty() { "—".to_owned() } else { pct(mean(&cal_err)) },
            if cal_err.is_empty() { "—".to_owned() } else { pct(max(&cal_err)) },
            c.per_run.last().map_or(c.tau_s, |s| s.mean_aim_s),
            flagged.len()
        ));
    }
    out
}

/// The memory of one campaign as the file `video2track sim --campaign` reads.
pub fn memory_json(memory: &CampaignMemory) -> Result<String, serde_json::Error> {
    serde_json::to_string_pretty(memory)
}

/// Reads a memory file's text, checked ([`v2t_model::validate::Validate`]).
pub fn memory_from_json(text: &str) -> Result<CampaignMemory, String> {
    use v2t_model::validate::Validate as _;
    let m: CampaignMemory = serde_json::from_str(text).map_err(|e| e.to_string())?;
    m.validate().map_err(|e| e.to_string())?;
    Ok(m)
}

/// What a run's memory knows about one test (for a run's one-line report).
pub fn case_line(memory: &CaseMemory, target: Target) -> String {
    let aim = memory.aim(target).tau_s();
    let valid = memory.runs.iter().filter(|r| r.valid_pet().is_some()).count();
    let mut s = format!(
        "{} runs before ({valid} with a PET in order); next aim {aim:.2} s for τ {:.2} s",
        memory.runs.len(),
        target.tau_s()
    );
    if memory.dropped {
        s.push_str("; learned model dropped (it predicted worse than none)");
    } else if valid > 0 {
        s.push_str(&format!("; model PET ≈ {:.2} + {:.2}·aim", memory.offset_s, memory.gain));
    }
    if let Some(b) = memory.below_reach {
        s.push_str(&format!(
            "; τ below reach ({}{})",
            cause(&b),
            b.pet_bound_s.map_or_else(String::new, |x| format!(", PET bound {x:.2} s"))
        ));
    }
    if let Some(r) = &memory.route_speed {
        s.push_str(&format!("; the VUT's speed along its route learned over {} run(s), to {:.0} m", r.runs, r.end_m()));
        if let Some((at, v)) = r.slowest() {
            s.push_str(&format!(", slowest {v:.1} m/s at {at:.0} m"));
        }
    }
    if let Some(id) = memory.reaction.as_ref().and_then(ReactionPosterior::identified) {
        s.push_str(&format!("; the VUT {id}"));
    }
    s
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing)]

    use super::*;

    fn run(k: usize, pet: Option<f64>, below: bool) -> CampaignRun {
        CampaignRun {
            campaign: 6,
            run: k,
            seed: run_seed(6, k),
            aim_s: 2.0,
            pet_s: pet,
            order_ok: pet.is_some(),
            collision: false,
            zone_overlap: false,
            below_reach: below.then_some(BelowReach { cause: BelowReachCause::Campaign, pet_bound_s: Some(2.5) }),
            failed: false,
            yield_kept: None,
            bv_lateral_mps2: Some(3.0),
            bv_lateral_limit_mps2: 4.5,
        }
    }

    #[test]
    fn seeds_of_tuning_and_reported_campaigns_never_meet() {
        assert_eq!(run_seed(6, 1), 6001);
        let tuning: Vec<u64> = (1..=5).flat_map(|c| (1..=MAX_RUNS).map(move |k| run_seed(c, k))).collect();
        assert!((6..=20).all(|c| (1..=10).all(|k| !tuning.contains(&run_seed(c, k)))));
    }

    #[test]
    fn a_run_index_is_scored_over_the_campaigns_and_against_the_bound_when_below_reach() {
        let runs = [run(3, Some(2.4), true), run(3, Some(2.6), true), run(3, None, false)];
        let s = index_stats(3, 2.0, Some(2.5), &runs.iter().collect::<Vec<_>>());
        assert!((s.mean_pet_s.unwrap() - 2.5).abs() < 1e-12);
        assert!((s.error_rel - 0.25).abs() < 1e-12);
        assert!(s.error_vs_bound_rel.unwrap().abs() < 1e-12);
        assert_eq!(s.unmeasured, 1);
        assert!((s.below_reach_frac - 2.0 / 3.0).abs() < 1e-12);
        assert!((s.order_ok_frac - 2.0 / 3.0).abs() < 1e-12);
        let none = index_stats(1, 2.0, None, &[&run(1, None, false)]);
        assert_eq!((none.mean_pet_s, none.error_rel), (None, 1.0), "no PET counts as error 1");
    }

    #[test]
    fn the_bound_is_the_reached_pet_nearest_to_tau_in_the_asked_order() {
        let reach = Reach {
            scenario: "s".into(),
            vut: "v".into(),
            seed: 1,
            profiles: 3,
            rush_pets_s: vec![0.9, 2.05, 3.1],
            yield_pets_s: vec![],
            collisions: 0,
            unreadable_yields: 0,
            failed: 0,
        };
        assert_eq!(nearest_reached(&reach, Target::new(1.5, Style::Rush).unwrap()), Some(2.05));
        assert_eq!(nearest_reached(&reach, Target::new(1.5, Style::Yield).unwrap()), None);
    }

    #[test]
    fn the_bvs_lateral_acceleration_is_counted_over_every_run_against_its_own_limit() {
        let at = |peak: Option<f64>, limit: f64| CampaignRun {
            bv_lateral_mps2: peak,
            bv_lateral_limit_mps2: limit,
            ..run(3, Some(2.0), false)
        };
        let runs = [at(Some(3.0), 4.5), at(Some(4.6), 4.5), at(Some(4.0), 3.5), at(None, 3.0)];
        let l = lateral_of(&runs.iter().collect::<Vec<_>>());
        assert_eq!(l.over_limit_runs, 2, "4.6 over 4.5 and 4.0 over 3.5; a run that failed counts nothing");
        assert_eq!(l.peak_mps2, 4.6);
        assert_eq!(l.limit_mps2, 3.0, "the lowest limit of the runs");
        assert_eq!(lateral_of(&[]).over_limit_runs, 0);
    }
}
