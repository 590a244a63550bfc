//! Planar geometry in the track frame (x east, y north): points, oriented boxes (vehicle footprints),
//! separating-axis overlap, box-to-box distance and convex polygon clipping.

use serde::{Deserialize, Serialize};

/// A point or vector in the plane, in metres.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize, schemars::JsonSchema)]
pub struct Point2 {
    /// East, m.
    pub x: f64,
    /// North, m.
    pub y: f64,
}

impl Point2 {
    /// A point from its coordinates.
    pub const fn new(x: f64, y: f64) -> Self {
        Self { x, y }
    }

    /// Unit vector at heading `theta_rad` (counter-clockwise from east).
    pub fn from_heading(theta_rad: f64) -> Self {
        let (s, c) = theta_rad.sin_cos();
        Self::new(c, s)
    }

    /// `self + other`.
    #[must_use]
    #[allow(clippy::should_implement_trait)] // plain methods keep call sites free of operator imports
    pub fn add(self, o: Self) -> Self {
        Self::new(self.x + o.x, self.y + o.y)
    }

    /// `self - other`.
    #[must_use]
    #[allow(clippy::should_implement_trait)]
    pub fn sub(self, o: Self) -> Self {
        Self::new(self.x - o.x, self.y - o.y)
    }

    /// `k * self`.
    #[must_use]
    pub fn scale(self, k: f64) -> Self {
        Self::new(k * self.x, k * self.y)
    }

    /// Dot product.
    pub fn dot(self, o: Self) -> f64 {
        self.x * o.x + self.y * o.y
    }

    /// z-component of the cross product.
    pub fn cross(self, o: Self) -> f64 {
        self.x * o.y - self.y * o.x
    }

    /// Euclidean norm.
    pub fn norm(self) -> f64 {
        self.x.hypot(self.y)
    }

    /// Distance to `o`.
    pub fn dist(self, o: Self) -> f64 {
        self.sub(o).norm()
    }

    /// Rotated by +90° (the left normal of a direction).
    #[must_use]
    pub fn perp(self) -> Self {
        Self::new(-self.y, self.x)
    }

    /// Both coordinates finite.
    pub fn is_finite(self) -> bool {
        self.x.is_finite() && self.y.is_finite()
    }

    /// Linear interpolation `self + t (o - self)`.
    #[must_use]
    pub fn lerp(self, o: Self, t: f64) -> Self {
        self.add(o.sub(self).scale(t))
    }
}

/// Wraps an angle to `(-π, π]`.
pub fn wrap_angle(a: f64) -> f64 {
    let two_pi = std::f64::consts::TAU;
    let mut r = a.rem_euclid(two_pi);
    if r > std::f64::consts::PI {
        r -= two_pi;
    }
    r
}

/// Distance from point `p` to the segment `a`–`b`.
pub fn point_segment_distance(p: Point2, a: Point2, b: Point2) -> f64 {
    let ab = b.sub(a);
    let len2 = ab.dot(ab);
    let t = if len2 > 0.0 { (p.sub(a).dot(ab) / len2).clamp(0.0, 1.0) } else { 0.0 };
    p.dist(a.lerp(b, t))
}

/// A rectangle with a centre, a heading and its dimensions: a vehicle footprint.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OrientedBox {
    /// Centre of the rectangle.
    pub center: Point2,
    /// Heading of the long axis, rad.
    pub heading_rad: f64,
    /// Extent along the heading, m.
    pub length_m: f64,
    /// Extent across the heading, m.
    pub width_m: f64,
}

impl OrientedBox {
    /// The four corners, counter-clockwise starting front-left.
    pub fn corners(&self) -> [Point2; 4] {
        let f = Point2::from_heading(self.heading_rad).scale(0.5 * self.length_m);
        let l = Point2::from_heading(self.heading_rad).perp().scale(0.5 * self.width_m);
        let c = self.center;
        [c.add(f).add(l), c.sub(f).add(l), c.sub(f).sub(l), c.add(f).sub(l)]
    }

    /// Whether two boxes overlap (touching counts), by the separating-axis theorem.
    pub fn overlaps(&self, other: &Self) -> bool {
        let a = self.corners();
        let b = other.corners();
        let axes = [
            Point2::from_heading(self.heading_rad),
            Point2::from_heading(self.heading_rad).perp(),
            Point2::from_heading(other.heading_rad),
            Point2::from_heading(other.heading_rad).perp(),
        ];
        axes.iter().all(|axis| {
            let (amin, amax) = project(&a, *axis);
            let (bmin, bmax) = project(&b, *axis);
            amax >= bmin && bmax >= amin
        })
    }

    /// Smallest distance between the two boxes; 0 when they overlap.
    pub fn distance(&self, other: &Self) -> f64 {
        if self.overlaps(other) {
            return 0.0;
        }
        let a = self.corners();
        let b = other.corners();
        let mut best = f64::INFINITY;
        for (p, poly) in a.iter().map(|p| (p, &b)).chain(b.iter().map(|p| (p, &a))) {
            for (s, e) in poly.iter().zip(poly.iter().cycle().skip(1)) {
                best = best.min(point_segment_distance(*p, *s, *e));
            }
        }
        best
    }
}

