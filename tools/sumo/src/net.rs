//! A SUMO network (`.net.xml`) as netconvert writes it: edges, lanes with their shapes,
//! connections, junctions; and where a point lies on it.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use crate::SumoError;
use crate::geometry;

/// The lane width SUMO assumes when a lane has no `width` attribute, in metres.
pub const DEFAULT_LANE_WIDTH_M: f64 = 3.2;
/// The largest angle between a heading and a lane's direction for the lane to count, radians
/// (60°).
pub const MAX_HEADING_ERROR_RAD: f64 = std::f64::consts::FRAC_PI_3;

/// What an edge is for (the `function` attribute).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EdgeFunction {
    /// A road between junctions (no `function` attribute).
    Normal,
    /// A lane bundle inside a junction; its id starts with `:`.
    Internal,
    /// A connector to a traffic assignment zone.
    Connector,
    /// A pedestrian crossing.
    Crossing,
    /// A pedestrian walking area.
    WalkingArea,
}

/// An edge of the network.
#[derive(Debug, Clone, PartialEq)]
pub struct Edge {
    /// SUMO's id (`-2`, `1#1`, `:100_9`).
    pub id: String,
    /// What it is for.
    pub function: EdgeFunction,
    /// The junction it leaves (normal edges only).
    pub from: Option<String>,
    /// The junction it enters (normal edges only).
    pub to: Option<String>,
    /// Its lanes' ids, rightmost (index 0) first.
    pub lanes: Vec<String>,
}

/// A lane of the network.
#[derive(Debug, Clone, PartialEq)]
pub struct Lane {
    /// SUMO's id: the edge's id, `_`, the index (`2_1`, `:100_9_1`).
    pub id: String,
    /// Its edge's id.
    pub edge_id: String,
    /// Its index on the edge, 0 the rightmost.
    pub index: u32,
    /// Speed limit in m/s.
    pub speed_mps: f64,
    /// SUMO's length in metres: the unit of lane positions (`departPos`, `getLanePosition`).
    /// For most lanes it equals the shape's arc length; where it does not, positions scale.
    pub length_m: f64,
    /// Width in metres ([`DEFAULT_LANE_WIDTH_M`] when the file gives none).
    pub width_m: f64,
    /// Centre line, in the direction of travel, `[x, y]` in metres.
    pub shape: Vec<[f64; 2]>,
    /// The OpenDRIVE lane it came from (`origId` parameter, e.g. `110_-1`: road 110, lane −1),
    /// when netconvert ran with `--output.original-names`.
    pub orig_id: Option<String>,
    /// Arc length of `shape` in metres.
    pub shape_length_m: f64,
    /// Whether its edge is internal (inside a junction).
    pub internal: bool,
}

impl Lane {
    /// SUMO's lane position (in [`Lane::length_m`] units) of arc length `s_m` along the shape.
    pub fn lane_pos(&self, s_m: f64) -> f64 {
        if self.shape_length_m > 0.0 { s_m * self.length_m / self.shape_length_m } else { s_m }
    }
}

/// A link from one lane to the next, through a junction (`<connection>`).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Connection {
    /// The edge it leaves.
    pub from_edge: String,
    /// The edge it enters.
    pub to_edge: String,
    /// The lane index it leaves.
    pub from_lane: u32,
    /// The lane index it enters.
    pub to_lane: u32,
    /// The internal lane that drives it, if any.
    pub via: Option<String>,
}

/// A junction of the network.
#[derive(Debug, Clone, PartialEq)]
pub struct Junction {
    /// SUMO's id (the OpenDRIVE junction id for imported junctions, e.g. `100`).
    pub id: String,
    /// SUMO's junction type (`priority`, `internal`, `dead_end`, …).
    pub kind: String,
    /// Its position `[x, y]` in metres.
    pub position: [f64; 2],
    /// The internal lanes inside it (`intLanes`).
    pub internal_lanes: Vec<String>,
}

/// Where a point lies on a lane.
#[derive(Debug, Clone, PartialEq)]
pub struct LanePos {
    /// The lane.
    pub lane_id: String,
    /// Arc length of the foot point along the lane's shape, metres.
    pub s_m: f64,
    /// Signed distance to the centre line, positive to the left of the direction of travel.
    pub lateral_m: f64,
    /// The heading minus the lane's direction at the foot point, radians in `(-π, π]`.
    pub heading_err: f64,
}

/// The axis-aligned box around every lane shape.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Bounds {
    /// Smallest x and y, metres.
    pub min: [f64; 2],
    /// Largest x and y, metres.
    pub max: [f64; 2],
}

