//! The network between the track and the cloud, as the simulated proving ground sees it: a one-way
//! delay per message drawn from a distribution, jitter, loss, and either in-order delivery (one TCP
//! connection, as MQTT runs: a late message holds back every later one) or independent delivery
//! (later messages may overtake: reordering). Both directions are set separately. Deterministic
//! given a seed. Settings are written in `config/network/*.toml`.
//!
//! ```
//! use v2t_sim::network::{Channel, Delay, Direction};
//! let dir = Direction { delay: Delay::Constant { ms: 50.0 }, jitter_ms: 0.0, loss: 0.0 };
//! let mut ch: Channel<&str> = Channel::new(dir, true, 1, 0);
//! ch.send(1.0, "state");
//! assert!(ch.deliver(1.04).is_empty());
//! assert_eq!(ch.deliver(1.05), vec![(1.05, "state")]);
//! ```

use std::collections::VecDeque;

use rand_chacha::ChaCha8Rng;
use rand_chacha::rand_core::SeedableRng;
use rand_distr::{Distribution, StandardNormal, StandardUniform};
use serde::{Deserialize, Serialize};
use v2t_model::validate::{Validate, ValidationError, in_range};

/// Longest one-way delay a setting may describe, ms (beyond it the link is down, not slow).
pub const MAX_DELAY_MS: f64 = 10_000.0;

/// The standard normal's 99th percentile.
const Z_99: f64 = 2.326_347_874_040_841;

/// A one-way delay distribution, ms.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum Delay {
    /// Always the same.
    Constant {
        /// The delay, ms.
        ms: f64,
    },
    /// A shifted log-normal, heavy-tailed as cellular links are: never below `min_ms`, half of
    /// the messages within `median_ms`, 99 % within `p99_ms`.
    Lognormal {
        /// Floor (propagation and processing), ms.
        min_ms: f64,
        /// Median, ms.
        median_ms: f64,
        /// 99th percentile, ms.
        p99_ms: f64,
    },
}

impl Delay {
    /// The median, ms.
    pub fn median_ms(&self) -> f64 {
        match *self {
            Self::Constant { ms } => ms,
            Self::Lognormal { median_ms, .. } => median_ms,
        }
    }

    fn sample(&self, rng: &mut ChaCha8Rng) -> f64 {
        match *self {
            Self::Constant { ms } => ms,
            Self::Lognormal { min_ms, median_ms, p99_ms } => {
                let mu = (median_ms - min_ms).ln();
                let sigma = ((p99_ms - min_ms) / (median_ms - min_ms)).ln() / Z_99;
                let z: f64 = StandardNormal.sample(rng);
                (min_ms + (mu + sigma * z).exp()).min(MAX_DELAY_MS)
            }
        }
    }
}

impl Validate for Delay {
    fn validate(&self) -> Result<(), ValidationError> {
        match *self {
            Self::Constant { ms } => in_range("ms", ms, 0.0, MAX_DELAY_MS),
            Self::Lognormal { min_ms, median_ms, p99_ms } => {
                in_range("min_ms", min_ms, 0.0, MAX_DELAY_MS)?;
                in_range("median_ms", median_ms, 0.0, MAX_DELAY_MS)?;
                in_range("p99_ms", p99_ms, 0.0, MAX_DELAY_MS)?;
                if !(min_ms < median_ms && median_ms < p99_ms) {
                    return Err(ValidationError::new(
                        "median_ms",
                        format!("must lie strictly between min_ms = {min_ms} and p99_ms = {p99_ms}, got {median_ms}"),
                    ));
                }
                Ok(())
            }
        }
    }
}

/// One direction of the link.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Direction {
    /// One-way delay.
    pub delay: Delay,
    /// Uniform extra delay in `[0, jitter_ms)` on top of the distribution, ms.
    #[serde(default)]
    pub jitter_ms: f64,
    /// Share of messages that never arrive, in `[0, 1)`.
    #[serde(default)]
    pub loss: f64,
}

impl Direction {
    /// No delay, no loss.
    pub const IDEAL: Self = Self { delay: Delay::Constant { ms: 0.0 }, jitter_ms: 0.0, loss: 0.0 };
}

impl Validate for Direction {
    fn validate(&self) -> Result<(), ValidationError> {
        self.delay.validate().map_err(|e| e.within("delay"))?;
        in_range("jitter_ms", self.jitter_ms, 0.0, MAX_DELAY_MS)?;
        in_range("loss", self.loss, 0.0, 0.99)
    }
}

