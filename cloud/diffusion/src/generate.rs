//! A grounded scenario → trajectory priors: the diffusion model generates the interaction window,
//! guided toward the grounded conflict timing and away from solid boundaries, and the prior is
//! completed before and after it.
//!
//! 1. **Timing.** The grounded scenario places the conflict but not when each vehicle passes it;
//!    the constant-speed prior along the routes that keeps the grounded start times
//!    ([`TrajectoryPrior::along_routes_at_start_speed`], the planned PET) gives each vehicle's
//!    passage time at each conflict point.
//! 2. **Window.** `T` steps (8 s) centred on the first conflict's two passages (clamped to the
//!    prior). Slot 0 is the BV of the first conflict, slot 1 the VUT, slot 2 a second BV. Initial
//!    states are the constant-speed prior's at the window start.
//! 3. **Guidance.** Conflict anchors for both vehicles of every conflict at their passage times,
//!    each agent's place on the grounded timeline at the window's end (the goal anchor brought
//!    into the window: it leaves the window in its lane and on time), the
//!    solid boundaries within 40 m of the routes (`v2t_map::boundaries`), clearance outside the
//!    intended conflicts, kinematic limits, and the first step's jerk against the lead-in
//!    (acceleration 0).
//! 4. **Stitching.** Before the window: the constant-speed lead-in; the window: the rollout of the
//!    sampled controls, each first brought within the vehicle limits (jerk, acceleration range, no
//!    reversing, lateral acceleration, at 99 % of each: a projection after guidance, which only
//!    acts where the soft kinematic term left an excess); after it: a pure-pursuit follower of the route that eases the acceleration
//!    to zero within the jerk limit and holds the speed. States are rollouts of the controls
//!    throughout, so the prior is dynamically consistent.

use v2t_map::Map;
use v2t_map::boundaries::{first_crossing, solid_boundaries};
use v2t_model::Style;
use v2t_model::driving::pure_pursuit;
use v2t_model::geometry::Point2;
use v2t_model::grounded::{AgentRole, GroundedScenario};
use v2t_model::kinematics::{Control, State, rollout_into, step};
use v2t_model::metrics::{Side, passage, pet};
use v2t_model::path::ReferencePath;
use v2t_model::prior::{AgentTrajectory, TrajectoryPrior};
use v2t_model::validate::Validate as _;

use crate::condition::{Condition, KindClass, PassingOrder, SlotCondition, point_on_route, route_ahead};
use crate::guidance::{
    Anchor, ConflictWindow, Guidance, GuidanceConfig, GuidanceContext, GuidanceWeights, KinematicLimits,
};
use crate::sample::{Problem, SampleError, SamplerOptions, sample};
use crate::train::passage_time_s;
use crate::weights::Model;

/// Boundaries farther than this from every route point are left out of the guidance, m.
const BOUNDARY_RADIUS_M: f64 = 40.0;
/// The clearance term is off this long around an intended conflict's passages, s.
const WINDOW_PAD_S: f64 = 1.5;

