//! Validation of parsed data ("parse, don't validate": serde gives the shape, `validate()` the ranges).
//!
//! Every range check is written so that NaN fails it: `value >= lo` is false for NaN, so we test the
//! positive condition and report the failure otherwise.

/// One problem found in a value, with the dotted path of the field that has it.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("field `{field}`: {problem}")]
pub struct ValidationError {
    /// Dotted path of the offending field, e.g. `limits.max_accel_mps2` or `bvs[0].speed_mps`.
    pub field: String,
    /// What is wrong, with the offending value.
    pub problem: String,
}

impl ValidationError {
    /// A problem at `field`.
    pub fn new(field: impl Into<String>, problem: impl Into<String>) -> Self {
        Self { field: field.into(), problem: problem.into() }
    }

    /// The same problem, one level deeper: `prefix.field`.
    #[must_use]
    pub fn within(mut self, prefix: &str) -> Self {
        self.field = if self.field.is_empty() {
            prefix.to_owned()
        } else if self.field.starts_with('[') {
            format!("{prefix}{}", self.field)
        } else {
            format!("{prefix}.{}", self.field)
        };
        self
    }
}

/// A type whose values can be checked after parsing.
pub trait Validate {
    /// Returns the first problem found, naming the field.
    fn validate(&self) -> Result<(), ValidationError>;
}

impl<T: Validate> Validate for [T] {
    fn validate(&self) -> Result<(), ValidationError> {
        for (i, item) in self.iter().enumerate() {
            item.validate().map_err(|e| e.within(&format!("[{i}]")))?;
        }
        Ok(())
    }
}

/// `value` must be finite.
pub fn finite(field: &str, value: f64) -> Result<(), ValidationError> {
    if value.is_finite() {
        Ok(())
    } else {
        Err(ValidationError::new(field, format!("must be a finite number, got {value}")))
    }
}

/// `value` must be finite and `> 0`.
pub fn positive(field: &str, value: f64) -> Result<(), ValidationError> {
    if value.is_finite() && value > 0.0 {
        Ok(())
    } else {
        Err(ValidationError::new(field, format!("must be a finite number > 0, got {value}")))
    }
}

/// `value` must be finite and `>= 0`.
pub fn non_negative(field: &str, value: f64) -> Result<(), ValidationError> {
    if value.is_finite() && value >= 0.0 {
        Ok(())
    } else {
        Err(ValidationError::new(field, format!("must be a finite number >= 0, got {value}")))
    }
}

/// `value` must lie in the closed range `[lo, hi]`.
pub fn in_range(field: &str, value: f64, lo: f64, hi: f64) -> Result<(), ValidationError> {
    if value >= lo && value <= hi {
        Ok(())
    } else {
        Err(ValidationError::new(field, format!("must lie in [{lo}, {hi}], got {value}")))
    }
}

/// Every element of `values` must be finite.
pub fn all_finite(field: &str, values: &[f64]) -> Result<(), ValidationError> {
    match values.iter().position(|v| !v.is_finite()) {
        None => Ok(()),
        Some(i) => Err(ValidationError::new(
            format!("{field}[{i}]"),
            format!("must be a finite number, got {}", values.get(i).copied().unwrap_or(f64::NAN)),
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nan_fails_every_range_check() {
        assert!(finite("x", f64::NAN).is_err());
        assert!(positive("x", f64::NAN).is_err());
        assert!(non_negative("x", f64::NAN).is_err());
        assert!(in_range("x", f64::NAN, -1.0, 1.0).is_err());
        assert!(all_finite("x", &[0.0, f64::INFINITY]).is_err());
    }

    #[test]
    fn nested_field_paths_read_naturally() {
        let e = ValidationError::new("speed_mps", "bad").within("[1]").within("bvs");
        assert_eq!(e.field, "bvs[1].speed_mps");
        assert_eq!(e.to_string(), "field `bvs[1].speed_mps`: bad");
    }
}
