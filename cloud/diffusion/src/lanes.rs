//! A recording's lane network (CommonRoad lanelets) and the route a recorded vehicle drove on it.
//!
//! A lanelet is a stretch of one lane between a left and a right bound with the same number of
//! points; its centreline is the midpoint of the bounds point by point. Lanelets link to their
//! predecessors and successors (lengthwise) and to their left and right neighbours.
//!
//! **The route of a track** ([`LaneletNetwork::route_of`]) is what the denoiser's condition needs:
//! the centreline of the lane the vehicle **ends in**, followed back to where the vehicle started
//! and ahead beyond where it stopped being recorded — as the synthetic corpus and a grounded
//! scenario give it (a vehicle that changes lanes has the target lane as its route; the model learns
//! to move over). Each sample is located in the lanelet that contains it and runs in its direction;
//! the route starts from the last lanelet occupied and walks back through the predecessors the
//! vehicle drove, staying in the target lane where the vehicle came from a neighbouring lane, then
//! goes on through predecessors until it starts behind the first sample, and through the straightest
//! successors until it reaches [`ROUTE_AHEAD_M`] past the last sample (or the network ends).

use serde::{Deserialize, Serialize};
use v2t_model::geometry::{Point2, wrap_angle};
use v2t_model::path::ReferencePath;

/// How far the route goes on past the last recorded position when the network allows, m.
pub const ROUTE_AHEAD_M: f64 = 160.0;
/// A sample belongs to a lanelet only when its heading is within this of the lanelet's, rad.
const HEADING_TOLERANCE_RAD: f64 = 1.0;
/// Lanelets added at most in each direction beyond those driven.
const MAX_EXTENSION: usize = 12;

/// A neighbouring lanelet.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Adjacent {
    /// Its id.
    pub id: String,
    /// Whether it runs in the same direction.
    pub same_direction: bool,
}

/// One lanelet.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Lanelet {
    /// Id in its scenario.
    pub id: String,
    /// Left bound (in driving direction), as many points as `right`.
    pub left: Vec<Point2>,
    /// Right bound.
    pub right: Vec<Point2>,
    /// Line marking of the left bound (`solid`, `dashed`, …), when given.
    pub left_marking: Option<String>,
    /// Line marking of the right bound, when given.
    pub right_marking: Option<String>,
    /// Lanelets that lead into this one.
    pub predecessors: Vec<String>,
    /// Lanelets this one leads into.
    pub successors: Vec<String>,
    /// The neighbour on the left.
    pub adjacent_left: Option<Adjacent>,
    /// The neighbour on the right.
    pub adjacent_right: Option<Adjacent>,
}

impl Lanelet {
    /// The centreline: midpoints of the bounds.
    pub fn centre(&self) -> Vec<Point2> {
        self.left.iter().zip(&self.right).map(|(l, r)| l.lerp(*r, 0.5)).collect()
    }

    /// The outline (left bound, then the right bound backwards).
    fn outline(&self) -> impl Iterator<Item = Point2> + '_ {
        self.left.iter().copied().chain(self.right.iter().rev().copied())
    }

    /// Whether `p` lies inside the outline (even-odd rule).
    pub fn contains(&self, p: Point2) -> bool {
        let poly: Vec<Point2> = self.outline().collect();
        let mut inside = false;
        let mut j = poly.len().saturating_sub(1);
        for (i, a) in poly.iter().enumerate() {
            let Some(b) = poly.get(j) else { continue };
            if (a.y > p.y) != (b.y > p.y) && p.x < (b.x - a.x) * (p.y - a.y) / (b.y - a.y) + a.x {
                inside = !inside;
            }
            j = i;
        }
        inside
    }

    /// The direction of the centreline segment nearest to `p`, rad.
    pub fn heading_near(&self, p: Point2) -> Option<f64> {
        let c = self.centre();
        c.windows(2)
            .filter_map(|w| match w {
                [a, b] if a.dist(*b) > 1e-6 => {
                    Some((v2t_model::geometry::point_segment_distance(p, *a, *b), b.sub(*a)))
                }
                _ => None,
            })
            .min_by(|x, y| x.0.total_cmp(&y.0))
            .map(|(_, d)| d.y.atan2(d.x))
    }
}

/// The lanelets of one recording, with a bounding box each for quick location.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct LaneletNetwork {
    lanelets: Vec<Lanelet>,
    boxes: Vec<(Point2, Point2)>,
}

impl LaneletNetwork {
    /// A network of `lanelets`.
    pub fn new(lanelets: Vec<Lanelet>) -> Self {
        let boxes = lanelets
            .iter()
            .map(|l| {
                l.outline().fold(
                    (Point2::new(f64::INFINITY, f64::INFINITY), Point2::new(f64::NEG_INFINITY, f64::NEG_INFINITY)),
                    |(lo, hi), p| {
                        (Point2::new(lo.x.min(p.x), lo.y.min(p.y)), Point2::new(hi.x.max(p.x), hi.y.max(p.y)))
                    },
                )
            })
            .collect();
        Self { lanelets, boxes }
    }

