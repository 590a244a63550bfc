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
use v2t_can::transport::CanTransport;
use v2t_edge::canbus::End;
use v2t_edge::clock::now_ns;
use v2t_edge::config::Loaded;
use v2t_edge::error::EdgeError;
use v2t_edge::gateway::open_transport;
use v2t_edge::ports::{Bus, send};
use v2t_model::{Style, TargetError};
use v2t_sim::plant::ActuationRequest;
use v2t_sim::recording::PlanRecord;
use v2t_sim::runfile::RunFile;
use v2t_sim::runner::{RunOutcome, Simulation};
use v2t_sim::vut::VutModel;
use v2t_wire::{
    ActivePrior, BelowReachCode, Code, DbwMode, GateState, Header, Localization, PlanStatus, RegulatedPlan, VutState,
    services,
};

use crate::world::{self, Vehicles, WorldError};

/// What the ECU saw of the commands, and a change of the actuation gate's state seen on the CAN bus:
/// as the run file holds them.
pub use v2t_sim::runfile::{EcuStats, GateRecord};

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
    /// and builds the world from it ([`world::from_prior`]), with these simulation settings.
    Uplink {
        /// Simulation settings (TOML, `config/sim/default.toml`).
        sim_settings: PathBuf,
        /// Longest wait for the prior, s.
        wait_s: f64,
    },
    /// A trajectory prior file (`TrajectoryPrior` JSON) accepted as the BV accepts an upload
    /// ([`world::accept`]), published on the prior service (the stand-in for the cloud upload), and
    /// the world built from it as for [`EcuSource::Uplink`].
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
    /// VUT driver model (the card's own if `None`; IDM normal for a prior).
    pub vut: Option<VutModel>,
    /// Seed of the noise.
    pub seed: u64,
    /// Longest wait for the gateway to engage before the scenario starts, s.
    pub engage_timeout_s: f64,
    /// Target PET instead of the card's, s (a card only: a prior carries its own).
    pub tau_s: Option<f64>,
    /// Style instead of the card's (a card only).
    pub style: Option<Style>,
    /// Recorded human driving per manoeuvre class: the run's realism is measured against it.
    pub human: Option<v2t_model::realism::HumanReference>,
    /// SUMO drives the VUT instead of [`EcuOptions::vut`]: the map (OpenDRIVE) it converts and the
    /// driver ([`crate::sumo`]).
    pub sumo: Option<(PathBuf, crate::sumo::SumoDriver)>,
}

/// What a run behind the CAN frames gave.
#[derive(Debug)]
pub struct EcuRun {
    /// The measured run.
    pub outcome: RunOutcome,
    /// The ECU's statistics.
    pub stats: EcuStats,
    /// The regulator's decisions, for the recording.
    pub plans: Vec<PlanRecord>,
    /// The actuation gate's state as the gateway reported it on `BV_ControlState`: every change,
    /// from the scenario's start.
    pub gate: Vec<GateRecord>,
    /// How human each vehicle's motion was (when [`EcuOptions::human`] is given).
    pub realism: Option<v2t_sim::realism::RunRealism>,
}

impl EcuRun {
    /// The run's file (`v2t-sim-ecu --out`): the run, its realism, the regulator's decisions, the
    /// ECU's frame counts and the gate's changes.
    pub fn file(&self) -> RunFile {
        RunFile {
            realism: self.realism.clone(),
            regulator: Some(vec![self.plans.clone()]),
            ecu: Some(self.stats),
            gate: Some(self.gate.clone()),
            ..RunFile::of(&self.outcome)
        }
    }
}

