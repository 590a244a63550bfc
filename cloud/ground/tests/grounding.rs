//! Grounding on the third-party test maps (`tests/data/maps/`): cut-ins on the two highways, the
//! unprotected left turn on the 4-arm and the 3-arm junction, merges on both merging maps, a
//! crossing on the 4-arm junction, and semantics that fit nowhere.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic, clippy::indexing_slicing)] // test code

mod common;

use common::{arm_at, bearing_gap_deg, check_common, dist_to_lane, example, fixture, load, path_of};
use v2t_ground::{GroundError, ground};
use v2t_map::library::{FragmentKind, Polyline, Turn};
use v2t_model::metrics::ConflictKind;
use v2t_model::semantics::{RelativeStart, ScenarioSemantics};

/// A cut-in: the VUT keeps the lane the semantics name; the BV starts in the adjacent lane on the
/// named side and ends in the VUT's lane.
fn check_cut_in(file: &str, s: &ScenarioSemantics) {
    let (map, lib) = load(file);
    let g = ground(&map, &lib, s).unwrap_or_else(|e| panic!("{file}: {e}"));
    check_common(&map, &g, s);
    let f = lib.fragment(&g.scenario.fragment_id).unwrap();
    assert_eq!(f.kind, FragmentKind::MultiLaneSegment);
    let k = usize::from(s.ego.start_lane.lane_index_from_left.unwrap());
    let named = f.maneuver(&format!("{}/m/p{}", f.id, k - 1)).unwrap();
    let vut = g.scenario.vut().unwrap();
    assert!(named.lanes.contains(&g.routes[0].start_lane), "{file}: the VUT starts on {}", g.routes[0].start_lane);
    assert!(dist_to_lane(&map, &g.routes[0].start_lane, vut.start.position) < 0.1);
    let bv = g.scenario.bvs().next().unwrap();
    let (vut_path, bv_path) = (path_of(vut), path_of(bv));
    let side = vut_path.project(bv.start.position).unwrap().l_m;
    match s.interacting_bvs[0].relative_start {
        RelativeStart::AdjacentRight => assert!((-4.5..-2.5).contains(&side), "{file}: BV starts {side} m left"),
        RelativeStart::AdjacentLeft => assert!((2.5..4.5).contains(&side), "{file}: BV starts {side} m left"),
        other => panic!("{other}"),
    }
    let vut_lane = Polyline::new(&named.path);
    assert!(vut_lane.project(bv.goal.position).unwrap().1 < 0.05, "{file}: the BV ends off the VUT's lane");
    assert_eq!(g.routes[1].goal_lane, g.routes[0].goal_lane);
    // The lane change is smooth: the BV's heading never turns more than 20° from the VUT's lane.
    for k in 0..=100 {
        let sb = bv_path.length() * f64::from(k) / 100.0;
        let p = bv_path.point_at(sb);
        let sv = vut_path.project(p).unwrap().s_m.clamp(0.0, vut_path.length());
        let d = (bv_path.heading_at(sb) - vut_path.heading_at(sv)).to_degrees().abs() % 360.0;
        assert!(d.min(360.0 - d) < 20.0, "{file}: BV heading off by {d}° at {sb} m");
    }
    let c = &g.scenario.conflicts[0];
    assert_eq!(c.kind, ConflictKind::Merge);
    assert!(c.anchor_id.contains("/cutin/"), "{}", c.anchor_id);
    println!("{file}: {}\n  notes: {:?}", g.ranking[0].explain(), g.notes);
}

#[test]
fn cut_in_on_the_straight_city_highway() {
    check_cut_in("city_highway_straight.xodr", &fixture("cut_in_two_lane.json"));
}

#[test]
fn cut_in_on_the_round_highway_from_the_right_and_from_the_left() {
    check_cut_in("round_highway.xodr", &example("semantics_cut_in.json"));
    check_cut_in("round_highway.xodr", &fixture("cut_in_from_left.json"));
}

