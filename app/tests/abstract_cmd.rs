//! `video2track abstract` end to end: the shipped cassettes replay to their recorded semantics byte
//! for byte, and bad input (a missing video, a bad label, no endpoint, a cassette for another video)
//! gives a message that says what to fix and exit code 2.

#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)] // test code

mod common;

use common::{repo, tempdir, text};

use std::process::{Command, Output};

/// Runs the binary in the repository root with no `V2T_VLM_*` variable set.
fn video2track(args: &[&str]) -> Output {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_video2track"));
    for (name, _) in std::env::vars_os() {
        if name.to_string_lossy().starts_with("V2T_VLM_") {
            cmd.env_remove(name);
        }
    }
    cmd.args(args).current_dir(repo()).output().unwrap()
}

#[test]
fn replaying_the_shipped_cassettes_writes_their_semantics_byte_for_byte() {
    let dir_scratch = tempdir("abstract-replay");
    let dir = dir_scratch.path();
    for (name, video, pet, kind) in [
        ("cut_in", "cut_in_4.70.mp4", "4.70", "cut_in"),
        ("left_turn", "left_turn_2.90.mp4", "2.90", "unprotected_left_turn"),
        ("left_turn_vut", "left_turn_vut_2.40.mp4", "2.40", "unprotected_left_turn"),
    ] {
        let out = dir.join(format!("{name}.json"));
        let cassette = format!("config/vlm/cassettes/{name}");
        let o = video2track(&[
            "abstract",
            video,
            "--replay",
            &cassette,
            "--pet-label",
            pet,
            "--out",
            out.to_str().unwrap(),
        ]);
        let (stdout, err) = text(&o);
        assert!(o.status.success(), "{name}: {err}");
        let recorded = std::fs::read(repo().join(&cassette).join("semantics.json")).unwrap();
        assert_eq!(std::fs::read(&out).unwrap(), recorded, "{name}: output differs from the cassette's semantics.json");
        for needle in [
            &format!("video {video}") as &str,
            "frames 16, 32x18 at ",
            "model none: hand-written exchange",
            "prompt semantics-v1",
            "1 request(s), 0 repair(s)",
            &format!("PET label {pet} s"),
            &format!("bv1: {kind}"),
            "wrote ",
        ] {
            assert!(stdout.contains(needle), "{name}: `{needle}` missing from:\n{stdout}");
        }
    }
    // The first frame of the cut-in cassette is at 0.313 s.
    let o =
        video2track(&["abstract", "cut_in_4.70.mp4", "--replay", "config/vlm/cassettes/cut_in", "--pet-label", "4.7"]);
    assert!(text(&o).0.contains("at 0.31 0.94 1.56"), "{}", text(&o).0);
}

#[test]
fn the_label_goes_into_the_semantics() {
    let dir_scratch = tempdir("abstract-label");
    let dir = dir_scratch.path();
    let out = dir.join("s.json");
    let o = video2track(&[
        "abstract",
        "left_turn_2.90.mp4",
        "--replay",
        "config/vlm/cassettes/left_turn",
        "--pet-label",
        "1.5",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", text(&o).1);
    let v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&out).unwrap()).unwrap();
    assert_eq!(v["pet_label_s"], 1.5);
}

fn expect_input_error(args: &[&str], needles: &[&str]) {
    let o = video2track(args);
    let (_, err) = text(&o);
    assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
    assert!(!err.contains("panicked"), "{err}");
    for n in needles {
        assert!(err.contains(n), "{args:?}: `{n}` missing from: {err}");
    }
}

#[test]
fn bad_labels_are_input_errors() {
    let replay = ["abstract", "cut_in_4.70.mp4", "--replay", "config/vlm/cassettes/cut_in", "--pet-label"];
    for (label, needle) in [
        ("nan", "NaN"),
        ("0", "PET label"),
        ("-1", "PET label"),
        ("0.05", "[0.1, 30]"),
        ("30.5", "[0.1, 30]"),
        ("soon", "soon"),
    ] {
        expect_input_error(&[&replay[..], &[label]].concat(), &[needle]);
        // Checked before the video and the endpoint.
        expect_input_error(&["abstract", "no/such/video.mp4", "--pet-label", label], &[needle]);
    }
}

