//! Decision latency and allocations of the regulator (`v2t-bench game`).
//!
//! With the shipped regulator settings (`config/regulator/default.toml`, the realism weight
//! included, around a prior), for N = 30 and N = 50, and for N = 50 with a follower that knows
//! how the VUT drives its route (a learned route speed, [`v2t_game::route_speed`]: the VUT
//! slowing evenly from its speed to half of it over 300 m), and for N = 50 with a regulator sure
//! that the VUT reacts to the BV (the reacting follower's search in every decision before the
//! zone, [`v2t_game::reaction`]), on one thread:
//! - *sim*: every decision of the regulated BV in the simulated proving ground — both bundled
//!   cards, rush and yield, τ ∈ {1.5, 3, 5} s, every VUT model, one seed each;
//! - *approaches*: a left-turn approach in both styles replayed kinematically (the BV moving as its
//!   decisions say, the VUT at constant speed);
//! - *random*: 10,000 decisions on randomized states.
//!
//! Heap allocations are counted by the caller's global allocator (`allocations` reads its
//! counter): all of them come from inside Clarabel; the regulator's own code allocates nothing
//! per cycle.

use std::cell::RefCell;
use std::collections::BTreeMap;
use std::rc::Rc;
use std::time::Instant;

use v2t_files::parse_toml;
use v2t_game::fixtures as common;
use v2t_game::reaction::{Reaction, ReactionPosterior};
use v2t_game::reference::ReferenceSample;
use v2t_game::regulator::{PathState, Regulator, RegulatorInput, RegulatorParams};
use v2t_game::route_speed::RouteSpeed;
use v2t_model::vehicle::VehicleConfig;
use v2t_model::{Style, Target};
use v2t_sim::bv::BvController;
use v2t_sim::config::{ScenarioCard, SimSettings};
use v2t_sim::observation::BvObservation;
use v2t_sim::plant::ActuationRequest;
use v2t_sim::runner::run;
use v2t_sim::scenario::Scenario;
use v2t_sim::vut::VutModel;

use crate::controllers::RegulatedBv;

/// The figures for one horizon.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct BenchFigures {
    /// MPC horizon N.
    pub horizon: usize,
    /// Whether the follower had a learned route speed.
    pub learned_route: bool,
    /// Whether the regulator started sure that the VUT reacts to the BV (gap 2.5 s): the
    /// reacting follower's search runs in every decision before the zone.
    pub reacting_prior: bool,
    /// Decisions timed (approaches + random).
    pub decisions: u64,
    /// Decisions timed in the closed-loop simulations.
    pub sim_decisions: usize,
    /// Closed loop: median, µs.
    pub sim_p50_us: f64,
    /// Closed loop: 99th percentile, µs.
    pub sim_p99_us: f64,
    /// Closed loop: largest, µs.
    pub sim_max_us: f64,
    /// Approaches: median, µs.
    pub approach_p50_us: f64,
    /// Approaches: 99th percentile, µs.
    pub approach_p99_us: f64,
    /// Approaches + random: median, µs.
    pub p50_us: f64,
    /// Approaches + random: 99th percentile, µs.
    pub p99_us: f64,
    /// Approaches + random: largest, µs.
    pub max_us: f64,
    /// Heap allocations per decision (approaches + random).
    pub allocs_per_decision: f64,
    /// Decisions with a non-finite acceleration.
    pub non_finite: u64,
    /// How often each status occurred.
    pub statuses: BTreeMap<String, u64>,
}

/// A tiny deterministic generator (SplitMix64) for the randomized states.
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        (z ^ (z >> 31)) as f64 / u64::MAX as f64
    }
    fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.next()
    }
}

fn percentile(sorted: &[f64], p: f64) -> f64 {
    let i = ((sorted.len() as f64 - 1.0) * p).round() as usize;
    sorted.get(i).copied().unwrap_or(f64::NAN)
}

/// A regulated BV whose every decision is timed into a shared sink.
struct Timed {
    inner: RegulatedBv,
    sink: Rc<RefCell<Vec<f64>>>,
}

impl BvController for Timed {
    fn name(&self) -> &str {
        "timed regulator"
    }
    fn control(&mut self, obs: &BvObservation<'_>) -> ActuationRequest {
        let t0 = Instant::now();
        let r = self.inner.control(obs);
        self.sink.borrow_mut().push(t0.elapsed().as_secs_f64() * 1e6);
        r
    }
}

