//! `video2track experiment adversariality|fidelity|style`: the paper's four methods (Section 4.1.2)
//! on the paper's scenarios (a cut-in and the unprotected left turn with the BV or the VUT
//! turning, their semantics replayed from the shipped hand-written cassettes, not from a model's
//! answer) in the simulated proving ground (sensor noise, delays, actuator lag), every VUT model,
//! seeded runs.
//!
//! For each scenario the replayed semantics are grounded on the proving ground with the
//! experiment's target τ and style, then:
//!
//! - **Predefined**: the BV follows the constant-speed trajectory along its grounded route whose
//!   timing gives τ if the VUT keeps its speed (no adaptation);
//! - **TroubleMaker-like**: the Stackelberg regulator along that constant-speed reference, its
//!   realism term (`w_real`) pulling toward the reference's timing and speed shape, running in the
//!   cloud as TroubleMaker's does: states up and plans down across [`Setup::baseline_network`]
//!   (the 5G SA preset in the shipped experiments; onboard when `None`);
//! - **Diffusion-only**: the BV follows the guided diffusion prior (best of 8 variants);
//! - **Video2Track**: the same regulator along the diffusion prior, its realism term pulling
//!   toward the prior.
//!
//! Every run's BV (and VUT) is measured against recorded human driving of its manoeuvre class when
//! [`Setup::human`] is given (the realism columns).
//!
//! The VUT starts where the prior puts it and drives its route with the chosen driver model. The
//! conflict measured is the prior's (the zone nearest the grounded conflict point).
//!
//! - `adversariality`: rush, τ = 1.5 s; per method the mean PET_min over runs (lower is more
//!   adversarial) and collisions.
//! - `fidelity`: the semantics' style and τ = the video's PET label; `PET^min_track` (minimum over
//!   runs) against the label.
//! - `style`: rush and yield at τ = the video's PET label; the share of runs in the asked order.
//! - `steerability --methods`: rush and yield at every τ (1.5–5 s); per method the steering error
//!   `|meanPET^min − τ| / τ`.

use std::ops::RangeInclusive;

use serde::Serialize;
use v2t_diffusion::weights::Model;
use v2t_game::regulator::RegulatorParams;
use v2t_map::Inspection;
use v2t_model::grounded::GroundedScenario;
use v2t_model::prior::TrajectoryPrior;
use v2t_model::realism::HumanReference;
use v2t_model::semantics::ScenarioSemantics;
use v2t_model::vehicle::VehicleConfig;
use v2t_model::{Style, Target};
use v2t_sim::bv::{BvController, ReferenceFollower};
use v2t_sim::config::SimSettings;
use v2t_sim::network::NetworkSettings;
use v2t_sim::realism::measure_run;
use v2t_sim::runner::run;
use v2t_sim::scenario::Scenario;
use v2t_sim::vut::VutModel;

use crate::controllers::{CloudRegulatedBv, RegulatedBv};
use crate::stats::{RealismStats, RunStats, Tally};
use crate::world::{self, Vehicles, WorldError};

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

    /// Whether the BV follows the diffusion prior (else the constant-speed stand-in).
    pub fn diffusion(self) -> bool {
        matches!(self, Self::DiffusionOnly | Self::Video2track)
    }

    /// Whether the regulator drives the BV (else it follows its reference).
    pub fn regulated(self) -> bool {
        matches!(self, Self::TroublemakerLike | Self::Video2track)
    }
}

/// Which comparison.
#[derive(Debug, Clone, PartialEq)]
pub enum Comparison {
    /// Each of these targets.
    Steerability(Vec<Target>),
    /// Rush at τ = 1.5 s.
    Adversariality,
    /// The video's style at its PET label.
    Fidelity,
    /// Rush and yield at the video's PET label.
    Style,
}

/// The adversariality experiment's target: rush at τ = 1.5 s (the paper's).
pub const ADVERSARIAL_TAU_S: f64 = 1.5;

impl Comparison {
    /// The targets of `rec` (the video's PET label is in range: the semantics validated it).
    pub fn targets(&self, rec: &PaperScenario) -> Vec<Target> {
        let label = |style| Target::new(rec.semantics.pet_label_s, style).ok();
        match self {
            Self::Steerability(targets) => targets.clone(),
            Self::Adversariality => Target::new(ADVERSARIAL_TAU_S, Style::Rush).ok().into_iter().collect(),
            Self::Fidelity => {
                label(rec.semantics.interacting_bvs.first().map_or(Style::Rush, |b| b.style)).into_iter().collect()
            }
            Self::Style => Style::ALL.into_iter().filter_map(label).collect(),
        }
    }
}

