//! `video2track train` and `realism`: the denoiser of `v2t-diffusion` trained on a corpus (by default the
//! **synthetic** corpus generated on the proving ground), with a progress bar, checkpoints, a
//! held-out split and a metrics file.

use std::io::Write as _;
use std::path::PathBuf;

use v2t_diffusion::denoiser::DenoiserConfig;
use v2t_diffusion::recorded::{self, RecordedCorpus};
use v2t_diffusion::synth::{SyntheticCorpus, from_jsonl, generate_corpus};
use v2t_diffusion::train::{Dataset, TrainMetrics, TrainOptions, Trainer};
use v2t_diffusion::weights;
use v2t_files::{out, outln};

use crate::Usage;

/// Default corpus: episodes and seed of the synthetic corpus the shipped weights were trained on.
pub const DEFAULT_EPISODES: usize = 1000;
/// … its seed.
pub const DEFAULT_CORPUS_SEED: u64 = 1;

/// `train`'s arguments.
#[derive(Debug, clap::Args)]
pub struct TrainCmd {
    #[command(flatten)]
    corpus: CorpusSource,
    /// Optimizer steps.
    #[arg(long, default_value_t = 5000)]
    steps: usize,
    /// Windows per step.
    #[arg(long, default_value_t = 64)]
    batch: usize,
    /// Peak learning rate.
    #[arg(long, default_value_t = 1e-3)]
    lr: f64,
    /// Seed of initialization, batches and noise.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Channels of the network.
    #[arg(long, default_value_t = 64)]
    hidden: usize,
    /// Residual blocks.
    #[arg(long, default_value_t = 4)]
    blocks: usize,
    /// Held-out loss (and a metrics line) every this many steps.
    #[arg(long, default_value_t = 250)]
    eval_every: usize,
    /// A checkpoint every this many steps (0: none).
    #[arg(long, default_value_t = 1000)]
    checkpoint_every: usize,
    /// Output directory.
    #[arg(long, default_value = "target/train")]
    out: PathBuf,
    /// Train on from these weights (their architecture and normalization; --hidden and --blocks
    /// are then ignored) instead of a fresh network.
    #[arg(long)]
    init: Option<PathBuf>,
    /// Draw each recorded training window this many times as often as a synthetic one (1–100).
    #[arg(long, default_value_t = 1)]
    recorded_repeat: usize,
}

/// `realism`'s arguments.
#[derive(Debug, clap::Args)]
pub struct RealismCmd {
    /// Denoiser weights (safetensors).
    #[arg(long, default_value = v2t_files::shipped::WEIGHTS)]
    weights: PathBuf,
    #[command(flatten)]
    corpus: CorpusSource,
    /// Held-out windows compared (one per held-out episode).
    #[arg(long, default_value_t = 100)]
    windows: usize,
    /// Sampling seed.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Write the rows as JSON here.
    #[arg(long)]
    json: Option<PathBuf>,
}

/// `train`: trains, writes, says what it did.
pub fn train(a: TrainCmd) -> anyhow::Result<()> {
    let command = std::env::args().collect::<Vec<_>>().join(" ");
    let args = TrainArgs {
        corpus: a.corpus,
        options: TrainOptions {
            steps: a.steps,
            batch: a.batch,
            learning_rate: a.lr,
            seed: a.seed,
            eval_every: a.eval_every,
            ..TrainOptions::default()
        },
        config: DenoiserConfig { hidden: a.hidden, blocks: a.blocks, ..DenoiserConfig::default() },
        stride: 5,
        out: a.out,
        checkpoint_every: a.checkpoint_every,
        command,
        init: a.init,
        recorded_repeat: a.recorded_repeat,
    };
    if !(1..=100).contains(&args.recorded_repeat) {
        return Err(Usage(format!("--recorded-repeat {}: must lie in 1..=100", args.recorded_repeat)).into());
    }
    let done = run_training(&args)?;
    outln!(
        "trained {} parameters in {:.0} s, held-out loss {:.4}; wrote {} and {}",
        done.parameters,
        done.elapsed_s,
        done.heldout_loss,
        done.weights.display(),
        done.metrics.display()
    )?;
    Ok(())
}

