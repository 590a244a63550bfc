//! The scenario runner: fixed-step closed loop of plants, localization, BV controllers and the VUT
//! driver; records the trace and measures the interaction.
//!
//! Agent 0 is the VUT, agents `1..` are the BVs in scenario order. Plants integrate at
//! `settings.plant_dt_s`; controllers run every `settings.control_period_s` on what their
//! localization and links deliver; PET and passages are measured on the true states at the plant
//! rate.

use serde::{Deserialize, Serialize};
use v2t_model::geometry::OrientedBox;
use v2t_model::kinematics::State;
use v2t_model::metrics::{ConflictKind, Passage, PetOutcome, predicted_pet_series};
use v2t_model::path::ReferencePath;
use v2t_model::{Style, Target, validate::ValidationError};

use crate::bv::BvController;
use crate::external::{ExternalVut, ExternalVutError, Segment};
use crate::measure::{AgentTruth, ConflictSetup, MeasureSetup, TruthLog, measure};
use crate::observation::{BvObservation, Perceived, VutObservation};
use crate::plant::{ActuationRequest, Plant};
use crate::scenario::{Agent, Scenario};
use crate::sensing::Localization;
use crate::vut::VutDriver;

/// Who went through a conflict zone first.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FirstThrough {
    /// The background vehicle.
    Bv,
    /// The vehicle under test.
    Vut,
}

/// The outcome at one BV's conflict zone.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ConflictResult {
    /// The BV.
    pub bv_id: String,
    /// Crossing or merge.
    pub kind: ConflictKind,
    /// PET at the zone.
    pub pet: PetOutcome,
    /// Who went through first, if anyone did.
    pub first: Option<FirstThrough>,
    /// Whether the order is the one the style asks for (rush: BV first; yield: VUT first).
    pub order_matches_style: Option<bool>,
    /// When the VUT was in the zone.
    pub vut_passage: Option<Passage>,
    /// When the BV was in the zone.
    pub bv_passage: Option<Passage>,
}

/// The first footprint overlap of a run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CollisionEvent {
    /// Time, s.
    pub t_s: f64,
    /// The two vehicles.
    pub agents: [String; 2],
}

/// What a run measured. Its file is `RunResultFile`'s layout: the target as the two keys `style`
/// and `tau_s`, range-checked as the file is read.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "RunResultFile", into = "RunResultFile")]
pub struct RunResult {
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
    /// Simulated time, s.
    pub duration_s: f64,
    /// Whether every vehicle reached the end of its route.
    pub completed: bool,
    /// One entry per conflict.
    pub conflicts: Vec<ConflictResult>,
    /// Smallest measured PET over the conflicts, s.
    pub pet_min_s: Option<f64>,
    /// Smallest footprint distance between any two vehicles, m (infinite with fewer than two).
    pub min_distance_m: f64,
    /// When it occurred, s.
    pub min_distance_t_s: f64,
    /// Smallest constant-velocity TTC between the VUT and a BV over the recorded samples, s.
    pub min_ttc_s: Option<f64>,
    /// First collision, if any.
    pub collision: Option<CollisionEvent>,
    /// Whether two vehicles were ever in one conflict zone at the same time.
    pub zone_overlap: bool,
}

/// The file form of a [`RunResult`]: its fields in the same order, the target written as `style`
/// and `tau_s` (s). Keys it does not know are ignored, as in the rest of a run file.
#[derive(Debug, Serialize, Deserialize)]
struct RunResultFile {
    scenario: String,
    vut_model: String,
    bv_controller: String,
    seed: u64,
    style: Style,
    tau_s: f64,
    duration_s: f64,
    completed: bool,
    conflicts: Vec<ConflictResult>,
    pet_min_s: Option<f64>,
    #[serde(deserialize_with = "crate::runfile::infinite_if_null")]
    min_distance_m: f64,
    min_distance_t_s: f64,
    min_ttc_s: Option<f64>,
    collision: Option<CollisionEvent>,
    zone_overlap: bool,
}

impl TryFrom<RunResultFile> for RunResult {
    type Error = ValidationError;

