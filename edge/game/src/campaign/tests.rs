#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing, clippy::panic)]

use proptest::prelude::*;

use super::*;

fn rush(tau: f64) -> Target {
    Target::new(tau, Style::Rush).unwrap()
}

fn run(aim: Target, pet: f64) -> RunRecord {
    RunRecord {
        aim_s: aim.tau_s(),
        pet_s: Some(pet),
        order_ok: true,
        collision: false,
        learned_route: false,
        reaction_prior: false,
    }
}

/// Runs `n` runs of a test against a VUT whose PET is `vut(aim, run index)`; returns the aims.
fn campaign(m: &mut CaseMemory, target: Target, n: usize, vut: impl Fn(f64, usize) -> f64) -> Vec<f64> {
    (0..n)
        .map(|k| {
            let aim = m.aim(target);
            m.record(target, run(aim, vut(aim.tau_s(), k)));
            aim.tau_s()
        })
        .collect()
}

#[test]
fn the_first_run_aims_at_tau_and_the_second_corrects_the_bias_it_saw() {
    let mut m = CaseMemory::default();
    let t = rush(3.0);
    assert_eq!(m.aim(t), t);
    m.record(t, run(t, 3.5));
    assert!((m.aim(t).tau_s() - 2.5).abs() < 1e-12);
    assert_eq!(m.aim(t).style(), Style::Rush);
}

#[test]
fn a_vut_that_adds_a_constant_lands_on_tau_from_the_second_run() {
    let mut m = CaseMemory::default();
    let t = rush(2.0);
    let aims = campaign(&mut m, t, 6, |aim, _| aim + 0.4);
    assert!((aims[0] - 2.0).abs() < 1e-12);
    for a in &aims[1..] {
        assert!((a - 1.6).abs() < 1e-9, "{aims:?}");
    }
    assert!(!m.dropped && m.below_reach.is_none());
}

#[test]
fn a_vut_that_follows_half_of_the_aim_converges() {
    // PET = 1.0 + 0.5·aim: τ = 3 needs aim 4.
    let mut m = CaseMemory::default();
    let t = rush(3.0);
    campaign(&mut m, t, 10, |aim, _| 1.0 + 0.5 * aim);
    let last = m.runs.last().unwrap().pet_s.unwrap();
    assert!((last - 3.0).abs() < 0.03, "{:?}", m.runs);
    // From the fourth run on within 2 % (the line is fitted once the aims spread).
    assert!(m.runs[3..].iter().all(|r| (r.pet_s.unwrap() - 3.0).abs() < 0.06), "{:?}", m.runs);
    assert!(m.below_reach.is_none());
}

#[test]
fn a_pet_floor_is_reported_with_its_bound_and_the_aim_goes_back() {
    // The VUT gives way below a 2 s PET, whatever the BV does.
    let mut m = CaseMemory::default();
    let t = rush(1.5);
    let aims = campaign(&mut m, t, 5, |aim, _| (aim + 0.1).max(2.0));
    let b = m.below_reach.unwrap();
    assert_eq!(b.cause, BelowReachCause::Campaign);
    assert!((b.pet_bound_s.unwrap() - 2.0).abs() < 1e-9);
    // After the verdict (run 2) the aim goes back to where the PET was closest to τ, and stays.
    assert!(aims.iter().all(|&a| a >= AIM_MIN_SHARE * 1.5 - 1e-12), "{aims:?}");
    assert!(aims[1] < 1.5 - 0.25 * 1.5, "{aims:?}");
    assert_eq!(&aims[2..], &[aims[0]; 3], "{aims:?}");
}

#[test]
fn a_vut_that_gives_way_the_more_the_harder_it_is_pressed_is_below_reach() {
    // Lowering the aim makes the PET longer: the reactive driver's rule.
    let mut m = CaseMemory::default();
    let t = rush(1.5);
    let aims = campaign(&mut m, t, 4, |aim, _| 2.5 - 0.5 * aim);
    assert_eq!(m.below_reach.map(|b| b.cause), Some(BelowReachCause::Campaign), "{:?}", m.runs);
    assert_eq!(aims[3], 1.5, "back to the aim with the PET closest to τ: {aims:?}");
}

