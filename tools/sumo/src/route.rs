//! Matching a sampled path to the lanes that drive it: the route SUMO needs to drive the path.
//!
//! Every sample gets the lanes near it that run its way (candidates); a Viterbi pass picks the
//! sequence of candidates that stays closest to the samples while only moving along a lane, to a
//! neighbouring lane of the same edge, or through connections (with the internal junction lanes
//! between). Deciding per sample alone fails at junction entries, where the straight and the
//! turning internal lanes start on top of each other.

use std::collections::HashMap;

use crate::SumoError;
use crate::geometry::{self, Projection};
use crate::net::{EdgeFunction, Network};

/// The cost of a lane change, in metres of lateral offset: a path changes lane when staying
/// would cost more offset than this.
const LANE_CHANGE_COST_M: f64 = 1.0;
/// The most internal lanes one link passes between two consecutive samples, plus one.
const MAX_LINK_HOPS: usize = 4;

/// A path matched to the network: what SUMO needs to drive it, and the lanes' polyline.
#[derive(Debug, Clone, PartialEq)]
pub struct MatchedRoute {
    /// The lanes driven, in order, internal junction lanes included, consecutive duplicates
    /// merged (a lane change on an edge shows as two lanes of that edge).
    pub lanes: Vec<String>,
    /// The normal edges driven, in order: the route to give SUMO.
    pub edges: Vec<String>,
    /// Index of the first lane on the first edge (SUMO's `departLane`).
    pub depart_lane: u32,
    /// Lane position of the first sample on the first lane, metres (SUMO's `departPos`; SUMO
    /// places the **front bumper** there).
    pub depart_pos_m: f64,
    /// Index of the last lane on the last edge.
    pub arrival_lane: u32,
    /// Lane position of the last sample on the last lane, metres (SUMO's `arrivalPos`).
    pub arrival_pos_m: f64,
    /// The lanes' centre lines from the first sample's foot point to the last's, `[x, y]`.
    pub shape: Vec<[f64; 2]>,
}

/// How one lane leads to another between two samples.
#[derive(Debug, Clone)]
struct Link {
    /// A lane of the first lane's edge changed to before the link, if any.
    via_sibling: Option<usize>,
    /// The internal lanes passed whole.
    intermediates: Vec<usize>,
    /// Their summed shape length, metres.
    between_m: f64,
}

/// A lane driven over a stretch of arc length.
#[derive(Debug, Clone, Copy)]
struct Span {
    lane: usize,
    enter_s: f64,
    exit_s: f64,
}

type Candidate = (usize, Projection);

impl Network {
    /// Matches `points` (`[x, y, heading_rad]`, heading 0 = east, counter-clockwise, sampled
    /// about every metre along a path) to the lanes that drive it. Every sample must lie within
    /// `max_off_m` of a lane running within 60° of its heading ([`SumoError::RouteMatch`]), the
    /// lanes must link up, and the path must start and end on normal (not junction) lanes
    /// ([`SumoError::RouteBroken`]). Positions are those of whatever point the samples describe;
    /// SUMO's `departPos` places the front bumper.
    pub fn match_route(&self, points: &[[f64; 3]], max_off_m: f64) -> Result<MatchedRoute, SumoError> {
        if !(max_off_m > 0.0 && max_off_m.is_finite()) {
            return Err(SumoError::InvalidArgument {
                what: "max_off_m",
                problem: format!("{max_off_m}: must be a finite positive distance in metres"),
            });
        }
        if points.len() < 2 {
            return Err(SumoError::InvalidArgument {
                what: "path",
                problem: format!("{} samples: a route needs at least 2", points.len()),
            });
        }
        let layers = self.candidate_layers(points, max_off_m)?;
        let mut memo = HashMap::new();
        let chosen = self.viterbi(points, &layers, &mut memo)?;
        let spans = self.spans(&chosen, &mut memo);
        self.route_of(points, &spans)
    }

    fn candidate_layers(&self, points: &[[f64; 3]], max_off_m: f64) -> Result<Vec<Vec<Candidate>>, SumoError> {
        let mut layers = Vec::with_capacity(points.len());
        for (index, &[x, y, heading]) in points.iter().enumerate() {
            let layer = self.candidates([x, y], heading, max_off_m);
            if layer.is_empty() {
                let (nearest_lane, distance_m) =
                    self.nearest_any([x, y]).map_or(("none".to_owned(), f64::INFINITY), |(l, d)| (l.id.clone(), d));
                return Err(SumoError::RouteMatch { index, x, y, nearest_lane, distance_m, max_off_m });
            }
            layers.push(layer);
        }
        Ok(layers)
    }

