//! The speed a path's curves allow: `v = √(a_lat / |κ̄|)`, with `κ̄` the path's mean curvature
//! over a window around the point, and the braking preview of a driver who slows down for the
//! curves ahead.
//!
//! Three formulas did this before, and they differed in how they read the curvature:
//!
//! - the BV's regulator (`v2t-game`) took the heading change over ±3 m, divided by the window's
//!   length;
//! - the simulated VUTs (`v2t-sim`) took the largest pointwise curvature over a window *ahead* of
//!   the point (5 m);
//! - the synthetic corpus's drivers (`v2t-diffusion`) took the pointwise curvature every 2 m.
//!
//! The regulator's is the right one, and what the vehicle runs: a path made from points (a prior's
//! trajectory, a map's polyline) has its pointwise curvature concentrated at its vertices, where it
//! spikes with the spacing and the noise of the points, while the heading change over a window
//! about a wheelbase long is what a vehicle following the path actually turns through. Looking
//! ahead is the preview's business ([`curve_speed_ahead`] from one point, [`braking_envelope`] for
//! every point of a sampled stretch at once, which the regulator's plans are capped by), not the
//! curvature's. The share of the lateral-acceleration limit a caller allows itself (the regulator
//! keeps 20 % for its tracker) is the caller's `lat_accel_mps2`.

/// Half the window over which [`curve_speed`] averages the curvature, m: about a car's wheelbase.
/// The regulator's value, which every driver uses too.
pub const CURVE_HALF_WINDOW_M: f64 = 3.0;
/// Below this mean curvature a path is straight, 1/m (a radius of 1000 km).
const STRAIGHT_CURVATURE_1PM: f64 = 1e-6;
/// A window shorter than this (a path shorter than it) measures nothing, m.
const MIN_WINDOW_M: f64 = 1e-3;
/// Smallest deceleration of the braking preview, m/s².
const MIN_PREVIEW_DECEL_MPS2: f64 = 0.1;
/// Smallest spacing of the braking preview's points, m.
const MIN_PREVIEW_STEP_M: f64 = 0.1;
/// Most points the braking preview reads.
const MAX_PREVIEW_POINTS: f64 = 10_000.0;

/// The curve speed `√(lat_accel_mps2 / |κ̄|)` of `path` at `s_m`, m/s; `f64::INFINITY` on a
/// straight (and on a path shorter than a millimetre). `κ̄` is the heading change over
/// `[s − half_window_m, s + half_window_m]` clipped to the path, divided by that window's length.
pub fn curve_speed(path: &crate::path::ReferencePath, s_m: f64, half_window_m: f64, lat_accel_mps2: f64) -> f64 {
    let (a, b) = ((s_m - half_window_m).max(0.0), (s_m + half_window_m).min(path.length()));
    if b - a < MIN_WINDOW_M {
        return f64::INFINITY;
    }
    let turn = (path.heading_at(b) - path.heading_at(a) + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU)
        - std::f64::consts::PI;
    let k = turn.abs() / (b - a);
    if k > STRAIGHT_CURVATURE_1PM { (lat_accel_mps2 / k).sqrt() } else { f64::INFINITY }
}

/// How far and how finely [`curve_speed_ahead`] reads the curves ahead.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CurvePreview {
    /// Half the window of each curve speed ([`curve_speed`]), m.
    pub half_window_m: f64,
    /// Spacing of the points read, m (at most twice `half_window_m`, so that the windows leave no
    /// gap).
    pub step_m: f64,
    /// Read this far beyond the braking distance, m.
    pub margin_m: f64,
    /// Never farther ahead than this, m.
    pub max_m: f64,
}

impl CurvePreview {
    /// What the simulated VUTs and the synthetic corpus's drivers read: the curve speed over
    /// ±[`CURVE_HALF_WINDOW_M`] every 2 m, from the point to 10 m beyond the braking distance,
    /// at most 200 m (the braking distance from 28 m/s at 2 m/s²). Before, the corpus's drivers
    /// read at most 80 m ahead, less than a fast driver with a gentle `b` needs to brake for a
    /// curve comfortably; the VUTs read every 5 m.
    pub const DRIVER: Self = Self { half_window_m: CURVE_HALF_WINDOW_M, step_m: 2.0, margin_m: 10.0, max_m: 200.0 };
}

