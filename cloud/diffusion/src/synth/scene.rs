//! Scenes of the synthetic corpus, set up on fragments of the topology library: an unprotected
//! left turn across another maneuver at an intersection, a cut-in on a multi-lane segment and a
//! merge at an on-ramp or lane drop. Each scene samples its drivers and places the agents so that
//! they reach the conflict within a few seconds of each other.

use rand_chacha::ChaCha8Rng;
use v2t_map::library::{AnchorKind, Fragment, FragmentKind, Maneuver, Turn};
use v2t_model::metrics::{ConflictKind, ConflictOptions, Dimensions, OccupancyInterval, conflict_zones};
use v2t_model::path::ReferencePath;

use super::driver::{DriverParams, uniform};
use super::sim::{AgentSetup, Behavior};
use crate::mining::InteractionKind;

/// Shortest lane pair a cut-in is simulated on, m.
const MIN_CUT_IN_M: f64 = 150.0;
/// How far before its route a vehicle behind may start, m.
const RUN_IN_M: f64 = 40.0;
/// Probability of a third vehicle in a scene.
const EXTRA_AGENT_P: f64 = 0.5;
/// Nominal speed where the map gives no limit: intersections, m/s.
const INTERSECTION_MPS: f64 = 10.0;
/// … and segments and merges, m/s.
const ROAD_MPS: f64 = 15.0;

fn sample_dims(rng: &mut ChaCha8Rng) -> Dimensions {
    Dimensions { length_m: uniform(rng, 4.2, 5.0), width_m: uniform(rng, 1.75, 1.95) }
}

fn route(m: &Maneuver) -> Option<ReferencePath> {
    ReferencePath::from_points(&m.path).ok()
}

fn pick<'a, T>(rng: &mut ChaCha8Rng, items: &'a [T]) -> Option<&'a T> {
    if items.is_empty() {
        return None;
    }
    let k = (uniform(rng, 0.0, items.len() as f64).floor() as usize).min(items.len() - 1);
    items.get(k)
}

/// The scene kinds a fragment can host.
pub(crate) fn kinds_of(f: &Fragment) -> Vec<InteractionKind> {
    let mut out = Vec::new();
    if !left_turn_pairs(f).is_empty() {
        out.push(InteractionKind::LeftTurn);
    }
    if f.lane_pairs.iter().any(|p| p.usable_m >= MIN_CUT_IN_M) {
        out.push(InteractionKind::CutIn);
    }
    if f.kind == FragmentKind::Merge && merge_pair(f).is_some() {
        out.push(InteractionKind::Merge);
    }
    out
}

/// (left-turning maneuver, other maneuver, arc length of the crossing along each).
fn left_turn_pairs(f: &Fragment) -> Vec<(&Maneuver, &Maneuver, f64, f64)> {
    let mut out = Vec::new();
    for a in f.anchors.iter().filter(|a| a.kind == AnchorKind::Conflict) {
        let [(p, sp), (q, sq)] = a.on_paths.as_slice() else { continue };
        let (Some(mp), Some(mq)) = (f.maneuver(p), f.maneuver(q)) else { continue };
        if mp.turn == Turn::Left {
            out.push((mp, mq, *sp, *sq));
        } else if mq.turn == Turn::Left {
            out.push((mq, mp, *sq, *sp));
        }
    }
    out
}

/// (merging maneuver, through maneuver, merge point along each).
fn merge_pair(f: &Fragment) -> Option<(&Maneuver, &Maneuver, f64, f64)> {
    let a = f.anchors.iter().find(|a| a.kind == AnchorKind::Merge)?;
    let [(p, sp), (q, sq)] = a.on_paths.as_slice() else { return None };
    let (mp, mq) = (f.maneuver(p)?, f.maneuver(q)?);
    if mp.id.ends_with("/merging") { Some((mp, mq, *sp, *sq)) } else { Some((mq, mp, *sq, *sp)) }
}

/// An occupancy interval of half-width `half` around `s`.
fn around(s: f64, half: f64) -> OccupancyInterval {
    OccupancyInterval { enter_s_m: s - half, exit_s_m: s + half }
}

/// Start arc length and speed so that the agent reaches `s_conflict` after about `t_arrive` s.
fn place(s_conflict: f64, v: f64, t_arrive: f64) -> f64 {
    (s_conflict - v * t_arrive).max(0.0)
}

