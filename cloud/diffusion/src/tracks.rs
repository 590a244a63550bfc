//! Recorded tracks: what the importers produce and what mining and inverse kinematics consume.
//!
//! A [`Track`] is one road user's samples `(t, x, y, vx?, vy?, ψ?)` in a planar frame (metres,
//! seconds); velocities and heading are optional because not every format records them. An
//! [`Episode`] is a set of tracks over a common time span, e.g. one recording of a dataset.

use serde::{Deserialize, Serialize};
use v2t_model::geometry::Point2;
use v2t_model::metrics::Dimensions;

/// What kind of road user a track belongs to, when the source says.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum AgentKind {
    /// Passenger car (also `van`).
    Car,
    /// Truck or bus.
    Truck,
    /// Motorcycle.
    Motorcycle,
    /// Bicycle.
    Bicycle,
    /// Pedestrian (INTERACTION's `pedestrian/bicycle` lands here).
    Pedestrian,
    /// Not given or not recognised.
    #[default]
    Unknown,
}

impl AgentKind {
    /// Reads the labels of INTERACTION, highD and CommonRoad (case-insensitive); anything else is
    /// [`AgentKind::Unknown`].
    pub fn from_label(label: &str) -> Self {
        match label.trim().to_ascii_lowercase().as_str() {
            "car" | "van" | "passenger_car" | "passengercar" | "taxi" | "priorityvehicle" => Self::Car,
            "truck" | "bus" | "trailer" | "semitrailer" | "truck_bus" => Self::Truck,
            "motorcycle" | "motorbike" => Self::Motorcycle,
            "bicycle" | "bike" => Self::Bicycle,
            "pedestrian" | "pedestrian/bicycle" => Self::Pedestrian,
            _ => Self::Unknown,
        }
    }

    /// Whether it is a motor vehicle that follows the kinematic model of `v2t-model`.
    pub fn is_vehicle(self) -> bool {
        matches!(self, Self::Car | Self::Truck | Self::Motorcycle | Self::Unknown)
    }
}

/// One sample of a track.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TrackSample {
    /// Time, s.
    pub t_s: f64,
    /// Position east, m.
    pub x_m: f64,
    /// Position north, m.
    pub y_m: f64,
    /// Velocity east, m/s, when recorded.
    pub vx_mps: Option<f64>,
    /// Velocity north, m/s, when recorded.
    pub vy_mps: Option<f64>,
    /// Heading, rad (counter-clockwise from east), when recorded.
    pub psi_rad: Option<f64>,
}

impl TrackSample {
    /// A sample with a position only.
    pub fn at(t_s: f64, x_m: f64, y_m: f64) -> Self {
        Self { t_s, x_m, y_m, vx_mps: None, vy_mps: None, psi_rad: None }
    }

    /// The position.
    pub fn position(&self) -> Point2 {
        Point2::new(self.x_m, self.y_m)
    }
}

/// One road user's samples in time order.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Track {
    /// Id within its episode.
    pub id: String,
    /// Nominal sampling period, s.
    pub dt_s: f64,
    /// Kind of road user.
    pub kind: AgentKind,
    /// Footprint, when known.
    pub dims: Option<Dimensions>,
    /// Samples, strictly increasing in time.
    pub samples: Vec<TrackSample>,
}

impl Track {
    /// First and last sample time, s.
    pub fn span_s(&self) -> Option<(f64, f64)> {
        Some((self.samples.first()?.t_s, self.samples.last()?.t_s))
    }

    /// Sample times, s.
    pub fn times(&self) -> Vec<f64> {
        self.samples.iter().map(|s| s.t_s).collect()
    }

    /// Positions.
    pub fn positions(&self) -> Vec<Point2> {
        self.samples.iter().map(TrackSample::position).collect()
    }

    /// Length driven (sum of distances between consecutive samples), m.
    pub fn path_length_m(&self) -> f64 {
        self.samples.windows(2).map(|w| if let [a, b] = w { a.position().dist(b.position()) } else { 0.0 }).sum()
    }