/// Why the simulated ECU could not run.
#[derive(Debug, thiserror::Error)]
pub enum EcuError {
    /// The onboard side (configuration, iceoryx2, CAN) failed.
    #[error(transparent)]
    Edge(#[from] EdgeError),
    /// The card cannot be run.
    #[error(transparent)]
    Card(#[from] v2t_sim::files::CardError),
    /// A file (prior, settings) cannot be read or is bad.
    #[error(transparent)]
    Input(#[from] v2t_files::InputError),
    /// The prior makes no world.
    #[error(transparent)]
    World(#[from] WorldError),
    /// `--tau` is not a target.
    #[error("--tau: {0}")]
    Target(#[from] TargetError),
    /// A frame could not be encoded or sent.
    #[error("CAN: {0}")]
    Can(String),
    /// No prior came from the uplink.
    #[error("no prior from the uplink within {0} s")]
    NoPrior(f64),
    /// The gateway never engaged.
    #[error("the gateway did not engage within {0} s")]
    NotEngaged(f64),
    /// SUMO could not start or does not fit the scenario.
    #[error(transparent)]
    Sumo(#[from] crate::sumo::SumoWorldError),
    /// SUMO failed during the run.
    #[error(transparent)]
    External(#[from] v2t_sim::external::ExternalVutError),
}

impl EcuError {
    /// Whether the input (files, options) is at fault.
    pub fn is_input(&self) -> bool {
        matches!(self, Self::Card(_) | Self::Input(_) | Self::World(_) | Self::Target(_))
            || matches!(self, Self::Edge(e) if e.is_input())
    }
}

fn vehicles(cfg: &Loaded) -> Vehicles<'_> {
    Vehicles { bv: &cfg.vehicle, vut: &cfg.vut_vehicle }
}

/// The ECU's command state: the newest enabled request, and when it arrived.
#[derive(Debug, Default)]
struct Commands {
    decoder: Decoder,
    accel: Option<(f64, u64)>,
    steer: Option<(f64, u64)>,
    engaged: bool,
    /// The newest gate state code from `BV_ControlState`.
    gate: Option<u8>,
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
            Ok(Message::Control(c)) => {
                self.stats.frames_ok += 1;
                self.gate = Some(c.gate_state);
            }
            Ok(Message::Feedback(_)) => self.stats.frames_ok += 1,
            Err(_) => self.stats.frames_rejected += 1,
        }
    }

    /// The request the actuators get at `now`: the commands while fresh, else the ECU's own stop.
    fn request(&mut self, now: u64, held_steer: f64) -> ActuationRequest {
        let fresh =
            |c: Option<(f64, u64)>| c.filter(|(_, t)| v2t_edge::clock::secs_between(*t, now) <= ECU_COMMAND_TIMEOUT_S);
        match (fresh(self.accel), fresh(self.steer)) {
            (Some((a, _)), Some((s, _))) => ActuationRequest { accel_mps2: a, steer_rad: s },
            _ => {
                self.stats.timeout_steps += 1;
                ActuationRequest { accel_mps2: -ECU_TIMEOUT_DECEL_MPS2, steer_rad: held_steer }
            }
        }
    }
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

    fn publish_fix(&mut self, state: &v2t_model::kinematics::State, age_s: f64) -> Result<(), EcuError> {
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
        Ok(send(&self.fixes, Some(&self.fix_wake), fix)?)
    }

    fn publish_vut(&mut self, state: &v2t_model::kinematics::State, age_s: f64) -> Result<(), EcuError> {
        self.vut_header.seq += 1;
        self.vut_header.stamp_ns = now_ns().saturating_sub((age_s * 1e9) as u64);
        let v = VutState {
            header: self.vut_header,
            px_m: state.px,
            py_m: state.py,
            theta_rad: state.theta_rad,
            speed_mps: state.speed_mps,
        };
        Ok(send(&self.vut, None, v)?)
    }

    fn feedback(&mut self, speed: f64, yaw_rate: f64, steer: f64) -> Result<(), EcuError> {
        let fb = DbwFeedback {
            wheel_speed_mps: speed,
            yaw_rate_radps: yaw_rate,
            steer_rad: steer,
            mode: DbwMode::Auto.code(),
        };
        let frame = self.encoder.feedback(&fb).map_err(|e| EcuError::Can(e.to_string()))?;
        self.can.send(&frame).map_err(|e| EcuError::Can(e.to_string()))
    }
}

/// Runs the scenario of `opts` against the onboard stack of `cfg` in real time; returns the
/// measured run, the ECU's statistics and the run's realism. Ends early (with `Ok`) on SIGINT/SIGTERM.
pub fn run<S: Service + 'static>(cfg: &Loaded, opts: &EcuOptions) -> Result<EcuRun, EcuError> {
    let bus = Bus::<S>::new("sim-ecu", &cfg.edge.namespace)?;
    // The regulator's decisions, for the recording.
    let plan_in = bus.subscriber::<RegulatedPlan>(services::PLAN)?;
    let mut plans = Vec::new();
    let (scenario, card_prior) = world_of::<S>(cfg, opts, &bus)?;
    let model = opts.vut.unwrap_or(scenario.vut.default_model);
    let sumo_world = match &opts.sumo {
        Some((map, driver)) => Some((crate::sumo::SumoWorld::new(map)?, driver)),
        None => None,
    };
    let mut session = match &sumo_world {
        Some((w, driver)) => Some(w.session(driver, &scenario, opts.seed)?),
        None => None,
    };
    let vut_name = match &opts.sumo {
        Some((_, driver)) => driver.name.clone(),
        None => model.as_str().to_owned(),
    };
    let finish = |outcome: RunOutcome, stats: EcuStats, plans: Vec<PlanRecord>, gate: Vec<GateRecord>| {
        let realism = opts.human.as_ref().and_then(|h| v2t_sim::realism::measure_run(&scenario, &outcome, h).ok());
        EcuRun { outcome, stats, plans, gate, realism }
    };
    let mut gate_log = GateLog::default();
    let mut driver = model.driver();
    let mut io = Io {
        fixes: bus.publisher(services::LOCALIZATION)?,
        fix_wake: bus.notifier(services::WAKE_STATE)?,
        vut: bus.publisher(services::VUT)?,
        can: open_transport(cfg, &bus, End::Ecu)?,
        encoder: Encoder::default(),
        fix_header: Header::default(),
        vut_header: Header::default(),
        bus,
    };
    // A card's prior is sent again every second, as the cloud would: a node that (re)starts later
    // gets it too. An uplinked prior stays with the uplink node.
    let prior = PriorResend { out: card_prior, every: (1.0 / scenario.settings.plant_dt_s).round().max(1.0) as u64 };
    prior.send()?;
    let mut sim = Simulation::new(&scenario, opts.seed);
    let dt = scenario.settings.plant_dt_s;
    let step_ns = (dt * 1e9) as u64;
    let control_every = scenario.settings.control_every();
    let wheelbase = scenario.bvs.first().map_or(2.8, |b| b.agent.vehicle.geometry.wheelbase_m);
    let mut cmds = Commands::default();

    if !stand_until_engaged(&mut io, &mut cmds, &sim, &scenario, opts.engage_timeout_s, &prior, step_ns)? {
        return Ok(finish(sim.finish(&vut_name, "v2t-edge"), cmds.stats, plans, gate_log.records));
    }

    let start = now_ns();
    let mut i: usize = 0;
    while !sim.is_done() {
        io.drain(&mut cmds);
        gate_log.log(i as f64 * dt, cmds.gate);
        while let Some(p) = plan_in.receive().map_err(|e| EdgeError::ipc("receive", services::PLAN, e))? {
            plans.push(plan_record(i as f64 * dt, &p));
        }
        prior.send_at(i as u64)?;
        let now = now_ns();
        let (_, held_steer) = sim.bv_actuators(0).unwrap_or((0.0, 0.0));
        sim.set_bv_request(0, cmds.request(now, held_steer));
        match session.as_mut() {
            Some(sumo) => sim.step_external(sumo, &mut |_, _| None)?,
            None => sim.step(driver.as_mut(), &mut |_, _| None),
        }
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
    Ok(finish(sim.finish(&vut_name, "v2t-edge"), cmds.stats, plans, gate_log.records))
}

/// The prior the ECU publishes in the cloud's stead, and where.
type PriorOut<S> = Option<(ActivePrior, iceoryx2::port::publisher::Publisher<S, ActivePrior, ()>)>;

/// The scenario of `opts.source`, and the prior to publish when the ECU stands in for the cloud
/// (a card or a prior file; an uplinked prior stays with the uplink node).
fn world_of<S: Service + 'static>(
    cfg: &Loaded,
    opts: &EcuOptions,
    bus: &Bus<S>,
) -> Result<(v2t_sim::scenario::Scenario, PriorOut<S>), EcuError> {
    match &opts.source {
        EcuSource::Card(card) => {
            let mut scenario = v2t_sim::files::load_scenario(card)?;
            if let Some(tau) = opts.tau_s {
                scenario.target = scenario.target.with_tau(tau)?;
            }
            if let Some(style) = opts.style {
                scenario.target = scenario.target.with_style(style);
            }
            let prior = world::prior_of_card(&scenario, 0, opts.seed.wrapping_add(1), now_ns())?;
            Ok((scenario, Some((prior, bus.publisher::<ActivePrior>(services::PRIOR)?))))
        }
        EcuSource::Prior { path, agent, sim_settings } => {
            let settings = v2t_files::load_toml(sim_settings)?;
            let file = v2t_files::read_prior(path)?;
            let prior = world::accept(&file, agent.as_deref(), vehicles(cfg), opts.seed.wrapping_add(1), now_ns())?;
            let model = opts.vut.unwrap_or(VutModel::IdmNormal);
            let name = format!("prior {}", prior.prior_id);
            let scenario = world::from_prior(&name, &prior, vehicles(cfg), settings, model)?;
            Ok((scenario, Some((prior, bus.publisher::<ActivePrior>(services::PRIOR)?))))
        }
        EcuSource::Uplink { sim_settings, wait_s } => {
            let settings = v2t_files::load_toml(sim_settings)?;
            let prior = uplinked_prior(bus, *wait_s)?;
            eprintln!("sim-ecu: prior {} from the uplink: τ {} s", prior.prior_id, prior.tau_s);
            let model = opts.vut.unwrap_or(VutModel::IdmNormal);
            let name = format!("prior {}", prior.prior_id);
            Ok((world::from_prior(&name, &prior, vehicles(cfg), settings, model)?, None))
        }
    }
}

/// The newest prior on the prior service, waiting for one at most `wait_s`.
fn uplinked_prior<S: Service + 'static>(bus: &Bus<S>, wait_s: f64) -> Result<ActivePrior, EcuError> {
    let priors = bus.subscriber::<ActivePrior>(services::PRIOR)?;
    let deadline = now_ns() + (wait_s * 1e9) as u64;
    loop {
        let mut newest = None;
        while let Some(sample) = priors.receive().map_err(|e| EdgeError::ipc("receive", services::PRIOR, e))? {
            newest = Some(sample.clone());
        }
        if let Some(p) = newest {
            return Ok(p);
        }
        if now_ns() > deadline || !bus.wait(Duration::from_millis(20)) {
            return Err(EcuError::NoPrior(wait_s));
        }
    }
}

/// The prior the ECU publishes as the cloud would, and again every `every` plant steps.
struct PriorResend<S: Service + 'static> {
    out: PriorOut<S>,
    every: u64,
}

impl<S: Service + 'static> PriorResend<S> {
    fn send(&self) -> Result<(), EcuError> {
        match &self.out {
            Some((prior, out)) => out
                .send_copy(prior.clone())
                .map(|_| ())
                .map_err(|e| EcuError::from(EdgeError::ipc("send", services::PRIOR, e))),
            None => Ok(()),
        }
    }

