//! How this VUT drives its route: the speed it had at each point of its route in earlier runs of
//! the same test, the follower's free motion once it is known.
//!
//! The regulator's follower (the VUT's best response, [`crate::regulator`]) tracks the speed the
//! VUT has now. A VUT that slows down for its junction or its turn (SUMO's IDM slows from 8 to
//! 4.3 m/s before it turns left, whatever the BV does) then arrives later than predicted, and it
//! does so after the BV has had to commit: every PET comes out about a second long. Within one run
//! that slowdown cannot be seen in time; after one run it has been seen. A [`RouteSpeed`] is that
//! observation: the VUT's speed on a fixed grid of its route's arc length (every
//! [`ROUTE_STEP_M`] from its start), the fastest it drove each point in the valid runs
//! ([`RouteSpeed::merge`]), kept by the campaign memory ([`crate::campaign`]) and given to the
//! regulator for the next run ([`crate::regulator::Regulator::set_route_speed`]).
//!
//! **How the follower uses it.** Its speed reference from where the VUT is becomes the learned
//! speed along its predicted way, plus the VUT's deviation from it now (measured speed minus the
//! learned speed here), fading with [`DEVIATION_FADE_S`]: a VUT that comes faster or slower than
//! last time is believed for the next seconds, and the learned shape of its approach after that.
//! A VUT that stands is predicted to keep standing, as without a learned speed (the rule that a
//! standing VUT waits for the BV stays).
//!
//! What a run shows is only recorded up to where the VUT stood still ([`RouteSpeed::from_samples`]):
//! how long a VUT waited is not a speed along its route.
//!
//! Pure; the grid is allocated when it is learned or set, never per decision.

use serde::{Deserialize, Serialize};
use v2t_model::validate::{Validate, ValidationError, in_range};

/// Spacing of the grid, m.
pub const ROUTE_STEP_M: f64 = 2.0;
/// The longest stretch of route kept, m (from the route's start).
pub const ROUTE_MAX_M: f64 = 1000.0;
/// Most grid points (`ROUTE_MAX_M / ROUTE_STEP_M + 1`).
pub const ROUTE_MAX_POINTS: usize = 501;
/// Valid runs counted in a record (it says how many runs a learned speed rests on, up to this).
pub const ROUTE_RUNS: u32 = 1000;
/// How long the VUT's deviation from its learned speed is believed, s (it fades as `exp(−t/T)`).
pub const DEVIATION_FADE_S: f64 = 2.0;
/// A VUT at or below this speed stands: the record of a run stops there, m/s.
pub const STANDING_MPS: f64 = 0.5;
/// The fastest speed a record may hold, m/s.
const MAX_SPEED_MPS: f64 = 70.0;

/// The VUT's speed at `i · step_m` of its route, `i = 0, 1, …`, learned over `runs` runs.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RouteSpeed {
    /// Grid spacing, m.
    pub step_m: f64,
    /// Speed at each grid point, m/s (the first at arc length 0).
    pub speeds_mps: Vec<f64>,
    /// Valid runs it was learned from, counted up to [`ROUTE_RUNS`].
    pub runs: u32,
}

impl RouteSpeed {
    /// What one run shows: the VUT's speed where it first passed each grid point, from its
    /// samples `(arc length, speed)` in time order, up to `until_s_m` (its zone's exit is enough:
    /// the follower looks no farther), and never beyond the first point where it stood or where
    /// the samples end. Linear between samples. `None` when it covers less than two grid points
    /// or a sample is not finite.
    pub fn from_samples(samples: impl IntoIterator<Item = (f64, f64)>, until_s_m: f64) -> Option<Self> {
        let until = until_s_m.min(ROUTE_MAX_M);
        let mut speeds = Vec::new();
        let mut prev: Option<(f64, f64)> = None;
        for (s, v) in samples {
            if !s.is_finite() || !v.is_finite() {
                return None;
            }
            if v <= STANDING_MPS {
                break;
            }
            let next = speeds.len() as f64 * ROUTE_STEP_M;
            match prev {
                None if s > next + ROUTE_STEP_M => return None, // it was first seen past the start
                None => {}
                Some((s0, v0)) => {
                    let mut g = speeds.len() as f64 * ROUTE_STEP_M;
                    while g <= s && g <= until && speeds.len() < ROUTE_MAX_POINTS {
                        let v_g = if s > s0 { v0 + (v - v0) * ((g - s0) / (s - s0)).clamp(0.0, 1.0) } else { v };
                        speeds.push(v_g.min(MAX_SPEED_MPS));
                        g += ROUTE_STEP_M;
                    }
                }
            }
            prev = Some((s, v));
            if s > until {
                break;
            }
        }
        (speeds.len() >= 2).then_some(Self { step_m: ROUTE_STEP_M, speeds_mps: speeds, runs: 1 })
    }

