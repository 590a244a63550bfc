//! The synthetic corpus on the project's proving ground: determinism, consistency of states and
//! controls, the interaction each episode claims, the JSON-lines format, and inverse kinematics
//! recovering the simulated controls from noisy positions.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic, clippy::indexing_slicing)]

use std::sync::OnceLock;

use rand_chacha::ChaCha8Rng;
use rand_chacha::rand_core::SeedableRng;
use rand_distr::{Distribution, Normal};
use v2t_diffusion::inverse::{InverseOptions, to_controls};
use v2t_diffusion::mining::{InteractionKind, MiningOptions, mine};
use v2t_diffusion::stats::ControlSamples;
use v2t_diffusion::synth::{
    CorpusIoError, SynthError, SyntheticCorpus, from_jsonl, generate_corpus, generate_episode, to_jsonl,
};
use v2t_map::Map;
use v2t_map::library::TopologyLibrary;
use v2t_model::validate::Validate;

fn map() -> &'static Map {
    static MAP: OnceLock<Map> = OnceLock::new();
    MAP.get_or_init(|| {
        Map::load(&std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config/maps/proving_ground.xodr"))
            .unwrap()
    })
}

fn corpus() -> &'static SyntheticCorpus {
    static CORPUS: OnceLock<SyntheticCorpus> = OnceLock::new();
    CORPUS.get_or_init(|| generate_corpus(map(), 30, 42).unwrap())
}

#[test]
fn the_corpus_is_deterministic_and_episodes_reproduce_alone() {
    let again = generate_corpus(map(), 30, 42).unwrap();
    assert_eq!(&again, corpus());
    let other = generate_corpus(map(), 3, 43).unwrap();
    assert_ne!(other.episodes[0], corpus().episodes[0]);
    let lib = TopologyLibrary::build(map());
    let (alone, _) = generate_episode(&lib, 42, 7).unwrap();
    assert_eq!(alone, corpus().episodes[7]);
}

#[test]
fn every_episode_is_consistent_and_has_its_interaction() {
    let c = corpus();
    assert_eq!(c.episodes.len(), 30);
    let kinds: Vec<InteractionKind> = c.episodes.iter().take(3).map(|e| e.interaction).collect();
    assert_eq!(kinds, vec![InteractionKind::LeftTurn, InteractionKind::CutIn, InteractionKind::Merge]);
    for e in &c.episodes {
        assert!(e.id.starts_with("synthetic-42-"));
        assert!((2..=3).contains(&e.agents.len()));
        let n = e.agents[0].controls.len();
        assert!(n >= 50, "{} has {n} steps", e.id);
        for t in e.trajectories() {
            t.validate().unwrap();
            assert_eq!(t.controls.len(), n, "one time grid");
            assert!(t.rollout_gap_m(e.dt_s) < 1e-9, "controls are the simulation's own");
            assert!(t.states.iter().all(|s| s.speed_mps >= -1e-9), "no reversing");
        }
        assert!(e.pet_s() >= 0.0 && e.pet_s() <= 6.0, "{}: PET {}", e.id, e.pet_s());
        // Mining the episode again finds the interaction it is labelled with.
        let found = mine(&e.to_episode(), &MiningOptions::default());
        let same = |x: &v2t_diffusion::mining::Interaction| {
            (x.kind, &x.actor, &x.other, &x.first) == (e.mined.kind, &e.mined.actor, &e.mined.other, &e.mined.first)
                && (x.pet_s - e.mined.pet_s).abs() < 1e-9
                && x.conflict_point.dist(e.mined.conflict_point) < 1e-6
        };
        assert!(found.iter().any(same), "{}: {:?} not in {found:?}", e.id, e.mined);
        match e.interaction {
            InteractionKind::LeftTurn => assert_eq!(e.mined.kind, InteractionKind::LeftTurn),
            InteractionKind::CutIn => {
                assert_eq!(e.mined.kind, InteractionKind::CutIn);
                assert_eq!((e.mined.actor.as_str(), e.mined.first.as_str()), ("cutter", "cutter"));
            }
            _ => assert_eq!(e.mined.actor, "merging"),
        }
    }
}

#[test]
fn the_summary_counts_every_episode() {
    let s = corpus().summary();
    assert_eq!(s.episodes, 30);
    assert_eq!(s.by_kind.iter().map(|k| k.2).sum::<usize>(), 30);
    assert_eq!(s.pet_s.total(), 30);
    let steps: usize = corpus().episodes.iter().flat_map(|e| e.agents.iter().map(|a| a.controls.len())).sum();
    assert_eq!(s.controls.accel.total() + s.controls.accel.non_finite, steps as u64);
    let back: v2t_diffusion::synth::CorpusSummary = serde_json::from_str(&serde_json::to_string(&s).unwrap()).unwrap();
    assert_eq!(back, s);
}

#[test]
fn drivers_are_heterogeneous() {
    let v0: Vec<f64> =
        corpus().episodes.iter().flat_map(|e| e.agents.iter().map(|a| a.driver.time_headway_s)).collect();
    let lo = v0.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = v0.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    assert!(lo < 1.1 && hi > 1.9, "T spans {lo}..{hi}");
}