/// A junction scenario: the VUT starts on the named lane of the named arm and turns as named; the
/// BV comes from the arm at `bv_offset_deg` from the VUT's arm (180 oncoming, −90 from the left).
fn check_junction(file: &str, s: &ScenarioSemantics, bv_offset_deg: f64, vut_turn: Turn, kind: ConflictKind) {
    let (map, lib) = load(file);
    let g = ground(&map, &lib, s).unwrap_or_else(|e| panic!("{file}: {e}"));
    check_common(&map, &g, s);
    let f = lib.fragment(&g.scenario.fragment_id).unwrap();
    assert_eq!(f.kind, FragmentKind::Intersection);
    let vut = g.scenario.vut().unwrap();
    let bv = g.scenario.bvs().next().unwrap();
    let vut_arm = arm_at(&map, f, vut.start.position);
    let named = match s.ego.start_lane.approach.unwrap().as_str() {
        "from_south" => 270.0,
        "from_east" => 0.0,
        "from_north" => 90.0,
        _ => 180.0,
    };
    assert!(bearing_gap_deg(vut_arm.bearing_rad, f64::to_radians(named)) < 45.0, "{file}: VUT on {}", vut_arm.id);
    let k = usize::from(s.ego.start_lane.lane_index_from_left.unwrap());
    assert_eq!(g.routes[0].start_lane, vut_arm.approach_lanes[k - 1]);
    assert!(dist_to_lane(&map, &vut_arm.approach_lanes[k - 1], vut.start.position) < 0.1);
    assert!(vut.start.anchor_id.starts_with(&format!("{}/entry/{}/", f.id, vut_arm.id)), "{}", vut.start.anchor_id);
    let m = f.maneuver(&g.routes[0].maneuvers[0]).unwrap();
    assert_eq!(m.turn, vut_turn);
    let bv_arm = arm_at(&map, f, bv.start.position);
    let gap = bearing_gap_deg(bv_arm.bearing_rad, vut_arm.bearing_rad + bv_offset_deg.to_radians());
    assert!(
        gap < 30.0,
        "{file}: BV from {} ({:.0}°), VUT from {}",
        bv_arm.id,
        bv_arm.bearing_rad.to_degrees(),
        vut_arm.id
    );
    assert_eq!(g.scenario.conflicts[0].kind, kind);
    println!("{file}: {}\n  notes: {:?}", g.ranking[0].explain(), g.notes);
}

#[test]
fn unprotected_left_turn_on_the_four_arm_junction() {
    // The ego turns left across an oncoming van …
    check_junction("4way_intersection.xodr", &fixture("left_turn_ego.json"), 180.0, Turn::Left, ConflictKind::Crossing);
    // … and the ego goes straight while an oncoming SUV turns left (the project's example).
    let s = example("semantics_left_turn.json");
    check_junction("4way_intersection.xodr", &s, 180.0, Turn::Straight, ConflictKind::Crossing);
}

#[test]
fn unprotected_left_turn_on_the_t_junction() {
    let s = fixture("left_turn_t_junction.json");
    check_junction("threeway_intersection.xodr", &s, 180.0, Turn::Left, ConflictKind::Crossing);
}

#[test]
fn crossing_from_the_left_on_the_four_arm_junction() {
    check_junction("4way_intersection.xodr", &fixture("crossing.json"), -90.0, Turn::Straight, ConflictKind::Crossing);
}

