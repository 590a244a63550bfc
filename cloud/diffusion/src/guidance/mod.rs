//! Guidance energies of the guided diffusion model (paper, Section 3.3.1), pure and without any ML
//! dependency.
//!
//! The diffusion model denoises a *joint control tensor*: `agents × steps` controls `[a, ω]`,
//! stored flat and agent-major, `controls[i · steps + t]` is agent `i`'s control over
//! `[t·dt, (t+1)·dt)`. Each agent starts from its own initial state `x0s[i]`; the trajectories are
//! rolled out with [`v2t_model::kinematics::rollout_into`] and every energy's gradient with respect
//! to the controls is taken through the rollout adjoint
//! ([`v2t_model::kinematics::rollout_vjp_into`]); energies that also depend on the controls
//! directly (kinematic limits) add that part.
//!
//! `E = λ_anch E_anch + λ_bound E_bound + λ_clear E_clear + λ_kin E_kin` (see [`terms`] and the crate
//! README for the formulas). [`Guidance::energy_and_grad`] allocates nothing: it works in a
//! [`GuidanceWorkspace`] built once for the problem's shape. Non-finite inputs are rejected with an
//! error and a non-finite result (overflow) is reported as an error, never returned.
//!
//! [`normalized`] has the guided correction of Algorithm 1 (`Ũ0 = Û0 − η ∇E`) in the denoiser's
//! normalized control space and the guided reverse-process mean.
//!
//! ```
//! use v2t_diffusion::guidance::{Anchor, Guidance, GuidanceConfig, GuidanceContext, GuidanceWorkspace};
//! use v2t_model::geometry::Point2;
//! use v2t_model::kinematics::{Control, State};
//! let config = GuidanceConfig { agents: 1, steps: 20, ..GuidanceConfig::default() };
//! let context = GuidanceContext {
//!     anchors: vec![Anchor { agent: 0, position: Point2::new(25.0, 0.0), time_s: 2.0 }],
//!     ..GuidanceContext::default()
//! };
//! let guidance = Guidance::new(config, context).unwrap();
//! let mut ws = GuidanceWorkspace::new(&guidance);
//! let x0 = [State { speed_mps: 10.0, ..State::default() }];
//! let mut u = vec![Control::default(); 20];
//! let mut grad = vec![Control::default(); 20];
//! let e0 = guidance.energy_and_grad(&mut ws, &x0, &u, &mut grad).unwrap();
//! assert!((e0.anchor - 25.0).abs() < 1e-9); // 20 m instead of 25 m after 2 s
//! assert!(grad[0].accel_mps2 < 0.0); // accelerating lowers the energy
//! ```

mod anchors;
pub mod normalized;
pub mod terms;

pub use anchors::ConflictTiming;

use v2t_model::geometry::Point2;
use v2t_model::kinematics::{Control, ShapeError, State, rollout_into, rollout_vjp_into};

/// Failures of the guidance computation.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum GuidanceError {
    /// A configuration value is out of its range (NaN included).
    #[error("guidance config: {field} {reason}")]
    InvalidConfig {
        /// Field name.
        field: &'static str,
        /// What is wrong.
        reason: String,
    },
    /// An array does not have the problem's shape.
    #[error("guidance: {what} has {got} entries, expected {expected}")]
    Shape {
        /// Which array.
        what: &'static str,
        /// Expected length.
        expected: usize,
        /// Actual length.
        got: usize,
    },
    /// An input value is NaN or infinite.
    #[error("guidance: {what}[{index}] is not finite")]
    NonFiniteInput {
        /// Which array.
        what: &'static str,
        /// Flat index of the first bad entry.
        index: usize,
    },
    /// The energy or its gradient overflowed (inputs far outside any physical range).
    #[error("guidance: the energy or its gradient is not finite (inputs far out of range)")]
    NonFiniteResult,
    /// An agent or BV id of the grounded scenario is not found.
    #[error("guidance: unknown agent `{0}`")]
    UnknownAgent(String),
    /// The rollout adjoint rejected the shapes (an internal inconsistency).
    #[error(transparent)]
    Adjoint(#[from] ShapeError),
}

/// Weights `λ` of the four terms; a zero weight switches a term off (its energy is still reported).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GuidanceWeights {
    /// `λ_anch`, 1/m².
    pub anchor: f64,
    /// `λ_bound`, 1/m².
    pub boundary: f64,
    /// `λ_clear`, 1/m².
    pub clearance: f64,
    /// `λ_kin`, for squared excesses in SI units.
    pub kinematic: f64,
}

