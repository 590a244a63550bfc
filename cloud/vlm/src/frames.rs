//! Frames from a video: probe it with `ffprobe`, pick the moments to show the model (uniformly, and
//! optionally where the picture changes most), decode each with `ffmpeg`, scaled so that the long
//! side is at most [`FrameSettings::max_long_side_px`], as JPEG.
//!
//! `ffmpeg` and `ffprobe` run as subprocesses (Debian package `ffmpeg`); nothing is linked.

use std::io::ErrorKind;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use base64::Engine as _;
use serde::{Deserialize, Serialize};

/// Most frames one request may carry.
pub const MAX_FRAMES: u32 = 64;
/// Side of the grayscale thumbnails compared for motion, px (width; height is 9/16 of it).
const MOTION_THUMB_W: u32 = 64;
const MOTION_THUMB_H: u32 = 36;
/// Most thumbnails decoded for the motion analysis.
const MAX_MOTION_SAMPLES: f64 = 600.0;
/// Rate at which thumbnails are taken for the motion analysis when the video is short enough, Hz.
const MOTION_RATE_HZ: f64 = 5.0;

/// Why frames could not be taken from a video.
#[derive(Debug, thiserror::Error)]
pub enum FrameError {
    /// The video file does not exist or cannot be read.
    #[error("video {path}: {source}")]
    Video {
        /// The path given.
        path: PathBuf,
        /// What the file system said.
        source: std::io::Error,
    },
    /// `ffmpeg` or `ffprobe` is not installed.
    #[error("`{tool}` was not found: install the Debian package `ffmpeg` (apt-get install ffmpeg) or set its path")]
    ToolMissing {
        /// The program that was run.
        tool: PathBuf,
    },
    /// The tool could not be started for another reason.
    #[error("could not run `{tool}`: {source}")]
    Spawn {
        /// The program that was run.
        tool: PathBuf,
        /// What the OS said.
        source: std::io::Error,
    },
    /// The tool ran and failed.
    #[error("`{tool}` failed ({status}) on {video}: {stderr}")]
    ToolFailed {
        /// The program that was run.
        tool: PathBuf,
        /// Its exit status.
        status: String,
        /// The video.
        video: PathBuf,
        /// The end of what it wrote to stderr.
        stderr: String,
    },
    /// `ffprobe` found no usable video stream, or its answer lacks a value.
    #[error("{video}: {problem}")]
    Probe {
        /// The video.
        video: PathBuf,
        /// What is missing or wrong.
        problem: String,
    },
    /// The video is longer than allowed.
    #[error("{video} lasts {duration_s:.1} s, more than the {max_s:.1} s allowed (frame settings `max_duration_s`)")]
    TooLong {
        /// The video.
        video: PathBuf,
        /// Its duration, s.
        duration_s: f64,
        /// The limit, s.
        max_s: f64,
    },
    /// `ffmpeg` gave no JPEG image for a timestamp.
    #[error("{video}: no frame decoded at {timestamp_s:.3} s")]
    NoFrame {
        /// The video.
        video: PathBuf,
        /// The timestamp asked for, s.
        timestamp_s: f64,
    },
    /// The frame settings are out of range.
    #[error("frame settings: {0}")]
    Settings(String),
}

/// Where the tools are.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Tools {
    /// The `ffmpeg` program (a name looked up in `PATH`, or a path).
    pub ffmpeg: PathBuf,
    /// The `ffprobe` program.
    pub ffprobe: PathBuf,
}

impl Default for Tools {
    fn default() -> Self {
        Self { ffmpeg: "ffmpeg".into(), ffprobe: "ffprobe".into() }
    }
}

/// How many frames to take and how large.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct FrameSettings {
    /// Frames shown to the model, 1 to [`MAX_FRAMES`].
    pub count: u32,
    /// Of `count`, how many are placed where the picture changes most (largest mean absolute
    /// difference between consecutive low-resolution grayscale frames); the rest are uniform.
    pub motion_frames: u32,
    /// Longest side of a frame sent, px (smaller videos are not enlarged).
    pub max_long_side_px: u32,
    /// Longest video accepted, s.
    pub max_duration_s: f64,
    /// JPEG quantizer for `ffmpeg -q:v`, 2 (best) to 31.
    pub jpeg_qscale: u8,
    /// The programs.
    pub tools: Tools,
}

