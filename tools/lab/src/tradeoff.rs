//! `video2track experiment tradeoff`: what the realism weight `w_real` of the regulator buys and
//! costs. For each weight, the two regulated methods (TroubleMaker-like: the regulator around the
//! constant-speed stand-in, here onboard like Video2Track — the sweep is about the realism term, the
//! network is `experiment latency`'s question; Video2Track: around the diffusion prior) on the paper's scenarios,
//! rush and yield at every τ, against every VUT model; Diffusion-only (the prior followed, no
//! regulator) once, as the end the realism term pulls toward.
//!
//! Per weight and method: the steering error `|meanPET^min − τ| / τ` per VUT model (never pooled
//! over models: the mean and the largest over that model's scenario × style × τ rows), collisions,
//! and the BV's realism (W₁ of acceleration and jerk to recorded human driving of its manoeuvre
//! class, jerk RMS, speed reversals) per scenario. The front is drawn as an SVG: realism against
//! the worst VUT model's mean steering error, one line per method.

use std::ops::RangeInclusive;

use serde::Serialize;
use v2t_model::Target;
use v2t_sim::vut::VutModel;

use crate::methods::{self, Method, MethodCase, MethodsError, PaperScenario, Setup};
use crate::stats::{RealismMeans, RealismStats};

/// The realism weights swept by default (`w_adv = 1`).
pub const WEIGHTS: [f64; 6] = [0.0, 0.1, 0.3, 1.0, 3.0, 10.0];
/// The targets τ swept by default, s (the range the realism criterion is stated over).
pub const TAUS_S: [f64; 4] = [2.0, 3.0, 4.0, 5.0];

/// One case of the sweep: a method case at one realism weight (Diffusion-only: no weight).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TradeoffCase {
    /// The realism weight (`None` for Diffusion-only, which has no regulator).
    pub w_real: Option<f64>,
    /// The case.
    #[serde(flatten)]
    pub case: MethodCase,
}

/// The steering error against one VUT model over its rows (scenario × style × τ).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ModelError {
    /// VUT model.
    pub vut: String,
    /// Rows.
    pub rows: usize,
    /// Mean of `|meanPET^min − τ| / τ` over the rows (a row without a measured PET counts as 1).
    pub mean_error_rel: f64,
    /// Largest.
    pub max_error_rel: f64,
}

/// One point of the front: a method at one weight.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TradeoffPoint {
    /// The realism weight (`None` for Diffusion-only).
    pub w_real: Option<f64>,
    /// Method.
    pub method: Method,
    /// Steering error per VUT model, over both scenarios.
    pub errors: Vec<ModelError>,
    /// The worst VUT model's mean steering error.
    pub worst_mean_error_rel: f64,
    /// Runs with a collision, over everything.
    pub collisions: usize,
    /// Runs.
    pub runs: usize,
    /// The BV's realism per scenario (pooled over styles, τ and VUT models).
    pub realism: Vec<(String, Option<RealismStats>)>,
    /// Per scenario, the worst VUT model's mean steering error over that scenario's rows.
    pub worst_by_scenario: Vec<(String, f64)>,
}

/// The whole sweep.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TradeoffReport {
    /// What the figures depend on (simulated world, hand-written VUT models and cassettes, the
    /// weights of the diffusion prior, the human reference).
    pub provenance: String,
    /// Seeds of the runs, first and last.
    pub seeds: [u64; 2],
    /// Targets τ, s.
    pub taus_s: Vec<f64>,
    /// Weights.
    pub weights: Vec<f64>,
    /// One per method and weight.
    pub points: Vec<TradeoffPoint>,
    /// Every case.
    pub cases: Vec<TradeoffCase>,
}

