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
    /// most [`MAX_SCENARIO_TIME_S`] from the first to the last. The error names `field(k)`, the
    /// field of sample `k` (`|k| format!("agents[0].states[{k}]")`).
    pub fn motion(
        field: impl Fn(usize) -> String,
        samples: impl IntoIterator<Item = (f64, f64, f64)>,
    ) -> Result<(), super::ValidationError> {
        let mut first: Option<f64> = None;
        let mut last: Option<(f64, f64, f64)> = None;
        for (k, (t, x, y)) in samples.into_iter().enumerate() {
            coordinates(&field(k), x, y)?;
            if let Some((t0, x0, y0)) = last {
                let jump = (x - x0).hypot(y - y0);
                if teleported(jump, t - t0) {
                    return Err(super::ValidationError::new(
                        field(k),
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
                    field(k),
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

    /// Absolute slack of [`kinematics`] on the distance moved over a window: positioning noise, a
    /// reference point that swings with the heading, rounding, m.
    pub const MOTION_SLACK_M: f64 = 0.25;
    /// Relative slack of [`kinematics`] on the distance the speeds allow over a window.
    pub const MOTION_SLACK_FRACTION: f64 = 0.1;
    /// Largest angle of [`kinematics`] between a vehicle's heading and the direction it moved over a
    /// window, rad (45°; half the heading change within the window is added: a chord of a bend).
    pub const HEADING_SLACK_RAD: f64 = std::f64::consts::FRAC_PI_4;
    /// Shortest move whose direction [`kinematics`] compares with the heading, m: below it the
    /// direction is noise.
    pub const MIN_HEADING_STEP_M: f64 = 0.5;
    /// The span [`kinematics`] checks at once, s: long enough that a trace sampled at 100 Hz still
    /// shows a car standing at 8 m/s (8 m, far beyond the slack), short enough to name the place.
    pub const MOTION_WINDOW_S: f64 = 1.0;

    /// One vehicle's states `(t_s, state)` in increasing time, as a prior, a run trace or a
    /// recording holds them, checked for being motion at all: every speed ≥ 0 (a test vehicle does
    /// not reverse); over each window of [`MOTION_WINDOW_S`] (or one longer step) the vehicle moved
    /// as far as its speeds say (the path it took, between the smaller and the larger speed of each
    /// step times the step, within [`MOTION_SLACK_FRACTION`] and [`MOTION_SLACK_M`]); and where the
    /// window's start and end lie at least [`MIN_HEADING_STEP_M`] apart, in the direction it heads
    /// (within [`HEADING_SLACK_RAD`]). A car standing still while its speed says 12.5 m/s, one driving
    /// while its speed says 0, and one driving backwards along its heading all fail. The error names
    /// `field(k)`, the field of the sample that ends the window, as [`motion`]'s does.
    pub fn kinematics(
        field: impl Fn(usize) -> String,
        samples: impl IntoIterator<Item = (f64, crate::kinematics::State)>,
    ) -> Result<(), super::ValidationError> {
        struct Window {
            t0: f64,
            x0: crate::kinematics::State,
            moved: f64,
            slow: f64,
            fast: f64,
            turn: f64,
        }
        let mut last: Option<(f64, crate::kinematics::State)> = None;
        let mut window: Option<Window> = None;
        let mut samples = samples.into_iter().enumerate().peekable();
        while let Some((k, (t, x))) = samples.next() {
            if x.speed_mps.is_nan() || x.speed_mps < 0.0 {
                return Err(super::ValidationError::new(
                    format!("{}.speed_mps", field(k)),
                    format!("must be ≥ 0 (a test vehicle does not reverse), got {}", super::shown(x.speed_mps)),
                ));
            }
            let Some((t_prev, x_prev)) = last.replace((t, x)) else {
                window = Some(Window { t0: t, x0: x, moved: 0.0, slow: 0.0, fast: 0.0, turn: 0.0 });
                continue;
            };
            let Some(w) = window.as_mut() else { continue };
            let dt = t - t_prev;
            w.moved += x.position().dist(x_prev.position());
            w.slow += x_prev.speed_mps.min(x.speed_mps) * dt;
            w.fast += x_prev.speed_mps.max(x.speed_mps) * dt;
            w.turn += wrap(x.theta_rad - x_prev.theta_rad).abs();
            if t - w.t0 < MOTION_WINDOW_S && samples.peek().is_some() {
                continue;
            }
            let span = t - w.t0;
            let least = w.slow * (1.0 - MOTION_SLACK_FRACTION) - MOTION_SLACK_M;
            let most = w.fast * (1.0 + MOTION_SLACK_FRACTION) + MOTION_SLACK_M;
            if !(w.moved >= least && w.moved <= most) {
                return Err(super::ValidationError::new(
                    field(k),
                    format!(
                        "moved {:.2} m in the {span:.3} s before it, while its speeds say {:.2} to {:.2} m \
                         (slack {MOTION_SLACK_M} m and {:.0} %)",
                        w.moved,
                        w.slow,
                        w.fast,
                        MOTION_SLACK_FRACTION * 100.0
                    ),
                ));
            }
            let chord = x.position().sub(w.x0.position());
            if chord.norm() >= MIN_HEADING_STEP_M {
                let heading = w.x0.theta_rad + 0.5 * wrap(x.theta_rad - w.x0.theta_rad);
                let off = wrap(chord.y.atan2(chord.x) - heading).abs();
                let allowed = HEADING_SLACK_RAD + 0.5 * w.turn;
                if off.is_nan() || off > allowed {
                    return Err(super::ValidationError::new(
                        field(k),
                        format!(
                            "moved {:.0}° away from its heading in the {span:.3} s before it, at most {:.0}° is \
                             accepted",
                            off.to_degrees(),
                            allowed.to_degrees()
                        ),
                    ));
                }
            }
            window = Some(Window { t0: t, x0: x, moved: 0.0, slow: 0.0, fast: 0.0, turn: 0.0 });
        }
        Ok(())
    }

    /// One vehicle's recorded track `(t_s, state)`, as a run trace or a recording holds it: times
    /// finite and increasing, every state finite, [`motion`] and [`kinematics`]. The error names
    /// `field(k)`.
    pub fn track<I>(field: impl Fn(usize) -> String, samples: I) -> Result<(), super::ValidationError>
    where
        I: IntoIterator<Item = (f64, crate::kinematics::State)>,
        I::IntoIter: Clone,
    {
        let samples = samples.into_iter();
        let mut last = f64::NEG_INFINITY;
        for (k, (t, x)) in samples.clone().enumerate() {
            if !(t.is_finite() && t > last) {
                return Err(super::ValidationError::new(
                    field(k),
                    format!("time {} s: times must be finite and increasing", super::shown(t)),
                ));
            }
            if !x.is_finite() {
                return Err(super::ValidationError::new(field(k), "must be finite"));
            }
            last = t;
        }
        motion(&field, samples.clone().map(|(t, x)| (t, x.px, x.py)))?;
        kinematics(&field, samples)
    }

    /// `a` wrapped to [-π, π), rad.
    fn wrap(a: f64) -> f64 {
        (a + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU) - std::f64::consts::PI
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

    fn states(xs: &[(f64, f64, f64, f64)]) -> Vec<(f64, crate::kinematics::State)> {
        xs.iter()
            .enumerate()
            .map(|(k, &(px, py, theta_rad, speed_mps))| {
                (k as f64 * 0.1, crate::kinematics::State { px, py, theta_rad, speed_mps })
            })
            .collect()
    }

    #[test]
    fn motion_that_is_not_motion_is_named() {
        let kin = |xs: &[(f64, f64, f64, f64)]| plausible::kinematics(|k| format!("states[{k}]"), states(xs));
        // Euler steps at 12.5 m/s east, a stop, a bend: motion.
        assert!(kin(&[(0.0, 0.0, 0.0, 12.5), (1.25, 0.0, 0.0, 12.5), (2.5, 0.0, 0.0, 12.0)]).is_ok());
        assert!(kin(&[(0.0, 0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 0.0), (0.01, 0.0, 0.0, 0.2)]).is_ok());
        assert!(kin(&[(0.0, 0.0, 0.0, 10.0), (0.995, 0.1, 0.2, 10.0)]).is_ok());
        // Standing still while the speed says 12.5 m/s.
        let e = kin(&[(5.0, 5.0, 0.0, 12.5), (5.0, 5.0, 0.0, 12.5)]).unwrap_err();
        assert_eq!(e.field, "states[1]");
        assert!(e.problem.contains("say 1.25 to 1.25 m"), "{e}");
        // Driving while the speed says 0.
        assert_eq!(kin(&[(0.0, 0.0, 0.0, 0.0), (1.0, 0.0, 0.0, 0.0)]).unwrap_err().field, "states[1]");
        // Against its own heading, and reversing.
        let e = kin(&[(0.0, 0.0, 0.0, 10.0), (-1.0, 0.0, 0.0, 10.0)]).unwrap_err();
        assert!(e.problem.contains("180°"), "{e}");
        let e = kin(&[(0.0, 0.0, 0.0, 1.0), (0.0, 0.0, 0.0, -1.0)]).unwrap_err();
        assert_eq!(e.field, "states[1].speed_mps");
        assert!(kin(&[(0.0, 0.0, 0.0, f64::NAN)]).is_err());
    }

    /// Sampled finely (100 Hz), a car standing at 8 m/s moves less than the slack at every step;
    /// over the window it is 8 m short, and the window's end is named.
    #[test]
    fn a_finely_sampled_car_standing_at_speed_is_caught_over_the_window() {
        let still: Vec<(f64, crate::kinematics::State)> = (0..300)
            .map(|k| (k as f64 * 0.01, crate::kinematics::State { px: 3.0, py: 4.0, theta_rad: 0.5, speed_mps: 8.0 }))
            .collect();
        let e = plausible::kinematics(|k| format!("trace[{k}]"), still).unwrap_err();
        assert_eq!(e.field, "trace[100]");
        assert!(
            e.problem.contains("moved 0.00 m in the 1.000 s before it") && e.problem.contains("8.00 to 8.00 m"),
            "{e}"
        );
        // Driving along at 8 m/s, sampled the same way: motion.
        let driving = (0..300).map(|k| {
            let t = k as f64 * 0.01;
            (t, crate::kinematics::State { px: 8.0 * t, py: 0.0, theta_rad: 0.0, speed_mps: 8.0 })
        });
        plausible::kinematics(|k| format!("trace[{k}]"), driving).unwrap();
    }

    #[test]
    fn nested_field_paths_read_naturally() {
        let e = ValidationError::new("speed_mps", "bad").within("[1]").within("bvs");
        assert_eq!(e.field, "bvs[1].speed_mps");
        assert_eq!(e.to_string(), "field `bvs[1].speed_mps`: bad");
    }
}
