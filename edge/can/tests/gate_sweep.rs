//! The safety gate tested like a safety model (opendbc's `safety/tests/common.py`): every input
//! signal swept from below its minimum to beyond its maximum, plus NaN and infinities, in every
//! gate state, after several previous outputs, held for several steps and at several step sizes —
//! and every single output checked against an envelope computed here, independently of the
//! gate's own code. Also: the ramps are exactly the jerk and rate limits, a timeout drives the
//! vehicle to a standstill, engagement is refused with stale inputs.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic, clippy::indexing_slicing)] // test code

use std::path::Path;

use proptest::prelude::*;
use v2t_can::gate::{Command, GateConfig, GateInput, GateOutput, GateReason, GateState, Request, SafetyGate};
use v2t_model::vehicle::VehicleConfig;

const EPS: f64 = 1e-9;
const NOMINAL_SPEED: f64 = 8.0;

fn load<T: serde::de::DeserializeOwned>(rel: &str) -> T {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..").join(rel);
    toml::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap()
}

fn vehicle() -> VehicleConfig {
    load("config/vehicles/bv_sedan.toml")
}

fn gate_config() -> GateConfig {
    load("config/can/gate.toml")
}

/// The envelope, computed from the configuration files on its own (not with the gate's code).
#[derive(Debug, Clone, Copy)]
struct Limits {
    max_accel: f64,
    max_decel: f64,
    max_jerk: f64,
    max_speed: f64,
    max_steer: f64,
    max_rate: f64,
    wheelbase: f64,
    lat_accel: f64,
    lat_jerk: f64,
}

impl Limits {
    fn new() -> Self {
        let v = vehicle();
        let g = gate_config();
        Self {
            max_accel: v.limits.max_accel_mps2,
            max_decel: v.limits.max_decel_mps2,
            max_jerk: v.limits.max_jerk_mps3,
            max_speed: v.limits.max_speed_mps,
            max_steer: v.limits.max_steer_rad,
            max_rate: v.limits.max_steer_rate_radps,
            wheelbase: v.geometry.wheelbase_m,
            lat_accel: g.max_lat_accel_mps2.min(v.limits.max_lat_accel_mps2),
            lat_jerk: g.max_lat_jerk_mps3,
        }
    }

    fn speed(&self, v: f64) -> f64 {
        if v.is_finite() { v.abs() } else { self.max_speed }
    }

    fn steer(&self, v: f64) -> f64 {
        let v = self.speed(v);
        if v == 0.0 { self.max_steer } else { self.max_steer.min((self.wheelbase * self.lat_accel / (v * v)).atan()) }
    }

    fn rate(&self, v: f64) -> f64 {
        let v = self.speed(v);
        if v == 0.0 { self.max_rate } else { self.max_rate.min(self.wheelbase * self.lat_jerk / (v * v)) }
    }
}

/// Drives a gate and checks every output.
struct Harness {
    gate: SafetyGate,
    lim: Limits,
    t: f64,
    last_finite_t: Option<f64>,
    prev: GateOutput,
    checked: u64,
    /// Speed of the nominal inputs, m/s.
    speed: f64,
}

impl Harness {
    fn new(gate: SafetyGate) -> Self {
        let prev = GateOutput {
            accel_mps2: 0.0,
            steer_rad: 0.0,
            enable: false,
            state: gate.state(),
            reason: GateReason::Init,
        };
        Self { gate, lim: Limits::new(), t: 100.0, last_finite_t: None, prev, checked: 0, speed: NOMINAL_SPEED }
    }

    /// Fresh nominal inputs at the current time.
    fn nominal(&self, accel: f64, steer: f64, request: Option<Request>) -> GateInput {
        GateInput {
            command: Some(Command { accel_mps2: accel, steer_rad: steer, stamp_s: self.t }),
            request,
            speed_mps: self.speed,
            dbw_mode: 1,
            feedback_stamp_s: Some(self.t),
        }
    }

    /// One step at `now` (the input's stamps are the caller's), with every check.
    fn step_at(&mut self, now: f64, input: &GateInput) -> GateOutput {
        let out = self.gate.step(now, input);
        let dt = match (now.is_finite(), self.last_finite_t) {
            (true, Some(last)) if now > last => now - last,
            _ => 0.0,
        };
        if now.is_finite() && self.last_finite_t.is_none_or(|l| now > l) {
            self.last_finite_t = Some(now);
        }
        check(&self.lim, &self.prev, &out, input, dt);
        self.prev = out;
        self.checked += 1;
        out
    }

