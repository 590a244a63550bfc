//! # v2t-sim — the simulated proving ground
//!
//! Stands in for the track, the BV's drive-by-wire vehicle and the vehicle under test when there is
//! no hardware: kinematic-bicycle [`plant`]s with actuator lag and limits, [`sensing`] with
//! localization noise and delay, VUT driver models ([`vut`]) that stand in for the ADS, a
//! [`bv::BvController`] slot for the BV's onboard stack, and a fixed-step [`runner`] that records
//! the full trace and measures PET per conflict, who passed first, distances and collisions.
//! Deterministic given a seed. A run is written, and read back, as one [`runfile::RunFile`].
//!
//! ```
//! use v2t_model::vehicle::VehicleConfig;
//! use v2t_sim::bv::{BvController, ReferenceFollower};
//! use v2t_files::parse_toml;
//! use v2t_sim::config::{ScenarioCard, SimSettings};
//! use v2t_sim::runner::run;
//! use v2t_sim::scenario::Scenario;
//! use v2t_sim::vut::VutModel;
//!
//! # fn main() -> Result<(), Box<dyn std::error::Error>> {
//! let card: ScenarioCard = parse_toml(include_str!("../../../config/scenarios/left_turn_basic.toml"), "card")?;
//! let settings: SimSettings = parse_toml(include_str!("../../../config/sim/default.toml"), "sim")?;
//! let vut: VehicleConfig = parse_toml(include_str!("../../../config/vehicles/vut_sedan.toml"), "vut")?;
//! let bv: VehicleConfig = parse_toml(include_str!("../../../config/vehicles/bv_sedan.toml"), "bv")?;
//! let scenario = Scenario::from_card(&card, settings, vut, vec![bv])?;
//!
//! let mut bvs: Vec<Box<dyn BvController>> = vec![Box::new(ReferenceFollower::default())];
//! let outcome = run(&scenario, &mut bvs, VutModel::IdmNormal.driver().as_mut(), 1)?;
//! assert!(outcome.result.collision.is_none());
//! println!("PET_min = {:?} s", outcome.result.pet_min_s);
//! # Ok(())
//! # }
//! ```

pub mod bv;
pub mod config;
pub mod control;
pub mod external;
pub mod files;
pub mod measure;
pub mod network;
pub mod observation;
pub mod plant;
pub mod realism;
#[cfg(feature = "mcap")]
pub mod recording;
pub mod runfile;
pub mod runner;
pub mod scenario;
pub mod sensing;
pub mod vut;
