//! Closed-loop conformance of the simulated proving ground: every bundled scenario card with every
//! VUT model, BVs following their references.

#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)] // test code

use v2t_lab::sim::run_reference;
use v2t_sim::files::load_scenario;
use v2t_sim::scenario::Scenario;
use v2t_sim::vut::VutModel;
use v2t_tests::scenario_cards;

fn scenarios() -> Vec<Scenario> {
    let cards = scenario_cards();
    assert!(cards.len() >= 2, "expected the left-turn and cut-in cards");
    cards.iter().map(|c| load_scenario(c).unwrap_or_else(|e| panic!("{e}"))).collect()
}

#[test]
fn every_vut_model_gets_through_every_scenario_without_collision() {
    for scenario in scenarios() {
        for model in VutModel::ALL {
            for seed in 1..=3 {
                let out = run_reference(&scenario, &v2t_lab::vut::Vut::Builtin(model), seed).unwrap();
                let r = &out.result;
                let tag = format!("{} / {} / seed {seed}", scenario.name, model);
                assert!(r.collision.is_none(), "{tag}: collision {:?}", r.collision);
                assert!(r.min_distance_m.is_finite() && r.min_distance_m > 0.0, "{tag}");
                assert_eq!(r.conflicts.len(), scenario.bvs.len(), "{tag}");
                for c in &r.conflicts {
                    assert!(c.first.is_some(), "{tag}: nobody went through {}", c.bv_id);
                }
                for s in &out.trace {
                    for a in &s.agents {
                        assert!(a.state.is_finite(), "{tag}: non-finite state at {}", s.t_s);
                    }
                }
            }
        }
    }
}

#[test]
fn runs_are_reproducible_from_their_seed() {
    for scenario in scenarios() {
        let a = run_reference(&scenario, &v2t_lab::vut::Vut::Builtin(VutModel::Reactive), 42).unwrap();
        let b = run_reference(&scenario, &v2t_lab::vut::Vut::Builtin(VutModel::Reactive), 42).unwrap();
        assert_eq!(a, b, "{}: same seed, different runs", scenario.name);
        let c = run_reference(&scenario, &v2t_lab::vut::Vut::Builtin(VutModel::Reactive), 43).unwrap();
        assert_ne!(a.trace, c.trace, "{}: the seed does not reach the noise", scenario.name);
    }
}

#[test]
fn vut_models_behave_differently() {
    // Stand-ins for different ADS must not all be the same driver.
    for scenario in scenarios() {
        let speeds: Vec<Vec<f64>> = VutModel::ALL
            .iter()
            .map(|m| {
                let out = run_reference(&scenario, &v2t_lab::vut::Vut::Builtin(*m), 7).unwrap();
                out.trace.iter().map(|s| s.agents[0].state.speed_mps).collect()
            })
            .collect();
        for i in 0..speeds.len() {
            for j in i + 1..speeds.len() {
                assert_ne!(speeds[i], speeds[j], "{}: models {i} and {j} drive identically", scenario.name);
            }
        }
    }
}

#[test]
fn two_bvs_each_get_their_own_conflict_and_regulator() {
    use v2t_files::load_toml;
    use v2t_files::parse_toml;
    use v2t_model::path::{PathSpec, SegmentSpec};
    use v2t_model::vehicle::VehicleConfig;
    use v2t_sim::config::{BvCard, ScenarioCard, SimSettings};

    let root = v2t_tests::repo_root().join("config");
    let card_path = root.join("scenarios/left_turn_basic.toml");
    let mut card: ScenarioCard = parse_toml(&std::fs::read_to_string(&card_path).unwrap(), "card").unwrap();
    // A second BV crosses from the west, 45 m further up the VUT's road.
    let mut second: BvCard = card.bvs[0].clone();
    second.id = "bv2".into();
    second.path = PathSpec {
        start_x_m: -60.0,
        start_y_m: 45.0,
        start_heading_deg: 0.0,
        segments: vec![SegmentSpec::Line { length_m: 140.0 }],
    };
    card.bvs.push(second);
    let settings: SimSettings = load_toml(&root.join("sim/default.toml")).unwrap();
    let vut: VehicleConfig = load_toml(&root.join("vehicles/vut_sedan.toml")).unwrap();
    let bv: VehicleConfig = load_toml(&root.join("vehicles/bv_sedan.toml")).unwrap();
    let scenario = Scenario::from_card(&card, settings, vut, vec![bv.clone(), bv]).unwrap();
    assert_eq!(scenario.conflicts.len(), 2);
    assert_ne!(scenario.conflicts[0].zone.vut, scenario.conflicts[1].zone.vut);

    let settings: v2t_game::regulator::RegulatorParams = load_toml(&root.join("regulator/default.toml")).unwrap();
    let target = v2t_model::Target::new(2.0, v2t_model::Style::Yield).unwrap();
    let c = v2t_lab::steer::steer_case(
        &settings,
        &scenario,
        target,
        &v2t_lab::vut::Vut::Builtin(VutModel::IdmNormal),
        1..=1,
        None,
    );
    let s = &c.stats;
    assert_eq!((s.collisions, s.zone_overlaps, s.unmeasured), (0, 0, 0), "{c:?}");
    assert_eq!(s.order_ok_frac, 1.0, "both BVs let the VUT through first: {c:?}");
}
