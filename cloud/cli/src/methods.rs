//! `video2track experiment adversariality|fidelity|style`: the paper's four methods (Section 4.1.2)
//! on the two recorded scenarios in the simulated proving ground (sensor noise, delays, actuator
//! lag), every VUT model, seeded runs.
//!
//! For each scenario the recorded semantics are grounded on the proving ground with the
//! experiment's target τ and style, then:
//!
//! - **Predefined**: the BV follows the constant-speed trajectory along its grounded route whose
//!   timing gives τ if the VUT keeps its speed (no adaptation);
//! - **TroubleMaker-like**: the Stackelberg regulator along that constant-speed reference;
//! - **Diffusion-only**: the BV follows the guided diffusion prior (best of 8 variants);
//! - **Video2Track**: the regulator along the diffusion prior.
//!
//! The VUT starts where the prior puts it and drives its route with the chosen driver model. The
//! conflict measured is the prior's (the zone nearest the grounded conflict point).
//!
//! - `adversariality`: rush, τ = 1.5 s; per method the mean PET_min over runs (lower is more
//!   adversarial) and collisions.
//! - `fidelity`: the recorded style and τ = the video's PET label; `PET^min_track` (minimum over
//!   runs) against the label.
//! - `style`: rush and yield at τ = the video's PET label; the share of runs in the asked order.
//! - `steerability --methods`: rush and yield at every τ (1.5–5 s); per method the steering error
//!   `|meanPET^min − τ| / τ`.

use serde::Serialize;
use v2t_game::regulator::RegulatorParams;
use v2t_game::sim::RegulatedBv;
use v2t_model::Style;
use v2t_model::grounded::{AgentRole, GroundedScenario};
use v2t_model::metrics::{ConflictOptions, conflict_zones, nearest_zone};
use v2t_model::path::ReferencePath;
use v2t_model::prior::TrajectoryPrior;
use v2t_model::semantics::ScenarioSemantics;
use v2t_model::vehicle::VehicleConfig;
use v2t_sim::bv::{BvController, ReferenceFollower};
use v2t_sim::config::SimSettings;
use v2t_sim::runner::run;
use v2t_sim::scenario::{Scenario, ScenarioPaths, SpeedProfile};
use v2t_sim::vut::VutModel;

/// The four methods.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Method {
    /// Fixed constant-speed trajectory, no adaptation.
    Predefined,
    /// Regulation along the constant-speed reference.
    TroublemakerLike,
    /// The diffusion prior, followed.
    DiffusionOnly,
    /// The diffusion prior, regulated.
    Video2track,
}

impl Method {
    /// All four, in the paper's order.
    pub const ALL: [Self; 4] = [Self::Predefined, Self::TroublemakerLike, Self::DiffusionOnly, Self::Video2track];

    /// Name in tables.
    pub fn name(self) -> &'static str {
        match self {
            Self::Predefined => "Predefined",
            Self::TroublemakerLike => "TroubleMaker-like",
            Self::DiffusionOnly => "Diffusion-only",
            Self::Video2track => "Video2Track",
        }
    }

    fn diffusion(self) -> bool {
        matches!(self, Self::DiffusionOnly | Self::Video2track)
    }

    fn regulated(self) -> bool {
        matches!(self, Self::TroublemakerLike | Self::Video2track)
    }
}

/// Which comparison.
#[derive(Debug, Clone, PartialEq)]
pub enum Comparison {
    /// Rush and yield at each of these τ.
    Steerability(Vec<f64>),
    /// Rush at τ = 1.5 s.
    Adversariality,
    /// The video's style at its PET label.
    Fidelity,
    /// Rush and yield at the video's PET label.
    Style,
}

impl Comparison {
    /// The (τ, style) targets of `rec`.
    pub fn targets(&self, rec: &Recorded) -> Vec<(f64, Style)> {
        let label = rec.semantics.pet_label_s;
        match self {
            Self::Steerability(taus) => taus.iter().flat_map(|t| [(*t, Style::Rush), (*t, Style::Yield)]).collect(),
            Self::Adversariality => vec![(1.5, Style::Rush)],
            Self::Fidelity => vec![(label, rec.semantics.interacting_bvs.first().map_or(Style::Rush, |b| b.style))],
            Self::Style => vec![(label, Style::Rush), (label, Style::Yield)],
        }
    }
}

/// One recorded scenario of the experiments.
#[derive(Debug, Clone)]
pub struct Recorded {
    /// Name.
    pub name: String,
    /// The semantics (from the replayed cassette).
    pub semantics: ScenarioSemantics,
}

