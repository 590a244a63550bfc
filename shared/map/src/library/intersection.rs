//! Intersections: every junction with three or more arms, its maneuvers (approach lane →
//! connecting lanes → exit lane) classified by their heading change, and the conflict anchors
//! where maneuver paths from different arms cross or merge.

use std::collections::BTreeMap;

use v2t_model::geometry::{Point2, wrap_angle};

use super::{
    APPROACH_M, Anchor, AnchorKind, Arm, DEPARTURE_M, Fragment, FragmentKind, Maneuver, Polyline, Turn, anchor_on,
    back_from_end, compass, crossing, forward_from_start, lane_label, run_points,
};
use crate::Map;
use crate::graph::{LaneGraph, LaneKey};
use crate::xodr::Junction;

/// Heading change below which a maneuver is straight, rad (35°).
const STRAIGHT_RAD: f64 = 0.61;
/// Heading change above which it is a U-turn, rad (150°).
const U_TURN_RAD: f64 = 2.62;

struct Candidate {
    approach: usize,
    chain: Vec<usize>,
    exit: usize,
}

/// The lanes of a junction from each lane entering it to the lane it leaves into.
fn candidates(g: &LaneGraph, junction: &str) -> Vec<Candidate> {
    let inside = |i: usize| g.lane(i).is_some_and(|l| l.drivable && l.junction.as_deref() == Some(junction));
    let outside = |i: usize| g.lane(i).is_some_and(|l| l.drivable && l.junction.is_none());
    let mut out = Vec::new();
    for (c, lane) in g.lanes.iter().enumerate() {
        if !inside(c) {
            continue;
        }
        let approaches: Vec<usize> = lane.predecessors.iter().copied().filter(|&p| outside(p)).collect();
        if approaches.is_empty() {
            continue;
        }
        let mut chain = vec![c];
        let mut cur = c;
        while let Some(next) = g.lane(cur).and_then(|l| l.successors.iter().copied().find(|&n| inside(n))) {
            if chain.contains(&next) || chain.len() > 16 {
                break;
            }
            chain.push(next);
            cur = next;
        }
        let exits: Vec<usize> =
            g.lane(cur).map(|l| l.successors.iter().copied().filter(|&n| outside(n)).collect()).unwrap_or_default();
        for &approach in &approaches {
            for &exit in &exits {
                out.push(Candidate { approach, chain: chain.clone(), exit });
            }
        }
    }
    out
}

fn turn_of(delta: f64) -> Turn {
    if delta.abs() < STRAIGHT_RAD {
        Turn::Straight
    } else if delta.abs() > U_TURN_RAD {
        Turn::UTurn
    } else if delta > 0.0 {
        Turn::Left
    } else {
        Turn::Right
    }
}

pub(super) fn build(map: &Map) -> Vec<Fragment> {
    let g = &map.graph;
    let mut fragments = Vec::new();
    for j in &map.document.junctions {
        let cands = candidates(g, &j.id);
        let Some(centre) = centre_of(g, &cands) else { continue };
        let arm_lanes = arms_by_road_end(g, &cands);
        // An intersection: three or more arms and turning traffic. A diverge or a merge of a ramp
        // has three arms too, but every path through it goes straight on.
        if arm_lanes.len() < 3 || !has_turning_traffic(g, &cands) {
            continue;
        }
        let fid = format!("J{}", j.id);
        let arm_list = arms(g, centre, &arm_lanes);
        let Paths { mut anchors, maneuvers, cores, chains } = paths(g, &fid, &arm_list, &cands);
        anchors.extend(conflict_anchors(g, &fid, &maneuvers, &cores, &chains));
        let lanes_per_direction =
            arm_list.iter().map(|a| a.approach_lanes.len().max(a.exit_lanes.len())).max().unwrap_or(0);
        let speed_limit_mps = arm_list
            .iter()
            .filter_map(|a| a.approach_lanes.first().and_then(|k| g.find(k)).and_then(|i| g.lane(i)?.speed_limit_mps))
            .reduce(f64::max);
        fragments.push(Fragment {
            id: fid,
            kind: FragmentKind::Intersection,
            name: (!j.name.is_empty()).then(|| j.name.clone()),
            description: description(j, &arm_list, &maneuvers, &anchors),
            roads: roads(g, &arm_list, &cands),
            centre,
            lanes_per_direction: u8::try_from(lanes_per_direction).unwrap_or(u8::MAX),
            speed_limit_mps,
            arms: arm_list,
            maneuvers,
            lane_pairs: Vec::new(),
            anchors,
            usable_length_m: 0.0,
            test_area_m: None,
        });
    }
    fragments
}

