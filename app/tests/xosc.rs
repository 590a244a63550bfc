//! `video2track export xosc` end to end: every input kind (a trajectory prior, a grounded scenario,
//! a simulated run) becomes an OpenSCENARIO 1.2 file whose entities, BV trajectories, VUT route and
//! map path are checked against the input; bad input is an input error (exit 2) with a message.
//! The ASAM checker runs on the same exports in CI (`tests/openscenario/qc.sh`).

#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)] // test code

mod common;

use std::path::{Path, PathBuf};

use common::{ok, repo, s, tempdir, video2track};

use v2t_model::geometry::Point2;
use v2t_model::grounded::{AgentRole, GroundedScenario};
use v2t_model::kinematics::State;
use v2t_model::prior::TrajectoryPrior;

/// Grounds the example semantics `which` (left_turn, cut_in) into `dir`.
fn grounded(dir: &Path, which: &str) -> (PathBuf, GroundedScenario) {
    let out = common::ground_example(dir, which);
    let g: GroundedScenario = serde_json::from_str(&std::fs::read_to_string(&out).unwrap()).unwrap();
    (out, g)
}

fn export(input: &Path, out: &Path) -> String {
    let text = ok(&["export", "xosc", s(input), "-o", s(out)]);
    assert!(text.contains("wrote"), "{text}");
    std::fs::read_to_string(out).unwrap()
}

/// One timed pose of the file.
#[derive(Debug, Clone, Copy)]
struct Pose {
    t: f64,
    x: f64,
    y: f64,
    h: f64,
}

fn world(node: roxmltree::Node<'_, '_>) -> Pose {
    let w = node.descendants().find(|n| n.has_tag_name("WorldPosition")).expect("a WorldPosition");
    let f = |k: &str| w.attribute(k).unwrap().parse::<f64>().unwrap();
    Pose { t: f64::NAN, x: f("x"), y: f("y"), h: f("h") }
}

/// What the tests read back from an exported file.
struct Xosc {
    entities: Vec<String>,
    /// Per BV: its trajectory's vertices.
    trajectories: Vec<(String, Vec<Pose>)>,
    /// Per agent: the teleport pose and the initial speed.
    init: Vec<(String, Pose, f64)>,
    /// The VUT's route waypoints.
    waypoints: Vec<Pose>,
    map: String,
    stop_s: f64,
    rev: (String, String),
    description: String,
}

fn child<'a, 'i>(n: roxmltree::Node<'a, 'i>, tag: &str) -> roxmltree::Node<'a, 'i> {
    n.children().find(|c| c.has_tag_name(tag)).unwrap_or_else(|| panic!("no {tag} in {}", n.tag_name().name()))
}

fn read(text: &str) -> Xosc {
    let doc = roxmltree::Document::parse(text).expect("well-formed XML");
    let root = doc.root_element();
    assert_eq!(root.tag_name().name(), "OpenSCENARIO");
    let header = child(root, "FileHeader");
    let entities = child(root, "Entities")
        .children()
        .filter(|c| c.has_tag_name("ScenarioObject"))
        .map(|c| {
            let v = child(c, "Vehicle");
            assert_eq!(v.attribute("vehicleCategory"), Some("car"));
            for tag in ["BoundingBox", "Performance", "Axles", "Properties"] {
                child(v, tag);
            }
            c.attribute("name").unwrap().to_owned()
        })
        .collect();
    let storyboard = child(root, "Storyboard");
    let mut trajectories = Vec::new();
    for story in storyboard.children().filter(|c| c.has_tag_name("Story")) {
        let actor = story.descendants().find(|n| n.has_tag_name("EntityRef")).unwrap();
        let follows: Vec<_> = story.descendants().filter(|n| n.has_tag_name("FollowTrajectoryAction")).collect();
        assert_eq!(follows.len(), 1, "one FollowTrajectoryAction per story");
        let f = follows[0];
        let timing = f.descendants().find(|n| n.has_tag_name("Timing")).unwrap();
        assert_eq!(timing.attribute("domainAbsoluteRelative"), Some("absolute"));
        assert_eq!(timing.attribute("scale"), Some("1"));
        assert_eq!(timing.attribute("offset"), Some("0"));
        assert_eq!(child(f, "TrajectoryFollowingMode").attribute("followingMode"), Some("position"));
        let vertices = f
            .descendants()
            .filter(|n| n.has_tag_name("Vertex"))
            .map(|v| Pose { t: v.attribute("time").unwrap().parse().unwrap(), ..world(v) })
            .collect();
        trajectories.push((actor.attribute("entityRef").unwrap().to_owned(), vertices));
    }
    let mut init = Vec::new();
    let mut waypoints = Vec::new();
    for private in storyboard.descendants().filter(|n| n.has_tag_name("Private")) {
        let teleport = private.descendants().find(|n| n.has_tag_name("TeleportAction")).unwrap();
        let speed = private.descendants().find(|n| n.has_tag_name("AbsoluteTargetSpeed")).unwrap();
        init.push((
            private.attribute("entityRef").unwrap().to_owned(),
            world(teleport),
            speed.attribute("value").unwrap().parse().unwrap(),
        ));
        for w in private.descendants().filter(|n| n.has_tag_name("Waypoint")) {
            assert_eq!(w.attribute("routeStrategy"), Some("shortest"));
            waypoints.push(world(w));
        }
    }
    let stop =
        child(storyboard, "StopTrigger").descendants().find(|n| n.has_tag_name("SimulationTimeCondition")).unwrap();
    Xosc {
        entities,
        trajectories,
        init,
        waypoints,
        map: child(child(root, "RoadNetwork"), "LogicFile").attribute("filepath").unwrap().to_owned(),
        stop_s: stop.attribute("value").unwrap().parse().unwrap(),
        rev: (header.attribute("revMajor").unwrap().to_owned(), header.attribute("revMinor").unwrap().to_owned()),
        description: header.attribute("description").unwrap().to_owned(),
    }
}