    /// Sends the prior when step `k` is due.
    fn send_at(&self, k: u64) -> Result<(), EcuError> {
        if k.is_multiple_of(self.every) { self.send() } else { Ok(()) }
    }
}

/// Before the start: the BV stands at its start (sensors alive, the prior resent) until the
/// gateway engages. `Ok(false)` when a signal ended the wait.
fn stand_until_engaged<S: Service + 'static>(
    io: &mut Io<S>,
    cmds: &mut Commands,
    sim: &Simulation,
    scenario: &v2t_sim::scenario::Scenario,
    timeout_s: f64,
    prior: &PriorResend<S>,
    step_ns: u64,
) -> Result<bool, EcuError> {
    let deadline = now_ns() + (timeout_s * 1e9) as u64;
    let mut k: u64 = 0;
    while !cmds.engaged {
        if now_ns() > deadline {
            return Err(EcuError::NotEngaged(timeout_s));
        }
        io.drain(cmds);
        prior.send_at(k)?;
        if let (Some(st), Some((vut, _))) =
            (sim.bv_truth(0), sim.vut_seen_by_bvs().or_else(|| Some((scenario_start_vut(scenario), 0.0))))
        {
            if k.is_multiple_of(FIX_EVERY as u64) {
                io.publish_fix(&st, 0.0)?;
                io.publish_vut(&vut, 0.0)?;
            }
            io.feedback(st.speed_mps, 0.0, 0.0)?;
        }
        k += 1;
        if !io.bus.wait(Duration::from_nanos(step_ns)) {
            return Ok(false);
        }
    }
    Ok(true)
}