fn project(poly: &[Point2; 4], axis: Point2) -> (f64, f64) {
    poly.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| {
        let d = p.dot(axis);
        (lo.min(d), hi.max(d))
    })
}

/// Signed area of a polygon (positive when counter-clockwise).
pub fn signed_area(poly: &[Point2]) -> f64 {
    let n = poly.len();
    (0..n).filter_map(|i| Some(poly.get(i)?.cross(*poly.get((i + 1) % n)?))).sum::<f64>() * 0.5
}

/// Intersection of the polygon `subject` with the convex polygon `clip` (Sutherland–Hodgman).
/// Both may be given in either orientation. The result is empty when they do not intersect.
pub fn clip_convex(subject: &[Point2], clip: &[Point2]) -> Vec<Point2> {
    let orientation = if signed_area(clip) >= 0.0 { 1.0 } else { -1.0 };
    let mut output: Vec<Point2> = subject.to_vec();
    let n = clip.len();
    for i in 0..n {
        let (Some(&a), Some(&b)) = (clip.get(i), clip.get((i + 1) % n)) else {
            continue;
        };
        let edge = b.sub(a);
        let inside = |p: Point2| orientation * edge.cross(p.sub(a)) >= 0.0;
        let input = std::mem::take(&mut output);
        let m = input.len();
        for j in 0..m {
            let (Some(&cur), Some(&prev)) = (input.get(j), input.get((j + m - 1) % m)) else {
                continue;
            };
            let (ci, pi) = (inside(cur), inside(prev));
            if ci != pi {
                // The segment prev→cur crosses the clip line a→b.
                let d = cur.sub(prev);
                let denom = edge.cross(d);
                if denom.abs() > f64::EPSILON {
                    let u = edge.cross(a.sub(prev)) / denom;
                    output.push(prev.add(d.scale(u)));
                }
            }
            if ci {
                output.push(cur);
            }
        }
        if output.is_empty() {
            break;
        }
    }
    output
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn square(cx: f64, cy: f64, h: f64) -> Vec<Point2> {
        vec![
            Point2::new(cx - h, cy - h),
            Point2::new(cx + h, cy - h),
            Point2::new(cx + h, cy + h),
            Point2::new(cx - h, cy + h),
        ]
    }

    #[test]
    fn clipping_two_offset_squares_gives_their_overlap() {
        let c = clip_convex(&square(0.0, 0.0, 1.0), &square(1.0, 1.0, 1.0));
        assert!((signed_area(&c).abs() - 1.0).abs() < 1e-12, "{c:?}");
        let none = clip_convex(&square(0.0, 0.0, 1.0), &square(5.0, 0.0, 1.0));
        assert!(none.len() < 3 || signed_area(&none).abs() < 1e-12);
        // Clockwise clip polygon gives the same area.
        let mut cw = square(1.0, 1.0, 1.0);
        cw.reverse();
        let c2 = clip_convex(&square(0.0, 0.0, 1.0), &cw);
        assert!((signed_area(&c2).abs() - 1.0).abs() < 1e-12);
    }

    #[test]
    fn boxes_side_by_side_have_the_gap_as_distance() {
        let a = OrientedBox { center: Point2::new(0.0, 0.0), heading_rad: 0.0, length_m: 4.0, width_m: 2.0 };
        let b = OrientedBox { center: Point2::new(0.0, 3.0), ..a };
        assert!(!a.overlaps(&b));
        assert!((a.distance(&b) - 1.0).abs() < 1e-12);
        let c = OrientedBox { center: Point2::new(3.9, 0.0), heading_rad: 0.3, ..a };
        assert!(a.overlaps(&c));
        assert_eq!(a.distance(&c), 0.0);
    }

    proptest! {
        #[test]
        fn wrap_angle_stays_in_range_and_keeps_the_direction(a in -100.0f64..100.0) {
            let w = wrap_angle(a);
            prop_assert!(w > -std::f64::consts::PI - 1e-12 && w <= std::f64::consts::PI + 1e-12);
            prop_assert!((w.sin() - a.sin()).abs() < 1e-9 && (w.cos() - a.cos()).abs() < 1e-9);
        }

        #[test]
        fn box_overlap_is_symmetric_and_agrees_with_distance(
            x in -8.0f64..8.0, y in -8.0f64..8.0, h1 in -3.2f64..3.2, h2 in -3.2f64..3.2,
        ) {
            let a = OrientedBox { center: Point2::new(0.0, 0.0), heading_rad: h1, length_m: 4.5, width_m: 1.8 };
            let b = OrientedBox { center: Point2::new(x, y), heading_rad: h2, length_m: 4.5, width_m: 1.8 };
            prop_assert_eq!(a.overlaps(&b), b.overlaps(&a));
            let d = a.distance(&b);
            prop_assert!((d - b.distance(&a)).abs() < 1e-9);
            prop_assert_eq!(d == 0.0, a.overlaps(&b));
        }
    }
}