/// Distance from `p` to the polyline `route`, m.
/// The route with the straight lead-in the constant-speed prior puts before an agent that is due
/// at its start anchor after the first one, and the straight lead-out it drives on past the
/// route's end (`TrajectoryPrior::along_routes_at_start_speed`).
fn with_lead_in_and_out(agent: &v2t_model::grounded::GroundedAgent) -> Vec<Point2> {
    let back = Point2::from_heading(agent.start.heading_rad).scale(-500.0);
    let mut r = vec![agent.route[0].add(back)];
    r.extend_from_slice(&agent.route);
    let [.., before, last] = agent.route.as_slice() else { unreachable!("a route of one point") };
    let along = last.sub(*before);
    r.push(last.add(along.scale(500.0 / along.norm())));
    r
}

fn off_route(p: Point2, route: &[Point2]) -> f64 {
    route
        .windows(2)
        .map(|w| {
            let (a, b) = (w[0], w[1]);
            let (dx, dy) = (b.x - a.x, b.y - a.y);
            let l2 = dx * dx + dy * dy;
            let f = if l2 > 0.0 { (((p.x - a.x) * dx + (p.y - a.y) * dy) / l2).clamp(0.0, 1.0) } else { 0.0 };
            p.dist(Point2 { x: a.x + f * dx, y: a.y + f * dy })
        })
        .fold(f64::INFINITY, f64::min)
}

fn angle_gap(a: f64, b: f64) -> f64 {
    (a - b + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU) - std::f64::consts::PI
}

/// Every vertex is the state at its time (times on the grid, positions within 1 cm); the first and
/// the last state are vertices; no gap between vertices exceeds 0.5 s.
fn vertices_match(vertices: &[Pose], states: &[State], times: &[f64]) {
    assert!(vertices.len() >= 2);
    assert!(vertices.len() < states.len(), "sparse: {} vertices for {} states", vertices.len(), states.len());
    let mut last_k = None;
    for v in vertices {
        let k = times
            .iter()
            .position(|t| (t - v.t).abs() < 1e-9)
            .unwrap_or_else(|| panic!("vertex at {} s is off the grid", v.t));
        let st = states[k];
        assert!(
            Point2 { x: v.x, y: v.y }.dist(Point2 { x: st.px, y: st.py }) < 0.01,
            "vertex at {} s: {v:?} vs {st:?}",
            v.t
        );
        assert!(angle_gap(v.h, st.theta_rad).abs() < 1e-5, "heading at {} s", v.t);
        if let Some(j) = last_k {
            assert!(k > j, "vertex times increase");
            assert!(times[k] - times[j] <= 0.5 + 1e-9, "gap {} s", times[k] - times[j]);
        }
        last_k = Some(k);
    }
    assert_eq!(vertices.first().unwrap().t, times[0]);
    assert!((vertices.last().unwrap().t - times[times.len() - 1]).abs() < 1e-9);
}

fn map_resolves(xosc_path: &Path, map: &str) {
    assert!(Path::new(map).is_relative(), "{map}");
    let resolved = xosc_path.parent().unwrap().join(map);
    assert_eq!(
        resolved.canonicalize().unwrap(),
        repo().join("config/maps/proving_ground.xodr").canonicalize().unwrap(),
        "{map} from {}",
        xosc_path.display()
    );
}

