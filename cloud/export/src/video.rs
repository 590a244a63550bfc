//! A bird's-eye video of a simulated run (the JSON `video2track sim --json`
//! writes). Each frame is drawn here into an RGB buffer ([`raster`]): the map's lanes when a map is
//! given, every vehicle's route (with `--card`) or else its whole trajectory as a faint line, the
//! part driven so far as a trail, each vehicle as a filled rectangle of its footprint turned to its
//! heading with a dark band at its front, and a progress bar for the time. The frames go to
//! `ffmpeg` as raw RGB24 on its standard input and come out as H.264 (MPEG-4 part 2 where `ffmpeg`
//! has no libx264).
//!
//! Drawing is pure: [`Scene::frame`] fills a [`raster::Canvas`] for an instant, testable without
//! `ffmpeg`; [`encode`] is the thin shell around the subprocess.
//!
//! The run JSON holds the vehicles' centre poses at 10 Hz and their ids, not their sizes nor their
//! routes: those come from the scenario card (`--card`); without it every vehicle is drawn
//! [`DEFAULT_LENGTH_M`] × [`DEFAULT_WIDTH_M`].

pub mod raster;

use std::io::{Read as _, Write as _};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

use v2t_model::geometry::Point2;
use v2t_model::kinematics::State;
use v2t_model::validate::Validate as _;
use v2t_sim::files::CardError;
use v2t_sim::runfile::RunFile;
use v2t_sim::scenario::Scenario;

use crate::video::raster::{Canvas, Rgb};

/// Vehicle length drawn when no card gives it (the bundled sedans'), m.
pub const DEFAULT_LENGTH_M: f64 = 4.8;
/// Vehicle width drawn when no card gives it, m.
pub const DEFAULT_WIDTH_M: f64 = 1.85;
/// Space around what moves, m.
const MARGIN_M: f64 = 8.0;

const BACKGROUND: Rgb = Rgb(0xf4, 0xf5, 0xf2);
const LANE: Rgb = Rgb(0xc9, 0xcd, 0xd2);
const OTHER_LANE: Rgb = Rgb(0xe3, 0xe5, 0xe8);
const PROGRESS: Rgb = Rgb(0x44, 0x44, 0x44);
/// The VUT, then the BVs in turn.
const COLOURS: [Rgb; 5] =
    [Rgb(0x1f, 0x77, 0xb4), Rgb(0xd6, 0x27, 0x28), Rgb(0xff, 0x7f, 0x0e), Rgb(0x2c, 0xa0, 0x2c), Rgb(0x94, 0x67, 0xbd)];

/// Why a run could not be rendered.
#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    /// The options are out of range.
    #[error("{0}")]
    Options(String),
    /// The run file could not be read.
    #[error("{path}: cannot read: {error}")]
    Read {
        /// The file.
        path: PathBuf,
        /// Why.
        error: std::io::Error,
    },
    /// The run file is not the JSON `video2track sim --json` writes.
    #[error("{path}: not a run (`video2track sim --json`): {error}")]
    Parse {
        /// The file.
        path: PathBuf,
        /// Why.
        error: serde_json::Error,
    },
    /// The run file is JSON of the right form with wrong values.
    #[error("{path}: {problem}")]
    Invalid {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        problem: String,
    },
    /// The scenario card could not be loaded.
    #[error(transparent)]
    Card(#[from] CardError),
    /// The card is not the run's scenario.
    #[error("{card}: {problem}")]
    CardMismatch {
        /// The card.
        card: PathBuf,
        /// What differs.
        problem: String,
    },
    /// The map could not be loaded.
    #[error(transparent)]
    Map(#[from] v2t_map::MapError),
    /// `ffmpeg` is not installed.
    #[error("`{tool}` was not found: install the Debian package `ffmpeg` (apt-get install ffmpeg) to render videos")]
    FfmpegMissing {
        /// The program that was run.
        tool: PathBuf,
    },
    /// `ffmpeg` could not be run, or could not be fed.
    #[error("running `{tool}`: {error}")]
    Io {
        /// The program.
        tool: PathBuf,
        /// What the OS said.
        error: std::io::Error,
    },
    /// `ffmpeg` failed.
    #[error("`{tool}` failed ({status}) writing {out}: {stderr}")]
    Ffmpeg {
        /// The program.
        tool: PathBuf,
        /// Its exit status.
        status: String,
        /// The video it was writing.
        out: PathBuf,
        /// The end of what it wrote to stderr.
        stderr: String,
    },
}

impl RenderError {
    /// Whether the user's input is at fault (options, run file, card, map), as opposed to `ffmpeg`.
    pub fn is_input(&self) -> bool {
        matches!(
            self,
            Self::Options(_)
                | Self::Read { .. }
                | Self::Parse { .. }
                | Self::Invalid { .. }
                | Self::Card(_)
                | Self::CardMismatch { .. }
                | Self::Map(_)
        )
    }
}

/// Size and rate of the video.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RenderOptions {
    /// Frames per second, 1 to 60. Poses between the run's 10 Hz samples are interpolated.
    pub fps: u32,
    /// Width, px: even, 160 to 3840. The height is 9/16 of it, rounded down to even.
    pub width: u32,
}

