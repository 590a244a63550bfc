//! Trajectory priors: the reference trajectories the diffusion model generates for every agent, on
//! one fixed time grid, which the cloud uploads to the BVs.

use serde::{Deserialize, Serialize};

use crate::grounded::{AgentRole, GroundedConflict, GroundedScenario, MIN_START_SEPARATION_M};
use crate::kinematics::{Control, State, step};
use crate::path::ReferencePath;
use crate::validate::plausible::{
    self, MAX_ACCEL_MPS2, MAX_AGENTS, MAX_SCENARIO_TIME_S, MAX_SPEED_MPS, MAX_YAW_RATE_RADPS,
};
use crate::validate::{Validate, ValidationError, in_range};
use crate::{Style, Target};

/// One agent's reference: `states[k]` at `t = k·dt`, `controls[k]` applied over `[k·dt, (k+1)·dt)`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AgentTrajectory {
    /// Agent id, as in the grounded scenario.
    pub id: String,
    /// VUT or BV.
    pub role: AgentRole,
    /// States `[px, py, θ, v]`, one more than controls.
    pub states: Vec<State>,
    /// Controls `[a, ω]`.
    pub controls: Vec<Control>,
}

/// The priors for one scenario. Its file is `TrajectoryPriorFile`'s layout: the target as the two
/// keys `tau_s` and `style`, range-checked as the file is read.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "TrajectoryPriorFile", into = "TrajectoryPriorFile")]
pub struct TrajectoryPrior {
    /// Grounded fragment id.
    pub fragment_id: String,
    /// Time step of every trajectory, s.
    pub dt_s: f64,
    /// One trajectory per agent.
    pub agents: Vec<AgentTrajectory>,
    /// Conflicts between each BV and the VUT.
    pub conflicts: Vec<GroundedConflict>,
    /// Target PET τ and who passes first.
    pub target: Target,
}

/// The file form of a [`TrajectoryPrior`]: its fields in the same order, the target written as
/// `tau_s` (s) and `style`.
#[derive(Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct TrajectoryPriorFile {
    fragment_id: String,
    dt_s: f64,
    agents: Vec<AgentTrajectory>,
    conflicts: Vec<GroundedConflict>,
    tau_s: f64,
    style: Style,
}

impl TryFrom<TrajectoryPriorFile> for TrajectoryPrior {
    type Error = ValidationError;

    fn try_from(f: TrajectoryPriorFile) -> Result<Self, Self::Error> {
        Ok(Self {
            fragment_id: f.fragment_id,
            dt_s: f.dt_s,
            agents: f.agents,
            conflicts: f.conflicts,
            target: Target::from_keys(f.tau_s, f.style)?,
        })
    }
}

impl From<TrajectoryPrior> for TrajectoryPriorFile {
    fn from(p: TrajectoryPrior) -> Self {
        Self {
            fragment_id: p.fragment_id,
            dt_s: p.dt_s,
            agents: p.agents,
            conflicts: p.conflicts,
            tau_s: p.target.tau_s(),
            style: p.target.style(),
        }
    }
}

impl TrajectoryPrior {
    /// The BV agent `agent` names, or the first BV when `None`.
    pub fn bv_agent(&self, agent: Option<&str>) -> Result<&AgentTrajectory, ValidationError> {
        let mut bvs = self.agents.iter().filter(|a| a.role == AgentRole::Bv);
        match agent {
            Some(id) => bvs
                .find(|a| a.id == id)
                .ok_or_else(|| ValidationError::new("agents", format!("has no BV agent `{id}`"))),
            None => bvs.next().ok_or_else(|| ValidationError::new("agents", "has no BV agent")),
        }
    }

