//! # v2t-files — the project's files, read into checked types
//!
//! Every binary reads the same kinds of files: TOML configuration (vehicles, regulator, tracker,
//! gate, simulation settings, scenario cards, the onboard runtime) and JSON documents that one
//! stage writes and the next reads (scenario semantics, grounded scenarios, trajectory priors).
//! This crate is the one place that turns their text into the typed, validated values of
//! `v2t-model` and the other crates, so that a bad file gives the same kind of error everywhere:
//! the file, the line and column where the parser stopped, the field and the bound it broke.
//!
//! Parsing is pure ([`parse_toml`] takes text); [`load_toml`] and the `read_*` functions add the
//! file read. Paths written inside a file are relative to that file ([`relative_to`]).
//!
//! ```
//! use v2t_files::parse_toml;
//! use v2t_model::vehicle::VehicleConfig;
//!
//! let text = include_str!("../../../config/vehicles/bv_sedan.toml");
//! let bv: VehicleConfig = parse_toml(text, "bv_sedan.toml").unwrap();
//! assert!(bv.limits.max_speed_mps > 0.0);
//! let bad = parse_toml::<VehicleConfig>(&text.replace("max_speed_mps =", "max_speed_mps = nan #"), "x.toml");
//! assert!(bad.unwrap_err().to_string().contains("max_speed_mps"));
//! ```

pub mod bounds;
mod documents;
pub mod stdout;

/// An error and its causes as one line, `outer: cause: cause`, for a binary's last words: a cause
/// whose text its parent already shows (an error that prints its source) is not repeated.
pub fn error_chain(err: &(dyn std::error::Error + 'static)) -> String {
    let mut line = err.to_string();
    let mut shown = line.clone();
    let mut cause = err.source();
    while let Some(c) = cause {
        let text = c.to_string();
        if !shown.contains(&text) {
            line.push_str(": ");
            line.push_str(&text);
        }
        shown = text;
        cause = c.source();
    }
    line
}

use std::path::{Path, PathBuf};

use serde::de::DeserializeOwned;
use v2t_model::validate::{Validate, ValidationError};

pub use documents::{
    DocumentError, DocumentKeys, PriorDocument, human_reference_or_shipped, prior_document, read_grounded,
    read_human_reference, read_prior, read_prior_or_grounded, read_semantics,
};

/// Where the shipped files live, relative to the repository root: the defaults of the commands.
pub mod shipped {
    /// The proving ground's map.
    pub const MAP: &str = "config/maps/proving_ground.xodr";
    /// The diffusion model's weights.
    pub const WEIGHTS: &str = "config/diffusion/denoiser.safetensors";
    /// Regulator settings.
    pub const REGULATOR: &str = "config/regulator/default.toml";
    /// Simulation settings (noise, delays, actuator lag).
    pub const SIM: &str = "config/sim/default.toml";
    /// The VUT's vehicle.
    pub const VUT_VEHICLE: &str = "config/vehicles/vut_sedan.toml";
    /// The BV's vehicle.
    pub const BV_VEHICLE: &str = "config/vehicles/bv_sedan.toml";
    /// Human driving per manoeuvre class, what a run's realism is measured against.
    pub const HUMAN_REFERENCE: &str = "config/realism/human_reference.json";
    /// One BV's onboard runtime.
    pub const EDGE: &str = "config/edge/bv1.toml";
    /// The scenario cards: the unprotected left turn with the BV turning, the same junction with the
    /// VUT turning, and the cut-in.
    pub const CARDS: [&str; 3] = [
        "config/scenarios/left_turn_basic.toml",
        "config/scenarios/left_turn_vut.toml",
        "config/scenarios/cut_in_basic.toml",
    ];
    /// The network presets between the track and the cloud: a 5G standalone cell, LTE, a
    /// congested cell.
    pub const NETWORKS: [&str; 3] =
        ["config/network/5g_sa.toml", "config/network/lte.toml", "config/network/congested.toml"];
    /// The network the TroubleMaker-like baseline runs its cloud regulator across.
    pub const BASELINE_NETWORK: &str = "config/network/5g_sa.toml";
}

/// A configuration text that did not parse or did not validate.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ConfigError {
    /// TOML syntax, a missing or unknown field, a wrong type.
    #[error("{origin}: {message}")]
    Parse {
        /// The file (or other origin) of the text.
        origin: String,
        /// The parser's message (names the line, column and key).
        message: String,
    },
    /// Parsed, but a value is out of range.
    #[error("{origin}: {source}")]
    Invalid {
        /// The file (or other origin) of the text.
        origin: String,
        /// The field and the problem.
        source: ValidationError,
    },
}

