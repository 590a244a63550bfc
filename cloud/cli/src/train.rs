//! `video2track train` and `realism`: the denoiser of `v2t-diffusion` trained on a corpus (by default the
//! **synthetic** corpus generated on the proving ground), with a progress bar, checkpoints, a
//! held-out split and a metrics file.

use std::io::Write as _;
use std::path::PathBuf;

use v2t_diffusion::denoiser::DenoiserConfig;
use v2t_diffusion::synth::{SyntheticCorpus, generate_corpus, read_jsonl_file};
use v2t_diffusion::train::{Dataset, TrainMetrics, TrainOptions, Trainer};
use v2t_diffusion::weights;

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
    };
    let done = run_training(&args)?;
    println!(
        "trained {} parameters in {:.0} s, held-out loss {:.4}; wrote {} and {}",
        done.parameters,
        done.elapsed_s,
        done.heldout_loss,
        done.weights.display(),
        done.metrics.display()
    );
    Ok(())
}

/// `realism`: the table, and the JSON when asked.
pub fn realism(a: RealismCmd) -> anyhow::Result<()> {
    let args = RealismArgs { weights: a.weights, corpus: a.corpus, windows: a.windows, seed: a.seed };
    let rows = realism_rows(&args)?;
    print!("{}", realism_table(&rows));
    if let Some(path) = a.json {
        crate::write_json(&path, &rows)?;
    }
    Ok(())
}

/// The corpus `train` learns from and `realism` compares with (also the command-line options).
#[derive(Debug, Clone, clap::Args)]
pub struct CorpusSource {
    /// A corpus file (JSON lines, as the synthetic corpus writer makes it); default: generate the
    /// synthetic corpus on --map (the one the shipped weights were trained on).
    #[arg(long)]
    pub data: Option<PathBuf>,
    /// The corpus's map (routes come from its topology library).
    #[arg(long, default_value = v2t_files::shipped::MAP)]
    pub map: PathBuf,
    /// Episodes of the generated corpus.
    #[arg(long, default_value_t = DEFAULT_EPISODES)]
    pub episodes: usize,
    /// Seed of the generated corpus.
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

fn load_corpus(args: &CorpusSource, map: &v2t_map::Map) -> anyhow::Result<(SyntheticCorpus, String)> {
    match &args.data {
        Some(path) => {
            let corpus = read_jsonl_file(path)?;
            let source = format!(
                "{} ({} episodes, seed {}, map {})",
                path.display(),
                corpus.episodes.len(),
                corpus.seed,
                corpus.map
            );
            Ok((corpus, source))
        }
        None => {
            eprintln!("generating the synthetic corpus: {} episodes, seed {} …", args.episodes, args.corpus_seed);
            let corpus = generate_corpus(map, args.episodes, args.corpus_seed)?;
            let source = format!(
                "synthetic corpus generated on {} ({} episodes, corpus seed {})",
                args.map.display(),
                corpus.episodes.len(),
                args.corpus_seed
            );
            Ok((corpus, source))
        }
    }
}

fn progress(m: &TrainMetrics, total: usize) {
    let width = 30;
    let done = (m.step * width / total.max(1)).min(width);
    let eta = if m.step > 0 { m.elapsed_s / m.step as f64 * (total - m.step.min(total)) as f64 } else { 0.0 };
    eprint!(
        "\r[{}{}] {}/{} train {:.4} held-out {} lr {:.1e} {:.0} s, eta {:.0} s   ",
        "#".repeat(done),
        ".".repeat(width - done),
        m.step,
        total,
        m.train_loss,
        m.heldout_loss.map_or("-".to_owned(), |l| format!("{l:.4}")),
        m.learning_rate,
        m.elapsed_s,
        eta
    );
    let _ = std::io::stderr().flush();
}

/// Trains and writes the weights, checkpoints and metrics under `args.out`.
fn run_training(args: &TrainArgs) -> anyhow::Result<TrainOutcome> {
    let started = std::time::Instant::now();
    let map = v2t_map::Map::load(&args.corpus.map)?;
    let library = v2t_map::library::TopologyLibrary::build(&map);
    let (corpus, source) = load_corpus(&args.corpus, &map)?;
    let data = Dataset::build(&corpus.episodes, &library, args.config, args.stride)?;
    eprintln!(
        "{} training windows, {} held-out windows ({} held-out episodes)",
        data.train.len(),
        data.heldout.len(),
        data.heldout_episodes.len()
    );
    std::fs::create_dir_all(args.out.join("checkpoints"))?;
    let metrics_path = args.out.join("metrics.jsonl");
    let mut metrics_file = std::fs::File::create(&metrics_path)?;
    let mut trainer = Trainer::new(args.config, args.options)?;
    let parameters = trainer.parameters();
    eprintln!("denoiser: {parameters} parameters, {:?}", args.config);
    let mut io_error: Option<anyhow::Error> = None;
    let heldout = trainer.run(&data, |t, m| {
        progress(m, args.options.steps);
        let line = serde_json::to_string(m).map_err(anyhow::Error::from);
        let written = line.and_then(|l| writeln!(metrics_file, "{l}").map_err(anyhow::Error::from));
        let checkpoint = if args.checkpoint_every > 0 && m.step % args.checkpoint_every == 0 {
            let meta = t.meta(&data, args.command.clone(), source.clone(), m.heldout_loss.unwrap_or(f64::NAN));
            let path = args.out.join("checkpoints").join(format!("step-{:06}.safetensors", m.step));
            weights::save(t.varmap(), &meta, &path).map_err(anyhow::Error::from)
        } else {
            Ok(())
        };
        if let Err(e) = written.and(checkpoint) {
            io_error.get_or_insert(e);
        }
    })?;
    eprintln!();
    if let Some(e) = io_error {
        return Err(e.context("writing metrics or a checkpoint"));
    }
    let meta = trainer.meta(&data, args.command.clone(), source, heldout);
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

/// The realism table (W₁ against the held-out split of the corpus the weights were trained on)
/// for no guidance, anchors only and full guidance.
fn realism_rows(args: &RealismArgs) -> anyhow::Result<Vec<v2t_diffusion::realism::RealismRow>> {
    use v2t_diffusion::guidance::GuidanceWeights;
    let model = weights::load(&args.weights)?;
    let map = v2t_map::Map::load(&args.corpus.map)?;
    let library = v2t_map::library::TopologyLibrary::build(&map);
    let (corpus, _) = load_corpus(&args.corpus, &map)?;
    let data = Dataset::build(&corpus.episodes, &library, model.meta.config, 5)?;
    let anchor_only = GuidanceWeights { anchor: 1.0, boundary: 0.0, clearance: 0.0, kinematic: 0.0 };
    let modes = [
        ("no guidance", None),
        ("anchor only", Some(anchor_only)),
        ("full", Some(v2t_diffusion::generate::FULL_GUIDANCE)),
    ];
    let rows = v2t_diffusion::realism::realism(
        &model,
        &data,
        Some(&map),
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
    let mut out = String::from(
        "| vs held-out | windows | W1 acceleration | W1 jerk | W1 yaw rate | median anchor error |\n|---|---|---|---|---|---|\n",
    );
    for r in rows {
        out.push_str(&format!(
            "| {} | {} | {} | {} | {} | {} |\n",
            r.name,
            r.windows,
            f(r.distances.accel_mps2, "m/s²"),
            f(r.distances.jerk_mps3, "m/s³"),
            f(r.distances.yaw_rate_radps, "rad/s"),
            f(r.median_anchor_error_m, "m")
        ));
    }
    out
}