/// One case: scenario × method × style × τ × VUT model.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MethodCase {
    /// Scenario.
    pub scenario: String,
    /// Method.
    pub method: Method,
    /// Style.
    pub style: Style,
    /// Target τ, s.
    pub tau_s: f64,
    /// VUT model.
    pub vut: String,
    /// Runs.
    pub repeats: usize,
    /// Mean PET_min over runs with a measured PET, s.
    pub mean_pet_min_s: Option<f64>,
    /// Smallest PET_min, s.
    pub pet_min_track_s: Option<f64>,
    /// Runs with a collision.
    pub collisions: usize,
    /// Share of runs in the style's order.
    pub order_ok_frac: f64,
    /// Runs without a measured PET.
    pub unmeasured: usize,
}

/// What the experiments need besides the scenarios.
#[derive(Debug)]
pub struct Setup<'a> {
    /// The proving ground and its topology library.
    pub inspection: &'a crate::map::Inspection,
    /// The diffusion model.
    pub model: &'a v2t_diffusion::weights::Model,
    /// Regulator settings.
    pub regulator: RegulatorParams,
    /// Simulation settings (noise, delays, lag).
    pub sim: SimSettings,
    /// VUT and BV vehicles.
    pub vut_vehicle: VehicleConfig,
    /// BV vehicle.
    pub bv_vehicle: VehicleConfig,
}

/// An agent's path (standstills dropped), speed profile and start speed.
fn trajectory_path(prior: &TrajectoryPrior, id: &str) -> Result<(ReferencePath, Vec<[f64; 2]>, f64), String> {
    let a = prior.agents.iter().find(|a| a.id == id).ok_or_else(|| format!("prior has no agent `{id}`"))?;
    let path = ReferencePath::through_states(&a.states).map_err(|e| format!("{id}: {e}"))?;
    let profile = a.states.iter().enumerate().map(|(k, x)| [k as f64 * prior.dt_s, x.speed_mps.max(0.0)]).collect();
    Ok((path, profile, a.states.first().map_or(0.0, |x| x.speed_mps)))
}

/// The simulated world of a prior: the first conflict's BV on its prior path and timing, the VUT
/// from its prior start on its prior path, the zone nearest the grounded conflict point.
pub fn scenario_of_prior(
    name: &str,
    prior: &TrajectoryPrior,
    grounded: &GroundedScenario,
    setup: &Setup<'_>,
) -> Result<Scenario, String> {
    let conflict = grounded.conflicts.first().ok_or("no conflict")?;
    let vut_id = grounded.agents.iter().find(|a| a.role == AgentRole::Vut).map(|a| a.id.clone()).ok_or("no VUT")?;
    let (vut_route, _, vut_speed) = trajectory_path(prior, &vut_id)?;
    let (bv_route, profile, _) = trajectory_path(prior, &conflict.bv_id)?;
    let dims = |v: &VehicleConfig| v2t_model::metrics::Dimensions {
        length_m: v.geometry.length_m,
        width_m: v.geometry.width_m,
    };
    let zones = conflict_zones(
        &vut_route,
        dims(&setup.vut_vehicle),
        &bv_route,
        dims(&setup.bv_vehicle),
        &ConflictOptions::default(),
    );
    let zone = nearest_zone(zones, Some(conflict.point)).ok_or("the prior's paths share no conflict zone")?;
    let paths = ScenarioPaths {
        name: name.to_owned(),
        tau_s: prior.tau_s,
        style: prior.style,
        duration_s: prior.duration_s() + 2.0,
        vut_route,
        vut_speed_mps: vut_speed,
        vut_model: VutModel::IdmNormal,
        bv_id: conflict.bv_id.clone(),
        bv_route,
        bv_reference: SpeedProfile::new(profile),
        conflict: Some(zone),
    };
    Scenario::from_paths(paths, setup.sim.clone(), setup.vut_vehicle.clone(), setup.bv_vehicle.clone())
        .map_err(|e| e.to_string())
}

/// The grounded scenario and the two priors (constant speed, diffusion) of `rec` at `tau_s` and
/// `style`.
pub fn priors(
    rec: &Recorded,
    tau_s: f64,
    style: Style,
    setup: &Setup<'_>,
    seed: u64,
) -> Result<(GroundedScenario, TrajectoryPrior, TrajectoryPrior), String> {
    let mut sem = rec.semantics.clone();
    sem.pet_label_s = tau_s;
    for b in &mut sem.interacting_bvs {
        b.style = style;
    }
    let g = v2t_ground::ground(&setup.inspection.map, &setup.inspection.library, &sem).map_err(|e| e.to_string())?;
    let grounded = g.scenario;
    let stand_in = crate::link::stand_in_prior(&grounded)?;
    let options = v2t_diffusion::generate::GenerateOptions {
        variants: crate::demo::VARIANTS,
        seed,
        ..v2t_diffusion::generate::GenerateOptions::default()
    };
    let (variants, _) = v2t_diffusion::generate::generate(setup.model, &setup.inspection.map, &grounded, &options)
        .map_err(|e| e.to_string())?;
    let best = crate::generate::best(&variants).ok_or("no diffusion variant")?.prior.clone();
    Ok((grounded, stand_in, best))
}

