use super::*;

/// A case: the expected reason and the input that causes it at a given time.
type Case = (GateReason, Box<dyn Fn(f64) -> GateInput>);

fn vehicle() -> VehicleConfig {
    toml::from_str(include_str!("../../../config/vehicles/bv_sedan.toml")).unwrap()
}

fn config() -> GateConfig {
    toml::from_str(include_str!("../../../config/can/gate.toml")).unwrap()
}

fn input(now: f64, accel: f64, steer: f64, request: Option<Request>) -> GateInput {
    GateInput {
        command: Some(Command { accel_mps2: accel, steer_rad: steer, stamp_s: now }),
        request,
        speed_mps: 5.0,
        dbw_mode: dbw_mode::AUTO,
        feedback_stamp_s: Some(now),
    }
}

fn engaged() -> (SafetyGate, f64) {
    let mut g = SafetyGate::try_new(config(), &vehicle()).unwrap();
    g.step(0.0, &input(0.0, 0.0, 0.0, None));
    let out = g.step(0.01, &input(0.01, 0.0, 0.0, Some(Request::Engage)));
    assert_eq!((out.state, out.reason), (GateState::Engaged, GateReason::EngageRequest));
    (g, 0.01)
}

#[test]
fn the_shipped_config_validates_against_the_shipped_vehicle() {
    config().validate_for(&vehicle()).unwrap();
}

#[test]
fn config_errors_name_the_field_and_nan_fails() {
    let mut c = config();
    c.command_timeout_s = f64::NAN;
    assert_eq!(c.validate().unwrap_err().field, "command_timeout_s");
    let mut c = config();
    c.stop_decel_mps2 = 7.0; // in range alone, but above the vehicle's 6 m/s²
    c.validate().unwrap();
    let e = c.validate_for(&vehicle()).unwrap_err();
    assert_eq!(e.field, "stop_decel_mps2");
    let mut c = config();
    c.max_lat_jerk_mps3 = -1.0;
    assert_eq!(c.validate().unwrap_err().field, "max_lat_jerk_mps3");
    let e = toml::from_str::<GateConfig>("command_timeout_s = 0.1\nbogus = 1").unwrap_err();
    assert!(e.to_string().contains("bogus"), "{e}");
}

#[test]
fn an_invalid_config_latches_fault() {
    let mut c = config();
    c.feedback_timeout_s = f64::INFINITY;
    assert!(SafetyGate::try_new(c.clone(), &vehicle()).is_err());
    let mut g = SafetyGate::new(c, &vehicle());
    for k in 0..5 {
        let t = f64::from(k) * 0.01;
        for r in [Request::Engage, Request::Reset, Request::Disengage] {
            let out = g.step(t, &input(t, 1.0, 0.1, Some(r)));
            assert_eq!(out.state, GateState::Fault);
            assert!(!out.enable);
            assert_eq!((out.accel_mps2, out.steer_rad), (0.0, 0.0));
        }
    }
}

