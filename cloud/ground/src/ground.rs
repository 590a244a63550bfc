//! Step-wise grounding (paper Sec. 3.2.2): on the retrieved fragment, the ego (the VUT) is placed on
//! the entry anchor of the lane and arm its start region names and given the maneuver path to the
//! exit anchor its maneuver leads to; every BV gets the route its relative start, maneuver and
//! interaction type imply; the conflict anchor is the one both routes share, and the occupancy
//! intervals follow from the routes and the vehicles' footprints. Speeds come from the semantics;
//! each BV's start time makes the pair pass the conflict in its style's order with the video's PET.

use serde::Serialize;
use v2t_map::Map;
use v2t_map::graph::LaneKey;
use v2t_map::library::{Anchor, AnchorKind, Fragment, Polyline, TopologyLibrary};
use v2t_model::Target;
use v2t_model::grounded::{AgentRole, AnchorState, GroundedAgent, GroundedConflict, GroundedScenario};
use v2t_model::metrics::{ConflictKind, ConflictOptions, ConflictZone, Dimensions, OccupancyInterval, conflict_zones};
use v2t_model::path::ReferencePath;
use v2t_model::semantics::{InteractingBv, ScenarioSemantics};
use v2t_model::validate::Validate;
use v2t_model::vehicle::VehicleConfig;

use crate::error::{GroundError, Misfit, Rejection, misfit};
use crate::plan::{Plan, RouteSpec, plan};
use crate::retrieve::{Candidate, ROOM_MIN_M, ROOM_TIME_S, rank};
use crate::route::{MAX_BLEND_M, MIN_BLEND_M, anchor_ref, nearest_lane, raw_points, upstream};
use crate::timing::{ConflictTiming, bv_start_s, passage, speed_after_mps, travel_time_s};

/// A route starts at least this far before its first conflict where the path allows, m.
pub const MIN_LEAD_M: f64 = 60.0;
/// A route ends this long (at speed) after its last conflict, s …
pub const TAIL_TIME_S: f64 = 4.0;
/// … and at least this far, m.
pub const MIN_TAIL_M: f64 = 60.0;
/// A conflict anchor must lie this close to every route through it, m.
const ON_ROUTE_M: f64 = 0.5;

/// What grounding needs besides the map and the semantics.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GroundOptions {
    /// Footprint of the VUT.
    pub vut: Dimensions,
    /// Footprint of every BV.
    pub bv: Dimensions,
    /// Long paths are cut to start this long (at the agent's speed) before the first conflict, s
    /// (at least [`MIN_LEAD_M`]).
    pub lead_time_s: f64,
    /// A lane change takes this long at the changing vehicle's speed, s (its length is clamped to
    /// 20–100 m).
    pub lane_change_time_s: f64,
    /// The target the scenario is grounded for; `None`: the video's, its PET label in each BV's
    /// style. An experiment that asks for another τ or style sets it here; the semantics stay what
    /// the video says.
    pub target: Option<Target>,
}

impl Default for GroundOptions {
    /// The project's sedans (`config/vehicles/vut_sedan.toml`, `bv_sedan.toml`), 6 s of lead, 3.5 s lane changes.
    fn default() -> Self {
        Self {
            vut: Dimensions { length_m: 4.7, width_m: 1.85 },
            bv: Dimensions { length_m: 4.8, width_m: 1.85 },
            lead_time_s: 6.0,
            lane_change_time_s: 3.5,
            target: None,
        }
    }
}

impl GroundOptions {
    /// Defaults with the footprints of the configured vehicles.
    pub fn for_vehicles(vut: &VehicleConfig, bv: &VehicleConfig) -> Self {
        let dims = |v: &VehicleConfig| Dimensions { length_m: v.geometry.length_m, width_m: v.geometry.width_m };
        Self { vut: dims(vut), bv: dims(bv), ..Self::default() }
    }
}

/// One agent's route, in terms of the library and the lane graph.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct AgentRoute {
    /// `vut` or the BV's id.
    pub id: String,
    /// The library maneuvers it follows, in order (two for a lane change).
    pub maneuvers: Vec<String>,
    /// The lane it starts on.
    pub start_lane: LaneKey,
    /// The lane it ends on.
    pub goal_lane: LaneKey,
    /// Route length, m.
    pub length_m: f64,
}