    /// The predefined reference of the TroubleMaker-like baseline and the stand-in where no
    /// diffusion prior exists: every agent of `scenario` drives its route at its start speed,
    /// sampled at 10 Hz over `horizon_s`; controls are the yaw rates of the path (acceleration 0),
    /// so states and controls agree to the path's discretization. The grounded timing is kept: an
    /// agent due at its start anchor `t0` later than the earliest one starts `v · t0` before it, on
    /// a straight lead-in along its start heading, so that every agent keeps moving and the planned
    /// PET holds. An agent that reaches its route's end before `horizon_s` drives on, straight
    /// along the route's last heading, at its speed (a state that stood at the end while its speed
    /// said it drives would not be motion).
    pub fn along_routes_at_start_speed(scenario: &GroundedScenario, horizon_s: f64) -> Result<Self, ValidationError> {
        let dt = 0.1;
        if !(horizon_s >= dt && horizon_s <= 600.0) {
            return Err(ValidationError::new("horizon_s", format!("must lie in [0.1, 600] s, got {horizon_s}")));
        }
        let n = (horizon_s / dt).round() as usize;
        let t_first = scenario.agents.iter().filter_map(|a| a.start.time_s).fold(f64::INFINITY, f64::min);
        let mut agents = Vec::with_capacity(scenario.agents.len());
        for a in &scenario.agents {
            let lead_m = match a.start.time_s {
                Some(t0) if t0 > t_first => (t0 - t_first) * a.start.speed_mps,
                _ => 0.0,
            };
            let mut route = a.route.clone();
            if lead_m > 0.01 {
                let back = crate::geometry::Point2::from_heading(a.start.heading_rad).scale(-lead_m);
                if let Some(first) = a.route.first() {
                    route.insert(0, first.add(back));
                }
            }
            let v = a.start.speed_mps;
            if let [.., before, last] = route.as_slice() {
                let lead_out_m = v * horizon_s + 1.0;
                let along = last.sub(*before);
                let norm = along.norm();
                if norm > 0.0 {
                    let end = last.add(along.scale(lead_out_m / norm));
                    route.push(end);
                }
            }
            let path = ReferencePath::from_points(&route)
                .map_err(|e| ValidationError::new(format!("{}.route", a.id), e.to_string()))?;
            let states: Vec<State> = (0..=n)
                .map(|k| {
                    let s = (v * k as f64 * dt).min(path.length());
                    let p = path.point_at(s);
                    State { px: p.x, py: p.y, theta_rad: path.heading_at(s), speed_mps: v }
                })
                .collect();
            let controls = states
                .windows(2)
                .map(|w| match w {
                    [x0, x1] => {
                        let d = (x1.theta_rad - x0.theta_rad + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU)
                            - std::f64::consts::PI;
                        Control { accel_mps2: 0.0, yaw_rate_radps: d / dt }
                    }
                    _ => Control::default(),
                })
                .collect();
            agents.push(AgentTrajectory { id: a.id.clone(), role: a.role, states, controls });
        }
        let prior = Self::of_scenario(scenario, dt, agents);
        prior.validate()?;
        Ok(prior)
    }

    /// A prior of `scenario`'s fragment, conflicts, τ and style with these agents (not validated).
    pub fn of_scenario(scenario: &GroundedScenario, dt_s: f64, agents: Vec<AgentTrajectory>) -> Self {
        Self {
            fragment_id: scenario.fragment_id.clone(),
            dt_s,
            agents,
            conflicts: scenario.conflicts.clone(),
            target: scenario.target,
        }
    }

    /// The constant-speed stand-in prior of `g`: every agent drives its grounded route at its start
    /// speed, keeping the grounded start times, until every one has reached its route's end
    /// ([`Self::stand_in_horizon_s`]). The predefined reference of the baselines, and what a
    /// grounded scenario becomes where a prior is expected.
    pub fn stand_in(g: &GroundedScenario) -> Result<Self, ValidationError> {
        Self::along_routes_at_start_speed(g, Self::stand_in_horizon_s(g))
    }

    /// How long [`Self::along_routes_at_start_speed`] must run for every agent of `g` to reach its
    /// route's end, counting the grounded start times (clamped to 1–120 s).
    pub fn stand_in_horizon_s(g: &GroundedScenario) -> f64 {
        let t_first = g.agents.iter().filter_map(|a| a.start.time_s).fold(f64::INFINITY, f64::min);
        g.agents
            .iter()
            .map(|a| {
                let lead = a.start.time_s.map_or(0.0, |t| if t > t_first { t - t_first } else { 0.0 });
                let length: f64 =
                    a.route.windows(2).map(|w| w.first().zip(w.get(1)).map_or(0.0, |(p, q)| p.dist(*q))).sum();
                let drive = if a.start.speed_mps > 0.1 { length / a.start.speed_mps } else { 0.0 };
                drive + lead
            })
            .fold(0.0, f64::max)
            .clamp(1.0, 120.0)
    }

