//! `video2track demo`: the whole pipeline on what ships with the repository. For each of the
//! paper's scenarios: the hand-written VLM exchange replayed into semantics → grounded on the
//! proving ground → a trajectory prior → the BV's onboard runtime as separate processes
//! (`v2t-edge launch`) closing the loop with the simulated proving ground (`v2t-sim-ecu --prior`)
//! over iceoryx2 → the run's metrics, OpenSCENARIO file, MCAP recording and an HTML report.
//!
//! The prior comes from the guided diffusion model with the shipped weights
//! (`config/diffusion/denoiser.safetensors`): the best of [`VARIANTS`] variants (no solid boundary
//! crossed, within the limits, the style's order, the smallest anchor error).

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use serde::Serialize;
use v2t_files::outln;
use v2t_sim::realism::VehicleRealism;
use v2t_sim::runfile::RunFile;
use v2t_vlm::{Mode, VlmConfig, VlmError};

mod report;

/// One of the paper's scenarios as shipped: a hand-written cassette and its video's PET label.
#[derive(Debug, Clone, Copy)]
pub struct DemoScenario {
    /// Short name, used for the output files.
    pub name: &'static str,
    /// The cassette directory.
    pub cassette: &'static str,
    /// The video the cassette recorded.
    pub video: &'static str,
    /// The operator's PET label, s.
    pub pet_label_s: f64,
}

impl DemoScenario {
    /// The semantics its hand-written VLM exchange replays to.
    pub fn replayed_semantics(&self) -> Result<v2t_model::semantics::ScenarioSemantics, VlmError> {
        let mode = Mode::Replay(PathBuf::from(self.cassette));
        v2t_vlm::abstract_video(Path::new(self.video), self.pet_label_s, &VlmConfig::default(), &mode)
            .map(|r| r.semantics)
    }
}

/// The paper's cut-in (PET 4.70 s), its unprotected left turn with the BV turning (PET 2.90 s), and
/// the left turn with the VUT turning across an oncoming BV that yields (PET label 2.40 s, made up
/// for the hand-written example: there is no such video).
pub const SCENARIOS: [DemoScenario; 3] = [
    DemoScenario {
        name: "cut_in",
        cassette: "config/vlm/cassettes/cut_in",
        video: "cut_in_4.70.mp4",
        pet_label_s: 4.70,
    },
    DemoScenario {
        name: "left_turn",
        cassette: "config/vlm/cassettes/left_turn",
        video: "left_turn_2.90.mp4",
        pet_label_s: 2.90,
    },
    DemoScenario {
        name: "left_turn_vut",
        cassette: "config/vlm/cassettes/left_turn_vut",
        video: "left_turn_vut_2.40.mp4",
        pet_label_s: 2.40,
    },
];

/// What the prior is, in every output: the weights file and what its training data were (its
/// metadata), so that a figure says whether recorded driving went into it.
pub fn prior_kind(weights: &Path, model: &v2t_diffusion::weights::Model) -> String {
    let data = if model.meta.training.synthetic {
        "trained on the synthetic corpus only"
    } else {
        "trained on recorded human driving and the synthetic corpus"
    };
    format!("guided diffusion prior ({}, {data}; best of {VARIANTS} variants)", weights.display())
}

/// Variants generated per scenario.
pub const VARIANTS: usize = 8;

