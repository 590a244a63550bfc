//! Priors on the BV: checking a prior uploaded over the cloud link ([`from_upload`]: validity,
//! time window, vehicle limits, drivable area) and building the IPC [`ActivePrior`] from it, and
//! turning a received one back into the paths, zone and target the regulator and the tracker use
//! ([`PriorContext`]). Every refusal is a [`PriorError`] that names what failed.

use v2t_game::reference::ReferenceSample;
use v2t_game::regulation::{Context, Zone};
use v2t_game::regulator::stop_line_station;
use v2t_map::drivable::DrivableArea;
use v2t_model::TargetError;
use v2t_model::geometry::Point2;
use v2t_model::grounded::AgentRole;
use v2t_model::metrics::{ConflictOptions, Dimensions, OccupancyInterval, conflict_zones, nearest_zone};
use v2t_model::path::{PathError, ReferencePath};
use v2t_model::validate::{Validate, ValidationError};
use v2t_model::vehicle::VehicleLimits;
use v2t_wire::link::PriorUpload;
use v2t_wire::{
    ActivePrior, Code, CodeError, Header, MAX_PATH_POINTS, PriorCodeError, ProfileSample, Vec2, Vector, ZoneKind,
};

/// Why a prior is refused, or cannot be turned into paths.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PriorError {
    /// The trajectories do not validate.
    #[error("invalid: {0}")]
    Invalid(ValidationError),
    /// The validity window is empty.
    #[error("validity window ends ({until_ms}) before it starts ({from_ms})")]
    Window {
        /// Start, Unix ms.
        from_ms: u64,
        /// End, Unix ms.
        until_ms: u64,
    },
    /// The validity window is over.
    #[error("expired {0} ms ago")]
    Expired(u64),
    /// The BV agent named is not in the prior.
    #[error("has no agent `{0}`")]
    NoAgent(String),
    /// The agent named is not a BV.
    #[error("agent `{0}` is not a BV")]
    NotBv(String),
    /// No VUT trajectory.
    #[error("has no VUT trajectory")]
    NoVut,
    /// The BV's trajectory leaves its vehicle's limits.
    #[error("{quantity} {value:.2} {unit} at t = {t_s:.1} s outside {bound}")]
    Limit {
        /// What: speed, acceleration, lateral acceleration, jerk.
        quantity: &'static str,
        /// Its value.
        value: f64,
        /// Unit.
        unit: &'static str,
        /// When, s from the prior's start.
        t_s: f64,
        /// The allowed range, in words.
        bound: String,
    },
    /// The BV's trajectory leaves the track.
    #[error("leaves the drivable area at t = {t_s:.1} s ({x_m:.1}, {y_m:.1}) by more than {margin_m} m")]
    OffTrack {
        /// When, s from the prior's start.
        t_s: f64,
        /// Where, m.
        x_m: f64,
        /// Where, m.
        y_m: f64,
        /// The margin allowed, m.
        margin_m: f64,
    },
    /// A path cannot be built from the trajectory or the IPC points.
    #[error("{who} path: {source}")]
    Path {
        /// `BV` or `VUT`.
        who: &'static str,
        /// Why.
        source: PathError,
    },
    /// The BV's and the VUT's trajectories never meet.
    #[error("the trajectories of `{0}` and the VUT never share a conflict zone")]
    NoConflict(String),
    /// The IPC prior is malformed (non-finite numbers, too few points, disordered intervals).
    #[error("{0}")]
    Malformed(&'static str),
    /// More points than the IPC prior holds.
    #[error("{what} does not fit the IPC prior")]
    Capacity {
        /// Which part.
        what: &'static str,
    },
    /// An unknown style or zone-kind code.
    #[error(transparent)]
    Code(#[from] CodeError),
    /// τ out of range.
    #[error(transparent)]
    Target(#[from] TargetError),
}

impl From<PriorCodeError> for PriorError {
    fn from(e: PriorCodeError) -> Self {
        match e {
            PriorCodeError::Code(c) => Self::Code(c),
            PriorCodeError::Target(t) => Self::Target(t),
        }
    }
}

/// An uploaded prior that was refused: which one, and why.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("prior {prior_id}: {reason}")]
pub struct Refused {
    /// The upload's prior id.
    pub prior_id: u64,
    /// Why.
    pub reason: PriorError,
}

/// `path` resampled into `out` at [`MAX_PATH_POINTS`] evenly spaced points.
pub fn path_points(
    path: &ReferencePath,
    out: &mut v2t_wire::StaticVec<Vec2, MAX_PATH_POINTS>,
) -> Result<(), PriorError> {
    let n = MAX_PATH_POINTS;
    let len = path.length();
    for i in 0..n {
        let p = path.point_at(len * i as f64 / (n - 1) as f64);
        out.push(Vec2 { x_m: p.x, y_m: p.y }).map_err(|_| PriorError::Capacity { what: "path" })?;
    }
    Ok(())
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
pub fn from_upload(up: &PriorUpload, now_ms: u64, checks: &PriorChecks, stamp_ns: u64) -> Result<ActivePrior, Refused> {
    accept(up, now_ms, checks, stamp_ns).map_err(|reason| Refused { prior_id: up.prior_id, reason })
}

fn accept(up: &PriorUpload, now_ms: u64, checks: &PriorChecks, stamp_ns: u64) -> Result<ActivePrior, PriorError> {
    let p = &up.prior;
    p.validate().map_err(PriorError::Invalid)?;
    let target = p.target;
    if up.valid_until_ms < up.valid_from_ms {
        return Err(PriorError::Window { from_ms: up.valid_from_ms, until_ms: up.valid_until_ms });
    }
    if now_ms > up.valid_until_ms {
        return Err(PriorError::Expired(now_ms - up.valid_until_ms));
    }
    let bv = p.agents.iter().find(|a| a.id == up.bv_agent).ok_or_else(|| PriorError::NoAgent(up.bv_agent.clone()))?;
    if bv.role != AgentRole::Bv {
        return Err(PriorError::NotBv(up.bv_agent.clone()));
    }
    let vut = p.agents.iter().find(|a| a.role == AgentRole::Vut).ok_or(PriorError::NoVut)?;
    within_limits(bv, p.dt_s, &checks.limits)?;
    if let Some(area) = &checks.area
        && let Some((k, q)) = area.first_outside(bv.states.iter().map(|x| x.position()), checks.geofence_margin_m)
    {
        return Err(PriorError::OffTrack {
            t_s: k as f64 * p.dt_s,
            x_m: q.x,
            y_m: q.y,
            margin_m: checks.geofence_margin_m,
        });
    }
    let bv_path = ReferencePath::through_states(&bv.states).map_err(|source| PriorError::Path { who: "BV", source })?;
    let vut_path =
        ReferencePath::through_states(&vut.states).map_err(|source| PriorError::Path { who: "VUT", source })?;
    let grounded = p.conflicts.iter().find(|c| c.bv_id == up.bv_agent);
    let hint = grounded.map(|c| c.point);
    let options = ConflictOptions::default();
    let zone = nearest_zone(conflict_zones(&vut_path, checks.vut, &bv_path, checks.bv, &options), hint)
        .ok_or_else(|| PriorError::NoConflict(up.bv_agent.clone()))?;
    let mut prior = ActivePrior {
        header: Header { seq: up.prior_id, stamp_ns },
        prior_id: up.prior_id,
        zone_kind: ZoneKind::from(zone.kind).code(),
        bv_zone_enter_s_m: zone.bv.enter_s_m,
        bv_zone_exit_s_m: zone.bv.exit_s_m,
        vut_zone_enter_s_m: zone.vut.enter_s_m,
        vut_zone_exit_s_m: zone.vut.exit_s_m,
        vut_speed_mps: vut.states.first().map_or(0.0, |x| x.speed_mps.max(0.0)),
        ..ActivePrior::default()
    };
    prior.set_target(target);
    // The stop line of a BV that gives way: where its path enters the junction of the conflict
    // (the grounding's point, from the map), its front just before it; none past its zone's entry.
    let stop_line = grounded
        .and_then(|c| c.bv_junction_entry)
        .and_then(|q| bv_path.project(q))
        .and_then(|f| stop_line_station(f.s_m, checks.bv.length_m, zone.bv.enter_s_m));
    prior.set_bv_stop_line(stop_line);
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
            let sample = ProfileSample { t_s: k as f64 * p.dt_s, s_m, v_mps: x.speed_mps.max(0.0) };
            prior.bv_profile.push(sample).map_err(|_| PriorError::Capacity { what: "profile" })?;
        }
    }
    prior.check().map_err(PriorError::Malformed)?;
    Ok(prior)
}

/// The BV's trajectory within its speed, acceleration, lateral-acceleration and jerk limits.
fn within_limits(bv: &v2t_model::prior::AgentTrajectory, dt: f64, l: &VehicleLimits) -> Result<(), PriorError> {
    let mut prev_a: Option<f64> = None;
    for (k, (x, u)) in bv.states.iter().zip(&bv.controls).enumerate() {
        let t_s = k as f64 * dt;
        let a = u.accel_mps2;
        if x.speed_mps > l.max_speed_mps * LIMIT_SLACK || x.speed_mps < -0.1 {
            let bound = format!("0–{} m/s", l.max_speed_mps);
            return Err(PriorError::Limit { quantity: "speed", value: x.speed_mps, unit: "m/s", t_s, bound });
        }
        if a > l.max_accel_mps2 * LIMIT_SLACK || -a > l.max_decel_mps2 * LIMIT_SLACK {
            let bound = format!("−{}…{} m/s²", l.max_decel_mps2, l.max_accel_mps2);
            return Err(PriorError::Limit { quantity: "acceleration", value: a, unit: "m/s²", t_s, bound });
        }
        let lat = (x.speed_mps * u.yaw_rate_radps).abs();
        if lat > l.max_lat_accel_mps2 * LIMIT_SLACK {
            let bound = format!("0–{} m/s²", l.max_lat_accel_mps2);
            return Err(PriorError::Limit { quantity: "lateral acceleration", value: lat, unit: "m/s²", t_s, bound });
        }
        if let Some(pa) = prev_a {
            let jerk = (a - pa).abs() / dt;
            if jerk > l.max_jerk_mps3 * LIMIT_SLACK {
                let bound = format!("0–{} m/s³", l.max_jerk_mps3);
                return Err(PriorError::Limit { quantity: "jerk", value: jerk, unit: "m/s³", t_s, bound });
            }
        }
        prev_a = Some(a);
    }
    Ok(())
}

/// A received prior, checked and turned into the regulator's [`Context`] (paths, zone, target, the
/// BV's timing); it reads as that context.
#[derive(Debug, Clone)]
pub struct PriorContext {
    /// Its identifier.
    pub prior_id: u64,
    /// What the regulator and the tracker use of it.
    pub context: Context,
}

impl std::ops::Deref for PriorContext {
    type Target = Context;

    fn deref(&self) -> &Context {
        &self.context
    }
}

impl PriorContext {
    /// Checks `prior` and builds its paths (allocates: once per prior, not per cycle).
    pub fn new(prior: &ActivePrior) -> Result<Self, PriorError> {
        prior.check().map_err(PriorError::Malformed)?;
        let target = prior.target()?;
        let kind = ZoneKind::from_code(prior.zone_kind)?.into();
        let path = |pts: &[Vec2], who: &'static str| {
            let points: Vec<Point2> = pts.iter().map(|p| Point2 { x: p.x_m, y: p.y_m }).collect();
            ReferencePath::from_points(&points).map_err(|source| PriorError::Path { who, source })
        };
        let zone = Zone {
            bv: OccupancyInterval { enter_s_m: prior.bv_zone_enter_s_m, exit_s_m: prior.bv_zone_exit_s_m },
            vut: OccupancyInterval { enter_s_m: prior.vut_zone_enter_s_m, exit_s_m: prior.vut_zone_exit_s_m },
            kind,
            stop_line_s_m: prior.bv_stop_line(),
        };
        let timing =
            prior.bv_profile.as_slice().iter().map(|q| ReferenceSample { t_s: q.t_s, s_m: q.s_m, v_mps: q.v_mps });
        let context = Context::new(
            path(prior.bv_path.as_slice(), "BV")?,
            path(prior.vut_path.as_slice(), "VUT")?,
            zone,
            target,
            timing,
        );
        Ok(Self { prior_id: prior.prior_id, context })
    }
}