/// `repeats` seeded runs of one method on `scenario`.
pub fn run_case(setup: &Setup<'_>, scenario: &Scenario, method: Method, model: VutModel, repeats: usize) -> MethodCase {
    let mut pets = Vec::new();
    let (mut collisions, mut order_ok, mut unmeasured) = (0, 0, 0);
    for seed in 1..=repeats as u64 {
        let controller: Box<dyn BvController> = if method.regulated() {
            let params = match RegulatedBv::limits_for(scenario, 0) {
                Some((bv, vut)) => setup.regulator.with_limits(bv, vut),
                None => setup.regulator,
            };
            match RegulatedBv::new(params, scenario.tau_s, scenario.style) {
                Ok(r) => Box::new(r),
                Err(_) => {
                    unmeasured += 1;
                    continue;
                }
            }
        } else {
            Box::new(ReferenceFollower::default())
        };
        let mut bvs = vec![controller];
        let mut driver = model.driver();
        let Ok(out) = run(scenario, &mut bvs, driver.as_mut(), seed) else {
            unmeasured += 1;
            continue;
        };
        let r = out.result;
        collisions += usize::from(r.collision.is_some());
        order_ok += usize::from(r.conflicts.iter().all(|c| c.order_matches_style == Some(true)));
        match r.pet_min_s {
            Some(p) => pets.push(p),
            None => unmeasured += 1,
        }
    }
    MethodCase {
        scenario: scenario.name.clone(),
        method,
        style: scenario.style,
        tau_s: scenario.tau_s,
        vut: model.to_string(),
        repeats,
        mean_pet_min_s: (!pets.is_empty()).then(|| pets.iter().sum::<f64>() / pets.len() as f64),
        pet_min_track_s: pets.iter().copied().reduce(f64::min),
        collisions,
        order_ok_frac: if repeats == 0 { 0.0 } else { order_ok as f64 / repeats as f64 },
        unmeasured,
    }
}

/// Every case of `targets` (per scenario: τ and style) × the four methods × `models`, on the
/// available cores.
pub fn run_all(
    setup: &Setup<'_>,
    recorded: &[Recorded],
    comparison: &Comparison,
    models: &[VutModel],
    repeats: usize,
) -> Result<Vec<MethodCase>, String> {
    let mut jobs = Vec::new();
    for rec in recorded {
        for (tau, style) in comparison.targets(rec) {
            let (grounded, stand_in, diffusion) = priors(rec, tau, style, setup, 1)?;
            let name = format!("{} ({:?}, τ {tau:.2} s)", rec.name, style).to_lowercase();
            let constant = scenario_of_prior(&name, &stand_in, &grounded, setup)?;
            let generated = scenario_of_prior(&name, &diffusion, &grounded, setup)?;
            for method in Method::ALL {
                let sc = if method.diffusion() { generated.clone() } else { constant.clone() };
                for &m in models {
                    jobs.push((sc.clone(), method, m));
                }
            }
        }
    }
    let cases = crate::experiment::parallel_map(&jobs, |(sc, me, m)| run_case(setup, sc, *me, *m, repeats));
    Ok(cases)
}

/// Per scenario and method: mean of the case means, smallest PET^min_track, collisions, order.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MethodSummary {
    /// Scenario.
    pub scenario: String,
    /// Method.
    pub method: Method,
    /// Style.
    pub style: Style,
    /// τ, s.
    pub tau_s: f64,
    /// Mean over VUT models of the mean PET_min, s.
    pub mean_pet_min_s: Option<f64>,
    /// Minimum over all runs, s.
    pub pet_min_track_s: Option<f64>,
    /// Runs with a collision.
    pub collisions: usize,
    /// Share of runs in the asked order.
    pub order_ok_frac: f64,
    /// Runs.
    pub runs: usize,
}

