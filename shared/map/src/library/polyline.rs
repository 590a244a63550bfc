//! Polylines with arc length: lookup, projection, crossings.

use v2t_model::geometry::Point2;

/// Points with their cumulative arc length.
#[derive(Debug, Clone, PartialEq)]
pub struct Polyline {
    points: Vec<Point2>,
    s: Vec<f64>,
}

impl Polyline {
    /// A polyline through `points`; repeated points are dropped.
    pub fn new(points: &[Point2]) -> Self {
        let mut pts: Vec<Point2> = Vec::with_capacity(points.len());
        let mut s = Vec::with_capacity(points.len());
        for &p in points {
            match pts.last() {
                Some(&q) if q.dist(p) < 1e-6 => {}
                Some(&q) => {
                    s.push(s.last().copied().unwrap_or(0.0) + q.dist(p));
                    pts.push(p);
                }
                None => {
                    s.push(0.0);
                    pts.push(p);
                }
            }
        }
        Self { points: pts, s }
    }

    /// Its points.
    pub fn points(&self) -> &[Point2] {
        &self.points
    }

    /// Total length, m.
    pub fn length(&self) -> f64 {
        self.s.last().copied().unwrap_or(0.0)
    }

    /// Point and heading at arc length `s` (clamped).
    pub fn at(&self, s: f64) -> Option<(Point2, f64)> {
        let i = self.s.partition_point(|&x| x < s).clamp(1, self.s.len().max(2) - 1);
        let (a, b) = (self.points.get(i - 1)?, self.points.get(i)?);
        let (sa, sb) = (self.s.get(i - 1)?, self.s.get(i)?);
        let f = if sb > sa { ((s - sa) / (sb - sa)).clamp(0.0, 1.0) } else { 0.0 };
        let d = b.sub(*a);
        Some((a.lerp(*b, f), d.y.atan2(d.x)))
    }

    /// Arc length of the point nearest to `p`, and the distance to it.
    pub fn project(&self, p: Point2) -> Option<(f64, f64)> {
        let mut best: Option<(f64, f64)> = None;
        for (i, w) in self.points.windows(2).enumerate() {
            let [a, b] = w else { continue };
            let d = b.sub(*a);
            let len2 = d.dot(d);
            let f = if len2 > 0.0 { (p.sub(*a).dot(d) / len2).clamp(0.0, 1.0) } else { 0.0 };
            let q = a.lerp(*b, f);
            let dist = q.dist(p);
            let s = self.s.get(i).copied().unwrap_or(0.0) + f * len2.sqrt();
            if best.is_none_or(|(_, bd)| dist < bd) {
                best = Some((s, dist));
            }
        }
        best
    }

    /// The part between arc lengths `from` and `to`, with interpolated ends.
    pub fn slice(&self, from: f64, to: f64) -> Vec<Point2> {
        let mut out = Vec::new();
        if let Some((p, _)) = self.at(from) {
            out.push(p);
        }
        for (p, &s) in self.points.iter().zip(&self.s) {
            if s > from && s < to {
                out.push(*p);
            }
        }
        if let Some((p, _)) = self.at(to) {
            out.push(p);
        }
        out
    }
}

fn segment_crossing(a0: Point2, a1: Point2, b0: Point2, b1: Point2) -> Option<(f64, f64)> {
    let r = a1.sub(a0);
    let q = b1.sub(b0);
    let denom = r.cross(q);
    if denom.abs() < 1e-12 {
        return None;
    }
    let w = b0.sub(a0);
    let t = w.cross(q) / denom;
    let u = w.cross(r) / denom;
    ((0.0..=1.0).contains(&t) && (0.0..=1.0).contains(&u)).then_some((t, u))
}

/// The first point (along `a`) where `a` and `b` cross, with the arc lengths along each.
pub fn crossing(a: &Polyline, b: &Polyline) -> Option<(Point2, f64, f64)> {
    let bbox = |p: &[Point2]| {
        p.iter().fold((f64::INFINITY, f64::INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY), |(x0, y0, x1, y1), q| {
            (x0.min(q.x), y0.min(q.y), x1.max(q.x), y1.max(q.y))
        })
    };
    let (ax0, ay0, ax1, ay1) = bbox(&a.points);
    let (bx0, by0, bx1, by1) = bbox(&b.points);
    if ax1 < bx0 || bx1 < ax0 || ay1 < by0 || by1 < ay0 {
        return None;
    }
    for (i, wa) in a.points.windows(2).enumerate() {
        let [a0, a1] = wa else { continue };
        for (j, wb) in b.points.windows(2).enumerate() {
            let [b0, b1] = wb else { continue };
            if let Some((t, u)) = segment_crossing(*a0, *a1, *b0, *b1) {
                let sa = a.s.get(i).copied().unwrap_or(0.0) + t * a0.dist(*a1);
                let sb = b.s.get(j).copied().unwrap_or(0.0) + u * b0.dist(*b1);
                return Some((a0.lerp(*a1, t), sa, sb));
            }
        }
    }
    None
}

/// `points` resampled every `step` m (ends kept).
pub fn resample(points: &[Point2], step: f64) -> Vec<Point2> {
    let line = Polyline::new(points);
    let n = (line.length() / step).ceil().max(1.0);
    let mut out = Vec::with_capacity(n as usize + 1);
    let mut i = 0.0;
    while i <= n {
        if let Some((p, _)) = line.at(line.length() * i / n) {
            out.push(p);
        }
        i += 1.0;
    }
    out
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]

    use super::*;

    #[test]
    fn two_crossing_lines_meet_where_they_cross() {
        let a = Polyline::new(&[Point2::new(0.0, 0.0), Point2::new(10.0, 0.0)]);
        let b = Polyline::new(&[Point2::new(3.0, -5.0), Point2::new(3.0, 5.0)]);
        let (p, sa, sb) = crossing(&a, &b).unwrap();
        assert!((p.x - 3.0).abs() < 1e-12 && p.y.abs() < 1e-12);
        assert!((sa - 3.0).abs() < 1e-12 && (sb - 5.0).abs() < 1e-12);
        assert!(crossing(&a, &Polyline::new(&[Point2::new(0.0, 1.0), Point2::new(10.0, 1.0)])).is_none());
    }

    #[test]
    fn projection_and_lookup_agree() {
        let line = Polyline::new(&[Point2::new(0.0, 0.0), Point2::new(10.0, 0.0), Point2::new(10.0, 10.0)]);
        assert!((line.length() - 20.0).abs() < 1e-12);
        let (p, h) = line.at(15.0).unwrap();
        assert!((p.x - 10.0).abs() < 1e-12 && (p.y - 5.0).abs() < 1e-12);
        assert!((h - std::f64::consts::FRAC_PI_2).abs() < 1e-12);
        let (s, d) = line.project(Point2::new(12.0, 5.0)).unwrap();
        assert!((s - 15.0).abs() < 1e-12 && (d - 2.0).abs() < 1e-12);
    }
}
