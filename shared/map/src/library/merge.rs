//! Merges: a drivable lane that ends into a neighbour driving the same way (an on-ramp's
//! acceleration lane, a lane drop), and a lane fed by two drivable lanes outside intersections (a
//! junction-based merge).

use std::collections::HashSet;

use v2t_model::geometry::Point2;

use super::{
    APPROACH_M, Anchor, AnchorKind, DEPARTURE_M, Fragment, FragmentKind, Maneuver, Polyline, Turn, anchor_on,
    back_from_end, compass, forward_from_start, lane_label, run_points,
};
use crate::Map;
use crate::graph::LaneGraph;

/// Width at its end below which a lane counts as tapering out, m.
const TAPERED_M: f64 = 0.5;
/// How far past the merge point a merge's core reaches, m.
const JOIN_M: f64 = 15.0;
/// The merging path moves across into the target lane over this much of the ending lane's end, m.
const BLEND_M: f64 = 60.0;

pub(super) fn build(map: &Map, intersections: &HashSet<String>) -> Vec<Fragment> {
    let g = &map.graph;
    let mut out = Vec::new();
    for (i, l) in g.lanes.iter().enumerate() {
        if !l.drivable || l.junction.is_some() {
            continue;
        }
        let Some(end) = l.end() else { continue };
        let drivable_next = l.successors.iter().any(|&n| g.lane(n).is_some_and(|x| x.drivable));
        for (nb, turn) in [(l.left, Turn::Left), (l.right, Turn::Right)] {
            let Some(nb) = nb.filter(|n| n.same_direction) else { continue };
            let Some(target) = g.lane(nb.lane).filter(|t| t.drivable) else { continue };
            let target_goes_on = target.successors.iter().any(|&n| g.lane(n).is_some_and(|x| x.drivable));
            let ends_here = end.width < TAPERED_M || (!drivable_next && target_goes_on);
            if ends_here && let Some(f) = lane_drop(g, i, nb.lane, turn) {
                out.push(f);
                break;
            }
        }
    }
    // Lanes fed by two drivable lanes, outside intersections.
    for (x, l) in g.lanes.iter().enumerate() {
        if !l.drivable || l.junction.as_ref().is_some_and(|j| intersections.contains(j)) {
            continue;
        }
        let feeders: Vec<usize> = l
            .predecessors
            .iter()
            .copied()
            .filter(|&p| {
                g.lane(p)
                    .is_some_and(|pl| pl.drivable && !pl.junction.as_ref().is_some_and(|j| intersections.contains(j)))
            })
            .collect();
        if feeders.len() >= 2
            && let Some(f) = fed_merge(g, x, &feeders)
        {
            out.push(f);
        }
    }
    out
}

