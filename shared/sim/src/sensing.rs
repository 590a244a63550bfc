//! Localization as the vehicle's computers see it: the true state, delayed, plus noise that is
//! either white (Gaussian) or correlated (Ornstein–Uhlenbeck). Deterministic given the seed.

use std::collections::VecDeque;

use rand_chacha::ChaCha8Rng;
use rand_chacha::rand_core::SeedableRng;
use rand_distr::{Distribution, StandardNormal};
use v2t_model::geometry::wrap_angle;
use v2t_model::kinematics::State;
use v2t_model::vehicle::{LocalizationNoise, NoiseModel};

/// A noisy, delayed view of one vehicle's state.
#[derive(Debug, Clone)]
pub struct Localization {
    noise: LocalizationNoise,
    enabled: bool,
    rng: ChaCha8Rng,
    /// True states with their times, oldest first.
    history: VecDeque<(f64, State)>,
    /// Current noise of `[x, y, θ, v]`.
    error: [f64; 4],
    last_noise_t: Option<f64>,
    /// Published measurements with their publication times, oldest first.
    published: VecDeque<(f64, State)>,
    horizon_s: f64,
}

impl Localization {
    /// A localization source with its own random stream (`seed`, `stream`), keeping enough history
    /// to serve any extra delay up to `max_extra_delay_s` on top of its own.
    pub fn new(noise: LocalizationNoise, enabled: bool, seed: u64, stream: u64, max_extra_delay_s: f64) -> Self {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        rng.set_stream(stream);
        Self {
            noise,
            enabled,
            rng,
            history: VecDeque::new(),
            error: [0.0; 4],
            last_noise_t: None,
            published: VecDeque::new(),
            horizon_s: noise.delay_s + max_extra_delay_s + 0.5,
        }
    }

    fn stds(&self) -> [f64; 4] {
        [self.noise.position_std_m, self.noise.position_std_m, self.noise.heading_std_rad, self.noise.speed_std_mps]
    }

    /// Records the true state at `t_s` (call every plant step).
    pub fn record_truth(&mut self, t_s: f64, truth: State) {
        self.history.push_back((t_s, truth));
        while self.history.len() > 2 && self.history.front().is_some_and(|(t, _)| *t < t_s - self.horizon_s) {
            self.history.pop_front();
        }
    }

    /// Advances the noise process to `t_s`.
    fn advance_noise(&mut self, t_s: f64) {
        if !self.enabled {
            return;
        }
        let stds = self.stds();
        let dt = self.last_noise_t.map_or(f64::INFINITY, |t0| (t_s - t0).max(0.0));
        self.last_noise_t = Some(t_s);
        for (e, sd) in self.error.iter_mut().zip(stds) {
            let z: f64 = StandardNormal.sample(&mut self.rng);
            *e = match self.noise.model {
                NoiseModel::Gaussian => sd * z,
                NoiseModel::OrnsteinUhlenbeck => {
                    // Exact discretisation: e' = φ e + sd √(1−φ²) z, φ = exp(−dt/τ).
                    let phi = if dt.is_finite() { (-dt / self.noise.correlation_time_s).exp() } else { 0.0 };
                    phi * *e + sd * (1.0 - phi * phi).sqrt() * z
                }
            };
        }
    }

    /// True state at `t_s`, linearly interpolated in the history (clamped at its ends).
    fn truth_at(&self, t_s: f64) -> Option<State> {
        let k = self.history.partition_point(|(t, _)| *t <= t_s);
        let after = self.history.get(k);
        let before = k.checked_sub(1).and_then(|i| self.history.get(i));
        match (before, after) {
            (Some((t0, a)), Some((t1, b))) if t1 > t0 => {
                let w = (t_s - t0) / (t1 - t0);
                let lerp = |x: f64, y: f64| x + w * (y - x);
                Some(State {
                    px: lerp(a.px, b.px),
                    py: lerp(a.py, b.py),
                    theta_rad: a.theta_rad + w * wrap_angle(b.theta_rad - a.theta_rad),
                    speed_mps: lerp(a.speed_mps, b.speed_mps),
                })
            }
            (Some((_, a)), _) => Some(*a),
            (None, Some((_, b))) => Some(*b),
            (None, None) => None,
        }
    }

