//! The BV's reference timing: the prior's arc length and speed over time along the BV's path,
//! what the realism term of the regulator weighs (see [`crate::regulator`]).
//!
//! Stored in buffers allocated once when the regulator is built ([`MAX_REFERENCE_SAMPLES`]);
//! setting a new reference copies into them, and every query is a binary search: no allocation.

use v2t_model::validate::ValidationError;

/// Most samples a reference may hold (the prior's wire format carries at most 512).
pub const MAX_REFERENCE_SAMPLES: usize = 4096;
/// Slowest speed at which the reference is extrapolated beyond its ends, m/s: a reference that
/// ends at a standstill never reaches a station beyond its end.
const EXTRAPOLATE_MIN_MPS: f64 = 0.1;
/// Largest arc length or time a sample may carry (m, s): a test track is far smaller.
const MAX_ABS: f64 = 1e6;

/// One sample of a reference: time since its start, arc length along the BV's path, speed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReferenceSample {
    /// Time since the start of the reference, s.
    pub t_s: f64,
    /// Arc length along the BV's path, m.
    pub s_m: f64,
    /// Speed, m/s.
    pub v_mps: f64,
}

/// The prior's timing along the BV's path: time strictly increasing, arc length non-decreasing.
#[derive(Debug, Clone)]
pub struct ReferenceTiming {
    t: Vec<f64>,
    s: Vec<f64>,
    v: Vec<f64>,
}

impl Default for ReferenceTiming {
    fn default() -> Self {
        Self {
            t: Vec::with_capacity(MAX_REFERENCE_SAMPLES),
            s: Vec::with_capacity(MAX_REFERENCE_SAMPLES),
            v: Vec::with_capacity(MAX_REFERENCE_SAMPLES),
        }
    }
}

impl ReferenceTiming {
    /// Whether a reference is set.
    pub fn is_set(&self) -> bool {
        self.t.len() >= 2
    }

    /// Forgets the reference.
    pub fn clear(&mut self) {
        self.t.clear();
        self.s.clear();
        self.v.clear();
    }

    /// Replaces the reference with `samples`: at least 2 and at most [`MAX_REFERENCE_SAMPLES`],
    /// finite, time strictly increasing, arc length non-decreasing (a small step back, as a
    /// rounded recording has, is held at the largest arc length so far), speed ≥ 0. The samples
    /// are checked before anything changes: on an error the reference is the one before, and the
    /// error names the sample and the bound.
    pub fn set<I>(&mut self, samples: I) -> Result<(), ValidationError>
    where
        I: IntoIterator<Item = ReferenceSample>,
        I::IntoIter: Clone,
    {
        let samples = samples.into_iter();
        Self::check(samples.clone())?;
        self.clear();
        for q in samples {
            let s = self.s.last().map_or(q.s_m, |&prev| q.s_m.max(prev));
            self.t.push(q.t_s);
            self.s.push(s);
            self.v.push(q.v_mps);
        }
        Ok(())
    }

    fn check(samples: impl Iterator<Item = ReferenceSample>) -> Result<(), ValidationError> {
        let mut t_prev: Option<f64> = None;
        let mut n = 0;
        for (i, q) in samples.enumerate() {
            let field = |name: &str| format!("reference[{i}].{name}");
            if i >= MAX_REFERENCE_SAMPLES {
                return Err(ValidationError::new(
                    "reference",
                    format!("holds more than {MAX_REFERENCE_SAMPLES} samples"),
                ));
            }
            for (name, x) in [("t_s", q.t_s), ("s_m", q.s_m), ("v_mps", q.v_mps)] {
                if !x.is_finite() || x.abs() > MAX_ABS {
                    return Err(ValidationError::new(
                        field(name),
                        format!("must be finite within ±{MAX_ABS}, got {x}"),
                    ));
                }
            }
            if q.v_mps < 0.0 {
                return Err(ValidationError::new(field("v_mps"), format!("must be ≥ 0, got {}", q.v_mps)));
            }
            if let Some(prev) = t_prev
                && q.t_s <= prev
            {
                return Err(ValidationError::new(field("t_s"), format!("must increase, got {} after {prev}", q.t_s)));
            }
            t_prev = Some(q.t_s);
            n = i + 1;
        }
        if n < 2 {
            return Err(ValidationError::new("reference", "needs at least 2 samples"));
        }
        Ok(())
    }

    /// When the reference first reaches arc length `s_m`, s since its start: interpolated between
    /// samples, extrapolated beyond the ends at the end speeds; `None` without a reference, or when
    /// `s_m` lies beyond the end of a reference that ends (nearly) standing.
    pub fn time_at_station(&self, s_m: f64) -> Option<f64> {
        let (&t0, &s0, &v0) = (self.t.first()?, self.s.first()?, self.v.first()?);
        let (&t1, &s1, &v1) = (self.t.last()?, self.s.last()?, self.v.last()?);
        if self.t.len() < 2 || !s_m.is_finite() {
            return None;
        }
        if s_m <= s0 {
            return Some(t0 - (s0 - s_m) / v0.max(EXTRAPOLATE_MIN_MPS));
        }
        if s_m > s1 {
            return (v1 >= EXTRAPOLATE_MIN_MPS).then(|| t1 + (s_m - s1) / v1);
        }
        // First sample at or beyond s_m (exists: s_m ≤ s1); the one before it is below s_m.
        let k = self.s.partition_point(|&s| s < s_m);
        let (ta, sa) = (*self.t.get(k.checked_sub(1)?)?, *self.s.get(k - 1)?);
        let (tb, sb) = (*self.t.get(k)?, *self.s.get(k)?);
        Some(if sb > sa { ta + (tb - ta) * (s_m - sa) / (sb - sa) } else { tb })
    }