#[test]
fn engage_is_refused_with_stale_missing_or_bad_inputs() {
    let cfg = config();
    let now = 10.0;
    let fresh = input(now, 0.0, 0.0, Some(Request::Engage));
    let cases: Vec<(&str, GateInput)> = vec![
        ("no command", GateInput { command: None, ..fresh }),
        (
            "stale command",
            GateInput {
                command: Some(Command { accel_mps2: 0.0, steer_rad: 0.0, stamp_s: now - cfg.command_timeout_s - 1e-3 }),
                ..fresh
            },
        ),
        (
            "command from the future",
            GateInput { command: Some(Command { accel_mps2: 0.0, steer_rad: 0.0, stamp_s: now + 5.0 }), ..fresh },
        ),
        (
            "NaN command",
            GateInput { command: Some(Command { accel_mps2: f64::NAN, steer_rad: 0.0, stamp_s: now }), ..fresh },
        ),
        ("no feedback", GateInput { feedback_stamp_s: None, ..fresh }),
        ("stale feedback", GateInput { feedback_stamp_s: Some(now - cfg.feedback_timeout_s - 1e-3), ..fresh }),
        ("NaN speed", GateInput { speed_mps: f64::NAN, ..fresh }),
        ("DBW override", GateInput { dbw_mode: dbw_mode::OVERRIDE, ..fresh }),
        ("DBW fault", GateInput { dbw_mode: dbw_mode::FAULT, ..fresh }),
        ("unknown DBW mode", GateInput { dbw_mode: 9, ..fresh }),
    ];
    for (what, inp) in cases {
        let mut g = SafetyGate::try_new(cfg.clone(), &vehicle()).unwrap();
        let out = g.step(now, &inp);
        assert_eq!((out.state, out.reason), (GateState::Disengaged, GateReason::EngageRefused), "{what}");
        assert!(!out.enable, "{what}");
    }
    // NaN time: nothing is fresh.
    let mut g = SafetyGate::try_new(cfg.clone(), &vehicle()).unwrap();
    assert_eq!(g.step(f64::NAN, &fresh).reason, GateReason::EngageRefused);
    // And fresh inputs engage.
    let mut g = SafetyGate::try_new(cfg.clone(), &vehicle()).unwrap();
    assert_eq!(g.step(now, &fresh).state, GateState::Engaged);
}

#[test]
fn every_fault_while_engaged_starts_a_minimal_risk_stop_with_its_reason() {
    let timeout = config().command_timeout_s;
    let cases: Vec<Case> = vec![
        (GateReason::EStop, Box::new(|t| input(t, 0.0, 0.0, Some(Request::EStop)))),
        (GateReason::StopRequest, Box::new(|t| input(t, 0.0, 0.0, Some(Request::MinimalRiskStop)))),
        (GateReason::NonFiniteCommand, Box::new(|t| input(t, f64::NAN, 0.0, None))),
        (GateReason::NonFiniteCommand, Box::new(|t| input(t, 0.0, f64::INFINITY, None))),
        (GateReason::DbwFault, Box::new(|t| GateInput { dbw_mode: dbw_mode::FAULT, ..input(t, 0.0, 0.0, None) })),
        (GateReason::DbwFault, Box::new(|t| GateInput { dbw_mode: dbw_mode::OVERRIDE, ..input(t, 0.0, 0.0, None) })),
        (GateReason::CommandTimeout, Box::new(|t| GateInput { command: None, ..input(t, 0.0, 0.0, None) })),
        (
            GateReason::CommandTimeout,
            Box::new(move |t| {
                let mut i = input(t, 0.0, 0.0, None);
                i.command = Some(Command { accel_mps2: 0.0, steer_rad: 0.0, stamp_s: t - timeout - 0.01 });
                i
            }),
        ),
        (GateReason::FeedbackTimeout, Box::new(|t| GateInput { feedback_stamp_s: None, ..input(t, 0.0, 0.0, None) })),
        (GateReason::FeedbackTimeout, Box::new(|t| GateInput { speed_mps: f64::NAN, ..input(t, 0.0, 0.0, None) })),
    ];
    for (reason, make) in cases {
        let (mut g, t) = engaged();
        let out = g.step(t + 0.01, &make(t + 0.01));
        assert_eq!((out.state, out.reason), (GateState::MinimalRiskStop, reason));
        assert!(out.enable);
        assert!(out.accel_mps2.is_finite() && out.steer_rad.is_finite());
    }
    let (mut g, t) = engaged();
    g.bus_error();
    let out = g.step(t + 0.01, &input(t + 0.01, 0.0, 0.0, None));
    assert_eq!((out.state, out.reason), (GateState::MinimalRiskStop, GateReason::BusError));
}

