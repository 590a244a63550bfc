//! How the VUT reacts to the BV at the conflict zone, identified while the run goes on.
//!
//! The follower of [`crate::regulator`] is the VUT's best response to the BV's key time: it
//! drives its free motion (its speed now, or the route speed earlier runs showed) and keeps the
//! order only as far as it must. A VUT written by someone else does more: it *sees* the BV and
//! brakes when it judges the gap too short — SUMO's drivers brake for a BV turning across them at
//! τ ≤ 2 s, a driver who must give way waits for a gap it accepts, and one that stood restarts
//! late. A BV that presses harder than the VUT accepts then gets a longer PET than it planned.
//!
//! **The model.** A small parametric driver, [`Reaction`]:
//!
//! - **Perception.** It sees the BV's arc length and speed and extrapolates them at constant
//!   speed (a BV standing before its zone is never coming); its own times to the zone are those
//!   of accelerating at its limit toward its free speed.
//! - **Gap acceptance.** It goes on when it clears the zone at least [`Reaction::gap_s`] before
//!   the BV enters, or enters at least `gap_s` after the BV has left; otherwise it yields: it
//!   brakes for a standing obstacle at its zone's entry (the IDM interaction term with its
//!   comfortable deceleration [`Reaction::decel_mps2`], time gap 1 s, standstill gap 1 m), unless
//!   it can no longer stop before the zone at that deceleration (it is committed).
//! - **Restart.** A VUT that stood and sees the gap open waits [`Reaction::restart_s`] before it
//!   moves off.
//! - Otherwise it drives its free motion (the IDM's free term toward its free speed).
//!
//! **Identification.** [`ReactionBelief`] is a posterior over a fixed grid of these drivers plus
//! one that does not react at all ([`HYPOTHESES`]; index 0). Every decision, each hypothesis
//! predicts the VUT's acceleration over the last cycle from the states measured at its start; the
//! measured acceleration updates the log-weights with a Gaussian likelihood (standard deviation
//! [`ACCEL_NOISE_MPS2`], tempered by [`EVIDENCE_WEIGHT`] because successive cycles are not
//! independent). Hypotheses differ only where one of them sees a conflict, so a VUT that is never
//! near one teaches nothing and keeps its prior. The prior is the campaign memory's posterior
//! from earlier runs of the test ([`ReactionBelief::set_prior`]) or [`DEFAULT_NONE_PRIOR`] on the
//! non-reacting driver and the rest spread evenly.
//!
//! **How the leader uses it** ([`crate::regulator`]): with a reacting driver most probable, the
//! leader predicts the VUT's delay for a candidate key time by simulating that driver against the
//! BV's motion to it ([`rollout`]), adds it to the follower's response and picks the key time whose
//! predicted PET is nearest τ. A harder press is predicted to cost what it costs.
//!
//! Pure, allocation-free and bounded: the belief is fixed arrays, a rollout at most
//! [`ROLLOUT_MAX_S`] of steps of [`ROLLOUT_DT_S`].

use serde::{Deserialize, Serialize};
use v2t_model::driving::{Idm, Obstacle, travel_time};
use v2t_model::metrics::OccupancyInterval;
use v2t_model::validate::{Validate, ValidationError, in_range};

