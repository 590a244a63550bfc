//! Conflict zones: where the swept corridors of two paths intersect.

use serde::{Deserialize, Serialize};

use super::Dimensions;
use crate::geometry::{Point2, clip_convex, signed_area};
use crate::path::ReferencePath;

/// Crossing (the paths cross and part again) or merge (one path joins the other's lane).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ConflictKind {
    /// The corridors cross and separate again (left turn, crossing traffic).
    Crossing,
    /// The BV's path joins the VUT's and they share the lane afterwards (cut-in, on-ramp merge). The
    /// zone is the encroachment point where the BV's corridor first enters the VUT's.
    Merge,
}

/// The reference-point arc lengths along one vehicle's own path during which its footprint is in
/// the zone: `[enter_s_m, exit_s_m]`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct OccupancyInterval {
    /// The vehicle enters the zone when its reference point reaches this arc length, m.
    pub enter_s_m: f64,
    /// It has left the zone when its reference point passes this arc length, m.
    pub exit_s_m: f64,
}

impl OccupancyInterval {
    /// Whether a vehicle at arc length `s_m` is in the zone.
    pub fn contains(&self, s_m: f64) -> bool {
        s_m >= self.enter_s_m && s_m <= self.exit_s_m
    }
}

/// One conflict zone between the VUT's path and a BV's, each side named by its role.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ConflictZone {
    /// Crossing or merge.
    pub kind: ConflictKind,
    /// Occupancy interval of the VUT along its own path.
    pub vut: OccupancyInterval,
    /// Occupancy interval of the BV along its own path.
    pub bv: OccupancyInterval,
    /// A representative point of the zone (centroid of the shared area).
    pub anchor: Point2,
}

/// Tuning of [`conflict_zones`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ConflictOptions {
    /// `b` has joined `a` once its centreline is this close to `a`'s, m.
    pub merge_tolerance_m: f64,
    /// … and stays that close for at least this long, m (otherwise it only crossed).
    pub merge_shared_length_m: f64,
}

impl Default for ConflictOptions {
    fn default() -> Self {
        Self { merge_tolerance_m: 0.25, merge_shared_length_m: 8.0 }
    }
}

/// A piece of shared area: the clipped polygon and the segment of `b` it came from.
struct Piece {
    /// The segment of `a` (the VUT's path) whose corridor the piece lies in.
    a_segment: usize,
    /// The segment of `b` (the BV's path) whose corridor the piece lies in.
    b_segment: usize,
    polygon: Vec<Point2>,
}

/// How far beyond its corridor segment's ends a piece's vertex is projected on a path, m: the piece
/// lies in that segment's corridor, so its foot point is on the segment or a neighbour.
/// Projecting near the segment (not over the whole path) keeps the zone of a path that passes the
/// same place many times (a hostile card that circles 900 times) linear, not quadratic, in its
/// length; for a path that does not overlap itself the foot point is the same.
const PIECE_WINDOW_M: f64 = 20.0;

/// Corridor quadrilateral of `path` between arc lengths `s0 < s1` with half-width `hw`.
fn corridor_quad(path: &ReferencePath, s0: f64, s1: f64, hw: f64) -> [Point2; 4] {
    [path.to_cartesian(s0, -hw), path.to_cartesian(s1, -hw), path.to_cartesian(s1, hw), path.to_cartesian(s0, hw)]
}

fn bounding_box(poly: &[Point2]) -> (Point2, Point2) {
    poly.iter().fold(
        (Point2::new(f64::INFINITY, f64::INFINITY), Point2::new(f64::NEG_INFINITY, f64::NEG_INFINITY)),
        |(lo, hi), p| (Point2::new(lo.x.min(p.x), lo.y.min(p.y)), Point2::new(hi.x.max(p.x), hi.y.max(p.y))),
    )
}

/// Vertex arc lengths of a path.
fn vertex_s(path: &ReferencePath) -> Vec<f64> {
    let mut s = Vec::with_capacity(path.points().len());
    let mut acc = 0.0;
    let mut prev: Option<Point2> = None;
    for p in path.points() {
        if let Some(q) = prev {
            acc += q.dist(*p);
        }
        s.push(acc);
        prev = Some(*p);
    }
    s
}

