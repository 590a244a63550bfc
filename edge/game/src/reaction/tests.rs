#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing, clippy::panic)]

use super::*;

fn scene() -> Scene {
    Scene {
        zone_bv: OccupancyInterval { enter_s_m: 40.0, exit_s_m: 50.0 },
        zone_vut: OccupancyInterval { enter_s_m: 60.0, exit_s_m: 70.0 },
        vut_accel_mps2: 2.0,
        vut_decel_mps2: 6.0,
    }
}

/// The true driver `truth` (`None`: does not react) at 10 m/s from 0 against a BV moving as `bv`,
/// measured every 0.1 s into a belief; returns the belief and the VUT's time at its zone entry.
fn drive(truth: Option<Reaction>, bv: &BvMotion) -> (ReactionBelief, Option<f64>) {
    let sc = scene();
    let mut belief = ReactionBelief::default();
    let (mut s, mut v) = (0.0, 10.0);
    let mut entry = None;
    let mut driver = Driver::new(truth);
    for k in 0..200 {
        let t = k as f64 * 0.1;
        let (bs, bvv) = bv.at(t);
        let snap = Snapshot { bv_s_m: bs, bv_v_mps: bvv, vut_s_m: s, vut_v_mps: v };
        belief.observe(t, snap, &sc, Some(&Constant(10.0)));
        let a = driver.accel(t, 0.1, &sc, &snap, 10.0);
        let v_next = (v + a * 0.1).max(0.0);
        let s_next = s + 0.5 * (v + v_next) * 0.1;
        if entry.is_none() && s_next >= sc.zone_vut.enter_s_m {
            entry = Some(t + (sc.zone_vut.enter_s_m - s) / (s_next - s) * 0.1);
        }
        (s, v) = (s_next, v_next);
    }
    (belief, entry)
}

/// A BV 40 m before its zone that crosses it at 10 m/s, out at `exit_s`.
fn bv_out_at(exit_s: f64) -> BvMotion {
    let v = 50.0 / exit_s;
    BvMotion::new(0.0, v, exit_s, 50.0, v)
}

#[test]
fn the_grid_holds_every_driver_once_and_index_0_does_not_react() {
    assert!(hypothesis(0).is_none());
    assert!(hypothesis(HYPOTHESES).is_none());
    let all: Vec<Reaction> = (1..HYPOTHESES).filter_map(hypothesis).collect();
    assert_eq!(all.len(), HYPOTHESES - 1);
    for (i, a) in all.iter().enumerate() {
        for b in &all[i + 1..] {
            assert_ne!(a, b);
        }
    }
}

#[test]
fn a_vut_that_does_not_react_arrives_at_its_free_motion_whatever_the_bv_does() {
    let sc = scene();
    let t = rollout(None, &sc, &bv_out_at(5.5), (0.0, 10.0), &Constant(10.0), 10.0, 60.0).unwrap();
    assert!((t - 6.0).abs() < 1e-9, "{t}");
}

#[test]
fn a_vut_that_wants_a_gap_of_2_s_arrives_at_least_that_long_after_a_bv_that_leaves_1_s_before_it() {
    let sc = scene();
    let r = Reaction { gap_s: 2.0, decel_mps2: 2.0, restart_s: 0.0 };
    let bv = bv_out_at(5.0);
    let free = rollout(None, &sc, &bv, (0.0, 10.0), &Constant(10.0), 10.0, 60.0).unwrap();
    let reacted = rollout(Some(&r), &sc, &bv, (0.0, 10.0), &Constant(10.0), 10.0, 60.0).unwrap();
    assert!((free - 6.0).abs() < 1e-9);
    assert!(reacted - 5.0 >= 1.5, "it brakes for the BV: in at {reacted} s, the BV out at 5 s");
    // A BV out 2.5 s before the VUT's free arrival leaves it the gap it wants: no reaction.
    let early = rollout(Some(&r), &sc, &bv_out_at(3.5), (0.0, 10.0), &Constant(10.0), 10.0, 60.0).unwrap();
    assert!((early - 6.0).abs() < 1e-9, "{early}");
}

#[test]
fn a_bv_standing_before_its_zone_is_not_waited_for() {
    let sc = scene();
    let r = Reaction { gap_s: 3.0, decel_mps2: 1.0, restart_s: 1.0 };
    let parked = BvMotion::new(10.0, 0.0, 1.0, 10.0, 0.0);
    let t = rollout(Some(&r), &sc, &parked, (0.0, 10.0), &Constant(10.0), 10.0, 60.0).unwrap();
    assert!((t - 6.0).abs() < 1e-9, "{t}");
}

#[test]
fn a_standing_vut_that_restarts_late_arrives_that_much_later() {
    let sc = scene();
    let quick = Reaction { gap_s: 1.0, decel_mps2: 2.0, restart_s: 0.0 };
    let slow = Reaction { restart_s: 1.0, ..quick };
    // The VUT stands 5 m before its zone; the BV is in its zone and leaves at 1 s.
    let bv = BvMotion::new(45.0, 5.0, 1.0, 50.0, 5.0);
    let a = rollout(Some(&quick), &sc, &bv, (55.0, 0.0), &Constant(10.0), 10.0, 60.0).unwrap();
    let b = rollout(Some(&slow), &sc, &bv, (55.0, 0.0), &Constant(10.0), 10.0, 60.0).unwrap();
    assert!((b - a - 1.0).abs() < 0.15, "{a} {b}");
}