    /// How far the track turns, rad, counter-clockwise positive (a left turn with y up): the
    /// unwrapped heading over its last five samples' mean minus over its first five's. The heading
    /// is the recorded one where every sample has it, else the direction of travel between samples
    /// at least 0.2 m apart. `None` with fewer than two headings.
    pub fn heading_change_rad(&self) -> Option<f64> {
        let headings: Vec<f64> = if self.samples.iter().all(|s| s.psi_rad.is_some_and(f64::is_finite)) {
            self.samples.iter().filter_map(|s| s.psi_rad).collect()
        } else {
            let mut out = Vec::new();
            let mut from: Option<Point2> = None;
            for p in self.positions() {
                match from {
                    Some(q) if q.dist(p) >= 0.2 => {
                        out.push((p.y - q.y).atan2(p.x - q.x));
                        from = Some(p);
                    }
                    None => from = Some(p),
                    Some(_) => {}
                }
            }
            out
        };
        let (first, rest) = headings.split_first()?;
        if rest.is_empty() {
            return None;
        }
        let mut unwrapped = vec![*first];
        let mut last = *first;
        for h in rest {
            last += v2t_model::geometry::wrap_angle(h - last);
            unwrapped.push(last);
        }
        let k = unwrapped.len().min(5);
        let mean = |xs: &[f64]| xs.iter().sum::<f64>() / xs.len() as f64;
        Some(mean(unwrapped.get(unwrapped.len() - k..)?) - mean(unwrapped.get(..k)?))
    }

    /// The footprint, or a typical car's (4.6 m × 1.9 m) when unknown.
    pub fn dims_or_default(&self) -> Dimensions {
        self.dims.unwrap_or(Dimensions { length_m: 4.6, width_m: 1.9 })
    }

    /// The track on a finer time grid of period `dt_s` (from its first sample to its last): positions
    /// by uniform Catmull–Rom interpolation between the recorded samples (C¹, through every
    /// sample), velocity and heading dropped (inverse kinematics derives them). Meant for a track
    /// without gaps whose period is a multiple of `dt_s` (e.g. 0.2 s → 0.1 s); `None` when `dt_s`
    /// is not a positive number below the track's period, more than 20 times finer than it, or the
    /// track has fewer than two samples.
    pub fn resampled(&self, dt_s: f64) -> Option<Track> {
        if !(dt_s.is_finite() && dt_s > 0.0 && dt_s < self.dt_s && self.dt_s / dt_s <= 20.0) || self.samples.len() < 2 {
            return None;
        }
        // A gap-free track holds at most 1.5 periods between samples: its span bounds the output.
        if !self.gaps().is_empty() {
            return None;
        }
        let (t0, t1) = self.span_s()?;
        let n = ((t1 - t0) / dt_s + 1e-6).floor() as usize;
        let p = |k: usize| {
            let s = self.samples.get(k.min(self.samples.len() - 1))?;
            Some(Point2::new(s.x_m, s.y_m))
        };
        let mut samples = Vec::with_capacity(n + 1);
        let mut k = 0;
        for j in 0..=n {
            let t = t0 + j as f64 * dt_s;
            while k + 2 < self.samples.len() && self.samples.get(k + 1).is_some_and(|s| s.t_s <= t) {
                k += 1;
            }
            let (a, b) = (self.samples.get(k)?, self.samples.get(k + 1)?);
            let u = ((t - a.t_s) / (b.t_s - a.t_s)).clamp(0.0, 1.0);
            let (p1, p2) = (p(k)?, p(k + 1)?);
            let p0 = if k == 0 { p1.add(p1.sub(p2)) } else { p(k - 1)? };
            let p3 = if k + 2 >= self.samples.len() { p2.add(p2.sub(p1)) } else { p(k + 2)? };
            let (u2, u3) = (u * u, u * u * u);
            let c = |x0: f64, x1: f64, x2: f64, x3: f64| {
                0.5 * (2.0 * x1
                    + (x2 - x0) * u
                    + (2.0 * x0 - 5.0 * x1 + 4.0 * x2 - x3) * u2
                    + (3.0 * x1 - x0 - 3.0 * x2 + x3) * u3)
            };
            samples.push(TrackSample::at(t, c(p0.x, p1.x, p2.x, p3.x), c(p0.y, p1.y, p2.y, p3.y)));
        }
        Some(Track { samples, dt_s, ..self.clone() })
    }

