//! The monitor node: a watchdog on every node's heartbeat and on the freshness of the BV state.
//! A silent node or a stale state makes it ask the gateway for the minimal-risk stop (and keep
//! asking while the fault lasts); the first time everything is healthy it may engage the gate.
//! Engaging again after a stop takes an explicit request: a restarted node resumes its work, but
//! the BV only moves again when the operator says so.
//!
//! It also reports, at most once a second per node, the cycles a node counted as over its budget
//! (the heartbeat's `deadline_misses`; the regulator's budget is `timing.regulator_budget_s`).

use std::time::Duration;

use iceoryx2::service::Service;
use v2t_wire::{
    BvState, Code, GateReport, GateState, Header, Heartbeat, NodeKind, SafetyAction, SafetyCommand, services,
};

use crate::clock::now_ns;
use crate::config::Loaded;
use crate::error::EdgeError;
use crate::heart::Heart;
use crate::ports::{Bus, latest, send};

/// While unhealthy, the stop request is repeated this often, ns.
const REPEAT_NS: u64 = 100_000_000;

/// Deadline misses of one node are reported at most this often, ns.
const OVERRUN_REPORT_NS: u64 = 1_000_000_000;

/// A node counted cycles over its budget since the last report.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Overruns {
    /// The node.
    pub node: NodeKind,
    /// Misses since the last report.
    pub new: u64,
    /// Misses since the node started.
    pub total: u64,
    /// Its longest cycle so far, ns.
    pub max_cycle_ns: u64,
}

/// The deadline misses of one node already reported, and when.
#[derive(Debug, Clone, Copy, Default)]
struct MissesSeen {
    reported: u64,
    at_ns: Option<u64>,
}

/// The watchdog's judgement. Pure: time comes in as arguments.
#[derive(Debug, Clone)]
pub struct Watchdog {
    expected: Vec<NodeKind>,
    last_beat_ns: Vec<Option<u64>>,
    misses: Vec<MissesSeen>,
    heartbeat_timeout_ns: u64,
    state_timeout_ns: u64,
    last_state_ns: Option<u64>,
    auto_engage: bool,
    healthy_once: bool,
    /// The automatic engage is over: the gate engaged once, or a stop came first.
    engage_done: bool,
    last_engage_ns: Option<u64>,
    unhealthy_since_ns: Option<u64>,
    last_stop_ns: u64,
    header: Header,
}

impl Watchdog {
    /// Watches `expected` nodes.
    pub fn new(expected: Vec<NodeKind>, heartbeat_timeout_s: f64, state_timeout_s: f64, auto_engage: bool) -> Self {
        let n = expected.len();
        Self {
            expected,
            last_beat_ns: vec![None; n],
            misses: vec![MissesSeen::default(); n],
            heartbeat_timeout_ns: (heartbeat_timeout_s * 1e9) as u64,
            state_timeout_ns: (state_timeout_s * 1e9) as u64,
            last_state_ns: None,
            auto_engage,
            healthy_once: false,
            engage_done: false,
            last_engage_ns: None,
            unhealthy_since_ns: None,
            last_stop_ns: 0,
            header: Header::default(),
        }
    }

    /// A heartbeat arrived at `now_ns`. Returns the node's new deadline misses when they are due
    /// to be reported.
    pub fn heartbeat(&mut self, beat: &Heartbeat, now_ns: u64) -> Option<Overruns> {
        let kind = NodeKind::from_code(beat.node).ok()?;
        let i = self.expected.iter().position(|k| *k == kind)?;
        if let Some(slot) = self.last_beat_ns.get_mut(i) {
            *slot = Some(now_ns);
        }
        let seen = self.misses.get_mut(i)?;
        if beat.deadline_misses < seen.reported {
            // The node restarted: its count did too.
            seen.reported = 0;
        }
        let due = seen.at_ns.is_none_or(|t| now_ns.saturating_sub(t) >= OVERRUN_REPORT_NS);
        if beat.deadline_misses == seen.reported || !due {
            return None;
        }
        let new = beat.deadline_misses - seen.reported;
        *seen = MissesSeen { reported: beat.deadline_misses, at_ns: Some(now_ns) };
        Some(Overruns { node: kind, new, total: beat.deadline_misses, max_cycle_ns: beat.max_cycle_ns })
    }

    /// A BV state valid at `stamp_ns` arrived.
    pub fn state(&mut self, stamp_ns: u64) {
        self.last_state_ns = Some(self.last_state_ns.map_or(stamp_ns, |t| t.max(stamp_ns)));
    }