fn scenario(card: &str, vut: &str, bv: &str, sim: &str) -> Result<Scenario, Box<dyn std::error::Error>> {
    let parse = || -> Result<Scenario, Box<dyn std::error::Error>> {
        let card: ScenarioCard = parse_toml(card, "card")?;
        let vut: VehicleConfig = parse_toml(vut, "vut")?;
        let bv: VehicleConfig = parse_toml(bv, "bv")?;
        let sim: SimSettings = parse_toml(sim, "sim")?;
        Ok(Scenario::from_card(&card, sim, vut, vec![bv])?)
    };
    parse()
}

/// Latencies of every regulator decision in closed-loop simulations, µs.
/// A learned route speed for the bench: from `v_mps` evenly down to half of it over 300 m.
fn learned_route(v_mps: f64) -> RouteSpeed {
    RouteSpeed { step_m: 2.0, speeds_mps: (0..=150).map(|i| v_mps * (1.0 - f64::from(i) / 300.0)).collect(), runs: 1 }
}

/// A posterior sure (p 0.9) that the VUT accepts gaps of 2.5 s, brakes at 2 m/s² and restarts
/// after 1 s: the bench's reacting VUT.
fn reacting_prior() -> Option<ReactionPosterior> {
    ReactionPosterior::sure_of(Some(Reaction { gap_s: 2.5, decel_mps2: 2.0, restart_s: 1.0 }), 0.9, 100)
}

fn sim_latencies(
    settings: RegulatorParams,
    learned: bool,
    reacting: bool,
) -> Result<Vec<f64>, Box<dyn std::error::Error>> {
    let prior = reacting.then(reacting_prior).flatten();
    let vut = include_str!("../../../config/vehicles/vut_sedan.toml");
    let bv = include_str!("../../../config/vehicles/bv_sedan.toml");
    let sim = include_str!("../../../config/sim/default.toml");
    let scenarios = [
        scenario(include_str!("../../../config/scenarios/left_turn_basic.toml"), vut, bv, sim)?,
        scenario(include_str!("../../../config/scenarios/cut_in_basic.toml"), vut, bv, sim)?,
    ];
    let sink = Rc::new(RefCell::new(Vec::new()));
    for base in &scenarios {
        for target in crate::steer::both_styles(&[1.5, 3.0, 5.0]) {
            for model in VutModel::ALL {
                let mut sc = base.clone();
                sc.target = target;
                let campaign = v2t_edge::campaign::Learned {
                    route: learned.then(|| learned_route(sc.vut.agent.initial_speed_mps)),
                    reaction: prior.clone(),
                    known: None,
                };
                let Ok(inner) = RegulatedBv::new(RegulatedBv::params_for(&settings, &sc, 0), &sc, 0)
                    .and_then(|r| r.with_campaign(&campaign.upload(crate::world::CARD_PRIOR_ID, target)))
                else {
                    continue;
                };
                let mut bvs: Vec<Box<dyn BvController>> = vec![Box::new(Timed { inner, sink: Rc::clone(&sink) })];
                let _ = run(&sc, &mut bvs, model.driver().as_mut(), 1);
            }
        }
    }
    Ok(sink.take())
}