/// A grounded scenario with how it was found.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Grounding {
    /// The scenario, valid.
    pub scenario: GroundedScenario,
    /// The VUT's route first, then each BV's.
    pub routes: Vec<AgentRoute>,
    /// Planned passages through each conflict.
    pub timing: Vec<ConflictTiming>,
    /// Where the grounding departs from the semantics (another arm or lane, a short route), and why.
    pub notes: Vec<String>,
    /// Every fragment, ranked; the scenario's fragment is the first feasible one that grounded.
    pub ranking: Vec<Candidate>,
}

/// Grounds `semantics` on the best-ranked fragment of `library` that it fits, with default options.
pub fn ground(map: &Map, library: &TopologyLibrary, semantics: &ScenarioSemantics) -> Result<Grounding, GroundError> {
    ground_with(map, library, semantics, &GroundOptions::default())
}

/// Grounds `semantics`: ranks the fragments and tries them best first; the first that grounds wins.
/// When none does, [`GroundError::NoFit`] says why for each.
pub fn ground_with(
    map: &Map,
    library: &TopologyLibrary,
    semantics: &ScenarioSemantics,
    options: &GroundOptions,
) -> Result<Grounding, GroundError> {
    semantics.validate()?;
    let ranking = rank(library, semantics);
    let mut rejections = Vec::new();
    for c in &ranking {
        if !c.feasible {
            rejections.push(Rejection { fragment_id: c.fragment_id.clone(), reason: Misfit(c.reasons.join("; ")) });
            continue;
        }
        let grounded = library
            .fragment(&c.fragment_id)
            .ok_or_else(|| Misfit::from("not in the library"))
            .and_then(|f| ground_on(map, f, semantics, options));
        match grounded {
            Ok((scenario, routes, timing, notes)) => {
                return Ok(Grounding { scenario, routes, timing, notes, ranking });
            }
            Err(reason) => rejections.push(Rejection { fragment_id: c.fragment_id.clone(), reason }),
        }
    }
    Err(GroundError::NoFit { rejections })
}

type Grounded = (GroundedScenario, Vec<AgentRoute>, Vec<ConflictTiming>, Vec<String>);

/// Grounds `s` on fragment `f`, or says why not.
pub(crate) fn ground_on(
    map: &Map,
    f: &Fragment,
    s: &ScenarioSemantics,
    opt: &GroundOptions,
) -> Result<Grounded, Misfit> {
    let p: Plan = plan(f, s)?;
    let tau_s = opt.target.map_or(s.pet_label_s, Target::tau_s);
    let style = |bv: &InteractingBv| opt.target.map_or(bv.style, Target::style);
    let mut notes = p.notes.clone();
    let anchor = |id: &str| f.anchor(id).ok_or_else(|| format!("no anchor {id}"));
    let conflicts: Vec<&Anchor> = p.bvs.iter().map(|b| anchor(&b.anchor)).collect::<Result<_, _>>()?;
    let first_conflict = conflicts.first().copied().ok_or("no BV to ground")?;
    let v_vut = s.ego.speed_estimate_mps;
    let vut = build_route(map, f, &p.vut, first_conflict, &conflicts, v_vut, opt, &mut notes, "vut")?;
    let mut agents = Vec::new();
    let mut routes = vec![vut.describe("vut")];
    let mut grounded_conflicts = Vec::new();
    let mut starts = Vec::new();
    for (b, a) in p.bvs.iter().zip(&conflicts) {
        let bv = s.interacting_bvs.get(b.index).ok_or("BV index out of range")?;
        let v = bv.behavior.speed_estimate_mps;
        let route = build_route(map, f, &b.route, a, &[*a], v, opt, &mut notes, &bv.id)?;
        let (kind, vi, bi) = zone(&vut.path, &route.path, a, opt, &mut notes, &bv.id)?;
        if vi.enter_s_m < 0.0 || bi.enter_s_m < 0.0 {
            return Err(misfit!("a route starts inside the conflict zone {} of {}", a.id, bv.id));
        }
        let t0 = bv_start_s(style(bv), tau_s, (vi, v_vut), (bi, v));
        // Where the BV's route enters the junction its zone lies in: a BV that gives way stops
        // before it (none for a zone outside every junction, or a route that starts inside).
        let bv_junction_entry = map
            .junction_entry(&route.path, 0.5 * (bi.enter_s_m + bi.exit_s_m))
            .filter(|s| *s > 0.0)
            .map(|s| route.path.point_at(s));
        starts.push((bv, route, t0, vi, bi));
        grounded_conflicts.push(GroundedConflict {
            bv_id: bv.id.clone(),
            kind,
            anchor_id: a.id.clone(),
            point: a.position,
            vut_interval: vi,
            bv_interval: bi,
            bv_junction_entry,
        });
    }
    // Shift so that nobody starts before 0.
    let shift = starts.iter().map(|x| x.2).fold(0.0_f64, f64::min).abs();
    agents.push(vut.agent("vut", AgentRole::Vut, v_vut, shift));
    let mut timing = Vec::new();
    for (bv, route, t0, vi, bi) in starts {
        let v = bv.behavior.speed_estimate_mps;
        timing.push(passage(&bv.id, style(bv), (shift, vi, v_vut), (shift + t0, bi, v)));
        agents.push(route.agent(&bv.id, AgentRole::Bv, v, shift + t0));
        routes.push(route.describe(&bv.id));
    }
    let first = s.interacting_bvs.first().ok_or("no BV")?;
    let scenario = GroundedScenario {
        fragment_id: f.id.clone(),
        interaction_type: first.interaction_type,
        agents,
        conflicts: grounded_conflicts,
        target: Target::from_keys(tau_s, style(first)).map_err(|e| misfit!("the grounded scenario is invalid: {e}"))?,
    };
    scenario.validate().map_err(|e| misfit!("the grounded scenario is invalid: {e}"))?;
    Ok((scenario, routes, timing, notes))
}

