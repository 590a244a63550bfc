//! What crosses a process boundary on the BV's onboard computer: the fixed-size `#[repr(C)]`
//! payloads the edge nodes exchange over iceoryx2 shared memory, and the names of their services.
//!
//! Every payload starts with a [`Header`]: a sequence number per publisher and the monotonic
//! timestamp (`CLOCK_MONOTONIC`, ns) at which the data it carries was valid. Consumers judge
//! freshness from the stamp, never from when they happened to read the sample. Enumerations cross
//! as `u8` codes with checked conversions ([`Code`]), so an unknown code from a newer or broken
//! peer is an error, not undefined behaviour. Variable-length data (paths, speed profiles) lives in
//! iceoryx2's fixed-capacity [`StaticVec`]; nothing points outside the payload.
//!
//! ```
//! use v2t_wire::{Header, Localization, services};
//!
//! let fix = Localization {
//!     header: Header { seq: 7, stamp_ns: 1_000_000 },
//!     px_m: 12.0, py_m: -3.5, theta_rad: 0.1, speed_mps: 8.0, valid: 1,
//! };
//! assert!(fix.is_finite());
//! assert_eq!(services::LOCALIZATION, "localization");
//! ```

use iceoryx2::prelude::ZeroCopySend;
pub use iceoryx2_bb_container::vector::{StaticVec, Vector};

mod codes;
pub mod link;
#[cfg(feature = "mqtt")]
pub mod mqtt;
mod payloads;
pub mod services;

pub use codes::{
    BelowReachCode, Code, CodeError, DbwMode, GateReason, GateState, NodeKind, PlanStatus, SafetyAction, StyleCode,
    ZoneKind,
};
pub use payloads::*;

/// Sequence number and validity time of a payload.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, ZeroCopySend)]
#[repr(C)]
pub struct Header {
    /// Per-publisher sequence number, starting at 1 and incremented on every sample.
    pub seq: u64,
    /// When the carried data was valid, `CLOCK_MONOTONIC` in ns.
    pub stamp_ns: u64,
}

impl Header {
    /// Age of the data at `now_ns` in seconds (0 if the stamp lies in the future).
    pub fn age_s(&self, now_ns: u64) -> f64 {
        now_ns.saturating_sub(self.stamp_ns) as f64 * 1e-9
    }
}