/// Why the demo stopped.
#[derive(Debug, thiserror::Error)]
pub enum DemoError {
    /// A stage failed for one scenario.
    #[error("{scenario}: {stage}: {message}")]
    Stage {
        /// The scenario.
        scenario: String,
        /// Which stage.
        stage: &'static str,
        /// Why.
        message: String,
    },
    /// The output could not be written.
    #[error("{path}: {error}")]
    Write {
        /// The file.
        path: PathBuf,
        /// Why.
        error: std::io::Error,
    },
    /// A binary of the onboard runtime or the lab is missing.
    #[error("{0} is not built: run `cargo build --release` first")]
    NotBuilt(PathBuf),
    /// The progress lines could not be written (stdout's reader went away: `| head`).
    #[error("printing the demo's progress")]
    Stdout(#[from] v2t_files::stdout::StdoutError),
}

/// How the demo runs.
#[derive(Debug, Clone)]
pub struct DemoOptions {
    /// Output folder.
    pub out: PathBuf,
    /// The proving ground.
    pub map: PathBuf,
    /// The BV's onboard runtime configuration.
    pub edge_config: PathBuf,
    /// The `v2t-edge` executable (the onboard runtime).
    pub edge_bin: PathBuf,
    /// The `v2t-sim-ecu` executable (the simulated proving ground behind the CAN frames).
    pub ecu_bin: PathBuf,
    /// VUT driver model.
    pub vut: String,
    /// Noise seed.
    pub seed: u64,
    /// Denoiser weights.
    pub weights: PathBuf,
}

/// One scenario's outcome, as `summary.json` holds it.
#[derive(Debug, Clone, Serialize)]
pub struct ScenarioSummary {
    /// The scenario.
    pub name: String,
    /// The video's PET label (the target), s.
    pub pet_video_s: f64,
    /// Interaction type from the semantics.
    pub interaction: String,
    /// The style.
    pub style: String,
    /// The grounded fragment.
    pub fragment: String,
    /// What the prior is.
    pub prior: String,
    /// PET^min of the closed-loop run, s.
    pub pet_min_track_s: Option<f64>,
    /// |PET^min_track − PET_video| / PET_video.
    pub fidelity_error_rel: Option<f64>,
    /// Whether the order matched the style.
    pub order_ok: Option<bool>,
    /// Whether the vehicles touched.
    pub collision: bool,
    /// Smallest footprint distance, m.
    pub min_distance_m: Option<f64>,
    /// How human the BV's motion was: its class and W₁ figures against recorded human driving
    /// (`realism` of `run.json`; the class alone when it has no human reference).
    pub bv_realism: Option<VehicleRealism>,
    /// Wall time of the scenario, s.
    pub wall_s: f64,
    /// Files written.
    pub files: Vec<String>,
}

/// The whole demo.
#[derive(Debug, Clone, Serialize)]
pub struct Summary {
    /// What the priors are ([`prior_kind`]).
    pub prior: String,
    /// Per scenario.
    pub scenarios: Vec<ScenarioSummary>,
    /// Wall time, s.
    pub wall_s: f64,
}

/// The executable `name` next to this one (`v2t-edge`, `v2t-sim-ecu`).
pub fn beside_me(name: &str) -> PathBuf {
    std::env::current_exe().ok().and_then(|p| p.parent().map(|d| d.join(name))).unwrap_or_else(|| PathBuf::from(name))
}

/// Runs every scenario; prints progress on stdout.
pub fn run(opts: &DemoOptions) -> Result<Summary, DemoError> {
    for bin in [&opts.edge_bin, &opts.ecu_bin] {
        if !bin.exists() {
            return Err(DemoError::NotBuilt(bin.clone()));
        }
    }
    std::fs::create_dir_all(&opts.out).map_err(|error| DemoError::Write { path: opts.out.clone(), error })?;
    let t0 = Instant::now();
    let inspection = v2t_map::inspect(&opts.map, None).map_err(|e| DemoError::Stage {
        scenario: "map".into(),
        stage: "load",
        message: e.to_string(),
    })?;
    let model = v2t_diffusion::weights::load(&opts.weights).map_err(|e| DemoError::Stage {
        scenario: "diffusion".into(),
        stage: "weights",
        message: e.to_string(),
    })?;
    let mut scenarios = Vec::new();
    let mut runs = Vec::new();
    for (i, sc) in SCENARIOS.iter().enumerate() {
        outln!("[{}/{}] {}", i + 1, SCENARIOS.len(), sc.name)?;
        let (summary, run, grounded) = run_one(opts, sc, &inspection, &model)?;
        scenarios.push(summary);
        runs.push((run, grounded));
    }
    let summary = Summary { prior: prior_kind(&opts.weights, &model), scenarios, wall_s: t0.elapsed().as_secs_f64() };
    write(&opts.out.join("summary.json"), &pretty(&summary))?;
    let runs: Vec<RunFile> = runs.into_iter().map(|(run, _)| run).collect();
    write(&opts.out.join("report.html"), &report::html(&summary, &runs, &inspection.map, &opts.map))?;
    Ok(summary)
}

fn write(path: &Path, text: &str) -> Result<(), DemoError> {
    std::fs::write(path, text).map_err(|error| DemoError::Write { path: path.to_owned(), error })
}

type Stage<T> = Result<T, DemoError>;

fn run_one(
    opts: &DemoOptions,
    sc: &DemoScenario,
    inspection: &v2t_map::Inspection,
    model: &v2t_diffusion::weights::Model,
) -> Stage<(ScenarioSummary, RunFile, v2t_model::grounded::GroundedScenario)> {
    let t0 = Instant::now();
    let fail = |stage: &'static str| move |e: String| DemoError::Stage { scenario: sc.name.into(), stage, message: e };
    let file = |suffix: &str| opts.out.join(format!("{}.{suffix}", sc.name));
    let mut files = Vec::new();
    let mut save = |suffix: &str, text: String| -> Stage<()> {
        let path = file(suffix);
        write(&path, &text)?;
        files.push(path.display().to_string());
        Ok(())
    };

    // Semantics from the recorded exchange.
    let sem = sc.replayed_semantics().map_err(|e| fail("abstract")(e.to_string()))?;
    save("semantics.json", pretty(&sem))?;
    let interaction = sem.interacting_bvs.first().map_or("?", |b| b.interaction_type.as_str());
    outln!("  semantics   {interaction}, PET label {:.2} s (replayed cassette)", sem.pet_label_s)?;

    // Grounding on the proving ground.
    let g =
        v2t_ground::ground(&inspection.map, &inspection.library, &sem).map_err(|e| fail("ground")(e.to_string()))?;
    let grounded = g.scenario;
    save("grounded.json", pretty(&grounded))?;
    outln!(
        "  grounded    on {} (τ {:.2} s, {:?})",
        grounded.fragment_id,
        grounded.target.tau_s(),
        grounded.target.style()
    )?;

    // The prior.
    let gen_options =
        v2t_diffusion::generate::GenerateOptions { variants: VARIANTS, seed: opts.seed, ..Default::default() };
    let started = Instant::now();
    let (variants, redrawn) = v2t_diffusion::generate::generate(model, &inspection.map, &grounded, &gen_options)
        .map_err(|e| fail("prior")(e.to_string()))?;
    let gen_summary = v2t_diffusion::generate::summarize(&variants, redrawn, started.elapsed().as_secs_f64());
    let chosen =
        v2t_diffusion::generate::best(&variants).ok_or_else(|| fail("prior")("no variant generated".into()))?;
    let prior = chosen.prior.clone();
    save("prior.json", pretty(&prior))?;
    save("prior_metrics.json", pretty(&gen_summary))?;
    outln!(
        "  prior       {} variants in {:.2} s, median anchor error {:.2} m, {:.1} s",
        gen_summary.variants,
        gen_summary.sampling_s,
        gen_summary.median_anchor_error_m,
        prior.duration_s()
    )?;

    // OpenSCENARIO.
    v2t_export::file::export_xosc(&v2t_export::file::XoscArgs {
        input: &file("prior.json"),
        out: &file("xosc"),
        map: &opts.map,
        vut_vehicle: Path::new(v2t_files::shipped::VUT_VEHICLE),
        bv_vehicle: Path::new(v2t_files::shipped::BV_VEHICLE),
    })
    .map_err(|e| fail("export xosc")(e.to_string()))?;
    files.push(file("xosc").display().to_string());

    // The closed loop through the onboard processes.
    let run_json = file("run.json");
    let mcap = file("mcap");
    closed_loop(opts, sc.name, &file("prior.json"), &run_json, &mcap, prior.duration_s())
        .map_err(fail("closed loop"))?;
    files.push(run_json.display().to_string());
    files.push(mcap.display().to_string());
    // A bird's-eye video of the run, when ffmpeg is there.
    let video = file("mp4");
    let scene = v2t_export::video::load_scene(&run_json, None, Some(&opts.map));
    let opts_video = v2t_export::video::RenderOptions { fps: 10, width: 640 };
    match scene.and_then(|scene| v2t_export::video::encode(&scene, &opts_video, &video, Path::new("ffmpeg"))) {
        Ok(_) => files.push(video.display().to_string()),
        Err(e) => outln!("  video       not rendered: {e}")?,
    }
    let text = std::fs::read_to_string(&run_json).map_err(|e| fail("closed loop")(e.to_string()))?;
    let run: RunFile =
        serde_json::from_str(&text).map_err(|e| fail("closed loop")(format!("{}: {e}", run_json.display())))?;
    let r = &run.result;
    let pet = r.pet_min_s;
    let fidelity = pet.map(|p| (p - sc.pet_label_s).abs() / sc.pet_label_s);
    let order_ok = r.conflicts.first().and_then(|c| c.order_matches_style);
    outln!(
        "  closed loop PET_min {} (video {:.2} s, error {}), order {}, collision {}",
        pet.map_or_else(|| "none".into(), |p| format!("{p:.2} s")),
        sc.pet_label_s,
        fidelity.map_or_else(|| "-".into(), |f| format!("{:.1} %", 100.0 * f)),
        if order_ok == Some(true) { "as the style asks" } else { "NOT as the style asks" },
        if r.collision.is_none() { "none" } else { "YES" }
    )?;
    let bv_realism = run.realism.as_ref().and_then(|m| m.bv(0)).cloned();
    if let Some(v) = &bv_realism {
        match &v.realism {
            Some(m) => outln!(
                "  BV realism ({}): W₁ accel {:.3} m/s², W₁ jerk {:.3} m/s³ against recorded human driving",
                v.class.name(),
                m.w1_accel_mps2,
                m.w1_jerk_mps3
            )?,
            None => outln!("  BV realism ({}): no human reference for this class", v.class.name())?,
        }
    }
    let summary = ScenarioSummary {
        name: sc.name.into(),
        pet_video_s: sc.pet_label_s,
        interaction: interaction.into(),
        style: format!("{:?}", grounded.target.style()).to_lowercase(),
        fragment: grounded.fragment_id.clone(),
        prior: prior_kind(&opts.weights, model),
        pet_min_track_s: pet,
        fidelity_error_rel: fidelity,
        order_ok,
        collision: r.collision.is_some(),
        min_distance_m: Some(r.min_distance_m).filter(|d| d.is_finite()),
        bv_realism,
        wall_s: t0.elapsed().as_secs_f64(),
        files,
    };
    Ok((summary, run, grounded))
}

/// Pretty JSON with a final newline (the demo's files).
fn pretty<T: Serialize>(value: &T) -> String {
    serde_json::to_string_pretty(value).unwrap_or_default() + "\n"
}

/// Stops a child with SIGTERM (the launcher stops its nodes on it), then kills it after 5 s.
fn terminate(child: &mut Child) {
    let _ = Command::new("kill").arg("-TERM").arg(child.id().to_string()).status();
    let deadline = Instant::now() + Duration::from_secs(5);
    while Instant::now() < deadline {
        if matches!(child.try_wait(), Ok(Some(_))) {
            return;
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    let _ = child.kill();
    let _ = child.wait();
}

fn closed_loop(
    opts: &DemoOptions,
    name: &str,
    prior: &Path,
    out: &Path,
    mcap: &Path,
    expected_s: f64,
) -> Result<(), String> {
    let ns = format!("v2t/demo/{name}{}", std::process::id());
    let cfg = opts.edge_config.display().to_string();
    let log = std::fs::File::create(out.with_extension("log")).map_err(|e| e.to_string())?;
    let log2 = log.try_clone().map_err(|e| e.to_string())?;
    let mut launcher = Command::new(&opts.edge_bin)
        .args(["launch", "--config", &cfg, "--namespace", &ns])
        .stdout(Stdio::null())
        .stderr(log)
        .spawn()
        .map_err(|e| format!("{}: {e}", opts.edge_bin.display()))?;
    let ecu = Command::new(&opts.ecu_bin)
        .args(["--config", &cfg, "--namespace", &ns, "--prior"])
        .arg(prior)
        .args(["--vut", &opts.vut, "--seed", &opts.seed.to_string(), "--out"])
        .arg(out)
        .arg("--mcap")
        .arg(mcap)
        .stdout(Stdio::null())
        .stderr(log2)
        .spawn();
    let mut ecu = match ecu {
        Ok(c) => c,
        Err(e) => {
            terminate(&mut launcher);
            return Err(format!("{}: {e}", opts.ecu_bin.display()));
        }
    };
    let t0 = Instant::now();
    let mut progress = crate::progress::Progress::stdout();
    let status = loop {
        if let Ok(Some(s)) = ecu.try_wait() {
            break s;
        }
        let frac = (t0.elapsed().as_secs_f64() / (expected_s + 1.0)).min(0.99);
        progress.update(
            frac,
            &format!("  closed loop {} {:>4.1} s", crate::progress::bar(frac, 30), t0.elapsed().as_secs_f64()),
        );
        if t0.elapsed() > Duration::from_secs_f64(expected_s + 60.0) {
            let _ = ecu.kill();
            terminate(&mut launcher);
            return Err("the simulated ECU did not finish".into());
        }
        std::thread::sleep(Duration::from_millis(200));
    };
    progress.finish(&format!("  closed loop {} {:>4.1} s", crate::progress::bar(1.0, 30), t0.elapsed().as_secs_f64()));
    terminate(&mut launcher);
    if !status.success() {
        return Err(format!("the simulated ECU failed ({status}); see {}", out.with_extension("log").display()));
    }
    Ok(())
}