impl Default for FrameSettings {
    fn default() -> Self {
        Self {
            count: 16,
            motion_frames: 0,
            max_long_side_px: 768,
            max_duration_s: 300.0,
            jpeg_qscale: 3,
            tools: Tools::default(),
        }
    }
}

impl FrameSettings {
    /// Checks the ranges (NaN fails them).
    pub fn validate(&self) -> Result<(), FrameError> {
        let bad = |m: String| Err(FrameError::Settings(m));
        if !(1..=MAX_FRAMES).contains(&self.count) {
            return bad(format!("count must lie in 1..={MAX_FRAMES}, got {}", self.count));
        }
        if self.motion_frames > self.count {
            return bad(format!("motion_frames ({}) must not exceed count ({})", self.motion_frames, self.count));
        }
        if !(16..=4096).contains(&self.max_long_side_px) {
            return bad(format!("max_long_side_px must lie in 16..=4096, got {}", self.max_long_side_px));
        }
        if !(self.max_duration_s > 0.0 && self.max_duration_s <= 3600.0) {
            return bad(format!("max_duration_s must lie in (0, 3600], got {}", self.max_duration_s));
        }
        if !(2..=31).contains(&self.jpeg_qscale) {
            return bad(format!("jpeg_qscale must lie in 2..=31, got {}", self.jpeg_qscale));
        }
        Ok(())
    }
}

/// What `ffprobe` says about a video.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct VideoInfo {
    /// Duration, s.
    pub duration_s: f64,
    /// Width, px.
    pub width: u32,
    /// Height, px.
    pub height: u32,
    /// Average frame rate, Hz.
    pub fps: f64,
}

/// One frame shown to the model.
#[derive(Clone, PartialEq, Eq)]
pub struct Frame {
    /// Where it is in the video, ms from the start (integer so that it prints and compares exactly).
    pub timestamp_ms: u64,
    /// Width, px.
    pub width: u32,
    /// Height, px.
    pub height: u32,
    /// The JPEG file.
    pub jpeg: Vec<u8>,
}

impl Frame {
    /// Its timestamp, s.
    pub fn timestamp_s(&self) -> f64 {
        self.timestamp_ms as f64 / 1000.0
    }

    /// The JPEG as a `data:image/jpeg;base64,…` URL.
    pub fn data_url(&self) -> String {
        format!("data:image/jpeg;base64,{}", base64::engine::general_purpose::STANDARD.encode(&self.jpeg))
    }
}

impl std::fmt::Debug for Frame {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Frame")
            .field("timestamp_ms", &self.timestamp_ms)
            .field("width", &self.width)
            .field("height", &self.height)
            .field("jpeg_bytes", &self.jpeg.len())
            .finish()
    }
}

/// Probes `video`, picks the frames and decodes them. Returns the video's facts and the frames in
/// time order.
pub fn extract_frames(video: &Path, settings: &FrameSettings) -> Result<(VideoInfo, Vec<Frame>), FrameError> {
    settings.validate()?;
    std::fs::metadata(video).map_err(|source| FrameError::Video { path: video.to_owned(), source })?;
    let info = probe(video, &settings.tools)?;
    // The probe only gives finite, positive durations.
    if info.duration_s > settings.max_duration_s {
        return Err(FrameError::TooLong {
            video: video.to_owned(),
            duration_s: info.duration_s,
            max_s: settings.max_duration_s,
        });
    }
    let motion = if settings.motion_frames > 0 { motion_scores(video, &info, &settings.tools)? } else { Vec::new() };
    let times = select_timestamps(info.duration_s, settings.count, settings.motion_frames, &motion);
    if times.is_empty() {
        return Err(FrameError::Probe { video: video.to_owned(), problem: "no frame to take".into() });
    }
    let (width, height) = fit_long_side(info.width, info.height, settings.max_long_side_px);
    let mut frames = Vec::with_capacity(times.len());
    for t in times {
        let jpeg = decode_jpeg(video, t, width, height, settings)?;
        let timestamp_ms = (t * 1000.0).round().max(0.0) as u64;
        frames.push(Frame { timestamp_ms, width, height, jpeg });
    }
    Ok((info, frames))
}

