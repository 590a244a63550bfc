//! The lane graph: every lane of every lane section as a centreline polyline in its driving
//! direction with both boundaries and their marks, and its successors, predecessors and
//! left/right neighbours.
//!
//! Links come from three places — lane links between the sections of a road, road links with the
//! lane links at the road's ends, and junction connections — and are first collected as pairs of
//! lane *ends* without a direction. The direction follows from the traffic rule: a link joins the
//! downstream end of one lane to the upstream end of another; a link that joins two downstream (or
//! two upstream) ends of drivable lanes contradicts the lanes' directions and is reported. The
//! gap between the two centrelines at every link is measured and kept.

use std::collections::{HashMap, HashSet};

use serde::Serialize;
use v2t_model::geometry::Point2;

use crate::error::MapWarning;
use crate::geometry::ReferenceLine;
use crate::xodr::{
    ContactPoint, Document, Lane, LaneSection, MarkType, Road, RoadLink, RoadMark, TrafficRule, piecewise,
};

/// Longest step between samples along a lane, m.
pub const SAMPLE_STEP_M: f64 = 0.5;

/// A lane of a lane section.
#[derive(Debug, Clone, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, serde::Deserialize)]
pub struct LaneKey {
    /// Road id.
    pub road: String,
    /// Lane section index on the road.
    pub section: usize,
    /// Lane id.
    pub lane: i32,
}

impl std::fmt::Display for LaneKey {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "road {} section {} lane {}", self.road, self.section, self.lane)
    }
}

/// One point along a lane, in driving order.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct LaneSample {
    /// Centreline point.
    pub p: Point2,
    /// Driving heading, rad.
    pub heading: f64,
    /// Distance along the lane's centreline from its upstream end, m.
    pub s: f64,
    /// s on the road's reference line.
    pub s_road: f64,
    /// Width, m.
    pub width: f64,
    /// Left boundary point (in the driving direction).
    pub left: Point2,
    /// Right boundary point.
    pub right: Point2,
    /// Mark on the left boundary.
    pub left_mark: MarkType,
    /// Mark on the right boundary.
    pub right_mark: MarkType,
}

/// A lane beside another in the same section.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct Neighbour {
    /// Index in [`LaneGraph::lanes`].
    pub lane: usize,
    /// Whether it drives the same way.
    pub same_direction: bool,
}

/// One lane of the graph.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LaneInfo {
    /// Where it comes from.
    pub key: LaneKey,
    /// OpenDRIVE lane type.
    pub kind: String,
    /// Drivable and at least 1 m wide somewhere.
    pub drivable: bool,
    /// The junction of its road, if a connecting road.
    pub junction: Option<String>,
    /// Whether it drives along the reference line's s.
    pub forward: bool,
    /// Samples from the upstream to the downstream end.
    pub samples: Vec<LaneSample>,
    /// Centreline length, m.
    pub length: f64,
    /// Lanes that continue it (indices).
    pub successors: Vec<usize>,
    /// Lanes it continues (indices).
    pub predecessors: Vec<usize>,
    /// Neighbour on the left, in the driving direction.
    pub left: Option<Neighbour>,
    /// Neighbour on the right.
    pub right: Option<Neighbour>,
    /// Speed limit of its road at its start, m/s.
    pub speed_limit_mps: Option<f64>,
}

impl LaneInfo {
    /// The first sample.
    pub fn start(&self) -> Option<&LaneSample> {
        self.samples.first()
    }

    /// The last sample.
    pub fn end(&self) -> Option<&LaneSample> {
        self.samples.last()
    }

    /// The sample at distance `s` along the lane (clamped), interpolated.
    pub fn at(&self, s: f64) -> Option<LaneSample> {
        let i = self.samples.partition_point(|q| q.s < s);
        match (i.checked_sub(1).and_then(|j| self.samples.get(j)), self.samples.get(i)) {
            (Some(a), Some(b)) if b.s > a.s => {
                let f = (s - a.s) / (b.s - a.s);
                let lerp = |p: Point2, q: Point2| p.lerp(q, f);
                Some(LaneSample {
                    p: lerp(a.p, b.p),
                    heading: a.heading + f * v2t_model::geometry::wrap_angle(b.heading - a.heading),
                    s,
                    s_road: a.s_road + f * (b.s_road - a.s_road),
                    width: a.width + f * (b.width - a.width),
                    left: lerp(a.left, b.left),
                    right: lerp(a.right, b.right),
                    left_mark: a.left_mark,
                    right_mark: a.right_mark,
                })
            }
            (_, Some(b)) => Some(*b),
            (Some(a), None) => Some(*a),
            (None, None) => None,
        }
    }
}

