//! The four energies on rolled-out trajectories. Each returns its raw value and adds `λ · ∂E/∂x`
//! into the per-agent state gradients (and `λ · ∂E/∂u` into the control gradients where it depends
//! on the controls directly). States are indexed `x_0 … x_T`; `x_0` is fixed, so terms that only
//! see `x_0` are constant and their gradient is dropped by the adjoint.
//!
//! All hinges are squared hinges `φ(z) = max(z, 0)²`: continuous first derivative, zero where the
//! constraint holds.

use v2t_model::geometry::Point2;
use v2t_model::kinematics::{Control, State};

use super::{Anchor, ConflictWindow, KinematicLimits};

/// Below this a distance is treated as zero (no direction): the gradient there is taken as zero.
const TINY_M: f64 = 1e-9;

fn add_pos(g: &mut State, k: f64, d: Point2) {
    g.px += k * d.x;
    g.py += k * d.y;
}

/// `E_anch = Σ_anchors ‖p̂ⁱ(t) − p‖²`, with `p̂ⁱ(t)` linearly interpolated between the states
/// `⌊t/dt⌋` and `⌊t/dt⌋ + 1` (`t` clamped to `[0, T·dt]`). Anchors of agents out of range are
/// skipped (the constructor rejects them).
pub fn anchor_energy(anchors: &[Anchor], dt_s: f64, states: &[Vec<State>], grads: &mut [Vec<State>], w: f64) -> f64 {
    let mut e = 0.0;
    for a in anchors {
        let (Some(xs), Some(gs)) = (states.get(a.agent), grads.get_mut(a.agent)) else { continue };
        let t_len = xs.len().saturating_sub(1);
        if t_len == 0 {
            continue;
        }
        let s = (a.time_s / dt_s).clamp(0.0, t_len as f64);
        let k = (s.floor() as usize).min(t_len - 1);
        let alpha = s - k as f64;
        let (Some(x0), Some(x1)) = (xs.get(k), xs.get(k + 1)) else { continue };
        let p = x0.position().lerp(x1.position(), alpha);
        let d = p.sub(a.position);
        e += d.dot(d);
        if let Some(g) = gs.get_mut(k) {
            add_pos(g, w * 2.0 * (1.0 - alpha), d);
        }
        if let Some(g) = gs.get_mut(k + 1) {
            add_pos(g, w * 2.0 * alpha, d);
        }
    }
    e
}

/// Distance from a point to a boundary polyline, from its nearest non-degenerate segment.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SideDistance {
    /// Alongside the polyline: the distance to the nearest segment's line inside its span, or to a
    /// joint between two segments, signed positive on the left of the polyline's direction.
    /// Beyond one of the polyline's two ends: the (positive) distance to that end point.
    pub signed_m: f64,
    /// Gradient of `signed_m` with respect to the point.
    pub gradient: Point2,
    /// Whether the point is alongside the polyline (false beyond its first or last point, where it
    /// has no side).
    pub alongside: bool,
}

/// [`SideDistance`] from `p` to the polyline; `None` when every segment has zero length.
pub fn signed_distance(polyline: &[Point2], p: Point2) -> Option<SideDistance> {
    let long = |i: &usize| match (polyline.get(*i), polyline.get(*i + 1)) {
        (Some(a), Some(b)) => a.dist(*b) > TINY_M,
        _ => false,
    };
    let n = polyline.len().saturating_sub(1);
    let first = (0..n).find(long)?;
    let last = (0..n).rev().find(long)?;
    let mut best: Option<(f64, SideDistance)> = None;
    for i in (first..=last).filter(long) {
        let (Some(&a), Some(&b)) = (polyline.get(i), polyline.get(i + 1)) else { continue };
        let ab = b.sub(a);
        let len2 = ab.dot(ab);
        let len = len2.sqrt();
        let normal = Point2::new(-ab.y / len, ab.x / len);
        let ap = p.sub(a);
        let tau = ap.dot(ab) / len2;
        let (unsigned, d) = if (0.0..=1.0).contains(&tau) {
            let sd = ap.dot(normal);
            (sd.abs(), SideDistance { signed_m: sd, gradient: normal, alongside: true })
        } else {
            let q = if tau < 0.0 { a } else { b };
            let r = p.sub(q);
            let dist = r.norm();
            let beyond_end = (tau < 0.0 && i == first) || (tau > 1.0 && i == last);
            let side = if beyond_end || ap.cross(ab) <= 0.0 { 1.0 } else { -1.0 };
            let gradient = if dist > TINY_M { r.scale(side / dist) } else { normal };
            (dist, SideDistance { signed_m: side * dist, gradient, alongside: !beyond_end })
        };
        if best.is_none_or(|(u, _)| unsigned < u) {
            best = Some((unsigned, d));
        }
    }
    best.map(|(_, d)| d)
}

