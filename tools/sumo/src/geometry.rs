//! Polyline geometry: projection of a point, arc length, cutting out a stretch.

use std::f64::consts::PI;

/// An angle in radians wrapped into `(-π, π]`.
pub(crate) fn wrap_angle(a: f64) -> f64 {
    let w = (a + PI).rem_euclid(2.0 * PI) - PI;
    if w <= -PI { w + 2.0 * PI } else { w }
}

/// Where a point projects onto a polyline.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Projection {
    /// Arc length of the foot point from the polyline's start, in metres.
    pub s: f64,
    /// Signed distance to the foot point, positive to the left of the direction of travel.
    pub lateral: f64,
    /// Heading of the segment of the foot point, radians.
    pub heading: f64,
}

/// The projection of `p` onto `shape` (the nearest foot point); `None` for fewer than 2 points.
pub(crate) fn project(shape: &[[f64; 2]], p: [f64; 2]) -> Option<Projection> {
    let mut best: Option<(f64, Projection)> = None;
    let mut s0 = 0.0;
    for seg in shape.windows(2) {
        let [a, b] = [seg.first()?, seg.get(1)?];
        let d = [b[0] - a[0], b[1] - a[1]];
        let len = d[0].hypot(d[1]);
        if len <= 1e-12 {
            continue;
        }
        let rel = [p[0] - a[0], p[1] - a[1]];
        let t = ((rel[0] * d[0] + rel[1] * d[1]) / (len * len)).clamp(0.0, 1.0);
        let foot = [a[0] + t * d[0], a[1] + t * d[1]];
        let dist = (p[0] - foot[0]).hypot(p[1] - foot[1]);
        if best.is_none_or(|(b, _)| dist < b) {
            let cross = d[0] * rel[1] - d[1] * rel[0];
            let lateral = if cross < 0.0 { -dist } else { dist };
            let heading = d[1].atan2(d[0]);
            best = Some((dist, Projection { s: s0 + t * len, lateral, heading }));
        }
        s0 += len;
    }
    best.map(|(_, proj)| proj)
}

/// The arc length of `shape` in metres.
pub(crate) fn length(shape: &[[f64; 2]]) -> f64 {
    shape.windows(2).filter_map(|w| Some(dist(*w.first()?, *w.get(1)?))).sum()
}

fn dist(a: [f64; 2], b: [f64; 2]) -> f64 {
    (b[0] - a[0]).hypot(b[1] - a[1])
}

/// The point at arc length `s` (clamped to the polyline).
pub(crate) fn point_at(shape: &[[f64; 2]], s: f64) -> Option<[f64; 2]> {
    let mut s0 = 0.0;
    for w in shape.windows(2) {
        let [a, b] = [*w.first()?, *w.get(1)?];
        let len = dist(a, b);
        if s <= s0 + len && len > 0.0 {
            let t = ((s - s0) / len).clamp(0.0, 1.0);
            return Some([a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])]);
        }
        s0 += len;
    }
    shape.last().copied()
}

/// Appends to `out` the stretch of `shape` from arc length `from` to `to` (`from <= to`): the
/// point at `from`, the vertices between, the point at `to`. A point equal to `out`'s last is
/// not repeated.
pub(crate) fn append_stretch(shape: &[[f64; 2]], from: f64, to: f64, out: &mut Vec<[f64; 2]>) {
    let push = |p: [f64; 2], out: &mut Vec<[f64; 2]>| {
        if out.last().is_none_or(|q| dist(*q, p) > 1e-9) {
            out.push(p);
        }
    };
    if let Some(p) = point_at(shape, from) {
        push(p, out);
    }
    let mut s = 0.0;
    let mut prev: Option<[f64; 2]> = None;
    for &v in shape {
        if let Some(q) = prev {
            s += dist(q, v);
        }
        prev = Some(v);
        if s > from && s < to {
            push(v, out);
        }
    }
    if let Some(p) = point_at(shape, to) {
        push(p, out);
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn projection_reports_arc_length_side_and_heading() {
        let shape = [[0.0, 0.0], [10.0, 0.0], [10.0, 10.0]];
        let p = project(&shape, [4.0, 1.5]).unwrap();
        assert!((p.s - 4.0).abs() < 1e-12 && (p.lateral - 1.5).abs() < 1e-12);
        assert!(p.heading.abs() < 1e-12);
        let q = project(&shape, [11.0, 5.0]).unwrap();
        assert!((q.s - 15.0).abs() < 1e-12 && (q.lateral + 1.0).abs() < 1e-12);
        assert!((q.heading - PI / 2.0).abs() < 1e-12);
        assert!(project(&shape[..1], [0.0, 0.0]).is_none());
        assert!((length(&shape) - 20.0).abs() < 1e-12);
    }

    #[test]
    fn a_stretch_keeps_the_vertices_between_its_ends() {
        let shape = [[0.0, 0.0], [10.0, 0.0], [10.0, 10.0]];
        let mut out = Vec::new();
        append_stretch(&shape, 5.0, 12.0, &mut out);
        assert_eq!(out, [[5.0, 0.0], [10.0, 0.0], [10.0, 2.0]]);
        append_stretch(&shape, 12.0, 20.0, &mut out);
        assert_eq!(out.len(), 4);
        assert_eq!(out.last(), Some(&[10.0, 10.0]));
    }

    #[test]
    fn angles_wrap_into_the_half_open_interval() {
        assert!((wrap_angle(3.0 * PI) - PI).abs() < 1e-12);
        assert!((wrap_angle(-PI) - PI).abs() < 1e-12);
        assert!((wrap_angle(-0.5) + 0.5).abs() < 1e-12);
    }
}