/// Runs the sweep: for each scenario and target the priors once, then every weight × regulated
/// method × VUT model (and Diffusion-only × VUT model) on the available cores.
pub fn sweep(
    setup: &Setup<'_>,
    scenarios: &[PaperScenario],
    taus_s: &[f64],
    weights: &[f64],
    models: &[VutModel],
    seeds: RangeInclusive<u64>,
    provenance: String,
) -> Result<TradeoffReport, MethodsError> {
    let targets = crate::steer::both_styles(taus_s);
    let mut jobs = Vec::new();
    for rec in scenarios {
        for &target in &targets {
            let (grounded, stand_in, diffusion) = methods::priors(rec, target, setup, 1)?;
            let name = case_name(&rec.name, target);
            let world = |prior| {
                methods::scenario_of_prior(&name, prior, &grounded, setup)
                    .map_err(|source| MethodsError::World { scenario: name.clone(), source })
            };
            let (constant, generated) = (world(&stand_in)?, world(&diffusion)?);
            for &m in models {
                jobs.push((generated.clone(), Method::DiffusionOnly, m, None));
                for &w in weights {
                    jobs.push((constant.clone(), Method::TroublemakerLike, m, Some(w)));
                    jobs.push((generated.clone(), Method::Video2track, m, Some(w)));
                }
            }
        }
    }
    let cases = crate::parallel_map(&jobs, |(sc, method, m, w)| {
        let params = v2t_game::regulator::RegulatorParams { w_real: w.unwrap_or(0.0), ..setup.regulator };
        TradeoffCase { w_real: *w, case: methods::run_case_with(setup, &params, None, sc, *method, *m, seeds.clone()) }
    });
    let mut points = vec![point(&cases, None, Method::DiffusionOnly, scenarios)];
    for method in [Method::TroublemakerLike, Method::Video2track] {
        for &w in weights {
            points.push(point(&cases, Some(w), method, scenarios));
        }
    }
    Ok(TradeoffReport {
        provenance,
        seeds: [*seeds.start(), *seeds.end()],
        taus_s: taus_s.to_vec(),
        weights: weights.to_vec(),
        points,
        cases,
    })
}

fn case_name(scenario: &str, target: Target) -> String {
    format!("{scenario} ({}, τ {:.2} s)", target.style(), target.tau_s())
}

fn point(cases: &[TradeoffCase], w: Option<f64>, method: Method, scenarios: &[PaperScenario]) -> TradeoffPoint {
    let of: Vec<&MethodCase> =
        cases.iter().filter(|c| c.w_real == w && c.case.method == method).map(|c| &c.case).collect();
    let mut vuts: Vec<&str> = of.iter().map(|c| c.vut.as_str()).collect();
    vuts.sort_unstable();
    vuts.dedup();
    let errors_of = |cases: &[&MethodCase]| -> Vec<ModelError> {
        vuts.iter()
            .map(|&vut| {
                let errs: Vec<f64> =
                    cases.iter().filter(|c| c.vut == vut).map(|c| c.stats.error_rel(c.tau_s).unwrap_or(1.0)).collect();
                ModelError {
                    vut: vut.to_owned(),
                    rows: errs.len(),
                    mean_error_rel: errs.iter().sum::<f64>() / errs.len().max(1) as f64,
                    max_error_rel: errs.iter().copied().fold(0.0, f64::max),
                }
            })
            .collect()
    };
    let worst = |errors: &[ModelError]| errors.iter().map(|e| e.mean_error_rel).fold(0.0, f64::max);
    let errors = errors_of(&of);
    let of_scenario = |rec: &PaperScenario| -> Vec<&MethodCase> {
        let prefix = format!("{} (", rec.name);
        of.iter().copied().filter(|c| c.scenario.starts_with(&prefix)).collect()
    };
    let worst_by_scenario =
        scenarios.iter().map(|rec| (rec.name.clone(), worst(&errors_of(&of_scenario(rec))))).collect();
    let realism = scenarios
        .iter()
        .map(|rec| {
            let pooled = RealismStats::pool(of_scenario(rec).iter().filter_map(|c| c.stats.bv_realism.as_ref()));
            (rec.name.clone(), pooled)
        })
        .collect();
    TradeoffPoint {
        w_real: w,
        method,
        worst_mean_error_rel: worst(&errors),
        worst_by_scenario,
        collisions: of.iter().map(|c| c.stats.collisions).sum(),
        runs: of.iter().map(|c| c.stats.repeats).sum(),
        errors,
        realism,
    }
}

fn weight_cell(w: Option<f64>) -> String {
    w.map_or("–".to_owned(), |w| format!("{w}"))
}