/// A SUMO network read from a `.net.xml` file.
#[derive(Debug, Clone)]
pub struct Network {
    /// The file it was read from.
    pub path: PathBuf,
    /// Edges in file order.
    pub edges: Vec<Edge>,
    /// Lanes in file order.
    pub lanes: Vec<Lane>,
    /// Connections in file order.
    pub connections: Vec<Connection>,
    /// Junctions in file order.
    pub junctions: Vec<Junction>,
    lane_index: HashMap<String, usize>,
    edge_index: HashMap<String, usize>,
    /// The lanes each lane leads to (connections resolved to `via` lanes or target lanes).
    pub(crate) successors: Vec<Vec<usize>>,
    /// Each lane's bounding box.
    lane_boxes: Vec<Bounds>,
}

/// A parse error at `element`/`attribute` of `file`.
fn parse_error(file: &Path, element: &str, attribute: &str, problem: impl Into<String>) -> SumoError {
    SumoError::NetParse {
        file: file.to_path_buf(),
        element: element.to_owned(),
        attribute: attribute.to_owned(),
        problem: problem.into(),
    }
}

struct Attrs<'a, 'i> {
    file: &'a Path,
    node: roxmltree::Node<'a, 'i>,
}

impl<'a> Attrs<'a, '_> {
    fn context(&self) -> String {
        let id = self.node.attribute("id").map(|id| format!(" id=\"{id}\"")).unwrap_or_default();
        format!("{}{id}", self.node.tag_name().name())
    }

    fn required(&self, name: &str) -> Result<&'a str, SumoError> {
        self.node.attribute(name).ok_or_else(|| parse_error(self.file, &self.context(), name, "missing"))
    }

    fn number<T: std::str::FromStr>(&self, name: &str) -> Result<Option<T>, SumoError> {
        self.node
            .attribute(name)
            .map(|v| {
                v.trim()
                    .parse::<T>()
                    .map_err(|_| parse_error(self.file, &self.context(), name, format!("`{v}` is not a number")))
            })
            .transpose()
    }

    fn required_number<T: std::str::FromStr>(&self, name: &str) -> Result<T, SumoError> {
        self.number(name)?.ok_or_else(|| parse_error(self.file, &self.context(), name, "missing"))
    }

    /// A finite, non-negative length.
    fn length(&self, name: &str) -> Result<Option<f64>, SumoError> {
        match self.number::<f64>(name)? {
            Some(v) if !(v >= 0.0 && v.is_finite()) => {
                Err(parse_error(self.file, &self.context(), name, format!("{v} is not a finite non-negative number")))
            }
            v => Ok(v),
        }
    }

    fn shape(&self, name: &str) -> Result<Vec<[f64; 2]>, SumoError> {
        let text = self.required(name)?;
        let bad = |what: &str| parse_error(self.file, &self.context(), name, format!("{what} in `{text}`"));
        let mut points = Vec::new();
        for pair in text.split_whitespace() {
            let mut coords = pair.split(',').map(|c| c.parse::<f64>());
            match (coords.next(), coords.next()) {
                (Some(Ok(x)), Some(Ok(y))) if x.is_finite() && y.is_finite() => points.push([x, y]),
                _ => return Err(bad(&format!("`{pair}` is not `x,y`"))),
            }
        }
        if points.len() < 2 {
            return Err(bad("fewer than 2 points"));
        }
        Ok(points)
    }
}

impl Network {
    /// Reads the network in `path`.
    pub fn read(path: &Path) -> Result<Network, SumoError> {
        let text = std::fs::read_to_string(path)
            .map_err(SumoError::io(format!("reading the SUMO network {}", path.display())))?;
        Self::parse(&text, path)
    }

    /// Parses the text of a network; `path` names it in errors.
    pub fn parse(text: &str, path: &Path) -> Result<Network, SumoError> {
        let doc =
            roxmltree::Document::parse(text).map_err(|e| parse_error(path, "net", "", format!("not XML: {e}")))?;
        let root = doc.root_element();
        if root.tag_name().name() != "net" {
            return Err(parse_error(path, root.tag_name().name(), "", "the root element is not <net>"));
        }
        let mut net = Network {
            path: path.to_path_buf(),
            edges: Vec::new(),
            lanes: Vec::new(),
            connections: Vec::new(),
            junctions: Vec::new(),
            lane_index: HashMap::new(),
            edge_index: HashMap::new(),
            successors: Vec::new(),
            lane_boxes: Vec::new(),
        };
        for node in root.children().filter(roxmltree::Node::is_element) {
            let attrs = Attrs { file: path, node };
            match node.tag_name().name() {
                "edge" => net.read_edge(&attrs)?,
                "connection" => net.connections.push(read_connection(&attrs)?),
                "junction" => net.junctions.push(read_junction(&attrs)?),
                _ => {}
            }
        }
        net.link()?;
        Ok(net)
    }

