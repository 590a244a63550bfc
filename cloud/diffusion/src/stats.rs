//! Statistics for realism checks: histograms and the Wasserstein-1 distance between empirical
//! one-dimensional distributions of acceleration, jerk and yaw rate.
//!
//! For two empirical distributions with CDFs `F` and `G`, `W₁ = ∫ |F(x) − G(x)| dx`: the mean
//! distance samples must move to turn one into the other, in the samples' own unit. Both inputs
//! are sorted once and the integral is taken exactly over the merged breakpoints, O((n + m) log).

use serde::{Deserialize, Serialize};
use v2t_model::kinematics::Control;

/// A fixed-bin histogram with underflow and overflow counts.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Histogram {
    /// Lower edge of the first bin.
    pub lo: f64,
    /// Upper edge of the last bin.
    pub hi: f64,
    /// Counts per bin (equal widths).
    pub counts: Vec<u64>,
    /// Samples below `lo`.
    pub underflow: u64,
    /// Samples at or above `hi`.
    pub overflow: u64,
    /// Non-finite samples (not binned).
    pub non_finite: u64,
}

impl Histogram {
    /// An empty histogram of `bins` equal bins over `[lo, hi)`; `None` unless `lo < hi` (finite)
    /// and `bins ≥ 1`.
    pub fn new(lo: f64, hi: f64, bins: usize) -> Option<Self> {
        (lo.is_finite() && hi.is_finite() && lo < hi && bins >= 1).then(|| Self {
            lo,
            hi,
            counts: vec![0; bins],
            underflow: 0,
            overflow: 0,
            non_finite: 0,
        })
    }

    /// Counts one sample.
    pub fn add(&mut self, x: f64) {
        if !x.is_finite() {
            self.non_finite += 1;
        } else if x < self.lo {
            self.underflow += 1;
        } else if x >= self.hi {
            self.overflow += 1;
        } else {
            let n = self.counts.len();
            let k = (((x - self.lo) / (self.hi - self.lo)) * n as f64).floor() as usize;
            if let Some(c) = self.counts.get_mut(k.min(n.saturating_sub(1))) {
                *c += 1;
            }
        }
    }

    /// Counts every sample.
    pub fn extend(&mut self, xs: impl IntoIterator<Item = f64>) {
        for x in xs {
            self.add(x);
        }
    }

    /// Total samples counted (binned, under- and overflow; not the non-finite).
    pub fn total(&self) -> u64 {
        self.counts.iter().sum::<u64>() + self.underflow + self.overflow
    }

    /// Centre of bin `k`.
    pub fn bin_centre(&self, k: usize) -> f64 {
        self.lo + (k as f64 + 0.5) * (self.hi - self.lo) / self.counts.len().max(1) as f64
    }
}

/// Wasserstein-1 distance between the empirical distributions of `a` and `b`; `None` if either is
/// empty or holds a non-finite value.
pub fn wasserstein1(a: &[f64], b: &[f64]) -> Option<f64> {
    if a.is_empty() || b.is_empty() || a.iter().chain(b).any(|x| !x.is_finite()) {
        return None;
    }
    let mut a = a.to_vec();
    let mut b = b.to_vec();
    a.sort_by(f64::total_cmp);
    b.sort_by(f64::total_cmp);
    let (na, nb) = (a.len() as f64, b.len() as f64);
    let (mut i, mut j) = (0usize, 0usize);
    let mut x = a.first().copied().unwrap_or(0.0).min(b.first().copied().unwrap_or(0.0));
    let mut total = 0.0;
    loop {
        let next = match (a.get(i), b.get(j)) {
            (Some(&p), Some(&q)) => p.min(q),
            (Some(&p), None) => p,
            (None, Some(&q)) => q,
            (None, None) => break,
        };
        total += ((i as f64 / na) - (j as f64 / nb)).abs() * (next - x);
        x = next;
        while a.get(i).is_some_and(|&p| p <= x) {
            i += 1;
        }
        while b.get(j).is_some_and(|&q| q <= x) {
            j += 1;
        }
    }
    Some(total)
}

