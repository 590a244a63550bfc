//! The drivable area of a map: every drivable lane (junction lanes included) as the strip of
//! quadrilaterals between its left and right boundary samples, with a grid index for fast point
//! queries. A BV checks an uploaded prior against it before the prior may reach the regulator.

use std::collections::HashMap;

use v2t_model::geometry::{Point2, point_segment_distance};

use crate::Map;

/// Grid cell of the index, m.
const CELL_M: f64 = 10.0;

/// The union of the map's drivable lanes.
#[derive(Debug, Clone)]
pub struct DrivableArea {
    quads: Vec<[Point2; 4]>,
    grid: HashMap<(i64, i64), Vec<u32>>,
}

fn cell(p: Point2) -> (i64, i64) {
    ((p.x / CELL_M).floor() as i64, (p.y / CELL_M).floor() as i64)
}

/// The four edges of `q`.
fn edges(q: &[Point2; 4]) -> [(Point2, Point2); 4] {
    let [a, b, c, d] = *q;
    [(a, b), (b, c), (c, d), (d, a)]
}

/// Whether `p` lies inside the polygon `q` (crossing number; any simple quadrilateral).
pub(crate) fn inside(p: Point2, q: &[Point2; 4]) -> bool {
    let mut crossings = false;
    for (a, b) in edges(q) {
        if (a.y > p.y) != (b.y > p.y) && p.x < a.x + (p.y - a.y) * (b.x - a.x) / (b.y - a.y) {
            crossings = !crossings;
        }
    }
    crossings
}

/// A lane's surface as the quadrilaterals between its successive left and right boundary samples.
pub(crate) fn lane_quads(lane: &crate::graph::LaneInfo) -> impl Iterator<Item = [Point2; 4]> + '_ {
    lane.samples.windows(2).filter_map(|w| match w {
        [a, b] => Some([a.left, b.left, b.right, a.right]),
        _ => None,
    })
}

impl DrivableArea {
    /// The drivable area of `map`.
    pub fn from_map(map: &Map) -> Self {
        let quads: Vec<[Point2; 4]> = map.graph.lanes.iter().filter(|l| l.drivable).flat_map(lane_quads).collect();
        let mut grid: HashMap<(i64, i64), Vec<u32>> = HashMap::new();
        for (i, q) in quads.iter().enumerate() {
            let (mut lo, mut hi) = (cell(q[0]), cell(q[0]));
            for p in q {
                let c = cell(*p);
                lo = (lo.0.min(c.0), lo.1.min(c.1));
                hi = (hi.0.max(c.0), hi.1.max(c.1));
            }
            for x in lo.0..=hi.0 {
                for y in lo.1..=hi.1 {
                    grid.entry((x, y)).or_default().push(u32::try_from(i).unwrap_or(u32::MAX));
                }
            }
        }
        Self { quads, grid }
    }

    /// Number of lane quadrilaterals.
    pub fn len(&self) -> usize {
        self.quads.len()
    }

    /// Whether the map has no drivable lane.
    pub fn is_empty(&self) -> bool {
        self.quads.is_empty()
    }

    /// Whether `p` lies on a drivable lane or within `margin_m` of one.
    pub fn contains(&self, p: Point2, margin_m: f64) -> bool {
        if !p.x.is_finite() || !p.y.is_finite() {
            return false;
        }
        // Points on an edge between two quadrilaterals (a lane's own samples) count as inside
        // whatever the rounding of the crossing test.
        let margin_m = margin_m.max(1e-6);
        let reach = (margin_m / CELL_M).ceil() as i64;
        let c = cell(p);
        for x in c.0 - reach..=c.0 + reach {
            for y in c.1 - reach..=c.1 + reach {
                let Some(ids) = self.grid.get(&(x, y)) else { continue };
                for &i in ids {
                    let Some(q) = self.quads.get(i as usize) else { continue };
                    if inside(p, q) || edges(q).iter().any(|&(a, b)| point_segment_distance(p, a, b) <= margin_m) {
                        return true;
                    }
                }
            }
        }
        false
    }

    /// The index of the first point off the drivable area (beyond `margin_m`), if any.
    pub fn first_outside(&self, points: impl IntoIterator<Item = Point2>, margin_m: f64) -> Option<(usize, Point2)> {
        points.into_iter().enumerate().find(|(_, p)| !self.contains(*p, margin_m))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn area() -> (Map, DrivableArea) {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config/maps/proving_ground.xodr");
        let map = Map::load(&path).unwrap();
        let area = DrivableArea::from_map(&map);
        (map, area)
    }

    #[test]
    fn lane_centres_are_inside_and_points_far_off_are_not() {
        let (map, area) = area();
        assert!(!area.is_empty());
        let mut n = 0;
        for l in map.graph.lanes.iter().filter(|l| l.drivable) {
            for q in l.samples.iter().step_by(7) {
                assert!(area.contains(q.p, 0.0), "{} at s = {:.1}", l.key, q.s);
                n += 1;
            }
        }
        assert!(n > 500, "{n}");
        // Beside the outermost lane: a lane's width past its outer boundary.
        let outer = map.graph.lanes.iter().find(|l| l.drivable && l.right.is_none()).unwrap();
        let q = &outer.samples[outer.samples.len() / 2];
        let away = q.right.add(q.right.sub(q.p).scale(2.0));
        assert!(!area.contains(away, 0.0) && !area.contains(away, 0.5));
        assert!(area.contains(away, 10.0), "within a generous margin");
        assert!(!area.contains(Point2::new(1e7, 1e7), 1.0));
        assert!(!area.contains(Point2::new(f64::NAN, 0.0), 1.0));
    }

    #[test]
    fn first_outside_names_the_first_stray_point() {
        let (map, area) = area();
        let l = map.graph.lanes.iter().find(|l| l.drivable).unwrap();
        let mut pts: Vec<Point2> = l.samples.iter().map(|q| q.p).collect();
        assert_eq!(area.first_outside(pts.iter().copied(), 0.0), None);
        pts.insert(3, Point2::new(5e5, 5e5));
        assert_eq!(area.first_outside(pts.iter().copied(), 0.5).map(|(i, _)| i), Some(3));
    }
}
