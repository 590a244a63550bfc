//! The committed NGSIM recordings (CommonRoad 2018b and 2020a, `config/diffusion/recordings/`)
//! through the importer, the lane network, mining, inverse kinematics and the training windows.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic, clippy::indexing_slicing)]

use std::path::{Path, PathBuf};

use v2t_diffusion::denoiser::DenoiserConfig;
use v2t_diffusion::import::commonroad::{self, CommonRoadError};
use v2t_diffusion::inverse::InverseOptions;
use v2t_diffusion::mining::{InteractionKind, MiningOptions};
use v2t_diffusion::recorded::{self, ImportOptions, RecordedCorpus};
use v2t_diffusion::train::{Dataset, MIN_WINDOW_STEPS, recorded_episodes};

fn recordings(split: &str) -> Vec<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config/diffusion/recordings/ngsim").join(split);
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().path()).collect();
    files.sort();
    files
}

fn import(split: &str) -> RecordedCorpus {
    let options = ImportOptions {
        dataset: format!("NGSIM {split}"),
        licence: "NGSIM: US DOT public data; CommonRoad conversion BSD-3-Clause / MIT".into(),
        mining: MiningOptions { position_noise_m: 0.1, ..MiningOptions::default() },
        inverse: InverseOptions { position_noise_m: 0.1, ..InverseOptions::default() },
        resample_s: None,
    };
    let mut corpus = RecordedCorpus::default();
    for f in recordings(split) {
        let s = commonroad::parse_scenario_file(&f).unwrap();
        let (source, episodes) =
            recorded::import_scenario(&s.episode, &s.lanes, &f.display().to_string(), &s.version, &options);
        corpus.sources.push(source);
        corpus.episodes.extend(episodes);
    }
    corpus
}

#[test]
fn both_commonroad_formats_read_with_their_lanes() {
    let old = commonroad::parse_scenario_file(&recordings("train")[4]).unwrap();
    assert!(old.episode.id.contains("US101-3_3"), "{}", old.episode.id);
    assert_eq!(old.version, "2018b");
    assert_eq!((old.episode.tracks.len(), old.lanes.lanelets().len()), (12, 12));
    assert!(old.source.contains("NGSIM"));
    let new = commonroad::parse_scenario_file(&recordings("heldout")[1]).unwrap();
    assert_eq!(new.version, "2020a");
    assert_eq!(new.episode.tracks.len(), 9);
    assert!(new.lanes.lanelets().len() > 50);
    for s in [&old, &new] {
        assert!((s.episode.dt_s - 0.1).abs() < 1e-12);
        for l in s.lanes.lanelets() {
            assert_eq!(l.left.len(), l.right.len());
        }
    }
}

#[test]
fn the_recordings_give_lane_changes_and_left_turns_with_routes_and_controls() {
    let train = import("train");
    let heldout = import("heldout");
    let tracks: usize = train.sources.iter().chain(&heldout.sources).map(|s| s.tracks).sum();
    assert_eq!(tracks, 250);
    let all: Vec<_> = train.episodes.iter().chain(&heldout.episodes).collect();
    assert!(all.len() >= 30, "{} episodes", all.len());
    let count = |k: InteractionKind| all.iter().filter(|e| e.mined.kind == k).count();
    assert!(count(InteractionKind::CutIn) + count(InteractionKind::LaneChange) >= 20);
    assert!(count(InteractionKind::LeftTurn) >= 1);
    for e in &all {
        assert!(e.licence.starts_with("NGSIM"));
        assert_eq!(e.agents.len(), 2);
        assert_eq!(e.agents[0].id, e.mined.actor);
        for a in &e.agents {
            assert_eq!(a.route_from, "lanes");
            assert!(a.route.len() >= 2);
            assert_eq!(a.controls.len() + 1, a.states.len());
            assert!(a.controls.iter().all(|u| u.accel_mps2.is_finite() && u.yaw_rate_radps.is_finite()));
            // NGSIM is noisy but no car brakes at 1 g or turns at 60°/s on these roads.
            assert!(a.controls.iter().all(|u| u.accel_mps2.abs() < 10.0 && u.yaw_rate_radps.abs() < 1.0), "{}", e.id);
        }
    }
    // Every lane change's actor moves into the other's lane: the other ends on the actor's route.
    for e in all.iter().filter(|e| matches!(e.mined.kind, InteractionKind::CutIn | InteractionKind::LaneChange)) {
        let route = v2t_model::path::ReferencePath::from_points(&e.agents[0].route).unwrap();
        let other_end = e.agents[1].states.last().unwrap().position();
        let off = route.project(other_end).map(|f| f.l_m.abs()).unwrap_or(f64::INFINITY);
        assert!(off <= 1.8, "{}: the other vehicle ends {off:.1} m off the actor's route", e.id);
    }
}

#[test]
fn recorded_windows_mask_what_was_not_recorded() {
    let (train, heldout) = (import("train"), import("heldout"));
    let mut episodes = recorded_episodes(&train.episodes, false).0;
    episodes.extend(recorded_episodes(&heldout.episodes, true).0);
    let cfg = DenoiserConfig::default();
    let data = Dataset::build_from(&episodes, cfg, 5, None).unwrap();
    assert!(data.train.len() >= 50 && data.heldout.len() >= 20, "{} / {}", data.train.len(), data.heldout.len());
    for w in data.train.iter().chain(&data.heldout) {
        for (slot, n) in w.data_steps.iter().enumerate() {
            assert!(*n >= MIN_WINDOW_STEPS && *n <= cfg.steps);
            for ch in 0..2 {
                let row = &w.mask[(2 * slot + ch) * cfg.steps..(2 * slot + ch + 1) * cfg.steps];
                assert!(row[..*n].iter().all(|v| *v == 1.0) && row[*n..].iter().all(|v| *v == 0.0));
            }
            assert_eq!(w.controls[slot].len(), *n);
        }
        // Both conflict vehicles pass the conflict inside their data.
        for (slot, s) in w.condition.slots.iter().take(2).enumerate() {
            let t = s.as_ref().unwrap().anchor.unwrap().1;
            assert!(t >= 0.5 - 1e-9 && t <= w.data_steps[slot] as f64 * 0.1 - 0.5 + 1e-9);
        }
    }
}

#[test]
fn a_damaged_recording_is_refused_with_its_line() {
    let path = &recordings("heldout")[1];
    let text = std::fs::read_to_string(path).unwrap();
    let at = text.find("<x>").unwrap() + 3;
    let line = text[..at].lines().count() as u32;
    let damaged = format!("{}NaN{}", &text[..at], &text[at..].split_once('<').map(|(_, r)| format!("<{r}")).unwrap());
    match commonroad::parse_scenario(&damaged, "d") {
        Err(
            CommonRoadError::Number { line: l, ref element, .. }
            | CommonRoadError::Lanelet { line: l, lanelet: ref element, .. },
        ) => {
            assert!(l >= line.saturating_sub(3) && l <= line + 3, "line {l}, expected about {line}");
            assert!(!element.is_empty());
        }
        other => panic!("{other:?}"),
    }
    let cut = &text[..text.len() / 2];
    assert!(matches!(commonroad::parse_scenario(cut, "d"), Err(CommonRoadError::Xml(_))));
    let newer = text.replacen("commonRoadVersion=\"2020a\"", "commonRoadVersion=\"2031z\"", 1);
    assert!(matches!(commonroad::parse_scenario(&newer, "d"), Err(CommonRoadError::Version { .. })));
}
