//! The SUMO world: Eclipse SUMO drives the vehicle under test, on the network `netconvert` makes
//! from the same OpenDRIVE map, with car-following, junction and lane-change models this project
//! did not write; every BV is driven by our plant, controller and sensing exactly as in the builtin
//! world and imposed on SUMO each control period (`moveToXY`, mapped onto its route), so SUMO's
//! drivers see it like any vehicle. The VUT's true state comes back each period into the same
//! sensing and delay model ([`v2t_sim::external`]); PET, collisions, overlaps and order are measured
//! by our own metrics on the poses, never by SUMO's.
//!
//! What SUMO believes of a BV: its pose and, each step, a top speed equal to its true speed. SUMO's
//! junction model predicts a foe's arrival from the foe's own plan; an imposed vehicle's plan would
//! otherwise be to accelerate to the lane's limit, so a parked BV looked, to SUMO's VUT, like a car
//! about to arrive (fixed 2026-11-27; before/after figures in `docs/BENCHMARKS.md`).
//!
//! Timing: at control tick `t` each BV is put where it truly is at `t`, SUMO advances one step of one
//! control period, and the VUT's state at `t + period` comes back. So SUMO's VUT sees the BVs one
//! control period late — the builtin world's VUT perceives them `perception_delay_s` (0.1 s) late.
//! Positions: SUMO places a vehicle by its front bumper, our state is the footprint's centre; the
//! conversion uses the vehicle file's length.
//!
//! One SUMO process per worker thread, reused across runs (TraCI `load` restarts it with the run's
//! seed); [`SumoWorld`] keeps the idle ones. SUMO is found by [`v2t_sumo::SumoBinaries::find`]; its
//! absence is an error that says how to install it (`scripts/install-sumo`).

use std::collections::{BTreeMap, HashMap};
use std::path::{Path, PathBuf};
use std::sync::Mutex;

use v2t_model::kinematics::State;
use v2t_model::validate::{Validate, ValidationError};
use v2t_model::vehicle::VehicleConfig;
use v2t_sim::bv::BvController;
use v2t_sim::external::{ExternalVut, ExternalVutError};
use v2t_sim::runner::{RunError, RunOutcome, run_external};
use v2t_sim::scenario::{Agent, Scenario};
use v2t_sumo::{
    MatchedRoute, MoveToXy, Network, NewVehicle, Reply, Request, StartOptions, Sumo, SumoBinaries, SumoError, VType,
    VehicleVar,
};

/// A point of the VUT's route farther than this from every lane of the SUMO network is not on the
/// map, m: SUMO drives the VUT on its lanes, and our measurement must follow the same path.
pub const MAX_OFF_LANE_M: f64 = 0.5;
/// The same for a BV's route, m: half a 3.5 m lane and a margin, so a lane change passes (between
/// two lanes the BV is on neither centre line; SUMO maps it onto the nearer).
pub const MAX_OFF_LANE_BV_M: f64 = 2.0;
/// The least speed SUMO is told an imposed BV can reach, m/s: SUMO refuses a vehicle whose top
/// speed is zero, and a BV at 1 cm/s is, to every driver, parked.
const MIN_BELIEVED_SPEED_MPS: f64 = 0.01;
/// SUMO must insert the VUT within this distance of its start, m.
const MAX_INSERT_ERROR_M: f64 = 0.5;
/// Attributes of the VUT's `<vType>` that come from the vehicle file, never from a driver file.
pub const RESERVED_ATTRIBUTES: [&str; 6] = ["id", "length", "width", "maxSpeed", "emergencyDecel", "vClass"];

/// The folder of the shipped SUMO drivers (relative to the repository root).
pub const DRIVERS_DIR: &str = "config/vut/sumo";
/// The driver a single run takes when none is named: SUMO's defaults.
pub const DEFAULT_DRIVER: &str = "config/vut/sumo/krauss.toml";

/// One SUMO driver of the VUT (a file under `config/vut/sumo/`).
#[derive(Debug, Clone, PartialEq, serde::Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields)]
pub struct SumoDriver {
    /// `sumo-` and lower-case letters, digits and dashes.
    pub name: String,
    /// One line for reports.
    pub description: String,
    /// Attributes of SUMO's `<vType>` element, as SUMO spells them.
    pub vtype: BTreeMap<String, AttributeValue>,
}