/// What can keep a scenario from being generated.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum GenerateError {
    /// The grounded scenario is invalid (no route, NaN anchors, …).
    #[error("grounded scenario: {0}")]
    Scenario(String),
    /// More agents than the model has slots.
    #[error("the scenario has {agents} agents, the model takes at most {slots}")]
    TooManyAgents {
        /// In the scenario.
        agents: usize,
        /// Model slots.
        slots: usize,
    },
    /// Guidance setup failed.
    #[error(transparent)]
    Guidance(#[from] crate::guidance::GuidanceError),
    /// Sampling failed.
    #[error(transparent)]
    Sample(#[from] SampleError),
    /// No variant was generated (zero asked for).
    #[error("no variant generated")]
    NoVariant,
    /// An option out of its bounds (checked before anything is allocated or sampled).
    #[error("{field} must lie in {bound}, got {value}")]
    Option {
        /// The option.
        field: &'static str,
        /// Its bounds.
        bound: &'static str,
        /// What was asked.
        value: String,
    },
}

/// Most variants one call generates.
pub const MAX_VARIANTS: usize = 1_000;
/// Most draws per variant.
pub const MAX_DRAWS: u64 = 100;
/// Most guided corrections of the final sample (the default is 300).
pub const MAX_FINAL_ITERATIONS: usize = 10_000;

impl GenerateOptions {
    /// Every option within its bounds: variants in [1, 1000], draws in [1, 100], final
    /// corrections at most 10,000, a finite guidance scale in [0, 100], DDIM steps at least 1.
    pub fn check(&self) -> Result<(), GenerateError> {
        let bad = |field, bound, value: String| Err(GenerateError::Option { field, bound, value });
        if !(1..=MAX_VARIANTS).contains(&self.variants) {
            return bad("variants", "[1, 1000]", self.variants.to_string());
        }
        if !(1..=MAX_DRAWS).contains(&self.draws) {
            return bad("draws", "[1, 100]", self.draws.to_string());
        }
        let g = &self.sampler.guidance;
        if g.final_iterations > MAX_FINAL_ITERATIONS {
            return bad("final_iterations", "[0, 10000]", g.final_iterations.to_string());
        }
        if !(g.scale.is_finite() && (0.0..=100.0).contains(&g.scale)) {
            return bad("guidance_scale", "[0, 100]", g.scale.to_string());
        }
        if let crate::sample::Method::Ddim { steps: 0 } = self.sampler.method {
            return bad("ddim", "[1, K]", "0".into());
        }
        Ok(())
    }
}

/// The weights of full guidance: the kinematic term counts four times, so that guidance trades
/// anchor precision for the vehicle limits before the final projection has to.
pub const FULL_GUIDANCE: GuidanceWeights =
    GuidanceWeights { anchor: 1.0, boundary: 1.0, clearance: 1.0, kinematic: 4.0 };

/// Settings of [`generate`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GenerateOptions {
    /// Variants.
    pub variants: usize,
    /// Seed of the first variant's noise (the batch shares one stream).
    pub seed: u64,
    /// Sampler.
    pub sampler: SamplerOptions,
    /// Guidance weights (a zero switches a term off).
    pub weights: GuidanceWeights,
    /// Limits of the kinematic term and of the metrics.
    pub limits: KinematicLimits,
    /// Draws a variant is given before it is handed on as it is (1: no redraw).
    pub draws: u64,
}

impl Default for GenerateOptions {
    fn default() -> Self {
        Self {
            variants: 1,
            seed: 1,
            sampler: SamplerOptions::default(),
            weights: FULL_GUIDANCE,
            limits: KinematicLimits::default(),
            draws: 4,
        }
    }
}

/// How well one generated prior meets its scenario.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct PriorMetrics {
    /// Distance to each anchor at its time, m: VUT and BV of every conflict, then every agent's
    /// window-end anchor.
    pub anchor_errors_m: Vec<f64>,
    /// Agents whose path crosses a solid boundary.
    pub boundary_crossings: usize,
    /// Agents whose acceleration, lateral acceleration and jerk stay within the limits (1 mm/s²
    /// of tolerance), and agents in all.
    pub agents_within_limits: usize,
    /// Agents.
    pub agents: usize,
    /// Largest |acceleration|, lateral acceleration and jerk of any agent.
    pub max_accel_mps2: f64,
    /// … lateral acceleration, m/s².
    pub max_lat_accel_mps2: f64,
    /// … jerk, m/s³.
    pub max_jerk_mps3: f64,
    /// Conflicts whose passing order is the style's.
    pub order_ok: usize,
    /// Conflicts.
    pub conflicts: usize,
    /// PET of every conflict, s (`None` if a vehicle does not pass).
    pub pet_s: Vec<Option<f64>>,
}

/// One generated prior and its metrics.
#[derive(Debug, Clone, PartialEq)]
pub struct Generated {
    /// The prior (all agents, the whole scenario).
    pub prior: TrajectoryPrior,
    /// Its metrics.
    pub metrics: PriorMetrics,
}

/// Everything fixed for one scenario: the constant-speed timeline, the window, the condition and
/// the guidance.
#[derive(Debug)]
pub struct Setup {
    /// The constant-speed prior with the grounded timing.
    pub base: TrajectoryPrior,
    /// Window start, steps.
    pub window_start: usize,
    /// Scenario agent index of each used slot, in slot order.
    pub slot_agents: Vec<usize>,
    /// The condition.
    pub condition: Condition,
    /// The guidance (window-relative times).
    pub guidance: Guidance,
    /// Initial states of the used slots.
    pub x0s: Vec<State>,
    /// The solid boundaries near the routes.
    pub boundaries: Vec<Vec<Point2>>,
    /// Routes by scenario agent index.
    pub routes: Vec<ReferencePath>,
    /// Anchors by scenario agent: (agent, point, time from the scenario start).
    pub anchors: Vec<(usize, Point2, f64)>,
}