    /// This learned speed with one more run's, over the stretch both cover: the faster of the two
    /// at each point. A VUT that slowed down for the BV in one run (a reaction, which the next
    /// run's BV would then meet later still) does not teach that it slows there on its own; what
    /// it does on its own (a slowdown for its turn) it does in every run.
    pub fn merge(&mut self, run: &RouteSpeed) {
        let len = self.speeds_mps.len().min(run.speeds_mps.len());
        self.speeds_mps.truncate(len);
        for (v, r) in self.speeds_mps.iter_mut().zip(&run.speeds_mps) {
            *v = v.max(*r);
        }
        self.runs = (self.runs + 1).min(ROUTE_RUNS);
    }

    /// The learned speed at arc length `s_m` (linear between grid points), `None` outside the
    /// grid.
    pub fn speed_at(&self, s_m: f64) -> Option<f64> {
        if s_m.is_nan() || s_m < 0.0 {
            return None;
        }
        let x = s_m / self.step_m;
        let i = x.floor() as usize;
        let a = *self.speeds_mps.get(i)?;
        match self.speeds_mps.get(i + 1) {
            Some(b) => Some(a + (b - a) * (x - i as f64)),
            None => (x - i as f64 <= f64::EPSILON).then_some(a),
        }
    }

    /// Where the grid ends, m.
    pub fn end_m(&self) -> f64 {
        self.speeds_mps.len().saturating_sub(1) as f64 * self.step_m
    }

    /// The slowest learned speed and where, (m, m/s).
    pub fn slowest(&self) -> Option<(f64, f64)> {
        self.speeds_mps.iter().enumerate().min_by(|a, b| a.1.total_cmp(b.1)).map(|(i, v)| (i as f64 * self.step_m, *v))
    }
}