/// The gap between two linked lanes' centrelines.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct LinkGap {
    /// Upstream lane.
    pub from: usize,
    /// Downstream lane.
    pub to: usize,
    /// Distance between the end of `from` and the start of `to`, m.
    pub gap_m: f64,
}

/// Every lane and how they connect.
#[derive(Debug, Clone, Default, Serialize)]
pub struct LaneGraph {
    /// The lanes.
    pub lanes: Vec<LaneInfo>,
    /// Every directed link with its gap.
    pub links: Vec<LinkGap>,
    #[serde(skip)]
    index: HashMap<LaneKey, usize>,
}

impl LaneGraph {
    /// Index of a lane.
    pub fn find(&self, key: &LaneKey) -> Option<usize> {
        self.index.get(key).copied()
    }

    /// The lane at an index.
    pub fn lane(&self, i: usize) -> Option<&LaneInfo> {
        self.lanes.get(i)
    }

    /// Builds the graph of a parsed document.
    pub fn build(doc: &Document, warnings: &mut Vec<MapWarning>) -> Self {
        let mut graph = Self::default();
        for road in &doc.roads {
            let line = ReferenceLine::new(&road.plan_view);
            if let Some((gap, s)) = line.worst_gap()
                && gap > 0.01
            {
                warnings.push(MapWarning::new(
                    format!("road {}", road.id),
                    format!("its plan view jumps {gap:.3} m at s = {s:.2}"),
                ));
            }
            let mut lanes = Vec::new();
            let mut beyond = None;
            for (k, sec) in road.sections.iter().enumerate() {
                let end = road.sections.get(k + 1).map_or(road.length, |n| n.s);
                if end <= sec.s + 1e-6 {
                    warnings.push(MapWarning::new(
                        format!("road {} laneSection {k}", road.id),
                        "has zero length and is skipped",
                    ));
                    continue;
                }
                for lane in sec.left.iter().chain(&sec.right) {
                    let (info, reach) = sample_lane(road, &line, sec, k, end, lane);
                    let width = info.samples.iter().map(|q| q.width).fold(0.0, f64::max);
                    if !(width <= MAX_LANE_WIDTH_M && reach <= MAX_LANE_REACH_M) && beyond.is_none() {
                        beyond = Some(format!(
                            "lane {} of laneSection {k} reaches a width of {} m and {} m off the reference \
                             line (bounds: {MAX_LANE_WIDTH_M} m, {MAX_LANE_REACH_M} m): the road is left out",
                            lane.id,
                            v2t_model::validate::shown(width),
                            v2t_model::validate::shown(reach)
                        ));
                    }
                    lanes.push(info);
                }
            }
            if let Some(message) = beyond {
                warnings.push(MapWarning::new(format!("road {}", road.id), message));
                continue;
            }
            for info in lanes {
                graph.index.insert(info.key.clone(), graph.lanes.len());
                graph.lanes.push(info);
            }
        }
        graph.neighbours(doc);
        let ends = collect_links(doc, &graph, warnings);
        graph.direct(ends, warnings);
        graph
    }

