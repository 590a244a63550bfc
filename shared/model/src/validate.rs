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
        Err(ValidationError::new(field, format!("must be a finite number, got {}", shown(value))))
    }
}

/// `value` must be finite and `> 0`.
pub fn positive(field: &str, value: f64) -> Result<(), ValidationError> {
    if value.is_finite() && value > 0.0 {
        Ok(())
    } else {
        Err(ValidationError::new(field, format!("must be a finite number > 0, got {}", shown(value))))
    }
}

/// `value` must be finite and `>= 0`.
pub fn non_negative(field: &str, value: f64) -> Result<(), ValidationError> {
    if value.is_finite() && value >= 0.0 {
        Ok(())
    } else {
        Err(ValidationError::new(field, format!("must be a finite number >= 0, got {}", shown(value))))
    }
}

/// `value` as an error message shows it: plain where that is short, else in exponent form
/// (`1e300`, not three hundred digits).
pub fn shown(value: f64) -> String {
    let plain = value.to_string();
    if plain.len() > 16 { format!("{value:e}") } else { plain }
}

/// `value` must lie in the closed range `[lo, hi]`.
pub fn in_range(field: &str, value: f64, lo: f64, hi: f64) -> Result<(), ValidationError> {
    if value >= lo && value <= hi {
        Ok(())
    } else {
        Err(ValidationError::new(field, format!("must lie in [{lo}, {hi}], got {}", shown(value))))
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

/// Physical bounds of the documents that describe motion on a track (grounded scenarios, priors, run
/// traces): a number beyond them is not a mistake of degree but a broken or hostile file, refused
/// before any loop runs over it.
pub mod plausible {
    /// Largest coordinate magnitude in the track frame, m (the OpenDRIVE reader's bound too).
    pub const MAX_COORDINATE_M: f64 = 1.0e8;
    /// Longest route of one agent, m: a test drives a proving ground's roads, not a country's.
    pub const MAX_ROUTE_LENGTH_M: f64 = 50_000.0;
    /// Most points of one route.
    pub const MAX_ROUTE_POINTS: usize = 200_000;
    /// Latest time in a scenario (start and anchor times, a prior's horizon, a run's span), s.
    pub const MAX_SCENARIO_TIME_S: f64 = 3600.0;
    /// Largest speed of any vehicle in a document, m/s (360 km/h); reversing down to minus it.
    pub const MAX_SPEED_MPS: f64 = 100.0;
    /// Largest magnitude of a longitudinal acceleration in a document, m/s².
    pub const MAX_ACCEL_MPS2: f64 = 30.0;
    /// Largest magnitude of a yaw rate in a document, rad/s.
    pub const MAX_YAW_RATE_RADPS: f64 = 5.0;
    /// Most agents in one document.
    pub const MAX_AGENTS: usize = 16;
    /// Slack of [`teleported`]: positioning noise and rounding, m.
    pub const STEP_SLACK_M: f64 = 1.0;

    /// `p` must lie within ±[`MAX_COORDINATE_M`] on both axes.
    pub fn coordinates(field: &str, x: f64, y: f64) -> Result<(), super::ValidationError> {
        super::in_range(&format!("{field}.x"), x, -MAX_COORDINATE_M, MAX_COORDINATE_M)?;
        super::in_range(&format!("{field}.y"), y, -MAX_COORDINATE_M, MAX_COORDINATE_M)
    }

    /// One vehicle's samples `(t_s, x, y)` in time order, as a run trace or an export holds them:
    /// every coordinate within bounds, no step faster than [`MAX_SPEED_MPS`] ([`teleported`]), at
    /// most [`MAX_SCENARIO_TIME_S`] from the first to the last. The error names `field[k]`.
    pub fn motion(
        field: &str,
        samples: impl IntoIterator<Item = (f64, f64, f64)>,
    ) -> Result<(), super::ValidationError> {
        let mut first: Option<f64> = None;
        let mut last: Option<(f64, f64, f64)> = None;
        for (k, (t, x, y)) in samples.into_iter().enumerate() {
            coordinates(&format!("{field}[{k}]"), x, y)?;
            if let Some((t0, x0, y0)) = last {
                let jump = (x - x0).hypot(y - y0);
                if teleported(jump, t - t0) {
                    return Err(super::ValidationError::new(
                        format!("{field}[{k}]"),
                        format!(
                            "lies {jump:.1} m from the sample {:.3} s before: faster than {MAX_SPEED_MPS} m/s",
                            t - t0
                        ),
                    ));
                }
            }
            let t0 = *first.get_or_insert(t);
            if t - t0 > MAX_SCENARIO_TIME_S {
                return Err(super::ValidationError::new(
                    format!("{field}[{k}]"),
                    format!(
                        "lies {:.0} s after the first sample, at most {MAX_SCENARIO_TIME_S} s are accepted",
                        t - t0
                    ),
                ));
            }
            last = Some((t, x, y));
        }
        Ok(())
    }

    /// Whether a vehicle moved `distance_m` in `dt_s` faster than [`MAX_SPEED_MPS`] allows (with
    /// [`STEP_SLACK_M`]): a jump no vehicle makes.
    pub fn teleported(distance_m: f64, dt_s: f64) -> bool {
        distance_m.is_nan() || distance_m > MAX_SPEED_MPS * dt_s.max(0.0) + STEP_SLACK_M
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
