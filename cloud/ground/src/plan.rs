//! The topological half of grounding: which library maneuvers each agent follows on one fragment and
//! which anchor is each BV's conflict with the VUT, chosen from the semantics' start lane, approach,
//! maneuvers and relative starts. No geometry is built here; retrieval uses the same plan to say
//! whether (and how exactly) a fragment fits, and grounding turns it into routes.

use std::f64::consts::{FRAC_PI_2, FRAC_PI_4, PI, TAU};

use v2t_map::library::{Anchor, AnchorKind, Arm, Fragment, FragmentKind, Maneuver, Turn};
use v2t_map::xodr::MarkType;
use v2t_model::geometry::Point2;
use v2t_model::semantics::{
    Approach, InteractingBv, InteractionType, Maneuver as Move, RelativeStart, ScenarioSemantics,
};

use crate::error::{Misfit, misfit};

/// Factor on the plan's exactness when the ego's approach arm is not the one the semantics name.
const RELAXED_ARM: f64 = 0.8;
/// … when the ego's lane is not the one the semantics name.
const RELAXED_LANE: f64 = 0.8;
/// … when a lane change crosses a mixed (solid on one side) line.
const MIXED_MARK: f64 = 0.9;
/// Largest angle between a wanted direction and an arm's bearing for the arm to count as that direction.
const ARM_TOLERANCE_RAD: f64 = PI / 3.0;

/// How an agent drives through the fragment.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum RouteSpec {
    /// Along one maneuver path.
    Path {
        /// Maneuver id.
        maneuver: String,
    },
    /// Starts on `from`'s path and changes into `to`'s path, completing the change at the conflict anchor.
    LaneChange {
        /// Maneuver the agent starts on.
        from: String,
        /// Maneuver it ends on.
        to: String,
    },
}

impl RouteSpec {
    /// The maneuver ids, in driving order.
    pub(crate) fn maneuvers(&self) -> Vec<String> {
        match self {
            Self::Path { maneuver } => vec![maneuver.clone()],
            Self::LaneChange { from, to } => vec![from.clone(), to.clone()],
        }
    }

    /// The maneuver the conflict anchor lies on (the one the route ends on).
    pub(crate) fn final_maneuver(&self) -> &str {
        match self {
            Self::Path { maneuver } => maneuver,
            Self::LaneChange { to, .. } => to,
        }
    }

    fn describe(&self) -> String {
        match self {
            Self::Path { maneuver } => maneuver.clone(),
            Self::LaneChange { from, to } => format!("{from} → lane change → {to}"),
        }
    }
}

/// One BV's route and its conflict with the VUT.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct BvPlan {
    /// Index in the semantics' `interacting_bvs`.
    pub index: usize,
    /// Its id.
    pub id: String,
    /// Its route.
    pub route: RouteSpec,
    /// Conflict anchor id.
    pub anchor: String,
    /// How well the anchor's kind fits the interaction type, 0–1.
    pub kind_fit: f64,
}

/// The maneuvers and anchors of a scenario on one fragment.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Plan {
    /// The VUT's route.
    pub vut: RouteSpec,
    /// One per BV, in the semantics' order.
    pub bvs: Vec<BvPlan>,
    /// 1 when every choice is the one the semantics name; each relaxation lowers it.
    pub exactness: f64,
    /// What was relaxed, and why.
    pub notes: Vec<String>,
}

impl Plan {
    /// One line: routes and conflict anchors.
    pub(crate) fn summary(&self) -> String {
        let mut parts = vec![format!("vut {}", self.vut.describe())];
        for b in &self.bvs {
            parts.push(format!("{} {} (conflict {})", b.id, b.route.describe(), b.anchor));
        }
        parts.join("; ")
    }
}

/// Plans `s` on `f`, or says why it does not fit.
pub(crate) fn plan(f: &Fragment, s: &ScenarioSemantics) -> Result<Plan, Misfit> {
    match f.kind {
        FragmentKind::Intersection => plan_intersection(f, s),
        FragmentKind::MultiLaneSegment => plan_segment(f, s),
        FragmentKind::Merge => plan_merge(f, s),
    }
}

