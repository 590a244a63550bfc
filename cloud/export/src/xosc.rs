//! OpenSCENARIO 1.2 export, pure: a scenario's agents with their timed states go in, the text of a
//! `.xosc` file comes out. No IO, no clock: the shell ([`crate::file`]) reads the input and the
//! vehicle files, resolves the map's path and passes the date.
//!
//! Three inputs are understood ([`parse_input`]): a `TrajectoryPrior` (`dt_s`), a
//! `GroundedScenario` (`fragment_id` and `agents` with `route`: every agent drives its route at its
//! start speed, [`TrajectoryPrior::along_routes_at_start_speed`]) and a run written by
//! `video2track sim --json` (`trace`). What is written:
//!
//! - the header (revision 1.2, the date, the source, τ and style), τ and style as parameters, empty
//!   catalog locations, the map as `RoadNetwork/LogicFile`;
//! - one `ScenarioObject` per agent with a `car` whose bounding box, performance and axles come
//!   from its vehicle file. Positions are footprint centres (this project's reference point), so the
//!   bounding box is centred on the origin and the axles sit at `-center_to_rear_axle_m` and
//!   `wheelbase_m - center_to_rear_axle_m`;
//! - `Init`: every agent teleported to its first state and given its first speed; the VUT assigned
//!   its route (waypoints along it, strategy `shortest`): the system under test gets its route and
//!   start, never its trajectory;
//! - one story per BV whose event follows its trajectory (a polyline of timed vertices, absolute
//!   timing, position following), sampled every [`VERTEX_PERIOD_S`] and wherever the heading has
//!   turned by [`VERTEX_HEADING_STEP_RAD`] since the last vertex, exact at both ends;
//! - a stop trigger at the end time.
//!
//! ```
//! use v2t_export::xosc::{escape, vertex_indices};
//! assert_eq!(escape("a<b & \"c\""), "a&lt;b &amp; &quot;c&quot;");
//! let times: Vec<f64> = (0..=20).map(|k| k as f64 * 0.1).collect();
//! let headings = vec![0.0; times.len()];
//! assert_eq!(vertex_indices(&times, &headings, 0.5, 0.2), vec![0, 5, 10, 15, 20]);
//! ```

use std::fmt::Write as _;

use v2t_files::{DocumentError, DocumentKeys, PriorDocument, prior_document};
use v2t_model::Style;
use v2t_model::geometry::Point2;
use v2t_model::grounded::{AgentRole, GroundedScenario};
use v2t_model::kinematics::State;
use v2t_model::prior::TrajectoryPrior;
use v2t_model::validate::{Validate as _, ValidationError};
use v2t_model::vehicle::VehicleConfig;
use v2t_sim::runfile::RunFile;

/// Longest time between two trajectory vertices, s.
pub const VERTEX_PERIOD_S: f64 = 0.5;
/// A vertex is also written wherever the heading has turned this much since the last one, rad.
pub const VERTEX_HEADING_STEP_RAD: f64 = 0.1;
/// Longest distance between two route waypoints of the VUT, m.
pub const WAYPOINT_SPACING_M: f64 = 25.0;
/// Vehicle height (the vehicle files hold none), m.
pub const VEHICLE_HEIGHT_M: f64 = 1.5;
/// Wheel diameter (the vehicle files hold none), m.
pub const WHEEL_DIAMETER_M: f64 = 0.65;
/// Track width below the vehicle's width (the vehicle files hold none), m.
pub const TRACK_INSET_M: f64 = 0.25;

/// What the input file was.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SourceKind {
    /// A `TrajectoryPrior`.
    Prior,
    /// A `GroundedScenario`, driven along its routes at the start speeds.
    Grounded,
    /// A run of `video2track sim --json`.
    Run,
}

impl SourceKind {
    /// How the header names it.
    pub fn describe(self) -> &'static str {
        match self {
            Self::Prior => "trajectory prior",
            Self::Grounded => "grounded scenario at constant speed along its routes",
            Self::Run => "simulated run",
        }
    }
}

/// One agent to export: its states at their times (from 0) and the path it follows.
#[derive(Debug, Clone, PartialEq)]
pub struct ExportAgent {
    /// Entity name.
    pub id: String,
    /// VUT or BV.
    pub role: AgentRole,
    /// Sample times, s, from 0, increasing.
    pub times_s: Vec<f64>,
    /// State at each time (footprint centre).
    pub states: Vec<State>,
    /// Its route: the grounded route, or else the path its states trace.
    pub route: Vec<Point2>,
}

