//! `video2track experiment steerability`: the regulator alone on scenario cards.
//!
//! For every scenario, style, target τ and VUT (a builtin driver model, or a SUMO driver in the
//! SUMO world), `repeats` seeded noisy runs with the regulated BV; per case the statistics of
//! [`crate::stats`], the steering error `|meanPET^min − τ| / τ`, and — when asked — whether any BV
//! can reach τ against that VUT at all ([`crate::reach`]), so that a miss the VUT imposes is told
//! apart from a miss of the regulator.

use serde::Serialize;
use v2t_game::regulator::RegulatorParams;
use v2t_model::{Style, Target};
use v2t_sim::bv::BvController;
use v2t_sim::scenario::Scenario;

use crate::campaign::FreeDrives;
use crate::controllers::RegulatedBv;
use crate::miss::Misses;
use crate::reach::{Reach, YieldRule, reach};
use crate::stats::{RunStats, SingleRuns, Tally};
use crate::vut::{Vut, World};
use v2t_edge::campaign::Learned;

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
    /// The VUT's driver.
    pub vut: String,
    /// The VUT's world.
    pub world: World,
    /// Target PET, s.
    pub tau_s: f64,
    /// What the runs measured.
    #[serde(flatten)]
    pub stats: RunStats,
    /// `|meanPET^min − τ| / τ`.
    pub error_rel: Option<f64>,
    /// Every run scored on its own against τ.
    pub single: Option<SingleRuns>,
    /// The runs that missed τ by more than 10 % (or gave no PET), by reason ([`crate::miss`]).
    pub misses: Misses,
    /// Whether some BV lands within ±10 % of τ in the asked order against this VUT: an open-loop
    /// profile of [`crate::reach`]'s grid did, or these regulated runs did on average (safely, in
    /// the asked order: they are a BV too). `None` when the grid was not run.
    pub reachable: Option<bool>,
    /// How the first BV's regulator identified the VUT's reaction by the end of each run.
    pub identified: IdentifiedRuns,
    /// Runs in which the VUT went first but the first BV did not give way as the regulator's BV
    /// must ([`YieldRule`]: behind its stop line until the VUT was in its zone, clear of the zone
    /// until it had left); 0 where the card has no stop line. Such a run is a near miss, not a
    /// yield: the case is not counted as reached by its own runs.
    pub yields_not_kept: usize,
    /// The first BV's lateral acceleration over the runs (speed times yaw rate, against its
    /// vehicle's `max_lat_accel_mps2`).
    pub bv_lateral: BvLateral,
}

/// The first BV's lateral acceleration over the runs of a case.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct BvLateral {
    /// Its vehicle's limit, m/s².
    pub limit_mps2: f64,
    /// The largest of any run, m/s².
    pub peak_mps2: f64,
    /// Runs in which it went over the limit.
    pub over_limit_runs: usize,
}

impl BvLateral {
    /// One run's largest lateral acceleration.
    pub(crate) fn add(&mut self, peak_mps2: f64) {
        self.add_against(peak_mps2, self.limit_mps2);
    }

    /// One run's largest lateral acceleration, against that run's BV's own limit.
    pub(crate) fn add_against(&mut self, peak_mps2: f64, limit_mps2: f64) {
        self.peak_mps2 = self.peak_mps2.max(peak_mps2);
        self.over_limit_runs += usize::from(peak_mps2 > limit_mps2);
    }
}

/// How a case's regulator identified the VUT's reaction by the end of its runs
/// ([`v2t_game::reaction`]).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct IdentifiedRuns {
    /// Runs whose regulator learnt something of the VUT's reaction (it saw a conflict).
    pub runs: usize,
    /// Runs whose regulator saw no conflict to learn from (merges are not modelled: always these).
    pub uninformed: usize,
    /// Of those, the runs that ended with a reacting driver most probable.
    pub reacting: usize,
    /// Mean over those runs of the final probability that the VUT reacts.
    pub reacts_p_mean: f64,
}

impl IdentifiedRuns {
    fn add(&mut self, id: &v2t_game::reaction::Identified) {
        if id.informative_cycles == 0 {
            self.uninformed += 1;
            return;
        }
        let n = self.runs as f64;
        self.reacts_p_mean = (self.reacts_p_mean * n + id.reacts_probability) / (n + 1.0);
        self.runs += 1;
        self.reacting += usize::from(id.reaction.is_some());
    }

