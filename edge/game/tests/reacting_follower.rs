//! The regulator in closed loop against a VUT that reacts to the BV (the reaction model's own
//! driver, [`v2t_game::reaction::Driver`]): a case whose answer is known.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing, clippy::panic)]

use v2t_game::reaction::{Driver, Reaction, ReactionPosterior, Scene, Snapshot};
use v2t_game::regulator::{PathState, Regulator, RegulatorInput, RegulatorParams};
use v2t_model::metrics::{ConflictKind, OccupancyInterval};
use v2t_model::{Style, Target};

const ZONE_BV: OccupancyInterval = OccupancyInterval { enter_s_m: 40.0, exit_s_m: 50.0 };
const ZONE_VUT: OccupancyInterval = OccupancyInterval { enter_s_m: 60.0, exit_s_m: 70.0 };

/// A posterior that puts `p` on the driver `truth` and the rest evenly on the others.
fn sure_of(truth: Reaction, p: f64) -> ReactionPosterior {
    ReactionPosterior::sure_of(Some(truth), p, 100).unwrap()
}

/// The regulator with the paper's follower (it does not react).
fn paper() -> Regulator {
    Regulator::new(RegulatorParams { reacting_follower: false, ..RegulatorParams::default() }).unwrap()
}

/// The shipped regulator, sure (0.9) that the VUT reacts as `truth`.
fn knowing(truth: Reaction) -> Regulator {
    let mut reg = Regulator::new(RegulatorParams::default()).unwrap();
    reg.set_reaction_prior(Some(&sure_of(truth, 0.9))).unwrap();
    reg
}

/// One run: the regulator's BV against the VUT `truth`, both at 10 m/s from the start of their
/// paths; returns the PET (the VUT's entry after the BV's exit, rush).
fn pet(params: RegulatorParams, prior: Option<&ReactionPosterior>, truth: Reaction, target: Target, bv0: f64) -> f64 {
    let mut reg = Regulator::new(params).unwrap();
    reg.set_reaction_prior(prior).unwrap();
    let scene = Scene {
        zone_bv: ZONE_BV,
        zone_vut: ZONE_VUT,
        vut_accel_mps2: params.vut.max_accel_mps2,
        vut_decel_mps2: params.vut.max_decel_mps2,
    };
    let mut vut = Driver::new(Some(truth));
    let (mut bs, mut bv, mut ba, mut vs, mut vv) = (0.0, bv0, 0.0, 0.0, 10.0);
    let (mut bv_out, mut vut_in) = (None, None);
    let dt = 0.1;
    for k in 0..400 {
        let t = k as f64 * dt;
        let d = reg.decide(&RegulatorInput {
            t_s: t,
            bv: PathState { s_m: bs, v_mps: bv, age_s: 0.0 },
            vut: PathState { s_m: vs, v_mps: vv, age_s: 0.0 },
            bv_accel_mps2: ba,
            zone_bv: ZONE_BV,
            zone_vut: ZONE_VUT,
            zone_kind: ConflictKind::Crossing,
            target,
            reference_speed_mps: 10.0,
            stop_line_s_m: None,
        });
        let snap = Snapshot { bv_s_m: bs, bv_v_mps: bv, vut_s_m: vs, vut_v_mps: vv };
        let va = vut.accel(t, dt, &scene, &snap, 10.0);
        ba = d.accel_mps2;
        let (nb, nv) = ((bv + ba * dt).max(0.0), (vv + va * dt).max(0.0));
        let (nbs, nvs) = (bs + 0.5 * (bv + nb) * dt, vs + 0.5 * (vv + nv) * dt);
        if bv_out.is_none() && nbs >= ZONE_BV.exit_s_m {
            bv_out = Some(t + (ZONE_BV.exit_s_m - bs) / (nbs - bs) * dt);
        }
        if vut_in.is_none() && nvs >= ZONE_VUT.enter_s_m {
            vut_in = Some(t + (ZONE_VUT.enter_s_m - vs) / (nvs - vs) * dt);
        }
        (bs, bv, vs, vv) = (nbs, nb, nvs, nv);
    }
    vut_in.unwrap() - bv_out.unwrap()
}

fn input(target: Target) -> RegulatorInput {
    RegulatorInput {
        t_s: 0.0,
        bv: PathState { s_m: 0.0, v_mps: 10.0, age_s: 0.0 },
        vut: PathState { s_m: 0.0, v_mps: 10.0, age_s: 0.0 },
        bv_accel_mps2: 0.0,
        zone_bv: ZONE_BV,
        zone_vut: ZONE_VUT,
        zone_kind: ConflictKind::Crossing,
        target,
        reference_speed_mps: 10.0,
        stop_line_s_m: None,
    }
}