/// A scenario ready to be written.
#[derive(Debug, Clone, PartialEq)]
pub struct ExportScenario {
    /// What it came from.
    pub kind: SourceKind,
    /// The fragment id (prior, grounded) or the scenario's name (run).
    pub name: String,
    /// Target PET τ, s.
    pub tau_s: f64,
    /// Who passes first.
    pub style: Style,
    /// The VUT and the BVs.
    pub agents: Vec<ExportAgent>,
}

impl ExportScenario {
    /// The last sample time, s.
    pub fn end_time_s(&self) -> f64 {
        self.agents.iter().filter_map(|a| a.times_s.last().copied()).fold(0.0, f64::max)
    }
}

/// An input that cannot be exported.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum XoscError {
    /// A prior or grounded scenario that does not parse or validate.
    #[error(transparent)]
    Document(#[from] DocumentError),
    /// Something with a `trace` that is not a run.
    #[error("not a run (`video2track sim --json`): {0}")]
    NotARun(String),
    /// None of the three inputs.
    #[error("neither a trajectory prior (`dt_s`), a grounded scenario (`fragment_id`, `agents`) nor a run (`trace`)")]
    Unknown,
    /// The right kind of input, with a value that cannot be written.
    #[error(transparent)]
    Invalid(#[from] ValidationError),
}

fn invalid(field: impl Into<String>, problem: impl Into<String>) -> XoscError {
    XoscError::Invalid(ValidationError::new(field, problem))
}

/// What the writer needs besides the scenario.
#[derive(Debug, Clone, Copy)]
pub struct XoscOptions<'a> {
    /// The input file, as the header names it.
    pub source: &'a str,
    /// `LogicFile` path of the map, as written (relative to the output file where possible).
    pub map_path: &'a str,
    /// `FileHeader` date, `YYYY-MM-DDThh:mm:ss`.
    pub date: &'a str,
    /// The VUT's vehicle.
    pub vut_vehicle: &'a VehicleConfig,
    /// Every BV's vehicle.
    pub bv_vehicle: &'a VehicleConfig,
}

/// Reads the text of an input file: a `TrajectoryPrior` (has `dt_s`), a `GroundedScenario` (has
/// `fragment_id` and `agents`) or a run (has `trace`). The error says what is wrong, without the
/// file's name.
pub fn parse_input(text: &str) -> Result<ExportScenario, XoscError> {
    let keys = DocumentKeys::of(text)?;
    let scenario = match prior_document(text, keys) {
        Some(doc) => match doc? {
            PriorDocument::Prior(p) => from_prior(&p, SourceKind::Prior, None),
            PriorDocument::Grounded { stand_in, grounded } => {
                from_prior(&stand_in, SourceKind::Grounded, Some(&grounded))
            }
        },
        None if keys.trace => {
            let run: RunFile = serde_json::from_str(text).map_err(|e| XoscError::NotARun(e.to_string()))?;
            from_run(run)?
        }
        None => return Err(XoscError::Unknown),
    };
    check(&scenario)?;
    Ok(scenario)
}

fn from_prior(p: &TrajectoryPrior, kind: SourceKind, grounded: Option<&GroundedScenario>) -> ExportScenario {
    let agents = p
        .agents
        .iter()
        .map(|a| {
            let route = grounded
                .and_then(|g| g.agents.iter().find(|b| b.id == a.id))
                .map_or_else(|| path_of(&a.states), |b| b.route.clone());
            ExportAgent {
                id: a.id.clone(),
                role: a.role,
                times_s: (0..a.states.len()).map(|k| k as f64 * p.dt_s).collect(),
                states: a.states.clone(),
                route,
            }
        })
        .collect();
    ExportScenario { kind, name: p.fragment_id.clone(), tau_s: p.target.tau_s(), style: p.target.style(), agents }
}

