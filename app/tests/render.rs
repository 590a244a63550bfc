//! `video2track render` end to end: a simulated left turn becomes an mp4 that `ffprobe` reads with
//! the run's duration and the asked size, and the scenario-abstraction frame pipeline (`v2t_vlm`'s
//! frame extraction, uniform and motion sampling) works on it.

#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)] // test code

mod common;

use common::{repo, tempdir, text, video2track};

use std::path::{Path, PathBuf};
use std::process::Command;

use v2t_vlm::frames::{FrameSettings, extract_frames};

/// `video2track sim` of the left-turn card: the run file and the time its trace spans, s.
fn left_turn_run(dir: &Path) -> (PathBuf, f64) {
    let json = dir.join("left_turn.json");
    let o = video2track(&["sim", "config/scenarios/left_turn_basic.toml", "--json", json.to_str().unwrap()]);
    assert!(o.status.success(), "{}", text(&o).1);
    let v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let trace = v["trace"].as_array().unwrap();
    let span = trace.last().unwrap()["t_s"].as_f64().unwrap() - trace[0]["t_s"].as_f64().unwrap();
    // The 10 Hz trace spans the whole simulated time.
    assert!((span - v["result"]["duration_s"].as_f64().unwrap()).abs() < 0.11, "{span}");
    (json, span)
}

fn ffprobe(video: &Path) -> serde_json::Value {
    let o = Command::new("ffprobe")
        .args(["-v", "error", "-select_streams", "v:0", "-count_frames"])
        .args(["-show_entries", "stream=codec_name,width,height,nb_read_frames,pix_fmt:format=duration"])
        .args(["-of", "json"])
        .arg(video)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", text(&o).1);
    serde_json::from_slice(&o.stdout).unwrap()
}

#[test]
fn a_simulated_left_turn_renders_to_an_mp4_the_frame_pipeline_reads() {
    v2t_test_support::require!(v2t_test_support::VIDEO_TOOLS);
    let dir_scratch = tempdir("render");
    let dir = dir_scratch.path();
    let (run, span) = left_turn_run(dir);
    assert!(span > 3.0, "{span}");
    let mp4 = dir.join("left_turn.mp4");
    let o = video2track(&["render", run.to_str().unwrap(), "-o", mp4.to_str().unwrap(), "--width", "640"]);
    let (out, err) = text(&o);
    assert!(o.status.success(), "{err}");
    assert!(out.contains("left_turn_basic: 2 vehicles") && out.contains("640x360") && out.contains("wrote"), "{out}");

    // ffprobe: H.264 (or MPEG-4), 640×360, one frame per 0.1 s of the trace and its first sample.
    let p = ffprobe(&mp4);
    let stream = &p["streams"][0];
    assert!(["h264", "mpeg4"].contains(&stream["codec_name"].as_str().unwrap()), "{p}");
    assert_eq!((stream["width"].as_u64(), stream["height"].as_u64()), (Some(640), Some(360)), "{p}");
    assert_eq!(stream["pix_fmt"], "yuv420p");
    let frames: f64 = stream["nb_read_frames"].as_str().unwrap().parse().unwrap();
    assert_eq!(frames, (span * 10.0).round() + 1.0, "{p}");
    let duration: f64 = p["format"]["duration"].as_str().unwrap().parse().unwrap();
    // The last sample is shown for one frame time too.
    assert!((duration - (span + 0.1)).abs() < 0.05, "duration {duration} s for a run of {span} s");
    assert!(std::fs::metadata(&mp4).unwrap().len() > 2_000);

    // The frame pipeline of scenario abstraction on the rendered video: uniform frames ...
    let settings = FrameSettings { count: 8, ..FrameSettings::default() };
    let (info, shots) = extract_frames(&mp4, &settings).unwrap();
    assert_eq!((info.width, info.height), (640, 360));
    assert!((info.duration_s - duration).abs() < 0.05, "{info:?}");
    assert!((info.fps - 10.0).abs() < 1e-6, "{info:?}");
    assert_eq!(shots.len(), 8);
    for (i, f) in shots.iter().enumerate() {
        let expected_ms = ((i as f64 + 0.5) * info.duration_s / 8.0 * 1000.0).round() as u64;
        assert_eq!(f.timestamp_ms, expected_ms, "frame {i}");
        assert_eq!((f.width, f.height), (640, 360), "no enlargement");
        assert_eq!(&f.jpeg[..2], &[0xff, 0xd8], "a JPEG");
        assert!(f.jpeg.len() > 1_000, "frame {i}: {} bytes", f.jpeg.len());
    }
    // ... and motion sampling: the vehicles move, so the places of change are found.
    let settings = FrameSettings { count: 6, motion_frames: 3, ..FrameSettings::default() };
    let (_, shots) = extract_frames(&mp4, &settings).unwrap();
    assert_eq!(shots.len(), 6);
    assert!(shots.windows(2).all(|w| w[0].timestamp_ms < w[1].timestamp_ms));
    assert!(shots.iter().all(|f| (f.timestamp_ms as f64) < info.duration_s * 1000.0));
    // Successive frames differ: something moves in the picture.
    assert!(shots.windows(2).all(|w| w[0].jpeg != w[1].jpeg));
}

