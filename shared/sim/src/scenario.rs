//! A scenario ready to run: routes built, vehicles resolved, conflict zones computed.

use v2t_model::Target;
use v2t_model::kinematics::State;
use v2t_model::metrics::{ConflictOptions, ConflictZone, Dimensions, conflict_zones};
use v2t_model::path::{PathError, ReferencePath};
use v2t_model::vehicle::VehicleConfig;

use crate::config::{ScenarioCard, SimSettings};
use crate::vut::VutModel;

/// Spacing at which card paths are sampled, m.
const PATH_SAMPLING_M: f64 = 0.5;

/// A card that cannot be turned into a runnable scenario.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ScenarioError {
    /// A path could not be built.
    #[error("{field}: {source}")]
    Path {
        /// Which path (`vut.path`, `bvs[0].path`).
        field: String,
        /// What went wrong.
        source: PathError,
    },
    /// Two vehicles overlap where they start.
    #[error("{field}: `{a}` and `{b}` overlap where they start (their footprints intersect at t = 0)")]
    StartOverlap {
        /// The later of the two in the card (`bvs[0].path`).
        field: String,
        /// One vehicle.
        a: String,
        /// The other.
        b: String,
    },
    /// A BV's path never meets the VUT's: there is no interaction to test.
    #[error("bvs[{index}].path: the BV `{id}` never comes into conflict with the VUT's path")]
    NoConflict {
        /// Index of the BV.
        index: usize,
        /// Its id.
        id: String,
    },
    /// The card names a VUT model that does not exist.
    #[error("vut.model: {0}")]
    UnknownModel(String),
    /// The number of vehicle configurations does not match the card.
    #[error("{expected} BV vehicle configurations expected, {got} given")]
    VehicleCount {
        /// BVs in the card.
        expected: usize,
        /// Configurations given.
        got: usize,
    },
}

/// A vehicle with its route.
#[derive(Debug, Clone)]
pub struct Agent {
    /// Unique id (`vut`, `bv1`, …).
    pub id: String,
    /// Vehicle description.
    pub vehicle: VehicleConfig,
    /// Route (VUT) or reference path (BV); the vehicle starts at its beginning.
    pub route: ReferencePath,
    /// Speed at the start, m/s.
    pub initial_speed_mps: f64,
}

impl Agent {
    /// Footprint size.
    pub fn dims(&self) -> Dimensions {
        Dimensions { length_m: self.vehicle.geometry.length_m, width_m: self.vehicle.geometry.width_m }
    }
}

/// Piecewise-linear speed over time, held constant after the last point.
#[derive(Debug, Clone, PartialEq)]
pub struct SpeedProfile {
    points: Vec<[f64; 2]>,
}

impl SpeedProfile {
    /// From `[t_s, speed_mps]` points with increasing times (validated by the card).
    pub fn new(points: Vec<[f64; 2]>) -> Self {
        Self { points }
    }

    /// Reference speed at `t_s`, m/s.
    pub fn speed_at(&self, t_s: f64) -> f64 {
        let k = self.points.partition_point(|[t, _]| *t <= t_s);
        match (k.checked_sub(1).and_then(|i| self.points.get(i)), self.points.get(k)) {
            (Some([t0, v0]), Some([t1, v1])) => v0 + (v1 - v0) * (t_s - t0) / (t1 - t0),
            (Some([_, v]), None) | (None, Some([_, v])) => *v,
            (None, None) => 0.0,
        }
    }

    /// Reference acceleration at `t_s` (slope of the current piece), m/s².
    pub fn accel_at(&self, t_s: f64) -> f64 {
        let k = self.points.partition_point(|[t, _]| *t <= t_s);
        match (k.checked_sub(1).and_then(|i| self.points.get(i)), self.points.get(k)) {
            (Some([t0, v0]), Some([t1, v1])) => (v1 - v0) / (t1 - t0),
            _ => 0.0,
        }
    }

    /// Distance covered from `t = 0` to `t_s` at the reference speed, m (exact for the piecewise-linear profile).
    pub fn distance_at(&self, t_s: f64) -> f64 {
        let mut dist = 0.0;
        let mut t_prev = 0.0;
        let mut v_prev = self.speed_at(0.0);
        for [t, v] in self.points.iter().copied().filter(|[t, _]| *t > 0.0) {
            if t >= t_s {
                break;
            }
            dist += 0.5 * (v_prev + v) * (t - t_prev);
            t_prev = t;
            v_prev = v;
        }
        dist + 0.5 * (v_prev + self.speed_at(t_s)) * (t_s - t_prev).max(0.0)
    }
}

