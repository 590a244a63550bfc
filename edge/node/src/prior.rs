//! Priors on the BV: checking a prior uploaded over the cloud link ([`from_upload`]: validity,
//! time window, vehicle limits, drivable area) and building the IPC [`ActivePrior`] from it, building
//! one from a scenario card (the simulated ECU's stand-in for the cloud), and turning a received one
//! back into paths the regulator and the tracker use.

use v2t_map::drivable::DrivableArea;
use v2t_model::Style;
use v2t_model::geometry::Point2;
use v2t_model::grounded::{AgentRole, GroundedScenario};
use v2t_model::metrics::{ConflictKind, ConflictOptions, Dimensions, OccupancyInterval, conflict_zones, nearest_zone};
use v2t_model::path::ReferencePath;
use v2t_model::prior::TrajectoryPrior;
use v2t_model::validate::Validate;
use v2t_model::vehicle::VehicleLimits;
use v2t_sim::scenario::Scenario;
use v2t_wire::link::PriorUpload;
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
        vut_speed_mps: scenario.vut.agent.initial_speed_mps,
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

/// What a BV checks an uploaded prior against before it may reach the regulator.
#[derive(Debug, Clone)]
pub struct PriorChecks {
    /// The BV's limits (speed, acceleration, deceleration, jerk, lateral acceleration).
    pub limits: VehicleLimits,
    /// The BV's footprint (conflict zone).
    pub bv: Dimensions,
    /// The VUT's footprint.
    pub vut: Dimensions,
    /// The track's drivable area; every state of the BV's trajectory must lie on it.
    pub area: Option<DrivableArea>,
    /// How far off the drivable area a trajectory point may lie, m.
    pub geofence_margin_m: f64,
}

impl PriorChecks {
    /// The checks for a BV `bv` meeting a VUT `vut` (their limits and footprints), on `area` when
    /// given.
    pub fn for_vehicles(
        bv: &v2t_model::vehicle::VehicleConfig,
        vut: &v2t_model::vehicle::VehicleConfig,
        area: Option<DrivableArea>,
        geofence_margin_m: f64,
    ) -> Self {
        let dims = |v: &v2t_model::vehicle::VehicleConfig| Dimensions {
            length_m: v.geometry.length_m,
            width_m: v.geometry.width_m,
        };
        Self { limits: bv.limits, bv: dims(bv), vut: dims(vut), area, geofence_margin_m }
    }
}

/// Relative slack on the vehicle limits (the generator works to them; rounding must not refuse).
const LIMIT_SLACK: f64 = 1.01;