/// Bad input: a file that cannot be read, parsed or validated. Commands exit with code 2 on it.
#[derive(Debug, thiserror::Error)]
pub enum InputError {
    /// The file could not be read.
    #[error("{path}: cannot read: {source}")]
    Read {
        /// The file.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// A TOML file did not parse or validate.
    #[error(transparent)]
    Config(#[from] ConfigError),
    /// A JSON document is not what was expected, or does not validate.
    #[error("{path}: {source}")]
    Document {
        /// The file.
        path: PathBuf,
        /// What is wrong, and where (line and column, or the field).
        source: DocumentError,
    },
}

/// Parses TOML text into `T` and validates it. `origin` (usually the file path) prefixes every error.
pub fn parse_toml<T: DeserializeOwned + Validate>(text: &str, origin: &str) -> Result<T, ConfigError> {
    let value: T = toml::from_str(text)
        .map_err(|e| ConfigError::Parse { origin: origin.to_owned(), message: e.to_string().trim_end().to_owned() })?;
    value.validate().map_err(|source| ConfigError::Invalid { origin: origin.to_owned(), source })?;
    Ok(value)
}

/// Reads the text of `path`, refused unread when it is larger than `bound` allows.
pub fn read_text_within(path: &Path, bound: bounds::SizeBound) -> Result<String, InputError> {
    bounds::read_text_within(path, bound).map_err(|source| InputError::Read { path: path.to_owned(), source })
}

/// Reads the text of a JSON document at `path` of any kind this crate reads (at most
/// [`bounds::GROUNDED`], the largest document bound).
pub fn read_text(path: &Path) -> Result<String, InputError> {
    read_text_within(path, bounds::GROUNDED)
}

/// Reads and validates a TOML file into `T` (at most [`bounds::CONFIG`]).
pub fn load_toml<T: DeserializeOwned + Validate>(path: &Path) -> Result<T, InputError> {
    Ok(parse_toml(&read_text_within(path, bounds::CONFIG)?, &path.display().to_string())?)
}

/// A path written in `file`, resolved relative to `file`'s folder.
pub fn relative_to(file: &Path, written: &str) -> PathBuf {
    file.parent().unwrap_or_else(|| Path::new(".")).join(written)
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use v2t_model::validate::in_range;

    #[derive(Debug, serde::Deserialize)]
    #[serde(deny_unknown_fields)]
    struct Settings {
        dt_s: f64,
    }

    impl Validate for Settings {
        fn validate(&self) -> Result<(), ValidationError> {
            in_range("dt_s", self.dt_s, 1e-4, 0.1)
        }
    }

    #[test]
    fn errors_name_the_file_the_field_and_the_problem() {
        let unknown = parse_toml::<Settings>("dt_s = 0.01\ncolour = 3\n", "a.toml").unwrap_err();
        let text = unknown.to_string();
        assert!(text.starts_with("a.toml: ") && text.contains("colour"), "{text}");
        let nan = parse_toml::<Settings>("dt_s = nan", "b.toml").unwrap_err();
        assert!(matches!(&nan, ConfigError::Invalid { source, .. } if source.field == "dt_s"), "{nan}");
        assert!(matches!(parse_toml::<Settings>("dt_s = [", "c.toml").unwrap_err(), ConfigError::Parse { .. }));
        let missing = load_toml::<Settings>(Path::new("/nonexistent/d.toml")).unwrap_err();
        assert!(matches!(missing, InputError::Read { .. }) && missing.to_string().contains("d.toml"));
    }

    #[test]
    fn paths_in_a_file_are_relative_to_it() {
        assert_eq!(
            relative_to(Path::new("config/edge/bv1.toml"), "../can/gate.toml"),
            Path::new("config/edge/../can/gate.toml")
        );
        assert_eq!(relative_to(Path::new("bv1.toml"), "x.toml"), Path::new("x.toml"));
    }
}
