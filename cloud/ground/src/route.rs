//! Route geometry: a maneuver path as it is, a lane change from one path into another with a smooth
//! lateral blend, the extension of a short route upstream along the lane graph, and the cut of a
//! long one to the stretch around its conflicts.

use v2t_map::Map;
use v2t_map::graph::LaneKey;
use v2t_map::library::{Anchor, Fragment, Polyline};
use v2t_model::geometry::Point2;
use v2t_model::path::ReferencePath;

use crate::error::{Misfit, misfit};
use crate::plan::RouteSpec;

/// Spacing of the points of a lane-change blend, m.
const BLEND_STEP_M: f64 = 0.5;
/// Shortest lane-change blend, m.
pub(crate) const MIN_BLEND_M: f64 = 20.0;
/// Longest lane-change blend, m.
pub(crate) const MAX_BLEND_M: f64 = 100.0;
/// Shortest blend accepted when the source lane is short, m.
const SHORTEST_BLEND_M: f64 = 10.0;

/// Quintic smoothstep: 0 → 1 with zero slope and curvature at both ends.
pub(crate) fn smoothstep5(x: f64) -> f64 {
    let x = x.clamp(0.0, 1.0);
    x * x * x * (10.0 - 15.0 * x + 6.0 * x * x)
}

/// Cumulative arc length of `points`.
fn arc_lengths(points: &[Point2]) -> Vec<f64> {
    let mut s = Vec::with_capacity(points.len());
    let mut acc = 0.0;
    let mut prev: Option<Point2> = None;
    for p in points {
        if let Some(q) = prev {
            acc += q.dist(*p);
        }
        s.push(acc);
        prev = Some(*p);
    }
    s
}

/// A route that starts on `from` and ends on `to`, changing over with a quintic lateral profile
/// that completes where `to` passes closest to `done_at`, over `blend_m` (shortened where `from`
/// starts later). Before the blend the route is `from`'s own points; after it, `to`'s.
pub(crate) fn lane_change(
    from: &[Point2],
    to: &[Point2],
    done_at: Point2,
    blend_m: f64,
) -> Result<Vec<Point2>, Misfit> {
    let target = ReferencePath::from_points(to).map_err(|e| misfit!("target path: {e}"))?;
    let s_done = target.project(done_at).ok_or("anchor is not finite")?.s_m.clamp(0.0, target.length());
    // The source in the target's Frenet frame, kept where it runs forward.
    let mut src: Vec<(f64, f64, Point2)> = Vec::with_capacity(from.len());
    for p in from {
        let Some(f) = target.project(*p) else { continue };
        if src.last().is_none_or(|(s, _, _)| f.s_m > *s + 1e-6) {
            src.push((f.s_m, f.l_m, *p));
        }
    }
    let first_s = src.first().map(|x| x.0).ok_or("source path is empty")?;
    let s_begin = (s_done - blend_m).max(first_s);
    if s_done - s_begin < SHORTEST_BLEND_M {
        return Err(misfit!(
            "only {:.1} m of the source lane before the lane change completes; {SHORTEST_BLEND_M} m needed",
            s_done - s_begin
        ));
    }
    let lateral_at = |s: f64| {
        let i = src.partition_point(|x| x.0 < s);
        match (i.checked_sub(1).and_then(|j| src.get(j)), src.get(i)) {
            (Some(a), Some(b)) if b.0 > a.0 => a.1 + (b.1 - a.1) * (s - a.0) / (b.0 - a.0),
            (_, Some(b)) => b.1,
            (Some(a), None) => a.1,
            (None, None) => 0.0,
        }
    };
    let mut out: Vec<Point2> = src.iter().filter(|x| x.0 < s_begin - 1e-6).map(|x| x.2).collect();
    let n = ((s_done - s_begin) / BLEND_STEP_M).ceil().max(1.0) as usize;
    for k in 0..=n {
        let xi = k as f64 / n as f64;
        let s = s_begin + (s_done - s_begin) * xi;
        out.push(target.to_cartesian(s, (1.0 - smoothstep5(xi)) * lateral_at(s)));
    }
    let ts = arc_lengths(target.points());
    out.extend(target.points().iter().zip(&ts).filter(|(_, s)| **s > s_done + 1e-6).map(|(p, _)| *p));
    Ok(out)
}