/// One of the paper's scenarios as the experiments take it: the semantics its hand-written
/// cassette replays to.
#[derive(Debug, Clone)]
pub struct PaperScenario {
    /// Name.
    pub name: String,
    /// The semantics (from the replayed cassette).
    pub semantics: ScenarioSemantics,
}

/// Why the comparison could not be set up.
#[derive(Debug, thiserror::Error)]
pub enum MethodsError {
    /// The semantics do not ground on the proving ground.
    #[error("{scenario}: grounding: {source}")]
    Ground {
        /// The scenario.
        scenario: String,
        /// Why.
        source: v2t_ground::GroundError,
    },
    /// The grounded scenario has no stand-in prior.
    #[error("{scenario}: stand-in prior: {source}")]
    StandIn {
        /// The scenario.
        scenario: String,
        /// Why.
        source: v2t_model::validate::ValidationError,
    },
    /// The diffusion model failed.
    #[error("{scenario}: diffusion prior: {source}")]
    Generate {
        /// The scenario.
        scenario: String,
        /// Why.
        source: v2t_diffusion::generate::GenerateError,
    },
    /// A prior makes no world.
    #[error("{scenario}: {source}")]
    World {
        /// The scenario.
        scenario: String,
        /// Why.
        source: WorldError,
    },
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
    /// What the runs measured.
    #[serde(flatten)]
    pub stats: RunStats,
}

/// What the experiments need besides the scenarios.
#[derive(Debug)]
pub struct Setup<'a> {
    /// The proving ground and its topology library.
    pub inspection: &'a Inspection,
    /// The diffusion model.
    pub model: &'a Model,
    /// Regulator settings.
    pub regulator: RegulatorParams,
    /// Simulation settings (noise, delays, lag).
    pub sim: SimSettings,
    /// The VUT's vehicle.
    pub vut_vehicle: VehicleConfig,
    /// The BV's vehicle.
    pub bv_vehicle: VehicleConfig,
    /// Recorded human driving per manoeuvre class: every run's realism is measured against it
    /// (`None`: not measured).
    pub human: Option<&'a HumanReference>,
    /// The network TroubleMaker-like's cloud regulator works across (`None`: it runs onboard).
    pub baseline_network: Option<NetworkSettings>,
}

/// The simulated world of a prior for the first conflict's BV ([`world::accept`], then
/// [`world::from_prior`]: as the BV accepts and decodes it).
pub fn scenario_of_prior(
    name: &str,
    prior: &TrajectoryPrior,
    grounded: &GroundedScenario,
    setup: &Setup<'_>,
) -> Result<Scenario, WorldError> {
    let vehicles = Vehicles { bv: &setup.bv_vehicle, vut: &setup.vut_vehicle };
    let bv_agent = grounded.conflicts.first().map(|c| c.bv_id.as_str());
    let accepted = world::accept(prior, bv_agent, vehicles, 1, 0)?;
    world::from_prior(name, &accepted, vehicles, setup.sim.clone(), VutModel::IdmNormal)
}

/// The grounded scenario and the two priors (the constant-speed stand-in, the best diffusion
/// variant) of `rec` at `target`.
pub fn priors(
    rec: &PaperScenario,
    target: Target,
    setup: &Setup<'_>,
    seed: u64,
) -> Result<(GroundedScenario, TrajectoryPrior, TrajectoryPrior), MethodsError> {
    let scenario = || rec.name.clone();
    let options = v2t_ground::GroundOptions { target: Some(target), ..v2t_ground::GroundOptions::default() };
    let grounded = v2t_ground::ground_with(&setup.inspection.map, &setup.inspection.library, &rec.semantics, &options)
        .map_err(|source| MethodsError::Ground { scenario: scenario(), source })?
        .scenario;
    let stand_in = TrajectoryPrior::stand_in(&grounded)
        .map_err(|source| MethodsError::StandIn { scenario: scenario(), source })?;
    let options = v2t_diffusion::generate::GenerateOptions {
        variants: crate::demo::VARIANTS,
        seed,
        ..v2t_diffusion::generate::GenerateOptions::default()
    };
    let (variants, _) = v2t_diffusion::generate::generate(setup.model, &setup.inspection.map, &grounded, &options)
        .map_err(|source| MethodsError::Generate { scenario: scenario(), source })?;
    let best = v2t_diffusion::generate::best(&variants)
        .ok_or_else(|| MethodsError::Generate {
            scenario: scenario(),
            source: v2t_diffusion::generate::GenerateError::NoVariant,
        })?
        .prior
        .clone();
    Ok((grounded, stand_in, best))
}