/// `realism`: the table, and the JSON when asked.
pub fn realism(a: RealismCmd) -> anyhow::Result<()> {
    let args = RealismArgs { weights: a.weights, corpus: a.corpus, windows: a.windows, seed: a.seed };
    let rows = realism_rows(&args)?;
    out!("{}", realism_table(&rows))?;
    if let Some(path) = a.json {
        crate::write_json(&path, &rows)?;
    }
    Ok(())
}

/// The corpus `train` learns from and `realism` compares with (also the command-line options).
#[derive(Debug, Clone, clap::Args)]
pub struct CorpusSource {
    /// Corpus files (JSON lines, repeatable): synthetic (as the `synthetic_corpus` example writes
    /// it: its episodes with index ≡ 0 mod 10 are held out) or recorded (`corpus import`: training
    /// data for `train`; for `realism` the held-out reference, whole).
    #[arg(long)]
    pub data: Vec<PathBuf>,
    /// Recorded corpus files held out whole (repeatable): `train` measures its held-out loss on
    /// them alone (every synthetic episode then trains); `realism` takes them as its floor (the
    /// training side) when given with a recorded --data.
    #[arg(long)]
    pub heldout_data: Vec<PathBuf>,
    /// The synthetic corpus's map (routes come from its topology library).
    #[arg(long, default_value = v2t_files::shipped::MAP)]
    pub map: PathBuf,
    /// Episodes of the synthetic corpus generated on --map (default: 1000 without --data, none
    /// with it).
    #[arg(long)]
    pub episodes: Option<usize>,
    /// Seed of the generated synthetic corpus.
    #[arg(long, default_value_t = DEFAULT_CORPUS_SEED)]
    pub corpus_seed: u64,
}

/// What training needs.
#[derive(Debug, Clone)]
struct TrainArgs {
    /// The corpus.
    pub corpus: CorpusSource,
    /// Optimizer settings.
    pub options: TrainOptions,
    /// Architecture.
    pub config: DenoiserConfig,
    /// Window stride, steps.
    pub stride: usize,
    /// Output directory: `denoiser.safetensors`, `metrics.jsonl`, `checkpoints/`.
    pub out: PathBuf,
    /// A checkpoint every this many steps (0: none).
    pub checkpoint_every: usize,
    /// The command line, recorded in the weights.
    pub command: String,
    /// Weights to train on from (their architecture and normalization), instead of a fresh network.
    pub init: Option<PathBuf>,
    /// How many times each recorded training window is drawn relative to a synthetic one.
    pub recorded_repeat: usize,
}

/// What training produced.
#[derive(Debug, Clone)]
struct TrainOutcome {
    /// The weights file.
    pub weights: PathBuf,
    /// The metrics file.
    pub metrics: PathBuf,
    /// Last held-out loss.
    pub heldout_loss: f64,
    /// Trainable numbers.
    pub parameters: usize,
    /// Wall time, s.
    pub elapsed_s: f64,
}

/// Every corpus named by a [`CorpusSource`], read.
struct Corpora {
    synthetic: Vec<SyntheticCorpus>,
    recorded: Vec<RecordedCorpus>,
    heldout: Vec<RecordedCorpus>,
    /// What they are, for the weights' training record.
    source: String,
}

impl Corpora {
    /// Whether any episode is recorded (not simulated).
    fn has_recorded(&self) -> bool {
        self.recorded.iter().chain(&self.heldout).any(|c| !c.episodes.is_empty())
    }
}

fn read_recorded(path: &std::path::Path) -> anyhow::Result<RecordedCorpus> {
    recorded::read_file(path).map_err(|e| crate::named(path, e).into())
}