#[test]
fn a_learned_bias_that_predicts_worse_than_none_is_dropped() {
    // A fluke first run (1 s long) teaches a bias this VUT does not have: afterwards it lands
    // exactly where the regulator aims, so the default prediction is perfect and the learned one
    // is not.
    let mut m = CaseMemory::default();
    let t = rush(3.0);
    let mut dropped_at = None;
    for k in 0..10 {
        let aim = m.aim(t).tau_s();
        m.record(t, run(m.aim(t), if k == 0 { aim + 1.0 } else { aim }));
        if m.dropped {
            dropped_at.get_or_insert(k + 1);
        }
    }
    assert_eq!(dropped_at, Some(DROP_AFTER as usize + 1), "dropped once {DROP_AFTER} runs were compared: {m:?}");
    assert!(m.learned_error_s > (1.0 + DROP_MARGIN) * m.default_error_s);
    assert_eq!(m.aim(t), t);
    assert_eq!((m.offset_s, m.gain), (0.0, 1.0));
}

#[test]
fn two_runs_without_a_pet_in_the_asked_order_refuse_the_order() {
    let mut m = CaseMemory::default();
    let t = Target::new(2.0, Style::Yield).unwrap();
    let none = RunRecord {
        aim_s: 2.0,
        pet_s: None,
        order_ok: false,
        collision: false,
        learned_route: false,
        reaction_prior: false,
    };
    m.record(t, none);
    assert!(m.below_reach.is_none());
    m.record(t, none);
    assert_eq!(m.below_reach.map(|b| b.cause), Some(BelowReachCause::OrderRefused));
    // A later run in the asked order clears it.
    m.record(t, run(t, 2.0));
    assert!(m.below_reach.is_none());
}

#[test]
fn runs_with_a_collision_teach_nothing() {
    let mut m = CaseMemory::default();
    let t = rush(2.0);
    m.record(
        t,
        RunRecord {
            aim_s: 2.0,
            pet_s: Some(0.2),
            order_ok: true,
            collision: true,
            learned_route: false,
            reaction_prior: false,
        },
    );
    assert_eq!(m.offset_s, 0.0);
    assert_eq!(m.aim(t), t);
}

#[test]
fn a_memory_refuses_another_vut_and_names_both() {
    let mut mem = CampaignMemory::new("idm-normal", "builtin");
    mem.case_mut("left_turn_basic", 0, rush(2.0)).record(rush(2.0), run(rush(2.0), 2.6));
    assert!(mem.check_vut("idm-normal", "builtin").is_ok());
    let e = mem.check_vut("reactive", "builtin").unwrap_err().to_string();
    assert!(e.contains("idm-normal") && e.contains("reactive"), "{e}");
    assert!(mem.check_vut("idm-normal", "sumo").is_err());
    // Tests are apart: another τ or style or BV starts uncalibrated.
    assert!((mem.aim("left_turn_basic", 0, rush(2.0)).tau_s() - 1.4).abs() < 1e-9);
    assert_eq!(mem.aim("left_turn_basic", 0, rush(3.0)), rush(3.0));
    assert_eq!(mem.aim("left_turn_basic", 1, rush(2.0)), rush(2.0));
    assert_eq!(mem.aim("cut_in_basic", 0, rush(2.0)), rush(2.0));
    let y = Target::new(2.0, Style::Yield).unwrap();
    assert_eq!(mem.aim("left_turn_basic", 0, y), y);
}

