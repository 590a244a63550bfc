use super::*;
use crate::reference::ReferenceSample;
use crate::route_speed::RouteSpeed;
use proptest::prelude::*;

fn zone(enter: f64, exit: f64) -> OccupancyInterval {
    OccupancyInterval { enter_s_m: enter, exit_s_m: exit }
}

/// BV 40 m and VUT 60 m before their zones (each zone 10 m of occupancy), both at 10 m/s.
fn input(style: Style, tau: f64) -> RegulatorInput {
    RegulatorInput {
        t_s: 0.0,
        bv: PathState { s_m: 0.0, v_mps: 10.0, age_s: 0.05 },
        vut: PathState { s_m: 0.0, v_mps: 10.0, age_s: 0.15 },
        bv_accel_mps2: 0.0,
        zone_bv: zone(40.0, 50.0),
        zone_vut: zone(60.0, 70.0),
        zone_kind: ConflictKind::Crossing,
        target: Target::new(tau, style).unwrap(),
        reference_speed_mps: 10.0,
        stop_line_s_m: None,
    }
}

fn regulator() -> Regulator {
    Regulator::new(RegulatorParams::default()).unwrap()
}

#[test]
fn pet_sign_conventions_follow_the_style() {
    // Rush: the BV must be out (s = 50) τ before the VUT comes in (t = 6 s at 10 m/s).
    let mut r = regulator();
    let d = r.decide(&input(Style::Rush, 2.0));
    assert_eq!(d.status, RegulatorStatus::Regulating, "{d:?}");
    let key = d.key_time_s.unwrap();
    assert!((key - 4.0).abs() < 0.05, "rush: key time {key} (VUT in at 6 s, τ = 2 s)");
    assert!((d.predicted_pet_s.unwrap() - 2.0).abs() < 0.05);
    // Yield: the BV comes in (s = 40) τ after the VUT is out (t = 7 s).
    let mut r = regulator();
    let d = r.decide(&input(Style::Yield, 2.0));
    assert_eq!(d.status, RegulatorStatus::Regulating, "{d:?}");
    let key = d.key_time_s.unwrap();
    assert!((key - 9.0).abs() < 0.05, "yield: key time {key} (VUT out at 7 s, τ = 2 s)");
    assert!((d.predicted_pet_s.unwrap() - 2.0).abs() < 0.05);
    assert!(d.accel_mps2 < 0.0, "yielding 2 s after the VUT means slowing down now");
}

#[test]
fn an_unreachable_target_degrades_and_says_so() {
    // Rush with τ = 5.5 s: out by t = 0.5 s is impossible from 50 m away.
    let mut r = regulator();
    let d = r.decide(&input(Style::Rush, 5.5));
    assert!(matches!(d.status, RegulatorStatus::Degraded | RegulatorStatus::SafetyYield), "{d:?}");
    assert!(d.accel_mps2 <= 3.0 + 1e-9 && d.accel_mps2 >= -6.0 - 1e-9);
}

#[test]
fn a_vut_already_in_the_zone_makes_a_rushing_bv_give_way() {
    let mut r = regulator();
    let mut inp = input(Style::Rush, 2.0);
    inp.vut.s_m = 62.0;
    inp.bv.s_m = 30.0;
    let d = r.decide(&inp);
    assert_eq!(d.status, RegulatorStatus::SafetyYield);
    assert!(d.accel_mps2 < -1.0, "it brakes to stay out of the zone: {d:?}");
}

#[test]
fn a_rush_the_vut_cannot_survive_is_refused() {
    // The VUT at 15 m/s is 12 m from its entry: it cannot stop, and the BV cannot be out in time.
    let mut r = regulator();
    let mut inp = input(Style::Rush, 1.5);
    inp.vut = PathState { s_m: 48.0, v_mps: 15.0, age_s: 0.1 };
    inp.bv.s_m = 25.0;
    let d = r.decide(&inp);
    assert_eq!(d.status, RegulatorStatus::SafetyYield, "{d:?}");
}

#[test]
fn a_bv_past_its_key_point_follows_its_reference() {
    let mut r = regulator();
    let mut inp = input(Style::Rush, 2.0);
    inp.bv.s_m = 55.0;
    let d = r.decide(&inp);
    assert_eq!(d.status, RegulatorStatus::Passed);
    assert!(d.accel_mps2.abs() < 0.1, "cruising at the reference: {d:?}");
}

/// The plan a cloud regulator sends starts with the acceleration the decision applies, covers the
/// horizon and, integrated, keeps the planned key time; a stale decision has none.
#[test]
fn the_planned_accelerations_are_the_decisions_plan() {
    for style in [Style::Rush, Style::Yield] {
        let mut r = regulator();
        let inp = input(style, 2.0);
        let d = r.decide(&inp);
        let plan = r.planned_accels(&d).unwrap();
        assert_eq!(plan.len(), RegulatorParams::default().horizon);
        assert!((plan[0] - d.accel_mps2).abs() < 1e-6, "{} vs {}", plan[0], d.accel_mps2);
        // Integrated, the plan reaches the BV's key station at the key time.
        let key_station = if style == Style::Rush { inp.zone_bv.exit_s_m } else { inp.zone_bv.enter_s_m };
        let path = rollout(inp.bv.s_m, inp.bv.v_mps, plan);
        let there = path.iter().find(|p| p.1 >= key_station);
        // Rush: the key time (4 s) lies within the horizon; yield: beyond it (9 s).
        let key = d.key_time_s.unwrap();
        if key < 4.9 {
            let t = there.map_or(f64::INFINITY, |p| p.0);
            assert!((t - key).abs() <= 0.15, "{style}: at the station at {t} s, key {key}");
        } else {
            assert!(there.is_none(), "{style}: at the station within the horizon, key {key}");
        }
    }
    let mut r = regulator();
    let mut inp = input(Style::Rush, 2.0);
    inp.vut.age_s = 2.0;
    let d = r.decide(&inp);
    assert_eq!(r.planned_accels(&d), None);
}

