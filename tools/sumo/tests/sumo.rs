//! The client and the network reader against the real SUMO (1.28 in `target/sumo-venv`): the
//! proving ground converted with netconvert, paths matched on it, vehicles driven, teleported and
//! read back, runs reloaded. Without SUMO these tests fail with the install instructions, or, with
//! `V2T_ALLOW_MISSING_TOOLS=1`, report themselves as not run.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic, clippy::indexing_slicing)]

use std::f64::consts::FRAC_PI_2;
use std::path::{Path, PathBuf};
use std::time::Instant;

use v2t_sumo::{
    INSTALL_HINT, MoveToXy, Network, Reply, Request, StartOptions, Sumo, SumoBinaries, SumoError, VehicleVar,
    convert_map, write_additional,
};

/// SUMO's programs, or `None` when the test is to report itself as not run.
fn sumo_binaries() -> Option<SumoBinaries> {
    let found = SumoBinaries::find();
    let what = "SUMO (sumo, netconvert)";
    if let Err(e) = &found {
        eprintln!("{e}");
    }
    v2t_test_support::found_or_not_run(found.is_ok(), what, INSTALL_HINT).then(|| found.unwrap())
}

/// The proving ground converted into `dir`.
fn proving_ground(bins: &SumoBinaries, dir: &Path) -> PathBuf {
    let xodr = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config/maps/proving_ground.xodr");
    let net = dir.join("proving_ground.net.xml");
    convert_map(bins, &xodr, &net).unwrap();
    net
}

/// Samples every metre along straight segments and circular arcs: `[x, y, heading]`.
struct PathBuilder {
    points: Vec<[f64; 3]>,
}

impl PathBuilder {
    fn straight(mut self, from: [f64; 2], to: [f64; 2]) -> Self {
        let (dx, dy) = (to[0] - from[0], to[1] - from[1]);
        let len = dx.hypot(dy);
        let heading = dy.atan2(dx);
        let n = len.round() as usize;
        for i in 0..=n {
            let t = i as f64 / n as f64;
            self.points.push([from[0] + t * dx, from[1] + t * dy, heading]);
        }
        self
    }

    /// An arc around `centre` from angle `a0` to `a1` (radians, counter-clockwise when a1 > a0).
    fn arc(mut self, centre: [f64; 2], radius: f64, a0: f64, a1: f64) -> Self {
        let n = (radius * (a1 - a0).abs()).round() as usize;
        let turn = if a1 > a0 { FRAC_PI_2 } else { -FRAC_PI_2 };
        for i in 1..n {
            let a = a0 + (a1 - a0) * i as f64 / n as f64;
            self.points.push([centre[0] + radius * a.cos(), centre[1] + radius * a.sin(), a + turn]);
        }
        self
    }
}

fn path() -> PathBuilder {
    PathBuilder { points: Vec::new() }
}

