//! Heartbeats and cycle timing of a node.

use iceoryx2::port::publisher::Publisher;
use iceoryx2::service::Service;
use v2t_wire::{Code, Header, Heartbeat, NodeKind, services};

use crate::error::EdgeError;
use crate::ports::Bus;

/// Publishes a node's heartbeat on schedule and keeps its cycle statistics.
#[derive(Debug)]
pub struct Heart<S: Service> {
    publisher: Publisher<S, Heartbeat, ()>,
    beat: Heartbeat,
    period_ns: u64,
    last_ns: u64,
}

impl<S: Service> Heart<S> {
    /// A heart for `node` beating every `period_s`.
    pub fn new(bus: &Bus<S>, node: NodeKind, period_s: f64) -> Result<Self, EdgeError> {
        Ok(Self {
            publisher: bus.publisher(services::HEARTBEAT)?,
            beat: Heartbeat { node: node.code(), inputs_ok: 0, ..Heartbeat::default() },
            period_ns: (period_s * 1e9) as u64,
            last_ns: 0,
        })
    }

    /// Records one work cycle that took `cycle_ns` against its budget `budget_ns`.
    pub fn cycle(&mut self, cycle_ns: u64, budget_ns: u64) {
        self.beat.cycles += 1;
        self.beat.max_cycle_ns = self.beat.max_cycle_ns.max(cycle_ns);
        if cycle_ns > budget_ns {
            self.beat.deadline_misses += 1;
        }
    }

    /// Sends a heartbeat if one is due at `now_ns`.
    pub fn tick(&mut self, now_ns: u64, inputs_ok: bool) -> Result<(), EdgeError> {
        if now_ns.saturating_sub(self.last_ns) < self.period_ns {
            return Ok(());
        }
        self.last_ns = now_ns;
        self.beat.header = Header { seq: self.beat.header.seq + 1, stamp_ns: now_ns };
        self.beat.inputs_ok = u8::from(inputs_ok);
        self.publisher.send_copy(self.beat).map_err(|e| EdgeError::ipc("send", services::HEARTBEAT, e))?;
        Ok(())
    }

    /// Time until the next heartbeat is due, ns.
    pub fn due_in_ns(&self, now_ns: u64) -> u64 {
        (self.last_ns + self.period_ns).saturating_sub(now_ns)
    }
}

/// Increments a header's sequence and stamps it.
pub fn next_header(h: &mut Header, stamp_ns: u64) -> Header {
    h.seq += 1;
    h.stamp_ns = stamp_ns;
    *h
}