#[test]
fn the_belief_finds_the_gap_a_reacting_vut_keeps() {
    for gap in [1.0, 2.0, 3.0] {
        let truth = Reaction { gap_s: gap, decel_mps2: 2.0, restart_s: 0.0 };
        // The BV leaves half the gap before the VUT's free arrival at 6 s.
        let (belief, entry) = drive(Some(truth), &bv_out_at(6.0 - 0.5 * gap));
        assert!(entry.unwrap() > 6.2, "it braked");
        let id = belief.identified();
        assert!(id.reacts_probability > 0.9, "gap {gap}: {id:?}");
        assert!((id.gap_mean_s - gap).abs() <= 0.5, "gap {gap}: {id:?}");
        assert!(id.informative_cycles > 0);
    }
}

#[test]
fn the_belief_learns_that_a_vut_driving_through_a_short_gap_does_not_react() {
    let (belief, entry) = drive(None, &bv_out_at(5.0));
    assert!((entry.unwrap() - 6.0).abs() < 0.01);
    let id = belief.identified();
    assert!(id.reaction.is_none(), "{id:?}");
    assert!(id.reacts_probability < 0.5, "{id:?}");
    // A VUT that meets no conflict teaches nothing: the prior stays.
    let (calm, _) = drive(None, &BvMotion::new(0.0, 0.0, 1.0, 0.0, 0.0));
    assert_eq!(calm.identified().informative_cycles, 0);
    assert!((calm.probabilities()[0] - DEFAULT_NONE_PRIOR).abs() < 1e-9);
}

#[test]
fn the_posterior_carries_to_the_next_run_and_a_bad_one_is_refused_by_name() {
    let truth = Reaction { gap_s: 2.0, decel_mps2: 2.0, restart_s: 0.0 };
    let (belief, _) = drive(Some(truth), &bv_out_at(5.0));
    let post = belief.posterior();
    let mut next = ReactionBelief::default();
    next.set_prior(Some(&post)).unwrap();
    assert_eq!(next.identified().reaction, belief.identified().reaction);
    let mut bad = post.clone();
    bad.probabilities[3] = f64::NAN;
    let e = next.set_prior(Some(&bad)).unwrap_err().to_string();
    assert!(e.contains("probabilities[3]"), "{e}");
    bad.probabilities.pop();
    let e = next.set_prior(Some(&bad)).unwrap_err().to_string();
    assert!(e.contains("probabilities") && e.contains(&HYPOTHESES.to_string()), "{e}");
    // The refused priors left the good one in place.
    assert_eq!(next.identified().reaction, belief.identified().reaction);
}

#[test]
fn garbage_measurements_teach_nothing() {
    let sc = scene();
    let mut b = ReactionBelief::default();
    let snap = Snapshot { bv_s_m: 30.0, bv_v_mps: 10.0, vut_s_m: 40.0, vut_v_mps: 10.0 };
    b.observe(0.0, snap, &sc, None);
    b.observe(0.1, Snapshot { vut_v_mps: f64::NAN, ..snap }, &sc, None);
    b.observe(0.2, Snapshot { vut_v_mps: 2.0, ..snap }, &sc, None);
    b.observe(5.0, Snapshot { vut_v_mps: 0.0, ..snap }, &sc, None);
    let p = b.probabilities();
    assert!(p.iter().all(|q| q.is_finite()));
    assert!((p.iter().sum::<f64>() - 1.0).abs() < 1e-9);
}

#[test]
fn bv_motion_meets_its_key_point_on_time() {
    let m = BvMotion::new(0.0, 12.0, 4.0, 30.0, 8.0);
    let (s, _) = m.at(4.0 - 1e-9);
    assert!((s - 30.0).abs() < 1e-6, "{s}");
    let (s, v) = m.at(5.0);
    assert!((s - 38.0).abs() < 1e-9 && (v - 8.0).abs() < 1e-12);
    // A BV with time to spare slows early to the speed that gets it there on time.
    let slow = BvMotion::new(0.0, 10.0, 10.0, 30.0, 5.0);
    for k in 0..100 {
        let (s, v) = slow.at(k as f64 * 0.1);
        assert!(v >= 0.0 && s <= 30.0 + 1e-9, "{k}: {s} {v}");
    }
    assert!((slow.at(10.0 - 1e-9).0 - 30.0).abs() < 1e-6, "{:?}", slow.at(10.0 - 1e-9));
    // One that cannot slow gently enough stops short of it.
    let stop = BvMotion::new(0.0, 10.0, 10.0, 20.0, 5.0);
    for k in 0..100 {
        let (s, v) = stop.at(k as f64 * 0.1);
        assert!(v >= 0.0 && s <= 20.0 + 1e-9, "{k}: {s} {v}");
    }
}