impl Default for RenderOptions {
    fn default() -> Self {
        Self { fps: 10, width: 960 }
    }
}

impl RenderOptions {
    /// Checks the ranges.
    pub fn validate(&self) -> Result<(), RenderError> {
        if !(1..=60).contains(&self.fps) {
            return Err(RenderError::Options(format!("--fps must lie in 1..=60, got {}", self.fps)));
        }
        if !(160..=3840).contains(&self.width) || !self.width.is_multiple_of(2) {
            return Err(RenderError::Options(format!(
                "--width must be even and lie in 160..=3840, got {}",
                self.width
            )));
        }
        Ok(())
    }

    /// Height, px.
    pub fn height(&self) -> u32 {
        (self.width.saturating_mul(9) / 16) & !1
    }
}

/// A vehicle to draw.
#[derive(Debug, Clone, PartialEq)]
pub struct Vehicle {
    /// Its id in the run.
    pub id: String,
    /// Footprint length, m.
    pub length_m: f64,
    /// Footprint width, m.
    pub width_m: f64,
    /// Its colour.
    pub colour: Rgb,
    /// Its route, if known.
    pub route: Vec<Point2>,
    /// Its centre pose at each of the scene's times.
    pub poses: Vec<State>,
}

/// A run to draw: the times, the vehicles, the lanes, and the view that holds them.
#[derive(Debug, Clone, PartialEq)]
pub struct Scene {
    /// The scenario's name.
    pub name: String,
    /// Sample times, s, increasing.
    pub times: Vec<f64>,
    /// VUT first, then the BVs.
    pub vehicles: Vec<Vehicle>,
    /// Lane outlines of the map: (outline, drivable).
    pub lanes: Vec<(Vec<Point2>, bool)>,
}

impl Scene {
    /// Reads a run from the text of its JSON file (`path` names it in errors).
    pub fn from_run_json(text: &str, path: &Path) -> Result<Self, RenderError> {
        let run: RunFile =
            serde_json::from_str(text).map_err(|error| RenderError::Parse { path: path.to_owned(), error })?;
        run.validate().map_err(|e| RenderError::Invalid { path: path.to_owned(), problem: e.to_string() })?;
        let mut vehicles: Vec<Vehicle> = run
            .agent_ids
            .iter()
            .enumerate()
            .map(|(i, id)| Vehicle {
                id: id.clone(),
                length_m: DEFAULT_LENGTH_M,
                width_m: DEFAULT_WIDTH_M,
                colour: COLOURS.get(i % COLOURS.len()).copied().unwrap_or(PROGRESS),
                route: Vec::new(),
                poses: Vec::with_capacity(run.trace.len()),
            })
            .collect();
        let mut times = Vec::with_capacity(run.trace.len());
        for sample in &run.trace {
            for (v, a) in vehicles.iter_mut().zip(&sample.agents) {
                v.poses.push(a.state);
            }
            times.push(sample.t_s);
        }
        Ok(Self { name: run.result.scenario, times, vehicles, lanes: Vec::new() })
    }