    /// The reference speed at `t_s` since its start, m/s (linear between samples; the ends hold;
    /// 0 without a reference).
    pub fn speed_at_time(&self, t_s: f64) -> f64 {
        self.interpolate_speed(t_s).unwrap_or(0.0)
    }

    fn interpolate_speed(&self, t_s: f64) -> Option<f64> {
        let (&t0, &v0, &t1, &v1) = (self.t.first()?, self.v.first()?, self.t.last()?, self.v.last()?);
        if t_s <= t0 {
            return Some(v0);
        }
        if t_s >= t1 {
            return Some(v1);
        }
        let k = self.t.partition_point(|&t| t <= t_s);
        let (ta, va) = (*self.t.get(k.checked_sub(1)?)?, *self.v.get(k - 1)?);
        let (tb, vb) = (*self.t.get(k)?, *self.v.get(k)?);
        Some(va + (vb - va) * (t_s - ta) / (tb - ta))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn constant(v: f64, n: usize) -> ReferenceTiming {
        let mut r = ReferenceTiming::default();
        r.set((0..n).map(|k| {
            let t = k as f64 * 0.1;
            ReferenceSample { t_s: t, s_m: v * t, v_mps: v }
        }))
        .unwrap();
        r
    }

    #[test]
    fn a_constant_speed_reference_reaches_each_station_at_distance_over_speed() {
        let r = constant(10.0, 101);
        assert!((r.time_at_station(25.0).unwrap() - 2.5).abs() < 1e-9);
        // Beyond the end (100 m at 10 s) at the end speed, before the start at the start speed.
        assert!((r.time_at_station(150.0).unwrap() - 15.0).abs() < 1e-9);
        assert!((r.time_at_station(-10.0).unwrap() + 1.0).abs() < 1e-9);
        assert!((r.speed_at_time(3.33) - 10.0).abs() < 1e-12);
    }

    #[test]
    fn a_standstill_is_reached_first_and_never_passed() {
        // 10 m/s for 1 s, then standing at 10 m from t = 2 s.
        let mut r = ReferenceTiming::default();
        r.set(
            [(0.0, 0.0, 10.0), (1.0, 10.0, 0.0), (2.0, 10.0, 0.0), (3.0, 10.0, 0.0)].map(|(t, s, v)| ReferenceSample {
                t_s: t,
                s_m: s,
                v_mps: v,
            }),
        )
        .unwrap();
        assert!((r.time_at_station(10.0).unwrap() - 1.0).abs() < 1e-9);
        assert_eq!(r.time_at_station(10.5), None, "it never gets beyond where it stops");
    }

    #[test]
    fn bad_samples_are_refused_with_the_field() {
        let mut r = ReferenceTiming::default();
        let q = |t, s, v| ReferenceSample { t_s: t, s_m: s, v_mps: v };
        let e = r.set([q(0.0, 0.0, 1.0), q(0.0, 1.0, 1.0)]).unwrap_err();
        assert!(e.to_string().contains("reference[1].t_s"), "{e}");
        let e = r.set([q(0.0, 0.0, 1.0), q(0.1, f64::NAN, 1.0)]).unwrap_err();
        assert!(e.to_string().contains("reference[1].s_m"), "{e}");
        let e = r.set([q(0.0, 0.0, -1.0), q(0.1, 0.0, 1.0)]).unwrap_err();
        assert!(e.to_string().contains("reference[0].v_mps"), "{e}");
        assert!(r.set([q(0.0, 0.0, 1.0)]).is_err());
        assert!(!r.is_set(), "nothing was set");
        r.set([q(0.0, 0.0, 2.0), q(1.0, 2.0, 2.0)]).unwrap();
        assert!(r.set([q(0.0, 0.0, 1.0), q(0.0, 1.0, 1.0)]).is_err());
        assert!((r.time_at_station(1.0).unwrap() - 0.5).abs() < 1e-12, "a refused reference keeps the one before");
        let e = r.set((0..=MAX_REFERENCE_SAMPLES).map(|k| q(k as f64, k as f64, 1.0))).unwrap_err();
        assert!(e.to_string().contains("4096"), "{e}");
    }

    proptest! {
        #[test]
        fn time_at_station_inverts_the_arc_length(speeds in proptest::collection::vec(0.5f64..20.0, 2..60), frac in 0.0f64..1.0) {
            let mut s = 0.0;
            let mut samples = Vec::new();
            for (k, &v) in speeds.iter().enumerate() {
                samples.push(ReferenceSample { t_s: k as f64 * 0.1, s_m: s, v_mps: v });
                s += v * 0.1;
            }
            let mut r = ReferenceTiming::default();
            r.set(samples.iter().copied()).unwrap();
            let end = samples.last().unwrap().s_m;
            let target = frac * end;
            let t = r.time_at_station(target).unwrap();
            // The arc length at `t`, interpolated back, is the station asked for.
            let k = samples.partition_point(|q| q.t_s <= t).clamp(1, samples.len() - 1);
            let (a, b) = (samples[k - 1], samples[k]);
            let s_at = a.s_m + (b.s_m - a.s_m) * (t - a.t_s) / (b.t_s - a.t_s);
            prop_assert!((s_at - target).abs() < 1e-6);
            prop_assert!(t >= 0.0 && t <= samples.last().unwrap().t_s + 1e-9);
        }
    }
}