    fn try_from(f: RunResultFile) -> Result<Self, Self::Error> {
        Ok(Self {
            scenario: f.scenario,
            vut_model: f.vut_model,
            bv_controller: f.bv_controller,
            seed: f.seed,
            target: Target::from_keys(f.tau_s, f.style)?,
            duration_s: f.duration_s,
            completed: f.completed,
            conflicts: f.conflicts,
            pet_min_s: f.pet_min_s,
            min_distance_m: f.min_distance_m,
            min_distance_t_s: f.min_distance_t_s,
            min_ttc_s: f.min_ttc_s,
            collision: f.collision,
            zone_overlap: f.zone_overlap,
        })
    }
}

impl From<RunResult> for RunResultFile {
    fn from(r: RunResult) -> Self {
        Self {
            scenario: r.scenario,
            vut_model: r.vut_model,
            bv_controller: r.bv_controller,
            seed: r.seed,
            style: r.target.style(),
            tau_s: r.target.tau_s(),
            duration_s: r.duration_s,
            completed: r.completed,
            conflicts: r.conflicts,
            pet_min_s: r.pet_min_s,
            min_distance_m: r.min_distance_m,
            min_distance_t_s: r.min_distance_t_s,
            min_ttc_s: r.min_ttc_s,
            collision: r.collision,
            zone_overlap: r.zone_overlap,
        }
    }
}

/// One vehicle at one recorded instant.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct AgentSample {
    /// True state.
    pub state: State,
    /// Arc length along its route, m.
    pub s_m: f64,
    /// Lateral offset from its route, m.
    pub l_m: f64,
    /// Acceleration delivered, m/s².
    pub accel_mps2: f64,
    /// Road-wheel angle, rad.
    pub steer_rad: f64,
    /// Last request of its controller.
    pub request: ActuationRequest,
}

/// One recorded instant.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TraceSample {
    /// Time, s.
    pub t_s: f64,
    /// VUT first, then the BVs.
    pub agents: Vec<AgentSample>,
    /// Predicted PET per conflict from the true states at this instant (constant velocity), s.
    pub predicted_pet_s: Vec<Option<f64>>,
}

/// What a drawing of a run needs besides its trace.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RunLayout {
    /// Footprint of every vehicle, in trace order (VUT first), m.
    pub dims: Vec<v2t_model::metrics::Dimensions>,
    /// Every BV's conflict zone with the VUT: the stretch of each vehicle's own path (arc length of
    /// its reference point, the trace's `s_m`) along which its footprint is in the zone.
    pub zones: Vec<ConflictSetup>,
    /// Every vehicle's route, in trace order, as `[x, y]` every [`ROUTE_STEP_M`] of arc length
    /// (point `k` at `s = k · ROUTE_STEP_M`, the last at the route's end), m.
    pub routes: Vec<Vec<[f64; 2]>>,
}

/// Spacing of the route points of a [`RunLayout`], m.
pub const ROUTE_STEP_M: f64 = 1.0;

/// Longest route a [`RunLayout`] keeps, points (longer routes are cut, so a report stays small).
const MAX_ROUTE_POINTS: usize = 20_000;

/// `route` every [`ROUTE_STEP_M`].
fn route_points(route: &ReferencePath) -> Vec<[f64; 2]> {
    let len = route.length();
    let n = ((len / ROUTE_STEP_M).floor() as usize).min(MAX_ROUTE_POINTS);
    let mut out: Vec<[f64; 2]> = (0..=n).map(|k| route.point_at(k as f64 * ROUTE_STEP_M)).map(|p| [p.x, p.y]).collect();
    if n < MAX_ROUTE_POINTS && len - n as f64 * ROUTE_STEP_M > 1e-6 {
        let p = route.point_at(len);
        out.push([p.x, p.y]);
    }
    out
}

/// A finished run. Its file is a [`crate::runfile::RunFile`].
#[derive(Debug, Clone, PartialEq)]
pub struct RunOutcome {
    /// The measurements.
    pub result: RunResult,
    /// Agent ids in trace order.
    pub agent_ids: Vec<String>,
    /// The recorded trace.
    pub trace: Vec<TraceSample>,
    /// The vehicles' footprints and the conflict zones, for drawings of the run (a report).
    pub layout: RunLayout,
    /// What the measurements are taken against (not in the run file: a recording keeps it).
    pub setup: MeasureSetup,
    /// The truth at the plant rate (not in the run file: a recording keeps it).
    pub truth: TruthLog,
}