    /// Takes the vehicles' footprints and routes from the run's scenario card.
    pub fn use_card(&mut self, scenario: &Scenario, card: &Path) -> Result<(), RenderError> {
        if scenario.name != self.name {
            return Err(RenderError::CardMismatch {
                card: card.to_owned(),
                problem: format!("scenario `{}`, the run is of `{}`", scenario.name, self.name),
            });
        }
        let agents: Vec<_> =
            std::iter::once(&scenario.vut.agent).chain(scenario.bvs.iter().map(|b| &b.agent)).collect();
        let ids: Vec<&str> = agents.iter().map(|a| a.id.as_str()).collect();
        let run_ids: Vec<&str> = self.vehicles.iter().map(|v| v.id.as_str()).collect();
        if ids != run_ids {
            return Err(RenderError::CardMismatch {
                card: card.to_owned(),
                problem: format!("its agents are {ids:?}, the run's are {run_ids:?}"),
            });
        }
        for (v, a) in self.vehicles.iter_mut().zip(agents) {
            v.length_m = a.vehicle.geometry.length_m;
            v.width_m = a.vehicle.geometry.width_m;
            v.route = a.route.points().to_vec();
        }
        Ok(())
    }

    /// Draws the map's lanes under the vehicles.
    pub fn use_map(&mut self, map: &v2t_map::Map) {
        self.lanes = map
            .graph
            .lanes
            .iter()
            .filter(|l| l.samples.len() >= 2)
            .map(|l| {
                let outline = l.samples.iter().map(|q| q.left).chain(l.samples.iter().rev().map(|q| q.right)).collect();
                (outline, l.drivable)
            })
            .collect();
    }

    /// First and last sample time, s.
    pub fn time_span(&self) -> (f64, f64) {
        (self.times.first().copied().unwrap_or(0.0), self.times.last().copied().unwrap_or(0.0))
    }

    /// Frames of a video at `fps`: one at the first sample and every `1/fps` s up to the last.
    pub fn frame_count(&self, fps: u32) -> u32 {
        let (t0, t1) = self.time_span();
        ((t1 - t0) * f64::from(fps) + 1e-6).floor().clamp(0.0, 1e7) as u32 + 1
    }

    /// The view that holds every pose and route, with a margin, in `width × height` px.
    pub fn view(&self, width: u32, height: u32) -> View {
        let mut b = (f64::INFINITY, f64::INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY);
        let mut grow = |x: f64, y: f64| b = (b.0.min(x), b.1.min(y), b.2.max(x), b.3.max(y));
        for v in &self.vehicles {
            v.poses.iter().for_each(|p| grow(p.px, p.py));
            v.route.iter().for_each(|p| grow(p.x, p.y));
        }
        if !b.0.is_finite() {
            b = (0.0, 0.0, 1.0, 1.0);
        }
        let (x0, y0, x1, y1) = (b.0 - MARGIN_M, b.1 - MARGIN_M, b.2 + MARGIN_M, b.3 + MARGIN_M);
        let scale = (f64::from(width) / (x1 - x0)).min(f64::from(height) / (y1 - y0));
        // Centred.
        let left = (x0 + x1) / 2.0 - f64::from(width) / scale / 2.0;
        let top = (y0 + y1) / 2.0 + f64::from(height) / scale / 2.0;
        View { left, top, scale }
    }

