//! A scenario grounded on the track: which map fragment, each agent's route and start/goal anchors,
//! the conflict zone(s), the target PET τ and the style. Produced by `cloud/ground`, consumed by the
//! diffusion model, the regulator and the simulated proving ground.

use serde::{Deserialize, Serialize};

use crate::geometry::Point2;
use crate::metrics::{ConflictKind, OccupancyInterval};
use crate::semantics::InteractionType;
use crate::validate::plausible::{self, MAX_AGENTS, MAX_ROUTE_LENGTH_M, MAX_ROUTE_POINTS, MAX_SCENARIO_TIME_S};
use crate::validate::{Validate, ValidationError, finite, in_range};
use crate::{Style, Target};

/// The vehicle under test or a background vehicle.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum AgentRole {
    /// The vehicle under test (the ADS, the game's follower).
    Vut,
    /// A background vehicle (the game's leader).
    Bv,
}

/// An anchor with the state a vehicle should have there.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AnchorState {
    /// Id of the anchor in the topology library.
    pub anchor_id: String,
    /// Position in the track frame.
    pub position: Point2,
    /// Heading, rad.
    pub heading_rad: f64,
    /// Speed, m/s.
    pub speed_mps: f64,
    /// Time at which the vehicle should be there, s from scenario start, when it matters.
    pub time_s: Option<f64>,
}

impl Validate for AnchorState {
    fn validate(&self) -> Result<(), ValidationError> {
        if self.anchor_id.trim().is_empty() {
            return Err(ValidationError::new("anchor_id", "must not be empty"));
        }
        plausible::coordinates("position", self.position.x, self.position.y)?;
        finite("heading_rad", self.heading_rad)?;
        in_range("speed_mps", self.speed_mps, 0.0, 70.0)?;
        if let Some(t) = self.time_s {
            in_range("time_s", t, 0.0, MAX_SCENARIO_TIME_S)?;
        }
        Ok(())
    }
}

/// Shortest route of an agent, m: a route that does not run (one point repeated) is no route.
pub const MIN_ROUTE_LENGTH_M: f64 = 1.0;
/// Closest two agents may start, m (centre to centre): narrower than any car, so two closer
/// vehicles overlap.
pub const MIN_START_SEPARATION_M: f64 = 1.5;

/// One agent of a grounded scenario.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GroundedAgent {
    /// Unique id (`vut`, `bv1`, `bv2`).
    pub id: String,
    /// VUT or BV.
    pub role: AgentRole,
    /// Route centreline in the track frame, in driving order.
    pub route: Vec<Point2>,
    /// Start anchor and state.
    pub start: AnchorState,
    /// Goal anchor and state.
    pub goal: AnchorState,
}

/// The conflict between one BV and the VUT.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GroundedConflict {
    /// The BV in this conflict.
    pub bv_id: String,
    /// Crossing or merge.
    pub kind: ConflictKind,
    /// Conflict anchor id in the topology library.
    pub anchor_id: String,
    /// Representative point of the zone.
    pub point: Point2,
    /// Occupancy interval along the VUT's route.
    pub vut_interval: OccupancyInterval,
    /// Occupancy interval along the BV's route.
    pub bv_interval: OccupancyInterval,
    /// Where the BV's route enters the junction the zone lies in (the junction's edge on its lane,
    /// from the map): a BV that gives way stops before it. `null` when the zone is in no junction;
    /// files written before it existed read as `null`. (Always written: the link's binary form has
    /// no optional fields.)
    #[serde(default)]
    pub bv_junction_entry: Option<Point2>,
}

/// A scenario grounded on a map fragment. Its file is `GroundedScenarioFile`'s layout: the target
/// as the two keys `tau_s` and `style`, range-checked as the file is read.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "GroundedScenarioFile", into = "GroundedScenarioFile")]
pub struct GroundedScenario {
    /// Topology fragment the scenario was placed on.
    pub fragment_id: String,
    /// Interaction type from the semantics.
    pub interaction_type: InteractionType,
    /// The VUT and 1–2 BVs.
    pub agents: Vec<GroundedAgent>,
    /// One conflict per BV.
    pub conflicts: Vec<GroundedConflict>,
    /// Target PET τ and who passes first.
    pub target: Target,
}