/// A yielding BV that crept over its entry before the VUT has left the zone gives way; one that is well
/// inside, or whose VUT has left, goes on.
#[test]
fn a_yielding_bv_that_crept_in_gives_way_to_a_vut_in_the_zone() {
    let mut inp = input(Style::Yield, 2.0);
    inp.bv = PathState { s_m: 40.3, v_mps: 0.2, age_s: 0.05 };
    inp.vut = PathState { s_m: 65.0, v_mps: 8.0, age_s: 0.15 };
    let d = regulator().decide(&inp);
    assert_eq!(d.status, RegulatorStatus::SafetyYield, "{d:?}");
    assert!(d.accel_mps2 < 0.0, "it stops, it does not drive on into the VUT: {d:?}");
    inp.vut.s_m = 40.0;
    assert_eq!(regulator().decide(&inp).status, RegulatorStatus::SafetyYield, "nor before it comes");
    inp.vut.s_m = 71.0;
    assert_eq!(regulator().decide(&inp).status, RegulatorStatus::Passed);
    inp.vut.s_m = 65.0;
    inp.bv.s_m = 42.0;
    assert_eq!(regulator().decide(&inp).status, RegulatorStatus::Passed, "committed: it clears the zone");
}

#[test]
fn stale_or_broken_inputs_give_the_minimal_risk_profile() {
    let mut r = regulator();
    let mut inp = input(Style::Rush, 2.0);
    inp.vut.age_s = 2.0;
    let d = r.decide(&inp);
    assert_eq!(d.status, RegulatorStatus::Stale);
    assert!((d.accel_mps2 + 2.0).abs() < 1e-12);
    inp.vut.age_s = 0.1;
    inp.vut.v_mps = f64::NAN;
    let d = r.decide(&inp);
    assert_eq!(d.status, RegulatorStatus::Fallback);
    assert!(d.accel_mps2.is_finite() && d.accel_mps2 <= 0.0);
    // Standing still, the fallback does not ask to reverse.
    inp.bv.v_mps = 0.0;
    assert_eq!(r.decide(&inp).accel_mps2, 0.0);
}

#[test]
fn yield_waits_for_a_vut_that_stands_before_the_zone() {
    let mut r = regulator();
    let mut inp = input(Style::Yield, 2.0);
    inp.vut = PathState { s_m: 55.0, v_mps: 0.0, age_s: 0.1 };
    inp.bv.s_m = 20.0;
    let d = r.decide(&inp);
    assert_eq!(d.status, RegulatorStatus::Waiting, "{d:?}");
    assert!(d.accel_mps2 < 0.0);
}

#[test]
fn yield_uses_the_observed_exit_once_the_vut_is_out() {
    let mut r = regulator();
    let mut inp = input(Style::Yield, 3.0);
    inp.bv = PathState { s_m: 25.0, v_mps: 4.0, age_s: 0.05 };
    inp.vut = PathState { s_m: 71.0, v_mps: 10.0, age_s: 0.1 };
    inp.t_s = 10.0;
    let d = r.decide(&inp);
    assert_eq!(d.status, RegulatorStatus::Regulating, "{d:?}");
    // Seen 1 m past the exit at 10 m/s: it left 0.1 s ago.
    assert!((d.key_time_s.unwrap() - 2.9).abs() < 0.02, "in 3 s from the observed exit: {d:?}");
    inp.t_s = 11.0;
    inp.vut.s_m = 81.0;
    inp.bv.s_m = 29.0;
    let d = r.decide(&inp);
    assert!((d.key_time_s.unwrap() - 1.9).abs() < 0.02, "the exit time is remembered: {d:?}");
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(120))]
    /// Randomized states: every decision is finite, within the BV's limits and a defined status.
    #[test]
    fn decisions_are_finite_and_within_limits(
        bv_s in -20.0f64..80.0, bv_v in 0.0f64..20.0, vut_s in -40.0f64..90.0, vut_v in 0.0f64..20.0,
        a_prev in -6.0f64..3.0, tau in 0.5f64..6.0, rush in any::<bool>(), age in 0.0f64..0.7,
    ) {
        let mut r = regulator();
        let mut inp = input(if rush { Style::Rush } else { Style::Yield }, tau);
        inp.bv = PathState { s_m: bv_s, v_mps: bv_v, age_s: age };
        inp.vut = PathState { s_m: vut_s, v_mps: vut_v, age_s: age };
        inp.bv_accel_mps2 = a_prev;
        let d = r.decide(&inp);
        prop_assert!(d.accel_mps2.is_finite() && d.accel_mps2 <= 3.0 + 1e-9 && d.accel_mps2 >= -6.0 - 1e-9, "{:?}", d);
        prop_assert!(d.next_speed_mps.is_finite() && d.next_speed_mps >= 0.0);
        prop_assert!(d.predicted_pet_s.is_none_or(|p| p.is_finite()));
        if age > 0.5 { prop_assert_eq!(d.status, RegulatorStatus::Stale); }
    }
}

