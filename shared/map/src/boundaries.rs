//! Lines a vehicle must not cross, as polylines: lane boundaries marked solid (`solid`,
//! `solid solid`, `curb`, `edge`) and the outer edges of the carriageway (a boundary with no
//! drivable lane beyond it), outside junctions. Used by the diffusion guidance (`E_bound`) and to
//! count crossings of generated trajectories.

use v2t_model::geometry::{Point2, point_segment_distance};

use crate::Map;
use crate::graph::LaneInfo;
use crate::xodr::MarkType;

/// Whether the lane's left (`left = true`) or right boundary may not be crossed, and whether this
/// lane is the one that reports it (a line between two lanes is reported once).
fn reports(map: &Map, lane: &LaneInfo, left: bool, mark: MarkType) -> bool {
    let neighbour = if left { lane.left } else { lane.right };
    let beyond = neighbour.and_then(|n| map.graph.lanes.get(n.lane)).filter(|l| l.drivable);
    match beyond {
        // An edge: nothing drivable beyond.
        None => true,
        Some(other) => {
            if mark != MarkType::Solid {
                return false;
            }
            match neighbour {
                // Same direction: the right boundary of the left lane reports it.
                Some(n) if n.same_direction => !left,
                // Opposite direction (centre line): the lane driving along s reports it.
                Some(_) => lane.forward || !other.forward,
                None => true,
            }
        }
    }
}

/// Douglas–Peucker simplification with tolerance `tol_m` (end points kept).
pub fn simplify(points: &[Point2], tol_m: f64) -> Vec<Point2> {
    fn rec(points: &[Point2], tol: f64, keep: &mut [bool], lo: usize, hi: usize) {
        if hi <= lo + 1 {
            return;
        }
        let (Some(&a), Some(&b)) = (points.get(lo), points.get(hi)) else { return };
        let mut worst = (0.0, lo);
        for (i, p) in points.iter().enumerate().take(hi).skip(lo + 1) {
            let d = point_segment_distance(*p, a, b);
            if d > worst.0 {
                worst = (d, i);
            }
        }
        if worst.0 > tol {
            if let Some(k) = keep.get_mut(worst.1) {
                *k = true;
            }
            rec(points, tol, keep, lo, worst.1);
            rec(points, tol, keep, worst.1, hi);
        }
    }
    if points.len() <= 2 {
        return points.to_vec();
    }
    let mut keep = vec![false; points.len()];
    if let Some(k) = keep.first_mut() {
        *k = true;
    }
    if let Some(k) = keep.last_mut() {
        *k = true;
    }
    rec(points, tol_m, &mut keep, 0, points.len() - 1);
    points.iter().zip(keep).filter(|(_, k)| *k).map(|(p, _)| *p).collect()
}

/// The solid boundaries of `map` that come within `radius_m` of any point of `near` (all of them
/// when `near` is empty), cut to that neighbourhood and simplified with tolerance `tol_m`.
/// Polylines run in the lane's driving direction (their left side is the lane's side for a
/// right boundary).
pub fn solid_boundaries(map: &Map, near: &[Point2], radius_m: f64, tol_m: f64) -> Vec<Vec<Point2>> {
    let close = |p: Point2| near.is_empty() || near.iter().any(|q| q.dist(p) <= radius_m);
    let mut out = Vec::new();
    for lane in map.graph.lanes.iter().filter(|l| l.drivable && l.junction.is_none()) {
        for left in [true, false] {
            let mut run: Vec<Point2> = Vec::new();
            for s in &lane.samples {
                let (p, mark) = if left { (s.left, s.left_mark) } else { (s.right, s.right_mark) };
                if reports(map, lane, left, mark) && close(p) {
                    run.push(p);
                } else if run.len() >= 2 {
                    out.push(simplify(&std::mem::take(&mut run), tol_m));
                } else {
                    run.clear();
                }
            }
            if run.len() >= 2 {
                out.push(simplify(&run, tol_m));
            }
        }
    }
    out
}

/// Whether the segment `a`–`b` crosses the segment `c`–`d` (proper or touching).
pub fn segments_cross(a: Point2, b: Point2, c: Point2, d: Point2) -> bool {
    let orient = |p: Point2, q: Point2, r: Point2| q.sub(p).cross(r.sub(p));
    let (d1, d2) = (orient(c, d, a), orient(c, d, b));
    let (d3, d4) = (orient(a, b, c), orient(a, b, d));
    ((d1 > 0.0 && d2 < 0.0) || (d1 < 0.0 && d2 > 0.0)) && ((d3 > 0.0 && d4 < 0.0) || (d3 < 0.0 && d4 > 0.0))
}

/// Index of the first step of `path` that crosses one of `boundaries`, if any.
pub fn first_crossing(path: &[Point2], boundaries: &[Vec<Point2>]) -> Option<usize> {
    path.windows(2).position(|w| {
        let [a, b] = w else { return false };
        boundaries.iter().any(|line| {
            line.windows(2).any(|s| match s {
                [c, d] => segments_cross(*a, *b, *c, *d),
                _ => false,
            })
        })
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn simplify_keeps_corners_and_drops_collinear_points() {
        let pts: Vec<Point2> =
            (0..=10).map(|i| Point2::new(f64::from(i), 0.0)).chain([Point2::new(10.0, 5.0)]).collect();
        let s = simplify(&pts, 0.01);
        assert_eq!(s, vec![Point2::new(0.0, 0.0), Point2::new(10.0, 0.0), Point2::new(10.0, 5.0)]);
    }

    #[test]
    fn crossing_is_found() {
        let line = vec![vec![Point2::new(0.0, 0.0), Point2::new(10.0, 0.0)]];
        let path = [Point2::new(1.0, 1.0), Point2::new(2.0, 0.5), Point2::new(3.0, -0.5)];
        assert_eq!(first_crossing(&path, &line), Some(1));
        assert_eq!(first_crossing(&path[..2], &line), None);
    }

    #[test]
    fn proving_ground_has_edges_near_its_cut_in_segment() {
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config/maps/proving_ground.xodr");
        let map = Map::load(&root).unwrap();
        let all = solid_boundaries(&map, &[], 0.0, 0.05);
        assert!(!all.is_empty());
        // Every boundary lies on a lane's edge: no point is farther than 0.01 m from some sample's
        // left or right point's polyline, and none lies inside a junction lane strip by construction.
        let near = solid_boundaries(&map, &[Point2::new(-570.0, -494.75)], 30.0, 0.05);
        assert!(!near.is_empty());
        assert!(near.iter().flatten().all(|p| p.dist(Point2::new(-570.0, -494.75)) <= 30.0 + 1e-9));
    }
}