/// Runs the benchmark; `allocations` reads the global allocator's running count of allocations.
pub fn run_bench(allocations: fn() -> u64) -> Result<Vec<BenchFigures>, Box<dyn std::error::Error>> {
    let mut report = Vec::new();
    // The shipped settings (the realism weight included), at each horizon.
    let shipped: RegulatorParams = parse_toml(include_str!("../../../config/regulator/default.toml"), "regulator")?;
    for (horizon, learned, reacting) in
        [(30usize, false, false), (50, false, false), (50, true, false), (50, false, true)]
    {
        let params = RegulatorParams { horizon, ..shipped };
        let mut reg = Regulator::new(params)?;
        reg.set_route_speed(learned.then(|| learned_route(8.0)))?;
        reg.set_reaction_prior(reacting.then(reacting_prior).flatten().as_ref())?;
        // The left turn's prior for the realism term: the BV at its start speed, easing off before
        // the zone and back (set once, as a BV does when a prior arrives).
        reg.set_reference((0..400).map(|k| {
            let t = k as f64 * 0.1;
            let v = if (2.0..4.0).contains(&t) { 8.0 } else { 10.0 };
            let s = 10.0 * t - 2.0 * (t.clamp(2.0, 4.0) - 2.0);
            ReferenceSample { t_s: t, s_m: s, v_mps: v }
        }))?;
        let mut lat_us = Vec::new();
        let mut approach_us: Vec<f64> = Vec::new();
        let mut statuses: BTreeMap<String, u64> = BTreeMap::new();
        let (mut allocs, mut counted, mut non_finite) = (0u64, 0u64, 0u64);
        let mut random_us: Vec<f64> = Vec::new();
        let mut decide = |reg: &mut Regulator, inp: &RegulatorInput, warm: bool, sink: &mut Vec<f64>| {
            let a0 = allocations();
            let t0 = Instant::now();
            let d = reg.decide(inp);
            let dt = t0.elapsed().as_secs_f64() * 1e6;
            let a1 = allocations();
            if warm {
                sink.push(dt);
                allocs += a1 - a0;
                counted += 1;
                *statuses.entry(format!("{:?}", d.status)).or_default() += 1;
                if !d.accel_mps2.is_finite() {
                    non_finite += 1;
                }
            }
            d
        };
        // Closed-loop-like approaches.
        for target in crate::steer::both_styles(&crate::steer::STEER_TAUS_S) {
            reg.reset();
            let mut inp = common::left_turn_start(target);
            for k in 0..200 {
                let d = decide(&mut reg, &inp, k >= 5, &mut approach_us);
                inp.t_s += 0.1;
                let v = (inp.bv.v_mps + d.accel_mps2 * 0.1).max(0.0);
                inp.bv.s_m += 0.5 * (inp.bv.v_mps + v) * 0.1;
                inp.bv.v_mps = v;
                inp.bv_accel_mps2 = d.accel_mps2;
                inp.vut.s_m += inp.vut.v_mps * 0.1;
            }
        }
        // Randomized states.
        let mut rng = Rng(horizon as u64);
        for _ in 0..10_000 {
            let style = if rng.next() < 0.5 { Style::Rush } else { Style::Yield };
            let Ok(target) = Target::new(rng.range(0.5, 6.0), style) else { continue };
            let mut inp = common::left_turn_start(target);
            inp.t_s = rng.range(0.0, 30.0);
            inp.bv = PathState { s_m: rng.range(-20.0, 80.0), v_mps: rng.range(0.0, 20.0), age_s: rng.range(0.0, 0.6) };
            inp.vut =
                PathState { s_m: rng.range(-40.0, 120.0), v_mps: rng.range(0.0, 20.0), age_s: rng.range(0.0, 0.6) };
            inp.bv_accel_mps2 = rng.range(-6.0, 3.0);
            reg.reset();
            decide(&mut reg, &inp, true, &mut random_us);
        }
        let mut sim_us = sim_latencies(params, learned, reacting)?;
        sim_us.sort_by(f64::total_cmp);
        lat_us.extend_from_slice(&approach_us);
        lat_us.extend_from_slice(&random_us);
        lat_us.sort_by(f64::total_cmp);
        approach_us.sort_by(f64::total_cmp);
        report.push(BenchFigures {
            horizon,
            learned_route: learned,
            reacting_prior: reacting,
            decisions: counted,
            sim_decisions: sim_us.len(),
            sim_p50_us: percentile(&sim_us, 0.5),
            sim_p99_us: percentile(&sim_us, 0.99),
            sim_max_us: sim_us.last().copied().unwrap_or(f64::NAN),
            approach_p50_us: percentile(&approach_us, 0.5),
            approach_p99_us: percentile(&approach_us, 0.99),
            p50_us: percentile(&lat_us, 0.5),
            p99_us: percentile(&lat_us, 0.99),
            max_us: lat_us.last().copied().unwrap_or(f64::NAN),
            allocs_per_decision: allocs as f64 / counted.max(1) as f64,
            non_finite,
            statuses,
        });
    }
    Ok(report)
}

/// The figures as a markdown table, with the statuses seen per horizon.
pub fn table(figures: &[BenchFigures]) -> String {
    let mut out = String::from(
        "| N | closed-loop decisions | p50 | p99 | max | approaches+random p50 | p99 | max | allocations/decision | non-finite |\n|---|---|---|---|---|---|---|---|---|---|\n",
    );
    for f in figures {
        out.push_str(&format!(
            "| {}{} | {} | {:.0} µs | {:.0} µs | {:.0} µs | {:.0} µs | {:.0} µs | {:.0} µs | {:.2} | {} |\n",
            f.horizon,
            variant(f),
            f.sim_decisions,
            f.sim_p50_us,
            f.sim_p99_us,
            f.sim_max_us,
            f.p50_us,
            f.p99_us,
            f.max_us,
            f.allocs_per_decision,
            f.non_finite
        ));
    }
    for f in figures {
        out.push_str(&format!("statuses (N = {}{}): {:?}\n", f.horizon, variant(f), f.statuses));
    }
    out
}

/// What a row's follower knew besides the shipped settings.
fn variant(f: &BenchFigures) -> &'static str {
    match (f.learned_route, f.reacting_prior) {
        (true, true) => ", learned route, reacting VUT",
        (true, false) => ", learned route",
        (false, true) => ", reacting VUT",
        (false, false) => "",
    }
}