    /// Advances the time by `dt` and steps with `make(now)`.
    fn step(&mut self, dt: f64, make: impl Fn(&Self) -> GateInput) -> GateOutput {
        self.t += dt;
        let input = make(self);
        self.step_at(self.t, &input)
    }
}

/// The envelope every output must lie in, given the previous output.
fn check(lim: &Limits, prev: &GateOutput, out: &GateOutput, input: &GateInput, dt: f64) {
    let ctx = || format!("out {out:?}\nprev {prev:?}\ninput {input:?}\ndt {dt}");
    assert!(out.accel_mps2.is_finite() && out.steer_rad.is_finite(), "non-finite output\n{}", ctx());
    if !out.enable {
        assert_eq!((out.accel_mps2, out.steer_rad), (0.0, 0.0), "disabled output not zero\n{}", ctx());
        assert!(matches!(out.state, GateState::Disengaged | GateState::Fault), "disabled while active\n{}", ctx());
        return;
    }
    assert!(
        matches!(out.state, GateState::Engaged | GateState::MinimalRiskStop),
        "enabled while {:?}\n{}",
        out.state,
        ctx()
    );
    let a = out.accel_mps2;
    assert!(a >= -lim.max_decel - EPS && a <= lim.max_accel + EPS, "accel outside limits\n{}", ctx());
    assert!((a - prev.accel_mps2).abs() <= lim.max_jerk * dt + EPS, "jerk limit broken\n{}", ctx());
    if lim.speed(input.speed_mps) >= lim.max_speed {
        assert!(a <= prev.accel_mps2.max(0.0) + EPS, "accelerating at top speed\n{}", ctx());
    }
    if out.state == GateState::MinimalRiskStop {
        assert!(a <= prev.accel_mps2 + EPS, "a stop braked less\n{}", ctx());
    }
    let s = out.steer_rad;
    let limit = lim.steer(input.speed_mps);
    assert!(s.abs() <= limit + EPS, "steer outside the speed-dependent limit {limit}\n{}", ctx());
    let within_rate = (s - prev.steer_rad).abs() <= lim.rate(input.speed_mps) * dt + EPS;
    let cut_to_limit = (s.abs() - limit).abs() <= EPS && s.abs() < prev.steer_rad.abs() && s * prev.steer_rad >= 0.0;
    assert!(within_rate || cut_to_limit, "steering rate limit broken\n{}", ctx());
}

/// Gate states the sweep starts from.
#[derive(Debug, Clone, Copy)]
enum Start {
    Disengaged,
    Engaged,
    Stop,
    EStop,
    Fault,
}

const STARTS: [Start; 5] = [Start::Disengaged, Start::Engaged, Start::Stop, Start::EStop, Start::Fault];

/// A gate in `start`, whose previous output came from holding `(accel, steer)` for a second.
fn harness_in(start: Start, accel: f64, steer: f64) -> Harness {
    let cfg = gate_config();
    let gate = match start {
        Start::Fault => {
            let mut bad = cfg;
            bad.command_timeout_s = f64::NAN;
            SafetyGate::new(bad, &vehicle())
        }
        _ => SafetyGate::try_new(cfg, &vehicle()).unwrap(),
    };
    let mut h = Harness::new(gate);
    h.step(0.01, |h| h.nominal(0.0, 0.0, None));
    if matches!(start, Start::Disengaged | Start::Fault) {
        return h;
    }
    assert_eq!(h.step(0.01, |h| h.nominal(0.0, 0.0, Some(Request::Engage))).state, GateState::Engaged);
    for _ in 0..100 {
        h.step(0.01, |h| h.nominal(accel, steer, None));
    }
    let request = match start {
        Start::Stop => Some(Request::MinimalRiskStop),
        Start::EStop => Some(Request::EStop),
        _ => None,
    };
    if request.is_some() {
        let out = h.step(0.01, |h| h.nominal(accel, steer, request));
        assert_eq!(out.state, GateState::MinimalRiskStop);
    }
    h
}

fn sweep(lo: f64, hi: f64, n: usize) -> Vec<f64> {
    let mut v: Vec<f64> = (0..=n).map(|i| lo + (hi - lo) * i as f64 / n as f64).collect();
    v.extend([f64::NAN, f64::INFINITY, f64::NEG_INFINITY, f64::MAX, f64::MIN, f64::MIN_POSITIVE, -0.0]);
    v
}

/// One swept signal: a name and how a value of it changes the nominal input.
type Apply = fn(&mut GateInput, f64, f64);