    fn read_edge(&mut self, attrs: &Attrs<'_, '_>) -> Result<(), SumoError> {
        let id = attrs.required("id")?.to_owned();
        let function = match attrs.node.attribute("function").unwrap_or("normal") {
            "normal" => EdgeFunction::Normal,
            "internal" => EdgeFunction::Internal,
            "connector" => EdgeFunction::Connector,
            "crossing" => EdgeFunction::Crossing,
            "walkingarea" => EdgeFunction::WalkingArea,
            other => {
                return Err(parse_error(attrs.file, &attrs.context(), "function", format!("unknown `{other}`")));
            }
        };
        let mut edge = Edge {
            id: id.clone(),
            function,
            from: attrs.node.attribute("from").map(str::to_owned),
            to: attrs.node.attribute("to").map(str::to_owned),
            lanes: Vec::new(),
        };
        for node in attrs.node.children().filter(|n| n.has_tag_name("lane")) {
            let la = Attrs { file: attrs.file, node };
            let shape = la.shape("shape")?;
            let orig_id = node
                .children()
                .filter(|n| n.has_tag_name("param"))
                .find(|n| n.attribute("key") == Some("origId"))
                .and_then(|n| n.attribute("value"))
                .map(str::to_owned);
            let lane = Lane {
                id: la.required("id")?.to_owned(),
                edge_id: id.clone(),
                index: la.required_number("index")?,
                speed_mps: la.length("speed")?.unwrap_or(13.89),
                length_m: la.length("length")?.unwrap_or_else(|| geometry::length(&shape)),
                width_m: la.length("width")?.unwrap_or(DEFAULT_LANE_WIDTH_M),
                shape_length_m: geometry::length(&shape),
                shape,
                orig_id,
                internal: function == EdgeFunction::Internal,
            };
            if self.lane_index.insert(lane.id.clone(), self.lanes.len()).is_some() {
                return Err(parse_error(attrs.file, "lane", "id", format!("`{}` appears twice", lane.id)));
            }
            edge.lanes.push(lane.id.clone());
            self.lanes.push(lane);
        }
        if self.edge_index.insert(id.clone(), self.edges.len()).is_some() {
            return Err(parse_error(attrs.file, "edge", "id", format!("`{id}` appears twice")));
        }
        self.edges.push(edge);
        Ok(())
    }

    /// Resolves connections into lane successors and computes the lane boxes.
    fn link(&mut self) -> Result<(), SumoError> {
        let mut successors = vec![Vec::new(); self.lanes.len()];
        for c in &self.connections {
            let to = self.lane_on(&c.to_edge, c.to_lane);
            let via = c.via.as_ref().map(|via| self.lane_index.get(via).copied());
            let (Some(from), Some(_), Some(target)) = (self.lane_on(&c.from_edge, c.from_lane), to, via.unwrap_or(to))
            else {
                return Err(parse_error(
                    &self.path,
                    &format!("connection from=\"{}\" to=\"{}\"", c.from_edge, c.to_edge),
                    "fromLane/toLane/via",
                    format!(
                        "names a lane that does not exist (lanes {} → {}, via {:?})",
                        c.from_lane, c.to_lane, c.via
                    ),
                ));
            };
            if let Some(list) = successors.get_mut(from)
                && !list.contains(&target)
            {
                list.push(target);
            }
        }
        self.successors = successors;
        self.lane_boxes = self.lanes.iter().map(|l| bounds_of(&l.shape)).collect();
        Ok(())
    }

    /// The lane `index` of edge `edge`.
    fn lane_on(&self, edge: &str, index: u32) -> Option<usize> {
        let edge = self.edges.get(*self.edge_index.get(edge)?)?;
        let id = edge.lanes.iter().find(|id| self.lane(id).is_some_and(|l| l.index == index))?;
        self.lane_index.get(id).copied()
    }

    /// The lane with id `id`.
    pub fn lane(&self, id: &str) -> Option<&Lane> {
        self.lanes.get(*self.lane_index.get(id)?)
    }

    /// The edge with id `id`.
    pub fn edge(&self, id: &str) -> Option<&Edge> {
        self.edges.get(*self.edge_index.get(id)?)
    }

    /// The junction with id `id`.
    pub fn junction(&self, id: &str) -> Option<&Junction> {
        self.junctions.iter().find(|j| j.id == id)
    }

    pub(crate) fn lane_at(&self, index: usize) -> Option<&Lane> {
        self.lanes.get(index)
    }

