//! The test target: the post-encroachment time τ the BV presses the interaction to, and the
//! style, who passes the conflict zone first.
//!
//! One type, one range, one parser: every command-line option, configuration file, link frame and
//! regulator input that names a target goes through [`Target::new`] (or [`Target::from_keys`] for
//! a file that writes τ and the style as two keys of the document, [`Target::check_tau`] for a τ
//! that is a number of its own), so a τ that one part of the system would refuse can never reach
//! another.
//!
//! ```
//! use v2t_model::{Style, Target};
//!
//! let t = Target::new(2.5, "rush".parse::<Style>().unwrap()).unwrap();
//! assert_eq!((t.tau_s(), t.style()), (2.5, Style::Rush));
//! assert!(Target::new(0.0, Style::Yield).is_err());
//! assert!(Target::new(f64::NAN, Style::Yield).is_err());
//! assert_eq!(Target::parse_tau("31").unwrap_err().to_string(), "τ must lie in [0.1, 30] s, got 31");
//! ```

use serde::{Deserialize, Serialize};

use crate::validate::ValidationError;

/// Who passes the conflict zone first: the BV (`rush`) or the VUT (`yield`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum Style {
    /// The BV passes the conflict zone first.
    Rush,
    /// The VUT passes the conflict zone first.
    Yield,
}

impl Style {
    /// Both styles, rush first.
    pub const ALL: [Self; 2] = [Self::Rush, Self::Yield];

    /// Its name: `rush` or `yield`.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Rush => "rush",
            Self::Yield => "yield",
        }
    }
}

impl std::fmt::Display for Style {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

impl std::str::FromStr for Style {
    type Err = TargetError;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "rush" => Ok(Self::Rush),
            "yield" => Ok(Self::Yield),
            other => Err(TargetError::Style(other.to_owned())),
        }
    }
}

/// A target that is not one.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum TargetError {
    /// τ outside [`Target::TAU_MIN_S`, `Target::TAU_MAX_S`], or not a number.
    #[error("τ must lie in [{min}, {max}] s, got {0}", min = Target::TAU_MIN_S, max = Target::TAU_MAX_S)]
    Tau(f64),
    /// τ that does not parse as a number.
    #[error("τ `{0}` is not a number of seconds")]
    NotANumber(String),
    /// A style other than `rush` or `yield`.
    #[error("style `{0}`: rush or yield")]
    Style(String),
}

/// Target PET τ and style of one interaction. Its τ always lies in
/// [[`Target::TAU_MIN_S`], [`Target::TAU_MAX_S`]]: the only way to make one is [`Target::new`]
/// (deserialization goes through it too).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "TargetFields", into = "TargetFields")]
pub struct Target {
    tau_s: f64,
    style: Style,
}

/// The serialized form of a [`Target`]: `{ tau_s, style }`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct TargetFields {
    tau_s: f64,
    style: Style,
}

impl TryFrom<TargetFields> for Target {
    type Error = TargetError;

    fn try_from(f: TargetFields) -> Result<Self, Self::Error> {
        Self::new(f.tau_s, f.style)
    }
}

impl From<Target> for TargetFields {
    fn from(t: Target) -> Self {
        Self { tau_s: t.tau_s, style: t.style }
    }
}

impl Target {
    /// The smallest τ, s: below it the two vehicles would all but touch (the BV's own safety margin
    /// keeps it further away anyway).
    pub const TAU_MIN_S: f64 = 0.1;
    /// The largest τ, s: beyond it there is no interaction left to test.
    pub const TAU_MAX_S: f64 = 30.0;

    /// `tau_s` in `style`, when τ lies in range (NaN does not).
    pub fn new(tau_s: f64, style: Style) -> Result<Self, TargetError> {
        if (Self::TAU_MIN_S..=Self::TAU_MAX_S).contains(&tau_s) {
            Ok(Self { tau_s, style })
        } else {
            Err(TargetError::Tau(tau_s))
        }
    }

    /// Target PET, s.
    pub fn tau_s(self) -> f64 {
        self.tau_s
    }