/// The actuation gate's state as `BV_ControlState` reported it: every change.
#[derive(Default)]
struct GateLog {
    records: Vec<GateRecord>,
    code: Option<u8>,
}

impl GateLog {
    /// Records `code` at `t_s` when it differs from the last one.
    fn log(&mut self, t_s: f64, code: Option<u8>) {
        let Some(code) = code.filter(|c| self.code != Some(*c)) else { return };
        self.code = Some(code);
        let state = GateState::from_code(code).map_or_else(|_| format!("code {code}"), |g| format!("{g:?}"));
        self.records.push(GateRecord { t_s, state });
    }
}

/// A regulator's decision as the recording keeps it, received at `t_s`.
fn plan_record(t_s: f64, p: &RegulatedPlan) -> PlanRecord {
    PlanRecord {
        t_s,
        prior_id: p.prior_id,
        status: PlanStatus::from_code(p.status).map_or_else(|_| format!("code {}", p.status), |s| format!("{s:?}")),
        s_m: p.s0_m,
        v_mps: p.v0_mps,
        accel_mps2: p.accel_mps2,
        predicted_pet_s: (p.has_predicted_pet != 0 && p.predicted_pet_s.is_finite()).then_some(p.predicted_pet_s),
        below_reach: (p.below_reach != 0).then(|| {
            BelowReachCode::from_code(p.below_reach)
                .map_or_else(|_| format!("code {}", p.below_reach), |c| format!("{c:?}"))
        }),
        pet_bound_s: (p.below_reach != 0 && p.has_pet_bound != 0 && p.pet_bound_s.is_finite()).then_some(p.pet_bound_s),
        vut_reacts_p: (p.has_reaction != 0 && p.vut_reacts_p.is_finite()).then_some(p.vut_reacts_p),
        vut_gap_s: (p.has_reaction != 0 && p.vut_gap_s.is_finite()).then_some(p.vut_gap_s),
        vut_gap_sd_s: (p.has_reaction != 0 && p.vut_gap_sd_s.is_finite()).then_some(p.vut_gap_sd_s),
        solve_us: p.solve_ns as f64 * 1e-3,
    }
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
