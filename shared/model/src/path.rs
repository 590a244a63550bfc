//! Reference paths: arc-length parameterised polylines with a smooth heading field, and the Frenet
//! frame `(s, l)` along them (`s` arc length, `l` lateral offset, positive to the left).
//!
//! Positions are linear between vertices; the heading is interpolated linearly in `s` between vertex
//! headings (the bisector of the adjacent segments), so the normal field is continuous and the map
//! `(s, l) → (x, y)` has no gaps or overlaps at vertices as long as `|l|` stays below the local
//! radius of curvature. [`ReferencePath::project`] inverts that map exactly (to solver tolerance),
//! which is what makes round trips sub-millimetre, and [`ReferencePath::project_near`] restricts the
//! search to a window around a previous `s` so that a vehicle on one branch of a self-approaching
//! path is never snapped onto the other branch.

use serde::{Deserialize, Serialize};

use crate::geometry::{Point2, wrap_angle};
use crate::validate::{Validate, ValidationError, finite, in_range};

/// A problem building a path.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PathError {
    /// Fewer than two distinct points.
    #[error("a path needs at least two distinct points, got {0}")]
    TooShort(usize),
    /// A coordinate is NaN or infinite.
    #[error("path point {index} is not finite: ({x}, {y})")]
    NotFinite {
        /// Index of the point.
        index: usize,
        /// Its x.
        x: f64,
        /// Its y.
        y: f64,
    },
    /// A builder parameter is out of range.
    #[error("path segment {index}: {problem}")]
    BadSegment {
        /// Index of the segment.
        index: usize,
        /// What is wrong.
        problem: String,
    },
}

/// A point in the Frenet frame of a path.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct FrenetPoint {
    /// Arc length along the path, m (negative before its start, beyond its length after its end).
    pub s_m: f64,
    /// Lateral offset, m, positive to the left of the direction of travel.
    pub l_m: f64,
}

/// An arc-length parameterised polyline with heading and curvature.
#[derive(Debug, Clone, PartialEq)]
pub struct ReferencePath {
    points: Vec<Point2>,
    /// Cumulative arc length at every vertex (`s[0] = 0`).
    s: Vec<f64>,
    /// Heading at every vertex, unwrapped (continuous), rad.
    heading: Vec<f64>,
}

/// Points closer than this are merged when a path is built.
const MIN_SEGMENT_M: f64 = 1e-6;

/// Longest primitive of a path specification (a line, a clothoid, a lane change), m: longer than
/// any straight of a proving ground.
pub const MAX_SEGMENT_LENGTH_M: f64 = 10_000.0;
/// Shortest primitive of a path specification, m: a millimetre. A shorter positive length (down
/// to the subnormal numbers, which pass every "> 0") is a mistake.
pub const MIN_SEGMENT_LENGTH_M: f64 = 1.0e-3;
/// Largest arc radius of a path specification, m.
pub const MAX_RADIUS_M: f64 = 10_000.0;
/// Smallest arc radius, m: the tightest curvature a clothoid may have ([`MAX_CURVATURE_1PM`]).
/// A smaller radius turned the heading within a sample (a radius of 1e-310 m was a 67° jump).
pub const MIN_RADIUS_M: f64 = 1.0 / MAX_CURVATURE_1PM;
/// Smallest arc angle, degrees.
pub const MIN_ANGLE_DEG: f64 = 0.01;
/// Largest curvature of a clothoid, 1/m (a radius of 0.1 m: tighter than any vehicle turns).
pub const MAX_CURVATURE_1PM: f64 = 10.0;
/// Most primitives in one path specification.
pub const MAX_SEGMENTS: usize = 1_000;
/// Farthest a path may start from the map's origin, m (beyond projected coordinates on Earth).
pub const MAX_COORDINATE_M: f64 = 1.0e8;
/// Most points a path is sampled into (a 10 km path at 5 mm).
pub const MAX_PATH_SAMPLES: usize = 2_000_000;

