//! How human a vehicle's motion is: the Wasserstein-1 distance of its longitudinal acceleration,
//! jerk and yaw rate to **recorded human driving in the same manoeuvre class**, its jerk RMS, and
//! how often it hurries and then brakes (speed reversals).
//!
//! The human side is a [`HumanReference`]: per [`ManoeuvreClass`], the quantile functions (101
//! quantiles, 0 %, 1 %, …, 100 %) of acceleration, jerk and yaw rate of recorded vehicles, with
//! the provenance of the recordings and how many vehicles stand behind each class (at least
//! [`MIN_VEHICLES`]; a class with fewer is left out, and runs in it are not measured). `video2track corpus reference` builds one from a recorded
//! corpus; the shipped one is `config/realism/human_reference.json`.
//!
//! **W₁ against quantiles.** For one-dimensional distributions `W₁ = ∫₀¹ |F⁻¹(u) − G⁻¹(u)| du`;
//! [`w1_to_quantiles`] evaluates it on 1,000 midpoints `u`, the run's empirical quantile function against
//! the reference's quantiles interpolated linearly. Storing 101 quantiles instead of every sample
//! costs at most the spacing of neighbouring quantiles inside each percentile (the tails beyond the
//! 0 % and 100 % quantiles are clamped to them).
//!
//! **Speed reversals**: the number of times the speed rises by at least [`REVERSAL_MPS`] from its
//! last low and then falls by at least as much from the following high (a hurry then a brake).
//! Noise smaller than that is not counted.

use serde::{Deserialize, Serialize};

use crate::geometry::wrap_angle;
use crate::kinematics::State;

/// Format name of a reference file.
pub const REFERENCE_FORMAT: &str = "v2t-human-reference";
/// Its version.
pub const REFERENCE_VERSION: u32 = 1;
/// Quantiles stored per quantity.
pub const QUANTILES: usize = 101;
/// Hysteresis of a speed reversal, m/s.
pub const REVERSAL_MPS: f64 = 0.5;
/// A class measured on fewer vehicles than this is left out of a reference (too few to stand for
/// human driving).
pub const MIN_VEHICLES: usize = 5;
/// Midpoints of the W₁ integral.
const W1_POINTS: usize = 1000;

/// What a vehicle does through the interaction.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ManoeuvreClass {
    /// Goes straight through (the vehicle a cut-in or a left turn comes at).
    Straight,
    /// Turns left.
    LeftTurn,
    /// Changes lanes into a gap.
    LaneChange,
}

impl ManoeuvreClass {
    /// Every class.
    pub const ALL: [Self; 3] = [Self::Straight, Self::LeftTurn, Self::LaneChange];

    /// Name in tables.
    pub fn name(self) -> &'static str {
        match self {
            Self::Straight => "straight",
            Self::LeftTurn => "left turn",
            Self::LaneChange => "lane change",
        }
    }

    /// The class of a driven trajectory: a left turn when its heading turns left by more than
    /// 1 rad overall, a lane change when it ends 2–5 m to the side of the line its start heading
    /// points along (having turned less than [`LANE_CHANGE_MAX_TURN_RAD`]), straight otherwise.
    pub fn of_states(states: &[State]) -> Self {
        let (Some(first), Some(last)) = (states.first(), states.last()) else { return Self::Straight };
        let turn = heading_change_rad(states);
        let d = last.position().sub(first.position());
        let (s, c) = first.theta_rad.sin_cos();
        let lateral = (-s * d.x + c * d.y).abs();
        if turn > 1.0 {
            Self::LeftTurn
        } else if turn.abs() < LANE_CHANGE_MAX_TURN_RAD && (2.0..=5.0).contains(&lateral) {
            Self::LaneChange
        } else {
            Self::Straight
        }
    }
}

/// A lane change turns by less than this overall, rad (a vehicle that turns into a lane is turning).
pub const LANE_CHANGE_MAX_TURN_RAD: f64 = 0.5;

/// How far a driven trajectory's heading turns overall, rad, counter-clockwise positive (the sum of
/// its wrapped steps).
pub fn heading_change_rad(states: &[State]) -> f64 {
    states
        .windows(2)
        .map(|w| match w {
            [a, b] => wrap_angle(b.theta_rad - a.theta_rad),
            _ => 0.0,
        })
        .sum()
}