/// The junction's centre: the mean of its connecting lanes' points; `None` without any.
fn centre_of(g: &LaneGraph, cands: &[Candidate]) -> Option<Point2> {
    let (mut sx, mut sy, mut n) = (0.0, 0.0, 0.0);
    for c in cands {
        for &i in &c.chain {
            for q in g.lane(i).map(|l| l.samples.as_slice()).unwrap_or_default() {
                sx += q.p.x;
                sy += q.p.y;
                n += 1.0;
            }
        }
    }
    (n != 0.0).then(|| Point2::new(sx / n, sy / n))
}

/// The approach and exit lanes of each arm, keyed by road end (road, at its end).
type ArmLanes = BTreeMap<(String, bool), (Vec<usize>, Vec<usize>)>;

/// Arms by road end (a loop road can touch the junction with both ends): an approach lane
/// arrives at the end it drives towards, an exit lane leaves from the end it starts at.
fn arms_by_road_end(g: &LaneGraph, cands: &[Candidate]) -> ArmLanes {
    let mut arms = ArmLanes::new();
    for c in cands {
        if let Some(l) = g.lane(c.approach) {
            let arm = arms.entry((l.key.road.clone(), l.forward)).or_default();
            if !arm.0.contains(&c.approach) {
                arm.0.push(c.approach);
            }
        }
        if let Some(l) = g.lane(c.exit) {
            let arm = arms.entry((l.key.road.clone(), !l.forward)).or_default();
            if !arm.1.contains(&c.exit) {
                arm.1.push(c.exit);
            }
        }
    }
    arms
}

/// Whether any path through the junction turns left or right.
fn has_turning_traffic(g: &LaneGraph, cands: &[Candidate]) -> bool {
    cands.iter().any(|c| {
        let heading =
            |i: usize, end: bool| g.lane(i).and_then(|l| if end { l.end() } else { l.start() }).map(|q| q.heading);
        matches!(
            (heading(c.approach, true), heading(c.exit, false)),
            (Some(a), Some(e)) if matches!(turn_of(wrap_angle(e - a)), Turn::Left | Turn::Right)
        )
    })
}

/// The arms counter-clockwise from east, named `a0`, `a1`, … in that order.
fn arms(g: &LaneGraph, centre: Point2, arm_lanes: &ArmLanes) -> Vec<Arm> {
    let mut arm_list: Vec<Arm> = Vec::new();
    for ((road, at_end), (approach, exit)) in arm_lanes {
        // Bearing from the centre to where the arm touches the junction.
        let touch: Vec<Point2> = approach
            .iter()
            .filter_map(|&i| g.lane(i).and_then(|l| l.end()).map(|q| q.p))
            .chain(exit.iter().filter_map(|&i| g.lane(i).and_then(|l| l.start()).map(|q| q.p)))
            .collect();
        let k = touch.len().max(1) as f64;
        let mid = Point2::new(touch.iter().map(|p| p.x).sum::<f64>() / k, touch.iter().map(|p| p.y).sum::<f64>() / k);
        let d = mid.sub(centre);
        let bearing = d.y.atan2(d.x).rem_euclid(std::f64::consts::TAU);
        // Left to right for a driver: approach lanes face the junction (left = +90° of
        // −bearing), exit lanes face away (left = +90° of bearing).
        arm_list.push(Arm {
            id: String::new(),
            road: road.clone(),
            road_end: *at_end,
            bearing_rad: bearing,
            approach_lanes: left_to_right(g, centre, approach, bearing + std::f64::consts::PI, true),
            exit_lanes: left_to_right(g, centre, exit, bearing, false),
        });
    }
    arm_list.sort_by(|a, b| a.bearing_rad.total_cmp(&b.bearing_rad));
    for (k, a) in arm_list.iter_mut().enumerate() {
        a.id = format!("a{k}");
    }
    arm_list
}