/// A network between the track and the cloud, as written in `config/network/*.toml`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NetworkSettings {
    /// Name in tables.
    pub name: String,
    /// Where the figures come from (shown with every result that depends on them).
    pub source: String,
    /// One connection per direction, as MQTT over TCP: a message never overtakes an earlier one
    /// (a late one holds the next back). `false`: every message travels on its own, and a later
    /// one may arrive first.
    pub in_order: bool,
    /// BV (and VUT) states to the cloud.
    pub uplink: Direction,
    /// Plans from the cloud to the BV.
    pub downlink: Direction,
    /// The cloud's time from a state's arrival to its plan's departure (the decision, signing,
    /// the broker's hops), ms.
    #[serde(default = "default_processing_ms")]
    pub processing_ms: f64,
}

/// The default [`NetworkSettings::processing_ms`]: the regulator's p99 decision time on a 2-core
/// machine (1.4 ms, `v2t-bench game`) plus signing and the broker's hops on loopback, rounded up.
pub const DEFAULT_PROCESSING_MS: f64 = 2.0;

fn default_processing_ms() -> f64 {
    DEFAULT_PROCESSING_MS
}

impl NetworkSettings {
    /// The same one-way `delay_ms` and `loss` both ways, no jitter, in order.
    pub fn constant(delay_ms: f64, loss: f64) -> Self {
        let d = Direction { delay: Delay::Constant { ms: delay_ms }, jitter_ms: 0.0, loss };
        Self {
            name: format!("{delay_ms:.0} ms, loss {:.0} %", 100.0 * loss),
            source: "sweep: constant one-way delay and independent loss".into(),
            in_order: true,
            uplink: d,
            downlink: d,
            processing_ms: DEFAULT_PROCESSING_MS,
        }
    }
}

impl Validate for NetworkSettings {
    fn validate(&self) -> Result<(), ValidationError> {
        if self.name.trim().is_empty() {
            return Err(ValidationError::new("name", "must not be empty"));
        }
        self.uplink.validate().map_err(|e| e.within("uplink"))?;
        self.downlink.validate().map_err(|e| e.within("downlink"))?;
        in_range("processing_ms", self.processing_ms, 0.0, MAX_DELAY_MS)
    }
}

/// One direction of a link in flight: messages with their arrival times. Deterministic given
/// `seed` and `stream`.
#[derive(Debug, Clone)]
pub struct Channel<T> {
    direction: Direction,
    in_order: bool,
    rng: ChaCha8Rng,
    /// In flight: (arrival time, sequence, message), unordered.
    flight: VecDeque<(f64, u64, T)>,
    sent: u64,
    lost: u64,
    last_arrival_s: f64,
}

impl<T> Channel<T> {
    /// A channel with its own random stream.
    pub fn new(direction: Direction, in_order: bool, seed: u64, stream: u64) -> Self {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        rng.set_stream(stream);
        Self { direction, in_order, rng, flight: VecDeque::new(), sent: 0, lost: 0, last_arrival_s: f64::NEG_INFINITY }
    }

    /// Sends `msg` at `t_s`: it is lost, or arrives after a drawn delay.
    pub fn send(&mut self, t_s: f64, msg: T) {
        self.sent += 1;
        if self.direction.loss > 0.0 && unit(&mut self.rng) < self.direction.loss {
            self.lost += 1;
            return;
        }
        let mut ms = self.direction.delay.sample(&mut self.rng);
        if self.direction.jitter_ms > 0.0 {
            ms += self.direction.jitter_ms * unit(&mut self.rng);
        }
        let mut at = t_s + ms.clamp(0.0, MAX_DELAY_MS) / 1000.0;
        if self.in_order {
            at = at.max(self.last_arrival_s);
            self.last_arrival_s = at;
        }
        self.flight.push_back((at, self.sent, msg));
    }

    /// Every message arrived by `t_s`, in order of arrival, with its arrival time.
    pub fn deliver(&mut self, t_s: f64) -> Vec<(f64, T)> {
        let mut out = Vec::new();
        let mut i = 0;
        while i < self.flight.len() {
            if self.flight.get(i).is_some_and(|m| m.0 <= t_s + 1e-9) {
                if let Some(m) = self.flight.remove(i) {
                    out.push(m);
                }
            } else {
                i += 1;
            }
        }
        out.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        out.into_iter().map(|(at, _, m)| (at, m)).collect()
    }

    /// Messages sent so far.
    pub fn sent(&self) -> u64 {
        self.sent
    }

    /// Messages lost so far.
    pub fn lost(&self) -> u64 {
        self.lost
    }
}