/// The file form of a [`GroundedScenario`]: its fields in the same order, the target written as
/// `tau_s` (s) and `style`.
#[derive(Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct GroundedScenarioFile {
    fragment_id: String,
    interaction_type: InteractionType,
    agents: Vec<GroundedAgent>,
    conflicts: Vec<GroundedConflict>,
    tau_s: f64,
    style: Style,
}

impl TryFrom<GroundedScenarioFile> for GroundedScenario {
    type Error = ValidationError;

    fn try_from(f: GroundedScenarioFile) -> Result<Self, Self::Error> {
        Ok(Self {
            fragment_id: f.fragment_id,
            interaction_type: f.interaction_type,
            agents: f.agents,
            conflicts: f.conflicts,
            target: Target::from_keys(f.tau_s, f.style)?,
        })
    }
}

impl From<GroundedScenario> for GroundedScenarioFile {
    fn from(g: GroundedScenario) -> Self {
        Self {
            fragment_id: g.fragment_id,
            interaction_type: g.interaction_type,
            agents: g.agents,
            conflicts: g.conflicts,
            tau_s: g.target.tau_s(),
            style: g.target.style(),
        }
    }
}

impl GroundedScenario {
    /// The VUT.
    pub fn vut(&self) -> Option<&GroundedAgent> {
        self.agents.iter().find(|a| a.role == AgentRole::Vut)
    }

    /// The BVs, in order.
    pub fn bvs(&self) -> impl Iterator<Item = &GroundedAgent> {
        self.agents.iter().filter(|a| a.role == AgentRole::Bv)
    }
}

fn check_interval(field: &str, i: &OccupancyInterval) -> Result<(), ValidationError> {
    in_range(&format!("{field}.enter_s_m"), i.enter_s_m, -MAX_ROUTE_LENGTH_M, MAX_ROUTE_LENGTH_M)?;
    in_range(&format!("{field}.exit_s_m"), i.exit_s_m, -MAX_ROUTE_LENGTH_M, MAX_ROUTE_LENGTH_M)?;
    if i.exit_s_m > i.enter_s_m {
        Ok(())
    } else {
        Err(ValidationError::new(field, format!("exit {} must be beyond entry {}", i.exit_s_m, i.enter_s_m)))
    }
}

impl Validate for GroundedAgent {
    fn validate(&self) -> Result<(), ValidationError> {
        if self.id.trim().is_empty() {
            return Err(ValidationError::new("id", "must not be empty"));
        }
        if self.route.len() < 2 {
            return Err(ValidationError::new("route", format!("needs at least 2 points, got {}", self.route.len())));
        }
        if self.route.len() > MAX_ROUTE_POINTS {
            return Err(ValidationError::new(
                "route",
                format!("has {} points, at most {MAX_ROUTE_POINTS} are accepted", self.route.len()),
            ));
        }
        for (i, p) in self.route.iter().enumerate() {
            plausible::coordinates(&format!("route[{i}]"), p.x, p.y)?;
        }
        let length: f64 = self.route.windows(2).map(|w| w.first().zip(w.get(1)).map_or(0.0, |(p, q)| p.dist(*q))).sum();
        if length < MIN_ROUTE_LENGTH_M {
            return Err(ValidationError::new(
                "route",
                format!(
                    "is {length:.3} m long over {} points: a route must run at least {MIN_ROUTE_LENGTH_M} m",
                    self.route.len()
                ),
            ));
        }
        if length > MAX_ROUTE_LENGTH_M {
            return Err(ValidationError::new(
                "route",
                format!("is {length:.0} m long, at most {MAX_ROUTE_LENGTH_M} m are accepted"),
            ));
        }
        self.start.validate().map_err(|e| e.within("start"))?;
        self.goal.validate().map_err(|e| e.within("goal"))
    }
}