impl Default for GuidanceWeights {
    fn default() -> Self {
        Self { anchor: 1.0, boundary: 1.0, clearance: 1.0, kinematic: 1.0 }
    }
}

/// Limits of the kinematic term (squared hinges on their excess).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct KinematicLimits {
    /// Strongest braking, m/s² (negative).
    pub accel_min_mps2: f64,
    /// Strongest acceleration, m/s².
    pub accel_max_mps2: f64,
    /// Largest lateral acceleration `|v ω|`, m/s².
    pub lat_accel_max_mps2: f64,
    /// Largest jerk `|Δa / dt|`, m/s³.
    pub jerk_max_mps3: f64,
    /// Largest speed, m/s (the smallest is 0: no reversing).
    pub speed_max_mps: f64,
}

impl Default for KinematicLimits {
    fn default() -> Self {
        Self {
            accel_min_mps2: -6.0,
            accel_max_mps2: 3.0,
            lat_accel_max_mps2: 4.0,
            jerk_max_mps3: 6.0,
            speed_max_mps: 40.0,
        }
    }
}

/// Shape and parameters of a guidance problem.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GuidanceConfig {
    /// Number of agents `N`.
    pub agents: usize,
    /// Control steps per agent `T` (states `T + 1`).
    pub steps: usize,
    /// Time step, s.
    pub dt_s: f64,
    /// Term weights.
    pub weights: GuidanceWeights,
    /// `d_safe` of the boundary term: the footprint centre should stay this far on its side of every
    /// solid boundary, m (half a car width plus a little).
    pub boundary_margin_m: f64,
    /// Clearance radius between agents' centres, m.
    pub clearance_radius_m: f64,
    /// Kinematic limits.
    pub limits: KinematicLimits,
}

impl Default for GuidanceConfig {
    fn default() -> Self {
        Self {
            agents: 1,
            steps: 50,
            dt_s: 0.1,
            weights: GuidanceWeights::default(),
            boundary_margin_m: 1.2,
            clearance_radius_m: 4.0,
            limits: KinematicLimits::default(),
        }
    }
}

/// A position an agent should have at a time: `(p_{i,a}, t_{i,a})` of the paper.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Anchor {
    /// Agent index.
    pub agent: usize,
    /// Anchor position, track frame.
    pub position: Point2,
    /// Anchor time, s from the first state; clamped to the horizon `[0, T·dt]`, and the position at
    /// a time between steps is interpolated linearly between the two neighbouring states.
    pub time_s: f64,
}

/// A pair and a time window in which the clearance term is off (the intended conflict).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ConflictWindow {
    /// One agent index.
    pub agent_a: usize,
    /// The other agent index.
    pub agent_b: usize,
    /// Window start, s.
    pub from_s: f64,
    /// Window end, s (inclusive).
    pub to_s: f64,
}

impl ConflictWindow {
    /// Whether the window switches the pair `(i, j)` off at `time_s`.
    pub fn covers(&self, i: usize, j: usize, time_s: f64) -> bool {
        let pair = (self.agent_a == i && self.agent_b == j) || (self.agent_a == j && self.agent_b == i);
        pair && time_s >= self.from_s && time_s <= self.to_s
    }
}

/// The conditioning of the energies: anchors, solid boundaries and intended conflicts.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct GuidanceContext {
    /// Anchors of all agents.
    pub anchors: Vec<Anchor>,
    /// Solid lane boundaries as polylines (zero-length segments are ignored).
    pub boundaries: Vec<Vec<Point2>>,
    /// Pairs and windows where the clearance term is off.
    pub conflict_windows: Vec<ConflictWindow>,
    /// The side of each boundary each agent belongs on, `[agent][boundary]`: `+1` left of the
    /// boundary's direction, `-1` right, `0` (or missing) the side it is on the first time it is
    /// alongside the boundary. A planner that knows the agents' routes sets it, so that an agent
    /// that starts or strays on the wrong side is pushed back rather than kept there.
    pub boundary_sides: Vec<Vec<i8>>,
    /// Each agent's acceleration just before the horizon (a prior stitched after a lead-in): the
    /// jerk of the first step is counted against it. Empty: not counted.
    pub previous_accel_mps2: Vec<f64>,
}

