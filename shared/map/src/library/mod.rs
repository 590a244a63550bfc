//! The topology library: the map cut into fragments where interactions happen — intersections,
//! multi-lane segments, merges — each with executable anchors (entry and exit per lane, conflict
//! points of maneuver paths, merge and cut-in points) in track coordinates, and a generated text
//! description that retrieval matches against the video's semantics. Built from the lane graph
//! alone; optional hand annotations (names, usable test areas) come from a TOML beside the map.

mod intersection;
mod merge;
mod polyline;
mod segment;

use serde::{Deserialize, Serialize};
use v2t_model::geometry::Point2;

use crate::Map;
use crate::graph::LaneKey;
use crate::xodr::MarkType;

pub use polyline::{Polyline, crossing, resample};

/// Distance an entry anchor lies before a fragment's core (junction, merge point), m.
pub const APPROACH_M: f64 = 40.0;
/// Distance an exit anchor lies after a fragment's core, m.
pub const DEPARTURE_M: f64 = 40.0;
/// Shortest multi-lane segment worth a fragment, m.
pub const MIN_SEGMENT_M: f64 = 60.0;
/// Largest curvature of a multi-lane segment, 1/m (radius ≥ 250 m).
pub const MAX_SEGMENT_CURVATURE: f64 = 1.0 / 250.0;

/// What kind of place a fragment is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FragmentKind {
    /// A junction with three or more arms.
    Intersection,
    /// Two or more lanes side by side in one direction, nearly straight.
    MultiLaneSegment,
    /// A lane that ends into its neighbour (on-ramp, lane drop), or two lanes that become one.
    Merge,
}

/// What an anchor marks.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum AnchorKind {
    /// Where a vehicle enters the fragment on a lane.
    Entry,
    /// Where it leaves.
    Exit,
    /// Where two maneuver paths cross.
    Conflict,
    /// Where two paths become one lane.
    Merge,
    /// Where a lane change into a neighbouring lane completes.
    CutIn,
}

/// A point of a fragment a scenario can be pinned to.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Anchor {
    /// Unique within the library, e.g. `J1/entry/a0/l-1`.
    pub id: String,
    /// What it marks.
    pub kind: AnchorKind,
    /// The lane it lies on (for conflicts: the lane of the first path).
    pub lane: LaneKey,
    /// Position in the track frame.
    pub position: Point2,
    /// Driving heading on `lane`, rad.
    pub heading_rad: f64,
    /// Distance along `lane` from its upstream end, m.
    pub lane_s_m: f64,
    /// The maneuvers or lane pair it belongs to (ids), with the arc length along each path.
    pub on_paths: Vec<(String, f64)>,
}

/// Which way a maneuver turns.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Turn {
    /// Turn left.
    Left,
    /// Go straight.
    Straight,
    /// Turn right.
    Right,
    /// Turn back.
    UTurn,
}

/// One arm of an intersection.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Arm {
    /// `a0`, `a1`, … counter-clockwise from east.
    pub id: String,
    /// The road of the arm.
    pub road: String,
    /// Whether the arm is the road's end at its largest s (else its start).
    pub road_end: bool,
    /// Direction from the junction out along the arm, rad (counter-clockwise from east).
    pub bearing_rad: f64,
    /// Lanes driving into the junction, left to right.
    pub approach_lanes: Vec<LaneKey>,
    /// Lanes driving out of the junction, left to right.
    pub exit_lanes: Vec<LaneKey>,
}

/// A path through a fragment, lane by lane.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Maneuver {
    /// Unique within the library, e.g. `J1/m/a0-l-1/left`.
    pub id: String,
    /// Which way it turns.
    pub turn: Turn,
    /// The arm it comes from (intersections).
    pub from_arm: Option<String>,
    /// The arm it leaves by.
    pub to_arm: Option<String>,
    /// The lanes it follows, in order.
    pub lanes: Vec<LaneKey>,
    /// Its centreline from the entry anchor to the exit anchor.
    pub path: Vec<Point2>,
    /// Entry anchor id.
    pub entry: String,
    /// Exit anchor id.
    pub exit: String,
    /// Where it enters the junction or merge core, m along `path`.
    pub core_from_m: f64,
    /// Where it leaves it, m along `path`.
    pub core_to_m: f64,
}

/// Two neighbouring lanes of one direction where a lane change or cut-in fits.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LanePair {
    /// The lane on the left (driving direction).
    pub left: String,
    /// The lane on the right.
    pub right: String,
    /// Length over which both exist side by side, m.
    pub usable_m: f64,
    /// The mark between them over most of that length.
    pub mark: MarkType,
}

/// A fragment of the map.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Fragment {
    /// Unique id: `J<junction>`, `S<road>/<dir>`, `M<road>/<lane>`.
    pub id: String,
    /// What kind of place.
    pub kind: FragmentKind,
    /// A name from the annotations.
    pub name: Option<String>,
    /// Generated text, for retrieval and operators.
    pub description: String,
    /// Roads it covers.
    pub roads: Vec<String>,
    /// A representative point.
    pub centre: Point2,
    /// Driving lanes per direction on its main road (intersections: the widest arm).
    pub lanes_per_direction: u8,
    /// Speed limit where known, m/s.
    pub speed_limit_mps: Option<f64>,
    /// Arms (intersections).
    pub arms: Vec<Arm>,
    /// Maneuvers (intersections, merges) and lanes driven straight through (segments).
    pub maneuvers: Vec<Maneuver>,
    /// Lane pairs (segments).
    pub lane_pairs: Vec<LanePair>,
    /// Every anchor.
    pub anchors: Vec<Anchor>,
    /// Usable length for the interaction, m (segments: side-by-side length; merges: the length of
    /// the ending lane; intersections: 0).
    pub usable_length_m: f64,
    /// Annotated test area, if any: usable from/to, m along the fragment's main path.
    pub test_area_m: Option<(f64, f64)>,
}

