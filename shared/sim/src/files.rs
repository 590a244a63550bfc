//! Loading configuration files: the file IO the pure crates leave to their callers. Every error
//! names the file; TOML errors also name the line, column and key, validation errors the field.

use std::path::{Path, PathBuf};

use crate::config::{ConfigError, ScenarioCard, SimSettings, parse_toml};
use crate::scenario::{Scenario, ScenarioError};
use serde::de::DeserializeOwned;
use v2t_model::validate::Validate;
use v2t_model::vehicle::VehicleConfig;

/// Bad input: a file that cannot be read, parsed, validated or turned into a scenario.
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
    /// The file did not parse or validate.
    #[error(transparent)]
    Config(#[from] ConfigError),
    /// The card is valid on its own but does not make a runnable scenario.
    #[error("{path}: {source}")]
    Scenario {
        /// The card.
        path: PathBuf,
        /// Why.
        source: ScenarioError,
    },
}

/// Reads and validates a TOML file into `T`.
pub fn load_toml<T: DeserializeOwned + Validate>(path: &Path) -> Result<T, InputError> {
    let text = std::fs::read_to_string(path).map_err(|source| InputError::Read { path: path.to_owned(), source })?;
    Ok(parse_toml(&text, &path.display().to_string())?)
}

/// A path written in `file`, resolved relative to `file`'s folder.
pub fn relative_to(file: &Path, written: &str) -> PathBuf {
    file.parent().unwrap_or_else(|| Path::new(".")).join(written)
}

/// Loads a scenario card and everything it names (settings, vehicles) and builds the scenario.
pub fn load_scenario(card_path: &Path) -> Result<Scenario, InputError> {
    let card: ScenarioCard = load_toml(card_path)?;
    let settings: SimSettings = load_toml(&relative_to(card_path, &card.sim))?;
    let vut: VehicleConfig = load_toml(&relative_to(card_path, &card.vut.vehicle))?;
    let bvs = card
        .bvs
        .iter()
        .map(|b| load_toml::<VehicleConfig>(&relative_to(card_path, &b.vehicle)))
        .collect::<Result<Vec<_>, _>>()?;
    Scenario::from_card(&card, settings, vut, bvs)
        .map_err(|source| InputError::Scenario { path: card_path.to_owned(), source })
}