/// A `<vType>` attribute's value.
#[derive(Debug, Clone, PartialEq, serde::Deserialize, serde::Serialize)]
#[serde(untagged)]
pub enum AttributeValue {
    /// A number.
    Number(f64),
    /// A word (a model's name).
    Text(String),
}

impl AttributeValue {
    fn xml(&self) -> String {
        match self {
            Self::Number(x) => format!("{x}"),
            Self::Text(s) => s.clone(),
        }
    }
}

impl Validate for SumoDriver {
    fn validate(&self) -> Result<(), ValidationError> {
        let plain = |s: &str| s.chars().all(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || c == '-');
        if !(self.name.starts_with("sumo-") && self.name.len() > 5 && self.name.len() <= 40 && plain(&self.name)) {
            return Err(ValidationError::new(
                "name",
                format!(
                    "`{}`: must be `sumo-` then lower-case letters, digits or dashes, at most 40 characters",
                    self.name
                ),
            ));
        }
        if self.description.trim().is_empty() || self.description.len() > 200 || self.description.contains('\n') {
            return Err(ValidationError::new("description", "one line of 1 to 200 characters"));
        }
        if self.vtype.len() > 64 {
            return Err(ValidationError::new("vtype", format!("{} attributes; at most 64", self.vtype.len())));
        }
        for (key, value) in &self.vtype {
            let field = format!("vtype.{key}");
            let ident = key.len() <= 64
                && key.chars().next().is_some_and(|c| c.is_ascii_alphabetic())
                && key.chars().all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '.');
            if !ident {
                return Err(ValidationError::new(
                    field,
                    "not a plain attribute name (a letter, then letters, digits, `_`, `.`)",
                ));
            }
            if RESERVED_ATTRIBUTES.contains(&key.as_str()) {
                return Err(ValidationError::new(
                    field,
                    "comes from the scenario's vehicle file (id, length, width, maxSpeed, emergencyDecel, vClass); remove it",
                ));
            }
            match value {
                AttributeValue::Number(x) if !x.is_finite() || x.abs() > 1e6 => {
                    return Err(ValidationError::new(field, format!("{x}: must be finite, |value| ≤ 1e6")));
                }
                AttributeValue::Text(s)
                    if s.is_empty()
                        || s.len() > 64
                        || !s.chars().all(|c| c.is_ascii_alphanumeric() || matches!(c, '-' | '_' | '.' | ':')) =>
                {
                    return Err(ValidationError::new(
                        field,
                        "text must be 1 to 64 characters of letters, digits, `-`, `_`, `.`, `:`",
                    ));
                }
                _ => {}
            }
        }
        Ok(())
    }
}

impl SumoDriver {
    /// Reads and validates a driver file.
    pub fn load(path: &Path) -> Result<Self, v2t_files::InputError> {
        v2t_files::load_toml(path)
    }

    /// Every driver file in `dir` (`*.toml`), by file name.
    pub fn load_dir(dir: &Path) -> Result<Vec<Self>, v2t_files::InputError> {
        let read =
            std::fs::read_dir(dir).map_err(|source| v2t_files::InputError::Read { path: dir.to_owned(), source })?;
        let mut files: Vec<PathBuf> = read
            .filter_map(Result::ok)
            .map(|e| e.path())
            .filter(|p| p.extension().is_some_and(|x| x == "toml"))
            .collect();
        files.sort();
        files.iter().map(|p| Self::load(p)).collect()
    }

    /// The `<vType>` of this driver for a vehicle.
    fn vtype(&self, id: &str, vehicle: &VehicleConfig) -> VType {
        let mut out = vehicle_attributes(vehicle);
        // The card's route keeps the VUT in its lane: no lane change for speed or to keep right,
        // unless the driver file asks for it (strategic changes for the route stay).
        for (k, v) in [("lcKeepRight", "0"), ("lcSpeedGain", "0")] {
            if !self.vtype.contains_key(k) {
                out.push((k.to_owned(), v.to_owned()));
            }
        }
        out.extend(self.vtype.iter().map(|(k, v)| (k.clone(), v.xml())));
        (id.to_owned(), out)
    }
}