/// The sweep as markdown: per point the steering error per VUT model, collisions, and the BV's
/// realism per scenario.
pub fn markdown(r: &TradeoffReport) -> String {
    let Some(first) = r.points.first() else { return String::new() };
    let vuts: Vec<&str> = first.errors.iter().map(|e| e.vut.as_str()).collect();
    let mut out = String::from(
        "\nSteering error `|meanPET^min − τ| / τ` per VUT model (mean over scenario × style × τ; max in brackets):\n\n| method | w_real |",
    );
    for v in &vuts {
        out.push_str(&format!(" {v} |"));
    }
    out.push_str(" worst model | collisions | runs |\n|---|---|");
    out.push_str(&"---|".repeat(vuts.len() + 3));
    out.push('\n');
    for p in &r.points {
        out.push_str(&format!("| {} | {} |", p.method.name(), weight_cell(p.w_real)));
        for v in &vuts {
            match p.errors.iter().find(|e| e.vut == *v) {
                Some(e) => {
                    out.push_str(&format!(" {:.1} % ({:.1} %) |", 100.0 * e.mean_error_rel, 100.0 * e.max_error_rel))
                }
                None => out.push_str(" – |"),
            }
        }
        out.push_str(&format!(" {:.1} % | {} | {} |\n", 100.0 * p.worst_mean_error_rel, p.collisions, p.runs));
    }
    let scenarios: Vec<&str> = first.realism.iter().map(|(n, _)| n.as_str()).collect();
    for sc in scenarios {
        out.push_str(&format!(
            "\nThe BV's realism in the {sc} (pooled over styles, τ and VUT models):\n\n| method | w_real | BV class | W₁ accel (m/s²) | W₁ jerk (m/s³) | jerk RMS (m/s³) | speed reversals |\n|---|---|---|---|---|---|---|\n"
        ));
        for p in &r.points {
            let stats = p.realism.iter().find(|(n, _)| n == sc).and_then(|(_, s)| s.as_ref());
            out.push_str(&format!(
                "| {} | {} | {} |\n",
                p.method.name(),
                weight_cell(p.w_real),
                RealismStats::cells(stats)
            ));
        }
    }
    out
}

