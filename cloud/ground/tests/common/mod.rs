//! Shared helpers of the grounding tests: maps, fixtures, and geometric checks.

#![allow(dead_code)]

use std::path::{Path, PathBuf};

use v2t_ground::Grounding;
use v2t_map::Map;
use v2t_map::graph::LaneKey;
use v2t_map::library::{Arm, Fragment, Polyline, TopologyLibrary};
use v2t_model::Style;
use v2t_model::geometry::Point2;
use v2t_model::grounded::GroundedAgent;
use v2t_model::path::ReferencePath;
use v2t_model::semantics::{ScenarioSemantics, parse_semantics_json};
use v2t_model::validate::Validate;

pub fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

pub fn load(file: &str) -> (Map, TopologyLibrary) {
    let path = root().join("tests/data/maps").join(file);
    let map = Map::load(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let lib = TopologyLibrary::build(&map);
    (map, lib)
}

pub fn fixture(name: &str) -> ScenarioSemantics {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data").join(name);
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    parse_semantics_json(&text).unwrap_or_else(|e| panic!("{name}: {e}"))
}

pub fn example(name: &str) -> ScenarioSemantics {
    let text = std::fs::read_to_string(root().join("config/examples").join(name)).unwrap();
    parse_semantics_json(&text).unwrap()
}

pub fn path_of(agent: &GroundedAgent) -> ReferencePath {
    ReferencePath::from_points(&agent.route).unwrap()
}

/// Distance from `p` to the centreline of `lane`.
pub fn dist_to_lane(map: &Map, lane: &LaneKey, p: Point2) -> f64 {
    let l = &map.graph.lanes[map.graph.find(lane).unwrap_or_else(|| panic!("no lane {lane}"))];
    let line = Polyline::new(&l.samples.iter().map(|q| q.p).collect::<Vec<_>>());
    line.project(p).unwrap().1
}

/// The arm of `f` whose approach lanes hold the lane `p` lies on (within 0.1 m).
pub fn arm_at<'a>(map: &Map, f: &'a Fragment, p: Point2) -> &'a Arm {
    f.arms
        .iter()
        .find(|a| a.approach_lanes.iter().any(|k| dist_to_lane(map, k, p) < 0.1))
        .unwrap_or_else(|| panic!("{p:?} lies on no approach lane of {}", f.id))
}

pub fn bearing_gap_deg(a: f64, b: f64) -> f64 {
    let d = (a - b).to_degrees().rem_euclid(360.0);
    d.min(360.0 - d)
}

/// What every grounding must satisfy: it validates; each conflict point lies on both routes within
/// 0.5 m and each route reaches it at least 3 s (at speed) after its start; the planned passages
/// meet τ in the style's order; every start time is ≥ 0 and one is 0; the starts and goals lie on
/// the lanes the routes record.
pub fn check_common(map: &Map, g: &Grounding, s: &ScenarioSemantics) {
    let sc = &g.scenario;
    assert_eq!(sc.validate(), Ok(()), "{sc:#?}");
    assert_eq!(sc.target.tau_s(), s.pet_label_s);
    let vut = sc.vut().unwrap();
    let vut_path = path_of(vut);
    for c in &sc.conflicts {
        let bv = sc.bvs().find(|b| b.id == c.bv_id).unwrap();
        let sem_bv = s.interacting_bvs.iter().find(|b| b.id == c.bv_id).unwrap();
        for (who, agent, path, speed) in [
            ("vut", vut, &vut_path, s.ego.speed_estimate_mps),
            (bv.id.as_str(), bv, &path_of(bv), sem_bv.behavior.speed_estimate_mps),
        ] {
            let f = path.project(c.point).unwrap();
            assert!(f.l_m.abs() < 0.5, "{who}: conflict {} is {:.3} m off the route", c.anchor_id, f.l_m);
            assert!(f.s_m >= 3.0 * speed, "{who}: only {:.1} m before the conflict", f.s_m);
            assert!(agent.start.speed_mps == speed);
        }
        let t = g.timing.iter().find(|t| t.bv_id == c.bv_id).unwrap();
        assert!((t.pet_s - s.pet_label_s).abs() < 1e-9, "{t:?}");
        match sem_bv.style {
            Style::Rush => assert!(t.bv_exit_s < t.vut_enter_s, "{t:?}"),
            Style::Yield => assert!(t.vut_exit_s < t.bv_enter_s, "{t:?}"),
        }
        assert!(c.vut_interval.enter_s_m > 0.0 && c.bv_interval.enter_s_m > 0.0);
    }
    let starts: Vec<f64> = sc.agents.iter().map(|a| a.start.time_s.unwrap()).collect();
    assert!(starts.iter().all(|t| *t >= 0.0) && starts.contains(&0.0), "{starts:?}");
    for (agent, route) in sc.agents.iter().zip(&g.routes) {
        assert_eq!(agent.id, route.id);
        assert!(agent.goal.time_s.unwrap() > agent.start.time_s.unwrap());
        assert!(dist_to_lane(map, &route.start_lane, agent.start.position) < 0.1, "{}: start off its lane", agent.id);
        assert!(dist_to_lane(map, &route.goal_lane, agent.goal.position) < 0.1, "{}: goal off its lane", agent.id);
        assert!(agent.route.first().unwrap().dist(agent.start.position) < 1e-9);
    }
    let first = g.ranking.iter().find(|c| c.feasible).unwrap();
    assert_eq!(first.fragment_id, sc.fragment_id, "the first feasible candidate grounds here");
    assert_eq!(first.criteria.len(), 6);
}
