use super::*;
use proptest::prelude::*;

fn shape(event: EventKind, horizon: usize) -> QpShape {
    QpShape { horizon, dt_s: 0.1, w_speed: 1.0, w_accel: 0.5, w_jerk: 0.5, w_slack: 1e4, event }
}

fn input(s0: f64, v0: f64, event_t_s: Option<f64>, station: f64) -> QpInput {
    QpInput {
        s0_m: s0,
        v0_mps: v0,
        a_prev_mps2: 0.0,
        v_max_mps: 20.0,
        a_max_mps2: 3.0,
        d_max_mps2: 6.0,
        event_t_s,
        event_station_m: station,
    }
}

fn qp(event: EventKind, horizon: usize, v_ref: f64) -> LongitudinalQp {
    let mut qp = LongitudinalQp::new(shape(event, horizon)).unwrap();
    qp.v_ref_mut().iter_mut().for_each(|v| *v = v_ref);
    qp
}

#[test]
fn without_an_event_it_cruises_at_the_reference() {
    let mut q = qp(EventKind::Upper, 30, 10.0);
    assert_eq!(q.solve(&input(0.0, 10.0, None, 0.0)), QpStatus::Solved);
    assert!(q.accel().iter().all(|a| a.abs() < 1e-3), "{:?}", q.accel());
    assert!((q.station()[30] - 30.0).abs() < 1e-4);
    assert!(q.slack_m() < 1e-6);
}

#[test]
fn an_equal_event_is_met_inside_and_beyond_the_horizon() {
    for (horizon, t) in [(50, 3.0), (30, 6.5)] {
        let mut q = qp(EventKind::Equal, horizon, 10.0);
        // At 10 m/s it would be at 10 t; ask to be 8 m short of that.
        let station = 10.0 * t - 8.0;
        let st = q.solve(&input(0.0, 10.0, Some(t), station));
        assert!(matches!(st, QpStatus::Solved | QpStatus::AlmostSolved));
        assert!(q.slack_m() < 1e-4, "slack {}", q.slack_m());
        let reached = q.time_at_station(station).unwrap();
        assert!((reached - t).abs() < 0.02, "horizon {horizon}: reaches at {reached} s, asked {t} s");
        assert!(q.speed().iter().all(|v| *v >= -1e-6));
        assert!(q.accel().iter().all(|a| *a <= 3.0 + 1e-6 && *a >= -6.0 - 1e-6));
    }
}

#[test]
fn an_impossible_event_is_reported_as_slack() {
    let mut q = qp(EventKind::Upper, 30, 10.0);
    // 10 m/s, asked to stay behind 3 m from now within 1 s: braking at 6 m/s² needs 8.3 m.
    let st = q.solve(&input(0.0, 10.0, Some(1.0), 3.0));
    assert!(matches!(st, QpStatus::Solved | QpStatus::AlmostSolved));
    assert!(q.slack_m() > 1.0, "slack {}", q.slack_m());
    assert!(q.accel()[0] < -5.9, "brakes as hard as it can: {}", q.accel()[0]);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(40))]
    /// The follower QP's solution satisfies the KKT conditions for any state and order constraint.
    #[test]
    fn follower_solutions_satisfy_kkt(
        v0 in 0.0f64..15.0, v_ref in 0.0f64..15.0, t in 0.2f64..9.0, station in 5.0f64..80.0, lower in any::<bool>(),
    ) {
        let kind = if lower { EventKind::Lower } else { EventKind::Upper };
        let mut q = qp(kind, 50, v_ref);
        let st = q.solve(&input(0.0, v0, Some(t), station));
        prop_assert!(matches!(st, QpStatus::Solved | QpStatus::AlmostSolved), "{:?}", st);
        let (stat, primal, comp) = q.kkt_residuals();
        // Primal feasibility relative to the distances in play (a missed event of 60 m leaves
        // residuals of 1e-5 m in the rows it spans).
        prop_assert!(stat < 1e-4 && primal < 1e-5 * (1.0 + station) && comp < 1e-4, "KKT {stat} {primal} {comp}");
        // The order constraint holds up to the reported slack.
        let s_t = {
            let k = (t / 0.1).floor() as usize;
            let a = t / 0.1 - k as f64;
            if k >= 50 { q.station()[50] + (t - 5.0) * q.speed()[50] } else { (1.0 - a) * q.station()[k] + a * q.station()[k + 1] }
        };
        if lower { prop_assert!(s_t >= station - q.slack_m() - 1e-4) } else { prop_assert!(s_t <= station + q.slack_m() + 1e-4) }
    }
}