/// How well an anchor kind fits an interaction type: 1 for the kind it names, less for a stand-in.
pub(crate) fn kind_fit(t: InteractionType, kind: AnchorKind) -> f64 {
    use AnchorKind as K;
    use InteractionType as I;
    let preferred: &[AnchorKind] = match t {
        I::UnprotectedLeftTurn | I::Crossing => &[K::Conflict, K::Merge],
        I::RightTurn => &[K::Merge, K::Conflict],
        I::Merge => &[K::Merge, K::CutIn, K::Conflict],
        I::CutIn | I::LaneChange => &[K::CutIn, K::Merge],
        I::RearEnd | I::Other => &[K::Conflict, K::Merge, K::CutIn],
    };
    match preferred.iter().position(|k| *k == kind) {
        Some(0) => 1.0,
        Some(1) => 0.7,
        Some(_) => 0.4,
        None => 0.0,
    }
}

/// The turn of a junction maneuver, if it is one.
fn turn_of(m: Move) -> Option<Turn> {
    match m {
        Move::Straight => Some(Turn::Straight),
        Move::LeftTurn => Some(Turn::Left),
        Move::RightTurn => Some(Turn::Right),
        Move::UTurn => Some(Turn::UTurn),
        Move::LaneChangeLeft | Move::LaneChangeRight | Move::Merge => None,
    }
}

/// Bearing, from the junction centre, of the arm a vehicle arriving `from_*` comes from.
fn approach_bearing(a: Approach) -> f64 {
    match a {
        Approach::FromEast => 0.0,
        Approach::FromNorth => FRAC_PI_2,
        Approach::FromWest => PI,
        Approach::FromSouth => 1.5 * PI,
    }
}

/// Absolute angle between two bearings, in [0, π].
pub(crate) fn angle_between(a: f64, b: f64) -> f64 {
    let d = (a - b).rem_euclid(TAU);
    d.min(TAU - d)
}

/// Compass name of a bearing.
pub(crate) fn compass(bearing: f64) -> &'static str {
    const NAMES: [&str; 8] = ["east", "north-east", "north", "north-west", "west", "south-west", "south", "south-east"];
    let i = ((bearing.rem_euclid(TAU) + FRAC_PI_4 / 2.0) / FRAC_PI_4).floor() as usize % 8;
    NAMES.get(i).copied().unwrap_or("east")
}

fn turn_name(t: Turn) -> &'static str {
    match t {
        Turn::Left => "left-turn",
        Turn::Straight => "straight",
        Turn::Right => "right-turn",
        Turn::UTurn => "U-turn",
    }
}

/// Lane positions `0..n` in the order to try them: the wanted one (1-based from the left) first,
/// then by distance from it. Each with whether it is the wanted one (any is, when none is named).
fn lane_order(n: usize, wanted_from_left: Option<u8>) -> Vec<(usize, bool)> {
    let mut v: Vec<usize> = (0..n).collect();
    match wanted_from_left {
        Some(k) => {
            let w = usize::from(k).saturating_sub(1);
            v.sort_by_key(|&i| (i.abs_diff(w), i));
            v.into_iter().map(|i| (i, i == w)).collect()
        }
        None => v.into_iter().map(|i| (i, true)).collect(),
    }
}

/// `(context, reason)` pairs as one message: each distinct reason once, with its context when only
/// one start led to it, else with the number of starts.
fn summarize(errors: &[(String, Misfit)]) -> Misfit {
    let mut groups: Vec<(&str, Vec<&str>)> = Vec::new();
    for (context, Misfit(reason)) in errors {
        match groups.iter_mut().find(|(r, _)| r == reason) {
            Some((_, contexts)) => contexts.push(context),
            None => groups.push((reason, vec![context])),
        }
    }
    let parts: Vec<String> = groups
        .iter()
        .map(|(reason, contexts)| match contexts.as_slice() {
            [c] if !c.is_empty() => format!("{c}: {reason}"),
            [_] => (*reason).to_owned(),
            many => format!("{reason} ({} ego starts)", many.len()),
        })
        .collect();
    Misfit(parts.join("; "))
}

// ---------------------------------------------------------------------------------------------
// Intersections