/// Prepares `scenario` for a model with `cfg`.
pub fn setup(
    model: &Model,
    map: &Map,
    scenario: &GroundedScenario,
    options: &GenerateOptions,
) -> Result<Setup, GenerateError> {
    scenario.validate().map_err(|e| GenerateError::Scenario(e.to_string()))?;
    let cfg = *model.denoiser.config();
    if scenario.agents.len() > cfg.slots {
        return Err(GenerateError::TooManyAgents { agents: scenario.agents.len(), slots: cfg.slots });
    }
    let dt = crate::synth::DT_S;
    let horizon = TrajectoryPrior::stand_in_horizon_s(scenario).max(cfg.steps as f64 * dt);
    let mut base = TrajectoryPrior::along_routes_at_start_speed(scenario, horizon)
        .map_err(|e| GenerateError::Scenario(e.to_string()))?;
    // Its states become the rollout of its controls, so that the whole prior (lead-in, window,
    // tail) is dynamically consistent; the difference is the path's discretization (centimetres).
    for a in &mut base.agents {
        let x0 = a.states.first().copied().unwrap_or_default();
        rollout_into(x0, &a.controls, dt, &mut a.states);
    }
    let routes = scenario
        .agents
        .iter()
        .map(|a| {
            ReferencePath::from_points(&a.route).map_err(|e| GenerateError::Scenario(format!("{}.route: {e}", a.id)))
        })
        .collect::<Result<Vec<_>, _>>()?;
    let index_of = |id: &str| scenario.agents.iter().position(|a| a.id == id);
    let vut = scenario
        .agents
        .iter()
        .position(|a| a.role == AgentRole::Vut)
        .ok_or_else(|| GenerateError::Scenario("no VUT".into()))?;
    // Passage times of every conflict on the constant-speed timeline.
    let mut anchors = Vec::new();
    let mut timings = Vec::new();
    for c in &scenario.conflicts {
        let bv = index_of(&c.bv_id)
            .ok_or_else(|| GenerateError::Scenario(format!("conflict names unknown BV `{}`", c.bv_id)))?;
        let time_of = |i: usize| base.agents.get(i).and_then(|a| passage_time_s(&a.states, c.point, dt));
        let (Some(tv), Some(tb)) = (time_of(vut), time_of(bv)) else {
            return Err(GenerateError::Scenario(format!("conflict `{}` is not on both routes", c.anchor_id)));
        };
        anchors.push((vut, c.point, tv));
        anchors.push((bv, c.point, tb));
        timings.push((bv, tv, tb));
    }
    let n = base.agents.iter().map(|a| a.controls.len()).min().unwrap_or(0);
    let window_start = match timings.first() {
        Some((_, tv, tb)) => {
            let mid = 0.5 * (tv + tb);
            (((mid - 0.5 * cfg.steps as f64 * dt) / dt).round().max(0.0) as usize).min(n.saturating_sub(cfg.steps))
        }
        None => 0,
    };
    let t0 = window_start as f64 * dt;
    // Slots: the first conflict's BV, the VUT, the other BV.
    let first_bv = timings.first().map(|(bv, _, _)| *bv);
    let mut slot_agents: Vec<usize> = first_bv.into_iter().collect();
    slot_agents.push(vut);
    slot_agents.extend((0..scenario.agents.len()).filter(|i| Some(*i) != first_bv && *i != vut));
    let bv_first = scenario.target.style() == Style::Rush;
    let mut slots = Vec::with_capacity(slot_agents.len());
    let mut x0s = Vec::with_capacity(slot_agents.len());
    for &i in &slot_agents {
        let (Some(traj), Some(route)) = (base.agents.get(i), routes.get(i)) else { continue };
        let start = traj.states.get(window_start).copied().unwrap_or_default();
        // The slot's own conflict anchor (the VUT's is that of the first conflict).
        let own = anchors.iter().find(|(a, _, _)| *a == i).map(|(_, p, t)| (*p, t - t0));
        let order = own.map(|_| if (i == vut) != bv_first { PassingOrder::First } else { PassingOrder::Second });
        slots.push(Some(SlotCondition { start, route_local: route_ahead(route, &start), anchor: own, order }));
        x0s.push(start);
    }
    let condition = Condition { slots, kind: KindClass::of_interaction(scenario.interaction_type) };
    let slot_of = |agent: usize| slot_agents.iter().position(|a| *a == agent);
    let horizon_s = cfg.steps as f64 * dt;
    // Goal anchors brought into the window: where the grounded timeline puts each agent at the
    // window's end (on its route, on time), so that every agent leaves the window in its lane and
    // the route-following tail has nothing to catch up.
    // Between its conflict passage and the window's end, an agent that merges follows its route
    // (an anchor every second on the timeline): the lane is joined, not crossed and re-crossed.
    let merges = scenario.conflicts.iter().any(|c| c.kind == v2t_model::metrics::ConflictKind::Merge);
    let passages: Vec<(usize, f64)> = anchors.iter().map(|(i, _, t)| (*i, *t)).collect();
    for &i in &slot_agents {
        if merges && let Some(t_pass) = passages.iter().filter(|(a, _)| *a == i).map(|(_, t)| *t).reduce(f64::min) {
            let mut t = (t_pass + 1.0).max(t0);
            while t < t0 + horizon_s - 0.5 {
                let k = ((t / dt).round() as usize).min(n);
                if let Some(x) = base.agents.get(i).and_then(|a| a.states.get(k)) {
                    anchors.push((i, x.position(), k as f64 * dt));
                }
                t += 1.0;
            }
        }
        if let Some(x) = base.agents.get(i).and_then(|a| a.states.get(window_start + cfg.steps)) {
            anchors.push((i, x.position(), t0 + horizon_s));
        }
    }
    let guidance_anchors = anchors
        .iter()
        .filter(|(_, _, t)| *t - t0 >= 0.0 && *t - t0 <= horizon_s)
        .filter_map(|(a, p, t)| slot_of(*a).map(|agent| Anchor { agent, position: *p, time_s: t - t0 }))
        .collect();
    let conflict_windows = timings
        .iter()
        .filter_map(|(bv, tv, tb)| {
            Some(ConflictWindow {
                agent_a: slot_of(vut)?,
                agent_b: slot_of(*bv)?,
                from_s: tv.min(*tb) - t0 - WINDOW_PAD_S,
                to_s: tv.max(*tb) - t0 + WINDOW_PAD_S,
            })
        })
        .collect();
    let near: Vec<Point2> = slot_agents
        .iter()
        .filter_map(|&i| base.agents.get(i))
        .flat_map(|a| a.states.iter().skip(window_start).take(cfg.steps + 1).step_by(5).map(State::position))
        .collect();
    let boundaries = solid_boundaries(map, &near, BOUNDARY_RADIUS_M, 0.05);
    let boundary_sides = slot_agents
        .iter()
        .map(|&i| boundaries.iter().map(|b| routes.get(i).map_or(0, |r| route_side(r, b))).collect())
        .collect();
    let context = GuidanceContext {
        anchors: guidance_anchors,
        boundaries: boundaries.clone(),
        boundary_sides,
        conflict_windows,
        previous_accel_mps2: vec![0.0; slot_agents.len()],
    };
    let config = GuidanceConfig {
        agents: slot_agents.len(),
        steps: cfg.steps,
        dt_s: dt,
        weights: options.weights,
        limits: options.limits,
        ..GuidanceConfig::default()
    };
    let guidance = Guidance::new(config, context)?;
    Ok(Setup { base, window_start, slot_agents, condition, guidance, x0s, boundaries, routes, anchors })
}