/// Median of `v` (sorted in place), `None` if empty.
pub fn median(v: &mut [f64]) -> Option<f64> {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n == 0 {
        return None;
    }
    if n % 2 == 1 { v.get(n / 2).copied() } else { Some(0.5 * (v.get(n / 2 - 1)? + v.get(n / 2)?)) }
}

/// Acceleration, jerk and yaw-rate samples of control sequences at period `dt_s`.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct ControlSamples {
    /// Accelerations, m/s².
    pub accel_mps2: Vec<f64>,
    /// Jerks `(a_{k+1} − a_k)/dt`, m/s³.
    pub jerk_mps3: Vec<f64>,
    /// Yaw rates, rad/s.
    pub yaw_rate_radps: Vec<f64>,
}

impl ControlSamples {
    /// Adds one control sequence.
    pub fn add_sequence(&mut self, controls: &[Control], dt_s: f64) {
        self.accel_mps2.extend(controls.iter().map(|u| u.accel_mps2));
        self.yaw_rate_radps.extend(controls.iter().map(|u| u.yaw_rate_radps));
        if dt_s > 0.0 {
            self.jerk_mps3.extend(controls.windows(2).filter_map(|w| match w {
                [u, v] => Some((v.accel_mps2 - u.accel_mps2) / dt_s),
                _ => None,
            }));
        }
    }

    /// Histograms over fixed ranges: acceleration ±8 m/s² (0.25), jerk ±20 m/s³ (0.5), yaw rate
    /// ±1 rad/s (0.025).
    pub fn histograms(&self) -> ControlHistograms {
        let mk = |lo: f64, hi: f64, bins: usize, xs: &[f64]| {
            let mut h = Histogram { lo, hi, counts: vec![0; bins], underflow: 0, overflow: 0, non_finite: 0 };
            h.extend(xs.iter().copied());
            h
        };
        ControlHistograms {
            accel: mk(-8.0, 8.0, 64, &self.accel_mps2),
            jerk: mk(-20.0, 20.0, 80, &self.jerk_mps3),
            yaw_rate: mk(-1.0, 1.0, 80, &self.yaw_rate_radps),
        }
    }

    /// Adds every sample of `other`.
    pub fn extend(&mut self, other: &Self) {
        self.accel_mps2.extend_from_slice(&other.accel_mps2);
        self.jerk_mps3.extend_from_slice(&other.jerk_mps3);
        self.yaw_rate_radps.extend_from_slice(&other.yaw_rate_radps);
    }

    /// Root mean square per quantity (`None` where there is no sample): with W₁ it says in which
    /// direction two distributions differ (a rougher or a calmer driver).
    pub fn rms(&self) -> ControlDistances {
        let rms =
            |xs: &[f64]| (!xs.is_empty()).then(|| (xs.iter().map(|x| x * x).sum::<f64>() / xs.len() as f64).sqrt());
        ControlDistances {
            accel_mps2: rms(&self.accel_mps2),
            jerk_mps3: rms(&self.jerk_mps3),
            yaw_rate_radps: rms(&self.yaw_rate_radps),
        }
    }

    /// W₁ distance to `other` per quantity (`None` where either side has no samples).
    pub fn distance(&self, other: &Self) -> ControlDistances {
        ControlDistances {
            accel_mps2: wasserstein1(&self.accel_mps2, &other.accel_mps2),
            jerk_mps3: wasserstein1(&self.jerk_mps3, &other.jerk_mps3),
            yaw_rate_radps: wasserstein1(&self.yaw_rate_radps, &other.yaw_rate_radps),
        }
    }
}

/// Histograms of [`ControlSamples`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ControlHistograms {
    /// Acceleration, m/s².
    pub accel: Histogram,
    /// Jerk, m/s³.
    pub jerk: Histogram,
    /// Yaw rate, rad/s.
    pub yaw_rate: Histogram,
}

