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
pub mod library;
pub mod svg;
pub mod xodr;

use std::path::Path;

pub use error::{MapError, MapWarning};
pub use inspect::{Inspection, inspect};

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
    /// Parses OpenDRIVE XML; `name` is used when the header has none.
    pub fn parse(xml: &str, name: &str) -> Result<Self, MapError> {
        let (document, mut warnings) = xodr::parse(xml)?;
        let graph = graph::LaneGraph::build(&document, &mut warnings);
        let name = if document.name.trim().is_empty() { name.to_owned() } else { document.name.clone() };
        Ok(Self { name, document, graph, warnings })
    }

    /// Reads and parses an `.xodr` file.
    pub fn load(path: &Path) -> Result<Self, MapError> {
        let xml = std::fs::read_to_string(path)
            .map_err(|source| MapError::Io { path: path.display().to_string(), source })?;
        let stem = path.file_stem().map_or_else(|| "map".to_owned(), |s| s.to_string_lossy().into_owned());
        Self::parse(&xml, &stem)
    }
}