/// A human-like acceleration shape: easing off and pressing on every 1.5 s (m/s²).
fn swell(k: usize) -> f64 {
    let t = k as f64 * 0.1;
    -0.8 * (std::f64::consts::PI * t / 0.75).sin()
}

/// The plan's accelerations for the speed reference that `swell` drives from 10 m/s, with or
/// without `swell` as the acceleration shape, under the shipped weights' ratio (jerk 30, effort 1,
/// speed 0.2).
fn shaped(with_shape: bool) -> Vec<f64> {
    let shape = QpShape { w_jerk: 30.0, w_accel: 1.0, w_speed: 0.2, ..shape(EventKind::Equal, 50) };
    let mut q = LongitudinalQp::new(shape).unwrap();
    let mut v = 10.0;
    for (k, r) in q.v_ref_mut().iter_mut().enumerate() {
        v += swell(k) * 0.1;
        *r = v;
    }
    if with_shape {
        q.a_ref_mut().iter_mut().enumerate().for_each(|(k, a)| *a = swell(k));
    }
    assert!(matches!(q.solve(&input(0.0, 10.0, None, 0.0)), QpStatus::Solved | QpStatus::AlmostSolved));
    let (stat, _, _) = q.kkt_residuals();
    assert!(stat < 1e-4, "stationarity {stat}");
    q.accel().to_vec()
}

#[test]
fn an_acceleration_shape_is_kept_under_a_heavy_jerk_weight() {
    // How far the plan's jerk is from the shape's, m/s³ RMS.
    let off = |a: &[f64]| {
        let n = a.len() - 1;
        ((1..=n).map(|k| ((a[k] - a[k - 1]) - (swell(k) - swell(k - 1))).powi(2)).sum::<f64>() / n as f64).sqrt() / 0.1
    };
    let (with, without) = (shaped(true), shaped(false));
    // Without it, the jerk weight irons the swell out; with it, the plan eases off and presses on
    // as the shape does.
    assert!(
        off(&with) < 0.25 * off(&without),
        "jerk off the shape: with {:.3}, without {:.3}",
        off(&with),
        off(&without)
    );
    let swing =
        |a: &[f64]| a.iter().fold(f64::NEG_INFINITY, |m, x| m.max(*x)) - a.iter().fold(f64::INFINITY, |m, x| m.min(*x));
    assert!(swing(&with) > 1.2 && swing(&without) < 0.5 * swing(&with), "{} {}", swing(&with), swing(&without));
    // The first step still keeps to the acceleration applied last (0).
    assert!(with[0].abs() < 0.2, "{}", with[0]);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(30))]
    /// With any acceleration reference the leader's solution satisfies the KKT conditions and
    /// still meets an exact event it can meet.
    #[test]
    fn an_acceleration_shape_keeps_the_solution_optimal_and_the_event_met(
        amp in 0.0f64..2.0, period in 1.0f64..8.0, v0 in 5.0f64..12.0, t in 2.0f64..6.0,
    ) {
        let mut q = qp(EventKind::Equal, 50, v0);
        q.a_ref_mut().iter_mut().enumerate().for_each(|(k, a)| *a = amp * (k as f64 * 0.1 * std::f64::consts::TAU / period).sin());
        let station = v0 * t * 0.9;
        let st = q.solve(&input(0.0, v0, Some(t), station));
        prop_assert!(matches!(st, QpStatus::Solved | QpStatus::AlmostSolved), "{:?}", st);
        let (stat, primal, comp) = q.kkt_residuals();
        prop_assert!(stat < 1e-4 && primal < 1e-5 * (1.0 + station) && comp < 1e-4, "KKT {stat} {primal} {comp}");
        prop_assert!(q.slack_m() < 1e-3, "slack {}", q.slack_m());
    }
}