/// The side of `boundary` the route runs on where it runs alongside it within 6 m (a majority of
/// its points every 2 m): `+1` left, `-1` right, `0` never alongside.
fn route_side(route: &ReferencePath, boundary: &[Point2]) -> i8 {
    let mut votes = 0i64;
    let mut s = 0.0;
    while s <= route.length() {
        if let Some(d) = crate::guidance::terms::signed_distance(boundary, route.point_at(s))
            && d.alongside
            && d.signed_m.abs() <= 6.0
        {
            votes += if d.signed_m >= 0.0 { 1 } else { -1 };
        }
        s += 2.0;
    }
    votes.signum() as i8
}

/// Pure pursuit of `route` from `x` for `steps` steps: acceleration eased from `a_start` to zero
/// within `jerk_max`, yaw rate toward a look-ahead point, lateral acceleration within `lat_max`.
fn follow_route(
    route: &ReferencePath,
    x: State,
    a_start: f64,
    steps: usize,
    dt: f64,
    limits: &KinematicLimits,
) -> (Vec<State>, Vec<Control>) {
    let mut states = Vec::with_capacity(steps + 1);
    let mut controls = Vec::with_capacity(steps);
    let mut state = x;
    let mut a = a_start;
    let mut s_hint = route.project(x.position()).map_or(0.0, |f| f.s_m);
    states.push(state);
    let da = 0.9 * limits.jerk_max_mps3 * dt;
    for _ in 0..steps {
        a = if a > 0.0 { (a - da).max(0.0) } else { (a + da).min(0.0) };
        if state.speed_mps + a * dt < 0.0 {
            a = -state.speed_mps / dt;
        }
        let foot = route.project_near(state.position(), s_hint, 20.0).map_or(s_hint, |f| f.s_m);
        s_hint = foot;
        let look = (1.0 * state.speed_mps).max(6.0);
        let target = point_on_route(route, foot + look);
        let mut omega = pure_pursuit(state.position(), state.theta_rad, target, state.speed_mps);
        if state.speed_mps > 0.5 {
            let cap = 0.9 * limits.lat_accel_max_mps2 / state.speed_mps;
            omega = omega.clamp(-cap, cap);
        }
        let u = Control { accel_mps2: a, yaw_rate_radps: omega };
        state = step(state, u, dt);
        controls.push(u);
        states.push(state);
    }
    (states, controls)
}

