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