impl ReferencePath {
    /// Builds a path through `points` (consecutive duplicates are dropped).
    pub fn from_points(points: &[Point2]) -> Result<Self, PathError> {
        let mut pts: Vec<Point2> = Vec::with_capacity(points.len());
        for (index, p) in points.iter().enumerate() {
            if !p.is_finite() {
                return Err(PathError::NotFinite { index, x: p.x, y: p.y });
            }
            if pts.last().is_none_or(|last| last.dist(*p) > MIN_SEGMENT_M) {
                pts.push(*p);
            }
        }
        if pts.len() < 2 {
            return Err(PathError::TooShort(pts.len()));
        }
        let mut s = Vec::with_capacity(pts.len());
        let mut seg_heading = Vec::with_capacity(pts.len() - 1);
        let mut acc = 0.0;
        s.push(0.0);
        for w in pts.windows(2) {
            if let [a, b] = w {
                let d = b.sub(*a);
                acc += d.norm();
                s.push(acc);
                let raw = d.y.atan2(d.x);
                let h = match seg_heading.last() {
                    Some(prev) => prev + wrap_angle(raw - prev),
                    None => raw,
                };
                seg_heading.push(h);
            }
        }
        let mut heading = Vec::with_capacity(pts.len());
        let first = seg_heading.first().copied().unwrap_or(0.0);
        heading.push(first);
        for w in seg_heading.windows(2) {
            if let [a, b] = w {
                heading.push(0.5 * (a + b));
            }
        }
        heading.push(seg_heading.last().copied().unwrap_or(first));
        Ok(Self { points: pts, s, heading })
    }

    /// The vertices.
    pub fn points(&self) -> &[Point2] {
        &self.points
    }

    /// Total arc length, m.
    pub fn length(&self) -> f64 {
        self.s.last().copied().unwrap_or(0.0)
    }

    /// Index `i` of the segment `[s_i, s_{i+1}]` that holds `s` (clamped to the first/last segment).
    fn segment_of(&self, s: f64) -> usize {
        let n_seg = self.points.len().saturating_sub(1);
        let i = self.s.partition_point(|&si| si <= s).saturating_sub(1);
        i.min(n_seg.saturating_sub(1))
    }

    fn vertex(&self, i: usize) -> (Point2, f64, f64) {
        (
            self.points.get(i).copied().unwrap_or_default(),
            self.s.get(i).copied().unwrap_or(0.0),
            self.heading.get(i).copied().unwrap_or(0.0),
        )
    }

    /// Position, heading (unwrapped) and curvature at `s`; linear extrapolation beyond the ends.
    pub fn sample(&self, s: f64) -> PathSample {
        let i = self.segment_of(s);
        let (a, sa, ha) = self.vertex(i);
        let (b, sb, hb) = self.vertex(i + 1);
        let len = (sb - sa).max(MIN_SEGMENT_M);
        if s < 0.0 {
            return PathSample { point: a.add(Point2::from_heading(ha).scale(s)), heading_rad: ha, curvature_1pm: 0.0 };
        }
        let total = self.length();
        if s > total {
            return PathSample {
                point: b.add(Point2::from_heading(hb).scale(s - total)),
                heading_rad: hb,
                curvature_1pm: 0.0,
            };
        }
        let t = (s - sa) / len;
        PathSample { point: a.lerp(b, t), heading_rad: ha + t * (hb - ha), curvature_1pm: (hb - ha) / len }
    }

    /// The path a trajectory's positions trace; points closer than 1 cm to the last one kept are
    /// dropped (a standstill repeats its position).
    pub fn through_states(states: &[crate::kinematics::State]) -> Result<Self, PathError> {
        let mut pts: Vec<Point2> = Vec::with_capacity(states.len());
        for x in states {
            let p = x.position();
            if pts.last().is_none_or(|q| q.dist(p) > 0.01) {
                pts.push(p);
            }
        }
        Self::from_points(&pts)
    }

    /// Position at arc length `s`.
    pub fn point_at(&self, s: f64) -> Point2 {
        self.sample(s).point
    }

    /// Heading at arc length `s`, wrapped to `(-π, π]`.
    pub fn heading_at(&self, s: f64) -> f64 {
        wrap_angle(self.sample(s).heading_rad)
    }