/// The summary rows of `cases`.
pub fn summarize(cases: &[MethodCase]) -> Vec<MethodSummary> {
    let mut out: Vec<MethodSummary> = Vec::new();
    for c in cases {
        let key = |s: &MethodSummary| s.scenario == c.scenario && s.method == c.method;
        if out.iter().any(key) {
            continue;
        }
        let group: Vec<&MethodCase> =
            cases.iter().filter(|d| d.scenario == c.scenario && d.method == c.method).collect();
        let means: Vec<f64> = group.iter().filter_map(|d| d.mean_pet_min_s).collect();
        let runs: usize = group.iter().map(|d| d.repeats).sum();
        out.push(MethodSummary {
            scenario: c.scenario.clone(),
            method: c.method,
            style: c.style,
            tau_s: c.tau_s,
            mean_pet_min_s: (!means.is_empty()).then(|| means.iter().sum::<f64>() / means.len() as f64),
            pet_min_track_s: group.iter().filter_map(|d| d.pet_min_track_s).reduce(f64::min),
            collisions: group.iter().map(|d| d.collisions).sum(),
            order_ok_frac: group.iter().map(|d| d.order_ok_frac * d.repeats as f64).sum::<f64>() / runs.max(1) as f64,
            runs,
        });
    }
    out
}

/// Steering error per method: `|meanPET^min − τ| / τ` over its (scenario, style, τ) rows, mean
/// and max over all of them and over τ ∈ [2, 5] s (the range).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SteeringError {
    /// Method.
    pub method: Method,
    /// Rows (scenario × style × τ).
    pub rows: usize,
    /// Mean error over all rows.
    pub mean_error_rel: f64,
    /// Largest error.
    pub max_error_rel: f64,
    /// Mean error over the rows with τ in [2, 5] s.
    pub mean_error_rel_tau_2_5: f64,
}

/// The steering errors of `rows` per method (a row without a measured PET counts as error 1).
pub fn steering_errors(rows: &[MethodSummary]) -> Vec<SteeringError> {
    Method::ALL
        .iter()
        .filter_map(|&method| {
            let errs: Vec<(f64, f64)> = rows
                .iter()
                .filter(|r| r.method == method)
                .map(|r| (r.tau_s, r.mean_pet_min_s.map_or(1.0, |m| (m - r.tau_s).abs() / r.tau_s)))
                .collect();
            if errs.is_empty() {
                return None;
            }
            let mid: Vec<f64> = errs.iter().filter(|(t, _)| (2.0..=5.0).contains(t)).map(|(_, e)| *e).collect();
            let mean = |v: &[f64]| if v.is_empty() { f64::NAN } else { v.iter().sum::<f64>() / v.len() as f64 };
            let all: Vec<f64> = errs.iter().map(|(_, e)| *e).collect();
            Some(SteeringError {
                method,
                rows: errs.len(),
                mean_error_rel: mean(&all),
                max_error_rel: all.iter().copied().fold(0.0, f64::max),
                mean_error_rel_tau_2_5: mean(&mid),
            })
        })
        .collect()
}

/// The steering errors as a markdown table.
pub fn steering_markdown(errors: &[SteeringError]) -> String {
    let mut out =
        String::from("\n| method | rows | mean steering error | max | mean, τ 2–5 s |\n|---|---|---|---|---|\n");
    for e in errors {
        out.push_str(&format!(
            "| {} | {} | {:.1} % | {:.1} % | {:.1} % |\n",
            e.method.name(),
            e.rows,
            100.0 * e.mean_error_rel,
            100.0 * e.max_error_rel,
            100.0 * e.mean_error_rel_tau_2_5
        ));
    }
    out
}

/// A markdown table of the summary, with the fidelity error against `label` (per scenario name
/// prefix) when given.
pub fn markdown(rows: &[MethodSummary], labels: &[(String, f64)]) -> String {
    let f = |v: Option<f64>| v.map_or("–".to_owned(), |x| format!("{x:.2} s"));
    let mut out = String::from(
        "| scenario | method | meanPET^min | PET^min_track | fidelity error | collisions | order as asked | runs |\n|---|---|---|---|---|---|---|---|\n",
    );
    for r in rows {
        let label = labels.iter().find(|(n, _)| r.scenario.starts_with(n.as_str())).map(|(_, l)| *l);
        let fidelity = match (r.pet_min_track_s, label) {
            (Some(p), Some(l)) if l > 0.0 => format!("{:.1} %", 100.0 * (p - l).abs() / l),
            _ => "–".into(),
        };
        out.push_str(&format!(
            "| {} | {} | {} | {} | {} | {} | {:.0} % | {} |\n",
            r.scenario,
            r.method.name(),
            f(r.mean_pet_min_s),
            f(r.pet_min_track_s),
            fidelity,
            r.collisions,
            100.0 * r.order_ok_frac,
            r.runs
        ));
    }
    out
}