/// The seeded runs of one method on `scenario`, one per seed, with the regulator settings of
/// `setup`.
pub fn run_case(
    setup: &Setup<'_>,
    scenario: &Scenario,
    method: Method,
    model: VutModel,
    seeds: RangeInclusive<u64>,
) -> MethodCase {
    let cloud = if method == Method::TroublemakerLike { setup.baseline_network.as_ref() } else { None };
    run_case_with(setup, &setup.regulator, cloud, scenario, method, model, seeds)
}

/// [`run_case`] with other regulator settings, the regulator in the cloud across `cloud` when
/// given (else onboard).
pub fn run_case_with(
    setup: &Setup<'_>,
    regulator: &RegulatorParams,
    cloud: Option<&NetworkSettings>,
    scenario: &Scenario,
    method: Method,
    model: VutModel,
    seeds: RangeInclusive<u64>,
) -> MethodCase {
    let mut tally = Tally::default();
    for seed in seeds {
        let params = RegulatedBv::params_for(regulator, scenario, 0);
        let controller: Option<Box<dyn BvController>> = match (method.regulated(), cloud) {
            (false, _) => Some(Box::new(ReferenceFollower::default())),
            (true, None) => RegulatedBv::new(params, scenario, 0).ok().map(|r| Box::new(r) as Box<dyn BvController>),
            (true, Some(net)) => {
                CloudRegulatedBv::new(params, scenario, 0, net, seed).ok().map(|r| Box::new(r) as Box<dyn BvController>)
            }
        };
        let Some(controller) = controller else {
            tally.add_failed();
            continue;
        };
        let mut bvs = vec![controller];
        match run(scenario, &mut bvs, model.driver().as_mut(), seed) {
            Ok(out) => {
                tally.add(&out.result);
                if let Some(realism) = setup.human.and_then(|h| measure_run(scenario, &out, h).ok()) {
                    tally.add_realism(&realism);
                }
            }
            Err(_) => tally.add_failed(),
        }
    }
    MethodCase {
        scenario: scenario.name.clone(),
        method,
        style: scenario.target.style(),
        tau_s: scenario.target.tau_s(),
        vut: model.to_string(),
        stats: tally.stats(),
    }
}

/// Every case of `targets` (per scenario: τ and style) × the four methods × `models`, on the
/// available cores.
pub fn run_all(
    setup: &Setup<'_>,
    scenarios: &[PaperScenario],
    comparison: &Comparison,
    models: &[VutModel],
    seeds: RangeInclusive<u64>,
) -> Result<Vec<MethodCase>, MethodsError> {
    let mut jobs = Vec::new();
    for rec in scenarios {
        for target in comparison.targets(rec) {
            let (grounded, stand_in, diffusion) = priors(rec, target, setup, 1)?;
            let name = format!("{} ({}, τ {:.2} s)", rec.name, target.style(), target.tau_s());
            let world = |prior: &TrajectoryPrior| {
                scenario_of_prior(&name, prior, &grounded, setup)
                    .map_err(|source| MethodsError::World { scenario: name.clone(), source })
            };
            let constant = world(&stand_in)?;
            let generated = world(&diffusion)?;
            for method in Method::ALL {
                let sc = if method.diffusion() { generated.clone() } else { constant.clone() };
                for &m in models {
                    jobs.push((sc.clone(), method, m));
                }
            }
        }
    }
    let cases = crate::parallel_map(&jobs, |(sc, me, m)| run_case(setup, sc, *me, *m, seeds.clone()));
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
    /// How human the BV's motion was, over every run of the row (all VUT models).
    pub bv_realism: Option<RealismStats>,
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
        let means: Vec<f64> = group.iter().filter_map(|d| d.stats.mean_pet_min_s).collect();
        let runs: usize = group.iter().map(|d| d.stats.repeats).sum();
        out.push(MethodSummary {
            scenario: c.scenario.clone(),
            method: c.method,
            style: c.style,
            tau_s: c.tau_s,
            mean_pet_min_s: (!means.is_empty()).then(|| means.iter().sum::<f64>() / means.len() as f64),
            pet_min_track_s: group.iter().filter_map(|d| d.stats.pet_min_track_s).reduce(f64::min),
            collisions: group.iter().map(|d| d.stats.collisions).sum(),
            order_ok_frac: group.iter().map(|d| d.stats.order_ok_frac * d.stats.repeats as f64).sum::<f64>()
                / runs.max(1) as f64,
            runs,
            bv_realism: RealismStats::pool(group.iter().filter_map(|d| d.stats.bv_realism.as_ref())),
        });
    }
    out
}

