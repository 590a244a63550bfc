//! `video2track experiment latency`: the same regulator onboard and in the cloud, over networks
//! from none to a congested cell, on the paper's scenarios (replayed hand-written cassettes,
//! grounded, the diffusion prior: the Video2Track world), rush and yield, τ ∈ {2, 3, 4} s, every
//! VUT model, in the simulated proving ground.
//!
//! - **Onboard**: [`RegulatedBv`], the regulator on the BV. Its loop takes the BV's own
//!   localization and the VUT's state over the direct V2X link (the simulator's `v2x_delay_s`);
//!   the cellular network carries only its telemetry and the cloud's commands, so it is run once per
//!   case and its figures hold at every network setting (they are shown on every row).
//! - **Cloud**: [`CloudRegulatedBv`], the regulator in the cloud; states up and plans down across
//!   the network setting of the row ([`v2t_sim::network`]).
//!
//! Per VUT model, never pooled across models: the steering error `|meanPET^min − τ| / τ` (a case
//! without a measured PET counts as 1), collisions (each listed with its run), runs in the asked
//! order, the smallest distance between the two vehicles, and how often the cloud BV fell back.

use std::ops::RangeInclusive;

use serde::Serialize;
use v2t_model::{Style, Target};
use v2t_sim::bv::BvController;
use v2t_sim::network::NetworkSettings;
use v2t_sim::runner::run;
use v2t_sim::scenario::Scenario;
use v2t_sim::vut::VutModel;

use crate::controllers::{CloudRegulatedBv, RegulatedBv};
use crate::methods::{MethodsError, PaperScenario, Setup, priors, scenario_of_prior};
use crate::report::plot::{Figure, LinePlot, Marker, Series, colour};
use crate::stats::{RunStats, Tally};

/// The sweep's one-way delays, ms.
pub const DELAYS_MS: [f64; 6] = [0.0, 20.0, 50.0, 100.0, 200.0, 300.0];
/// The sweep's losses.
pub const LOSSES: [f64; 2] = [0.0, 0.05];
/// The targets, s.
pub const TAUS_S: [f64; 3] = [2.0, 3.0, 4.0];

/// Where the regulator runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Deployment {
    /// On the BV.
    Onboard,
    /// In the cloud, across the network.
    Cloud,
}

/// A collision, with the run that had it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Collision {
    /// Seed of the run.
    pub seed: u64,
    /// When, s.
    pub t_s: f64,
    /// Whether the BV was braking on the minimal-risk profile (no plan) at the end of the run.
    pub bv_fell_back: bool,
}

/// One case: scenario × style × τ × VUT model × deployment × network.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LatencyCase {
    /// Scenario.
    pub scenario: String,
    /// Style.
    pub style: Style,
    /// τ, s.
    pub tau_s: f64,
    /// VUT model.
    pub vut: String,
    /// Where the regulator ran.
    pub deployment: Deployment,
    /// The network setting's name (the onboard rows: every setting).
    pub network: String,
    /// What the runs measured.
    #[serde(flatten)]
    pub stats: RunStats,
    /// Smallest distance between the vehicles over the runs, m.
    pub min_distance_m: f64,
    /// Runs in which the BV fell back at least once.
    pub fallback_runs: usize,
    /// Share of control cycles spent on the fallback, over the runs.
    pub fallback_cycle_frac: f64,
    /// Every collision.
    pub collisions: Vec<Collision>,
    /// The BV's lateral acceleration over the runs: runs over its limit, and the largest.
    pub bv_lateral: crate::steer::BvLateral,
}