fn from_run(run: RunFile) -> Result<ExportScenario, XoscError> {
    let (tau_s, style) = (run.result.target.tau_s(), run.result.target.style());
    run.validate()?;
    if run.trace.len() < 2 {
        return Err(invalid("trace", format!("needs at least 2 samples, got {}", run.trace.len())));
    }
    let t0 = run.trace.first().map_or(0.0, |s| s.t_s);
    let mut agents: Vec<ExportAgent> = run
        .agent_ids
        .iter()
        .enumerate()
        .map(|(i, id)| ExportAgent {
            id: id.clone(),
            // The trace holds the VUT first, then the BVs.
            role: if i == 0 { AgentRole::Vut } else { AgentRole::Bv },
            times_s: Vec::with_capacity(run.trace.len()),
            states: Vec::with_capacity(run.trace.len()),
            route: Vec::new(),
        })
        .collect();
    for sample in &run.trace {
        for (a, s) in agents.iter_mut().zip(&sample.agents) {
            a.times_s.push(sample.t_s - t0);
            a.states.push(s.state);
        }
    }
    for a in &mut agents {
        a.route = path_of(&a.states);
    }
    Ok(ExportScenario { kind: SourceKind::Run, name: run.result.scenario, tau_s, style, agents })
}

/// The positions of `states`, without repeats (a vehicle standing still).
fn path_of(states: &[State]) -> Vec<Point2> {
    let mut path: Vec<Point2> = Vec::with_capacity(states.len());
    for s in states {
        let p = Point2 { x: s.px, y: s.py };
        if path.last().is_none_or(|q| q.dist(p) > 1e-6) {
            path.push(p);
        }
    }
    path
}

fn check(s: &ExportScenario) -> Result<(), XoscError> {
    if s.agents.is_empty() {
        return Err(invalid("agents", "needs at least one agent"));
    }
    v2t_model::Target::check_tau("tau_s", s.tau_s)?;
    for (i, a) in s.agents.iter().enumerate() {
        if a.id.trim().is_empty() {
            return Err(invalid(format!("agents[{i}].id"), "must not be empty"));
        }
        if s.agents.iter().skip(i + 1).any(|b| b.id == a.id) {
            return Err(invalid(format!("agents[{i}].id"), format!("`{}` is used twice", a.id)));
        }
        if a.states.len() < 2 || a.times_s.len() != a.states.len() {
            return Err(invalid(format!("agents[{i}]"), format!("(`{}`) needs at least 2 states", a.id)));
        }
        if let Some(k) = a.states.iter().position(|x| !x.is_finite()) {
            return Err(invalid(format!("agents[{i}].states[{k}]"), "must be finite"));
        }
        if let Some(k) = a.route.iter().position(|p| !p.is_finite()) {
            return Err(invalid(format!("agents[{i}].route[{k}]"), "must be finite"));
        }
        let samples = a.times_s.iter().zip(&a.states).map(|(t, x)| (*t, x.px, x.py));
        v2t_model::validate::plausible::motion(|k| format!("agents[{i}].states[{k}]"), samples)?;
        for (k, p) in a.route.iter().enumerate() {
            v2t_model::validate::plausible::coordinates(&format!("agents[{i}].route[{k}]"), p.x, p.y)?;
        }
    }
    let vuts = s.agents.iter().filter(|a| a.role == AgentRole::Vut).count();
    if vuts > 1 {
        return Err(invalid("agents", format!("at most one VUT, got {vuts}")));
    }
    Ok(())
}

/// `text` escaped for attribute values and text (the project's one escape).
pub use v2t_model::text::xml_escape as escape;

/// A number as written: at most 6 decimals, no trailing zeros, never `-0`.
pub fn num(x: f64) -> String {
    let text = format!("{x:.6}");
    let text = if text.contains('.') { text.trim_end_matches('0').trim_end_matches('.') } else { text.as_str() };
    if text == "-0" { "0".to_owned() } else { text.to_owned() }
}

/// Angle wrapped to (-π, π], rad.
fn wrap(a: f64) -> f64 {
    let w = (a + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU) - std::f64::consts::PI;
    if w <= -std::f64::consts::PI { w + std::f64::consts::TAU } else { w }
}

/// Which samples become trajectory vertices: the first and the last, then every sample at least
/// `period_s` after the last vertex, or whose heading differs from the last vertex's by at least
/// `heading_step_rad`.
pub fn vertex_indices(times_s: &[f64], headings_rad: &[f64], period_s: f64, heading_step_rad: f64) -> Vec<usize> {
    let n = times_s.len().min(headings_rad.len());
    let mut keep: Vec<usize> = Vec::new();
    let mut kept: Option<(f64, f64)> = None;
    for (k, (&t, &h)) in times_s.iter().zip(headings_rad).enumerate() {
        let take = match kept {
            None => true,
            Some((t0, h0)) => k + 1 == n || t - t0 >= period_s - 1e-9 || wrap(h - h0).abs() >= heading_step_rad - 1e-9,
        };
        if take {
            keep.push(k);
            kept = Some((t, h));
        }
    }
    keep
}

