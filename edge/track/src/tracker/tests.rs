use proptest::prelude::*;
use v2t_model::path::PathBuilder;
use v2t_model::vehicle::{ActuatorResponse, LocalizationNoise, NoiseModel, VehicleGeometry, VehicleLimits};

use super::*;

const DEFAULT_TOML: &str = include_str!("../../../../config/track/default.toml");

fn bv() -> VehicleConfig {
    VehicleConfig {
        name: "bv".into(),
        geometry: VehicleGeometry { length_m: 4.8, width_m: 1.85, wheelbase_m: 2.85, center_to_rear_axle_m: 1.45 },
        limits: VehicleLimits {
            max_speed_mps: 22.0,
            max_accel_mps2: 3.0,
            max_decel_mps2: 6.0,
            max_jerk_mps3: 8.0,
            max_steer_rad: 0.55,
            max_steer_rate_radps: 0.6,
            max_lat_accel_mps2: 4.5,
        },
        actuator: ActuatorResponse { accel_time_constant_s: 0.35, steer_time_constant_s: 0.12, delay_s: 0.08 },
        localization: LocalizationNoise {
            model: NoiseModel::Gaussian,
            position_std_m: 0.0,
            heading_std_rad: 0.0,
            speed_std_mps: 0.0,
            correlation_time_s: 0.0,
            delay_s: 0.0,
        },
    }
}

fn east() -> ReferencePath {
    PathBuilder::new(0.0, 0.0, 0.0).line(200.0).build(0.5).unwrap()
}

fn tracker() -> Tracker {
    Tracker::try_new(TrackerConfig::default(), &bv()).unwrap()
}

fn at(x: f64, y: f64, theta: f64, v: f64) -> State {
    State { px: x, py: y, theta_rad: theta, speed_mps: v }
}

fn plan(s: f64, v: f64) -> PlanSample {
    PlanSample { s_m: s, v_mps: v, a_mps2: 0.0 }
}

#[test]
fn the_default_file_is_the_default_configuration() {
    let parsed: TrackerConfig = toml::from_str(DEFAULT_TOML).unwrap();
    parsed.validate().unwrap();
    assert_eq!(parsed, TrackerConfig::default());
}

#[test]
fn unknown_and_out_of_range_fields_are_refused_by_name() {
    let typo = DEFAULT_TOML.replace("kp_1ps", "kp");
    assert!(toml::from_str::<TrackerConfig>(&typo).unwrap_err().to_string().contains("kp"));
    let mut c = TrackerConfig::default();
    c.lateral.cross_track_gain_1ps = f64::NAN;
    assert_eq!(c.validate().unwrap_err().field, "lateral.cross_track_gain_1ps");
    let c = TrackerConfig { accel_latency_s: -0.1, ..TrackerConfig::default() };
    assert_eq!(c.validate().unwrap_err().field, "accel_latency_s");
    let mut c = TrackerConfig::default();
    c.longitudinal.max_station_error_m = f64::INFINITY;
    assert_eq!(c.validate().unwrap_err().field, "longitudinal.max_station_error_m");
}

#[test]
fn an_invalid_configuration_or_vehicle_never_drives() {
    let c = TrackerConfig { max_dt_s: 0.0, ..TrackerConfig::default() };
    assert!(matches!(Tracker::try_new(c.clone(), &bv()), Err(TrackError::Config(e)) if e.field == "max_dt_s"));
    let mut t = Tracker::new(c, &bv());
    assert!(matches!(t.step(&at(0.0, 0.0, 0.0, 5.0), &east(), &plan(0.0, 5.0), 0.1), Err(TrackError::Config(_))));
    let mut v = bv();
    v.limits.max_steer_rad = f64::NAN;
    let err = Tracker::try_new(TrackerConfig::default(), &v).unwrap_err();
    assert!(err.to_string().contains("vehicle.limits.max_steer_rad"), "{err}");
}

#[test]
fn on_the_path_and_on_the_plan_nothing_is_corrected() {
    let mut t = tracker();
    for k in 0..20 {
        let s = 10.0 + k as f64;
        let out = t.step(&at(s, 0.0, 0.0, 10.0), &east(), &plan(s, 10.0), 0.1).unwrap();
        assert_eq!(out.steer_rad, 0.0);
        assert!(out.accel_mps2.abs() < 1e-9, "{out:?}");
        assert!(out.cross_track_m.abs() < 1e-9 && out.station_error_m.abs() < 1e-9);
        assert!((out.s_m - s).abs() < 1e-9 && t.station_m() == Some(out.s_m), "{out:?}");
    }
}