/// W₁ distances between two sets of control samples.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ControlDistances {
    /// Acceleration, m/s².
    pub accel_mps2: Option<f64>,
    /// Jerk, m/s³.
    pub jerk_mps3: Option<f64>,
    /// Yaw rate, rad/s.
    pub yaw_rate_radps: Option<f64>,
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn histogram_bins_and_overflows() {
        let mut h = Histogram::new(0.0, 1.0, 4).unwrap();
        h.extend([0.0, 0.1, 0.3, 0.99, 1.0, -0.1, f64::NAN]);
        assert_eq!(h.counts, vec![2, 1, 0, 1]);
        assert_eq!((h.underflow, h.overflow, h.non_finite, h.total()), (1, 1, 1, 6));
        assert!((h.bin_centre(1) - 0.375).abs() < 1e-12);
        assert!(Histogram::new(1.0, 1.0, 3).is_none() && Histogram::new(0.0, f64::NAN, 3).is_none());
    }

    #[test]
    fn known_distances() {
        assert_eq!(wasserstein1(&[0.0], &[1.0]), Some(1.0));
        assert!((wasserstein1(&[0.0, 1.0], &[0.0]).unwrap() - 0.5).abs() < 1e-12);
        assert!((wasserstein1(&[0.0, 0.0, 3.0], &[1.0]).unwrap() - (2.0 / 3.0 + 2.0 / 3.0)).abs() < 1e-12);
        assert_eq!(wasserstein1(&[], &[1.0]), None);
        assert_eq!(wasserstein1(&[f64::NAN], &[1.0]), None);
    }

    #[test]
    fn control_samples_give_jerk() {
        let u = [0.0, 1.0, 3.0].map(|a| Control { accel_mps2: a, yaw_rate_radps: 0.1 });
        let mut s = ControlSamples::default();
        s.add_sequence(&u, 0.1);
        assert_eq!(s.jerk_mps3.len(), 2);
        assert!((s.jerk_mps3[1] - 20.0).abs() < 1e-9);
        let d = s.distance(&s);
        assert_eq!(d.accel_mps2, Some(0.0));
        assert_eq!(s.histograms().accel.total(), 3);
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(128))]
        #[test]
        fn identical_samples_are_at_zero(a in prop::collection::vec(-100.0f64..100.0, 1..60)) {
            prop_assert!(wasserstein1(&a, &a).unwrap().abs() < 1e-9);
            let mut shuffled = a.clone();
            shuffled.reverse();
            prop_assert!(wasserstein1(&a, &shuffled).unwrap().abs() < 1e-9);
        }

        #[test]
        fn a_shift_moves_by_its_size(a in prop::collection::vec(-100.0f64..100.0, 1..60), c in -50.0f64..50.0) {
            let b: Vec<f64> = a.iter().map(|x| x + c).collect();
            let d = wasserstein1(&a, &b).unwrap();
            prop_assert!((d - c.abs()).abs() < 1e-9 * (1.0 + c.abs()) * a.len() as f64, "{d} vs {c}");
        }

        #[test]
        fn symmetric_and_triangle(
            a in prop::collection::vec(-10.0f64..10.0, 1..40),
            b in prop::collection::vec(-10.0f64..10.0, 1..40),
            c in prop::collection::vec(-10.0f64..10.0, 1..40),
        ) {
            let ab = wasserstein1(&a, &b).unwrap();
            prop_assert!((ab - wasserstein1(&b, &a).unwrap()).abs() < 1e-9);
            prop_assert!(ab >= 0.0);
            prop_assert!(ab <= wasserstein1(&a, &c).unwrap() + wasserstein1(&c, &b).unwrap() + 1e-9);
            // For equal sizes W₁ is the mean distance between sorted pairs.
            if a.len() == b.len() {
                let (mut x, mut y) = (a.clone(), b.clone());
                x.sort_by(f64::total_cmp);
                y.sort_by(f64::total_cmp);
                let pairs = x.iter().zip(&y).map(|(p, q)| (p - q).abs()).sum::<f64>() / x.len() as f64;
                prop_assert!((ab - pairs).abs() < 1e-9);
            }
        }
    }
}