/// Raw (unweighted) energies and the weighted total.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct EnergyBreakdown {
    /// `E_anch`, m².
    pub anchor: f64,
    /// `E_bound`, m².
    pub boundary: f64,
    /// `E_clear`, m².
    pub clearance: f64,
    /// `E_kin`.
    pub kinematic: f64,
    /// `Σ λ E`.
    pub total: f64,
}

/// The guidance energy of one problem: configuration and conditioning, checked.
#[derive(Debug, Clone, PartialEq)]
pub struct Guidance {
    config: GuidanceConfig,
    context: GuidanceContext,
}

fn check(field: &'static str, ok: bool, value: f64, what: &str) -> Result<(), GuidanceError> {
    if ok { Ok(()) } else { Err(GuidanceError::InvalidConfig { field, reason: format!("{what}, got {value}") }) }
}

impl Guidance {
    /// Checks the configuration and context.
    pub fn new(config: GuidanceConfig, context: GuidanceContext) -> Result<Self, GuidanceError> {
        let c = &config;
        check("agents", c.agents >= 1, c.agents as f64, "must be at least 1")?;
        check("steps", c.steps >= 1, c.steps as f64, "must be at least 1")?;
        check("dt_s", c.dt_s > 0.0 && c.dt_s.is_finite(), c.dt_s, "must be positive and finite")?;
        let w = c.weights;
        for (field, v) in [
            ("weights.anchor", w.anchor),
            ("weights.boundary", w.boundary),
            ("weights.clearance", w.clearance),
            ("weights.kinematic", w.kinematic),
            ("boundary_margin_m", c.boundary_margin_m),
            ("clearance_radius_m", c.clearance_radius_m),
            ("limits.accel_max_mps2", c.limits.accel_max_mps2),
            ("limits.lat_accel_max_mps2", c.limits.lat_accel_max_mps2),
            ("limits.jerk_max_mps3", c.limits.jerk_max_mps3),
            ("limits.speed_max_mps", c.limits.speed_max_mps),
        ] {
            check(field, v >= 0.0 && v.is_finite(), v, "must be non-negative and finite")?;
        }
        let a_min = c.limits.accel_min_mps2;
        check("limits.accel_min_mps2", a_min <= 0.0 && a_min.is_finite(), a_min, "must be non-positive and finite")?;
        for a in &context.anchors {
            check("anchors.agent", a.agent < c.agents, a.agent as f64, "must be an agent index")?;
            let ok = a.position.is_finite() && a.time_s.is_finite();
            check("anchors.position/time_s", ok, a.time_s, "must be finite")?;
        }
        for (i, b) in context.boundaries.iter().enumerate() {
            if let Some(k) = b.iter().position(|p| !p.is_finite()) {
                return Err(GuidanceError::InvalidConfig {
                    field: "boundaries",
                    reason: format!("point {k} of boundary {i} is not finite"),
                });
            }
        }
        for w in &context.conflict_windows {
            let ok = w.agent_a < c.agents && w.agent_b < c.agents && !w.from_s.is_nan() && !w.to_s.is_nan();
            check("conflict_windows", ok, w.from_s, "need agent indices and non-NaN times")?;
        }
        let n_sides = context.boundary_sides.len();
        check(
            "boundary_sides",
            n_sides == 0 || n_sides == c.agents,
            n_sides as f64,
            "needs none or one row per agent",
        )?;
        let n_prev = context.previous_accel_mps2.len();
        check("previous_accel_mps2", n_prev == 0 || n_prev == c.agents, n_prev as f64, "needs none or one per agent")?;
        for a in &context.previous_accel_mps2 {
            check("previous_accel_mps2", a.is_finite(), *a, "must be finite")?;
        }
        Ok(Self { config, context })
    }

    /// The configuration.
    pub fn config(&self) -> &GuidanceConfig {
        &self.config
    }

    /// The conditioning.
    pub fn context(&self) -> &GuidanceContext {
        &self.context
    }

    /// Number of controls of the joint tensor, `N · T`.
    pub fn len(&self) -> usize {
        self.config.agents * self.config.steps
    }

