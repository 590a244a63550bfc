//! # v2t-sim — the simulated proving ground
//!
//! Stands in for the track, the BV's drive-by-wire vehicle and the vehicle under test when there is
//! no hardware: kinematic-bicycle [`plant`]s with actuator lag and limits, [`sensing`] with
//! localization noise and delay, VUT driver models ([`vut`]) that stand in for the ADS, a
//! [`bv::BvController`] slot for the BV's onboard stack, and a fixed-step [`runner`] that records
//! the full trace and measures PET per conflict, who passed first, distances and collisions.
//! Deterministic given a seed.

pub mod bv;
pub mod config;
pub mod control;
pub mod observation;
pub mod plant;
pub mod runner;
pub mod scenario;
pub mod sensing;
pub mod vut;
