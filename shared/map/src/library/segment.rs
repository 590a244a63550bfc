//! Multi-lane segments: stretches of a road outside junctions with two or more drivable lanes side
//! by side in one direction, nearly straight, long enough for a lane change or a cut-in.

use v2t_model::geometry::Point2;

use super::{
    Anchor, AnchorKind, Fragment, FragmentKind, LanePair, MAX_SEGMENT_CURVATURE, MIN_SEGMENT_M, Maneuver, Polyline,
    Turn, anchor_on, compass,
};
use crate::Map;
use crate::geometry::ReferenceLine;
use crate::graph::LaneGraph;
use crate::xodr::{MarkType, Road};

/// Narrowest a lane may get and still count as a lane of a multi-lane segment, m.
const MIN_LANE_WIDTH_M: f64 = 2.5;

/// Drivable lanes of one section driving one way, left to right in the driving direction.
fn lanes_of(g: &LaneGraph, road: &str, section: usize, forward: bool) -> Vec<usize> {
    // Start from any lane of the direction and walk to the leftmost, then rightwards.
    // Lanes that narrow below 2.5 m (a taper, an ending acceleration lane) do not count.
    let mine = |i: usize| {
        g.lane(i).is_some_and(|l| {
            l.key.road == road
                && l.key.section == section
                && l.forward == forward
                && l.drivable
                && l.samples.iter().all(|q| q.width >= MIN_LANE_WIDTH_M)
        })
    };
    let Some(start) = (0..g.lanes.len()).find(|&i| mine(i)) else { return Vec::new() };
    let mut left = start;
    while let Some(n) = g.lane(left).and_then(|l| l.left).filter(|n| n.same_direction && mine(n.lane)) {
        left = n.lane;
    }
    let mut out = vec![left];
    let mut cur = left;
    while let Some(n) = g.lane(cur).and_then(|l| l.right).filter(|n| n.same_direction && mine(n.lane)) {
        if out.contains(&n.lane) {
            break;
        }
        out.push(n.lane);
        cur = n.lane;
    }
    out
}

fn max_curvature(road: &Road, from: f64, to: f64) -> f64 {
    let line = ReferenceLine::new(&road.plan_view);
    let n = ((to - from) / 1.0).ceil().max(1.0);
    let mut k = 0.0_f64;
    let mut i = 0.0;
    while i <= n {
        k = k.max(line.curvature(from + (to - from) * i / n).abs());
        i += 1.0;
    }
    k
}

fn majority_mark(marks: &[MarkType]) -> MarkType {
    let count = |m: MarkType| marks.iter().filter(|&&x| x == m).count();
    [MarkType::Broken, MarkType::Solid, MarkType::Mixed, MarkType::None]
        .into_iter()
        .max_by_key(|&m| count(m))
        .unwrap_or(MarkType::None)
}

pub(super) fn build(map: &Map) -> Vec<Fragment> {
    let g = &map.graph;
    let mut out = Vec::new();
    for road in map.document.roads.iter().filter(|r| r.junction.is_none()) {
        for forward in [true, false] {
            // Sections in driving order, with their lanes.
            let mut secs: Vec<(usize, Vec<usize>)> =
                (0..road.sections.len()).map(|k| (k, lanes_of(g, &road.id, k, forward))).collect();
            if !forward {
                secs.reverse();
            }
            let mut k = 0;
            while k < secs.len() {
                let count = secs.get(k).map_or(0, |s| s.1.len());
                let mut e = k + 1;
                while e < secs.len() && secs.get(e).map_or(0, |s| s.1.len()) == count {
                    e += 1;
                }
                if count >= 2
                    && let Some(f) = fragment(map, road, forward, secs.get(k..e).unwrap_or_default())
                {
                    out.push(f);
                }
                k = e;
            }
        }
    }
    out
}

