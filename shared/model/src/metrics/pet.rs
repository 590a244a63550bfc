//! Post-encroachment time from recorded or predicted passages through a conflict zone.

use serde::{Deserialize, Serialize};

use super::OccupancyInterval;

/// One of the two vehicles of a conflict zone (the one on path `a` or on path `b`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Side {
    /// The vehicle on path `a`.
    A,
    /// The vehicle on path `b`.
    B,
}

/// When one vehicle entered and left a zone.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Passage {
    /// Entry time, s.
    pub enter_t_s: f64,
    /// Exit time, s; `None` while still inside at the end of the record.
    pub exit_t_s: Option<f64>,
}

/// Time at which the samples `(t, s)` first reach `target`, interpolated linearly, searching from
/// sample `from`. Returns the time and the index of the first sample at or beyond `target`.
fn first_crossing(times: &[f64], s: &[f64], target: f64, from: usize) -> Option<(f64, usize)> {
    let k = (from..s.len()).find(|&k| s.get(k).is_some_and(|v| *v >= target))?;
    let (tk, sk) = (*times.get(k)?, *s.get(k)?);
    if k == from {
        return Some((tk, k));
    }
    let (tp, sp) = (*times.get(k - 1)?, *s.get(k - 1)?);
    let ds = sk - sp;
    let t = if ds > 0.0 { tp + (tk - tp) * (target - sp) / ds } else { tk };
    Some((t, k))
}

/// The passage of a vehicle through a zone from its sampled arc lengths `s` at `times` along its
/// own path. `None` if it never reached the zone. A vehicle already inside at the first sample
/// entered at that sample's time. Samples must share one time base; lengths must agree.
pub fn passage(times: &[f64], s: &[f64], zone: &OccupancyInterval) -> Option<Passage> {
    if times.len() != s.len() {
        return None;
    }
    let (enter_t_s, k) = first_crossing(times, s, zone.enter_s_m, 0)?;
    let exit_t_s = first_crossing(times, s, zone.exit_s_m, k).map(|(t, _)| t.max(enter_t_s));
    Some(Passage { enter_t_s, exit_t_s })
}

/// PET at one zone.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(tag = "outcome", rename_all = "snake_case")]
pub enum PetOutcome {
    /// Both vehicles passed: `pet_s = second entry − first exit`. Negative means both were in the
    /// zone at once (`overlap`).
    Measured {
        /// Who entered first.
        first: Side,
        /// PET, s.
        pet_s: f64,
        /// Whether the occupancies overlapped in time.
        overlap: bool,
    },
    /// Only the first vehicle passed before the record ended: PET is at least `pet_lower_bound_s`.
    Censored {
        /// Who passed.
        first: Side,
        /// Lower bound on PET, s.
        pet_lower_bound_s: f64,
    },
    /// Neither vehicle reached the zone.
    NotReached,
}

impl PetOutcome {
    /// PET in seconds when measured.
    pub fn pet_s(&self) -> Option<f64> {
        match *self {
            Self::Measured { pet_s, .. } => Some(pet_s),
            _ => None,
        }
    }

    /// Who went through first, if anyone did.
    pub fn first(&self) -> Option<Side> {
        match *self {
            Self::Measured { first, .. } | Self::Censored { first, .. } => Some(first),
            Self::NotReached => None,
        }
    }
}

/// PET from the two passages; `t_end_s` is the end of the record (for open intervals).
pub fn pet(a: Option<Passage>, b: Option<Passage>, t_end_s: f64) -> PetOutcome {
    match (a, b) {
        (None, None) => PetOutcome::NotReached,
        (Some(p), None) | (None, Some(p)) => {
            let first = if a.is_some() { Side::A } else { Side::B };
            let exit = p.exit_t_s.unwrap_or(t_end_s);
            PetOutcome::Censored { first, pet_lower_bound_s: (t_end_s - exit).max(0.0) }
        }
        (Some(pa), Some(pb)) => {
            let (first, f, s) = if pa.enter_t_s <= pb.enter_t_s { (Side::A, pa, pb) } else { (Side::B, pb, pa) };
            let first_exit = f.exit_t_s.unwrap_or(t_end_s);
            let pet_s = s.enter_t_s - first_exit;
            PetOutcome::Measured { first, pet_s, overlap: pet_s < 0.0 }
        }
    }
}

