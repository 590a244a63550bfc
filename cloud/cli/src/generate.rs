//! `video2track generate`: trajectory priors for a grounded scenario from the diffusion model, with
//! their metrics (anchor error, boundary crossings, vehicle limits, passing order).

use std::path::Path;

use serde::Serialize;
use v2t_diffusion::generate::{GenerateOptions, Generated, PriorMetrics, generate};
use v2t_diffusion::guidance::GuidanceWeights;
use v2t_diffusion::weights::{self, Model};
use v2t_model::grounded::GroundedScenario;
use v2t_model::prior::TrajectoryPrior;
use v2t_model::validate::Validate as _;

/// Which guidance terms are on (the ablation of the crate README).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum GuidanceMode {
    /// All four terms.
    Full,
    /// Anchors only.
    AnchorOnly,
    /// None (the bare denoiser).
    None,
}

impl GuidanceMode {
    /// The weights of the mode.
    pub fn weights(self) -> GuidanceWeights {
        match self {
            Self::Full => v2t_diffusion::generate::FULL_GUIDANCE,
            Self::AnchorOnly => GuidanceWeights { anchor: 1.0, boundary: 0.0, clearance: 0.0, kinematic: 0.0 },
            Self::None => GuidanceWeights { anchor: 0.0, boundary: 0.0, clearance: 0.0, kinematic: 0.0 },
        }
    }

    /// Its name in reports.
    pub fn name(self) -> &'static str {
        match self {
            Self::Full => "full",
            Self::AnchorOnly => "anchor only",
            Self::None => "no guidance",
        }
    }
}

/// Summary over variants.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Summary {
    /// Variants generated.
    pub variants: usize,
    /// Median anchor error over every anchor of every variant, m.
    pub median_anchor_error_m: f64,
    /// Largest anchor error, m.
    pub max_anchor_error_m: f64,
    /// Agents crossing a solid boundary, over all variants.
    pub boundary_crossings: usize,
    /// Fraction of agent trajectories within the vehicle limits.
    pub within_limits_frac: f64,
    /// Fraction of conflicts passed in the style's order.
    pub order_ok_frac: f64,
    /// Variants drawn again because they crossed a boundary, left the limits or the order.
    pub redrawn: usize,
    /// Wall time of the sampling (all variants), s.
    pub sampling_s: f64,
}

/// The metrics file.
#[derive(Debug, Clone, Serialize)]
pub struct MetricsFile {
    /// The grounded scenario's fragment.
    pub fragment_id: String,
    /// Guidance mode.
    pub guidance: String,
    /// Sampler.
    pub sampler: String,
    /// Weights file and their training record.
    pub weights: String,
    /// Summary.
    pub summary: Summary,
    /// Per variant.
    pub variants: Vec<PriorMetrics>,
}

/// Summary of generated variants.
pub fn summarize(generated: &[Generated], redrawn: usize, sampling_s: f64) -> Summary {
    let mut errors: Vec<f64> = generated.iter().flat_map(|g| g.metrics.anchor_errors_m.iter().copied()).collect();
    let agents: usize = generated.iter().map(|g| g.metrics.agents).sum();
    let conflicts: usize = generated.iter().map(|g| g.metrics.conflicts).sum();
    Summary {
        variants: generated.len(),
        max_anchor_error_m: errors.iter().copied().fold(0.0, f64::max),
        median_anchor_error_m: v2t_diffusion::stats::median(&mut errors).unwrap_or(f64::NAN),
        boundary_crossings: generated.iter().map(|g| g.metrics.boundary_crossings).sum(),
        within_limits_frac: generated.iter().map(|g| g.metrics.agents_within_limits).sum::<usize>() as f64
            / agents.max(1) as f64,
        order_ok_frac: generated.iter().map(|g| g.metrics.order_ok).sum::<usize>() as f64 / conflicts.max(1) as f64,
        redrawn,
        sampling_s,
    }
}

/// Reads and checks a grounded scenario file.
pub fn read_grounded(path: &Path) -> anyhow::Result<GroundedScenario> {
    let text = std::fs::read_to_string(path).map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
    let g: GroundedScenario =
        serde_json::from_str(&text).map_err(|e| anyhow::anyhow!("{}: not a grounded scenario: {e}", path.display()))?;
    g.validate().map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
    Ok(g)
}

/// Loads the weights, with the file named in the error.
pub fn load_model(path: &Path) -> anyhow::Result<Model> {
    weights::load(path).map_err(|e| match e {
        weights::WeightsError::Io { .. } => anyhow::anyhow!("{e}"),
        _ => anyhow::anyhow!("{}: {e}", path.display()),
    })
}

/// Generates the variants of `scenario` with `model`; returns them with the summary.
pub fn run(
    model: &Model,
    map: &v2t_map::Map,
    scenario: &GroundedScenario,
    options: &GenerateOptions,
) -> anyhow::Result<(Vec<Generated>, Summary)> {
    let started = std::time::Instant::now();
    let (generated, redrawn) = generate(model, map, scenario, options)?;
    let summary = summarize(&generated, redrawn, started.elapsed().as_secs_f64());
    Ok((generated, summary))
}

/// The variant to hand on: the one with the smallest worst anchor error among the
/// [`acceptable`](v2t_diffusion::generate::acceptable) ones (else the smallest overall).
pub fn best(generated: &[Generated]) -> Option<&Generated> {
    let worst = |g: &Generated| g.metrics.anchor_errors_m.iter().copied().fold(0.0, f64::max);
    let clean = |g: &&Generated| v2t_diffusion::generate::acceptable(&g.metrics);
    let by_worst = |a: &&Generated, b: &&Generated| worst(a).total_cmp(&worst(b));
    generated.iter().filter(clean).min_by(by_worst).or_else(|| generated.iter().min_by(by_worst))
}

/// Writes a prior as JSON.
pub fn write_prior(path: &Path, prior: &TrajectoryPrior) -> anyhow::Result<()> {
    std::fs::write(path, serde_json::to_string_pretty(prior)?).map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))
}

/// A markdown line for the summary.
pub fn report(summary: &Summary, guidance: GuidanceMode) -> String {
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

/// The report's table header.
pub const REPORT_HEADER: &str = "| guidance | variants | median anchor error | max anchor error | boundary crossings | within limits | order as asked | redrawn | sampling |\n|---|---|---|---|---|---|---|---|---|\n";