/// Shared area between `a`'s corridor and `b`'s corridor (vertex arc lengths `sa`, `sb`, half
/// widths `a_hw`, `b_hw`), as polygon pieces tagged with the segments they lie in.
fn shared_pieces(a: &ReferencePath, sa: &[f64], a_hw: f64, b: &ReferencePath, sb: &[f64], b_hw: f64) -> Vec<Piece> {
    let a_quads: Vec<([Point2; 4], (Point2, Point2))> = sa
        .windows(2)
        .filter_map(|w| match w {
            [s0, s1] => {
                let q = corridor_quad(a, *s0, *s1, a_hw);
                Some((q, bounding_box(&q)))
            }
            _ => None,
        })
        .collect();
    let mut pieces = Vec::new();
    for (j, w) in sb.windows(2).enumerate() {
        let [s0, s1] = w else { continue };
        let qb = corridor_quad(b, *s0, *s1, b_hw);
        let (blo, bhi) = bounding_box(&qb);
        for (i, (qa, (alo, ahi))) in a_quads.iter().enumerate() {
            if alo.x > bhi.x || blo.x > ahi.x || alo.y > bhi.y || blo.y > ahi.y {
                continue;
            }
            let poly = clip_convex(qa, &qb);
            if poly.len() >= 3 && signed_area(&poly).abs() > 1e-9 {
                pieces.push(Piece { a_segment: i, b_segment: j, polygon: poly });
            }
        }
    }
    pieces
}

/// Groups pieces into runs of consecutive `b` segments (one run per separate shared area).
fn components(pieces: Vec<Piece>) -> Vec<Vec<Piece>> {
    let mut out: Vec<Vec<Piece>> = Vec::new();
    for p in pieces {
        match out.last_mut() {
            Some(run) if run.last().is_some_and(|q| p.b_segment <= q.b_segment + 1) => run.push(p),
            _ => out.push(vec![p]),
        }
    }
    out
}

/// Where `b`'s centreline joins `a`'s for good within `[s_from, s_to]`, if it does.
fn merge_point(a: &ReferencePath, b: &ReferencePath, s_from: f64, s_to: f64, opt: &ConflictOptions) -> Option<f64> {
    let step = 0.05;
    let joined = |s: f64| a.project(b.point_at(s)).is_some_and(|f| f.l_m.abs() <= opt.merge_tolerance_m);
    let n = ((s_to - s_from) / step).ceil().max(0.0) as usize;
    let s_join = (0..=n).map(|k| s_from + step * k as f64).find(|s| joined(*s))?;
    // It must stay joined over the shared length (or to the end of b).
    let end = (s_join + opt.merge_shared_length_m).min(b.length());
    let m = ((end - s_join) / 0.5).ceil().max(1.0) as usize;
    (0..=m).all(|k| joined(s_join + (end - s_join) * k as f64 / m as f64)).then_some(s_join)
}

/// Where on a path to look for the foot points of a piece in the corridor of its segment `k`
/// (vertex arc lengths `s`): `(hint, window)` for [`ReferencePath::project_near`].
fn near_segment(s: &[f64], k: usize) -> (f64, f64) {
    let (s0, s1) = (s.get(k).copied().unwrap_or(0.0), s.get(k + 1).copied().unwrap_or(0.0));
    (0.5 * (s0 + s1), 0.5 * (s1 - s0).abs() + PIECE_WINDOW_M)
}

/// Extent of the pieces along a path: `(min s, max s)` of their vertices, each projected near the
/// segment it lies in (`near` of the piece, [`near_segment`]).
fn extent(path: &ReferencePath, pieces: &[Piece], near: impl Fn(&Piece) -> (f64, f64)) -> Option<(f64, f64)> {
    let mut lo = f64::INFINITY;
    let mut hi = f64::NEG_INFINITY;
    for piece in pieces {
        let (hint, window) = near(piece);
        for p in &piece.polygon {
            let f = path.project_near(*p, hint, window)?;
            lo = lo.min(f.s_m);
            hi = hi.max(f.s_m);
        }
    }
    (lo <= hi).then_some((lo, hi))
}

/// The encroachment point of a merge: the first point (along `b`) where `b`'s corridor enters
/// `a`'s. Each vehicle occupies it while its reference point is within half its length of the
/// point's arc length on its own path, so PET is the time from the rear of the first vehicle
/// passing the point to the front of the second reaching it (the usual cut-in PET).
fn merge_zone(
    (a, sa, a_dims): (&ReferencePath, &[f64], Dimensions),
    (b, sb, b_dims): (&ReferencePath, &[f64], Dimensions),
    run: &[Piece],
) -> Option<ConflictZone> {
    let mut best: Option<(f64, Point2, usize)> = None;
    for piece in run {
        let (hint, window) = near_segment(sb, piece.b_segment);
        for p in &piece.polygon {
            let s_b = b.project_near(*p, hint, window)?.s_m;
            if best.is_none_or(|(s, _, _)| s_b < s) {
                best = Some((s_b, *p, piece.a_segment));
            }
        }
    }
    let (s_b, point, a_segment) = best?;
    let (hint, window) = near_segment(sa, a_segment);
    let s_a = a.project_near(point, hint, window)?.s_m;
    Some(ConflictZone {
        kind: ConflictKind::Merge,
        vut: OccupancyInterval { enter_s_m: s_a - 0.5 * a_dims.length_m, exit_s_m: s_a + 0.5 * a_dims.length_m },
        bv: OccupancyInterval { enter_s_m: s_b - 0.5 * b_dims.length_m, exit_s_m: s_b + 0.5 * b_dims.length_m },
        anchor: point,
    })
}