/// A uniform draw in `[0, 1)`.
fn unit(rng: &mut ChaCha8Rng) -> f64 {
    StandardUniform.sample(rng)
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing)]

    use super::*;
    use proptest::prelude::*;

    fn lognormal() -> Direction {
        Direction { delay: Delay::Lognormal { min_ms: 5.0, median_ms: 12.0, p99_ms: 40.0 }, jitter_ms: 0.0, loss: 0.0 }
    }

    #[test]
    fn the_lognormal_keeps_its_floor_median_and_99th_percentile() {
        let mut ch: Channel<u32> = Channel::new(lognormal(), false, 7, 0);
        for k in 0..20_000 {
            ch.send(0.0, k);
        }
        let mut d: Vec<f64> = ch.deliver(100.0).into_iter().map(|(at, _)| at * 1000.0).collect();
        d.sort_by(f64::total_cmp);
        assert!(d[0] >= 5.0, "{}", d[0]);
        let q = |p: f64| d[(p * d.len() as f64) as usize];
        assert!((q(0.5) - 12.0).abs() < 0.3, "median {}", q(0.5));
        assert!((q(0.99) - 40.0).abs() < 3.0, "p99 {}", q(0.99));
    }

    #[test]
    fn in_order_never_lets_a_message_overtake_and_independent_delivery_does() {
        for in_order in [true, false] {
            let mut ch: Channel<u32> = Channel::new(lognormal(), in_order, 3, 1);
            for k in 0..2_000 {
                ch.send(f64::from(k) * 0.001, k);
            }
            let got: Vec<u32> = ch.deliver(100.0).into_iter().map(|(_, m)| m).collect();
            assert_eq!(got.len(), 2_000);
            let overtaken = got.windows(2).filter(|w| w[1] < w[0]).count();
            assert_eq!(overtaken == 0, in_order, "in_order {in_order}: {overtaken} overtakings");
        }
    }

    #[test]
    fn loss_drops_its_share_and_the_same_seed_gives_the_same_draws() {
        let dir = Direction { loss: 0.05, ..Direction::IDEAL };
        let run = |seed| {
            let mut ch: Channel<u32> = Channel::new(dir, true, seed, 0);
            (0..20_000).for_each(|k| ch.send(0.0, k));
            (ch.lost(), ch.deliver(0.0).into_iter().map(|(_, m)| m).collect::<Vec<_>>())
        };
        let (lost, got) = run(11);
        assert!((900..1100).contains(&lost), "lost {lost}");
        assert_eq!(got.len() as u64 + lost, 20_000);
        assert_eq!(run(11), (lost, got));
        assert_ne!(run(12).1, run(11).1);
    }

    #[test]
    fn settings_name_the_field_and_the_bound() {
        let bad = Direction {
            delay: Delay::Lognormal { min_ms: 5.0, median_ms: 50.0, p99_ms: 40.0 },
            jitter_ms: 0.0,
            loss: 0.0,
        };
        let e = bad.validate().unwrap_err().to_string();
        assert!(e.contains("delay.median_ms") && e.contains("p99_ms = 40"), "{e}");
        let e = Direction { loss: 1.0, ..Direction::IDEAL }.validate().unwrap_err().to_string();
        assert!(e.contains("loss"), "{e}");
        let e = Direction { delay: Delay::Constant { ms: f64::NAN }, ..Direction::IDEAL }.validate().unwrap_err();
        assert!(e.to_string().contains("ms"), "{e}");
    }

    proptest! {
        /// Nothing arrives before it was sent, nothing arrives twice, and what is not lost arrives
        /// within the largest delay the setting allows.
        #[test]
        fn every_message_arrives_once_after_it_was_sent(
            seed in 0u64..1000,
            ms in 0.0f64..500.0,
            jitter in 0.0f64..100.0,
            loss in 0.0f64..0.5,
            in_order: bool,
        ) {
            let dir = Direction { delay: Delay::Constant { ms }, jitter_ms: jitter, loss };
            let mut ch: Channel<(u32, f64)> = Channel::new(dir, in_order, seed, 0);
            for k in 0..200u32 {
                let t = f64::from(k) * 0.1;
                ch.send(t, (k, t));
            }
            let got = ch.deliver(1.0e6);
            prop_assert_eq!(got.len() as u64 + ch.lost(), 200);
            let mut seen = std::collections::HashSet::new();
            for (at, (k, sent)) in &got {
                prop_assert!(seen.insert(*k));
                prop_assert!(*at >= sent + ms / 1000.0 - 1e-9);
                if !in_order {
                    prop_assert!(*at <= sent + (ms + jitter) / 1000.0 + 1e-9);
                }
            }
        }
    }
}