/// Why a run could not start.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum RunError {
    /// One controller per BV is needed.
    #[error("{bvs} BVs in the scenario but {controllers} BV controllers given")]
    ControllerCount {
        /// BVs in the scenario.
        bvs: usize,
        /// Controllers given.
        controllers: usize,
    },
    /// The simulator that drives the VUT failed.
    #[error(transparent)]
    External(#[from] ExternalVutError),
}

/// Tracks a vehicle's arc length along its route between steps.
fn track(route: &ReferencePath, p: v2t_model::geometry::Point2, s_hint: f64, speed: f64, dt: f64) -> (f64, f64) {
    let window = 5.0 + 2.0 * speed * dt;
    route.project_near(p, s_hint, window).map_or((s_hint, 0.0), |f| (f.s_m, f.l_m))
}

fn start_state(agent: &Agent) -> State {
    let p = agent.route.point_at(0.0);
    State { px: p.x, py: p.y, theta_rad: agent.route.heading_at(0.0), speed_mps: agent.initial_speed_mps }
}

/// Runs `scenario` with one controller per BV and the VUT `driver`, deterministic for a `seed`.
pub fn run(
    scenario: &Scenario,
    bv_controllers: &mut [Box<dyn BvController>],
    driver: &mut dyn VutDriver,
    seed: u64,
) -> Result<RunOutcome, RunError> {
    run_with(scenario, bv_controllers, VutSide::Driver(driver), seed)
}

/// Runs `scenario` with one controller per BV and the VUT driven by another simulator (see
/// [`crate::external`]), deterministic for a `seed` when that simulator is.
pub fn run_external(
    scenario: &Scenario,
    bv_controllers: &mut [Box<dyn BvController>],
    vut: &mut dyn ExternalVut,
    seed: u64,
) -> Result<RunOutcome, RunError> {
    run_with(scenario, bv_controllers, VutSide::External(vut), seed)
}

fn run_with(
    scenario: &Scenario,
    bv_controllers: &mut [Box<dyn BvController>],
    mut vut: VutSide<'_>,
    seed: u64,
) -> Result<RunOutcome, RunError> {
    if bv_controllers.len() != scenario.bvs.len() {
        return Err(RunError::ControllerCount { bvs: scenario.bvs.len(), controllers: bv_controllers.len() });
    }
    let bv_name = bv_controllers.iter().map(|c| c.name()).collect::<Vec<_>>().join("+");
    let mut sim = Simulation::new(scenario, seed);
    while !sim.is_done() {
        sim.step_with(vut.reborrow(), &mut |b, obs| bv_controllers.get_mut(b).map(|c| c.control(obs)))?;
    }
    let name = match &vut {
        VutSide::Driver(d) => d.name(),
        VutSide::External(e) => e.name(),
    };
    Ok(sim.finish(name, &bv_name))
}

/// Who moves the VUT in a step.
enum VutSide<'a> {
    /// One of the builtin driver models, through the VUT's plant.
    Driver(&'a mut dyn VutDriver),
    /// Another simulator; the VUT's plant only carries its state.
    External(&'a mut dyn ExternalVut),
}

impl VutSide<'_> {
    fn reborrow(&mut self) -> VutSide<'_> {
        match self {
            Self::Driver(d) => VutSide::Driver(&mut **d),
            Self::External(e) => VutSide::External(&mut **e),
        }
    }
}

/// The closed loop one plant step at a time, for callers that drive a BV from outside (the
/// simulated drive-by-wire ECU of the onboard runtime feeds it the requests that arrive over CAN).
#[derive(Debug)]
pub struct Simulation<'s> {
    scenario: &'s Scenario,
    agents: Vec<&'s Agent>,
    plants: Vec<Plant>,
    locs: Vec<Localization>,
    s_true: Vec<f64>,
    l_true: Vec<f64>,
    s_perceived: Vec<f64>,
    requests: Vec<ActuationRequest>,
    truth: TruthLog,
    trace: Vec<TraceSample>,
    collision: Option<CollisionEvent>,
    n_steps: usize,
    control_every: usize,
    record_every: usize,
    completed: bool,
    perceived_bvs: Vec<Perceived>,
    /// Until every BV has been perceived once, the VUT driver is not asked (its actuators hold).
    bv_seen: Vec<bool>,
    vut_at_bv: Option<Perceived>,
    /// The VUT between two answers of an external simulator.
    external: Option<Segment>,
    k: usize,
    done: bool,
    seed: u64,
}

