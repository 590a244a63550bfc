//! Variants of the basic cases: the ego is the one that changes lanes or merges, two BVs, PET and
//! style swept over the 4-arm junction, the footprints of the configured vehicles, and the
//! project's own proving ground when it is there.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic, clippy::indexing_slicing)] // test code

mod common;

use common::{check_common, dist_to_lane, example, fixture, load, path_of, root};
use proptest::prelude::*;
use v2t_ground::{GroundOptions, ground, ground_with};
use v2t_map::Map;
use v2t_map::library::TopologyLibrary;
use v2t_model::Style;
use v2t_model::semantics::{InteractionType, Maneuver, RelativeStart};
use v2t_model::validate::Validate;
use v2t_model::vehicle::VehicleConfig;

#[test]
fn the_ego_changes_into_the_bvs_lane_on_the_round_highway() {
    let (map, lib) = load("round_highway.xodr");
    let mut s = example("semantics_cut_in.json");
    s.ego.maneuver = Maneuver::LaneChangeLeft;
    let bv = &mut s.interacting_bvs[0];
    (bv.relative_start, bv.behavior.maneuver, bv.interaction_type) =
        (RelativeStart::AdjacentLeft, Maneuver::Straight, InteractionType::LaneChange);
    s.validate().unwrap();
    let g = ground(&map, &lib, &s).unwrap();
    check_common(&map, &g, &s);
    let f = lib.fragment(&g.scenario.fragment_id).unwrap();
    // Lane 2 from the left (p1) into lane 1 (p0), where the BV drives.
    assert_eq!(g.routes[0].maneuvers, [format!("{}/m/p1", f.id), format!("{}/m/p0", f.id)]);
    assert_eq!(g.routes[1].maneuvers, [format!("{}/m/p0", f.id)]);
    assert_eq!(g.routes[0].goal_lane, g.routes[1].goal_lane);
    let (vut, bv) = (g.scenario.vut().unwrap(), g.scenario.bvs().next().unwrap());
    assert!(path_of(bv).project(vut.start.position).unwrap().l_m < -2.5, "the VUT starts right of the BV");
    assert_eq!(g.scenario.conflicts[0].anchor_id, format!("{}/cutin/p1>p0", f.id));
}

#[test]
fn the_ego_merges_in_front_of_a_bv_on_the_german_merge() {
    let (map, lib) = load("DR_DEU_Merging_MT_v01_centered.xodr");
    let mut s = fixture("merge_ramp.json");
    (s.ego.maneuver, s.ego.start_lane.lane_index_from_left) = (Maneuver::Merge, Some(2));
    let bv = &mut s.interacting_bvs[0];
    (bv.relative_start, bv.behavior.maneuver, bv.style) =
        (RelativeStart::AdjacentLeft, Maneuver::Straight, Style::Yield);
    s.validate().unwrap();
    let g = ground(&map, &lib, &s).unwrap();
    check_common(&map, &g, &s);
    assert!(g.notes.is_empty(), "{:?}", g.notes);
    let f = lib.fragment(&g.scenario.fragment_id).unwrap();
    let merging = f.maneuvers.iter().find(|m| m.id.ends_with("/m/merging")).unwrap();
    assert!(dist_to_lane(&map, &merging.lanes[0], g.scenario.vut().unwrap().start.position) < 0.1);
    assert_eq!(g.routes[0].goal_lane, g.routes[1].goal_lane);
}

#[test]
fn two_bvs_each_get_their_conflict_and_start_time() {
    // The left-turn example plus a second BV crossing from the right that goes straight.
    let (map, lib) = load("4way_intersection.xodr");
    let mut s = example("semantics_left_turn.json");
    let mut second = s.interacting_bvs[0].clone();
    second.id = "bv2".into();
    (second.relative_start, second.behavior.maneuver, second.interaction_type, second.style) =
        (RelativeStart::CrossingFromRight, Maneuver::Straight, InteractionType::Crossing, Style::Yield);
    s.interacting_bvs.push(second);
    s.validate().unwrap();
    let g = ground(&map, &lib, &s).unwrap();
    check_common(&map, &g, &s);
    assert_eq!(g.scenario.conflicts.len(), 2);
    assert_eq!(g.timing.len(), 2);
    assert_ne!(g.scenario.conflicts[0].anchor_id, g.scenario.conflicts[1].anchor_id);
    // The grounding serializes for the operator's tools.
    let json = serde_json::to_value(&g).unwrap();
    assert_eq!(json["scenario"]["agents"].as_array().unwrap().len(), 3);
}