    /// The first problem at `now_ns`, if any: the node at fault.
    pub fn fault(&self, now_ns: u64) -> Option<NodeKind> {
        for (kind, last) in self.expected.iter().zip(&self.last_beat_ns) {
            if last.is_none_or(|t| now_ns.saturating_sub(t) > self.heartbeat_timeout_ns) {
                return Some(*kind);
            }
        }
        if self.last_state_ns.is_none_or(|t| now_ns.saturating_sub(t) > self.state_timeout_ns) {
            return Some(NodeKind::State);
        }
        None
    }

    /// The gate reported it is engaged: the automatic engage is over.
    pub fn gate_engaged(&mut self) {
        self.engage_done = true;
    }

    /// Whether an unhealthy spell is on.
    pub fn is_unhealthy(&self) -> bool {
        self.unhealthy_since_ns.is_some()
    }

    /// What to tell the gateway at `now_ns`, if anything.
    pub fn check(&mut self, now_ns: u64) -> Option<SafetyCommand> {
        let fault = self.fault(now_ns);
        let action = match fault {
            None => {
                self.unhealthy_since_ns = None;
                self.healthy_once = true;
                // The gate refuses until commands and feedback flow: ask again until it engages.
                if self.auto_engage
                    && !self.engage_done
                    && self.last_engage_ns.is_none_or(|t| now_ns.saturating_sub(t) >= REPEAT_NS)
                {
                    self.last_engage_ns = Some(now_ns);
                    Some((SafetyAction::Engage, None))
                } else {
                    None
                }
            }
            // Before the runtime was ever healthy the gate is disengaged anyway: start-up is not a fault.
            Some(_) if !self.healthy_once => None,
            Some(culprit) => {
                let new = self.unhealthy_since_ns.is_none();
                if new {
                    self.unhealthy_since_ns = Some(now_ns);
                }
                if new || now_ns.saturating_sub(self.last_stop_ns) >= REPEAT_NS {
                    self.last_stop_ns = now_ns;
                    // After a stop, only the operator engages again.
                    self.engage_done = true;
                    Some((SafetyAction::MinimalRiskStop, Some(culprit)))
                } else {
                    None
                }
            }
        }?;
        self.header.seq += 1;
        self.header.stamp_ns = now_ns;
        Some(SafetyCommand { header: self.header, action: action.0.code(), culprit: action.1.map_or(0, |k| k.code()) })
    }
}