#[test]
fn merge_from_the_ending_lane_on_both_merging_maps() {
    let s = fixture("merge_ramp.json");
    for file in ["DR_DEU_Merging_MT_v01_centered.xodr", "DR_CHN_Merging_ZS_partial_v02.xodr"] {
        let (map, lib) = load(file);
        let g = ground(&map, &lib, &s).unwrap_or_else(|e| panic!("{file}: {e}"));
        check_common(&map, &g, &s);
        let f = lib.fragment(&g.scenario.fragment_id).unwrap();
        assert_eq!(f.kind, FragmentKind::Merge);
        let merging = f.maneuvers.iter().find(|m| m.id.ends_with("/m/merging")).unwrap();
        let through = f.maneuvers.iter().find(|m| m.id.ends_with("/m/through")).unwrap();
        let vut = g.scenario.vut().unwrap();
        let bv = g.scenario.bvs().next().unwrap();
        // The VUT drives the through lane, the BV starts on the ending lane and ends in the VUT's lane.
        assert_eq!(g.routes[0].maneuvers, std::slice::from_ref(&through.id));
        assert_eq!(g.routes[1].maneuvers, [merging.id.clone(), through.id.clone()]);
        assert!(dist_to_lane(&map, &through.lanes[0], vut.start.position) < 0.1, "{file}");
        assert!(dist_to_lane(&map, &merging.lanes[0], bv.start.position) < 0.1, "{file}");
        let ending = &merging.lanes[0];
        assert_eq!(&g.routes[1].start_lane, ending);
        assert_eq!(g.routes[1].goal_lane, g.routes[0].goal_lane);
        assert!(Polyline::new(&through.path).project(bv.goal.position).unwrap().1 < 0.05, "{file}");
        let vut_path = path_of(vut);
        // The ending lane lies on the VUT's right (it merges left).
        assert!(vut_path.project(bv.start.position).unwrap().l_m < -2.0);
        let c = &g.scenario.conflicts[0];
        assert_eq!((c.kind, c.anchor_id.as_str()), (ConflictKind::Merge, format!("{}/merge", f.id).as_str()));
        println!("{file}: {}\n  notes: {:?}", g.ranking[0].explain(), g.notes);
    }
}

#[test]
fn semantics_that_fit_nowhere_fail_with_a_reason_per_fragment() {
    let cases = [
        ("DR_DEU_Merging_MT_v01_centered.xodr", "roundabout.json", "roundabout"),
        ("DR_DEU_Merging_MT_v01_centered.xodr", "intersection_four_lanes.json", "junction"),
        ("DR_CHN_Merging_ZS_partial_v02.xodr", "intersection_four_lanes.json", "junction"),
        ("4way_intersection.xodr", "roundabout.json", "roundabout"),
        ("4way_intersection.xodr", "cut_in_two_lane.json", "own arm"),
        ("city_highway_straight.xodr", "left_turn_ego.json", "junction"),
        ("round_highway.xodr", "crossing.json", "junction"),
    ];
    for (file, name, why) in cases {
        let (map, lib) = load(file);
        let s = fixture(name);
        let Err(GroundError::NoFit { rejections }) = ground(&map, &lib, &s) else {
            panic!("{file} × {name}: grounded");
        };
        assert_eq!(rejections.len(), lib.fragments.len(), "{file} × {name}");
        for (r, f) in rejections.iter().zip(&lib.fragments) {
            assert_eq!(r.fragment_id, f.id);
            assert!(r.reason.contains(why), "{file} × {name}: {}: {}", r.fragment_id, r.reason);
        }
        let text = GroundError::NoFit { rejections }.to_string();
        println!("{file} × {name}: {text}");
    }
}

/// An experiment's target replaces the video's PET label and style in the grounded scenario and
/// its planned timing; the semantics stay what the video says, and the routes do not change.
#[test]
fn another_target_changes_the_timing_not_the_place() {
    use v2t_ground::{GroundOptions, ground_with};
    use v2t_model::{Style, Target};
    let (map, lib) = load("4way_intersection.xodr");
    let s = example("semantics_left_turn.json");
    let video = ground(&map, &lib, &s).unwrap();
    let target = Target::new(4.0, Style::Yield).unwrap();
    let opts = GroundOptions { target: Some(target), ..GroundOptions::default() };
    let g = ground_with(&map, &lib, &s, &opts).unwrap();
    assert_eq!((g.scenario.target.tau_s(), g.scenario.target.style()), (4.0, Style::Yield));
    assert_eq!(g.scenario.fragment_id, video.scenario.fragment_id);
    assert!((g.timing[0].pet_s - 4.0).abs() < 1e-9, "{:?}", g.timing[0]);
    assert_eq!(g.timing[0].style, Style::Yield);
    for (a, b) in g.scenario.agents.iter().zip(&video.scenario.agents) {
        assert_eq!(a.route, b.route, "{}: the route moved", a.id);
    }
    assert!((s.pet_label_s - 2.9).abs() < 1e-12 && s.interacting_bvs[0].style == Style::Rush);
}
