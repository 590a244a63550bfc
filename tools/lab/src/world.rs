//! How a prior becomes a run: the one place that turns the priors of the pipeline into the
//! simulated proving ground's scenarios.
//!
//! A trajectory prior reaches a simulated world the way it reaches a BV: [`accept`] runs the BV's
//! own acceptance (`v2t_edge::prior::from_upload`: limits, the conflict zone, the IPC encoding),
//! and [`from_prior`] builds the world from the accepted IPC prior, decoded as the regulator
//! decodes it (`v2t_edge::prior::PriorContext`). So the in-process experiments, the simulated ECU
//! behind the onboard processes and the demo all measure the conflict zone and the paths the BV
//! regulates. [`prior_of_card`] goes the other way, for scenario cards: the prior a card's BV would
//! have received from the cloud.

use v2t_edge::prior::{PriorChecks, PriorContext, PriorError, Refused, from_upload, path_points};
use v2t_game::regulator::{junction_entry_of_stop_line, stop_line_station};
use v2t_model::metrics::ConflictZone;
use v2t_model::prior::TrajectoryPrior;
use v2t_model::vehicle::VehicleConfig;
use v2t_sim::config::SimSettings;
use v2t_sim::scenario::{Scenario, ScenarioError, ScenarioPaths, SpeedProfile};
use v2t_sim::vut::VutModel;
use v2t_wire::link::PriorUpload;
use v2t_wire::{ActivePrior, Code as _, Header, ProfileSample, Vector as _, ZoneKind};

/// Longest simulated run built from a prior, s.
pub const MAX_PRIOR_RUN_S: f64 = 120.0;
/// The run goes on this long after the later of the BV's reference and the VUT's route ends, s.
pub const RUN_TAIL_S: f64 = 2.0;
/// Samples of the BV's reference timing in a prior made from a card, per second.
const PROFILE_RATE_HZ: f64 = 10.0;

/// A prior that makes no world.
#[derive(Debug, thiserror::Error)]
pub enum WorldError {
    /// The BV's acceptance refused the prior.
    #[error(transparent)]
    Refused(#[from] Refused),
    /// The prior does not decode, or its BV agent is missing.
    #[error(transparent)]
    Prior(#[from] PriorError),
    /// The paths make no scenario.
    #[error(transparent)]
    Scenario(#[from] ScenarioError),
    /// The card has no such BV, or it has no conflict.
    #[error("the scenario has no BV {0} with a conflict")]
    NoBv(usize),
}

/// The vehicles of a world: the BV's (its limits are what a prior is checked against) and the VUT's.
#[derive(Debug, Clone, Copy)]
pub struct Vehicles<'a> {
    /// The BV.
    pub bv: &'a VehicleConfig,
    /// The VUT.
    pub vut: &'a VehicleConfig,
}

/// `prior` accepted by a BV with `vehicles` driving agent `bv_agent` (default: the first BV): the
/// acceptance of an upload, without a geofence and with an open validity window.
pub fn accept(
    prior: &TrajectoryPrior,
    bv_agent: Option<&str>,
    vehicles: Vehicles<'_>,
    prior_id: u64,
    stamp_ns: u64,
) -> Result<ActivePrior, WorldError> {
    let bv_agent =
        prior.bv_agent(bv_agent).map_err(|e| Refused { prior_id, reason: PriorError::Invalid(e) })?.id.clone();
    let up = PriorUpload { prior_id, bv_agent, valid_from_ms: 0, valid_until_ms: u64::MAX, prior: prior.clone() };
    let checks = PriorChecks::for_vehicles(vehicles.bv, vehicles.vut, None, 0.0);
    Ok(from_upload(&up, 0, &checks, stamp_ns)?)
}

/// The simulated world of an accepted prior: the BV on its reference path with the prior's
/// timing, the VUT from the start of its route at the prior's start speed (wishing to keep it)
/// driven by `vut_model`, the conflict zone the BV regulates.
pub fn from_prior(
    name: &str,
    prior: &ActivePrior,
    vehicles: Vehicles<'_>,
    settings: SimSettings,
    vut_model: VutModel,
) -> Result<Scenario, WorldError> {
    let ctx = PriorContext::new(prior)?.context;
    let profile: Vec<[f64; 2]> = prior.bv_profile.as_slice().iter().map(|q| [q.t_s, q.v_mps]).collect();
    let bv_end_s = profile.last().map_or(0.0, |[t, _]| *t);
    let vut_end_s = ctx.vut_path.length() / prior.vut_speed_mps.max(1.0);
    let zone = ConflictZone {
        kind: ctx.zone_kind,
        vut: ctx.zone_vut,
        bv: ctx.zone_bv,
        anchor: ctx.vut_path.point_at(0.5 * (ctx.zone_vut.enter_s_m + ctx.zone_vut.exit_s_m)),
    };
    let paths = ScenarioPaths {
        name: name.to_owned(),
        target: ctx.target,
        duration_s: (bv_end_s.max(vut_end_s) + RUN_TAIL_S).min(MAX_PRIOR_RUN_S),
        vut_route: ctx.vut_path,
        vut_speed_mps: prior.vut_speed_mps,
        vut_model,
        bv_id: "bv".into(),
        bv_route: ctx.bv_path,
        bv_reference: SpeedProfile::new(profile),
        conflict: Some(zone),
        // The BV's own stop line again when the scenario's prior is rebuilt for the regulator.
        bv_junction_entry_m: prior
            .bv_stop_line()
            .map(|l| junction_entry_of_stop_line(l, vehicles.bv.geometry.length_m)),
    };
    Ok(Scenario::from_paths(paths, settings, vehicles.vut.clone(), vehicles.bv.clone())?)
}

/// The id of the prior the lab's regulated BVs regulate around ([`prior_of_card`]), which a
/// campaign's upload names.
pub const CARD_PRIOR_ID: u64 = 0;

/// The prior BV `bv_index` of a card's `scenario` would have received from the cloud: its path
/// and reference timing, the VUT's route and start speed, their conflict zone and the target.
pub fn prior_of_card(
    scenario: &Scenario,
    bv_index: usize,
    prior_id: u64,
    stamp_ns: u64,
) -> Result<ActivePrior, WorldError> {
    let (Some(bv), Some(conflict)) = (scenario.bvs.get(bv_index), scenario.conflict_of(bv_index)) else {
        return Err(WorldError::NoBv(bv_index));
    };
    let mut prior = ActivePrior {
        header: Header { seq: prior_id, stamp_ns },
        prior_id,
        zone_kind: ZoneKind::from(conflict.zone.kind).code(),
        bv_zone_enter_s_m: conflict.zone.bv.enter_s_m,
        bv_zone_exit_s_m: conflict.zone.bv.exit_s_m,
        vut_zone_enter_s_m: conflict.zone.vut.enter_s_m,
        vut_zone_exit_s_m: conflict.zone.vut.exit_s_m,
        vut_speed_mps: scenario.vut.agent.initial_speed_mps,
        ..ActivePrior::default()
    };
    prior.set_target(scenario.target);
    // The stop line of a BV that gives way, where the card says its path enters a junction (a
    // junction past its zone's entry gives none).
    let length = bv.agent.vehicle.geometry.length_m;
    prior.set_bv_stop_line(bv.junction_entry_m.and_then(|j| stop_line_station(j, length, conflict.zone.bv.enter_s_m)));
    path_points(&bv.agent.route, &mut prior.bv_path)?;
    path_points(&scenario.vut.agent.route, &mut prior.vut_path)?;
    // What the cloud would send for this target: the card's speed profile re-timed for it (a
    // prior is timed for its target; a card's profile is not).
    let reference = scenario.realism_reference(bv_index).unwrap_or_else(|| bv.reference.clone());
    // Every PROFILE_RATE_HZ, or as often as the whole run fits the prior's samples.
    let capacity = prior.bv_profile.capacity();
    let period = (1.0 / PROFILE_RATE_HZ).max(scenario.duration_s / capacity.saturating_sub(1).max(1) as f64);
    for [t_s, s_m, v_mps] in reference.samples(scenario.duration_s, period, capacity) {
        let sample = ProfileSample { t_s, s_m, v_mps };
        prior.bv_profile.push(sample).map_err(|_| PriorError::Capacity { what: "profile" })?;
    }
    prior.check().map_err(PriorError::Malformed)?;
    Ok(prior)
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing)]
    use super::*;

