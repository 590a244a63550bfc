//! Retrieval (paper eq. `M* = Retrieve(Ψ, D)`): every fragment of the topology library scored for a
//! scenario's semantics by structured compatibility and by lexical similarity, with the reasons.
//!
//! The structured part asks what the test needs: the road type against the fragment kind and arm
//! count, the lanes per direction, whether the maneuvers and the conflict exist (the same plan
//! grounding uses: a left turn with a path from the oncoming arm that crosses it, two lanes with a
//! broken line for a cut-in, a merge anchor for a merge), whether the anchor's kind is the one the
//! interaction type names, and whether there is room before the conflict to reach the speeds. The
//! lexical part is BM25 between the fragment's description and the video's event and behaviour
//! descriptions, with the road topology Ψ and the interaction types added in words. A fragment without the needed maneuvers is infeasible, with the reason, and ranks
//! after every feasible one.

use serde::Serialize;
use v2t_map::library::{Fragment, FragmentKind, Polyline, TopologyLibrary};
use v2t_model::semantics::{RoadTopology, RoadType, ScenarioSemantics};

use crate::plan::{Plan, RouteSpec, plan};
use crate::text::{Bm25, tokenize};

/// Weight of the road type and arm count.
pub const W_ROAD: f64 = 0.25;
/// Weight of the maneuver plan's exactness (named arm, named lane, line type).
pub const W_MANEUVERS: f64 = 0.25;
/// Weight of the conflict anchor's kind against the interaction type.
pub const W_INTERACTION: f64 = 0.15;
/// Weight of the lanes per direction.
pub const W_LANES: f64 = 0.10;
/// Weight of the room before the conflict.
pub const W_ROOM: f64 = 0.10;
/// Weight of the BM25 similarity of the descriptions.
pub const W_LEXICAL: f64 = 0.15;
/// Time at speed each agent should have before the conflict, s.
pub const ROOM_TIME_S: f64 = 3.0;
/// … and at least this distance, m.
pub const ROOM_MIN_M: f64 = 20.0;

/// One criterion of a candidate's score.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Criterion {
    /// `road_type`, `maneuvers`, `interaction`, `lanes`, `room` or `lexical`.
    pub name: &'static str,
    /// Its weight in the score.
    pub weight: f64,
    /// Its value, 0–1.
    pub score: f64,
    /// Why.
    pub reason: String,
}

/// A fragment ranked for a semantics.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Candidate {
    /// Fragment id.
    pub fragment_id: String,
    /// Its kind.
    pub kind: FragmentKind,
    /// Weighted sum of the criteria, 0–1.
    pub score: f64,
    /// Whether the scenario can be placed on it at all.
    pub feasible: bool,
    /// Why not, when infeasible.
    pub reasons: Vec<String>,
    /// The per-criterion scores and reasons.
    pub criteria: Vec<Criterion>,
}

impl Candidate {
    /// A multi-line explanation: the verdict, then one line per criterion.
    pub fn explain(&self) -> String {
        let mut out = format!(
            "{} ({:?}): score {:.3}{}",
            self.fragment_id,
            self.kind,
            self.score,
            if self.feasible { String::new() } else { format!(", infeasible: {}", self.reasons.join("; ")) }
        );
        for c in &self.criteria {
            out.push_str(&format!("\n  {:<11} {:.2} × {:.2}  {}", c.name, c.weight, c.score, c.reason));
        }
        out
    }
}

/// Every fragment of `library` ranked for `semantics`, best first: feasible before infeasible, then
/// by score (ties by fragment id).
pub fn rank(library: &TopologyLibrary, semantics: &ScenarioSemantics) -> Vec<Candidate> {
    let docs: Vec<Vec<String>> = library.fragments.iter().map(|f| tokenize(&document(f))).collect();
    let index = Bm25::new(&docs);
    let query = tokenize(&query(semantics));
    let raw: Vec<f64> = (0..docs.len()).map(|i| index.score(i, &query)).collect();
    let best = raw.iter().copied().fold(0.0, f64::max);
    let mut out: Vec<Candidate> = library
        .fragments
        .iter()
        .zip(&raw)
        .map(|(f, &r)| {
            let lexical = if best > 0.0 { r / best } else { 0.0 };
            candidate(f, semantics, lexical, r)
        })
        .collect();
    out.sort_by(|a, b| {
        b.feasible.cmp(&a.feasible).then(b.score.total_cmp(&a.score)).then_with(|| a.fragment_id.cmp(&b.fragment_id))
    });
    out
}