/// One class's human distributions.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ClassReference {
    /// The class.
    pub class: ManoeuvreClass,
    /// Vehicles it was measured on.
    pub vehicles: usize,
    /// Acceleration samples behind it.
    pub samples: usize,
    /// Quantiles of longitudinal acceleration, m/s² ([`QUANTILES`], non-decreasing).
    pub accel_mps2: Vec<f64>,
    /// Quantiles of jerk, m/s³.
    pub jerk_mps3: Vec<f64>,
    /// Quantiles of yaw rate, rad/s.
    pub yaw_rate_radps: Vec<f64>,
}

/// Human reference distributions per manoeuvre class.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HumanReference {
    /// [`REFERENCE_FORMAT`].
    pub format: String,
    /// [`REFERENCE_VERSION`].
    pub version: u32,
    /// Where the recordings came from, their licences, and the command that made this file.
    pub provenance: String,
    /// Sampling period of the recordings, s (jerk depends on it: compare runs at this period).
    pub dt_s: f64,
    /// One entry per class measured.
    pub classes: Vec<ClassReference>,
}

/// What is wrong with a reference.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ReferenceError {
    /// Another format or version.
    #[error("format `{format}` version {version}: expected `{REFERENCE_FORMAT}` version {REFERENCE_VERSION}")]
    Format {
        /// In the file.
        format: String,
        /// In the file.
        version: u32,
    },
    /// A field out of range.
    #[error("{field}: {reason}")]
    Field {
        /// Which field.
        field: String,
        /// Why.
        reason: String,
    },
}

/// The [`QUANTILES`] quantiles of `samples` (linear between order statistics); `None` when there
/// is no finite sample.
pub fn quantiles(samples: &[f64]) -> Option<Vec<f64>> {
    let mut v: Vec<f64> = samples.iter().copied().filter(|x| x.is_finite()).collect();
    if v.is_empty() {
        return None;
    }
    v.sort_by(f64::total_cmp);
    let n = v.len();
    Some(
        (0..QUANTILES)
            .map(|k| {
                let pos = (n - 1) as f64 * k as f64 / (QUANTILES - 1) as f64;
                let (i, f) = (pos.floor() as usize, pos.fract());
                let a = v.get(i).copied().unwrap_or(0.0);
                let b = v.get(i + 1).copied().unwrap_or(a);
                a + f * (b - a)
            })
            .collect(),
    )
}

/// Acceleration, jerk and yaw-rate samples of a trajectory sampled every `dt_s`.
pub fn motion_samples(states: &[State], dt_s: f64) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
    if !(dt_s.is_finite() && dt_s > 0.0) {
        return (Vec::new(), Vec::new(), Vec::new());
    }
    let accel: Vec<f64> = states
        .windows(2)
        .filter_map(|w| match w {
            [a, b] => Some((b.speed_mps - a.speed_mps) / dt_s),
            _ => None,
        })
        .collect();
    let jerk = accel
        .windows(2)
        .filter_map(|w| match w {
            [a, b] => Some((b - a) / dt_s),
            _ => None,
        })
        .collect();
    let yaw = states
        .windows(2)
        .filter_map(|w| match w {
            [a, b] => Some(wrap_angle(b.theta_rad - a.theta_rad) / dt_s),
            _ => None,
        })
        .collect();
    (accel, jerk, yaw)
}

/// W₁ between the samples `run` and the distribution given by `reference` quantiles (see the
/// module documentation); `None` without finite samples or with a malformed quantile list.
pub fn w1_to_quantiles(run: &[f64], reference: &[f64]) -> Option<f64> {
    let mut v: Vec<f64> = run.iter().copied().filter(|x| x.is_finite()).collect();
    if v.is_empty() || reference.len() < 2 {
        return None;
    }
    v.sort_by(f64::total_cmp);
    let n = v.len();
    let m = reference.len() - 1;
    let mut sum = 0.0;
    for k in 0..W1_POINTS {
        let u = (k as f64 + 0.5) / W1_POINTS as f64;
        let q_run = v.get(((u * n as f64) as usize).min(n - 1)).copied()?;
        let pos = u * m as f64;
        let (i, f) = (pos.floor() as usize, pos.fract());
        let a = *reference.get(i)?;
        let b = reference.get(i + 1).copied().unwrap_or(a);
        sum += (q_run - (a + f * (b - a))).abs();
    }
    Some(sum / W1_POINTS as f64)
}