/// A route as built: its geometry and where it starts and ends in library terms.
struct Built {
    path: ReferencePath,
    maneuvers: Vec<String>,
    start_ref: String,
    goal_ref: String,
    start_lane: LaneKey,
    goal_lane: LaneKey,
}

impl Built {
    fn describe(&self, id: &str) -> AgentRoute {
        AgentRoute {
            id: id.to_owned(),
            maneuvers: self.maneuvers.clone(),
            start_lane: self.start_lane.clone(),
            goal_lane: self.goal_lane.clone(),
            length_m: self.path.length(),
        }
    }

    fn agent(&self, id: &str, role: AgentRole, speed_mps: f64, t0_s: f64) -> GroundedAgent {
        let len = self.path.length();
        let state = |anchor_id: &str, s: f64, speed_mps: f64, t: f64| AnchorState {
            anchor_id: anchor_id.to_owned(),
            position: self.path.point_at(s),
            heading_rad: self.path.heading_at(s),
            speed_mps,
            time_s: Some(t),
        };
        GroundedAgent {
            id: id.to_owned(),
            role,
            route: self.path.points().to_vec(),
            start: state(&self.start_ref, 0.0, speed_mps, t0_s),
            goal: state(&self.goal_ref, len, speed_after_mps(len, speed_mps), t0_s + travel_time_s(len, speed_mps)),
        }
    }
}