/// The braking envelope of speed limits sampled every `step_m` along a path, in place: each
/// `limits[i]` becomes `min over j ≥ i of √(limits[j]² + 2 b (j − i) step)`, the highest speed at
/// point `i` from which braking at `decel_mps2` meets every limit after it — the formula of
/// [`curve_speed_ahead`] for every point at once, from the far end back (one pass). An infinite
/// limit is no limit; the envelope of the last point is its own limit.
pub fn braking_envelope(limits: &mut [f64], step_m: f64, decel_mps2: f64) {
    let gain = 2.0 * decel_mps2 * step_m;
    let mut behind = f64::INFINITY;
    for e in limits.iter_mut().rev() {
        *e = e.min((behind * behind + gain).sqrt());
        behind = *e;
    }
}

/// The highest speed at arc length `s_m` of `path` from which braking at `decel_mps2` meets the
/// curve speed ([`curve_speed`] with `lat_accel_mps2`) at every point the preview reads:
/// `min over d of √(v_c(s + d)² + 2 b d)` for `d = 0, step, 2 step, …` up to the braking distance
/// from `speed_mps` at `b` plus the margin (at most `max_m`), m/s. `f64::INFINITY` when no curve
/// is in reach.
pub fn curve_speed_ahead(
    path: &crate::path::ReferencePath,
    s_m: f64,
    speed_mps: f64,
    lat_accel_mps2: f64,
    decel_mps2: f64,
    preview: &CurvePreview,
) -> f64 {
    let b = decel_mps2.max(MIN_PREVIEW_DECEL_MPS2);
    let v = speed_mps.max(0.0);
    let reach = (v * v / (2.0 * b) + preview.margin_m).min(preview.max_m);
    let step = preview.step_m.max(MIN_PREVIEW_STEP_M);
    let points = (reach / step).floor().clamp(0.0, MAX_PREVIEW_POINTS) as usize;
    (0..=points)
        .map(|i| {
            let d = i as f64 * step;
            let v_curve = curve_speed(path, s_m + d, preview.half_window_m, lat_accel_mps2);
            (v_curve * v_curve + 2.0 * b * d).sqrt()
        })
        .fold(f64::INFINITY, f64::min)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::path::{PathBuilder, ReferencePath};
    use proptest::prelude::*;

    /// 30 m straight, then an arc of `radius_m` over `angle_rad`, then 30 m straight.
    fn bend(radius_m: f64, angle_rad: f64) -> ReferencePath {
        PathBuilder::new(0.0, 0.0, 0.0).line(30.0).arc(radius_m, angle_rad).line(30.0).build(0.5).unwrap()
    }

    #[test]
    fn the_curve_speed_of_an_arc_and_a_straight() {
        let path = bend(20.0, 1.5);
        let mid = 30.0 + 0.5 * 20.0 * 1.5;
        let v = curve_speed(&path, mid, CURVE_HALF_WINDOW_M, 2.0);
        assert!((v - 40f64.sqrt()).abs() < 1e-3, "{v}");
        assert_eq!(curve_speed(&path, 10.0, CURVE_HALF_WINDOW_M, 2.0), f64::INFINITY);
        // Half the window on the arc: half its curvature.
        let v = curve_speed(&path, 30.0, CURVE_HALF_WINDOW_M, 2.0);
        assert!((v - 80f64.sqrt()).abs() < 0.05, "{v}");
        // Turning right is as slow as turning left.
        assert!((curve_speed(&bend(20.0, -1.5), mid, CURVE_HALF_WINDOW_M, 2.0) - 40f64.sqrt()).abs() < 1e-3);
        // At the ends the window is clipped to the path; a window of nothing measures nothing.
        let arc = PathBuilder::new(0.0, 0.0, 0.0).arc(20.0, 1.0).build(0.5).unwrap();
        let v = curve_speed(&arc, 0.0, CURVE_HALF_WINDOW_M, 2.0);
        assert!((v - 40f64.sqrt()).abs() < 0.05 * 40f64.sqrt(), "{v}");
        assert_eq!(curve_speed(&arc, 0.0, 0.0, 2.0), f64::INFINITY);
    }

    #[test]
    fn the_preview_brakes_for_the_curve_ahead_and_not_for_one_out_of_reach() {
        let path = bend(20.0, 1.5);
        let v_curve = 40f64.sqrt();
        let ahead = |s: f64, v: f64| curve_speed_ahead(&path, s, v, 2.0, 2.0, &CurvePreview::DRIVER);
        // Well inside the arc: its curve speed.
        assert!((ahead(45.0, v_curve) - v_curve).abs() < 1e-3);
        // 20 m before the arc: braking at 2 m/s² meets the curve speed where the window lies on
        // the arc whole, half a window into it (at the next point read).
        let v = ahead(10.0, 10.0);
        let reach = |d: f64| (v_curve * v_curve + 2.0 * 2.0 * d).sqrt();
        assert!(v > reach(20.0) && v <= reach(20.0 + CURVE_HALF_WINDOW_M + CurvePreview::DRIVER.step_m) + 1e-9, "{v}");
        // The nearer the curve, the lower the speed allowed.
        assert!(ahead(20.0, 10.0) < v);
        // Slow and far: nothing in reach.
        assert_eq!(ahead(0.0, 2.0), f64::INFINITY);
        // After the bend: nothing.
        assert_eq!(ahead(path.length() - 20.0, 10.0), f64::INFINITY);
    }

    proptest! {
        /// The envelope is the formula, point by point: never above a limit, and braking at the
        /// deceleration from it meets every later limit, one of them exactly.
        #[test]
        fn the_braking_envelope_is_the_lowest_speed_that_brakes_for_every_limit_ahead(
            limits in proptest::collection::vec(prop_oneof![1.0f64..30.0, Just(f64::INFINITY)], 1..60),
            step in 0.5f64..3.0, decel in 0.5f64..6.0,
        ) {
            let mut env = limits.clone();
            braking_envelope(&mut env, step, decel);
            for (i, e) in env.iter().enumerate() {
                let direct = limits[i..]
                    .iter()
                    .enumerate()
                    .map(|(d, l)| (l * l + 2.0 * decel * d as f64 * step).sqrt())
                    .fold(f64::INFINITY, f64::min);
                prop_assert!(*e <= limits[i]);
                prop_assert!(
                    (e - direct).abs() <= 1e-9 * direct.max(1.0) || (e.is_infinite() && direct.is_infinite()),
                    "point {i}: {e} against {direct}"
                );
            }
        }

        #[test]
        fn the_curve_speed_falls_as_the_curvature_rises(
            r in 20.0f64..500.0, tighter in 0.5f64..1.0, angle in 0.8f64..2.0, a_lat in 0.5f64..4.0,
            v in 0.0f64..25.0, s in 0.0f64..30.0,
        ) {
            let (wide, tight) = (bend(r, angle), bend(r * tighter, angle));
            // In the middle of each arc (8 m long at least: longer than the window).
            let (mid_wide, mid_tight) = (30.0 + 0.5 * r * angle, 30.0 + 0.5 * r * tighter * angle);
            let (v_wide, v_tight) = (
                curve_speed(&wide, mid_wide, CURVE_HALF_WINDOW_M, a_lat),
                curve_speed(&tight, mid_tight, CURVE_HALF_WINDOW_M, a_lat),
            );
            prop_assert!(v_tight <= v_wide * (1.0 + 1e-9), "{v_tight} > {v_wide}");
            prop_assert!((v_wide - (a_lat * r).sqrt()).abs() < 1e-3 * v_wide, "{v_wide} vs {}", (a_lat * r).sqrt());
            // More lateral acceleration allowed: faster.
            prop_assert!(curve_speed(&wide, mid_wide, CURVE_HALF_WINDOW_M, 1.5 * a_lat) >= v_wide);
            // The preview from the same place before the arcs: never faster on the tighter one,
            // never faster than the curve speed where it stands.
            let p = CurvePreview::DRIVER;
            let (c_wide, c_tight) =
                (curve_speed_ahead(&wide, s, v, a_lat, 2.0, &p), curve_speed_ahead(&tight, s, v, a_lat, 2.0, &p));
            prop_assert!(c_tight <= c_wide * (1.0 + 1e-9), "{c_tight} > {c_wide}");
            prop_assert!(c_wide <= curve_speed(&wide, s, CURVE_HALF_WINDOW_M, a_lat));
        }
    }
}