/// `points` without the points a path overshoots and comes back from: each point whose next
/// segment turns back (by more than 90°) on the segment before it is dropped, repeatedly, so that
/// a path that runs to a lane's end and restarts a little before it runs forward only (v2t-map's
/// paths run forward, which its tests check; a hand-edited library JSON need not). Repeated
/// points are dropped too.
pub(crate) fn forward_only(points: &[Point2]) -> Vec<Point2> {
    let mut out: Vec<Point2> = Vec::with_capacity(points.len());
    for &p in points {
        while let [.., a, b] = out.as_slice() {
            if b.sub(*a).dot(p.sub(*b)) < 0.0 {
                out.pop();
            } else {
                break;
            }
        }
        if out.last().is_none_or(|q| q.dist(p) > 1e-6) {
            out.push(p);
        }
    }
    out
}

/// The points of `spec` on fragment `f` before any cut: a maneuver path, or a lane change that
/// completes at `anchor`.
pub(crate) fn raw_points(f: &Fragment, spec: &RouteSpec, anchor: &Anchor, blend_m: f64) -> Result<Vec<Point2>, Misfit> {
    let path_of = |id: &str| f.maneuver(id).map(|m| forward_only(&m.path)).ok_or_else(|| misfit!("no maneuver {id}"));
    match spec {
        RouteSpec::Path { maneuver } => path_of(maneuver),
        RouteSpec::LaneChange { from, to } => lane_change(&path_of(from)?, &path_of(to)?, anchor.position, blend_m),
    }
}

/// Up to `need_m` of lane centreline upstream of `lane_s` on `lane`, through unique drivable
/// predecessors outside junctions: the points in driving order (without the start point itself),
/// their length, and the lane where they begin.
pub(crate) fn upstream(map: &Map, lane: &LaneKey, lane_s: f64, need_m: f64) -> (Vec<Point2>, f64, LaneKey) {
    let g = &map.graph;
    let mut rev: Vec<Point2> = Vec::new();
    let mut got = 0.0;
    let mut key = lane.clone();
    let mut cur = g.find(lane);
    let mut from_s = lane_s;
    let mut visited = Vec::new();
    while let Some(i) = cur {
        let Some(l) = g.lane(i) else { break };
        visited.push(i);
        key = l.key.clone();
        let left = need_m - got;
        let stop_s = (from_s - left).max(0.0);
        rev.extend(l.samples.iter().rev().filter(|q| q.s < from_s - 1e-6 && q.s > stop_s + 1e-6).map(|q| q.p));
        if let Some(q) = l.at(stop_s)
            && stop_s < from_s - 1e-6
        {
            rev.push(q.p);
        }
        got += from_s - stop_s;
        if got >= need_m - 1e-6 {
            break;
        }
        cur = match l.predecessors.as_slice() {
            [p] => g.lane(*p).filter(|pl| pl.drivable && pl.junction.is_none()).map(|_| *p),
            _ => None,
        };
        if cur.is_some_and(|p| visited.contains(&p)) {
            break;
        }
        from_s = cur.and_then(|p| g.lane(p)).map_or(0.0, |pl| pl.length);
    }
    rev.reverse();
    (rev, got, key)
}

/// The lane among `keys` whose centreline passes nearest to `p`.
pub(crate) fn nearest_lane<'a>(map: &Map, keys: impl IntoIterator<Item = &'a LaneKey>, p: Point2) -> Option<LaneKey> {
    let mut best: Option<(f64, &LaneKey)> = None;
    for k in keys {
        let Some(l) = map.graph.find(k).and_then(|i| map.graph.lane(i)) else { continue };
        let line = Polyline::new(&l.samples.iter().map(|q| q.p).collect::<Vec<_>>());
        if let Some((_, d)) = line.project(p)
            && best.is_none_or(|(b, _)| d < b)
        {
            best = Some((d, k));
        }
    }
    best.map(|(_, k)| k.clone())
}