impl<'s> Simulation<'s> {
    /// The scenario at its start, deterministic for `seed`.
    pub fn new(scenario: &'s Scenario, seed: u64) -> Self {
        let settings = &scenario.settings;
        let agents: Vec<&Agent> =
            std::iter::once(&scenario.vut.agent).chain(scenario.bvs.iter().map(|b| &b.agent)).collect();
        let max_extra = settings.v2x_delay_s.max(settings.perception_delay_s);
        let plants = agents.iter().map(|a| Plant::new(a.vehicle.clone(), start_state(a))).collect();
        let locs = agents
            .iter()
            .enumerate()
            .map(|(i, a)| Localization::new(a.vehicle.localization, settings.noise_enabled, seed, i as u64, max_extra))
            .collect();
        let n = agents.len();
        let nb = scenario.bvs.len();
        let truth_agents = agents
            .iter()
            .map(|a| AgentTruth {
                id: a.id.clone(),
                dims: a.dims(),
                route_length_m: a.route.length(),
                states: Vec::new(),
                s_m: Vec::new(),
                accel_mps2: Vec::new(),
            })
            .collect();
        Self {
            scenario,
            agents,
            plants,
            locs,
            s_true: vec![0.0; n],
            l_true: vec![0.0; n],
            s_perceived: vec![0.0; n],
            requests: vec![ActuationRequest::default(); n],
            truth: TruthLog { times: Vec::new(), agents: truth_agents },
            trace: Vec::new(),
            collision: None,
            n_steps: (scenario.duration_s / settings.plant_dt_s).ceil() as usize,
            control_every: settings.control_every(),
            record_every: settings.record_every(),
            completed: false,
            perceived_bvs: vec![Perceived { state: State::default(), s_m: 0.0, l_m: 0.0, age_s: 0.0 }; nb],
            bv_seen: vec![false; nb],
            vut_at_bv: None,
            external: None,
            k: 0,
            done: false,
            seed,
        }
    }

    /// Simulated time of the next step, s.
    pub fn t_s(&self) -> f64 {
        self.k as f64 * self.scenario.settings.plant_dt_s
    }

    /// The run has ended (collision, every vehicle at its route's end, or the scenario's duration).
    pub fn is_done(&self) -> bool {
        self.done
    }

    /// True state of BV `b`.
    pub fn bv_truth(&self, b: usize) -> Option<State> {
        self.plants.get(b + 1).map(Plant::state)
    }

    /// Actuator state of BV `b`: (acceleration, road-wheel angle) as realised by the plant.
    pub fn bv_actuators(&self, b: usize) -> Option<(f64, f64)> {
        self.plants.get(b + 1).map(|p| (p.accel_mps2(), p.steer_rad()))
    }

    /// Sends a request to BV `b`'s actuators now (it takes effect after the actuator delay).
    pub fn set_bv_request(&mut self, b: usize, req: ActuationRequest) {
        let t = self.t_s();
        if let (Some(plant), Some(slot)) = (self.plants.get_mut(b + 1), self.requests.get_mut(b + 1)) {
            *slot = req;
            plant.request(t, req);
        }
    }

    /// Publishes a localization fix of BV `b` now and returns it with its age, s (as the BV's own
    /// GNSS/INS delivers it: noise and delay from its vehicle file).
    pub fn publish_bv_localization(&mut self, b: usize) -> Option<(State, f64)> {
        let t = self.t_s();
        let loc = self.locs.get_mut(b + 1)?;
        loc.publish(t);
        loc.seen_at(t, 0.0)
    }

    /// The VUT as the BVs last received it over V2X (refreshed every control period), with its age.
    pub fn vut_seen_by_bvs(&self) -> Option<(State, f64)> {
        self.vut_at_bv.map(|p| (p.state, p.age_s))
    }

