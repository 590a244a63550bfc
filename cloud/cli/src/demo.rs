//! `video2track demo`: the whole pipeline on embedded defaults. For each of the paper's two
//! scenarios: the recorded VLM exchange replayed into semantics → grounded on the proving ground →
//! a trajectory prior → the BV's onboard runtime as separate processes (`v2t-edge launch`) closing
//! the loop with the simulated proving ground (`v2t-edge sim-ecu --prior`) over iceoryx2 → the
//! run's metrics, OpenSCENARIO file, MCAP recording and an HTML report.
//!
//! The prior comes from the guided diffusion model with the shipped weights
//! (`config/diffusion/denoiser.safetensors`): the best of [`VARIANTS`] variants (no solid boundary
//! crossed, within the limits, the style's order, the smallest anchor error).

use std::fmt::Write as _;
use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use serde::Serialize;
use serde_json::Value;

use crate::abstract_cmd::{AbstractArgs, abstract_video};

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
    /// The semantics its recorded VLM exchange replays to.
    pub fn replayed_semantics(
        &self,
    ) -> Result<v2t_model::semantics::ScenarioSemantics, crate::abstract_cmd::AbstractError> {
        let args = AbstractArgs {
            video: PathBuf::from(self.video),
            pet_label_s: self.pet_label_s,
            record: None,
            replay: Some(PathBuf::from(self.cassette)),
            frames: None,
            sampling: None,
        };
        abstract_video(&args, |_| None).map(|r| r.semantics)
    }
}

/// The paper's cut-in (PET 4.70 s) and unprotected left turn (PET 2.90 s).
pub const SCENARIOS: [DemoScenario; 2] = [
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
];

/// What the prior is, in every output.
pub const PRIOR_KIND: &str =
    "guided diffusion prior (shipped weights, trained on the synthetic corpus; best of 8 variants)";

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
    /// The onboard runtime's binary is missing.
    #[error("{0} is not built: run `cargo build --release -p v2t-edge -p video2track` first")]
    NoEdge(PathBuf),
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
    /// The `v2t-edge` executable.
    pub edge_bin: PathBuf,
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
    /// Wall time of the scenario, s.
    pub wall_s: f64,
    /// Files written.
    pub files: Vec<String>,
}

/// The whole demo.
#[derive(Debug, Clone, Serialize)]
pub struct Summary {
    /// Per scenario.
    pub scenarios: Vec<ScenarioSummary>,
    /// Wall time, s.
    pub wall_s: f64,
}

/// The `v2t-edge` executable next to this one.
pub fn edge_beside_me() -> PathBuf {
    std::env::current_exe()
        .ok()
        .and_then(|p| p.parent().map(|d| d.join("v2t-edge")))
        .unwrap_or_else(|| PathBuf::from("v2t-edge"))
}

/// Runs every scenario; prints progress on stdout.
pub fn run(opts: &DemoOptions) -> Result<Summary, DemoError> {
    if !opts.edge_bin.exists() {
        return Err(DemoError::NoEdge(opts.edge_bin.clone()));
    }
    std::fs::create_dir_all(&opts.out).map_err(|error| DemoError::Write { path: opts.out.clone(), error })?;
    let t0 = Instant::now();
    let inspection = crate::map::inspect(&opts.map, None).map_err(|e| DemoError::Stage {
        scenario: "map".into(),
        stage: "load",
        message: e.to_string(),
    })?;
    let model = crate::generate::load_model(&opts.weights).map_err(|e| DemoError::Stage {
        scenario: "diffusion".into(),
        stage: "weights",
        message: e.to_string(),
    })?;
    let mut scenarios = Vec::new();
    let mut runs = Vec::new();
    for (i, sc) in SCENARIOS.iter().enumerate() {
        println!("[{}/{}] {}", i + 1, SCENARIOS.len(), sc.name);
        let (summary, run, grounded) = run_one(opts, sc, &inspection, &model)?;
        scenarios.push(summary);
        runs.push((run, grounded));
    }
    let summary = Summary { scenarios, wall_s: t0.elapsed().as_secs_f64() };
    write(&opts.out.join("summary.json"), &pretty(&summary))?;
    write(&opts.out.join("report.html"), &report_html(&summary, &runs))?;
    Ok(summary)
}

fn write(path: &Path, text: &str) -> Result<(), DemoError> {
    std::fs::write(path, text).map_err(|error| DemoError::Write { path: path.to_owned(), error })
}

type Stage<T> = Result<T, DemoError>;