fn load_corpora(args: &CorpusSource, map: &v2t_map::Map) -> anyhow::Result<Corpora> {
    let mut out = Corpora { synthetic: Vec::new(), recorded: Vec::new(), heldout: Vec::new(), source: String::new() };
    let mut parts = Vec::new();
    for path in &args.data {
        let text = v2t_files::bounds::read_text_within(path, v2t_files::bounds::DRIVING_DATA)
            .map_err(|e| Usage(format!("{}: {e}", path.display())))?;
        if recorded::format_of(&text).as_deref() == Some(recorded::FORMAT) {
            let c = recorded::from_jsonl(&text).map_err(|e| Usage(format!("{}: {e}", path.display())))?;
            parts.push(format!("recorded {} ({} episodes: {})", path.display(), c.episodes.len(), datasets(&c)));
            out.recorded.push(c);
        } else {
            let c = from_jsonl(&text).map_err(|e| Usage(format!("{}: {e}", path.display())))?;
            parts.push(format!(
                "synthetic {} ({} episodes, seed {}, map {})",
                path.display(),
                c.episodes.len(),
                c.seed,
                c.map
            ));
            out.synthetic.push(c);
        }
    }
    for path in &args.heldout_data {
        let c = read_recorded(path)?;
        parts.push(format!("held out: recorded {} ({} episodes: {})", path.display(), c.episodes.len(), datasets(&c)));
        out.heldout.push(c);
    }
    let episodes = args.episodes.unwrap_or(if args.data.is_empty() { DEFAULT_EPISODES } else { 0 });
    if episodes > 0 {
        eprintln!("generating the synthetic corpus: {episodes} episodes, seed {} …", args.corpus_seed);
        let corpus = generate_corpus(map, episodes, args.corpus_seed)?;
        parts.push(format!(
            "synthetic corpus generated on {} ({} episodes, corpus seed {})",
            args.map.display(),
            corpus.episodes.len(),
            args.corpus_seed
        ));
        out.synthetic.push(corpus);
    }
    if parts.is_empty() {
        return Err(Usage("no data: give --data, --heldout-data or --episodes > 0".into()).into());
    }
    out.source = parts.join("; ");
    Ok(out)
}

/// The datasets and licences of a recorded corpus, for the training record.
fn datasets(c: &RecordedCorpus) -> String {
    let mut seen: Vec<String> = Vec::new();
    for s in &c.sources {
        let d = format!("{} [{}]", s.dataset, s.licence);
        if !seen.contains(&d) {
            seen.push(d);
        }
    }
    seen.join(", ")
}

/// The training episodes of every corpus; recorded episodes at another sampling period than the
/// model's are left out (and counted on stderr).
fn training_episodes<'a>(
    corpora: &'a Corpora,
    library: &v2t_map::library::TopologyLibrary,
) -> Vec<v2t_diffusion::train::TrainingEpisode<'a>> {
    use v2t_diffusion::train::{recorded_episodes, synthetic_episodes};
    let mut out = Vec::new();
    // With recorded held-out data, that is the held-out split and every synthetic episode trains.
    let hold_out = corpora.heldout.iter().all(|c| c.episodes.is_empty());
    for c in &corpora.synthetic {
        out.extend(synthetic_episodes(&c.episodes, library, hold_out));
    }
    let mut skipped = 0;
    for (c, heldout) in corpora.recorded.iter().map(|c| (c, false)).chain(corpora.heldout.iter().map(|c| (c, true))) {
        let (e, n) = recorded_episodes(&c.episodes, heldout);
        out.extend(e);
        skipped += n;
    }
    if skipped > 0 {
        eprintln!("{skipped} recorded episodes left out: sampled at another period than the model's 0.1 s");
    }
    out
}

fn progress(bar: &mut v2t_lab::progress::Progress<std::io::Stderr>, m: &TrainMetrics, total: usize) {
    let frac = m.step as f64 / total.max(1) as f64;
    let eta = if m.step > 0 { m.elapsed_s / m.step as f64 * (total - m.step.min(total)) as f64 } else { 0.0 };
    let line = format!(
        "{} {}/{} train {:.4} held-out {} lr {:.1e} {:.0} s, eta {:.0} s   ",
        v2t_lab::progress::bar(frac, 30),
        m.step,
        total,
        m.train_loss,
        m.heldout_loss.map_or("-".to_owned(), |l| format!("{l:.4}")),
        m.learning_rate,
        m.elapsed_s,
        eta
    );
    bar.update(frac, &line);
}