/// `lanes` left to right for a driver heading `facing` (left = +90° of it), placed by their end
/// (`at_end`) or start.
fn left_to_right(g: &LaneGraph, centre: Point2, lanes: &[usize], facing: f64, at_end: bool) -> Vec<LaneKey> {
    let left = Point2::from_heading(facing + std::f64::consts::FRAC_PI_2);
    let mut v: Vec<(f64, usize)> = lanes
        .iter()
        .filter_map(|&i| {
            let l = g.lane(i)?;
            let q = if at_end { l.end()? } else { l.start()? };
            Some((q.p.sub(centre).dot(left), i))
        })
        .collect();
    v.sort_by(|a, b| b.0.total_cmp(&a.0));
    v.into_iter().filter_map(|(_, i)| g.lane(i).map(|l| l.key.clone())).collect()
}

/// A junction's maneuvers with their entry and exit anchors, and per maneuver the path through
/// the junction (its core) and the connecting lanes it runs on.
struct Paths {
    anchors: Vec<Anchor>,
    maneuvers: Vec<Maneuver>,
    cores: Vec<Polyline>,
    chains: Vec<Vec<usize>>,
}

/// One maneuver per candidate whose approach and exit lanes exist, each entry and exit anchor
/// once.
fn paths(g: &LaneGraph, fid: &str, arm_list: &[Arm], cands: &[Candidate]) -> Paths {
    let arm_of = |road: &str, at_end: bool| {
        arm_list.iter().find(|a| a.road == road && a.road_end == at_end).map(|a| a.id.clone())
    };
    let mut out = Paths { anchors: Vec::new(), maneuvers: Vec::new(), cores: Vec::new(), chains: Vec::new() };
    for c in cands {
        let (Some(al), Some(el)) = (g.lane(c.approach), g.lane(c.exit)) else { continue };
        let (Some(a_end), Some(e_start)) = (al.end(), el.start()) else { continue };
        let turn = turn_of(wrap_angle(e_start.heading - a_end.heading));
        let from_arm = arm_of(&al.key.road, al.forward).unwrap_or_default();
        let to_arm = arm_of(&el.key.road, !el.forward).unwrap_or_default();
        let back = back_from_end(g, c.approach, APPROACH_M);
        let ahead = forward_from_start(g, c.exit, DEPARTURE_M);
        let core_runs: Vec<_> = c.chain.iter().filter_map(|&i| g.lane(i).map(|l| (i, 0.0, l.length))).collect();
        let (mut path, back_len) = run_points(g, &back);
        let (core, core_len) = run_points(g, &core_runs);
        let (tail, _) = run_points(g, &ahead);
        path.extend(&core);
        path.extend(&tail);
        let entry_id = format!("{fid}/entry/{from_arm}/{}", lane_label(&al.key));
        let exit_id = format!("{fid}/exit/{to_arm}/{}", lane_label(&el.key));
        if out.anchors.iter().all(|a| a.id != entry_id)
            && let Some(&(i, s, _)) = back.first()
            && let Some(a) = anchor_on(g, i, s, entry_id.clone(), AnchorKind::Entry)
        {
            out.anchors.push(a);
        }
        if out.anchors.iter().all(|a| a.id != exit_id)
            && let Some(&(i, _, s)) = ahead.last()
            && let Some(a) = anchor_on(g, i, s, exit_id.clone(), AnchorKind::Exit)
        {
            out.anchors.push(a);
        }
        let turn_name = format!("{turn:?}").to_lowercase();
        let mut lanes: Vec<_> = back.iter().filter_map(|r| g.lane(r.0).map(|l| l.key.clone())).collect();
        lanes.extend(c.chain.iter().filter_map(|&i| g.lane(i).map(|l| l.key.clone())));
        lanes.extend(ahead.iter().filter_map(|r| g.lane(r.0).map(|l| l.key.clone())));
        out.maneuvers.push(Maneuver {
            id: format!("{fid}/m/{from_arm}:{}>{to_arm}:{}/{turn_name}", lane_label(&al.key), lane_label(&el.key)),
            turn,
            from_arm: Some(from_arm),
            to_arm: Some(to_arm),
            lanes,
            path: Polyline::new(&path).points().to_vec(),
            entry: entry_id,
            exit: exit_id,
            core_from_m: back_len,
            core_to_m: back_len + core_len,
        });
        out.cores.push(Polyline::new(&core));
        out.chains.push(c.chain.clone());
    }
    out
}