/// The `<vType>` attributes a vehicle file sets ([`RESERVED_ATTRIBUTES`] but the id).
fn vehicle_attributes(v: &VehicleConfig) -> Vec<(String, String)> {
    vec![
        ("vClass".to_owned(), "passenger".to_owned()),
        ("length".to_owned(), format!("{}", v.geometry.length_m)),
        ("width".to_owned(), format!("{}", v.geometry.width_m)),
        ("maxSpeed".to_owned(), format!("{}", v.limits.max_speed_mps)),
        ("emergencyDecel".to_owned(), format!("{}", v.limits.max_decel_mps2)),
    ]
}

/// Why the SUMO world could not run.
#[derive(Debug, thiserror::Error)]
pub enum SumoWorldError {
    /// SUMO itself (missing, crashed, refused a command).
    #[error(transparent)]
    Sumo(#[from] SumoError),
    /// A scenario that does not fit the network.
    #[error("{scenario}: {message}")]
    Scenario {
        /// The scenario.
        scenario: String,
        /// What does not fit.
        message: String,
    },
    /// A scratch file.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
}

/// The SUMO world of one map: the converted network, and the SUMO processes of the workers.
#[derive(Debug)]
pub struct SumoWorld {
    bins: SumoBinaries,
    version: String,
    dir: PathBuf,
    net: PathBuf,
    network: Network,
    idle: Mutex<Vec<Sumo>>,
    /// Routes matched to the network, by a hash of the sampled path and the tolerance.
    matched: Mutex<HashMap<u64, MatchedRoute>>,
}

impl Drop for SumoWorld {
    fn drop(&mut self) {
        if let Ok(idle) = self.idle.get_mut() {
            for sumo in idle.drain(..) {
                let _ = sumo.close();
            }
        }
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}

impl SumoWorld {
    /// Finds SUMO, converts `map` (OpenDRIVE) with `netconvert` into a scratch folder and reads the
    /// network.
    pub fn new(map: &Path) -> Result<Self, SumoWorldError> {
        let bins = SumoBinaries::find()?;
        let version = bins.version()?;
        let dir = std::env::temp_dir().join(format!(
            "v2t-sumo-{}-{}",
            std::process::id(),
            std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map_or(0, |d| d.as_nanos())
        ));
        std::fs::create_dir_all(&dir).map_err(|source| SumoWorldError::Io { path: dir.clone(), source })?;
        let net = dir.join("map.net.xml");
        v2t_sumo::convert_map(&bins, map, &net)?;
        let network = Network::read(&net)?;
        Ok(Self { bins, version, dir, net, network, idle: Mutex::new(Vec::new()), matched: Mutex::new(HashMap::new()) })
    }

    /// SUMO's version line (for reports).
    pub fn version(&self) -> &str {
        &self.version
    }

    /// The converted network.
    pub fn network(&self) -> &Network {
        &self.network
    }

    /// Where `agent`'s route runs on the network: its front bumper's path from the start to the end.
    /// Matched once per route and tolerance: every later run of the same route reuses it.
    fn place(&self, scenario: &Scenario, agent: &Agent, max_off_m: f64) -> Result<MatchedRoute, SumoWorldError> {
        let route = &agent.route;
        let half = 0.5 * agent.vehicle.geometry.length_m;
        let n = (route.length() - half).max(0.0).ceil() as usize;
        let points: Vec<[f64; 3]> = (0..=n)
            .map(|k| {
                let s = (half + k as f64).min(route.length());
                let p = route.point_at(s);
                [p.x, p.y, route.heading_at(s)]
            })
            .collect();
        let key = fnv1a(points.iter().flatten().chain([&max_off_m]).flat_map(|x| x.to_le_bytes()));
        if let Some(hit) = self.matched.lock().ok().and_then(|m| m.get(&key).cloned()) {
            return Ok(hit);
        }
        let matched = self.network.match_route(&points, max_off_m).map_err(|e| SumoWorldError::Scenario {
            scenario: scenario.name.clone(),
            message: format!("{}'s route is not on the SUMO network of the map: {e}", agent.id),
        })?;
        if let Ok(mut m) = self.matched.lock() {
            m.insert(key, matched.clone());
        }
        Ok(matched)
    }