/// Waypoints along `route`: its start, a point every `spacing_m` of arc length, its end; each with
/// the heading of the segment it lies on. Always at least two.
pub fn route_waypoints(route: &[Point2], spacing_m: f64) -> Vec<(Point2, f64)> {
    let segments: Vec<(Point2, Point2)> = route
        .windows(2)
        .filter_map(|w| w.first().copied().zip(w.get(1).copied()))
        .filter(|(a, b)| a.dist(*b) > 1e-9)
        .collect();
    let heading = |a: Point2, b: Point2| (b.y - a.y).atan2(b.x - a.x);
    let (Some(&(first_a, first_b)), Some(&(last_a, last_b))) = (segments.first(), segments.last()) else {
        let p = route.first().copied().unwrap_or(Point2 { x: 0.0, y: 0.0 });
        return vec![(p, 0.0), (p, 0.0)];
    };
    let mut out = vec![(first_a, heading(first_a, first_b))];
    let mut next = spacing_m;
    let mut s0 = 0.0;
    for (a, b) in &segments {
        let len = a.dist(*b);
        while next < s0 + len && spacing_m > 0.0 {
            let f = (next - s0) / len;
            out.push((Point2 { x: a.x + f * (b.x - a.x), y: a.y + f * (b.y - a.y) }, heading(*a, *b)));
            next += spacing_m;
        }
        s0 += len;
    }
    // The end, replacing a spaced point that fell within a metre of it.
    if out.len() > 1 && out.last().is_some_and(|(p, _)| p.dist(last_b) < 1.0) {
        out.pop();
    }
    out.push((last_b, heading(last_a, last_b)));
    out
}

/// `YYYY-MM-DDThh:mm:ss` (UTC) of a Unix time, s.
pub fn iso_date_time(unix_s: u64) -> String {
    let days = (unix_s / 86_400) as i64;
    let secs = unix_s % 86_400;
    // Howard Hinnant's civil_from_days.
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let day = doy - (153 * mp + 2) / 5 + 1;
    let month = if mp < 10 { mp + 3 } else { mp - 9 };
    let year = yoe + era * 400 + i64::from(month <= 2);
    format!("{year:04}-{month:02}-{day:02}T{:02}:{:02}:{:02}", secs / 3600, secs % 3600 / 60, secs % 60)
}

/// An indenting XML writer; attribute values are escaped here.
struct Xml {
    out: String,
    depth: usize,
}

impl Xml {
    fn line(&mut self, tag: &str, attrs: &[(&str, String)], end: &str) {
        let _ = write!(self.out, "{:1$}<{tag}", "", self.depth * 2);
        for (k, v) in attrs {
            let _ = write!(self.out, " {k}=\"{}\"", escape(v));
        }
        self.out.push_str(end);
        self.out.push('\n');
    }
    fn open(&mut self, tag: &str, attrs: &[(&str, String)]) {
        self.line(tag, attrs, ">");
        self.depth += 1;
    }
    fn empty(&mut self, tag: &str, attrs: &[(&str, String)]) {
        self.line(tag, attrs, "/>");
    }
    fn close(&mut self, tag: &str) {
        self.depth = self.depth.saturating_sub(1);
        let _ = writeln!(self.out, "{:1$}</{tag}>", "", self.depth * 2);
    }
}

fn a(k: &'static str, v: impl Into<String>) -> (&'static str, String) {
    (k, v.into())
}

fn world_position(x: &mut Xml, p: Point2, h: f64) {
    x.open("Position", &[]);
    x.empty("WorldPosition", &[a("x", num(p.x)), a("y", num(p.y)), a("z", "0"), a("h", num(wrap(h)))]);
    x.close("Position");
}

fn time_trigger(x: &mut Xml, tag: &str, name: &str, rule_value_s: f64) {
    x.open(tag, &[]);
    x.open("ConditionGroup", &[]);
    x.open("Condition", &[a("name", name), a("delay", "0"), a("conditionEdge", "rising")]);
    x.open("ByValueCondition", &[]);
    x.empty("SimulationTimeCondition", &[a("value", num(rule_value_s)), a("rule", "greaterThan")]);
    x.close("ByValueCondition");
    x.close("Condition");
    x.close("ConditionGroup");
    x.close(tag);
}