#[test]
fn a_rushing_cut_in_arrives_fast_enough_for_the_vut_headway() {
    // Merge, rush, τ = 1.5 s, VUT at 12 m/s keeping (assumed) 2 s: the BV should pass the
    // encroachment point at about 2 · 12 / 1.5 = 16 m/s, and still on time.
    let params = RegulatorParams { vut_headway_s: 2.0, ..RegulatorParams::default() };
    let mut r = Regulator::new(params).unwrap();
    let mut inp = input(Style::Rush, 1.5);
    inp.zone_kind = ConflictKind::Merge;
    inp.vut = PathState { s_m: 0.0, v_mps: 12.0, age_s: 0.1 };
    inp.zone_vut = zone(75.0, 80.0); // in at 6.25 s
    inp.bv = PathState { s_m: 0.0, v_mps: 8.0, age_s: 0.05 };
    let d = r.decide(&inp);
    assert_eq!(d.status, RegulatorStatus::Regulating, "{d:?}");
    let key = d.key_time_s.unwrap();
    assert!((key - (75.0 / 12.0 - 1.5)).abs() < 0.05, "{key}");
    let k = (key / 0.1).floor() as usize;
    let v_key = r.leader_equal.speed()[k];
    assert!(v_key >= 12.0, "arrives at {v_key} m/s (the ramp is tracked against effort penalties)");
    // The same crossing is planned at its plain average speed (50 m in 4.75 s).
    let mut r2 = Regulator::new(params).unwrap();
    inp.zone_kind = ConflictKind::Crossing;
    r2.decide(&inp);
    assert!(r2.leader_equal.speed()[k] < v_key - 0.5, "{}", r2.leader_equal.speed()[k]);
}

/// A reference that drives `speed(t)` from arc length 0, sampled every 0.1 s for 30 s.
fn reference_of(speed: impl Fn(f64) -> f64) -> Vec<ReferenceSample> {
    let mut s = 0.0;
    (0..300)
        .map(|k| {
            let t = k as f64 * 0.1;
            let q = ReferenceSample { t_s: t, s_m: s, v_mps: speed(t) };
            s += 0.5 * (speed(t) + speed(t + 0.1)) * 0.1;
            q
        })
        .collect()
}

fn realistic(w_real: f64, reference: &[ReferenceSample]) -> Regulator {
    let mut r = Regulator::new(RegulatorParams { w_real, ..RegulatorParams::default() }).unwrap();
    r.set_reference(reference.iter().copied()).unwrap();
    r
}

#[test]
fn the_realism_term_pulls_the_key_time_toward_the_prior() {
    // Rush, τ = 2 s: the game alone wants the BV out (50 m) at 4 s. A prior at a steady 8 m/s is
    // out at 6.25 s; with w_real = w_adv the key time is the mean of the two, and the BV speeds up
    // less now than without the pull.
    let slow = reference_of(|_| 8.0);
    let alone = regulator().decide(&input(Style::Rush, 2.0));
    let d = realistic(1.0, &slow).decide(&input(Style::Rush, 2.0));
    assert_eq!(d.status, RegulatorStatus::Regulating, "{d:?}");
    let key = d.key_time_s.unwrap();
    assert!((key - 0.5 * (4.0 + 6.25)).abs() < 0.1, "key time {key}, expected about 5.1 s");
    assert!(d.accel_mps2 < alone.accel_mps2, "{} vs {}", d.accel_mps2, alone.accel_mps2);
    // A heavier realism weight comes closer still; the predicted PET moves off τ accordingly.
    let heavy = realistic(9.0, &slow).decide(&input(Style::Rush, 2.0));
    assert!(heavy.key_time_s.unwrap() > key && (heavy.key_time_s.unwrap() - 6.25).abs() < 0.35, "{heavy:?}");
    // Yield, τ = 2 s: the game wants the BV in (40 m) at 9 s; a prior at 4 m/s is in at 10 s.
    let d = realistic(1.0, &reference_of(|_| 4.0)).decide(&input(Style::Yield, 2.0));
    let key = d.key_time_s.unwrap();
    assert!((key - 9.5).abs() < 0.1, "yield key time {key}, expected about 9.5 s");
    // A prior that would go in at 4 s pulls the BV no closer to the VUT (out at 7 s) than the
    // safety margin (0.5 s).
    let d = realistic(1.0, &reference_of(|_| 10.0)).decide(&input(Style::Yield, 2.0));
    let key = d.key_time_s.unwrap();
    assert!((key - 7.5).abs() < 0.1, "yield key time {key}, expected the margin's 7.5 s");
}

#[test]
fn the_plan_takes_the_shape_of_the_prior() {
    // Two priors that are both out of the zone at 4 s (the game's own key time, so the pull does
    // not move it): one steady at 12.5 m/s, one that starts slow (6 m/s) and speeds up late. The
    // plan around the second starts slower.
    let steady = reference_of(|_| 12.5);
    let late = reference_of(|t| if t < 2.0 { 6.0 } else { 19.0 });
    let s_late = late.iter().find(|q| q.t_s >= 4.0 - 1e-9).unwrap().s_m;
    assert!((s_late - 50.0).abs() < 2.0, "the late prior is out at about 4 s: {s_late} m");
    let a_steady = realistic(1.0, &steady).decide(&input(Style::Rush, 2.0));
    let a_late = realistic(1.0, &late).decide(&input(Style::Rush, 2.0));
    assert!(a_late.accel_mps2 < a_steady.accel_mps2 - 0.3, "late {a_late:?} vs steady {a_steady:?}");
    assert!((a_late.key_time_s.unwrap() - a_steady.key_time_s.unwrap()).abs() < 0.15);
}