/// The runs of one case.
fn run_case(
    setup: &Setup<'_>,
    sc: &Scenario,
    model: VutModel,
    network: Option<&NetworkSettings>,
    seeds: &RangeInclusive<u64>,
) -> LatencyCase {
    let params = RegulatedBv::params_for(&setup.regulator, sc, 0);
    let mut tally = Tally::default();
    let (mut min_distance_m, mut fallback_runs, mut cycles, mut fallback_cycles) = (f64::INFINITY, 0, 0, 0);
    let mut collisions = Vec::new();
    let limit_mps2 = sc.bvs.first().map_or(f64::INFINITY, |b| b.agent.vehicle.limits.max_lat_accel_mps2);
    let mut bv_lateral = crate::steer::BvLateral { limit_mps2, ..Default::default() };
    for seed in seeds.clone() {
        let (controller, report): (Box<dyn BvController>, _) = match network {
            None => match RegulatedBv::new(params, sc, 0) {
                Ok(r) => (Box::new(r), None),
                Err(_) => {
                    tally.add_failed();
                    continue;
                }
            },
            Some(net) => match CloudRegulatedBv::new(params, sc, 0, net, seed) {
                Ok(c) => {
                    let report = c.link_report();
                    (Box::new(c), Some(report))
                }
                Err(_) => {
                    tally.add_failed();
                    continue;
                }
            },
        };
        let mut bvs = vec![controller];
        match run(sc, &mut bvs, model.driver().as_mut(), seed) {
            Ok(out) => {
                tally.add(&out.result);
                min_distance_m = min_distance_m.min(out.result.min_distance_m);
                bv_lateral.add(crate::stats::peak_lateral_mps2(&out, 1));
                let link = report.map(|r| r.get()).unwrap_or_default();
                cycles += link.cycles;
                fallback_cycles += link.fallback_cycles;
                fallback_runs += usize::from(link.fallback_cycles > 0);
                if let Some(c) = &out.result.collision {
                    collisions.push(Collision { seed, t_s: c.t_s, bv_fell_back: link.fallback_cycles > 0 });
                }
            }
            Err(_) => tally.add_failed(),
        }
    }
    LatencyCase {
        scenario: sc.name.clone(),
        style: sc.target.style(),
        tau_s: sc.target.tau_s(),
        vut: model.to_string(),
        deployment: if network.is_some() { Deployment::Cloud } else { Deployment::Onboard },
        network: network.map_or_else(|| "every setting".to_owned(), |n| n.name.clone()),
        stats: tally.stats(),
        min_distance_m,
        fallback_runs,
        fallback_cycle_frac: if cycles == 0 { 0.0 } else { fallback_cycles as f64 / cycles as f64 },
        collisions,
        bv_lateral,
    }
}

/// Every case: the onboard runs once per (scenario, style, τ, model), the cloud's per network.
pub fn run_all(
    setup: &Setup<'_>,
    scenarios: &[PaperScenario],
    networks: &[NetworkSettings],
    models: &[VutModel],
    seeds: RangeInclusive<u64>,
) -> Result<Vec<LatencyCase>, MethodsError> {
    let mut jobs: Vec<(Scenario, VutModel, Option<usize>)> = Vec::new();
    for rec in scenarios {
        for style in Style::ALL {
            for tau in TAUS_S {
                let Ok(target) = Target::new(tau, style) else { continue };
                let (grounded, _, diffusion) = priors(rec, target, setup, 1)?;
                let name = format!("{} ({}, τ {:.2} s)", rec.name, target.style(), target.tau_s());
                let sc = scenario_of_prior(&name, &diffusion, &grounded, setup)
                    .map_err(|source| MethodsError::World { scenario: name.clone(), source })?;
                for &m in models {
                    jobs.push((sc.clone(), m, None));
                    for n in 0..networks.len() {
                        jobs.push((sc.clone(), m, Some(n)));
                    }
                }
            }
        }
    }
    Ok(crate::parallel_map(&jobs, |(sc, m, n)| run_case(setup, sc, *m, n.and_then(|n| networks.get(n)), &seeds)))
}

/// The networks of the sweep: constant one-way delays × losses, in order.
pub fn sweep() -> Vec<NetworkSettings> {
    LOSSES.iter().flat_map(|&loss| DELAYS_MS.iter().map(move |&d| NetworkSettings::constant(d, loss))).collect()
}

/// One row of the summary: a VUT model, a deployment and a network.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LatencyRow {
    /// VUT model.
    pub vut: String,
    /// Deployment.
    pub deployment: Deployment,
    /// Network.
    pub network: String,
    /// Cases.
    pub cases: usize,
    /// Mean steering error over the cases.
    pub mean_error_rel: f64,
    /// Largest.
    pub max_error_rel: f64,
    /// Runs.
    pub runs: usize,
    /// Collisions.
    pub collisions: usize,
    /// Share of runs in the asked order.
    pub order_ok_frac: f64,
    /// Smallest distance over every run, m.
    pub min_distance_m: f64,
    /// Share of runs in which the BV fell back.
    pub fallback_run_frac: f64,
    /// Share of control cycles on the fallback.
    pub fallback_cycle_frac: f64,
    /// Runs in which the BV went over its lateral-acceleration limit.
    pub bv_over_lateral_limit: usize,
    /// The BV's largest lateral acceleration of any run, m/s².
    pub bv_lateral_peak_mps2: f64,
}