/// Constant-velocity estimate of entry and exit times from the present state, given the times
/// already observed (`known`).
fn predicted_passage(t: f64, s: f64, v: f64, zone: &OccupancyInterval, known: Option<Passage>) -> Option<(f64, f64)> {
    let eta = |target: f64| {
        if s >= target {
            Some(t)
        } else if v > 1e-3 {
            Some(t + (target - s) / v)
        } else {
            None
        }
    };
    let enter = known.map(|p| p.enter_t_s).or_else(|| eta(zone.enter_s_m))?;
    let exit = known.and_then(|p| p.exit_t_s).or_else(|| eta(zone.exit_s_m))?;
    Some((enter, exit.max(enter)))
}

/// Predicted PET at time `t_s` from the two vehicles' arc lengths and speeds (constant velocity),
/// using already observed passages where given. `None` when a vehicle that has not yet passed is
/// standing still (it may never come), which makes PET unbounded.
#[allow(clippy::too_many_arguments)]
pub fn predict_pet(
    t_s: f64,
    a: (f64, f64),
    a_zone: &OccupancyInterval,
    a_known: Option<Passage>,
    b: (f64, f64),
    b_zone: &OccupancyInterval,
    b_known: Option<Passage>,
) -> Option<(Side, f64)> {
    let (a_in, a_out) = predicted_passage(t_s, a.0, a.1, a_zone, a_known)?;
    let (b_in, b_out) = predicted_passage(t_s, b.0, b.1, b_zone, b_known)?;
    if a_in <= b_in { Some((Side::A, b_in - a_out)) } else { Some((Side::B, a_in - b_out)) }
}