fn fragment(map: &Map, road: &Road, forward: bool, secs: &[(usize, Vec<usize>)]) -> Option<Fragment> {
    let g = &map.graph;
    let count = secs.first()?.1.len();
    let dir = if forward { "fwd" } else { "bwd" };
    let first_sec = secs.first()?.0;
    let fid = format!("S{}/{dir}/{first_sec}", road.id);
    // One straight path per lane position, through every section of the run.
    let mut maneuvers = Vec::new();
    let mut anchors = Vec::new();
    let mut paths = Vec::new();
    for pos in 0..count {
        let lanes: Vec<usize> = secs.iter().filter_map(|(_, l)| l.get(pos).copied()).collect();
        let points: Vec<Point2> =
            lanes.iter().filter_map(|&i| g.lane(i)).flat_map(|l| l.samples.iter().map(|q| q.p)).collect();
        let path = Polyline::new(&points);
        let (first, last) = (*lanes.first()?, *lanes.last()?);
        let entry = format!("{fid}/entry/p{pos}");
        let exit = format!("{fid}/exit/p{pos}");
        anchors.push(anchor_on(g, first, 0.0, entry.clone(), AnchorKind::Entry)?);
        anchors.push(anchor_on(g, last, g.lane(last)?.length, exit.clone(), AnchorKind::Exit)?);
        maneuvers.push(Maneuver {
            id: format!("{fid}/m/p{pos}"),
            turn: Turn::Straight,
            from_arm: None,
            to_arm: None,
            lanes: lanes.iter().filter_map(|&i| g.lane(i).map(|l| l.key.clone())).collect(),
            path: path.points().to_vec(),
            entry,
            exit,
            core_from_m: 0.0,
            core_to_m: path.length(),
        });
        paths.push((lanes, path));
    }
    let usable = paths.iter().map(|(_, p)| p.length()).fold(f64::INFINITY, f64::min);
    if usable < MIN_SEGMENT_M {
        return None;
    }
    let s_from = secs.iter().filter_map(|(k, _)| road.sections.get(*k).map(|s| s.s)).fold(f64::INFINITY, f64::min);
    let s_to = secs
        .iter()
        .filter_map(|(k, _)| road.sections.get(k + 1).map_or(Some(road.length), |n| Some(n.s)))
        .fold(0.0, f64::max);
    let kappa = max_curvature(road, s_from, s_to);
    if kappa > MAX_SEGMENT_CURVATURE {
        return None;
    }
    let mut lane_pairs = Vec::new();
    for pos in 0..count.saturating_sub(1) {
        let (Some((left_lanes, left_path)), Some((_, right_path))) = (paths.get(pos), paths.get(pos + 1)) else {
            continue;
        };
        let marks: Vec<MarkType> =
            left_lanes.iter().filter_map(|&i| g.lane(i)).flat_map(|l| l.samples.iter().map(|q| q.right_mark)).collect();
        let mark = majority_mark(&marks);
        let left_id = format!("{fid}/m/p{pos}");
        let right_id = format!("{fid}/m/p{}", pos + 1);
        // Cut-in points half way: into the left lane from the right one, and the other way.
        for (target_path, target_pos, tag) in
            [(left_path, pos, format!("p{}>p{pos}", pos + 1)), (right_path, pos + 1, format!("p{pos}>p{}", pos + 1))]
        {
            let s = 0.5 * target_path.length();
            let (p, h) = target_path.at(s)?;
            let lanes = &paths.get(target_pos)?.0;
            let (lane, lane_s) = locate(g, lanes, s)?;
            anchors.push(Anchor {
                id: format!("{fid}/cutin/{tag}"),
                kind: AnchorKind::CutIn,
                lane,
                position: p,
                heading_rad: h,
                lane_s_m: lane_s,
                on_paths: vec![(format!("{fid}/m/p{target_pos}"), s)],
            });
        }
        lane_pairs.push(LanePair { left: left_id, right: right_id, usable_m: usable, mark });
    }
    let opposite = secs.first().map_or(0, |(k, _)| lanes_of(g, &road.id, *k, !forward).len());
    let heading = paths.first().and_then(|(_, p)| p.at(0.5 * p.length())).map_or(0.0, |(_, h)| h);
    let centre = paths.first().and_then(|(_, p)| p.at(0.5 * p.length())).map_or(Point2::new(0.0, 0.0), |(p, _)| p);
    let marks: Vec<String> = lane_pairs.iter().map(|p| format!("{:?}", p.mark).to_lowercase()).collect();
    let speed_limit_mps = paths.first().and_then(|(l, _)| l.first()).and_then(|&i| g.lane(i)?.speed_limit_mps);
    let description = format!(
        "{count}-lane multi-lane segment on road {}{} heading {}, {usable:.0} m long, {} (min radius {}), \
         lane lines {}; {}: fits lane changes, cut-ins and car following{}.",
        road.id,
        if road.name.is_empty() { String::new() } else { format!(" ({})", road.name) },
        compass(heading),
        if kappa < 1e-4 { "straight" } else { "gently curved" },
        if kappa < 1e-9 { "∞".to_owned() } else { format!("{:.0} m", 1.0 / kappa) },
        marks.join("/"),
        if opposite > 0 { format!("two-way road, {opposite} lanes the other way") } else { "one-way".to_owned() },
        speed_limit_mps.map_or(String::new(), |v| format!(", speed limit {:.0} km/h", v * 3.6)),
    );
    Some(Fragment {
        id: fid,
        kind: FragmentKind::MultiLaneSegment,
        name: None,
        description,
        roads: vec![road.id.clone()],
        centre,
        lanes_per_direction: u8::try_from(count).unwrap_or(u8::MAX),
        speed_limit_mps,
        arms: Vec::new(),
        maneuvers,
        lane_pairs,
        anchors,
        usable_length_m: usable,
        test_area_m: None,
    })
}

/// The lane of a chain at distance `s` along it, and s along that lane.
fn locate(g: &LaneGraph, lanes: &[usize], s: f64) -> Option<(crate::graph::LaneKey, f64)> {
    let mut acc = 0.0;
    let mut last = None;
    for &i in lanes {
        let l = g.lane(i)?;
        last = Some((l.key.clone(), (s - acc).clamp(0.0, l.length)));
        if s <= acc + l.length {
            break;
        }
        acc += l.length;
    }
    last
}
