//! Interaction mining: cut-ins, lane changes, left turns, crossings and merges between pairs of
//! tracks of an episode, each with the pair, the conflict point and time and the measured
//! post-encroachment time (PET).
//!
//! Each track is smoothed ([`crate::inverse::smooth`], [`MiningOptions::position_noise_m`]) and its
//! driven path becomes a [`ReferencePath`]; [`conflict_zones`] of `v2t-model` finds
//! where the two swept corridors meet, and [`passage`]/[`pet`] measure the PET there from the
//! tracks' arc lengths over time, with the conventions of `v2t-model` (second entry minus first
//! exit, negative when both occupied the zone at once). A zone after which the paths part is a
//! crossing — a **left turn** when one of the two turns left by more than
//! [`MiningOptions::left_turn_min_rad`] across it. A zone after which one path stays on the other
//! is a join: if the joining vehicle drove parallel in a neighbouring lane just before, it is a
//! **cut-in** when it enters ahead of the other and a **lane change** (behind) otherwise; if it
//! came in at an angle it is a **merge**. Two paths that join are joined both ways, geometrically;
//! the vehicle that moved over is the one whose path weaves there (an S-shaped lane change leaves
//! a residual to a quadratic fit, a straight or evenly curved lane does not). Without the map a merge out of a parallel acceleration
//! lane reads as a cut-in or lane change. Vehicles following each other in one lane from the start
//! are not an interaction.

use serde::{Deserialize, Serialize};
use v2t_model::geometry::{Point2, wrap_angle};
use v2t_model::metrics::{ConflictKind, ConflictOptions, ConflictZone, PetOutcome, conflict_zones, passage, pet};
use v2t_model::path::ReferencePath;

use crate::tracks::{Episode, Track};

/// Jerk standard deviation of the smoother applied to tracks before mining, m/s³.
const SMOOTHING_JERK_MPS3: f64 = 2.0;

/// What kind of interaction.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum InteractionKind {
    /// A vehicle changes into another's lane ahead of it.
    CutIn,
    /// A vehicle changes into another's lane behind it.
    LaneChange,
    /// Paths cross while one vehicle turns left.
    LeftTurn,
    /// Paths cross otherwise.
    Crossing,
    /// A path joins another at an angle (on-ramp, lane drop, turn into a lane).
    Merge,
}

/// One mined interaction.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Interaction {
    /// What kind.
    pub kind: InteractionKind,
    /// The vehicle that cuts in, changes lanes, turns left or merges (for crossings: the second
    /// track of the pair).
    pub actor: String,
    /// The other vehicle.
    pub other: String,
    /// The vehicle that passed the conflict first.
    pub first: String,
    /// A representative point of the conflict zone.
    pub conflict_point: Point2,
    /// When the second vehicle entered the zone, s.
    pub conflict_time_s: f64,
    /// PET, s (negative: both in the zone at once).
    pub pet_s: f64,
}

/// Tuning of [`mine`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MiningOptions {
    /// Interactions with a larger PET are dropped, s.
    pub max_pet_s: f64,
    /// … and those with a PET below this (a long overlap: side by side, not a conflict), s.
    pub min_pet_s: f64,
    /// Standard deviation of the recording's position noise, for the smoother that tracks go
    /// through first (`inverse::smooth`), m; 0 turns smoothing off.
    pub position_noise_m: f64,
    /// Tracks that travel less than this are left out, m.
    pub min_travel_m: f64,
    /// Spacing of the points of the path built from a track, m.
    pub path_spacing_m: f64,
    /// A path has joined another once within this of its centreline, m (driven paths wobble).
    pub merge_tolerance_m: f64,
    /// A left turn turns by at least this across the zone, rad.
    pub left_turn_min_rad: f64,
    /// How far before a join the joining path is examined, m.
    pub approach_m: f64,
    /// Largest heading difference for "parallel" before a join, rad.
    pub parallel_max_rad: f64,
    /// Lateral offset range of a neighbouring lane, m.
    pub lane_offset_m: (f64, f64),
}

