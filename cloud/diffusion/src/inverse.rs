//! Positions → controls for the kinematic model of `v2t-model`.
//!
//! Two steps:
//!
//! 1. **Smoothing.** Each coordinate is smoothed by the Whittaker–Henderson smoother with a
//!    third-difference penalty, `p = argmin Σ (p_k − y_k)² + λ Σ (Δ³p_k)²`, solved exactly as the
//!    banded system `(I + λ D₃ᵀD₃) p = y` (bandwidth 3, Cholesky, O(n)). This is the maximum a
//!    posteriori estimate when positions carry white noise of standard deviation `σ_p` and jerk is
//!    white noise of standard deviation `σ_j` (a discrete smoothing spline): `λ = (σ_p / (σ_j dt³))²`.
//!    It is chosen over a Savitzky–Golay filter because the controls need *second* differences of
//!    positions: a Savitzky–Golay kernel is truncated at its window edge, and that jump passes
//!    position noise into acceleration almost undamped, whereas the penalised solution is smooth
//!    everywhere, needs no padding at the ends and is unbiased on constant-acceleration motion
//!    (`Δ³p = 0` there, so the penalty does not act).
//! 2. **Exact inversion.** The discrete model is `p_{k+1} = p_k + v_k dt (cos θ_k, sin θ_k)`, so
//!    `v_k` and `θ_k` follow from each displacement of the smoothed path, then
//!    `a_k = (v_{k+1} − v_k)/dt` and `ω_k = (θ_{k+1} − θ_k)/dt` with θ unwrapped. Rolling these
//!    controls out from the first state reproduces the smoothed path up to rounding. Below
//!    `min_speed_mps` the heading of a displacement is noise: the heading is held there (and the
//!    speed taken along it), which is the only place the rollout gap can grow, by at most
//!    `min_speed_mps · dt` per held step. A displacement against the held heading is driven in
//!    reverse (negative speed) rather than by a half turn.

use v2t_model::geometry::{Point2, wrap_angle};
use v2t_model::grounded::AgentRole;
use v2t_model::kinematics::{Control, State};
use v2t_model::prior::AgentTrajectory;

use crate::tracks::Track;

/// What can keep a track from being inverted.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum InverseError {
    /// Fewer than three samples.
    #[error("track `{track}`: {samples} samples, need at least 3")]
    TooShort {
        /// Track id.
        track: String,
        /// Samples it has.
        samples: usize,
    },
    /// Samples not on one time grid (split the track at its gaps first).
    #[error("track `{track}`: step {index} lasts {step_s} s, the track's period is {dt_s} s")]
    NonUniform {
        /// Track id.
        track: String,
        /// Index of the sample before the odd step.
        index: usize,
        /// The step, s.
        step_s: f64,
        /// The period, s.
        dt_s: f64,
    },
    /// A position is not finite.
    #[error("track `{track}`: sample {index} is not finite")]
    NonFinite {
        /// Track id.
        track: String,
        /// Sample index.
        index: usize,
    },
    /// An option out of range.
    #[error("inverse options: {0}")]
    Options(String),
}

/// Tuning of [`to_controls`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct InverseOptions {
    /// Standard deviation of the position noise, m (0 turns smoothing off).
    pub position_noise_m: f64,
    /// Standard deviation of the jerk the smoother allows, m/s³.
    pub jerk_std_mps3: f64,
    /// Below this speed the heading is held, m/s.
    pub min_speed_mps: f64,
}

impl Default for InverseOptions {
    fn default() -> Self {
        Self { position_noise_m: 0.05, jerk_std_mps3: 2.0, min_speed_mps: 0.3 }
    }
}

/// A track turned into states and controls.
#[derive(Debug, Clone, PartialEq)]
pub struct InverseResult {
    /// States (smoothed positions, derived heading and speed) and controls; role BV.
    pub trajectory: AgentTrajectory,
    /// Sampling period, s.
    pub dt_s: f64,
    /// Largest distance between the rollout of the controls from the first state and the stored
    /// states ([`AgentTrajectory::rollout_gap_m`]), m.
    pub rollout_gap_m: f64,
    /// RMS distance between the recorded and the smoothed positions, m.
    pub smoothing_rms_m: f64,
}

