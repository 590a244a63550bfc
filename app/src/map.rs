//! `video2track map inspect`: parse a proving ground's OpenDRIVE map, build its topology library
//! and report what is in it (fragments by kind, anchors, warnings, parse and build time).

use std::path::{Path, PathBuf};

use serde::Serialize;
use v2t_files::{out, outln};
use v2t_map::Inspection;
use v2t_map::library::{AnchorKind, FragmentKind, TopologyLibrary};

/// `map`'s commands.
#[derive(Debug, clap::Subcommand)]
pub enum MapCommand {
    /// Parse an OpenDRIVE map, build its topology library and report fragments, anchors and timings.
    Inspect {
        /// The map (.xodr).
        map: PathBuf,
        /// Write the topology library (fragments, anchors, maneuver paths) as JSON here.
        #[arg(long)]
        json: Option<PathBuf>,
        /// Draw lanes, marks, fragments and anchors as SVG here.
        #[arg(long)]
        svg: Option<PathBuf>,
        /// Hand annotations (TOML; default: the map's name with .toml, when it exists).
        #[arg(long)]
        annotations: Option<PathBuf>,
    },
}

/// Runs a `map` command.
pub fn run(command: MapCommand) -> anyhow::Result<()> {
    use anyhow::Context as _;
    let MapCommand::Inspect { map, json: json_out, svg, annotations } = command;
    let inspection = v2t_map::inspect(&map, annotations.as_deref())?;
    out!("{}", report(&map, &inspection))?;
    if let Some(path) = json_out {
        crate::write_json(&path, &json(&map, &inspection))?;
    }
    if let Some(path) = svg {
        let text = v2t_map::svg::render(&inspection.map, &inspection.library);
        std::fs::write(&path, text).with_context(|| format!("writing {}", path.display()))?;
        outln!("wrote {}", path.display())?;
    }
    Ok(())
}

/// What `--json` writes: the library with the map's warnings and timings.
#[derive(Debug, Serialize)]
struct InspectJson<'a> {
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

/// The `--json` document.
fn json<'a>(file: &Path, i: &'a Inspection) -> InspectJson<'a> {
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
fn report(file: &Path, i: &Inspection) -> String {
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