#[test]
fn a_trajectory_prior_exports_its_bv_trajectories_and_the_vut_route() {
    let dir_scratch = tempdir("prior");
    let dir = dir_scratch.path();
    let (_, g) = grounded(dir, "left_turn");
    // Two BVs (the second a copy of the first, 8 m further): one story and one trajectory each.
    let mut prior = TrajectoryPrior::along_routes_at_start_speed(&g, 12.0).unwrap();
    let mut bv2 = prior.agents.iter().find(|a| a.role == AgentRole::Bv).unwrap().clone();
    bv2.id = "bv2".into();
    bv2.states.iter_mut().for_each(|st| st.px += 8.0);
    prior.agents.push(bv2);
    let input = dir.join("prior.json");
    std::fs::write(&input, serde_json::to_string_pretty(&prior).unwrap()).unwrap();
    let out = dir.join("prior.xosc");
    let x = read(&export(&input, &out));
    assert_eq!(x.rev, ("1".to_owned(), "2".to_owned()));
    assert!(
        x.description.contains("prior.json") && x.description.contains("τ 2.9 s") && x.description.contains("rush")
    );
    assert_eq!(x.entities, ["vut", "bv1", "bv2"]);
    assert_eq!(x.trajectories.len(), 2);
    for (id, vertices) in &x.trajectories {
        let agent = prior.agents.iter().find(|a| &a.id == id).unwrap();
        assert_eq!(agent.role, AgentRole::Bv);
        let times: Vec<f64> = (0..agent.states.len()).map(|k| k as f64 * prior.dt_s).collect();
        vertices_match(vertices, &agent.states, &times);
    }
    for (id, pose, speed) in &x.init {
        let first = prior.agents.iter().find(|a| &a.id == id).unwrap().states[0];
        assert!(Point2 { x: pose.x, y: pose.y }.dist(Point2 { x: first.px, y: first.py }) < 0.01);
        assert!((speed - first.speed_mps).abs() < 1e-6);
    }
    assert_eq!(x.init.len(), 3);
    // The VUT's route is the path its states trace, from its start to its end.
    let vut = prior.agents.iter().find(|a| a.role == AgentRole::Vut).unwrap();
    let path: Vec<Point2> = vut.states.iter().map(|st| Point2 { x: st.px, y: st.py }).collect();
    assert!(x.waypoints.len() >= 2);
    for w in &x.waypoints {
        assert!(off_route(Point2 { x: w.x, y: w.y }, &path) < 0.01, "{w:?}");
    }
    let (first, last) = (x.waypoints[0], x.waypoints[x.waypoints.len() - 1]);
    assert!(Point2 { x: first.x, y: first.y }.dist(path[0]) < 0.01);
    assert!(Point2 { x: last.x, y: last.y }.dist(path[path.len() - 1]) < 0.01);
    assert!((x.stop_s - prior.duration_s()).abs() < 1e-6);
    map_resolves(&out, &x.map);
}

#[test]
fn grounded_scenarios_export_constant_speed_along_their_routes() {
    let dir_scratch = tempdir("grounded");
    let dir = dir_scratch.path();
    // The output in a subfolder: the map's path is written relative to it.
    std::fs::create_dir_all(dir.join("xosc")).unwrap();
    for which in ["left_turn", "cut_in"] {
        let (input, g) = grounded(dir, which);
        let out = dir.join("xosc").join(format!("{which}.xosc"));
        let x = read(&export(&input, &out));
        let ids: Vec<&str> = g.agents.iter().map(|a| a.id.as_str()).collect();
        assert_eq!(x.entities, ids);
        assert_eq!(x.trajectories.len(), g.bvs().count());
        for (id, vertices) in &x.trajectories {
            let agent = g.agents.iter().find(|a| &a.id == id).unwrap();
            assert_eq!(agent.role, AgentRole::Bv);
            for v in vertices {
                assert!(
                    off_route(Point2 { x: v.x, y: v.y }, &with_lead_in_and_out(agent)) < 0.01,
                    "{which} {id}: {v:?}"
                );
            }
            // Constant speed: the distance between vertices is the speed times the time between them.
            for w in vertices.windows(2) {
                let d = Point2 { x: w[0].x, y: w[0].y }.dist(Point2 { x: w[1].x, y: w[1].y });
                assert!(d <= agent.start.speed_mps * (w[1].t - w[0].t) + 0.01, "{which} {id}: {d} m");
            }
        }
        let vut = g.vut().unwrap();
        for w in &x.waypoints {
            assert!(off_route(Point2 { x: w.x, y: w.y }, &with_lead_in_and_out(vut)) < 0.01, "{which}: {w:?}");
        }
        let last = x.waypoints[x.waypoints.len() - 1];
        assert!(Point2 { x: last.x, y: last.y }.dist(vut.route[vut.route.len() - 1]) < 0.01);
        let (_, start, speed) = x.init.iter().find(|(id, _, _)| id == &vut.id).unwrap();
        assert!(off_route(Point2 { x: start.x, y: start.y }, &with_lead_in_and_out(vut)) < 0.01);
        assert!((speed - vut.start.speed_mps).abs() < 1e-6);
        assert!(x.description.contains("grounded scenario") && x.description.contains(&g.fragment_id));
        map_resolves(&out, &x.map);
    }
}