    fn neighbours(&mut self, doc: &Document) {
        for road in &doc.roads {
            for k in 0..road.sections.len() {
                let ids: Vec<(usize, i32)> = self
                    .lanes
                    .iter()
                    .enumerate()
                    .filter(|(_, l)| l.key.road == road.id && l.key.section == k)
                    .map(|(i, l)| (i, l.key.lane))
                    .collect();
                for &(i, id) in &ids {
                    let Some(forward) = self.lanes.get(i).map(|l| l.forward) else { continue };
                    // The lane on the +t side and on the −t side.
                    let plus = if id == -1 { 1 } else { id + 1 };
                    let minus = if id == 1 { -1 } else { id - 1 };
                    let find = |want: i32| ids.iter().find(|(_, other)| *other == want).map(|(j, _)| *j);
                    let (left, right) = if forward { (find(plus), find(minus)) } else { (find(minus), find(plus)) };
                    let neighbour = |j: Option<usize>, lanes: &[LaneInfo]| {
                        j.and_then(|j| {
                            lanes.get(j).map(|n| Neighbour { lane: j, same_direction: n.forward == forward })
                        })
                    };
                    let (l, r) = (neighbour(left, &self.lanes), neighbour(right, &self.lanes));
                    if let Some(lane) = self.lanes.get_mut(i) {
                        lane.left = l;
                        lane.right = r;
                    }
                }
            }
        }
    }

    fn direct(&mut self, ends: Vec<(End, End)>, warnings: &mut Vec<MapWarning>) {
        for (a, b) in ends {
            let (Some(la), Some(lb)) = (self.lanes.get(a.lane), self.lanes.get(b.lane)) else { continue };
            let a_down = a.at_end == la.forward;
            let b_down = b.at_end == lb.forward;
            let (from, to) = match (a_down, b_down) {
                (true, false) => (a.lane, b.lane),
                (false, true) => (b.lane, a.lane),
                _ => {
                    if la.drivable && lb.drivable {
                        warnings.push(MapWarning::new(
                            format!("{} ↔ {}", la.key, lb.key),
                            "linked, but their driving directions run into each other: link ignored",
                        ));
                    }
                    continue;
                }
            };
            let gap_m =
                match (self.lanes.get(from).and_then(LaneInfo::end), self.lanes.get(to).and_then(LaneInfo::start)) {
                    (Some(e), Some(s)) => e.p.dist(s.p),
                    _ => f64::INFINITY,
                };
            self.links.push(LinkGap { from, to, gap_m });
            if let Some(l) = self.lanes.get_mut(from)
                && !l.successors.contains(&to)
            {
                l.successors.push(to);
            }
            if let Some(l) = self.lanes.get_mut(to)
                && !l.predecessors.contains(&from)
            {
                l.predecessors.push(from);
            }
        }
    }
}

/// One end of a lane: index and whether it is the end at the section's larger s.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
struct End {
    lane: usize,
    at_end: bool,
}

fn mark_at(marks: &[RoadMark], ds: f64) -> MarkType {
    marks.iter().rev().find(|m| m.s_offset <= ds + 1e-9).or(marks.first()).map_or(MarkType::None, |m| m.kind)
}

/// (t of the inner edge, t of the outer edge) of every lane on one side, in id order.
fn side_edges(lanes: &[Lane], offset: f64, ds: f64, sign: f64) -> Vec<(f64, f64)> {
    let mut t = offset;
    let mut out = Vec::with_capacity(lanes.len());
    for lane in lanes {
        let outer = if lane.border {
            // <border> gives the outer edge's distance from the reference line.
            let b = piecewise(&lane.widths, ds);
            if sign * (b - t) >= 0.0 { b } else { t }
        } else {
            t + sign * piecewise(&lane.widths, ds).max(0.0)
        };
        out.push((t, outer));
        t = outer;
    }
    out
}

/// Widest a sampled lane may become (the width polynomials' `b`, `c`, `d` can make a lane that
/// starts 3.5 m wide a kilometre wide at its end), m.
pub const MAX_LANE_WIDTH_M: f64 = crate::xodr::MAX_LANE_WIDTH_M;
/// Farthest a lane's edge may lie from its road's reference line (lane offsets, many wide lanes), m.
pub const MAX_LANE_REACH_M: f64 = 1_000.0;