fn lane_drop(g: &LaneGraph, ending: usize, target: usize, turn: Turn) -> Option<Fragment> {
    let l = g.lane(ending)?;
    let t = g.lane(target)?;
    let fid = format!("M{}", lane_label(&l.key));
    let end = l.end()?;
    // Where the ending lane's end lies along the target lane.
    let target_line = Polyline::new(&t.samples.iter().map(|q| q.p).collect::<Vec<_>>());
    let (merge_s, _) = target_line.project(end.p)?;
    // The through path: the target lane and what feeds it, up to the merge point, then on.
    let mut through_back = back_from_end(g, target, APPROACH_M + t.length);
    if let Some(last) = through_back.last_mut() {
        last.2 = merge_s.max(last.1);
    }
    let (mut through_path, through_merge_s) = run_points(g, &through_back);
    let after = forward_ahead(g, target, merge_s, JOIN_M + DEPARTURE_M);
    let (after_pts, _) = run_points(g, &after);
    through_path.extend(after_pts.iter().skip(1));
    let through_line = Polyline::new(&through_path);
    // The merging path: the ending lane (up to APPROACH_M plus its own length), drawn over its
    // last BLEND_M into the target lane so that it reaches the target's centreline at the merge
    // point, then the target lane on.
    let back = back_from_end(g, ending, APPROACH_M + l.length);
    let (raw, back_len) = run_points(g, &back);
    let mut merge_path = blend_into(&raw, &through_line, BLEND_M.min(back_len));
    let merge_on_merging = Polyline::new(&merge_path).length();
    merge_path.extend(after_pts.iter().skip(1));
    let merge_line = Polyline::new(&merge_path);
    let mut anchors = Vec::new();
    let entry_merge = format!("{fid}/entry/merging");
    let entry_through = format!("{fid}/entry/through");
    let exit = format!("{fid}/exit");
    let &(mi, ms, _) = back.first()?;
    anchors.push(anchor_on(g, mi, ms, entry_merge.clone(), AnchorKind::Entry)?);
    let &(ti, ts, _) = through_back.first()?;
    anchors.push(anchor_on(g, ti, ts, entry_through.clone(), AnchorKind::Entry)?);
    let &(ei, _, es) = after.last()?;
    anchors.push(anchor_on(g, ei, es, exit.clone(), AnchorKind::Exit)?);
    let merging_id = format!("{fid}/m/merging");
    let through_id = format!("{fid}/m/through");
    let mut merge_anchor = anchor_on(g, target, merge_s, format!("{fid}/merge"), AnchorKind::Merge)?;
    merge_anchor.on_paths =
        vec![(merging_id.clone(), merge_on_merging), (through_id.clone(), through_merge_s.max(0.0))];
    anchors.push(merge_anchor);
    let keys =
        |runs: &[(usize, f64, f64)]| runs.iter().filter_map(|r| g.lane(r.0).map(|x| x.key.clone())).collect::<Vec<_>>();
    let mut merging_lanes = keys(&back);
    merging_lanes.extend(keys(&after));
    let mut through_lanes = keys(&through_back);
    through_lanes.extend(keys(&after));
    // The target lane ends the approach and starts what follows the merge point: name it once.
    through_lanes.dedup();
    let maneuvers = vec![
        Maneuver {
            id: merging_id,
            turn,
            from_arm: None,
            to_arm: None,
            lanes: merging_lanes,
            path: merge_line.points().to_vec(),
            entry: entry_merge,
            exit: exit.clone(),
            core_from_m: (back_len - l.length).max(0.0),
            core_to_m: (merge_on_merging + JOIN_M).min(merge_line.length()),
        },
        Maneuver {
            id: through_id,
            turn: Turn::Straight,
            from_arm: None,
            to_arm: None,
            lanes: through_lanes,
            path: through_line.points().to_vec(),
            entry: entry_through,
            exit,
            core_from_m: (through_merge_s - l.length).max(0.0),
            core_to_m: through_merge_s + JOIN_M,
        },
    ];
    let side = if turn == Turn::Left { "left" } else { "right" };
    let ramp = matches!(l.kind.as_str(), "onRamp" | "entry" | "connectingRamp") || back.len() > 1;
    let description = format!(
        "Merge on road {}: lane {} ({}) ends after {:.0} m and merges {side} into lane {}, heading {}; \
         {} lanes the same way at the merge point. {} Fits merging, cut-in at a lane drop, zipper merging.",
        l.key.road,
        l.key.lane,
        l.kind,
        l.length,
        t.key.lane,
        compass(end.heading),
        1 + count_same_direction(g, target),
        if ramp { "On-ramp acceleration lane." } else { "Lane drop." },
    );
    Some(Fragment {
        id: fid,
        kind: FragmentKind::Merge,
        name: None,
        description,
        roads: vec![l.key.road.clone()],
        centre: end.p,
        lanes_per_direction: u8::try_from(1 + count_same_direction(g, target)).unwrap_or(u8::MAX),
        speed_limit_mps: t.speed_limit_mps,
        arms: Vec::new(),
        maneuvers,
        lane_pairs: Vec::new(),
        anchors,
        usable_length_m: l.length,
        test_area_m: None,
    })
}

/// `points` with their last `blend_m` moved onto `onto`: each point goes the fraction
/// `w(u) = 10u³ − 15u⁴ + 6u⁵` of the way to its nearest point on `onto`, `u` running from 0 at the
/// blend's start to 1 at the last point, so the result leaves `points` with zero slope and
/// curvature and ends on `onto`.
fn blend_into(points: &[Point2], onto: &Polyline, blend_m: f64) -> Vec<Point2> {
    let line = Polyline::new(points);
    let total = line.length();
    let start = total - blend_m;
    let mut s = 0.0;
    let mut out = Vec::with_capacity(points.len());
    for (k, &p) in points.iter().enumerate() {
        if k > 0
            && let Some(prev) = points.get(k - 1)
        {
            s += prev.dist(p);
        }
        if blend_m <= 0.0 || s < start {
            out.push(p);
            continue;
        }
        let u = ((s - start) / blend_m).clamp(0.0, 1.0);
        let w = u * u * u * (10.0 - 15.0 * u + 6.0 * u * u);
        let q = onto.project(p).and_then(|(sq, _)| onto.at(sq)).map_or(p, |(q, _)| q);
        out.push(p.lerp(q, w));
    }
    out
}