    /// Curvature at arc length `s`, 1/m, positive turning left.
    pub fn curvature_at(&self, s: f64) -> f64 {
        self.sample(s).curvature_1pm
    }

    /// The point at Frenet coordinates `(s, l)`.
    pub fn to_cartesian(&self, s: f64, l: f64) -> Point2 {
        let p = self.sample(s);
        p.point.add(Point2::from_heading(p.heading_rad).perp().scale(l))
    }

    /// Frenet coordinates of `q`: the nearest foot point over the whole path.
    /// `None` only when `q` is not finite.
    pub fn project(&self, q: Point2) -> Option<FrenetPoint> {
        self.project_in(q, 0, self.points.len().saturating_sub(1))
    }

    /// Frenet coordinates of `q`, searching only foot points within `window_m` of `s_hint_m`.
    ///
    /// Use this to track a moving vehicle: pass its previous `s` as the hint and a window a little
    /// larger than the distance it can travel between calls. Falls back to [`Self::project`] when
    /// nothing lies in the window.
    pub fn project_near(&self, q: Point2, s_hint_m: f64, window_m: f64) -> Option<FrenetPoint> {
        if !s_hint_m.is_finite() || !window_m.is_finite() {
            return self.project(q);
        }
        let lo = self.segment_of(s_hint_m - window_m);
        let hi = (self.segment_of(s_hint_m + window_m) + 1).min(self.points.len().saturating_sub(1));
        let near = self.project_in(q, lo, hi).filter(|f| (f.s_m - s_hint_m).abs() <= window_m);
        near.or_else(|| self.project(q))
    }

    /// Tangential residual `G(i) = (q - P_i)·τ_i` at vertex `i`.
    fn residual_at_vertex(&self, q: Point2, i: usize) -> f64 {
        let (p, _, h) = self.vertex(i);
        q.sub(p).dot(Point2::from_heading(h))
    }

    /// Best foot point over vertices `lo..=hi` (segments `lo..hi`), plus the end extensions when
    /// the range touches an end.
    fn project_in(&self, q: Point2, lo: usize, hi: usize) -> Option<FrenetPoint> {
        if !q.is_finite() {
            return None;
        }
        let last = self.points.len().saturating_sub(1);
        let mut best: Option<FrenetPoint> = None;
        // At a foot point the tangential residual is zero, so the distance to the path is |l|.
        let mut consider = |f: FrenetPoint| {
            if best.is_none_or(|b| f.l_m.abs() < b.l_m.abs()) {
                best = Some(f);
            }
        };
        let mut g_prev = self.residual_at_vertex(q, lo);
        if lo == 0 && g_prev <= 0.0 {
            let (p0, _, h0) = self.vertex(0);
            let d = q.sub(p0);
            consider(FrenetPoint { s_m: d.dot(Point2::from_heading(h0)), l_m: d.dot(Point2::from_heading(h0).perp()) });
        }
        for i in lo..hi {
            let g_next = self.residual_at_vertex(q, i + 1);
            if g_prev >= 0.0 && g_next <= 0.0 {
                consider(self.solve_on_segment(q, i, g_prev, g_next));
            }
            g_prev = g_next;
        }
        if hi == last && g_prev >= 0.0 {
            let (pn, sn, hn) = self.vertex(last);
            let d = q.sub(pn);
            consider(FrenetPoint {
                s_m: sn + d.dot(Point2::from_heading(hn)),
                l_m: d.dot(Point2::from_heading(hn).perp()),
            });
        }
        best
    }