/// Slowest VUT for which a card's reference is re-timed for the target, m/s.
const MIN_TIMING_SPEED_MPS: f64 = 0.5;
/// Shortest time to the key point a re-timed reference may have, s.
const MIN_TIMING_S: f64 = 0.5;
/// Length of the ramp between the re-timed and the unchanged part of a reference, s.
const RETIME_RAMP_S: f64 = 0.1;
/// Steps of the search for where a reference reaches a station, s.
const RETIME_SEARCH_STEP_S: f64 = 0.05;
/// Longest a reference is searched for its key point, s.
const RETIME_SEARCH_MAX_S: f64 = 600.0;

impl SpeedProfile {
    /// When the profile (from arc length 0 at `t = 0`) first reaches `station_m`, s (searched in
    /// steps of 0.05 s, then interpolated; `None` within 600 s).
    pub fn time_at_distance(&self, station_m: f64) -> Option<f64> {
        if station_m <= 0.0 {
            return Some(0.0);
        }
        let mut t = 0.0;
        let mut d = 0.0;
        while t < RETIME_SEARCH_MAX_S {
            let t1 = t + RETIME_SEARCH_STEP_S;
            let d1 = self.distance_at(t1);
            if d1 >= station_m {
                return Some(if d1 > d { t + (t1 - t) * (station_m - d) / (d1 - d) } else { t1 });
            }
            (t, d) = (t1, d1);
        }
        None
    }

    /// The profile sampled every `period_s` from 0 to `duration_s` (the end included when it
    /// falls on a sample, to rounding), at most `max` samples: `(t_s, distance_m, speed_mps)` — what a prior's
    /// timing along its path carries.
    pub fn samples(&self, duration_s: f64, period_s: f64, max: usize) -> impl Iterator<Item = [f64; 3]> + Clone + '_ {
        let n =
            if period_s > 0.0 && duration_s >= 0.0 { (duration_s / period_s + 1e-9).floor() as usize + 1 } else { 1 };
        (0..n.min(max)).map(move |k| {
            let t = k as f64 * period_s;
            [t, self.distance_at(t), self.speed_at(t)]
        })
    }

    /// This profile re-timed so that it reaches `key_m` at `t_key_s` instead of when it does: the
    /// part before is stretched (or compressed) in time, its speeds scaled inversely so the
    /// distance is kept; the part after is unchanged, shifted in time, joined by a 0.1 s ramp.
    /// `None` when the profile never reaches `key_m` or `t_key_s` is under 0.5 s.
    pub fn retimed(&self, key_m: f64, t_key_s: f64) -> Option<SpeedProfile> {
        if !(t_key_s.is_finite() && t_key_s >= MIN_TIMING_S) {
            return None;
        }
        let t_r = self.time_at_distance(key_m)?;
        if t_r < 1e-6 {
            return None;
        }
        let k = t_key_s / t_r;
        let mut points: Vec<[f64; 2]> = vec![[0.0, self.speed_at(0.0) / k]];
        points.extend(self.points.iter().filter(|[t, _]| *t > 0.0 && *t < t_r).map(|[t, v]| [t * k, v / k]));
        points.push([t_key_s, self.speed_at(t_r) / k]);
        points.push([t_key_s + RETIME_RAMP_S, self.speed_at(t_r)]);
        points.extend(
            self.points.iter().filter(|[t, _]| *t > t_r + 1e-9).map(|[t, v]| [t - t_r + t_key_s + RETIME_RAMP_S, *v]),
        );
        Some(SpeedProfile::new(points))
    }
}

/// A BV and the reference it is meant to follow.
#[derive(Debug, Clone)]
pub struct BvSetup {
    /// The vehicle and its reference path.
    pub agent: Agent,
    /// Reference speed over time.
    pub reference: SpeedProfile,
    /// Whether `reference` was made for the scenario's target (a prior generated for τ and the
    /// style), so its timing at the conflict is the one the target asks for. A card's speed
    /// profile is not: [`Scenario::realism_reference`] re-times it.
    pub timed_for_target: bool,
    /// Where its path enters the junction of its conflict, m along it (from the map; `None`: no
    /// junction, or no map): a BV that gives way stops before it.
    pub junction_entry_m: Option<f64>,
}