/// An anchor id, or `<id>@<offset>` for a point `offset_m` along the route from it (negative: upstream).
pub(crate) fn anchor_ref(id: &str, offset_m: f64) -> String {
    if offset_m.abs() < 0.05 { id.to_owned() } else { format!("{id}@{offset_m:+.1}") }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn line(x0: f64, y: f64, x1: f64) -> Vec<Point2> {
        let n = ((x1 - x0) / 0.5).round() as usize;
        (0..=n).map(|k| Point2::new(x0 + (x1 - x0) * k as f64 / n as f64, y)).collect()
    }

    #[test]
    fn smoothstep_is_flat_at_both_ends() {
        assert_eq!(smoothstep5(0.0), 0.0);
        assert_eq!(smoothstep5(1.0), 1.0);
        assert!((smoothstep5(0.5) - 0.5).abs() < 1e-12);
        assert!(smoothstep5(1e-3) < 1e-8 && 1.0 - smoothstep5(1.0 - 1e-3) < 1e-8);
        assert_eq!(smoothstep5(-1.0), 0.0);
    }

    #[test]
    fn a_lane_change_leaves_one_lane_and_completes_on_the_other_at_the_anchor() {
        // From y = -3.5 into y = 0 (a change to the left), completing at x = 100 over 40 m.
        let from = line(0.0, -3.5, 200.0);
        let to = line(0.0, 0.0, 200.0);
        let pts = lane_change(&from, &to, Point2::new(100.0, 0.3), 40.0).unwrap();
        let path = ReferencePath::from_points(&pts).unwrap();
        let target = ReferencePath::from_points(&to).unwrap();
        // On the source lane up to x = 60, on the target from x = 100, and monotone in between.
        let mut prev_y = f64::NEG_INFINITY;
        for p in &pts {
            if p.x <= 60.0 {
                assert!((p.y + 3.5).abs() < 1e-9, "{p:?}");
            } else if p.x >= 100.0 {
                assert!(p.y.abs() < 1e-9, "{p:?}");
            }
            assert!(p.y >= prev_y - 1e-12, "lateral motion reverses at {p:?}");
            prev_y = p.y;
        }
        assert!(path.project(Point2::new(100.0, 0.0)).unwrap().l_m.abs() < 1e-9);
        assert!((path.length() - 200.0).abs() < 0.5, "{}", path.length());
        // The lateral slope stays below the quintic's maximum 15/8 · 3.5 / 40.
        let max_slope = pts.windows(2).map(|w| ((w[1].y - w[0].y) / (w[1].x - w[0].x)).abs()).fold(0.0, f64::max);
        assert!(max_slope <= 1.875 * 3.5 / 40.0 + 1e-3, "{max_slope}");
        assert!(target.project(*pts.last().unwrap()).unwrap().l_m.abs() < 1e-9);
    }

    #[test]
    fn a_short_source_shortens_the_blend_or_is_refused() {
        let to = line(0.0, 0.0, 100.0);
        let pts = lane_change(&line(70.0, 3.5, 100.0), &to, Point2::new(90.0, 0.0), 40.0).unwrap();
        assert!((pts[0].x - 70.0).abs() < 1e-9 && (pts[0].y - 3.5).abs() < 1e-9);
        let err = lane_change(&line(85.0, 3.5, 100.0), &to, Point2::new(90.0, 0.0), 40.0).unwrap_err();
        assert!(err.contains("before the lane change completes"), "{err}");
    }

    #[test]
    fn overshoots_are_dropped() {
        let p = |x: f64| Point2::new(x, 0.0);
        // Runs to 10, restarts at 9.997, goes on: the overshoot to 10 is dropped.
        let got = forward_only(&[p(0.0), p(5.0), p(10.0), p(9.997), p(10.0), p(15.0)]);
        assert_eq!(got, [p(0.0), p(5.0), p(9.997), p(10.0), p(15.0)]);
        // A long backtrack drops everything past the restart.
        let got = forward_only(&[p(0.0), p(1.0), p(2.0), p(3.0), p(1.5), p(4.0)]);
        assert_eq!(got, [p(0.0), p(1.0), p(1.5), p(4.0)]);
        // A turn of less than 90° is kept.
        let turn = [p(0.0), p(1.0), Point2::new(1.5, 1.0)];
        assert_eq!(forward_only(&turn), turn);
    }

    #[test]
    fn anchor_refs_carry_the_offset() {
        assert_eq!(anchor_ref("J4/entry/a3/r3s0l1", 0.0), "J4/entry/a3/r3s0l1");
        assert_eq!(anchor_ref("S16/fwd/0/entry/p1", 627.43), "S16/fwd/0/entry/p1@+627.4");
        assert_eq!(anchor_ref("J4/entry/a3/r3s0l1", -8.9), "J4/entry/a3/r3s0l1@-8.9");
    }
}