#[test]
fn a_prior_that_never_reaches_the_key_point_leaves_the_game_alone() {
    // A prior that stops at 30 m, before the zone: no pull (nothing to be realistic about there).
    let stops = reference_of(|t| if t < 3.0 { 10.0 } else { 0.0 });
    let alone = regulator().decide(&input(Style::Rush, 2.0));
    let d = realistic(1.0, &stops).decide(&input(Style::Rush, 2.0));
    assert_eq!(d, alone);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(80))]
    /// `w_real = 0` is the regulator without the realism term, whatever the reference: every
    /// decision of a closed sequence is identical (bit for bit).
    #[test]
    fn zero_realism_weight_is_the_regulator_without_it(
        bv_v in 2.0f64..18.0, vut_s in -30.0f64..40.0, vut_v in 2.0f64..18.0, tau in 1.0f64..5.0,
        rush in any::<bool>(), v_prior in 2.0f64..18.0, late in 0.5f64..5.0,
    ) {
        let prior = reference_of(|t| if t < late { 0.5 * v_prior } else { v_prior });
        let mut plain = regulator();
        let mut zero = realistic(0.0, &prior);
        let mut inp = input(if rush { Style::Rush } else { Style::Yield }, tau);
        inp.bv.v_mps = bv_v;
        inp.vut = PathState { s_m: vut_s, v_mps: vut_v, age_s: 0.1 };
        for k in 0..30 {
            let a = plain.decide(&inp);
            let b = zero.decide(&inp);
            prop_assert_eq!(a, b);
            // Move both vehicles on, the BV as decided.
            inp.t_s = k as f64 * 0.1 + 0.1;
            inp.bv.s_m += inp.bv.v_mps * 0.1;
            inp.bv.v_mps = a.next_speed_mps;
            inp.bv_accel_mps2 = a.accel_mps2;
            inp.vut.s_m += inp.vut.v_mps * 0.1;
        }
    }
}

#[test]
fn a_vut_that_waits_for_a_yielding_bv_is_reported_below_reach_after_its_wait() {
    let mut r = regulator();
    let mut inp = input(Style::Yield, 2.0);
    inp.vut = PathState { s_m: 55.0, v_mps: 0.0, age_s: 0.1 };
    inp.bv.v_mps = 2.0;
    let mut first_report = None;
    for k in 0..50 {
        inp.t_s = 0.1 * f64::from(k);
        // The measured speed flickers just above zero, as a noisy sensor gives it.
        inp.vut.v_mps = if k % 3 == 0 { 0.12 } else { 0.0 };
        let d = r.decide(&inp);
        if let Some(b) = d.below_reach {
            assert_eq!(b, BelowReach { cause: BelowReachCause::VutWaits, pet_bound_s: None });
            first_report.get_or_insert(inp.t_s);
        }
    }
    let t = first_report.expect("reported");
    assert!((t - WAIT_BELOW_REACH_S).abs() < 0.11, "after {t} s of waiting");
    // Forgotten between runs.
    r.reset();
    inp.t_s = 0.0;
    assert_eq!(r.decide(&inp).below_reach, None);
}

#[test]
fn a_moving_vut_or_a_rushing_bv_is_never_reported_waiting() {
    for (style, v) in [(Style::Yield, 3.0), (Style::Rush, 0.0)] {
        let mut r = regulator();
        let mut inp = input(style, 2.0);
        inp.vut = PathState { s_m: 55.0, v_mps: v, age_s: 0.1 };
        for k in 0..60 {
            inp.t_s = 0.1 * f64::from(k);
            assert_eq!(r.decide(&inp).below_reach, None, "{style:?} at {v} m/s");
        }
    }
}

#[test]
fn what_earlier_runs_showed_is_reported_and_changes_no_plan() {
    let known = BelowReach { cause: BelowReachCause::Campaign, pet_bound_s: Some(2.04) };
    for style in Style::ALL {
        let (mut plain, mut told) = (regulator(), regulator());
        told.set_known_below_reach(Some(known));
        let mut inp = input(style, 1.5);
        for k in 0..30 {
            inp.t_s = 0.1 * f64::from(k);
            let (a, b) = (plain.decide(&inp), told.decide(&inp));
            assert_eq!(b.below_reach, Some(known));
            assert_eq!(Decision { below_reach: None, ..b }, a, "{style:?}: the plan is the same");
            inp.bv.s_m += 1.0;
            inp.vut.s_m += 1.0;
        }
        // It outlives a reset (it is what earlier runs showed, not this run).
        told.reset();
        assert_eq!(told.decide(&input(style, 1.5)).below_reach, Some(known));
    }
}

#[test]
fn settings_beyond_their_bounds_are_refused_naming_the_field() {
    use v2t_model::validate::Validate as _;
    RegulatorParams::default().validate().unwrap();
    for (params, field, bound) in [
        (RegulatorParams { max_input_age_s: 1e-320, ..RegulatorParams::default() }, "max_input_age_s", "[0.01, 5]"),
        (RegulatorParams { w_adv: 9.2e18, ..RegulatorParams::default() }, "w_adv", "[0.000001, 1000000]"),
        (
            RegulatorParams { fallback_decel_mps2: 1e20, ..RegulatorParams::default() },
            "fallback_decel_mps2",
            "[0.5, 12]",
        ),
        (RegulatorParams { w_adv: f64::NAN, ..RegulatorParams::default() }, "w_adv", "NaN"),
        (RegulatorParams { accel_latency_s: 5.0, ..RegulatorParams::default() }, "accel_latency_s", "[0, 2]"),
        (RegulatorParams { accel_latency_s: -0.1, ..RegulatorParams::default() }, "accel_latency_s", "[0, 2]"),
    ] {
        let e = params.validate().unwrap_err();
        assert_eq!(e.field, field);
        assert!(e.to_string().contains(bound), "{e}");
        assert!(Regulator::new(params).is_err(), "{field}: a regulator is built from refused settings");
    }
}

/// The farthest station the last hold plan reaches.
fn farthest(r: &Regulator) -> f64 {
    r.leader_upper.station().iter().fold(f64::NEG_INFINITY, |m, s| m.max(*s))
}