fn signals(lim: &Limits, cfg: &GateConfig) -> Vec<(&'static str, Vec<f64>, Apply)> {
    let ages = |timeout: f64| {
        let mut a = sweep(-2.0 * timeout, 3.0 * timeout, 20);
        a.extend([timeout, timeout + 1e-6, -timeout - 1e-6, 1e6]);
        a
    };
    vec![
        ("accel", sweep(-3.0 * lim.max_decel, 3.0 * lim.max_accel, 60), set_accel as Apply),
        ("steer", sweep(-3.0 * lim.max_steer, 3.0 * lim.max_steer, 60), set_steer),
        ("speed", sweep(-10.0, 2.0 * lim.max_speed, 60), |i, _, x| i.speed_mps = x),
        ("command age", ages(cfg.command_timeout_s), set_command_age),
        ("feedback age", ages(cfg.feedback_timeout_s), |i, now, x| i.feedback_stamp_s = Some(now - x)),
        ("dbw mode", (0..=255).map(f64::from).collect(), |i, _, x| i.dbw_mode = x as u8),
    ]
}

fn set_accel(i: &mut GateInput, _: f64, x: f64) {
    if let Some(c) = i.command.as_mut() {
        c.accel_mps2 = x;
    }
}

fn set_steer(i: &mut GateInput, _: f64, x: f64) {
    if let Some(c) = i.command.as_mut() {
        c.steer_rad = x;
    }
}

fn set_command_age(i: &mut GateInput, now: f64, x: f64) {
    if let Some(c) = i.command.as_mut() {
        c.stamp_s = now - x;
    }
}

const REQUESTS: [Option<Request>; 6] = [
    None,
    Some(Request::Engage),
    Some(Request::Disengage),
    Some(Request::MinimalRiskStop),
    Some(Request::EStop),
    Some(Request::Reset),
];

#[test]
fn every_signal_in_every_state_stays_inside_the_envelope() {
    let lim = Limits::new();
    let cfg = gate_config();
    let previous = [(-lim.max_decel, -0.3), (0.0, 0.0), (lim.max_accel, 0.3), (1.0, 0.05)];
    let dts = [0.0, 0.001, 0.01, 0.1, 1.0];
    let mut checked = 0u64;
    for (start, speed) in STARTS.into_iter().flat_map(|s| [0.0, NOMINAL_SPEED, lim.max_speed].map(|v| (s, v))) {
        for &(pa, ps) in &previous {
            let mut base = harness_in(start, pa, ps);
            base.speed = speed;
            checked += base.checked;
            for (name, values, apply) in signals(&lim, &cfg) {
                for &x in &values {
                    for request in REQUESTS {
                        for &dt in &dts {
                            let mut h = Harness { gate: base.gate.clone(), checked: 0, ..base };
                            // Hold the value for several steps (the ramps move), the request on the first.
                            for k in 0..4 {
                                h.step(dt, |h| {
                                    let mut i = h.nominal(0.5, 0.02, if k == 0 { request } else { None });
                                    apply(&mut i, h.t, x);
                                    i
                                });
                            }
                            checked += h.checked;
                        }
                    }
                    let _ = name;
                }
            }
        }
    }
    println!("gate sweep: {checked} outputs checked, 0 outside the envelope");
    assert!(checked > 3_000_000, "{checked}");
}

#[test]
fn time_that_stands_still_jumps_back_or_is_not_finite_moves_nothing() {
    let mut checked = 0;
    for start in STARTS {
        let mut h = harness_in(start, 1.0, 0.1);
        let t0 = h.t;
        for now in [t0, t0 - 1.0, f64::NAN, f64::INFINITY, f64::NEG_INFINITY, t0 - 1e9] {
            let before = h.prev;
            let input = h.nominal(3.0, -0.5, None);
            let out = h.step_at(now, &input);
            if out.enable && before.enable {
                assert_eq!(
                    (out.accel_mps2, out.steer_rad),
                    (before.accel_mps2, before.steer_rad),
                    "{start:?} at {now}"
                );
            }
        }
        checked += h.checked;
    }
    println!("clock sweep: {checked} outputs checked");
}