/// Checks an uploaded prior at Unix time `now_ms` — validity, time window, the BV's agent and its
/// conflict with the VUT, the vehicle limits, the drivable area — and builds the IPC prior with
/// `stamp_ns` (monotonic) as its header time. Every refusal names what failed.
pub fn from_upload(
    up: &PriorUpload,
    now_ms: u64,
    checks: &PriorChecks,
    stamp_ns: u64,
) -> Result<ActivePrior, EdgeError> {
    let refuse = |m: String| Err(EdgeError::Prior(format!("prior {}: {m}", up.prior_id)));
    let p = &up.prior;
    if let Err(e) = p.validate() {
        return refuse(format!("invalid: {e}"));
    }
    if up.valid_until_ms < up.valid_from_ms {
        return refuse(format!("validity window ends ({}) before it starts ({})", up.valid_until_ms, up.valid_from_ms));
    }
    if now_ms > up.valid_until_ms {
        return refuse(format!("expired {} ms ago", now_ms - up.valid_until_ms));
    }
    let Some(bv) = p.agents.iter().find(|a| a.id == up.bv_agent) else {
        return refuse(format!("has no agent `{}`", up.bv_agent));
    };
    if bv.role != AgentRole::Bv {
        return refuse(format!("agent `{}` is not a BV", up.bv_agent));
    }
    let Some(vut) = p.agents.iter().find(|a| a.role == AgentRole::Vut) else {
        return refuse("has no VUT trajectory".into());
    };
    let dt = p.dt_s;
    let l = &checks.limits;
    let mut prev_a: Option<f64> = None;
    for (k, (x, u)) in bv.states.iter().zip(&bv.controls).enumerate() {
        let t = k as f64 * dt;
        let a = u.accel_mps2;
        if x.speed_mps > l.max_speed_mps * LIMIT_SLACK || x.speed_mps < -0.1 {
            return refuse(format!("speed {:.2} m/s at t = {t:.1} s outside 0–{} m/s", x.speed_mps, l.max_speed_mps));
        }
        if a > l.max_accel_mps2 * LIMIT_SLACK || -a > l.max_decel_mps2 * LIMIT_SLACK {
            return refuse(format!(
                "acceleration {a:.2} m/s² at t = {t:.1} s outside −{}…{} m/s²",
                l.max_decel_mps2, l.max_accel_mps2
            ));
        }
        let lat = (x.speed_mps * u.yaw_rate_radps).abs();
        if lat > l.max_lat_accel_mps2 * LIMIT_SLACK {
            return refuse(format!(
                "lateral acceleration {lat:.2} m/s² at t = {t:.1} s above {} m/s²",
                l.max_lat_accel_mps2
            ));
        }
        if let Some(pa) = prev_a {
            let jerk = (a - pa).abs() / dt;
            if jerk > l.max_jerk_mps3 * LIMIT_SLACK {
                return refuse(format!("jerk {jerk:.1} m/s³ at t = {t:.1} s above {} m/s³", l.max_jerk_mps3));
            }
        }
        prev_a = Some(a);
    }
    if let Some(area) = &checks.area
        && let Some((k, q)) = area.first_outside(bv.states.iter().map(|x| x.position()), checks.geofence_margin_m)
    {
        return refuse(format!(
            "leaves the drivable area at t = {:.1} s ({:.1}, {:.1}) by more than {} m",
            k as f64 * dt,
            q.x,
            q.y,
            checks.geofence_margin_m
        ));
    }
    let bv_path = ReferencePath::through_states(&bv.states)
        .map_err(|e| EdgeError::Prior(format!("prior {}: BV path: {e}", up.prior_id)))?;
    let vut_path = ReferencePath::through_states(&vut.states)
        .map_err(|e| EdgeError::Prior(format!("prior {}: VUT path: {e}", up.prior_id)))?;
    let hint = p.conflicts.iter().find(|c| c.bv_id == up.bv_agent).map(|c| c.point);
    let options = ConflictOptions::default();
    let zone = nearest_zone(conflict_zones(&bv_path, checks.bv, &vut_path, checks.vut, &options), hint);
    let Some(zone) = zone else {
        return refuse(format!("the trajectories of `{}` and the VUT never share a conflict zone", up.bv_agent));
    };
    let mut prior = ActivePrior {
        header: Header { seq: up.prior_id, stamp_ns },
        prior_id: up.prior_id,
        tau_s: p.tau_s,
        style: match p.style {
            Style::Rush => StyleCode::Rush,
            Style::Yield => StyleCode::Yield,
        }
        .code(),
        zone_kind: match zone.kind {
            ConflictKind::Crossing => ZoneKind::Crossing,
            ConflictKind::Merge => ZoneKind::Merge,
        }
        .code(),
        bv_zone_enter_s_m: zone.a.enter_s_m,
        bv_zone_exit_s_m: zone.a.exit_s_m,
        vut_zone_enter_s_m: zone.b.enter_s_m,
        vut_zone_exit_s_m: zone.b.exit_s_m,
        vut_speed_mps: vut.states.first().map_or(0.0, |x| x.speed_mps.max(0.0)),
        ..ActivePrior::default()
    };
    path_points(&bv_path, &mut prior.bv_path)?;
    path_points(&vut_path, &mut prior.vut_path)?;
    let n = bv.states.len();
    let stride = n.div_ceil(prior.bv_profile.capacity()).max(1);
    let mut s_m = 0.0;
    let mut last = bv.states.first().map(|x| x.position());
    for (k, x) in bv.states.iter().enumerate() {
        if let Some(q) = last {
            s_m += q.dist(x.position());
        }
        last = Some(x.position());
        if k % stride == 0 || k + 1 == n {
            let sample = ProfileSample { t_s: k as f64 * dt, s_m, v_mps: x.speed_mps.max(0.0) };
            prior.bv_profile.push(sample).map_err(|e| EdgeError::Prior(format!("profile: {e:?}")))?;
        }
    }
    prior.check().map_err(|e| EdgeError::Prior(format!("prior {}: {e}", up.prior_id)))?;
    Ok(prior)
}

