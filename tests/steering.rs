//! Closed-loop steering regression: the regulated BV against VUT models in the simulated proving
//! ground lands on the target PET in the cases where the full experiment shows it does (see
//! `docs/BENCHMARKS.md` for the whole table), with no collision, no zone overlap and the order the
//! style asks for in every run.

#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)] // test code

use v2t_files::load_toml;
use v2t_game::regulator::RegulatorParams;
use v2t_lab::steer::steer_case;
use v2t_model::Style;
use v2t_sim::files::load_scenario;
use v2t_sim::vut::VutModel;
use v2t_tests::repo_root;

#[test]
fn the_regulated_bv_lands_on_the_target_pet() {
    let left = load_scenario(&repo_root().join("config/scenarios/left_turn_basic.toml")).unwrap();
    let cut = load_scenario(&repo_root().join("config/scenarios/cut_in_basic.toml")).unwrap();
    let vut_left = load_scenario(&repo_root().join("config/scenarios/left_turn_vut.toml")).unwrap();
    let settings: RegulatorParams = load_toml(&repo_root().join("config/regulator/default.toml")).unwrap();
    let cases = [
        (&left, Style::Rush, 4.0, VutModel::Sampling),
        // Rush τ 2 s against this IDM misses by about 20 % since a rushing BV slows before the
        // junction rather than in it (docs/BENCHMARKS.md, "A rush the VUT can read").
        (&left, Style::Rush, 4.0, VutModel::IdmNormal),
        (&left, Style::Yield, 1.5, VutModel::IdmCautious),
        (&left, Style::Yield, 3.0, VutModel::Reactive),
        (&cut, Style::Rush, 4.0, VutModel::Reactive),
        (&cut, Style::Yield, 2.0, VutModel::Sampling),
        (&vut_left, Style::Rush, 4.0, VutModel::IdmNormal),
        (&vut_left, Style::Yield, 4.0, VutModel::Reactive),
    ];
    for (scenario, style, tau, model) in cases {
        // The shipped jerk weight (30, was 3) costs the yield at τ 1.5 s against the cautious IDM
        // 2.8 points on these seeds (7.7 → 10.5 %): the smoother BV starts later behind the VUT.
        let bound = if (style, tau, model) == (Style::Yield, 1.5, VutModel::IdmCautious) { 0.12 } else { 0.10 };
        let c = steer_case(
            &settings,
            scenario,
            v2t_model::Target::new(tau, style).unwrap(),
            &v2t_lab::vut::Vut::Builtin(model),
            1..=2,
            None,
        );
        let tag = format!("{} {style} τ={tau} {model}", scenario.name);
        assert_eq!(c.stats.collisions, 0, "{tag}");
        assert_eq!(c.stats.zone_overlaps, 0, "{tag}");
        assert_eq!(c.stats.order_ok_frac, 1.0, "{tag}");
        assert_eq!(c.stats.unmeasured, 0, "{tag}");
        // Within its own lateral limit in every run: the rush at τ 4 s against the sampling driver
        // went 0.04 m/s² over it on seed 1 while the plan's caps left out the speed its actuator
        // still added after the plan stopped asking (`accel_latency_s`).
        let lateral = c.bv_lateral;
        assert_eq!(lateral.over_limit_runs, 0, "{tag}: {:.2} m/s², limit {}", lateral.peak_mps2, lateral.limit_mps2);
        let err = c.error_rel.unwrap();
        assert!(err <= bound, "{tag}: mean PET_min {:?} s, error {:.1} %", c.stats.mean_pet_min_s, 100.0 * err);
        // Every run says how the regulator identified the VUT by its end (the shipped follower reacts).
        let id = c.identified;
        assert_eq!(id.runs + id.uninformed, 2, "{tag}");
        assert!(id.reacting <= id.runs && (0.0..=1.0).contains(&id.reacts_p_mean), "{tag}: {id:?}");
    }
    // The paper's follower identifies nothing.
    let paper = RegulatorParams { reacting_follower: false, ..settings };
    let target = v2t_model::Target::new(2.0, Style::Rush).unwrap();
    let c = steer_case(&paper, &left, target, &v2t_lab::vut::Vut::Builtin(VutModel::IdmNormal), 1..=1, None);
    assert_eq!(c.identified.runs + c.identified.uninformed, 0);
}