    /// The additional file with the VUT's and the BVs' vehicle types for `driver`.
    fn vtypes(&self, driver: &SumoDriver, scenario: &Scenario) -> Result<PathBuf, SumoWorldError> {
        let mut types: Vec<VType> = vec![driver.vtype("vut", &scenario.vut.agent.vehicle)];
        for (i, bv) in scenario.bvs.iter().enumerate() {
            // A BV is imposed; its type only tells SUMO's drivers its size and what it could do.
            let v = &bv.agent.vehicle;
            let mut attributes = vehicle_attributes(v);
            attributes.extend([
                ("accel".to_owned(), format!("{}", v.limits.max_accel_mps2)),
                ("decel".to_owned(), format!("{}", v.limits.max_decel_mps2)),
                ("sigma".to_owned(), "0".to_owned()),
            ]);
            types.push((format!("bv{i}"), attributes));
        }
        let text = v2t_sumo::additional_xml(&types)?;
        let path = self.dir.join(format!("vtypes-{:016x}.add.xml", fnv1a(text.bytes())));
        if !path.exists() {
            let tmp = path.with_extension(format!("tmp{:?}", std::thread::current().id()).replace(['(', ')'], ""));
            std::fs::write(&tmp, &text).map_err(|source| SumoWorldError::Io { path: tmp.clone(), source })?;
            std::fs::rename(&tmp, &path).map_err(|source| SumoWorldError::Io { path: path.clone(), source })?;
        }
        Ok(path)
    }

    fn take(&self, options: &StartOptions) -> Result<Sumo, SumoWorldError> {
        let reused = self.idle.lock().ok().and_then(|mut idle| idle.pop());
        match reused {
            Some(mut sumo) => match sumo.load(options) {
                Ok(()) => Ok(sumo),
                // A process that cannot restart is dropped (and killed); a fresh one takes its place.
                Err(_) => Ok(Sumo::start(&self.bins, options)?),
            },
            None => Ok(Sumo::start(&self.bins, options)?),
        }
    }

    fn give_back(&self, sumo: Sumo) {
        if let Ok(mut idle) = self.idle.lock() {
            idle.push(sumo);
        }
    }

    /// A SUMO process ready to drive the VUT of `scenario` with `driver`: the vehicles added at
    /// their starts, deterministic for a `seed`. Step it through [`v2t_sim::runner::run_external`]
    /// or [`v2t_sim::runner::Simulation::step_external`]; dropped, it goes back to the idle pool
    /// unless SUMO failed.
    pub fn session(
        &self,
        driver: &SumoDriver,
        scenario: &Scenario,
        seed: u64,
    ) -> Result<SumoSession<'_>, SumoWorldError> {
        let vut_place = self.place(scenario, &scenario.vut.agent, MAX_OFF_LANE_M)?;
        let bv_places = scenario
            .bvs
            .iter()
            .map(|b| self.place(scenario, &b.agent, MAX_OFF_LANE_BV_M))
            .collect::<Result<Vec<_>, _>>()?;
        let vtypes = self.vtypes(driver, scenario)?;
        let options = StartOptions {
            net: self.net.clone(),
            additional: vec![vtypes],
            step_length_s: scenario.settings.control_period_s,
            seed,
            extra_args: Vec::new(),
        };
        let sumo = self.take(&options)?;
        let vut = SumoVut::begin(sumo, scenario, &vut_place, &bv_places, driver)?;
        Ok(SumoSession { world: self, vut: Some(vut) })
    }

    /// One run of `scenario` with `driver` driving the VUT in SUMO, every BV under its controller,
    /// deterministic for a `seed`.
    pub fn run(
        &self,
        driver: &SumoDriver,
        scenario: &Scenario,
        bvs: &mut [Box<dyn BvController>],
        seed: u64,
    ) -> Result<RunOutcome, RunError> {
        let mut session = self
            .session(driver, scenario, seed)
            .map_err(|e| RunError::External(ExternalVutError::new("sumo", 0.0, e.to_string())))?;
        run_external(scenario, bvs, &mut session, seed)
    }
}

/// A SUMO process driving one run's VUT (see [`SumoWorld::session`]).
#[derive(Debug)]
pub struct SumoSession<'w> {
    world: &'w SumoWorld,
    vut: Option<SumoVut>,
}

impl Drop for SumoSession<'_> {
    fn drop(&mut self) {
        if let Some(vut) = self.vut.take()
            && vut.healthy
        {
            self.world.give_back(vut.sumo);
        }
    }
}

