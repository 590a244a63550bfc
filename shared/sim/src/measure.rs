//! Measuring a run from its truth log: PET and passages at every conflict, the passing order, the
//! smallest footprint distance, the first collision, the smallest TTC, zone overlaps. The runner
//! measures its own runs with it, and a recording (`video2track replay`) is measured again by the
//! same code on the same numbers, so the two agree exactly.

use serde::{Deserialize, Serialize};
use v2t_model::kinematics::State;
use v2t_model::metrics::{ConflictZone, Dimensions, Motion, MotionSnapshot, PetOutcome, Side, passage, pet, ttc_2d};
use v2t_model::validate::ValidationError;
use v2t_model::{Style, Target};

use crate::runner::{CollisionEvent, ConflictResult, FirstThrough, RunResult};

/// One vehicle's true motion at every plant step.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct AgentTruth {
    /// Its id (`vut` first, then the BVs).
    pub id: String,
    /// Footprint size.
    pub dims: Dimensions,
    /// Length of its route, m (it has completed the run within 0.5 m of the end).
    pub route_length_m: f64,
    /// True states.
    pub states: Vec<State>,
    /// Arc lengths along its route, m.
    pub s_m: Vec<f64>,
    /// Accelerations the plant delivered, m/s².
    pub accel_mps2: Vec<f64>,
}

/// A run's truth at the plant rate: what every metric is computed from.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct TruthLog {
    /// Time of every step, s.
    pub times: Vec<f64>,
    /// The VUT, then the BVs.
    pub agents: Vec<AgentTruth>,
}

/// One BV's conflict zone with the VUT: side `a` on the VUT's route, side `b` on the BV's.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ConflictSetup {
    /// Index of the BV among the BVs.
    pub bv_index: usize,
    /// The zone.
    pub zone: ConflictZone,
}

/// What a run is measured against, apart from its truth. A recording keeps it in the layout of
/// `MeasureSetupFile`: the target as the two keys `style` and `tau_s`, range-checked as it is
/// read.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "MeasureSetupFile", into = "MeasureSetupFile")]
pub struct MeasureSetup {
    /// Scenario name.
    pub scenario: String,
    /// VUT driver model.
    pub vut_model: String,
    /// BV controller.
    pub bv_controller: String,
    /// Random seed.
    pub seed: u64,
    /// Intended order and target PET τ.
    pub target: Target,
    /// One per BV.
    pub conflicts: Vec<ConflictSetup>,
    /// TTC is taken every this many steps (the record period).
    pub ttc_every: usize,
}

/// The serialized form of a [`MeasureSetup`]: its fields in the same order, the target written as
/// `style` and `tau_s` (s).
#[derive(Debug, Serialize, Deserialize)]
struct MeasureSetupFile {
    scenario: String,
    vut_model: String,
    bv_controller: String,
    seed: u64,
    style: Style,
    tau_s: f64,
    conflicts: Vec<ConflictSetup>,
    ttc_every: usize,
}

impl TryFrom<MeasureSetupFile> for MeasureSetup {
    type Error = ValidationError;

    fn try_from(f: MeasureSetupFile) -> Result<Self, Self::Error> {
        Ok(Self {
            scenario: f.scenario,
            vut_model: f.vut_model,
            bv_controller: f.bv_controller,
            seed: f.seed,
            target: Target::from_keys(f.tau_s, f.style)?,
            conflicts: f.conflicts,
            ttc_every: f.ttc_every,
        })
    }
}

impl From<MeasureSetup> for MeasureSetupFile {
    fn from(m: MeasureSetup) -> Self {
        Self {
            scenario: m.scenario,
            vut_model: m.vut_model,
            bv_controller: m.bv_controller,
            seed: m.seed,
            style: m.target.style(),
            tau_s: m.target.tau_s(),
            conflicts: m.conflicts,
            ttc_every: m.ttc_every,
        }
    }
}

/// Footprint distance below which two vehicles touch, m.
const TOUCH_M: f64 = 0.0;
/// TTC horizon, s.
const TTC_HORIZON_S: f64 = 10.0;