/// The lane's samples, and how far its edges reach from the reference line at most, m.
fn sample_lane(
    road: &Road,
    line: &ReferenceLine<'_>,
    sec: &LaneSection,
    k: usize,
    end: f64,
    lane: &Lane,
) -> (LaneInfo, f64) {
    let forward = (lane.id < 0) == (road.rule == TrafficRule::Rht);
    let left_side = lane.id > 0;
    let side = if left_side { &sec.left } else { &sec.right };
    let pos = side.iter().position(|l| l.id == lane.id).unwrap_or(0);
    let sign = if left_side { 1.0 } else { -1.0 };
    // The lane on its inner side carries the mark of its inner edge.
    let inner_marks: &[RoadMark] =
        pos.checked_sub(1).and_then(|p| side.get(p)).map_or(sec.center_marks.as_slice(), |l| l.marks.as_slice());
    let n = ((end - sec.s) / SAMPLE_STEP_M).ceil().max(1.0);
    let mut samples = Vec::with_capacity(n as usize + 1);
    let mut i = 0.0;
    let mut max_width = 0.0_f64;
    let mut reach = 0.0_f64;
    while i <= n {
        let s_road = sec.s + (end - sec.s) * i / n;
        i += 1.0;
        let Some(pose) = line.pose(s_road) else { continue };
        let ds = s_road - sec.s;
        let offset = piecewise(&road.lane_offsets, s_road);
        let edges = side_edges(side, offset, ds, sign);
        let (inner, outer) = edges.get(pos).copied().unwrap_or((offset, offset));
        let (sin, cos) = pose.hdg.sin_cos();
        let at = |t: f64| Point2::new(pose.x - t * sin, pose.y + t * cos);
        let centre = at(0.5 * (inner + outer));
        let (plus, minus) = if left_side { (outer, inner) } else { (inner, outer) };
        let (plus_mark, minus_mark) = if left_side {
            (mark_at(&lane.marks, ds), mark_at(inner_marks, ds))
        } else {
            (mark_at(inner_marks, ds), mark_at(&lane.marks, ds))
        };
        let width = (outer - inner).abs();
        max_width = max_width.max(width);
        reach = reach.max(inner.abs()).max(outer.abs());
        if reach.is_nan() {
            reach = f64::INFINITY;
        }
        let sample = if forward {
            LaneSample {
                p: centre,
                heading: pose.hdg,
                s: 0.0,
                s_road,
                width,
                left: at(plus),
                right: at(minus),
                left_mark: plus_mark,
                right_mark: minus_mark,
            }
        } else {
            LaneSample {
                p: centre,
                heading: v2t_model::geometry::wrap_angle(pose.hdg + std::f64::consts::PI),
                s: 0.0,
                s_road,
                width,
                left: at(minus),
                right: at(plus),
                left_mark: minus_mark,
                right_mark: plus_mark,
            }
        };
        samples.push(sample);
    }
    if !forward {
        samples.reverse();
    }
    let mut length = 0.0;
    let mut prev: Option<Point2> = None;
    for q in &mut samples {
        if let Some(p) = prev {
            length += p.dist(q.p);
        }
        q.s = length;
        prev = Some(q.p);
    }
    let speed_limit_mps = road.speed_limits.iter().rev().find(|(s, _)| *s <= sec.s + 1e-9).map(|(_, v)| *v);
    let info = LaneInfo {
        key: LaneKey { road: road.id.clone(), section: k, lane: lane.id },
        kind: lane.kind.clone(),
        drivable: lane.is_drivable() && max_width >= 1.0,
        junction: road.junction.clone(),
        forward,
        samples,
        length,
        successors: Vec::new(),
        predecessors: Vec::new(),
        left: None,
        right: None,
        speed_limit_mps,
    };
    (info, reach)
}

fn section_at(road: &Road, contact: ContactPoint) -> usize {
    match contact {
        ContactPoint::Start => 0,
        ContactPoint::End => road.sections.len().saturating_sub(1),
    }
}

