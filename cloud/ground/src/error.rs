//! Why a scenario could not be grounded.

use serde::Serialize;
use v2t_model::validate::ValidationError;

/// Why a fragment does not fit the semantics, in words for the operator ("the ego's `u_turn`
/// needs a junction"); reasons from several candidate placements are joined.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, thiserror::Error)]
#[serde(transparent)]
#[error("{0}")]
pub struct Misfit(pub String);

impl From<String> for Misfit {
    fn from(reason: String) -> Self {
        Self(reason)
    }
}

impl std::ops::Deref for Misfit {
    type Target = str;

    fn deref(&self) -> &str {
        &self.0
    }
}

impl From<&str> for Misfit {
    fn from(reason: &str) -> Self {
        Self(reason.to_owned())
    }
}

/// A misfit with a formatted reason.
macro_rules! misfit {
    ($($t:tt)*) => {
        $crate::error::Misfit(format!($($t)*))
    };
}
pub(crate) use misfit;

/// One fragment that did not fit, and why.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct Rejection {
    /// Fragment id.
    pub fragment_id: String,
    /// Why it does not fit.
    pub reason: Misfit,
}

/// Grounding failed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum GroundError {
    /// The semantics do not validate.
    #[error("invalid semantics: {0}")]
    InvalidSemantics(#[from] ValidationError),
    /// No fragment of the library fits: the reason for each, best-ranked first.
    #[error("{}", no_fit(.rejections))]
    NoFit {
        /// One per fragment.
        rejections: Vec<Rejection>,
    },
}

fn no_fit(rejections: &[Rejection]) -> String {
    if rejections.is_empty() {
        return "no fragment fits: the topology library is empty".to_owned();
    }
    let lines: Vec<String> = rejections.iter().map(|r| format!("  {}: {}", r.fragment_id, r.reason)).collect();
    format!("no fragment of the library fits ({} tried):\n{}", rejections.len(), lines.join("\n"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn no_fit_names_every_fragment_and_its_reason() {
        let e = GroundError::NoFit {
            rejections: vec![
                Rejection { fragment_id: "J4".into(), reason: "a roundabout cannot be placed".into() },
                Rejection { fragment_id: "S16/fwd/0".into(), reason: "needs a junction".into() },
            ],
        };
        let text = e.to_string();
        assert!(text.contains("2 tried") && text.contains("J4: a roundabout") && text.contains("S16/fwd/0: needs"));
        assert!(GroundError::NoFit { rejections: vec![] }.to_string().contains("empty"));
    }
}