    /// Produces the measurement published at `t_s`: the true state of `delay_s` ago plus the
    /// current noise. Keeps it so that observers further away can read it later.
    pub fn publish(&mut self, t_s: f64) -> Option<State> {
        self.advance_noise(t_s);
        let truth = self.truth_at(t_s - self.noise.delay_s)?;
        let [ex, ey, eth, ev] = if self.enabled { self.error } else { [0.0; 4] };
        let measured = State {
            px: truth.px + ex,
            py: truth.py + ey,
            theta_rad: wrap_angle(truth.theta_rad + eth),
            speed_mps: (truth.speed_mps + ev).max(0.0),
        };
        self.published.push_back((t_s, measured));
        while self.published.len() > 2 && self.published.front().is_some_and(|(t, _)| *t < t_s - self.horizon_s) {
            self.published.pop_front();
        }
        Some(measured)
    }

    /// The newest measurement an observer `extra_delay_s` downstream has at `t_s`, and its age
    /// (time since the true state it describes), s.
    pub fn seen_at(&self, t_s: f64, extra_delay_s: f64) -> Option<(State, f64)> {
        let k = self.published.partition_point(|(t, _)| *t <= t_s - extra_delay_s + 1e-9);
        let (t_pub, state) = k.checked_sub(1).and_then(|i| self.published.get(i)).copied()?;
        Some((state, t_s - t_pub + self.noise.delay_s))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn noise(model: NoiseModel) -> LocalizationNoise {
        LocalizationNoise {
            model,
            position_std_m: 0.1,
            heading_std_rad: 0.01,
            speed_std_mps: 0.1,
            correlation_time_s: 1.0,
            delay_s: 0.1,
        }
    }

    fn moving(t: f64) -> State {
        State { px: 10.0 * t, py: 0.0, theta_rad: 0.0, speed_mps: 10.0 }
    }

    #[test]
    fn delay_without_noise_returns_the_past_state() {
        let mut loc = Localization::new(noise(NoiseModel::Gaussian), false, 1, 0, 0.2);
        for k in 0..=100 {
            let t = k as f64 * 0.01;
            loc.record_truth(t, moving(t));
            if k % 5 == 0 {
                loc.publish(t).unwrap();
            }
        }
        let own = loc.seen_at(1.0, 0.0).unwrap();
        assert!((own.1 - 0.1).abs() < 1e-9 && (own.0.px - 9.0).abs() < 1e-9, "{own:?}");
        // 0.07 s downstream the newest measurement is the one published at 0.9 s.
        let (s, age) = loc.seen_at(1.0, 0.07).unwrap();
        assert!((age - 0.2).abs() < 1e-9, "{age}");
        assert!((s.px - 8.0).abs() < 1e-9, "{s:?}");
    }

    #[test]
    fn same_seed_same_noise_and_statistics_match_the_configuration() {
        for model in [NoiseModel::Gaussian, NoiseModel::OrnsteinUhlenbeck] {
            let run = |seed| {
                let mut loc = Localization::new(noise(model), true, seed, 3, 0.0);
                (0..20000)
                    .map(|k| {
                        let t = k as f64 * 0.1;
                        loc.record_truth(t, moving(t));
                        loc.publish(t).unwrap().py
                    })
                    .collect::<Vec<f64>>()
            };
            let a = run(7);
            assert_eq!(a, run(7));
            assert_ne!(a, run(8));
            let sd = (a.iter().map(|e| e * e).sum::<f64>() / a.len() as f64).sqrt();
            assert!((sd - 0.1).abs() < 0.01, "{model:?}: std {sd}");
            // OU noise is correlated from one 0.1 s sample to the next; Gaussian is not.
            let lag1 = a.windows(2).map(|w| w[0] * w[1]).sum::<f64>() / (a.len() as f64 * sd * sd);
            match model {
                NoiseModel::Gaussian => assert!(lag1.abs() < 0.05, "{lag1}"),
                NoiseModel::OrnsteinUhlenbeck => assert!((lag1 - (-0.1f64).exp()).abs() < 0.05, "{lag1}"),
            }
        }
    }
}
