#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic, clippy::indexing_slicing)]

use std::f64::consts::PI;

use super::*;

/// Edge `a` (two lanes, eastbound along y = 0 and y = 3.2) enters junction `J1`, whose internal
/// lane `:J1_0_0` leads on to edge `b`; edge `c` starts where `b` ends but nothing connects them.
pub(crate) const TINY_NET: &str = r#"<?xml version="1.0" encoding="UTF-8"?>
<net version="1.20">
    <location netOffset="0.00,0.00"/>
    <edge id=":J1_0" function="internal">
        <lane id=":J1_0_0" index="0" speed="10.00" length="10.00" shape="100.00,0.00 110.00,0.00"/>
    </edge>
    <edge id="a" from="J0" to="J1" priority="1">
        <lane id="a_0" index="0" speed="13.89" length="100.00" width="3.20" shape="0.00,0.00 100.00,0.00">
            <param key="origId" value="7_-2"/>
        </lane>
        <lane id="a_1" index="1" speed="13.89" length="100.00" shape="0.00,3.20 100.00,3.20"/>
    </edge>
    <edge id="b" from="J1" to="J2" priority="1">
        <lane id="b_0" index="0" speed="13.89" length="100.00" width="3.50" shape="110.00,0.00 210.00,0.00"/>
    </edge>
    <edge id="c" from="J2" to="J3" priority="1">
        <lane id="c_0" index="0" speed="13.89" length="90.00" width="3.50" shape="210.00,0.00 300.00,0.00"/>
    </edge>
    <junction id="J1" type="priority" x="105.00" y="0.00" incLanes="a_0 a_1" intLanes=":J1_0_0" shape=""/>
    <connection from="a" to="b" fromLane="0" toLane="0" via=":J1_0_0" dir="s" state="M"/>
    <connection from=":J1_0" to="b" fromLane="0" toLane="0" dir="s" state="M"/>
</net>
"#;

pub(crate) fn tiny() -> Network {
    Network::parse(TINY_NET, Path::new("tiny.net.xml")).unwrap()
}

/// Samples every metre from x0 to x1 (eastbound), with y = f(x).
fn eastbound(x0: i32, x1: i32, f: impl Fn(f64) -> f64) -> Vec<[f64; 3]> {
    (x0..=x1)
        .map(|x| {
            let x = f64::from(x);
            let heading = (f(x + 0.5) - f(x - 0.5)).atan2(1.0);
            [x, f(x), heading]
        })
        .collect()
}

#[test]
fn the_tiny_net_reads_edges_lanes_connections_and_junctions() {
    let net = tiny();
    assert_eq!(net.edges.len(), 4);
    assert_eq!(net.lanes.len(), 5);
    let a1 = net.lane("a_1").unwrap();
    assert_eq!((a1.edge_id.as_str(), a1.index, a1.width_m), ("a", 1, DEFAULT_LANE_WIDTH_M));
    assert_eq!(net.lane("a_0").unwrap().orig_id.as_deref(), Some("7_-2"));
    let internal = net.lane(":J1_0_0").unwrap();
    assert!(internal.internal && (internal.speed_mps - 10.0).abs() < 1e-9);
    assert_eq!(net.edge(":J1_0").unwrap().function, EdgeFunction::Internal);
    assert_eq!(net.edge("a").unwrap().to.as_deref(), Some("J1"));
    assert_eq!(net.junction("J1").unwrap().internal_lanes, [":J1_0_0"]);
    assert_eq!(net.connections.len(), 2);
    assert_eq!(net.connections[0].via.as_deref(), Some(":J1_0_0"));
    let b = net.bounds();
    assert_eq!((b.min, b.max), ([0.0, 0.0], [300.0, 3.2]));
}

#[test]
fn the_nearest_lane_runs_the_way_of_the_heading() {
    let net = tiny();
    let on = net.nearest_lane(30.0, 2.5, 0.1, 2.0).unwrap();
    assert_eq!(on.lane_id, "a_1");
    assert!((on.s_m - 30.0).abs() < 1e-9 && (on.lateral_m + 0.7).abs() < 1e-9);
    assert!((on.heading_err - 0.1).abs() < 1e-9);
    // 59° off still counts, 61° does not; westbound is no lane at all.
    assert!(net.nearest_lane(30.0, 0.0, 59f64.to_radians(), 2.0).is_some());
    assert!(net.nearest_lane(30.0, 0.0, 61f64.to_radians(), 2.0).is_none());
    assert!(net.nearest_lane(30.0, 0.0, PI, 2.0).is_none());
    assert!(net.nearest_lane(30.0, 10.0, 0.0, 2.0).is_none());
    assert_eq!(net.nearest_lane(105.0, 0.3, 0.0, 2.0).unwrap().lane_id, ":J1_0_0");
}