/// Runs `ffprobe` on a video.
pub fn probe(video: &Path, tools: &Tools) -> Result<VideoInfo, FrameError> {
    let mut cmd = Command::new(&tools.ffprobe);
    cmd.args(["-v", "error", "-select_streams", "v:0", "-show_entries"])
        .arg("stream=width,height,avg_frame_rate,r_frame_rate,duration:format=duration")
        .args(["-of", "json"])
        .arg(video);
    let out = run(&mut cmd, &tools.ffprobe, video)?;
    parse_probe(&String::from_utf8_lossy(&out.stdout))
        .map_err(|problem| FrameError::Probe { video: video.to_owned(), problem })
}

#[derive(Deserialize)]
struct ProbeJson {
    #[serde(default)]
    streams: Vec<ProbeStream>,
    format: Option<ProbeFormat>,
}

#[derive(Deserialize)]
struct ProbeStream {
    width: Option<u32>,
    height: Option<u32>,
    avg_frame_rate: Option<String>,
    r_frame_rate: Option<String>,
    duration: Option<String>,
}

#[derive(Deserialize)]
struct ProbeFormat {
    duration: Option<String>,
}

/// Reads `ffprobe -of json` output.
fn parse_probe(text: &str) -> Result<VideoInfo, String> {
    let probe: ProbeJson = serde_json::from_str(text).map_err(|e| format!("unreadable ffprobe output: {e}"))?;
    let stream = probe.streams.first().ok_or("no video stream")?;
    let (Some(width), Some(height)) = (stream.width, stream.height) else {
        return Err("the video stream has no size".into());
    };
    if width == 0 || height == 0 {
        return Err(format!("the video stream is {width}x{height}"));
    }
    let seconds = |s: &Option<String>| s.as_deref().and_then(|d| d.trim().parse::<f64>().ok());
    let duration_s = probe
        .format
        .as_ref()
        .and_then(|f| seconds(&f.duration))
        .or_else(|| seconds(&stream.duration))
        .filter(|d| d.is_finite() && *d > 0.0)
        .ok_or("no positive duration")?;
    let fps = [&stream.avg_frame_rate, &stream.r_frame_rate]
        .into_iter()
        .filter_map(|r| r.as_deref().and_then(parse_rate))
        .next()
        .ok_or("no frame rate")?;
    Ok(VideoInfo { duration_s, width, height, fps })
}

/// `"30000/1001"` or `"25"` → Hz; `None` for `0/0` and nonsense.
fn parse_rate(rate: &str) -> Option<f64> {
    let value = match rate.split_once('/') {
        Some((n, d)) => n.trim().parse::<f64>().ok()? / d.trim().parse::<f64>().ok()?,
        None => rate.trim().parse::<f64>().ok()?,
    };
    (value.is_finite() && value > 0.0).then_some(value)
}

/// The size that keeps the aspect ratio and puts the long side at most `max_long` px (never
/// enlarging), both sides even and at least 2 px.
pub fn fit_long_side(width: u32, height: u32, max_long: u32) -> (u32, u32) {
    let long = width.max(height).max(1);
    let scale = if long > max_long { f64::from(max_long) / f64::from(long) } else { 1.0 };
    let side = |v: u32| {
        let scaled = (f64::from(v) * scale).floor() as u32;
        (scaled - scaled % 2).max(2)
    };
    (side(width), side(height))
}