impl ExternalVut for SumoSession<'_> {
    fn name(&self) -> &str {
        self.vut.as_ref().map_or("sumo", |v| v.name.as_str())
    }

    fn advance(&mut self, t_s: f64, period_s: f64, bvs: &[State]) -> Result<State, ExternalVutError> {
        match self.vut.as_mut() {
            Some(v) => v.advance(t_s, period_s, bvs),
            None => Err(ExternalVutError::new("sumo", t_s, "the session has ended")),
        }
    }
}

/// FNV-1a: a stable key (a scratch file's name, a cached route's) from bytes.
fn fnv1a(bytes: impl IntoIterator<Item = u8>) -> u64 {
    bytes.into_iter().fold(0xcbf2_9ce4_8422_2325_u64, |h, b| (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3))
}

/// SUMO's angle (degrees, clockwise from north) of a heading (radians, counter-clockwise from east).
fn sumo_angle_deg(theta_rad: f64) -> f64 {
    (90.0 - theta_rad.to_degrees()).rem_euclid(360.0)
}

/// The heading (radians, counter-clockwise from east, in (−π, π]) of SUMO's angle.
fn heading_of_sumo_angle(angle_deg: f64) -> f64 {
    v2t_model::geometry::wrap_angle((90.0 - angle_deg).to_radians())
}

/// The VUT in a running SUMO, as the simulated proving ground's [`ExternalVut`].
#[derive(Debug)]
struct SumoVut {
    sumo: Sumo,
    name: String,
    vut_half_length_m: f64,
    bv_half_lengths_m: Vec<f64>,
    /// The BVs' SUMO ids, in scenario order.
    bv_ids: Vec<String>,
    /// Each BV's route end and heading there, in scenario order.
    bv_route_ends: Vec<(f64, f64, f64)>,
    /// Which BVs have driven past their route's end and are no longer imposed (SUMO drives them
    /// off the end of their route, where they leave its network).
    bv_released: Vec<bool>,
    healthy: bool,
    scenario: String,
}