/// Per VUT model and network: the onboard row and the cloud's.
pub fn summarize(cases: &[LatencyCase], networks: &[NetworkSettings]) -> Vec<LatencyRow> {
    let mut vuts: Vec<&str> = cases.iter().map(|c| c.vut.as_str()).collect();
    vuts.sort_unstable();
    vuts.dedup();
    let mut out = Vec::new();
    for vut in vuts {
        let row = |deployment: Deployment, network: &str| {
            let group: Vec<&LatencyCase> =
                cases.iter().filter(|c| c.vut == vut && c.deployment == deployment && c.network == network).collect();
            let errs: Vec<f64> = group.iter().map(|c| c.stats.error_rel(c.tau_s).unwrap_or(1.0)).collect();
            let runs: usize = group.iter().map(|c| c.stats.repeats).sum();
            let cycles_weight: f64 = group.iter().map(|c| c.fallback_cycle_frac).sum::<f64>();
            LatencyRow {
                vut: vut.to_owned(),
                deployment,
                network: network.to_owned(),
                cases: group.len(),
                mean_error_rel: errs.iter().sum::<f64>() / errs.len().max(1) as f64,
                max_error_rel: errs.iter().copied().fold(0.0, f64::max),
                runs,
                collisions: group.iter().map(|c| c.stats.collisions).sum(),
                order_ok_frac: group.iter().map(|c| c.stats.order_ok_frac * c.stats.repeats as f64).sum::<f64>()
                    / runs.max(1) as f64,
                min_distance_m: group.iter().map(|c| c.min_distance_m).fold(f64::INFINITY, f64::min),
                fallback_run_frac: group.iter().map(|c| c.fallback_runs).sum::<usize>() as f64 / runs.max(1) as f64,
                fallback_cycle_frac: cycles_weight / group.len().max(1) as f64,
                bv_over_lateral_limit: group.iter().map(|c| c.bv_lateral.over_limit_runs).sum(),
                bv_lateral_peak_mps2: group.iter().map(|c| c.bv_lateral.peak_mps2).fold(0.0, f64::max),
            }
        };
        out.push(row(Deployment::Onboard, "every setting"));
        for n in networks {
            out.push(row(Deployment::Cloud, &n.name));
        }
    }
    out
}

/// The summary as markdown: one table per VUT model, then the networks' sources and every
/// collision.
pub fn markdown(rows: &[LatencyRow], cases: &[LatencyCase], networks: &[NetworkSettings]) -> String {
    let mut out = String::new();
    let mut vut: Option<&str> = None;
    for r in rows {
        if vut != Some(r.vut.as_str()) {
            vut = Some(&r.vut);
            out.push_str(&format!(
                "\nVUT model {} (simulated proving ground):\n\n| regulator | network (one way) | cases | mean steering error | max | collisions | order as asked | min distance | runs with a fallback | cycles on the fallback | BV over its lateral limit: runs (largest) |\n|---|---|---|---|---|---|---|---|---|---|---|\n",
                r.vut
            ));
        }
        out.push_str(&format!(
            "| {} | {} | {} | {:.1} % | {:.1} % | {} | {:.0} % | {:.2} m | {:.0} % | {:.1} % | {} ({:.2} m/s²) |\n",
            match r.deployment {
                Deployment::Onboard => "onboard",
                Deployment::Cloud => "cloud",
            },
            r.network,
            r.cases,
            100.0 * r.mean_error_rel,
            100.0 * r.max_error_rel,
            r.collisions,
            100.0 * r.order_ok_frac,
            r.min_distance_m,
            100.0 * r.fallback_run_frac,
            100.0 * r.fallback_cycle_frac,
            r.bv_over_lateral_limit,
            r.bv_lateral_peak_mps2
        ));
    }
    out.push_str("\nNetworks:\n\n");
    for n in networks {
        out.push_str(&format!("- {}: {}\n", n.name, n.source));
    }
    let hits: Vec<String> = cases
        .iter()
        .flat_map(|c| {
            c.collisions.iter().map(move |k| {
                format!(
                    "- {} vs {}, {} regulator over {}: seed {}, at {:.2} s{}\n",
                    c.scenario,
                    c.vut,
                    match c.deployment {
                        Deployment::Onboard => "onboard",
                        Deployment::Cloud => "cloud",
                    },
                    c.network,
                    k.seed,
                    k.t_s,
                    if k.bv_fell_back { ", the BV had fallen back (no plan to follow)" } else { "" }
                )
            })
        })
        .collect();
    out.push_str(&format!("\nCollisions: {}\n", hits.len()));
    for h in hits {
        out.push_str(&h);
    }
    out
}

