//! The SUMO world end to end (needs SUMO: `scripts/install-sumo`; without it these tests fail with
//! the install instructions, or report themselves as not run under `scripts/test --no-install`):
//! every shipped scenario card co-simulated with SUMO driving the VUT and our regulated BV, SUMO's
//! driver reacting to the imposed BV, a card off the network refused by name, one process reused
//! across runs with the same result for the same seed.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic, clippy::indexing_slicing)]

use std::path::{Path, PathBuf};

use v2t_game::regulator::RegulatorParams;
use v2t_lab::steer::steer_case;
use v2t_lab::sumo::{SumoDriver, SumoWorld};
use v2t_lab::vut::Vut;
use v2t_model::{Style, Target};
use v2t_sim::bv::{BvController, ReferenceFollower};
use v2t_sim::runner::FirstThrough;
use v2t_sumo::{INSTALL_HINT, SumoBinaries};

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// The SUMO world on the proving ground, or `None` when the test is to report itself as not run.
fn world() -> Option<SumoWorld> {
    let found = SumoBinaries::find();
    if let Err(e) = &found {
        eprintln!("{e}");
    }
    if !v2t_test_support::found_or_not_run(found.is_ok(), "SUMO (sumo, netconvert)", INSTALL_HINT) {
        return None;
    }
    Some(SumoWorld::new(&root().join("config/maps/proving_ground.xodr")).unwrap())
}

fn driver(name: &str) -> SumoDriver {
    SumoDriver::load(&root().join(format!("config/vut/sumo/{name}.toml"))).unwrap()
}

fn card(name: &str) -> v2t_sim::scenario::Scenario {
    v2t_sim::files::load_scenario(&root().join(format!("config/scenarios/{name}.toml"))).unwrap()
}

#[test]
fn the_regulated_bv_steers_sumos_vut_in_every_scenario() {
    let Some(world) = world() else { return };
    let settings: RegulatorParams = v2t_files::load_toml(&root().join("config/regulator/default.toml")).unwrap();
    let idm = driver("idm");
    let vut = Vut::Sumo { world: &world, driver: &idm };
    // How close each lands is BENCHMARKS' business; here: every run safe and in the asked order,
    // and the target moves the PET (a later target, a clearly later PET).
    for name in ["left_turn_basic", "left_turn_vut", "cut_in_basic"] {
        let sc = card(name);
        let pets = [2.0, 4.0].map(|tau| {
            let c = steer_case(&settings, &sc, Target::new(tau, Style::Rush).unwrap(), &vut, 1..=1);
            let s = &c.stats;
            assert_eq!((s.collisions, s.zone_overlaps, s.unmeasured), (0, 0, 0), "{name} τ {tau}: {c:?}");
            assert_eq!(s.order_ok_frac, 1.0, "{name} τ {tau}: {c:?}");
            assert_eq!((c.vut.as_str(), c.world), ("sumo-idm", v2t_lab::vut::World::Sumo));
            s.mean_pet_min_s.unwrap()
        });
        // Rush at τ 2 s lands long against SUMO's priority VUT in the left turn (it brakes for a BV
        // still in the junction): seed 1 gives 3.12 s there and 4.00 s for τ 4 s with the
        // vehicle's adapter (2.99 s before the lab ran it), so "clearly later" is half a second.
        assert!(pets[1] > pets[0] + 0.5, "{name}: PET {:.2} s for τ 2 s, {:.2} s for τ 4 s", pets[0], pets[1]);
    }
}

#[test]
fn sumos_turning_vut_waits_for_the_imposed_oncoming_bv() {
    let Some(world) = world() else { return };
    // The BV holds 5 m/s and reaches the crossing (50 m) when the VUT (80 m at 8 m/s) would: SUMO's
    // left-turning VUT must see it (it is imposed, not SUMO's own) and wait rather than drive into it.
    let mut sc = card("left_turn_vut");
    sc.bvs[0].agent.initial_speed_mps = 5.0;
    sc.bvs[0].reference = v2t_sim::scenario::SpeedProfile::new(vec![[0.0, 5.0]]);
    let mut bvs: Vec<Box<dyn BvController>> = vec![Box::new(ReferenceFollower::default())];
    let out = world.run(&driver("krauss"), &sc, &mut bvs, 1).unwrap();
    let r = &out.result;
    assert!(r.collision.is_none() && !r.zone_overlap, "{r:?}");
    let c = &r.conflicts[0];
    assert_eq!(c.first, Some(FirstThrough::Bv), "{c:?}");
    let entry = c.vut_passage.as_ref().unwrap().enter_t_s;
    let slowest_before =
        out.trace.iter().filter(|s| s.t_s < entry).map(|s| s.agents[0].state.speed_mps).fold(f64::INFINITY, f64::min);
    assert!(slowest_before < 4.0, "the VUT did not slow for the BV: {slowest_before} m/s before the zone");
    assert!(r.min_distance_m > 0.0, "{}", r.min_distance_m);
    assert_eq!(r.vut_model, "sumo-krauss");
}

#[test]
fn a_card_off_the_maps_lanes_is_refused_by_name() {
    let Some(world) = world() else { return };
    let mut sc = card("left_turn_vut");
    // On the centre line between the two directions: no lane there runs north.
    let off = v2t_model::path::PathSpec {
        start_x_m: 0.0,
        start_y_m: -80.0,
        start_heading_deg: 90.0,
        segments: vec![v2t_model::path::SegmentSpec::Line { length_m: 60.0 }],
    };
    sc.vut.agent.route = off.builder().build(0.5).unwrap();
    let mut bvs: Vec<Box<dyn BvController>> = vec![Box::new(ReferenceFollower::default())];
    let err = world.run(&driver("idm"), &sc, &mut bvs, 1).unwrap_err().to_string();
    assert!(err.contains("vut's route is not on the SUMO network") && err.contains("left_turn_vut"), "{err}");
}

#[test]
fn one_process_serves_many_runs_and_a_seed_repeats_its_run() {
    let Some(world) = world() else { return };
    let sc = card("cut_in_basic");
    let krauss = driver("krauss");
    let run = |seed| {
        let mut bvs: Vec<Box<dyn BvController>> = vec![Box::new(ReferenceFollower::default())];
        world.run(&krauss, &sc, &mut bvs, seed).unwrap()
    };
    let (a, b, c) = (run(3), run(3), run(4));
    assert_eq!(a.result.pet_min_s, b.result.pet_min_s);
    assert_eq!(a.truth.agents[0].states, b.truth.agents[0].states, "SUMO's VUT differs for the same seed");
    // Krauss draws its imperfection from the seed: another seed drives the VUT differently.
    assert_ne!(a.truth.agents[0].states, c.truth.agents[0].states);
}