/// Accepted gaps of the grid, s.
pub const GAPS_S: [f64; 6] = [0.5, 1.0, 1.5, 2.0, 2.5, 3.0];
/// Comfortable decelerations of the grid, m/s².
pub const DECELS_MPS2: [f64; 3] = [1.0, 2.0, 3.5];
/// Restart delays of the grid, s.
pub const RESTARTS_S: [f64; 2] = [0.0, 1.0];
/// Hypotheses: the driver that does not react (index 0) and every reacting one of the grid.
pub const HYPOTHESES: usize = 1 + GAPS_S.len() * DECELS_MPS2.len() * RESTARTS_S.len();
/// Prior weight of the driver that does not react when nothing earlier is known.
pub const DEFAULT_NONE_PRIOR: f64 = 0.3;
/// Standard deviation of a measured acceleration about a hypothesis' prediction, m/s².
pub const ACCEL_NOISE_MPS2: f64 = 1.0;
/// Share of one cycle's log-likelihood a hypothesis is credited with.
pub const EVIDENCE_WEIGHT: f64 = 0.5;
/// No hypothesis' probability falls below this (a VUT may change its mind).
pub const MIN_PROBABILITY: f64 = 1e-4;
/// Step of a rollout, s.
pub const ROLLOUT_DT_S: f64 = 0.1;
/// Longest rollout, s.
pub const ROLLOUT_MAX_S: f64 = 20.0;
/// A measurement cycle longer than this (or not positive) teaches nothing, s.
const MAX_CYCLE_S: f64 = 0.5;
/// A VUT at or below this speed stands, m/s.
const STANDING_MPS: f64 = 0.3;
/// How far before its zone's entry a yielding VUT aims to stop, m.
const STOP_MARGIN_M: f64 = 1.0;
/// IDM time gap and standstill gap of the yielding driver, s and m.
const IDM_TIME_GAP_S: f64 = 1.0;
const IDM_MIN_GAP_M: f64 = 1.0;
/// Largest deceleration a hypothesis predicts, m/s².
const MAX_REACT_DECEL_MPS2: f64 = 8.0;

/// One driver of the grid: how it reacts to the BV.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Reaction {
    /// The gap it accepts between one vehicle leaving the zone and the other entering, s.
    pub gap_s: f64,
    /// Its comfortable deceleration when it yields, m/s².
    pub decel_mps2: f64,
    /// How long it waits to move off after standing, once the gap is open, s.
    pub restart_s: f64,
}

/// Hypothesis `i` of the grid: `None` for the driver that does not react (`i = 0`) or out of range.
#[must_use]
pub fn hypothesis(i: usize) -> Option<Reaction> {
    if i == 0 || i >= HYPOTHESES {
        return None;
    }
    let k = i - 1;
    let (r, rest) = (k % RESTARTS_S.len(), k / RESTARTS_S.len());
    let (d, g) = (rest % DECELS_MPS2.len(), rest / DECELS_MPS2.len());
    Some(Reaction { gap_s: *GAPS_S.get(g)?, decel_mps2: *DECELS_MPS2.get(d)?, restart_s: *RESTARTS_S.get(r)? })
}

/// What the VUT knows of the scene: the zone along both paths and its own limits.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Scene {
    /// The zone along the BV's path.
    pub zone_bv: OccupancyInterval,
    /// The zone along the VUT's route.
    pub zone_vut: OccupancyInterval,
    /// The VUT's largest acceleration, m/s².
    pub vut_accel_mps2: f64,
    /// The VUT's largest deceleration, m/s².
    pub vut_decel_mps2: f64,
}

/// Both vehicles along their paths at one instant (arc length m, speed m/s).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Snapshot {
    /// BV arc length, m.
    pub bv_s_m: f64,
    /// BV speed, m/s.
    pub bv_v_mps: f64,
    /// VUT arc length, m.
    pub vut_s_m: f64,
    /// VUT speed, m/s.
    pub vut_v_mps: f64,
}

impl Reaction {
    /// Whether this driver, at `snap`, yields to the BV (its gap is too short and it can still stop).
    #[must_use]
    pub fn yields(&self, scene: &Scene, snap: &Snapshot, free_mps: f64) -> bool {
        let (zb, zv) = (scene.zone_bv, scene.zone_vut);
        if snap.bv_s_m >= zb.exit_s_m || snap.vut_s_m >= zv.enter_s_m {
            return false;
        }
        let (v, d) = (snap.vut_v_mps.max(0.0), zv.enter_s_m - snap.vut_s_m);
        if v * v / (2.0 * self.decel_mps2) > d {
            return false; // Committed: it can no longer stop before the zone.
        }
        let v_b = snap.bv_v_mps.max(0.0);
        let (t_in_b, t_out_b) = if v_b < STANDING_MPS {
            if snap.bv_s_m < zb.enter_s_m {
                return false; // A BV standing before its zone is not coming.
            }
            (0.0, f64::INFINITY)
        } else {
            ((zb.enter_s_m - snap.bv_s_m).max(0.0) / v_b, (zb.exit_s_m - snap.bv_s_m) / v_b)
        };
        let v_max = free_mps.max(v).max(1.0);
        let t_in_v = travel_time(d, v, scene.vut_accel_mps2, v_max);
        let t_out_v = travel_time(zv.exit_s_m - snap.vut_s_m, v, scene.vut_accel_mps2, v_max);
        !(t_in_b - t_out_v >= self.gap_s || t_in_v - t_out_b >= self.gap_s)
    }