/// The zone of `zones` nearest `hint` (a grounded conflict point), or without a hint the first
/// along the VUT's path.
pub fn nearest_zone(zones: Vec<ConflictZone>, hint: Option<Point2>) -> Option<ConflictZone> {
    let key = |z: &ConflictZone| hint.map_or(z.vut.enter_s_m, |h| z.anchor.dist(h));
    zones.into_iter().min_by(|a, b| key(a).total_cmp(&key(b)))
}

/// All conflict zones between the VUT (size `vut_dims`) on path `vut` and a BV (size `bv_dims`)
/// on path `bv`, in order along the BV's path.
///
/// For a crossing, the zone is the intersection of the two corridors (each path swept by its
/// vehicle's width); a vehicle occupies it while its footprint overlaps it, i.e. while its
/// reference point is within half its length of the area's extent along its path. A shared area
/// after which the BV stays on the VUT's centreline is a [`ConflictKind::Merge`]; its zone is the
/// encroachment point where the BV's corridor first enters the VUT's (a cut-in's PET is measured
/// there: following in one lane afterwards is not a conflict).
///
/// Where neither vehicle is a BV (mining real traffic), the vehicle that may join the other's lane
/// plays the BV's side.
pub fn conflict_zones(
    vut: &ReferencePath,
    vut_dims: Dimensions,
    bv: &ReferencePath,
    bv_dims: Dimensions,
    options: &ConflictOptions,
) -> Vec<ConflictZone> {
    let (a, a_dims, b, b_dims) = (vut, vut_dims, bv, bv_dims);
    let (a_hw, b_hw) = (0.5 * a_dims.width_m, 0.5 * b_dims.width_m);
    let (sa, sb) = (vertex_s(a), vertex_s(b));
    let all = shared_pieces(a, &sa, a_hw, b, &sb, b_hw);
    let mut zones = Vec::new();
    for run in components(all) {
        let (Some(first), Some(last)) = (run.first(), run.last()) else { continue };
        let s_from = sb.get(first.b_segment).copied().unwrap_or(0.0);
        let s_to = sb.get(last.b_segment + 1).copied().unwrap_or_else(|| b.length());
        if merge_point(a, b, s_from, s_to, options).is_some() {
            if let Some(zone) = merge_zone((a, &sa, a_dims), (b, &sb, b_dims), &run) {
                zones.push(zone);
            }
            continue;
        }
        let (Some((a_lo, a_hi)), Some((b_lo, b_hi))) =
            (extent(a, &run, |p| near_segment(&sa, p.a_segment)), extent(b, &run, |p| near_segment(&sb, p.b_segment)))
        else {
            continue;
        };
        let n_vertices = run.iter().map(|p| p.polygon.len()).sum::<usize>().max(1);
        let sum = run.iter().flat_map(|p| p.polygon.iter()).fold(Point2::default(), |acc, p| acc.add(*p));
        zones.push(ConflictZone {
            kind: ConflictKind::Crossing,
            vut: OccupancyInterval { enter_s_m: a_lo - 0.5 * a_dims.length_m, exit_s_m: a_hi + 0.5 * a_dims.length_m },
            bv: OccupancyInterval { enter_s_m: b_lo - 0.5 * b_dims.length_m, exit_s_m: b_hi + 0.5 * b_dims.length_m },
            anchor: sum.scale(1.0 / n_vertices as f64),
        });
    }
    zones
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::path::PathBuilder;
    use std::f64::consts::FRAC_PI_2;

    const CAR: Dimensions = Dimensions { length_m: 4.5, width_m: 1.8 };

    #[test]
    fn right_angle_crossing_gives_the_exact_square() {
        // a runs east along y = 0, b runs north along x = 50; they cross at (50, 0).
        let a = PathBuilder::new(0.0, 0.0, 0.0).line(100.0).build(1.0).unwrap();
        let b = PathBuilder::new(50.0, -40.0, FRAC_PI_2).line(80.0).build(1.0).unwrap();
        let zones = conflict_zones(&a, CAR, &b, CAR, &ConflictOptions::default());
        assert_eq!(zones.len(), 1);
        let z = zones[0];
        assert_eq!(z.kind, ConflictKind::Crossing);
        let (hw, hl) = (0.9, 2.25);
        assert!((z.vut.enter_s_m - (50.0 - hw - hl)).abs() < 1e-9, "{z:?}");
        assert!((z.vut.exit_s_m - (50.0 + hw + hl)).abs() < 1e-9);
        assert!((z.bv.enter_s_m - (40.0 - hw - hl)).abs() < 1e-9);
        assert!((z.bv.exit_s_m - (40.0 + hw + hl)).abs() < 1e-9);
        assert!(z.anchor.dist(Point2::new(50.0, 0.0)) < 1e-9);
    }

    #[test]
    fn parallel_lanes_do_not_conflict() {
        let a = PathBuilder::new(0.0, 0.0, 0.0).line(100.0).build(1.0).unwrap();
        let b = PathBuilder::new(0.0, 3.5, 0.0).line(100.0).build(1.0).unwrap();
        assert!(conflict_zones(&a, CAR, &b, CAR, &ConflictOptions::default()).is_empty());
    }

    #[test]
    fn cut_in_is_a_merge_measured_at_the_encroachment_point() {
        let a = PathBuilder::new(0.0, 0.0, 0.0).line(200.0).build(0.5).unwrap();
        // b starts one lane to the left, changes lane between x = 50 and x = 80, then follows a.
        let b = PathBuilder::new(0.0, 3.5, 0.0).line(50.0).lane_change(30.0, -3.5).line(90.0).build(0.25).unwrap();
        let zones = conflict_zones(&a, CAR, &b, CAR, &ConflictOptions::default());
        assert_eq!(zones.len(), 1, "{zones:?}");
        let z = zones[0];
        assert_eq!(z.kind, ConflictKind::Merge);
        // b's corridor (half-width 0.9 along its normal) first reaches a's (|y| <= 0.9) near where
        // b's centreline is at y = 1.8; the slope there is small, so its x is close to that point's.
        let shape = |xi: f64| xi * xi * xi * (10.0 - 15.0 * xi + 6.0 * xi * xi);
        let (mut lo, mut hi) = (0.0, 1.0);
        for _ in 0..60 {
            let mid = 0.5 * (lo + hi);
            if 3.5 - 3.5 * shape(mid) > 1.8 { lo = mid } else { hi = mid }
        }
        let x_touch = 50.0 + 30.0 * lo;
        assert!((z.anchor.y - 0.9).abs() < 1e-6, "{z:?}");
        assert!((z.anchor.x - x_touch).abs() < 1.0, "{} vs {x_touch}", z.anchor.x);
        assert!(
            (z.vut.enter_s_m - (z.anchor.x - 2.25)).abs() < 1e-6 && (z.vut.exit_s_m - (z.anchor.x + 2.25)).abs() < 1e-6
        );
        assert!((z.bv.exit_s_m - z.bv.enter_s_m - CAR.length_m).abs() < 1e-9);
        // The point lies on b's corridor edge, 0.9 m along b's tilted normal: its arc length on b
        // is ahead of its x by at most 0.9·sin(max slope) plus the extra length of the curve.
        let s_b = z.bv.enter_s_m + 2.25;
        assert!(s_b > z.anchor.x && s_b - z.anchor.x < 0.5, "{s_b} vs {}", z.anchor.x);
    }

    #[test]
    fn left_turn_across_oncoming_lane_is_one_crossing() {
        // VUT goes straight north on x = 1.75; the oncoming BV comes south on x = -1.75 and turns
        // left (east) with a 12 m radius.
        let a = PathBuilder::new(1.75, -60.0, FRAC_PI_2).line(120.0).build(0.5).unwrap();
        let b =
            PathBuilder::new(-1.75, 60.0, -FRAC_PI_2).line(50.0).arc(12.0, FRAC_PI_2).line(40.0).build(0.25).unwrap();
        let zones = conflict_zones(&a, CAR, &b, CAR, &ConflictOptions::default());
        assert_eq!(zones.len(), 1, "{zones:?}");
        assert_eq!(zones[0].kind, ConflictKind::Crossing);
        let z = zones[0];
        assert!(z.vut.exit_s_m - z.vut.enter_s_m > CAR.length_m + CAR.width_m - 1e-6);
    }

    #[test]
    fn nearest_zone_follows_the_hint_else_the_first_along_the_vut() {
        let zone = |enter: f64, x: f64| ConflictZone {
            kind: ConflictKind::Crossing,
            vut: OccupancyInterval { enter_s_m: enter, exit_s_m: enter + 5.0 },
            bv: OccupancyInterval { enter_s_m: 0.0, exit_s_m: 5.0 },
            anchor: Point2::new(x, 0.0),
        };
        let zones = || vec![zone(40.0, 40.0), zone(10.0, 10.0), zone(70.0, 70.0)];
        assert_eq!(nearest_zone(zones(), None).unwrap().vut.enter_s_m, 10.0);
        assert_eq!(nearest_zone(zones(), Some(Point2::new(66.0, 3.0))).unwrap().vut.enter_s_m, 70.0);
        assert!(nearest_zone(Vec::new(), None).is_none());
    }
}