#[test]
fn a_memory_file_keeps_style_and_tau_as_two_keys_and_refuses_a_tau_out_of_range() {
    let mut mem = CampaignMemory::new("idm-normal", "builtin");
    mem.case_mut("s", 0, rush(2.0)).record(rush(2.0), run(rush(2.0), 2.2));
    let json = serde_json::to_string(&mem).unwrap();
    let case = r#""cases":[{"scenario":"s","bv":0,"style":"rush","tau_s":2.0,"memory":{"runs":[{"aim_s":2.0,"#;
    assert!(json.starts_with(&format!(r#"{{"format":{FORMAT},"vut":"idm-normal","world":"builtin",{case}"#)), "{json}");
    let back: CampaignMemory = serde_json::from_str(&json).unwrap();
    assert_eq!(back, mem);
    assert_eq!(serde_json::to_string(&back).unwrap(), json);
    let pretty = serde_json::to_string_pretty(&mem).unwrap();
    assert_eq!(
        serde_json::to_string_pretty(&serde_json::from_str::<CampaignMemory>(&pretty).unwrap()).unwrap(),
        pretty
    );
    for bad in ["1e300", "0.0", "-2.0"] {
        let text = json.replace(r#""tau_s":2.0"#, &format!(r#""tau_s":{bad}"#));
        let e = serde_json::from_str::<CampaignMemory>(&text).unwrap_err().to_string();
        assert!(e.contains("`cases[0].tau_s`") && e.contains("[0.1, 30]"), "{e}");
    }
    let e = serde_json::from_str::<CampaignMemory>(&json.replace(r#""rush""#, r#""fast""#)).unwrap_err();
    assert!(e.to_string().contains("fast"), "{e}");
    let e = serde_json::from_str::<CampaignMemory>(&json.replace(r#""bv":0,"#, r#""bv":0,"x":1,"#)).unwrap_err();
    assert!(e.to_string().contains("unknown field `x`"), "{e}");
    let e = serde_json::from_str::<CampaignMemory>(&json.replacen(r#""world""#, r#""x":1,"world""#, 1)).unwrap_err();
    assert!(e.to_string().contains("unknown field `x`"), "{e}");
}

#[test]
fn validation_names_the_field_and_the_bound() {
    let mut mem = CampaignMemory::new("idm-normal", "builtin");
    mem.case_mut("s", 0, rush(2.0)).record(rush(2.0), run(rush(2.0), 2.2));
    assert!(mem.validate().is_ok());
    let mut bad = mem.clone();
    bad.cases[0].memory.runs[0].aim_s = f64::NAN;
    let e = bad.validate().unwrap_err().to_string();
    assert!(e.contains("cases[0].memory.runs[0].aim_s"), "{e}");
    let mut bad = mem.clone();
    bad.cases[0].memory.offset_s = 1e300;
    assert!(bad.validate().unwrap_err().to_string().contains("offset_s"));
    let mut bad = mem.clone();
    bad.format = 7;
    assert!(bad.validate().unwrap_err().to_string().contains("format"));
    let mut bad = mem;
    bad.vut = String::new();
    assert!(bad.validate().unwrap_err().to_string().contains("vut"));
}

proptest! {
    /// Whatever the runs measured, the next aim is a valid target within [0.5 τ, 1.5 τ] in the
    /// test's style.
    #[test]
    fn the_aim_stays_within_its_bounds(
        tau in 0.5f64..10.0,
        yield_ in any::<bool>(),
        runs in prop::collection::vec((prop::option::of(-1e6f64..1e6), any::<bool>(), any::<bool>()), 0..30),
    ) {
        let t = Target::new(tau, if yield_ { Style::Yield } else { Style::Rush }).unwrap();
        let mut m = CaseMemory::default();
        for (pet, order_ok, collision) in runs {
            let aim = m.aim(t);
            prop_assert!(aim.tau_s() >= AIM_MIN_SHARE * tau - 1e-9 && aim.tau_s() <= AIM_MAX_SHARE * tau + 1e-9);
            prop_assert_eq!(aim.style(), t.style());
            m.record(t, RunRecord { aim_s: aim.tau_s(), pet_s: pet, order_ok, collision, learned_route: false, reaction_prior: false });
            prop_assert!(m.offset_s.is_finite() && m.gain.is_finite());
        }
    }
}

#[test]
fn runs_that_keep_missing_on_either_side_show_tau_out_of_reach_without_holding_the_aim() {
    // Either the VUT lets the BV through (1.33 s) or it gives way (about 2 s), never 1.5 s; the aim
    // stays at τ here (as after a dropped model), so only the misses tell.
    let pets = [1.33, 2.04, 1.89, 2.03, 1.88];
    let mut m = CaseMemory::default();
    let t = rush(1.5);
    for (k, pet) in pets.into_iter().enumerate() {
        let aim = t;
        m.record(t, run(aim, pet));
        if k < 3 {
            assert!(m.below_reach.is_none(), "run {}: {m:?}", k + 1);
        }
    }
    let b = m.below_reach.unwrap();
    assert_eq!(b.cause, BelowReachCause::Campaign);
    assert_eq!(b.pet_bound_s, Some(1.88), "the PET of the last four closest to τ");
    assert!(!m.holding);
    // One run on τ ends it.
    m.record(t, run(t, 1.52));
    assert!(m.below_reach.is_none());
}

/// A learned route speed: `v` m/s over 100 m.
fn route(v: f64) -> RouteSpeed {
    RouteSpeed { step_m: 2.0, speeds_mps: vec![v; 51], runs: 1 }
}

#[test]
fn the_first_learned_route_starts_the_reaction_model_over() {
    let mut m = CaseMemory::default();
    let t = rush(2.0);
    // Run 1 without a learned route: 1 s long.
    m.record(t, run(t, 3.0));
    assert!((m.aim(t).tau_s() - 1.0).abs() < 1e-12, "the bias alone would aim 1 s lower");
    m.learn_route(t, &route(8.0));
    assert_eq!(m.aim(t), t, "the next run's follower knows the route: nothing is known of how it errs");
    assert_eq!((m.offset_s, m.gain), (0.0, 1.0));
    // Run 2 with it: 0.3 s long; the model is fitted to it alone.
    m.record(t, RunRecord { learned_route: true, ..run(t, 2.3) });
    assert!((m.offset_s - 0.3).abs() < 1e-12, "{}", m.offset_s);
    m.learn_route(t, &route(6.0));
    let learned = m.route_speed.as_ref().unwrap();
    assert_eq!(learned.runs, 2);
    assert_eq!(learned.speeds_mps[0], 8.0, "the faster of the two runs");
    assert!((m.offset_s - 0.3).abs() < 1e-12, "a merged route keeps the model");
}

#[test]
fn a_free_drive_teaches_the_route_before_any_run() {
    let mut m = CaseMemory::default();
    let t = rush(2.0);
    m.learn_free_drive(t, &RouteSpeed { speeds_mps: vec![f64::NAN; 3], ..route(8.0) });
    assert!(m.route_speed.is_none(), "a record that is not one");
    m.learn_free_drive(t, &route(6.0));
    assert_eq!(m.route_speed.as_ref().map(|r| r.runs), Some(1), "no run needed: a free drive has no PET");
    assert!(m.runs.is_empty() && m.aim(t) == t, "a free drive is no run of the test: run 1 aims at τ");
    // The first run is made with the route known, and counts for the model.
    m.record(t, RunRecord { learned_route: true, ..run(t, 2.3) });
    assert!((m.offset_s - 0.3).abs() < 1e-12, "{}", m.offset_s);
    // A second free drive merges as a run's route does (the faster at each point).
    m.learn_free_drive(t, &route(7.0));
    let learned = m.route_speed.as_ref().unwrap();
    assert_eq!((learned.runs, learned.speeds_mps[0]), (2, 7.0));
}

#[test]
fn a_run_that_went_wrong_teaches_no_route() {
    let mut m = CaseMemory::default();
    let t = rush(2.0);
    m.record(t, RunRecord { collision: true, ..run(t, 0.4) });
    m.learn_route(t, &route(8.0));
    assert!(m.route_speed.is_none(), "a collision");
    m.record(t, RunRecord { order_ok: false, ..run(t, 2.0) });
    m.learn_route(t, &route(8.0));
    assert!(m.route_speed.is_none(), "the order refused");
    m.record(t, run(t, 2.0));
    m.learn_route(t, &RouteSpeed { speeds_mps: vec![f64::NAN; 3], ..route(8.0) });
    assert!(m.route_speed.is_none(), "a record that is not one");
    m.learn_route(t, &route(8.0));
    assert!(m.route_speed.is_some());
}

#[test]
fn a_memory_with_a_learned_route_is_read_back_and_an_older_file_without_one_too() {
    let mut mem = CampaignMemory::new("sumo-idm", "sumo");
    let t = rush(2.0);
    let case = mem.case_mut("left_turn_vut", 0, t);
    case.record(t, run(t, 2.9));
    case.learn_route(t, &route(8.0));
    let json = serde_json::to_string(&mem).unwrap();
    let back: CampaignMemory = serde_json::from_str(&json).unwrap();
    assert_eq!(back, mem);
    assert!(back.validate().is_ok());
    // A file written before routes were learned: no `route_speed`, no `learned_route`.
    let old = json.replace(r#","learned_route":false"#, "");
    let old = &old[..old.find(r#","route_speed""#).unwrap()];
    let old = format!("{old}}}}}]}}");
    let back: CampaignMemory = serde_json::from_str(&old).unwrap();
    assert!(back.cases[0].memory.route_speed.is_none() && !back.cases[0].memory.runs[0].learned_route);
    // A learned speed out of range is refused naming it.
    let bad = json.replacen("[8.0,", "[-8.0,", 1);
    let e = serde_json::from_str::<CampaignMemory>(&bad).unwrap().validate().unwrap_err().to_string();
    assert!(e.contains("cases[0].memory.route_speed.speeds_mps[0]"), "{e}");
}

fn posterior(reacting: f64, informative: u32) -> ReactionPosterior {
    ReactionPosterior::sure_of(None, 1.0 - reacting, informative).unwrap()
}

#[test]
fn the_first_identified_reaction_starts_the_reaction_model_over_and_later_ones_replace_it() {
    let mut m = CaseMemory::default();
    let t = rush(2.0);
    m.record(t, run(t, 2.6));
    assert!((m.offset_s - 0.6).abs() < 1e-12);
    // A run that saw no conflict taught nothing: nothing is kept, the model stays.
    m.learn_reaction(t, &posterior(0.7, 0));
    assert!(m.reaction.is_none() && (m.offset_s - 0.6).abs() < 1e-12);
    m.learn_reaction(t, &posterior(0.9, 12));
    assert_eq!(m.reaction.as_ref().unwrap().informative_cycles, 12);
    assert_eq!(m.aim(t), t, "the next run starts from the identified reaction: nothing is known of how it errs");
    // Run 2, made with it: the model is fitted to it alone, and a later posterior keeps it.
    m.record(t, RunRecord { reaction_prior: true, ..run(t, 2.2) });
    assert!((m.offset_s - 0.2).abs() < 1e-12, "{}", m.offset_s);
    m.learn_reaction(t, &posterior(0.95, 30));
    assert_eq!(m.reaction.as_ref().unwrap().informative_cycles, 30);
    assert!((m.offset_s - 0.2).abs() < 1e-12);
    // A posterior that is not one is not kept.
    let mut bad = posterior(0.5, 40);
    bad.probabilities[0] = 2.0;
    m.learn_reaction(t, &bad);
    assert_eq!(m.reaction.as_ref().unwrap().informative_cycles, 30);
}

#[test]
fn a_memory_with_an_identified_reaction_is_read_back_and_a_bad_one_is_refused_by_name() {
    let mut mem = CampaignMemory::new("sumo-idm", "sumo");
    let t = rush(2.0);
    let case = mem.case_mut("left_turn_basic", 0, t);
    case.record(t, run(t, 2.9));
    case.learn_reaction(t, &posterior(0.8, 5));
    let json = serde_json::to_string(&mem).unwrap();
    let back: CampaignMemory = serde_json::from_str(&json).unwrap();
    assert_eq!(back, mem);
    assert!(back.validate().is_ok());
    let mut bad = back.clone();
    if let Some(r) = bad.cases[0].memory.reaction.as_mut() {
        r.probabilities[3] = -0.1;
    }
    let e = bad.validate().unwrap_err().to_string();
    assert!(e.contains("cases[0].memory.reaction.probabilities[3]"), "{e}");
}
