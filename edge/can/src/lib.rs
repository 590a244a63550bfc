//! Video2Track drive-by-wire CAN: how the background vehicle's onboard computer talks to its
//! drive-by-wire ECU, and the safety gate that decides what it may say.
//!
//! - [`codec`]: the frames of `config/can/bv.dbc` (acceleration and steering requests, the gate's
//!   state, the ECU's feedback). The bit layout is generated from the DBC at build time by
//!   `dbc-codegen` ([`generated`]); the hand-written layer adds per-id rolling counters, the
//!   CRC-8/SAE-J1850 checksum ([`checksum`]) and range checks that NaN fails.
//! - [`gate`]: the actuation safety gate, pure (time comes in as an argument). Only commands
//!   inside the vehicle's envelope leave it; stale or non-finite input, a DBW fault, a bus error
//!   or a stop request bring the vehicle to a standstill on the gate's own braking profile.
//! - [`transport`]: the [`transport::CanTransport`] trait and its SocketCAN implementation,
//!   which reports bus-off, error-passive and controller problems as typed errors.
//!
//! ```
//! use v2t_can::codec::{AccelCmd, Decoder, Encoder, Message};
//! use v2t_can::gate::{Command, GateConfig, GateInput, GateState, Request, SafetyGate};
//! use v2t_model::vehicle::VehicleConfig;
//!
//! // Encode an acceleration request; the frame carries a rolling counter and a checksum.
//! let mut encoder = Encoder::default();
//! let frame = encoder.accel(&AccelCmd { accel_mps2: -1.5, enable: true })?;
//! assert_eq!((frame.id, frame.len), (0x110, 8));
//!
//! // Decode it on the other side: checksum, counter and ranges are verified.
//! let mut decoder = Decoder::default();
//! assert_eq!(decoder.decode(&frame)?, Message::Accel(AccelCmd { accel_mps2: -1.5, enable: true }));
//! // The same frame again is a replay: its counter did not advance.
//! assert!(decoder.decode(&frame).is_err());
//!
//! // One step of the safety gate: an engage request with fresh inputs engages, and the first
//! // output is the command limited by the jerk limit (nothing moves in a zero-length step).
//! let vehicle: VehicleConfig = toml::from_str(include_str!("../../../config/vehicles/bv_sedan.toml"))?;
//! let config: GateConfig = toml::from_str(include_str!("../../../config/can/gate.toml"))?;
//! let mut gate = SafetyGate::try_new(config, &vehicle)?;
//! let now_s = 12.0;
//! let input = GateInput {
//!     command: Some(Command { accel_mps2: 1.0, steer_rad: 0.1, stamp_s: now_s }),
//!     request: Some(Request::Engage),
//!     speed_mps: 5.0,
//!     dbw_mode: 1, // auto
//!     feedback_stamp_s: Some(now_s),
//! };
//! let out = gate.step(now_s, &input);
//! assert_eq!(out.state, GateState::Engaged);
//! assert!(out.enable && out.accel_mps2 == 0.0);
//! // 10 ms later the acceleration has moved by at most max_jerk · dt = 8 m/s³ · 0.01 s.
//! let later = GateInput { request: None, feedback_stamp_s: Some(now_s + 0.01), ..input };
//! let out = gate.step(now_s + 0.01, &later);
//! assert!((out.accel_mps2 - 0.08).abs() < 1e-9);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

pub mod checksum;
pub mod codec;
pub mod gate;
pub mod transport;

/// Frame types generated from `config/can/bv.dbc` by dbc-codegen at build time (bit layout, id
/// dispatch, payload-size checks). The workspace lints (no `unwrap`, no indexing, …) are relaxed
/// for this module only: the generated code uses `unwrap` in constants and slices by fixed ranges.
#[allow(
    dead_code,
    missing_debug_implementations,
    clippy::all,
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::indexing_slicing
)]
pub mod generated {
    include!(concat!(env!("OUT_DIR"), "/bv_messages.rs"));
}