/// Predicted PET at every sample of a record, using at each time the passages observed up to then.
/// Inputs are the sample times and, for each vehicle, its arc length and speed series.
pub fn predicted_pet_series(
    times: &[f64],
    a: (&[f64], &[f64]),
    a_zone: &OccupancyInterval,
    b: (&[f64], &[f64]),
    b_zone: &OccupancyInterval,
) -> Vec<Option<(Side, f64)>> {
    let n = times.len().min(a.0.len()).min(a.1.len()).min(b.0.len()).min(b.1.len());
    (0..n)
        .map(|k| {
            let upto = k + 1;
            let ts = times.get(..upto)?;
            let known = |s: &[f64], zone: &OccupancyInterval| {
                let p = passage(ts, s.get(..upto)?, zone)?;
                // Only facts observed so far: an entry with no exit yet stays open.
                Some(p)
            };
            let t = *times.get(k)?;
            predict_pet(
                t,
                (*a.0.get(k)?, *a.1.get(k)?),
                a_zone,
                known(a.0, a_zone),
                (*b.0.get(k)?, *b.1.get(k)?),
                b_zone,
                known(b.0, b_zone),
            )
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn samples(dt: f64, n: usize, s0: f64, v: f64) -> (Vec<f64>, Vec<f64>) {
        let t: Vec<f64> = (0..n).map(|k| k as f64 * dt).collect();
        let s = t.iter().map(|t| s0 + v * t).collect();
        (t, s)
    }

    proptest! {
        /// Constant-speed right-angle crossing: PET is known in closed form.
        #[test]
        fn right_angle_crossing_matches_the_analytic_pet(
            va in 3.0f64..20.0, vb in 3.0f64..20.0, gap in 0.5f64..6.0, dt in 0.02f64..0.2,
        ) {
            // Zone on each path: centre at 50 m, half extent 0.9 (width) + 2.25 (length).
            let h = 0.9 + 2.25;
            let za = OccupancyInterval { enter_s_m: 50.0 - h, exit_s_m: 50.0 + h };
            let zb = za;
            // a reaches the zone centre at t = 4 s; b enters `gap` s after a exits.
            let a_exit = 4.0 + h / va;
            let b_enter = a_exit + gap;
            let (t, sa) = samples(dt, (30.0 / dt) as usize, 50.0 - 4.0 * va, va);
            let sb: Vec<f64> = t.iter().map(|t| (50.0 - h) + vb * (t - b_enter)).collect();
            let out = pet(passage(&t, &sa, &za), passage(&t, &sb, &zb), *t.last().unwrap());
            match out {
                PetOutcome::Measured { first, pet_s, overlap } => {
                    prop_assert_eq!(first, Side::A);
                    prop_assert!(!overlap);
                    prop_assert!((pet_s - gap).abs() < 1e-3, "pet {} vs {}", pet_s, gap);
                }
                other => prop_assert!(false, "{:?}", other),
            }
        }
    }

    #[test]
    fn cut_in_at_a_known_time() {
        // The BV (path b) clears the merge zone at t = 3.0 s; the VUT (path a, 12 m/s) reaches the
        // zone's entry 1.5 s later.
        let za = OccupancyInterval { enter_s_m: 60.0, exit_s_m: 75.0 };
        let zb = OccupancyInterval { enter_s_m: 40.0, exit_s_m: 58.0 };
        let t: Vec<f64> = (0..=100).map(|k| k as f64 * 0.1).collect();
        let sb: Vec<f64> = t.iter().map(|t| 58.0 + 15.0 * (t - 3.0)).collect();
        let sa: Vec<f64> = t.iter().map(|t| 60.0 + 12.0 * (t - 4.5)).collect();
        let out = pet(passage(&t, &sa, &za), passage(&t, &sb, &zb), 10.0);
        assert_eq!(out.first(), Some(Side::B));
        assert!((out.pet_s().unwrap() - 1.5).abs() < 1e-3, "{out:?}");
    }

    #[test]
    fn simultaneous_occupancy_is_a_negative_pet() {
        let z = OccupancyInterval { enter_s_m: 10.0, exit_s_m: 20.0 };
        let (t, sa) = samples(0.1, 50, 0.0, 10.0); // inside from 1 s to 2 s
        let (_, sb) = samples(0.1, 50, -5.0, 10.0); // inside from 1.5 s to 2.5 s
        let out = pet(passage(&t, &sa, &z), passage(&t, &sb, &z), 4.9);
        assert!(matches!(out, PetOutcome::Measured { first: Side::A, overlap: true, .. }));
        assert!((out.pet_s().unwrap() + 0.5).abs() < 1e-9);
    }

    #[test]
    fn a_vehicle_that_never_comes_censors_the_pet() {
        let z = OccupancyInterval { enter_s_m: 10.0, exit_s_m: 20.0 };
        let (t, sa) = samples(0.1, 50, 0.0, 10.0);
        let sb = vec![0.0; t.len()];
        let out = pet(passage(&t, &sa, &z), passage(&t, &sb, &z), 4.9);
        assert!(matches!(out, PetOutcome::Censored { first: Side::A, .. }));
        assert_eq!(pet(None, None, 1.0), PetOutcome::NotReached);
    }

    #[test]
    fn predicted_pet_of_constant_speeds_equals_the_measured_one() {
        let z = OccupancyInterval { enter_s_m: 46.85, exit_s_m: 53.15 };
        let (t, sa) = samples(0.1, 120, 0.0, 10.0);
        let (_, sb) = samples(0.1, 120, -20.0, 8.0);
        let va = vec![10.0; t.len()];
        let vb = vec![8.0; t.len()];
        let measured = pet(passage(&t, &sa, &z), passage(&t, &sb, &z), 11.9).pet_s().unwrap();
        let series = predicted_pet_series(&t, (&sa, &va), &z, (&sb, &vb), &z);
        for p in series.iter().step_by(10) {
            let (side, v) = p.unwrap();
            assert_eq!(side, Side::A);
            assert!((v - measured).abs() < 0.02, "{v} vs {measured}");
        }
        // A stopped vehicle that has not passed makes the prediction unbounded.
        assert_eq!(predict_pet(0.0, (0.0, 0.0), &z, None, (0.0, 5.0), &z, None), None);
    }
}