/// Smoothing weight `λ` for position noise `σ_p`, jerk `σ_j` and period `dt`.
pub fn smoothing_lambda(position_noise_m: f64, jerk_std_mps3: f64, dt_s: f64) -> f64 {
    let q = jerk_std_mps3 * dt_s.powi(3);
    if q > 0.0 { (position_noise_m / q).powi(2) } else { 0.0 }
}

/// The third-difference-penalised least-squares smoothing of `y` with weight `lambda ≥ 0`.
pub fn smooth(y: &[f64], lambda: f64) -> Vec<f64> {
    let n = y.len();
    if n < 4 || lambda <= 0.0 {
        return y.to_vec();
    }
    // band[i][k] = A(i, i − k), A = I + λ D₃ᵀD₃.
    let mut band = vec![[0.0_f64; 4]; n];
    const D3: [f64; 4] = [-1.0, 3.0, -3.0, 1.0];
    for j in 0..n - 3 {
        for (a, ca) in D3.iter().enumerate() {
            let Some(row) = band.get_mut(j + a) else { continue };
            for (b, cb) in D3.iter().enumerate().take(a + 1) {
                if let Some(cell) = row.get_mut(a - b) {
                    *cell += lambda * ca * cb;
                }
            }
        }
    }
    for row in &mut band {
        row[0] += 1.0;
    }
    // Cholesky: l[i][k] = L(i, i − k).
    let mut l = vec![[0.0_f64; 4]; n];
    for i in 0..n {
        for k in (0..4.min(i + 1)).rev() {
            let j = i - k;
            let mut sum = band.get(i).and_then(|r| r.get(k)).copied().unwrap_or(0.0);
            for m in 1..(4 - k) {
                if m > j {
                    break;
                }
                let lik = l.get(i).and_then(|r| r.get(k + m)).copied().unwrap_or(0.0);
                let ljm = l.get(j).and_then(|r| r.get(m)).copied().unwrap_or(0.0);
                sum -= lik * ljm;
            }
            let value = if k == 0 { sum.max(1e-300).sqrt() } else { sum / l.get(j).map_or(1.0, |r| r[0]) };
            if let Some(cell) = l.get_mut(i).and_then(|r| r.get_mut(k)) {
                *cell = value;
            }
        }
    }
    // L z = y, then Lᵀ p = z.
    let mut z = vec![0.0; n];
    for i in 0..n {
        let mut s = y.get(i).copied().unwrap_or(0.0);
        for k in 1..4.min(i + 1) {
            s -= l.get(i).and_then(|r| r.get(k)).copied().unwrap_or(0.0) * z.get(i - k).copied().unwrap_or(0.0);
        }
        if let Some(zi) = z.get_mut(i) {
            *zi = s / l.get(i).map_or(1.0, |r| r[0]);
        }
    }
    let mut p = vec![0.0; n];
    for i in (0..n).rev() {
        let mut s = z.get(i).copied().unwrap_or(0.0);
        for k in 1..4 {
            let Some(pk) = p.get(i + k) else { break };
            s -= l.get(i + k).and_then(|r| r.get(k)).copied().unwrap_or(0.0) * pk;
        }
        if let Some(pi) = p.get_mut(i) {
            *pi = s / l.get(i).map_or(1.0, |r| r[0]);
        }
    }
    p
}