#[test]
fn stanley_signs_through_the_whole_tracker() {
    // Left of the path: steer right. Right of it: steer left.
    let mut t = tracker();
    let out = t.step(&at(10.0, 0.5, 0.0, 10.0), &east(), &plan(10.0, 10.0), 0.1).unwrap();
    assert!(out.steer_rad < 0.0 && out.cross_track_m > 0.0, "{out:?}");
    let mut t = tracker();
    let out = t.step(&at(10.0, -0.5, 0.0, 10.0), &east(), &plan(10.0, 10.0), 0.1).unwrap();
    assert!(out.steer_rad > 0.0 && out.cross_track_m < 0.0, "{out:?}");
    // Pointing left of the path: steer right.
    let mut t = tracker();
    let out = t.step(&at(10.0, 0.0, 0.05, 10.0), &east(), &plan(10.0, 10.0), 0.1).unwrap();
    assert!(out.steer_rad < 0.0 && out.heading_error_rad > 0.0, "{out:?}");
    // The same on a path heading west (the sign follows the path's direction, not the frame's).
    let west = PathBuilder::new(0.0, 0.0, std::f64::consts::PI).line(100.0).build(0.5).unwrap();
    let mut t = tracker();
    let out = t.step(&at(-10.0, -0.5, std::f64::consts::PI, 10.0), &west, &plan(10.0, 10.0), 0.1).unwrap();
    assert!(out.cross_track_m > 0.0 && out.steer_rad < 0.0, "left of a westbound path is south: {out:?}");
}

#[test]
fn behind_the_plan_or_too_slow_accelerates_and_ahead_brakes() {
    let mut t = tracker();
    let out = t.step(&at(10.0, 0.0, 0.0, 8.0), &east(), &plan(12.0, 10.0), 0.1).unwrap();
    assert!(out.accel_mps2 > 0.0 && out.speed_error_mps > 0.0 && out.station_error_m > 0.0, "{out:?}");
    let mut t = tracker();
    let out = t.step(&at(10.0, 0.0, 0.0, 12.0), &east(), &plan(8.0, 10.0), 0.1).unwrap();
    assert!(out.accel_mps2 < 0.0, "{out:?}");
}

#[test]
fn the_plan_is_extrapolated_over_the_latency_and_a_braking_plan_stops() {
    let p = PlanSample { s_m: 10.0, v_mps: 4.0, a_mps2: 1.0 }.advanced(0.5);
    assert!((p.s_m - 12.125).abs() < 1e-12 && (p.v_mps - 4.5).abs() < 1e-12 && p.a_mps2 == 1.0);
    let p = PlanSample { s_m: 10.0, v_mps: 1.0, a_mps2: -2.0 }.advanced(1.0);
    assert!((p.s_m - 10.25).abs() < 1e-12 && p.v_mps == 0.0 && p.a_mps2 == 0.0, "{p:?}");
}

#[test]
fn the_projection_stays_on_its_branch_of_a_hairpin() {
    // East 40 m, a U-turn of radius 2 m, back west 4 m to the north: the two legs are 4 m apart.
    let hairpin =
        PathBuilder::new(0.0, 0.0, 0.0).line(40.0).arc(2.0, std::f64::consts::PI).line(40.0).build(0.1).unwrap();
    // 2.5 m off is beyond the default refusal distance; the projection is what is tested here.
    let mut t = Tracker::try_new(TrackerConfig { max_cross_track_m: 3.0, ..TrackerConfig::default() }, &bv()).unwrap();
    // The BV has drifted 2.5 m left of the first leg: nearer the return leg, but it is on the first.
    let mut out = t.step(&at(10.0, 0.0, 0.0, 5.0), &hairpin, &plan(10.0, 5.0), 0.1).unwrap();
    for k in 1..=5 {
        let x = 10.0 + 0.5 * k as f64;
        out = t.step(&at(x, 0.5 * k as f64, 0.0, 5.0), &hairpin, &plan(x, 5.0), 0.1).unwrap();
    }
    assert!(out.cross_track_m > 2.0, "still measured from the first leg: {out:?}");
    assert!(out.steer_rad < 0.0, "steers back right, toward the first leg");
    assert!(t.station_m().unwrap() < 20.0);
    // After a reset, on a fresh plan along the return leg, the same point belongs to it.
    t.reset();
    let back = t.step(&at(12.5, 2.5, std::f64::consts::PI, 5.0), &hairpin, &plan(40.0 + 6.3 + 27.5, 5.0), 0.1).unwrap();
    assert!(back.cross_track_m.abs() < 2.0 && t.station_m().unwrap() > 60.0, "{back:?}");
}