#[test]
fn a_straight_path_goes_through_the_junction_lane() {
    let route = tiny().match_route(&eastbound(10, 200, |_| 0.2), 2.0).unwrap();
    assert_eq!(route.lanes, ["a_0", ":J1_0_0", "b_0"]);
    assert_eq!(route.edges, ["a", "b"]);
    assert_eq!((route.depart_lane, route.arrival_lane), (0, 0));
    assert!((route.depart_pos_m - 10.0).abs() < 1e-9, "{}", route.depart_pos_m);
    assert!((route.arrival_pos_m - 90.0).abs() < 1e-9, "{}", route.arrival_pos_m);
    assert_eq!(route.shape.first(), Some(&[10.0, 0.0]));
    assert_eq!(route.shape.last(), Some(&[200.0, 0.0]));
}

#[test]
fn a_lane_change_on_an_edge_is_part_of_the_route() {
    let y = |x: f64| match x {
        x if x <= 40.0 => 3.2,
        x if x >= 50.0 => 0.0,
        x => 3.2 * (50.0 - x) / 10.0,
    };
    let route = tiny().match_route(&eastbound(10, 150, y), 2.0).unwrap();
    assert_eq!(route.lanes, ["a_1", "a_0", ":J1_0_0", "b_0"]);
    assert_eq!(route.edges, ["a", "b"]);
    assert_eq!(route.depart_lane, 1);
    assert_eq!(route.shape.first(), Some(&[10.0, 3.2]));
    assert_eq!(route.shape.last(), Some(&[150.0, 0.0]));
}

#[test]
fn a_sample_off_every_lane_is_named_with_its_nearest_lane() {
    let mut path = eastbound(10, 80, |_| 0.0);
    path[40] = [50.0, 20.0, 0.0];
    match tiny().match_route(&path, 2.0) {
        Err(SumoError::RouteMatch { index, x, y, nearest_lane, distance_m, max_off_m }) => {
            assert_eq!((index, x, y, nearest_lane.as_str()), (40, 50.0, 20.0, "a_1"));
            assert!((distance_m - 16.8).abs() < 1e-9 && max_off_m == 2.0);
        }
        other => panic!("{other:?}"),
    }
    // Driving against the lanes matches nothing either.
    let mut west = eastbound(10, 80, |_| 0.0);
    for p in &mut west {
        p[2] = PI;
    }
    let err = tiny().match_route(&west, 2.0).unwrap_err();
    assert!(matches!(err, SumoError::RouteMatch { index: 0, .. }), "{err}");
    assert!(err.to_string().contains("sample 0 at (10.00, 0.00)"), "{err}");
}

#[test]
fn unlinked_lanes_and_junction_ends_break_the_route() {
    let err = tiny().match_route(&eastbound(150, 250, |_| 0.0), 2.0).unwrap_err();
    match &err {
        SumoError::RouteBroken { index, problem, .. } => {
            // b_0's end still counts within 2 m: the path breaks 3 m into c_0.
            assert_eq!(*index, 63, "{err}");
            assert!(problem.contains("c_0") && problem.contains("b_0"), "{err}");
        }
        other => panic!("{other:?}"),
    }
    let err = tiny().match_route(&eastbound(102, 150, |_| 0.0), 2.0).unwrap_err();
    assert!(matches!(err, SumoError::RouteBroken { index: 0, .. }), "{err}");
    assert!(err.to_string().contains(":J1_0_0"), "{err}");
    assert!(matches!(tiny().match_route(&eastbound(10, 10, |_| 0.0), 2.0), Err(SumoError::InvalidArgument { .. })));
    assert!(matches!(
        tiny().match_route(&eastbound(10, 20, |_| 0.0), f64::NAN),
        Err(SumoError::InvalidArgument { .. })
    ));
}

#[test]
fn malformed_networks_name_the_element_and_attribute() {
    let cases = [
        (TINY_NET.replace(r#"shape="0.00,3.20 100.00,3.20""#, ""), "lane id=\"a_1\"", "shape"),
        (TINY_NET.replace(r#"speed="10.00""#, r#"speed="fast""#), "lane id=\":J1_0_0\"", "speed"),
        (
            TINY_NET.replace(r#"toLane="0" via"#, r#"toLane="5" via"#),
            "connection from=\"a\" to=\"b\"",
            "fromLane/toLane/via",
        ),
        (TINY_NET.replace("<net ", "<nett ").replace("</net>", "</nett>"), "nett", ""),
        (TINY_NET.replace("</net>", ""), "net", ""),
    ];
    for (text, element, attribute) in cases {
        match Network::parse(&text, Path::new("bad.net.xml")) {
            Err(SumoError::NetParse { file, element: e, attribute: a, .. }) => {
                assert_eq!(file, Path::new("bad.net.xml"));
                assert_eq!((e.as_str(), a.as_str()), (element, attribute));
            }
            other => panic!("{element}: {other:?}"),
        }
    }
}