/// The conflict and merge anchors between maneuvers from different arms, in maneuver-pair order.
fn conflict_anchors(
    g: &LaneGraph,
    fid: &str,
    maneuvers: &[Maneuver],
    cores: &[Polyline],
    chains: &[Vec<usize>],
) -> Vec<Anchor> {
    let mut anchors = Vec::new();
    for i in 0..maneuvers.len() {
        for k in i + 1..maneuvers.len() {
            let (Some(mi), Some(mk)) = (maneuvers.get(i), maneuvers.get(k)) else { continue };
            if mi.from_arm == mk.from_arm {
                continue;
            }
            let (Some(ci), Some(ck)) = (cores.get(i), cores.get(k)) else { continue };
            // Paths into the same exit lane that only touch where they end (parallel there, so
            // no proper crossing) merge at the exit lane's start.
            let touch =
                || (mi.exit == mk.exit).then(|| ci.points().last().map(|p| (*p, ci.length(), ck.length()))).flatten();
            let Some((p, si, sk)) = crossing(ci, ck).or_else(touch) else { continue };
            // Two paths into the same exit lane merge: their first contact is where the merge
            // conflict begins.
            let (kind, tag) =
                if mi.exit == mk.exit { (AnchorKind::Merge, "merge") } else { (AnchorKind::Conflict, "x") };
            let heading = ci.at(si).map_or(0.0, |(_, h)| h);
            let chain = chains.get(i).map(Vec::as_slice).unwrap_or_default();
            let Some((lane, lane_s_m)) = lane_at(g, chain, si) else { continue };
            anchors.push(Anchor {
                id: format!("{fid}/{tag}/{i}-{k}"),
                kind,
                lane,
                position: p,
                heading_rad: heading,
                lane_s_m,
                on_paths: vec![(mi.id.clone(), mi.core_from_m + si), (mk.id.clone(), mk.core_from_m + sk)],
            });
        }
    }
    anchors
}

/// The connecting lane of `chain` that holds distance `s` along it, and `s` along that lane
/// (clamped onto it); the last lane when `s` lies beyond the chain.
fn lane_at(g: &LaneGraph, chain: &[usize], s: f64) -> Option<(LaneKey, f64)> {
    let mut acc = 0.0;
    let mut on = None;
    for &lane in chain {
        let len = g.lane(lane).map_or(0.0, |l| l.length);
        on = g.lane(lane).map(|l| (l.key.clone(), (s - acc).clamp(0.0, len)));
        if s <= acc + len {
            break;
        }
        acc += len;
    }
    on
}

/// The fragment's text: its arms, its maneuvers by turn, its conflict and merge points.
fn description(j: &Junction, arm_list: &[Arm], maneuvers: &[Maneuver], anchors: &[Anchor]) -> String {
    let count = |t: Turn| maneuvers.iter().filter(|m| m.turn == t).count();
    let conflicts = anchors.iter().filter(|a| a.kind == AnchorKind::Conflict).count();
    let merges = anchors.iter().filter(|a| a.kind == AnchorKind::Merge).count();
    let arm_text: Vec<String> = arm_list
        .iter()
        .map(|a| {
            format!(
                "{} arm to the {} ({} lanes in, {} out)",
                a.id,
                compass(a.bearing_rad),
                a.approach_lanes.len(),
                a.exit_lanes.len()
            )
        })
        .collect();
    format!(
        "{}-arm intersection, junction {}{}: {}. Maneuvers: {} left turns, {} straight, {} right turns{}; \
         {} crossing conflict points, {} merge points. Unprotected left turn against oncoming traffic, \
         crossing paths, turning into the same lane.",
        arm_list.len(),
        j.id,
        if j.name.is_empty() { String::new() } else { format!(" ({})", j.name) },
        arm_text.join(", "),
        count(Turn::Left),
        count(Turn::Straight),
        count(Turn::Right),
        if count(Turn::UTurn) > 0 { format!(", {} U-turns", count(Turn::UTurn)) } else { String::new() },
        conflicts,
        merges,
    )
}

/// The roads of the arms, then those of the connecting lanes, each once, in that order.
fn roads(g: &LaneGraph, arm_list: &[Arm], cands: &[Candidate]) -> Vec<String> {
    let mut roads: Vec<String> = Vec::new();
    for a in arm_list {
        if !roads.contains(&a.road) {
            roads.push(a.road.clone());
        }
    }
    for c in cands {
        for &i in &c.chain {
            if let Some(l) = g.lane(i)
                && !roads.contains(&l.key.road)
            {
                roads.push(l.key.road.clone());
            }
        }
    }
    roads
}