#[test]
fn a_minimal_risk_stop_ignores_commands_and_engage_and_leaves_only_on_disengage_or_reset() {
    for leave in [Request::Disengage, Request::Reset] {
        let (mut g, mut t) = engaged();
        t += 0.01;
        g.step(t, &input(t, 0.0, 0.0, Some(Request::MinimalRiskStop)));
        for r in [None, Some(Request::Engage), Some(Request::MinimalRiskStop)] {
            t += 0.01;
            let out = g.step(t, &input(t, 3.0, 0.5, r));
            assert_eq!(out.state, GateState::MinimalRiskStop);
            assert!(out.accel_mps2 <= 0.0);
        }
        t += 0.01;
        let out = g.step(t, &input(t, 0.0, 0.0, Some(leave)));
        assert_eq!((out.state, out.reason, out.enable), (GateState::Disengaged, GateReason::DisengageRequest, false));
        // And it can engage again.
        t += 0.01;
        assert_eq!(g.step(t, &input(t, 0.0, 0.0, Some(Request::Engage))).state, GateState::Engaged);
    }
}

#[test]
fn an_estop_during_a_stop_brakes_harder() {
    let (mut g, mut t) = engaged();
    t += 0.01;
    g.step(t, &input(t, 0.0, 0.0, Some(Request::MinimalRiskStop)));
    let mut last = 0.0;
    for _ in 0..200 {
        t += 0.01;
        last = g.step(t, &input(t, 0.0, 0.0, None)).accel_mps2;
    }
    assert!((last + config().stop_decel_mps2).abs() < 1e-9, "{last}");
    t += 0.01;
    let out = g.step(t, &input(t, 0.0, 0.0, Some(Request::EStop)));
    assert_eq!(out.reason, GateReason::EStop);
    for _ in 0..200 {
        t += 0.01;
        last = g.step(t, &input(t, 0.0, 0.0, None)).accel_mps2;
    }
    assert!((last + vehicle().limits.max_decel_mps2).abs() < 1e-9, "{last}");
}

#[test]
fn stop_requests_while_disengaged_are_ignored() {
    let mut g = SafetyGate::try_new(config(), &vehicle()).unwrap();
    for (k, r) in [Request::MinimalRiskStop, Request::EStop, Request::Disengage, Request::Reset].into_iter().enumerate()
    {
        let t = k as f64 * 0.01;
        let out = g.step(t, &input(t, 1.0, 0.1, Some(r)));
        assert_eq!((out.state, out.enable), (GateState::Disengaged, false));
        assert_eq!((out.accel_mps2, out.steer_rad), (0.0, 0.0));
    }
}

#[test]
fn engaged_commands_pass_when_inside_the_envelope() {
    let (mut g, mut t) = engaged();
    // Hold a small constant command long enough for the ramps to settle.
    let mut out = g.step(t, &input(t, 0.0, 0.0, None));
    for _ in 0..300 {
        t += 0.01;
        out = g.step(t, &input(t, 1.5, 0.05, None));
    }
    assert_eq!(out.state, GateState::Engaged);
    assert!((out.accel_mps2 - 1.5).abs() < 1e-12);
    assert!((out.steer_rad - 0.05).abs() < 1e-12);
    // No positive acceleration at the top speed.
    for _ in 0..100 {
        t += 0.01;
        out = g.step(t, &GateInput { speed_mps: 22.0, ..input(t, 1.5, 0.0, None) });
    }
    assert_eq!(out.accel_mps2, 0.0);
}

#[test]
fn steering_limits_shrink_with_speed() {
    let g = SafetyGate::try_new(config(), &vehicle()).unwrap();
    let env = g.envelope();
    assert_eq!(env.steer_limit_rad(0.0), 0.55);
    assert_eq!(env.steer_rate_limit_radps(0.0), 0.6);
    let mut last = (f64::INFINITY, f64::INFINITY);
    for k in 0..=40 {
        let v = f64::from(k) * 0.75;
        let now = (env.steer_limit_rad(v), env.steer_rate_limit_radps(v));
        assert!(now.0 <= last.0 && now.1 <= last.1, "not shrinking at {v}");
        last = now;
        // The angle limit keeps the kinematic lateral acceleration within the configured one.
        assert!(v * v * now.0.tan() / env.wheelbase_m <= config().max_lat_accel_mps2 + 1e-9);
    }
    // Reverse speeds use |v|; a non-finite speed counts as the top speed.
    assert_eq!(env.steer_limit_rad(-10.0), env.steer_limit_rad(10.0));
    assert_eq!(env.steer_limit_rad(f64::NAN), env.steer_limit_rad(22.0));
}