/// A left turn: the turner gives way to the other maneuver by gap acceptance.
pub(crate) fn left_turn(f: &Fragment, rng: &mut ChaCha8Rng) -> Option<Vec<AgentSetup>> {
    let pairs = left_turn_pairs(f);
    let &(turner, other, s_t, s_o) = pick(rng, &pairs)?;
    let (rt, ro) = (route(turner)?, route(other)?);
    let nominal = f.speed_limit_mps.unwrap_or(INTERSECTION_MPS);
    let (dt, d_o) = (sample_dims(rng), sample_dims(rng));
    let zone = conflict_zones(&rt, dt, &ro, d_o, &ConflictOptions::default())
        .into_iter()
        .filter(|z| z.kind == ConflictKind::Crossing)
        .min_by(|a, b| {
            let da = (0.5 * (a.vut.enter_s_m + a.vut.exit_s_m) - s_t).abs();
            let db = (0.5 * (b.vut.enter_s_m + b.vut.exit_s_m) - s_t).abs();
            da.total_cmp(&db)
        });
    let (own, theirs) =
        zone.map_or((around(s_t, 0.5 * dt.length_m + 2.0), around(s_o, 0.5 * d_o.length_m + 2.0)), |z| (z.vut, z.bv));
    let d_turner = DriverParams::sample(rng, nominal);
    let d_other = DriverParams::sample(rng, nominal);
    let t_arrive = uniform(rng, 3.0, 6.0);
    let delta = uniform(rng, -3.0, 4.0);
    let v_t = d_turner.curve_capped_speed(&rt, own.enter_s_m, d_turner.desired_speed_mps) * uniform(rng, 0.7, 1.0);
    let v_o = d_other.desired_speed_mps * uniform(rng, 0.7, 1.0);
    let mut agents = vec![
        AgentSetup {
            name: "turner",
            route_id: turner.id.clone(),
            start_s: place(own.enter_s_m, v_t, t_arrive),
            route: rt,
            start_speed_mps: v_t,
            start_offset_m: 0.0,
            driver: d_turner,
            dims: dt,
            behavior: Behavior::GiveWay { others: [Some(1), Some(2)], own, theirs },
        },
        AgentSetup {
            name: "crossing",
            route_id: other.id.clone(),
            start_s: place(theirs.enter_s_m, v_o, (t_arrive + delta).max(1.0)),
            route: ro,
            start_speed_mps: v_o,
            start_offset_m: 0.0,
            driver: d_other,
            dims: d_o,
            behavior: Behavior::Free,
        },
    ];
    add_behind(&mut agents, 1, "crossing_2", nominal, rng);
    Some(agents)
}

/// A cut-in: the cutter changes from a neighbouring lane into the follower's lane ahead of it.
pub(crate) fn cut_in(f: &Fragment, rng: &mut ChaCha8Rng) -> Option<Vec<AgentSetup>> {
    let pairs: Vec<_> = f.lane_pairs.iter().filter(|p| p.usable_m >= MIN_CUT_IN_M).collect();
    let pair = *pick(rng, &pairs)?;
    let into_left = uniform(rng, 0.0, 1.0) < 0.5;
    let (target_id, source_id) = if into_left { (&pair.left, &pair.right) } else { (&pair.right, &pair.left) };
    let (target, source) = (f.maneuver(target_id)?, f.maneuver(source_id)?);
    let (rt, rs) = (route(target)?, route(source)?);
    let offset = rt.project(rs.point_at(0.5 * rs.length()))?.l_m;
    let nominal = f.speed_limit_mps.unwrap_or(ROAD_MPS);
    let d_follower = DriverParams::sample(rng, nominal);
    let d_cutter = DriverParams::sample(rng, nominal);
    let s_follower = uniform(rng, 5.0, 30.0);
    let v_follower = d_follower.desired_speed_mps * uniform(rng, 0.7, 1.0);
    let v_cutter = (v_follower + uniform(rng, -4.0, 2.0)).max(3.0);
    let (df, dc) = (sample_dims(rng), sample_dims(rng));
    let lead = uniform(rng, 8.0, 45.0);
    let mut agents = vec![
        AgentSetup {
            name: "cutter",
            route_id: target.id.clone(),
            route: rt.clone(),
            start_s: s_follower + lead,
            start_speed_mps: v_cutter,
            start_offset_m: offset,
            driver: DriverParams { desired_speed_mps: v_cutter.max(d_cutter.desired_speed_mps * 0.8), ..d_cutter },
            dims: dc,
            behavior: Behavior::LaneChange { behind: 1, intent_s: uniform(rng, 0.5, 3.0), give_up_s: 8.0 },
        },
        AgentSetup {
            name: "follower",
            route_id: target.id.clone(),
            route: rt.clone(),
            start_s: s_follower,
            start_speed_mps: v_follower,
            start_offset_m: 0.0,
            driver: d_follower,
            dims: df,
            behavior: Behavior::Free,
        },
    ];
    // Half the time a third vehicle leads in the target lane, 15–60 m ahead of the cutter.
    if uniform(rng, 0.0, 1.0) < EXTRA_AGENT_P {
        let v = v_cutter * uniform(rng, 0.8, 1.15);
        let driver = DriverParams { desired_speed_mps: v, ..DriverParams::sample(rng, nominal) };
        let dims = sample_dims(rng);
        agents.push(AgentSetup {
            name: "lead",
            route_id: target.id.clone(),
            route: rt,
            start_s: s_follower + lead + uniform(rng, 15.0, 60.0),
            start_speed_mps: v,
            start_offset_m: 0.0,
            driver,
            dims,
            behavior: Behavior::Free,
        });
    }
    Some(agents)
}

