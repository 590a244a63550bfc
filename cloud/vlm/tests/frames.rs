//! The frame pipeline end to end on videos made with ffmpeg's `testsrc`.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic, clippy::indexing_slicing)]

mod common;

use common::{make_video, temp_dir};
use v2t_vlm::frames::{FrameError, FrameSettings, extract_frames, motion_scores, probe};

#[test]
fn uniform_frames_are_scaled_jpegs_with_timestamps() {
    v2t_test_support::require!(v2t_test_support::VIDEO_TOOLS);
    let dir_scratch = temp_dir("frames");
    let dir = dir_scratch.path();
    let video = make_video(dir, "hd.mp4", "testsrc=duration=4:size=1280x720:rate=25");
    let settings = FrameSettings { count: 5, ..FrameSettings::default() };
    let (info, frames) = extract_frames(&video, &settings).unwrap();
    assert_eq!((info.width, info.height), (1280, 720));
    assert!((info.duration_s - 4.0).abs() < 0.05 && (info.fps - 25.0).abs() < 1e-9, "{info:?}");
    assert_eq!(frames.len(), 5);
    let times: Vec<u64> = frames.iter().map(|f| f.timestamp_ms).collect();
    assert_eq!(times, vec![400, 1200, 2000, 2800, 3600]);
    for f in &frames {
        assert_eq!((f.width, f.height), (768, 432));
        assert!(f.jpeg.starts_with(&[0xFF, 0xD8]) && f.jpeg.ends_with(&[0xFF, 0xD9]), "a whole JPEG");
        assert!(f.data_url().starts_with("data:image/jpeg;base64,/9j/"));
    }
    // testsrc's counter changes: different moments give different pictures.
    assert_ne!(frames[0].jpeg, frames[4].jpeg);
    // The Debug output does not dump the image.
    assert!(format!("{:?}", frames[0]).len() < 120);
}

#[test]
fn motion_frames_land_where_the_picture_changes() {
    v2t_test_support::require!(v2t_test_support::VIDEO_TOOLS);
    let dir_scratch = temp_dir("motion");
    let dir = dir_scratch.path();
    // 3 s of a still grey picture, then 3 s of testsrc: the cut at 3 s is the largest change.
    let graph = "color=c=gray:size=320x180:rate=10:duration=3[a];testsrc=size=320x180:rate=10:duration=3[b];[a][b]concat=n=2:v=1";
    let video = make_video(dir, "cut.mp4", graph);
    let info = probe(&video, &Default::default()).unwrap();
    let scores = motion_scores(&video, &info, &Default::default()).unwrap();
    let (t_max, _) = scores.iter().copied().max_by(|a, b| a.1.total_cmp(&b.1)).unwrap();
    assert!((t_max - 3.0).abs() <= 0.25, "largest change at {t_max} s, {scores:?}");
    let still: f64 = scores.iter().filter(|(t, _)| *t < 2.5).map(|(_, s)| s).sum();
    assert!(still < 1.0, "the still part barely changes: {still}");

    let settings = FrameSettings { count: 4, motion_frames: 1, ..FrameSettings::default() };
    let (_, frames) = extract_frames(&video, &settings).unwrap();
    assert_eq!(frames.len(), 4);
    assert!(frames.iter().any(|f| f.timestamp_ms.abs_diff(3000) <= 250), "{frames:?}");
    assert_eq!((frames[0].width, frames[0].height), (320, 180), "small videos are not enlarged");
}

#[test]
fn limits_and_missing_inputs_are_clear_errors() {
    v2t_test_support::require!(v2t_test_support::VIDEO_TOOLS);
    let dir_scratch = temp_dir("limits");
    let dir = dir_scratch.path();
    let video = make_video(dir, "short.mp4", "testsrc=duration=2:size=160x120:rate=10");
    let too_long = FrameSettings { max_duration_s: 1.0, ..FrameSettings::default() };
    let e = extract_frames(&video, &too_long).unwrap_err();
    assert!(matches!(e, FrameError::TooLong { .. }), "{e:?}");
    assert!(e.to_string().contains("max_duration_s"), "{e}");

    let too_many = FrameSettings { count: 65, ..FrameSettings::default() };
    assert!(matches!(extract_frames(&video, &too_many), Err(FrameError::Settings(_))));

    let e = extract_frames(&dir.join("absent.mp4"), &FrameSettings::default()).unwrap_err();
    assert!(matches!(e, FrameError::Video { .. }) && e.to_string().contains("absent.mp4"), "{e}");

    let not_video = dir.join("notes.mp4");
    std::fs::write(&not_video, "not a video").unwrap();
    let e = extract_frames(&not_video, &FrameSettings::default()).unwrap_err();
    assert!(matches!(e, FrameError::ToolFailed { .. }), "{e:?}");

    let mut no_ffmpeg = FrameSettings::default();
    no_ffmpeg.tools.ffmpeg = "/nonexistent/ffmpeg".into();
    no_ffmpeg.tools.ffprobe = "/nonexistent/ffprobe".into();
    let e = extract_frames(&video, &no_ffmpeg).unwrap_err();
    assert!(matches!(e, FrameError::ToolMissing { .. }) && e.to_string().contains("apt-get install ffmpeg"), "{e}");
}