fn vehicle(x: &mut Xml, v: &VehicleConfig, role: AgentRole) {
    let g = &v.geometry;
    let l = &v.limits;
    x.open("Vehicle", &[a("name", v.name.as_str()), a("vehicleCategory", "car")]);
    x.open("BoundingBox", &[]);
    x.empty("Center", &[a("x", "0"), a("y", "0"), a("z", num(VEHICLE_HEIGHT_M / 2.0))]);
    x.empty(
        "Dimensions",
        &[a("width", num(g.width_m)), a("length", num(g.length_m)), a("height", num(VEHICLE_HEIGHT_M))],
    );
    x.close("BoundingBox");
    x.empty(
        "Performance",
        &[
            a("maxSpeed", num(l.max_speed_mps)),
            a("maxAcceleration", num(l.max_accel_mps2)),
            a("maxDeceleration", num(l.max_decel_mps2)),
            a("maxAccelerationRate", num(l.max_jerk_mps3)),
            a("maxDecelerationRate", num(l.max_jerk_mps3)),
        ],
    );
    let track = (g.width_m - TRACK_INSET_M).max(0.1);
    let axle = |steer: f64, x_m: f64| {
        [
            a("maxSteering", num(steer)),
            a("wheelDiameter", num(WHEEL_DIAMETER_M)),
            a("trackWidth", num(track)),
            a("positionX", num(x_m)),
            a("positionZ", num(WHEEL_DIAMETER_M / 2.0)),
        ]
    };
    x.open("Axles", &[]);
    x.empty("FrontAxle", &axle(l.max_steer_rad, g.wheelbase_m - g.center_to_rear_axle_m));
    x.empty("RearAxle", &axle(0.0, -g.center_to_rear_axle_m));
    x.close("Axles");
    x.open("Properties", &[]);
    let role = match role {
        AgentRole::Vut => "vut",
        AgentRole::Bv => "bv",
    };
    x.empty("Property", &[a("name", "v2t:role"), a("value", role)]);
    x.empty("Property", &[a("name", "v2t:reference_point"), a("value", "footprint centre")]);
    x.close("Properties");
    x.close("Vehicle");
}

fn init_actions(x: &mut Xml, agent: &ExportAgent) {
    let Some(first) = agent.states.first() else { return };
    x.open("Private", &[a("entityRef", agent.id.as_str())]);
    x.open("PrivateAction", &[]);
    x.open("TeleportAction", &[]);
    world_position(x, first.position(), first.theta_rad);
    x.close("TeleportAction");
    x.close("PrivateAction");
    x.open("PrivateAction", &[]);
    x.open("LongitudinalAction", &[]);
    x.open("SpeedAction", &[]);
    x.empty("SpeedActionDynamics", &[a("dynamicsShape", "step"), a("value", "0"), a("dynamicsDimension", "time")]);
    x.open("SpeedActionTarget", &[]);
    x.empty("AbsoluteTargetSpeed", &[a("value", num(first.speed_mps))]);
    x.close("SpeedActionTarget");
    x.close("SpeedAction");
    x.close("LongitudinalAction");
    x.close("PrivateAction");
    if agent.role == AgentRole::Vut {
        x.open("PrivateAction", &[]);
        x.open("RoutingAction", &[]);
        x.open("AssignRouteAction", &[]);
        x.open("Route", &[a("name", format!("{}_route", agent.id)), a("closed", "false")]);
        for (p, h) in route_waypoints(&agent.route, WAYPOINT_SPACING_M) {
            x.open("Waypoint", &[a("routeStrategy", "shortest")]);
            world_position(x, p, h);
            x.close("Waypoint");
        }
        x.close("Route");
        x.close("AssignRouteAction");
        x.close("RoutingAction");
        x.close("PrivateAction");
    }
    x.close("Private");
}