/// Picks `count` timestamps in `[0, duration)`: `count − motion` on a uniform grid (the middle of
/// equal slices), then up to `motion` where `motion_scores` (timestamp, score) is largest, each at
/// least half a slice of `count` away from every one already taken; if fewer are found, points of
/// the uniform grid of `count` that keep that distance. Sorted, in s.
pub fn select_timestamps(duration_s: f64, count: u32, motion: u32, motion_scores: &[(f64, f64)]) -> Vec<f64> {
    let motion = motion.min(count);
    let uniform = count - motion;
    let mut times: Vec<f64> =
        (0..uniform).map(|i| (f64::from(i) + 0.5) * duration_s / f64::from(uniform.max(1))).collect();
    let min_gap = duration_s / (2.0 * f64::from(count.max(1)));
    let mut ranked: Vec<&(f64, f64)> = motion_scores.iter().filter(|(t, s)| t.is_finite() && s.is_finite()).collect();
    ranked.sort_by(|a, b| b.1.total_cmp(&a.1).then(a.0.total_cmp(&b.0)));
    let mut added = 0;
    for &&(t, _) in &ranked {
        if added == motion {
            break;
        }
        if (0.0..duration_s).contains(&t) && times.iter().all(|&u| (u - t).abs() >= min_gap) {
            times.push(t);
            added += 1;
        }
    }
    // Too few places of motion (a still or very short video): fill from the uniform grid of `count`.
    let grid = (0..count).map(|i| (f64::from(i) + 0.5) * duration_s / f64::from(count.max(1)));
    for t in grid {
        if times.len() >= count as usize {
            break;
        }
        if times.iter().all(|&u| (u - t).abs() >= min_gap) {
            times.push(t);
        }
    }
    times.sort_by(f64::total_cmp);
    times
}

/// Mean absolute difference between each low-resolution grayscale frame and the one before it, as
/// (timestamp of the later frame, score in 0..=255).
pub fn motion_scores(video: &Path, info: &VideoInfo, tools: &Tools) -> Result<Vec<(f64, f64)>, FrameError> {
    let rate = MOTION_RATE_HZ.min(MAX_MOTION_SAMPLES / info.duration_s).min(info.fps);
    let filter = format!("fps={rate:.6},scale={MOTION_THUMB_W}:{MOTION_THUMB_H}:flags=area,format=gray");
    let mut cmd = Command::new(&tools.ffmpeg);
    cmd.args(["-nostdin", "-v", "error", "-i"]).arg(video).args(["-vf", &filter, "-f", "rawvideo", "pipe:1"]);
    let out = run(&mut cmd, &tools.ffmpeg, video)?;
    Ok(frame_differences(&out.stdout, (MOTION_THUMB_W * MOTION_THUMB_H) as usize, rate))
}

/// Splits raw 8-bit frames of `frame_len` bytes taken at `rate` Hz and scores consecutive pairs.
pub fn frame_differences(raw: &[u8], frame_len: usize, rate: f64) -> Vec<(f64, f64)> {
    if frame_len == 0 {
        return Vec::new();
    }
    let frames: Vec<&[u8]> = raw.chunks_exact(frame_len).collect();
    frames
        .windows(2)
        .enumerate()
        .filter_map(|(i, pair)| {
            let [a, b] = pair else { return None };
            let sum: u64 = a.iter().zip(b.iter()).map(|(x, y)| u64::from(x.abs_diff(*y))).sum();
            Some(((i + 1) as f64 / rate, sum as f64 / frame_len as f64))
        })
        .collect()
}

fn decode_jpeg(video: &Path, t: f64, width: u32, height: u32, s: &FrameSettings) -> Result<Vec<u8>, FrameError> {
    let mut cmd = Command::new(&s.tools.ffmpeg);
    cmd.args(["-nostdin", "-v", "error", "-ss", &format!("{t:.3}"), "-i"])
        .arg(video)
        .args(["-frames:v", "1", "-vf", &format!("scale={width}:{height}:flags=area")])
        .args(["-q:v", &s.jpeg_qscale.to_string(), "-f", "image2pipe", "-c:v", "mjpeg", "pipe:1"]);
    let out = run(&mut cmd, &s.tools.ffmpeg, video)?;
    if out.stdout.starts_with(&[0xFF, 0xD8]) {
        Ok(out.stdout)
    } else {
        Err(FrameError::NoFrame { video: video.to_owned(), timestamp_s: t })
    }
}