/// Steering error per method and VUT model: `|meanPET^min − τ| / τ` per case (scenario, style, τ
/// and one VUT model: the mean is over that model's runs only), mean and max over the cases of the
/// model, and over τ ∈ [2, 5] s. Never pooled across models: an overshoot against one model and an
/// undershoot against another do not cancel.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SteeringError {
    /// Method.
    pub method: Method,
    /// The VUT model.
    pub vut: String,
    /// Cases (scenario × style × τ).
    pub rows: usize,
    /// Mean error over the cases.
    pub mean_error_rel: f64,
    /// Largest error.
    pub max_error_rel: f64,
    /// Mean error over the cases with τ in [2, 5] s.
    pub mean_error_rel_tau_2_5: f64,
}

/// The steering errors of `cases` per method and VUT model (a case without a measured PET counts
/// as error 1).
pub fn steering_errors(cases: &[MethodCase]) -> Vec<SteeringError> {
    let mut vuts: Vec<&str> = cases.iter().map(|c| c.vut.as_str()).collect();
    vuts.sort_unstable();
    vuts.dedup();
    let mut out = Vec::new();
    for method in Method::ALL {
        for &vut in &vuts {
            let errs: Vec<(f64, f64)> = cases
                .iter()
                .filter(|c| c.method == method && c.vut == vut)
                .map(|c| (c.tau_s, c.stats.error_rel(c.tau_s).unwrap_or(1.0)))
                .collect();
            if errs.is_empty() {
                continue;
            }
            let mid: Vec<f64> = errs.iter().filter(|(t, _)| (2.0..=5.0).contains(t)).map(|(_, e)| *e).collect();
            let mean = |v: &[f64]| if v.is_empty() { f64::NAN } else { v.iter().sum::<f64>() / v.len() as f64 };
            let all: Vec<f64> = errs.iter().map(|(_, e)| *e).collect();
            out.push(SteeringError {
                method,
                vut: vut.to_owned(),
                rows: errs.len(),
                mean_error_rel: mean(&all),
                max_error_rel: all.iter().copied().fold(0.0, f64::max),
                mean_error_rel_tau_2_5: mean(&mid),
            });
        }
    }
    out
}

/// The steering errors as a markdown table: per method one row per VUT model, then the largest
/// per-model mean (the figure a method is judged by; never a mean pooled over models).
pub fn steering_markdown(errors: &[SteeringError]) -> String {
    let mut out = String::from(
        "\nSteering error per method and VUT model (each case's mean PET over that model's runs only; never pooled across models):\n\n| method | VUT | cases | mean steering error | max | mean, τ 2–5 s |\n|---|---|---|---|---|---|\n",
    );
    for method in Method::ALL {
        let mine: Vec<&SteeringError> = errors.iter().filter(|e| e.method == method).collect();
        for e in &mine {
            out.push_str(&format!(
                "| {} | {} | {} | {:.1} % | {:.1} % | {:.1} % |\n",
                e.method.name(),
                e.vut,
                e.rows,
                100.0 * e.mean_error_rel,
                100.0 * e.max_error_rel,
                100.0 * e.mean_error_rel_tau_2_5
            ));
        }
        let worst = |f: fn(&SteeringError) -> f64| mine.iter().map(|e| f(e)).fold(0.0, f64::max);
        if mine.len() > 1 {
            out.push_str(&format!(
                "| {} | **worst model** | | {:.1} % | {:.1} % | {:.1} % |\n",
                method.name(),
                100.0 * worst(|e| e.mean_error_rel),
                100.0 * worst(|e| e.max_error_rel),
                100.0 * worst(|e| e.mean_error_rel_tau_2_5)
            ));
        }
    }
    out
}