impl Validate for GroundedConflict {
    fn validate(&self) -> Result<(), ValidationError> {
        plausible::coordinates("point", self.point.x, self.point.y)?;
        check_interval("vut_interval", &self.vut_interval)?;
        check_interval("bv_interval", &self.bv_interval)?;
        match self.bv_junction_entry {
            Some(q) => plausible::coordinates("bv_junction_entry", q.x, q.y),
            None => Ok(()),
        }
    }
}

impl Validate for GroundedScenario {
    fn validate(&self) -> Result<(), ValidationError> {
        if self.fragment_id.trim().is_empty() {
            return Err(ValidationError::new("fragment_id", "must not be empty"));
        }
        if self.agents.len() > MAX_AGENTS {
            return Err(ValidationError::new(
                "agents",
                format!("has {} agents, at most {MAX_AGENTS} are accepted", self.agents.len()),
            ));
        }
        self.agents.validate().map_err(|e| e.within("agents"))?;
        let vuts = self.agents.iter().filter(|a| a.role == AgentRole::Vut).count();
        if vuts != 1 {
            return Err(ValidationError::new("agents", format!("needs exactly one VUT, got {vuts}")));
        }
        let bvs = self.bvs().count();
        if !(1..=2).contains(&bvs) {
            return Err(ValidationError::new("agents", format!("needs 1 or 2 BVs, got {bvs}")));
        }
        for (i, a) in self.agents.iter().enumerate() {
            if self.agents.iter().skip(i + 1).any(|b| b.id == a.id) {
                return Err(ValidationError::new(format!("agents[{i}].id"), format!("`{}` is used twice", a.id)));
            }
            let p = a.start.position;
            if let Some(b) = self.agents.iter().skip(i + 1).find(|b| b.start.position.dist(p) < MIN_START_SEPARATION_M)
            {
                return Err(ValidationError::new(
                    format!("agents[{i}].start.position"),
                    format!(
                        "`{}` starts {:.2} m from `{}`: two vehicles closer than {MIN_START_SEPARATION_M} m overlap",
                        a.id,
                        b.start.position.dist(p),
                        b.id
                    ),
                ));
            }
        }
        self.conflicts.validate().map_err(|e| e.within("conflicts"))?;
        for (i, c) in self.conflicts.iter().enumerate() {
            if !self.bvs().any(|b| b.id == c.bv_id) {
                return Err(ValidationError::new(
                    format!("conflicts[{i}].bv_id"),
                    format!("`{}` is not a BV of this scenario", c.bv_id),
                ));
            }
        }
        if self.conflicts.is_empty() {
            return Err(ValidationError::new("conflicts", "needs at least one conflict"));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing)]
    use super::*;

    fn anchor(x: f64) -> AnchorState {
        AnchorState {
            anchor_id: "a".into(),
            position: Point2 { x, y: 0.0 },
            heading_rad: 0.0,
            speed_mps: 10.0,
            time_s: Some(0.0),
        }
    }

    fn agent(id: &str, role: AgentRole) -> GroundedAgent {
        let route = (0..=100).map(|i| Point2 { x: f64::from(i), y: 0.0 }).collect();
        GroundedAgent { id: id.into(), role, route, start: anchor(0.0), goal: anchor(100.0) }
    }

    fn scenario() -> GroundedScenario {
        let interval = OccupancyInterval { enter_s_m: 40.0, exit_s_m: 45.0 };
        GroundedScenario {
            fragment_id: "f".into(),
            interaction_type: InteractionType::CutIn,
            agents: vec![agent("vut", AgentRole::Vut), {
                // The next lane over, as in a cut-in.
                let mut bv = agent("bv1", AgentRole::Bv);
                bv.start.position.y = 3.5;
                bv
            }],
            conflicts: vec![GroundedConflict {
                bv_id: "bv1".into(),
                kind: ConflictKind::Merge,
                anchor_id: "c".into(),
                point: Point2 { x: 42.0, y: 0.0 },
                vut_interval: interval,
                bv_interval: interval,
                bv_junction_entry: None,
            }],
            target: Target::new(2.0, Style::Rush).unwrap(),
        }
    }