    /// This driver's acceleration while it yields: the IDM toward a standing obstacle just
    /// before its zone, with free speed `free_mps`.
    fn yield_accel(&self, scene: &Scene, snap: &Snapshot, free_mps: f64) -> f64 {
        let stop = Obstacle { gap_m: scene.zone_vut.enter_s_m - STOP_MARGIN_M - snap.vut_s_m, speed_mps: 0.0 };
        idm(scene, self.decel_mps2).accel(snap.vut_v_mps, free_mps, Some(stop))
    }
}

/// The IDM of a driver of `scene` with comfortable deceleration `decel_mps2` (δ = 4).
fn idm(scene: &Scene, decel_mps2: f64) -> Idm {
    Idm {
        time_gap_s: IDM_TIME_GAP_S,
        min_gap_m: IDM_MIN_GAP_M,
        max_accel_mps2: scene.vut_accel_mps2,
        comfort_decel_mps2: decel_mps2,
        accel_exponent: 4.0,
    }
}

/// What the VUT's free speed is along its route: `speed_at(s)`, or the fallback where it says nothing.
pub trait FreeSpeed {
    /// The free speed at arc length `s_m`, m/s, if known there.
    fn free_speed_at(&self, s_m: f64) -> Option<f64>;
}

/// A free speed that is the same everywhere.
#[derive(Debug, Clone, Copy)]
pub struct Constant(pub f64);

impl FreeSpeed for Constant {
    fn free_speed_at(&self, _s_m: f64) -> Option<f64> {
        Some(self.0)
    }
}

impl FreeSpeed for crate::route_speed::RouteSpeed {
    fn free_speed_at(&self, s_m: f64) -> Option<f64> {
        self.speed_at(s_m)
    }
}

/// How a BV that must cover less than its speed allows slows down in [`BvMotion`], m/s².
pub const BV_SLOWING_MPS2: f64 = 2.0;

/// The BV's motion a candidate key time stands for, as the VUT will see it: from `s0`/`v0` to
/// `s1` at `t1`, then on at constant speed `v1`. To `s1` it goes at constant acceleration, or,
/// when that would have it stop and back up, it slows at [`BV_SLOWING_MPS2`] to the speed that
/// then gets it there on time (as a BV that holds back slows early), or stops on the way when
/// even that is too fast.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BvMotion {
    s0_m: f64,
    v0_mps: f64,
    t1_s: f64,
    s1_m: f64,
    v1_mps: f64,
    /// First phase: constant acceleration (`Some(a)`), or slowing to a cruise speed (`None`).
    accel: Option<f64>,
    /// Cruise speed after slowing, m/s.
    cruise_mps: f64,
    /// How it slows to it, m/s².
    slowing_mps2: f64,
}

impl BvMotion {
    /// From `s0`/`v0` to `s1` at `t1`, then on at `v1`.
    #[must_use]
    pub fn new(s0_m: f64, v0_mps: f64, t1_s: f64, s1_m: f64, v1_mps: f64) -> Self {
        let (v0, t1, s1) = (v0_mps.max(0.0), t1_s.max(1e-3), s1_m.max(s0_m));
        let d = s1 - s0_m;
        let mut m = Self {
            s0_m,
            v0_mps: v0,
            t1_s: t1,
            s1_m: s1,
            v1_mps: v1_mps.max(0.0),
            accel: None,
            cruise_mps: 0.0,
            slowing_mps2: BV_SLOWING_MPS2,
        };
        if 2.0 * d >= v0 * t1 {
            m.accel = Some(2.0 * (d - v0 * t1) / (t1 * t1));
            return m;
        }
        // (v0 − c)² / 2b + c t1 = d.
        let b = BV_SLOWING_MPS2;
        let disc = b * b * t1 * t1 - 2.0 * b * t1 * v0 + 2.0 * b * d;
        match (disc >= 0.0).then(|| v0 - b * t1 + disc.sqrt()).filter(|c| (0.0..=v0).contains(c)) {
            Some(c) => m.cruise_mps = c,
            None => m.slowing_mps2 = (v0 * v0 / (2.0 * d.max(1e-3))).max(b),
        }
        m
    }

