//! # v2t-supervisor — the cloud's side of the cloud–edge link
//!
//! The cloud supervises; every BV decides on its own. This crate is what the operator's side of
//! that link needs: [`link`] holds the supervisor's Ed25519 key pair, signs priors and commands
//! with sequence numbers that keep increasing across processes, and sends one frame and waits for
//! the BV's verdict (`video2track upload`, `send`); [`serve`] follows a whole fleet from its
//! telemetry, heartbeats and events, takes operator commands and runs an embedded MQTT broker for a
//! single machine (`video2track serve`). Frames and topics are `v2t-wire`'s.
//!
//! ```
//! use v2t_supervisor::link::Signer;
//! use v2t_wire::link::{CloudBody, Command, SigningKey};
//!
//! let mut signer = Signer::new(SigningKey::from_bytes(&[7; 32]), "pg").unwrap();
//! let (topic, _frame, seq) = signer.seal("bv1", CloudBody::Command(Command::Abort)).unwrap();
//! assert_eq!(topic, "v2t/pg/bv/bv1/cmd");
//! assert!(seq > 0);
//! ```

pub mod link;
pub mod serve;
