//! # v2t-game — the Stackelberg risk regulator
//!
//! Runs on each BV's onboard computer, every control cycle: decides how the BV moves so that its
//! interaction with the VUT reaches a target post-encroachment time τ in a given style (rush: BV
//! first; yield: VUT first), staying close to its reference and within its limits. The method and
//! why it holds in closed loop are in [`regulator`]; the QP it solves in [`qp`]; how it predicts
//! and identifies the VUT's reaction to the BV in [`reaction`]; how a prior and
//! measurements become its input, the one adapter the vehicle and the lab both run, in [`regulation`].
//!
//! Pure: no IO, no clock, no allocation per cycle after construction (Clarabel's `solve` itself
//! allocates once per call).
//!
//! ```
//! use v2t_game::regulator::{PathState, Regulator, RegulatorInput, RegulatorParams, RegulatorStatus};
//! use v2t_model::{Style, Target};
//! use v2t_model::metrics::{ConflictKind, OccupancyInterval};
//!
//! let mut regulator = Regulator::new(RegulatorParams::default()).unwrap();
//! // BV 40 m and VUT 60 m before their zones, both at 10 m/s: rush with τ = 2 s.
//! let decision = regulator.decide(&RegulatorInput {
//!     t_s: 0.0,
//!     bv: PathState { s_m: 0.0, v_mps: 10.0, age_s: 0.05 },
//!     vut: PathState { s_m: 0.0, v_mps: 10.0, age_s: 0.15 },
//!     bv_accel_mps2: 0.0,
//!     zone_bv: OccupancyInterval { enter_s_m: 40.0, exit_s_m: 50.0 },
//!     zone_vut: OccupancyInterval { enter_s_m: 60.0, exit_s_m: 70.0 },
//!     zone_kind: ConflictKind::Crossing,
//!     target: Target::new(2.0, Style::Rush).unwrap(),
//!     reference_speed_mps: 10.0,
//!     stop_line_s_m: None,
//! });
//! assert_eq!(decision.status, RegulatorStatus::Regulating);
//! // Out of the zone at 4 s, two seconds before the VUT comes in at 6 s.
//! assert!((decision.key_time_s.unwrap() - 4.0).abs() < 0.05);
//! assert!((decision.predicted_pet_s.unwrap() - 2.0).abs() < 0.05);
//! ```

pub mod campaign;
pub mod fixtures;
pub mod qp;
pub mod reaction;
pub mod reference;
pub mod regulation;
pub mod regulator;
pub mod route_speed;