    /// Root of `G(t) = (q - p(t))·τ(t)` on segment `i`, given `G(0) ≥ 0 ≥ G(1)`: safeguarded Newton.
    fn solve_on_segment(&self, q: Point2, i: usize, g0: f64, g1: f64) -> FrenetPoint {
        let (a, sa, ha) = self.vertex(i);
        let (b, sb, hb) = self.vertex(i + 1);
        let d = b.sub(a);
        let dh = hb - ha;
        let eval = |t: f64| {
            let p = a.add(d.scale(t));
            let tau = Point2::from_heading(ha + t * dh);
            let n = tau.perp();
            let r = q.sub(p);
            (r.dot(tau), -d.dot(tau) + dh * r.dot(n), r.dot(n))
        };
        let (mut lo, mut hi) = (0.0_f64, 1.0_f64);
        let mut t = if (g0 - g1).abs() > 0.0 { g0 / (g0 - g1) } else { 0.0 };
        for _ in 0..60 {
            let (g, dg, _) = eval(t);
            if g.abs() < 1e-13 * (1.0 + d.norm()) {
                break;
            }
            if g > 0.0 {
                lo = t;
            } else {
                hi = t;
            }
            let newton = if dg.abs() > 1e-300 { t - g / dg } else { f64::NAN };
            t = if newton > lo && newton < hi { newton } else { 0.5 * (lo + hi) };
            if hi - lo < 1e-15 {
                break;
            }
        }
        let (_, _, l) = eval(t);
        FrenetPoint { s_m: sa + t * (sb - sa), l_m: l }
    }

    /// Resamples the path at (at most) `ds_m` spacing, keeping the end points.
    pub fn resampled(&self, ds_m: f64) -> Result<Self, PathError> {
        if !(ds_m.is_finite() && ds_m > 0.0) {
            return Err(PathError::BadSegment {
                index: 0,
                problem: format!("resampling step must be > 0, got {ds_m}"),
            });
        }
        let total = self.length();
        let n = (total / ds_m).ceil().max(1.0);
        if n > MAX_PATH_SAMPLES as f64 {
            return Err(PathError::BadSegment {
                index: 0,
                problem: format!("{n:.0} samples at {ds_m} m spacing, at most {MAX_PATH_SAMPLES}"),
            });
        }
        let n = n as usize;
        let pts: Vec<Point2> = (0..=n).map(|k| self.point_at(total * k as f64 / n as f64)).collect();
        Self::from_points(&pts)
    }
}

/// Position, heading and curvature at one arc length.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PathSample {
    /// Position on the path.
    pub point: Point2,
    /// Heading, rad (unwrapped along the path).
    pub heading_rad: f64,
    /// Curvature, 1/m.
    pub curvature_1pm: f64,
}

/// Builds paths from geometric primitives, sampling each at a given spacing.
#[derive(Debug, Clone)]
pub struct PathBuilder {
    start: Point2,
    start_heading: f64,
    segments: Vec<SegmentSpec>,
}

impl PathBuilder {
    /// Starts at `(x, y)` heading `heading_rad`.
    pub fn new(x: f64, y: f64, heading_rad: f64) -> Self {
        Self { start: Point2::new(x, y), start_heading: heading_rad, segments: Vec::new() }
    }

    /// A straight line.
    #[must_use]
    pub fn line(mut self, length_m: f64) -> Self {
        self.segments.push(SegmentSpec::Line { length_m });
        self
    }

    /// A circular arc; positive `angle_rad` turns left.
    #[must_use]
    pub fn arc(mut self, radius_m: f64, angle_rad: f64) -> Self {
        self.segments.push(SegmentSpec::Arc { radius_m, angle_deg: angle_rad.to_degrees() });
        self
    }

    /// A clothoid whose curvature goes linearly from `k0` to `k1` (1/m).
    #[must_use]
    pub fn clothoid(mut self, length_m: f64, k0_1pm: f64, k1_1pm: f64) -> Self {
        self.segments.push(SegmentSpec::Clothoid { length_m, curvature_start_1pm: k0_1pm, curvature_end_1pm: k1_1pm });
        self
    }

    /// A smooth lateral shift by `offset_m` (positive left) over `length_m`, leaving the heading unchanged.
    #[must_use]
    pub fn lane_change(mut self, length_m: f64, offset_m: f64) -> Self {
        self.segments.push(SegmentSpec::LaneChange { length_m, offset_m });
        self
    }