fn bv_story(x: &mut Xml, agent: &ExportAgent) {
    let id = agent.id.as_str();
    x.open("Story", &[a("name", format!("{id}_story"))]);
    x.open("Act", &[a("name", format!("{id}_act"))]);
    x.open("ManeuverGroup", &[a("maximumExecutionCount", "1"), a("name", format!("{id}_maneuver_group"))]);
    x.open("Actors", &[a("selectTriggeringEntities", "false")]);
    x.empty("EntityRef", &[a("entityRef", id)]);
    x.close("Actors");
    x.open("Maneuver", &[a("name", format!("{id}_maneuver"))]);
    x.open(
        "Event",
        &[a("name", format!("{id}_follow_prior")), a("priority", "override"), a("maximumExecutionCount", "1")],
    );
    x.open("Action", &[a("name", format!("{id}_follow_trajectory"))]);
    x.open("PrivateAction", &[]);
    x.open("RoutingAction", &[]);
    x.open("FollowTrajectoryAction", &[]);
    x.open("TrajectoryRef", &[]);
    x.open("Trajectory", &[a("name", format!("{id}_trajectory")), a("closed", "false")]);
    x.open("Shape", &[]);
    x.open("Polyline", &[]);
    let headings: Vec<f64> = agent.states.iter().map(|s| s.theta_rad).collect();
    for k in vertex_indices(&agent.times_s, &headings, VERTEX_PERIOD_S, VERTEX_HEADING_STEP_RAD) {
        let (Some(t), Some(s)) = (agent.times_s.get(k), agent.states.get(k)) else { continue };
        x.open("Vertex", &[a("time", num(*t))]);
        world_position(x, s.position(), s.theta_rad);
        x.close("Vertex");
    }
    x.close("Polyline");
    x.close("Shape");
    x.close("Trajectory");
    x.close("TrajectoryRef");
    x.open("TimeReference", &[]);
    x.empty("Timing", &[a("domainAbsoluteRelative", "absolute"), a("scale", "1"), a("offset", "0")]);
    x.close("TimeReference");
    x.empty("TrajectoryFollowingMode", &[a("followingMode", "position")]);
    x.close("FollowTrajectoryAction");
    x.close("RoutingAction");
    x.close("PrivateAction");
    x.close("Action");
    time_trigger(x, "StartTrigger", &format!("{id}_event_start"), 0.0);
    x.close("Event");
    x.close("Maneuver");
    x.close("ManeuverGroup");
    time_trigger(x, "StartTrigger", &format!("{id}_act_start"), 0.0);
    x.close("Act");
    x.close("Story");
}

