//! Loading a scenario card and the files it names (settings, vehicles) into a runnable scenario.

use std::path::{Path, PathBuf};

use v2t_files::{load_toml, relative_to};
use v2t_model::vehicle::VehicleConfig;

use crate::config::{ScenarioCard, SimSettings};
use crate::scenario::{Scenario, ScenarioError};

pub use v2t_files::InputError;

/// A scenario card that cannot be run: a file that does not read, parse or validate, or a card
/// that is valid on its own but makes no runnable scenario.
#[derive(Debug, thiserror::Error)]
pub enum CardError {
    /// The card or a file it names.
    #[error(transparent)]
    Input(#[from] InputError),
    /// The card is valid on its own but does not make a runnable scenario.
    #[error("{path}: {source}")]
    Scenario {
        /// The card.
        path: PathBuf,
        /// Why.
        source: ScenarioError,
    },
}

/// Loads a scenario card and everything it names (settings, vehicles) and builds the scenario.
pub fn load_scenario(card_path: &Path) -> Result<Scenario, CardError> {
    let card: ScenarioCard = load_toml(card_path)?;
    let settings: SimSettings = load_toml(&relative_to(card_path, &card.sim))?;
    let vut: VehicleConfig = load_toml(&relative_to(card_path, &card.vut.vehicle))?;
    let bvs = card
        .bvs
        .iter()
        .map(|b| load_toml::<VehicleConfig>(&relative_to(card_path, &b.vehicle)))
        .collect::<Result<Vec<_>, _>>()?;
    Scenario::from_card(&card, settings, vut, bvs)
        .map_err(|source| CardError::Scenario { path: card_path.to_owned(), source })
}