fn plan_intersection(f: &Fragment, s: &ScenarioSemantics) -> Result<Plan, Misfit> {
    let ego_turn = turn_of(s.ego.maneuver)
        .ok_or_else(|| format!("the ego's `{}` cannot be grounded inside a junction", s.ego.maneuver))?;
    let named = s.ego.start_lane.approach;
    // Without a named approach, the convention puts the ego on the south arm; any arm is as good.
    let reference = approach_bearing(named.unwrap_or(Approach::FromSouth));
    let mut arms: Vec<&Arm> = f.arms.iter().filter(|a| !a.approach_lanes.is_empty()).collect();
    arms.sort_by(|a, b| angle_between(a.bearing_rad, reference).total_cmp(&angle_between(b.bearing_rad, reference)));
    let mut errors = Vec::new();
    for arm in arms {
        let arm_exact = named.is_none() || angle_between(arm.bearing_rad, reference) <= FRAC_PI_4;
        let mut tried = false;
        for (pos, lane_exact) in lane_order(arm.approach_lanes.len(), s.ego.start_lane.lane_index_from_left) {
            let Some(lane) = arm.approach_lanes.get(pos) else { continue };
            let from_here = f.maneuvers.iter().filter(|m| {
                m.from_arm.as_deref() == Some(arm.id.as_str()) && m.turn == ego_turn && m.lanes.contains(lane)
            });
            for m in from_here {
                tried = true;
                match plan_bvs_at_junction(f, arm, m, s) {
                    Ok(bvs) => {
                        let mut notes = Vec::new();
                        let mut exactness = 1.0;
                        if !arm_exact {
                            exactness *= RELAXED_ARM;
                            notes.push(format!(
                                "the ego approaches from {} arm {} ({}), not {}",
                                compass(arm.bearing_rad),
                                arm.id,
                                arm.road,
                                named.map_or("-", Approach::as_str)
                            ));
                        }
                        if !lane_exact {
                            exactness *= RELAXED_LANE;
                            notes.push(format!(
                                "the ego starts in lane {} from the left of arm {}, not lane {}",
                                pos + 1,
                                arm.id,
                                s.ego.start_lane.lane_index_from_left.unwrap_or(0)
                            ));
                        }
                        return Ok(Plan { vut: RouteSpec::Path { maneuver: m.id.clone() }, bvs, exactness, notes });
                    }
                    Err(e) => errors.push((format!("ego on {}", m.id), e)),
                }
            }
        }
        if !tried {
            let why = format!("arm {} ({}) has no {} path", arm.id, compass(arm.bearing_rad), turn_name(ego_turn));
            errors.push((String::new(), Misfit(why)));
        }
    }
    if errors.is_empty() {
        return Err(Misfit::from("no arm has approach lanes"));
    }
    Err(summarize(&errors))
}

fn plan_bvs_at_junction(
    f: &Fragment,
    ego_arm: &Arm,
    ego: &Maneuver,
    s: &ScenarioSemantics,
) -> Result<Vec<BvPlan>, Misfit> {
    s.interacting_bvs.iter().enumerate().map(|(i, bv)| plan_bv_at_junction(f, ego_arm, ego, bv, i)).collect()
}

