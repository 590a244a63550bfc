//! # v2t-game — the Stackelberg risk regulator
//!
//! Runs on each BV's onboard computer, every control cycle: decides how the BV moves so that its
//! interaction with the VUT reaches a target post-encroachment time τ in a given style (rush: BV
//! first; yield: VUT first), staying close to its reference and within its limits.
//!
//! Pure: no IO, no clock, no allocation per cycle after construction.

pub mod qp;
pub mod regulator;
#[cfg(feature = "sim")]
pub mod sim;