/// The steering error against the one-way delay: one plot per VUT model; onboard (one value,
/// every delay), cloud without loss and cloud with loss.
pub fn figure(rows: &[LatencyRow], networks: &[NetworkSettings], seeds: &RangeInclusive<u64>) -> Figure {
    let mut vuts: Vec<&str> = rows.iter().map(|r| r.vut.as_str()).collect();
    vuts.dedup();
    let x_max = DELAYS_MS.iter().copied().fold(0.0, f64::max).max(1.0);
    // Up to the next of 1, 2, 5, 10, … % that leaves four or five steps, with room for the legend.
    let top = 1.15 * rows.iter().map(|r| 100.0 * r.mean_error_rel).fold(0.0, f64::max).max(1.0);
    let step = [1.0, 2.0, 5.0, 10.0, 20.0, 50.0].into_iter().find(|s| top / s <= 5.0).unwrap_or(100.0);
    let y_max = step * (top / step).ceil().max(1.0);
    let series: [(&str, Option<f64>); 3] =
        [("onboard", None), ("cloud, no loss", Some(0.0)), ("cloud, 5 % loss", Some(0.05))];
    let panels = vuts
        .iter()
        .map(|vut| {
            let lines = series
                .iter()
                .enumerate()
                .map(|(i, (name, loss))| {
                    let points = match loss {
                        None => rows
                            .iter()
                            .find(|r| r.vut == *vut && r.deployment == Deployment::Onboard)
                            .map(|r| DELAYS_MS.iter().map(|&d| (d, 100.0 * r.mean_error_rel)).collect())
                            .unwrap_or_default(),
                        Some(loss) => cloud_points(rows, networks, vut, *loss),
                    };
                    Series { marker: Some(Marker::Dot), ..Series::line(*name, points, colour(i)) }
                })
                .collect();
            let plot = LinePlot {
                title: (*vut).to_owned(),
                x_label: "one-way delay (ms)".into(),
                y_label: "steering error (%)".into(),
                series: lines,
                levels: Vec::new(),
                y_range: Some((0.0, y_max)),
                x_range: Some((-0.03 * x_max, 1.03 * x_max)),
                cursor: false,
                markers: false,
            };
            (plot, "latency".to_owned())
        })
        .collect();
    Figure {
        title: format!(
            "Mean steering error against the one-way network delay, per VUT model: the regulator onboard and in the \
             cloud (simulated proving ground and network; seeds {}–{})",
            seeds.start(),
            seeds.end()
        ),
        panels,
        columns: 2,
    }
}

/// The figure as a file of its own (`experiment latency --svg`).
pub fn svg(rows: &[LatencyRow], networks: &[NetworkSettings], seeds: &RangeInclusive<u64>) -> String {
    figure(rows, networks, seeds).file()
}

/// The cloud regulator's mean error (%) against the constant delay (ms) of the networks without
/// jitter that lose `loss` of the messages.
fn cloud_points(rows: &[LatencyRow], networks: &[NetworkSettings], vut: &str, loss: f64) -> Vec<(f64, f64)> {
    networks
        .iter()
        .filter_map(|n| match n.uplink.delay {
            v2t_sim::network::Delay::Constant { ms } if n.uplink.loss == loss && n.uplink.jitter_ms == 0.0 => {
                let r =
                    rows.iter().find(|r| r.vut == vut && r.deployment == Deployment::Cloud && r.network == n.name)?;
                Some((ms, 100.0 * r.mean_error_rel))
            }
            _ => None,
        })
        .collect()
}

