//! Every third-party test map (`tests/data/maps/`) and the project's own proving ground parse into
//! a lane graph whose linked centrelines are continuous, whose widths are positive, and whose
//! topology library has the fragments the map holds — with conflict anchors for every left turn
//! against every oncoming straight path at each 4-arm intersection.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic, clippy::indexing_slicing)] // test code

use std::path::{Path, PathBuf};

use v2t_map::Map;
use v2t_map::library::{AnchorKind, FragmentKind, TopologyLibrary, Turn};

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn third_party() -> Vec<PathBuf> {
    let mut maps: Vec<PathBuf> = std::fs::read_dir(root().join("tests/data/maps"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "xodr"))
        .collect();
    maps.sort();
    assert_eq!(maps.len(), 6, "the six third-party maps are in tests/data/maps");
    maps
}

fn all_maps() -> Vec<PathBuf> {
    let mut maps = third_party();
    let own = root().join("config/maps/proving_ground.xodr");
    if own.exists() {
        maps.push(own);
    }
    maps
}

fn load(path: &Path) -> (Map, TopologyLibrary) {
    let map = Map::load(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let lib = TopologyLibrary::build(&map);
    (map, lib)
}

#[test]
fn every_map_parses_with_continuous_lanes_and_positive_widths() {
    for path in all_maps() {
        let (map, lib) = load(&path);
        let name = path.file_name().unwrap().to_string_lossy();
        for w in &map.warnings {
            println!("{name}: warning: {w}");
        }
        let count = |k| lib.of_kind(k).count();
        println!(
            "{name}: {} roads, {} junctions, {} lanes ({} drivable), {} links; fragments: {} intersections, {} segments, {} merges",
            map.document.roads.len(),
            map.document.junctions.len(),
            map.graph.lanes.len(),
            map.graph.lanes.iter().filter(|l| l.drivable).count(),
            map.graph.links.len(),
            count(FragmentKind::Intersection),
            count(FragmentKind::MultiLaneSegment),
            count(FragmentKind::Merge),
        );
        assert!(!map.graph.links.is_empty() || map.document.roads.len() == 1, "{name}: no lane links");
        let worst = map.graph.links.iter().max_by(|a, b| a.gap_m.total_cmp(&b.gap_m));
        if let Some(w) = worst {
            let (from, to) = (&map.graph.lanes[w.from].key, &map.graph.lanes[w.to].key);
            println!("{name}: largest centreline gap {:.4} m ({from} → {to})", w.gap_m);
            assert!(w.gap_m < 0.01, "{name}: centreline gap {:.4} m from {from} to {to}", w.gap_m);
        }
        for l in &map.graph.lanes {
            assert!(l.samples.len() >= 2, "{name}: {} has no extent", l.key);
            for q in &l.samples {
                assert!(q.p.is_finite() && q.width.is_finite() && q.width >= 0.0, "{name}: {} at s {}", l.key, q.s);
            }
            if l.drivable {
                let max = l.samples.iter().map(|q| q.width).fold(0.0, f64::max);
                assert!(max > 1.0, "{name}: drivable {} is never wider than 1 m", l.key);
                // Widths are positive along the lane; only a lane that tapers out reaches 0 at its end.
                let inner = &l.samples[1..l.samples.len() - 1];
                assert!(inner.iter().all(|q| q.width > 0.0), "{name}: {} has a zero width inside the lane", l.key);
            }
        }
    }
}

#[test]
fn four_arm_intersections_have_a_conflict_for_every_left_turn_against_oncoming_traffic() {
    let mut checked = 0;
    for path in all_maps() {
        let (_, lib) = load(&path);
        let name = path.file_name().unwrap().to_string_lossy();
        for f in lib.of_kind(FragmentKind::Intersection).filter(|f| f.arms.len() == 4) {
            for left in f.maneuvers.iter().filter(|m| m.turn == Turn::Left) {
                let from = f.arms.iter().position(|a| Some(&a.id) == left.from_arm.as_ref()).unwrap();
                let opposite = &f.arms[(from + 2) % 4].id;
                let oncoming: Vec<_> = f
                    .maneuvers
                    .iter()
                    .filter(|m| m.from_arm.as_ref() == Some(opposite) && m.turn == Turn::Straight)
                    .collect();
                assert!(!oncoming.is_empty(), "{name} {}: no straight path from {opposite}", f.id);
                for o in oncoming {
                    let conflict = f.anchors.iter().find(|a| {
                        a.kind == AnchorKind::Conflict
                            && a.on_paths.iter().any(|(m, _)| *m == left.id)
                            && a.on_paths.iter().any(|(m, _)| *m == o.id)
                    });
                    let a = conflict.unwrap_or_else(|| panic!("{name}: no conflict anchor for {} × {}", left.id, o.id));
                    // The anchor lies on both paths, inside the junction part of each.
                    for (m, s) in &a.on_paths {
                        let man = f.maneuver(m).unwrap();
                        assert!(
                            *s >= man.core_from_m - 1e-6 && *s <= man.core_to_m + 1e-6,
                            "{m}: {s} outside its core"
                        );
                    }
                    checked += 1;
                }
            }
        }
    }
    println!("{checked} left-turn × oncoming conflicts checked");
    assert!(checked >= 4, "the 4-arm test map has left turns against oncoming straight paths: {checked}");
}

#[test]
fn the_merging_maps_yield_merges_and_the_highways_yield_multi_lane_segments() {
    for (file, kind) in [
        ("DR_DEU_Merging_MT_v01_centered.xodr", FragmentKind::Merge),
        ("DR_CHN_Merging_ZS_partial_v02.xodr", FragmentKind::Merge),
        ("city_highway_straight.xodr", FragmentKind::MultiLaneSegment),
        ("round_highway.xodr", FragmentKind::MultiLaneSegment),
        ("threeway_intersection.xodr", FragmentKind::Intersection),
        ("4way_intersection.xodr", FragmentKind::Intersection),
    ] {
        let (map, lib) = load(&root().join("tests/data/maps").join(file));
        let frags: Vec<_> = lib.of_kind(kind).collect();
        assert!(!frags.is_empty(), "{file}: no {kind:?} fragment");
        for f in frags {
            println!("{file}: {} — {}", f.id, f.description);
            for a in &f.anchors {
                let lane = map
                    .graph
                    .find(&a.lane)
                    .unwrap_or_else(|| panic!("{}: anchor {} on unknown {}", f.id, a.id, a.lane));
                let l = &map.graph.lanes[lane];
                let q = l.at(a.lane_s_m).unwrap();
                assert!(
                    q.p.dist(a.position) < 0.05,
                    "{}: anchor {} is {} m off its lane",
                    f.id,
                    a.id,
                    q.p.dist(a.position)
                );
            }
            for m in &f.maneuvers {
                assert!(m.path.len() >= 2, "{}: empty path", m.id);
                assert!(f.anchor(&m.entry).is_some() && f.anchor(&m.exit).is_some(), "{}: anchors missing", m.id);
            }
        }
    }
}

#[test]
fn the_proving_ground_has_its_intersection_three_lane_straight_and_ramp_merge_and_its_annotations_apply() {
    let path = root().join("config/maps/proving_ground.xodr");
    let (map, mut lib) = load(&path);
    assert!(map.warnings.is_empty(), "{:?}", map.warnings);
    let j = lib.fragment("J100").expect("the 4-arm intersection");
    assert_eq!(j.arms.len(), 4);
    assert!(j.arms.iter().all(|a| a.approach_lanes.len() == 2 && a.exit_lanes.len() == 2), "2 lanes each way");
    for turn in [Turn::Left, Turn::Straight, Turn::Right] {
        for a in &j.arms {
            assert!(
                j.maneuvers.iter().any(|m| m.turn == turn && m.from_arm.as_ref() == Some(&a.id)),
                "{turn:?} from {}",
                a.id
            );
        }
    }
    let s = lib.fragment("S5/fwd/0").expect("the 3-lane straight");
    assert_eq!(s.lanes_per_direction, 3);
    assert!(s.usable_length_m >= 400.0, "{}", s.usable_length_m);
    assert!(lib.of_kind(FragmentKind::Merge).any(|f| f.id == "Mr5s1l-3"), "the on-ramp merge");
    let text = std::fs::read_to_string(root().join("config/maps/proving_ground.toml")).unwrap();
    let notes = v2t_map::annotate::Annotations::parse(&text, "proving_ground.toml").unwrap();
    lib.annotate(&notes).unwrap();
    assert_eq!(lib.fragment("J100").unwrap().name.as_deref(), Some("main intersection"));
    assert_eq!(lib.fragment("S5/fwd/0").unwrap().test_area_m, Some((20.0, 420.0)));
    // An annotation naming a fragment the map does not have is an error that says so.
    let bad = v2t_map::annotate::Annotations::parse("[[fragment]]\nid = \"J9\"\n", "bad.toml").unwrap();
    let e = lib.annotate(&bad).unwrap_err().to_string();
    assert!(e.contains("bad.toml") && e.contains("J9"), "{e}");
}

/// Every maneuver path of every fragment runs forward only (no segment turns back on the one
/// before), and every anchor that names a path lies on it at the arc length it gives: a merging
/// path reaches the target lane's centreline at the merge point, a through path does not run to
/// a lane's end and restart.
#[test]
fn maneuver_paths_run_forward_and_pass_through_their_anchors() {
    let mut checked = 0;
    for path in all_maps() {
        let (_, lib) = load(&path);
        let name = path.file_name().unwrap().to_string_lossy();
        for f in &lib.fragments {
            for m in &f.maneuvers {
                for w in m.path.windows(3) {
                    let (a, b, c) = (w[0], w[1], w[2]);
                    let turn_back = b.sub(a).dot(c.sub(b));
                    assert!(turn_back >= -1e-9, "{name}: {} turns back at ({:.2}, {:.2})", m.id, b.x, b.y);
                }
                // (A lane may come twice, apart: the proving ground's loop road leaves and
                // re-enters its junction, so one lane is both approach and departure.)
                for w in m.lanes.windows(2) {
                    assert!(w[0] != w[1], "{name}: {} lists lane {} twice in a row", m.id, w[0]);
                }
            }
            for a in &f.anchors {
                for (pid, s) in &a.on_paths {
                    let m = f.maneuver(pid).unwrap_or_else(|| panic!("{name}: {} names unknown {pid}", a.id));
                    let line = v2t_map::library::Polyline::new(&m.path);
                    let (p, _) = line.at(*s).unwrap();
                    let off = p.dist(a.position);
                    assert!(off < 0.10, "{name}: {} lies {off:.2} m off {pid} at s = {s:.1}", a.id);
                    checked += 1;
                }
            }
        }
    }
    println!("{checked} anchor-on-path positions checked");
    assert!(checked > 50, "{checked}");
}