#[test]
fn a_missing_video_is_an_input_error() {
    expect_input_error(&["abstract", "no/such/video.mp4", "--pet-label", "2.0"], &["no/such/video.mp4"]);
    expect_input_error(
        &["abstract", "no/such/video.mp4", "--pet-label", "2.0", "--record", "/tmp/v2t-never-written"],
        &["no/such/video.mp4"],
    );
}

#[test]
fn no_endpoint_is_a_clear_error() {
    // Any readable file will do: the endpoint is checked before the frames are taken.
    let dir_scratch = tempdir("abstract-endpoint");
    let dir = dir_scratch.path();
    let video = dir.join("clip.mp4");
    std::fs::write(&video, b"not really a video").unwrap();
    expect_input_error(
        &["abstract", video.to_str().unwrap(), "--pet-label", "2.0"],
        &["no VLM endpoint configured", "V2T_VLM_BASE_URL", "V2T_VLM_MODEL", "V2T_VLM_API_KEY", "--replay"],
    );
}

#[test]
fn replay_options_are_checked() {
    // The cassette is for another video.
    expect_input_error(
        &["abstract", "left_turn_2.90.mp4", "--replay", "config/vlm/cassettes/cut_in", "--pet-label", "2.9"],
        &["cut_in_4.70.mp4", "left_turn_2.90.mp4"],
    );
    // No such cassette.
    expect_input_error(
        &["abstract", "x.mp4", "--replay", "config/vlm/cassettes/nope", "--pet-label", "2.9"],
        &["nope", "cassette.json"],
    );
    // Frames come from the cassette.
    expect_input_error(
        &[
            "abstract",
            "cut_in_4.70.mp4",
            "--replay",
            "config/vlm/cassettes/cut_in",
            "--pet-label",
            "4.7",
            "--frames",
            "8",
        ],
        &["--frames"],
    );
    expect_input_error(
        &[
            "abstract",
            "cut_in_4.70.mp4",
            "--replay",
            "config/vlm/cassettes/cut_in",
            "--pet-label",
            "4.7",
            "--record",
            "/tmp/x",
        ],
        &["--record"],
    );
    expect_input_error(&["abstract", "a.mp4", "--pet-label", "4.7", "--frames", "65"], &["--frames", "64"]);
    expect_input_error(&["abstract", "a.mp4", "--pet-label", "4.7", "--sampling", "random"], &["random"]);
}

#[test]
fn the_label_comes_from_the_annotation_file_beside_the_video_when_not_given() {
    let dir_scratch = tempdir("abstract-labels");
    let dir = dir_scratch.path();
    // The cassette recorded `cut_in_4.70.mp4`: an annotation beside a video of that name.
    let video = dir.join("cut_in_4.70.mp4");
    std::fs::write(dir.join("cut_in_4.70.labels.toml"), "pet_label_s = 4.70\nnote = \"measured by hand\"\n").unwrap();
    let out = dir.join("cut_in.json");
    let cassette = "config/vlm/cassettes/cut_in";
    let o = video2track(&["abstract", video.to_str().unwrap(), "--replay", cassette, "--out", out.to_str().unwrap()]);
    assert!(o.status.success(), "{}", text(&o).1);
    let recorded = std::fs::read(repo().join(cassette).join("semantics.json")).unwrap();
    assert_eq!(std::fs::read(&out).unwrap(), recorded);

    // An explicit --labels file; a bad one and none at all are input errors that say what to do.
    let other = dir.join("other.toml");
    std::fs::write(&other, "pet_label_s = 4.70\n").unwrap();
    let o =
        video2track(&["abstract", video.to_str().unwrap(), "--replay", cassette, "--labels", other.to_str().unwrap()]);
    assert!(o.status.success(), "{}", text(&o).1);
    std::fs::write(&other, "pet = 4.70\n").unwrap();
    let o =
        video2track(&["abstract", video.to_str().unwrap(), "--replay", cassette, "--labels", other.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o).1);
    assert!(text(&o).1.contains("pet"), "{}", text(&o).1);
    let o = video2track(&["abstract", "elsewhere/cut_in_4.70.mp4", "--replay", cassette]);
    assert_eq!(o.status.code(), Some(2));
    assert!(text(&o).1.contains("--pet-label"), "{}", text(&o).1);
}
