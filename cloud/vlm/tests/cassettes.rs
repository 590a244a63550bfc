//! The shipped, hand-written cassettes for the paper's scenarios (the cut-in, the left turn with the
//! BV turning, the left turn with the VUT turning) replay offline to the example semantics, byte for
//! byte.
//!
//! `V2T_BLESS_CASSETTES=1 cargo test -p v2t-vlm --test cassettes` rebuilds their requests after a
//! prompt or request change (hand-written cassettes only; recorded ones must be recorded again).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic, clippy::indexing_slicing)]

mod common;

use std::path::Path;

use common::repo_root;
use v2t_model::semantics::parse_semantics_json;
use v2t_vlm::cassette::{Cassette, SEMANTICS_FILE, semantics_text};
use v2t_vlm::{Mode, VlmConfig, abstract_video, bless_cassette};

const CASES: [(&str, &str, &str, f64); 3] = [
    ("cut_in", "cut_in_4.70.mp4", "semantics_cut_in.json", 4.70),
    ("left_turn", "left_turn_2.90.mp4", "semantics_left_turn.json", 2.90),
    ("left_turn_vut", "left_turn_vut_2.40.mp4", "semantics_left_turn_vut.json", 2.40),
];

#[test]
fn shipped_cassettes_replay_to_the_example_semantics() {
    let bless = std::env::var_os("V2T_BLESS_CASSETTES").is_some();
    for (name, video, example, pet) in CASES {
        let dir = repo_root().join("config/vlm/cassettes").join(name);
        if bless {
            bless_cassette(&dir, &VlmConfig::default()).unwrap();
        }
        let cassette = Cassette::load(&dir).unwrap();
        assert!(cassette.manifest.provenance.starts_with("HAND-WRITTEN, not real model output"), "{name}");
        assert!(cassette.manifest.settings.model.contains("hand-written"), "{name}: names no real model");

        let a = abstract_video(Path::new(video), pet, &VlmConfig::default(), &Mode::Replay(dir.clone())).unwrap();
        assert_eq!((a.requests, a.repairs), (1, 0), "{name}");
        assert!(a.provenance.contains("HAND-WRITTEN"), "{name}: a replay says where its answer comes from");
        let replayed = semantics_text(&a.semantics).unwrap();

        // The document the cassette recorded ...
        let recorded = std::fs::read_to_string(dir.join(SEMANTICS_FILE)).unwrap();
        assert_eq!(replayed, recorded, "{name}: replay differs from the recorded semantics");
        // ... is the example, written the way the pipeline writes documents.
        let example = std::fs::read_to_string(repo_root().join("config/examples").join(example)).unwrap();
        let example = parse_semantics_json(&example).unwrap();
        assert_eq!(a.semantics, example, "{name}");
        assert_eq!(replayed, semantics_text(&example).unwrap(), "{name}");
    }
}

#[test]
fn the_pet_label_comes_from_the_caller_not_the_cassette() {
    let dir = repo_root().join("config/vlm/cassettes/left_turn");
    let a = abstract_video(Path::new("left_turn_2.90.mp4"), 1.5, &VlmConfig::default(), &Mode::Replay(dir)).unwrap();
    assert_eq!(a.semantics.pet_label_s, 1.5);
}

#[test]
fn a_missing_cassette_is_a_clear_error() {
    let dir = repo_root().join("config/vlm/cassettes/no_such_scenario");
    let e = abstract_video(Path::new("x.mp4"), 1.0, &VlmConfig::default(), &Mode::Replay(dir)).unwrap_err();
    assert!(e.to_string().contains("no_such_scenario") && e.to_string().contains("cassette.json"), "{e}");
}

#[test]
fn every_file_under_config_vlm_checks() {
    fn walk(dir: &Path, out: &mut Vec<std::path::PathBuf>) {
        for entry in std::fs::read_dir(dir).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() { walk(&path, out) } else { out.push(path) }
        }
    }
    let mut files = Vec::new();
    walk(&repo_root().join("config/vlm"), &mut files);
    assert!(files.len() >= 7, "{files:?}");
    for path in &files {
        v2t_vlm::check_config_file(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    }
    let stray = repo_root().join("config/vlm/cassettes/cut_in/notes.txt");
    let e = v2t_vlm::check_config_file(&stray).unwrap_err();
    assert!(e.to_string().contains("not part of the cassette"), "{e}");
}
