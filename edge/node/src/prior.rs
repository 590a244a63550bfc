//! Priors on the BV: building the IPC [`ActivePrior`] from a scenario (the stand-in for the cloud
//! upload until the MQTT link exists), and turning a received one back into paths the regulator
//! and the tracker use.

use v2t_model::Style;
use v2t_model::geometry::Point2;
use v2t_model::metrics::{ConflictKind, OccupancyInterval};
use v2t_model::path::ReferencePath;
use v2t_sim::scenario::Scenario;
use v2t_wire::{ActivePrior, Code, Header, MAX_PATH_POINTS, ProfileSample, StyleCode, Vec2, Vector, ZoneKind};

use crate::error::EdgeError;

/// Samples of the BV's reference timing in a prior built from a scenario, per second.
const PROFILE_RATE_HZ: f64 = 10.0;

fn path_points(path: &ReferencePath, out: &mut v2t_wire::StaticVec<Vec2, MAX_PATH_POINTS>) -> Result<(), EdgeError> {
    let n = MAX_PATH_POINTS;
    let len = path.length();
    for i in 0..n {
        let p = path.point_at(len * i as f64 / (n - 1) as f64);
        out.push(Vec2 { x_m: p.x, y_m: p.y }).map_err(|e| EdgeError::Prior(format!("path: {e:?}")))?;
    }
    Ok(())
}

/// The prior of BV `bv_index` of `scenario`: its path and timing, the VUT's route, their
/// conflict zone, τ and style. `prior_id` identifies it; `stamp_ns` is when it was issued.
pub fn from_scenario(
    scenario: &Scenario,
    bv_index: usize,
    prior_id: u64,
    stamp_ns: u64,
) -> Result<ActivePrior, EdgeError> {
    let bv = scenario.bvs.get(bv_index).ok_or_else(|| EdgeError::Prior(format!("no BV {bv_index} in the scenario")))?;
    let conflict = scenario
        .conflict_of(bv_index)
        .ok_or_else(|| EdgeError::Prior(format!("BV {} has no conflict with the VUT", bv.agent.id)))?;
    let mut prior = ActivePrior {
        header: Header { seq: prior_id, stamp_ns },
        prior_id,
        tau_s: scenario.tau_s,
        style: match scenario.style {
            Style::Rush => StyleCode::Rush,
            Style::Yield => StyleCode::Yield,
        }
        .code(),
        zone_kind: match conflict.zone.kind {
            ConflictKind::Crossing => ZoneKind::Crossing,
            ConflictKind::Merge => ZoneKind::Merge,
        }
        .code(),
        bv_zone_enter_s_m: conflict.zone.b.enter_s_m,
        bv_zone_exit_s_m: conflict.zone.b.exit_s_m,
        vut_zone_enter_s_m: conflict.zone.a.enter_s_m,
        vut_zone_exit_s_m: conflict.zone.a.exit_s_m,
        ..ActivePrior::default()
    };
    path_points(&bv.agent.route, &mut prior.bv_path)?;
    path_points(&scenario.vut.agent.route, &mut prior.vut_path)?;
    let samples = ((scenario.duration_s * PROFILE_RATE_HZ) as usize + 1).min(prior.bv_profile.capacity());
    for i in 0..samples {
        let t_s = i as f64 / PROFILE_RATE_HZ;
        let sample = ProfileSample { t_s, s_m: bv.reference.distance_at(t_s), v_mps: bv.reference.speed_at(t_s) };
        prior.bv_profile.push(sample).map_err(|e| EdgeError::Prior(format!("profile: {e:?}")))?;
    }
    prior.check().map_err(|e| EdgeError::Prior(e.to_owned()))?;
    Ok(prior)
}

/// A received prior, checked and turned into paths.
#[derive(Debug, Clone)]
pub struct PriorContext {
    /// Its identifier.
    pub prior_id: u64,
    /// The BV's reference path.
    pub bv_path: ReferencePath,
    /// The VUT's route.
    pub vut_path: ReferencePath,
    /// Zone along the BV's path.
    pub zone_bv: OccupancyInterval,
    /// Zone along the VUT's route.
    pub zone_vut: OccupancyInterval,
    /// Crossing or merge.
    pub zone_kind: ConflictKind,
    /// Target PET, s.
    pub tau_s: f64,
    /// Who passes first.
    pub style: Style,
    /// Reference speed over arc length: (s, v), s increasing.
    profile: Vec<(f64, f64)>,
}