    /// One line for the table of missed runs.
    fn line(&self) -> String {
        let quiet = match self.uninformed {
            0 => String::new(),
            n => format!("; {n} run(s) saw no conflict to learn from"),
        };
        if self.runs == 0 {
            return if self.uninformed == 0 { "—".to_owned() } else { quiet.trim_start_matches("; ").to_owned() };
        }
        format!("{}/{} runs (mean p {:.2}){quiet}", self.reacting, self.runs, self.reacts_p_mean)
    }
}

/// The whole experiment.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SteerReport {
    /// Whether every regulated run was prepared by a free drive of the VUT ([`FreeDrives`]): the
    /// regulator knew how this VUT drives the route alone.
    pub free_drive: bool,
    /// Every case.
    pub cases: Vec<SteerCase>,
    /// Mean of the per-case steering errors (a case without a measured PET counts as 1).
    pub mean_error_rel: f64,
    /// Largest per-case steering error.
    pub max_error_rel: f64,
    /// What the open-loop grid reached per scenario and VUT, when measured.
    pub reach: Vec<Reach>,
    /// Over the cases whose target is reachable (when reach was measured): mean and largest error.
    pub reachable_errors: Option<(f64, f64)>,
    /// Per VUT: the same figures over that VUT's cases only (never pooled across VUTs).
    pub per_vut: Vec<VutErrors>,
}

/// The steering errors of one VUT.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct VutErrors {
    /// The VUT.
    pub vut: String,
    /// Its cases.
    pub cases: usize,
    /// Mean and largest error over its cases.
    pub all: (f64, f64),
    /// Cases whose τ some BV reached, and the mean and largest error over them (when measured).
    pub reachable: Option<(usize, f64, f64)>,
    /// Single runs of its cases (of the reachable ones when reach was measured): the mean of their
    /// errors and the share within ±10 % of τ.
    pub single_runs: SingleRuns,
}

impl SteerCase {
    /// The regulated runs themselves landed within ±10 % of τ on average, every run in the asked
    /// order, without a collision or zone overlap, and every yield given as the rule asks
    /// ([`Self::yields_not_kept`]).
    pub fn landed_safely(&self) -> bool {
        let s = &self.stats;
        self.error_rel.is_some_and(|e| e <= 0.10)
            && self.yields_not_kept == 0
            && s.collisions == 0
            && s.zone_overlaps == 0
            && s.unmeasured == 0
            && s.order_ok_frac >= 1.0
    }
}

/// Mean and largest of per-case errors (a case without a measured PET counts as 1).
fn mean_max<'a>(cases: impl Iterator<Item = &'a SteerCase>) -> (f64, f64) {
    let errs: Vec<f64> = cases.map(|c| c.error_rel.unwrap_or(1.0)).collect();
    let mean = if errs.is_empty() { 0.0 } else { errs.iter().sum::<f64>() / errs.len() as f64 };
    (mean, errs.iter().copied().fold(0.0, f64::max))
}

/// The single runs of `cases` pooled (each case weighted by its runs): mean error and share within
/// ±10 % of τ.
fn single_runs<'a>(cases: impl Iterator<Item = &'a SteerCase>) -> SingleRuns {
    SingleRuns::pool(cases.filter_map(|c| Some((c.single?, c.stats.repeats.max(c.stats.pets_s.len())))))
}