/// The OpenSCENARIO 1.2 file for `scenario`.
pub fn to_xosc(scenario: &ExportScenario, opts: &XoscOptions<'_>) -> String {
    let mut x = Xml { out: String::from("<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n"), depth: 0 };
    let end = scenario.end_time_s();
    let description = format!(
        "Video2Track export of {} ({} `{}`): target PET τ {} s, style {}; positions are footprint centres",
        opts.source,
        scenario.kind.describe(),
        scenario.name,
        num(scenario.tau_s),
        scenario.style
    );
    x.open("OpenSCENARIO", &[]);
    x.empty(
        "FileHeader",
        &[
            a("revMajor", "1"),
            a("revMinor", "2"),
            a("date", opts.date),
            a("description", description),
            a("author", "video2track"),
        ],
    );
    x.open("ParameterDeclarations", &[]);
    x.empty(
        "ParameterDeclaration",
        &[a("name", "TargetPet_s"), a("parameterType", "double"), a("value", num(scenario.tau_s))],
    );
    x.empty(
        "ParameterDeclaration",
        &[a("name", "Style"), a("parameterType", "string"), a("value", scenario.style.to_string())],
    );
    x.close("ParameterDeclarations");
    x.empty("CatalogLocations", &[]);
    x.open("RoadNetwork", &[]);
    x.empty("LogicFile", &[a("filepath", opts.map_path)]);
    x.close("RoadNetwork");
    x.open("Entities", &[]);
    for agent in &scenario.agents {
        x.open("ScenarioObject", &[a("name", agent.id.as_str())]);
        let v = match agent.role {
            AgentRole::Vut => opts.vut_vehicle,
            AgentRole::Bv => opts.bv_vehicle,
        };
        vehicle(&mut x, v, agent.role);
        x.close("ScenarioObject");
    }
    x.close("Entities");
    x.open("Storyboard", &[]);
    x.open("Init", &[]);
    x.open("Actions", &[]);
    for agent in &scenario.agents {
        init_actions(&mut x, agent);
    }
    x.close("Actions");
    x.close("Init");
    for agent in scenario.agents.iter().filter(|a| a.role == AgentRole::Bv) {
        bv_story(&mut x, agent);
    }
    time_trigger(&mut x, "StopTrigger", "end_of_prior", end);
    x.close("Storyboard");
    x.close("OpenSCENARIO");
    x.out
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing)]
    use super::*;

    #[test]
    fn escaping_covers_the_five_entities_and_control_characters() {
        assert_eq!(escape("a & b < c > d \"e\" 'f'"), "a &amp; b &lt; c &gt; d &quot;e&quot; &#39;f&#39;");
        assert_eq!(escape("τ 3 s\tok\u{1}"), "τ 3 s&#9;ok ");
        assert_eq!(escape("&amp;"), "&amp;amp;");
        let doc = format!("<x v=\"{}\"/>", escape("<&\"'>"));
        assert_eq!(roxmltree::Document::parse(&doc).unwrap().root_element().attribute("v"), Some("<&\"'>"));
    }

    #[test]
    fn numbers_are_short_and_never_negative_zero() {
        assert_eq!(num(0.30000000000000004), "0.3");
        assert_eq!(num(-0.0000001), "0");
        assert_eq!(num(12.0), "12");
        assert_eq!(num(-1.25), "-1.25");
    }

    #[test]
    fn vertices_every_period_at_turns_and_at_both_ends() {
        let times: Vec<f64> = (0..=23).map(|k| k as f64 * 0.1).collect();
        let straight = vec![1.0; times.len()];
        assert_eq!(vertex_indices(&times, &straight, 0.5, 0.1), vec![0, 5, 10, 15, 20, 23]);
        // A turn between samples 6 and 9: 0.05 rad per sample, so every second sample there.
        let turning: Vec<f64> = (0..=23).map(|k: i32| 0.05 * f64::from(k.clamp(6, 12) - 6)).collect();
        assert_eq!(vertex_indices(&times, &turning, 0.5, 0.1), vec![0, 5, 8, 10, 12, 17, 22, 23]);
        // Headings across ±π are a small turn, not a large one.
        let wrapping = vec![3.1, -3.1, 3.1, -3.1, 3.1, -3.1];
        assert_eq!(vertex_indices(&times[..6], &wrapping, 0.5, 0.1), vec![0, 5]);
        assert_eq!(vertex_indices(&[0.0], &[0.0], 0.5, 0.1), vec![0]);
        assert!(vertex_indices(&[], &[], 0.5, 0.1).is_empty());
    }

    #[test]
    fn waypoints_lie_on_the_route_and_end_at_its_ends() {
        let route = [Point2 { x: 0.0, y: 0.0 }, Point2 { x: 60.0, y: 0.0 }, Point2 { x: 60.0, y: 30.5 }];
        let w = route_waypoints(&route, 25.0);
        let xs: Vec<(f64, f64)> = w.iter().map(|(p, _)| (p.x, p.y)).collect();
        assert_eq!(xs, vec![(0.0, 0.0), (25.0, 0.0), (50.0, 0.0), (60.0, 15.0), (60.0, 30.5)]);
        assert!((w[3].1 - std::f64::consts::FRAC_PI_2).abs() < 1e-12);
        let still = route_waypoints(&[Point2 { x: 1.0, y: 2.0 }], 25.0);
        assert_eq!(still.len(), 2);
    }

    #[test]
    fn dates_are_iso_8601() {
        assert_eq!(iso_date_time(0), "1970-01-01T00:00:00");
        assert_eq!(iso_date_time(951_782_400), "2000-02-29T00:00:00");
        assert_eq!(iso_date_time(1_795_453_261), "2026-11-23T17:01:01");
    }

    #[test]
    fn inputs_that_are_not_scenarios_say_so() {
        assert!(parse_input("nope").unwrap_err().to_string().starts_with("not JSON"));
        assert!(parse_input("{}").unwrap_err().to_string().starts_with("neither"));
        let no_agents = serde_json::to_string(&crate::test_run::run("x", &[], &[])).unwrap();
        assert!(parse_input(&no_agents).unwrap_err().to_string().contains("agent_ids"));
        // A run without a part every run has says which.
        let e =
            parse_input(r#"{"trace": [], "agent_ids": [], "result": {"scenario": "x", "tau_s": 2, "style": "rush"}}"#);
        assert!(e.unwrap_err().to_string().contains("missing field `vut_model`"));
    }
}