/// Runs the monitor node until termination.
pub fn run<S: Service>(cfg: &Loaded) -> Result<(), EdgeError> {
    let bus = Bus::<S>::new("monitor", &cfg.edge.namespace)?;
    let beats = bus.subscriber::<Heartbeat>(services::HEARTBEAT)?;
    let states = bus.subscriber::<BvState>(services::STATE)?;
    let gate = bus.subscriber::<GateReport>(services::GATE)?;
    let out = bus.publisher::<SafetyCommand>(services::SAFETY)?;
    let out_wake = bus.notifier(services::WAKE_GATEWAY)?;
    let t = cfg.edge.timing;
    let mut heart = Heart::new(&bus, NodeKind::Monitor, t.heartbeat_period_s)?;
    let expected = cfg.edge.launch.nodes.iter().filter(|n| **n != crate::NodeRole::Monitor).map(|n| n.kind()).collect();
    let mut dog = Watchdog::new(expected, t.heartbeat_timeout_s, t.state_timeout_s, cfg.edge.launch.auto_engage);
    let period = Duration::from_secs_f64(t.monitor_period_s);
    loop {
        let now = now_ns();
        while let Some(beat) = beats.receive().map_err(|e| EdgeError::ipc("receive", services::HEARTBEAT, e))? {
            if let Some(o) = dog.heartbeat(&beat, now) {
                eprintln!(
                    "monitor: {:?} overran its cycle budget {} more time(s), {} in all (longest cycle {:.1} ms)",
                    o.node,
                    o.new,
                    o.total,
                    o.max_cycle_ns as f64 * 1e-6
                );
            }
        }
        if let Some(s) = latest(&states)? {
            // Judge the state by its own stamp: a state that arrives late is as stale as none.
            dog.state(s.header.stamp_ns);
        }
        while let Some(r) = gate.receive().map_err(|e| EdgeError::ipc("receive", services::GATE, e))? {
            if r.state == GateState::Engaged.code() {
                dog.gate_engaged();
            }
        }
        if let Some(cmd) = dog.check(now) {
            if cmd.action == SafetyAction::MinimalRiskStop.code() {
                let culprit = NodeKind::from_code(cmd.culprit).map(|k| format!("{k:?}")).unwrap_or_default();
                eprintln!("monitor: minimal-risk stop ({culprit})");
            }
            send(&out, Some(&out_wake), cmd)?;
        }
        heart.cycle(now_ns() - now, (t.monitor_period_s * 1e9) as u64);
        heart.tick(now_ns(), !dog.is_unhealthy())?;
        if !bus.wait(period) {
            return Ok(());
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MS: u64 = 1_000_000;

    fn beat(node: NodeKind) -> Heartbeat {
        Heartbeat { node: node.code(), ..Heartbeat::default() }
    }

    fn all_beat(dog: &mut Watchdog, now: u64) {
        for k in [NodeKind::State, NodeKind::Regulator] {
            dog.heartbeat(&beat(k), now);
        }
        dog.state(now);
    }

    #[test]
    fn engages_until_the_gate_reports_it_then_stops_on_a_silent_node_and_keeps_stopping() {
        let mut dog = Watchdog::new(vec![NodeKind::State, NodeKind::Regulator], 0.06, 0.2, true);
        assert_eq!(dog.check(0), None, "start-up is not a fault");
        all_beat(&mut dog, 10 * MS);
        let c = dog.check(10 * MS).unwrap();
        assert_eq!(c.action, SafetyAction::Engage.code());
        all_beat(&mut dog, 30 * MS);
        assert_eq!(dog.check(30 * MS), None, "not again within 100 ms");
        all_beat(&mut dog, 110 * MS);
        assert_eq!(dog.check(110 * MS).map(|c| c.action), Some(SafetyAction::Engage.code()), "asks again");
        dog.gate_engaged();
        all_beat(&mut dog, 220 * MS);
        assert_eq!(dog.check(220 * MS), None, "engaged: no more requests");
        // The regulator goes silent after 220 ms; the state keeps coming.
        for t in (230..=400).step_by(10) {
            dog.heartbeat(&beat(NodeKind::State), t * MS);
            dog.state(t * MS);
        }
        assert_eq!(dog.check(280 * MS), None, "60 ms timeout not yet over");
        let c = dog.check(281 * MS).unwrap();
        assert_eq!((c.action, c.culprit), (SafetyAction::MinimalRiskStop.code(), NodeKind::Regulator.code()));
        assert_eq!(dog.check(350 * MS), None);
        assert!(dog.check(381 * MS).is_some(), "repeated while the fault lasts");
        // It comes back: healthy again, but no automatic re-engage.
        all_beat(&mut dog, 500 * MS);
        assert_eq!(dog.check(500 * MS), None);
        assert!(!dog.is_unhealthy());
    }

    #[test]
    fn deadline_misses_are_reported_at_most_once_a_second_and_a_restart_starts_over() {
        let mut dog = Watchdog::new(vec![NodeKind::State, NodeKind::Regulator], 0.06, 0.2, true);
        let reg =
            |misses: u64| Heartbeat { deadline_misses: misses, max_cycle_ns: 120 * MS, ..beat(NodeKind::Regulator) };
        assert_eq!(dog.heartbeat(&reg(0), 0), None, "none missed");
        let o = dog.heartbeat(&reg(1), 20 * MS).unwrap();
        assert_eq!((o.node, o.new, o.total, o.max_cycle_ns), (NodeKind::Regulator, 1, 1, 120 * MS));
        assert_eq!(dog.heartbeat(&reg(3), 40 * MS), None, "not again within a second");
        let o = dog.heartbeat(&reg(4), 1_020 * MS).unwrap();
        assert_eq!((o.new, o.total), (3, 4), "what came meanwhile is in the next report");
        assert_eq!(dog.heartbeat(&reg(4), 3_000 * MS), None, "nothing new");
        let o = dog.heartbeat(&reg(2), 3_020 * MS).unwrap();
        assert_eq!((o.new, o.total), (2, 2), "a restarted node counts from zero");
        assert_eq!(dog.fault(3_020 * MS), Some(NodeKind::State), "the beats still count as beats");
    }

    #[test]
    fn a_stale_state_is_a_fault_of_the_state_path() {
        let mut dog = Watchdog::new(vec![NodeKind::State], 0.06, 0.2, false);
        dog.heartbeat(&beat(NodeKind::State), 0);
        dog.state(0);
        assert_eq!(dog.check(0), None, "no auto engage");
        dog.heartbeat(&beat(NodeKind::State), 250 * MS);
        let c = dog.check(250 * MS).unwrap();
        assert_eq!((c.action, c.culprit), (SafetyAction::MinimalRiskStop.code(), NodeKind::State.code()));
    }
}