/// Engaging from `Disengaged` with one input changed: granted exactly when everything is fresh,
/// finite and the DBW is ready.
#[test]
fn engage_is_granted_only_with_fresh_finite_inputs_and_a_ready_dbw() {
    let lim = Limits::new();
    let cfg = gate_config();
    let mut checked = 0;
    for (name, values, apply) in signals(&lim, &cfg) {
        for &x in &values {
            let mut h = harness_in(Start::Disengaged, 0.0, 0.0);
            let out = h.step(0.01, |h| {
                let mut i = h.nominal(0.5, 0.02, Some(Request::Engage));
                apply(&mut i, h.t, x);
                i
            });
            checked += h.checked;
            let ok = match name {
                "accel" | "steer" => x.is_finite(),
                "speed" => x.is_finite(),
                // The stamp was written as `now - x`: judge the age the gate sees.
                "command age" => (h.t - (h.t - x)).abs() <= cfg.command_timeout_s,
                "feedback age" => (h.t - (h.t - x)).abs() <= cfg.feedback_timeout_s,
                "dbw mode" => x == 0.0 || x == 1.0,
                _ => unreachable!(),
            };
            let expected = if ok {
                (GateState::Engaged, GateReason::EngageRequest)
            } else {
                (GateState::Disengaged, GateReason::EngageRefused)
            };
            assert_eq!((out.state, out.reason), expected, "{name} = {x}");
        }
    }
    // No feedback yet, or no command yet.
    for change in [0, 1] {
        let mut h = harness_in(Start::Disengaged, 0.0, 0.0);
        let out = h.step(0.01, |h| {
            let mut i = h.nominal(0.0, 0.0, Some(Request::Engage));
            if change == 0 {
                i.feedback_stamp_s = None;
            } else {
                i.command = None;
            }
            i
        });
        assert_eq!((out.state, out.reason), (GateState::Disengaged, GateReason::EngageRefused));
    }
    println!("engage sweep: {checked} outputs checked");
}

#[test]
fn ramps_follow_the_jerk_and_rate_limits_exactly() {
    let lim = Limits::new();
    let dt = 0.01;
    let mut h = harness_in(Start::Engaged, -lim.max_decel, 0.0);
    assert!((h.prev.accel_mps2 + lim.max_decel).abs() < EPS);
    // Full brake to full throttle: exactly max_jerk · dt per step until reached.
    let mut a = h.prev.accel_mps2;
    while a < lim.max_accel - EPS {
        let out = h.step(dt, |h| h.nominal(100.0, 0.0, None));
        let expected = (a + lim.max_jerk * dt).min(lim.max_accel);
        assert!((out.accel_mps2 - expected).abs() < EPS, "{} vs {expected}", out.accel_mps2);
        a = out.accel_mps2;
    }
    // Full left at nominal speed: exactly the rate limit per step, up to the angle limit.
    let (limit, rate) = (lim.steer(NOMINAL_SPEED), lim.rate(NOMINAL_SPEED));
    let mut s = h.prev.steer_rad;
    while s < limit - EPS {
        let out = h.step(dt, |h| h.nominal(0.0, 10.0, None));
        let expected = (s + rate * dt).min(limit);
        assert!((out.steer_rad - expected).abs() < EPS, "{} vs {expected}", out.steer_rad);
        s = out.steer_rad;
    }
    // Speeding up shrinks the angle limit: the angle is cut to it.
    let out = h.step(dt, |h| GateInput { speed_mps: 20.0, ..h.nominal(0.0, 10.0, None) });
    assert!((out.steer_rad - lim.steer(20.0)).abs() < EPS);
    println!("ramp test: {} outputs checked", h.checked);
}