#[test]
fn a_bv_that_gives_way_waits_at_least_the_clearance_before_its_zone() {
    // The VUT stands before its zone: the BV waits, its plan never nearer the zone than the
    // clearance (its front 2.5 m from the VUT's swept path).
    let mut r = regulator();
    let mut inp = input(Style::Yield, 2.0);
    inp.vut.v_mps = 0.0;
    let d = r.decide(&inp);
    assert_eq!(d.status, RegulatorStatus::Waiting, "{d:?}");
    let far = farthest(&r);
    assert!(far <= 40.0 - HOLD_CLEARANCE_M + 0.05, "waits at {far} m, the zone begins at 40 m");
    // Nearer, it stands there.
    inp.bv = PathState { s_m: 30.0, v_mps: 3.0, age_s: 0.05 };
    r.decide(&inp);
    let far = farthest(&r);
    assert!((far - (40.0 - HOLD_CLEARANCE_M)).abs() <= 0.1, "stands at {far} m");
}

#[test]
fn a_bv_that_gives_way_at_a_junction_waits_before_its_stop_line_until_the_vut_commits() {
    // The left turn with the VUT turning: the BV (12 m/s) 28.1 m from its stop line (its front
    // 1 m before the junction's edge), the zone 44.8 m ahead; the VUT (8 m/s) is in its zone at
    // 9.2 s. Yield τ = 2 s: the plan that meets the key time would cross the line at once; the BV
    // holds before it until the VUT is in its zone, slowing from now on.
    let mut r = regulator();
    let mut inp = crate::fixtures::left_turn_start(Target::new(2.0, Style::Yield).unwrap());
    inp.bv.v_mps = 12.0;
    inp.reference_speed_mps = 12.0;
    inp.zone_bv = zone(44.76, 56.21);
    inp.zone_vut = zone(73.76, 85.14);
    inp.stop_line_s_m = Some(28.11);
    let d = r.decide(&inp);
    assert_eq!(d.status, RegulatorStatus::Waiting, "{d:?}");
    assert!(d.key_time_s.is_some_and(|k| k > 9.2), "the key time it aims at is kept: {d:?}");
    let far = farthest(&r);
    assert!(far <= 28.11 + 0.05, "the plan crosses the stop line: {far} m");
    // Slowing early and evenly (2.6 m/s² stops within the 28 m), not at the last moment.
    let a = r.leader_upper.accel();
    assert!(d.accel_mps2 < -1.0, "slows from the start: {}", d.accel_mps2);
    assert!(a.iter().all(|x| *x >= -3.5), "never brakes hard: {a:?}");
    // Once the VUT is in its zone the BV goes for its key time.
    let mut later = inp;
    later.t_s = 9.5;
    later.bv = PathState { s_m: 28.0, v_mps: 0.0, age_s: 0.05 };
    later.vut = PathState { s_m: 75.0, v_mps: 8.0, age_s: 0.15 };
    let d = r.decide(&later);
    assert!(matches!(d.status, RegulatorStatus::Regulating | RegulatorStatus::Degraded), "{d:?}");
    assert!(d.accel_mps2 > 0.5, "{d:?}");
    // Without a map (no stop line) the same BV regulates as before: it need not stop.
    let mut r = regulator();
    inp.stop_line_s_m = None;
    assert!(matches!(r.decide(&inp).status, RegulatorStatus::Regulating | RegulatorStatus::Degraded));
}

#[test]
fn a_bv_too_fast_to_stop_at_its_line_stops_before_the_zone_and_a_bad_line_falls_back() {
    // At 15 m/s, 5 m before its line: it cannot stop there at a comfortable share of its
    // deceleration, so when it must give way (the VUT stands) it stops just before the zone.
    let mut r = regulator();
    let mut inp = input(Style::Yield, 2.0);
    inp.vut.v_mps = 0.0;
    inp.bv.v_mps = 15.0;
    inp.stop_line_s_m = Some(5.0);
    let d = r.decide(&inp);
    assert_eq!(d.status, RegulatorStatus::Waiting, "{d:?}");
    let far = farthest(&r);
    assert!(far > 30.0 && far <= 40.0, "stops at {far} m");
    inp.stop_line_s_m = Some(f64::NAN);
    assert_eq!(r.decide(&inp).status, RegulatorStatus::Fallback);
}

#[test]
fn while_the_vut_crosses_a_yielding_bv_keeps_the_clearance_from_its_path() {
    // The VUT (10 m/s) is in its zone, out at 1 s; the BV (2 m/s) 4 m before its zone would, for
    // τ = 1.5 s, roll on toward the zone's edge while the VUT still passes. It stays 2.5 m back
    // until the VUT is out, and then goes.
    let mut r = regulator();
    let mut inp = input(Style::Yield, 1.5);
    inp.bv = PathState { s_m: 36.0, v_mps: 2.0, age_s: 0.05 };
    inp.vut = PathState { s_m: 60.0, v_mps: 10.0, age_s: 0.05 };
    inp.reference_speed_mps = 2.0;
    let d = r.decide(&inp);
    assert_eq!(d.status, RegulatorStatus::Waiting, "{d:?}");
    let plan = r.leader_upper.station();
    let out_k = 10; // 1 s
    assert!(plan[out_k] <= 40.0 - HOLD_CLEARANCE_M + 0.05, "at the VUT's exit the BV is at {} m", plan[out_k]);
    // Out of the zone: nothing holds it back any more.
    inp.t_s = 1.1;
    inp.vut = PathState { s_m: 71.0, v_mps: 10.0, age_s: 0.05 };
    inp.bv = PathState { s_m: 37.0, v_mps: 1.0, age_s: 0.05 };
    let d = r.decide(&inp);
    assert!(matches!(d.status, RegulatorStatus::Regulating | RegulatorStatus::Degraded), "{d:?}");
}

