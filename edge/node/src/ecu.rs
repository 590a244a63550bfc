//! The simulated drive-by-wire ECU: the BV's actuators and sensors in the simulated proving
//! ground, so the onboard stack runs unchanged, as separate processes. It reads the gateway's
//! command frames (SocketCAN where the kernel has CAN, the iceoryx2 virtual bus elsewhere),
//! checks their counters and checksums like a real ECU, drives the `v2t-sim` plant in real time,
//! and sends back feedback frames, GNSS/INS fixes and the VUT's state (as V2X would). It also
//! publishes the scenario's prior (the stand-in for the cloud upload) and measures the run.

use std::path::PathBuf;
use std::time::Duration;

use iceoryx2::service::Service;
use v2t_can::codec::{CanFrame, DbwFeedback, Decoder, Encoder, Message};
use v2t_can::transport::{CanTransport, SocketCanBus};
use v2t_sim::plant::ActuationRequest;
use v2t_sim::recording::PlanRecord;
use v2t_sim::runner::{RunOutcome, Simulation};
use v2t_sim::vut::VutModel;
use v2t_wire::{ActivePrior, Code, DbwMode, Header, Localization, PlanStatus, RegulatedPlan, VutState, services};

use crate::canbus::{End, IpcCanBus};
use crate::clock::now_ns;
use crate::config::{CanLink, Loaded};
use crate::error::EdgeError;
use crate::ports::{Bus, send};

/// Without a valid enabled command for this long the ECU brakes on its own, s.
const ECU_COMMAND_TIMEOUT_S: f64 = 0.1;
/// The ECU's own braking when commands stop, m/s².
const ECU_TIMEOUT_DECEL_MPS2: f64 = 3.0;
/// GNSS/INS fixes every this many plant steps.
const FIX_EVERY: usize = 2;

/// Where the simulated world comes from.
#[derive(Debug, Clone)]
pub enum EcuSource {
    /// A scenario card; the ECU also publishes the card's prior (the stand-in for a cloud upload).
    Card(PathBuf),
    /// The prior the uplink node accepted from the cloud: the ECU waits for it on the prior service
    /// and builds the world from its paths (the BV at the start of its reference, the VUT at the
    /// start of its route with the prior's speed), with these simulation settings.
    Uplink {
        /// Simulation settings (TOML, `config/sim/default.toml`).
        sim_settings: PathBuf,
        /// Longest wait for the prior, s.
        wait_s: f64,
    },
    /// A trajectory prior file (`TrajectoryPrior` JSON) checked against the BV's limits like an
    /// upload, published on the prior service (the stand-in for the cloud upload), and the world
    /// built from it as for [`EcuSource::Uplink`].
    Prior {
        /// The prior.
        path: PathBuf,
        /// The prior's BV agent this BV drives (default: the first BV).
        agent: Option<String>,
        /// Simulation settings (TOML).
        sim_settings: PathBuf,
    },
}

/// What the simulated ECU runs.
#[derive(Debug, Clone)]
pub struct EcuOptions {
    /// The world.
    pub source: EcuSource,
    /// VUT driver model (the card's own if `None`; IDM normal for an uplinked prior).
    pub vut: Option<VutModel>,
    /// Seed of the noise.
    pub seed: u64,
    /// Longest wait for the gateway to engage before the scenario starts, s.
    pub engage_timeout_s: f64,
    /// Target PET instead of the card's, s (a card only: an uplinked prior carries its own).
    pub tau_s: Option<f64>,
    /// Style instead of the card's (a card only).
    pub style: Option<v2t_model::Style>,
}

/// Longest simulated run built from a prior, s.
const MAX_PRIOR_RUN_S: f64 = 120.0;