/// A plant that follows the sent acceleration exactly; returns the time and distance to standstill
/// and checks that the steering is held.
fn stop_with(cause: impl Fn(&Harness, f64) -> GateInput, reason: GateReason) {
    let lim = Limits::new();
    let cfg = gate_config();
    let dt = 0.01;
    let mut h = harness_in(Start::Engaged, 0.0, 0.02);
    let mut v = 20.0;
    // Cruise at 20 m/s.
    for _ in 0..50 {
        h.step(dt, |h| GateInput { speed_mps: v, ..h.nominal(0.0, 0.02, None) });
    }
    let steer = h.prev.steer_rad;
    let t_fail = h.t;
    let (mut t_stop, mut x) = (None, 0.0);
    for _ in 0..3000 {
        let out = h.step(dt, |h| cause(h, v));
        if h.t - t_fail > cfg.command_timeout_s.max(cfg.feedback_timeout_s) + 2.0 * dt {
            assert_eq!((out.state, out.reason), (GateState::MinimalRiskStop, reason));
        }
        if out.state == GateState::MinimalRiskStop {
            assert!((out.steer_rad - steer).abs() < EPS, "steering not held");
            assert!(out.enable);
        }
        v = (v + out.accel_mps2 * dt).max(0.0);
        x += v * dt;
        if v <= cfg.standstill_speed_mps && t_stop.is_none() {
            t_stop = Some(h.t - t_fail);
            assert!(h.gate.at_standstill(v));
        }
    }
    let t_stop = t_stop.expect("no standstill");
    // Bound: the timeout, the ramp to the stop deceleration, then braking at it.
    let timeout = cfg.command_timeout_s.max(cfg.feedback_timeout_s);
    let ramp = (lim.max_accel + cfg.stop_decel_mps2) / cfg.stop_jerk_mps3;
    let bound = timeout + ramp + (20.0 + lim.max_accel * timeout) / cfg.stop_decel_mps2 + 0.2;
    assert!(t_stop <= bound, "standstill after {t_stop} s > {bound} s");
    // Still braking at standstill, until a disengage.
    assert!(h.prev.accel_mps2 <= -cfg.stop_decel_mps2 + EPS && h.prev.enable);
    let out = h.step(dt, |h| GateInput { request: Some(Request::Disengage), ..cause(h, 0.0) });
    assert_eq!((out.state, out.enable), (GateState::Disengaged, false));
    println!("{reason:?}: standstill {t_stop:.2} s and {x:.1} m after the failure; {} outputs checked", h.checked);
}

#[test]
fn a_command_timeout_stops_the_vehicle() {
    let frozen = std::cell::Cell::new(None::<f64>);
    stop_with(
        |h, v| {
            let stamp = frozen.get().unwrap_or_else(|| {
                frozen.set(Some(h.t));
                h.t
            });
            let mut i = h.nominal(1.0, 0.02, None);
            i.command = Some(Command { accel_mps2: 1.0, steer_rad: 0.02, stamp_s: stamp });
            i.speed_mps = v;
            i
        },
        GateReason::CommandTimeout,
    );
}

#[test]
fn a_feedback_timeout_stops_the_vehicle() {
    let frozen = std::cell::Cell::new(None::<f64>);
    stop_with(
        |h, v| {
            let stamp = frozen.get().unwrap_or_else(|| {
                frozen.set(Some(h.t));
                h.t
            });
            GateInput { feedback_stamp_s: Some(stamp), speed_mps: v, ..h.nominal(1.0, 0.02, None) }
        },
        GateReason::FeedbackTimeout,
    );
}

#[test]
fn a_nan_command_stops_the_vehicle() {
    stop_with(|h, v| GateInput { speed_mps: v, ..h.nominal(f64::NAN, f64::NAN, None) }, GateReason::NonFiniteCommand);
}

fn any_value(lo: f64, hi: f64) -> impl Strategy<Value = f64> {
    prop_oneof![
        8 => lo..hi,
        1 => Just(f64::NAN),
        1 => prop_oneof![Just(f64::INFINITY), Just(f64::NEG_INFINITY), Just(lo * 10.0), Just(hi * 10.0)],
    ]
}

fn any_request() -> impl Strategy<Value = Option<Request>> {
    (0usize..REQUESTS.len() * 4).prop_map(|i| REQUESTS.get(i).copied().flatten())
}

fn any_step() -> impl Strategy<Value = (f64, f64, f64, f64, f64, f64, u8, Option<Request>, bool)> {
    (
        prop_oneof![Just(0.0), 0.0..0.05, 0.0..1.0],
        any_value(-20.0, 20.0),
        any_value(-2.0, 2.0),
        any_value(-5.0, 40.0),
        any_value(-0.5, 0.5),
        any_value(-0.5, 0.5),
        prop_oneof![4 => Just(1u8), 1 => any::<u8>()],
        any_request(),
        prop::bool::weighted(0.02),
    )
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 200, failure_persistence: None, ..ProptestConfig::default() })]

    /// Random sequences of everything at once, from every start state.
    #[test]
    fn random_input_sequences_stay_inside_the_envelope(
        start in 0usize..STARTS.len(),
        steps in prop::collection::vec(any_step(), 1..300),
    ) {
        let mut h = harness_in(STARTS[start], 1.0, 0.05);
        for (dt, accel, steer, speed, cmd_age, fb_age, mode, request, bus_error) in steps {
            if bus_error {
                h.gate.bus_error();
            }
            h.step(dt, |h| GateInput {
                command: Some(Command { accel_mps2: accel, steer_rad: steer, stamp_s: h.t - cmd_age }),
                request,
                speed_mps: speed,
                dbw_mode: mode,
                feedback_stamp_s: Some(h.t - fb_age),
            });
        }
    }
}