    /// The lanes' positions in [`Network::lanes`] that lie on the same edge as lane `index`,
    /// `index` excluded.
    pub(crate) fn siblings(&self, index: usize) -> impl Iterator<Item = usize> + '_ {
        let edge = self.lanes.get(index).and_then(|l| self.edge(&l.edge_id));
        edge.into_iter()
            .flat_map(|e| e.lanes.iter())
            .filter_map(|id| self.lane_index.get(id).copied())
            .filter(move |&i| i != index)
    }

    /// Every lane within `max_dist_m` of `(x, y)` whose direction there is within
    /// [`MAX_HEADING_ERROR_RAD`] of `heading_rad`, as (position in [`Network::lanes`], projection).
    pub(crate) fn candidates(
        &self,
        p: [f64; 2],
        heading_rad: f64,
        max_dist_m: f64,
    ) -> Vec<(usize, geometry::Projection)> {
        let mut out = Vec::new();
        for (i, (lane, b)) in self.lanes.iter().zip(&self.lane_boxes).enumerate() {
            let outside = p[0] < b.min[0] - max_dist_m
                || p[0] > b.max[0] + max_dist_m
                || p[1] < b.min[1] - max_dist_m
                || p[1] > b.max[1] + max_dist_m;
            if outside {
                continue;
            }
            let Some(proj) = geometry::project(&lane.shape, p) else { continue };
            let heading_ok = geometry::wrap_angle(heading_rad - proj.heading).abs() <= MAX_HEADING_ERROR_RAD;
            if proj.lateral.abs() <= max_dist_m && heading_ok {
                out.push((i, proj));
            }
        }
        out
    }

    /// The nearest lane to `(x, y)` of any heading and its distance, if the network has lanes.
    pub(crate) fn nearest_any(&self, p: [f64; 2]) -> Option<(&Lane, f64)> {
        self.lanes
            .iter()
            .filter_map(|l| Some((l, geometry::project(&l.shape, p)?.lateral.abs())))
            .min_by(|a, b| a.1.total_cmp(&b.1))
    }

    /// The nearest lane within `max_dist_m` of `(x, y)` that runs within 60° of `heading_rad`
    /// (radians, 0 = east, counter-clockwise), internal lanes included; `None` when there is none.
    pub fn nearest_lane(&self, x: f64, y: f64, heading_rad: f64, max_dist_m: f64) -> Option<LanePos> {
        let (i, proj) = self
            .candidates([x, y], heading_rad, max_dist_m)
            .into_iter()
            .min_by(|a, b| a.1.lateral.abs().total_cmp(&b.1.lateral.abs()))?;
        Some(LanePos {
            lane_id: self.lanes.get(i)?.id.clone(),
            s_m: proj.s,
            lateral_m: proj.lateral,
            heading_err: geometry::wrap_angle(heading_rad - proj.heading),
        })
    }

    /// The box around every lane shape; all zeros for a network without lanes.
    pub fn bounds(&self) -> Bounds {
        let mut it = self.lane_boxes.iter();
        let Some(first) = it.next() else { return Bounds { min: [0.0; 2], max: [0.0; 2] } };
        it.fold(*first, |acc, b| Bounds {
            min: [acc.min[0].min(b.min[0]), acc.min[1].min(b.min[1])],
            max: [acc.max[0].max(b.max[0]), acc.max[1].max(b.max[1])],
        })
    }
}

fn bounds_of(shape: &[[f64; 2]]) -> Bounds {
    let mut b = Bounds { min: [f64::INFINITY; 2], max: [f64::NEG_INFINITY; 2] };
    for p in shape {
        b.min = [b.min[0].min(p[0]), b.min[1].min(p[1])];
        b.max = [b.max[0].max(p[0]), b.max[1].max(p[1])];
    }
    b
}

fn read_connection(attrs: &Attrs<'_, '_>) -> Result<Connection, SumoError> {
    Ok(Connection {
        from_edge: attrs.required("from")?.to_owned(),
        to_edge: attrs.required("to")?.to_owned(),
        from_lane: attrs.required_number("fromLane")?,
        to_lane: attrs.required_number("toLane")?,
        via: attrs.node.attribute("via").map(str::to_owned),
    })
}

fn read_junction(attrs: &Attrs<'_, '_>) -> Result<Junction, SumoError> {
    Ok(Junction {
        id: attrs.required("id")?.to_owned(),
        kind: attrs.node.attribute("type").unwrap_or("").to_owned(),
        position: [attrs.required_number("x")?, attrs.required_number("y")?],
        internal_lanes: attrs
            .node
            .attribute("intLanes")
            .map(|v| v.split_whitespace().map(str::to_owned).collect())
            .unwrap_or_default(),
    })
}

#[cfg(test)]
mod tests;