#[test]
fn a_rushing_bv_that_knows_the_vut_brakes_for_it_plans_against_the_braking_within_a_bound() {
    // BV out at 5 s and VUT in at 6 s at their speeds: τ 2.5 s needs the BV out at 3.5 s. A VUT
    // that wants a gap of 2 s sees a BV coming 1 s before it and brakes until the BV's speed-up
    // shows: the PET comes out longer. The leader that knows it plans the BV later to make up for
    // it, counting on the braking for at most a fifth of τ.
    let target = Target::new(2.5, Style::Rush).unwrap();
    let truth = Reaction { gap_s: 2.0, decel_mps2: 2.0, restart_s: 0.0 };
    let mut paper = paper();
    let d0 = paper.decide(&input(target));
    assert!(d0.reaction.is_none());
    assert!((d0.key_time_s.unwrap() - 3.5).abs() < 0.05, "{d0:?}");
    assert!((d0.predicted_pet_s.unwrap() - 2.5).abs() < 0.05, "{d0:?}");
    let mut fresh = Regulator::new(RegulatorParams::default()).unwrap();
    let d1 = fresh.decide(&input(target));
    assert_eq!(d1.key_time_s, d0.key_time_s, "the default prior: a VUT that does not react is most probable");
    let mut knows = knowing(truth);
    let d2 = knows.decide(&input(target));
    assert_eq!(d2.reaction.unwrap().reaction, Some(truth));
    let key = d2.key_time_s.unwrap();
    assert!(key > 3.5 + 0.05 && key <= 3.5 + 0.2 * 2.5 + 0.01, "{d2:?}");
    assert!((d2.predicted_pet_s.unwrap() - 2.5).abs() < 0.05, "{d2:?}");
    // A VUT that accepts 0.5 s sees no conflict: nothing changes.
    let mut easy = knowing(Reaction { gap_s: 0.5, ..truth });
    let d3 = easy.decide(&input(target));
    assert_eq!((d3.key_time_s, d3.predicted_pet_s), (d0.key_time_s, d0.predicted_pet_s));
}

#[test]
fn a_yielding_bv_waits_longer_for_a_vut_known_to_wait_for_a_gap() {
    // Yield τ 2 s: the VUT out at 7 s at its speed, the BV in at 9 s. A VUT that wants 3 s of
    // gap sees the BV coming 2 s after it leaves and slows down: the BV plans to come later.
    let target = Target::new(2.0, Style::Yield).unwrap();
    let truth = Reaction { gap_s: 3.0, decel_mps2: 2.0, restart_s: 0.0 };
    let mut paper = paper();
    let d0 = paper.decide(&input(target));
    let mut knows = knowing(truth);
    let d2 = knows.decide(&input(target));
    assert!(d2.key_time_s.unwrap() > d0.key_time_s.unwrap() + 0.1, "{d0:?} {d2:?}");
    assert!((d2.predicted_pet_s.unwrap() - 2.0).abs() <= 0.1, "{d2:?}");
}

#[test]
fn the_regulator_identifies_a_vut_that_brakes_for_the_bv_while_the_run_goes_on() {
    let target = Target::new(2.5, Style::Rush).unwrap();
    let mut reg = Regulator::new(RegulatorParams::default()).unwrap();
    // The BV holds 10 m/s; the VUT brakes at 2 m/s² from 0.5 s on while the BV comes (it wants
    // a gap the BV does not leave), as a driver with a gap of 2 s and a comfortable deceleration
    // of 2 m/s² does.
    let mut last = None;
    for k in 0..20 {
        let t = k as f64 * 0.1;
        let v = if t <= 0.5 { 10.0 } else { 10.0 - 2.0 * (t - 0.5) };
        let s_v = if t <= 0.5 { 10.0 * t } else { 5.0 + 10.0 * (t - 0.5) - (t - 0.5) * (t - 0.5) };
        let inp = RegulatorInput {
            t_s: t,
            bv: PathState { s_m: 10.0 * t, v_mps: 10.0, age_s: 0.0 },
            vut: PathState { s_m: s_v, v_mps: v, age_s: 0.0 },
            ..input(target)
        };
        last = Some(reg.decide(&inp));
    }
    let id = last.unwrap().reaction.unwrap();
    assert!(id.reacts_probability > 0.9, "{id:?}");
    assert!(id.informative_cycles >= 10, "{id:?}");
    // And one that drives on at its speed does not react, as far as it shows.
    let mut calm = Regulator::new(RegulatorParams::default()).unwrap();
    for k in 0..20 {
        let t = k as f64 * 0.1;
        let inp = RegulatorInput {
            t_s: t,
            bv: PathState { s_m: 10.0 * t, v_mps: 10.0, age_s: 0.0 },
            vut: PathState { s_m: 10.0 * t, v_mps: 10.0, age_s: 0.0 },
            ..input(target)
        };
        last = Some(calm.decide(&inp));
    }
    // It cannot tell one that does not react from one that accepts any gap the BV left it: what
    // is left of the reacting drivers accepts short gaps.
    let id = last.unwrap().reaction.unwrap();
    assert!(id.reaction.is_none() && id.probability > 0.5, "{id:?}");
    assert!(id.gap_mean_s < 1.0, "{id:?}");
}

#[test]
fn in_closed_loop_the_reacting_follower_presses_at_most_a_fifth_of_tau_harder_than_the_one_that_does_not_react() {
    let params = RegulatorParams::default();
    let paper = RegulatorParams { reacting_follower: false, ..params };
    for gap in [2.0, 3.0] {
        for tau in [1.5, 2.5] {
            for bv0 in [6.0, 14.0] {
                let truth = Reaction { gap_s: gap, decel_mps2: 2.0, restart_s: 0.0 };
                let target = Target::new(tau, Style::Rush).unwrap();
                let off = pet(paper, None, truth, target, bv0);
                let known = pet(params, Some(&sure_of(truth, 0.9)), truth, target, bv0);
                let learning = pet(params, None, truth, target, bv0);
                let floor = off - 0.2 * tau - 0.05;
                assert!(
                    known >= floor && learning >= floor,
                    "gap {gap} τ {tau} BV {bv0} m/s: {off} {known} {learning}"
                );
            }
        }
    }
}