/// Builds the route of `spec`, cut (or extended upstream) around its conflicts.
#[allow(clippy::too_many_arguments)]
fn build_route(
    map: &Map,
    f: &Fragment,
    spec: &RouteSpec,
    completion: &Anchor,
    conflicts: &[&Anchor],
    speed: f64,
    opt: &GroundOptions,
    notes: &mut Vec<String>,
    who: &str,
) -> Result<Built, Misfit> {
    let blend = (opt.lane_change_time_s * speed).clamp(MIN_BLEND_M, MAX_BLEND_M);
    let raw = raw_points(f, spec, completion, blend).map_err(|e| misfit!("{who}: {e}"))?;
    let raw_path = ReferencePath::from_points(&raw).map_err(|e| misfit!("{who}'s route: {e}"))?;
    let mut on_route = Vec::new();
    for a in conflicts {
        let hint = match spec {
            RouteSpec::Path { maneuver } => a.on_paths.iter().find(|(m, _)| m == maneuver).map(|x| x.1),
            RouteSpec::LaneChange { .. } => None,
        };
        let foot = match hint {
            Some(h) => raw_path.project_near(a.position, h, 10.0),
            None => raw_path.project(a.position),
        }
        .ok_or("anchor is not finite")?;
        if foot.l_m.abs() > ON_ROUTE_M {
            return Err(misfit!("conflict anchor {} lies {:.2} m off {who}'s route", a.id, foot.l_m.abs()));
        }
        on_route.push(foot.s_m.clamp(0.0, raw_path.length()));
    }
    let first = on_route.iter().copied().fold(f64::INFINITY, f64::min);
    let last = on_route.iter().copied().fold(0.0, f64::max);
    let lead = (opt.lead_time_s * speed).max(MIN_LEAD_M);
    let need = (ROOM_TIME_S * speed).max(ROOM_MIN_M);
    let tail = (TAIL_TIME_S * speed).max(MIN_TAIL_M);
    let names = spec.maneuvers();
    let maneuver = |id: Option<&String>| id.and_then(|m| f.maneuver(m)).ok_or("route without a maneuver");
    let (first_m, last_m) = (maneuver(names.first())?, maneuver(names.last())?);
    let entry = f.anchor(&first_m.entry).ok_or("no entry anchor")?;
    let (ext, ext_len, ext_lane) = if first < need {
        upstream(map, &entry.lane, entry.lane_s_m, lead - first)
    } else {
        (Vec::new(), 0.0, entry.lane.clone())
    };
    let start_s = if ext_len > 0.0 { 0.0 } else { (first - lead).max(0.0) };
    let end_s = (last + tail).min(raw_path.length());
    let mut points = ext;
    points.extend(Polyline::new(&raw).slice(start_s, end_s));
    let path = ReferencePath::from_points(&points).map_err(|e| misfit!("{who}'s route: {e}"))?;
    let lead_got = first - start_s + ext_len;
    if lead_got < need - 0.5 {
        notes.push(format!(
            "{who}'s route starts {lead_got:.0} m before its conflict; {need:.0} m ({ROOM_TIME_S} s at {speed:.1} m/s) wanted"
        ));
    }
    let start_lane = if ext_len > 0.0 {
        ext_lane
    } else {
        nearest_lane(map, &first_m.lanes, path.point_at(0.0)).unwrap_or_else(|| entry.lane.clone())
    };
    let exit_lane = f.anchor(&last_m.exit).map(|a| a.lane.clone());
    let goal_lane =
        nearest_lane(map, &last_m.lanes, path.point_at(path.length())).or(exit_lane).ok_or("no exit anchor")?;
    Ok(Built {
        start_ref: anchor_ref(&first_m.entry, start_s - ext_len),
        goal_ref: anchor_ref(&last_m.exit, end_s - raw_path.length()),
        path,
        maneuvers: names,
        start_lane,
        goal_lane,
    })
}

/// The conflict zone of the VUT's and a BV's routes at `anchor`: kind and the two intervals.
fn zone(
    vut: &ReferencePath,
    bv: &ReferencePath,
    anchor: &Anchor,
    opt: &GroundOptions,
    notes: &mut Vec<String>,
    who: &str,
) -> Result<(ConflictKind, OccupancyInterval, OccupancyInterval), Misfit> {
    let options = ConflictOptions::default();
    let reach = MAX_BLEND_M + 15.0;
    let nearest = |zones: Vec<ConflictZone>| {
        zones
            .into_iter()
            .filter(|z| z.anchor.dist(anchor.position) <= reach)
            .min_by(|a, b| a.anchor.dist(anchor.position).total_cmp(&b.anchor.dist(anchor.position)))
    };
    if let Some(z) = nearest(conflict_zones(vut, opt.vut, bv, opt.bv, &options)) {
        return Ok((z.kind, z.vut, z.bv));
    }
    // The VUT's route joining the BV's lane: the BV's path plays the joined side, so the sides swap.
    if let Some(z) = nearest(conflict_zones(bv, opt.bv, vut, opt.vut, &options)) {
        return Ok((z.kind, z.bv, z.vut));
    }
    // The corridors do not overlap near the anchor (it should not happen): the footprints at the anchor.
    let s_v = vut.project(anchor.position).ok_or("anchor is not finite")?.s_m;
    let s_b = bv.project(anchor.position).ok_or("anchor is not finite")?.s_m;
    let half_v = 0.5 * (opt.vut.length_m + opt.bv.width_m);
    let half_b = 0.5 * (opt.bv.length_m + opt.vut.width_m);
    notes.push(format!("{who}: no corridor overlap found at {}; intervals are the footprints there", anchor.id));
    let kind = if anchor.kind == AnchorKind::Conflict { ConflictKind::Crossing } else { ConflictKind::Merge };
    Ok((
        kind,
        OccupancyInterval { enter_s_m: s_v - half_v, exit_s_m: s_v + half_v },
        OccupancyInterval { enter_s_m: s_b - half_b, exit_s_m: s_b + half_b },
    ))
}
