//! `video2track export xosc`: the file shell around [`crate::xosc`]. Reads the input and the two vehicle
//! files, writes the map's path relative to the output file's folder (the OpenSCENARIO checker and
//! simulators resolve `LogicFile` from there), takes the date from the clock (or from
//! `SOURCE_DATE_EPOCH`, for reproducible files) and writes the file.

use std::path::{Component, Path, PathBuf};

use v2t_files::{InputError, load_toml};
use v2t_model::vehicle::VehicleConfig;

use crate::xosc::{ExportScenario, XoscError, XoscOptions, iso_date_time, parse_input, to_xosc};

/// Why an export failed.
#[derive(Debug, thiserror::Error)]
pub enum ExportError {
    /// The input file is not a prior, a grounded scenario or a run.
    #[error("{path}: {source}")]
    Input {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        source: XoscError,
    },
    /// The input or a vehicle file cannot be read, or a vehicle file is bad.
    #[error(transparent)]
    File(#[from] InputError),
    /// The map does not exist.
    #[error("{path}: cannot use as the map: {error}")]
    Map {
        /// The map.
        path: PathBuf,
        /// Why.
        error: std::io::Error,
    },
    /// The output could not be written.
    #[error("writing {path}: {error}")]
    Write {
        /// The file.
        path: PathBuf,
        /// Why.
        error: std::io::Error,
    },
}

impl ExportError {
    /// Whether the user's input is at fault (input, vehicle files, map), as opposed to the output.
    pub fn is_input(&self) -> bool {
        !matches!(self, Self::Write { .. })
    }
}

/// What `export xosc` is given.
#[derive(Debug, Clone)]
pub struct XoscArgs<'a> {
    /// A prior, a grounded scenario or a run (JSON).
    pub input: &'a Path,
    /// The `.xosc` to write.
    pub out: &'a Path,
    /// The map (.xodr) the file names.
    pub map: &'a Path,
    /// The VUT's vehicle file.
    pub vut_vehicle: &'a Path,
    /// The BVs' vehicle file.
    pub bv_vehicle: &'a Path,
}

/// What was written.
#[derive(Debug, Clone)]
pub struct Exported {
    /// The scenario as exported.
    pub scenario: ExportScenario,
    /// The `LogicFile` path as written.
    pub map_path: String,
}

/// Exports `args.input` to `args.out`.
pub fn export_xosc(args: &XoscArgs<'_>) -> Result<Exported, ExportError> {
    // A prior, a grounded scenario or a run file: the largest of their bounds.
    let text = v2t_files::read_text_within(args.input, v2t_files::bounds::RUN)?;
    let scenario = parse_input(&text).map_err(|source| ExportError::Input { path: args.input.to_owned(), source })?;
    let vut_vehicle: VehicleConfig = load_toml(args.vut_vehicle)?;
    let bv_vehicle: VehicleConfig = load_toml(args.bv_vehicle)?;
    let map = args.map.canonicalize().map_err(|error| ExportError::Map { path: args.map.to_owned(), error })?;
    let out_dir = match args.out.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_owned(),
        _ => PathBuf::from("."),
    };
    let out_dir = out_dir.canonicalize().map_err(|error| ExportError::Write { path: args.out.to_owned(), error })?;
    let map_path = relative_path(&out_dir, &map).display().to_string();
    let date = iso_date_time(date_unix_s());
    let source =
        args.input.file_name().map_or_else(|| args.input.display().to_string(), |n| n.to_string_lossy().into_owned());
    let opts = XoscOptions {
        source: &source,
        map_path: &map_path,
        date: &date,
        vut_vehicle: &vut_vehicle,
        bv_vehicle: &bv_vehicle,
    };
    let xml = to_xosc(&scenario, &opts);
    std::fs::write(args.out, xml).map_err(|error| ExportError::Write { path: args.out.to_owned(), error })?;
    Ok(Exported { scenario, map_path })
}

/// `SOURCE_DATE_EPOCH` when set, else now, s since 1970.
fn date_unix_s() -> u64 {
    std::env::var("SOURCE_DATE_EPOCH").ok().and_then(|s| s.trim().parse().ok()).unwrap_or_else(|| {
        std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map_or(0, |d| d.as_secs())
    })
}

/// `to` written relative to the folder `from_dir` (both absolute and without `..`); `to` itself
/// when they share no root (another drive).
pub fn relative_path(from_dir: &Path, to: &Path) -> PathBuf {
    let from: Vec<Component<'_>> = from_dir.components().collect();
    let target: Vec<Component<'_>> = to.components().collect();
    let common = from.iter().zip(&target).take_while(|(a, b)| a == b).count();
    if common == 0 {
        return to.to_owned();
    }
    let mut rel = PathBuf::new();
    for _ in common..from.len() {
        rel.push("..");
    }
    for c in target.iter().skip(common) {
        rel.push(c.as_os_str());
    }
    rel
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn relative_paths_climb_to_the_common_folder() {
        let rel = |a: &str, b: &str| relative_path(Path::new(a), Path::new(b)).display().to_string();
        assert_eq!(rel("/w/repo/target", "/w/repo/config/maps/pg.xodr"), "../config/maps/pg.xodr");
        assert_eq!(rel("/w/repo", "/w/repo/config/maps/pg.xodr"), "config/maps/pg.xodr");
        assert_eq!(rel("/tmp/a/b", "/w/pg.xodr"), "../../../w/pg.xodr");
        assert_eq!(rel("/w/maps", "/w/maps/pg.xodr"), "pg.xodr");
    }
}