    /// Duration covered, s.
    pub fn duration_s(&self) -> f64 {
        self.agents.iter().map(|a| a.controls.len()).max().unwrap_or(0) as f64 * self.dt_s
    }
}

impl AgentTrajectory {
    /// Largest distance between the stored states and the rollout of the stored controls from the
    /// first state: how far the pair is from being dynamically consistent, m.
    pub fn rollout_gap_m(&self, dt_s: f64) -> f64 {
        let mut x = self.states.first().copied().unwrap_or_default();
        let mut worst: f64 = 0.0;
        for (u, s) in self.controls.iter().zip(self.states.iter().skip(1)) {
            x = step(x, *u, dt_s);
            worst = worst.max(x.position().dist(s.position()));
        }
        worst
    }
}

impl Validate for AgentTrajectory {
    fn validate(&self) -> Result<(), ValidationError> {
        if self.id.trim().is_empty() {
            return Err(ValidationError::new("id", "must not be empty"));
        }
        if self.controls.is_empty() || self.states.len() != self.controls.len() + 1 {
            return Err(ValidationError::new(
                "states",
                format!(
                    "need controls ≥ 1 and states = controls + 1, got {} states and {} controls",
                    self.states.len(),
                    self.controls.len()
                ),
            ));
        }
        if let Some(i) = self.states.iter().position(|s| !s.is_finite()) {
            return Err(ValidationError::new(format!("states[{i}]"), "must be finite"));
        }
        if let Some(i) = self.controls.iter().position(|u| !u.is_finite()) {
            return Err(ValidationError::new(format!("controls[{i}]"), "must be finite"));
        }
        for (i, s) in self.states.iter().enumerate() {
            let field = format!("states[{i}]");
            plausible::coordinates(&field, s.px, s.py)?;
            in_range(&format!("{field}.speed_mps"), s.speed_mps, 0.0, MAX_SPEED_MPS)?;
        }
        for (i, u) in self.controls.iter().enumerate() {
            in_range(&format!("controls[{i}].accel_mps2"), u.accel_mps2, -MAX_ACCEL_MPS2, MAX_ACCEL_MPS2)?;
            let field = format!("controls[{i}].yaw_rate_radps");
            in_range(&field, u.yaw_rate_radps, -MAX_YAW_RATE_RADPS, MAX_YAW_RATE_RADPS)?;
        }
        Ok(())
    }
}

impl AgentTrajectory {
    /// The first step between two states longer than a vehicle drives in `dt_s`
    /// ([`plausible::teleported`]): `(index of the later state, distance, m)`.
    pub fn first_jump(&self, dt_s: f64) -> Option<(usize, f64)> {
        self.states.windows(2).enumerate().find_map(|(i, w)| {
            let d = w.first().zip(w.get(1)).map_or(0.0, |(a, b)| a.position().dist(b.position()));
            plausible::teleported(d, dt_s).then_some((i + 1, d))
        })
    }
}