/// A campaign learns what one run cannot: against the cautious IDM driver the left turn's rush at
/// 3 s misses by about 6 % uncalibrated (the driver eases off before a BV crossing its path; 14 %
/// with the jerk weight of 3 the plan had until 2026-11-27); from run 3 on, what was learned (how
/// the VUT drives its route, and the aim) lands closer, within 5 %. Against the reactive driver, which yields below a
/// predicted PET of 2 s, τ = 1.5 s in rush is out of reach: the memory says so with a bound near
/// 2 s and the regulator reports it in the following runs. Every run without a collision and in the
/// asked order; nothing learned leaks between the two VUTs' memories.
#[test]
fn a_campaign_learns_the_vuts_reaction_and_reports_a_target_out_of_its_reach() {
    use v2t_game::campaign::CampaignMemory;
    use v2t_game::regulator::BelowReachCause;
    use v2t_lab::campaign::run_campaign;
    let left = load_scenario(&repo_root().join("config/scenarios/left_turn_basic.toml")).unwrap();
    let settings: RegulatorParams = load_toml(&repo_root().join("config/regulator/default.toml")).unwrap();

    let vut = v2t_lab::vut::Vut::Builtin(VutModel::IdmCautious);
    let target = v2t_model::Target::new(3.0, Style::Rush).unwrap();
    let err = |r: &v2t_lab::campaign::CampaignRun| (r.pet_s.unwrap() - 3.0).abs() / 3.0;
    // With the paper's follower (it does not react to the BV), run 1 misses and the campaign
    // corrects it from run 3 on.
    let paper = RegulatorParams { reacting_follower: false, ..settings };
    let mut memory = CampaignMemory::new("idm-cautious", "builtin");
    let runs = run_campaign(&paper, &left, target, &vut, 1, 5, &mut memory);
    assert!(err(&runs[0]) > 0.05, "run 1 is uncalibrated: {runs:#?}");
    for r in &runs[2..] {
        assert!(err(r) < 0.05, "run {}: PET {:?} aiming at {:.2} s", r.run, r.pet_s, r.aim_s);
    }
    // The shipped follower identifies, within run 1, that this VUT brakes for the BV: run 1 lands
    // nearer τ, and no run misses by more than 6 % (measured: 1.8, 0.7, 0.5, 5.0, 3.2 %).
    let mut reacting = CampaignMemory::new("idm-cautious", "builtin");
    let shipped = run_campaign(&settings, &left, target, &vut, 1, 5, &mut reacting);
    assert!(err(&shipped[0]) < err(&runs[0]), "{shipped:#?}");
    assert!(shipped.iter().all(|r| err(r) < 0.06 && !r.collision && r.order_ok), "{shipped:#?}");
    let identified = reacting.case(&left.name, 0, target).and_then(|c| c.reaction.as_ref());
    assert!(identified.is_some_and(|p| p.informative_cycles > 0), "the memory keeps the identification");
    let learned = memory.case(&left.name, 0, target).and_then(|c| c.route_speed.as_ref());
    assert!(learned.is_some_and(|r| r.runs >= 4), "the route is learned from every valid run: {learned:?}");
    assert!(runs.iter().all(|r| !r.collision && r.order_ok && !r.zone_overlap && r.below_reach.is_none()));

    let vut = v2t_lab::vut::Vut::Builtin(VutModel::Reactive);
    let target = v2t_model::Target::new(1.5, Style::Rush).unwrap();
    let mut other = CampaignMemory::new("reactive", "builtin");
    let runs = run_campaign(&settings, &left, target, &vut, 1, 6, &mut other);
    let case = other.case(&left.name, 0, target).unwrap();
    let b = case.below_reach.unwrap_or_else(|| panic!("below reach: {:#?}", case.runs));
    assert_eq!(b.cause, BelowReachCause::Campaign);
    assert!((1.7..2.6).contains(&b.pet_bound_s.unwrap()), "{b:?}");
    let last = runs.last().unwrap();
    assert_eq!(last.below_reach.map(|b| b.cause), Some(BelowReachCause::Campaign), "reported in the run");
    assert!(runs.iter().all(|r| !r.collision && r.order_ok && !r.zone_overlap));
    assert!(memory.case(&left.name, 0, target).is_none(), "the cautious driver's memory knows nothing of this test");
    assert!(memory.check_vut("reactive", "builtin").is_err());
}