fn plan_bv_at_junction(
    f: &Fragment,
    ego_arm: &Arm,
    ego: &Maneuver,
    bv: &InteractingBv,
    index: usize,
) -> Result<BvPlan, Misfit> {
    let offset = match bv.relative_start {
        RelativeStart::Oncoming => PI,
        RelativeStart::CrossingFromLeft => -FRAC_PI_2,
        RelativeStart::CrossingFromRight => FRAC_PI_2,
        other => {
            return Err(misfit!(
                "{} starts `{other}`, on the ego's own arm; the library has no conflicts between paths from one arm",
                bv.id
            ));
        }
    };
    let target = ego_arm.bearing_rad + offset;
    let arm = f
        .arms
        .iter()
        .filter(|a| a.id != ego_arm.id && !a.approach_lanes.is_empty())
        .min_by(|a, b| angle_between(a.bearing_rad, target).total_cmp(&angle_between(b.bearing_rad, target)))
        .filter(|a| angle_between(a.bearing_rad, target) <= ARM_TOLERANCE_RAD)
        .ok_or_else(|| {
            format!(
                "{} starts `{}` but no arm lies to the {} (the ego comes from the {})",
                bv.id,
                bv.relative_start,
                compass(target),
                compass(ego_arm.bearing_rad)
            )
        })?;
    let turn = turn_of(bv.behavior.maneuver)
        .ok_or_else(|| format!("{}'s `{}` cannot be grounded inside a junction", bv.id, bv.behavior.maneuver))?;
    let mut best: Option<(f64, &Maneuver, &Anchor)> = None;
    let mut any_path = false;
    for m in f.maneuvers.iter().filter(|m| m.from_arm.as_deref() == Some(arm.id.as_str()) && m.turn == turn) {
        any_path = true;
        for a in shared_anchors(f, &ego.id, &m.id) {
            let fit = kind_fit(bv.interaction_type, a.kind);
            if best.is_none_or(|(b, _, _)| fit > b) {
                best = Some((fit, m, a));
            }
        }
    }
    match best {
        Some((kind_fit, m, a)) => Ok(BvPlan {
            index,
            id: bv.id.clone(),
            route: RouteSpec::Path { maneuver: m.id.clone() },
            anchor: a.id.clone(),
            kind_fit,
        }),
        None if !any_path => {
            Err(misfit!("{}: arm {} ({}) has no {} path", bv.id, arm.id, compass(arm.bearing_rad), turn_name(turn)))
        }
        None => Err(misfit!(
            "{}: no {} path from arm {} ({}) meets the ego's path",
            bv.id,
            turn_name(turn),
            arm.id,
            compass(arm.bearing_rad)
        )),
    }
}

/// Conflict and merge anchors on both maneuvers.
fn shared_anchors<'a>(f: &'a Fragment, a: &'a str, b: &'a str) -> impl Iterator<Item = &'a Anchor> + 'a {
    f.anchors.iter().filter(move |x| {
        matches!(x.kind, AnchorKind::Conflict | AnchorKind::Merge | AnchorKind::CutIn)
            && x.on_paths.iter().any(|(m, _)| m == a)
            && x.on_paths.iter().any(|(m, _)| m == b)
    })
}

// ---------------------------------------------------------------------------------------------
// Multi-lane segments

fn segment_path(f: &Fragment, pos: usize) -> Option<String> {
    let id = format!("{}/m/p{pos}", f.id);
    f.maneuver(&id).map(|m| m.id.clone())
}

fn plan_segment(f: &Fragment, s: &ScenarioSemantics) -> Result<Plan, Misfit> {
    let n = f.maneuvers.len();
    let mut errors = Vec::new();
    for (pos, exact) in lane_order(n, s.ego.start_lane.lane_index_from_left) {
        match plan_segment_at(f, s, pos) {
            Ok(mut plan) => {
                if !exact {
                    plan.exactness *= RELAXED_LANE;
                    plan.notes.push(format!(
                        "the ego starts in lane {} from the left (of {n}), not lane {}",
                        pos + 1,
                        s.ego.start_lane.lane_index_from_left.unwrap_or(0)
                    ));
                }
                return Ok(plan);
            }
            Err(e) => errors.push((format!("ego in lane {} from the left", pos + 1), e)),
        }
    }
    if errors.is_empty() {
        return Err(Misfit::from("the segment has no lanes"));
    }
    Err(summarize(&errors))
}

/// Lane position `pos` shifted by `d` (−1 left, +1 right), if it exists among `n`.
fn shifted(pos: usize, d: i8, n: usize) -> Option<usize> {
    let p = match d {
        -1 => pos.checked_sub(1)?,
        1 => pos + 1,
        _ => pos,
    };
    (p < n).then_some(p)
}