/// The text of a fragment that BM25 sees.
fn document(f: &Fragment) -> String {
    format!("{} {}", f.name.as_deref().unwrap_or(""), f.description)
}

/// The text of a semantics that BM25 sees: the road topology Ψ in words (road type, lanes, arms),
/// the event, and every BV's behaviour with its interaction type.
fn query(s: &ScenarioSemantics) -> String {
    let topo = &s.road_topology;
    let mut q = format!("{} {}-lane", topo.road_type.as_str().replace('_', " "), topo.lanes_per_direction);
    if let Some(arms) = topo.junction_arms {
        q.push_str(&format!(" {arms}-arm"));
    }
    q.push(' ');
    q.push_str(&s.event_description);
    for bv in &s.interacting_bvs {
        q.push(' ');
        q.push_str(&bv.interaction_type.as_str().replace('_', " "));
        q.push(' ');
        q.push_str(&bv.behavior.description);
    }
    q
}

/// Scores one fragment.
pub(crate) fn candidate(f: &Fragment, s: &ScenarioSemantics, lexical: f64, bm25: f64) -> Candidate {
    let mut reasons = Vec::new();
    let (road_score, road_reason, road_hard) = road_fit(f, &s.road_topology);
    if let Some(r) = road_hard {
        reasons.push(r);
    }
    let planned = plan(f, s);
    let (maneuvers, interaction, room) = match &planned {
        Ok(p) => {
            let m = Criterion { name: "maneuvers", weight: W_MANEUVERS, score: p.exactness, reason: plan_reason(p) };
            (m, interaction_fit(p, s), room_fit(f, p, s))
        }
        Err(e) => {
            reasons.push(e.0.clone());
            let none = |name, weight| Criterion { name, weight, score: 0.0, reason: "no plan".to_owned() };
            (
                Criterion { name: "maneuvers", weight: W_MANEUVERS, score: 0.0, reason: e.0.clone() },
                none("interaction", W_INTERACTION),
                none("room", W_ROOM),
            )
        }
    };
    let criteria = vec![
        Criterion { name: "road_type", weight: W_ROAD, score: road_score, reason: road_reason },
        maneuvers,
        interaction,
        lanes_fit(f, &s.road_topology),
        room,
        Criterion {
            name: "lexical",
            weight: W_LEXICAL,
            score: lexical,
            reason: format!("BM25 {bm25:.2} against the description, normalised by the library's best"),
        },
    ];
    let score = criteria.iter().map(|c| c.weight * c.score).sum();
    Candidate { fragment_id: f.id.clone(), kind: f.kind, score, feasible: reasons.is_empty(), reasons, criteria }
}

fn plan_reason(p: &Plan) -> String {
    if p.notes.is_empty() { p.summary() } else { format!("{}; relaxed: {}", p.summary(), p.notes.join("; ")) }
}

/// Whether the fragment's first path turns (more than 0.1 rad over its length).
fn is_curved(f: &Fragment) -> bool {
    let Some(m) = f.maneuvers.first() else { return false };
    let line = Polyline::new(&m.path);
    let n = (line.length() / 5.0).ceil().max(1.0) as usize;
    let mut prev: Option<f64> = None;
    let mut total = 0.0;
    for k in 0..=n {
        if let Some((_, h)) = line.at(line.length() * k as f64 / n as f64) {
            if let Some(p) = prev {
                total += v2t_model::geometry::wrap_angle(h - p).abs();
            }
            prev = Some(h);
        }
    }
    total > 0.1
}

