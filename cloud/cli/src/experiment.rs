//! `video2track experiment`: the paper's research questions in the simulated proving ground.
//!
//! `steerability`: for every scenario, style, target τ and VUT model, `repeats` seeded noisy runs
//! with the regulated BV; per case the mean of the per-run PET_min, the minimum over runs
//! (`PET^min_track`), the steering error `|mean − τ| / τ`, collisions, zone overlaps and the
//! fraction of runs with the order the style asks for.

use serde::Serialize;
use v2t_game::regulator::RegulatorParams;
use v2t_game::sim::RegulatedBv;
use v2t_model::Style;
use v2t_sim::bv::BvController;
use v2t_sim::runner::run;
use v2t_sim::scenario::Scenario;
use v2t_sim::vut::VutModel;

/// Targets of the steerability experiment, s.
pub const STEER_TAUS_S: [f64; 5] = [1.5, 2.0, 3.0, 4.0, 5.0];

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
    /// Runs.
    pub repeats: usize,
    /// Mean over runs of PET_min, s (runs without a measured PET are excluded and counted below).
    pub mean_pet_min_s: Option<f64>,
    /// Smallest PET_min over runs, s.
    pub pet_min_track_s: Option<f64>,
    /// `|mean − τ| / τ`.
    pub error_rel: Option<f64>,
    /// Runs with a collision.
    pub collisions: usize,
    /// Runs in which both vehicles were in the zone at once.
    pub zone_overlaps: usize,
    /// Fraction of runs in which the order matched the style.
    pub order_ok_frac: f64,
    /// Runs without a measured PET (the second vehicle never came).
    pub unmeasured: usize,
}

/// The whole experiment.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SteerReport {
    /// Every case.
    pub cases: Vec<SteerCase>,
    /// Mean of the per-case steering errors.
    pub mean_error_rel: f64,
    /// Largest per-case steering error.
    pub max_error_rel: f64,
}

/// `settings` with BV `bv_index`'s and the VUT's limits from `scenario`.
fn params_for(settings: &RegulatorParams, scenario: &Scenario, bv_index: usize) -> RegulatorParams {
    match RegulatedBv::limits_for(scenario, bv_index) {
        Some((bv, vut)) => settings.with_limits(bv, vut),
        None => *settings,
    }
}

/// One case: `repeats` runs with seeds `1..=repeats`, the regulator configured by `settings`.
pub fn steer_case(
    settings: &RegulatorParams,
    scenario: &Scenario,
    style: Style,
    tau_s: f64,
    model: VutModel,
    repeats: usize,
) -> SteerCase {
    let mut pets = Vec::new();
    let (mut collisions, mut overlaps, mut order_ok, mut unmeasured) = (0, 0, 0, 0);
    for seed in 1..=repeats as u64 {
        // Parameters come from validated vehicle files, so building cannot fail; if it did, the
        // run would count as one without a measured PET.
        let Ok(mut bvs) = scenario
            .bvs
            .iter()
            .enumerate()
            .map(|(i, _)| {
                RegulatedBv::new(params_for(settings, scenario, i), tau_s, style)
                    .map(|r| Box::new(r) as Box<dyn BvController>)
            })
            .collect::<Result<Vec<_>, _>>()
        else {
            unmeasured += 1;
            continue;
        };
        let mut driver = model.driver();
        let mut sc = scenario.clone();
        sc.style = style;
        sc.tau_s = tau_s;
        let Ok(out) = run(&sc, &mut bvs, driver.as_mut(), seed) else { continue };
        let r = out.result;
        collisions += usize::from(r.collision.is_some());
        overlaps += usize::from(r.zone_overlap);
        order_ok += usize::from(r.conflicts.iter().all(|c| c.order_matches_style == Some(true)));
        match r.pet_min_s {
            Some(p) => pets.push(p),
            None => unmeasured += 1,
        }
    }
    let mean = (!pets.is_empty()).then(|| pets.iter().sum::<f64>() / pets.len() as f64);
    SteerCase {
        scenario: scenario.name.clone(),
        style,
        vut: model.to_string(),
        tau_s,
        repeats,
        mean_pet_min_s: mean,
        pet_min_track_s: pets.iter().copied().reduce(f64::min),
        error_rel: mean.map(|m| (m - tau_s).abs() / tau_s),
        collisions,
        zone_overlaps: overlaps,
        order_ok_frac: if repeats == 0 { 0.0 } else { order_ok as f64 / repeats as f64 },
        unmeasured,
    }
}

/// `f` of every job, in order, on up to 8 of the available cores (contiguous chunks). A chunk
/// whose thread panicked contributes nothing.
pub fn parallel_map<T: Sync, R: Send>(jobs: &[T], f: impl Fn(&T) -> R + Sync) -> Vec<R> {
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get()).clamp(1, 8);
    let chunk = jobs.len().div_ceil(threads).max(1);
    let f = &f;
    std::thread::scope(|s| {
        let handles: Vec<_> =
            jobs.chunks(chunk).map(|part| s.spawn(move || part.iter().map(f).collect::<Vec<R>>())).collect();
        handles.into_iter().flat_map(|h| h.join().unwrap_or_default()).collect()
    })
}

/// Runs every case on the available cores.
pub fn steerability(
    settings: &RegulatorParams,
    scenarios: &[Scenario],
    taus: &[f64],
    models: &[VutModel],
    repeats: usize,
) -> SteerReport {
    let mut jobs = Vec::new();
    for sc in scenarios {
        for style in [Style::Rush, Style::Yield] {
            for &tau in taus {
                for &m in models {
                    jobs.push((sc, style, tau, m));
                }
            }
        }
    }
    let mut cases = parallel_map(&jobs, |(sc, st, tau, m)| steer_case(settings, sc, *st, *tau, *m, repeats));
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
            f(c.mean_pet_min_s),
            f(c.pet_min_track_s),
            c.error_rel.map_or_else(|| "—".to_owned(), |e| format!("{:.1} %", 100.0 * e)),
            c.collisions,
            c.zone_overlaps,
            c.order_ok_frac,
            c.unmeasured
        ));
    }
    let runs: usize = r.cases.iter().map(|c| c.repeats).sum();
    let total = |f: fn(&SteerCase) -> usize| r.cases.iter().map(f).sum::<usize>();
    out.push_str(&format!(
        "\nmean error {:.1} %, max error {:.1} %; {} runs: {} collisions, {} zone overlaps, {} without a measured PET\n",
        100.0 * r.mean_error_rel,
        100.0 * r.max_error_rel,
        runs,
        total(|c| c.collisions),
        total(|c| c.zone_overlaps),
        total(|c| c.unmeasured)
    ));
    out
}
