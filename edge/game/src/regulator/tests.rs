use super::*;
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
        reference_key_time_s: None,
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
