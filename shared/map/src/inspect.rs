//! A map loaded for use: parsed, its topology library built and its hand annotations applied.

use std::path::Path;
use std::time::{Duration, Instant};

use crate::annotate::Annotations;
use crate::library::TopologyLibrary;
use crate::{Map, MapError};

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
        let text = v2t_files::bounds::read_text_within(&p, v2t_files::bounds::CONFIG)
            .map_err(|source| MapError::Io { path: p.display().to_string(), source })?;
        library.annotate(&Annotations::parse(&text, &p.display().to_string())?)?;
        applied = Some(p.display().to_string());
    }
    Ok(Inspection { map, library, parse, build, annotations: applied })
}