/// `u` brought within the limits from state `x` after acceleration `a_prev`: jerk first, then the
/// acceleration range, no reversing, then the yaw rate for the lateral acceleration (all at 99 %
/// of the limit).
fn within_limits(x: State, u: Control, a_prev: f64, dt: f64, limits: &KinematicLimits) -> Control {
    let m = 0.99;
    let dj = m * limits.jerk_max_mps3 * dt;
    let mut a = u.accel_mps2.clamp(a_prev - dj, a_prev + dj);
    a = a.clamp(m * limits.accel_min_mps2, m * limits.accel_max_mps2);
    a = a.max(-x.speed_mps / dt);
    let mut omega = u.yaw_rate_radps;
    if x.speed_mps > 1e-6 {
        let cap = m * limits.lat_accel_max_mps2 / x.speed_mps;
        omega = omega.clamp(-cap, cap);
    }
    Control { accel_mps2: a, yaw_rate_radps: omega }
}

/// The prior of one sampled variant: lead-in, window, route-following tail.
fn stitch(
    scenario: &GroundedScenario,
    setup: &Setup,
    window: &[Vec<Control>],
    limits: &KinematicLimits,
) -> TrajectoryPrior {
    let dt = setup.base.dt_s;
    let total = setup.base.agents.iter().map(|a| a.controls.len()).min().unwrap_or(0);
    let w0 = setup.window_start;
    let mut agents = setup.base.agents.clone();
    for (slot, &i) in setup.slot_agents.iter().enumerate() {
        let (Some(agent), Some(u), Some(route)) = (agents.get_mut(i), window.get(slot), setup.routes.get(i)) else {
            continue;
        };
        let mut states: Vec<State> = agent.states.iter().take(w0 + 1).copied().collect();
        let mut controls: Vec<Control> = agent.controls.iter().take(w0).copied().collect();
        let mut x = states.last().copied().unwrap_or_default();
        let mut a_prev = controls.last().map_or(0.0, |c| c.accel_mps2);
        for c in u {
            let c = within_limits(x, *c, a_prev, dt, limits);
            a_prev = c.accel_mps2;
            x = step(x, c, dt);
            controls.push(c);
            states.push(x);
        }
        let a_last = controls.last().map_or(0.0, |c| c.accel_mps2);
        let (tail_states, tail_controls) =
            follow_route(route, x, a_last, total.saturating_sub(controls.len()), dt, limits);
        states.extend(tail_states.into_iter().skip(1));
        controls.extend(tail_controls);
        *agent = AgentTrajectory { id: agent.id.clone(), role: agent.role, states, controls };
    }
    TrajectoryPrior::of_scenario(scenario, dt, agents)
}

