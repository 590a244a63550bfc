//! Which PETs can a rushing BV reach at all against each VUT model? Every BV here drives an
//! open-loop speed profile ([`v2t_lab::reach::OpenLoop`]: acceleration `a1` for `t1` seconds, then
//! `a2` until it has left the conflict zone, then its reference speed) over a finer grid than the
//! one `experiment steerability` runs, on the bundled left turn (or
//! the card given), with the card's sensor noise and delays. For each VUT model it prints the
//! smallest and largest PET measured among runs where the BV passed first without collision or
//! zone overlap, and how many profiles land within ±10 % of each target τ. A second table counts
//! the profiles that land within ±10 % against several models at once (a regulator cannot tell
//! the models apart before the VUT reacts to the BV), and the rarest of them are listed.
//!
//! ```sh
//! cargo run --release -p v2t-lab --example reachable_pet [-- config/scenarios/cut_in_basic.toml]
//! ```
//!
//! It bounds what any regulator can achieve against a VUT model: if no profile of the grid reaches a
//! PET, the regulator's miss there is the VUT's rule, not the regulator's.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing, clippy::panic)] // a measurement tool

use std::path::Path;

use v2t_lab::reach::{OpenLoop, Profile};
use v2t_model::Style;
use v2t_sim::bv::BvController;
use v2t_sim::files::load_scenario;
use v2t_sim::runner::run;
use v2t_sim::vut::VutModel;

fn main() {
    let card = std::env::args().nth(1).unwrap_or_else(|| "config/scenarios/left_turn_basic.toml".to_owned());
    let mut scenario = load_scenario(Path::new(&card)).expect("the card loads");
    scenario.target = scenario.target.with_style(Style::Rush);
    let taus = [1.5, 2.0, 3.0, 4.0, 5.0];
    let accels = [-3.0, -2.0, -1.0, 0.0, 1.0, 2.0, 3.0];
    let mut profiles = Vec::new();
    for a1 in accels {
        for k in 0..=12 {
            for a2 in accels {
                profiles.push(Profile { a1_mps2: a1, t1_s: 0.5 * f64::from(k), a2_mps2: a2 });
            }
        }
    }
    println!("{card}: {} open-loop rush profiles per VUT model, seed 1", profiles.len());
    println!(
        "| VUT | runs BV first, safe | min PET (s) | max PET (s) | {} |",
        taus.map(|t| format!("within ±10 % of {t} s")).join(" | ")
    );
    println!("|---|---|---|---|{}", "---|".repeat(taus.len()));
    // PET of every profile against every VUT model (None: not a safe BV-first run).
    let mut table: Vec<Vec<Option<f64>>> = Vec::new();
    for model in VutModel::ALL {
        let mut row = Vec::with_capacity(profiles.len());
        for p in &profiles {
            let mut bvs: Vec<Box<dyn BvController>> = vec![Box::new(OpenLoop { profile: *p, keep: None })];
            let mut driver = model.driver();
            let pet = run(&scenario, &mut bvs, driver.as_mut(), 1).ok().and_then(|out| {
                let r = out.result;
                let bv_first = r.conflicts.iter().all(|c| c.order_matches_style == Some(true));
                match (bv_first, r.collision, r.zone_overlap, r.pet_min_s) {
                    (true, None, false, Some(pet)) => Some(pet),
                    _ => None,
                }
            });
            row.push(pet);
        }
        let pets: Vec<f64> = row.iter().flatten().copied().collect();
        let min = pets.iter().copied().fold(f64::INFINITY, f64::min);
        let max = pets.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        let within = taus.map(|t| pets.iter().filter(|p| within_10(**p, t)).count().to_string());
        println!("| {model} | {} | {min:.2} | {max:.2} | {} |", pets.len(), within.join(" | "));
        table.push(row);
    }
    // A regulator sees the same VUT until the VUT reacts to it, so a profile that suits one VUT
    // model only is of little use: count the profiles that land within ±10 % against several
    // models at once.
    println!();
    println!("| profiles within ±10 % against | {} |", taus.map(|t| format!("{t} s")).join(" | "));
    println!("|---|{}", "---|".repeat(taus.len()));
    let groups: [(&str, Membership); 3] = [
        ("every VUT model", |_| true),
        ("every VUT model but the reactive one", |m| m != VutModel::Reactive),
        ("the three IDM drivers", |m| {
            matches!(m, VutModel::IdmCautious | VutModel::IdmNormal | VutModel::IdmAggressive)
        }),
    ];
    // Profiles that suit a group at a τ, listed when there are at most three of them.
    let mut rare: Vec<(&str, f64, usize)> = Vec::new();
    for (name, member) in groups {
        let counts = taus.map(|t| {
            let hits: Vec<usize> = (0..profiles.len())
                .filter(|i| {
                    VutModel::ALL
                        .iter()
                        .zip(&table)
                        .all(|(m, row)| !member(*m) || row[*i].is_some_and(|p| within_10(p, t)))
                })
                .collect();
            if hits.len() <= 3 {
                rare.extend(hits.iter().map(|i| (name, t, *i)));
            }
            hits.len().to_string()
        });
        println!("| {name} | {} |", counts.join(" | "));
    }
    println!();
    let names = VutModel::ALL.map(|m| m.to_string()).join(" / ");
    for (name, t, i) in rare {
        let pets: Vec<String> =
            table.iter().map(|row| row[i].map_or_else(|| "-".to_owned(), |p| format!("{p:.2}"))).collect();
        println!("τ {t} s, {name}: {:?} → PET {} ({names})", profiles[i], pets.join(" / "));
    }
}

/// Which VUT models belong to a group.
type Membership = fn(VutModel) -> bool;

/// Whether `pet` lands within ±10 % of `tau`.
fn within_10(pet: f64, tau: f64) -> bool {
    (pet - tau).abs() <= 0.1 * tau
}