#[test]
fn the_proving_ground_converts_and_its_paths_match_lanes() {
    let Some(bins) = sumo_binaries() else { return };
    eprintln!("{}", bins.version().unwrap());
    let dir = tempfile::tempdir().unwrap();
    let net = Network::read(&proving_ground(&bins, dir.path())).unwrap();

    let j100 = net.junction("100").unwrap();
    eprintln!("junction 100 internal lanes (id, OpenDRIVE lane, speed m/s, length m):");
    for id in &j100.internal_lanes {
        let l = net.lane(id).unwrap();
        eprintln!("  {id:10} {:8} {:6.2} {:6.2}", l.orig_id.as_deref().unwrap_or("-"), l.speed_mps, l.length_m);
    }
    assert_eq!(j100.internal_lanes.len(), 16);
    assert_eq!(net.lane(":100_9_1").unwrap().orig_id.as_deref(), Some("110_-1"));
    assert_eq!(net.lane(":100_11_0").unwrap().orig_id.as_deref(), Some("111_-1"));
    assert_eq!(net.lane(":100_17_0").unwrap().orig_id.as_deref(), Some("111_-1"));
    let b = net.bounds();
    eprintln!("bounds {:?} .. {:?}", b.min, b.max);
    assert!(b.min[0] < -1100.0 && b.max[0] > 495.0 && b.min[1] < -495.0 && b.max[1] > 495.0);

    // The south arm's inner northbound lane.
    let on = net.nearest_lane(1.75, -60.0, FRAC_PI_2, 2.0).unwrap();
    assert_eq!(on.lane_id, "2_1");
    let lane = net.lane("2_1").unwrap();
    assert!((on.s_m - (lane.shape[0][1] - -60.0).abs()).abs() < 1e-6 && on.lateral_m.abs() < 1e-6, "{on:?}");
    assert!(net.nearest_lane(1.75, -60.0, -FRAC_PI_2, 2.0).is_none(), "no southbound lane there");

    // Straight north through junction 100.
    let straight = path().straight([1.75, -70.0], [1.75, 80.0]).points;
    let route = net.match_route(&straight, 1.0).unwrap();
    assert_eq!(route.lanes, ["2_1", ":100_9_1", "1#1_1"]);
    assert_eq!(route.edges, ["2", "1#1"]);
    assert_eq!(route.depart_lane, 1);
    assert!((route.depart_pos_m - 36.0).abs() < 0.01, "{}", route.depart_pos_m);
    // 55 m along 1#1_1's shape; SUMO's lane positions scale with the edge's length (886.82 m),
    // which on this curved edge differs from the inner lane's shape (890.95 m).
    let arrival = net.lane("1#1_1").unwrap().lane_pos(55.0);
    eprintln!("straight: arrival at 55 m of shape = lane position {arrival:.3} m");
    assert!((arrival - 54.745).abs() < 0.01, "{arrival}");
    assert!((route.arrival_pos_m - arrival).abs() < 0.01, "{}", route.arrival_pos_m);
    let (first, last) = (route.shape[0], *route.shape.last().unwrap());
    assert!((first[0] - 1.75).abs() < 0.01 && (first[1] + 70.0).abs() < 0.01, "{first:?}");
    assert!((last[0] - 1.75).abs() < 0.01 && (last[1] - 80.0).abs() < 0.01, "{last:?}");

    // Left from the south arm into the west arm's inner westbound lane (y = +1.75): a quarter
    // circle between the arms' ends; the junction lane (spiral, arc, spiral) bulges out of it.
    let r = 26.75;
    let left = path()
        .straight([1.75, -70.0], [1.75, -25.0])
        .arc([-25.0, -25.0], r, 0.0, FRAC_PI_2)
        .straight([-25.0, 1.75], [-80.0, 1.75])
        .points;
    let worst = left
        .iter()
        .map(|p| net.nearest_lane(p[0], p[1], p[2], 5.0).map_or(f64::INFINITY, |l| l.lateral_m.abs()))
        .fold(0.0, f64::max);
    eprintln!("left turn: the circular path is at most {worst:.2} m from the junction lanes");
    let route = net.match_route(&left, 2.5).unwrap();
    assert_eq!(route.lanes, ["2_1", ":100_11_0", ":100_17_0", "6_1"]);
    assert_eq!(route.edges, ["2", "6"]);
    assert_eq!((route.depart_lane, route.arrival_lane), (1, 1));

    // The same left turn bent 20 m out of the way is named at its first stray sample.
    let mut stray = left.clone();
    let k = stray.iter().position(|p| p[1] > -15.0).unwrap();
    stray[k][0] -= 20.0;
    match net.match_route(&stray, 2.5) {
        Err(SumoError::RouteMatch { index, nearest_lane, distance_m, .. }) => {
            assert_eq!(index, k);
            eprintln!("stray sample {index}: nearest lane {nearest_lane} at {distance_m:.2} m");
        }
        other => panic!("{other:?}"),
    }
    let against = path().straight([1.75, 80.0], [1.75, -70.0]).points;
    assert!(matches!(net.match_route(&against, 1.0), Err(SumoError::RouteMatch { index: 0, .. })));
}

fn near(a: [f64; 2], b: [f64; 2], tol: f64) -> bool {
    (a[0] - b[0]).hypot(a[1] - b[1]) <= tol
}