/// Position at time `t` (linear between states).
fn position_at(states: &[State], t: f64, dt: f64) -> Option<Point2> {
    let k = (t / dt).floor().max(0.0) as usize;
    let f = t / dt - k as f64;
    match (states.get(k), states.get(k + 1)) {
        (Some(a), Some(b)) => Some(a.position().lerp(b.position(), f.clamp(0.0, 1.0))),
        (Some(a), None) => Some(a.position()),
        _ => states.last().map(State::position),
    }
}

/// The metrics of `prior` against its scenario and setup.
pub fn measure(
    scenario: &GroundedScenario,
    setup: &Setup,
    prior: &TrajectoryPrior,
    limits: &KinematicLimits,
) -> PriorMetrics {
    let dt = prior.dt_s;
    let anchor_errors_m = setup
        .anchors
        .iter()
        .map(|(i, p, t)| {
            prior.agents.get(*i).and_then(|a| position_at(&a.states, *t, dt)).map_or(f64::INFINITY, |q| q.dist(*p))
        })
        .collect();
    let mut boundary_crossings = 0;
    let (mut within, mut max_a, mut max_lat, mut max_j) = (0, 0.0f64, 0.0f64, 0.0f64);
    for a in &prior.agents {
        let path: Vec<Point2> = a.states.iter().map(State::position).collect();
        if first_crossing(&path, &setup.boundaries).is_some() {
            boundary_crossings += 1;
        }
        let mut ok = true;
        let tol = 1e-3;
        for (k, (x, u)) in a.states.iter().zip(&a.controls).enumerate() {
            let lat = (x.speed_mps * u.yaw_rate_radps).abs();
            max_a = max_a.max(u.accel_mps2.abs());
            max_lat = max_lat.max(lat);
            ok &= u.accel_mps2 >= limits.accel_min_mps2 - tol && u.accel_mps2 <= limits.accel_max_mps2 + tol;
            ok &= lat <= limits.lat_accel_max_mps2 + tol;
            if let Some(prev) = k.checked_sub(1).and_then(|j| a.controls.get(j)) {
                let jerk = ((u.accel_mps2 - prev.accel_mps2) / dt).abs();
                max_j = max_j.max(jerk);
                ok &= jerk <= limits.jerk_max_mps3 + tol;
            }
        }
        if ok {
            within += 1;
        }
    }
    let vut = scenario.agents.iter().position(|a| a.role == AgentRole::Vut);
    let mut order_ok = 0;
    let mut pets = Vec::new();
    for c in &scenario.conflicts {
        let bv = scenario.agents.iter().position(|a| a.id == c.bv_id);
        let series = |i: Option<usize>| -> Option<(Vec<f64>, Vec<f64>)> {
            let i = i?;
            let (a, route) = (prior.agents.get(i)?, setup.routes.get(i)?);
            let mut hint = 0.0;
            let mut s = Vec::with_capacity(a.states.len());
            for x in &a.states {
                hint = route.project_near(x.position(), hint, 30.0).map_or(hint, |f| f.s_m);
                s.push(hint);
            }
            Some(((0..a.states.len()).map(|k| k as f64 * dt).collect(), s))
        };
        let (Some((tv, sv)), Some((tb, sb))) = (series(vut), series(bv)) else {
            pets.push(None);
            continue;
        };
        let t_end = tv.last().copied().unwrap_or(0.0);
        let outcome = pet(passage(&tv, &sv, &c.vut_interval), passage(&tb, &sb, &c.bv_interval), t_end);
        let wanted = if scenario.target.style() == Style::Rush { Side::B } else { Side::A };
        if outcome.first() == Some(wanted) {
            order_ok += 1;
        }
        pets.push(outcome.pet_s());
    }
    PriorMetrics {
        anchor_errors_m,
        boundary_crossings,
        agents_within_limits: within,
        agents: prior.agents.len(),
        max_accel_mps2: max_a,
        max_lat_accel_mps2: max_lat,
        max_jerk_mps3: max_j,
        order_ok,
        conflicts: scenario.conflicts.len(),
        pet_s: pets,
    }
}

/// Whether a generated prior may be handed on: no solid boundary crossed, every agent within the
/// limits, every conflict in the style's order.
pub fn acceptable(m: &PriorMetrics) -> bool {
    m.boundary_crossings == 0 && m.agents_within_limits == m.agents && m.order_ok == m.conflicts
}

