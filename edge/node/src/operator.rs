//! Operator requests to the gateway (engage, stop, disengage, e-stop) from the command line.

use std::time::Duration;

use iceoryx2::service::Service;
use v2t_wire::{BvState, Code, GateReport, GateState, Header, SafetyAction, SafetyCommand, services};

use crate::clock::now_ns;
use crate::config::Loaded;
use crate::error::EdgeError;
use crate::ports::{Bus, latest, send};

/// Sends `action` to the gateway of `cfg`'s BV.
pub fn request<S: Service>(cfg: &Loaded, action: SafetyAction) -> Result<(), EdgeError> {
    let bus = Bus::<S>::new("operator", &cfg.edge.namespace)?;
    let out = bus.publisher::<SafetyCommand>(services::SAFETY)?;
    let wake = bus.notifier(services::WAKE_GATEWAY)?;
    // Let the gateway's subscriber connect to the new publisher before the request goes out.
    bus.wait(Duration::from_millis(50));
    let cmd = SafetyCommand { header: Header { seq: 1, stamp_ns: now_ns() }, action: action.code(), culprit: 0 };
    send(&out, Some(&wake), cmd)?;
    // Keep the publisher (and its history) alive a moment so a gateway between cycles still reads it.
    bus.wait(Duration::from_millis(100));
    Ok(())
}

/// Below this speed the BV stands, m/s.
pub const STANDSTILL_MPS: f64 = 0.05;

/// How a wait for the minimal-risk stop ended.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum StopWait {
    /// The gate is in its minimal-risk stop (or disengaged, or failed) and the BV stands.
    Stopped {
        /// Seconds from the request.
        after_s: f64,
    },
    /// No BV state arrived within a second: no runtime is running, nothing moves.
    NoRuntime,
    /// Still moving (or the gate not stopping) when the time was up.
    TimedOut {
        /// The BV's last speed, m/s.
        speed_mps: f64,
        /// The gate's last state.
        gate: Option<GateState>,
    },
}

/// Requests the minimal-risk stop of `cfg`'s BV and waits up to `limit` until the BV stands with
/// its gate stopped (what the service's `ExecStop` does before the runtime is terminated, so that
/// the gateway keeps commanding the braking until it is done).
pub fn stop_and_wait<S: Service>(cfg: &Loaded, limit: Duration) -> Result<StopWait, EdgeError> {
    let bus = Bus::<S>::new("operator", &cfg.edge.namespace)?;
    let states = bus.subscriber::<BvState>(services::STATE)?;
    let gates = bus.subscriber::<GateReport>(services::GATE)?;
    request::<S>(cfg, SafetyAction::MinimalRiskStop)?;
    let started = std::time::Instant::now();
    let (mut speed, mut gate, mut heard) = (f64::NAN, None, false);
    while started.elapsed() < limit {
        if let Some(s) = latest(&states)? {
            speed = s.speed_mps;
            heard = true;
        }
        if let Some(g) = latest(&gates)? {
            gate = GateState::from_code(g.state).ok();
        }
        let gate_stopped = matches!(gate, Some(GateState::MinimalRiskStop | GateState::Disengaged | GateState::Fault));
        if heard && gate_stopped && speed.abs() < STANDSTILL_MPS {
            return Ok(StopWait::Stopped { after_s: started.elapsed().as_secs_f64() });
        }
        if !heard && started.elapsed() > Duration::from_secs(1) {
            return Ok(StopWait::NoRuntime);
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    Ok(StopWait::TimedOut { speed_mps: speed, gate })
}
