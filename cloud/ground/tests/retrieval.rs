//! Retrieval over a library that holds every kind of fragment: the fragments of the 4-arm junction,
//! the city highway and the German merge put together. Each kind of semantics ranks its own kind of
//! fragment first, every candidate explains itself, and infeasible ones rank last with a reason.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic, clippy::indexing_slicing)] // test code

mod common;

use common::{example, fixture, load};
use v2t_ground::{Candidate, rank};
use v2t_map::library::{FragmentKind, TopologyLibrary};

fn mixed_library() -> TopologyLibrary {
    let mut fragments = Vec::new();
    for file in ["4way_intersection.xodr", "city_highway_straight.xodr", "DR_DEU_Merging_MT_v01_centered.xodr"] {
        fragments.extend(load(file).1.fragments);
    }
    TopologyLibrary { map: "mixed".into(), fragments }
}

fn check_explained(ranking: &[Candidate]) {
    let names = ["road_type", "maneuvers", "interaction", "lanes", "room", "lexical"];
    let mut seen_infeasible = false;
    for c in ranking {
        let got: Vec<&str> = c.criteria.iter().map(|x| x.name).collect();
        assert_eq!(got, names, "{}", c.fragment_id);
        for x in &c.criteria {
            assert!((0.0..=1.0).contains(&x.score) && !x.reason.is_empty(), "{}: {x:?}", c.fragment_id);
        }
        let sum: f64 = c.criteria.iter().map(|x| x.weight * x.score).sum();
        assert!((sum - c.score).abs() < 1e-12);
        assert_eq!(c.feasible, c.reasons.is_empty(), "{}", c.fragment_id);
        // Feasible candidates come first.
        assert!(!(seen_infeasible && c.feasible), "a feasible candidate after an infeasible one");
        seen_infeasible |= !c.feasible;
        assert!(c.explain().starts_with(&c.fragment_id));
    }
    let weights: f64 = ranking[0].criteria.iter().map(|x| x.weight).sum();
    assert!((weights - 1.0).abs() < 1e-12);
}

#[test]
fn each_kind_of_semantics_ranks_its_kind_of_fragment_first() {
    let lib = mixed_library();
    for (name, s, kind) in [
        ("left turn", example("semantics_left_turn.json"), FragmentKind::Intersection),
        ("crossing", fixture("crossing.json"), FragmentKind::Intersection),
        ("cut-in", fixture("cut_in_two_lane.json"), FragmentKind::MultiLaneSegment),
        ("merge", fixture("merge_ramp.json"), FragmentKind::Merge),
    ] {
        let ranking = rank(&lib, &s);
        assert_eq!(ranking.len(), lib.fragments.len());
        check_explained(&ranking);
        println!("{name}:\n{}", ranking.iter().map(Candidate::explain).collect::<Vec<_>>().join("\n"));
        assert_eq!(ranking[0].kind, kind, "{name}");
        assert!(ranking[0].feasible && ranking[0].score > ranking[1].score, "{name}");
        // The lexical criterion alone points at the right kind for the junction and the merge; for
        // the cut-in the lane-drop description ("cut-in at a lane drop") is as close as the segment's.
        let lexical = |c: &Candidate| c.criteria.iter().find(|x| x.name == "lexical").unwrap().score;
        let best = ranking.iter().max_by(|a, b| lexical(a).total_cmp(&lexical(b))).unwrap();
        if kind == FragmentKind::MultiLaneSegment {
            assert!(lexical(&ranking[0]) > 0.5, "{name}");
        } else {
            assert_eq!(best.kind, kind, "{name}: lexical best is {}", best.fragment_id);
        }
    }
}

#[test]
fn junction_semantics_are_infeasible_off_junctions_with_the_reason() {
    let lib = mixed_library();
    let ranking = rank(&lib, &fixture("left_turn_ego.json"));
    for c in ranking.iter().filter(|c| c.kind != FragmentKind::Intersection) {
        assert!(!c.feasible, "{}", c.explain());
        assert!(c.reasons.iter().any(|r| r.contains("needs a junction")), "{}", c.explain());
    }
    // A cut-in is feasible on the segment and, as a lane drop, on the merge, but not on the junction.
    let ranking = rank(&lib, &fixture("cut_in_two_lane.json"));
    let by_kind = |k| ranking.iter().find(|c| c.kind == k).unwrap();
    assert!(by_kind(FragmentKind::MultiLaneSegment).feasible);
    assert!(by_kind(FragmentKind::Merge).feasible, "{}", by_kind(FragmentKind::Merge).explain());
    assert!(!by_kind(FragmentKind::Intersection).feasible);
    assert!(by_kind(FragmentKind::MultiLaneSegment).score > by_kind(FragmentKind::Merge).score);
}

#[test]
fn a_solid_line_forbids_the_cut_in() {
    let (_, mut lib) = load("city_highway_straight.xodr");
    for p in &mut lib.fragments[0].lane_pairs {
        p.mark = v2t_map::xodr::MarkType::Solid;
    }
    let c = &rank(&lib, &fixture("cut_in_two_lane.json"))[0];
    assert!(!c.feasible);
    assert!(c.reasons[0].contains("solid line"), "{}", c.explain());
}