/// Road type against fragment kind: score, reason, and a reason to reject outright.
fn road_fit(f: &Fragment, topo: &RoadTopology) -> (f64, String, Option<String>) {
    use FragmentKind as K;
    use RoadType as R;
    let road = topo.road_type;
    let kind = match f.kind {
        K::Intersection => format!("{}-arm intersection", f.arms.len()),
        K::MultiLaneSegment => "multi-lane segment".to_owned(),
        K::Merge => "merge".to_owned(),
    };
    let fit = |score: f64, why: &str| (score, format!("`{road}` on a {kind}: {why}"), None);
    match (road, f.kind) {
        (R::Roundabout, _) => {
            let why = "the library has no roundabouts (circulating paths are not detected)";
            (
                0.0,
                format!("`{road}` on a {kind}: {why}"),
                Some(format!("a roundabout cannot be placed on a {kind}: {why}")),
            )
        }
        (R::Intersection | R::TJunction, K::Intersection) => {
            let want = if road == R::TJunction { 3 } else { topo.junction_arms.map_or(4, usize::from) };
            let have = f.arms.len();
            match have.abs_diff(want) {
                0 => fit(1.0, "same number of arms"),
                1 if have > want => fit(0.6, &format!("{want} arms wanted, one arm stays unused")),
                1 => fit(0.4, &format!("{want} arms wanted, one is missing")),
                _ => fit(0.2, &format!("{want} arms wanted")),
            }
        }
        (R::Intersection | R::TJunction, _) => {
            let why = "needs a junction";
            (
                0.0,
                format!("`{road}` on a {kind}: {why}"),
                Some(format!("road type `{road}` {why}; {} is a {kind}", f.id)),
            )
        }
        (R::Straight, K::MultiLaneSegment) if !is_curved(f) => fit(1.0, "straight"),
        (R::Straight, K::MultiLaneSegment) => fit(0.8, "gently curved"),
        (R::Curve, K::MultiLaneSegment) if is_curved(f) => fit(1.0, "curved"),
        (R::Curve, K::MultiLaneSegment) => fit(0.7, "straight, not curved"),
        (R::Merge, K::Merge) => fit(1.0, "a lane merges"),
        (R::Merge, K::MultiLaneSegment) => fit(0.5, "the merge is played as a lane change"),
        (R::Straight | R::Curve, K::Merge) => fit(0.5, "lanes side by side before the lane drop"),
        (R::Straight | R::Curve | R::Merge, K::Intersection) => fit(0.2, "only the junction's paths"),
        (R::Other, _) => fit(0.5, "unknown road type"),
    }
}

fn lanes_fit(f: &Fragment, topo: &RoadTopology) -> Criterion {
    let (want, have) = (topo.lanes_per_direction, f.lanes_per_direction);
    let lanes = if have == 1 { "1 lane".to_owned() } else { format!("{have} lanes") };
    let (score, reason) = if have == want {
        (1.0, format!("{lanes} per direction, as wanted"))
    } else if have > want {
        (0.7, format!("{lanes} per direction, {want} wanted: extra lanes stay empty"))
    } else {
        (1.0 / (1.0 + f64::from(want - have)), format!("{lanes} per direction, {want} wanted"))
    };
    Criterion { name: "lanes", weight: W_LANES, score, reason }
}

fn interaction_fit(p: &Plan, s: &ScenarioSemantics) -> Criterion {
    let n = p.bvs.len().max(1) as f64;
    let score = p.bvs.iter().map(|b| b.kind_fit).sum::<f64>() / n;
    let reason = p
        .bvs
        .iter()
        .map(|b| {
            let t = s.interacting_bvs.get(b.index).map_or("?", |bv| bv.interaction_type.as_str());
            format!("{} `{t}` at {} (fit {:.1})", b.id, b.anchor, b.kind_fit)
        })
        .collect::<Vec<_>>()
        .join("; ");
    Criterion { name: "interaction", weight: W_INTERACTION, score, reason }
}

/// Distance along the final maneuver of `route` to the anchor, from the anchor's `on_paths`.
fn lead_m(f: &Fragment, route: &RouteSpec, anchor: &str) -> Option<f64> {
    let a = f.anchor(anchor)?;
    let on = route.final_maneuver();
    a.on_paths.iter().find(|(m, _)| m == on).map(|(_, s)| *s)
}

fn room_fit(f: &Fragment, p: &Plan, s: &ScenarioSemantics) -> Criterion {
    let mut score: f64 = 1.0;
    let mut parts = Vec::new();
    let mut check = |who: &str, route: &RouteSpec, anchor: &str, speed: f64| {
        let need = (ROOM_TIME_S * speed).max(ROOM_MIN_M);
        let have = lead_m(f, route, anchor).unwrap_or(0.0);
        score = score.min((have / need).min(1.0));
        parts.push(format!("{who} {have:.0} m before {anchor} (wants {need:.0})"));
    };
    for b in &p.bvs {
        check("vut", &p.vut, &b.anchor, s.ego.speed_estimate_mps);
        let speed = s.interacting_bvs.get(b.index).map_or(0.0, |bv| bv.behavior.speed_estimate_mps);
        check(&b.id, &b.route, &b.anchor, speed);
    }
    Criterion { name: "room", weight: W_ROOM, score: score.max(0.0), reason: parts.join("; ") }
}