/// Grounded scenarios on the proving ground and their checks, for the tests of this crate.
#[cfg(test)]
pub(crate) mod fixtures {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use v2t_model::grounded::GroundedScenario;

    fn root() -> std::path::PathBuf {
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
    }

    /// The example semantics `config/examples/<semantics>` grounded on the proving ground, and the map.
    pub(crate) fn grounded(semantics: &str) -> (v2t_map::Map, GroundedScenario) {
        let map = v2t_map::Map::load(&root().join("config/maps/proving_ground.xodr")).unwrap();
        let lib = v2t_map::library::TopologyLibrary::build(&map);
        let sem = v2t_files::read_semantics(&root().join("config/examples").join(semantics)).unwrap();
        let scenario = v2t_ground::ground(&map, &lib, &sem).unwrap().scenario;
        (map, scenario)
    }

    /// Its constant-speed prior along the routes (25 s) as an upload, and the checks of the bundled
    /// sedans on the proving ground.
    pub(crate) fn upload(semantics: &str, prior_id: u64, valid_ms: (u64, u64)) -> (PriorUpload, PriorChecks) {
        let (map, sc) = grounded(semantics);
        let prior = v2t_model::prior::TrajectoryPrior::along_routes_at_start_speed(&sc, 25.0).unwrap();
        let bv_agent = prior.bv_agent(None).unwrap().id.clone();
        let up = PriorUpload { prior_id, bv_agent, valid_from_ms: valid_ms.0, valid_until_ms: valid_ms.1, prior };
        let load = |f: &str| -> v2t_model::vehicle::VehicleConfig {
            v2t_files::load_toml(&root().join("config/vehicles").join(f)).unwrap()
        };
        let checks = PriorChecks::for_vehicles(
            &load("bv_sedan.toml"),
            &load("vut_sedan.toml"),
            Some(DrivableArea::from_map(&map)),
            0.5,
        );
        (up, checks)
    }

