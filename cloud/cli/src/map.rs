//! `video2track map inspect`: parse a proving ground's OpenDRIVE map, build its topology library
//! and report what is in it (fragments by kind, anchors, warnings, parse and build time).

use std::path::Path;
use std::time::{Duration, Instant};

use serde::Serialize;
use v2t_map::annotate::Annotations;
use v2t_map::library::{AnchorKind, FragmentKind, TopologyLibrary};
use v2t_map::{Map, MapError};

/// A map, its library and how long they took.
#[derive(Debug)]
pub struct Inspection {
    /// The map.
    pub map: Map,
    /// Its fragments.
    pub library: TopologyLibrary,
    /// Reading and parsing the file, lane graph included.
    pub parse: Duration,
    /// Building the library.
    pub build: Duration,
    /// The annotations applied, if a TOML was found or given.
    pub annotations: Option<String>,
}

/// What `--json` writes: the library with the map's warnings and timings.
#[derive(Debug, Serialize)]
pub struct InspectJson<'a> {
    /// Map file.
    pub file: String,
    /// OpenDRIVE revision.
    pub revision: String,
    /// geoReference, kept verbatim.
    pub geo_reference: Option<&'a str>,
    /// Parse time, ms.
    pub parse_ms: f64,
    /// Library build time, ms.
    pub build_ms: f64,
    /// Warnings.
    pub warnings: Vec<String>,
    /// The topology library.
    pub library: &'a TopologyLibrary,
}

/// Loads `path`, builds the library and applies annotations (`annotations`, or `<map>.toml`
/// beside the map when it exists).
pub fn inspect(path: &Path, annotations: Option<&Path>) -> Result<Inspection, MapError> {
    let t0 = Instant::now();
    let map = Map::load(path)?;
    let parse = t0.elapsed();
    let t1 = Instant::now();
    let mut library = TopologyLibrary::build(&map);
    let build = t1.elapsed();
    let beside = path.with_extension("toml");
    let notes_path = annotations.map(Path::to_path_buf).or_else(|| beside.exists().then_some(beside));
    let mut applied = None;
    if let Some(p) = notes_path {
        let text =
            std::fs::read_to_string(&p).map_err(|source| MapError::Io { path: p.display().to_string(), source })?;
        library.annotate(&Annotations::parse(&text, &p.display().to_string())?)?;
        applied = Some(p.display().to_string());
    }
    Ok(Inspection { map, library, parse, build, annotations: applied })
}

/// The `--json` document.
pub fn json<'a>(file: &Path, i: &'a Inspection) -> InspectJson<'a> {
    InspectJson {
        file: file.display().to_string(),
        revision: format!("{}.{}", i.map.document.revision.0, i.map.document.revision.1),
        geo_reference: i.map.document.geo_reference.as_deref(),
        parse_ms: i.parse.as_secs_f64() * 1e3,
        build_ms: i.build.as_secs_f64() * 1e3,
        warnings: i.map.warnings.iter().map(ToString::to_string).collect(),
        library: &i.library,
    }
}

/// The human-readable report.
pub fn report(file: &Path, i: &Inspection) -> String {
    use std::fmt::Write;
    let m = &i.map;
    let lib = &i.library;
    let mut s = String::new();
    let _ = writeln!(
        s,
        "{} (OpenDRIVE {}.{}, \"{}\"): {} roads, {} junctions, {} lanes ({} drivable), {} lane links",
        file.display(),
        m.document.revision.0,
        m.document.revision.1,
        m.name,
        m.document.roads.len(),
        m.document.junctions.len(),
        m.graph.lanes.len(),
        m.graph.lanes.iter().filter(|l| l.drivable).count(),
        m.graph.links.len()
    );
    if let Some(g) = &m.document.geo_reference {
        let _ = writeln!(s, "geoReference: {g}");
    }
    let worst = m.graph.links.iter().map(|l| l.gap_m).fold(0.0, f64::max);
    let _ = writeln!(s, "largest centreline gap across a link: {:.2} mm", worst * 1e3);
    let _ = writeln!(
        s,
        "parse {:.2} ms, library {:.2} ms{}",
        i.parse.as_secs_f64() * 1e3,
        i.build.as_secs_f64() * 1e3,
        i.annotations.as_ref().map_or(String::new(), |a| format!(", annotations {a}"))
    );
    let count = |k| lib.of_kind(k).count();
    let anchors = |k| lib.fragments.iter().flat_map(|f| &f.anchors).filter(|a| a.kind == k).count();
    let _ = writeln!(
        s,
        "fragments: {} intersections, {} multi-lane segments, {} merges; anchors: {} entry, {} exit, {} conflict, {} merge, {} cut-in",
        count(FragmentKind::Intersection),
        count(FragmentKind::MultiLaneSegment),
        count(FragmentKind::Merge),
        anchors(AnchorKind::Entry),
        anchors(AnchorKind::Exit),
        anchors(AnchorKind::Conflict),
        anchors(AnchorKind::Merge),
        anchors(AnchorKind::CutIn),
    );
    for f in &lib.fragments {
        let _ = writeln!(
            s,
            "  {:<24} {:>3} maneuvers {:>4} anchors  {}",
            f.id,
            f.maneuvers.len(),
            f.anchors.len(),
            f.description
        );
    }
    for w in &m.warnings {
        let _ = writeln!(s, "warning: {w}");
    }
    s
}