impl Default for MiningOptions {
    fn default() -> Self {
        Self {
            max_pet_s: 6.0,
            min_pet_s: -2.0,
            position_noise_m: 0.05,
            min_travel_m: 10.0,
            path_spacing_m: 1.0,
            merge_tolerance_m: 0.8,
            left_turn_min_rad: 0.8,
            approach_m: 15.0,
            parallel_max_rad: 0.25,
            lane_offset_m: (2.0, 5.5),
        }
    }
}

/// A track's path and its arc length at every sample.
struct Driven<'a> {
    track: &'a Track,
    path: ReferencePath,
    times: Vec<f64>,
    s: Vec<f64>,
}

impl<'a> Driven<'a> {
    fn new(track: &'a Track, opts: &MiningOptions) -> Option<Self> {
        // Recorded positions are smoothed first (the smoother of `inverse`): paths, headings and
        // joins are then read from the motion rather than from the noise.
        let lambda = crate::inverse::smoothing_lambda(opts.position_noise_m, SMOOTHING_JERK_MPS3, track.dt_s);
        let xs: Vec<f64> = track.samples.iter().map(|s| s.x_m).collect();
        let ys: Vec<f64> = track.samples.iter().map(|s| s.y_m).collect();
        let positions: Vec<Point2> = crate::inverse::smooth(&xs, lambda)
            .into_iter()
            .zip(crate::inverse::smooth(&ys, lambda))
            .map(|(x, y)| Point2::new(x, y))
            .collect();
        let mut pts: Vec<Point2> = Vec::new();
        for &p in &positions {
            if pts.last().is_none_or(|q| q.dist(p) >= opts.path_spacing_m) {
                pts.push(p);
            }
        }
        if let (Some(last), Some(&end)) = (pts.last(), positions.last())
            && last.dist(end) > 1e-6
        {
            pts.push(end);
        }
        let path = ReferencePath::from_points(&pts).ok()?;
        let mut hint = 0.0;
        let s = positions
            .iter()
            .map(|p| {
                hint = path.project_near(*p, hint, 4.0 * opts.path_spacing_m + 10.0).map_or(hint, |f| f.s_m);
                hint
            })
            .collect();
        Some(Self { track, path, times: track.times(), s })
    }

    /// How much the path weaves over `[from, to]`: the RMS residual of a quadratic fit of its
    /// points in the frame of their chord, m. A lane change (an S, cubic about its inflection)
    /// leaves a residual; a straight or evenly curved lane does not.
    fn weave(&self, from: f64, to: f64) -> f64 {
        let (from, to) = (from.max(0.0), to.min(self.path.length()));
        let n = ((to - from) / 1.0).ceil().max(2.0) as usize;
        let pts: Vec<Point2> = (0..=n).map(|k| self.path.point_at(from + (to - from) * k as f64 / n as f64)).collect();
        let (Some(&p0), Some(&p1)) = (pts.first(), pts.last()) else { return 0.0 };
        let chord = p1.sub(p0);
        let len = chord.norm();
        if len < 1.0 {
            return 0.0;
        }
        let (ex, ey) = (chord.scale(1.0 / len), chord.scale(1.0 / len).perp());
        let local: Vec<(f64, f64)> = pts.iter().map(|p| (p.sub(p0).dot(ex) / len, p.sub(p0).dot(ey))).collect();
        quadratic_fit_rms(&local)
    }

    /// Heading change of the path across `[from − d, to + d]`, rad, positive left.
    fn turn(&self, from: f64, to: f64, d: f64) -> f64 {
        let a = (from - d).max(0.0);
        let b = (to + d).min(self.path.length());
        wrap_angle(self.path.heading_at(b) - self.path.heading_at(a))
    }
}

