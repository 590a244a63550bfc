//! Broken maps give clear errors naming the road, lane or junction, never a panic; a map with one
//! bad road still loads the rest with a warning.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic, clippy::indexing_slicing)] // test code

use proptest::prelude::*;
use v2t_map::library::TopologyLibrary;
use v2t_map::{Map, MapError};

fn road(id: &str, x: f64, succ: &str, geometry: &str, width: &str) -> String {
    format!(
        r#"<road id="{id}" length="50" junction="-1">
  <link>{succ}</link>
  <planView><geometry s="0" x="{x}" y="0" hdg="0" length="50">{geometry}</geometry></planView>
  <lanes><laneSection s="0">
    <center><lane id="0" type="none"/></center>
    <right>
      <lane id="-1" type="driving"><link><successor id="-1"/><predecessor id="-1"/></link><width sOffset="0" a="{width}" b="0" c="0" d="0"/></lane>
    </right>
  </laneSection></lanes>
</road>"#
    )
}

fn doc(roads: &[String]) -> String {
    format!(
        r#"<?xml version="1.0"?><OpenDRIVE><header revMajor="1" revMinor="4" name="t"/>{}</OpenDRIVE>"#,
        roads.concat()
    )
}

fn good_pair() -> Vec<String> {
    vec![
        road("1", 0.0, r#"<successor elementType="road" elementId="2" contactPoint="start"/>"#, "<line/>", "3.5"),
        road("2", 50.0, r#"<predecessor elementType="road" elementId="1" contactPoint="end"/>"#, "<line/>", "3.5"),
    ]
}

#[test]
fn a_good_pair_of_roads_links_without_warnings() {
    let map = Map::parse(&doc(&good_pair()), "t").unwrap();
    assert!(map.warnings.is_empty(), "{:?}", map.warnings);
    assert_eq!(map.graph.links.len(), 1);
    assert!(map.graph.links[0].gap_m < 1e-9);
}

#[test]
fn malformed_xml_is_an_error_with_the_position() {
    let e = Map::parse("<OpenDRIVE><header revMajor=\"1\" revMinor=\"4\"></OpenDRIVE>", "t").unwrap_err();
    assert!(matches!(e, MapError::Xml(_)), "{e}");
    assert!(e.to_string().contains("1:"), "names the position: {e}");
    let e = Map::parse("<osm/>", "t").unwrap_err();
    assert!(e.to_string().contains("<osm>"), "{e}");
    let e = Map::parse("<OpenDRIVE/>", "t").unwrap_err();
    assert!(e.to_string().contains("header"), "{e}");
}

#[test]
fn an_unknown_geometry_leaves_out_that_road_only_and_says_which() {
    let mut roads = good_pair();
    roads[1] = road("2", 50.0, "", r#"<clothoidSpline foo="1"/>"#, "3.5");
    let map = Map::parse(&doc(&roads), "t").unwrap();
    assert_eq!(map.document.roads.len(), 1);
    let text: Vec<String> = map.warnings.iter().map(ToString::to_string).collect();
    assert!(
        text.iter().any(|w| w.starts_with("road 2") && w.contains("unknown plan-view geometry <clothoidSpline>")),
        "{text:?}"
    );
    // Road 1 still links to the missing road: a warning, not a crash.
    assert!(text.iter().any(|w| w.contains("road 1") && w.contains("road 2, which does not exist")), "{text:?}");
    assert!(map.graph.lanes.iter().all(|l| l.key.road == "1"));
    let _ = TopologyLibrary::build(&map);
}

#[test]
fn missing_attributes_and_non_finite_numbers_name_the_road_and_line() {
    let mut roads = good_pair();
    roads[1] = roads[1].replace(r#"length="50" junction"#, r#"junction"#);
    let map = Map::parse(&doc(&roads), "t").unwrap();
    let w = map.warnings.iter().find(|w| w.context == "road 2").unwrap().to_string();
    assert!(w.contains("lacks the attribute length") && w.contains("line"), "{w}");

    let mut roads = good_pair();
    roads[0] = road("1", 0.0, "", "<line/>", "NaN");
    let map = Map::parse(&doc(&roads), "t").unwrap();
    let w = map.warnings.iter().find(|w| w.context == "road 1").unwrap().to_string();
    assert!(w.contains("lane -1") && w.contains("not finite"), "{w}");

    let mut roads = good_pair();
    roads[0] = roads[0].replace(r#"x="0""#, r#"x="east""#);
    let map = Map::parse(&doc(&roads), "t").unwrap();
    let w = map.warnings.iter().find(|w| w.context == "road 1").unwrap().to_string();
    assert!(w.contains("x=\"east\" is not a number"), "{w}");
}

#[test]
fn broken_links_and_lane_id_gaps_are_reported() {
    let mut roads = good_pair();
    roads[0] =
        road("1", 0.0, r#"<successor elementType="road" elementId="9" contactPoint="start"/>"#, "<line/>", "3.5");
    let map = Map::parse(&doc(&roads), "t").unwrap();
    assert!(map.warnings.iter().any(|w| w.context == "road 1" && w.message.contains("road 9, which does not exist")));

    let mut roads = good_pair();
    roads[0] = roads[0].replace(r#"lane id="-1" type="driving""#, r#"lane id="-2" type="driving""#);
    let map = Map::parse(&doc(&roads), "t").unwrap();
    let w = map.warnings.iter().find(|w| w.context == "road 1").unwrap().to_string();
    assert!(w.contains("without gaps"), "{w}");

    let mut roads = good_pair();
    roads[1] = roads[1].replace(r#"contactPoint="end""#, r#"contactPoint="middle""#);
    let map = Map::parse(&doc(&roads), "t").unwrap();
    let w = map.warnings.iter().find(|w| w.context == "road 2").unwrap().to_string();
    assert!(w.contains("contactPoint \"middle\""), "{w}");
}

#[test]
fn directions_that_run_into_each_other_are_reported_not_linked() {
    let mut roads = good_pair();
    // Road 2 turned around: its end touches road 1's end, both lanes drive towards the joint.
    roads[1] =
        road("2", 100.0, r#"<successor elementType="road" elementId="1" contactPoint="end"/>"#, "<line/>", "3.5")
            .replace(r#"hdg="0""#, r#"hdg="3.141592653589793""#);
    roads[0] = road("1", 0.0, r#"<successor elementType="road" elementId="2" contactPoint="end"/>"#, "<line/>", "3.5");
    let map = Map::parse(&doc(&roads), "t").unwrap();
    assert!(map.graph.links.is_empty());
    assert!(
        map.warnings.iter().any(|w| w.message.contains("driving directions run into each other")),
        "{:?}",
        map.warnings
    );
}

#[test]
fn a_map_without_a_usable_road_is_an_error() {
    let e = Map::parse(&doc(&[road("1", 0.0, "", "<spiral/>", "3.5")]), "t").unwrap_err();
    assert!(e.to_string().contains("no usable road"), "{e}");
}

#[test]
fn a_file_that_does_not_parse_is_named_in_the_error() {
    let dir = std::env::temp_dir().join(format!("v2t-map-bad-input-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("every_road_refused.xodr");
    std::fs::write(&path, doc(&[road("1", 0.0, "", "<spiral/>", "3.5")])).unwrap();
    let e = Map::load(&path).unwrap_err().to_string();
    std::fs::write(&path, "<OpenDRIVE>").unwrap();
    let xml = Map::load(&path).unwrap_err().to_string();
    std::fs::remove_dir_all(&dir).unwrap();
    let shown = path.display().to_string();
    assert!(e.starts_with(&shown) && e.contains("no usable road"), "{e}");
    assert!(xml.starts_with(&shown) && xml.contains("not OpenDRIVE XML"), "{xml}");
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, ..ProptestConfig::default() })]

    /// Truncated files and random bytes spliced in anywhere: an error or a map, never a panic.
    #[test]
    fn corrupted_maps_never_panic(cut in 0.0..1.0_f64, at in 0.0..1.0_f64, junk in "[ -~]{0,12}") {
        let text = doc(&good_pair());
        let cut = ((text.len() as f64) * cut) as usize;
        let at = ((cut as f64) * at) as usize;
        let mut broken: String = text.chars().take(cut).collect();
        let at = broken.char_indices().map(|(i, _)| i).find(|&i| i >= at).unwrap_or(broken.len());
        broken.insert_str(at, &junk);
        if let Ok(map) = Map::parse(&broken, "t") {
            let _ = TopologyLibrary::build(&map);
        }
    }
}

/// Sizes taken from the file are bounded before anything is sampled: a road of 1e9 m (a 176 GB
/// allocation once), a coordinate of 1e308, a lane 1e5 m wide: the road is left out with a warning
/// naming the field and the bound, the other road still loads.
/// The good pair with `from` replaced by `to` in its second road: that road is left out, and its
/// warning says `needle`.
fn second_road_left_out(from: &str, to: &str, needle: &str) {
    let mut roads = good_pair();
    roads[1] = roads[1].replace(from, to);
    assert_ne!(roads[1], good_pair()[1], "{from}");
    let map = Map::parse(&doc(&roads), "t").unwrap();
    assert_eq!(map.document.roads.len(), 1, "{to}");
    let w = map.warnings.iter().find(|w| w.context.starts_with("road 2")).unwrap().to_string();
    assert!(w.contains(needle), "{to}: {w}");
}

#[test]
fn absurd_lengths_coordinates_and_widths_leave_out_their_road_with_the_bound() {
    for (from, to, needle) in [
        (r#"<road id="2" length="50""#, r#"<road id="2" length="1e9""#, "beyond ±1e8"),
        (r#"<road id="2" length="50""#, r#"<road id="2" length="5e5""#, "100000] m"),
        (r#"x="50" y="0""#, r#"x="50" y="1e308""#, "beyond ±1e8"),
        (r#"length="50">"#, r#"length="2e5">"#, "100000] m"),
    ] {
        second_road_left_out(from, to, needle);
    }
    let mut roads = good_pair();
    roads[1] = road("2", 50.0, "", "<line/>", "1e5");
    let map = Map::parse(&doc(&roads), "t").unwrap();
    let w = map.warnings.iter().find(|w| w.context.starts_with("road 2")).unwrap().to_string();
    assert!(w.contains("a=100000") && w.contains("±100 m"), "{w}");
}

/// Subnormal numbers pass every "> 0" check; a geometry of length 1e-320 holding a spiral once
/// panicked the junction builder. Now any subnormal attribute, and any road or geometry shorter
/// than a millimetre, leaves its road out with a warning naming the road, the attribute and the
/// bound.
#[test]
fn subnormal_and_sub_millimetre_lengths_leave_their_road_out_by_name() {
    for (from, to, needle) in [
        (r#"length="50">"#, r#"length="1e-320">"#, "subnormal"),
        (r#"x="50" y="0""#, r#"x="50" y="5e-324""#, "subnormal"),
        (r#"length="50">"#, r#"length="1e-4">"#, "[0.001, 100000] m"),
        (r#"<road id="2" length="50""#, r#"<road id="2" length="1e-5""#, "within [0.001, 100000] m"),
    ] {
        second_road_left_out(from, to, needle);
    }
    // A geometry of length exactly 0 stays allowed (some exporters write one), as before.
    let mut roads = good_pair();
    roads[1] = roads[1].replace(r#"<planView><geometry s="0" x="50" y="0" hdg="0" length="50"><line/></geometry>"#,
        r#"<planView><geometry s="0" x="50" y="0" hdg="0" length="0"><line/></geometry><geometry s="0" x="50" y="0" hdg="0" length="50"><line/></geometry>"#);
    let map = Map::parse(&doc(&roads), "t").unwrap();
    assert_eq!(map.document.roads.len(), 2, "{:?}", map.warnings);
}

/// The proving ground with one junction spiral shortened to a subnormal length loads, leaves
/// that connecting road out by name, and does not panic.
#[test]
fn the_proving_ground_with_a_subnormal_spiral_loads_without_it() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config/maps/proving_ground.xodr");
    let xml = std::fs::read_to_string(&path).unwrap();
    let mut shortened = 0;
    let mut out = String::with_capacity(xml.len());
    let mut rest = xml.as_str();
    // The 17th spiral geometry of the file is a junction's connecting road.
    let mut spirals = 0;
    while let Some(at) = rest.find("<geometry ") {
        let (head, tail) = rest.split_at(at);
        out.push_str(head);
        let end = tail.find('>').unwrap() + 1;
        let (tag, after) = tail.split_at(end);
        let is_spiral = after.trim_start().starts_with("<spiral");
        if is_spiral {
            spirals += 1;
        }
        if is_spiral && spirals == 17 {
            let start = tag.find("length=\"").unwrap() + 8;
            let stop = start + tag[start..].find('"').unwrap();
            out.push_str(&format!("{}1e-320{}", &tag[..start], &tag[stop..]));
            shortened += 1;
        } else {
            out.push_str(tag);
        }
        rest = after;
    }
    out.push_str(rest);
    assert_eq!(shortened, 1);
    let map = Map::parse(&out, "proving_ground").unwrap();
    let w = map.warnings.iter().find(|w| w.to_string().contains("subnormal")).expect("a warning names it");
    assert!(w.context.starts_with("road "), "{w}");
    let _ = TopologyLibrary::build(&map);
}

/// Maps that are wrong but used to load silently: each is now named in a warning (and the part
/// that cannot be used is left out); a map with no drivable lane left is an error.
#[test]
fn wrong_but_loadable_maps_are_named_and_a_map_without_a_drivable_lane_is_refused() {
    let warned = |roads: &[String], needle: &str| {
        let map = Map::parse(&doc(roads), "t").unwrap();
        let w: Vec<String> = map.warnings.iter().map(ToString::to_string).collect();
        assert!(w.iter().any(|w| w.contains(needle)), "expected {needle:?} in {w:?}");
        map
    };
    // A negative lane width on one road: named, that lane not drivable, the map still loads.
    let mut roads = good_pair();
    roads[1] = road("2", 50.0, "", "<line/>", "-3.5");
    let map = warned(&roads, "a=-3.5 m, not a positive width");
    assert_eq!(map.graph.lanes.iter().filter(|l| l.drivable).count(), 1);
    // Every width negative: nothing drivable is left, exit 2 for the CLI.
    let all = vec![road("1", 0.0, "", "<line/>", "-3.5"), road("2", 50.0, "", "<line/>", "0")];
    let e = Map::parse(&doc(&all), "t").unwrap_err().to_string();
    assert!(e.contains("no drivable lane") && e.contains("not a positive width"), "{e}");
    // Geometries out of s order.
    let mut roads = good_pair();
    roads[1] = roads[1].replace(
        r#"<planView><geometry s="0" x="50" y="0" hdg="0" length="50"><line/></geometry>"#,
        r#"<planView><geometry s="25" x="75" y="0" hdg="0" length="25"><line/></geometry><geometry s="0" x="50" y="0" hdg="0" length="25"><line/></geometry>"#,
    );
    warned(&roads, "not in increasing s (s=0 after s=25)");
    // A lane section before the road's start is left out; the road keeps its other section.
    let mut roads = good_pair();
    let section = roads[1].split("<lanes>").nth(1).unwrap().split("</lanes>").next().unwrap().to_owned();
    roads[1] = roads[1].replace(
        &section,
        &format!("{}{section}", section.replace(r#"<laneSection s="0">"#, r#"<laneSection s="-5">"#)),
    );
    let map = warned(&roads, "starts at s=-5 before the road's start");
    assert_eq!(map.document.roads.len(), 2);
    // NaN in an element the reader does not use (elevation) is named with its line.
    let mut roads = good_pair();
    roads[1] = roads[1].replace(
        "<lanes>",
        r#"<elevationProfile><elevation s="0" a="NaN" b="0" c="0" d="0"/></elevationProfile><lanes>"#,
    );
    warned(&roads, r#"<elevation> a="NaN" is not a finite normal number"#);
}

/// A lane whose width polynomial grows without bound (found by the mutation harness: `d = 1e6`
/// made a 3.5 m lane 10¹² m wide and hung the topology library) leaves its road out, named.
#[test]
fn a_lane_growing_past_its_bound_leaves_its_road_out() {
    let mut roads = good_pair();
    roads.push(road("3", 200.0, "", "<line/>", "3.5").replace("d=\"0\"/>", "d=\"1e6\"/>"));
    let map = Map::parse(&doc(&roads), "t").unwrap();
    let w = map.warnings.iter().find(|w| w.context == "road 3").unwrap().to_string();
    assert!(w.contains("the road is left out") && w.contains("100 m"), "{w}");
    assert!(map.graph.lanes.iter().all(|l| l.key.road != "3"));
    assert!(map.graph.lanes.iter().any(|l| l.key.road == "1"), "the good roads stay");
    let _ = TopologyLibrary::build(&map);
}

/// A road whose geometries do not join (found by the mutation harness: one geometry's `x` scaled
/// by 10⁶ put it 38,000 km from the next, and the drivable area's grid over that lane hung the
/// upload check) is left out, named with the jump and the bound; a centimetre's gap still loads,
/// with a warning.
#[test]
fn a_road_whose_geometries_do_not_join_is_left_out() {
    let two = |x2: &str| {
        road("3", 200.0, "", "<line/>", "3.5").replace(
            r#"<planView><geometry s="0" x="200" y="0" hdg="0" length="50"><line/></geometry></planView>"#,
            &format!(
                r#"<planView><geometry s="0" x="200" y="0" hdg="0" length="25"><line/></geometry><geometry s="25" x="{x2}" y="0" hdg="0" length="25"><line/></geometry></planView>"#
            ),
        )
    };
    let mut roads = good_pair();
    roads.push(two("-38357989.2"));
    let map = Map::parse(&doc(&roads), "t").unwrap();
    let w = map.warnings.iter().find(|w| w.context == "road 3").unwrap().to_string();
    assert!(w.contains("left out") && w.contains("jumps 38358214.200 m at s = 25.00") && w.contains("1 m"), "{w}");
    assert!(map.graph.lanes.iter().all(|l| l.key.road != "3"));
    let _ = v2t_map::drivable::DrivableArea::from_map(&map);
    let mut roads = good_pair();
    roads.push(two("225.05"));
    let map = Map::parse(&doc(&roads), "t").unwrap();
    let w = map.warnings.iter().find(|w| w.context == "road 3").unwrap().to_string();
    assert!(w.contains("jumps 0.050 m") && !w.contains("left out"), "{w}");
    assert!(map.graph.lanes.iter().any(|l| l.key.road == "3"));
}

/// A grounded scenario must lie on the map it is generated for: the first point outside the
/// lanes' extent plus the margin is named.
#[test]
fn a_scenario_off_the_map_is_refused_naming_the_first_point_outside() {
    let map = Map::parse(&doc(&good_pair()), "t").unwrap();
    let agent = |id: &str, role: &str, far: f64| {
        serde_json::json!({
            "id": id, "role": role,
            "route": [{"x": 0.0, "y": -1.75}, {"x": 40.0 + far, "y": -1.75}],
            "start": {"anchor_id": "a", "position": {"x": 0.0, "y": -1.75}, "heading_rad": 0.0, "speed_mps": 8.0, "time_s": 0.0},
            "goal": {"anchor_id": "b", "position": {"x": 40.0, "y": -1.75}, "heading_rad": 0.0, "speed_mps": 8.0, "time_s": null}
        })
    };
    let scenario = |far: f64| -> v2t_model::grounded::GroundedScenario {
        serde_json::from_value(serde_json::json!({
            "fragment_id": "f", "interaction_type": "cut_in",
            "agents": [agent("vut", "vut", 0.0), agent("bv1", "bv", far)],
            "conflicts": [{"bv_id": "bv1", "kind": "merge", "anchor_id": "c", "point": {"x": 20.0, "y": -1.75},
                "vut_interval": {"enter_s_m": 18.0, "exit_s_m": 22.0}, "bv_interval": {"enter_s_m": 18.0, "exit_s_m": 22.0}}],
            "tau_s": 2.0, "style": "rush"
        }))
        .unwrap()
    };
    map.check_scenario(&scenario(0.0)).unwrap();
    let e = map.check_scenario(&scenario(5_000.0)).unwrap_err().to_string();
    assert!(e.contains("agents[1].route[1]") && e.contains("more than 500 m outside"), "{e}");
}