/// The VUT and its driver's wishes.
#[derive(Debug, Clone)]
pub struct VutSetup {
    /// The vehicle and its route.
    pub agent: Agent,
    /// Speed the driver wants to keep, m/s.
    pub desired_speed_mps: f64,
    /// Driver model the card asks for.
    pub default_model: VutModel,
}

/// The conflict between one BV and the VUT.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Conflict {
    /// Index of the BV in [`Scenario::bvs`].
    pub bv_index: usize,
    /// The zone.
    pub zone: ConflictZone,
}

/// A runnable scenario.
#[derive(Debug, Clone)]
pub struct Scenario {
    /// Name from the card.
    pub name: String,
    /// Description from the card.
    pub description: String,
    /// Target PET τ and the intended passing order.
    pub target: Target,
    /// Simulated duration, s.
    pub duration_s: f64,
    /// Simulation settings.
    pub settings: SimSettings,
    /// The vehicle under test.
    pub vut: VutSetup,
    /// The background vehicles.
    pub bvs: Vec<BvSetup>,
    /// The first conflict of every BV with the VUT, in BV order.
    pub conflicts: Vec<Conflict>,
}

impl Scenario {
    /// Builds the scenario of a validated card, with the vehicles its files name already loaded
    /// (`bv_vehicles` in the card's BV order).
    pub fn from_card(
        card: &ScenarioCard,
        settings: SimSettings,
        vut_vehicle: VehicleConfig,
        bv_vehicles: Vec<VehicleConfig>,
    ) -> Result<Self, ScenarioError> {
        if bv_vehicles.len() != card.bvs.len() {
            return Err(ScenarioError::VehicleCount { expected: card.bvs.len(), got: bv_vehicles.len() });
        }
        let build = |spec: &v2t_model::path::PathSpec, field: String| {
            spec.builder().build(PATH_SAMPLING_M).map_err(|source| ScenarioError::Path { field, source })
        };
        let vut = VutSetup {
            agent: Agent {
                id: "vut".into(),
                vehicle: vut_vehicle,
                route: build(&card.vut.path, "vut.path".into())?,
                initial_speed_mps: card.vut.initial_speed_mps,
            },
            desired_speed_mps: card.vut.desired_speed_mps,
            default_model: card.vut.model.parse().map_err(ScenarioError::UnknownModel)?,
        };
        let mut bvs = Vec::with_capacity(card.bvs.len());
        for (i, (bv, vehicle)) in card.bvs.iter().zip(bv_vehicles).enumerate() {
            bvs.push(BvSetup {
                agent: Agent {
                    id: bv.id.clone(),
                    vehicle,
                    route: build(&bv.path, format!("bvs[{i}].path"))?,
                    initial_speed_mps: bv.initial_speed_mps,
                },
                reference: SpeedProfile::new(bv.speed_profile.clone()),
                timed_for_target: false,
                junction_entry_m: bv.junction_entry_m,
            });
        }
        start_apart(&vut, &bvs)?;
        let conflicts = first_conflicts(&vut, &bvs)?;
        Ok(Self {
            name: card.name.clone(),
            description: card.description.clone(),
            target: card.target,
            duration_s: card.duration_s,
            settings,
            vut,
            bvs,
            conflicts,
        })
    }

    /// A scenario of one BV from paths already built — what the simulated ECU runs when the BV's
    /// prior comes from the cloud: the VUT drives `vut_route` from its start at `vut_speed_mps`
    /// (wishing to keep it) with driver `vut_model`; the BV's reference is `bv_route` with
    /// `bv_reference`.
    pub fn from_paths(
        paths: ScenarioPaths,
        settings: SimSettings,
        vut_vehicle: VehicleConfig,
        bv_vehicle: VehicleConfig,
    ) -> Result<Self, ScenarioError> {
        let bv_speed = paths.bv_reference.speed_at(0.0);
        let vut = VutSetup {
            agent: Agent {
                id: "vut".into(),
                vehicle: vut_vehicle,
                route: paths.vut_route,
                initial_speed_mps: paths.vut_speed_mps,
            },
            desired_speed_mps: paths.vut_speed_mps,
            default_model: paths.vut_model,
        };
        let bvs = vec![BvSetup {
            agent: Agent { id: paths.bv_id, vehicle: bv_vehicle, route: paths.bv_route, initial_speed_mps: bv_speed },
            reference: paths.bv_reference,
            timed_for_target: true,
            junction_entry_m: paths.bv_junction_entry_m,
        }];
        start_apart(&vut, &bvs)?;
        let conflicts = match paths.conflict {
            Some(zone) => vec![Conflict { bv_index: 0, zone }],
            None => first_conflicts(&vut, &bvs)?,
        };
        Ok(Self {
            name: paths.name,
            description: "built from a prior's paths".into(),
            target: paths.target,
            duration_s: paths.duration_s,
            settings,
            vut,
            bvs,
            conflicts,
        })
    }