/// Same-direction drivable lanes beside `lane` (not counting it).
fn count_same_direction(g: &LaneGraph, lane: usize) -> usize {
    let mut n = 0;
    for go_left in [true, false] {
        let mut cur = lane;
        while let Some(nb) = g.lane(cur).and_then(|l| if go_left { l.left } else { l.right }) {
            if !nb.same_direction || !g.lane(nb.lane).is_some_and(|x| x.drivable) || n > 16 {
                break;
            }
            n += 1;
            cur = nb.lane;
        }
    }
    n
}

/// Runs from `s` along `lane` for `dist` m, then through unique successors.
fn forward_ahead(g: &LaneGraph, lane: usize, s: f64, dist: f64) -> Vec<(usize, f64, f64)> {
    let Some(l) = g.lane(lane) else { return Vec::new() };
    if s + dist <= l.length {
        return vec![(lane, s.max(0.0), s + dist)];
    }
    let mut runs = if s < l.length { vec![(lane, s.max(0.0), l.length)] } else { Vec::new() };
    let rest = dist - (l.length - s).max(0.0);
    let into = (s - l.length).max(0.0);
    if let [n] = l.successors.as_slice() {
        let mut more = forward_from_start(g, *n, into + rest);
        if let Some(first) = more.first_mut() {
            first.1 = into.min(first.2);
        }
        runs.extend(more);
    }
    runs
}

fn fed_merge(g: &LaneGraph, lane: usize, feeders: &[usize]) -> Option<Fragment> {
    let l = g.lane(lane)?;
    let fid = format!("M{}", lane_label(&l.key));
    let start = l.start()?;
    let after = forward_from_start(g, lane, DEPARTURE_M);
    let (after_pts, _) = run_points(g, &after);
    let exit = format!("{fid}/exit");
    let &(ei, _, es) = after.last()?;
    let mut anchors = vec![anchor_on(g, ei, es, exit.clone(), AnchorKind::Exit)?];
    let mut maneuvers = Vec::new();
    let mut on_paths = Vec::new();
    for (k, &f) in feeders.iter().enumerate() {
        let back = back_from_end(g, f, APPROACH_M);
        let (mut pts, back_len) = run_points(g, &back);
        pts.extend(&after_pts);
        let &(bi, bs, _) = back.first()?;
        let entry = format!("{fid}/entry/f{k}");
        anchors.push(anchor_on(g, bi, bs, entry.clone(), AnchorKind::Entry)?);
        let id = format!("{fid}/m/f{k}");
        on_paths.push((id.clone(), back_len));
        let line = Polyline::new(&pts);
        let mut lanes: Vec<_> = back.iter().filter_map(|r| g.lane(r.0).map(|x| x.key.clone())).collect();
        lanes.extend(after.iter().filter_map(|r| g.lane(r.0).map(|x| x.key.clone())));
        maneuvers.push(Maneuver {
            id,
            turn: Turn::Straight,
            from_arm: None,
            to_arm: None,
            lanes,
            path: line.points().to_vec(),
            entry,
            exit: exit.clone(),
            core_from_m: (back_len - 10.0).max(0.0),
            core_to_m: back_len + 10.0,
        });
    }
    anchors.push(Anchor {
        id: format!("{fid}/merge"),
        kind: AnchorKind::Merge,
        lane: l.key.clone(),
        position: start.p,
        heading_rad: start.heading,
        lane_s_m: 0.0,
        on_paths,
    });
    Some(Fragment {
        id: fid,
        kind: FragmentKind::Merge,
        name: None,
        description: format!(
            "Merge: {} lanes become lane {} of road {}, heading {}. Fits merging and zipper merging.",
            feeders.len(),
            l.key.lane,
            l.key.road,
            compass(start.heading)
        ),
        roads: vec![l.key.road.clone()],
        centre: start.p,
        lanes_per_direction: u8::try_from(1 + count_same_direction(g, lane)).unwrap_or(u8::MAX),
        speed_limit_mps: l.speed_limit_mps,
        arms: Vec::new(),
        maneuvers,
        lane_pairs: Vec::new(),
        anchors,
        usable_length_m: 0.0,
        test_area_m: None,
    })
}