    #[test]
    fn implausible_scenarios_are_refused_with_the_bound() {
        scenario().validate().unwrap();
        // One route point far away (it hung `generate` and aborted `export xosc`).
        let mut g = scenario();
        g.agents[1].route[50].x = 1e9;
        let e = g.validate().unwrap_err();
        assert_eq!(e.field, "agents[1].route[50].x");
        assert!(e.problem.contains("100000000"), "{e}");
        // A route within the bound of coordinates but longer than any test drives.
        let mut long = scenario();
        long.agents[0].route = vec![Point2 { x: 0.0, y: 0.0 }, Point2 { x: 6e4, y: 0.0 }];
        let e = long.validate().unwrap_err();
        assert!(e.field == "agents[0].route" && e.problem.contains("at most 50000 m"), "{e}");
        // A start an age after the scenario's (it exported a BV at x = 1.1e10 m).
        let mut late = scenario();
        late.agents[1].start.time_s = Some(1e9);
        assert_eq!(late.validate().unwrap_err().field, "agents[1].start.time_s");
        // A conflict interval beyond any route.
        let mut far = scenario();
        far.conflicts[0].vut_interval.exit_s_m = 1e12;
        assert_eq!(far.validate().unwrap_err().field, "conflicts[0].vut_interval.exit_s_m");
    }

    /// Motion that is not motion: a route of one point repeated (it exported, and `generate`
    /// exited 1 without naming the file), and a BV that starts on the VUT.
    #[test]
    fn a_route_that_does_not_run_and_agents_that_start_on_each_other_are_refused() {
        let mut still = scenario();
        still.agents[0].route = vec![Point2 { x: 5.0, y: 0.0 }; 300];
        let e = still.validate().unwrap_err();
        assert!(e.field == "agents[0].route" && e.problem.contains("at least 1 m"), "{e}");
        let mut on_top = scenario();
        on_top.agents[1].start.position = Point2 { x: 0.4, y: 0.3 };
        let e = on_top.validate().unwrap_err();
        assert_eq!(e.field, "agents[0].start.position");
        assert!(e.problem.contains("`vut` starts 0.50 m from `bv1`") && e.problem.contains("1.5 m"), "{e}");
    }

    #[test]
    fn the_file_keeps_tau_and_style_as_two_keys_and_refuses_a_tau_out_of_range() {
        let g = scenario();
        let json = serde_json::to_string_pretty(&g).unwrap();
        let keys: Vec<&str> = json.lines().filter(|l| l.starts_with("  \"")).map(str::trim).collect();
        assert_eq!(keys.last().copied(), Some("\"style\": \"rush\""), "{json}");
        assert_eq!(keys.get(keys.len() - 2).copied(), Some("\"tau_s\": 2.0,"), "{json}");
        let back: GroundedScenario = serde_json::from_str(&json).unwrap();
        assert_eq!(back, g);
        assert_eq!(serde_json::to_string_pretty(&back).unwrap(), json);
        let e = serde_json::from_str::<GroundedScenario>(&json.replace("\"tau_s\": 2.0", "\"tau_s\": 31.0"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("`tau_s`") && e.contains("[0.1, 30]"), "{e}");
        let e = serde_json::from_str::<GroundedScenario>(&json.replace("\"rush\"", "\"fast\"")).unwrap_err();
        assert!(e.to_string().contains("fast"), "{e}");
        let e = serde_json::from_str::<GroundedScenario>(&json.replacen('{', "{\"x\": 1,", 1)).unwrap_err();
        assert!(e.to_string().contains("unknown field `x`"), "{e}");
    }
}