/// Half the time, a second vehicle on the route of `agents[of]`, 1.5–5 s behind it (starting at
/// most [`RUN_IN_M`] before the route, on its straight extension).
fn add_behind(agents: &mut Vec<AgentSetup>, of: usize, name: &'static str, nominal: f64, rng: &mut ChaCha8Rng) {
    if uniform(rng, 0.0, 1.0) >= EXTRA_AGENT_P {
        return;
    }
    let Some(base) = agents.get(of) else { return };
    let driver = DriverParams::sample(rng, nominal);
    let dims = sample_dims(rng);
    let v = base.start_speed_mps * uniform(rng, 0.85, 1.1);
    let start_s = base.start_s - v * uniform(rng, 1.5, 5.0) - 0.5 * (base.dims.length_m + dims.length_m);
    if start_s < -RUN_IN_M {
        return;
    }
    let extra =
        AgentSetup { name, start_s, start_speed_mps: v, driver, dims, behavior: Behavior::Free, ..base.clone() };
    agents.push(extra);
}

/// A merge: the merging vehicle gives way to the through vehicle by gap acceptance at the merge
/// point, or goes ahead of it.
pub(crate) fn merge(f: &Fragment, rng: &mut ChaCha8Rng) -> Option<Vec<AgentSetup>> {
    let (merging, through, s_m, s_t) = merge_pair(f)?;
    let (rm, rt) = (route(merging)?, route(through)?);
    let nominal = f.speed_limit_mps.unwrap_or(ROAD_MPS);
    let (dm, dt) = (sample_dims(rng), sample_dims(rng));
    let own = around(s_m, 0.5 * (dm.length_m + dt.length_m));
    let theirs = around(s_t, 0.5 * (dm.length_m + dt.length_m));
    let d_merging = DriverParams::sample(rng, nominal);
    let d_through = DriverParams::sample(rng, nominal);
    let t_arrive = uniform(rng, 3.0, 6.0);
    let delta = uniform(rng, -3.0, 3.0);
    let v_m = d_merging.curve_capped_speed(&rm, own.enter_s_m, d_merging.desired_speed_mps) * uniform(rng, 0.6, 1.0);
    let v_t = d_through.desired_speed_mps * uniform(rng, 0.7, 1.0);
    let mut agents = vec![
        AgentSetup {
            name: "merging",
            route_id: merging.id.clone(),
            start_s: place(own.enter_s_m, v_m, t_arrive),
            route: rm,
            start_speed_mps: v_m,
            start_offset_m: 0.0,
            driver: d_merging,
            dims: dm,
            behavior: Behavior::GiveWay { others: [Some(1), Some(2)], own, theirs },
        },
        AgentSetup {
            name: "through",
            route_id: through.id.clone(),
            start_s: place(theirs.enter_s_m, v_t, (t_arrive + delta).max(1.0)),
            route: rt,
            start_speed_mps: v_t,
            start_offset_m: 0.0,
            driver: d_through,
            dims: dt,
            behavior: Behavior::Free,
        },
    ];
    add_behind(&mut agents, 1, "through_2", nominal, rng);
    Some(agents)
}