    /// Who passes first.
    pub fn style(self) -> Style {
        self.style
    }

    /// The same τ in `style`.
    #[must_use]
    pub fn with_style(self, style: Style) -> Self {
        Self { style, ..self }
    }

    /// `tau_s` in the style of this target, when it lies in range.
    pub fn with_tau(self, tau_s: f64) -> Result<Self, TargetError> {
        Self::new(tau_s, self.style)
    }

    /// The target of a document whose file writes τ and the style as two keys of its own, `tau_s`
    /// and `style` (a scenario card, a grounded scenario, a prior, a run result, a campaign
    /// memory's case): the error names the field `tau_s` and the range.
    pub fn from_keys(tau_s: f64, style: Style) -> Result<Self, ValidationError> {
        Self::new(tau_s, style).map_err(|e| ValidationError::new("tau_s", e.to_string()))
    }

    /// The range check for a τ that is a number of its own, not part of a target (the semantics'
    /// PET label, a wire payload's τ): the field named in the error.
    pub fn check_tau(field: &str, tau_s: f64) -> Result<(), ValidationError> {
        Self::new(tau_s, Style::Rush).map(|_| ()).map_err(|e| ValidationError::new(field, e.to_string()))
    }

    /// τ from a command-line word, range-checked.
    pub fn parse_tau(s: &str) -> Result<f64, TargetError> {
        let tau_s: f64 = s.trim().parse().map_err(|_| TargetError::NotANumber(s.to_owned()))?;
        Self::new(tau_s, Style::Rush).map(|t| t.tau_s)
    }
}

impl std::fmt::Display for Target {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "τ {} s, {}", self.tau_s, self.style)
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn the_range_holds_at_both_ends_and_refuses_nan() {
        for ok in [Target::TAU_MIN_S, 2.0, Target::TAU_MAX_S] {
            assert!(Target::new(ok, Style::Rush).is_ok(), "{ok}");
        }
        for bad in [0.0, 0.099, 30.01, -1.0, f64::NAN, f64::INFINITY, 1e308] {
            assert_eq!(Target::new(bad, Style::Yield).map_err(|e| matches!(e, TargetError::Tau(_))), Err(true));
        }
        let e = Target::check_tau("tau_s", 0.0).unwrap_err();
        assert_eq!(e.field, "tau_s");
        assert!(e.problem.contains("[0.1, 30]"), "{e}");
        let e = Target::from_keys(30.5, Style::Yield).unwrap_err();
        assert_eq!(e.to_string(), "field `tau_s`: τ must lie in [0.1, 30] s, got 30.5");
        assert_eq!(Target::from_keys(2.0, Style::Yield).unwrap(), Target::new(2.0, Style::Yield).unwrap());
    }

    #[test]
    fn words_parse_or_say_why_not() {
        assert_eq!("yield".parse::<Style>().unwrap(), Style::Yield);
        assert_eq!("fast".parse::<Style>().unwrap_err().to_string(), "style `fast`: rush or yield");
        assert_eq!(Target::parse_tau(" 3.5 ").unwrap(), 3.5);
        assert!(matches!(Target::parse_tau("x"), Err(TargetError::NotANumber(_))));
        assert!(matches!(Target::parse_tau("nan"), Err(TargetError::Tau(_))));
        for s in Style::ALL {
            assert_eq!(s.as_str().parse::<Style>().unwrap(), s);
        }
    }

    #[test]
    fn serde_goes_through_the_range_check() {
        let t = Target::new(2.5, Style::Yield).unwrap();
        let json = serde_json::to_string(&t).unwrap();
        assert_eq!(json, r#"{"tau_s":2.5,"style":"yield"}"#);
        assert_eq!(serde_json::from_str::<Target>(&json).unwrap(), t);
        assert!(serde_json::from_str::<Target>(r#"{"tau_s":0,"style":"yield"}"#).is_err());
        assert!(serde_json::from_str::<Target>(r#"{"tau_s":2,"style":"yield","x":1}"#).is_err());
    }
}