/// RMS residual of the least-squares fit `y = c0 + c1 x + c2 x²` to `points` (normal equations,
/// Cramer's rule); 0 when the fit is degenerate.
fn quadratic_fit_rms(points: &[(f64, f64)]) -> f64 {
    let mut m = [0.0_f64; 5]; // Σ x^k, k = 0..4
    let mut r = [0.0_f64; 3]; // Σ x^k y, k = 0..2
    for &(x, y) in points {
        let (x2, x3) = (x * x, x * x * x);
        m = [m[0] + 1.0, m[1] + x, m[2] + x2, m[3] + x3, m[4] + x2 * x2];
        r = [r[0] + y, r[1] + x * y, r[2] + x2 * y];
    }
    let det3 = |a: [f64; 9]| {
        a[0] * (a[4] * a[8] - a[5] * a[7]) - a[1] * (a[3] * a[8] - a[5] * a[6]) + a[2] * (a[3] * a[7] - a[4] * a[6])
    };
    let base = [m[0], m[1], m[2], m[1], m[2], m[3], m[2], m[3], m[4]];
    let d = det3(base);
    if d.abs() < 1e-12 {
        return 0.0;
    }
    let c0 = det3([r[0], m[1], m[2], r[1], m[2], m[3], r[2], m[3], m[4]]) / d;
    let c1 = det3([m[0], r[0], m[2], m[1], r[1], m[3], m[2], r[2], m[4]]) / d;
    let c2 = det3([m[0], m[1], r[0], m[1], m[2], r[1], m[2], m[3], r[2]]) / d;
    let sum: f64 = points.iter().map(|&(x, y)| (y - c0 - c1 * x - c2 * x * x).powi(2)).sum();
    (sum / points.len().max(1) as f64).sqrt()
}

/// PET at a zone and who went first; `None` unless both passed.
fn measure(a: &Driven<'_>, b: &Driven<'_>, zone: &ConflictZone, t_end: f64) -> Option<(bool, f64, f64)> {
    let pa = passage(&a.times, &a.s, &zone.vut);
    let pb = passage(&b.times, &b.s, &zone.bv);
    match pet(pa, pb, t_end) {
        PetOutcome::Measured { first, pet_s, .. } => {
            let a_first = first == v2t_model::metrics::Side::A;
            let second_enter = if a_first { pb?.enter_t_s } else { pa?.enter_t_s };
            Some((a_first, pet_s, second_enter))
        }
        _ => None,
    }
}

/// Interactions where `b` joins `a` or the two cross. In the zones, `a` takes the VUT's side and
/// `b` the BV's (the side that may join the other's lane).
/// Joins come with how much the joining path weaves around the join (to tell, when both
/// directions report one, which vehicle moved over).
fn zones_of(a: &Driven<'_>, b: &Driven<'_>, opts: &MiningOptions, crossings: bool, out: &mut Vec<(Interaction, f64)>) {
    let copt = ConflictOptions { merge_tolerance_m: opts.merge_tolerance_m, ..ConflictOptions::default() };
    let (da, db) = (a.track.dims_or_default(), b.track.dims_or_default());
    let t_end = a.times.last().copied().unwrap_or(0.0).min(b.times.last().copied().unwrap_or(0.0));
    for zone in conflict_zones(&a.path, da, &b.path, db, &copt) {
        let Some((a_first, pet_s, time)) = measure(a, b, &zone, t_end) else { continue };
        if pet_s > opts.max_pet_s || pet_s < opts.min_pet_s {
            continue;
        }
        let (id_a, id_b) = (a.track.id.clone(), b.track.id.clone());
        let first = if a_first { id_a.clone() } else { id_b.clone() };
        let s_b = 0.5 * (zone.bv.enter_s_m + zone.bv.exit_s_m);
        let weave = b.weave(s_b - 3.0 * opts.approach_m, s_b + 2.0 * opts.approach_m);
        let kind_actor = match zone.kind {
            ConflictKind::Crossing if crossings => {
                let ta = a.turn(zone.vut.enter_s_m, zone.vut.exit_s_m, 15.0);
                let tb = b.turn(zone.bv.enter_s_m, zone.bv.exit_s_m, 15.0);
                if ta.max(tb) >= opts.left_turn_min_rad {
                    Some((InteractionKind::LeftTurn, if ta >= tb { (id_a, id_b) } else { (id_b, id_a) }))
                } else {
                    Some((InteractionKind::Crossing, (id_b, id_a)))
                }
            }
            ConflictKind::Crossing => None,
            ConflictKind::Merge => {
                let s_a = 0.5 * (zone.vut.enter_s_m + zone.vut.exit_s_m);
                if s_b < 1.0 || s_a < 1.0 {
                    None // following in one lane from the start, or `a` appears at the join
                } else {
                    let before = b.path.point_at((s_b - opts.approach_m).max(0.0));
                    // `a`'s path may start after that point (it was ahead): its extension counts.
                    let lateral = a.path.project(before);
                    let parallel = lateral.is_some_and(|f| {
                        let dh =
                            wrap_angle(b.path.heading_at((s_b - opts.approach_m).max(0.0)) - a.path.heading_at(f.s_m));
                        dh.abs() <= opts.parallel_max_rad
                            && f.l_m.abs() >= opts.lane_offset_m.0
                            && f.l_m.abs() <= opts.lane_offset_m.1
                    });
                    let kind = match (parallel, a_first) {
                        (true, false) => InteractionKind::CutIn,
                        (true, true) => InteractionKind::LaneChange,
                        (false, _) => InteractionKind::Merge,
                    };
                    Some((kind, (id_b, id_a)))
                }
            }
        };
        let Some((kind, (actor, other))) = kind_actor else { continue };
        out.push((
            Interaction { kind, actor, other, first, conflict_point: zone.anchor, conflict_time_s: time, pet_s },
            weave,
        ));
    }
}