/// Integrates a plan of accelerations from `(s, v)` at the regulator's step: (time, station, speed)
/// after each step.
fn rollout(s: f64, v: f64, plan: &[f64]) -> Vec<(f64, f64, f64)> {
    let dt = RegulatorParams::default().dt_s;
    let (mut s, mut v) = (s, v);
    plan.iter()
        .enumerate()
        .map(|(k, a)| {
            s += v * dt + 0.5 * a * dt * dt;
            v = (v + a * dt).max(0.0);
            ((k + 1) as f64 * dt, s, v)
        })
        .collect()
}

#[test]
fn a_rushing_bv_with_time_to_spare_slows_before_the_junction_and_crosses_at_speed() {
    // Rush τ = 3 s at a crossing: the VUT (10 m/s) is in its zone at 10 s, so the BV (10 m/s) is
    // out of its zone (40–50 m) at 7 s, on average 7.1 m/s. Its front enters the junction at
    // 27 m (stop line 25 m). In closed loop (the BV applies each decision for one step, the VUT
    // keeps its speed) it does its slowing before the junction and never slows after it: no
    // creeping through the junction.
    let run = |stop_line: Option<f64>| {
        let mut r = regulator();
        let mut inp = input(Style::Rush, 3.0);
        inp.zone_vut = zone(100.0, 110.0);
        inp.stop_line_s_m = stop_line;
        let mut trace = Vec::new();
        while inp.bv.s_m < 50.0 && inp.t_s < 12.0 {
            let d = r.decide(&inp);
            assert!(matches!(d.status, RegulatorStatus::Regulating | RegulatorStatus::Degraded), "{d:?}");
            inp.bv.s_m += inp.bv.v_mps * 0.1 + 0.5 * d.accel_mps2 * 0.01;
            inp.bv.v_mps = (inp.bv.v_mps + d.accel_mps2 * 0.1).max(0.0);
            inp.bv_accel_mps2 = d.accel_mps2;
            inp.vut.s_m += inp.vut.v_mps * 0.1;
            inp.t_s += 0.1;
            trace.push((inp.t_s, inp.bv.s_m, inp.bv.v_mps));
        }
        trace
    };
    let trace = run(Some(25.0));
    let out = trace.last().unwrap();
    // It arrives at its commit station slower than it crosses, so it is a little late (a PET
    // within 10 % of τ, against a VUT that does not react).
    assert!(out.1 >= 50.0 && (out.0 - 7.0).abs() <= 0.3 + 1e-6, "out of the zone at {} s, 7 s asked", out.0);
    let speeds_from = |t: &[(f64, f64, f64)]| t.iter().filter(|p| p.1 >= 27.0).map(|p| p.2).collect::<Vec<f64>>();
    let after = speeds_from(&trace);
    assert!(after.windows(2).all(|w| w[1] >= w[0] - 0.05), "slows in the junction: {after:?}");
    // Without a stop line it is still slowing where the junction begins.
    let plain = speeds_from(&run(None));
    assert!(plain.windows(2).any(|w| w[1] < w[0] - 1e-3), "{plain:?}");
}

#[test]
fn a_rushing_bv_in_the_zone_of_a_crossing_never_slows_for_a_late_vut() {
    // The BV (6 m/s) is 2 m into its zone; the VUT comes slowly: to keep τ = 2 s the BV would
    // have to stay in the VUT's path for 18 s more. It clears the zone at no less than its speed,
    // and says the PET it expects.
    let mut r = regulator();
    let mut inp = input(Style::Rush, 2.0);
    inp.bv = PathState { s_m: 42.0, v_mps: 6.0, age_s: 0.05 };
    inp.vut = PathState { s_m: 0.0, v_mps: 5.0, age_s: 0.15 };
    inp.zone_vut = zone(100.0, 110.0);
    let d = r.decide(&inp);
    assert!(matches!(d.status, RegulatorStatus::Regulating | RegulatorStatus::Degraded), "{d:?}");
    assert!(d.key_time_s.is_some_and(|k| k <= 8.0 / 6.0 + 0.05), "{d:?}");
    assert!(d.predicted_pet_s.is_some_and(|p| p > 15.0), "{d:?}");
    let plan = r.planned_accels(&d).unwrap();
    let path = rollout(inp.bv.s_m, inp.bv.v_mps, plan);
    assert!(path.iter().take_while(|p| p.1 < 50.0).all(|p| p.2 >= 6.0 - 0.05), "slows in the zone: {path:?}");
}

#[test]
fn a_rushing_bv_with_much_time_to_spare_keeps_rolling_instead_of_stopping_before_the_junction() {
    // The VUT is far (in its zone at 20 s), so the BV (5 m/s) has 17 s for its 50 m. Slowing to
    // cross at speed would mean crawling the 27 m to the junction at 1.6 m/s, and a VUT that then
    // slows for it would hold it there, standing, until both go at once: it rolls on instead,
    // at about its average speed.
    let mut r = regulator();
    let mut inp = input(Style::Rush, 3.0);
    inp.bv.v_mps = 5.0;
    inp.reference_speed_mps = 10.0;
    inp.zone_vut = zone(200.0, 210.0);
    inp.stop_line_s_m = Some(25.0);
    let d = r.decide(&inp);
    assert_eq!(d.status, RegulatorStatus::Regulating, "{d:?}");
    let path = rollout(inp.bv.s_m, inp.bv.v_mps, r.planned_accels(&d).unwrap());
    let slowest = path.iter().map(|p| p.2).fold(f64::INFINITY, f64::min);
    assert!(slowest >= 2.0, "crawls at {slowest} m/s: {path:?}");
}