    /// The lanelets.
    pub fn lanelets(&self) -> &[Lanelet] {
        &self.lanelets
    }

    /// Whether it has no lanelet.
    pub fn is_empty(&self) -> bool {
        self.lanelets.is_empty()
    }

    fn index(&self, id: &str) -> Option<usize> {
        self.lanelets.iter().position(|l| l.id == id)
    }

    fn get(&self, i: usize) -> Option<&Lanelet> {
        self.lanelets.get(i)
    }

    /// The lanelet containing `p` that runs within 1 rad of `heading_rad`
    /// (the one whose direction is closest when several do).
    pub fn locate(&self, p: Point2, heading_rad: f64) -> Option<usize> {
        self.lanelets
            .iter()
            .zip(&self.boxes)
            .enumerate()
            .filter(|(_, (_, (lo, hi)))| p.x >= lo.x && p.x <= hi.x && p.y >= lo.y && p.y <= hi.y)
            .filter(|(_, (l, _))| l.contains(p))
            .filter_map(|(i, (l, _))| {
                let off = wrap_angle(l.heading_near(p)? - heading_rad).abs();
                (off <= HEADING_TOLERANCE_RAD).then_some((i, off))
            })
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .map(|(i, _)| i)
    }

    fn predecessors(&self, i: usize) -> Vec<usize> {
        self.get(i).map_or_else(Vec::new, |l| l.predecessors.iter().filter_map(|id| self.index(id)).collect())
    }

    fn successors(&self, i: usize) -> Vec<usize> {
        self.get(i).map_or_else(Vec::new, |l| l.successors.iter().filter_map(|id| self.index(id)).collect())
    }

    /// Whether `a` and `b` are same-direction neighbours.
    fn neighbours(&self, a: usize, b: usize) -> bool {
        let (Some(la), Some(lb)) = (self.get(a), self.get(b)) else { return false };
        let side = |l: &Lanelet, other: &str| {
            [&l.adjacent_left, &l.adjacent_right].into_iter().flatten().any(|x| x.same_direction && x.id == other)
        };
        side(la, &lb.id) || side(lb, &la.id)
    }

    /// Of `candidates`, the lanelet whose direction at its joint with `joint` (its end when
    /// `at_end`, else its start) is closest to `heading_rad`.
    fn straightest(&self, candidates: &[usize], joint: Point2, heading_rad: f64) -> Option<usize> {
        candidates
            .iter()
            .filter_map(|&i| Some((i, wrap_angle(self.get(i)?.heading_near(joint)? - heading_rad).abs())))
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .map(|(i, _)| i)
    }

    /// The lanelets a vehicle with these positions drove through, in order (consecutive repeats
    /// removed; samples outside every lanelet or standing still skipped).
    pub fn occupied(&self, positions: &[Point2]) -> Vec<usize> {
        let heading = |k: usize| {
            let a = positions.get(k.saturating_sub(1))?;
            let b = positions.get((k + 1).min(positions.len().saturating_sub(1)))?;
            let d = b.sub(*a);
            (d.norm() > 0.05).then(|| d.y.atan2(d.x))
        };
        let mut occupied: Vec<usize> = Vec::new();
        for (k, p) in positions.iter().enumerate() {
            let Some(h) = heading(k) else { continue };
            if let Some(i) = self.locate(*p, h)
                && occupied.last() != Some(&i)
            {
                occupied.push(i);
            }
        }
        occupied
    }

    /// Whether a vehicle with these positions moved sideways into a neighbouring lanelet of the
    /// same direction (a lane change).
    pub fn changes_lanes(&self, positions: &[Point2]) -> bool {
        self.occupied(positions).windows(2).any(|w| matches!(w, [a, b] if self.neighbours(*a, *b)))
    }