fn plan_segment_at(f: &Fragment, s: &ScenarioSemantics, ego_pos: usize) -> Result<Plan, Misfit> {
    let n = f.maneuvers.len();
    let side_of = |r: RelativeStart| match r {
        RelativeStart::AdjacentLeft => Some(-1),
        RelativeStart::AdjacentRight => Some(1),
        _ => None,
    };
    let ego_shift: i8 = match s.ego.maneuver {
        Move::Straight => 0,
        Move::LaneChangeLeft => -1,
        Move::LaneChangeRight => 1,
        Move::Merge => s
            .interacting_bvs
            .first()
            .and_then(|b| side_of(b.relative_start))
            .ok_or("the ego merges, but no BV drives beside it to merge towards")?,
        m => return Err(misfit!("the ego's `{m}` needs a junction")),
    };
    let ego_target = shifted(ego_pos, ego_shift, n).ok_or_else(|| {
        format!("no lane on the ego's {} to change into", if ego_shift < 0 { "left" } else { "right" })
    })?;
    let mut exactness = 1.0;
    let mut notes = Vec::new();
    let mut bvs = Vec::new();
    for (index, bv) in s.interacting_bvs.iter().enumerate() {
        let side = match bv.relative_start {
            RelativeStart::Ahead | RelativeStart::Behind => 0,
            r => side_of(r).ok_or_else(|| format!("{} starts `{r}`; a multi-lane segment has one direction", bv.id))?,
        };
        let bv_pos = shifted(ego_pos, side, n).ok_or_else(|| {
            format!("{} starts `{}` but the ego's lane is the outermost one", bv.id, bv.relative_start)
        })?;
        let bv_shift: i8 = match bv.behavior.maneuver {
            Move::Straight => 0,
            Move::LaneChangeLeft => -1,
            Move::LaneChangeRight => 1,
            Move::Merge if side != 0 => -side,
            m => return Err(misfit!("{}'s `{m}` has no counterpart on a multi-lane segment", bv.id)),
        };
        let (from, to, route) = match (ego_shift, bv_shift) {
            (0, 0) => return Err(misfit!("neither {} nor the ego changes lanes: their paths never meet", bv.id)),
            (0, d) => {
                let target = shifted(bv_pos, d, n);
                if target != Some(ego_pos) {
                    return Err(misfit!("{} changes lanes away from the ego's lane", bv.id));
                }
                let route = RouteSpec::LaneChange {
                    from: segment_path(f, bv_pos).ok_or("missing lane path")?,
                    to: segment_path(f, ego_pos).ok_or("missing lane path")?,
                };
                (bv_pos, ego_pos, route)
            }
            (_, 0) => {
                if bv_pos != ego_target {
                    return Err(misfit!(
                        "the ego changes into lane {}, {} drives in lane {}",
                        ego_target + 1,
                        bv.id,
                        bv_pos + 1
                    ));
                }
                (ego_pos, ego_target, RouteSpec::Path { maneuver: segment_path(f, bv_pos).ok_or("missing lane path")? })
            }
            _ => return Err(misfit!("both the ego and {} change lanes", bv.id)),
        };
        let (left, right) = (from.min(to), from.max(to));
        let pair = f
            .lane_pairs
            .iter()
            .find(|p| p.left == format!("{}/m/p{left}", f.id) && p.right == format!("{}/m/p{right}", f.id));
        match pair.map(|p| p.mark) {
            Some(MarkType::Solid) => {
                return Err(misfit!("a solid line separates lanes {} and {}: no lane change", left + 1, right + 1));
            }
            Some(MarkType::Mixed) => {
                exactness *= MIXED_MARK;
                notes.push(format!("a mixed line separates lanes {} and {}", left + 1, right + 1));
            }
            _ => {}
        }
        let anchor = format!("{}/cutin/p{from}>p{to}", f.id);
        let a = f.anchor(&anchor).ok_or_else(|| format!("the library has no cut-in anchor {anchor}"))?;
        bvs.push(BvPlan { index, id: bv.id.clone(), route, anchor, kind_fit: kind_fit(bv.interaction_type, a.kind) });
    }
    let vut = if ego_shift == 0 {
        RouteSpec::Path { maneuver: segment_path(f, ego_pos).ok_or("missing lane path")? }
    } else {
        RouteSpec::LaneChange {
            from: segment_path(f, ego_pos).ok_or("missing lane path")?,
            to: segment_path(f, ego_target).ok_or("missing lane path")?,
        }
    };
    Ok(Plan { vut, bvs, exactness, notes })
}

// ---------------------------------------------------------------------------------------------
// Merges

fn plan_merge(f: &Fragment, s: &ScenarioSemantics) -> Result<Plan, Misfit> {
    let merging = f.maneuvers.iter().find(|m| m.id.ends_with("/m/merging"));
    let through = f.maneuvers.iter().find(|m| m.id.ends_with("/m/through"));
    let anchor = f.anchors.iter().find(|a| a.kind == AnchorKind::Merge).ok_or("the fragment has no merge anchor")?;
    match (merging, through) {
        (Some(mg), Some(th)) => plan_lane_drop(f, s, mg, th, anchor),
        _ => plan_fed_merge(f, s, anchor),
    }
}