/// Trains and writes the weights, checkpoints and metrics under `args.out`.
fn run_training(args: &TrainArgs) -> anyhow::Result<TrainOutcome> {
    let started = std::time::Instant::now();
    let map = v2t_map::Map::load(&args.corpus.map)?;
    let library = v2t_map::library::TopologyLibrary::build(&map);
    let corpora = load_corpora(&args.corpus, &map)?;
    let synthetic = !corpora.has_recorded();
    let mut source = corpora.source.clone();
    let (mut trainer, normalization) = match &args.init {
        Some(path) => {
            let bytes = v2t_files::bounds::read_bytes_within(path, v2t_files::bounds::WEIGHTS)
                .map_err(|e| Usage(format!("--init {}: {e}", path.display())))?;
            let (t, n) = Trainer::from_weights(&bytes, args.options)
                .map_err(|e| Usage(format!("--init {}: {e}", path.display())))?;
            source = format!("{source}; trained on from {}", path.display());
            (t, Some(n))
        }
        None => (Trainer::new(args.config, args.options)?, None),
    };
    let config = *trainer.denoiser().config();
    let episodes = training_episodes(&corpora, &library);
    let mut data = Dataset::build_from(&episodes, config, args.stride, normalization)?;
    let recorded: Vec<_> =
        data.train.iter().filter(|w| episodes.get(w.episode).is_some_and(|e| !e.full_windows_only)).cloned().collect();
    let recorded_train = recorded.len();
    if args.recorded_repeat > 1 {
        for _ in 1..args.recorded_repeat {
            data.train.extend(recorded.iter().cloned());
        }
        source = format!("{source}; recorded training windows repeated {}×", args.recorded_repeat);
    }
    eprintln!(
        "{} training windows ({} recorded, ×{}), {} held-out windows ({} held-out episodes)",
        data.train.len(),
        recorded_train,
        args.recorded_repeat.max(1),
        data.heldout.len(),
        data.heldout_episodes.len()
    );
    std::fs::create_dir_all(args.out.join("checkpoints"))?;
    let metrics_path = args.out.join("metrics.jsonl");
    let mut metrics_file = std::fs::File::create(&metrics_path)?;
    let parameters = trainer.parameters();
    eprintln!("denoiser: {parameters} parameters, {config:?}");
    let mut io_error: Option<anyhow::Error> = None;
    let mut bar = v2t_lab::progress::Progress::stderr();
    let heldout = trainer.run(&data, |t, m| {
        progress(&mut bar, m, args.options.steps);
        let line = serde_json::to_string(m).map_err(anyhow::Error::from);
        let written = line.and_then(|l| writeln!(metrics_file, "{l}").map_err(anyhow::Error::from));
        let checkpoint = if args.checkpoint_every > 0 && m.step % args.checkpoint_every == 0 {
            let meta =
                t.meta(&data, args.command.clone(), source.clone(), synthetic, m.heldout_loss.unwrap_or(f64::NAN));
            let path = args.out.join("checkpoints").join(format!("step-{:06}.safetensors", m.step));
            weights::save(t.varmap(), &meta, &path).map_err(anyhow::Error::from)
        } else {
            Ok(())
        };
        if let Err(e) = written.and(checkpoint) {
            io_error.get_or_insert(e);
        }
    })?;
    bar.finish("training done");
    if let Some(e) = io_error {
        return Err(e.context("writing metrics or a checkpoint"));
    }
    let meta = trainer.meta(&data, args.command.clone(), source, synthetic, heldout);
    let weights_path = args.out.join("denoiser.safetensors");
    weights::save(trainer.varmap(), &meta, &weights_path)?;
    Ok(TrainOutcome {
        weights: weights_path,
        metrics: metrics_path,
        heldout_loss: heldout,
        parameters,
        elapsed_s: started.elapsed().as_secs_f64(),
    })
}

/// Recorded windows compared by `realism` start at least this many steps (2 s) apart.
const RECORDED_WINDOW_SPACING_STEPS: usize = 20;

/// What the realism measurement needs.
#[derive(Debug, Clone)]
struct RealismArgs {
    /// Weights to evaluate.
    pub weights: PathBuf,
    /// The corpus they were trained on.
    pub corpus: CorpusSource,
    /// Held-out windows compared (one per episode).
    pub windows: usize,
    /// Sampling seed.
    pub seed: u64,
}