    /// Samples every primitive at spacing `ds_m` or finer and builds the path.
    pub fn build(&self, ds_m: f64) -> Result<ReferencePath, PathError> {
        if !(ds_m.is_finite() && ds_m > 0.0) {
            return Err(PathError::BadSegment { index: 0, problem: format!("sampling step must be > 0, got {ds_m}") });
        }
        let mut samples = 1.0;
        for (index, seg) in self.segments.iter().enumerate() {
            seg.validate().map_err(|e| PathError::BadSegment { index, problem: e.to_string() })?;
            samples += (seg.arc_length_m() / ds_m).ceil().max(1.0);
        }
        // Checked before anything is allocated: the sizes come from a file.
        if samples > MAX_PATH_SAMPLES as f64 {
            return Err(PathError::BadSegment {
                index: 0,
                problem: format!(
                    "{samples:.0} samples at {ds_m} m spacing, at most {MAX_PATH_SAMPLES} (a coarser step or a shorter path)"
                ),
            });
        }
        let mut pts = Vec::with_capacity(samples as usize);
        pts.push(self.start);
        let mut pose = (self.start, self.start_heading);
        for seg in &self.segments {
            pose = seg.sample_into(pose, ds_m, &mut pts);
        }
        ReferencePath::from_points(&pts)
    }
}

/// A path as written in configuration: a start pose and a list of primitives.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PathSpec {
    /// Start x, m.
    pub start_x_m: f64,
    /// Start y, m.
    pub start_y_m: f64,
    /// Start heading, degrees counter-clockwise from east.
    pub start_heading_deg: f64,
    /// The primitives, in order.
    pub segments: Vec<SegmentSpec>,
}

impl PathSpec {
    /// The builder for this specification.
    pub fn builder(&self) -> PathBuilder {
        PathBuilder {
            start: Point2::new(self.start_x_m, self.start_y_m),
            start_heading: self.start_heading_deg.to_radians(),
            segments: self.segments.clone(),
        }
    }
}

impl Validate for PathSpec {
    fn validate(&self) -> Result<(), ValidationError> {
        in_range("start_x_m", self.start_x_m, -MAX_COORDINATE_M, MAX_COORDINATE_M)?;
        in_range("start_y_m", self.start_y_m, -MAX_COORDINATE_M, MAX_COORDINATE_M)?;
        in_range("start_heading_deg", self.start_heading_deg, -3600.0, 3600.0)?;
        if self.segments.is_empty() {
            return Err(ValidationError::new("segments", "a path needs at least one segment"));
        }
        if self.segments.len() > MAX_SEGMENTS {
            return Err(ValidationError::new(
                "segments",
                format!("at most {MAX_SEGMENTS} segments, got {}", self.segments.len()),
            ));
        }
        self.segments.validate().map_err(|e| e.within("segments"))
    }
}

/// One geometric primitive of a path.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum SegmentSpec {
    /// Straight line.
    Line {
        /// Length, m.
        length_m: f64,
    },
    /// Circular arc, positive angle turns left.
    Arc {
        /// Radius, m.
        radius_m: f64,
        /// Turned angle, degrees, positive left.
        angle_deg: f64,
    },
    /// Clothoid (curvature linear in arc length).
    Clothoid {
        /// Length, m.
        length_m: f64,
        /// Curvature at the start, 1/m.
        curvature_start_1pm: f64,
        /// Curvature at the end, 1/m.
        curvature_end_1pm: f64,
    },
    /// Smooth lateral shift (quintic), heading unchanged at both ends.
    LaneChange {
        /// Longitudinal length, m.
        length_m: f64,
        /// Lateral offset, m, positive left.
        offset_m: f64,
    },
}