/// A prior upload in which every agent of `scenario` drives its grounded route at its start speed
/// from t = 0 for `horizon_s` (dt 0.1 s; states and controls consistent), valid over `valid_ms`
/// (Unix ms, from–until). A stand-in for generated priors in link tests and benches: it keeps the
/// routes and the conflict, not the agents' start times.
pub fn upload_along_routes(
    scenario: &GroundedScenario,
    prior_id: u64,
    horizon_s: f64,
    valid_ms: (u64, u64),
) -> Result<PriorUpload, EdgeError> {
    let prior = TrajectoryPrior::along_routes_at_start_speed(scenario, horizon_s)
        .map_err(|e| EdgeError::Prior(format!("stand-in prior: {e}")))?;
    let bv = scenario.bvs().next().ok_or_else(|| EdgeError::Prior("the scenario has no BV".into()))?;
    Ok(PriorUpload { prior_id, bv_agent: bv.id.clone(), valid_from_ms: valid_ms.0, valid_until_ms: valid_ms.1, prior })
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

/// Grounded scenarios on the proving ground and their checks, for the tests of this crate.
#[cfg(test)]
pub(crate) mod fixtures {
    #![allow(clippy::unwrap_used)]
    use super::*;

    fn root() -> std::path::PathBuf {
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
    }

    /// The example semantics `config/examples/<semantics>` grounded on the proving ground, and the map.
    pub(crate) fn grounded(semantics: &str) -> (v2t_map::Map, GroundedScenario) {
        let map = v2t_map::Map::load(&root().join("config/maps/proving_ground.xodr")).unwrap();
        let lib = v2t_map::library::TopologyLibrary::build(&map);
        let text = std::fs::read_to_string(root().join("config/examples").join(semantics)).unwrap();
        let sem = v2t_model::semantics::parse_semantics_json(&text).unwrap();
        let scenario = v2t_ground::ground(&map, &lib, &sem).unwrap().scenario;
        (map, scenario)
    }

    /// Its stand-in prior upload (25 s) and the checks of the bundled sedans on the proving ground.
    pub(crate) fn upload(semantics: &str, prior_id: u64, valid_ms: (u64, u64)) -> (PriorUpload, PriorChecks) {
        let (map, sc) = grounded(semantics);
        let up = upload_along_routes(&sc, prior_id, 25.0, valid_ms).unwrap();
        let load = |f: &str| -> v2t_model::vehicle::VehicleConfig {
            v2t_sim::files::load_toml(&root().join("config/vehicles").join(f)).unwrap()
        };
        let checks = PriorChecks::for_vehicles(
            &load("bv_sedan.toml"),
            &load("vut_sedan.toml"),
            Some(DrivableArea::from_map(&map)),
            0.5,
        );
        (up, checks)
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

    mod upload {
        use super::super::*;

        fn upload() -> (PriorUpload, PriorChecks) {
            let (up, checks) = fixtures::upload("semantics_left_turn.json", 77, (1_000, 61_000));
            (up, checks)
        }

        fn refused(up: &PriorUpload, checks: &PriorChecks, now_ms: u64) -> String {
            from_upload(up, now_ms, checks, 5).unwrap_err().to_string()
        }

        #[test]
        fn a_grounded_prior_is_accepted_and_its_zone_lies_where_the_routes_cross() {
            let (up, checks) = upload();
            let prior = from_upload(&up, 2_000, &checks, 5).unwrap();
            assert_eq!((prior.prior_id, prior.header.stamp_ns), (77, 5));
            let ctx = PriorContext::new(&prior).unwrap();
            assert_eq!((ctx.tau_s, ctx.style), (up.prior.tau_s, up.prior.style));
            let c = &up.prior.conflicts[0];
            let zone_mid = ctx.bv_path.point_at(0.5 * (ctx.zone_bv.enter_s_m + ctx.zone_bv.exit_s_m));
            assert!(zone_mid.dist(c.point) < 3.0, "zone at {zone_mid:?}, grounded conflict at {:?}", c.point);
            let vut_mid = ctx.vut_path.point_at(0.5 * (ctx.zone_vut.enter_s_m + ctx.zone_vut.exit_s_m));
            assert!(vut_mid.dist(c.point) < 3.0);
            let v0 = up.prior.agents[1].states[0].speed_mps;
            assert!((ctx.reference_speed_at(10.0) - v0).abs() < 1e-9);
        }

        #[test]
        fn every_broken_upload_is_refused_with_its_reason() {
            let (up, checks) = upload();
            assert!(refused(&up, &checks, 61_001).contains("expired 1 ms ago"));
            let mut u = up.clone();
            u.valid_until_ms = 500;
            assert!(refused(&u, &checks, 400).contains("ends"));
            let mut u = up.clone();
            u.bv_agent = "bv9".into();
            assert!(refused(&u, &checks, 2_000).contains("no agent `bv9`"));
            let mut u = up.clone();
            u.bv_agent = "vut".into();
            assert!(refused(&u, &checks, 2_000).contains("not a BV"));
            let mut u = up.clone();
            u.prior.agents.remove(0);
            assert!(refused(&u, &checks, 2_000).contains("no VUT"));
            let mut u = up.clone();
            u.prior.agents[1].states[40].py = f64::NAN;
            assert!(refused(&u, &checks, 2_000).contains("invalid"));
            let mut u = up.clone();
            for x in &mut u.prior.agents[1].states {
                x.speed_mps = checks.limits.max_speed_mps + 1.0;
            }
            assert!(refused(&u, &checks, 2_000).contains("speed"));
            let mut u = up.clone();
            u.prior.agents[1].controls[30].accel_mps2 = -(checks.limits.max_decel_mps2 + 1.0);
            assert!(refused(&u, &checks, 2_000).contains("acceleration"));
            let mut u = up.clone();
            u.prior.agents[1].controls[30].accel_mps2 = 0.5 * checks.limits.max_accel_mps2;
            u.prior.agents[1].controls[31].accel_mps2 = -0.5 * checks.limits.max_decel_mps2;
            assert!(refused(&u, &checks, 2_000).contains("jerk"));
            let mut u = up.clone();
            u.prior.agents[1].controls[50].yaw_rate_radps = 2.0;
            assert!(refused(&u, &checks, 2_000).contains("lateral acceleration"));
            let mut u = up.clone();
            for x in &mut u.prior.agents[1].states[60..] {
                x.px += 40.0;
            }
            assert!(refused(&u, &checks, 2_000).contains("leaves the drivable area at t = 6.0 s"));
            let mut u = up.clone();
            for x in &mut u.prior.agents[0].states {
                x.px += 500.0;
            }
            let far = PriorChecks { area: None, ..checks.clone() };
            assert!(refused(&u, &far, 2_000).contains("never share a conflict zone"));
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