/// The realism table for no guidance, anchors only and full guidance: W₁ against the held-out
/// split of a synthetic corpus, or against every window of the recorded --data corpora (then the
/// floor row compares the recorded --heldout-data corpora's windows with them, when given).
fn realism_rows(args: &RealismArgs) -> anyhow::Result<Vec<v2t_diffusion::realism::RealismRow>> {
    use v2t_diffusion::guidance::GuidanceWeights;
    use v2t_diffusion::train::{TrainingEpisode, Window, episode_windows, recorded_episodes};
    let model = weights::load(&args.weights).map_err(crate::BadFile::of)?;
    let map = v2t_map::Map::load(&args.corpus.map)?;
    let library = v2t_map::library::TopologyLibrary::build(&map);
    let corpora = load_corpora(&args.corpus, &map)?;
    let cfg = model.meta.config;
    let norm = model.meta.normalization;
    let windows_of = |episodes: &[TrainingEpisode<'_>]| -> Vec<Window> {
        episodes.iter().enumerate().flat_map(|(i, e)| episode_windows(i, e, &cfg, &norm, 5)).collect()
    };
    let (heldout, floor, spacing) = if corpora.recorded.is_empty() {
        let data = Dataset::build_from(&training_episodes(&corpora, &library), cfg, 5, Some(norm))?;
        (data.heldout, Some(data.train), None)
    } else {
        let reference: Vec<_> = corpora.recorded.iter().flat_map(|c| recorded_episodes(&c.episodes, true).0).collect();
        let floor: Vec<_> = corpora.heldout.iter().flat_map(|c| recorded_episodes(&c.episodes, false).0).collect();
        let floor = (!floor.is_empty()).then(|| windows_of(&floor));
        (windows_of(&reference), floor, Some(RECORDED_WINDOW_SPACING_STEPS))
    };
    if heldout.is_empty() {
        return Err(Usage("no held-out window in the data (recorded episodes need 0.1 s sampling)".into()).into());
    }
    let anchor_only = GuidanceWeights { anchor: 1.0, boundary: 0.0, clearance: 0.0, kinematic: 0.0 };
    // Solid boundaries come from the synthetic corpus's map: recorded windows lie elsewhere.
    let boundary_map = corpora.recorded.is_empty().then_some(&map);
    let modes = [
        ("no guidance", None),
        ("anchor only", Some(anchor_only)),
        ("full", Some(v2t_diffusion::generate::FULL_GUIDANCE)),
    ];
    let rows = v2t_diffusion::realism::realism(
        &model,
        &heldout,
        floor.as_deref(),
        spacing,
        boundary_map,
        &modes,
        args.windows,
        args.seed,
        &v2t_diffusion::sample::SamplerOptions::default(),
    )?;
    Ok(rows)
}

/// The realism rows as a markdown table.
fn realism_table(rows: &[v2t_diffusion::realism::RealismRow]) -> String {
    let f = |v: Option<f64>, unit: &str| v.map_or("-".to_owned(), |x| format!("{x:.3} {unit}"));
    let fi = |v: Option<f64>, i: Option<(f64, f64)>, unit: &str| match (v, i) {
        (Some(x), Some((lo, hi))) => format!("{x:.3} ({lo:.3}–{hi:.3}) {unit}"),
        _ => f(v, unit),
    };
    let g = |v: Option<f64>| v.map_or("-".to_owned(), |x| format!("{x:.3}"));
    let mut out = String::from(
        "| vs held-out | windows | W1 acceleration | W1 jerk | W1 yaw rate | median anchor error | RMS a / jerk / yaw rate |\n|---|---|---|---|---|---|---|\n",
    );
    for r in rows {
        out.push_str(&format!(
            "| {} | {} | {} | {} | {} | {} | {} / {} / {} |\n",
            r.name,
            r.windows,
            fi(r.distances.accel_mps2, r.interval.and_then(|i| i.accel_mps2), "m/s²"),
            fi(r.distances.jerk_mps3, r.interval.and_then(|i| i.jerk_mps3), "m/s³"),
            fi(r.distances.yaw_rate_radps, r.interval.and_then(|i| i.yaw_rate_radps), "rad/s"),
            f(r.median_anchor_error_m, "m"),
            g(r.rms.accel_mps2),
            g(r.rms.jerk_mps3),
            g(r.rms.yaw_rate_radps)
        ));
    }
    out.push_str(&format!(
        "\nIn brackets: 5–95 % of W1 over {} bootstrap draws of the held-out windows.\n",
        v2t_diffusion::realism::BOOTSTRAP_DRAWS
    ));
    out
}
