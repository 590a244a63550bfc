//! Heap allocations per decision after warm-up. The regulator's own code allocates nothing per
//! cycle; what remains comes from inside Clarabel's `solve`, which this test measures on a bare
//! QP and then bounds the regulator by (at most five solves per decision).

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic, clippy::indexing_slicing)] // test code

use v2t_game::qp::{EventKind, LongitudinalQp, QpInput, QpShape};
use v2t_game::reaction::ReactionPosterior;
use v2t_game::reference::ReferenceSample;
use v2t_game::regulator::{Regulator, RegulatorParams};
use v2t_game::route_speed::RouteSpeed;
use v2t_model::{Style, Target};
use v2t_test_support::alloc::count;

#[global_allocator]
static GLOBAL: v2t_test_support::alloc::Counting = v2t_test_support::alloc::Counting;

#[test]
fn allocations_per_decision_come_only_from_the_solver() {
    // A bare QP solve (update + solve) after warm-up.
    let shape = QpShape {
        horizon: 50,
        dt_s: 0.1,
        w_speed: 1.0,
        w_accel: 1.0,
        w_jerk: 2.0,
        w_slack: 1e4,
        event: EventKind::Equal,
    };
    let mut qp = LongitudinalQp::new(shape).unwrap();
    qp.v_ref_mut().iter_mut().for_each(|v| *v = 8.0);
    let mut per_solve = 0;
    for k in 0..30 {
        let input = QpInput {
            s0_m: k as f64,
            v0_mps: 9.0,
            a_prev_mps2: 0.0,
            v_max_mps: 20.0,
            a_max_mps2: 3.0,
            d_max_mps2: 6.0,
            event_t_s: Some(4.0 - 0.1 * k as f64),
            event_station_m: 40.0,
        };
        let (_, n) = count(|| qp.solve(&input));
        if k >= 5 {
            per_solve = per_solve.max(n);
        }
    }
    // The regulator over an approach, after warm-up: without the realism term, with it
    // around a prior (10 m/s, then easing to 7 m/s), whose reference is set once before.
    let prior: Vec<ReferenceSample> = {
        let mut s = 0.0;
        (0..300)
            .map(|k| {
                let t = k as f64 * 0.1;
                let v = if t < 2.0 { 10.0 } else { 7.0 };
                let q = ReferenceSample { t_s: t, s_m: s, v_mps: v };
                s += v * 0.1;
                q
            })
            .collect()
    };
    // And with a follower that knows how the VUT drives its route (slowing to 5 m/s from 60 m on).
    let route =
        RouteSpeed { step_m: 2.0, speeds_mps: (0..=100).map(|i| if i < 30 { 10.0 } else { 5.0 }).collect(), runs: 1 };
    // And with a regulator sure that the VUT reacts to the BV (the reacting follower's search
    // runs every decision before the zone).
    let last = v2t_game::reaction::hypothesis(v2t_game::reaction::HYPOTHESES - 1);
    let reacting = ReactionPosterior::sure_of(last, 0.9, 10).unwrap();
    let mut worst = 0;
    for (w_real, learned, prior_reaction) in
        [(0.0, None, None), (1.0, None, None), (0.0, Some(route.clone()), None), (1.0, Some(route), Some(&reacting))]
    {
        let mut reg = Regulator::new(RegulatorParams { w_real, ..RegulatorParams::default() }).unwrap();
        reg.set_reference(prior.iter().copied()).unwrap();
        reg.set_route_speed(learned).unwrap();
        reg.set_reaction_prior(prior_reaction).unwrap();
        for style in [Style::Rush, Style::Yield] {
            reg.reset();
            let mut inp = v2t_game::fixtures::left_turn_start(Target::new(2.0, style).unwrap());
            for k in 0..120 {
                let (d, n) = count(|| reg.decide(&inp));
                if k >= 5 {
                    worst = worst.max(n);
                }
                inp.t_s += 0.1;
                inp.bv.v_mps = (inp.bv.v_mps + d.accel_mps2 * 0.1).max(0.0);
                inp.bv.s_m += inp.bv.v_mps * 0.1;
                inp.bv_accel_mps2 = d.accel_mps2;
                inp.vut.s_m += inp.vut.v_mps * 0.1;
            }
        }
    }
    println!("allocations: bare solve ≤ {per_solve}, decision ≤ {worst}");
    // The longest decision solves five QPs: the follower twice (the fixed point), the leader, the
    // safety check and, when that fails, the hold-back plan (a realism pull can lead there).
    assert!(
        worst <= 5 * per_solve,
        "a decision allocated {worst} times, more than its ≤ 5 solves ({per_solve} each) explain"
    );
}
