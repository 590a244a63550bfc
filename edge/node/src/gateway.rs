//! The CAN gateway node: the only process that talks to the actuators. Every tracker command and
//! every safety request goes through the safety gate (`v2t-can`); only what leaves the gate is
//! encoded (DBC codec, rolling counters, checksums) and written to the bus. It transmits every
//! `timing.gateway_period_s` and at once on a new command; drive-by-wire feedback frames are
//! decoded and published for the state node; rejected frames are counted and reported.

use std::time::Duration;

use iceoryx2::service::Service;
use v2t_can::codec::{AccelCmd, CanFrame, ControlState, Decoder, Encoder, Message, SteerCmd};
use v2t_can::gate::{Command, GateInput, GateOutput, Request, SafetyGate};
use v2t_can::transport::{CanTransport, SocketCanBus};
use v2t_wire::{
    ActuationCommand, Code, GateReport, Header, NodeKind, SafetyAction, SafetyCommand, VehicleFeedback, services,
};

use crate::canbus::{End, IpcCanBus};
use crate::clock::{Throttle, now_ns, skipped_note};
use crate::config::{CanLink, Loaded};
use crate::error::EdgeError;
use crate::heart::Heart;
use crate::ports::{Bus, latest, send, wait_wake};

/// The gate's request for a safety command.
pub fn request_of(cmd: &SafetyCommand) -> Option<Request> {
    match SafetyAction::from_code(cmd.action).ok()? {
        SafetyAction::Engage => Some(Request::Engage),
        SafetyAction::MinimalRiskStop => Some(Request::MinimalRiskStop),
        SafetyAction::Disengage => Some(Request::Disengage),
        SafetyAction::EStop => Some(Request::EStop),
        SafetyAction::Reset => Some(Request::Reset),
    }
}

/// Frame counters of the gateway.
#[derive(Debug, Clone, Copy, Default)]
pub struct Counters {
    /// Frames written.
    pub tx: u64,
    /// Frames accepted.
    pub rx: u64,
    /// Frames rejected by the decoder.
    pub rejected: u64,
    /// Transport errors.
    pub bus_errors: u64,
}

/// Gate + codec: everything the gateway decides, without the IO. Pure: time comes in as arguments.
#[derive(Debug)]
pub struct Gateway {
    gate: SafetyGate,
    encoder: Encoder,
    decoder: Decoder,
    feedback: Option<VehicleFeedback>,
    feedback_header: Header,
    /// Frame statistics.
    pub counters: Counters,
    heartbeat: u8,
    /// Rejected frames: one log line per second at most.
    reject_log: Throttle,
}

/// One log line per second at most for each recurring CAN problem.
const LOG_PERIOD_NS: u64 = 1_000_000_000;

impl Gateway {
    /// A gateway with the gate of `cfg`.
    pub fn new(cfg: &Loaded) -> Self {
        Self {
            gate: SafetyGate::new(cfg.gate.clone(), &cfg.vehicle),
            encoder: Encoder::default(),
            decoder: Decoder::default(),
            feedback: None,
            feedback_header: Header::default(),
            counters: Counters::default(),
            heartbeat: 0,
            reject_log: Throttle::new(LOG_PERIOD_NS),
        }
    }

    /// Decodes a received frame; feedback becomes a [`VehicleFeedback`] stamped `now_ns`.
    pub fn receive(&mut self, frame: &CanFrame, now_ns: u64) -> Option<VehicleFeedback> {
        match self.decoder.decode(frame) {
            Ok(Message::Feedback(fb)) => {
                self.counters.rx += 1;
                self.feedback_header.seq += 1;
                self.feedback_header.stamp_ns = now_ns;
                let out = VehicleFeedback {
                    header: self.feedback_header,
                    wheel_speed_mps: fb.wheel_speed_mps,
                    yaw_rate_radps: fb.yaw_rate_radps,
                    steer_rad: fb.steer_rad,
                    mode: fb.mode,
                };
                self.feedback = Some(out);
                Some(out)
            }
            // Our own command frames echoed by the bus (several nodes on one bus) are not input.
            Ok(_) => None,
            Err(e) => {
                self.counters.rejected += 1;
                if let Some(skipped) = self.reject_log.admit(now_ns) {
                    eprintln!("gateway: frame {:#05x} rejected: {e}{}", frame.id, skipped_note(skipped));
                }
                None
            }
        }
    }

    /// One gate step at `now_ns` with the newest command and a safety request, if any.
    pub fn step(&mut self, now_ns: u64, command: Option<&ActuationCommand>, request: Option<Request>) -> GateOutput {
        let s = |ns: u64| ns as f64 * 1e-9;
        let input = GateInput {
            command: command.map(|c| Command {
                accel_mps2: c.accel_mps2,
                steer_rad: c.steer_rad,
                stamp_s: s(c.header.stamp_ns),
            }),
            request,
            speed_mps: self.feedback.map_or(0.0, |f| f.wheel_speed_mps),
            dbw_mode: self.feedback.map_or(0, |f| f.mode),
            feedback_stamp_s: self.feedback.map(|f| s(f.header.stamp_ns)),
        };
        self.gate.step(s(now_ns), &input)
    }

    /// The frames that carry `out`.
    pub fn frames(&mut self, out: &GateOutput) -> Result<[CanFrame; 3], EdgeError> {
        self.heartbeat = self.heartbeat.wrapping_add(1);
        let accel = self.encoder.accel(&AccelCmd { accel_mps2: out.accel_mps2, enable: out.enable })?;
        let steer = self.encoder.steer(&SteerCmd { steer_rad: out.steer_rad, enable: out.enable })?;
        let control = self.encoder.control(&ControlState {
            gate_state: out.state.code(),
            engage_request: out.enable,
            heartbeat: self.heartbeat,
        })?;
        Ok([accel, steer, control])
    }
}