#[test]
fn the_default_footprints_are_the_configured_vehicles() {
    let read = |f: &str| -> VehicleConfig {
        toml::from_str(&std::fs::read_to_string(root().join("config/vehicles").join(f)).unwrap()).unwrap()
    };
    let from_config = GroundOptions::for_vehicles(&read("vut_sedan.toml"), &read("bv_sedan.toml"));
    assert_eq!(from_config, GroundOptions::default());
    // Longer vehicles occupy the zone longer.
    let (map, lib) = load("4way_intersection.xodr");
    let s = example("semantics_left_turn.json");
    let mut long = GroundOptions::default();
    long.bv.length_m = 12.0;
    let (a, b) = (ground(&map, &lib, &s).unwrap(), ground_with(&map, &lib, &s, &long).unwrap());
    let span = |g: &v2t_ground::Grounding| {
        g.scenario.conflicts[0].bv_interval.exit_s_m - g.scenario.conflicts[0].bv_interval.enter_s_m
    };
    assert!((span(&b) - span(&a) - 7.2).abs() < 1e-6);
}

fn four_way() -> &'static (Map, TopologyLibrary) {
    static MAP: std::sync::OnceLock<(Map, TopologyLibrary)> = std::sync::OnceLock::new();
    MAP.get_or_init(|| load("4way_intersection.xodr"))
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 24, failure_persistence: None, ..ProptestConfig::default() })]

    /// Whatever the PET, the style and the speeds, the grounding validates and its planned passage
    /// meets τ in the style's order.
    #[test]
    fn the_planned_pet_is_the_label(
        tau in 0.2f64..12.0,
        rush in any::<bool>(),
        ego_speed in 0.0f64..16.0,
        bv_speed in 0.0f64..16.0,
        ego_left in any::<bool>(),
    ) {
        let (map, lib) = four_way();
        let mut s = if ego_left { fixture("left_turn_ego.json") } else { example("semantics_left_turn.json") };
        s.pet_label_s = (tau * 100.0).round() / 100.0;
        s.ego.speed_estimate_mps = ego_speed;
        let bv = &mut s.interacting_bvs[0];
        bv.behavior.speed_estimate_mps = bv_speed;
        bv.style = if rush { Style::Rush } else { Style::Yield };
        let g = ground(map, lib, &s).unwrap();
        prop_assert_eq!(g.scenario.validate(), Ok(()));
        let t = &g.timing[0];
        prop_assert!((t.pet_s - s.pet_label_s).abs() < 1e-9);
        if rush { prop_assert!(t.bv_exit_s < t.vut_enter_s) } else { prop_assert!(t.vut_exit_s < t.bv_enter_s) }
        let starts: Vec<f64> = g.scenario.agents.iter().map(|a| a.start.time_s.unwrap()).collect();
        prop_assert!(starts.iter().all(|t| *t >= 0.0) && starts.contains(&0.0));
    }
}

/// The project's proving ground (`config/maps/proving_ground.xodr`), while it is being authored:
/// every example kind grounds on it with the same guarantees as on the third-party maps.
#[test]
fn the_proving_ground_grounds_every_example_kind() {
    let path = root().join("config/maps/proving_ground.xodr");
    if !path.exists() {
        println!("no {}: skipped", path.display());
        return;
    }
    let map = Map::load(&path).unwrap();
    let lib = TopologyLibrary::build(&map);
    for s in [
        example("semantics_cut_in.json"),
        example("semantics_left_turn.json"),
        fixture("left_turn_ego.json"),
        fixture("crossing.json"),
        fixture("merge_ramp.json"),
        fixture("cut_in_two_lane.json"),
    ] {
        let g = ground(&map, &lib, &s).unwrap_or_else(|e| panic!("{}: {e}", s.source.video));
        check_common(&map, &g, &s);
        println!("{}: {} {:?}", s.source.video, g.scenario.fragment_id, g.notes);
    }
}
