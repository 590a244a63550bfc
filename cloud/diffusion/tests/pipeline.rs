//! Importer and miner together: synthetic episodes written as INTERACTION-style CSV and read back
//! give the same interactions; a CommonRoad file goes through inverse kinematics.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic, clippy::indexing_slicing)]

use v2t_diffusion::import::commonroad;
use v2t_diffusion::import::csv::{CsvOptions, parse, write};
use v2t_diffusion::inverse::{InverseOptions, split_at_gaps, to_controls};
use v2t_diffusion::mining::{MiningOptions, mine};
use v2t_diffusion::synth::generate_corpus;

#[test]
fn csv_round_trip_keeps_the_mined_interactions() {
    let map = v2t_map::Map::load(
        &std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config/maps/proving_ground.xodr"),
    )
    .unwrap();
    let corpus = generate_corpus(&map, 6, 5).unwrap();
    for e in &corpus.episodes {
        let episode = e.to_episode();
        let back = parse(&write(&episode), &e.id, &CsvOptions::default()).unwrap();
        assert!(back.gaps.is_empty());
        let (a, b) = (mine(&episode, &MiningOptions::default()), mine(&back.episode, &MiningOptions::default()));
        assert_eq!(a.len(), b.len(), "{}", e.id);
        for (x, y) in a.iter().zip(&b) {
            assert_eq!((x.kind, &x.actor, &x.first), (y.kind, &y.actor, &y.first));
            assert!((x.pet_s - y.pet_s).abs() < 1e-6, "{} vs {}", x.pet_s, y.pet_s);
        }
    }
}

#[test]
fn a_commonroad_file_goes_through_inverse_kinematics() {
    let e = commonroad::parse_file(
        &std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/two_vehicles.cr.xml"),
    )
    .unwrap();
    let car = to_controls(&e.tracks[0], &InverseOptions::default()).unwrap();
    assert!(car.rollout_gap_m < 1e-9);
    assert!((car.trajectory.states[0].speed_mps - 10.0).abs() < 1e-6);
    // The truck has a missing step: split first; a piece of one step is too short.
    let pieces = split_at_gaps(&e.tracks[1]);
    assert_eq!(pieces.len(), 2);
    assert!(to_controls(&pieces[1], &InverseOptions::default()).is_err());
}