/// `E_bound = Σ_i Σ_b Σ_{t=1..T} φ(d_safe − σ_{i,b} s_b(p_tⁱ))`, `s_b` the signed distance to
/// boundary `b` ([`signed_distance`]) and `σ_{i,b} = ±1` the side of `b` agent `i` belongs on:
/// given in `sides[i][b]`, else the side it is on the first time it is alongside `b` (`+1` on the
/// line). Approaching a boundary within `d_safe` and
/// crossing it (a negative side distance) are penalised alike, growing quadratically with the depth.
/// Beyond a boundary's ends there is no side: only coming within `d_safe` of the end point counts,
/// so a boundary that ends at a junction does not reach across it.
pub fn boundary_energy(
    boundaries: &[Vec<Point2>],
    sides: &[Vec<i8>],
    margin_m: f64,
    states: &[Vec<State>],
    grads: &mut [Vec<State>],
    w: f64,
) -> f64 {
    let mut e = 0.0;
    for (agent, (xs, gs)) in states.iter().zip(grads.iter_mut()).enumerate() {
        for (bi, b) in boundaries.iter().enumerate() {
            let mut side: Option<f64> = match sides.get(agent).and_then(|row| row.get(bi)) {
                Some(1) => Some(1.0),
                Some(-1) => Some(-1.0),
                _ => None,
            };
            for (k, (x, g)) in xs.iter().zip(gs.iter_mut()).enumerate() {
                let Some(d) = signed_distance(b, x.position()) else { break };
                let sigma =
                    if d.alongside { *side.get_or_insert(if d.signed_m >= 0.0 { 1.0 } else { -1.0 }) } else { 1.0 };
                if k == 0 {
                    continue;
                }
                let h = margin_m - sigma * d.signed_m;
                if h > 0.0 {
                    e += h * h;
                    add_pos(g, -w * 2.0 * h * sigma, d.gradient);
                }
            }
        }
    }
    e
}

/// `E_clear = Σ_{i<j} Σ_{t=1..T} φ(r − ‖p_tⁱ − p_tʲ‖)`, skipping `(i, j, t)` covered by a conflict
/// window (`t·dt` inside it). At coincident centres the gradient is taken as zero.
pub fn clearance_energy(
    windows: &[ConflictWindow],
    radius_m: f64,
    dt_s: f64,
    states: &[Vec<State>],
    grads: &mut [Vec<State>],
    w: f64,
) -> f64 {
    let mut e = 0.0;
    let n = states.len();
    for i in 0..n {
        for j in (i + 1)..n {
            let (Some(xi), Some(xj)) = (states.get(i), states.get(j)) else { continue };
            for (t, (a, b)) in xi.iter().zip(xj).enumerate().skip(1) {
                if windows.iter().any(|win| win.covers(i, j, t as f64 * dt_s)) {
                    continue;
                }
                let r = a.position().sub(b.position());
                let d = r.norm();
                let h = radius_m - d;
                if h <= 0.0 {
                    continue;
                }
                e += h * h;
                if d <= TINY_M {
                    continue;
                }
                let k = -w * 2.0 * h / d;
                if let Some(g) = grads.get_mut(i).and_then(|g| g.get_mut(t)) {
                    add_pos(g, k, r);
                }
                if let Some(g) = grads.get_mut(j).and_then(|g| g.get_mut(t)) {
                    add_pos(g, -k, r);
                }
            }
        }
    }
    e
}