impl Validate for TrajectoryPrior {
    fn validate(&self) -> Result<(), ValidationError> {
        in_range("dt_s", self.dt_s, 0.001, 1.0)?;
        if self.agents.is_empty() {
            return Err(ValidationError::new("agents", "needs at least one trajectory"));
        }
        if self.agents.len() > MAX_AGENTS {
            return Err(ValidationError::new(
                "agents",
                format!("has {} trajectories, at most {MAX_AGENTS} are accepted", self.agents.len()),
            ));
        }
        self.agents.validate().map_err(|e| e.within("agents"))?;
        let n = self.agents.first().map(|a| a.controls.len()).unwrap_or(0);
        if let Some(i) = self.agents.iter().position(|a| a.controls.len() != n) {
            return Err(ValidationError::new(format!("agents[{i}].controls"), "every agent must share one time grid"));
        }
        let horizon_s = n as f64 * self.dt_s;
        if horizon_s > MAX_SCENARIO_TIME_S {
            return Err(ValidationError::new(
                "agents[0].controls",
                format!("cover {horizon_s:.0} s, at most {MAX_SCENARIO_TIME_S} s are accepted"),
            ));
        }
        for (i, a) in self.agents.iter().enumerate() {
            if let Some((k, d)) = a.first_jump(self.dt_s) {
                return Err(ValidationError::new(
                    format!("agents[{i}].states[{k}]"),
                    format!(
                        "lies {d:.1} m from the state before it, {:.1} m is the most a vehicle drives in dt_s = {} s",
                        MAX_SPEED_MPS * self.dt_s + plausible::STEP_SLACK_M,
                        self.dt_s
                    ),
                ));
            }
            let samples = a.states.iter().enumerate().map(|(k, x)| (k as f64 * self.dt_s, *x));
            plausible::kinematics(|k| format!("agents[{i}].states[{k}]"), samples)?;
            if self.agents.iter().skip(i + 1).any(|b| b.id == a.id) {
                return Err(ValidationError::new(format!("agents[{i}].id"), format!("`{}` is used twice", a.id)));
            }
            let start = a.states.first().map(State::position).unwrap_or_default();
            let near = |b: &&AgentTrajectory| {
                b.states.first().is_some_and(|x| x.position().dist(start) < MIN_START_SEPARATION_M)
            };
            if let Some(b) = self.agents.iter().skip(i + 1).find(near) {
                let apart = b.states.first().map_or(0.0, |x| x.position().dist(start));
                return Err(ValidationError::new(
                    format!("agents[{i}].states[0]"),
                    format!(
                        "`{}` starts {apart:.2} m from `{}`: two vehicles closer than {MIN_START_SEPARATION_M} m overlap",
                        a.id, b.id
                    ),
                ));
            }
        }
        self.conflicts.validate().map_err(|e| e.within("conflicts"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kinematics::rollout;

    fn prior() -> TrajectoryPrior {
        let controls = vec![Control { accel_mps2: 0.5, yaw_rate_radps: 0.05 }; 40];
        let states = rollout(State { px: 0.0, py: 0.0, theta_rad: 0.0, speed_mps: 8.0 }, &controls, 0.1);
        TrajectoryPrior {
            fragment_id: "x1".into(),
            dt_s: 0.1,
            agents: vec![AgentTrajectory { id: "bv1".into(), role: AgentRole::Bv, states, controls }],
            conflicts: vec![],
            target: Target::new(2.0, Style::Rush).unwrap(),
        }
    }

    #[test]
    fn a_rolled_out_prior_is_valid_and_consistent() {
        let p = prior();
        p.validate().unwrap();
        assert!(p.agents[0].rollout_gap_m(p.dt_s) < 1e-12);
        assert!((p.duration_s() - 4.0).abs() < 1e-12);
        let back: TrajectoryPrior = serde_json::from_str(&serde_json::to_string(&p).unwrap()).unwrap();
        assert_eq!(back, p);
    }

    #[test]
    fn bad_priors_name_the_field() {
        let mut p = prior();
        p.agents[0].states[3].speed_mps = f64::NAN;
        assert_eq!(p.validate().unwrap_err().field, "agents[0].states[3]");
        let mut q = prior();
        q.agents[0].states.pop();
        assert_eq!(q.validate().unwrap_err().field, "agents[0].states");
        let mut r = prior();
        r.dt_s = -0.1;
        assert_eq!(r.validate().unwrap_err().field, "dt_s");
    }

    #[test]
    fn implausible_priors_are_refused_with_the_bound() {
        // A state far out (a hostile or broken file; it hung the route loops downstream).
        let mut p = prior();
        p.agents[0].states[5].px = 1e300;
        let e = p.validate().unwrap_err();
        assert_eq!(e.field, "agents[0].states[5].x");
        assert!(e.problem.contains("100000000"), "{e}");
        // A jump no vehicle drives in one step.
        let mut q = prior();
        q.agents[0].states[7].py += 50.0;
        let e = q.validate().unwrap_err();
        assert_eq!(e.field, "agents[0].states[7]");
        assert!(e.problem.contains("11.0 m is the most"), "{e}");
        // Speeds, accelerations and yaw rates beyond any vehicle's.
        let mut r = prior();
        r.agents[0].states[2].speed_mps = 150.0;
        assert_eq!(r.validate().unwrap_err().field, "agents[0].states[2].speed_mps");
        let mut a = prior();
        a.agents[0].controls[0].accel_mps2 = -31.0;
        assert_eq!(a.validate().unwrap_err().field, "agents[0].controls[0].accel_mps2");
        let mut w = prior();
        w.agents[0].controls[1].yaw_rate_radps = 9.0;
        assert_eq!(w.validate().unwrap_err().field, "agents[0].controls[1].yaw_rate_radps");
        // A horizon of more than an hour.
        let mut h = prior();
        h.dt_s = 1.0;
        let controls = vec![Control { accel_mps2: 0.0, yaw_rate_radps: 0.0 }; 3601];
        h.agents[0].states = rollout(State { px: 0.0, py: 0.0, theta_rad: 0.0, speed_mps: 1.0 }, &controls, 1.0);
        h.agents[0].controls = controls;
        let e = h.validate().unwrap_err();
        assert!(e.problem.contains("3601 s, at most 3600 s"), "{e}");
        // More agents than any scenario has.
        let mut many = prior();
        many.agents = vec![many.agents[0].clone(); MAX_AGENTS + 1];
        assert_eq!(many.validate().unwrap_err().field, "agents");
    }

    #[test]
    fn motion_that_is_not_motion_is_refused() {
        // Negative speeds: a car reversing down its route.
        let mut back = prior();
        let controls = vec![Control { accel_mps2: 0.0, yaw_rate_radps: 0.0 }; 40];
        back.agents[0].states = rollout(State { px: 0.0, py: 0.0, theta_rad: 0.0, speed_mps: -3.0 }, &controls, 0.1);
        back.agents[0].controls = controls;
        let e = back.validate().unwrap_err();
        assert!(e.field == "agents[0].states[0].speed_mps" && e.problem.contains("[0, 100]"), "{e}");
        // Every state identical while the speed says 12.5 m/s.
        let mut still = prior();
        let x = State { px: 10.0, py: 5.0, theta_rad: 0.3, speed_mps: 12.5 };
        still.agents[0].states.iter_mut().for_each(|s| *s = x);
        still.agents[0].controls.iter_mut().for_each(|u| *u = Control::default());
        let e = still.validate().unwrap_err();
        assert!(e.field == "agents[0].states[10]" && e.problem.contains("say 12.50 to 12.50 m"), "{e}");
        // Driving against its own heading.
        let mut against = prior();
        against.agents[0].states.iter_mut().for_each(|s| s.theta_rad += std::f64::consts::PI);
        let e = against.validate().unwrap_err();
        assert!(e.field == "agents[0].states[10]" && e.problem.contains("away from its heading"), "{e}");
        // Two agents that start on each other, and one id twice.
        let mut two = prior();
        let mut vut = two.agents[0].clone();
        vut.id = "vut".into();
        vut.role = AgentRole::Vut;
        vut.states.iter_mut().for_each(|s| s.py += 1.0);
        two.agents.push(vut);
        let e = two.validate().unwrap_err();
        assert!(e.field == "agents[0].states[0]" && e.problem.contains("`bv1` starts 1.00 m from `vut`"), "{e}");
        two.agents[1].states.iter_mut().for_each(|s| s.py += 3.0);
        two.validate().unwrap();
        two.agents[1].id = "bv1".into();
        assert_eq!(two.validate().unwrap_err().field, "agents[0].id");
    }

    #[test]
    fn the_file_keeps_tau_and_style_as_two_keys_and_refuses_a_tau_out_of_range() {
        let mut p = prior();
        p.agents[0].states.truncate(2);
        p.agents[0].controls.truncate(1);
        let json = serde_json::to_string(&p).unwrap();
        assert!(json.starts_with(r#"{"fragment_id":"x1","dt_s":0.1,"agents":[{"id":"bv1","#), "{json}");
        assert!(json.ends_with(r#""conflicts":[],"tau_s":2.0,"style":"rush"}"#), "{json}");
        let back: TrajectoryPrior = serde_json::from_str(&json).unwrap();
        assert_eq!(back, p);
        assert_eq!(serde_json::to_string(&back).unwrap(), json);
        let e = serde_json::from_str::<TrajectoryPrior>(&json.replace(r#""tau_s":2.0"#, r#""tau_s":0.05"#))
            .unwrap_err()
            .to_string();
        assert!(e.contains("`tau_s`") && e.contains("[0.1, 30]"), "{e}");
        let e = serde_json::from_str::<TrajectoryPrior>(&json.replace(r#""tau_s":2.0,"#, "")).unwrap_err();
        assert!(e.to_string().contains("missing field `tau_s`"), "{e}");
    }
}