    /// Arc length and speed at `t` s from now.
    #[must_use]
    pub fn at(&self, t: f64) -> (f64, f64) {
        let t = t.max(0.0);
        if t >= self.t1_s {
            return (self.s1_m + self.v1_mps * (t - self.t1_s), self.v1_mps);
        }
        if let Some(a) = self.accel {
            return (self.s0_m + self.v0_mps * t + 0.5 * a * t * t, self.v0_mps + a * t);
        }
        let (v0, b, c) = (self.v0_mps, self.slowing_mps2, self.cruise_mps);
        let t_dec = (v0 - c) / b;
        if t < t_dec {
            return ((self.s0_m + v0 * t - 0.5 * b * t * t).min(self.s1_m), v0 - b * t);
        }
        ((self.s0_m + (v0 * v0 - c * c) / (2.0 * b) + c * (t - t_dec)).min(self.s1_m), c)
    }
}

/// One driver of the model, stepped in time: what [`rollout`] simulates, and a VUT for tests.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Driver {
    reaction: Option<Reaction>,
    /// Since when a standing driver has seen the gap open, s.
    open_since: Option<f64>,
}

impl Driver {
    /// A driver that reacts as `reaction` says (`None`: not at all).
    #[must_use]
    pub fn new(reaction: Option<Reaction>) -> Self {
        Self { reaction, open_since: None }
    }

    /// Its acceleration at time `t` (steps of `dt`) at `snap`, with free speed `free_mps`: the
    /// IDM's free term, or its yielding, or standing until its restart delay has passed; within
    /// its acceleration limit, and never below the deceleration that stops it within the step.
    pub fn accel(&mut self, t: f64, dt: f64, scene: &Scene, snap: &Snapshot, free_mps: f64) -> f64 {
        let v = snap.vut_v_mps.max(0.0);
        // The IDM's free term (its comfortable deceleration plays no part in it).
        let free_a = idm(scene, 1.0).accel(v, free_mps, None);
        let a = match &self.reaction {
            Some(r) if r.yields(scene, snap, free_mps) => {
                self.open_since = None;
                r.yield_accel(scene, snap, free_mps)
            }
            Some(r) if v <= STANDING_MPS && r.restart_s > 0.0 => {
                let since = *self.open_since.get_or_insert(t);
                if t - since < r.restart_s { -v / dt } else { free_a }
            }
            _ => free_a,
        };
        a.max(-MAX_REACT_DECEL_MPS2.min(scene.vut_decel_mps2))
    }
}

/// When the VUT at `vut_s_m`/`vut_v_mps`, driving its free motion (`free`, else `fallback_mps`)
/// and reacting as `reaction` says (`None`: not at all) to the BV moving as `bv`, reaches
/// `station`, s from now; `None` if not within [`ROLLOUT_MAX_S`].
#[must_use]
pub fn rollout(
    reaction: Option<&Reaction>,
    scene: &Scene,
    bv: &BvMotion,
    (vut_s_m, vut_v_mps): (f64, f64),
    free: &dyn FreeSpeed,
    fallback_mps: f64,
    station: f64,
) -> Option<f64> {
    let dt = ROLLOUT_DT_S;
    let (mut s, mut v) = (vut_s_m, vut_v_mps.max(0.0));
    if s >= station {
        return Some(0.0);
    }
    let mut driver = Driver::new(reaction.copied());
    let steps = (ROLLOUT_MAX_S / dt) as usize;
    for k in 0..steps {
        let t = k as f64 * dt;
        let (bs, bvv) = bv.at(t);
        let snap = Snapshot { bv_s_m: bs, bv_v_mps: bvv, vut_s_m: s, vut_v_mps: v };
        let v0 = free.free_speed_at(s).unwrap_or(fallback_mps).max(0.0);
        let a = driver.accel(t, dt, scene, &snap, v0);
        let v_next = (v + a * dt).max(0.0);
        let s_next = s + 0.5 * (v + v_next) * dt;
        if s_next >= station {
            let frac = (station - s) / (s_next - s).max(1e-9);
            return Some(t + frac * dt);
        }
        (s, v) = (s_next, v_next);
    }
    None
}

