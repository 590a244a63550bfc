//! The same vehicle in several recordings: CommonRoad cuts one NGSIM recording into many
//! scenarios, and a vehicle that drives through two cuts is a track in each (the 2018b set holds
//! each vehicle about twice). Each cut is shifted to its own origin and renumbers its obstacles,
//! so neither positions nor ids tell two copies apart; what the conversion copies unchanged is a
//! vehicle's footprint and its speeds, sample by sample.
//!
//! A [`VehicleIndex`] gives each track a vehicle number across every recording it has seen: two
//! tracks are the same vehicle when they share a *key* — the footprint (to the millimetre) and
//! [`KEY_SAMPLES`] consecutive speeds (to the mm/s) in which the speed takes at least
//! [`MIN_DISTINCT_SPEEDS`] values. A vehicle that stands or keeps one speed throughout gives no
//! such key; its key is its footprint, its id and its first [`KEY_SAMPLES`] speeds and headings
//! (a standing car keeps its id within a recording's cuts; across recordings it stays apart, which
//! counts it twice rather than merging two cars). Recordings with another sampling period never
//! share keys.

use std::collections::HashMap;

use crate::tracks::Track;

/// Consecutive samples whose speeds make a key.
pub const KEY_SAMPLES: usize = 10;
/// A window of speeds is a key only when it takes at least this many distinct values.
pub const MIN_DISTINCT_SPEEDS: usize = 3;

/// What [`VehicleIndex::identify`] says of one track.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Identity {
    /// The vehicle's number across every recording seen.
    pub vehicle: usize,
    /// Whether an earlier recording (or an earlier track of this one) already held it.
    pub seen_before: bool,
}

/// Vehicle numbers across recordings (see the module).
#[derive(Debug, Default)]
pub struct VehicleIndex {
    keys: HashMap<Vec<i64>, usize>,
    vehicles: usize,
}

/// The track's speeds, m/s (from its velocity components; `None` where a sample has none).
fn speeds(track: &Track) -> Vec<Option<f64>> {
    track.samples.iter().map(|s| s.vx_mps.zip(s.vy_mps).map(|(vx, vy)| vx.hypot(vy))).collect()
}

fn milli(x: f64) -> i64 {
    (x * 1000.0).round() as i64
}

/// Every key of a track (see the module).
fn keys(track: &Track) -> Vec<Vec<i64>> {
    let (l, w) = track.dims.map_or((-1, -1), |d| (milli(d.length_m), milli(d.width_m)));
    let period = milli(track.dt_s);
    let v = speeds(track);
    let mut out = Vec::new();
    for window in v.windows(KEY_SAMPLES) {
        let Some(w_speeds) = window.iter().copied().collect::<Option<Vec<f64>>>() else { continue };
        let milli_speeds: Vec<i64> = w_speeds.iter().map(|s| milli(*s)).collect();
        let mut distinct = milli_speeds.clone();
        distinct.sort_unstable();
        distinct.dedup();
        if distinct.len() >= MIN_DISTINCT_SPEEDS {
            let mut key = vec![0, period, l, w];
            key.extend(milli_speeds);
            out.push(key);
        }
    }
    if out.is_empty() {
        // A standing (or constant-speed) vehicle: its id, footprint and first states.
        let mut key = vec![1, period, l, w];
        key.extend(track.id.bytes().map(i64::from));
        key.push(-1);
        for (s, q) in v.iter().zip(&track.samples).take(KEY_SAMPLES) {
            key.push(s.map_or(i64::MIN, milli));
            key.push(q.psi_rad.map_or(i64::MIN, milli));
        }
        out.push(key);
    }
    out
}

impl VehicleIndex {
    /// An empty index.
    pub fn new() -> Self {
        Self::default()
    }

    /// Vehicles numbered so far.
    pub fn vehicles(&self) -> usize {
        self.vehicles
    }

    /// The vehicle of each track of one recording, in order; the recording's keys are added.
    pub fn identify(&mut self, tracks: &[Track]) -> Vec<Identity> {
        tracks
            .iter()
            .map(|t| {
                let keys = keys(t);
                let known = keys.iter().find_map(|k| self.keys.get(k).copied());
                let vehicle = known.unwrap_or_else(|| {
                    self.vehicles += 1;
                    self.vehicles - 1
                });
                for k in keys {
                    self.keys.entry(k).or_insert(vehicle);
                }
                Identity { vehicle, seen_before: known.is_some() }
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tracks::{AgentKind, TrackSample};
    use v2t_model::metrics::Dimensions;

    /// A track of `speeds` at 0.1 s, starting at `x0`, heading east.
    fn track(id: &str, x0: f64, speeds: &[f64], length_m: f64) -> Track {
        let mut x = x0;
        let samples = speeds
            .iter()
            .enumerate()
            .map(|(k, &v)| {
                let s = TrackSample {
                    t_s: k as f64 * 0.1,
                    x_m: x,
                    y_m: 0.0,
                    vx_mps: Some(v),
                    vy_mps: Some(0.0),
                    psi_rad: Some(0.0),
                };
                x += v * 0.1;
                s
            })
            .collect();
        Track {
            id: id.into(),
            dt_s: 0.1,
            kind: AgentKind::Car,
            dims: Some(Dimensions { length_m, width_m: 1.8 }),
            samples,
        }
    }

    fn accelerating(from: f64, n: usize) -> Vec<f64> {
        (0..n).map(|k| from + 0.05 * k as f64).collect()
    }

    #[test]
    fn a_vehicle_in_two_cuts_is_one_vehicle_whatever_its_id_and_origin() {
        let mut index = VehicleIndex::new();
        let speeds = accelerating(8.0, 40);
        let first = index.identify(&[track("12", 0.0, &speeds, 4.5), track("13", 5.0, &accelerating(3.0, 40), 4.5)]);
        assert_eq!(first.iter().map(|i| i.seen_before).collect::<Vec<_>>(), vec![false, false]);
        // The next cut starts 2 s later, shifted to another origin, the vehicle renumbered.
        let second = index.identify(&[track("801", -300.0, &speeds[20..], 4.5), track("802", 0.0, &speeds, 4.6)]);
        assert_eq!(second[0], Identity { vehicle: first[0].vehicle, seen_before: true });
        assert!(!second[1].seen_before, "another footprint is another vehicle");
        assert_eq!(index.vehicles(), 3);
    }

    #[test]
    fn standing_vehicles_are_told_apart_by_id_and_too_short_a_track_is_its_own() {
        let mut index = VehicleIndex::new();
        let standing = vec![0.0; 30];
        let a = index.identify(&[track("5", 0.0, &standing, 4.5), track("6", 10.0, &standing, 4.5)]);
        assert_ne!(a[0].vehicle, a[1].vehicle, "two cars waiting at the light");
        let b = index.identify(&[track("5", -50.0, &standing, 4.5)]);
        assert!(b[0].seen_before, "the same standing car in the next cut keeps its id");
        let short = index.identify(&[track("9", 0.0, &accelerating(8.0, 4), 4.5)]);
        assert!(!short[0].seen_before);
    }
}