    /// Never true (a problem has at least one agent and one step).
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The energy `E(Rollout(x0s, controls))` and its gradient with respect to `controls` written
    /// into `out_grad` (same layout, agent-major). No allocation.
    pub fn energy_and_grad(
        &self,
        ws: &mut GuidanceWorkspace,
        x0s: &[State],
        controls: &[Control],
        out_grad: &mut [Control],
    ) -> Result<EnergyBreakdown, GuidanceError> {
        let (n, t_len) = (self.config.agents, self.config.steps);
        let shape = |what, expected, got| {
            if expected == got { Ok(()) } else { Err(GuidanceError::Shape { what, expected, got }) }
        };
        shape("x0s", n, x0s.len())?;
        shape("controls", n * t_len, controls.len())?;
        shape("out_grad", n * t_len, out_grad.len())?;
        shape("workspace", n, ws.states.len())?;
        shape("workspace", n * t_len, ws.vjp.len() * n)?;
        if let Some(index) = x0s.iter().position(|x| !x.is_finite()) {
            return Err(GuidanceError::NonFiniteInput { what: "x0s", index });
        }
        if let Some(index) = controls.iter().position(|u| !u.is_finite()) {
            return Err(GuidanceError::NonFiniteInput { what: "controls", index });
        }
        let dt = self.config.dt_s;
        for ((xs, g), (x0, u)) in
            ws.states.iter_mut().zip(ws.state_grads.iter_mut()).zip(x0s.iter().zip(controls.chunks_exact(t_len)))
        {
            rollout_into(*x0, u, dt, xs);
            g.iter_mut().for_each(|s| *s = State::default());
        }
        out_grad.iter_mut().for_each(|g| *g = Control::default());

        let w = self.config.weights;
        let ctx = &self.context;
        let mut e = EnergyBreakdown {
            anchor: terms::anchor_energy(&ctx.anchors, dt, &ws.states, &mut ws.state_grads, w.anchor),
            boundary: terms::boundary_energy(
                &ctx.boundaries,
                &ctx.boundary_sides,
                self.config.boundary_margin_m,
                &ws.states,
                &mut ws.state_grads,
                w.boundary,
            ),
            clearance: terms::clearance_energy(
                &ctx.conflict_windows,
                self.config.clearance_radius_m,
                dt,
                &ws.states,
                &mut ws.state_grads,
                w.clearance,
            ),
            kinematic: 0.0,
            total: 0.0,
        };
        for (agent, ((xs, g), (u, ug))) in ws
            .states
            .iter()
            .zip(ws.state_grads.iter_mut())
            .zip(controls.chunks_exact(t_len).zip(out_grad.chunks_exact_mut(t_len)))
            .enumerate()
        {
            let previous = ctx.previous_accel_mps2.get(agent).copied();
            e.kinematic += terms::kinematic_energy(&self.config.limits, dt, (xs, u), (g, ug), w.kinematic, previous);
        }
        for ((xs, g), (u, ug)) in ws
            .states
            .iter()
            .zip(ws.state_grads.iter())
            .zip(controls.chunks_exact(t_len).zip(out_grad.chunks_exact_mut(t_len)))
        {
            rollout_vjp_into(xs, u, dt, g, &mut ws.vjp)?;
            for (o, d) in ug.iter_mut().zip(&ws.vjp) {
                o.accel_mps2 += d.accel_mps2;
                o.yaw_rate_radps += d.yaw_rate_radps;
            }
        }
        e.total = w.anchor * e.anchor + w.boundary * e.boundary + w.clearance * e.clearance + w.kinematic * e.kinematic;
        let finite = [e.anchor, e.boundary, e.clearance, e.kinematic, e.total].iter().all(|v| v.is_finite())
            && out_grad.iter().all(Control::is_finite);
        if finite { Ok(e) } else { Err(GuidanceError::NonFiniteResult) }
    }
}

/// Preallocated buffers of one problem shape: rolled-out states, their gradients and the adjoint's
/// output.
#[derive(Debug, Clone)]
pub struct GuidanceWorkspace {
    states: Vec<Vec<State>>,
    state_grads: Vec<Vec<State>>,
    vjp: Vec<Control>,
    pub(crate) controls: Vec<Control>,
    pub(crate) grad: Vec<Control>,
}

impl GuidanceWorkspace {
    /// Buffers for `guidance`'s shape.
    pub fn new(guidance: &Guidance) -> Self {
        let (n, t) = (guidance.config.agents, guidance.config.steps);
        Self {
            states: vec![Vec::with_capacity(t + 1); n],
            state_grads: vec![vec![State::default(); t + 1]; n],
            vjp: vec![Control::default(); t],
            controls: vec![Control::default(); n * t],
            grad: vec![Control::default(); n * t],
        }
    }

    /// The states of the last evaluation, agent `i`'s `T + 1` states (empty before the first).
    pub fn states(&self, agent: usize) -> &[State] {
        self.states.get(agent).map_or(&[], Vec::as_slice)
    }
}