    /// Indices `k` where the time step to sample `k + 1` is more than 1.5 sampling periods: holes in
    /// the record.
    pub fn gaps(&self) -> Vec<usize> {
        self.samples
            .windows(2)
            .enumerate()
            .filter_map(|(k, w)| match w {
                [a, b] if b.t_s - a.t_s > 1.5 * self.dt_s => Some(k),
                _ => None,
            })
            .collect()
    }
}

/// A set of tracks over a common time span.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Episode {
    /// Where it came from (file name, scenario id, synthetic episode id).
    pub id: String,
    /// Nominal sampling period shared by the tracks, s.
    pub dt_s: f64,
    /// Start of the span, s.
    pub t_start_s: f64,
    /// End of the span, s.
    pub t_end_s: f64,
    /// The tracks, by id.
    pub tracks: Vec<Track>,
}

impl Episode {
    /// An episode spanning all of `tracks`; `dt_s` is the smallest track period (0.1 s if none).
    pub fn from_tracks(id: impl Into<String>, mut tracks: Vec<Track>) -> Self {
        tracks.sort_by(|a, b| natural_order(&a.id, &b.id));
        let spans: Vec<(f64, f64)> = tracks.iter().filter_map(Track::span_s).collect();
        let t_start_s = spans.iter().map(|s| s.0).fold(f64::INFINITY, f64::min);
        let t_end_s = spans.iter().map(|s| s.1).fold(f64::NEG_INFINITY, f64::max);
        let dt_s = tracks.iter().map(|t| t.dt_s).filter(|d| *d > 0.0).fold(f64::INFINITY, f64::min);
        Self {
            id: id.into(),
            dt_s: if dt_s.is_finite() { dt_s } else { 0.1 },
            t_start_s: if t_start_s.is_finite() { t_start_s } else { 0.0 },
            t_end_s: if t_end_s.is_finite() { t_end_s } else { 0.0 },
            tracks,
        }
    }

    /// A track by id.
    pub fn track(&self, id: &str) -> Option<&Track> {
        self.tracks.iter().find(|t| t.id == id)
    }
}