    /// One plant step: record the truth; every control period ask the VUT driver and, for each BV
    /// `b`, `bv_control(b, observation)` (`None`: the BV is driven from outside, its request
    /// holds); every record period add a trace sample; then advance the plants.
    pub fn step(
        &mut self,
        driver: &mut dyn VutDriver,
        bv_control: &mut dyn FnMut(usize, &BvObservation<'_>) -> Option<ActuationRequest>,
    ) {
        // A builtin driver cannot fail.
        let _ = self.step_with(VutSide::Driver(driver), bv_control);
    }

    /// One plant step with the VUT driven by another simulator (asked once per control period,
    /// after the BV controllers; see [`crate::external`]). Its error ends the run.
    pub fn step_external(
        &mut self,
        vut: &mut dyn ExternalVut,
        bv_control: &mut dyn FnMut(usize, &BvObservation<'_>) -> Option<ActuationRequest>,
    ) -> Result<(), ExternalVutError> {
        self.step_with(VutSide::External(vut), bv_control)
    }

    fn step_with(
        &mut self,
        mut vut: VutSide<'_>,
        bv_control: &mut dyn FnMut(usize, &BvObservation<'_>) -> Option<ActuationRequest>,
    ) -> Result<(), ExternalVutError> {
        if self.done {
            return Ok(());
        }
        let t = self.t_s();
        let dt = self.scenario.settings.plant_dt_s;
        self.record_truth(t, dt);
        if self.k.is_multiple_of(self.control_every)
            && let Err(e) = self.control(t, &mut vut, bv_control)
        {
            self.done = true;
            return Err(e);
        }
        if self.k.is_multiple_of(self.record_every) {
            self.record(t);
        }
        self.completed = self.agents.iter().zip(&self.s_true).all(|(a, s)| *s >= a.route.length() - 0.5);
        if self.collision.is_some() || self.completed || self.k >= self.n_steps {
            self.done = true;
            return Ok(());
        }
        for (i, plant) in self.plants.iter_mut().enumerate() {
            match (i, &vut, self.external) {
                (0, VutSide::External(_), Some(seg)) => {
                    let geo = &plant.config().geometry;
                    let (state, accel, steer) = seg.at(t + dt, geo.wheelbase_m, plant.config().limits.max_steer_rad);
                    plant.set_external(state, accel, steer);
                }
                _ => plant.step(t, dt),
            }
        }
        self.k += 1;
        Ok(())
    }

    fn record_truth(&mut self, t: f64, dt: f64) {
        let n = self.agents.len();
        let mut boxes: Vec<OrientedBox> = Vec::with_capacity(n);
        for i in 0..n {
            let (Some(plant), Some(agent), Some(loc)) = (self.plants.get(i), self.agents.get(i), self.locs.get_mut(i))
            else {
                continue;
            };
            let st = plant.state();
            let hint = self.s_true.get(i).copied().unwrap_or(0.0);
            let (s, l) = track(&agent.route, st.position(), hint, st.speed_mps, dt);
            if let (Some(sv), Some(lv), Some(truth)) =
                (self.s_true.get_mut(i), self.l_true.get_mut(i), self.truth.agents.get_mut(i))
            {
                *sv = s;
                *lv = l;
                truth.states.push(st);
                truth.s_m.push(s);
                truth.accel_mps2.push(plant.accel_mps2());
            }
            loc.record_truth(t, st);
            boxes.push(agent.vehicle.footprint(&st));
        }
        self.truth.times.push(t);
        // A touch ends the run; the measurements come from the truth log at the end.
        if self.collision.is_none() {
            for i in 0..n {
                for j in i + 1..n {
                    let (Some(a), Some(b)) = (boxes.get(i), boxes.get(j)) else { continue };
                    if a.distance(b) <= 0.0 && self.collision.is_none() {
                        let id = |x: usize| self.agents.get(x).map(|a| a.id.clone()).unwrap_or_default();
                        self.collision = Some(CollisionEvent { t_s: t, agents: [id(i), id(j)] });
                    }
                }
            }
        }
    }

    fn control(
        &mut self,
        t: f64,
        vut: &mut VutSide<'_>,
        bv_control: &mut dyn FnMut(usize, &BvObservation<'_>) -> Option<ActuationRequest>,
    ) -> Result<(), ExternalVutError> {
        let settings = &self.scenario.settings;
        let n = self.agents.len();
        let dt = settings.plant_dt_s;
        let control_every = self.control_every;
        for loc in &mut self.locs {
            let _ = loc.publish(t);
        }
        let (locs, agents) = (&self.locs, &self.agents);
        let perceive = |i: usize, extra: f64, hint: f64| -> Option<Perceived> {
            let (state, age_s) = locs.get(i)?.seen_at(t, extra)?;
            let route = &agents.get(i)?.route;
            let (s_m, l_m) = track(route, state.position(), hint, state.speed_mps, age_s + control_every as f64 * dt);
            Some(Perceived { state, s_m, l_m, age_s })
        };
        let hints = self.s_perceived.clone();
        let hint = |i: usize| hints.get(i).copied().unwrap_or(0.0);
        let own: Vec<Option<Perceived>> = (0..n).map(|i| perceive(i, 0.0, hint(i))).collect();
        for (i, p) in own.iter().enumerate() {
            if let (Some(p), Some(sp)) = (p, self.s_perceived.get_mut(i)) {
                *sp = p.s_m;
            }
        }
        let vut_at_bv = perceive(0, settings.v2x_delay_s, hint(0));
        self.vut_at_bv = vut_at_bv;
        for (b, (slot, seen)) in self.perceived_bvs.iter_mut().zip(self.bv_seen.iter_mut()).enumerate() {
            if let Some(p) = perceive(b + 1, settings.perception_delay_s, hint(b + 1)) {
                *slot = p;
                *seen = true;
            }
        }
        let control_dt = control_every as f64 * dt;
        let scenario = self.scenario;
        if let (VutSide::Driver(driver), Some(Some(vut_own)), true) =
            (&mut *vut, own.first(), self.bv_seen.iter().all(|s| *s))
        {
            let obs = VutObservation { t_s: t, dt_s: control_dt, own: *vut_own, bvs: &self.perceived_bvs, scenario };
            if let Some(r) = self.requests.first_mut() {
                *r = driver.control(&obs);
            }
        }
        for b in 0..scenario.bvs.len() {
            let (Some(Some(bv_own)), Some(vut)) = (own.get(b + 1), vut_at_bv) else { continue };
            let obs = BvObservation { t_s: t, dt_s: control_dt, bv_index: b, own: *bv_own, vut, scenario };
            if let (Some(req), Some(r)) = (bv_control(b, &obs), self.requests.get_mut(b + 1)) {
                *r = req;
            }
        }
        for (plant, req) in self.plants.iter_mut().zip(&self.requests) {
            plant.request(t, *req);
        }
        if let VutSide::External(ext) = vut {
            // The other simulator sees every BV where it truly is now, and answers with the VUT one
            // control period on.
            let bvs: Vec<State> = self.plants.iter().skip(1).map(Plant::state).collect();
            let from = self.plants.first().map(Plant::state).unwrap_or_default();
            let to = ext.advance(t, control_dt, &bvs)?;
            if let Some(r) = self.requests.first_mut() {
                // What the trace shows as the VUT's "request": the acceleration it is about to realise.
                r.accel_mps2 = (to.speed_mps - from.speed_mps) / control_dt;
                r.steer_rad = 0.0;
            }
            self.external = Some(Segment { t0_s: t, from, t1_s: t + control_dt, to });
        }
        Ok(())
    }

    fn record(&mut self, t: f64) {
        let n = self.agents.len();
        let samples: Vec<AgentSample> = (0..n)
            .filter_map(|i| {
                let p = self.plants.get(i)?;
                Some(AgentSample {
                    state: p.state(),
                    s_m: *self.s_true.get(i)?,
                    l_m: *self.l_true.get(i)?,
                    accel_mps2: p.accel_mps2(),
                    steer_rad: p.steer_rad(),
                    request: *self.requests.get(i)?,
                })
            })
            .collect();
        self.trace.push(TraceSample { t_s: t, agents: samples, predicted_pet_s: Vec::new() });
    }

    /// Measures the interaction on the true states and returns the run's outcome.
    pub fn finish(self, vut_model: &str, bv_controller: &str) -> RunOutcome {
        let scenario = self.scenario;
        let setup = MeasureSetup {
            scenario: scenario.name.clone(),
            vut_model: vut_model.to_owned(),
            bv_controller: bv_controller.to_owned(),
            seed: self.seed,
            target: scenario.target,
            conflicts: scenario
                .conflicts
                .iter()
                .map(|c| ConflictSetup { bv_index: c.bv_index, zone: c.zone })
                .collect(),
            ttc_every: self.record_every,
        };
        let result = measure(&setup, &self.truth);
        let mut trace = self.trace;
        fill_predicted_pet(scenario, &mut trace);
        let layout = RunLayout {
            dims: self.truth.agents.iter().map(|a| a.dims).collect(),
            zones: setup.conflicts.clone(),
            routes: std::iter::once(&scenario.vut.agent)
                .chain(scenario.bvs.iter().map(|b| &b.agent))
                .map(|a| route_points(&a.route))
                .collect(),
        };
        RunOutcome {
            result,
            agent_ids: self.agents.iter().map(|a| a.id.clone()).collect(),
            trace,
            layout,
            setup,
            truth: self.truth,
        }
    }
}

/// Adds the constant-velocity predicted PET of every conflict to every trace sample.
fn fill_predicted_pet(scenario: &Scenario, trace: &mut [TraceSample]) {
    let times: Vec<f64> = trace.iter().map(|s| s.t_s).collect();
    let series = |i: usize| -> (Vec<f64>, Vec<f64>) {
        trace.iter().map(|s| s.agents.get(i).map_or((0.0, 0.0), |a| (a.s_m, a.state.speed_mps))).unzip()
    };
    let (vut_s, vut_v) = series(0);
    let per_conflict: Vec<Vec<Option<f64>>> = scenario
        .conflicts
        .iter()
        .map(|c| {
            let (bv_s, bv_v) = series(c.bv_index + 1);
            predicted_pet_series(&times, (&vut_s, &vut_v), &c.zone.vut, (&bv_s, &bv_v), &c.zone.bv)
                .into_iter()
                .map(|p| p.map(|(_, pet)| pet))
                .collect()
        })
        .collect();
    for (k, sample) in trace.iter_mut().enumerate() {
        sample.predicted_pet_s = per_conflict.iter().map(|c| c.get(k).copied().flatten()).collect();
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bv::ReferenceFollower;
    use crate::vut::common::fixtures::{Blind, VUT_SPEED, crossing};

    #[test]
    fn measured_pet_of_a_constant_speed_crossing_is_the_analytic_one() {
        let bv_speed = 6.0;
        let mut scenario = crossing(bv_speed);
        scenario.settings.noise_enabled = false;
        let mut bvs: Vec<Box<dyn BvController>> = vec![Box::new(ReferenceFollower::default())];
        let out = run(&scenario, &mut bvs, &mut Blind, 1).unwrap();
        let r = &out.result;
        // VUT +x from (0, 0) at 10 m/s, BV +y from (50, -40) at 6 m/s, both 4.6 × 1.85 m.
        let (half_len, half_width) = (2.3, 0.925);
        let vut_enter = (50.0 - half_width - half_len) / VUT_SPEED;
        let vut_exit = (50.0 + half_width + half_len) / VUT_SPEED;
        let bv_enter = (40.0 - half_width - half_len) / bv_speed;
        let bv_exit = (40.0 + half_width + half_len) / bv_speed;
        let (expected_first, expected_pet) = if vut_enter <= bv_enter {
            (FirstThrough::Vut, bv_enter - vut_exit)
        } else {
            (FirstThrough::Bv, vut_enter - bv_exit)
        };
        let c = &r.conflicts[0];
        assert_eq!(c.first, Some(expected_first));
        let pet_s = c.pet.pet_s().unwrap();
        assert!((pet_s - expected_pet).abs() < 1e-3, "PET {pet_s} vs analytic {expected_pet}");
        assert!(pet_s > 0.5, "the case is built with a clear gap: {pet_s}");
        assert_eq!(r.pet_min_s, Some(pet_s));
        assert!(r.collision.is_none() && !r.zone_overlap);
    }

    #[test]
    fn a_collision_is_detected_and_ends_the_run() {
        // The BV (8 m/s, 40 m to go) and the VUT (10 m/s, 50 m to go) reach the crossing together.
        let mut scenario = crossing(8.0);
        scenario.settings.noise_enabled = false;
        let mut bvs: Vec<Box<dyn BvController>> = vec![Box::new(ReferenceFollower::default())];
        let out = run(&scenario, &mut bvs, &mut Blind, 1).unwrap();
        let r = &out.result;
        let collision = r.collision.as_ref().expect("both arrive at 5 s: they must collide");
        assert_eq!(collision.agents, ["vut".to_owned(), "bv1".to_owned()]);
        assert!((collision.t_s - 4.7).abs() < 0.3, "{collision:?}");
        assert_eq!(r.min_distance_m, 0.0);
        assert!(r.duration_s < scenario.duration_s);
        assert!(!r.completed);
    }

    /// A VUT of "another simulator" that drives +x at constant speed from the origin, and fails
    /// from `fail_at_s` on.
    struct Straight {
        speed: f64,
        fail_at_s: f64,
        seen_bvs: Vec<State>,
    }

    impl ExternalVut for Straight {
        fn name(&self) -> &str {
            "test:straight"
        }
        fn advance(&mut self, t_s: f64, period_s: f64, bvs: &[State]) -> Result<State, ExternalVutError> {
            if t_s >= self.fail_at_s {
                return Err(ExternalVutError::new("test", t_s, "the VUT left the simulation"));
            }
            self.seen_bvs.extend_from_slice(bvs);
            let t = t_s + period_s;
            Ok(State { px: self.speed * t, py: 0.0, theta_rad: 0.0, speed_mps: self.speed })
        }
    }

    #[test]
    fn an_external_vut_is_measured_like_a_builtin_one() {
        let bv_speed = 6.0;
        let mut scenario = crossing(bv_speed);
        scenario.settings.noise_enabled = false;
        let mut bvs: Vec<Box<dyn BvController>> = vec![Box::new(ReferenceFollower::default())];
        let mut ext = Straight { speed: VUT_SPEED, fail_at_s: f64::INFINITY, seen_bvs: Vec::new() };
        let out = run_external(&scenario, &mut bvs, &mut ext, 1).unwrap();
        let mut builtin_bvs: Vec<Box<dyn BvController>> = vec![Box::new(ReferenceFollower::default())];
        let builtin = run(&scenario, &mut builtin_bvs, &mut Blind, 1).unwrap();
        // The blind builtin VUT holds its speed on the same line: the same PET, at the plant rate.
        let (a, b) = (out.result.pet_min_s.unwrap(), builtin.result.pet_min_s.unwrap());
        assert!((a - b).abs() < 0.02, "external {a} vs builtin {b}");
        assert_eq!(out.result.vut_model, "test:straight");
        // The other simulator was told where the BV truly was, once per control period.
        let first = ext.seen_bvs.first().unwrap();
        assert!((first.px - 50.0).abs() < 1e-9 && (first.py + 40.0).abs() < 1e-9, "{first:?}");
        assert_eq!(ext.seen_bvs.len(), out.trace.len());
        // Between answers the VUT is interpolated, never integrated: it stays on y = 0.
        assert!(out.truth.agents[0].states.iter().all(|s| s.py == 0.0 && (s.speed_mps - VUT_SPEED).abs() < 1e-12));
    }

    #[test]
    fn a_failing_external_simulator_ends_the_run_with_its_error() {
        let scenario = crossing(6.0);
        let mut bvs: Vec<Box<dyn BvController>> = vec![Box::new(ReferenceFollower::default())];
        let mut ext = Straight { speed: VUT_SPEED, fail_at_s: 1.0, seen_bvs: Vec::new() };
        let err = run_external(&scenario, &mut bvs, &mut ext, 1).unwrap_err();
        assert!(matches!(&err, RunError::External(e) if e.message.contains("left") && e.t_s == "1.00 s"), "{err}");
    }

    #[test]
    fn the_controller_count_must_match_the_bvs() {
        let scenario = crossing(8.0);
        let err = run(&scenario, &mut [], &mut Blind, 1).unwrap_err();
        assert_eq!(err, RunError::ControllerCount { bvs: 1, controllers: 0 });
    }
}
