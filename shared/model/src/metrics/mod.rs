//! Interaction metrics: conflict zones of two paths, post-encroachment time (PET), predicted PET,
//! time to collision (TTC), footprint distance and collision.
//!
//! Conventions (docs/ARCHITECTURE.md): PET at a conflict zone is the entry time of the second vehicle minus
//! the exit time of the first, interpolated between samples. A vehicle *occupies* a zone while any
//! part of its footprint is inside it; along its own path that is an interval of the reference-point
//! arc length, [`OccupancyInterval`], which already includes half the vehicle length on each side.

mod conflict;
mod pet;
mod ttc;

pub use conflict::{ConflictKind, ConflictOptions, ConflictZone, OccupancyInterval, conflict_zones, nearest_zone};
pub use pet::{Passage, PetOutcome, Side, passage, pet, predict_pet, predicted_pet_series};
pub use ttc::{Motion, MotionSnapshot, collision, min_distance, ttc_1d, ttc_2d};

/// Length and width of a footprint, m.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Dimensions {
    /// Length, m.
    pub length_m: f64,
    /// Width, m.
    pub width_m: f64,
}