impl Validate for SegmentSpec {
    fn validate(&self) -> Result<(), ValidationError> {
        match *self {
            Self::Line { length_m } => length("length_m", length_m),
            Self::Arc { radius_m, angle_deg } => {
                in_range("radius_m", radius_m, MIN_RADIUS_M, MAX_RADIUS_M)?;
                finite("angle_deg", angle_deg)?;
                if angle_deg.abs() >= MIN_ANGLE_DEG && angle_deg.abs() <= 360.0 {
                    Ok(())
                } else {
                    Err(ValidationError::new(
                        "angle_deg",
                        format!("|angle| must lie within [{MIN_ANGLE_DEG}, 360] degrees, got {angle_deg}"),
                    ))
                }
            }
            Self::Clothoid { length_m, curvature_start_1pm, curvature_end_1pm } => {
                length("length_m", length_m)?;
                in_range("curvature_start_1pm", curvature_start_1pm, -MAX_CURVATURE_1PM, MAX_CURVATURE_1PM)?;
                in_range("curvature_end_1pm", curvature_end_1pm, -MAX_CURVATURE_1PM, MAX_CURVATURE_1PM)
            }
            Self::LaneChange { length_m, offset_m } => {
                length("length_m", length_m)?;
                finite("offset_m", offset_m)?;
                if offset_m.abs() < 0.5 * length_m {
                    Ok(())
                } else {
                    Err(ValidationError::new(
                        "offset_m",
                        format!("|offset| must be below half the length, got {offset_m}"),
                    ))
                }
            }
        }
    }
}

/// A primitive's length: within [[`MIN_SEGMENT_LENGTH_M`], [`MAX_SEGMENT_LENGTH_M`]].
fn length(field: &str, value: f64) -> Result<(), ValidationError> {
    in_range(field, value, MIN_SEGMENT_LENGTH_M, MAX_SEGMENT_LENGTH_M)
}

impl SegmentSpec {
    /// Length along the path, m (an arc's from its radius and angle).
    fn arc_length_m(&self) -> f64 {
        match *self {
            Self::Line { length_m } | Self::Clothoid { length_m, .. } | Self::LaneChange { length_m, .. } => length_m,
            Self::Arc { radius_m, angle_deg } => radius_m * angle_deg.to_radians().abs(),
        }
    }

    /// Appends samples (excluding the start point) and returns the end pose.
    fn sample_into(&self, (p0, h0): (Point2, f64), ds: f64, out: &mut Vec<Point2>) -> (Point2, f64) {
        let steps = |len: f64| (len / ds).ceil().max(1.0) as usize;
        let dir = Point2::from_heading(h0);
        let left = dir.perp();
        match *self {
            Self::Line { length_m } => {
                let n = steps(length_m);
                out.extend((1..=n).map(|k| p0.add(dir.scale(length_m * k as f64 / n as f64))));
                (p0.add(dir.scale(length_m)), h0)
            }
            Self::Arc { radius_m, angle_deg } => {
                let angle = angle_deg.to_radians();
                let sign = angle.signum();
                let center = p0.add(left.scale(sign * radius_m));
                let n = steps(radius_m * angle.abs());
                let at = |phi: f64| {
                    // Rotate (p0 - center) by phi.
                    let r = p0.sub(center);
                    let (s, c) = phi.sin_cos();
                    center.add(Point2::new(c * r.x - s * r.y, s * r.x + c * r.y))
                };
                out.extend((1..=n).map(|k| at(angle * k as f64 / n as f64)));
                (at(angle), h0 + angle)
            }
            Self::Clothoid { length_m, curvature_start_1pm: k0, curvature_end_1pm: k1 } => {
                let n = steps(length_m);
                // Integrate with fine substeps (midpoint rule on the heading, exact heading law).
                let sub = 20;
                let h = length_m / (n * sub) as f64;
                let heading = |s: f64| h0 + k0 * s + 0.5 * (k1 - k0) / length_m * s * s;
                let mut p = p0;
                for k in 0..n {
                    for j in 0..sub {
                        let s_mid = ((k * sub + j) as f64 + 0.5) * h;
                        p = p.add(Point2::from_heading(heading(s_mid)).scale(h));
                    }
                    out.push(p);
                }
                (p, heading(length_m))
            }
            Self::LaneChange { length_m, offset_m } => {
                let n = steps(length_m);
                let shape = |xi: f64| xi * xi * xi * (10.0 - 15.0 * xi + 6.0 * xi * xi);
                out.extend((1..=n).map(|k| {
                    let xi = k as f64 / n as f64;
                    p0.add(dir.scale(length_m * xi)).add(left.scale(offset_m * shape(xi)))
                }));
                (p0.add(dir.scale(length_m)).add(left.scale(offset_m)), h0)
            }
        }
    }
}

#[cfg(test)]
mod tests;