/// The largest anchor error a prior may have and still be handed on, m: a vehicle this far from
/// where the grounded scenario puts it at the anchor's time is about half a second off the
/// grounded timing at 10 m/s (the shipped weights stay below 1 m).
pub const ANCHOR_TOLERANCE_M: f64 = 5.0;

/// A criterion a generated prior misses ([`shortfalls`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Shortfall {
    /// Conflicts passed in the style's order, of all.
    Order {
        /// In order.
        ok: usize,
        /// All.
        of: usize,
    },
    /// Agents crossing a solid boundary, of all.
    Boundary {
        /// Crossing.
        crossing: usize,
        /// All.
        of: usize,
    },
    /// Agents within the vehicle limits, of all.
    Limits {
        /// Within.
        ok: usize,
        /// All.
        of: usize,
    },
    /// The worst anchor error, beyond [`ANCHOR_TOLERANCE_M`], m.
    Anchor {
        /// The worst error.
        worst_m: f64,
    },
}

impl Shortfall {
    /// The criterion, in words (the same for every variant that misses it).
    pub fn criterion(&self) -> &'static str {
        match self {
            Self::Order { .. } => "passing order missed",
            Self::Boundary { .. } => "solid boundary crossed",
            Self::Limits { .. } => "vehicle limits left",
            Self::Anchor { .. } => "anchor error above 5 m",
        }
    }
}

impl std::fmt::Display for Shortfall {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Order { ok, of } => write!(f, "{ok} of {of} conflicts in the asked order"),
            Self::Boundary { crossing, of } => write!(f, "{crossing} of {of} agents cross a solid boundary"),
            Self::Limits { ok, of } => write!(f, "{ok} of {of} agents within the vehicle limits"),
            Self::Anchor { worst_m } => write!(f, "worst anchor error {worst_m:.1} m (at most {ANCHOR_TOLERANCE_M} m)"),
        }
    }
}

/// Why a generated prior may not be handed on: each criterion it misses ([`acceptable`], and every
/// anchor within [`ANCHOR_TOLERANCE_M`]); empty when it meets them all.
pub fn shortfalls(m: &PriorMetrics) -> Vec<Shortfall> {
    let mut out = Vec::new();
    if m.order_ok != m.conflicts {
        out.push(Shortfall::Order { ok: m.order_ok, of: m.conflicts });
    }
    if m.boundary_crossings > 0 {
        out.push(Shortfall::Boundary { crossing: m.boundary_crossings, of: m.agents });
    }
    if m.agents_within_limits != m.agents {
        out.push(Shortfall::Limits { ok: m.agents_within_limits, of: m.agents });
    }
    let worst_m = m.anchor_errors_m.iter().copied().fold(0.0, f64::max);
    if worst_m.is_nan() || worst_m > ANCHOR_TOLERANCE_M {
        out.push(Shortfall::Anchor { worst_m });
    }
    out
}

/// The variant to hand on: the one with the smallest worst anchor error among the [`acceptable`]
/// ones (else the smallest overall).
pub fn best(generated: &[Generated]) -> Option<&Generated> {
    let worst = |g: &Generated| g.metrics.anchor_errors_m.iter().copied().fold(0.0, f64::max);
    let by_worst = |a: &&Generated, b: &&Generated| worst(a).total_cmp(&worst(b));
    generated.iter().filter(|g| acceptable(&g.metrics)).min_by(by_worst).or_else(|| generated.iter().min_by(by_worst))
}

/// Summary over variants.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Summary {
    /// Variants generated.
    pub variants: usize,
    /// Median anchor error over every anchor of every variant, m.
    pub median_anchor_error_m: f64,
    /// Largest anchor error, m.
    pub max_anchor_error_m: f64,
    /// Agents crossing a solid boundary, over all variants.
    pub boundary_crossings: usize,
    /// Fraction of agent trajectories within the vehicle limits.
    pub within_limits_frac: f64,
    /// Fraction of conflicts passed in the style's order.
    pub order_ok_frac: f64,
    /// Variants drawn again because they crossed a boundary, left the limits or the order.
    pub redrawn: usize,
    /// Wall time of the sampling (all variants), s.
    pub sampling_s: f64,
}