/// The front of one scenario as an SVG: the BV's W₁ of acceleration (left) and of jerk (right)
/// against the worst VUT model's mean steering error in that scenario, one line per regulated
/// method through its weights, Diffusion-only as a single point. `None` when the scenario's BV has no measured realism.
pub fn svg(r: &TradeoffReport, scenario: &str) -> Option<String> {
    let realism = |p: &TradeoffPoint| -> Option<RealismMeans> {
        p.realism.iter().find(|(n, _)| n == scenario).and_then(|(_, s)| s.as_ref()).and_then(|s| s.means)
    };
    let error = |p: &TradeoffPoint| {
        100.0 * p.worst_by_scenario.iter().find(|(n, _)| n == scenario).map_or(p.worst_mean_error_rel, |(_, e)| *e)
    };
    let pts: Vec<(&TradeoffPoint, RealismMeans)> = r.points.iter().filter_map(|p| Some((p, realism(p)?))).collect();
    if pts.is_empty() {
        return None;
    }
    let (w, h, pad) = (440.0, 320.0, 56.0);
    let x_max = pts.iter().map(|(p, _)| error(p)).fold(1.0, f64::max) * 1.1;
    let mut out = format!(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{}\" height=\"{}\" font-family=\"sans-serif\" font-size=\"12\">\n",
        2.0 * w,
        h + 40.0
    );
    out.push_str(&format!(
        "<text x=\"10\" y=\"18\" font-size=\"13\">{}: the BV's realism (W₁ to recorded human driving) against the steering error, per w_real (simulated proving ground; seeds {}–{})</text>\n",
        crate::report::esc(scenario),
        r.seeds[0],
        r.seeds[1]
    ));
    let panels: [(&str, Quantity); 2] =
        [("W₁ acceleration (m/s²)", |m| m.w1_accel_mps2), ("W₁ jerk (m/s³)", |m| m.w1_jerk_mps3)];
    for (i, (label, value)) in panels.iter().enumerate() {
        let x0 = i as f64 * w;
        let y_max = pts.iter().map(|(_, m)| value(m)).fold(0.0, f64::max) * 1.15;
        let sx = |e: f64| x0 + pad + (w - 1.5 * pad) * e / x_max;
        let sy = |v: f64| 30.0 + (h - pad) * (1.0 - v / y_max.max(1e-9));
        out.push_str(&format!(
            "<rect x=\"{:.1}\" y=\"30\" width=\"{:.1}\" height=\"{:.1}\" fill=\"none\" stroke=\"#999\"/>\n",
            x0 + pad,
            w - 1.5 * pad,
            h - pad
        ));
        for k in 0..=4 {
            let (e, v) = (x_max * k as f64 / 4.0, y_max * k as f64 / 4.0);
            out.push_str(&format!(
                "<text x=\"{:.1}\" y=\"{:.1}\" text-anchor=\"middle\">{e:.1}</text>\n<text x=\"{:.1}\" y=\"{:.1}\" text-anchor=\"end\">{v:.2}</text>\n",
                sx(e),
                h - pad + 46.0,
                x0 + pad - 4.0,
                sy(v) + 4.0
            ));
        }
        out.push_str(&format!(
            "<text x=\"{:.1}\" y=\"{:.1}\" text-anchor=\"middle\">worst VUT model's mean steering error in this scenario (%)</text>\n<text x=\"{:.1}\" y=\"{:.1}\" transform=\"rotate(-90 {:.1} {:.1})\" text-anchor=\"middle\">{label}</text>\n",
            x0 + w / 2.0,
            h + 30.0,
            x0 + 14.0,
            30.0 + (h - pad) / 2.0,
            x0 + 14.0,
            30.0 + (h - pad) / 2.0
        ));
        for (method, colour) in [(Method::TroublemakerLike, "#d62728"), (Method::Video2track, "#1f77b4")] {
            let line: Vec<(f64, f64, Option<f64>)> = pts
                .iter()
                .filter(|(p, _)| p.method == method)
                .map(|(p, m)| (sx(error(p)), sy(value(m)), p.w_real))
                .collect();
            let path: Vec<String> = line.iter().map(|(x, y, _)| format!("{x:.1},{y:.1}")).collect();
            out.push_str(&format!(
                "<polyline points=\"{}\" fill=\"none\" stroke=\"{colour}\" stroke-width=\"1.5\"/>\n",
                path.join(" ")
            ));
            for (x, y, wr) in &line {
                out.push_str(&format!(
                    "<circle cx=\"{x:.1}\" cy=\"{y:.1}\" r=\"3\" fill=\"{colour}\"/><text x=\"{:.1}\" y=\"{:.1}\" font-size=\"10\" fill=\"{colour}\">{}</text>\n",
                    x + 4.0,
                    y - 4.0,
                    weight_cell(*wr)
                ));
            }
        }
        for (p, m) in pts.iter().filter(|(p, _)| p.method == Method::DiffusionOnly) {
            let (x, y) = (sx(error(p)), sy(value(m)));
            out.push_str(&format!(
                "<rect x=\"{:.1}\" y=\"{:.1}\" width=\"7\" height=\"7\" fill=\"#2ca02c\"/>\n",
                x - 3.5,
                y - 3.5
            ));
        }
        let legend = [("#d62728", "TroubleMaker-like"), ("#1f77b4", "Video2Track"), ("#2ca02c", "Diffusion-only")];
        for (k, (colour, name)) in legend.iter().enumerate() {
            let y = h - pad - 12.0 + 14.0 * (k as f64 - 2.0);
            out.push_str(&format!(
                "<rect x=\"{:.1}\" y=\"{:.1}\" width=\"10\" height=\"10\" fill=\"{colour}\"/><text x=\"{:.1}\" y=\"{:.1}\">{name}</text>\n",
                x0 + w - 0.5 * pad - 130.0,
                y - 9.0,
                x0 + w - 0.5 * pad - 116.0,
                y
            ));
        }
    }
    out.push_str("</svg>\n");
    Some(out)
}

/// One realism quantity of a plot panel.
type Quantity = fn(&RealismMeans) -> f64;