    /// The route a vehicle with these positions drove (see the module documentation), as a
    /// centreline polyline; `None` when no sample lies in a lanelet.
    pub fn route_of(&self, positions: &[Point2]) -> Option<Vec<Point2>> {
        let occupied = self.occupied(positions);
        let &last = occupied.last()?;
        let mut chain = vec![last];
        let mut cur = last;
        for &o in occupied.iter().rev().skip(1) {
            if o == cur || chain.contains(&o) {
                continue;
            }
            let preds = self.predecessors(cur);
            if preds.contains(&o) {
                chain.push(o);
                cur = o;
            } else if self.neighbours(cur, o) {
                // Came from the neighbouring lane: the route stays in the target lane.
            } else if let Some(&p) = preds.iter().find(|&&p| self.neighbours(p, o) && !chain.contains(&p)) {
                chain.push(p);
                cur = p;
            } else {
                break;
            }
        }
        chain.reverse();
        let centre_of = |chain: &[usize]| -> Vec<Point2> {
            let mut pts: Vec<Point2> = Vec::new();
            for l in chain.iter().filter_map(|&i| self.get(i)) {
                for p in l.centre() {
                    if pts.last().is_none_or(|q| q.dist(p) > 1e-3) {
                        pts.push(p);
                    }
                }
            }
            pts
        };
        let (first_p, last_p) = (*positions.first()?, *positions.last()?);
        for _ in 0..MAX_EXTENSION {
            let pts = centre_of(&chain);
            let path = ReferencePath::from_points(&pts).ok()?;
            if path.project(first_p).is_some_and(|f| f.s_m > 5.0) {
                break;
            }
            let Some(&head) = chain.first() else { break };
            let start = *pts.first()?;
            let h = path.heading_at(0.0);
            match self.straightest(&self.predecessors(head), start, h) {
                Some(p) if !chain.contains(&p) => chain.insert(0, p),
                _ => break,
            }
        }
        for _ in 0..MAX_EXTENSION {
            let pts = centre_of(&chain);
            let path = ReferencePath::from_points(&pts).ok()?;
            let s_last = path.project(last_p).map_or(0.0, |f| f.s_m);
            if path.length() - s_last >= ROUTE_AHEAD_M {
                break;
            }
            let Some(&tail) = chain.last() else { break };
            let end = *pts.last()?;
            let h = path.heading_at(path.length());
            match self.straightest(&self.successors(tail), end, h) {
                Some(s) if !chain.contains(&s) => chain.push(s),
                _ => break,
            }
        }
        let pts = centre_of(&chain);
        (pts.len() >= 2).then_some(pts)
    }
}

/// An eastbound lanelet 3.5 m wide centred on `y`, its bounds through `xs`, linked to nothing
/// (for tests).
#[cfg(test)]
pub(crate) fn straight_lanelet(id: &str, xs: &[f64], y: f64) -> Lanelet {
    Lanelet {
        id: id.into(),
        left: xs.iter().map(|&x| Point2::new(x, y + 1.75)).collect(),
        right: xs.iter().map(|&x| Point2::new(x, y - 1.75)).collect(),
        left_marking: None,
        right_marking: None,
        predecessors: Vec::new(),
        successors: Vec::new(),
        adjacent_left: None,
        adjacent_right: None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A straight lanelet from x0 to x1 at lane centre y (width 3.5 m, eastbound).
    fn lane(id: &str, x0: f64, x1: f64, y: f64) -> Lanelet {
        straight_lanelet(id, &[x0, 0.5 * (x0 + x1), x1], y)
    }

    /// Two lanes (y = 0 and y = 3.5) of three lanelets each, 50 m long.
    fn two_lanes() -> LaneletNetwork {
        let mut ls = Vec::new();
        for (lane_no, y) in [(0, 0.0), (1, 3.5)] {
            for k in 0..3 {
                let mut l = lane(&format!("{lane_no}{k}"), 50.0 * k as f64, 50.0 * (k + 1) as f64, y);
                if k > 0 {
                    l.predecessors.push(format!("{lane_no}{}", k - 1));
                }
                if k < 2 {
                    l.successors.push(format!("{lane_no}{}", k + 1));
                }
                let other = format!("{}{k}", 1 - lane_no);
                let adj = Some(Adjacent { id: other, same_direction: true });
                if lane_no == 0 {
                    l.adjacent_left = adj;
                } else {
                    l.adjacent_right = adj;
                }
                ls.push(l);
            }
        }
        LaneletNetwork::new(ls)
    }

    #[test]
    fn a_point_is_located_in_its_lane_and_direction() {
        let n = two_lanes();
        let i = n.locate(Point2::new(60.0, 3.0), 0.0).unwrap();
        assert_eq!(n.lanelets()[i].id, "11");
        assert_eq!(n.locate(Point2::new(60.0, 3.0), std::f64::consts::PI), None, "wrong way");
        assert_eq!(n.locate(Point2::new(60.0, 9.0), 0.0), None, "off the road");
    }

    #[test]
    fn a_lane_change_gets_the_target_lane_as_route() {
        let n = two_lanes();
        // From lane 0 at x = 20 to lane 1 by x = 80, then on to x = 100.
        let positions: Vec<Point2> = (0..=80)
            .map(|k| {
                let x = 20.0 + k as f64;
                let f = ((x - 40.0) / 40.0).clamp(0.0, 1.0);
                Point2::new(x, 3.5 * f)
            })
            .collect();
        let route = n.route_of(&positions).unwrap();
        assert!(route.iter().all(|p| (p.y - 3.5).abs() < 1e-9), "stays in the target lane: {route:?}");
        assert!(route.first().unwrap().x <= 20.0 - 5.0 + 1e-9 || route.first().unwrap().x == 0.0);
        assert!((route.last().unwrap().x - 150.0).abs() < 1e-9, "ahead as far as the network goes");
    }

    #[test]
    fn a_vehicle_off_the_network_has_no_route() {
        let n = two_lanes();
        assert_eq!(n.route_of(&[Point2::new(0.0, 50.0), Point2::new(10.0, 50.0)]), None);
        assert_eq!(LaneletNetwork::default().route_of(&[Point2::new(1.0, 0.0), Point2::new(2.0, 0.0)]), None);
    }
}