/// States and controls whose rollout reproduces `positions` (see the module documentation);
/// `initial_heading_rad` is used only if the vehicle never moves faster than `min_speed_mps`.
pub fn invert_positions(
    positions: &[Point2],
    dt_s: f64,
    min_speed_mps: f64,
    initial_heading_rad: f64,
) -> (Vec<State>, Vec<Control>) {
    let steps: Vec<Point2> =
        positions.windows(2).map(|w| if let [a, b] = w { b.sub(*a) } else { Point2::default() }).collect();
    let min_step = min_speed_mps * dt_s;
    let dir = |d: &Point2| d.y.atan2(d.x);
    let mut theta = steps.iter().find(|d| d.norm() >= min_step && d.norm() > 0.0).map_or(initial_heading_rad, dir);
    let mut heads = Vec::with_capacity(steps.len());
    for d in &steps {
        let norm = d.norm();
        let v = if norm >= min_step && norm > 0.0 {
            let turn = wrap_angle(dir(d) - theta);
            if turn.abs() <= std::f64::consts::FRAC_PI_2 {
                theta += turn;
                norm / dt_s
            } else {
                theta += wrap_angle(turn - std::f64::consts::PI);
                -norm / dt_s
            }
        } else {
            // Held heading: the speed is the displacement along it.
            d.dot(Point2::from_heading(theta)) / dt_s
        };
        heads.push((theta, v));
    }
    // The last state keeps the last step's heading and speed (a single position stands still).
    heads.push(heads.last().copied().unwrap_or((theta, 0.0)));
    let states: Vec<State> = positions
        .iter()
        .zip(&heads)
        .map(|(p, &(theta_rad, speed_mps))| State { px: p.x, py: p.y, theta_rad, speed_mps })
        .collect();
    let mut controls: Vec<Control> = states
        .windows(2)
        .map(|w| match w {
            [a, b] => Control {
                accel_mps2: (b.speed_mps - a.speed_mps) / dt_s,
                yaw_rate_radps: (b.theta_rad - a.theta_rad) / dt_s,
            },
            _ => Control::default(),
        })
        .collect();
    controls.truncate(positions.len().saturating_sub(1));
    (states, controls)
}

/// Turns a track sampled on one time grid into states and controls of the kinematic model.
pub fn to_controls(track: &Track, options: &InverseOptions) -> Result<InverseResult, InverseError> {
    let InverseOptions { position_noise_m, jerk_std_mps3, min_speed_mps } = *options;
    let finite = position_noise_m.is_finite() && jerk_std_mps3.is_finite() && min_speed_mps.is_finite();
    if !(finite && position_noise_m >= 0.0 && jerk_std_mps3 > 0.0 && min_speed_mps >= 0.0) {
        return Err(InverseError::Options(format!("{options:?}: noise ≥ 0, jerk > 0, min speed ≥ 0, all finite")));
    }
    let n = track.samples.len();
    if n < 3 {
        return Err(InverseError::TooShort { track: track.id.clone(), samples: n });
    }
    let dt_s = track.dt_s;
    if !(dt_s.is_finite() && dt_s > 0.0) {
        return Err(InverseError::Options(format!("track `{}` has period {dt_s} s", track.id)));
    }
    for (index, w) in track.samples.windows(2).enumerate() {
        let [a, b] = w else { continue };
        let step_s = b.t_s - a.t_s;
        if (step_s - dt_s).abs().is_nan() || (step_s - dt_s).abs() > 0.01 * dt_s {
            return Err(InverseError::NonUniform { track: track.id.clone(), index, step_s, dt_s });
        }
    }
    if let Some(index) = track.samples.iter().position(|s| !s.position().is_finite()) {
        return Err(InverseError::NonFinite { track: track.id.clone(), index });
    }
    let lambda = smoothing_lambda(position_noise_m, jerk_std_mps3, dt_s);
    let xs: Vec<f64> = track.samples.iter().map(|s| s.x_m).collect();
    let ys: Vec<f64> = track.samples.iter().map(|s| s.y_m).collect();
    let smoothed: Vec<Point2> =
        smooth(&xs, lambda).into_iter().zip(smooth(&ys, lambda)).map(|(x, y)| Point2::new(x, y)).collect();
    let smoothing_rms_m =
        (smoothed.iter().zip(&track.samples).map(|(p, s)| p.dist(s.position()).powi(2)).sum::<f64>() / n as f64).sqrt();
    let psi0 = track.samples.iter().find_map(|s| s.psi_rad).unwrap_or(0.0);
    let (states, controls) = invert_positions(&smoothed, dt_s, min_speed_mps, psi0);
    let trajectory = AgentTrajectory { id: track.id.clone(), role: AgentRole::Bv, states, controls };
    let rollout_gap_m = trajectory.rollout_gap_m(dt_s);
    Ok(InverseResult { trajectory, dt_s, rollout_gap_m, smoothing_rms_m })
}

