//! `video2track generate`: trajectory priors for a grounded scenario from the diffusion model
//! ([`v2t_diffusion::generate`]), with their metrics (anchor error, boundary crossings, vehicle
//! limits, passing order).

use std::path::{Path, PathBuf};

use serde::Serialize;
use v2t_diffusion::generate::{GenerateOptions, PriorMetrics, Summary, best, generate, summarize};
use v2t_diffusion::guidance::GuidanceWeights;
use v2t_diffusion::sample::{GuidanceSchedule, Method, SamplerOptions};
use v2t_files::{out, outln, shipped};

use crate::write_json;

/// Guidance terms of `generate` (the ablation of the crate README).
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum GuidanceArg {
    /// Anchors, solid boundaries, clearance, kinematic limits.
    Full,
    /// Anchors only.
    Anchor,
    /// None: the bare denoiser.
    None,
}

impl GuidanceArg {
    /// The weights of the mode.
    fn weights(self) -> GuidanceWeights {
        match self {
            Self::Full => v2t_diffusion::generate::FULL_GUIDANCE,
            Self::Anchor => GuidanceWeights { anchor: 1.0, boundary: 0.0, clearance: 0.0, kinematic: 0.0 },
            Self::None => GuidanceWeights { anchor: 0.0, boundary: 0.0, clearance: 0.0, kinematic: 0.0 },
        }
    }

    /// Its name in reports.
    fn name(self) -> &'static str {
        match self {
            Self::Full => "full",
            Self::Anchor => "anchor only",
            Self::None => "no guidance",
        }
    }
}

/// `generate`'s arguments.
#[derive(Debug, clap::Args)]
pub struct GenerateArgs {
    /// Grounded scenario (JSON, as `ground --out` writes it).
    grounded: PathBuf,
    /// Variants to generate (seeded, one batch).
    #[arg(long, default_value_t = 1)]
    variants: usize,
    /// Write the best variant (no boundary crossing, within limits, order as asked, smallest
    /// anchor error) as a trajectory prior (JSON) here.
    #[arg(long)]
    out: Option<PathBuf>,
    /// Write every variant as DIR/variant-NNN.json.
    #[arg(long)]
    all: Option<PathBuf>,
    /// Write per-variant metrics and their summary (JSON) here.
    #[arg(long)]
    json_metrics: Option<PathBuf>,
    /// Denoiser weights (safetensors).
    #[arg(long, default_value = shipped::WEIGHTS)]
    weights: PathBuf,
    /// The map the scenario is grounded on.
    #[arg(long, default_value = shipped::MAP)]
    map: PathBuf,
    /// Seed of the noise.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// DDIM with this many steps instead of DDPM over all K.
    #[arg(long)]
    ddim: Option<usize>,
    /// Guidance terms (ablation): full, anchor, none.
    #[arg(long, value_enum, default_value_t = GuidanceArg::Full)]
    guidance: GuidanceArg,
    /// Guidance scale η of every denoising step.
    #[arg(long, default_value_t = GuidanceSchedule::default().scale)]
    guidance_scale: f64,
    /// Guided corrections of the final sample (0: the paper's algorithm alone).
    #[arg(long, default_value_t = GuidanceSchedule::default().final_iterations)]
    final_iterations: usize,
    /// Draws per variant: one that crosses a solid boundary, leaves the limits or the order is
    /// drawn again up to this many times in all (1: no redraw, for ablations).
    #[arg(long, default_value_t = GenerateOptions::default().draws)]
    draws: u64,
    /// Write `--out` and `--all` even when no variant meets the criteria (the passing order,
    /// no solid boundary crossed, the vehicle limits, every anchor within 5 m); without it such a
    /// run writes no prior and exits 1 with the reasons.
    #[arg(long)]
    write_failing: bool,
}

/// No variant met the criteria of a prior that may be handed on: a failure of the work (exit 1).
#[derive(Debug, thiserror::Error)]
#[error("none of the {variants} variants meets the criteria of a prior ({reasons})")]
struct NoAcceptablePrior {
    variants: usize,
    reasons: String,
}