impl SumoVut {
    /// Adds the VUT and the BVs at their starts and steps once, so that SUMO has inserted them.
    fn begin(
        mut sumo: Sumo,
        scenario: &Scenario,
        vut: &MatchedRoute,
        bvs: &[MatchedRoute],
        driver: &SumoDriver,
    ) -> Result<Self, SumoWorldError> {
        let fail = |message: String| SumoWorldError::Scenario { scenario: scenario.name.clone(), message };
        let vut_agent = &scenario.vut.agent;
        sumo.add_route("vut_route", &vut.edges)?;
        let mut replies = Vec::new();
        sumo.batch(
            &[Request::AddVehicle(NewVehicle {
                id: "vut",
                route: "vut_route",
                vehicle_type: "vut",
                depart: "now",
                depart_lane: &vut.depart_lane.to_string(),
                depart_pos: &format!("{:.3}", vut.depart_pos_m),
                depart_speed: &format!("{:.3}", vut_agent.initial_speed_mps),
                arrival_pos: "max",
            })],
            &mut replies,
        )?;
        sumo.set_max_speed("vut", scenario.vut.desired_speed_mps)?;
        for (i, (bv, place)) in scenario.bvs.iter().zip(bvs).enumerate() {
            let id = format!("bv{}", i + 1);
            let route = format!("{id}_route");
            sumo.add_route(&route, &place.edges)?;
            sumo.batch(
                &[Request::AddVehicle(NewVehicle {
                    id: &id,
                    route: &route,
                    vehicle_type: &format!("bv{i}"),
                    depart: "now",
                    depart_lane: &place.depart_lane.to_string(),
                    depart_pos: &format!("{:.3}", place.depart_pos_m),
                    depart_speed: &format!("{:.3}", bv.agent.initial_speed_mps),
                    arrival_pos: "max",
                })],
                &mut replies,
            )?;
            // Imposed: no speed or lane-change checks of SUMO's own.
            sumo.set_speed_mode(&id, 0)?;
            sumo.set_lane_change_mode(&id, 0)?;
        }
        // SUMO inserts the vehicles in the step after they are added: that step is our t = 0.
        sumo.step()?;
        let ids = sumo.vehicle_ids()?;
        for id in std::iter::once("vut".to_owned()).chain((1..=scenario.bvs.len()).map(|i| format!("bv{i}"))) {
            if !ids.contains(&id) {
                let place = if id == "vut" {
                    Some(vut)
                } else {
                    id.strip_prefix("bv").and_then(|k| k.parse::<usize>().ok()).and_then(|k| bvs.get(k - 1))
                };
                let route = place.map_or_else(String::new, |p| {
                    format!(
                        " (route {:?}, depart lane {}, front bumper at {:.2} m)",
                        p.edges, p.depart_lane, p.depart_pos_m
                    )
                });
                return Err(fail(format!(
                    "SUMO did not insert `{id}` at its start{route}: a vehicle in the way, or a start SUMO refuses. SUMO said: {}",
                    sumo.output_tail().trim()
                )));
            }
        }
        let start = vut_agent.route.point_at(0.0);
        let half = 0.5 * vut_agent.vehicle.geometry.length_m;
        let front = sumo.position("vut")?;
        let heading = heading_of_sumo_angle(sumo.angle_deg("vut")?);
        let centre = [front[0] - half * heading.cos(), front[1] - half * heading.sin()];
        let err = (centre[0] - start.x).hypot(centre[1] - start.y);
        if err > MAX_INSERT_ERROR_M {
            return Err(fail(format!(
                "SUMO inserted the VUT {err:.2} m from its start ({:.2}, {:.2}); bound {MAX_INSERT_ERROR_M} m",
                start.x, start.y
            )));
        }
        Ok(Self {
            sumo,
            name: driver.name.clone(),
            vut_half_length_m: half,
            bv_half_lengths_m: scenario.bvs.iter().map(|b| 0.5 * b.agent.vehicle.geometry.length_m).collect(),
            bv_ids: (1..=scenario.bvs.len()).map(|i| format!("bv{i}")).collect(),
            bv_route_ends: scenario
                .bvs
                .iter()
                .map(|b| {
                    let route = &b.agent.route;
                    let end = route.point_at(route.length());
                    (end.x, end.y, route.heading_at(route.length()))
                })
                .collect(),
            bv_released: vec![false; scenario.bvs.len()],
            healthy: true,
            scenario: scenario.name.clone(),
        })
    }

    fn advance_inner(&mut self, bvs: &[State]) -> Result<State, SumoError> {
        // SUMO takes the BV's speed from how far it moved in the step. What its drivers *predict*
        // of the BV is another matter: a junction foe's arrival is estimated from the foe's own
        // plan, and an imposed vehicle's plan is its car-following model's, which accelerates to
        // the lane's limit; a BV parked 50 m from the junction then "arrives" in a few seconds and
        // the VUT waits for it. Capping the BV's speed at its true speed each step makes SUMO
        // predict what a driver who sees the BV predicts: it goes on at the speed it has
        // (`tests/sumo.rs` holds the known answers: parked, far and near).
        // A BV that has driven past its route's end (a rushing BV keeps going on its lead-out)
        // is past every interaction and soon off SUMO's network, which ends with the map: it is
        // no longer imposed, and SUMO drives its copy off the end of its route.
        for ((st, end), released) in bvs.iter().zip(&self.bv_route_ends).zip(self.bv_released.iter_mut()) {
            let (ex, ey, heading) = *end;
            *released |= (st.px - ex) * heading.cos() + (st.py - ey) * heading.sin() > 0.0;
        }
        let mut requests = Vec::with_capacity(2 * bvs.len());
        let imposed = bvs.iter().zip(&self.bv_half_lengths_m).zip(&self.bv_ids).zip(&self.bv_released);
        for (((st, half), id), _) in imposed.filter(|(_, released)| !**released) {
            requests.push(Request::SetMaxSpeed { vehicle: id, mps: st.speed_mps.max(MIN_BELIEVED_SPEED_MPS) });
            // keepRoute 1: onto the nearest lane of the BV's own route, so SUMO's drivers see it on
            // its route (a junction's conflicts, a lane's leader) wherever our plant has put it.
            requests.push(Request::MoveToXy(MoveToXy {
                vehicle: id,
                edge: "",
                lane: -1,
                x: st.px + half * st.theta_rad.cos(),
                y: st.py + half * st.theta_rad.sin(),
                angle_deg: sumo_angle_deg(st.theta_rad),
                keep_route: 1,
            }));
        }
        let mut replies = Vec::new();
        self.sumo.batch(&requests, &mut replies)?;
        self.sumo.step()?;
        let reads = [
            Request::Vehicle { vehicle: "vut", var: VehicleVar::Position },
            Request::Vehicle { vehicle: "vut", var: VehicleVar::Angle },
            Request::Vehicle { vehicle: "vut", var: VehicleVar::Speed },
        ];
        self.sumo.batch(&reads, &mut replies)?;
        let (Some(Reply::Position(front)), Some(Reply::Number(angle)), Some(Reply::Number(speed))) =
            (replies.first(), replies.get(1), replies.get(2))
        else {
            return Err(SumoError::Protocol {
                field: "the VUT's position, angle and speed",
                problem: format!("replies {replies:?}"),
            });
        };
        let (front, speed) = (*front, *speed);
        let theta = heading_of_sumo_angle(*angle);
        Ok(State {
            px: front[0] - self.vut_half_length_m * theta.cos(),
            py: front[1] - self.vut_half_length_m * theta.sin(),
            theta_rad: theta,
            speed_mps: speed,
        })
    }
}