/// A BV that gives way at a junction waits where a driver who gives way waits: its front before the
/// junction's edge on its lane (the card's `junction_entry_m`, held to the map by
/// `tests/config_files.rs`) until the VUT is in the zone, and it stands well clear of the VUT's swept
/// path. The left turn with the VUT turning, yield τ 4 s, against every builtin VUT model: the BV's
/// front has not passed the junction's edge when the VUT enters its zone, and the VUT goes first.
#[test]
fn a_yielding_bv_waits_before_the_junction_until_the_vut_is_in_the_zone() {
    let sc = load_scenario(&repo_root().join("config/scenarios/left_turn_vut.toml")).unwrap();
    let settings: RegulatorParams = load_toml(&repo_root().join("config/regulator/default.toml")).unwrap();
    let edge = sc.bvs[0].junction_entry_m.unwrap();
    let half = 0.5 * sc.bvs[0].agent.vehicle.geometry.length_m;
    let mut scenario = sc.clone();
    scenario.target = v2t_model::Target::new(4.0, Style::Yield).unwrap();
    for model in VutModel::ALL {
        let run = v2t_lab::campaign::regulated_run(&settings, &scenario, &v2t_lab::vut::Vut::Builtin(model), 1, None)
            .unwrap();
        let r = &run.outcome.result;
        let c = &r.conflicts[0];
        let vut_in = c.vut_passage.as_ref().expect("the VUT went through").enter_t_s;
        assert_eq!(c.first, Some(v2t_sim::runner::FirstThrough::Vut), "{model}");
        let front_then = run
            .outcome
            .trace
            .iter()
            .filter(|t| t.t_s <= vut_in)
            .map(|t| t.agents[1].s_m + half)
            .fold(f64::NEG_INFINITY, f64::max);
        assert!(front_then <= edge, "{model}: the BV's front at {front_then:.2} m, the junction's edge at {edge} m");
        assert!(r.pet_min_s.is_some_and(|p| (p - 4.0).abs() <= 0.4), "{model}: PET {:?}", r.pet_min_s);
    }
}