#[test]
fn json_lines_round_trip_and_errors() {
    let c = corpus();
    let text = to_jsonl(c).unwrap();
    assert!(text.lines().next().unwrap().contains("\"synthetic\":true"));
    assert_eq!(&from_jsonl(&text).unwrap(), c);
    let newer = text.replacen("\"version\":1", "\"version\":2", 1);
    assert_eq!(from_jsonl(&newer).unwrap_err(), CorpusIoError::Version { found: 2, known: 1 });
    let recorded = text.replacen("\"synthetic\":true", "\"synthetic\":false", 1);
    assert!(matches!(from_jsonl(&recorded), Err(CorpusIoError::Format { .. })));
    let mut lines: Vec<&str> = text.lines().collect();
    lines.pop();
    assert_eq!(from_jsonl(&lines.join("\n")).unwrap_err(), CorpusIoError::Count { announced: 30, found: 29 });
    lines[3] = "{\"id\": 5}";
    assert!(matches!(from_jsonl(&lines.join("\n")), Err(CorpusIoError::Json { line: 4, .. })));
    assert_eq!(from_jsonl("").unwrap_err(), CorpusIoError::Empty);
}

#[test]
fn a_map_without_fragments_is_an_error() {
    let xodr = r#"<OpenDRIVE><header revMajor="1" revMinor="6"/>
      <road id="1" length="100" junction="-1">
        <planView><geometry s="0" x="0" y="0" hdg="0" length="100"><line/></geometry></planView>
        <lanes><laneSection s="0">
          <center><lane id="0" type="none"/></center>
          <right><lane id="-1" type="driving"><width sOffset="0" a="3.5" b="0" c="0" d="0"/></lane></right>
        </laneSection></lanes>
      </road></OpenDRIVE>"#;
    let m = Map::parse(xodr, "single").unwrap();
    assert!(matches!(generate_corpus(&m, 1, 0), Err(SynthError::NoFragments(_))));
}

/// The realism pipeline end to end: positions of the synthetic episodes with 5 cm noise go through
/// inverse kinematics; the recovered controls are close to the simulated ones in distribution.
#[test]
fn inverse_kinematics_recovers_the_simulated_controls() {
    let mut rng = ChaCha8Rng::seed_from_u64(9);
    let noise = Normal::new(0.0, 0.05).unwrap();
    let (mut truth, mut recovered) = (ControlSamples::default(), ControlSamples::default());
    let mut worst_gap: f64 = 0.0;
    for e in &corpus().episodes {
        for (a, mut track) in e.agents.iter().zip(e.to_episode().tracks) {
            for s in &mut track.samples {
                s.x_m += noise.sample(&mut rng);
                s.y_m += noise.sample(&mut rng);
            }
            let inv = to_controls(&track, &InverseOptions::default()).unwrap();
            worst_gap = worst_gap.max(inv.rollout_gap_m);
            truth.add_sequence(&a.controls, e.dt_s);
            recovered.add_sequence(&inv.trajectory.controls, e.dt_s);
        }
    }
    let d = truth.distance(&recovered);
    println!("W1 simulated vs recovered: {d:?}, worst rollout gap {worst_gap:.2e} m");
    assert!(worst_gap < 0.05, "gap {worst_gap}");
    assert!(d.accel_mps2.unwrap() < 0.25, "{d:?}");
    assert!(d.yaw_rate_radps.unwrap() < 0.02, "{d:?}");
}

/// Any map: a plain straight two-lane road long enough for cut-ins gives a corpus of cut-ins only.
#[test]
fn a_two_lane_road_gives_cut_ins() {
    let xodr = r#"<OpenDRIVE><header revMajor="1" revMinor="6"/>
      <road id="1" length="400" junction="-1">
        <planView><geometry s="0" x="0" y="0" hdg="0" length="400"><line/></geometry></planView>
        <lanes><laneSection s="0">
          <center><lane id="0" type="none"/></center>
          <right>
            <lane id="-1" type="driving"><width sOffset="0" a="3.5" b="0" c="0" d="0"/></lane>
            <lane id="-2" type="driving"><width sOffset="0" a="3.5" b="0" c="0" d="0"/></lane>
          </right>
        </laneSection></lanes>
      </road></OpenDRIVE>"#;
    let m = Map::parse(xodr, "straight").unwrap();
    let c = generate_corpus(&m, 4, 3).unwrap();
    assert!(
        c.episodes.iter().all(|e| e.interaction == InteractionKind::CutIn && e.mined.kind == InteractionKind::CutIn)
    );
    assert!(
        c.episodes.iter().all(|e| e.agents[0].states.iter().all(|s| s.py < 0.5 && s.py > -7.5)),
        "stays on the road"
    );
}

/// Mining is robust to recording noise: with 10 cm position noise the labelled interaction is still
/// found, with the same kind and order, and PET within 0.25 s.
#[test]
fn mining_survives_position_noise() {
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let noise = Normal::new(0.0, 0.1).unwrap();
    let mut worst: f64 = 0.0;
    for e in &corpus().episodes {
        let mut episode = e.to_episode();
        for t in &mut episode.tracks {
            for s in &mut t.samples {
                s.x_m += noise.sample(&mut rng);
                s.y_m += noise.sample(&mut rng);
            }
        }
        let found = mine(&episode, &MiningOptions::default());
        let m = &e.mined;
        let hit = found
            .iter()
            .filter(|x| (x.kind, &x.actor, &x.other, &x.first) == (m.kind, &m.actor, &m.other, &m.first))
            .map(|x| (x.pet_s - m.pet_s).abs())
            .fold(f64::INFINITY, f64::min);
        assert!(hit < 0.25, "{}: {m:?} vs {found:?}", e.id);
        worst = worst.max(hit);
    }
    println!("largest PET change under 10 cm noise: {worst:.3} s");
}
