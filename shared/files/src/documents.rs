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

fn typed<T: DeserializeOwned + Validate>(text: &str, what: &'static str) -> Result<T, DocumentError> {
    let v: T = serde_json::from_str(text).map_err(|e| DocumentError::Shape { what, message: e.to_string() })?;
    v.validate()?;
    Ok(v)
}

/// Which of the keys that tell the JSON documents apart a document has at its top level, read
/// without building the document: every value is skipped ([`serde::de::IgnoredAny`]), so telling a
/// 200 MB run from a prior costs no memory, where a `serde_json::Value` of it took 15 times the
/// text.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct DocumentKeys {
    /// `dt_s`: a trajectory prior.
    pub dt_s: bool,
    /// `agents`: a grounded scenario or a prior.
    pub agents: bool,
    /// `fragment_id`: a grounded scenario or a prior.
    pub fragment_id: bool,
    /// `trace`: a run.
    pub trace: bool,
}

impl DocumentKeys {
    /// The keys of `text` (none when it is JSON but not an object); the error when it is not JSON.
    pub fn of(text: &str) -> Result<Self, DocumentError> {
        let not_json = |e: serde_json::Error| DocumentError::NotJson(e.to_string());
        if !text.trim_start().starts_with('{') {
            serde_json::from_str::<serde::de::IgnoredAny>(text).map_err(not_json)?;
            return Ok(Self::default());
        }
        #[derive(serde::Deserialize)]
        struct Probe {
            dt_s: Option<serde::de::IgnoredAny>,
            agents: Option<serde::de::IgnoredAny>,
            fragment_id: Option<serde::de::IgnoredAny>,
            trace: Option<serde::de::IgnoredAny>,
        }
        let p: Probe = serde_json::from_str(text).map_err(not_json)?;
        Ok(Self {
            dt_s: p.dt_s.is_some(),
            agents: p.agents.is_some(),
            fragment_id: p.fragment_id.is_some(),
            trace: p.trace.is_some(),
        })
    }
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

/// A JSON text with these keys ([`DocumentKeys::of`]) as a priors document: a trajectory prior (it
/// has `dt_s`) or a grounded scenario (it has `fragment_id` and `agents`); `None` when it is
/// neither.
pub fn prior_document(text: &str, keys: DocumentKeys) -> Option<Result<PriorDocument, DocumentError>> {
    if keys.dt_s {
        Some(typed(text, "a trajectory prior").map(PriorDocument::Prior))
    } else if keys.agents && keys.fragment_id {
        Some(typed::<GroundedScenario>(text, "a grounded scenario").and_then(|grounded| {
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
    let text = read_text(path)?;
    match prior_document(&text, DocumentKeys::of(&text).map_err(bad)?) {
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

    /// The keys that tell the documents apart are read without the values, nested keys are not
    /// top-level ones, JSON that is not an object has none, and a text that is not JSON is an
    /// error.
    #[test]
    fn the_keys_of_a_document_are_read_without_its_values() {
        let keys =
            DocumentKeys::of(r#"{"fragment_id": "x", "agents": [{"dt_s": 1, "trace": []}], "other": {"a": [1, 2]}}"#);
        assert_eq!(keys.unwrap(), DocumentKeys { agents: true, fragment_id: true, ..DocumentKeys::default() });
        assert!(DocumentKeys::of(r#"{"trace": [], "result": null}"#).unwrap().trace);
        assert_eq!(DocumentKeys::of(" [1, 2]").unwrap(), DocumentKeys::default());
        assert!(matches!(DocumentKeys::of("[1, 2"), Err(DocumentError::NotJson(_))));
        assert!(matches!(DocumentKeys::of(r#"{"dt_s": NaN}"#), Err(DocumentError::NotJson(_))));
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