fn run_one(
    opts: &DemoOptions,
    sc: &DemoScenario,
    inspection: &crate::map::Inspection,
    model: &v2t_diffusion::weights::Model,
) -> Stage<(ScenarioSummary, Value, v2t_model::grounded::GroundedScenario)> {
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
    println!("  semantics   {interaction}, PET label {:.2} s (replayed cassette)", sem.pet_label_s);

    // Grounding on the proving ground.
    let g =
        v2t_ground::ground(&inspection.map, &inspection.library, &sem).map_err(|e| fail("ground")(e.to_string()))?;
    let grounded = g.scenario;
    save("grounded.json", pretty(&grounded))?;
    println!("  grounded    on {} (τ {:.2} s, {:?})", grounded.fragment_id, grounded.tau_s, grounded.style);

    // The prior.
    let gen_options =
        v2t_diffusion::generate::GenerateOptions { variants: VARIANTS, seed: opts.seed, ..Default::default() };
    let (variants, gen_summary) = crate::generate::run(model, &inspection.map, &grounded, &gen_options)
        .map_err(|e| fail("prior")(e.to_string()))?;
    let chosen = crate::generate::best(&variants).ok_or_else(|| fail("prior")("no variant generated".into()))?;
    let prior = chosen.prior.clone();
    save("prior.json", pretty(&prior))?;
    save("prior_metrics.json", pretty(&gen_summary))?;
    println!(
        "  prior       {} variants in {:.2} s, median anchor error {:.2} m, {:.1} s",
        gen_summary.variants,
        gen_summary.sampling_s,
        gen_summary.median_anchor_error_m,
        prior.duration_s()
    );

    // OpenSCENARIO.
    let vehicles = Path::new("config/vehicles");
    crate::export::export_xosc(&crate::export::XoscArgs {
        input: &file("prior.json"),
        out: &file("xosc"),
        map: &opts.map,
        vut_vehicle: &vehicles.join("vut_sedan.toml"),
        bv_vehicle: &vehicles.join("bv_sedan.toml"),
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
    let text = std::fs::read_to_string(&run_json).map_err(|e| fail("closed loop")(e.to_string()))?;
    let run: Value = serde_json::from_str(&text).map_err(|e| fail("closed loop")(e.to_string()))?;
    let r = at(&run, "/result");
    let pet = at(r, "/pet_min_s").as_f64();
    let fidelity = pet.map(|p| (p - sc.pet_label_s).abs() / sc.pet_label_s);
    println!(
        "  closed loop PET_min {} (video {:.2} s, error {}), order {}, collision {}",
        pet.map_or_else(|| "none".into(), |p| format!("{p:.2} s")),
        sc.pet_label_s,
        fidelity.map_or_else(|| "-".into(), |f| format!("{:.1} %", 100.0 * f)),
        if at(r, "/conflicts/0/order_matches_style").as_bool() == Some(true) {
            "as the style asks"
        } else {
            "NOT as the style asks"
        },
        if at(r, "/collision").is_null() { "none" } else { "YES" }
    );
    let summary = ScenarioSummary {
        name: sc.name.into(),
        pet_video_s: sc.pet_label_s,
        interaction: interaction.into(),
        style: format!("{:?}", grounded.style).to_lowercase(),
        fragment: grounded.fragment_id.clone(),
        prior: PRIOR_KIND.into(),
        pet_min_track_s: pet,
        fidelity_error_rel: fidelity,
        order_ok: at(r, "/conflicts/0/order_matches_style").as_bool(),
        collision: !at(r, "/collision").is_null(),
        min_distance_m: at(r, "/min_distance_m").as_f64(),
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
    let ecu = Command::new(&opts.edge_bin)
        .args(["sim-ecu", "--config", &cfg, "--namespace", &ns, "--prior"])
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
            return Err(format!("{}: {e}", opts.edge_bin.display()));
        }
    };
    let t0 = Instant::now();
    let status = loop {
        if let Ok(Some(s)) = ecu.try_wait() {
            break s;
        }
        let frac = (t0.elapsed().as_secs_f64() / (expected_s + 1.0)).min(0.99);
        let done = (frac * 30.0) as usize;
        print!("\r  closed loop [{}{}] {:>4.1} s", "#".repeat(done), ".".repeat(30 - done), t0.elapsed().as_secs_f64());
        let _ = std::io::stdout().flush();
        if t0.elapsed() > Duration::from_secs_f64(expected_s + 60.0) {
            let _ = ecu.kill();
            terminate(&mut launcher);
            return Err("the simulated ECU did not finish".into());
        }
        std::thread::sleep(Duration::from_millis(200));
    };
    println!("\r  closed loop [{}] {:>4.1} s", "#".repeat(30), t0.elapsed().as_secs_f64());
    terminate(&mut launcher);
    if !status.success() {
        return Err(format!("the simulated ECU failed ({status}); see {}", out.with_extension("log").display()));
    }
    Ok(())
}

fn report_html(summary: &Summary, runs: &[(Value, v2t_model::grounded::GroundedScenario)]) -> String {
    let mut h = String::from(
        "<!doctype html><html><head><meta charset=\"utf-8\"><title>Video2Track demo</title><style>\
         body{font-family:sans-serif;max-width:1100px;margin:2em auto;color:#222}table{border-collapse:collapse}\
         td,th{border:1px solid #ccc;padding:4px 8px;text-align:right}th{background:#f4f4f4}\
         .row{display:flex;gap:1em;flex-wrap:wrap}svg{border:1px solid #ddd;background:#fafafa}</style></head><body>\
         <h1>Video2Track demo</h1>",
    );
    let _ = write!(
        h,
        "<p>Semantics replayed from the shipped hand-written cassettes, grounded on the proving ground, prior: {}; \
         each run closes the loop through the BV's onboard processes (iceoryx2) and the simulated proving ground. \
         Wall time {:.1} s.</p><table><tr><th>scenario</th><th>style</th><th>PET video (s)</th><th>PET<sup>min</sup> track (s)</th>\
         <th>fidelity error</th><th>order</th><th>collision</th><th>min distance (m)</th></tr>",
        esc(PRIOR_KIND),
        summary.wall_s
    );
    for s in &summary.scenarios {
        let _ = write!(
            h,
            "<tr><td style=\"text-align:left\">{}</td><td>{}</td><td>{:.2}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
            esc(&s.name),
            esc(&s.style),
            s.pet_video_s,
            s.pet_min_track_s.map_or_else(|| "–".into(), |p| format!("{p:.2}")),
            s.fidelity_error_rel.map_or_else(|| "–".into(), |f| format!("{:.1} %", 100.0 * f)),
            match s.order_ok {
                Some(true) => "as asked",
                Some(false) => "wrong",
                None => "–",
            },
            if s.collision { "yes" } else { "no" },
            s.min_distance_m.map_or_else(|| "–".into(), |d| format!("{d:.2}"))
        );
    }
    h.push_str("</table>");
    for (s, (run, grounded)) in summary.scenarios.iter().zip(runs) {
        let _ = write!(
            h,
            "<h2>{}</h2><div class=\"row\">{}{}</div>",
            esc(&s.name),
            map_svg(run, grounded),
            pet_svg(run, s.pet_video_s)
        );
    }
    h.push_str("</body></html>\n");
    h
}

fn esc(s: &str) -> String {
    s.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;").replace('"', "&quot;")
}

const COLORS: [&str; 3] = ["#1f6fd1", "#d2461c", "#2a9d4b"];

/// Routes (grey) and driven paths (colour) in the track frame, north up.
fn map_svg(run: &Value, grounded: &v2t_model::grounded::GroundedScenario) -> String {
    let ids: Vec<&str> =
        at(run, "/agent_ids").as_array().map(|a| a.iter().filter_map(Value::as_str).collect()).unwrap_or_default();
    let trace = at(run, "/trace").as_array().cloned().unwrap_or_default();
    let mut paths: Vec<Vec<(f64, f64)>> = vec![Vec::new(); ids.len()];
    for sample in &trace {
        for (i, a) in at(sample, "/agents").as_array().into_iter().flatten().enumerate() {
            if let (Some(p), Some(x), Some(y)) =
                (paths.get_mut(i), at(a, "/state/px").as_f64(), at(a, "/state/py").as_f64())
            {
                p.push((x, y));
            }
        }
    }
    let routes: Vec<Vec<(f64, f64)>> =
        grounded.agents.iter().map(|a| a.route.iter().map(|p| (p.x, p.y)).collect()).collect();
    let all = paths.iter().chain(&routes).flatten();
    let (mut x0, mut y0, mut x1, mut y1) = (f64::INFINITY, f64::INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY);
    for (x, y) in all {
        x0 = x0.min(*x);
        y0 = y0.min(*y);
        x1 = x1.max(*x);
        y1 = y1.max(*y);
    }
    if !x0.is_finite() {
        return String::new();
    }
    let (w, hgt) = (480.0, 480.0);
    let span = (x1 - x0).max(y1 - y0).max(1.0) + 20.0;
    let scale = w / span;
    let (cx, cy) = ((x0 + x1) / 2.0, (y0 + y1) / 2.0);
    let tx = |x: f64| w / 2.0 + (x - cx) * scale;
    let ty = |y: f64| hgt / 2.0 - (y - cy) * scale;
    let poly = |pts: &[(f64, f64)]| {
        pts.iter().map(|(x, y)| format!("{:.1},{:.1}", tx(*x), ty(*y))).collect::<Vec<_>>().join(" ")
    };
    let mut s =
        format!("<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{w}\" height=\"{hgt}\" viewBox=\"0 0 {w} {hgt}\">");
    for r in &routes {
        let _ = write!(
            s,
            "<polyline points=\"{}\" fill=\"none\" stroke=\"#bbb\" stroke-width=\"{:.1}\" stroke-linecap=\"round\"/>",
            poly(r),
            3.5 * scale
        );
    }
    for (i, p) in paths.iter().enumerate() {
        let c = COLORS.get(i % COLORS.len()).copied().unwrap_or("#000");
        let _ = write!(s, "<polyline points=\"{}\" fill=\"none\" stroke=\"{c}\" stroke-width=\"2\"/>", poly(p));
        if let (Some((x, y)), Some(id)) = (p.first(), ids.get(i)) {
            let _ = write!(
                s,
                "<circle cx=\"{:.1}\" cy=\"{:.1}\" r=\"4\" fill=\"{c}\"/><text x=\"{:.1}\" y=\"{:.1}\" font-size=\"12\" fill=\"{c}\">{}</text>",
                tx(*x),
                ty(*y),
                tx(*x) + 6.0,
                ty(*y) - 6.0,
                esc(id)
            );
        }
    }
    for c in &grounded.conflicts {
        let _ = write!(
            s,
            "<circle cx=\"{:.1}\" cy=\"{:.1}\" r=\"6\" fill=\"none\" stroke=\"#c00\" stroke-width=\"2\"><title>conflict {}</title></circle>",
            tx(c.point.x),
            ty(c.point.y),
            esc(&c.anchor_id)
        );
    }
    let _ = write!(
        s,
        "<text x=\"8\" y=\"{:.0}\" font-size=\"11\" fill=\"#666\">grey: grounded routes; colour: driven; red: conflict; {:.0} m across</text></svg>",
        hgt - 8.0,
        span
    );
    s
}

/// Predicted PET over time with τ.
fn pet_svg(run: &Value, tau: f64) -> String {
    let trace = at(run, "/trace").as_array().cloned().unwrap_or_default();
    let pts: Vec<(f64, f64)> = trace
        .iter()
        .filter_map(|s| Some((at(s, "/t_s").as_f64()?, at(s, "/predicted_pet_s").as_array()?.first()?.as_f64()?)))
        .collect();
    let t_end = trace.last().and_then(|s| at(s, "/t_s").as_f64()).unwrap_or(1.0).max(1.0);
    let (w, hgt, pad) = (560.0, 300.0, 40.0);
    let y_max = pts.iter().map(|p| p.1).fold(tau * 2.0, f64::max).clamp(1.0, 15.0);
    let tx = |t: f64| pad + t / t_end * (w - 2.0 * pad);
    let ty = |v: f64| hgt - pad - v.clamp(0.0, y_max) / y_max * (hgt - 2.0 * pad);
    let mut s =
        format!("<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{w}\" height=\"{hgt}\" viewBox=\"0 0 {w} {hgt}\">");
    let _ = write!(
        s,
        "<line x1=\"{pad}\" y1=\"{:.1}\" x2=\"{:.1}\" y2=\"{:.1}\" stroke=\"#999\"/><line x1=\"{pad}\" y1=\"{pad}\" x2=\"{pad}\" y2=\"{:.1}\" stroke=\"#999\"/>",
        hgt - pad,
        w - pad,
        hgt - pad,
        hgt - pad
    );
    let _ = write!(
        s,
        "<line x1=\"{pad}\" y1=\"{0:.1}\" x2=\"{1:.1}\" y2=\"{0:.1}\" stroke=\"#c00\" stroke-dasharray=\"6 4\"/><text x=\"{2:.1}\" y=\"{3:.1}\" font-size=\"11\" fill=\"#c00\">τ = {tau:.2} s</text>",
        ty(tau),
        w - pad,
        w - pad - 60.0,
        ty(tau) - 4.0
    );
    let line = pts.iter().map(|(t, v)| format!("{:.1},{:.1}", tx(*t), ty(*v))).collect::<Vec<_>>().join(" ");
    let _ = write!(s, "<polyline points=\"{line}\" fill=\"none\" stroke=\"#1f6fd1\" stroke-width=\"2\"/>");
    let _ = write!(
        s,
        "<text x=\"{pad}\" y=\"16\" font-size=\"12\">predicted PET (s) over time (0–{t_end:.0} s); axis top {y_max:.1} s</text></svg>"
    );
    s
}

/// The value at a JSON pointer, `null` when absent.
fn at<'a>(v: &'a Value, pointer: &str) -> &'a Value {
    v.pointer(pointer).unwrap_or(&Value::Null)
}