    /// The candidate of every sample on the cheapest linked sequence.
    fn viterbi(
        &self,
        points: &[[f64; 3]],
        layers: &[Vec<Candidate>],
        memo: &mut HashMap<(usize, usize), Option<Link>>,
    ) -> Result<Vec<Candidate>, SumoError> {
        let mut costs: Vec<f64> =
            layers.first().map(|l| l.iter().map(|c| c.1.lateral.abs()).collect()).unwrap_or_default();
        let mut back: Vec<Vec<usize>> = Vec::with_capacity(layers.len());
        for (i, pair) in layers.windows(2).enumerate() {
            let [prev, layer] = pair else { continue };
            let (p0, p1) = (points.get(i), points.get(i + 1));
            let step = p0.zip(p1).map_or(0.0, |(a, b)| (b[0] - a[0]).hypot(b[1] - a[1]));
            let mut next_costs = Vec::with_capacity(layer.len());
            let mut next_back = Vec::with_capacity(layer.len());
            for cand in layer {
                let best = prev
                    .iter()
                    .zip(&costs)
                    .enumerate()
                    .filter_map(|(j, (from, cost))| Some((j, cost + self.transition(memo, from, cand, step)?)))
                    .min_by(|a, b| a.1.total_cmp(&b.1));
                let (j, cost) = best.unwrap_or((0, f64::INFINITY));
                next_costs.push(cost + cand.1.lateral.abs());
                next_back.push(j);
            }
            if next_costs.iter().all(|c| !c.is_finite()) {
                let [x, y, _] = p1.copied().unwrap_or_default();
                let names = |l: &mut dyn Iterator<Item = &Candidate>| {
                    l.filter_map(|c| Some(self.lane_at(c.0)?.id.as_str())).collect::<Vec<_>>().join(", ")
                };
                let reachable = prev.iter().zip(&costs).filter(|(_, c)| c.is_finite()).map(|(p, _)| p);
                return Err(SumoError::RouteBroken {
                    index: i + 1,
                    x,
                    y,
                    problem: format!(
                        "no lane near it ({}) links to a lane the path can be on at the sample before ({})",
                        names(&mut layer.iter()),
                        names(&mut reachable.into_iter())
                    ),
                });
            }
            costs = next_costs;
            back.push(next_back);
        }
        let mut k = costs.iter().enumerate().min_by(|a, b| a.1.total_cmp(b.1)).map_or(0, |(k, _)| k);
        let mut chosen = Vec::with_capacity(layers.len());
        for (i, layer) in layers.iter().enumerate().rev() {
            chosen.push(layer.get(k).copied().ok_or_else(|| missing("backtrack"))?);
            if i > 0 {
                k = back.get(i - 1).and_then(|b| b.get(k)).copied().ok_or_else(|| missing("backtrack"))?;
            }
        }
        chosen.reverse();
        Ok(chosen)
    }

    /// The cost of moving from candidate `a` to candidate `b` over a sample step of `step` metres:
    /// how far the distance along the lanes differs from the step, plus lane changes; `None` when
    /// `b` cannot follow `a`.
    fn transition(
        &self,
        memo: &mut HashMap<(usize, usize), Option<Link>>,
        a: &Candidate,
        b: &Candidate,
        step: f64,
    ) -> Option<f64> {
        if a.0 == b.0 {
            return Some((b.1.s - a.1.s - step).abs());
        }
        if self.siblings(a.0).any(|s| s == b.0) {
            return Some(LANE_CHANGE_COST_M + (b.1.s - a.1.s - step).abs());
        }
        let link = memo.entry((a.0, b.0)).or_insert_with(|| self.find_link(a.0, b.0)).as_ref()?;
        let left = link.via_sibling.unwrap_or(a.0);
        let remaining = (self.lane_at(left)?.shape_length_m - a.1.s).max(0.0);
        let along = remaining + link.between_m + b.1.s;
        let change = if link.via_sibling.is_some() { LANE_CHANGE_COST_M } else { 0.0 };
        Some((along - step).abs() + change)
    }