#[test]
fn render_takes_the_card_and_the_map_and_other_rates() {
    v2t_test_support::require!(v2t_test_support::VIDEO_TOOLS);
    let dir_scratch = tempdir("render-card");
    let dir = dir_scratch.path();
    let (run, span) = left_turn_run(dir);
    let mp4 = dir.join("card.mp4");
    let o = video2track(&[
        "render",
        run.to_str().unwrap(),
        "--out",
        mp4.to_str().unwrap(),
        "--fps",
        "20",
        "--width",
        "320",
        "--card",
        "config/scenarios/left_turn_basic.toml",
        "--map",
        "config/maps/proving_ground.xodr",
    ]);
    let (out, err) = text(&o);
    assert!(o.status.success(), "{err}");
    assert!(out.contains("at 20 fps, 320x180"), "{out}");
    let p = ffprobe(&mp4);
    let frames: f64 = p["streams"][0]["nb_read_frames"].as_str().unwrap().parse().unwrap();
    assert_eq!(frames, (span * 20.0).round() + 1.0, "{p}");

    // A card of another scenario does not fit the run.
    let o = video2track(&[
        "render",
        run.to_str().unwrap(),
        "-o",
        dir.join("x.mp4").to_str().unwrap(),
        "--card",
        "config/scenarios/cut_in_basic.toml",
    ]);
    let (_, err) = text(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("cut_in_basic.toml") && err.contains("`left_turn_basic`"), "{err}");
}

#[test]
fn bad_render_input_is_an_input_error_and_a_missing_ffmpeg_is_named() {
    let dir_scratch = tempdir("render-bad");
    let dir = dir_scratch.path();
    let bad = dir.join("bad.json");
    std::fs::write(&bad, "{\"trace\": 3}").unwrap();
    for args in [
        vec!["render", bad.to_str().unwrap(), "-o", "/tmp/never.mp4"],
        vec!["render", "no/such/run.json", "-o", "/tmp/never.mp4"],
        vec!["render", bad.to_str().unwrap(), "-o", "/tmp/never.mp4", "--width", "641"],
        vec!["render", bad.to_str().unwrap(), "-o", "/tmp/never.mp4", "--fps", "0"],
    ] {
        let o = video2track(&args);
        let (_, err) = text(&o);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
        assert!(!err.contains("panicked"), "{err}");
    }
    let o = video2track(&["render", bad.to_str().unwrap(), "-o", "/tmp/never.mp4"]);
    assert!(text(&o).1.contains("bad.json"));

    let (run, _) = left_turn_run(dir);
    let o = Command::new(env!("CARGO_BIN_EXE_video2track"))
        .args(["render", run.to_str().unwrap(), "-o", dir.join("x.mp4").to_str().unwrap()])
        .env("PATH", dir.join("empty-path"))
        .current_dir(repo())
        .output()
        .unwrap();
    let (_, err) = text(&o);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(err.contains("`ffmpeg` was not found") && err.contains("apt-get install ffmpeg"), "{err}");
}