impl Validate for RouteSpeed {
    fn validate(&self) -> Result<(), ValidationError> {
        in_range("step_m", self.step_m, 0.5, 10.0)?;
        if !(2..=ROUTE_MAX_POINTS).contains(&self.speeds_mps.len()) {
            return Err(ValidationError::new(
                "speeds_mps",
                format!("must hold 2 to {ROUTE_MAX_POINTS} speeds, got {}", self.speeds_mps.len()),
            ));
        }
        for (i, v) in self.speeds_mps.iter().enumerate() {
            in_range(&format!("speeds_mps[{i}]"), *v, 0.0, MAX_SPEED_MPS)?;
        }
        if !(1..=ROUTE_RUNS).contains(&self.runs) {
            return Err(ValidationError::new("runs", format!("must lie in [1, {ROUTE_RUNS}], got {}", self.runs)));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// A VUT at 8 m/s that slows to 4 m/s between 40 and 60 m, sampled every 0.1 s.
    fn slowing() -> Vec<(f64, f64)> {
        let (mut s, mut out) = (0.0, Vec::new());
        while s < 100.0 {
            let v = if s < 40.0 {
                8.0
            } else if s < 60.0 {
                8.0 - 4.0 * (s - 40.0) / 20.0
            } else {
                4.0
            };
            out.push((s, v));
            s += v * 0.1;
        }
        out
    }

    #[test]
    fn a_run_is_read_on_the_grid_up_to_the_asked_station() {
        let r = RouteSpeed::from_samples(slowing(), 70.0).unwrap();
        assert_eq!(r.speeds_mps.len(), 36, "0, 2, …, 70 m");
        assert!((r.speed_at(20.0).unwrap() - 8.0).abs() < 1e-9);
        assert!((r.speed_at(50.0).unwrap() - 6.0).abs() < 0.05);
        assert!((r.speed_at(69.0).unwrap() - 4.0).abs() < 1e-9);
        assert_eq!(r.speed_at(71.0), None);
        assert_eq!(r.speed_at(-1.0), None);
        assert_eq!(r.slowest().map(|(s, v)| (s >= 60.0, v)), Some((true, 4.0)));
    }

    #[test]
    fn a_run_stops_where_the_vut_stood() {
        let mut samples = slowing();
        samples.retain(|(s, _)| *s < 30.0);
        samples.extend([(30.0, 0.2), (30.0, 0.0), (31.0, 3.0), (40.0, 8.0)]);
        let r = RouteSpeed::from_samples(samples, 100.0).unwrap();
        assert!(r.end_m() < 30.0, "ends before the standstill at 30 m, not {}", r.end_m());
        assert!(RouteSpeed::from_samples([(0.0, 0.0), (5.0, 5.0)], 50.0).is_none(), "stood at its start");
        assert!(RouteSpeed::from_samples([(0.0, 5.0), (f64::NAN, 5.0)], 50.0).is_none());
        assert!(RouteSpeed::from_samples([(20.0, 5.0), (30.0, 5.0)], 50.0).is_none(), "first seen past the start");
    }

    #[test]
    fn the_learned_speed_is_the_fastest_seen_over_the_common_stretch() {
        let mut r = RouteSpeed { step_m: 2.0, speeds_mps: vec![8.0; 10], runs: 1 };
        let mut slower = vec![8.0; 8];
        slower[5] = 4.0; // it braked for the BV in this run
        r.merge(&RouteSpeed { step_m: 2.0, speeds_mps: slower, runs: 1 });
        assert_eq!((r.speeds_mps.len(), r.runs), (8, 2));
        assert_eq!(r.speeds_mps[5], 8.0, "a slowdown seen once is not learned as its own");
        let mut faster = vec![8.0; 8];
        faster[2] = 9.0;
        r.merge(&RouteSpeed { step_m: 2.0, speeds_mps: faster, runs: 1 });
        assert_eq!((r.speeds_mps[2], r.runs), (9.0, 3));
    }

    #[test]
    fn a_bad_record_is_refused_naming_the_field() {
        let mut r = RouteSpeed { step_m: 2.0, speeds_mps: vec![8.0; 10], runs: 1 };
        assert!(r.validate().is_ok());
        r.speeds_mps[3] = f64::NAN;
        assert!(r.validate().unwrap_err().to_string().contains("speeds_mps[3]"));
        r.speeds_mps = vec![1.0];
        assert!(r.validate().unwrap_err().to_string().contains("speeds_mps"));
        r = RouteSpeed { step_m: 2.0, speeds_mps: vec![8.0; 3], runs: 0 };
        assert!(r.validate().unwrap_err().to_string().contains("runs"));
    }

    proptest! {
        #[test]
        fn the_record_lies_within_the_speeds_it_was_read_from(
            speeds in proptest::collection::vec(0.6f64..30.0, 2..200),
            until in 0.0f64..500.0,
        ) {
            let mut s = 0.0;
            let samples: Vec<(f64, f64)> = speeds.iter().map(|&v| { let q = (s, v); s += v * 0.1; q }).collect();
            let (lo, hi) = speeds.iter().fold((f64::INFINITY, 0.0f64), |(l, h), &v| (l.min(v), h.max(v)));
            if let Some(r) = RouteSpeed::from_samples(samples, until) {
                prop_assert!(r.validate().is_ok());
                prop_assert!(r.end_m() <= until.max(0.0) + 1e-9);
                for v in &r.speeds_mps {
                    prop_assert!(*v >= lo - 1e-9 && *v <= hi + 1e-9);
                }
            }
        }
    }
}