/// Speed reversals of a speed series (see the module documentation).
pub fn speed_reversals(speeds: &[f64]) -> usize {
    let mut count = 0;
    let Some(&first) = speeds.first() else { return 0 };
    // Rising: looking for a high after a low; falling: looking for a low after a high.
    let (mut low, mut high, mut rising) = (first, first, false);
    for &v in speeds.iter().filter(|v| v.is_finite()) {
        if rising {
            if v > high {
                high = v;
            } else if high - v >= REVERSAL_MPS {
                count += 1;
                rising = false;
                low = v;
            }
        } else if v < low {
            low = v;
        } else if v - low >= REVERSAL_MPS {
            rising = true;
            high = v;
        }
    }
    count
}

/// One vehicle's samples for a reference: its class, then its acceleration (m/s²), jerk (m/s³) and
/// yaw-rate (rad/s) samples.
pub type VehicleSamples = (ManoeuvreClass, Vec<f64>, Vec<f64>, Vec<f64>);

/// How human one vehicle's motion was.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct MotionRealism {
    /// The class it was compared in.
    pub class: ManoeuvreClass,
    /// W₁ of longitudinal acceleration to the class's human reference, m/s².
    pub w1_accel_mps2: f64,
    /// W₁ of jerk, m/s³.
    pub w1_jerk_mps3: f64,
    /// W₁ of yaw rate, rad/s.
    pub w1_yaw_rate_radps: f64,
    /// Root mean square of jerk, m/s³.
    pub jerk_rms_mps3: f64,
    /// Speed reversals (hurry then brake).
    pub speed_reversals: usize,
}

impl HumanReference {
    /// A reference from per-vehicle samples: `(class, accel, jerk, yaw rate)` per vehicle; a class
    /// with fewer than [`MIN_VEHICLES`] vehicles is left out.
    pub fn from_vehicles(provenance: String, dt_s: f64, vehicles: &[VehicleSamples]) -> Self {
        let classes = ManoeuvreClass::ALL
            .iter()
            .filter_map(|&class| {
                let of: Vec<_> = vehicles.iter().filter(|v| v.0 == class).collect();
                if of.len() < MIN_VEHICLES {
                    return None;
                }
                let cat = |f: &dyn Fn(&VehicleSamples) -> &Vec<f64>| {
                    of.iter().flat_map(|v| f(v).iter().copied()).collect::<Vec<f64>>()
                };
                let (a, j, y) = (cat(&|v| &v.1), cat(&|v| &v.2), cat(&|v| &v.3));
                Some(ClassReference {
                    class,
                    vehicles: of.len(),
                    samples: a.len(),
                    accel_mps2: quantiles(&a)?,
                    jerk_mps3: quantiles(&j)?,
                    yaw_rate_radps: quantiles(&y)?,
                })
            })
            .collect();
        Self { format: REFERENCE_FORMAT.into(), version: REFERENCE_VERSION, provenance, dt_s, classes }
    }

    /// Checks format, version, period and every quantile list.
    pub fn validate(&self) -> Result<(), ReferenceError> {
        if self.format != REFERENCE_FORMAT || self.version != REFERENCE_VERSION {
            return Err(ReferenceError::Format { format: self.format.clone(), version: self.version });
        }
        let field = |field: String, reason: &str| ReferenceError::Field { field, reason: reason.into() };
        if !(self.dt_s.is_finite() && self.dt_s > 0.0 && self.dt_s <= 1.0) {
            return Err(field("dt_s".into(), "must lie in (0, 1] s"));
        }
        if self.provenance.trim().is_empty() {
            return Err(field("provenance".into(), "is empty: say where the recordings came from"));
        }
        for (i, c) in self.classes.iter().enumerate() {
            if self.classes.iter().take(i).any(|d| d.class == c.class) {
                return Err(field(format!("classes[{i}].class"), "given twice"));
            }
            for (name, q) in
                [("accel_mps2", &c.accel_mps2), ("jerk_mps3", &c.jerk_mps3), ("yaw_rate_radps", &c.yaw_rate_radps)]
            {
                let ok = q.len() == QUANTILES
                    && q.iter().all(|v| v.is_finite() && v.abs() <= 1e3)
                    && q.windows(2).all(|w| matches!(w, [a, b] if a <= b));
                if !ok {
                    return Err(field(
                        format!("classes[{i}].{name}"),
                        "needs 101 finite, non-decreasing quantiles within ±1000",
                    ));
                }
            }
        }
        Ok(())
    }