#[test]
fn refused_cycles_leave_the_tracker_unchanged() {
    let mut t = tracker();
    t.step(&at(10.0, 0.3, 0.0, 9.0), &east(), &plan(11.0, 10.0), 0.1).unwrap();
    let (pid, stanley, s) = (*t.longitudinal(), *t.lateral(), t.station_m());
    for dt in [0.0, -0.1, f64::NAN, 0.6] {
        assert!(matches!(
            t.step(&at(11.0, 0.3, 0.0, 9.0), &east(), &plan(12.0, 10.0), dt),
            Err(TrackError::TimeStep { .. })
        ));
    }
    let nan = [
        at(f64::NAN, 0.0, 0.0, 9.0),
        at(11.0, f64::INFINITY, 0.0, 9.0),
        at(11.0, 0.0, f64::NAN, 9.0),
        at(11.0, 0.0, 0.0, f64::NEG_INFINITY),
    ];
    for st in nan {
        assert!(matches!(t.step(&st, &east(), &plan(12.0, 10.0), 0.1), Err(TrackError::NotFinite { .. })));
    }
    let bad_plan = PlanSample { a_mps2: f64::NAN, ..plan(12.0, 10.0) };
    let err = t.step(&at(11.0, 0.3, 0.0, 9.0), &east(), &bad_plan, 0.1).unwrap_err();
    assert_eq!(err.to_string(), "`plan.a_mps2` must be a finite number, got NaN");
    assert_eq!((*t.longitudinal(), *t.lateral(), t.station_m()), (pid, stanley, s));
}

#[test]
fn a_kinematic_closed_loop_converges_onto_a_curved_path() {
    // The tracker's own prediction model as the plant, without lag: from 1 m off, the BV settles
    // onto a line-arc-line path, and once the arc's entry transient has decayed its centre is on
    // the arc (without the front-axle offset it would sit 0.12 m inside).
    let path = PathBuilder::new(0.0, 0.0, 0.0)
        .line(30.0)
        .arc(25.0, std::f64::consts::FRAC_PI_2)
        .line(40.0)
        .build(0.5)
        .unwrap();
    let config = TrackerConfig { steer_latency_s: 0.0, ..TrackerConfig::default() };
    let mut t = Tracker::try_new(config, &bv()).unwrap();
    let model = *t.lateral().model();
    let mut x = at(0.0, 1.0, 0.0, 10.0);
    let mut worst_on_arc: f64 = 0.0;
    for k in 0..100 {
        let time = k as f64 * 0.1;
        let out = t.step(&x, &path, &plan(10.0 * time, 10.0), 0.1).unwrap();
        let s = t.station_m().unwrap();
        if s > 55.0 && s < 65.0 {
            worst_on_arc = worst_on_arc.max(out.cross_track_m.abs());
        }
        for _ in 0..10 {
            x = crate::latency::drive(x, out.steer_rad, 0.01, &model);
        }
    }
    assert!(worst_on_arc < 0.02, "centre off the arc by {worst_on_arc} m in the steady turn");
}