impl PriorContext {
    /// Checks `prior` and builds its paths (allocates: once per prior, not per cycle).
    pub fn new(prior: &ActivePrior) -> Result<Self, EdgeError> {
        prior.check().map_err(|e| EdgeError::Prior(e.to_owned()))?;
        let style = match StyleCode::from_code(prior.style).map_err(|e| EdgeError::Prior(e.to_string()))? {
            StyleCode::Rush => Style::Rush,
            StyleCode::Yield => Style::Yield,
        };
        let zone_kind = match ZoneKind::from_code(prior.zone_kind).map_err(|e| EdgeError::Prior(e.to_string()))? {
            ZoneKind::Crossing => ConflictKind::Crossing,
            ZoneKind::Merge => ConflictKind::Merge,
        };
        let path = |pts: &[Vec2], what: &str| {
            let points: Vec<Point2> = pts.iter().map(|p| Point2 { x: p.x_m, y: p.y_m }).collect();
            ReferencePath::from_points(&points).map_err(|e| EdgeError::Prior(format!("{what} path: {e}")))
        };
        let mut profile: Vec<(f64, f64)> = Vec::with_capacity(prior.bv_profile.len());
        for q in prior.bv_profile.as_slice() {
            // Keep s strictly increasing (a standstill in the reference repeats s).
            if profile.last().is_none_or(|(s, _)| q.s_m > *s) {
                profile.push((q.s_m, q.v_mps.max(0.0)));
            }
        }
        Ok(Self {
            prior_id: prior.prior_id,
            bv_path: path(prior.bv_path.as_slice(), "BV")?,
            vut_path: path(prior.vut_path.as_slice(), "VUT")?,
            zone_bv: OccupancyInterval { enter_s_m: prior.bv_zone_enter_s_m, exit_s_m: prior.bv_zone_exit_s_m },
            zone_vut: OccupancyInterval { enter_s_m: prior.vut_zone_enter_s_m, exit_s_m: prior.vut_zone_exit_s_m },
            zone_kind,
            tau_s: prior.tau_s,
            style,
            profile,
        })
    }

    /// The reference speed where the BV is, m/s (linear in arc length; the ends hold).
    pub fn reference_speed_at(&self, s_m: f64) -> f64 {
        let (Some(first), Some(last)) = (self.profile.first(), self.profile.last()) else { return 0.0 };
        if s_m <= first.0 {
            return first.1;
        }
        if s_m >= last.0 {
            return last.1;
        }
        let i = self.profile.partition_point(|(s, _)| *s <= s_m);
        match (self.profile.get(i.saturating_sub(1)), self.profile.get(i)) {
            (Some(a), Some(b)) => a.1 + (b.1 - a.1) * (s_m - a.0) / (b.0 - a.0),
            _ => last.1,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scenario() -> Scenario {
        let card = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config/scenarios/left_turn_basic.toml");
        v2t_sim::files::load_scenario(&card).unwrap()
    }

    #[test]
    fn a_prior_from_a_scenario_round_trips_into_the_same_geometry() {
        let sc = scenario();
        let prior = from_scenario(&sc, 0, 42, 7).unwrap();
        let ctx = PriorContext::new(&prior).unwrap();
        let bv = &sc.bvs[0];
        assert!((ctx.bv_path.length() - bv.agent.route.length()).abs() < 0.05);
        assert!((ctx.vut_path.length() - sc.vut.agent.route.length()).abs() < 0.05);
        let c = sc.conflict_of(0).unwrap();
        assert_eq!(ctx.zone_bv, c.zone.b);
        assert_eq!(ctx.tau_s, sc.tau_s);
        assert_eq!(ctx.style, sc.style);
        for t in [0.0, 2.0, 5.0] {
            let s = bv.reference.distance_at(t);
            assert!((ctx.reference_speed_at(s) - bv.reference.speed_at(t)).abs() < 0.2, "t = {t}");
        }
    }

    #[test]
    fn a_broken_prior_is_refused_with_a_reason() {
        let sc = scenario();
        let mut prior = from_scenario(&sc, 0, 1, 1).unwrap();
        prior.style = 9;
        assert_eq!(PriorContext::new(&prior).unwrap_err().to_string(), "prior: unknown style code 9");
        let mut prior = from_scenario(&sc, 0, 1, 1).unwrap();
        prior.tau_s = f64::NAN;
        assert!(PriorContext::new(&prior).is_err());
        assert!(from_scenario(&sc, 3, 1, 1).is_err());
    }
}
