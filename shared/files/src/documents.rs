//! The JSON documents one stage writes and the next reads: scenario semantics (`abstract`),
//! grounded scenarios (`ground`) and trajectory priors (`generate`). Each is parsed, validated and
//! refused with the file named, before anything uses it.

use std::path::Path;

use serde::de::DeserializeOwned;
use v2t_model::grounded::GroundedScenario;
use v2t_model::prior::TrajectoryPrior;
use v2t_model::realism::{HumanReference, ReferenceError};
use v2t_model::semantics::{ScenarioSemantics, SemanticsError, parse_semantics_json};
use v2t_model::validate::{Validate, ValidationError};

use crate::bounds::{self, SizeBound};
use crate::{InputError, read_text, read_text_within};

/// A JSON document that is not the one expected.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum DocumentError {
    /// Not JSON at all.
    #[error("not JSON: {0}")]
    NotJson(String),
    /// JSON of another shape (a missing or unknown field, a wrong type).
    #[error("not {what}: {message}")]
    Shape {
        /// What was expected.
        what: &'static str,
        /// The parser's message (line and column).
        message: String,
    },
    /// The right shape, but a value out of range.
    #[error(transparent)]
    Invalid(#[from] ValidationError),
    /// Semantics that do not parse or validate.
    #[error(transparent)]
    Semantics(#[from] SemanticsError),
    /// None of the document kinds that are accepted here.
    #[error("neither {0}")]
    Unknown(&'static str),
}

fn typed<T: DeserializeOwned + Validate>(value: serde_json::Value, what: &'static str) -> Result<T, DocumentError> {
    let v: T = serde_json::from_value(value).map_err(|e| DocumentError::Shape { what, message: e.to_string() })?;
    v.validate()?;
    Ok(v)
}

fn document<T: DeserializeOwned + Validate>(
    path: &Path,
    what: &'static str,
    bound: SizeBound,
) -> Result<T, InputError> {
    let bad = |source: DocumentError| InputError::Document { path: path.to_owned(), source };
    let value: T = serde_json::from_str(&read_text_within(path, bound)?)
        .map_err(|e| bad(DocumentError::Shape { what, message: e.to_string() }))?;
    value.validate().map_err(|e| bad(e.into()))?;
    Ok(value)
}

/// Reads scenario semantics (what `abstract` writes, or a hand-written file).
pub fn read_semantics(path: &Path) -> Result<ScenarioSemantics, InputError> {
    parse_semantics_json(&read_text_within(path, bounds::SEMANTICS)?)
        .map_err(|e| InputError::Document { path: path.to_owned(), source: e.into() })
}

/// Reads a grounded scenario (what `ground --out` writes).
pub fn read_grounded(path: &Path) -> Result<GroundedScenario, InputError> {
    document(path, "a grounded scenario", bounds::GROUNDED)
}

/// Reads a human reference of motion per manoeuvre class (what `corpus reference` writes), checked.
pub fn read_human_reference(path: &Path) -> Result<HumanReference, InputError> {
    let bad = |source: DocumentError| InputError::Document { path: path.to_owned(), source };
    let what = "a human reference";
    let r: HumanReference = serde_json::from_str(&read_text_within(path, bounds::HUMAN_REFERENCE)?)
        .map_err(|e| bad(DocumentError::Shape { what, message: e.to_string() }))?;
    r.validate().map_err(|e| {
        bad(match e {
            ReferenceError::Format { .. } => DocumentError::Shape { what, message: e.to_string() },
            ReferenceError::Field { field, reason } => ValidationError::new(field, reason).into(),
        })
    })?;
    Ok(r)
}

/// The human reference a command measures realism against: the file given (which must read),
/// or else the shipped one when it is there (run from the repository), or else none.
pub fn human_reference_or_shipped(given: Option<&Path>) -> Result<Option<HumanReference>, InputError> {
    match given {
        Some(path) => read_human_reference(path).map(Some),
        None => {
            let shipped = Path::new(crate::shipped::HUMAN_REFERENCE);
            if shipped.is_file() { read_human_reference(shipped).map(Some) } else { Ok(None) }
        }
    }
}

/// Reads a trajectory prior (what `generate --out` writes).
pub fn read_prior(path: &Path) -> Result<TrajectoryPrior, InputError> {
    document(path, "a trajectory prior", bounds::PRIOR)
}

/// A document that stands for trajectory priors.
#[derive(Debug, Clone, PartialEq)]
pub enum PriorDocument {
    /// A trajectory prior.
    Prior(TrajectoryPrior),
    /// A grounded scenario, with its constant-speed stand-in prior ([`TrajectoryPrior::stand_in`]).
    Grounded {
        /// The stand-in prior.
        stand_in: TrajectoryPrior,
        /// The scenario.
        grounded: GroundedScenario,
    },
}

impl PriorDocument {
    /// The prior (the stand-in of a grounded scenario).
    pub fn prior(&self) -> &TrajectoryPrior {
        match self {
            Self::Prior(p) | Self::Grounded { stand_in: p, .. } => p,
        }
    }

    /// The prior, taken out.
    pub fn into_prior(self) -> TrajectoryPrior {
        match self {
            Self::Prior(p) | Self::Grounded { stand_in: p, .. } => p,
        }
    }
}

/// A parsed JSON value as a priors document: a trajectory prior (it has `dt_s`) or a grounded
/// scenario (it has `fragment_id` and `agents`); `None` when it is neither.
pub fn prior_document(value: serde_json::Value) -> Option<Result<PriorDocument, DocumentError>> {
    if value.get("dt_s").is_some() {
        Some(typed(value, "a trajectory prior").map(PriorDocument::Prior))
    } else if value.get("agents").is_some() && value.get("fragment_id").is_some() {
        Some(typed::<GroundedScenario>(value, "a grounded scenario").and_then(|grounded| {
            let stand_in = TrajectoryPrior::stand_in(&grounded)?;
            Ok(PriorDocument::Grounded { stand_in, grounded })
        }))
    } else {
        None
    }
}

/// Reads a file that is either a trajectory prior or a grounded scenario ([`prior_document`]).
pub fn read_prior_or_grounded(path: &Path) -> Result<PriorDocument, InputError> {
    let bad = |source: DocumentError| InputError::Document { path: path.to_owned(), source };
    let value: serde_json::Value =
        serde_json::from_str(&read_text(path)?).map_err(|e| bad(DocumentError::NotJson(e.to_string())))?;
    match prior_document(value) {
        Some(doc) => doc.map_err(bad),
        None => Err(bad(DocumentError::Unknown(
            "a trajectory prior (`dt_s`) nor a grounded scenario (`fragment_id`, `agents`)",
        ))),
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    fn root() -> std::path::PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
    }

    #[test]
    fn documents_are_checked_and_errors_name_the_file() {
        let sem = read_semantics(&root().join("config/examples/semantics_left_turn.json")).unwrap();
        assert!((sem.pet_label_s - 2.9).abs() < 1e-9);
        let dir = tempfile::tempdir().unwrap();
        let bad = dir.path().join("bad.json");
        std::fs::write(&bad, "{\"dt_s\": 0.1}").unwrap();
        let e = read_prior_or_grounded(&bad).unwrap_err();
        assert!(matches!(e, InputError::Document { .. }) && e.to_string().contains("bad.json"), "{e}");
        std::fs::write(&bad, "[1, 2]").unwrap();
        assert!(read_prior_or_grounded(&bad).unwrap_err().to_string().contains("neither"));
        std::fs::write(&bad, "{").unwrap();
        assert!(read_prior_or_grounded(&bad).unwrap_err().to_string().contains("not JSON"));
        assert!(matches!(read_grounded(&dir.path().join("none.json")), Err(InputError::Read { .. })));
    }

    #[test]
    fn the_shipped_human_reference_reads_and_a_broken_one_names_the_field() {
        let path = root().join(crate::shipped::HUMAN_REFERENCE);
        let r = read_human_reference(&path).unwrap();
        assert!(!r.classes.is_empty());
        let dir = tempfile::tempdir().unwrap();
        let bad = dir.path().join("ref.json");
        let text = read_text(&path).unwrap().replacen("\"dt_s\": 0.1", "\"dt_s\": 7.0", 1);
        std::fs::write(&bad, text).unwrap();
        let e = read_human_reference(&bad).unwrap_err().to_string();
        assert!(e.contains("ref.json") && e.contains("dt_s"), "{e}");
    }
}