fn finite() -> impl Strategy<Value = f64> {
    any::<f64>().prop_filter("finite", |x| x.is_finite())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn requests_stay_finite_and_inside_the_limits(
        cycles in prop::collection::vec(
            ((-300.0f64..300.0, -50.0f64..50.0, -10.0f64..10.0, -5.0f64..40.0),
             (-100.0f64..400.0, -5.0f64..40.0, -20.0f64..20.0, 0.001f64..0.5)),
            1..30),
    ) {
        let path = PathBuilder::new(0.0, 0.0, 0.0).line(50.0).arc(20.0, 2.0).line(50.0).build(0.5).unwrap();
        // Arbitrary states, however far from the path (the cross-track refusal has its own test).
        let config = TrackerConfig { max_cross_track_m: 1.0e6, ..TrackerConfig::default() };
        let mut t = Tracker::try_new(config, &bv()).unwrap();
        let (mut prev_a, mut prev_d) = (0.0, 0.0);
        for ((x, y, th, v), (s, vr, ar, dt)) in cycles {
            let out = t.step(&at(x, y, th, v), &path, &PlanSample { s_m: s, v_mps: vr, a_mps2: ar }, dt).unwrap();
            prop_assert!(out.accel_mps2.is_finite() && out.steer_rad.is_finite());
            prop_assert!(out.accel_mps2 >= -6.0 && out.accel_mps2 <= 3.0);
            prop_assert!(out.steer_rad.abs() <= 0.55);
            prop_assert!((out.accel_mps2 - prev_a).abs() <= 8.0 * dt + 1e-9);
            prop_assert!((out.steer_rad - prev_d).abs() <= 0.6 * dt + 1e-9);
            prop_assert!(out.cross_track_m.is_finite() && out.heading_error_rad.is_finite());
            prop_assert!(out.station_error_m.is_finite() && out.speed_error_mps.is_finite() && out.s_m.is_finite());
            prev_a = out.accel_mps2;
            prev_d = out.steer_rad;
        }
    }

    #[test]
    fn any_finite_input_gives_a_request_inside_the_limits_or_an_error(
        x in finite(), y in finite(), th in finite(), v in finite(),
        s in finite(), vr in finite(), ar in finite(), dt in finite(),
    ) {
        let mut t = tracker();
        match t.step(&at(x, y, th, v), &east(), &PlanSample { s_m: s, v_mps: vr, a_mps2: ar }, dt) {
            Ok(out) => {
                prop_assert!(out.accel_mps2.is_finite() && out.steer_rad.is_finite());
                prop_assert!(out.accel_mps2 >= -6.0 && out.accel_mps2 <= 3.0);
                prop_assert!(out.steer_rad.abs() <= 0.55);
            }
            Err(TrackError::TimeStep { .. }) => prop_assert!(!(dt > 0.0 && dt <= 0.5)),
            Err(TrackError::OffPath { .. }) => {}
            Err(TrackError::Implausible { value, bound, .. }) => prop_assert!(value.abs() > bound),
            Err(TrackError::FarFromPath { cross_track_m, limit_m }) => prop_assert!(cross_track_m.abs() > limit_m),
            Err(e) => prop_assert!(false, "unexpected error {e}"),
        }
    }

    #[test]
    fn a_nan_anywhere_is_an_error(which in 0usize..7, v in -20.0f64..20.0) {
        let mut t = tracker();
        let mut input = [10.0, 0.2, 0.0, v, 10.0, 10.0, 0.0];
        input[which] = f64::NAN;
        let [x, y, th, sp, s, vr, ar] = input;
        let r = t.step(&at(x, y, th, sp), &east(), &PlanSample { s_m: s, v_mps: vr, a_mps2: ar }, 0.1);
        prop_assert!(matches!(r, Err(TrackError::NotFinite { .. })), "{r:?}");
    }
}

#[test]
fn implausible_speeds_and_plans_are_refused_by_name() {
    // Found by the property test above: a measured speed of −1.1e308 m/s overflowed the station
    // estimate to −∞ inside the speed controller.
    let mut t = tracker();
    let plan = PlanSample { s_m: 0.0, v_mps: 0.0, a_mps2: 0.0 };
    let e = t.step(&at(0.0, 0.0, 0.0, -1.1375287301691592e308), &east(), &plan, 3.5e-6).unwrap_err();
    assert!(matches!(e, TrackError::Implausible { field: "state.speed_mps", .. }), "{e}");
    for (plan, field) in [
        (PlanSample { s_m: 2.0e6, v_mps: 10.0, a_mps2: 0.0 }, "plan.s_m"),
        (PlanSample { s_m: 0.0, v_mps: 200.0, a_mps2: 0.0 }, "plan.v_mps"),
        (PlanSample { s_m: 0.0, v_mps: 10.0, a_mps2: -80.0 }, "plan.a_mps2"),
    ] {
        let e = t.step(&at(0.0, 0.0, 0.0, 10.0), &east(), &plan, 0.01).unwrap_err();
        assert!(matches!(e, TrackError::Implausible { field: f, .. } if f == field), "{e}");
        assert!(e.to_string().contains(field), "{e}");
    }
    // Plausible values still track.
    assert!(
        t.step(&at(0.0, 0.0, 0.0, 10.0), &east(), &PlanSample { s_m: 0.0, v_mps: 10.0, a_mps2: 0.0 }, 0.01).is_ok()
    );
}

#[test]
fn a_vehicle_far_from_its_path_is_refused_and_taken_back_when_it_returns() {
    let mut t = tracker();
    let plan = PlanSample { s_m: 10.0, v_mps: 10.0, a_mps2: 0.0 };
    assert!(t.step(&at(10.0, 1.9, 0.0, 10.0), &east(), &plan, 0.1).is_ok());
    let e = t.step(&at(10.5, 2.6, 0.0, 10.0), &east(), &plan, 0.1).unwrap_err();
    assert!(matches!(e, TrackError::FarFromPath { limit_m: 2.0, .. }), "{e}");
    assert!(e.to_string().contains("2.60 m from its path"), "{e}");
    let e = t.step(&at(11.0, -3.0, 0.0, 10.0), &east(), &plan, 0.1).unwrap_err();
    assert!(matches!(e, TrackError::FarFromPath { cross_track_m, .. } if cross_track_m < -2.0), "{e}");
    assert!(t.step(&at(11.5, 0.5, 0.0, 10.0), &east(), &plan, 0.1).is_ok());
}