/// Measures `log` as [`Simulation`](crate::runner::Simulation) does at the end of a run.
pub fn measure(setup: &MeasureSetup, log: &TruthLog) -> RunResult {
    let times = &log.times;
    let t_end = times.last().copied().unwrap_or(0.0);
    let mut conflicts = Vec::with_capacity(setup.conflicts.len());
    for c in &setup.conflicts {
        let (Some(vut), Some(bv)) = (log.agents.first(), log.agents.get(c.bv_index + 1)) else { continue };
        let vut_passage = passage(times, &vut.s_m, &c.zone.vut);
        let bv_passage = passage(times, &bv.s_m, &c.zone.bv);
        let outcome = pet(vut_passage, bv_passage, t_end);
        let first = outcome.first().map(|s| match s {
            Side::A => FirstThrough::Vut,
            Side::B => FirstThrough::Bv,
        });
        let wanted = match setup.target.style() {
            Style::Rush => FirstThrough::Bv,
            Style::Yield => FirstThrough::Vut,
        };
        conflicts.push(ConflictResult {
            bv_id: bv.id.clone(),
            kind: c.zone.kind,
            pet: outcome,
            first,
            order_matches_style: first.map(|f| f == wanted),
            vut_passage,
            bv_passage,
        });
    }
    let (min_distance, collision) = distances(log);
    let pet_min_s = conflicts.iter().filter_map(|c| c.pet.pet_s()).reduce(f64::min);
    let zone_overlap = conflicts.iter().any(|c| matches!(c.pet, PetOutcome::Measured { overlap: true, .. }));
    let last = |a: &AgentTruth| a.s_m.last().copied().unwrap_or(0.0);
    let completed = !log.agents.is_empty() && log.agents.iter().all(|a| last(a) >= a.route_length_m - 0.5);
    RunResult {
        scenario: setup.scenario.clone(),
        vut_model: setup.vut_model.clone(),
        bv_controller: setup.bv_controller.clone(),
        seed: setup.seed,
        target: setup.target,
        duration_s: t_end,
        completed,
        conflicts,
        pet_min_s,
        min_distance_m: min_distance.0,
        min_distance_t_s: min_distance.1,
        min_ttc_s: min_ttc(log, setup.ttc_every),
        collision,
        zone_overlap,
    }
}

/// The smallest footprint distance over every pair and step (the first when tied) and the first
/// touching pair.
fn distances(log: &TruthLog) -> ((f64, f64), Option<CollisionEvent>) {
    let mut min = (f64::INFINITY, 0.0);
    let mut collision = None;
    for (k, t) in log.times.iter().enumerate() {
        let boxes: Vec<_> = log.agents.iter().filter_map(|a| a.states.get(k).map(|st| footprint(a.dims, st))).collect();
        for i in 0..boxes.len() {
            for j in i + 1..boxes.len() {
                let (Some(a), Some(b)) = (boxes.get(i), boxes.get(j)) else { continue };
                let d = a.distance(b);
                if d < min.0 {
                    min = (d, *t);
                }
                if d <= TOUCH_M && collision.is_none() {
                    let id = |x: usize| log.agents.get(x).map(|a| a.id.clone()).unwrap_or_default();
                    collision = Some(CollisionEvent { t_s: *t, agents: [id(i), id(j)] });
                }
            }
        }
    }
    (min, collision)
}

fn footprint(dims: Dimensions, st: &State) -> v2t_model::geometry::OrientedBox {
    v2t_model::geometry::OrientedBox {
        center: st.position(),
        heading_rad: st.theta_rad,
        length_m: dims.length_m,
        width_m: dims.width_m,
    }
}

/// The smallest constant-velocity TTC between the VUT and any BV, every `every` steps.
fn min_ttc(log: &TruthLog, every: usize) -> Option<f64> {
    let snapshot = |a: &AgentTruth, k: usize| -> Option<MotionSnapshot> {
        let st = a.states.get(k)?;
        Some(MotionSnapshot {
            position: st.position(),
            heading_rad: st.theta_rad,
            speed_mps: st.speed_mps,
            accel_mps2: *a.accel_mps2.get(k)?,
            dims: a.dims,
        })
    };
    let mut min: Option<f64> = None;
    let vut = log.agents.first()?;
    for k in (0..log.times.len()).step_by(every.max(1)) {
        for bv in log.agents.iter().skip(1) {
            if let (Some(v), Some(x)) = (snapshot(vut, k), snapshot(bv, k))
                && let Some(ttc) = ttc_2d(&v, &x, Motion::ConstantVelocity, TTC_HORIZON_S)
            {
                min = Some(min.map_or(ttc, |m| m.min(ttc)));
            }
        }
    }
    min
}