    /// Each vehicle's pose at `t_s`, interpolated between the samples (held before the first and
    /// after the last).
    pub fn poses_at(&self, t_s: f64) -> Vec<State> {
        let k = self.times.partition_point(|t| *t <= t_s);
        self.vehicles
            .iter()
            .map(|v| {
                let (Some(a), Some(t_a)) =
                    (k.checked_sub(1).and_then(|i| v.poses.get(i)), k.checked_sub(1).and_then(|i| self.times.get(i)))
                else {
                    return v.poses.first().copied().unwrap_or_default();
                };
                let (Some(b), Some(t_b)) = (v.poses.get(k), self.times.get(k)) else {
                    return *a;
                };
                let f = ((t_s - t_a) / (t_b - t_a)).clamp(0.0, 1.0);
                let turn = (b.theta_rad - a.theta_rad + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU)
                    - std::f64::consts::PI;
                State {
                    px: a.px + (b.px - a.px) * f,
                    py: a.py + (b.py - a.py) * f,
                    theta_rad: a.theta_rad + turn * f,
                    speed_mps: a.speed_mps + (b.speed_mps - a.speed_mps) * f,
                }
            })
            .collect()
    }

    /// What does not move: background, lanes, routes or whole trajectories, faint.
    pub fn background(&self, view: &View, width: u32, height: u32) -> Canvas {
        let mut c = Canvas::new(width, height, BACKGROUND);
        for (outline, drivable) in &self.lanes {
            let pts: Vec<(f64, f64)> = outline.iter().map(|p| view.px(p.x, p.y)).collect();
            c.fill_polygon(&pts, if *drivable { LANE } else { OTHER_LANE });
        }
        let line = (view.scale * 0.25).clamp(1.0, 3.0);
        for v in &self.vehicles {
            let pts: Vec<(f64, f64)> = if v.route.is_empty() {
                v.poses.iter().map(|p| view.px(p.px, p.py)).collect()
            } else {
                v.route.iter().map(|p| view.px(p.x, p.y)).collect()
            };
            c.polyline(&pts, line, v.colour.mix(BACKGROUND, 0.65));
        }
        c
    }

    /// Draws the instant `t_s` onto `canvas`, which holds [`Self::background`].
    pub fn frame(&self, view: &View, t_s: f64, canvas: &mut Canvas) {
        let poses = self.poses_at(t_s);
        let k = self.times.partition_point(|t| *t <= t_s);
        let trail = (view.scale * 0.4).clamp(1.5, 5.0);
        for (v, now) in self.vehicles.iter().zip(&poses) {
            let driven: Vec<(f64, f64)> =
                v.poses.iter().take(k).chain(std::iter::once(now)).map(|p| view.px(p.px, p.py)).collect();
            canvas.polyline(&driven, trail, v.colour.mix(BACKGROUND, 0.3));
        }
        for (v, p) in self.vehicles.iter().zip(&poses) {
            let body = footprint(p, v.length_m, v.width_m, -0.5, 0.5);
            canvas.fill_polygon(&body.map(|q| view.px(q.0, q.1)), v.colour);
            // A dark band at the front shows the heading.
            let nose = footprint(p, v.length_m, v.width_m, 0.3, 0.45);
            canvas.fill_polygon(&nose.map(|q| view.px(q.0, q.1)), v.colour.mix(Rgb(0, 0, 0), 0.55));
        }
        let (t0, t1) = self.time_span();
        let done = if t1 > t0 { ((t_s - t0) / (t1 - t0)).clamp(0.0, 1.0) } else { 1.0 };
        let (w, h) = (i64::from(canvas.width()), i64::from(canvas.height()));
        canvas.fill_rect(0, h - 4, (done * w as f64).round() as i64, h, PROGRESS);
    }
}

