//! Fixtures for tests and benchmarks.

use crate::regulator::{PathState, RegulatorInput};
use v2t_model::Target;
use v2t_model::metrics::{ConflictKind, OccupancyInterval};

/// The bundled left turn's geometry at its start: the BV (10 m/s) 33.5 m before its zone, the VUT
/// (8 m/s) 74.6 m before its own.
pub fn left_turn_start(target: Target) -> RegulatorInput {
    RegulatorInput {
        t_s: 0.0,
        bv: PathState { s_m: 0.0, v_mps: 10.0, age_s: 0.05 },
        vut: PathState { s_m: 0.0, v_mps: 8.0, age_s: 0.15 },
        bv_accel_mps2: 0.0,
        zone_bv: OccupancyInterval { enter_s_m: 33.5, exit_s_m: 45.3 },
        zone_vut: OccupancyInterval { enter_s_m: 74.6, exit_s_m: 86.4 },
        zone_kind: ConflictKind::Crossing,
        target,
        reference_speed_mps: 10.0,
        stop_line_s_m: None,
    }
}