/// How many variants miss each criterion, in words (`generated` has no variant that meets them all).
fn refusal(generated: &[v2t_diffusion::generate::Generated]) -> NoAcceptablePrior {
    use v2t_diffusion::generate::shortfalls;
    let mut counts: Vec<(&'static str, usize)> = Vec::new();
    for shortfall in generated.iter().flat_map(|g| shortfalls(&g.metrics)) {
        match counts.iter_mut().find(|(k, _)| *k == shortfall.criterion()) {
            Some((_, n)) => *n += 1,
            None => counts.push((shortfall.criterion(), 1)),
        }
    }
    let all = generated.len();
    let mut reasons: Vec<String> = counts.iter().map(|(k, n)| format!("{k} in {n} of {all}")).collect();
    if let Some(b) = v2t_diffusion::generate::best(generated) {
        let best: Vec<String> = shortfalls(&b.metrics).iter().map(ToString::to_string).collect();
        reasons.push(format!("the best has {}", best.join(", ")));
    }
    NoAcceptablePrior { variants: all, reasons: reasons.join("; ") }
}

/// The metrics file.
#[derive(Debug, Clone, Serialize)]
struct MetricsFile {
    /// The grounded scenario's fragment.
    fragment_id: String,
    /// Guidance mode.
    guidance: String,
    /// Sampler.
    sampler: String,
    /// Weights file and their training record.
    weights: String,
    /// Summary.
    summary: Summary,
    /// Per variant.
    variants: Vec<PriorMetrics>,
}

/// The report's table header.
const REPORT_HEADER: &str = "| guidance | variants | median anchor error | max anchor error | boundary crossings | within limits | order as asked | redrawn | sampling |\n|---|---|---|---|---|---|---|---|---|\n";

/// A markdown line for the summary.
fn report(summary: &Summary, guidance: GuidanceArg) -> String {
    format!(
        "| {} | {} | {:.3} m | {:.3} m | {} | {:.1} % | {:.1} % | {} | {:.2} s |\n",
        guidance.name(),
        summary.variants,
        summary.median_anchor_error_m,
        summary.max_anchor_error_m,
        summary.boundary_crossings,
        100.0 * summary.within_limits_frac,
        100.0 * summary.order_ok_frac,
        summary.redrawn,
        summary.sampling_s
    )
}

/// Generates the variants, prints their summary, writes what was asked.
pub fn run(a: GenerateArgs) -> anyhow::Result<()> {
    let method = match a.ddim {
        Some(steps) => Method::Ddim { steps },
        None => Method::Ddpm { noise: true },
    };
    let schedule = GuidanceSchedule {
        scale: a.guidance_scale,
        final_iterations: a.final_iterations,
        ..GuidanceSchedule::default()
    };
    let options = GenerateOptions {
        variants: a.variants,
        seed: a.seed,
        sampler: SamplerOptions { method, guidance: schedule },
        weights: a.guidance.weights(),
        draws: a.draws,
        ..GenerateOptions::default()
    };
    // Bounds before anything is loaded: bad input, exit 2.
    options.check().map_err(|e| crate::Usage(format!("--{}", e.to_string().replace('_', "-"))))?;
    let scenario = v2t_files::read_grounded(&a.grounded)?;
    let model = v2t_diffusion::weights::load(&a.weights).map_err(crate::BadFile::of)?;
    let map = v2t_map::Map::load(&a.map)?;
    map.check_scenario(&scenario).map_err(|e| anyhow::Error::new(e).context(a.grounded.display().to_string()))?;
    let started = std::time::Instant::now();
    let (generated, redrawn) = generate(&model, &map, &scenario, &options)?;
    let summary = summarize(&generated, redrawn, started.elapsed().as_secs_f64());
    out!("{REPORT_HEADER}{}", report(&summary, a.guidance))?;
    let none_meets = !generated.iter().any(|g| v2t_diffusion::generate::shortfalls(&g.metrics).is_empty());
    let writes_prior = a.out.is_some() || a.all.is_some();
    if let Some(path) = &a.json_metrics {
        let file = MetricsFile {
            fragment_id: scenario.fragment_id.clone(),
            guidance: a.guidance.name().to_owned(),
            sampler: format!("{method:?}"),
            weights: format!("{} ({})", a.weights.display(), model.meta.training.command),
            summary,
            variants: generated.iter().map(|v| v.metrics.clone()).collect(),
        };
        write_json(path, &file)?;
    }
    if writes_prior && none_meets {
        let why = refusal(&generated);
        if !a.write_failing {
            return Err(anyhow::Error::new(why).context(
                "no prior written (more --variants or --draws may find one; --write-failing writes the best anyway)",
            ));
        }
        eprintln!("warning: writing the best anyway (--write-failing): {why}");
    }
    if let Some(dir) = &a.all {
        std::fs::create_dir_all(dir)?;
        for (i, v) in generated.iter().enumerate() {
            write_prior(&dir.join(format!("variant-{i:03}.json")), &v.prior)?;
        }
        outln!("wrote {} variants to {}", generated.len(), dir.display())?;
    }
    if let Some(path) = &a.out {
        let chosen = best(&generated).ok_or_else(|| anyhow::anyhow!("no variant generated"))?;
        write_prior(path, &chosen.prior)?;
        outln!("wrote {}", path.display())?;
    }
    Ok(())
}

/// Writes a prior as JSON.
fn write_prior(path: &Path, prior: &v2t_model::prior::TrajectoryPrior) -> anyhow::Result<()> {
    std::fs::write(path, serde_json::to_string_pretty(prior)?).map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))
}