/// The summary of generated variants, `redrawn` of which were drawn again, sampled in `sampling_s`.
pub fn summarize(generated: &[Generated], redrawn: usize, sampling_s: f64) -> Summary {
    let mut errors: Vec<f64> = generated.iter().flat_map(|g| g.metrics.anchor_errors_m.iter().copied()).collect();
    let agents: usize = generated.iter().map(|g| g.metrics.agents).sum();
    let conflicts: usize = generated.iter().map(|g| g.metrics.conflicts).sum();
    Summary {
        variants: generated.len(),
        max_anchor_error_m: errors.iter().copied().fold(0.0, f64::max),
        median_anchor_error_m: crate::stats::median(&mut errors).unwrap_or(f64::NAN),
        boundary_crossings: generated.iter().map(|g| g.metrics.boundary_crossings).sum(),
        within_limits_frac: generated.iter().map(|g| g.metrics.agents_within_limits).sum::<usize>() as f64
            / agents.max(1) as f64,
        order_ok_frac: generated.iter().map(|g| g.metrics.order_ok).sum::<usize>() as f64 / conflicts.max(1) as f64,
        redrawn,
        sampling_s,
    }
}

/// `options.variants` priors for `scenario`, with the number of variants drawn again.
///
/// A variant that is not [`acceptable`] is drawn again with new noise (the whole batch of such
/// variants at once, up to `options.draws` draws in all); one still unacceptable after that is
/// returned as it is, its metrics say why. The count of redraws is returned so that reports can
/// say how often the guided sampler alone fell short.
pub fn generate(
    model: &Model,
    map: &Map,
    scenario: &GroundedScenario,
    options: &GenerateOptions,
) -> Result<(Vec<Generated>, usize), GenerateError> {
    options.check()?;
    let setup = setup(model, map, scenario, options)?;
    let problem = Problem { condition: &setup.condition, guidance: Some(&setup.guidance), x0s: &setup.x0s };
    let mut out: Vec<Option<Generated>> = vec![None; options.variants.max(1)];
    let mut todo: Vec<usize> = (0..out.len()).collect();
    let mut redrawn = 0;
    let draws = options.draws.max(1);
    for draw in 0..draws {
        if todo.is_empty() {
            break;
        }
        if draw > 0 {
            redrawn += todo.len();
        }
        let seed = options.seed.wrapping_add(draw.wrapping_mul(0x9E37_79B9_7F4A_7C15));
        let variants = sample(model, &problem, todo.len(), seed, &options.sampler)?;
        let mut still = Vec::new();
        for (&slot, v) in todo.iter().zip(variants) {
            let prior = stitch(scenario, &setup, &v.controls, &options.limits);
            prior.validate().map_err(|e| GenerateError::Scenario(format!("generated prior invalid: {e}")))?;
            let metrics = measure(scenario, &setup, &prior, &options.limits);
            if !acceptable(&metrics) && draw + 1 < draws {
                still.push(slot);
            }
            if let Some(o) = out.get_mut(slot) {
                *o = Some(Generated { prior, metrics });
            }
        }
        todo = still;
    }
    Ok((out.into_iter().flatten().collect(), redrawn))
}

#[cfg(test)]
mod option_tests {
    #![allow(clippy::unwrap_used)]

    use super::*;

    /// Sizes that once aborted (100,000 variants) or hung (4,294,967,295 final corrections) are
    /// refused before anything is allocated, naming the option and its bounds.
    #[test]
    fn options_out_of_bounds_are_refused_with_the_field() {
        assert!(GenerateOptions::default().check().is_ok());
        let e = GenerateOptions { variants: 100_000, ..GenerateOptions::default() }.check().unwrap_err();
        assert_eq!(e.to_string(), "variants must lie in [1, 1000], got 100000");
        let mut o = GenerateOptions::default();
        o.sampler.guidance.final_iterations = 4_294_967_295;
        assert!(o.check().unwrap_err().to_string().starts_with("final_iterations"));
        o = GenerateOptions { draws: 0, ..GenerateOptions::default() };
        assert!(o.check().unwrap_err().to_string().starts_with("draws"));
        o = GenerateOptions::default();
        o.sampler.guidance.scale = f64::NAN;
        assert!(o.check().unwrap_err().to_string().starts_with("guidance_scale"));
    }
}