/// Whether the bounding boxes of the two tracks' positions, grown by `margin_m`, overlap (a cheap
/// test before the corridors are intersected).
fn near(a: &Track, b: &Track, margin_m: f64) -> bool {
    let bbox = |t: &Track| {
        t.samples
            .iter()
            .fold((f64::INFINITY, f64::INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY), |(x0, y0, x1, y1), s| {
                (x0.min(s.x_m), y0.min(s.y_m), x1.max(s.x_m), y1.max(s.y_m))
            })
    };
    let (a, b) = (bbox(a), bbox(b));
    a.0 - margin_m <= b.2 && b.0 - margin_m <= a.2 && a.1 - margin_m <= b.3 && b.1 - margin_m <= a.3
}

/// Interactions between two tracks.
pub fn pair(a: &Track, b: &Track, opts: &MiningOptions) -> Vec<Interaction> {
    let ok = |t: &Track| t.kind.is_vehicle() && t.path_length_m() >= opts.min_travel_m;
    if !(ok(a) && ok(b) && near(a, b, 10.0)) {
        return Vec::new();
    }
    let (Some(da), Some(db)) = (Driven::new(a, opts), Driven::new(b, opts)) else {
        return Vec::new();
    };
    let mut found = Vec::new();
    zones_of(&da, &db, opts, true, &mut found);
    zones_of(&db, &da, opts, false, &mut found);
    // A join seen from both sides: keep the side whose path weaves more there (the one that moved).
    let is_join = |k: InteractionKind| !matches!(k, InteractionKind::LeftTurn | InteractionKind::Crossing);
    let mut out: Vec<Interaction> = Vec::new();
    for (i, (x, wx)) in found.iter().enumerate() {
        let beaten = is_join(x.kind)
            && found.iter().enumerate().any(|(j, (y, wy))| {
                j != i
                    && is_join(y.kind)
                    && y.actor != x.actor
                    && (y.conflict_time_s - x.conflict_time_s).abs() < 3.0
                    && (wy > wx || (wy == wx && j < i))
            });
        if !beaten {
            out.push(x.clone());
        }
    }
    out.sort_by(|x, y| x.conflict_time_s.total_cmp(&y.conflict_time_s));
    out
}