/// The corners of the part of a footprint between `from` and `to` (fractions of the length from the
/// centre, −0.5 the rear, 0.5 the front), in the track frame.
fn footprint(p: &State, length_m: f64, width_m: f64, from: f64, to: f64) -> [(f64, f64); 4] {
    let (s, c) = p.theta_rad.sin_cos();
    let at = |along: f64, across: f64| (p.px + c * along - s * across, p.py + s * along + c * across);
    let (a, b, w) = (from * length_m, to * length_m, width_m / 2.0);
    [at(a, -w), at(b, -w), at(b, w), at(a, w)]
}

/// Track frame (m, y up) to pixels (y down).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct View {
    /// Track x at the left edge, m.
    pub left: f64,
    /// Track y at the top edge, m.
    pub top: f64,
    /// Pixels per metre.
    pub scale: f64,
}

impl View {
    /// The pixel position of track point (x, y).
    pub fn px(&self, x: f64, y: f64) -> (f64, f64) {
        ((x - self.left) * self.scale, (self.top - y) * self.scale)
    }
}

/// Loads a run, and optionally its card and a map, into a scene.
pub fn load_scene(run: &Path, card: Option<&Path>, map: Option<&Path>) -> Result<Scene, RenderError> {
    let text = v2t_files::bounds::read_text_within(run, v2t_files::bounds::RUN)
        .map_err(|error| RenderError::Read { path: run.to_owned(), error })?;
    let mut scene = Scene::from_run_json(&text, run)?;
    if let Some(card) = card {
        let scenario = v2t_sim::files::load_scenario(card)?;
        scene.use_card(&scenario, card)?;
    }
    if let Some(map) = map {
        scene.use_map(&v2t_map::Map::load(map)?);
    }
    Ok(scene)
}

/// What [`encode`] wrote.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Encoded {
    /// Frames written.
    pub frames: u32,
    /// Width, px.
    pub width: u32,
    /// Height, px.
    pub height: u32,
    /// The `ffmpeg` encoder used.
    pub encoder: &'static str,
}

/// Renders `scene` into the video file `out` with `ffmpeg` (a name looked up in `PATH`, or a path).
pub fn encode(scene: &Scene, opts: &RenderOptions, out: &Path, ffmpeg: &Path) -> Result<Encoded, RenderError> {
    opts.validate()?;
    let (width, height) = (opts.width, opts.height());
    let encoder = pick_encoder(ffmpeg)?;
    let mut cmd = Command::new(ffmpeg);
    cmd.args(["-hide_banner", "-loglevel", "error", "-nostdin", "-y", "-f", "rawvideo", "-pix_fmt", "rgb24"])
        .arg("-s")
        .arg(format!("{width}x{height}"))
        .arg("-r")
        .arg(opts.fps.to_string())
        .args(["-i", "-", "-c:v", encoder, "-pix_fmt", "yuv420p"]);
    if encoder == "mpeg4" {
        cmd.args(["-q:v", "3"]);
    }
    cmd.arg(out).stdin(Stdio::piped()).stdout(Stdio::null()).stderr(Stdio::piped());
    let io = |error: std::io::Error| RenderError::Io { tool: ffmpeg.to_owned(), error };
    let mut child = cmd.spawn().map_err(|e| spawn_error(ffmpeg, e))?;
    // Read stderr on the side, so that a chatty ffmpeg cannot block on a full pipe.
    let stderr = child.stderr.take().map(|mut s| {
        std::thread::spawn(move || {
            let mut text = String::new();
            let _ = s.read_to_string(&mut text);
            text
        })
    });
    let view = scene.view(width, height);
    let background = scene.background(&view, width, height);
    let mut canvas = background.clone();
    let frames = scene.frame_count(opts.fps);
    let (t0, _) = scene.time_span();
    let mut fed = Ok(());
    if let Some(mut stdin) = child.stdin.take() {
        for k in 0..frames {
            canvas.copy_from(&background);
            scene.frame(&view, t0 + f64::from(k) / f64::from(opts.fps), &mut canvas);
            fed = stdin.write_all(canvas.as_bytes());
            if fed.is_err() {
                break;
            }
        }
        // Dropping stdin closes it: ffmpeg finishes the file.
    }
    let status = child.wait().map_err(io)?;
    let stderr = stderr.and_then(|h| h.join().ok()).unwrap_or_default();
    if !status.success() {
        let tail: String = stderr.trim().chars().rev().take(2000).collect::<Vec<_>>().into_iter().rev().collect();
        return Err(RenderError::Ffmpeg {
            tool: ffmpeg.to_owned(),
            status: status.to_string(),
            out: out.to_owned(),
            stderr: tail,
        });
    }
    fed.map_err(io)?;
    Ok(Encoded { frames, width, height, encoder })
}