/// Numeric ids in numeric order (`2` before `10`), others after them in text order.
fn natural_order(a: &str, b: &str) -> std::cmp::Ordering {
    match (a.parse::<i64>(), b.parse::<i64>()) {
        (Ok(x), Ok(y)) => x.cmp(&y),
        (Ok(_), Err(_)) => std::cmp::Ordering::Less,
        (Err(_), Ok(_)) => std::cmp::Ordering::Greater,
        (Err(_), Err(_)) => a.cmp(b),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A track on a circle of radius 20 m through `angle` rad (positive: counter-clockwise, a left
    /// turn), 40 samples, with or without recorded headings.
    fn turning(angle: f64, with_heading: bool) -> Track {
        let samples = (0..40)
            .map(|k| {
                let a = angle * f64::from(k) / 39.0;
                let (x, y) = if angle >= 0.0 {
                    (20.0 * a.sin(), 20.0 * (1.0 - a.cos()))
                } else {
                    (20.0 * (-a).sin(), -20.0 * (1.0 - a.cos()))
                };
                TrackSample {
                    t_s: f64::from(k) * 0.1,
                    x_m: x,
                    y_m: y,
                    vx_mps: None,
                    vy_mps: None,
                    psi_rad: with_heading.then_some(a),
                }
            })
            .collect();
        Track { id: "t".into(), dt_s: 0.1, kind: AgentKind::Car, dims: None, samples }
    }

    #[test]
    fn a_left_turn_turns_counter_clockwise_from_headings_or_from_motion() {
        let quarter = std::f64::consts::FRAC_PI_2;
        for with_heading in [true, false] {
            let left = turning(quarter, with_heading).heading_change_rad().unwrap();
            // The means over five samples at each end take a little off the full quarter turn.
            assert!(left > 0.8 * quarter && left <= quarter + 1e-9, "{left}");
            let right = turning(-quarter, with_heading).heading_change_rad().unwrap();
            assert!(right < -0.8 * quarter, "{right}");
            let mut straight = turning(quarter, with_heading);
            for (k, s) in straight.samples.iter_mut().enumerate() {
                (s.x_m, s.y_m, s.psi_rad) = (k as f64, 0.0, s.psi_rad.map(|_| 0.0));
            }
            let straight = straight.heading_change_rad();
            assert!(straight.is_some_and(|d| d.abs() < 1e-9), "{straight:?}");
        }
        // Headings across ±π are unwrapped: a turn through west is still one left turn.
        let mut t = turning(quarter, true);
        for s in &mut t.samples {
            s.psi_rad = s
                .psi_rad
                .map(|p| (p + 2.5 + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU) - std::f64::consts::PI);
        }
        assert!(t.heading_change_rad().unwrap() > 0.8 * quarter);
    }

    fn track(id: &str, t0: f64, n: usize) -> Track {
        let samples = (0..n).map(|k| TrackSample::at(t0 + 0.1 * k as f64, k as f64, 0.0)).collect();
        Track { id: id.into(), dt_s: 0.1, kind: AgentKind::Car, dims: None, samples }
    }

    #[test]
    fn an_episode_spans_its_tracks_in_id_order() {
        let e = Episode::from_tracks("e", vec![track("10", 1.0, 5), track("2", 0.5, 3)]);
        assert_eq!(e.tracks[0].id, "2");
        assert!((e.t_start_s - 0.5).abs() < 1e-12 && (e.t_end_s - 1.4).abs() < 1e-12);
        assert!((e.track("10").unwrap().path_length_m() - 4.0).abs() < 1e-12);
    }

    #[test]
    fn resampling_goes_through_the_samples_and_keeps_straight_motion() {
        let t = Track { dt_s: 0.2, ..track("1", 0.0, 6) };
        // track() spaces samples 0.1 s apart; re-time them at 0.2 s, x = k metres (5 m/s).
        let t = Track {
            samples: t.samples.iter().enumerate().map(|(k, s)| TrackSample { t_s: 0.2 * k as f64, ..*s }).collect(),
            ..t
        };
        let r = t.resampled(0.1).unwrap();
        assert_eq!(r.samples.len(), 11);
        for (j, s) in r.samples.iter().enumerate() {
            assert!((s.t_s - 0.1 * j as f64).abs() < 1e-9);
            assert!((s.x_m - 0.5 * j as f64).abs() < 1e-9, "uniform motion stays uniform: {} at {j}", s.x_m);
        }
        assert!(t.resampled(0.2).is_none() && t.resampled(f64::NAN).is_none() && t.resampled(0.001).is_none());
        let mut holed = t.clone();
        holed.samples.remove(3);
        assert!(holed.resampled(0.1).is_none(), "a track with a hole is cut at it first");
    }

    #[test]
    fn gaps_are_found() {
        let mut t = track("1", 0.0, 5);
        t.samples.remove(2);
        assert_eq!(t.gaps(), vec![1]);
    }

    #[test]
    fn labels_map_to_kinds() {
        assert_eq!(AgentKind::from_label("Truck"), AgentKind::Truck);
        assert_eq!(AgentKind::from_label("pedestrian/bicycle"), AgentKind::Pedestrian);
        assert_eq!(AgentKind::from_label("zeppelin"), AgentKind::Unknown);
    }
}