/// Interactions between every pair of tracks of `episode`, in time order.
pub fn mine(episode: &Episode, opts: &MiningOptions) -> Vec<Interaction> {
    let mut out = Vec::new();
    for (i, a) in episode.tracks.iter().enumerate() {
        for b in episode.tracks.iter().skip(i + 1) {
            let overlap = a.span_s().zip(b.span_s()).is_some_and(|((a0, a1), (b0, b1))| a0 < b1 && b0 < a1);
            if overlap {
                out.extend(pair(a, b, opts));
            }
        }
    }
    out.sort_by(|x, y| x.conflict_time_s.total_cmp(&y.conflict_time_s));
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tracks::{AgentKind, TrackSample};
    use proptest::prelude::*;
    use v2t_model::metrics::Dimensions;
    use v2t_model::path::PathBuilder;

    /// A track driving `path` at `v` from arc length `s0`, 10 Hz for `secs`.
    fn drive(id: &str, path: &ReferencePath, s0: f64, v: f64, secs: f64) -> Track {
        let n = (secs / 0.1).round() as usize;
        let samples = (0..=n)
            .map(|k| {
                let t = k as f64 * 0.1;
                let p = path.point_at(s0 + v * t);
                TrackSample::at(t, p.x, p.y)
            })
            .collect();
        Track { id: id.into(), dt_s: 0.1, kind: AgentKind::Car, dims: None, samples }
    }

    fn episode(tracks: Vec<Track>) -> Episode {
        Episode::from_tracks("t", tracks)
    }

    #[test]
    fn a_left_turn_across_straight_traffic() {
        // A drives east along y = −1.75; B comes west along y = +1.75 and turns left (south).
        let a = PathBuilder::new(-60.0, -1.75, 0.0).line(120.0).build(0.5).unwrap();
        let b = PathBuilder::new(60.0, 1.75, std::f64::consts::PI)
            .line(55.0)
            .arc(8.0, std::f64::consts::FRAC_PI_2)
            .line(50.0)
            .build(0.5)
            .unwrap();
        // A reaches x = −3 (the zone) after ~5.7 s, B after ~6 s + its turn: B goes second.
        let found = mine(
            &episode(vec![drive("1", &a, 0.0, 10.0, 12.0), drive("2", &b, 0.0, 8.0, 14.0)]),
            &MiningOptions::default(),
        );
        let [x] = found.as_slice() else { panic!("{found:?}") };
        assert_eq!(x.kind, InteractionKind::LeftTurn);
        assert_eq!((x.actor.as_str(), x.other.as_str(), x.first.as_str()), ("2", "1", "1"));
        assert!(x.pet_s > 0.0 && x.pet_s < 6.0, "{x:?}");
        assert!(x.conflict_point.x.abs() < 8.0 && x.conflict_point.y.abs() < 8.0, "{x:?}");
    }

    #[test]
    fn crossings_without_a_left_turn_are_crossings() {
        let a = PathBuilder::new(-60.0, 0.0, 0.0).line(120.0).build(0.5).unwrap();
        let b = PathBuilder::new(0.0, -60.0, std::f64::consts::FRAC_PI_2).line(120.0).build(0.5).unwrap();
        let found = pair(
            &drive("a", &a, 0.0, 10.0, 12.0),
            &drive("b", &b, 0.0, 10.0, 12.0),
            &MiningOptions { max_pet_s: 6.0, ..Default::default() },
        );
        // Both arrive at once: they overlap in the zone, PET negative.
        let [x] = found.as_slice() else { panic!("{found:?}") };
        assert_eq!(x.kind, InteractionKind::Crossing);
        assert!(x.pet_s < 0.0);
        let later =
            pair(&drive("a", &a, 0.0, 10.0, 12.0), &drive("b", &b, -40.0, 10.0, 16.0), &MiningOptions::default());
        assert!(later.iter().all(|x| x.pet_s > 0.0 && x.first == "a"), "{later:?}");
    }

    #[test]
    fn cut_in_ahead_and_lane_change_behind() {
        let a = PathBuilder::new(0.0, 0.0, 0.0).line(400.0).build(0.5).unwrap();
        // B drives in the left lane (y = 3.5) and moves into A's lane over 60 m from x = 60.
        let b = PathBuilder::new(0.0, 3.5, 0.0).line(60.0).lane_change(60.0, -3.5).line(280.0).build(0.5).unwrap();
        let ahead = mine(
            &episode(vec![drive("a", &a, 0.0, 14.0, 15.0), drive("b", &b, 25.0, 14.0, 15.0)]),
            &MiningOptions::default(),
        );
        let [x] = ahead.as_slice() else { panic!("{ahead:?}") };
        assert_eq!((x.kind, x.actor.as_str(), x.first.as_str()), (InteractionKind::CutIn, "b", "b"));
        assert!(x.pet_s > 0.5 && x.pet_s < 3.0, "{x:?}");
        let behind = mine(
            &episode(vec![drive("a", &a, 80.0, 14.0, 15.0), drive("b", &b, 40.0, 14.0, 15.0)]),
            &MiningOptions::default(),
        );
        let [y] = behind.as_slice() else { panic!("{behind:?}") };
        assert_eq!((y.kind, y.actor.as_str(), y.first.as_str()), (InteractionKind::LaneChange, "b", "a"));
    }

    #[test]
    fn joining_at_an_angle_is_a_merge() {
        let a = PathBuilder::new(0.0, 0.0, 0.0).line(300.0).build(0.5).unwrap();
        // B comes in at 20° and turns onto A's line.
        let b = PathBuilder::new(0.0, -20.0, 20f64.to_radians())
            .line((20.0 - 30.0 * (1.0 - 20f64.to_radians().cos())) / 20f64.to_radians().sin())
            .arc(30.0, -20f64.to_radians())
            .line(150.0)
            .build(0.5)
            .unwrap();
        let found = mine(
            &episode(vec![drive("a", &a, 0.0, 12.0, 15.0), drive("b", &b, 0.0, 12.0, 15.0)]),
            &MiningOptions::default(),
        );
        let [x] = found.as_slice() else { panic!("{found:?}") };
        assert_eq!((x.kind, x.actor.as_str()), (InteractionKind::Merge, "b"));
    }

    #[test]
    fn following_pedestrians_and_standing_are_not_interactions() {
        let a = PathBuilder::new(0.0, 0.0, 0.0).line(300.0).build(0.5).unwrap();
        let follow = vec![drive("lead", &a, 30.0, 12.0, 10.0), drive("follower", &a, 0.0, 12.0, 10.0)];
        assert!(mine(&episode(follow), &MiningOptions::default()).is_empty());
        let b = PathBuilder::new(0.0, -60.0, std::f64::consts::FRAC_PI_2).line(120.0).build(0.5).unwrap();
        let mut walker = drive("w", &b, 30.0, 10.0, 12.0);
        walker.kind = AgentKind::Pedestrian;
        assert!(mine(&episode(vec![drive("a", &a, 0.0, 10.0, 12.0), walker]), &MiningOptions::default()).is_empty());
        let parked = drive("p", &b, 55.0, 0.0, 12.0);
        assert!(mine(&episode(vec![drive("a", &a, 0.0, 10.0, 12.0), parked]), &MiningOptions::default()).is_empty());
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(48))]
        /// Two vehicles crossing at right angles at constant speeds: the zone is the square where the
        /// corridors meet, so PET has a closed form.
        #[test]
        fn perpendicular_crossing_pet_is_exact(
            va in 5.0f64..15.0, vb in 5.0f64..15.0, delay in 0.5f64..5.0,
            la in 3.5f64..6.0, wa in 1.6f64..2.2, lb in 3.5f64..6.0, wb in 1.6f64..2.2,
        ) {
            let a_path = PathBuilder::new(-60.0, 0.0, 0.0).line(120.0).build(0.5).unwrap();
            let b_path = PathBuilder::new(0.0, -60.0, std::f64::consts::FRAC_PI_2).line(120.0).build(0.5).unwrap();
            let mut a = drive("a", &a_path, 0.0, va, 20.0);
            a.dims = Some(Dimensions { length_m: la, width_m: wa });
            // B starts `delay` seconds after A leaves the zone would have let it arrive together.
            let a_exit = (60.0 + 0.5 * wb + 0.5 * la) / va;
            let b_enter_at_zero = (60.0 - 0.5 * wa - 0.5 * lb) / vb;
            let s0 = -vb * (a_exit + delay - b_enter_at_zero);
            let mut b = drive("b", &b_path, s0, vb, 30.0);
            b.dims = Some(Dimensions { length_m: lb, width_m: wb });
            b.samples.retain(|x| x.y_m >= -60.0);
            let found = pair(&a, &b, &MiningOptions { max_pet_s: 10.0, ..Default::default() });
            prop_assert_eq!(found.len(), 1, "{:?}", found);
            let x = &found[0];
            prop_assert_eq!(x.kind, InteractionKind::Crossing);
            prop_assert_eq!(x.first.as_str(), "a");
            prop_assert!((x.pet_s - delay).abs() < 0.05, "PET {} expected {}", x.pet_s, delay);
        }
    }
}