    /// The accepted IPC prior of the grounded left turn.
    pub(crate) fn left_turn(prior_id: u64) -> ActivePrior {
        let (up, checks) = upload("semantics_left_turn.json", prior_id, (0, u64::MAX));
        from_upload(&up, 1, &checks, 0).unwrap()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn upload() -> (PriorUpload, PriorChecks) {
        fixtures::upload("semantics_left_turn.json", 77, (1_000, 61_000))
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
        assert_eq!(ctx.target, up.prior.target);
        let c = &up.prior.conflicts[0];
        let zone_mid = ctx.bv_path.point_at(0.5 * (ctx.zone_bv.enter_s_m + ctx.zone_bv.exit_s_m));
        assert!(zone_mid.dist(c.point) < 3.0, "zone at {zone_mid:?}, grounded conflict at {:?}", c.point);
        let vut_mid = ctx.vut_path.point_at(0.5 * (ctx.zone_vut.enter_s_m + ctx.zone_vut.exit_s_m));
        assert!(vut_mid.dist(c.point) < 3.0);
        let v0 = up.prior.agents[1].states[0].speed_mps;
        assert!((ctx.reference_speed_at(10.0) - v0).abs() < 1e-9);
        // The path keeps the trajectory's length.
        let bv = &up.prior.agents[1];
        let length = ReferencePath::through_states(&bv.states).unwrap().length();
        assert!((ctx.bv_path.length() - length).abs() < 0.05);
    }

    #[test]
    fn a_bv_in_a_junction_gets_its_stop_line_from_the_grounding_and_a_cut_in_none() {
        // The left turn crosses in junction 100: the grounding marks where the BV's route enters
        // it, and the prior's stop line puts the BV's front 2 m before that edge.
        let (up, checks) = upload();
        let entry = up.prior.conflicts[0].bv_junction_entry.expect("the left turn crosses in a junction");
        let prior = from_upload(&up, 2_000, &checks, 5).unwrap();
        let ctx = PriorContext::new(&prior).unwrap();
        let line = ctx.stop_line_s_m.expect("a stop line");
        let edge_s = ctx.bv_path.project(entry).unwrap().s_m;
        let front = line + 0.5 * checks.bv.length_m;
        assert!(
            (edge_s - front - v2t_game::regulator::STOP_LINE_MARGIN_M).abs() < 1e-6,
            "front {front}, edge {edge_s}"
        );
        assert!(line < ctx.zone_bv.enter_s_m - 5.0, "the line is outside the junction, before the zone");
        // A cut-in merges on a straight road: no junction, no stop line.
        let (up, checks) = fixtures::upload("semantics_cut_in.json", 78, (0, u64::MAX));
        assert!(up.prior.conflicts[0].bv_junction_entry.is_none());
        let prior = from_upload(&up, 2_000, &checks, 5).unwrap();
        assert_eq!((prior.has_bv_stop_line, prior.bv_stop_line()), (0, None));
    }

    #[test]
    fn every_broken_upload_is_refused_with_its_reason() {
        let (up, checks) = upload();
        assert_eq!(refused(&up, &checks, 61_001), "prior 77: expired 1 ms ago");
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
        // Faster than the BV drives, as motion.
        let mut u = up.clone();
        let bv = &mut u.prior.agents[1];
        bv.states[0].speed_mps = checks.limits.max_speed_mps + 1.0;
        bv.states = v2t_model::kinematics::rollout(bv.states[0], &bv.controls, u.prior.dt_s);
        let e = refused(&u, &checks, 2_000);
        assert!(e.contains("speed") && !e.contains("invalid"), "{e}");
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
        // A 40 m jump between two states is no motion at all: refused before any other check.
        let mut u = up.clone();
        for x in &mut u.prior.agents[1].states[60..] {
            x.px += 40.0;
        }
        assert!(refused(&u, &checks, 2_000).contains("from the state before it"));
        // Steered off the road from t = 6 s, as motion (states rolled out of the controls), so that
        // only the area refuses it; the same rollout unsteered stays on the road.
        let mut u = up.clone();
        let bv = &mut u.prior.agents[1];
        bv.states = v2t_model::kinematics::rollout(bv.states[0], &bv.controls, u.prior.dt_s);
        from_upload(&u, 2_000, &checks, 5).unwrap();
        let bv = &mut u.prior.agents[1];
        bv.controls[60..70].iter_mut().for_each(|c| c.yaw_rate_radps -= 0.3);
        bv.states = v2t_model::kinematics::rollout(bv.states[0], &bv.controls, u.prior.dt_s);
        let e = refused(&u, &checks, 2_000);
        assert!(e.contains("leaves the drivable area at t = 12.8 s"), "{e}");
        let mut u = up.clone();
        for x in &mut u.prior.agents[0].states {
            x.px += 500.0;
        }
        let far = PriorChecks { area: None, ..checks.clone() };
        assert!(refused(&u, &far, 2_000).contains("never share a conflict zone"));
    }

    #[test]
    fn a_broken_ipc_prior_is_refused_with_a_reason() {
        let mut prior = fixtures::left_turn(1);
        prior.style = 9;
        assert_eq!(PriorContext::new(&prior).unwrap_err().to_string(), "unknown style code 9");
        let mut prior = fixtures::left_turn(1);
        prior.tau_s = f64::NAN;
        assert!(PriorContext::new(&prior).is_err());
        let mut prior = fixtures::left_turn(1);
        prior.zone_kind = 0;
        assert!(matches!(PriorContext::new(&prior), Err(PriorError::Code(_))));
    }
}