    /// How lane `a` (or, failing that, a lane of its edge) leads to lane `b` through at most
    /// [`MAX_LINK_HOPS`] connections, passing internal lanes only.
    fn find_link(&self, a: usize, b: usize) -> Option<Link> {
        let starts = std::iter::once((a, None)).chain(self.siblings(a).map(|s| (s, Some(s))));
        for (start, via_sibling) in starts {
            let mut frontier: Vec<(usize, Vec<usize>)> = vec![(start, Vec::new())];
            for _ in 0..MAX_LINK_HOPS {
                let mut next = Vec::new();
                for (lane, path) in &frontier {
                    for &succ in self.successors.get(*lane).into_iter().flatten() {
                        if succ == b {
                            let between_m = path.iter().filter_map(|&i| Some(self.lane_at(i)?.shape_length_m)).sum();
                            return Some(Link { via_sibling, intermediates: path.clone(), between_m });
                        }
                        let internal = self.lane_at(succ).is_some_and(|l| l.internal);
                        if internal && !path.contains(&succ) {
                            let mut longer = path.clone();
                            longer.push(succ);
                            next.push((succ, longer));
                        }
                    }
                }
                frontier = next;
            }
        }
        None
    }

    /// The lanes driven by the chosen candidates, with the stretch of each.
    fn spans(&self, chosen: &[Candidate], memo: &mut HashMap<(usize, usize), Option<Link>>) -> Vec<Span> {
        let mut spans: Vec<Span> = Vec::new();
        let full = |lane: usize| self.lane_at(lane).map_or(0.0, |l| l.shape_length_m);
        for (i, &(lane, proj)) in chosen.iter().enumerate() {
            let prev = i.checked_sub(1).and_then(|j| chosen.get(j));
            let Some(&(prev_lane, prev_proj)) = prev else {
                spans.push(Span { lane, enter_s: proj.s, exit_s: proj.s });
                continue;
            };
            if lane == prev_lane {
                if let Some(last) = spans.last_mut() {
                    last.exit_s = last.exit_s.max(proj.s);
                }
                continue;
            }
            let link = memo.entry((prev_lane, lane)).or_insert_with(|| self.find_link(prev_lane, lane));
            let is_sibling = self.siblings(prev_lane).any(|s| s == lane);
            match (is_sibling, link.as_ref()) {
                (false, Some(link)) => {
                    if let Some(sib) = link.via_sibling {
                        spans.push(Span { lane: sib, enter_s: prev_proj.s, exit_s: full(sib) });
                    } else if let Some(last) = spans.last_mut() {
                        last.exit_s = full(last.lane);
                    }
                    for &m in &link.intermediates {
                        spans.push(Span { lane: m, enter_s: 0.0, exit_s: full(m) });
                    }
                    spans.push(Span { lane, enter_s: 0.0, exit_s: proj.s });
                }
                // A lane change on one edge (the Viterbi pass allowed nothing else).
                _ => spans.push(Span { lane, enter_s: proj.s, exit_s: proj.s }),
            }
        }
        spans
    }

    fn route_of(&self, points: &[[f64; 3]], spans: &[Span]) -> Result<MatchedRoute, SumoError> {
        let with_lane = |s: &Span| Some((*s, self.lane_at(s.lane)?));
        let ends = (spans.first().and_then(with_lane), spans.last().and_then(with_lane));
        let (Some((first, first_lane)), Some((last, last_lane))) = ends else {
            return Err(missing("matched lanes"));
        };
        for (index, l, end) in [(0, first_lane, "starts"), (points.len() - 1, last_lane, "ends")] {
            if l.internal {
                let [x, y, _] = points.get(index).copied().unwrap_or_default();
                return Err(SumoError::RouteBroken {
                    index,
                    x,
                    y,
                    problem: format!(
                        "the path {end} on junction lane {}; SUMO routes start and end on normal \
                         lanes: extend the path past the junction",
                        l.id
                    ),
                });
            }
        }
        let mut lanes: Vec<String> = Vec::new();
        let mut edges: Vec<String> = Vec::new();
        let mut shape = Vec::new();
        for span in spans {
            let Some(l) = self.lane_at(span.lane) else { continue };
            if lanes.last() != Some(&l.id) {
                lanes.push(l.id.clone());
            }
            let normal = self.edge(&l.edge_id).is_some_and(|e| e.function == EdgeFunction::Normal);
            if normal && edges.last() != Some(&l.edge_id) {
                edges.push(l.edge_id.clone());
            }
            geometry::append_stretch(&l.shape, span.enter_s, span.exit_s.max(span.enter_s), &mut shape);
        }
        Ok(MatchedRoute {
            lanes,
            edges,
            depart_lane: first_lane.index,
            depart_pos_m: first_lane.lane_pos(first.enter_s),
            arrival_lane: last_lane.index,
            arrival_pos_m: last_lane.lane_pos(last.exit_s),
            shape,
        })
    }
}

/// An internal inconsistency reported as an error rather than a panic.
fn missing(what: &'static str) -> SumoError {
    SumoError::InvalidArgument { what: "path", problem: format!("route matching lost its {what} (a bug in v2t-sumo)") }
}
