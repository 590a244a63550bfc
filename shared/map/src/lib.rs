//! OpenDRIVE maps for Video2Track: the parser, the lane graph and the topology library.
//!
//! A proving ground's `.xodr` is read into plain data ([`xodr`]), every lane becomes a centreline
//! polyline with boundaries, marks and links ([`graph`]), and the map is cut into fragments where
//! interactions happen — intersections, multi-lane segments, merges — with anchors that grounding
//! pins a scenario to ([`library`]). Nothing here does IO except [`Map::load`] and [`inspect()`] (a
//! map with its library and its hand annotations, ready for grounding).
//!
//! ```
//! let xodr = r#"<OpenDRIVE><header revMajor="1" revMinor="6"/>
//!   <road id="1" length="100" junction="-1">
//!     <planView><geometry s="0" x="0" y="0" hdg="0" length="100"><line/></geometry></planView>
//!     <lanes><laneSection s="0">
//!       <center><lane id="0" type="none"/></center>
//!       <right>
//!         <lane id="-1" type="driving"><width sOffset="0" a="3.5" b="0" c="0" d="0"/></lane>
//!         <lane id="-2" type="driving"><width sOffset="0" a="3.5" b="0" c="0" d="0"/></lane>
//!       </right>
//!     </laneSection></lanes>
//!   </road></OpenDRIVE>"#;
//! let map = v2t_map::Map::parse(xodr, "doc").unwrap();
//! let lib = v2t_map::library::TopologyLibrary::build(&map);
//! assert_eq!(lib.of_kind(v2t_map::library::FragmentKind::MultiLaneSegment).count(), 1);
//! ```

pub mod annotate;
pub mod boundaries;
pub mod drivable;
pub mod error;
pub mod geometry;
pub mod graph;
pub mod inspect;
pub mod junction;
pub mod library;
pub mod svg;
pub mod xodr;

use std::path::Path;

pub use error::{MapError, MapWarning};
pub use inspect::{Inspection, inspect};

/// How far outside a map's lanes a scenario's coordinates may lie, m ([`Map::check_scenario`]).
pub const EXTENT_MARGIN_M: f64 = 500.0;

/// A parsed map with its lane graph.
#[derive(Debug, Clone)]
pub struct Map {
    /// Name: the header's, or the file stem.
    pub name: String,
    /// The OpenDRIVE data.
    pub document: xodr::Document,
    /// The lane graph.
    pub graph: graph::LaneGraph,
    /// What was left out or looks wrong.
    pub warnings: Vec<MapWarning>,
}

impl Map {
    /// Parses OpenDRIVE XML; `name` is used when the header has none. A map with no drivable lane
    /// left is an error (with the first warnings that say why).
    pub fn parse(xml: &str, name: &str) -> Result<Self, MapError> {
        let (document, mut warnings) = xodr::parse(xml)?;
        let graph = graph::LaneGraph::build(&document, &mut warnings);
        if !graph.lanes.iter().any(|l| l.drivable) {
            let shown: Vec<String> = warnings.iter().take(3).map(ToString::to_string).collect();
            return Err(MapError::Invalid {
                context: "map".into(),
                message: format!(
                    "no drivable lane (a lane is drivable when its type is driven on and it is at least 1 m wide); \
                     {} warning(s){}{}",
                    warnings.len(),
                    if shown.is_empty() { "" } else { ": " },
                    shown.join("; ")
                ),
            });
        }
        let name = if document.name.trim().is_empty() { name.to_owned() } else { document.name.clone() };
        Ok(Self { name, document, graph, warnings })
    }

    /// The smallest axis-aligned box holding every lane's outline, `(min, max)`; `None` for a map
    /// without lanes.
    pub fn extent(&self) -> Option<(v2t_model::geometry::Point2, v2t_model::geometry::Point2)> {
        use v2t_model::geometry::Point2;
        let mut points = self.graph.lanes.iter().flat_map(|l| l.samples.iter()).flat_map(|q| [q.left, q.right]);
        let first = points.next()?;
        Some(points.fold((first, first), |(lo, hi), p| {
            (Point2 { x: lo.x.min(p.x), y: lo.y.min(p.y) }, Point2 { x: hi.x.max(p.x), y: hi.y.max(p.y) })
        }))
    }

    /// Checks that a grounded scenario lies on this map: every route point, anchor and conflict
    /// point within the map's [`extent`](Self::extent) plus [`EXTENT_MARGIN_M`]. A scenario for
    /// another map, or a hand-edited one, is refused here with the first point outside, before any
    /// loop runs along its routes.
    pub fn check_scenario(&self, g: &v2t_model::grounded::GroundedScenario) -> Result<(), MapError> {
        let Some((lo, hi)) = self.extent() else {
            return Err(MapError::Invalid { context: self.name.clone(), message: "the map has no lanes".into() });
        };
        let m = EXTENT_MARGIN_M;
        let inside =
            |p: v2t_model::geometry::Point2| p.x >= lo.x - m && p.x <= hi.x + m && p.y >= lo.y - m && p.y <= hi.y + m;
        // The first point outside, named only when there is one (routes hold up to 200,000 points).
        let outside = g.agents.iter().enumerate().find_map(|(i, a)| {
            let at =
                |what: &str, p: v2t_model::geometry::Point2| (!inside(p)).then(|| (format!("agents[{i}].{what}"), p));
            at("start.position", a.start.position).or_else(|| at("goal.position", a.goal.position)).or_else(|| {
                let (k, p) = a.route.iter().enumerate().find(|(_, p)| !inside(**p))?;
                Some((format!("agents[{i}].route[{k}]"), *p))
            })
        });
        let outside = outside.or_else(|| {
            let (i, c) = g.conflicts.iter().enumerate().find(|(_, c)| !inside(c.point))?;
            Some((format!("conflicts[{i}].point"), c.point))
        });
        match outside {
            None => Ok(()),
            Some((field, p)) => Err(MapError::Invalid {
                context: format!("the scenario on map `{}`", self.name),
                message: format!(
                    "field `{field}` = ({:.1}, {:.1}) lies more than {m} m outside the map's lanes \
                     (x {:.1} to {:.1}, y {:.1} to {:.1})",
                    p.x, p.y, lo.x, hi.x, lo.y, hi.y
                ),
            }),
        }
    }

    /// Reads and parses an `.xodr` file; every error names the file.
    pub fn load(path: &Path) -> Result<Self, MapError> {
        let xml = v2t_files::bounds::read_text_within(path, v2t_files::bounds::MAP)
            .map_err(|source| MapError::Io { path: path.display().to_string(), source })?;
        let stem = path.file_stem().map_or_else(|| "map".to_owned(), |s| s.to_string_lossy().into_owned());
        Self::parse(&xml, &stem)
            .map_err(|error| MapError::File { path: path.display().to_string(), error: Box::new(error) })
    }
}