/// One case: one run per seed, every BV regulated by `settings` (with the
/// scenario's vehicle limits) towards `target`. With `free_drives`, every run is prepared by the
/// free drive of its seed ([`FreeDrives`]): each BV's regulator knows how the VUT drove its route
/// alone, as after a first run of a campaign; a run whose free drive failed counts as failed.
pub fn steer_case(
    settings: &RegulatorParams,
    scenario: &Scenario,
    target: Target,
    vut: &Vut<'_>,
    seeds: std::ops::RangeInclusive<u64>,
    free_drives: Option<&FreeDrives>,
) -> SteerCase {
    let mut tally = Tally::default();
    let mut misses = Misses::default();
    let mut identified = IdentifiedRuns::default();
    let mut yields_not_kept = 0;
    let limit_mps2 = scenario.bvs.first().map_or(f64::INFINITY, |b| b.agent.vehicle.limits.max_lat_accel_mps2);
    let mut bv_lateral = BvLateral { limit_mps2, ..BvLateral::default() };
    let mut sc = scenario.clone();
    sc.target = target;
    for seed in seeds {
        let routes = match free_drives.map(|d| d.routes(seed)) {
            None => &[][..],
            Some(Some(r)) => r,
            Some(None) => {
                tally.add_failed();
                continue;
            }
        };
        let mut report = None;
        let bvs: Result<Vec<Box<dyn BvController>>, _> = (0..sc.bvs.len())
            .map(|i| {
                // A free drive's route, given as a campaign would give it (aim: the target).
                let learned = Learned { route: routes.get(i).cloned().flatten(), ..Learned::default() };
                let r = RegulatedBv::new(RegulatedBv::params_for(settings, &sc, i), &sc, i)?
                    .with_campaign(&learned.upload(crate::world::CARD_PRIOR_ID, target))?;
                if i == 0 {
                    report = Some(r.reaction_report());
                }
                Ok::<_, crate::controllers::RegulatedBvError>(Box::new(r) as Box<dyn BvController>)
            })
            .collect();
        let Ok(mut bvs) = bvs else {
            tally.add_failed();
            continue;
        };
        match vut.run(&sc, &mut bvs, seed) {
            Ok(out) => {
                tally.add(&out.result);
                misses.add(&sc, &out, target);
                bv_lateral.add(crate::stats::peak_lateral_mps2(&out, 1));
                if YieldRule::kept_in(&sc, 0, &out) == Some(false) {
                    yields_not_kept += 1;
                }
                let last = report.and_then(|r| r.get()).map(v2t_game::reaction::ReactionPosterior::from);
                if let Some(id) = last.as_ref().and_then(v2t_game::reaction::ReactionPosterior::identified) {
                    identified.add(&id);
                }
            }
            Err(_) => tally.add_failed(),
        }
    }
    let stats = tally.stats();
    SteerCase {
        scenario: scenario.name.clone(),
        style: target.style(),
        vut: vut.name(),
        world: vut.world(),
        tau_s: target.tau_s(),
        error_rel: stats.error_rel(target.tau_s()),
        single: stats.single_runs(target.tau_s()),
        misses,
        stats,
        reachable: None,
        identified,
        yields_not_kept,
        bv_lateral,
    }
}