#[test]
fn sumo_drives_teleports_reloads_and_closes() {
    let Some(bins) = sumo_binaries() else { return };
    let dir = tempfile::tempdir().unwrap();
    let net = proving_ground(&bins, dir.path());
    let types = dir.path().join("types.add.xml");
    let bv_type = vec![("length".to_owned(), "4.5".to_owned()), ("maxSpeed".to_owned(), "30".to_owned())];
    write_additional(&types, &[("bv".to_owned(), bv_type)]).unwrap();
    let opts = StartOptions { net, additional: vec![types], step_length_s: 0.1, seed: 1, extra_args: Vec::new() };
    let mut sumo = Sumo::start(&bins, &opts).unwrap();
    eprintln!("TraCI API version {} ({}), port {}", sumo.api_version(), sumo.identifier(), sumo.port());
    assert!(sumo.api_version() >= 21);
    assert_eq!(sumo.time_s().unwrap(), 0.0);

    // The VUT: departPos `base` puts its rear at the lane's start (plus SUMO's POSITION_EPS,
    // 0.1 m), so its front (SUMO's position) is one vehicle length (5 m for DEFAULT_VEHTYPE)
    // and 0.1 m up the lane.
    let north = ["2".to_owned(), "1#1".to_owned()];
    sumo.add_route("north", &north).unwrap();
    sumo.add_vehicle("vut", "north", "DEFAULT_VEHTYPE", "now", "1", "base", "0").unwrap();
    sumo.step().unwrap();
    assert!((sumo.time_s().unwrap() - 0.1).abs() < 1e-9);
    assert_eq!(sumo.vehicle_ids().unwrap(), ["vut"]);
    assert_eq!(sumo.lane_id("vut").unwrap(), "2_1");
    let start = sumo.position("vut").unwrap();
    let s0 = sumo.lane_position("vut").unwrap();
    eprintln!("inserted at {start:?}, lane position {s0:.3} m");
    assert!((s0 - 5.1).abs() < 1e-6, "the front bumper is 5.1 m up the lane: {s0}");
    assert!(near(start, [1.75, -106.0 + s0], 0.01), "{start:?}");

    for _ in 0..50 {
        sumo.step().unwrap();
    }
    let p = sumo.position("vut").unwrap();
    let (speed, accel, angle) =
        (sumo.speed("vut").unwrap(), sumo.acceleration("vut").unwrap(), sumo.angle_deg("vut").unwrap());
    let (lane, road) = (sumo.lane_id("vut").unwrap(), sumo.road_id("vut").unwrap());
    eprintln!("after 5 s: {p:?} on {lane} ({road}), {speed:.2} m/s, {accel:.2} m/s², angle {angle:.1}°");
    assert!((p[0] - 1.75).abs() < 0.01 && p[1] - start[1] > 10.0, "{p:?}");
    assert!(speed > 5.0 && speed < 16.0, "{speed}");
    assert!(angle.abs() < 1.0 || (angle - 360.0).abs() < 1.0, "northbound is 0°: {angle}");
    assert_eq!(lane, "2_1");
    assert_eq!(road, "2");

    let (front, angle_now, speed_now) = sumo.vehicle_pose("vut").unwrap();
    assert_eq!((front, angle_now, speed_now), (p, angle, speed));

    // A speed cap: SUMO's driver brakes down to it (4.5 m/s² at most for DEFAULT_VEHTYPE).
    sumo.set_max_speed("vut", 3.0).unwrap();
    for _ in 0..30 {
        sumo.step().unwrap();
    }
    let capped = sumo.speed("vut").unwrap();
    eprintln!("after setMaxSpeed 3 and 3 s: {capped:.2} m/s");
    assert!(capped <= 3.0 + 1e-9 && capped > 2.0, "{capped}");

    // A refused command names itself and leaves the connection usable.
    match sumo.speed("ghost") {
        Err(SumoError::Command { command, message }) => {
            eprintln!("refused {command}: {message}");
            assert!(command.contains("ghost"));
        }
        other => panic!("{other:?}"),
    }
    assert!(sumo.time_s().unwrap() > 5.0);

    // The BV, teleported: the point given is its front bumper.
    sumo.add_vehicle("bv", "north", "bv", "now", "0", "base", "0").unwrap();
    sumo.step().unwrap();
    sumo.set_speed_mode("bv", 0).unwrap();
    sumo.set_lane_change_mode("bv", 0).unwrap();
    let before = sumo.position("bv").unwrap();
    let to = |x: f64, y: f64, angle_deg: f64, keep_route: u8| MoveToXy {
        vehicle: "bv",
        edge: "",
        lane: -1,
        x,
        y,
        angle_deg,
        keep_route,
    };
    sumo.move_to_xy("bv", "", -1, 5.25, -50.0, 0.0, 1).unwrap();
    let pending = sumo.position("bv").unwrap();
    assert_eq!(pending, before, "moveToXY takes effect in the next step");
    sumo.step().unwrap();
    let moved = sumo.position("bv").unwrap();
    let s = sumo.lane_position("bv").unwrap();
    eprintln!("moveToXY (5.25, -50) keepRoute 1 → {moved:?}, lane {} at {s:.3} m", sumo.lane_id("bv").unwrap());
    assert!(near(moved, [5.25, -50.0], 0.1), "{moved:?}");
    assert!((s - 56.0).abs() < 0.1, "the front bumper is 56 m up lane 2_0: {s}");

    // Off to the side of its lane with keepRoute 1: mapped onto the route's lane centre.
    sumo.move_to_xy("bv", "2", 0, 7.25, -45.0, 0.0, 1).unwrap();
    sumo.step().unwrap();
    let off = sumo.position("bv").unwrap();
    eprintln!("moveToXY (7.25, -45) keepRoute 1 → {off:?} on {}", sumo.lane_id("bv").unwrap());
    assert!(near(off, [5.25, -45.0], 0.1), "{off:?}");

    // The per-step exchange of the proving ground: move the BV, read the VUT, step. keepRoute 1
    // (the BV on a route of its own) is cheap for SUMO; keepRoute 0 and 2 search the whole
    // network for the point every step.
    let reads =
        [VehicleVar::Position, VehicleVar::Angle, VehicleVar::Speed, VehicleVar::LaneId, VehicleVar::LanePosition];
    let mut replies = Vec::new();
    for (keep_route, x, y0) in [(1, 5.25, -40.0), (2, 30.0, -100.0)] {
        let (mut batch_s, mut step_s, mut worst_xy) = (0.0, 0.0, 0.0_f64);
        let steps = 150;
        for k in 0..steps {
            let y = y0 + f64::from(k) * 0.5;
            let mut requests = vec![Request::MoveToXy(to(x, y, 0.0, keep_route))];
            requests.extend(reads.map(|var| Request::Vehicle { vehicle: "vut", var }));
            requests.push(Request::Vehicle { vehicle: "bv", var: VehicleVar::Position });
            let t0 = Instant::now();
            sumo.batch(&requests, &mut replies).unwrap();
            let t1 = Instant::now();
            sumo.step().unwrap();
            batch_s += (t1 - t0).as_secs_f64();
            step_s += t1.elapsed().as_secs_f64();
            assert_eq!(replies.len(), requests.len());
            assert_eq!(replies[0], Reply::Done);
            assert!(matches!(replies[4], Reply::Text(ref lane) if !lane.is_empty()));
            if k > 0 {
                // The BV's position, read before this step's move, is where the last move put it.
                let p = replies[6].position().unwrap();
                worst_xy = worst_xy.max((p[0] - x).hypot(p[1] - (y - 0.5)));
            }
        }
        let per = |t: f64| t / f64::from(steps) * 1e3;
        eprintln!(
            "keepRoute {keep_route}, {steps} steps: batch (moveToXY + 6 gets) {:.3} ms, step {:.3} ms, \
             total {:.3} ms per step; BV at most {worst_xy:.3} m off its points, now {:.2} m/s at {:.1}°",
            per(batch_s),
            per(step_s),
            per(batch_s + step_s),
            sumo.speed("bv").unwrap(),
            sumo.angle_deg("bv").unwrap(),
        );
        assert!(worst_xy < 0.1, "{worst_xy}");
    }
    let free = sumo.position("bv").unwrap();
    eprintln!("keepRoute 2 off every lane → {free:?} on '{}'", sumo.lane_id("bv").unwrap());

    // keepRoute 0: any lane of the network; the route becomes that edge.
    sumo.move_to_xy("bv", "", -1, -100.0, 1.75, 270.0, 0).unwrap();
    sumo.step().unwrap();
    let other = sumo.position("bv").unwrap();
    let road = sumo.road_id("bv").unwrap();
    eprintln!("moveToXY (-100, 1.75) keepRoute 0 → {other:?} on {road}");
    assert!(near(other, [-100.0, 1.75], 0.1) && road == "6", "{other:?} {road}");

    // Reload twice in the same process.
    for run in 0..2 {
        sumo.load(&opts).unwrap();
        assert_eq!(sumo.time_s().unwrap(), 0.0, "run {run}");
        assert!(sumo.vehicle_ids().unwrap().is_empty(), "run {run}");
        sumo.add_route("north", &north).unwrap();
        sumo.add_vehicle("vut", "north", "DEFAULT_VEHTYPE", "now", "1", "base", "0").unwrap();
        sumo.step().unwrap();
        assert_eq!(sumo.vehicle_ids().unwrap(), ["vut"], "run {run}");
        assert!((sumo.lane_position("vut").unwrap() - 5.1).abs() < 1e-6, "run {run}");
    }
    sumo.close().unwrap();
}

#[test]
fn a_sumo_that_cannot_start_reports_its_own_error() {
    let Some(bins) = sumo_binaries() else { return };
    let opts = StartOptions {
        net: PathBuf::from("/nonexistent/v2t.net.xml"),
        additional: Vec::new(),
        step_length_s: 0.1,
        seed: 0,
        extra_args: Vec::new(),
    };
    match Sumo::start(&bins, &opts) {
        Err(e @ SumoError::Connect { .. }) => {
            let text = e.to_string();
            eprintln!("{text}");
            assert!(text.contains("exited") && text.contains("v2t.net.xml"), "{text}");
        }
        other => panic!("{other:?}"),
    }
}