/// The paper's left turn, grounded on the proving ground from its cassette, rush at τ 1.5 s
/// against the reactive VUT, which slows down for a BV it sees coming: the BV slowing before the
/// junction must not stand at its edge until both go at once. Before a rushing BV's plan to its
/// commit station had a floor on the approach speed, the two shared the zone in all 20 runs and
/// collided in 9 (Video2Track, onboard; TroubleMaker-like, in the cloud across 5G SA, collided in
/// all 20).
#[test]
fn a_rushing_bv_that_slows_before_the_junction_never_meets_a_vut_that_slowed_for_it() {
    use v2t_lab::methods::{Method, PaperScenario, Setup, priors, run_case, scenario_of_prior};
    let root = repo_root();
    let shipped = |p: &str| root.join(p);
    let inspection = v2t_map::inspect(&shipped(v2t_files::shipped::MAP), None).unwrap();
    let model = v2t_diffusion::weights::load(&shipped(v2t_files::shipped::WEIGHTS)).unwrap();
    let setup = Setup {
        inspection: &inspection,
        model: &model,
        regulator: load_toml(&root.join("config/regulator/default.toml")).unwrap(),
        sim: load_toml(&shipped(v2t_files::shipped::SIM)).unwrap(),
        vut_vehicle: load_toml(&shipped(v2t_files::shipped::VUT_VEHICLE)).unwrap(),
        bv_vehicle: load_toml(&shipped(v2t_files::shipped::BV_VEHICLE)).unwrap(),
        human: None,
        baseline_network: Some(load_toml(&shipped(v2t_files::shipped::BASELINE_NETWORK)).unwrap()),
    };
    let sc = v2t_lab::demo::SCENARIOS.iter().find(|s| s.name == "left_turn").unwrap();
    // Its hand-written cassette (no model's answer), replayed.
    let mode = v2t_vlm::Mode::Replay(root.join(sc.cassette));
    let semantics =
        v2t_vlm::abstract_video(&root.join(sc.video), sc.pet_label_s, &v2t_vlm::VlmConfig::default(), &mode)
            .unwrap()
            .semantics;
    let rec = PaperScenario { name: sc.name.to_owned(), semantics };
    let target = v2t_model::Target::new(1.5, Style::Rush).unwrap();
    let (grounded, stand_in, diffusion) = priors(&rec, target, &setup, 1).unwrap();
    for (method, prior) in [(Method::Video2track, &diffusion), (Method::TroublemakerLike, &stand_in)] {
        let scenario = scenario_of_prior("left_turn", prior, &grounded, &setup).unwrap();
        let c = run_case(&setup, &scenario, method, VutModel::Reactive, 1..=20);
        let s = &c.stats;
        let tag = format!("{method:?}: {s:?}");
        assert_eq!((s.collisions, s.zone_overlaps, s.unmeasured), (0, 0, 0), "{tag}");
        assert_eq!(s.order_ok_frac, 1.0, "{tag}");
    }
}

/// The experiments hold the regulated BV's yields to the rule the reach grid holds its profiles
/// to: against every builtin VUT model, the VUT-turning yield at τ 1.5 s (out of reach of a BV
/// that waits behind its line) is given way to from behind the line, and counted so.
#[test]
fn the_experiments_read_whether_the_regulated_bv_kept_the_yield_rule() {
    let sc = load_scenario(&repo_root().join("config/scenarios/left_turn_vut.toml")).unwrap();
    let settings: RegulatorParams = load_toml(&repo_root().join("config/regulator/default.toml")).unwrap();
    let target = v2t_model::Target::new(1.5, Style::Yield).unwrap();
    for model in VutModel::ALL {
        let case = steer_case(&settings, &sc, target, &v2t_lab::vut::Vut::Builtin(model), 1..=1, None);
        assert_eq!(case.stats.order_ok_frac, 1.0, "{model}: {case:?}");
        assert_eq!(case.yields_not_kept, 0, "{model}: {case:?}");
        assert!(!case.landed_safely(), "{model}: τ 1.5 s is out of reach of a BV that keeps the rule");
    }
    // A case its own runs landed on counts as reached only while none of them broke the rule.
    let four = v2t_model::Target::new(4.0, Style::Yield).unwrap();
    let mut case = steer_case(&settings, &sc, four, &v2t_lab::vut::Vut::Builtin(VutModel::IdmNormal), 1..=1, None);
    assert!(case.yields_not_kept == 0 && case.landed_safely(), "{case:?}");
    case.yields_not_kept = 1;
    assert!(!case.landed_safely(), "a yield given from inside the junction is no landing");
}