    /// The reference of `class`, if measured.
    pub fn class(&self, class: ManoeuvreClass) -> Option<&ClassReference> {
        self.classes.iter().find(|c| c.class == class)
    }

    /// How human `states` (sampled every `dt_s`) are, in their own class ([`ManoeuvreClass::of_states`]);
    /// `None` when the class has no reference or the trajectory has fewer than three states.
    pub fn measure(&self, states: &[State], dt_s: f64) -> Option<MotionRealism> {
        self.measure_as(ManoeuvreClass::of_states(states), states, dt_s)
    }

    /// [`Self::measure`] in a given class (the manoeuvre the vehicle's route asks for, which a run
    /// cut short by its duration may not complete).
    pub fn measure_as(&self, class: ManoeuvreClass, states: &[State], dt_s: f64) -> Option<MotionRealism> {
        let r = self.class(class)?;
        let (a, j, y) = motion_samples(states, dt_s);
        if j.is_empty() {
            return None;
        }
        let speeds: Vec<f64> = states.iter().map(|s| s.speed_mps).collect();
        Some(MotionRealism {
            class,
            w1_accel_mps2: w1_to_quantiles(&a, &r.accel_mps2)?,
            w1_jerk_mps3: w1_to_quantiles(&j, &r.jerk_mps3)?,
            w1_yaw_rate_radps: w1_to_quantiles(&y, &r.yaw_rate_radps)?,
            jerk_rms_mps3: (j.iter().map(|x| x * x).sum::<f64>() / j.len() as f64).sqrt(),
            speed_reversals: speed_reversals(&speeds),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn drive(speeds: &[f64], heading: impl Fn(usize) -> f64, dt: f64) -> Vec<State> {
        let mut x = 0.0;
        let mut y = 0.0;
        speeds
            .iter()
            .enumerate()
            .map(|(k, &v)| {
                let th = heading(k);
                let s = State { px: x, py: y, theta_rad: th, speed_mps: v };
                x += v * th.cos() * dt;
                y += v * th.sin() * dt;
                s
            })
            .collect()
    }

    #[test]
    fn w1_of_a_shifted_uniform_is_the_shift() {
        let reference: Vec<f64> = (0..QUANTILES).map(|k| k as f64 / 100.0).collect(); // U(0, 1)
        let run: Vec<f64> = (0..10_000).map(|k| 0.25 + (k as f64 + 0.5) / 10_000.0).collect(); // U(0.25, 1.25)
        let w = w1_to_quantiles(&run, &reference).unwrap();
        assert!((w - 0.25).abs() < 2e-3, "{w}");
        assert!(w1_to_quantiles(&reference, &reference).unwrap() < 0.01);
        assert_eq!(w1_to_quantiles(&[], &reference), None);
        assert_eq!(w1_to_quantiles(&[f64::NAN], &reference), None);
    }

    #[test]
    fn quantiles_of_known_samples() {
        let q = quantiles(&[3.0, 1.0, 2.0, f64::NAN]).unwrap();
        assert_eq!(q.len(), QUANTILES);
        assert_eq!((q[0], q[50], q[100]), (1.0, 2.0, 3.0));
        assert!((q[25] - 1.5).abs() < 1e-12);
        assert_eq!(quantiles(&[f64::INFINITY]), None);
    }

    #[test]
    fn speed_reversals_count_hurry_then_brake_only() {
        assert_eq!(speed_reversals(&[5.0, 6.0, 7.0, 6.0, 5.0, 6.0, 7.0, 6.0]), 2);
        assert_eq!(speed_reversals(&[5.0, 5.3, 5.0, 5.3, 5.0]), 0, "noise under 0.5 m/s");
        assert_eq!(speed_reversals(&[8.0, 7.0, 6.0, 5.0]), 0, "braking alone");
        assert_eq!(speed_reversals(&[]), 0);
    }

    #[test]
    fn classes_follow_the_path() {
        let dt = 0.1;
        let straight = drive(&[10.0; 60], |_| 0.3, dt);
        assert_eq!(ManoeuvreClass::of_states(&straight), ManoeuvreClass::Straight);
        let left = drive(&[8.0; 80], |k| (k as f64 / 79.0) * std::f64::consts::FRAC_PI_2, dt);
        assert_eq!(ManoeuvreClass::of_states(&left), ManoeuvreClass::LeftTurn);
        // A lane change: the heading swings up to 0.094 rad and back, about 3.5 m sideways over 60 m.
        let s = drive(&[12.0; 50], |k| 0.094 * (std::f64::consts::PI * k as f64 / 49.0).sin(), dt);
        let lateral = s.last().unwrap().py;
        assert!((2.0..=5.0).contains(&lateral), "{lateral}");
        assert_eq!(ManoeuvreClass::of_states(&s), ManoeuvreClass::LaneChange);
    }

    #[test]
    fn a_human_like_run_is_closer_than_a_jerky_one() {
        let dt = 0.1;
        // Human reference: gentle speed changes.
        let gentle: Vec<f64> = (0..200).map(|k| 10.0 + (k as f64 * 0.05).sin()).collect();
        let human = drive(&gentle, |_| 0.0, dt);
        let (a, j, y) = motion_samples(&human, dt);
        let five = vec![(ManoeuvreClass::Straight, a, j, y); MIN_VEHICLES];
        let reference = HumanReference::from_vehicles("made by this test".into(), dt, &five);
        reference.validate().unwrap();
        let same = reference.measure(&human, dt).unwrap();
        assert!(same.w1_accel_mps2 < 0.01 && same.w1_jerk_mps3 < 0.01, "{same:?}");
        // Bang-bang: ±2 m/s² every second.
        let jerky: Vec<f64> = (0..200)
            .map(|k| 10.0 + if (k / 10) % 2 == 0 { 0.2 * (k % 10) as f64 } else { 2.0 - 0.2 * (k % 10) as f64 })
            .collect();
        let run = reference.measure(&drive(&jerky, |_| 0.0, dt), dt).unwrap();
        assert!(run.w1_accel_mps2 > 1.0 && run.jerk_rms_mps3 > same.jerk_rms_mps3, "{run:?}");
        assert_eq!(run.speed_reversals, 10, "one per 2 s period");
        assert_eq!(reference.measure(&drive(&[8.0; 80], |k| k as f64 / 40.0, dt), dt), None, "no left-turn reference");
    }

    #[test]
    fn malformed_references_are_named() {
        let one = (ManoeuvreClass::Straight, vec![0.0, 1.0], vec![0.0], vec![0.0]);
        let alone = HumanReference::from_vehicles("p".into(), 0.1, std::slice::from_ref(&one));
        assert!(alone.classes.is_empty(), "one vehicle is no reference");
        let mut r = HumanReference::from_vehicles("p".into(), 0.1, &vec![one; MIN_VEHICLES]);
        r.validate().unwrap();
        r.classes[0].jerk_mps3[3] = f64::NAN;
        assert!(
            matches!(r.validate(), Err(ReferenceError::Field { ref field, .. }) if field == "classes[0].jerk_mps3")
        );
        r.classes[0].jerk_mps3[3] = 0.0;
        r.classes.push(r.classes[0].clone());
        assert!(r.validate().is_err());
        r.classes.pop();
        r.version = 2;
        assert!(matches!(r.validate(), Err(ReferenceError::Format { .. })));
    }

    proptest! {
        #[test]
        fn w1_is_symmetric_in_a_shift_and_zero_to_itself(shift in -5.0f64..5.0, spread in 0.1f64..3.0) {
            let base: Vec<f64> = (0..2000).map(|k| spread * ((k as f64 + 0.5) / 2000.0 - 0.5)).collect();
            let q = quantiles(&base).unwrap();
            let moved: Vec<f64> = base.iter().map(|x| x + shift).collect();
            let w = w1_to_quantiles(&moved, &q).unwrap();
            prop_assert!((w - shift.abs()).abs() < 0.01 * spread + 1e-9, "{} vs {}", w, shift.abs());
            prop_assert!(w1_to_quantiles(&base, &q).unwrap() < 0.01 * spread + 1e-9);
        }
    }
}