/// A markdown table of the summary, with the fidelity error against `label` (per scenario name
/// prefix) when given, and the BV's realism (W₁ to recorded human driving of its manoeuvre class).
pub fn markdown(rows: &[MethodSummary], labels: &[(String, f64)]) -> String {
    let f = |v: Option<f64>| v.map_or("–".to_owned(), |x| format!("{x:.2} s"));
    let mut out = String::from(
        "| scenario | method | meanPET^min | PET^min_track | fidelity error | collisions | order as asked | runs | BV class | BV W₁ accel (m/s²) | BV W₁ jerk (m/s³) | BV jerk RMS (m/s³) | BV speed reversals |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|\n",
    );
    for r in rows {
        // The scenario's own label: "left_turn (…)" is not "left_turn_vut (…)".
        let label = labels
            .iter()
            .find(|(n, _)| r.scenario.strip_prefix(n.as_str()).is_some_and(|rest| rest.starts_with(" (")))
            .map(|(_, l)| *l);
        let fidelity = match (r.pet_min_track_s, label) {
            (Some(p), Some(l)) if l > 0.0 => format!("{:.1} %", 100.0 * (p - l).abs() / l),
            _ => "–".into(),
        };
        out.push_str(&format!(
            "| {} | {} | {} | {} | {} | {} | {:.0} % | {} | {} |\n",
            r.scenario,
            r.method.name(),
            f(r.mean_pet_min_s),
            f(r.pet_min_track_s),
            fidelity,
            r.collisions,
            100.0 * r.order_ok_frac,
            r.runs,
            RealismStats::cells(r.bv_realism.as_ref())
        ));
    }
    out
}

/// The four methods (`adversariality`, `fidelity`, `style`, `steerability --methods`).
impl crate::report::experiment::ExperimentView for Vec<MethodCase> {
    fn case_views(&self) -> Vec<crate::report::experiment::CaseView> {
        self.iter()
            .map(|c| {
                let method = c.method.name().to_owned();
                crate::report::experiment::CaseView::of_stats(&c.scenario, &c.vut, method, c.style, c.tau_s, &c.stats)
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing)]

    use super::*;

    fn case(vut: &str, tau_s: f64, mean: f64) -> MethodCase {
        MethodCase {
            scenario: "s".into(),
            method: Method::Video2track,
            style: Style::Rush,
            tau_s,
            vut: vut.into(),
            stats: RunStats {
                repeats: 1,
                mean_pet_min_s: Some(mean),
                pets_s: vec![mean],
                pet_min_track_s: Some(mean),
                collisions: 0,
                zone_overlaps: 0,
                order_ok_frac: 1.0,
                unmeasured: 0,
                failed: 0,
                bv_realism: None,
                vut_realism: None,
            },
        }
    }

    /// Each scenario is scored against its own label, never another's whose name it starts with.
    #[test]
    fn the_fidelity_error_takes_the_scenarios_own_label() {
        let mut vut = case("a", 2.4, 2.34);
        vut.scenario = "left_turn_vut (yield, τ 2.40 s)".into();
        let mut bv = case("a", 2.9, 2.9);
        bv.scenario = "left_turn (yield, τ 2.90 s)".into();
        let labels = [("left_turn".to_owned(), 2.9), ("left_turn_vut".to_owned(), 2.4)];
        let md = markdown(&summarize(&[vut, bv]), &labels);
        assert!(md.contains("| left_turn_vut (yield, τ 2.40 s) | Video2Track | 2.34 s | 2.34 s | 2.5 % |"), "{md}");
        assert!(md.contains("| left_turn (yield, τ 2.90 s) | Video2Track | 2.90 s | 2.90 s | 0.0 % |"), "{md}");
    }

    /// An overshoot against one model and an undershoot against another do not cancel.
    #[test]
    fn steering_errors_are_per_model_and_never_cancel() {
        let cases = [case("a", 2.0, 2.4), case("b", 2.0, 1.6), case("a", 4.0, 4.0)];
        let e = steering_errors(&cases);
        assert_eq!(e.len(), 2);
        assert_eq!((e[0].vut.as_str(), e[0].rows), ("a", 2));
        assert!((e[0].mean_error_rel - 0.1).abs() < 1e-12 && (e[0].max_error_rel - 0.2).abs() < 1e-12);
        assert!((e[1].mean_error_rel - 0.2).abs() < 1e-12, "pooled, 2.4 and 1.6 would average to 2.0: 0 %");
        let md = steering_markdown(&e);
        assert!(md.contains("| Video2Track | **worst model** | | 20.0 % | 20.0 %"), "{md}");
    }
}