/// Whether `m` moves a vehicle from the ending lane into the through lane.
fn merges_into(m: Move, joins_left: bool) -> bool {
    m == Move::Merge || m == if joins_left { Move::LaneChangeLeft } else { Move::LaneChangeRight }
}

fn plan_lane_drop(
    f: &Fragment,
    s: &ScenarioSemantics,
    mg: &Maneuver,
    th: &Maneuver,
    anchor: &Anchor,
) -> Result<Plan, Misfit> {
    let joins_left = mg.turn != Turn::Right;
    // Seen from the through lane, the ending lane lies on the side it merges from.
    let (ramp_side, through_side) = if joins_left {
        (RelativeStart::AdjacentRight, RelativeStart::AdjacentLeft)
    } else {
        (RelativeStart::AdjacentLeft, RelativeStart::AdjacentRight)
    };
    let lanes = usize::from(f.lanes_per_direction).max(2);
    // The ending lane is the outermost on its side, the through lane beside it (an assumption: the
    // library does not say where the other lanes lie).
    let (ending_index, through_index) = if joins_left { (lanes, lanes - 1) } else { (1, 2) };
    let ego_merges = merges_into(s.ego.maneuver, joins_left);
    let side = if joins_left { "right" } else { "left" };
    let mut bvs = Vec::new();
    for (index, bv) in s.interacting_bvs.iter().enumerate() {
        let kind_fit = kind_fit(bv.interaction_type, anchor.kind);
        let route = if ego_merges {
            if merges_into(bv.behavior.maneuver, joins_left) {
                return Err(misfit!("both the ego and {} merge", bv.id));
            }
            if bv.relative_start != through_side {
                return Err(misfit!(
                    "the ego merges from the {side}, so {} must start `{through_side}`, not `{}`",
                    bv.id,
                    bv.relative_start
                ));
            }
            RouteSpec::Path { maneuver: th.id.clone() }
        } else {
            if !merges_into(bv.behavior.maneuver, joins_left) {
                return Err(misfit!(
                    "neither the ego nor {} merges ({} makes `{}`; the lane ends on the {side})",
                    bv.id,
                    bv.id,
                    bv.behavior.maneuver
                ));
            }
            if bv.relative_start != ramp_side {
                return Err(misfit!(
                    "the ending lane joins from the {side}, so {} must start `{ramp_side}`, not `{}`",
                    bv.id,
                    bv.relative_start
                ));
            }
            RouteSpec::LaneChange { from: mg.id.clone(), to: th.id.clone() }
        };
        bvs.push(BvPlan { index, id: bv.id.clone(), route, anchor: anchor.id.clone(), kind_fit });
    }
    let (vut, wanted_index) = if ego_merges {
        (RouteSpec::LaneChange { from: mg.id.clone(), to: th.id.clone() }, ending_index)
    } else if s.ego.maneuver == Move::Straight {
        (RouteSpec::Path { maneuver: th.id.clone() }, through_index)
    } else {
        return Err(misfit!("the ego's `{}` does not fit a merge from the {side}", s.ego.maneuver));
    };
    let mut plan = Plan { vut, bvs, exactness: 1.0, notes: Vec::new() };
    if let Some(k) = s.ego.start_lane.lane_index_from_left
        && usize::from(k) != wanted_index
    {
        plan.exactness *= RELAXED_LANE;
        plan.notes.push(format!("the ego starts in lane {wanted_index} from the left (of {lanes}), not lane {k}"));
    }
    Ok(plan)
}