/// The posterior over the grid of drivers ([`hypothesis`]), updated every decision.
#[derive(Debug, Clone, PartialEq)]
pub struct ReactionBelief {
    /// Log-weights, normalised so the largest is 0.
    log_w: [f64; HYPOTHESES],
    /// The prior the run started from (log, normalised).
    prior: [f64; HYPOTHESES],
    /// Each hypothesis as a driver (its restart clock).
    drivers: [Driver; HYPOTHESES],
    /// The last measurement: time and states.
    last: Option<(f64, Snapshot)>,
    /// The fastest the VUT was seen this run, m/s (its free speed where nothing else says).
    top_speed_mps: f64,
    /// Cycles that taught something (some hypotheses differed).
    informative: u32,
}

impl Default for ReactionBelief {
    fn default() -> Self {
        let prior = default_prior();
        Self { log_w: prior, prior, drivers: drivers(), last: None, top_speed_mps: 0.0, informative: 0 }
    }
}

fn drivers() -> [Driver; HYPOTHESES] {
    std::array::from_fn(|i| Driver::new(hypothesis(i)))
}

fn default_prior() -> [f64; HYPOTHESES] {
    let rest = (1.0 - DEFAULT_NONE_PRIOR) / (HYPOTHESES - 1) as f64;
    let mut p = [rest.ln(); HYPOTHESES];
    p[0] = DEFAULT_NONE_PRIOR.ln();
    normalised(p)
}

fn normalised(mut log_w: [f64; HYPOTHESES]) -> [f64; HYPOTHESES] {
    let top = log_w.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    if top.is_finite() {
        log_w.iter_mut().for_each(|w| *w -= top);
    }
    log_w
}

/// A posterior as probabilities, one per hypothesis (what the campaign memory keeps).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ReactionPosterior {
    /// Probability of each hypothesis, in [`hypothesis`] order (index 0: does not react).
    pub probabilities: Vec<f64>,
    /// Cycles that taught something, over every run it rests on.
    pub informative_cycles: u32,
}

/// A belief's state as plain numbers, copied out without allocating (the probabilities in
/// [`hypothesis`] order and the informative cycles): what a controller hands out every cycle.
pub type BeliefSnapshot = ([f64; HYPOTHESES], u32);

impl From<BeliefSnapshot> for ReactionPosterior {
    fn from((p, informative): BeliefSnapshot) -> Self {
        Self { probabilities: p.to_vec(), informative_cycles: informative }
    }
}

impl Validate for ReactionPosterior {
    fn validate(&self) -> Result<(), ValidationError> {
        if self.probabilities.len() != HYPOTHESES {
            return Err(ValidationError::new(
                "probabilities",
                format!("must hold {HYPOTHESES} values, got {}", self.probabilities.len()),
            ));
        }
        for (i, p) in self.probabilities.iter().enumerate() {
            in_range(&format!("probabilities[{i}]"), *p, 0.0, 1.0)?;
        }
        let sum: f64 = self.probabilities.iter().sum();
        if (sum - 1.0).abs() > 1e-3 {
            return Err(ValidationError::new("probabilities", format!("must sum to 1, got {sum}")));
        }
        Ok(())
    }
}