/// What a VUT did on its route in earlier runs: 10 m/s to 30 m, slowing evenly in arc length to
/// 5 m/s at 50 m, 5 m/s on to 100 m.
fn slowing_route() -> RouteSpeed {
    let speeds = (0..=50)
        .map(|i| {
            let s = 2.0 * f64::from(i);
            if s <= 30.0 {
                10.0
            } else if s <= 50.0 {
                10.0 - 5.0 * (s - 30.0) / 20.0
            } else {
                5.0
            }
        })
        .collect();
    RouteSpeed { step_m: 2.0, speeds_mps: speeds, runs: 1 }
}

#[test]
fn a_learned_route_speed_is_where_the_follower_slows_down() {
    // Rush, τ = 2 s. The VUT at 10 m/s reaches its zone (60 m) at 6 s if it keeps its speed; as
    // learned, at 3 + 20 / ∫(10 → 5) + 2 ≈ 7.77 s (the slowdown's 20 m take 4 ln 2 s).
    let arrival = 3.0 + 4.0 * 2f64.ln() + 2.0;
    let mut r = regulator();
    r.set_route_speed(Some(slowing_route())).unwrap();
    let d = r.decide(&input(Style::Rush, 2.0));
    let key = d.key_time_s.unwrap();
    assert!((key - (arrival - 2.0)).abs() < 0.1, "key time {key}, the VUT in at {arrival:.2} s");
    assert!((d.predicted_pet_s.unwrap() - 2.0).abs() < 0.05, "{d:?}");
    // A learned speed that is the VUT's own changes nothing.
    let mut r = regulator();
    r.set_route_speed(Some(RouteSpeed { speeds_mps: vec![10.0; 51], ..slowing_route() })).unwrap();
    let d = r.decide(&input(Style::Rush, 2.0));
    assert!((d.key_time_s.unwrap() - 4.0).abs() < 0.05, "{d:?}");
    // It outlives a reset (it belongs to the test, not to one run).
    r.reset();
    assert!(r.route_speed().is_some());
}

#[test]
fn a_vut_faster_than_learned_is_believed_for_a_while() {
    // Learned 10 m/s everywhere, the VUT comes at 12 m/s: between 60/12 and 60/10 s.
    let mut r = regulator();
    r.set_route_speed(Some(RouteSpeed { speeds_mps: vec![10.0; 51], ..slowing_route() })).unwrap();
    let mut inp = input(Style::Rush, 2.0);
    inp.vut.v_mps = 12.0;
    let key = r.decide(&inp).key_time_s.unwrap() + 2.0;
    assert!(key > 5.0 + 0.2 && key < 6.0 - 0.2, "the VUT predicted in at {key} s");
}

#[test]
fn a_standing_vut_keeps_standing_whatever_was_learned() {
    let mut inp = input(Style::Yield, 2.0);
    inp.vut = PathState { s_m: 50.0, v_mps: 0.0, age_s: 0.1 };
    inp.bv.s_m = 20.0;
    let plain = regulator().decide(&inp);
    let mut r = regulator();
    r.set_route_speed(Some(slowing_route())).unwrap();
    let learned = r.decide(&inp);
    assert_eq!((learned.status, learned.key_time_s), (plain.status, plain.key_time_s));
}

#[test]
fn a_refused_route_speed_names_its_field_and_keeps_the_one_before() {
    let mut r = regulator();
    r.set_route_speed(Some(slowing_route())).unwrap();
    let mut bad = slowing_route();
    bad.speeds_mps[7] = f64::NAN;
    let e = r.set_route_speed(Some(bad)).unwrap_err().to_string();
    assert!(e.contains("route_speed.speeds_mps[7]"), "{e}");
    assert_eq!(r.route_speed(), Some(&slowing_route()));
}

/// Settings as a file written before the jerk weight and the prior's shape were settings.
fn written_before_the_later_settings() -> RegulatorParams {
    let text = r#"{"horizon": 50, "dt_s": 0.1, "w_adv": 1.0, "w_real": 0.1, "safety_margin_s": 0.5,
                   "max_input_age_s": 0.5, "fallback_decel_mps2": 2.0, "vut_headway_s": 2.0}"#;
    serde_json::from_str(text).unwrap()
}

#[test]
fn the_plans_jerk_weight_is_a_setting_that_smooths_the_plan() {
    // A file written before the setting reads as the weight the plans always had.
    let p = written_before_the_later_settings();
    assert_eq!(p.w_jerk, 3.0);
    let e = RegulatorParams { w_jerk: 0.0, ..p }.validate().unwrap_err().to_string();
    assert!(e.contains("w_jerk"), "{e}");
    // From rest, asked to be 40 m on in 4 s: the smoother plan starts more gently.
    let first_jerk = |w_jerk: f64| {
        let mut r = Regulator::new(RegulatorParams { w_jerk, ..p }).unwrap();
        let mut inp = input(Style::Rush, 2.0);
        inp.bv.v_mps = 5.0;
        let d = r.decide(&inp);
        let a = r.planned_accels(&d).unwrap();
        (a[1] - a[0]).abs().max((a[0] - inp.bv_accel_mps2).abs())
    };
    assert!(first_jerk(30.0) < first_jerk(3.0), "{} {}", first_jerk(30.0), first_jerk(3.0));
}