/// The CAN transport of `cfg` for this end of the bus: the SocketCAN interface, or the iceoryx2
/// virtual bus.
pub fn open_transport<S: Service + 'static>(
    cfg: &Loaded,
    bus: &Bus<S>,
    end: End,
) -> Result<Box<dyn CanTransport>, EdgeError> {
    Ok(match &cfg.edge.can {
        CanLink::Socketcan { interface } => Box::new(SocketCanBus::open(interface)?),
        CanLink::Ipc => Box::new(IpcCanBus::open(bus, end)?),
    })
}

/// Runs the gateway node until termination.
pub fn run<S: Service + 'static>(cfg: &Loaded) -> Result<(), EdgeError> {
    let bus = Bus::<S>::new("gateway", &cfg.edge.namespace)?;
    let commands = bus.subscriber::<ActuationCommand>(services::ACTUATION)?;
    let safety = bus.subscriber::<SafetyCommand>(services::SAFETY)?;
    let wake = bus.listener(services::WAKE_GATEWAY)?;
    let feedback_out = bus.publisher::<VehicleFeedback>(services::FEEDBACK)?;
    let report_out = bus.publisher::<GateReport>(services::GATE)?;
    let mut transport = open_transport(cfg, &bus, End::Gateway)?;
    let t = cfg.edge.timing;
    let mut heart = Heart::new(&bus, NodeKind::Gateway, t.heartbeat_period_s)?;
    let mut gw = Gateway::new(cfg);
    let period_ns = (t.gateway_period_s * 1e9) as u64;
    let mut next_ns = now_ns();
    let mut command: Option<ActuationCommand> = None;
    let mut report = GateReport::default();
    let (mut bus_log, mut send_log) = (Throttle::new(LOG_PERIOD_NS), Throttle::new(LOG_PERIOD_NS));
    loop {
        let wait = next_ns.saturating_sub(now_ns());
        wait_wake(&wake, Duration::from_nanos(wait))?;
        if bus.terminating() {
            break;
        }
        let now = now_ns();
        // Feedback first, so the gate judges the newest vehicle state.
        loop {
            match transport.recv(Duration::ZERO) {
                Ok(Some(frame)) => {
                    if let Some(fb) = gw.receive(&frame, now) {
                        send(&feedback_out, None, fb)?;
                    }
                }
                Ok(None) => break,
                // A controller fault (bus-off, error-passive, …) stops the BV; a frame we do not
                // speak (extended, remote, FD) from another node is counted and skipped.
                Err(e) if e.is_bus_fault() => {
                    gw.counters.bus_errors += 1;
                    if let Some(skipped) = bus_log.admit(now) {
                        eprintln!("gateway: bus error: {e}{}", skipped_note(skipped));
                    }
                    gw.gate_bus_error();
                    break;
                }
                Err(e) => {
                    gw.counters.rejected += 1;
                    if let Some(skipped) = gw.reject_log.admit(now) {
                        eprintln!("gateway: frame rejected: {e}{}", skipped_note(skipped));
                    }
                }
            }
        }
        let fresh = latest(&commands)?;
        if fresh.is_some() {
            command = fresh;
        }
        // Every safety request, in order.
        let mut request = None;
        while let Some(s) = safety.receive().map_err(|e| EdgeError::ipc("receive", services::SAFETY, e))? {
            request = request_of(&s).or(request);
        }
        if fresh.is_none() && request.is_none() && now < next_ns {
            continue;
        }
        if now >= next_ns {
            next_ns = (next_ns + period_ns).max(now);
        }
        let out = gw.step(now, command.as_ref(), request);
        if (out.state.code(), out.reason.code()) != (report.state, report.reason) || report.header.seq == 0 {
            eprintln!("gateway: gate {:?} ({:?})", out.state, out.reason);
        }
        for frame in gw.frames(&out)? {
            match transport.send(&frame) {
                Ok(()) => gw.counters.tx += 1,
                Err(e) => {
                    gw.counters.bus_errors += 1;
                    if let Some(skipped) = send_log.admit(now) {
                        eprintln!("gateway: cannot send {:#05x}: {e}{}", frame.id, skipped_note(skipped));
                    }
                }
            }
        }
        let sent = now_ns();
        report.header.seq += 1;
        report.header.stamp_ns = sent;
        report.state = out.state.code();
        report.reason = out.reason.code();
        report.accel_sent_mps2 = out.accel_mps2;
        report.steer_sent_rad = out.steer_rad;
        report.frames_tx = gw.counters.tx;
        report.frames_rx = gw.counters.rx;
        report.frames_rejected = gw.counters.rejected;
        report.bus_errors = gw.counters.bus_errors;
        report.fresh_command = u8::from(fresh.is_some());
        report.state_received_ns = fresh.map_or(0, |c| c.state_received_ns);
        send(&report_out, None, report)?;
        heart.cycle(sent - now, period_ns);
        heart.tick(sent, gw.feedback.is_some())?;
    }
    // Leaving: command the stop profile once more so the ECU's own timeout meets a braking request.
    let out = gw.step(now_ns(), None, Some(Request::MinimalRiskStop));
    for frame in gw.frames(&out)? {
        let _ = transport.send(&frame);
    }
    Ok(())
}

impl Gateway {
    /// A transport error: the gate goes to its minimal-risk stop.
    pub fn gate_bus_error(&mut self) {
        self.gate.bus_error();
    }
}