/// A prior file made into the prior the BV would have accepted from the cloud (limits checked; the
/// geofence is the uplink's business).
fn prior_from_file(
    cfg: &Loaded,
    path: &std::path::Path,
    agent: Option<&str>,
    prior_id: u64,
) -> Result<ActivePrior, EdgeError> {
    use v2t_model::grounded::AgentRole;
    let bad = |m: String| EdgeError::Prior(format!("{}: {m}", path.display()));
    let text = std::fs::read_to_string(path).map_err(|e| bad(e.to_string()))?;
    let prior: v2t_model::prior::TrajectoryPrior = serde_json::from_str(&text).map_err(|e| bad(e.to_string()))?;
    let bv_agent = match agent {
        Some(a) => a.to_owned(),
        None => prior
            .agents
            .iter()
            .find(|a| a.role == AgentRole::Bv)
            .map(|a| a.id.clone())
            .ok_or_else(|| bad("has no BV agent".into()))?,
    };
    let now = crate::uplink::unix_ms();
    let up =
        v2t_wire::link::PriorUpload { prior_id, bv_agent, valid_from_ms: now, valid_until_ms: now + 3_600_000, prior };
    let checks = crate::prior::PriorChecks::for_vehicles(&cfg.vehicle, &cfg.vut_vehicle, None, 0.0);
    crate::prior::from_upload(&up, now, &checks, now_ns()).map_err(|e| bad(e.to_string()))
}

/// The world of an uplinked prior: its paths, the BV's reference timing, the VUT's start speed.
fn scenario_from_prior(
    prior: &ActivePrior,
    cfg: &Loaded,
    settings: v2t_sim::config::SimSettings,
    vut_model: VutModel,
) -> Result<v2t_sim::scenario::Scenario, EdgeError> {
    use v2t_wire::Vector as _;
    // The paths, the zone the regulator works on and the style, decoded as the regulator does, so
    // that the run measures the conflict the BV regulates.
    let ctx = crate::prior::PriorContext::new(prior)
        .map_err(|e| EdgeError::Prior(format!("prior {}: {e}", prior.prior_id)))?;
    let profile: Vec<[f64; 2]> = prior.bv_profile.as_slice().iter().map(|q| [q.t_s, q.v_mps]).collect();
    let bv_end_s = profile.last().map_or(0.0, |[t, _]| *t);
    let vut_end_s = ctx.vut_path.length() / prior.vut_speed_mps.max(1.0);
    let zone = v2t_model::metrics::ConflictZone {
        kind: ctx.zone_kind,
        a: ctx.zone_vut,
        b: ctx.zone_bv,
        anchor: ctx.vut_path.point_at(0.5 * (ctx.zone_vut.enter_s_m + ctx.zone_vut.exit_s_m)),
    };
    let paths = v2t_sim::scenario::ScenarioPaths {
        name: format!("prior {}", prior.prior_id),
        tau_s: ctx.tau_s,
        style: ctx.style,
        duration_s: (bv_end_s.max(vut_end_s) + 2.0).min(MAX_PRIOR_RUN_S),
        vut_route: ctx.vut_path,
        vut_speed_mps: prior.vut_speed_mps,
        vut_model,
        bv_id: "bv".into(),
        bv_route: ctx.bv_path,
        bv_reference: v2t_sim::scenario::SpeedProfile::new(profile),
        conflict: Some(zone),
    };
    v2t_sim::scenario::Scenario::from_paths(paths, settings, cfg.vut_vehicle.clone(), cfg.vehicle.clone())
        .map_err(|e| EdgeError::Prior(format!("prior {}: {e}", prior.prior_id)))
}

/// What the ECU saw of the commands.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize)]
pub struct EcuStats {
    /// Command frames accepted.
    pub frames_ok: u64,
    /// Frames rejected (checksum, counter, range, unknown id).
    pub frames_rejected: u64,
    /// Plant steps during which the ECU's own command timeout braked.
    pub timeout_steps: u64,
    /// Plant steps that started late by more than one step (real-time overruns).
    pub late_steps: u64,
}

/// The ECU's command state: the newest enabled request, and when it arrived.
#[derive(Debug, Default)]
struct Commands {
    decoder: Decoder,
    accel: Option<(f64, u64)>,
    steer: Option<(f64, u64)>,
    engaged: bool,
    stats: EcuStats,
}