    fn root() -> std::path::PathBuf {
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
    }

    #[test]
    fn a_card_round_trips_through_its_prior_into_the_same_world() {
        let sc = v2t_sim::files::load_scenario(&root().join("config/scenarios/left_turn_basic.toml")).unwrap();
        let prior = prior_of_card(&sc, 0, 42, 7).unwrap();
        let bv = &sc.bvs[0];
        let vehicles = Vehicles { bv: &bv.agent.vehicle, vut: &sc.vut.agent.vehicle };
        let world = from_prior("again", &prior, vehicles, sc.settings.clone(), VutModel::IdmNormal).unwrap();
        assert!((world.bvs[0].agent.route.length() - bv.agent.route.length()).abs() < 0.05);
        assert!((world.vut.agent.route.length() - sc.vut.agent.route.length()).abs() < 0.05);
        let (a, b) = (world.conflicts[0].zone, sc.conflicts[0].zone);
        assert_eq!((a.kind, a.bv, a.vut), (b.kind, b.bv, b.vut));
        assert_eq!(world.target, sc.target);
        // And its stop line: the world rebuilt from the prior gives the regulator the same one.
        let line = prior.bv_stop_line().expect("the left turn's BV crosses in a junction");
        let entry = world.bvs[0].junction_entry_m.unwrap();
        assert!((entry - bv.junction_entry_m.unwrap()).abs() < 1e-9, "{entry}");
        assert_eq!(prior_of_card(&world, 0, 42, 7).unwrap().bv_stop_line(), Some(line));
        // The prior carries the card's speed profile re-timed for the card's target (what the
        // cloud would send for it): slower up to the key point here, the card's own speed after.
        let timed = sc.realism_reference(0).unwrap();
        for t in [0.0, 2.0, 5.0, 20.0] {
            assert!((world.bvs[0].reference.speed_at(t) - timed.speed_at(t)).abs() < 0.2, "t = {t}");
        }
        assert!(timed.speed_at(0.0) < bv.reference.speed_at(0.0) - 1.0);
        assert!((world.bvs[0].reference.speed_at(20.0) - bv.reference.speed_at(20.0)).abs() < 0.2);
        assert!(matches!(prior_of_card(&sc, 3, 1, 1), Err(WorldError::NoBv(3))));
    }
}