/// The most probable driver and how sure the belief is of it (what the run file and the report show).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Identified {
    /// The most probable driver; `None`: the one that does not react.
    pub reaction: Option<Reaction>,
    /// Its probability.
    pub probability: f64,
    /// Probability that the VUT reacts at all (every reacting hypothesis together).
    pub reacts_probability: f64,
    /// Expected accepted gap of the reacting hypotheses, s.
    pub gap_mean_s: f64,
    /// Its standard deviation, s.
    pub gap_sd_s: f64,
    /// Cycles that taught something.
    pub informative_cycles: u32,
}

impl ReactionBelief {
    /// Starts from `prior` (earlier runs' posterior; `None`: the default prior). A refused prior
    /// leaves the one before.
    pub fn set_prior(&mut self, prior: Option<&ReactionPosterior>) -> Result<(), ValidationError> {
        let p = match prior {
            Some(post) => {
                post.validate()?;
                let mut p = [0.0; HYPOTHESES];
                for (w, q) in p.iter_mut().zip(&post.probabilities) {
                    *w = q.max(MIN_PROBABILITY).ln();
                }
                self.informative = post.informative_cycles;
                normalised(p)
            }
            None => {
                self.informative = 0;
                default_prior()
            }
        };
        self.prior = p;
        self.reset();
        Ok(())
    }

    /// Back to the prior for a new run (what the run before taught stays only through
    /// [`Self::set_prior`]).
    pub fn reset(&mut self) {
        self.log_w = self.prior;
        self.drivers = drivers();
        self.last = None;
        self.top_speed_mps = 0.0;
    }

    /// The fastest the VUT was seen this run, m/s.
    #[must_use]
    pub fn top_speed_mps(&self) -> f64 {
        self.top_speed_mps
    }

    /// One measurement at absolute time `t_s`: each hypothesis predicted the VUT's acceleration
    /// since the last one; the measured acceleration weighs them. `free` is the VUT's free speed
    /// along its route where known.
    pub fn observe(&mut self, t_s: f64, snap: Snapshot, scene: &Scene, free: Option<&dyn FreeSpeed>) {
        let finite = [t_s, snap.bv_s_m, snap.bv_v_mps, snap.vut_s_m, snap.vut_v_mps].iter().all(|x| x.is_finite());
        if !finite {
            return;
        }
        self.top_speed_mps = self.top_speed_mps.max(snap.vut_v_mps);
        let Some((t0, prev)) = self.last.replace((t_s, snap)) else { return };
        let dt = t_s - t0;
        if !(dt > 1e-3 && dt <= MAX_CYCLE_S) {
            return;
        }
        let measured = (snap.vut_v_mps - prev.vut_v_mps) / dt;
        let v0 = free.and_then(|f| f.free_speed_at(prev.vut_s_m)).unwrap_or(self.top_speed_mps).max(0.0);
        let mut predicted = [0.0; HYPOTHESES];
        for (p, driver) in predicted.iter_mut().zip(self.drivers.iter_mut()) {
            *p = driver.accel(t0, dt, scene, &prev, v0);
        }
        // A standing VUT cannot decelerate: clip the predictions as the measurement is.
        let floor = -prev.vut_v_mps.max(0.0) / dt;
        let differ = predicted.iter().any(|p| (p.max(floor) - predicted[0].max(floor)).abs() > 1e-6);
        if !differ || !measured.is_finite() {
            return;
        }
        self.informative = self.informative.saturating_add(1);
        let var = ACCEL_NOISE_MPS2 * ACCEL_NOISE_MPS2;
        for (w, p) in self.log_w.iter_mut().zip(predicted) {
            let r = measured - p.max(floor);
            *w -= EVIDENCE_WEIGHT * r * r / (2.0 * var);
        }
        let floor_w = MIN_PROBABILITY.ln();
        self.log_w = normalised(self.log_w);
        // Keep every hypothesis above the floor relative to the best.
        self.log_w.iter_mut().for_each(|w| *w = w.max(floor_w));
    }

    /// Probabilities, in [`hypothesis`] order.
    #[must_use]
    pub fn probabilities(&self) -> [f64; HYPOTHESES] {
        let mut p = [0.0; HYPOTHESES];
        let mut sum = 0.0;
        for (q, w) in p.iter_mut().zip(&self.log_w) {
            *q = w.exp();
            sum += *q;
        }
        p.iter_mut().for_each(|q| *q /= sum);
        p
    }

