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
use crate::report::plot::{Figure, LinePlot, Marker, Series, colour};
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

/// The front of one scenario: the BV's W₁ of acceleration (left) and of jerk (right) against the
/// worst VUT model's mean steering error in that scenario, one line per regulated method through
/// its weights, Diffusion-only as a single point. `None` when the scenario's BV has no measured
/// realism.
pub fn figure(r: &TradeoffReport, scenario: &str) -> Option<Figure> {
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
    let x_max = pts.iter().map(|(p, _)| error(p)).fold(1.0, f64::max) * 1.1;
    let panels: [(&str, &str, Quantity); 2] = [
        ("The BV's acceleration", "W₁ acceleration (m/s²)", |m| m.w1_accel_mps2),
        ("The BV's jerk", "W₁ jerk (m/s³)", |m| m.w1_jerk_mps3),
    ];
    let methods = [
        (Method::TroublemakerLike, "TroubleMaker-like", colour(1)),
        (Method::Video2track, "Video2Track", colour(0)),
        (Method::DiffusionOnly, "Diffusion-only", colour(2)),
    ];
    let panels = panels
        .iter()
        .map(|(title, label, value)| {
            // Room above the highest point for the legend.
            let y_max = pts.iter().map(|(_, m)| value(m)).fold(0.0, f64::max) * 1.3;
            let series = methods
                .iter()
                .map(|(method, name, c)| {
                    let of: Vec<&(&TradeoffPoint, RealismMeans)> =
                        pts.iter().filter(|(p, _)| p.method == *method).collect();
                    let marker = if *method == Method::DiffusionOnly { Marker::Square } else { Marker::Dot };
                    Series {
                        marker: Some(marker),
                        labels: match method {
                            Method::DiffusionOnly => Vec::new(),
                            _ => of.iter().map(|(p, _)| weight_cell(p.w_real)).collect(),
                        },
                        ..Series::line(*name, of.iter().map(|(p, m)| (error(p), value(m))).collect(), c)
                    }
                })
                .collect();
            let plot = LinePlot {
                title: (*title).to_owned(),
                x_label: "worst VUT model's mean steering error in this scenario (%)".into(),
                y_label: (*label).to_owned(),
                series,
                levels: Vec::new(),
                y_range: Some((0.0, y_max.max(1e-9))),
                x_range: Some((0.0, x_max)),
                cursor: false,
                markers: false,
            };
            (plot, "tradeoff".to_owned())
        })
        .collect();
    Some(Figure {
        title: format!(
            "{scenario}: the BV's realism (W₁ to recorded human driving) against the steering error, per w_real \
             (simulated proving ground; seeds {}–{})",
            r.seeds[0], r.seeds[1]
        ),
        panels,
        columns: 2,
    })
}

/// The front of one scenario as a file of its own (`experiment tradeoff --svg-dir`); `None` when
/// the scenario's BV has no measured realism.
pub fn svg(r: &TradeoffReport, scenario: &str) -> Option<String> {
    figure(r, scenario).map(|f| f.file())
}

/// One realism quantity of a plot panel.
type Quantity = fn(&RealismMeans) -> f64;

/// The realism-weight sweep: each weight a setting of its method.
impl crate::report::experiment::ExperimentView for TradeoffReport {
    fn case_views(&self) -> Vec<crate::report::experiment::CaseView> {
        self.cases
            .iter()
            .map(|t| {
                let c = &t.case;
                let method = match t.w_real {
                    Some(w) => format!("{} w_real {w}", c.method.name()),
                    None => c.method.name().to_owned(),
                };
                crate::report::experiment::CaseView::of_stats(&c.scenario, &c.vut, method, c.style, c.tau_s, &c.stats)
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing)]

    use super::*;
    use v2t_model::realism::ManoeuvreClass;

    fn point(method: Method, w_real: Option<f64>, error: f64, w1: f64) -> TradeoffPoint {
        let means = RealismMeans {
            w1_accel_mps2: w1,
            w1_jerk_mps3: 2.0 * w1,
            w1_yaw_rate_radps: 0.01,
            jerk_rms_mps3: 1.0,
            speed_reversals: 0.0,
        };
        TradeoffPoint {
            w_real,
            method,
            errors: Vec::new(),
            worst_mean_error_rel: error,
            collisions: 0,
            runs: 4,
            realism: vec![(
                "cut_in".into(),
                Some(RealismStats { class: ManoeuvreClass::LaneChange, runs: 4, measured: 4, means: Some(means) }),
            )],
            worst_by_scenario: vec![("cut_in".into(), error)],
        }
    }

    /// The front has a plot per realism quantity, a line per regulated method through its weights
    /// (each point labelled with its weight) and Diffusion-only as one point; a scenario whose BV
    /// has no measured realism has none.
    #[test]
    fn the_front_plots_each_method_through_its_weights() {
        let r = TradeoffReport {
            provenance: String::new(),
            seeds: [6, 8],
            taus_s: vec![2.0],
            weights: vec![0.0, 1.0],
            points: vec![
                point(Method::DiffusionOnly, None, 0.4, 0.2),
                point(Method::TroublemakerLike, Some(0.0), 0.05, 0.9),
                point(Method::TroublemakerLike, Some(1.0), 0.08, 0.6),
                point(Method::Video2track, Some(0.0), 0.04, 0.5),
                point(Method::Video2track, Some(1.0), 0.06, 0.3),
            ],
            cases: Vec::new(),
        };
        let front = svg(&r, "cut_in").unwrap();
        assert!(front.starts_with("<svg") && front.contains("seeds 6–8"), "{front}");
        assert_eq!(front.matches("class=\"series\"").count(), 2 * 3, "2 plots × (2 methods and Diffusion-only)");
        for part in [
            ">W₁ acceleration (m/s²)<",
            ">W₁ jerk (m/s³)<",
            ">worst VUT model&#39;s mean steering error in this scenario (%)<",
            ">TroubleMaker-like<",
            ">Video2Track<",
            ">Diffusion-only<",
        ] {
            assert!(front.contains(part), "`{part}` missing");
        }
        assert_eq!(front.matches("class=\"pointlabel\"").count(), 2 * 4, "every regulated point with its weight");
        assert!(svg(&r, "left_turn").is_none(), "no realism measured there: no front");
    }
}