impl SumoVut {
    fn advance(&mut self, t_s: f64, _period_s: f64, bvs: &[State]) -> Result<State, ExternalVutError> {
        self.advance_inner(bvs).map_err(|e| {
            self.healthy = false;
            ExternalVutError::new("sumo", t_s, format!("{} (scenario {})", e, self.scenario))
        })
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing)]
    use super::*;

    #[test]
    fn sumo_angles_and_headings_convert_both_ways() {
        for (heading_deg, angle) in [(0.0, 90.0), (90.0, 0.0), (180.0, 270.0), (-90.0, 180.0), (45.0, 45.0)] {
            let h = f64::to_radians(heading_deg);
            assert!((sumo_angle_deg(h) - angle).abs() < 1e-9, "{heading_deg} → {}", sumo_angle_deg(h));
            assert!(v2t_model::geometry::wrap_angle(heading_of_sumo_angle(angle) - h).abs() < 1e-9);
        }
    }

    #[test]
    fn the_shipped_drivers_load_and_bad_ones_name_the_field() {
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
        let drivers = SumoDriver::load_dir(&root.join("config/vut/sumo")).unwrap();
        let names: Vec<&str> = drivers.iter().map(|d| d.name.as_str()).collect();
        assert_eq!(names, ["sumo-eidm", "sumo-idm", "sumo-impatient", "sumo-krauss"]);
        // The held-out drivers are apart: not in the default sweep, each of a family the shipped ones
        // are not, none sharing a shipped driver's name.
        let heldout = SumoDriver::load_dir(&root.join("config/vut/sumo/heldout")).unwrap();
        let held: Vec<&str> = heldout.iter().map(|d| d.name.as_str()).collect();
        assert_eq!(held, ["sumo-acc", "sumo-kraussps-bold", "sumo-w99", "sumo-wiedemann"]);
        let family = |d: &SumoDriver| format!("{:?}", d.vtype.get("carFollowModel"));
        for d in &heldout {
            assert!(drivers.iter().all(|s| family(s) != family(d)), "{}: {}", d.name, family(d));
        }
        let bad = |text: &str| v2t_files::parse_toml::<SumoDriver>(text, "driver.toml").unwrap_err().to_string();
        let head = "name = \"sumo-x\"\ndescription = \"x\"\n[vtype]\n";
        assert!(bad(&format!("{head}length = 4.0\n")).contains("vtype.length"));
        assert!(bad(&format!("{head}sigma = nan\n")).contains("vtype.sigma"));
        assert!(bad(&format!("{head}sigma = 1e300\n")).contains("≤ 1e6"));
        assert!(bad(&format!("{head}\"a b\" = 1\n")).contains("plain attribute name"));
        assert!(bad(&format!("{head}carFollowModel = \"<x/>\"\n")).contains("vtype.carFollowModel"));
        assert!(bad("name = \"krauss\"\ndescription = \"x\"\n[vtype]\n").contains("name"));
        assert!(bad(&format!("{head}extra = {{ a = 1 }}\n")).contains("driver.toml"));
    }
}