    /// The posterior as plain numbers (no allocation).
    #[must_use]
    pub fn snapshot(&self) -> BeliefSnapshot {
        (self.probabilities(), self.informative)
    }

    /// The posterior, to carry to the next run.
    #[must_use]
    pub fn posterior(&self) -> ReactionPosterior {
        ReactionPosterior { probabilities: self.probabilities().to_vec(), informative_cycles: self.informative }
    }

    /// The most probable driver and the summary of the belief.
    #[must_use]
    pub fn identified(&self) -> Identified {
        summarise(&self.probabilities(), self.informative)
    }
}

/// Index of `driver` in the grid ([`hypothesis`]; `None`, the driver that does not react, is 0);
/// `None` when it is not on the grid.
#[must_use]
pub fn hypothesis_index(driver: Option<Reaction>) -> Option<usize> {
    match driver {
        None => Some(0),
        Some(r) => (1..HYPOTHESES).find(|&i| hypothesis(i) == Some(r)),
    }
}

impl ReactionPosterior {
    /// A posterior that puts `p` on `driver` (`None`: the one that does not react) and the rest
    /// evenly on the other hypotheses, resting on `informative_cycles`: what an operator who
    /// knows the VUT gives as a prior, and the fixtures of tests and benches. `None` when the
    /// driver is not on the grid or `p` is not in [0, 1].
    #[must_use]
    pub fn sure_of(driver: Option<Reaction>, p: f64, informative_cycles: u32) -> Option<Self> {
        let i = hypothesis_index(driver)?;
        if !(0.0..=1.0).contains(&p) {
            return None;
        }
        let mut probabilities = vec![(1.0 - p) / (HYPOTHESES - 1) as f64; HYPOTHESES];
        *probabilities.get_mut(i)? = p;
        Some(Self { probabilities, informative_cycles })
    }

    /// The most probable driver and the summary of the posterior (`None` when it does not
    /// validate).
    #[must_use]
    pub fn identified(&self) -> Option<Identified> {
        self.validate().ok()?;
        let mut p = [0.0; HYPOTHESES];
        p.copy_from_slice(&self.probabilities);
        Some(summarise(&p, self.informative_cycles))
    }
}

impl std::fmt::Display for Identified {
    /// One line for an operator: whether the VUT reacts, the gap it accepts, the most probable driver.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "reacts to the BV with p {:.2} (accepted gap {:.1} ± {:.1} s); most probable: ",
            self.reacts_probability, self.gap_mean_s, self.gap_sd_s
        )?;
        match self.reaction {
            Some(r) => write!(
                f,
                "gap {:.1} s, deceleration {:.1} m/s², restart {:.1} s (p {:.2})",
                r.gap_s, r.decel_mps2, r.restart_s, self.probability
            ),
            None => write!(f, "does not react (p {:.2})", self.probability),
        }?;
        write!(f, "; {} informative cycles", self.informative_cycles)
    }
}

/// The summary of probabilities `p` in [`hypothesis`] order.
fn summarise(p: &[f64; HYPOTHESES], informative: u32) -> Identified {
    {
        let (best, top) =
            p.iter().enumerate().fold((0, f64::NEG_INFINITY), |b, (i, &q)| if q > b.1 { (i, q) } else { b });
        let reacts: f64 = p[1..].iter().sum();
        let (mut mean, mut sq) = (0.0, 0.0);
        for (i, q) in p.iter().enumerate().skip(1) {
            let g = hypothesis(i).map_or(0.0, |r| r.gap_s);
            mean += q * g;
            sq += q * g * g;
        }
        let (mean, sq) = if reacts > 0.0 { (mean / reacts, sq / reacts) } else { (0.0, 0.0) };
        Identified {
            reaction: hypothesis(best),
            probability: top,
            reacts_probability: reacts,
            gap_mean_s: mean,
            gap_sd_s: (sq - mean * mean).max(0.0).sqrt(),
            informative_cycles: informative,
        }
    }
}

#[cfg(test)]
mod tests;