/// Runs every case (scenario × target × VUT) on the available cores. With `reach_seed`, first runs
/// the open-loop grid of [`crate::reach`] for every scenario and VUT on that seed and marks each
/// case reachable or not.
/// With `free_drive`, every regulated run is prepared by a free drive ([`FreeDrives`], driven
/// once per scenario, VUT and seed).
pub fn steerability(
    settings: &RegulatorParams,
    scenarios: &[Scenario],
    targets: &[Target],
    vuts: &[Vut<'_>],
    seeds: std::ops::RangeInclusive<u64>,
    reach_seed: Option<u64>,
    free_drive: bool,
) -> SteerReport {
    // Per scenario and VUT (pair `i · vuts.len() + j`): the open-loop grid and the free drives.
    let pairs: Vec<(&Scenario, &Vut<'_>)> = scenarios.iter().flat_map(|sc| vuts.iter().map(move |v| (sc, v))).collect();
    let reaches = match reach_seed {
        Some(seed) => crate::parallel_map(&pairs, |(sc, v)| reach(sc, v, seed)),
        None => Vec::new(),
    };
    let drives: Vec<FreeDrives> = if free_drive {
        crate::parallel_map(&pairs, |(sc, v)| FreeDrives::drive(settings, sc, v, seeds.clone()))
    } else {
        Vec::new()
    };
    let mut jobs = Vec::new();
    for (i, sc) in scenarios.iter().enumerate() {
        for &target in targets {
            for (j, v) in vuts.iter().enumerate() {
                jobs.push((sc, target, v, drives.get(i * vuts.len() + j)));
            }
        }
    }
    let mut cases = crate::parallel_map(&jobs, |(sc, target, v, drives)| {
        steer_case(settings, sc, *target, v, seeds.clone(), *drives)
    });
    for c in &mut cases {
        let target = Target::new(c.tau_s, c.style).ok();
        c.reachable = reaches
            .iter()
            .find(|r| r.scenario == c.scenario && r.vut == c.vut)
            .zip(target)
            .map(|(r, t)| r.reachable(t) || c.landed_safely());
    }
    cases.sort_by(|a, b| {
        (&a.scenario, a.style as u8, a.tau_s.to_bits(), &a.vut).cmp(&(
            &b.scenario,
            b.style as u8,
            b.tau_s.to_bits(),
            &b.vut,
        ))
    });
    let (mean_error_rel, max_error_rel) = mean_max(cases.iter());
    let reachable_errors = reach_seed.map(|_| mean_max(cases.iter().filter(|c| c.reachable == Some(true))));
    let mut names: Vec<&str> = cases.iter().map(|c| c.vut.as_str()).collect();
    names.sort_unstable();
    names.dedup();
    let per_vut = names
        .iter()
        .map(|&vut| {
            let mine = || cases.iter().filter(move |c| c.vut == vut);
            VutErrors {
                vut: vut.to_owned(),
                cases: mine().count(),
                all: mean_max(mine()),
                reachable: reach_seed.map(|_| {
                    let (mean, max) = mean_max(mine().filter(|c| c.reachable == Some(true)));
                    (mine().filter(|c| c.reachable == Some(true)).count(), mean, max)
                }),
                single_runs: single_runs(mine().filter(|c| reach_seed.is_none() || c.reachable == Some(true))),
            }
        })
        .collect();
    SteerReport { free_drive, mean_error_rel, max_error_rel, reach: reaches, reachable_errors, per_vut, cases }
}

/// A markdown table of the report.
pub fn steer_markdown(r: &SteerReport) -> String {
    let mut out = String::new();
    if r.free_drive {
        out.push_str("Every regulated run was prepared by a free drive: the VUT drove the test once with every BV parked, and the regulator knew how it drove its route (another seed than the run's).\n\n");
    }
    out.push_str(
        "| scenario | style | VUT | τ (s) | mean PET_min (s) | PET^min_track (s) | error of the mean | single-run error | single runs within 10 % | collisions | overlaps | order ok | no PET | yields not kept | τ reachable |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n",
    );
    let f = |x: Option<f64>| x.map_or_else(|| "—".to_owned(), |v| format!("{v:.2}"));
    for c in &r.cases {
        let reachable = match c.reachable {
            Some(true) => "yes",
            Some(false) => "**no**: no BV reached it against this VUT",
            None => "not measured",
        };
        out.push_str(&format!(
            "| {} | {} | {} | {:.1} | {} | {} | {} | {} | {} | {} | {} | {:.2} | {} | {} | {reachable} |\n",
            c.scenario,
            c.style,
            c.vut,
            c.tau_s,
            f(c.stats.mean_pet_min_s),
            f(c.stats.pet_min_track_s),
            c.error_rel.map_or_else(|| "—".to_owned(), |e| format!("{:.1} %", 100.0 * e)),
            c.single.map_or_else(|| "—".to_owned(), |s| format!("{:.1} %", 100.0 * s.mean_error_rel)),
            c.single.map_or_else(|| "—".to_owned(), |s| format!("{:.0} %", 100.0 * s.within_10_frac)),
            c.stats.collisions,
            c.stats.zone_overlaps,
            c.stats.order_ok_frac,
            c.stats.unmeasured,
            c.yields_not_kept
        ));
    }
    let runs: usize = r.cases.iter().map(|c| c.stats.repeats).sum();
    let total = |f: fn(&SteerCase) -> usize| r.cases.iter().map(f).sum::<usize>();
    let lateral = r.cases.iter().map(|c| c.bv_lateral).max_by(|a, b| a.peak_mps2.total_cmp(&b.peak_mps2));
    out.push_str(&format!(
        "\nmean error {:.1} %, max error {:.1} %; {} runs: {} collisions, {} zone overlaps, {} without a measured PET, {} yields not kept back (the BV past its stop line before the VUT was in its zone, or near the zone while it was)\n",
        100.0 * r.mean_error_rel,
        100.0 * r.max_error_rel,
        runs,
        total(|c| c.stats.collisions),
        total(|c| c.stats.zone_overlaps),
        total(|c| c.stats.unmeasured),
        total(|c| c.yields_not_kept)
    ));
    if let Some(l) = lateral {
        out.push_str(&format!(
            "the BV's lateral acceleration: over its limit in {} runs; largest {:.2} m/s² (its limit {:.1} m/s²)\n",
            total(|c| c.bv_lateral.over_limit_runs),
            l.peak_mps2,
            l.limit_mps2
        ));
    }
    if let Some((mean, max)) = r.reachable_errors {
        let n = r.cases.iter().filter(|c| c.reachable == Some(true)).count();
        out.push_str(&format!(
            "over the {n} cases whose τ some BV reached: mean error {:.1} %, max error {:.1} %; {} cases not reachable\n",
            100.0 * mean,
            100.0 * max,
            r.cases.len() - n
        ));
    }
    out.push_str("\nPer VUT (each case's mean PET over that VUT's runs only; never pooled across VUTs; single runs: every run scored on its own, over the reachable cases when reach was measured):\n\n| VUT | cases | mean error | max error | cases τ reachable | mean error, reachable | max error, reachable | single-run mean error | single runs within 10 % |\n|---|---|---|---|---|---|---|---|---|\n");
    for v in &r.per_vut {
        let (n, mean, max) = v.reachable.map_or_else(
            || ("not measured".to_owned(), "—".to_owned(), "—".to_owned()),
            |(n, mean, max)| (n.to_string(), format!("{:.1} %", 100.0 * mean), format!("{:.1} %", 100.0 * max)),
        );
        out.push_str(&format!(
            "| {} | {} | {:.1} % | {:.1} % | {n} | {mean} | {max} | {:.1} % | {:.0} % |\n",
            v.vut,
            v.cases,
            100.0 * v.all.0,
            100.0 * v.all.1,
            100.0 * v.single_runs.mean_error_rel,
            100.0 * v.single_runs.within_10_frac
        ));
    }
    if let Some(worst) = r.per_vut.iter().map(|v| v.reachable.map_or(v.all.0, |x| x.1)).reduce(f64::max) {
        out.push_str(&format!("worst VUT's mean error (reachable cases when measured): {:.1} %\n", 100.0 * worst));
    }
    let missed: Vec<&SteerCase> = r.cases.iter().filter(|c| c.misses.runs > 0).collect();
    if !missed.is_empty() {
        out.push_str("\nWhy single runs missed τ by more than 10 % (each missed run counted once, by the first reason that holds: no PET; the VUT stood ≥ 1 s before the zone; the VUT slowed below a quarter of its start speed; the BV at its acceleration limits ≥ 1 s; else the regulator), and in how many of the case's runs the regulator ended identifying the VUT as reacting to the BV (its final probability that it does, averaged; — : the follower does not react):\n\n| scenario | style | VUT | τ (s) | missed runs | VUT identified as reacting |\n|---|---|---|---|---|---|\n");
        for c in missed {
            out.push_str(&format!(
                "| {} | {} | {} | {:.1} | {} | {} |\n",
                c.scenario,
                c.style,
                c.vut,
                c.tau_s,
                c.misses.line(),
                c.identified.line()
            ));
        }
    }
    if !r.reach.is_empty() {
        out.push_str("\nWhat open-loop BVs reached (a grid of ");
        out.push_str(&crate::reach::grid().len().to_string());
        out.push_str(" speed profiles, one seed, every BV within its lateral-acceleration limit in the curves, each run once more keeping the yield rule below where it applies; PET range of the safe runs in each order; a τ counts as reached when a profile lands within ±10 % of it, or the regulated runs did; at a crossing a yield counts only when the BV waited behind its stop line until the VUT was in its zone and kept 2.5 m from its zone until the VUT had left, as the regulator's BV must):\n\n| scenario | VUT | rush PETs (s) | yield PETs (s) | yields not kept back | collisions | failed |\n|---|---|---|---|---|---|---|\n");
        let range = |x: Option<(f64, f64)>| x.map_or_else(|| "none".to_owned(), |(a, b)| format!("{a:.2}–{b:.2}"));
        for x in &r.reach {
            out.push_str(&format!(
                "| {} | {} | {} ({} runs) | {} ({} runs) | {} | {} | {} |\n",
                x.scenario,
                x.vut,
                range(x.range(Style::Rush)),
                x.rush_pets_s.len(),
                range(x.range(Style::Yield)),
                x.yield_pets_s.len(),
                x.unreadable_yields,
                x.collisions,
                x.failed
            ));
        }
    }
    out
}

impl crate::report::experiment::ExperimentView for SteerReport {
    fn case_views(&self) -> Vec<crate::report::experiment::CaseView> {
        self.cases
            .iter()
            .map(|c| crate::report::experiment::CaseView {
                reachable: c.reachable,
                error_rel: c.error_rel,
                ..crate::report::experiment::CaseView::of_stats(
                    &c.scenario,
                    &c.vut,
                    String::new(),
                    c.style,
                    c.tau_s,
                    &c.stats,
                )
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing)]

    use super::*;
    use v2t_game::reaction::{ReactionPosterior, hypothesis};

    /// A posterior with probability `reacting` that the VUT reacts: a reacting driver the most
    /// probable when it is above one half, the driver that does not react otherwise.
    fn posterior(reacting: f64) -> ReactionPosterior {
        if reacting > 0.5 {
            ReactionPosterior::sure_of(hypothesis(1), reacting, 3).unwrap()
        } else {
            ReactionPosterior::sure_of(None, 1.0 - reacting, 3).unwrap()
        }
    }

    #[test]
    fn the_identification_of_a_cases_runs_is_counted_and_said_in_one_line() {
        let mut runs = IdentifiedRuns::default();
        assert_eq!(runs.line(), "—", "a follower that does not react identifies nothing");
        let (calm, reacting) = (posterior(0.2).identified().unwrap(), posterior(0.99).identified().unwrap());
        assert!(calm.reaction.is_none() && reacting.reaction.is_some());
        runs.add(&calm);
        runs.add(&reacting);
        assert_eq!((runs.runs, runs.reacting), (2, 1));
        let mean = (calm.reacts_probability + reacting.reacts_probability) / 2.0;
        assert!((runs.reacts_p_mean - mean).abs() < 1e-9, "{runs:?}");
        assert_eq!(runs.line(), format!("1/2 runs (mean p {mean:.2})"));
        runs.add(&ReactionPosterior { informative_cycles: 0, ..posterior(0.9) }.identified().unwrap());
        assert_eq!(runs.runs, 2, "a run that saw no conflict teaches nothing");
        assert!(runs.line().ends_with("; 1 run(s) saw no conflict to learn from"), "{}", runs.line());
        let mut merge = IdentifiedRuns::default();
        merge.add(&ReactionPosterior { informative_cycles: 0, ..posterior(0.2) }.identified().unwrap());
        assert_eq!(merge.line(), "1 run(s) saw no conflict to learn from");
    }

    /// A BV driven through the BV-turning card's left turn by its reference at a steady speed:
    /// the measured lateral acceleration is v²/R in the arc (R 21.75 m) and nothing on the
    /// straight, and the case counts the runs over the limit.
    #[test]
    fn the_bvs_lateral_acceleration_is_its_speed_squared_over_the_radius_and_runs_over_the_limit_count() {
        use v2t_sim::bv::ReferenceFollower;
        let root = concat!(env!("CARGO_MANIFEST_DIR"), "/../../config/scenarios/left_turn_basic.toml");
        let mut sc = v2t_sim::files::load_scenario(std::path::Path::new(root)).unwrap();
        let peak = |sc: &Scenario| {
            let mut bvs: Vec<Box<dyn BvController>> = vec![Box::new(ReferenceFollower::default())];
            let run = Vut::Builtin(v2t_sim::vut::VutModel::IdmNormal).run(sc, &mut bvs, 1).unwrap();
            crate::stats::peak_lateral_mps2(&run, 1)
        };
        for v in [6.0, 8.0] {
            sc.bvs[0].agent.initial_speed_mps = v;
            sc.bvs[0].reference = v2t_sim::scenario::SpeedProfile::new(vec![[0.0, v]]);
            let got = peak(&sc);
            assert!((got - v * v / 21.75).abs() < 0.25 * v * v / 21.75, "{v} m/s: {got:.2} m/s²");
        }
        let mut lateral = BvLateral { limit_mps2: 2.5, ..BvLateral::default() };
        for p in [1.7, 2.9, 2.4, 3.1] {
            lateral.add(p);
        }
        assert_eq!((lateral.over_limit_runs, lateral.peak_mps2), (2, 3.1));
    }
}