/// Every vehicle track of `episode`, cut at its gaps, turned into controls; pieces shorter than
/// `min_samples` (at least 3) are left out, and the pieces that fail come back with their error.
pub fn episode_to_controls(
    episode: &crate::tracks::Episode,
    options: &InverseOptions,
    min_samples: usize,
) -> (Vec<InverseResult>, Vec<InverseError>) {
    let mut done = Vec::new();
    let mut failed = Vec::new();
    for track in episode.tracks.iter().filter(|t| t.kind.is_vehicle()) {
        for piece in split_at_gaps(track).iter().filter(|p| p.samples.len() >= min_samples.max(3)) {
            match to_controls(piece, options) {
                Ok(r) => done.push(r),
                Err(e) => failed.push(e),
            }
        }
    }
    (done, failed)
}

/// `track` cut at its gaps ([`Track::gaps`]) into pieces on one time grid each; pieces keep the
/// id with `#k` appended when there is more than one.
pub fn split_at_gaps(track: &Track) -> Vec<Track> {
    let gaps = track.gaps();
    if gaps.is_empty() {
        return vec![track.clone()];
    }
    let mut out = Vec::new();
    let mut from = 0;
    for (k, end) in gaps.iter().map(|g| g + 1).chain(std::iter::once(track.samples.len())).enumerate() {
        let samples = track.samples.get(from..end).unwrap_or_default().to_vec();
        out.push(Track { id: format!("{}#{k}", track.id), samples, ..track.clone() });
        from = end;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tracks::{AgentKind, TrackSample};
    use proptest::prelude::*;
    use rand_chacha::ChaCha8Rng;
    use rand_chacha::rand_core::SeedableRng;
    use rand_distr::{Distribution, Normal};
    use v2t_model::kinematics::rollout;

    /// Smooth controls: sums of slow sinusoids (periods 3–12 s), as a driver would apply.
    fn controls(n: usize, dt: f64, amp_a: f64, amp_w: f64, phase: f64) -> Vec<Control> {
        (0..n)
            .map(|k| {
                let t = k as f64 * dt;
                Control {
                    accel_mps2: amp_a * ((t / 8.0 * std::f64::consts::TAU) + phase).sin(),
                    yaw_rate_radps: amp_w * ((t / 6.0 * std::f64::consts::TAU) + 2.0 * phase).sin(),
                }
            })
            .collect()
    }

    fn track_of(states: &[State], dt: f64, noise_m: f64, seed: u64) -> Track {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let normal = Normal::new(0.0, noise_m.max(1e-300)).unwrap();
        let mut e = || if noise_m > 0.0 { normal.sample(&mut rng) } else { 0.0 };
        let samples =
            states.iter().enumerate().map(|(k, s)| TrackSample::at(k as f64 * dt, s.px + e(), s.py + e())).collect();
        Track { id: "t".into(), dt_s: dt, kind: AgentKind::Car, dims: None, samples }
    }

    fn rms(a: impl Iterator<Item = f64>) -> f64 {
        let v: Vec<f64> = a.collect();
        (v.iter().map(|x| x * x).sum::<f64>() / v.len().max(1) as f64).sqrt()
    }

    #[test]
    fn smoothing_keeps_quadratics() {
        let y: Vec<f64> = (0..50).map(|k| 0.05 * (k as f64).powi(2) - 2.0 * k as f64 + 7.0).collect();
        let p = smooth(&y, 1e4);
        for (a, b) in y.iter().zip(&p) {
            assert!((a - b).abs() < 1e-6 * a.abs().max(1.0), "{a} {b}");
        }
    }

    #[test]
    fn noiseless_tracks_give_back_their_controls() {
        let dt = 0.1;
        let u = controls(120, dt, 1.5, 0.2, 0.3);
        let xs = rollout(State { px: 5.0, py: -3.0, theta_rad: 0.7, speed_mps: 12.0 }, &u, dt);
        let opts = InverseOptions { position_noise_m: 0.0, ..InverseOptions::default() };
        let r = to_controls(&track_of(&xs, dt, 0.0, 0), &opts).unwrap();
        assert!(r.rollout_gap_m < 1e-9, "gap {}", r.rollout_gap_m);
        for (a, b) in u.iter().zip(&r.trajectory.controls).take(118) {
            assert!((a.accel_mps2 - b.accel_mps2).abs() < 1e-6 && (a.yaw_rate_radps - b.yaw_rate_radps).abs() < 1e-6);
        }
        assert!((r.trajectory.states[0].theta_rad - 0.7).abs() < 1e-9);
    }

    #[test]
    fn standing_and_reversing_do_not_spin() {
        let dt = 0.1;
        // Forward 2 s, stand 2 s (with 1 cm jitter), back 1 s.
        let mut pos = Vec::new();
        for k in 0..20 {
            pos.push(Point2::new(0.5 * k as f64, 0.0));
        }
        for k in 0..20 {
            pos.push(Point2::new(9.5 + if k % 2 == 0 { 0.01 } else { -0.01 }, 0.003 * (k % 3) as f64));
        }
        for k in 0..10 {
            pos.push(Point2::new(9.5 - 0.2 * k as f64, 0.0));
        }
        let (states, u) = invert_positions(&pos, dt, 0.3, 0.0);
        assert!(u.iter().all(|c| c.yaw_rate_radps.abs() < 1e-9), "no turning");
        assert!(states[45].speed_mps < -1.0);
        let traj = AgentTrajectory { id: "r".into(), role: AgentRole::Bv, states, controls: u };
        assert!(traj.rollout_gap_m(dt) < 0.3 * dt * 20.0);
    }

    #[test]
    fn whole_episodes_are_inverted_piece_by_piece() {
        let dt = 0.1;
        let u = controls(60, dt, 1.0, 0.1, 0.0);
        let xs = rollout(State { px: 0.0, py: 0.0, theta_rad: 0.0, speed_mps: 10.0 }, &u, dt);
        let mut car = track_of(&xs, dt, 0.0, 0);
        car.samples.drain(20..23);
        let mut walker = track_of(&xs, dt, 0.0, 0);
        walker.id = "w".into();
        walker.kind = AgentKind::Pedestrian;
        let mut bad = track_of(&xs, dt, 0.0, 0);
        bad.id = "bad".into();
        bad.samples[30].x_m = f64::INFINITY;
        let e = crate::tracks::Episode::from_tracks("e", vec![car, walker, bad]);
        let (done, failed) = episode_to_controls(&e, &InverseOptions::default(), 10);
        assert_eq!(done.len(), 2, "the car in two pieces");
        assert_eq!(done[0].trajectory.id, "t#0");
        assert_eq!(failed.len(), 1);
    }

    #[test]
    fn one_or_two_positions_still_give_states() {
        let (s1, u1) = invert_positions(&[Point2::new(1.0, 2.0)], 0.1, 0.3, 0.5);
        assert_eq!((s1.len(), u1.len()), (1, 0));
        assert_eq!((s1[0].theta_rad, s1[0].speed_mps), (0.5, 0.0));
        let (s2, u2) = invert_positions(&[Point2::new(0.0, 0.0), Point2::new(0.0, 1.0)], 0.1, 0.3, 0.0);
        assert_eq!((s2.len(), u2.len()), (2, 1));
        assert!((s2[0].theta_rad - std::f64::consts::FRAC_PI_2).abs() < 1e-12 && (s2[0].speed_mps - 10.0).abs() < 1e-9);
        assert!(invert_positions(&[], 0.1, 0.3, 0.0).0.is_empty());
    }

    #[test]
    fn bad_tracks_are_errors() {
        let t = track_of(&[State::default(); 2], 0.1, 0.0, 0);
        assert!(matches!(to_controls(&t, &InverseOptions::default()), Err(InverseError::TooShort { .. })));
        let mut t = track_of(&[State::default(); 10], 0.1, 0.0, 0);
        t.samples.remove(4);
        assert!(matches!(to_controls(&t, &InverseOptions::default()), Err(InverseError::NonUniform { index: 3, .. })));
        let pieces = split_at_gaps(&t);
        assert_eq!(pieces.iter().map(|p| p.samples.len()).collect::<Vec<_>>(), vec![4, 5]);
        assert!(pieces.iter().all(|p| to_controls(p, &InverseOptions::default()).is_ok()));
        let mut t = track_of(&[State::default(); 10], 0.1, 0.0, 0);
        t.samples[3].y_m = f64::NAN;
        assert!(matches!(to_controls(&t, &InverseOptions::default()), Err(InverseError::NonFinite { index: 3, .. })));
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(64))]
        /// The smoother is exact on quadratics, linear, and never increases the jerk penalty's
        /// objective above that of the data itself.
        #[test]
        fn smoother_properties(
            y in prop::collection::vec(-50.0f64..50.0, 4..80),
            c in prop::array::uniform3(-5.0f64..5.0),
            log_lambda in -2.0f64..6.0,
        ) {
            let lambda = 10f64.powf(log_lambda);
            let n = y.len();
            let q: Vec<f64> = (0..n).map(|k| c[0] + c[1] * k as f64 + c[2] * 0.01 * (k * k) as f64).collect();
            for (a, b) in q.iter().zip(smooth(&q, lambda)) {
                prop_assert!((a - b).abs() < 1e-6 * (1.0 + a.abs()), "{} {}", a, b);
            }
            let sum: Vec<f64> = y.iter().zip(&q).map(|(a, b)| a + b).collect();
            let (sy, sq, ss) = (smooth(&y, lambda), smooth(&q, lambda), smooth(&sum, lambda));
            for k in 0..n {
                prop_assert!((ss[k] - sy[k] - sq[k]).abs() < 1e-6 * (1.0 + ss[k].abs()));
            }
            let objective = |p: &[f64]| {
                let fit: f64 = p.iter().zip(&y).map(|(a, b)| (a - b).powi(2)).sum();
                let d3: f64 = p.windows(4).map(|w| (w[3] - 3.0 * w[2] + 3.0 * w[1] - w[0]).powi(2)).sum();
                fit + lambda * d3
            };
            prop_assert!(objective(&sy) <= objective(&y) * (1.0 + 1e-9) + 1e-9);
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(32))]
        /// Known controls rolled out, 5 cm position noise added: the recovered controls match within
        /// 0.35 m/s² and 0.06 rad/s RMS away from the ends, and their rollout reproduces the
        /// smoothed path.
        #[test]
        fn noisy_rollouts_give_back_their_controls(
            amp_a in 0.0f64..2.0, amp_w in 0.0f64..0.3, phase in 0.0f64..6.0,
            v0 in 6.0f64..20.0, th0 in -3.0f64..3.0, seed in 0u64..1000,
        ) {
            let dt = 0.1;
            let u = controls(150, dt, amp_a, amp_w, phase);
            let xs = rollout(State { px: 100.0, py: 50.0, theta_rad: th0, speed_mps: v0 }, &u, dt);
            let r = to_controls(&track_of(&xs, dt, 0.05, seed), &InverseOptions::default()).unwrap();
            prop_assert!(r.rollout_gap_m < 1e-6, "gap {}", r.rollout_gap_m);
            prop_assert!(r.smoothing_rms_m < 0.1);
            let inner = 15..135;
            let ea = rms(inner.clone().map(|k| u[k].accel_mps2 - r.trajectory.controls[k].accel_mps2));
            let ew = rms(inner.map(|k| u[k].yaw_rate_radps - r.trajectory.controls[k].yaw_rate_radps));
            prop_assert!(ea < 0.35, "accel rms error {ea}");
            prop_assert!(ew < 0.06, "yaw rate rms error {ew}");
        }
    }

    #[test]
    fn report_recovery_errors() {
        // Not a property: prints the typical errors for the README.
        let dt = 0.1;
        let u = controls(150, dt, 1.5, 0.2, 0.4);
        let xs = rollout(State { px: 0.0, py: 0.0, theta_rad: 0.3, speed_mps: 12.0 }, &u, dt);
        for noise in [0.02, 0.05, 0.1] {
            let opts = InverseOptions { position_noise_m: noise, ..InverseOptions::default() };
            let r = to_controls(&track_of(&xs, dt, noise, 7), &opts).unwrap();
            let ea = rms((15..135).map(|k| u[k].accel_mps2 - r.trajectory.controls[k].accel_mps2));
            let ew = rms((15..135).map(|k| u[k].yaw_rate_radps - r.trajectory.controls[k].yaw_rate_radps));
            println!(
                "noise {noise} m: accel rms err {ea:.3} m/s², yaw rate rms err {ew:.4} rad/s, gap {:.2e} m, smoothing rms {:.3} m",
                r.rollout_gap_m, r.smoothing_rms_m
            );
        }
    }
}