fn spawn_error(ffmpeg: &Path, source: std::io::Error) -> RenderError {
    if source.kind() == std::io::ErrorKind::NotFound {
        RenderError::FfmpegMissing { tool: ffmpeg.to_owned() }
    } else {
        RenderError::Io { tool: ffmpeg.to_owned(), error: source }
    }
}

/// `libx264` when this `ffmpeg` has it, else `mpeg4` (every build has that).
fn pick_encoder(ffmpeg: &Path) -> Result<&'static str, RenderError> {
    let out = Command::new(ffmpeg)
        .args(["-hide_banner", "-encoders"])
        .stdin(Stdio::null())
        .stderr(Stdio::null())
        .output()
        .map_err(|e| spawn_error(ffmpeg, e))?;
    let list = String::from_utf8_lossy(&out.stdout);
    let has_x264 = list.lines().any(|l| l.split_whitespace().nth(1) == Some("libx264"));
    Ok(if has_x264 { "libx264" } else { "mpeg4" })
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing)]

    use super::*;

    /// Two vehicles crossing: the VUT east along y = 0, the BV north along x = 20.
    fn run_file() -> v2t_sim::runfile::RunFile {
        let samples: Vec<(f64, Vec<State>)> = (0..=40)
            .map(|k| {
                let t = f64::from(k) * 0.1;
                let vut = State { px: 10.0 * t, py: 0.0, theta_rad: 0.0, speed_mps: 10.0 };
                let bv =
                    State { px: 20.0, py: -10.0 + 5.0 * t, theta_rad: std::f64::consts::FRAC_PI_2, speed_mps: 5.0 };
                (t, vec![vut, bv])
            })
            .collect();
        crate::test_run::run("cross", &["vut", "bv1"], &samples)
    }

    fn run_json() -> String {
        serde_json::to_string(&run_file()).unwrap()
    }

    #[test]
    fn a_run_reads_into_a_scene_and_interpolates() {
        let s = Scene::from_run_json(&run_json(), Path::new("run.json")).unwrap();
        assert_eq!(s.name, "cross");
        assert_eq!(s.times.len(), 41);
        assert_eq!(s.vehicles[1].id, "bv1");
        assert_eq!(s.frame_count(10), 41);
        assert_eq!(s.frame_count(25), 101);
        let p = s.poses_at(1.25);
        assert!((p[0].px - 12.5).abs() < 1e-9 && (p[1].py + 3.75).abs() < 1e-9, "{p:?}");
        assert_eq!(s.poses_at(-1.0)[0].px, 0.0);
        assert!((s.poses_at(99.0)[0].px - 40.0).abs() < 1e-9);
    }

    #[test]
    fn bad_runs_are_refused_with_the_reason() {
        let p = Path::new("r.json");
        let e = Scene::from_run_json("{}", p).unwrap_err();
        assert!(matches!(e, RenderError::Parse { .. }) && e.is_input(), "{e}");
        let json = |r: &v2t_sim::runfile::RunFile| serde_json::to_string(r).unwrap();
        let mut repeated = run_file();
        repeated.trace[1].t_s = 0.0;
        let e = Scene::from_run_json(&json(&repeated), p).unwrap_err();
        assert!(e.to_string().contains("trace[1].t_s") && e.is_input(), "{e}");
        let mut short = run_file();
        short.agent_ids.pop();
        let e = Scene::from_run_json(&json(&short), p).unwrap_err();
        assert!(e.to_string().contains("agent_ids names 1"), "{e}");
        let mut empty = run_file();
        empty.trace.clear();
        assert!(Scene::from_run_json(&json(&empty), p).unwrap_err().to_string().contains("empty"));
        // A run file without a part every run has is refused, naming it.
        let e = Scene::from_run_json(r#"{"result": {"scenario": "x"}, "agent_ids": ["vut"], "trace": []}"#, p);
        let e = e.unwrap_err();
        assert!(matches!(e, RenderError::Parse { .. }) && e.to_string().contains("vut_model"), "{e}");
    }

    #[test]
    fn a_frame_shows_each_vehicle_at_its_pose_with_its_footprint() {
        let s = Scene::from_run_json(&run_json(), Path::new("run.json")).unwrap();
        let opts = RenderOptions { fps: 10, width: 320 };
        let (w, h) = (opts.width, opts.height());
        assert_eq!((w, h), (320, 180));
        let view = s.view(w, h);
        let bg = s.background(&view, w, h);
        let mut c = bg.clone();
        s.frame(&view, 2.0, &mut c);
        // VUT at (20, 0) heading east, BV at (20, 0)… they meet at t = 2: look at t = 1 instead.
        let mut c1 = bg.clone();
        s.frame(&view, 1.0, &mut c1);
        let colour_at = |c: &Canvas, x: f64, y: f64| {
            let (u, v) = view.px(x, y);
            c.pixel(u as u32, v as u32).unwrap()
        };
        // The VUT's centre (10, 0) and its rear (8, 0) are blue; 3 m behind its rear is not.
        assert_eq!(colour_at(&c1, 10.0, 0.0), COLOURS[0]);
        assert_eq!(colour_at(&c1, 8.0, 0.5), COLOURS[0]);
        assert_ne!(colour_at(&c1, 4.0, 0.8), COLOURS[0]);
        // Its front band is darker.
        assert_eq!(colour_at(&c1, 11.8, 0.0), COLOURS[0].mix(Rgb(0, 0, 0), 0.55));
        // The BV's centre (20, −5) is red; it is turned: 1.5 m beside its centre across is not.
        assert_eq!(colour_at(&c1, 20.0, -5.0), COLOURS[1]);
        assert_eq!(colour_at(&c1, 20.0, -4.0), COLOURS[1]);
        assert_ne!(colour_at(&c1, 21.5, -5.0), COLOURS[1]);
        // The frames differ, the background stays as it was, and the progress bar grows.
        assert_ne!(c1, c);
        let bar = |c: &Canvas| (0..w).filter(|x| c.pixel(*x, h - 1) == Some(PROGRESS)).count();
        assert_eq!(bar(&bg), 0);
        assert_eq!(bar(&c1), 80);
        assert_eq!(bar(&c), 160);
    }

    #[test]
    fn options_are_checked() {
        assert!(RenderOptions { fps: 0, width: 640 }.validate().is_err());
        assert!(RenderOptions { fps: 10, width: 641 }.validate().is_err());
        assert!(RenderOptions { fps: 10, width: 100 }.validate().is_err());
        assert!(RenderOptions::default().validate().is_ok());
        assert_eq!(RenderOptions { fps: 10, width: 1000 }.height(), 562);
    }

    #[test]
    fn a_missing_ffmpeg_is_named() {
        let s = Scene::from_run_json(&run_json(), Path::new("run.json")).unwrap();
        let e =
            encode(&s, &RenderOptions::default(), Path::new("/tmp/x.mp4"), Path::new("/no/such/ffmpeg")).unwrap_err();
        assert!(matches!(e, RenderError::FfmpegMissing { .. }) && !e.is_input(), "{e}");
        assert!(e.to_string().contains("apt-get install ffmpeg"), "{e}");
    }
}