#[test]
fn the_plan_keeps_the_priors_acceleration_shape_as_asked_and_lands_where_the_game_says() {
    // A file written before the setting reads as 0; more than 1 is refused by name.
    let p = written_before_the_later_settings();
    assert_eq!(p.shape_share, 0.0);
    let e = RegulatorParams { shape_share: 1.5, ..p }.validate().unwrap_err().to_string();
    assert!(e.contains("shape_share"), "{e}");
    // A prior that eases off and presses on every 2 s around 12 m/s, at the shipped jerk weight.
    let wavy = reference_of(|t| 12.0 + 1.2 * (std::f64::consts::PI * t).sin());
    let plan = |shape_share: f64, w_real: f64| {
        let params = RegulatorParams { w_jerk: 30.0, w_real, shape_share, ..RegulatorParams::default() };
        let mut r = Regulator::new(params).unwrap();
        r.set_reference(wavy.iter().copied()).unwrap();
        let mut inp = input(Style::Rush, 2.0);
        inp.bv.v_mps = 12.0;
        let d = r.decide(&inp);
        (d, r.planned_accels(&d).unwrap().to_vec())
    };
    // How much the plan's acceleration swings over its first 3 s (before the shape fades).
    let swing = |a: &[f64]| {
        let first = &a[..30];
        first.iter().fold(f64::NEG_INFINITY, |m, x| m.max(*x)) - first.iter().fold(f64::INFINITY, |m, x| m.min(*x))
    };
    let ((d_flat, flat), (d_shaped, shaped)) = (plan(0.0, 0.1), plan(1.0, 0.1));
    assert!(swing(&shaped) > 2.0 * swing(&flat), "swing {:.2} shaped vs {:.2}", swing(&shaped), swing(&flat));
    // The key time and the PET are the game's either way.
    assert_eq!(d_shaped.status, RegulatorStatus::Regulating, "{d_shaped:?}");
    let (k_flat, k_shaped) = (d_flat.key_time_s.unwrap(), d_shaped.key_time_s.unwrap());
    assert!((k_flat - k_shaped).abs() < 0.05, "{k_flat} vs {k_shaped}");
    // Without the realism term there is no prior to take a shape from: the same plan bit for bit.
    assert_eq!(plan(1.0, 0.0), plan(0.0, 0.0));
}

/// A rushing BV 30 m before a curve it may take at 8.85 m/s, at 14 m/s and in a hurry (τ 5 s):
/// its plan slows for the curve along the braking envelope of [`CURVE_BRAKE_SHARE`] of its
/// largest deceleration, so that its actuator, which follows the plan late, is not still too fast
/// in the curve. Before, the plan held its speed until the curve was within reach of the step and
/// then braked at up to 4.8 m/s²: the regulated BV of the BV-turning card entered its turn at
/// 11.6 m/s, 5.5 m/s² of lateral acceleration for a limit of 4.5.
#[test]
fn a_plan_slows_for_a_curve_ahead_along_its_braking_envelope() {
    let mut r = regulator();
    let mut inp = input(Style::Rush, 5.0);
    inp.bv.v_mps = 14.0;
    inp.vut.s_m = -40.0;
    let (curve_at, curve_mps) = (30.0, 8.85);
    let limit = |s: f64| if s >= curve_at { curve_mps } else { f64::INFINITY };
    let d = r.decide_on_path(&inp, &limit);
    let brake = CURVE_BRAKE_SHARE * r.params().bv.max_decel_mps2;
    let envelope = |s: f64| (curve_mps * curve_mps + 2.0 * brake * (curve_at - s).max(0.0)).sqrt();
    let dt = r.params().dt_s;
    let (mut s, mut v) = (inp.bv.s_m, inp.bv.v_mps);
    let accels = r.planned_accels(&d).unwrap().to_vec();
    for (k, a) in accels.iter().enumerate() {
        let v1 = (v + a * dt).max(0.0);
        s += 0.5 * (v + v1) * dt;
        v = v1;
        assert!(v <= envelope(s) + 0.05, "step {k}: {v:.2} m/s at {s:.1} m, envelope {:.2} m/s", envelope(s));
    }
    assert!(s > curve_at, "the plan reaches the curve within the horizon ({s:.1} m)");
}

#[test]
fn a_bv_still_speeding_up_plans_its_curve_slower_by_the_speed_its_actuator_still_adds() {
    let (curve_at, curve_mps) = (30.0, 8.85);
    let limit = |s: f64| if s >= curve_at { curve_mps } else { f64::INFINITY };
    // The fastest the plan is anywhere in the curve, with the BV's last request `accel`.
    let in_curve = |accel: f64| {
        let mut r = regulator();
        let mut inp = input(Style::Rush, 5.0);
        inp.bv.v_mps = 14.0;
        inp.vut.s_m = -40.0;
        inp.bv_accel_mps2 = accel;
        let d = r.decide_on_path(&inp, &limit);
        let dt = r.params().dt_s;
        let (mut s, mut v, mut fastest) = (inp.bv.s_m, inp.bv.v_mps, 0.0f64);
        for a in r.planned_accels(&d).unwrap() {
            let v1 = (v + a * dt).max(0.0);
            s += 0.5 * (v + v1) * dt;
            v = v1;
            if s >= curve_at {
                fastest = fastest.max(v);
            }
        }
        assert!(s > curve_at, "the plan reaches the curve within the horizon ({s:.1} m)");
        fastest
    };
    // A file written before the setting reads as the tracker's latency.
    let latency = written_before_the_later_settings().accel_latency_s;
    assert_eq!(latency, RegulatorParams::default().accel_latency_s);
    let (holding, braking, speeding_up) = (in_curve(0.0), in_curve(-2.0), in_curve(3.0));
    assert!(latency > 0.0);
    // Holding or braking: up to the curve's speed; a request that brakes adds no margin.
    assert!((holding - curve_mps).abs() < 0.1, "holding speed: {holding:.2} m/s in the curve");
    assert!((braking - holding).abs() < 0.02, "braking: {braking:.3}, holding: {holding:.3} m/s");
    // Speeding up at 3 m/s²: the actuator still adds `latency` × 3 m/s, which the plan leaves free.
    let expected = curve_mps - 3.0 * latency;
    assert!((speeding_up - expected).abs() < 0.1, "speeding up: {speeding_up:.2} m/s, expected {expected:.2}");
}