/// Two (or more) lanes that become one: the BV and the ego each come along one feeder.
fn plan_fed_merge(f: &Fragment, s: &ScenarioSemantics, anchor: &Anchor) -> Result<Plan, Misfit> {
    // Feeders left to right, by the lateral offset of their entry from the merge point.
    let left = Point2::from_heading(anchor.heading_rad).perp();
    let mut feeders: Vec<(f64, &Maneuver)> = f
        .maneuvers
        .iter()
        .filter(|m| anchor.on_paths.iter().any(|(id, _)| *id == m.id))
        .filter_map(|m| f.anchor(&m.entry).map(|e| (e.position.sub(anchor.position).dot(left), m)))
        .collect();
    feeders.sort_by(|a, b| b.0.total_cmp(&a.0));
    if feeders.len() < 2 {
        return Err(Misfit::from("the merge has fewer than two feeding paths on its anchor"));
    }
    let n = feeders.len();
    let mut errors = Vec::new();
    for (ego_pos, exact) in lane_order(n, s.ego.start_lane.lane_index_from_left) {
        let Some((_, ego)) = feeders.get(ego_pos) else { continue };
        let mut bvs = Vec::new();
        for (index, bv) in s.interacting_bvs.iter().enumerate() {
            let d = match bv.relative_start {
                RelativeStart::AdjacentLeft => -1,
                RelativeStart::AdjacentRight => 1,
                r => {
                    errors.push(format!("{} starts `{r}`, not on a neighbouring feeder", bv.id));
                    break;
                }
            };
            match shifted(ego_pos, d, n).and_then(|p| feeders.get(p)) {
                Some((_, m)) => bvs.push(BvPlan {
                    index,
                    id: bv.id.clone(),
                    route: RouteSpec::Path { maneuver: m.id.clone() },
                    anchor: anchor.id.clone(),
                    kind_fit: kind_fit(bv.interaction_type, anchor.kind),
                }),
                None => errors.push(format!("no feeder on the {} of feeder {}", bv.relative_start, ego_pos + 1)),
            }
        }
        if bvs.len() == s.interacting_bvs.len() {
            let mut plan =
                Plan { vut: RouteSpec::Path { maneuver: ego.id.clone() }, bvs, exactness: 1.0, notes: vec![] };
            if !exact {
                plan.exactness *= RELAXED_LANE;
                plan.notes.push(format!("the ego comes along feeder {} from the left", ego_pos + 1));
            }
            return Ok(plan);
        }
    }
    Err(Misfit(errors.join("; ")))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn arms_are_found_by_bearing() {
        assert!((angle_between(0.1, TAU - 0.1) - 0.2).abs() < 1e-12);
        assert!((angle_between(PI, 0.0) - PI).abs() < 1e-12);
        assert_eq!(compass(1.5 * PI), "south");
        assert_eq!(compass(-0.1), "east");
        assert_eq!(compass(3.0), "west");
        // The ego from the south (arm bearing 270°): its left is the west arm, its right the east arm.
        let south = approach_bearing(Approach::FromSouth);
        assert!(angle_between(south - FRAC_PI_2, PI) < 1e-12);
        assert!(angle_between(south + FRAC_PI_2, 0.0) < 1e-12);
        assert!(angle_between(south + PI, FRAC_PI_2) < 1e-12);
    }

    #[test]
    fn lanes_are_tried_from_the_named_one_outwards() {
        assert_eq!(lane_order(4, Some(2)), [(1, true), (0, false), (2, false), (3, false)]);
        assert_eq!(lane_order(2, Some(5)), [(1, false), (0, false)]);
        assert_eq!(lane_order(2, None), [(0, true), (1, true)]);
        assert_eq!(shifted(0, -1, 3), None);
        assert_eq!(shifted(2, 1, 3), None);
        assert_eq!(shifted(1, 1, 3), Some(2));
    }

    #[test]
    fn repeated_reasons_are_given_once() {
        let e = |c: &str, r: &str| (c.to_owned(), Misfit::from(r));
        let errors = [e("ego in lane 1", "no lane"), e("ego in lane 2", "no lane"), e("ego in lane 3", "solid line")];
        assert_eq!(&*summarize(&errors), "no lane (2 ego starts); ego in lane 3: solid line");
        assert_eq!(&*summarize(&[e("", "arm a0 has no left-turn path")]), "arm a0 has no left-turn path");
    }

    fn anchor(id: &str, kind: AnchorKind, x: f64, y: f64, on_paths: &[(&str, f64)]) -> Anchor {
        Anchor {
            id: id.to_owned(),
            kind,
            lane: v2t_map::graph::LaneKey { road: "1".into(), section: 0, lane: -1 },
            position: Point2::new(x, y),
            heading_rad: 0.0,
            lane_s_m: 0.0,
            on_paths: on_paths.iter().map(|(m, s)| ((*m).to_owned(), *s)).collect(),
        }
    }

    fn feeder(id: &str, y: f64) -> Maneuver {
        Maneuver {
            id: format!("M/m/{id}"),
            turn: Turn::Straight,
            from_arm: None,
            to_arm: None,
            lanes: Vec::new(),
            path: vec![Point2::new(0.0, y), Point2::new(100.0, 0.0), Point2::new(140.0, 0.0)],
            entry: format!("M/entry/{id}"),
            exit: "M/exit".to_owned(),
            core_from_m: 90.0,
            core_to_m: 110.0,
        }
    }

    /// Two lanes that become one, heading east: `f0` from the right (y < 0), `f1` from the left.
    fn fed_merge() -> Fragment {
        Fragment {
            id: "M".into(),
            kind: FragmentKind::Merge,
            name: None,
            description: "Merge: 2 lanes become one.".into(),
            roads: vec!["1".into()],
            centre: Point2::new(100.0, 0.0),
            lanes_per_direction: 1,
            speed_limit_mps: None,
            arms: Vec::new(),
            maneuvers: vec![feeder("f0", -3.5), feeder("f1", 3.5)],
            lane_pairs: Vec::new(),
            anchors: vec![
                anchor("M/entry/f0", AnchorKind::Entry, 0.0, -3.5, &[]),
                anchor("M/entry/f1", AnchorKind::Entry, 0.0, 3.5, &[]),
                anchor("M/merge", AnchorKind::Merge, 100.0, 0.0, &[("M/m/f0", 100.06), ("M/m/f1", 100.06)]),
            ],
            usable_length_m: 0.0,
            test_area_m: None,
        }
    }

    fn cut_in() -> ScenarioSemantics {
        let text = include_str!("../../../config/examples/semantics_cut_in.json");
        v2t_model::semantics::parse_semantics_json(text).unwrap()
    }

    #[test]
    fn a_fed_merge_puts_the_bv_on_the_feeder_beside_the_ego() {
        // The BV starts on the ego's right: the ego takes the left feeder (f1), the BV the right one.
        let p = plan(&fed_merge(), &cut_in()).unwrap();
        assert_eq!(p.vut, RouteSpec::Path { maneuver: "M/m/f1".into() });
        assert_eq!(p.bvs[0].route, RouteSpec::Path { maneuver: "M/m/f0".into() });
        assert_eq!(p.bvs[0].anchor, "M/merge");
        // Lane 2 of 3 was named; the left feeder is lane 1 of 2.
        assert!(p.exactness < 1.0 && !p.notes.is_empty(), "{p:?}");
        let mut s = cut_in();
        s.interacting_bvs[0].relative_start = RelativeStart::Oncoming;
        let e = plan(&fed_merge(), &s).unwrap_err();
        assert!(e.contains("not on a neighbouring feeder"), "{e}");
    }

    #[test]
    fn a_junction_has_no_lane_change_and_a_segment_no_turn() {
        let mut s = cut_in();
        let e = plan_intersection(&fed_merge(), &s).unwrap_err();
        assert!(e.contains("no arm"), "{e}");
        s.ego.maneuver = Move::LeftTurn;
        let e = plan_segment_at(&fed_merge(), &s, 0).unwrap_err();
        assert!(e.contains("needs a junction"), "{e}");
        s.ego.maneuver = Move::LaneChangeLeft;
        let e = plan_intersection(&fed_merge(), &s).unwrap_err();
        assert!(e.contains("cannot be grounded inside a junction"), "{e}");
    }

    #[test]
    fn anchor_kinds_fit_their_interactions() {
        assert_eq!(kind_fit(InteractionType::UnprotectedLeftTurn, AnchorKind::Conflict), 1.0);
        assert_eq!(kind_fit(InteractionType::CutIn, AnchorKind::CutIn), 1.0);
        assert_eq!(kind_fit(InteractionType::Merge, AnchorKind::Merge), 1.0);
        assert!(kind_fit(InteractionType::Merge, AnchorKind::CutIn) < 1.0);
        assert_eq!(kind_fit(InteractionType::Crossing, AnchorKind::CutIn), 0.0);
    }
}