    /// The reference the regulator's realism term weighs for BV `bv_index`: its reference when
    /// that was made for the target; else (a card's speed profile) the same profile re-timed up to
    /// the BV's key point (zone exit in rush, entry in yield) so that it gets there when the target
    /// asks if the VUT kept its initial speed, and unchanged after it. `None` when no such timing
    /// exists (no conflict, a VUT standing, a key time in the past, or a reference that never gets
    /// to the key point).
    pub fn realism_reference(&self, bv_index: usize) -> Option<SpeedProfile> {
        let bv = self.bvs.get(bv_index)?;
        if bv.timed_for_target {
            return Some(bv.reference.clone());
        }
        let zone = self.conflict_of(bv_index)?.zone;
        let v_vut = self.vut.agent.initial_speed_mps;
        if v_vut < MIN_TIMING_SPEED_MPS {
            return None;
        }
        let tau = self.target.tau_s();
        let (key_s, t_target) = match self.target.style() {
            v2t_model::Style::Rush => (zone.bv.exit_s_m, zone.vut.enter_s_m / v_vut - tau),
            v2t_model::Style::Yield => (zone.bv.enter_s_m, zone.vut.exit_s_m / v_vut + tau),
        };
        bv.reference.retimed(key_s, t_target)
    }

    /// The conflict of BV `bv_index`.
    pub fn conflict_of(&self, bv_index: usize) -> Option<&Conflict> {
        self.conflicts.iter().find(|c| c.bv_index == bv_index)
    }
}

/// What [`Scenario::from_paths`] builds from.
#[derive(Debug, Clone)]
pub struct ScenarioPaths {
    /// Name of the run.
    pub name: String,
    /// Target PET τ and the intended passing order.
    pub target: Target,
    /// Simulated duration, s.
    pub duration_s: f64,
    /// The VUT's route.
    pub vut_route: ReferencePath,
    /// The VUT's start (and wished) speed, m/s.
    pub vut_speed_mps: f64,
    /// The VUT's driver.
    pub vut_model: VutModel,
    /// The BV's id.
    pub bv_id: String,
    /// The BV's reference path.
    pub bv_route: ReferencePath,
    /// The BV's reference speed over time.
    pub bv_reference: SpeedProfile,
    /// The conflict zone the BV regulates, when the prior fixes it; `None`: the first zone of the
    /// two paths. Measuring the zone the BV regulates matters when the paths share more than one
    /// (a generated lane change that runs alongside).
    pub conflict: Option<ConflictZone>,
    /// Where the BV's path enters the junction of its conflict, m along it (the prior's stop line
    /// brought back to the junction's edge); `None`: none.
    pub bv_junction_entry_m: Option<f64>,
}

/// The first conflict of every BV with the VUT; a BV without one is an error.
/// Every pair of vehicles apart at their starts (a BV placed on the VUT, or on another BV, is a
/// collision at t = 0, not a test).
fn start_apart(vut: &VutSetup, bvs: &[BvSetup]) -> Result<(), ScenarioError> {
    let agents: Vec<&Agent> = std::iter::once(&vut.agent).chain(bvs.iter().map(|b| &b.agent)).collect();
    let footprints: Vec<_> = agents
        .iter()
        .map(|a| {
            let p = a.route.point_at(0.0);
            let theta_rad = a.route.heading_at(0.0);
            a.vehicle.footprint(&State { px: p.x, py: p.y, theta_rad, speed_mps: a.initial_speed_mps })
        })
        .collect();
    for (j, (b, fb)) in agents.iter().zip(&footprints).enumerate().skip(1) {
        if let Some((a, _)) = agents.iter().zip(&footprints).take(j).find(|(_, fa)| fa.overlaps(fb)) {
            return Err(ScenarioError::StartOverlap {
                field: format!("bvs[{}].path", j - 1),
                a: a.id.clone(),
                b: b.id.clone(),
            });
        }
    }
    Ok(())
}