#[test]
fn a_simulated_run_exports_its_trace() {
    let dir_scratch = tempdir("run");
    let dir = dir_scratch.path();
    let run = dir.join("run.json");
    ok(&["sim", "config/scenarios/left_turn_basic.toml", "--json", s(&run)]);
    let v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&run).unwrap()).unwrap();
    let out = dir.join("run.xosc");
    let x = read(&export(&run, &out));
    let ids: Vec<String> = serde_json::from_value(v["agent_ids"].clone()).unwrap();
    assert_eq!(x.entities, ids);
    let trace = v["trace"].as_array().unwrap();
    let t0 = trace[0]["t_s"].as_f64().unwrap();
    let times: Vec<f64> = trace.iter().map(|k| k["t_s"].as_f64().unwrap() - t0).collect();
    let states = |i: usize| -> Vec<State> {
        trace.iter().map(|k| serde_json::from_value(k["agents"][i]["state"].clone()).unwrap()).collect()
    };
    // The trace holds the VUT first, then the BVs: every BV follows its trace.
    assert_eq!(x.trajectories.len(), ids.len() - 1);
    for (id, vertices) in &x.trajectories {
        let i = ids.iter().position(|a| a == id).unwrap();
        assert!(i > 0, "the VUT follows no trajectory");
        vertices_match(vertices, &states(i), &times);
    }
    let vut: Vec<Point2> = states(0).iter().map(|st| Point2 { x: st.px, y: st.py }).collect();
    for w in &x.waypoints {
        assert!(off_route(Point2 { x: w.x, y: w.y }, &vut) < 0.01, "{w:?}");
    }
    assert!((x.stop_s - times[times.len() - 1]).abs() < 1e-6);
    assert!(x.description.contains("simulated run") && x.description.contains("left_turn_basic"));
    map_resolves(&out, &x.map);
}

#[test]
fn names_are_escaped() {
    let dir_scratch = tempdir("escape");
    let dir = dir_scratch.path();
    let (_, g) = grounded(dir, "cut_in");
    let mut prior = TrajectoryPrior::along_routes_at_start_speed(&g, 5.0).unwrap();
    prior.fragment_id = "a<b & \"c\"".into();
    prior.agents[1].id = "bv<1>&'x'".into();
    let input = dir.join("odd.json");
    std::fs::write(&input, serde_json::to_string(&prior).unwrap()).unwrap();
    let x = read(&export(&input, &dir.join("odd.xosc")));
    assert!(x.entities.contains(&"bv<1>&'x'".to_owned()), "{:?}", x.entities);
    assert!(x.description.contains("a<b & \"c\""));
}