impl Fragment {
    /// An anchor by id.
    pub fn anchor(&self, id: &str) -> Option<&Anchor> {
        self.anchors.iter().find(|a| a.id == id)
    }

    /// A maneuver by id.
    pub fn maneuver(&self, id: &str) -> Option<&Maneuver> {
        self.maneuvers.iter().find(|m| m.id == id)
    }
}

/// All fragments of a map.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TopologyLibrary {
    /// The map's header name or file stem.
    pub map: String,
    /// The fragments.
    pub fragments: Vec<Fragment>,
}

impl TopologyLibrary {
    /// Cuts `map` into fragments.
    pub fn build(map: &Map) -> Self {
        let mut fragments = intersection::build(map);
        let junctions: std::collections::HashSet<String> =
            fragments.iter().filter_map(|f| f.id.strip_prefix('J').map(str::to_owned)).collect();
        fragments.extend(segment::build(map));
        fragments.extend(merge::build(map, &junctions));
        Self { map: map.name.clone(), fragments }
    }

    /// Fragments of one kind.
    pub fn of_kind(&self, kind: FragmentKind) -> impl Iterator<Item = &Fragment> {
        self.fragments.iter().filter(move |f| f.kind == kind)
    }

    /// A fragment by id.
    pub fn fragment(&self, id: &str) -> Option<&Fragment> {
        self.fragments.iter().find(|f| f.id == id)
    }

    /// Applies hand annotations (names, test areas).
    pub fn annotate(&mut self, notes: &crate::annotate::Annotations) -> Result<(), crate::error::MapError> {
        crate::annotate::apply(self, notes)
    }
}

/// `lane` as a short label for ids: `r3s0l-1`.
fn lane_label(k: &LaneKey) -> String {
    format!("r{}s{}l{}", k.road, k.section, k.lane)
}

fn compass(bearing: f64) -> &'static str {
    let deg = bearing.to_degrees().rem_euclid(360.0);
    const NAMES: [&str; 8] = ["east", "north-east", "north", "north-west", "west", "south-west", "south", "south-east"];
    let i = (((deg + 22.5) / 45.0).floor() as usize) % 8;
    NAMES.get(i).copied().unwrap_or("east")
}

/// A stretch of one lane: index, from s, to s.
type Run = (usize, f64, f64);

/// The runs covering `dist` m upstream of the downstream end of `lane`, through unique drivable
/// predecessors outside junctions (shorter where the lanes run out), in driving order.
fn back_from_end(g: &crate::graph::LaneGraph, lane: usize, dist: f64) -> Vec<Run> {
    let mut runs = Vec::new();
    let mut left = dist;
    let mut cur = Some(lane);
    let mut guard = 0;
    while let Some(i) = cur {
        let Some(l) = g.lane(i) else { break };
        let from = (l.length - left).max(0.0);
        runs.push((i, from, l.length));
        left -= l.length - from;
        guard += 1;
        if left <= 1e-9 || guard > 32 {
            break;
        }
        cur = match l.predecessors.as_slice() {
            [p] => g.lane(*p).filter(|pl| pl.drivable && pl.junction.is_none()).map(|_| *p),
            _ => None,
        };
        if cur.is_some_and(|p| runs.iter().any(|r| r.0 == p)) {
            break;
        }
    }
    runs.reverse();
    runs
}

/// The runs covering `dist` m downstream of the upstream end of `lane`, through unique drivable
/// successors outside junctions.
fn forward_from_start(g: &crate::graph::LaneGraph, lane: usize, dist: f64) -> Vec<Run> {
    let mut runs = Vec::new();
    let mut left = dist;
    let mut cur = Some(lane);
    let mut guard = 0;
    while let Some(i) = cur {
        let Some(l) = g.lane(i) else { break };
        let to = left.min(l.length);
        runs.push((i, 0.0, to));
        left -= to;
        guard += 1;
        if left <= 1e-9 || guard > 32 {
            break;
        }
        cur = match l.successors.as_slice() {
            [n] => g.lane(*n).filter(|nl| nl.drivable && nl.junction.is_none()).map(|_| *n),
            _ => None,
        };
        if cur.is_some_and(|n| runs.iter().any(|r| r.0 == n)) {
            break;
        }
    }
    runs
}

/// Centreline points of `runs`, in order, and the length of each run.
fn run_points(g: &crate::graph::LaneGraph, runs: &[Run]) -> (Vec<Point2>, f64) {
    let mut out = Vec::new();
    let mut total = 0.0;
    for &(i, from, to) in runs {
        let Some(l) = g.lane(i) else { continue };
        if let Some(a) = l.at(from) {
            out.push(a.p);
        }
        out.extend(l.samples.iter().filter(|q| q.s > from && q.s < to).map(|q| q.p));
        if let Some(b) = l.at(to) {
            out.push(b.p);
        }
        total += to - from;
    }
    (out, total)
}

/// An anchor on lane `i` at distance `s` along it.
fn anchor_on(g: &crate::graph::LaneGraph, i: usize, s: f64, id: String, kind: AnchorKind) -> Option<Anchor> {
    let l = g.lane(i)?;
    let q = l.at(s)?;
    Some(Anchor {
        id,
        kind,
        lane: l.key.clone(),
        position: q.p,
        heading_rad: q.heading,
        lane_s_m: q.s,
        on_paths: Vec::new(),
    })
}
