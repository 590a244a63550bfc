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
        (&left, Style::Rush, 2.0, VutModel::IdmNormal),
        (&left, Style::Yield, 1.5, VutModel::IdmCautious),
        (&left, Style::Yield, 3.0, VutModel::Reactive),
        (&cut, Style::Rush, 4.0, VutModel::Reactive),
        (&cut, Style::Yield, 2.0, VutModel::Sampling),
        (&vut_left, Style::Rush, 4.0, VutModel::IdmNormal),
        (&vut_left, Style::Yield, 2.0, VutModel::Reactive),
    ];
    for (scenario, style, tau, model) in cases {
        let c = steer_case(
            &settings,
            scenario,
            v2t_model::Target::new(tau, style).unwrap(),
            &v2t_lab::vut::Vut::Builtin(model),
            1..=2,
        );
        let tag = format!("{} {style} τ={tau} {model}", scenario.name);
        assert_eq!(c.stats.collisions, 0, "{tag}");
        assert_eq!(c.stats.zone_overlaps, 0, "{tag}");
        assert_eq!(c.stats.order_ok_frac, 1.0, "{tag}");
        assert_eq!(c.stats.unmeasured, 0, "{tag}");
        let err = c.error_rel.unwrap();
        assert!(err <= 0.10, "{tag}: mean PET_min {:?} s, error {:.1} %", c.stats.mean_pet_min_s, 100.0 * err);
    }
}