/// Every linked pair of lane ends, undirected, without duplicates.
fn collect_links(doc: &Document, graph: &LaneGraph, warnings: &mut Vec<MapWarning>) -> Vec<(End, End)> {
    let roads: HashMap<&str, &Road> = doc.roads.iter().map(|r| (r.id.as_str(), r)).collect();
    let mut pairs: HashSet<(End, End)> = HashSet::new();
    let mut add = |a: (&Road, usize, i32, bool), b: (&Road, usize, i32, bool), warnings: &mut Vec<MapWarning>| {
        let key = |r: &Road, s: usize, l: i32| LaneKey { road: r.id.clone(), section: s, lane: l };
        let (ka, kb) = (key(a.0, a.1, a.2), key(b.0, b.1, b.2));
        match (graph.find(&ka), graph.find(&kb)) {
            (Some(ia), Some(ib)) => {
                let (x, y) = (End { lane: ia, at_end: a.3 }, End { lane: ib, at_end: b.3 });
                pairs.insert(if x <= y { (x, y) } else { (y, x) });
            }
            (None, _) => {
                warnings.push(MapWarning::new(kb.to_string(), format!("linked to {ka}, which does not exist")))
            }
            (_, None) => {
                warnings.push(MapWarning::new(ka.to_string(), format!("linked to {kb}, which does not exist")))
            }
        }
    };
    for road in &doc.roads {
        // Between the sections of the road.
        for (k, w) in road.sections.windows(2).enumerate() {
            let [a, b] = w else { continue };
            let explicit = a.left.iter().chain(&a.right).any(|l| l.successor.is_some())
                || b.left.iter().chain(&b.right).any(|l| l.predecessor.is_some());
            for lane in a.left.iter().chain(&a.right) {
                let to = if explicit { lane.successor } else { Some(lane.id) };
                if let Some(to) = to
                    && (explicit || b.left.iter().chain(&b.right).any(|l| l.id == to))
                {
                    add((road, k, lane.id, true), (road, k + 1, to, false), warnings);
                }
            }
            for lane in b.left.iter().chain(&b.right) {
                if let Some(from) = lane.predecessor {
                    add((road, k + 1, lane.id, false), (road, k, from, true), warnings);
                }
            }
        }
        // Across road links.
        let last = road.sections.len().saturating_sub(1);
        for (link, k, at_end) in [(&road.successor, last, true), (&road.predecessor, 0, false)] {
            let Some(RoadLink::Road { id, contact }) = link else { continue };
            let Some(other) = roads.get(id.as_str()) else {
                warnings.push(MapWarning::new(
                    format!("road {}", road.id),
                    format!("links to road {id}, which does not exist"),
                ));
                continue;
            };
            let Some(sec) = road.sections.get(k) else { continue };
            let ok = section_at(other, *contact);
            for lane in sec.left.iter().chain(&sec.right) {
                let target = if at_end { lane.successor } else { lane.predecessor };
                if let Some(t) = target {
                    add((road, k, lane.id, at_end), (other, ok, t, *contact == ContactPoint::End), warnings);
                }
            }
        }
    }
    // Junction connections.
    for j in &doc.junctions {
        for c in &j.connections {
            let (Some(inc), Some(con)) = (roads.get(c.incoming.as_str()), roads.get(c.connecting.as_str())) else {
                warnings.push(MapWarning::new(
                    format!("junction {} connection {}", j.id, c.id),
                    format!("road {} or {} does not exist", c.incoming, c.connecting),
                ));
                continue;
            };
            let is_j = |l: &Option<RoadLink>| matches!(l, Some(RoadLink::Junction { id }) if *id == j.id);
            // The end of the incoming road at the junction: the one linked to it; when both ends
            // are (a loop) or neither is, the end nearer to the connecting road's contact point.
            let nearer_end = || {
                let line = ReferenceLine::new(&inc.plan_view);
                let cline = ReferenceLine::new(&con.plan_view);
                let cs = if c.contact == ContactPoint::Start { 0.0 } else { con.length };
                match (line.pose(0.0), line.pose(inc.length), cline.pose(cs)) {
                    (Some(a), Some(b), Some(p)) => (b.x - p.x).hypot(b.y - p.y) < (a.x - p.x).hypot(a.y - p.y),
                    _ => true,
                }
            };
            let inc_end = match (is_j(&inc.successor), is_j(&inc.predecessor)) {
                (true, false) => true,
                (false, true) => false,
                _ => nearer_end(),
            };
            let k_inc = if inc_end { inc.sections.len().saturating_sub(1) } else { 0 };
            let k_con = section_at(con, c.contact);
            for &(from, to) in &c.lane_links {
                add((inc, k_inc, from, inc_end), (con, k_con, to, c.contact == ContactPoint::End), warnings);
            }
        }
    }
    let mut out: Vec<_> = pairs.into_iter().collect();
    out.sort();
    out
}