fn run(cmd: &mut Command, tool: &Path, video: &Path) -> Result<Output, FrameError> {
    let out = cmd.output().map_err(|source| match source.kind() {
        ErrorKind::NotFound => FrameError::ToolMissing { tool: tool.to_owned() },
        _ => FrameError::Spawn { tool: tool.to_owned(), source },
    })?;
    if out.status.success() {
        Ok(out)
    } else {
        let stderr = String::from_utf8_lossy(&out.stderr);
        let tail: String = stderr.trim().chars().rev().take(600).collect::<Vec<_>>().into_iter().rev().collect();
        Err(FrameError::ToolFailed {
            tool: tool.to_owned(),
            status: out.status.to_string(),
            video: video.to_owned(),
            stderr: tail,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn long_side_is_capped_and_aspect_kept() {
        assert_eq!(fit_long_side(1920, 1080, 768), (768, 432));
        assert_eq!(fit_long_side(1080, 1920, 768), (432, 768));
        assert_eq!(fit_long_side(640, 360, 768), (640, 360));
        assert_eq!(fit_long_side(641, 361, 768), (640, 360));
        assert_eq!(fit_long_side(4000, 10, 768), (768, 2));
    }

    #[test]
    fn uniform_timestamps_sit_mid_slice() {
        assert_eq!(select_timestamps(10.0, 4, 0, &[]), vec![1.25, 3.75, 6.25, 8.75]);
        let t = select_timestamps(10.0, 16, 0, &[]);
        assert_eq!(t.len(), 16);
        assert!((t[0] - 0.3125).abs() < 1e-12);
    }

    #[test]
    fn motion_frames_go_where_the_picture_changes_and_keep_apart() {
        let scores = [(2.0, 1.0), (5.0, 90.0), (5.1, 80.0), (7.3, 50.0), (f64::NAN, 99.0)];
        let t = select_timestamps(10.0, 4, 2, &scores);
        // Uniform 2.5 and 7.5; 5.0 (largest), 5.1 too close to it, 7.3 too close to 7.5, then 2.0 is 0.5 s
        // from 2.5: the gap is 10 / 8 = 1.25 s, so it is skipped too; the grid of 4 fills in 1.25.
        assert_eq!(t, vec![1.25, 2.5, 5.0, 7.5]);
        let t = select_timestamps(10.0, 4, 2, &[(5.0, 9.0), (0.2, 3.0)]);
        assert_eq!(t, vec![0.2, 2.5, 5.0, 7.5]);
        // No motion found: the uniform grid of `count` fills in.
        assert_eq!(select_timestamps(8.0, 2, 2, &[]), vec![2.0, 6.0]);
        assert_eq!(select_timestamps(8.0, 2, 2, &[(2.5, 1.0)]), vec![2.5, 6.0]);
    }

    #[test]
    fn frame_differences_score_consecutive_pairs() {
        let raw = [0u8, 0, 10, 10, 10, 30, 7];
        let d = frame_differences(&raw, 2, 2.0);
        assert_eq!(d, vec![(0.5, 10.0), (1.0, 10.0)]);
        assert!(frame_differences(&raw, 0, 2.0).is_empty());
    }

    #[test]
    fn probe_output_is_read_and_checked() {
        let ok = r#"{"streams":[{"width":1280,"height":720,"avg_frame_rate":"0/0","r_frame_rate":"30000/1001",
            "duration":"4.5"}],"format":{"duration":"4.000000"}}"#;
        let info = parse_probe(ok).unwrap();
        assert_eq!((info.width, info.height, info.duration_s), (1280, 720, 4.0));
        assert!((info.fps - 29.97).abs() < 0.01);
        assert!(parse_probe(r#"{"streams":[],"format":{}}"#).unwrap_err().contains("no video stream"));
        let no_duration = r#"{"streams":[{"width":2,"height":2,"avg_frame_rate":"25/1"}],"format":{"duration":"N/A"}}"#;
        assert!(parse_probe(no_duration).unwrap_err().contains("duration"));
    }

    #[test]
    fn settings_ranges_reject_nan_and_overflow() {
        assert!(FrameSettings::default().validate().is_ok());
        for s in [
            FrameSettings { count: 0, ..Default::default() },
            FrameSettings { count: MAX_FRAMES + 1, ..Default::default() },
            FrameSettings { motion_frames: 17, ..Default::default() },
            FrameSettings { max_duration_s: f64::NAN, ..Default::default() },
            FrameSettings { jpeg_qscale: 1, ..Default::default() },
        ] {
            assert!(matches!(s.validate(), Err(FrameError::Settings(_))), "{s:?}");
        }
    }
}
