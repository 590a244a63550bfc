//! When each agent starts: the VUT and every BV drive their routes at the semantics' speeds, and each
//! BV starts so that the VUT and it pass their conflict zone in the order its style names with the
//! video's PET between them.
//!
//! PET = entry time of the second vehicle − exit time of the first (docs/ARCHITECTURE.md). With `rush` the BV
//! is first: `t_enter(VUT) − t_exit(BV) = τ`; with `yield` the VUT is: `t_enter(BV) − t_exit(VUT) = τ`.

use serde::Serialize;
use v2t_model::Style;
use v2t_model::metrics::OccupancyInterval;

/// Below this speed a vehicle is planned to pull away rather than to roll at its speed, m/s.
pub const CREEP_SPEED_MPS: f64 = 2.0;
/// The acceleration it pulls away with, m/s².
pub const START_ACCEL_MPS2: f64 = 1.5;

/// Time to cover `d_m` from speed `v0_mps`: at constant speed, or, below [`CREEP_SPEED_MPS`],
/// accelerating at [`START_ACCEL_MPS2`] up to that speed first.
pub fn travel_time_s(d_m: f64, v0_mps: f64) -> f64 {
    if d_m <= 0.0 {
        return 0.0;
    }
    if v0_mps >= CREEP_SPEED_MPS {
        return d_m / v0_mps;
    }
    let v0 = v0_mps.max(0.0);
    let a = START_ACCEL_MPS2;
    let d_acc = (CREEP_SPEED_MPS * CREEP_SPEED_MPS - v0 * v0) / (2.0 * a);
    if d_m <= d_acc {
        ((v0 * v0 + 2.0 * a * d_m).sqrt() - v0) / a
    } else {
        (CREEP_SPEED_MPS - v0) / a + (d_m - d_acc) / CREEP_SPEED_MPS
    }
}

/// Speed after `d_m` under the same profile.
pub fn speed_after_mps(d_m: f64, v0_mps: f64) -> f64 {
    if v0_mps >= CREEP_SPEED_MPS {
        v0_mps
    } else {
        (v0_mps.max(0.0).powi(2) + 2.0 * START_ACCEL_MPS2 * d_m.max(0.0)).sqrt().min(CREEP_SPEED_MPS)
    }
}

/// The planned passage of the VUT and one BV through their conflict zone, s from scenario start.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ConflictTiming {
    /// The BV.
    pub bv_id: String,
    /// Who passes first.
    pub style: Style,
    /// The VUT enters the zone.
    pub vut_enter_s: f64,
    /// The VUT has left it.
    pub vut_exit_s: f64,
    /// The BV enters it.
    pub bv_enter_s: f64,
    /// The BV has left it.
    pub bv_exit_s: f64,
    /// Planned PET: second entry − first exit, s (τ by construction).
    pub pet_s: f64,
}

/// Start time of a BV relative to a VUT that starts at 0, so that the pair meets `tau_s` with `style`.
/// `vut` and `bv` are the zone intervals along each route, measured from the route's start.
pub fn bv_start_s(style: Style, tau_s: f64, vut: (OccupancyInterval, f64), bv: (OccupancyInterval, f64)) -> f64 {
    let (vi, v_speed) = vut;
    let (bi, b_speed) = bv;
    match style {
        Style::Rush => travel_time_s(vi.enter_s_m, v_speed) - tau_s - travel_time_s(bi.exit_s_m, b_speed),
        Style::Yield => travel_time_s(vi.exit_s_m, v_speed) + tau_s - travel_time_s(bi.enter_s_m, b_speed),
    }
}

/// The passage times for a VUT starting at `vut_t0` and a BV starting at `bv_t0`.
pub fn passage(
    bv_id: &str,
    style: Style,
    (vut_t0, vi, v_speed): (f64, OccupancyInterval, f64),
    (bv_t0, bi, b_speed): (f64, OccupancyInterval, f64),
) -> ConflictTiming {
    let vut_enter_s = vut_t0 + travel_time_s(vi.enter_s_m, v_speed);
    let vut_exit_s = vut_t0 + travel_time_s(vi.exit_s_m, v_speed);
    let bv_enter_s = bv_t0 + travel_time_s(bi.enter_s_m, b_speed);
    let bv_exit_s = bv_t0 + travel_time_s(bi.exit_s_m, b_speed);
    let pet_s = match style {
        Style::Rush => vut_enter_s - bv_exit_s,
        Style::Yield => bv_enter_s - vut_exit_s,
    };
    ConflictTiming { bv_id: bv_id.to_owned(), style, vut_enter_s, vut_exit_s, bv_enter_s, bv_exit_s, pet_s }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn zone(a: f64, b: f64) -> OccupancyInterval {
        OccupancyInterval { enter_s_m: a, exit_s_m: b }
    }

    #[test]
    fn travel_time_is_distance_over_speed_or_a_pull_away() {
        assert!((travel_time_s(100.0, 10.0) - 10.0).abs() < 1e-12);
        assert_eq!(travel_time_s(-1.0, 10.0), 0.0);
        // From rest: 2 m/s after 4/3 m, reached in 4/3 s; then 2 m/s.
        assert!((travel_time_s(4.0 / 3.0, 0.0) - 4.0 / 3.0).abs() < 1e-12);
        assert!((travel_time_s(4.0 / 3.0 + 10.0, 0.0) - (4.0 / 3.0 + 5.0)).abs() < 1e-12);
        assert!((travel_time_s(0.3, 0.0) - (0.6f64 / 1.5).sqrt()).abs() < 1e-12);
        assert_eq!(speed_after_mps(100.0, 0.0), CREEP_SPEED_MPS);
        assert_eq!(speed_after_mps(100.0, 9.0), 9.0);
        // Continuous in the distance and monotone.
        let mut prev = 0.0;
        for k in 1..400 {
            let t = travel_time_s(k as f64 * 0.05, 0.5);
            assert!(t > prev);
            prev = t;
        }
    }

    #[test]
    fn start_times_meet_the_pet_in_the_style_order() {
        let (vi, bi) = (zone(40.0, 50.0), zone(30.0, 36.0));
        for style in [Style::Rush, Style::Yield] {
            for tau in [0.5, 2.9, 6.0] {
                for (v, b) in [(9.0, 6.5), (12.0, 0.0), (0.0, 14.0)] {
                    let t0 = bv_start_s(style, tau, (vi, v), (bi, b));
                    let shift = (-t0).max(0.0);
                    let p = passage("bv1", style, (shift, vi, v), (shift + t0, bi, b));
                    assert!((p.pet_s - tau).abs() < 1e-9, "{style} {tau} {v} {b}: {p:?}");
                    match style {
                        Style::Rush => assert!(p.bv_exit_s < p.vut_enter_s),
                        Style::Yield => assert!(p.vut_exit_s < p.bv_enter_s),
                    }
                    assert!(p.vut_enter_s >= 0.0 && p.bv_enter_s >= 0.0);
                }
            }
        }
    }
}