/// Squared hinge of the excess of `|z|` over `limit`: value and derivative in `z`.
fn abs_hinge(z: f64, limit: f64) -> (f64, f64) {
    let m = z.abs() - limit;
    if m > 0.0 { (m * m, 2.0 * m * z.signum()) } else { (0.0, 0.0) }
}

/// Squared hinge of `z` outside `[lo, hi]`: value and derivative in `z`.
fn range_hinge(z: f64, lo: f64, hi: f64) -> (f64, f64) {
    if z > hi {
        ((z - hi) * (z - hi), 2.0 * (z - hi))
    } else if z < lo {
        ((lo - z) * (lo - z), -2.0 * (lo - z))
    } else {
        (0.0, 0.0)
    }
}

/// One agent's kinematic-limit energy
///
/// `E_kin = Σ_{t<T} [φ(a_t ∉ [a_min, a_max]) + φ(|v_t ω_t| − a_lat)] + Σ_{t<T−1} φ(|a_{t+1} − a_t|/dt − j_max) + Σ_{t=1..T} φ(v_t ∉ [0, v_max])`
///
/// where `φ(z ∉ [lo, hi])` is the squared distance of `z` to the interval. The lateral term's speed
/// part goes into the state gradient (`v_t`, through the adjoint), its yaw rate part and the
/// acceleration and jerk terms into `ctrl_grads` directly. The jerk of the first step counts against
/// `previous_accel_mps2` when it is known (`φ(|a_0 − a_prev|/dt − j_max)`), not at all otherwise.
pub fn kinematic_energy(
    limits: &KinematicLimits,
    dt_s: f64,
    (states, controls): (&[State], &[Control]),
    (state_grads, ctrl_grads): (&mut [State], &mut [Control]),
    w: f64,
    previous_accel_mps2: Option<f64>,
) -> f64 {
    let mut e = 0.0;
    if let (Some(a_prev), Some(u0), Some(g0)) = (previous_accel_mps2, controls.first(), ctrl_grads.first_mut()) {
        let (ej, dj) = abs_hinge((u0.accel_mps2 - a_prev) / dt_s, limits.jerk_max_mps3);
        e += ej;
        g0.accel_mps2 += w * dj / dt_s;
    }
    for ((x, u), (gx, gu)) in states.iter().zip(controls).zip(state_grads.iter_mut().zip(ctrl_grads.iter_mut())) {
        let (ea, da) = range_hinge(u.accel_mps2, limits.accel_min_mps2, limits.accel_max_mps2);
        let (el, dl) = abs_hinge(x.speed_mps * u.yaw_rate_radps, limits.lat_accel_max_mps2);
        e += ea + el;
        gu.accel_mps2 += w * da;
        gu.yaw_rate_radps += w * dl * x.speed_mps;
        gx.speed_mps += w * dl * u.yaw_rate_radps;
    }
    for (k, pair) in controls.windows(2).enumerate() {
        let (Some(u0), Some(u1)) = (pair.first(), pair.get(1)) else { continue };
        let (ej, dj) = abs_hinge((u1.accel_mps2 - u0.accel_mps2) / dt_s, limits.jerk_max_mps3);
        e += ej;
        if let Some(g) = ctrl_grads.get_mut(k) {
            g.accel_mps2 -= w * dj / dt_s;
        }
        if let Some(g) = ctrl_grads.get_mut(k + 1) {
            g.accel_mps2 += w * dj / dt_s;
        }
    }
    for (x, g) in states.iter().zip(state_grads.iter_mut()).skip(1) {
        let (ev, dv) = range_hinge(x.speed_mps, 0.0, limits.speed_max_mps);
        e += ev;
        g.speed_mps += w * dv;
    }
    e
}