impl Commands {
    fn take(&mut self, frame: &CanFrame, now: u64) {
        match self.decoder.decode(frame) {
            Ok(Message::Accel(a)) => {
                self.stats.frames_ok += 1;
                self.accel = a.enable.then_some((a.accel_mps2, now));
                self.engaged |= a.enable;
            }
            Ok(Message::Steer(s)) => {
                self.stats.frames_ok += 1;
                self.steer = s.enable.then_some((s.steer_rad, now));
            }
            Ok(_) => self.stats.frames_ok += 1,
            Err(_) => self.stats.frames_rejected += 1,
        }
    }

    /// The request the actuators get at `now`: the commands while fresh, else the ECU's own stop.
    fn request(&mut self, now: u64, held_steer: f64) -> ActuationRequest {
        let fresh =
            |c: Option<(f64, u64)>| c.filter(|(_, t)| crate::clock::secs_between(*t, now) <= ECU_COMMAND_TIMEOUT_S);
        match (fresh(self.accel), fresh(self.steer)) {
            (Some((a, _)), Some((s, _))) => ActuationRequest { accel_mps2: a, steer_rad: s },
            _ => {
                self.stats.timeout_steps += 1;
                ActuationRequest { accel_mps2: -ECU_TIMEOUT_DECEL_MPS2, steer_rad: held_steer }
            }
        }
    }
}

fn open_transport<S: Service + 'static>(cfg: &Loaded, bus: &Bus<S>) -> Result<Box<dyn CanTransport>, EdgeError> {
    Ok(match &cfg.edge.can {
        CanLink::Socketcan { interface } => {
            Box::new(SocketCanBus::open(interface).map_err(|e| EdgeError::Can(format!("{interface}: {e}")))?)
        }
        CanLink::Ipc => Box::new(IpcCanBus::open(bus, End::Ecu)?),
    })
}

struct Io<S: Service + 'static> {
    bus: Bus<S>,
    fixes: iceoryx2::port::publisher::Publisher<S, Localization, ()>,
    fix_wake: iceoryx2::port::notifier::Notifier<S>,
    vut: iceoryx2::port::publisher::Publisher<S, VutState, ()>,
    can: Box<dyn CanTransport>,
    encoder: Encoder,
    fix_header: Header,
    vut_header: Header,
}

impl<S: Service + 'static> Io<S> {
    fn drain(&mut self, cmds: &mut Commands) {
        let now = now_ns();
        while let Ok(Some(frame)) = self.can.recv(Duration::ZERO) {
            cmds.take(&frame, now);
        }
    }

    fn publish_fix(&mut self, state: &v2t_model::kinematics::State, age_s: f64) -> Result<(), EdgeError> {
        let stamp = now_ns().saturating_sub((age_s * 1e9) as u64);
        self.fix_header.seq += 1;
        self.fix_header.stamp_ns = stamp;
        let fix = Localization {
            header: self.fix_header,
            px_m: state.px,
            py_m: state.py,
            theta_rad: state.theta_rad,
            speed_mps: state.speed_mps,
            valid: 1,
        };
        send(&self.fixes, Some(&self.fix_wake), fix)
    }

    fn publish_vut(&mut self, state: &v2t_model::kinematics::State, age_s: f64) -> Result<(), EdgeError> {
        self.vut_header.seq += 1;
        self.vut_header.stamp_ns = now_ns().saturating_sub((age_s * 1e9) as u64);
        let v = VutState {
            header: self.vut_header,
            px_m: state.px,
            py_m: state.py,
            theta_rad: state.theta_rad,
            speed_mps: state.speed_mps,
        };
        send(&self.vut, None, v)
    }

    fn feedback(&mut self, speed: f64, yaw_rate: f64, steer: f64) -> Result<(), EdgeError> {
        let fb = DbwFeedback {
            wheel_speed_mps: speed,
            yaw_rate_radps: yaw_rate,
            steer_rad: steer,
            mode: DbwMode::Auto.code(),
        };
        let frame = self.encoder.feedback(&fb).map_err(|e| EdgeError::Can(e.to_string()))?;
        self.can.send(&frame).map_err(|e| EdgeError::Can(e.to_string()))
    }
}