#[test]
fn bad_input_is_an_input_error_with_a_message() {
    let dir_scratch = tempdir("bad");
    let dir = dir_scratch.path();
    let (_, g) = grounded(dir, "left_turn");
    let prior = serde_json::to_string_pretty(&TrajectoryPrior::along_routes_at_start_speed(&g, 5.0).unwrap()).unwrap();
    let mut value: serde_json::Value = serde_json::from_str(&prior).unwrap();
    value["agents"] = serde_json::json!([]);
    let empty = serde_json::to_string(&value).unwrap();
    // A NaN is not JSON: put one where the first state's x is.
    let first_x =
        serde_json::to_string(&TrajectoryPrior::along_routes_at_start_speed(&g, 5.0).unwrap().agents[0].states[0].px)
            .unwrap();
    let nan = prior.replacen(&first_x, "NaN", 1);
    assert_ne!(nan, prior);
    let cases: [(&str, String, &str); 6] = [
        ("not_json.json", "this is not JSON".into(), "not JSON"),
        ("nan.json", nan, "not JSON"),
        ("empty.json", empty, "agents"),
        ("other.json", r#"{"name": "x"}"#.into(), "neither a trajectory prior"),
        (
            "empty_run.json",
            r#"{"result": {"scenario": "x", "vut_model": "idm-normal", "bv_controller": "reference", "seed": 1,
                "style": "rush", "tau_s": 2, "duration_s": 0, "completed": false, "conflicts": [], "pet_min_s": null,
                "min_distance_m": null, "min_distance_t_s": 0, "min_ttc_s": null, "collision": null,
                "zone_overlap": false}, "agent_ids": [], "trace": []}"#
                .into(),
            "agent_ids",
        ),
        (
            "partial_run.json",
            r#"{"result": {"scenario": "x", "tau_s": 2, "style": "rush"}, "agent_ids": [], "trace": []}"#.into(),
            "missing field `vut_model`",
        ),
    ];
    for (name, text, expect) in cases {
        let err = refused_export(dir, name, &text);
        assert!(err.contains(expect), "{name}: {err}");
    }
    // A missing input, a missing map and a bad vehicle file are input errors too.
    let good = dir.join("left_turn.json");
    let out = dir.join("x.xosc");
    for (args, expect) in [
        (vec!["export", "xosc", "no/such.json", "-o", s(&out)], "no/such.json"),
        (vec!["export", "xosc", s(&good), "-o", s(&out), "--map", "no/such.xodr"], "no/such.xodr"),
        (
            vec!["export", "xosc", s(&good), "-o", s(&out), "--bv-vehicle", "config/maps/proving_ground.xodr"],
            "proving_ground.xodr",
        ),
    ] {
        let o = video2track(&args);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(expect), "{err}");
    }
}

/// Motion that is not motion: a prior that reverses, one that stands while its speed says
/// 12.5 m/s, one that drives against its heading, two agents that start on each other, and a run
/// whose trace stands while its speed says it drives: each refused with exit 2, naming the file
/// and the field.
#[test]
fn motion_that_is_not_motion_is_refused_naming_the_field() {
    let dir_scratch = tempdir("motion");
    let dir = dir_scratch.path();
    let (_, g) = grounded(dir, "left_turn");
    let prior = TrajectoryPrior::along_routes_at_start_speed(&g, 5.0).unwrap();
    let edit = |f: &dyn Fn(&mut TrajectoryPrior)| {
        let mut p = prior.clone();
        f(&mut p);
        serde_json::to_string(&p).unwrap()
    };
    let reversing = edit(&|p| p.agents[1].states.iter_mut().for_each(|x| x.speed_mps = -x.speed_mps));
    let standing = edit(&|p| {
        let x0 = p.agents[1].states[0];
        p.agents[1].states.iter_mut().for_each(|x| *x = v2t_model::kinematics::State { speed_mps: 12.5, ..x0 });
    });
    let backwards = edit(&|p| p.agents[1].states.iter_mut().for_each(|x| x.theta_rad += std::f64::consts::PI));
    let on_each_other = edit(&|p| {
        let mut copy = p.agents[1].clone();
        copy.id = "bv2".into();
        p.agents.push(copy);
    });
    // A run of the shipped left turn, its VUT standing while its speed says it drives.
    let run = dir.join("run.json");
    ok(&["sim", "config/scenarios/left_turn_basic.toml", "--json", s(&run)]);
    let mut value: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&run).unwrap()).unwrap();
    let still = value["trace"][0]["agents"][0]["state"].clone();
    for sample in value["trace"].as_array_mut().unwrap() {
        sample["agents"][0]["state"] = still.clone();
    }
    let standing_run = serde_json::to_string(&value).unwrap();
    for (name, text, field) in [
        ("reversing.json", reversing, "agents[1].states[0].speed_mps"),
        ("standing.json", standing, "agents[1].states[10]"),
        ("backwards.json", backwards, "agents[1].states[10]"),
        ("on_each_other.json", on_each_other, "agents[1].states[0]"),
        ("standing_run.json", standing_run, "trace[10].agents[0].state"),
    ] {
        let err = refused_export(dir, name, &text);
        assert!(err.contains(&format!("`{field}`")), "{name}: {err}");
    }
}

/// `export xosc` of `text`, written to `dir/name`: exit 2, an error naming the file and no panic,
/// nothing written; returns the error.
fn refused_export(dir: &Path, name: &str, text: &str) -> String {
    let input = dir.join(name);
    std::fs::write(&input, text).unwrap();
    let out = dir.join("bad.xosc");
    let o = video2track(&["export", "xosc", s(&input), "-o", s(&out)]);
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert_eq!(o.status.code(), Some(2), "{name}: {err}");
    assert!(err.contains(name) && !err.contains("panicked"), "{name}: {err}");
    assert!(!out.exists(), "{name}: nothing written");
    err
}