/// Onboard against the cloud: each deployment and network a setting, collisions marked.
impl crate::report::experiment::ExperimentView for Vec<LatencyCase> {
    fn case_views(&self) -> Vec<crate::report::experiment::CaseView> {
        self.iter()
            .map(|c| {
                let method = format!("{:?} {}", c.deployment, c.network).to_lowercase();
                let mut v = crate::report::experiment::CaseView::of_stats(
                    &c.scenario,
                    &c.vut,
                    method,
                    c.style,
                    c.tau_s,
                    &c.stats,
                );
                for col in &c.collisions {
                    v.runs.push(vec![
                        format!("seed {}", col.seed),
                        format!("<span class=\"warn\">collision at {:.2} s</span>", col.t_s),
                        if col.bv_fell_back { "BV in fallback".into() } else { String::new() },
                    ]);
                }
                v
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing)]

    use super::*;

    fn case(vut: &str, deployment: Deployment, network: &str, tau_s: f64, mean: Option<f64>) -> LatencyCase {
        LatencyCase {
            scenario: "s".into(),
            style: Style::Rush,
            tau_s,
            vut: vut.into(),
            deployment,
            network: network.into(),
            stats: RunStats {
                repeats: 2,
                mean_pet_min_s: mean,
                pets_s: mean.map(|m| vec![m, m]).unwrap_or_default(),
                pet_min_track_s: mean,
                collisions: 0,
                zone_overlaps: 0,
                order_ok_frac: 1.0,
                unmeasured: usize::from(mean.is_none()) * 2,
                failed: 0,
                bv_realism: None,
                vut_realism: None,
            },
            min_distance_m: 3.0,
            fallback_runs: 1,
            fallback_cycle_frac: 0.1,
            collisions: vec![],
            bv_lateral: crate::steer::BvLateral {
                limit_mps2: 4.5,
                peak_mps2: tau_s,
                over_limit_runs: usize::from(tau_s > 4.5),
            },
        }
    }

    /// Rows are per VUT model and network, an unmeasured case counts as a full miss, and the plot
    /// has one panel per model with the three series.
    #[test]
    fn rows_are_per_model_and_network_and_the_plot_draws_them() {
        let nets = vec![NetworkSettings::constant(0.0, 0.0), NetworkSettings::constant(100.0, 0.05)];
        let cases = vec![
            case("a", Deployment::Onboard, "every setting", 2.0, Some(2.2)),
            case("a", Deployment::Cloud, &nets[0].name, 2.0, Some(2.2)),
            case("a", Deployment::Cloud, &nets[1].name, 2.0, None),
            case("b", Deployment::Onboard, "every setting", 4.0, Some(3.6)),
            case("b", Deployment::Cloud, &nets[0].name, 4.0, Some(4.0)),
            case("b", Deployment::Cloud, &nets[1].name, 4.0, Some(5.0)),
        ];
        let rows = summarize(&cases, &nets);
        assert_eq!(rows.len(), 6);
        assert!((rows[0].mean_error_rel - 0.1).abs() < 1e-12);
        assert_eq!(rows[2].mean_error_rel, 1.0, "no PET: a full miss");
        assert!((rows[5].mean_error_rel - 0.25).abs() < 1e-12 && rows[5].vut == "b");
        let md = markdown(&rows, &cases, &nets);
        assert!(md.contains("VUT model a") && md.contains("| cloud | 100 ms, loss 5 % | 1 | 100.0 %"), "{md}");
        assert!(md.contains("Collisions: 0"));
        // The BV's lateral acceleration per row: the runs over its limit, the largest.
        assert_eq!((rows[0].bv_over_lateral_limit, rows[0].bv_lateral_peak_mps2), (0, 2.0));
        assert!(md.contains("| 0 (4.00 m/s²) |"), "{md}");
        let svg = svg(&rows, &nets, &(6..=10));
        assert_eq!(svg.matches("class=\"series\"").count(), 6, "{svg}");
        assert!(svg.contains("seeds 6–10") && svg.contains(">b</text>") && svg.contains(">one-way delay (ms)<"));
        assert!(
            svg.starts_with("<svg")
                && svg.contains("xmlns=")
                && !figure(&rows, &nets, &(6..=10)).svg().contains("xmlns=")
        );
    }
}