/// Runs the scenario of `opts` against the onboard stack of `cfg` in real time; returns the
/// measured run and the ECU's statistics. Ends early (with `Ok`) on SIGINT/SIGTERM.
pub fn run<S: Service + 'static>(
    cfg: &Loaded,
    opts: &EcuOptions,
) -> Result<(RunOutcome, EcuStats, Vec<PlanRecord>), EdgeError> {
    let bus = Bus::<S>::new("sim-ecu", &cfg.edge.namespace)?;
    // The regulator's decisions, for the recording.
    let plan_in = bus.subscriber::<RegulatedPlan>(services::PLAN)?;
    let mut plans = Vec::new();
    let (scenario, card_prior) = match &opts.source {
        EcuSource::Card(card) => {
            let mut scenario = v2t_sim::files::load_scenario(card).map_err(|e| EdgeError::Prior(e.to_string()))?;
            if let Some(tau) = opts.tau_s {
                if !(tau.is_finite() && tau > 0.0) {
                    return Err(EdgeError::Prior(format!("target PET must be positive, got {tau}")));
                }
                scenario.tau_s = tau;
            }
            if let Some(style) = opts.style {
                scenario.style = style;
            }
            let prior = crate::prior::from_scenario(&scenario, 0, opts.seed.wrapping_add(1), now_ns())?;
            (scenario, Some((prior, bus.publisher::<ActivePrior>(services::PRIOR)?)))
        }
        EcuSource::Prior { path, agent, sim_settings } => {
            let settings: v2t_sim::config::SimSettings =
                v2t_sim::files::load_toml(sim_settings).map_err(|e| EdgeError::Prior(e.to_string()))?;
            let prior = prior_from_file(cfg, path, agent.as_deref(), opts.seed.wrapping_add(1))?;
            let model = opts.vut.unwrap_or(VutModel::IdmNormal);
            let scenario = scenario_from_prior(&prior, cfg, settings, model)?;
            (scenario, Some((prior, bus.publisher::<ActivePrior>(services::PRIOR)?)))
        }
        EcuSource::Uplink { sim_settings, wait_s } => {
            let settings: v2t_sim::config::SimSettings =
                v2t_sim::files::load_toml(sim_settings).map_err(|e| EdgeError::Prior(e.to_string()))?;
            let priors = bus.subscriber::<ActivePrior>(services::PRIOR)?;
            let deadline = now_ns() + (wait_s * 1e9) as u64;
            let prior = loop {
                let mut newest = None;
                while let Some(sample) = priors.receive().map_err(|e| EdgeError::ipc("receive", services::PRIOR, e))? {
                    newest = Some(sample.clone());
                }
                if let Some(p) = newest {
                    break p;
                }
                if now_ns() > deadline {
                    return Err(EdgeError::Prior(format!("no prior from the uplink within {wait_s} s")));
                }
                if !bus.wait(Duration::from_millis(20)) {
                    return Err(EdgeError::Prior("stopped while waiting for a prior".into()));
                }
            };
            eprintln!("sim-ecu: prior {} from the uplink: τ {} s", prior.prior_id, prior.tau_s);
            let model = opts.vut.unwrap_or(VutModel::IdmNormal);
            (scenario_from_prior(&prior, cfg, settings, model)?, None)
        }
    };
    let model = opts.vut.unwrap_or(scenario.vut.default_model);
    let mut driver = model.driver();
    let mut io = Io {
        fixes: bus.publisher(services::LOCALIZATION)?,
        fix_wake: bus.notifier(services::WAKE_STATE)?,
        vut: bus.publisher(services::VUT)?,
        can: open_transport(cfg, &bus)?,
        encoder: Encoder::default(),
        fix_header: Header::default(),
        vut_header: Header::default(),
        bus,
    };
    // A card's prior is sent again every second, as the cloud would: a node that (re)starts later
    // gets it too. An uplinked prior stays with the uplink node.
    let send_prior = || match &card_prior {
        Some((prior, out)) => {
            out.send_copy(prior.clone()).map(|_| ()).map_err(|e| EdgeError::ipc("send", services::PRIOR, e))
        }
        None => Ok(()),
    };
    send_prior()?;
    let prior_every = (1.0 / scenario.settings.plant_dt_s).round().max(1.0) as u64;
    let mut sim = Simulation::new(&scenario, opts.seed);
    let dt = scenario.settings.plant_dt_s;
    let step_ns = (dt * 1e9) as u64;
    let control_every = scenario.settings.control_every();
    let wheelbase = scenario.bvs.first().map_or(2.8, |b| b.agent.vehicle.geometry.wheelbase_m);
    let mut cmds = Commands::default();

    // Before the start: the BV stands at its start (sensors alive) until the gateway engages.
    let deadline = now_ns() + (opts.engage_timeout_s * 1e9) as u64;
    let mut k: u64 = 0;
    while !cmds.engaged {
        if now_ns() > deadline {
            return Err(EdgeError::Can(format!("the gateway did not engage within {} s", opts.engage_timeout_s)));
        }
        io.drain(&mut cmds);
        if k.is_multiple_of(prior_every) {
            send_prior()?;
        }
        if let (Some(st), Some((vut, _))) =
            (sim.bv_truth(0), sim.vut_seen_by_bvs().or_else(|| Some((scenario_start_vut(&scenario), 0.0))))
        {
            if k.is_multiple_of(FIX_EVERY as u64) {
                io.publish_fix(&st, 0.0)?;
                io.publish_vut(&vut, 0.0)?;
            }
            io.feedback(st.speed_mps, 0.0, 0.0)?;
        }
        k += 1;
        if !io.bus.wait(Duration::from_nanos(step_ns)) {
            return Ok((sim.finish(model.as_str(), "v2t-edge"), cmds.stats, plans));
        }
    }

    let start = now_ns();
    let mut i: usize = 0;
    while !sim.is_done() {
        io.drain(&mut cmds);
        while let Some(p) = plan_in.receive().map_err(|e| EdgeError::ipc("receive", services::PLAN, e))? {
            plans.push(PlanRecord {
                t_s: i as f64 * dt,
                prior_id: p.prior_id,
                status: PlanStatus::from_code(p.status)
                    .map_or_else(|_| format!("code {}", p.status), |s| format!("{s:?}")),
                s_m: p.s0_m,
                v_mps: p.v0_mps,
                accel_mps2: p.accel_mps2,
                predicted_pet_s: (p.has_predicted_pet != 0 && p.predicted_pet_s.is_finite())
                    .then_some(p.predicted_pet_s),
                solve_us: p.solve_ns as f64 * 1e-3,
            });
        }
        if (i as u64).is_multiple_of(prior_every) {
            send_prior()?;
        }
        let now = now_ns();
        let (_, held_steer) = sim.bv_actuators(0).unwrap_or((0.0, 0.0));
        sim.set_bv_request(0, cmds.request(now, held_steer));
        sim.step(driver.as_mut(), &mut |_, _| None);
        if i.is_multiple_of(FIX_EVERY)
            && let Some((fix, age)) = sim.publish_bv_localization(0)
        {
            io.publish_fix(&fix, age)?;
        }
        if i.is_multiple_of(control_every)
            && let Some((vut, age)) = sim.vut_seen_by_bvs()
        {
            io.publish_vut(&vut, age)?;
        }
        if let (Some(st), Some((_, steer))) = (sim.bv_truth(0), sim.bv_actuators(0)) {
            io.feedback(st.speed_mps, st.speed_mps * steer.tan() / wheelbase, steer)?;
        }
        i += 1;
        let next = start + i as u64 * step_ns;
        let now = now_ns();
        if now > next + step_ns {
            cmds.stats.late_steps += 1;
        }
        if !io.bus.wait(Duration::from_nanos(next.saturating_sub(now))) {
            break;
        }
    }
    Ok((sim.finish(model.as_str(), "v2t-edge"), cmds.stats, plans))
}

fn scenario_start_vut(scenario: &v2t_sim::scenario::Scenario) -> v2t_model::kinematics::State {
    let route = &scenario.vut.agent.route;
    let p = route.point_at(0.0);
    v2t_model::kinematics::State {
        px: p.x,
        py: p.y,
        theta_rad: route.heading_at(0.0),
        speed_mps: scenario.vut.agent.initial_speed_mps,
    }
}
