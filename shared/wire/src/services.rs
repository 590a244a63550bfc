//! Names of the onboard iceoryx2 services, in one place. Every BV's services live under its own
//! namespace (`<namespace>/<leaf>`, e.g. `v2t/bv1/state`), so several BVs, or several tests, can
//! share one machine.

/// GNSS/INS fixes ([`crate::Localization`]).
pub const LOCALIZATION: &str = "localization";
/// Decoded drive-by-wire feedback ([`crate::VehicleFeedback`]).
pub const FEEDBACK: &str = "feedback";
/// The fused BV state ([`crate::BvState`]).
pub const STATE: &str = "state";
/// The VUT's state ([`crate::VutState`]).
pub const VUT: &str = "vut";
/// The active prior ([`crate::ActivePrior`]).
pub const PRIOR: &str = "prior";
/// Regulator decisions ([`crate::RegulatedPlan`]).
pub const PLAN: &str = "plan";
/// What a run taught the regulator about the VUT ([`crate::RunLearnedMsg`]), once per run.
pub const LEARNED: &str = "learned";
/// Tracker requests ([`crate::ActuationCommand`]).
pub const ACTUATION: &str = "actuation";
/// Monitor and operator requests to the gateway ([`crate::SafetyCommand`]).
pub const SAFETY: &str = "safety";
/// The gateway's report ([`crate::GateReport`]).
pub const GATE: &str = "gate";
/// Heartbeats of every node ([`crate::Heartbeat`]).
pub const HEARTBEAT: &str = "heartbeat";
/// Virtual CAN bus, gateway → ECU ([`crate::CanFrameMsg`]).
pub const CAN_TX: &str = "can/tx";
/// Virtual CAN bus, ECU → gateway ([`crate::CanFrameMsg`]).
pub const CAN_RX: &str = "can/rx";

/// Event service that wakes the state node (a new localization fix).
pub const WAKE_STATE: &str = "wake/state";
/// Event service that wakes the tracker (a new BV state).
pub const WAKE_TRACKER: &str = "wake/tracker";
/// Event service that wakes the gateway (a new actuation command or safety request).
pub const WAKE_GATEWAY: &str = "wake/gateway";
/// Event service that wakes the simulated ECU (a frame on the virtual bus).
pub const WAKE_ECU: &str = "wake/ecu";

/// Every publish-subscribe service leaf.
pub const ALL: [&str; 13] =
    [LOCALIZATION, FEEDBACK, STATE, VUT, PRIOR, PLAN, LEARNED, ACTUATION, SAFETY, GATE, HEARTBEAT, CAN_TX, CAN_RX];

/// Every event service leaf.
pub const WAKES: [&str; 4] = [WAKE_STATE, WAKE_TRACKER, WAKE_GATEWAY, WAKE_ECU];

/// The full service name of `leaf` under `namespace`.
pub fn name(namespace: &str, leaf: &str) -> String {
    format!("{namespace}/{leaf}")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_are_unique_and_namespaced() {
        let mut all: Vec<String> = ALL.iter().chain(WAKES.iter()).map(|l| name("v2t/bv1", l)).collect();
        all.sort();
        all.dedup();
        assert_eq!(all.len(), ALL.len() + WAKES.len());
        assert_eq!(name("v2t/bv1", STATE), "v2t/bv1/state");
    }
}