/// A free drive: the VUT drives the test alone, every BV parked where it starts, and what it shows
/// (how the VUT drives its route up to the BV's zone) is what the regulator of the runs it prepares
/// knows. What it shows is what the parked BV's regulator measured, as on the track: the traced
/// route within the noise and age of the VUT's states. This project's IDM keeps its speed through
/// the turn; the runs still land.
#[test]
fn a_free_drive_shows_how_the_vut_drives_its_route_alone() {
    use v2t_lab::campaign::{FreeDrives, free_drive_run, vut_route_speed};
    let sc = load_scenario(&repo_root().join("config/scenarios/left_turn_vut.toml")).unwrap();
    let settings: RegulatorParams = load_toml(&repo_root().join("config/regulator/default.toml")).unwrap();
    let vut = v2t_lab::vut::Vut::Builtin(VutModel::IdmNormal);
    let drive = free_drive_run(&settings, &sc, &vut, 7).unwrap();
    let out = &drive.outcome;
    let bv_s: Vec<f64> = out.trace.iter().map(|t| t.agents[1].s_m).collect();
    let moved = bv_s.iter().fold(0.0_f64, |m, s| m.max((s - bv_s[0]).abs()));
    assert!(moved < 0.05, "the parked BV moved {moved:.3} m");
    let c = &out.result.conflicts[0];
    assert!(c.vut_passage.is_some() && c.bv_passage.is_none(), "the VUT passed the zone alone: {c:?}");
    let route = drive.routes[0].as_ref().expect("a route up to the zone, as the parked BV measured it");
    let traced = vut_route_speed(out, 0).expect("a traced route");
    let exit = out.layout.zones[0].zone.vut.exit_s_m;
    assert!(route.end_m() + v2t_game::route_speed::ROUTE_STEP_M >= exit, "{} m of {exit:.1} m", route.end_m());
    let worst = route.speeds_mps.iter().zip(&traced.speeds_mps).map(|(m, t)| (m - t).abs()).fold(0.0, f64::max);
    assert!(worst < 0.25, "measured and traced speeds differ by up to {worst:.2} m/s");
    let (_, slowest) = route.slowest().unwrap();
    assert!(slowest > 7.5, "idm-normal slowed to {slowest:.2} m/s on its own");
    let four = v2t_model::Target::new(4.0, Style::Rush).unwrap();
    let drives = FreeDrives::drive(&settings, &sc, &vut, 1..=2);
    let case = steer_case(&settings, &sc, four, &vut, 1..=2, Some(&drives));
    assert!(case.landed_safely(), "{case:?}");
}

/// What a campaign learns of a run is what the BV's regulator measured (the lesson the onboard node
/// reports), not the simulator's trace of the VUT: the same route within the noise and age of the
/// VUT's states, up to its zone's exit, and the identification of its reaction.
#[test]
fn a_campaign_learns_what_the_bvs_regulator_measured_of_the_vut() {
    use v2t_lab::campaign::{regulated_run, vut_route_speed};
    let mut sc = load_scenario(&repo_root().join("config/scenarios/left_turn_vut.toml")).unwrap();
    sc.target = v2t_model::Target::new(3.0, Style::Rush).unwrap();
    let settings: RegulatorParams = load_toml(&repo_root().join("config/regulator/default.toml")).unwrap();
    let vut = v2t_lab::vut::Vut::Builtin(VutModel::IdmCautious);
    let run = regulated_run(&settings, &sc, &vut, 3, None).unwrap();
    let lesson = run.lessons[0].as_ref().expect("the VUT left its zone");
    let measured = lesson.route.as_ref().expect("a route");
    let traced = vut_route_speed(&run.outcome, 0).unwrap();
    let exit = run.outcome.layout.zones[0].zone.vut.exit_s_m;
    assert!(measured.end_m() + v2t_game::route_speed::ROUTE_STEP_M >= exit, "{} m of {exit:.1} m", measured.end_m());
    let worst = measured.speeds_mps.iter().zip(&traced.speeds_mps).map(|(m, t)| (m - t).abs()).fold(0.0, f64::max);
    println!(
        "measured against traced route: {} and {} points, worst {worst:.3} m/s",
        measured.speeds_mps.len(),
        traced.speeds_mps.len()
    );
    // Each speed is recorded with the arc length of its own instant (0.15 m/s here); brought to
    // the decision's time, a VUT that slows was recorded ahead of where it had that speed (0.27).
    assert!(worst < 0.25, "measured and traced speeds differ by up to {worst:.2} m/s");
    assert!(lesson.reaction.is_some(), "the shipped follower identifies the reaction");
    assert_eq!(run.reactions[0].is_some(), lesson.reaction.is_some());
}