fn first_conflicts(vut: &VutSetup, bvs: &[BvSetup]) -> Result<Vec<Conflict>, ScenarioError> {
    let mut conflicts = Vec::with_capacity(bvs.len());
    for (bv_index, bv) in bvs.iter().enumerate() {
        let zones = conflict_zones(
            &vut.agent.route,
            vut.agent.dims(),
            &bv.agent.route,
            bv.agent.dims(),
            &ConflictOptions::default(),
        );
        let zone = zones
            .into_iter()
            .next()
            .ok_or_else(|| ScenarioError::NoConflict { index: bv_index, id: bv.agent.id.clone() })?;
        conflicts.push(Conflict { bv_index, zone });
    }
    Ok(conflicts)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn speed_profile_interpolates_and_integrates() {
        let p = SpeedProfile::new(vec![[0.0, 10.0], [2.0, 6.0], [4.0, 6.0]]);
        assert_eq!(p.speed_at(1.0), 8.0);
        assert_eq!(p.speed_at(10.0), 6.0);
        assert_eq!(p.accel_at(1.0), -2.0);
        assert_eq!(p.accel_at(5.0), 0.0);
        // 0–2 s: mean 8 m/s → 16 m; 2–5 s: 6 m/s → 18 m.
        assert!((p.distance_at(5.0) - 34.0).abs() < 1e-12);
        assert!((p.distance_at(1.0) - 9.0).abs() < 1e-12);
        let late = SpeedProfile::new(vec![[1.0, 5.0]]);
        assert_eq!(late.speed_at(0.0), 5.0);
        assert!((late.distance_at(2.0) - 10.0).abs() < 1e-12);
    }

    #[test]
    fn a_retimed_profile_reaches_the_key_point_when_asked_and_keeps_its_speed_after() {
        let p = SpeedProfile::new(vec![[0.0, 10.0], [2.0, 6.0], [4.0, 6.0]]);
        // It reaches 34 m at 5 s; asked for 8 s.
        assert!((p.time_at_distance(34.0).unwrap() - 5.0).abs() < 1e-6);
        let r = p.retimed(34.0, 8.0).unwrap();
        assert!((r.time_at_distance(34.0).unwrap() - 8.0).abs() < 1e-3);
        assert!((r.speed_at(0.0) - 10.0 * 5.0 / 8.0).abs() < 1e-9, "slower by the same factor");
        assert!((r.speed_at(20.0) - 6.0).abs() < 1e-12, "after the key point its own speed");
        // Faster too; nothing sensible before 0.5 s or for a station never reached.
        assert!((p.retimed(34.0, 2.5).unwrap().time_at_distance(34.0).unwrap() - 2.5).abs() < 1e-3);
        assert_eq!(p.retimed(34.0, 0.2), None);
        assert_eq!(SpeedProfile::new(vec![[0.0, 0.0]]).retimed(10.0, 5.0), None);
    }

    #[test]
    fn a_cards_reference_is_retimed_for_the_target_and_a_priors_is_not() {
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
        let mut sc = crate::files::load_scenario(&root.join("config/scenarios/left_turn_basic.toml")).unwrap();
        let zone = sc.conflicts[0].zone;
        let v = sc.vut.agent.initial_speed_mps;
        for (style, key, t) in [
            (v2t_model::Style::Rush, zone.bv.exit_s_m, zone.vut.enter_s_m / v - 2.0),
            (v2t_model::Style::Yield, zone.bv.enter_s_m, zone.vut.exit_s_m / v + 2.0),
        ] {
            sc.target = Target::new(2.0, style).unwrap();
            let r = sc.realism_reference(0).unwrap();
            assert!((r.time_at_distance(key).unwrap() - t).abs() < 0.01, "{style}: {t} s");
        }
        sc.bvs[0].timed_for_target = true;
        assert_eq!(sc.realism_reference(0), Some(sc.bvs[0].reference.clone()));
    }
}
