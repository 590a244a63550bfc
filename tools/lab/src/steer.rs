//! `video2track experiment steerability`: the regulator alone on scenario cards.
//!
//! For every scenario, style, target τ and VUT model, `repeats` seeded noisy runs with the
//! regulated BV; per case the statistics of [`crate::stats`] and the steering error
//! `|meanPET^min − τ| / τ`.

use serde::Serialize;
use v2t_game::regulator::RegulatorParams;
use v2t_model::{Style, Target};
use v2t_sim::bv::BvController;
use v2t_sim::runner::run;
use v2t_sim::scenario::Scenario;
use v2t_sim::vut::VutModel;

use crate::controllers::RegulatedBv;
use crate::stats::{RunStats, Tally};

/// Targets τ of the steerability experiment, s.
pub const STEER_TAUS_S: [f64; 5] = [1.5, 2.0, 3.0, 4.0, 5.0];

/// Every τ of `taus_s` in both styles (rush first); a τ out of range is left out.
pub fn both_styles(taus_s: &[f64]) -> Vec<Target> {
    taus_s.iter().flat_map(|&t| Style::ALL.map(|s| Target::new(t, s).ok())).flatten().collect()
}

/// One case of the steerability experiment.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SteerCase {
    /// Scenario name.
    pub scenario: String,
    /// Style.
    pub style: Style,
    /// VUT model.
    pub vut: String,
    /// Target PET, s.
    pub tau_s: f64,
    /// What the runs measured.
    #[serde(flatten)]
    pub stats: RunStats,
    /// `|meanPET^min − τ| / τ`.
    pub error_rel: Option<f64>,
}

/// The whole experiment.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SteerReport {
    /// Every case.
    pub cases: Vec<SteerCase>,
    /// Mean of the per-case steering errors (a case without a measured PET counts as 1).
    pub mean_error_rel: f64,
    /// Largest per-case steering error.
    pub max_error_rel: f64,
}

/// One case: one run per seed, every BV regulated by `settings` (with the
/// scenario's vehicle limits) towards `target`.
pub fn steer_case(
    settings: &RegulatorParams,
    scenario: &Scenario,
    target: Target,
    model: VutModel,
    seeds: std::ops::RangeInclusive<u64>,
) -> SteerCase {
    let mut tally = Tally::default();
    let mut sc = scenario.clone();
    sc.target = target;
    for seed in seeds {
        let bvs: Result<Vec<Box<dyn BvController>>, _> = (0..sc.bvs.len())
            .map(|i| {
                RegulatedBv::new(RegulatedBv::params_for(settings, &sc, i), &sc, i)
                    .map(|r| Box::new(r) as Box<dyn BvController>)
            })
            .collect();
        let Ok(mut bvs) = bvs else {
            tally.add_failed();
            continue;
        };
        match run(&sc, &mut bvs, model.driver().as_mut(), seed) {
            Ok(out) => tally.add(&out.result),
            Err(_) => tally.add_failed(),
        }
    }
    let stats = tally.stats();
    SteerCase {
        scenario: scenario.name.clone(),
        style: target.style(),
        vut: model.to_string(),
        tau_s: target.tau_s(),
        error_rel: stats.error_rel(target.tau_s()),
        stats,
    }
}

/// Runs every case (scenario × target × VUT model) on the available cores.
pub fn steerability(
    settings: &RegulatorParams,
    scenarios: &[Scenario],
    targets: &[Target],
    models: &[VutModel],
    seeds: std::ops::RangeInclusive<u64>,
) -> SteerReport {
    let mut jobs = Vec::new();
    for sc in scenarios {
        for &target in targets {
            for &m in models {
                jobs.push((sc, target, m));
            }
        }
    }
    let mut cases = crate::parallel_map(&jobs, |(sc, target, m)| steer_case(settings, sc, *target, *m, seeds.clone()));
    cases.sort_by(|a, b| {
        (&a.scenario, a.style as u8, a.tau_s.to_bits(), &a.vut).cmp(&(
            &b.scenario,
            b.style as u8,
            b.tau_s.to_bits(),
            &b.vut,
        ))
    });
    let errs: Vec<f64> = cases.iter().map(|c| c.error_rel.unwrap_or(1.0)).collect();
    SteerReport {
        mean_error_rel: if errs.is_empty() { 0.0 } else { errs.iter().sum::<f64>() / errs.len() as f64 },
        max_error_rel: errs.iter().copied().fold(0.0, f64::max),
        cases,
    }
}

/// A markdown table of the report.
pub fn steer_markdown(r: &SteerReport) -> String {
    let mut out = String::from(
        "| scenario | style | VUT | τ (s) | mean PET_min (s) | PET^min_track (s) | error | collisions | overlaps | order ok | no PET |\n|---|---|---|---|---|---|---|---|---|---|---|\n",
    );
    let f = |x: Option<f64>| x.map_or_else(|| "—".to_owned(), |v| format!("{v:.2}"));
    for c in &r.cases {
        out.push_str(&format!(
            "| {} | {} | {} | {:.1} | {} | {} | {} | {} | {} | {:.2} | {} |\n",
            c.scenario,
            c.style,
            c.vut,
            c.tau_s,
            f(c.stats.mean_pet_min_s),
            f(c.stats.pet_min_track_s),
            c.error_rel.map_or_else(|| "—".to_owned(), |e| format!("{:.1} %", 100.0 * e)),
            c.stats.collisions,
            c.stats.zone_overlaps,
            c.stats.order_ok_frac,
            c.stats.unmeasured
        ));
    }
    let runs: usize = r.cases.iter().map(|c| c.stats.repeats).sum();
    let total = |f: fn(&SteerCase) -> usize| r.cases.iter().map(f).sum::<usize>();
    out.push_str(&format!(
        "\nmean error {:.1} %, max error {:.1} %; {} runs: {} collisions, {} zone overlaps, {} without a measured PET\n",
        100.0 * r.mean_error_rel,
        100.0 * r.max_error_rel,
        runs,
        total(|c| c.stats.collisions),
        total(|c| c.stats.zone_overlaps),
        total(|c| c.stats.unmeasured)
    ));
    out
}
