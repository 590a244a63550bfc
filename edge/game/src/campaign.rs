//! Steering over a test campaign: what a BV learns about one VUT from one run of a test to the
//! next.
//!
//! A proving-ground test is repeated many times against the same ADS. Within one run the
//! regulator cannot tell how this VUT reacts to being pressed (it predicts the VUT's best response
//! from a model that does not react); after a run it has seen the outcome. The memory here keeps,
//! per test (scenario, BV, style, τ), every run's *aim* (the τ the regulator was given) and the PET
//! it measured, and from them:
//!
//! - **a model of this VUT's reaction** — the PET a run measures as a line in the aim,
//!   `PET ≈ offset + gain · aim`, fitted by least squares to the last [`FIT_WINDOW`] valid runs (a
//!   valid run measured a PET in the asked order without a collision). Until those runs' aims spread
//!   over [`SLOPE_SPREAD`]·τ the gain is 1 (the VUT adds a constant to what the regulator predicts);
//!   a fitted gain is kept within [[`GAIN_MIN`], [`GAIN_MAX`]];
//! - **the aim of the next run** — the aim at which the model gives τ, `(τ − offset) / gain`, but
//!   only once the model's miss at τ (`offset + (gain − 1)·τ`) exceeds [`DEADBAND_SHARE`]·τ: a
//!   smaller one is within a run's noise, and chasing it only adds the noise of the runs it was
//!   learnt from. Run 1 is uncalibrated: it aims at τ. The aim stays within
//!   [[`AIM_MIN_SHARE`]·τ, [`AIM_MAX_SHARE`]·τ] and the range of [`Target`];
//! - **whether the learned model is kept** — each valid run from the second on tests two
//!   predictions of its PET made before it ran: the learned one (`offset + gain · aim`) and the
//!   default one (`aim`: the VUT does what the regulator's model says). Their absolute errors are
//!   summed; once at least [`DROP_AFTER`] runs have been compared and the learned sum exceeds the
//!   default's by more than [`DROP_MARGIN`] of it, the learned model is dropped for good for this
//!   test (`dropped`) and every later run aims at τ;
//! - **whether τ is out of this VUT's reach** — when the two last valid runs both missed τ by more
//!   than [`MISS_TOL`] on the same side although the aim had moved at least [`REACH_AIM_SHIFT`]·τ
//!   against that miss since the first run, and the PET followed by less than [`REACH_FOLLOW`] of the
//!   aim's move in the aim's direction (or moved the other way: a VUT that gives way the more, the
//!   harder it is pressed), the VUT sets the PET, not the BV: the memory reports [`BelowReach`] with
//!   the bound (the mean of those two PETs), and the next runs aim where the PET closest to τ came
//!   from instead of winding the aim further. The report stands while the runs keep missing on that
//!   side (its bound follows the last two) and ends with the first run within the tolerance. The
//!   same report, without holding the aim, comes when the last [`REACH_MISS_RUNS`] valid runs all
//!   missed τ by more than [`MISS_TOL`], on either side (a VUT that either lets the BV through or
//!   gives way, never in between); its bound is the PET of those runs closest to τ.
//!   Two runs in a row without a PET in the asked order (a VUT that never goes first when asked to)
//!   report the order as refused.
//!
//! **Safety.** Learning only moves the aim. The regulator's safety margin, the hold-back rule, the
//! vehicle limits and the actuation gate are not part of the memory and do not change with it; an
//! aim is a [`Target`] like any other (a run that aims lower presses harder, within the same
//! constraints). Nothing learned about one VUT is used against another: a memory names its VUT,
//! and [`CampaignMemory::check_vut`] refuses another's.
//!
//! Pure: no IO. The memory is a small serde document; the lab and the command line keep one file
//! per VUT.

use serde::{Deserialize, Serialize};
use v2t_model::validate::{Validate, ValidationError, in_range};
use v2t_model::{Style, Target};

use crate::reaction::ReactionPosterior;
use crate::regulator::{BelowReach, BelowReachCause};
use crate::route_speed::RouteSpeed;

/// Valid runs the reaction model is fitted to (the most recent).
pub const FIT_WINDOW: usize = 4;
/// The aims of the fitted runs must spread over this share of τ before a gain other than 1 is fitted.
pub const SLOPE_SPREAD: f64 = 0.2;
/// A model miss at τ below this share of τ is left alone (run-to-run noise).
pub const DEADBAND_SHARE: f64 = 0.04;
/// The smallest fitted gain (a VUT that ignores the aim still gets a finite correction).
pub const GAIN_MIN: f64 = 0.25;
/// The largest fitted gain.
pub const GAIN_MAX: f64 = 1.5;
/// The lowest aim, as a share of τ.
pub const AIM_MIN_SHARE: f64 = 0.5;
/// The highest aim, as a share of τ.
pub const AIM_MAX_SHARE: f64 = 1.5;
/// Valid runs compared before the learned model may be dropped.
pub const DROP_AFTER: u32 = 6;
/// The learned model is dropped when its summed error exceeds the default's by this share: two
/// predictions within one run's noise of each other are not told apart by a few runs, and a small
/// real bias would otherwise be dropped as often as kept.
pub const DROP_MARGIN: f64 = 0.25;
/// A run misses τ when its PET lies farther than this share of τ from it.
pub const MISS_TOL: f64 = 0.10;
/// How far (share of τ) the aim must have moved against the misses before they count as the VUT's.
pub const REACH_AIM_SHIFT: f64 = 0.25;
/// A PET that moved by less than this share of the aim's move did not follow the aim.
pub const REACH_FOLLOW: f64 = 0.5;
/// Valid runs in a row that all missed τ by more than [`MISS_TOL`] show it out of reach, whatever
/// the aims were.
pub const REACH_MISS_RUNS: usize = 4;
/// Runs a memory keeps per test (the oldest are forgotten first; the model uses the last few).
pub const MAX_RUNS: usize = 1000;
/// Tests a memory holds.
pub const MAX_CASES: usize = 10_000;
/// The version of the file layout.
pub const FORMAT: u32 = 1;

/// One run of a test, as the memory keeps it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RunRecord {
    /// The τ the regulator was given, s.
    pub aim_s: f64,
    /// The PET measured, s (`None`: no PET).
    pub pet_s: Option<f64>,
    /// Whether the vehicles passed in the asked order.
    pub order_ok: bool,
    /// Whether the run ended in a collision.
    pub collision: bool,
    /// Whether the regulator's follower knew how the VUT drives its route in this run (a
    /// learned [`RouteSpeed`]). The reaction model is fitted to runs made the same way as the next
    /// one: what a follower without it got wrong, one with it has already corrected.
    #[serde(default)]
    pub learned_route: bool,
    /// Whether the regulator started this run from how earlier runs identified the VUT's
    /// reaction (a [`ReactionPosterior`] prior). Like `learned_route`, the reaction model is
    /// fitted to runs made the same way as the next one.
    #[serde(default)]
    pub reaction_prior: bool,
}

impl RunRecord {
    /// A PET in the asked order without a collision.
    pub fn valid_pet(&self) -> Option<f64> {
        self.pet_s.filter(|p| p.is_finite() && self.order_ok && !self.collision)
    }
}

/// What the memory knows about one test against its VUT.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CaseMemory {
    /// Every run, oldest first (at most [`MAX_RUNS`]).
    pub runs: Vec<RunRecord>,
    /// The reaction model's offset, s (0 until a valid run, and once dropped).
    pub offset_s: f64,
    /// The reaction model's gain (1 until fitted, and once dropped).
    pub gain: f64,
    /// The learned model predicted worse than the default and is not used any more.
    pub dropped: bool,
    /// Sum of the learned prediction's absolute errors, s.
    pub learned_error_s: f64,
    /// Sum of the default prediction's absolute errors over the same runs, s.
    pub default_error_s: f64,
    /// Runs on which the two predictions were compared.
    pub compared: u32,
    /// τ is out of this VUT's reach, as far as the runs show.
    pub below_reach: Option<BelowReach>,
    /// The aim holds where the PET came closest to τ (the PET did not follow the aim).
    #[serde(default)]
    pub holding: bool,
    /// How the VUT drove its route in the last valid runs (the follower's free motion in the
    /// next run, [`crate::route_speed`]); `None` until a valid run was recorded with it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub route_speed: Option<RouteSpeed>,
    /// How the VUT was identified to react to the BV by the end of the last run (the next run's
    /// prior, [`crate::reaction`]); `None` until a run identified anything.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reaction: Option<ReactionPosterior>,
}

impl Default for CaseMemory {
    fn default() -> Self {
        Self {
            runs: Vec::new(),
            offset_s: 0.0,
            gain: 1.0,
            dropped: false,
            learned_error_s: 0.0,
            default_error_s: 0.0,
            compared: 0,
            below_reach: None,
            holding: false,
            route_speed: None,
            reaction: None,
        }
    }
}

impl CaseMemory {
    /// The PET the learned model predicts for a run that aims at `aim_s`, s.
    pub fn predicted_pet_s(&self, aim_s: f64) -> f64 {
        self.offset_s + self.gain * aim_s
    }

    /// The τ to give the regulator in the next run of a test whose target is `target`.
    pub fn aim(&self, target: Target) -> Target {
        let tau = target.tau_s();
        let aim = if self.dropped {
            tau
        } else if self.holding {
            // The VUT sets the PET: aim where the PET closest to τ came from.
            self.valid().min_by(|a, b| (a.1 - tau).abs().total_cmp(&(b.1 - tau).abs())).map_or(tau, |(aim, _)| aim)
        } else if (self.predicted_pet_s(tau) - tau).abs() <= DEADBAND_SHARE * tau {
            tau
        } else {
            (tau - self.offset_s) / self.gain
        };
        let lo = (AIM_MIN_SHARE * tau).max(Target::TAU_MIN_S);
        let hi = (AIM_MAX_SHARE * tau).min(Target::TAU_MAX_S);
        let aim = if aim.is_finite() { aim.clamp(lo, hi) } else { tau };
        Target::new(aim, target.style()).unwrap_or(target)
    }

    /// The valid runs `(aim, PET)` made as the next run will be: with a learned route speed when
    /// one is known, without one otherwise.
    fn valid(&self) -> impl DoubleEndedIterator<Item = (f64, f64)> + '_ {
        let (learned, prior) = (self.route_speed.is_some(), self.reaction.is_some());
        self.runs
            .iter()
            .filter(move |r| r.learned_route == learned && r.reaction_prior == prior)
            .filter_map(|r| r.valid_pet().map(|p| (r.aim_s, p)))
    }

    /// Records a run of the test whose target is `target`, and updates what is learned.
    pub fn record(&mut self, target: Target, run: RunRecord) {
        let tau = target.tau_s();
        if let Some(pet) = run.valid_pet()
            && !self.dropped
            && self.valid().next().is_some()
        {
            self.learned_error_s += (pet - self.predicted_pet_s(run.aim_s)).abs();
            self.default_error_s += (pet - run.aim_s).abs();
            self.compared += 1;
            if self.compared >= DROP_AFTER && self.learned_error_s > (1.0 + DROP_MARGIN) * self.default_error_s {
                self.dropped = true;
            }
        }
        if self.runs.len() >= MAX_RUNS {
            self.runs.remove(0);
        }
        self.runs.push(run);
        self.update(tau);
    }

    /// The reaction model and the reach verdict after the runs so far.
    fn update(&mut self, tau: f64) {
        (self.offset_s, self.gain) = if self.dropped { (0.0, 1.0) } else { self.fit(tau) };
        (self.below_reach, self.holding) = self.reach_verdict(tau);
    }

    /// Learns how the VUT drove its route in a run just [`Self::record`]ed: kept only when that
    /// run measured a PET in the asked order without a collision (a run that went wrong says
    /// little about how this VUT drives), merged with what earlier runs showed
    /// ([`RouteSpeed::merge`]).
    /// The first learned route starts the reaction model over: the runs made without one no
    /// longer describe how the next run's follower errs.
    pub fn learn_route(&mut self, target: Target, route: &RouteSpeed) {
        if self.runs.last().and_then(RunRecord::valid_pet).is_some() {
            self.learn_free_drive(target, route);
        }
    }

    /// Learns how the VUT drove its route in a *free drive* (the test driven with every BV
    /// parked: no PET, no run to record), merged with what is known as [`Self::learn_route`]
    /// merges. A record that does not validate is not kept.
    pub fn learn_free_drive(&mut self, target: Target, route: &RouteSpeed) {
        if route.validate().is_err() {
            return;
        }
        match &mut self.route_speed {
            Some(known) if known.step_m == route.step_m => known.merge(route),
            _ => {
                self.route_speed = Some(RouteSpeed { runs: 1, ..route.clone() });
                self.update(target.tau_s());
            }
        }
    }

    /// Keeps how a run just [`Self::record`]ed identified the VUT's reaction (it started from the
    /// posterior kept before, so it carries every earlier run): the next run's prior. A run that
    /// taught nothing new changes nothing; a posterior that does not validate is not kept. The
    /// first one starts the reaction model `(offset, gain)` over, as a first learned route does.
    pub fn learn_reaction(&mut self, target: Target, posterior: &ReactionPosterior) {
        if posterior.validate().is_err() || posterior.informative_cycles == 0 {
            return;
        }
        let first = self.reaction.is_none();
        self.reaction = Some(posterior.clone());
        if first {
            self.update(target.tau_s());
        }
    }

    /// The reaction model `(offset, gain)` fitted to the recent valid runs.
    fn fit(&self, tau: f64) -> (f64, f64) {
        let recent: Vec<(f64, f64)> = self.valid().rev().take(FIT_WINDOW).collect();
        let n = recent.len() as f64;
        if recent.is_empty() {
            return (0.0, 1.0);
        }
        let (ma, mp) = (recent.iter().map(|r| r.0).sum::<f64>() / n, recent.iter().map(|r| r.1).sum::<f64>() / n);
        let (lo, hi) = recent.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), r| (l.min(r.0), h.max(r.0)));
        let gain = if hi - lo >= SLOPE_SPREAD * tau {
            let sxy: f64 = recent.iter().map(|(a, p)| (a - ma) * (p - mp)).sum();
            let sxx: f64 = recent.iter().map(|(a, _)| (a - ma) * (a - ma)).sum();
            (sxy / sxx).clamp(GAIN_MIN, GAIN_MAX)
        } else {
            1.0
        };
        let offset = mp - gain * ma;
        if offset.is_finite() && gain.is_finite() { (offset, gain) } else { (0.0, 1.0) }
    }

    /// The verdict on reach after the runs so far (see the module's documentation), and whether
    /// the aim holds where the PET came closest (only when the PET did not follow the aim; a
    /// verdict of misses alone leaves the aim to the model).
    fn reach_verdict(&self, tau: f64) -> (Option<BelowReach>, bool) {
        let refused = self.runs.len() >= 2
            && self.runs.iter().rev().take(2).all(|r| !r.collision && (r.pet_s.is_none() || !r.order_ok));
        if refused {
            return (Some(BelowReach { cause: BelowReachCause::OrderRefused, pet_bound_s: None }), false);
        }
        let valid: Vec<(f64, f64)> = self.valid().collect();
        let [.., (_, p_prev), (_, p_last)] = valid[..] else { return (None, false) };
        let miss = side(p_last, tau);
        let floor = Some(BelowReach { cause: BelowReachCause::Campaign, pet_bound_s: Some(0.5 * (p_prev + p_last)) });
        // Once the PET has shown that it does not follow the aim, that stands while the runs keep
        // missing on the same side (the aim no longer moves against the misses, so the test below
        // cannot be repeated).
        if self.holding
            && miss != 0.0
            && self.below_reach.and_then(|b| b.pet_bound_s).is_some_and(|b| side(b, tau) == miss)
        {
            return (floor, true);
        }
        if aim_moved_in_vain(&valid, tau) {
            return (floor, true);
        }
        // However the aim moved, none of the last runs landed on τ.
        let recent: Vec<f64> = valid.iter().rev().take(REACH_MISS_RUNS).map(|&(_, p)| p).collect();
        if recent.len() == REACH_MISS_RUNS && recent.iter().all(|&p| side(p, tau) != 0.0) {
            let nearest = recent.iter().copied().min_by(|a, b| (a - tau).abs().total_cmp(&(b - tau).abs()));
            return (Some(BelowReach { cause: BelowReachCause::Campaign, pet_bound_s: nearest }), self.holding);
        }
        (None, false)
    }
}

/// Which side of τ a PET misses on: 1 above, −1 below, 0 within [`MISS_TOL`].
fn side(pet: f64, tau: f64) -> f64 {
    if pet > tau * (1.0 + MISS_TOL) {
        1.0
    } else if pet < tau * (1.0 - MISS_TOL) {
        -1.0
    } else {
        0.0
    }
}

/// The first reach rule over the valid runs `(aim, PET)`, oldest first: the two last missed on one
/// side, the aim moved against that side since the first by at least [`REACH_AIM_SHIFT`]·τ, and the
/// PET did not follow by [`REACH_FOLLOW`] of that move in its direction.
fn aim_moved_in_vain(valid: &[(f64, f64)], tau: f64) -> bool {
    let (Some(&(a_first, p_first)), [.., (_, p_prev), (a_last, p_last)]) = (valid.first(), valid) else {
        return false;
    };
    let (miss, aim_move) = (side(*p_last, tau), a_last - a_first);
    miss != 0.0
        && side(*p_prev, tau) == miss
        && -aim_move * miss >= REACH_AIM_SHIFT * tau
        && (p_last - p_first) * aim_move.signum() < REACH_FOLLOW * aim_move.abs()
}

/// Which test a [`CaseMemory`] belongs to. Its file is `CaseEntryFile`'s layout: the target as the
/// two keys `style` and `tau_s`, range-checked as the file is read.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "CaseEntryFile", into = "CaseEntryFile")]
pub struct CaseEntry {
    /// Scenario name.
    pub scenario: String,
    /// Which BV of the scenario (index).
    pub bv: usize,
    /// Who passes first and the test's target τ.
    pub target: Target,
    /// What was learned.
    pub memory: CaseMemory,
}

/// The file form of a [`CaseEntry`]: its fields in the same order, the target written as `style`
/// and `tau_s` (s).
#[derive(Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct CaseEntryFile {
    scenario: String,
    bv: usize,
    style: Style,
    tau_s: f64,
    memory: CaseMemory,
}

impl TryFrom<CaseEntryFile> for CaseEntry {
    type Error = ValidationError;

    fn try_from(f: CaseEntryFile) -> Result<Self, Self::Error> {
        Ok(Self { scenario: f.scenario, bv: f.bv, target: Target::from_keys(f.tau_s, f.style)?, memory: f.memory })
    }
}

impl From<CaseEntry> for CaseEntryFile {
    fn from(c: CaseEntry) -> Self {
        Self { scenario: c.scenario, bv: c.bv, style: c.target.style(), tau_s: c.target.tau_s(), memory: c.memory }
    }
}

impl CaseEntry {
    fn is(&self, scenario: &str, bv: usize, target: Target) -> bool {
        self.scenario == scenario && self.bv == bv && self.target == target
    }
}

/// Everything one campaign learned about one VUT: the file the next run loads. It is read through
/// `CampaignMemoryFile`, so that a case whose target is out of range is refused naming it
/// (`cases[3].tau_s`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "CampaignMemoryFile")]
pub struct CampaignMemory {
    /// Layout version ([`FORMAT`]).
    pub format: u32,
    /// The VUT it was learned from (a driver name, or the ADS under test as the operator names it).
    pub vut: String,
    /// Where the runs took place (`builtin`, `sumo`, a proving ground's name).
    pub world: String,
    /// One entry per test.
    pub cases: Vec<CaseEntry>,
}

/// A [`CampaignMemory`] as read, its cases not yet checked (it is written as the memory itself).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct CampaignMemoryFile {
    format: u32,
    vut: String,
    world: String,
    cases: Vec<CaseEntryFile>,
}

impl TryFrom<CampaignMemoryFile> for CampaignMemory {
    type Error = ValidationError;

    fn try_from(f: CampaignMemoryFile) -> Result<Self, Self::Error> {
        let cases = f
            .cases
            .into_iter()
            .enumerate()
            .map(|(i, c)| CaseEntry::try_from(c).map_err(|e| e.within(&format!("cases[{i}]"))))
            .collect::<Result<_, _>>()?;
        Ok(Self { format: f.format, vut: f.vut, world: f.world, cases })
    }
}

/// A memory used against a VUT it was not learned from.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error(
    "the campaign memory was learned from VUT `{learned}` in world `{learned_world}`, not from `{asked}` in \
     `{asked_world}`: keep one file per VUT"
)]
pub struct WrongVut {
    /// The memory's VUT.
    pub learned: String,
    /// Its world.
    pub learned_world: String,
    /// The VUT of the run.
    pub asked: String,
    /// The run's world.
    pub asked_world: String,
}

impl CampaignMemory {
    /// An empty memory for `vut` in `world`.
    pub fn new(vut: impl Into<String>, world: impl Into<String>) -> Self {
        Self { format: FORMAT, vut: vut.into(), world: world.into(), cases: Vec::new() }
    }

    /// Refuses a memory learned from another VUT or in another world.
    pub fn check_vut(&self, vut: &str, world: &str) -> Result<(), WrongVut> {
        if self.vut == vut && self.world == world {
            Ok(())
        } else {
            Err(WrongVut {
                learned: self.vut.clone(),
                learned_world: self.world.clone(),
                asked: vut.to_owned(),
                asked_world: world.to_owned(),
            })
        }
    }

    /// What is known about a test (`None`: never run).
    pub fn case(&self, scenario: &str, bv: usize, target: Target) -> Option<&CaseMemory> {
        self.cases.iter().find(|c| c.is(scenario, bv, target)).map(|c| &c.memory)
    }

    /// The memory of a test, made empty when it was never run.
    pub fn case_mut(&mut self, scenario: &str, bv: usize, target: Target) -> &mut CaseMemory {
        let i = match self.cases.iter().position(|c| c.is(scenario, bv, target)) {
            Some(i) => i,
            None => {
                self.cases.push(CaseEntry { scenario: scenario.to_owned(), bv, target, memory: CaseMemory::default() });
                self.cases.len() - 1
            }
        };
        #[allow(clippy::indexing_slicing)] // `i` is a position found in, or the index just pushed onto, `cases`
        &mut self.cases[i].memory
    }

    /// The aim of the next run of a test (its target when never run).
    pub fn aim(&self, scenario: &str, bv: usize, target: Target) -> Target {
        self.case(scenario, bv, target).map_or(target, |c| c.aim(target))
    }
}

impl Validate for RunRecord {
    fn validate(&self) -> Result<(), ValidationError> {
        in_range("aim_s", self.aim_s, Target::TAU_MIN_S, Target::TAU_MAX_S)?;
        match self.pet_s {
            Some(p) => in_range("pet_s", p, 0.0, 3600.0),
            None => Ok(()),
        }
    }
}

impl Validate for CaseEntry {
    fn validate(&self) -> Result<(), ValidationError> {
        if self.bv > 64 {
            return Err(ValidationError::new("bv", format!("must lie in [0, 64], got {}", self.bv)));
        }
        let m = &self.memory;
        if m.runs.len() > MAX_RUNS {
            return Err(ValidationError::new("memory.runs", format!("at most {MAX_RUNS} runs, got {}", m.runs.len())));
        }
        for (i, r) in m.runs.iter().enumerate() {
            r.validate().map_err(|e| e.within(&format!("memory.runs[{i}]")))?;
        }
        in_range("memory.offset_s", m.offset_s, -3600.0, 3600.0)?;
        in_range("memory.gain", m.gain, GAIN_MIN, GAIN_MAX)?;
        in_range("memory.learned_error_s", m.learned_error_s, 0.0, 1e9)?;
        in_range("memory.default_error_s", m.default_error_s, 0.0, 1e9)?;
        if let Some(b) = m.below_reach.and_then(|b| b.pet_bound_s) {
            in_range("memory.below_reach.pet_bound_s", b, 0.0, 3600.0)?;
        }
        if let Some(r) = &m.route_speed {
            r.validate().map_err(|e| e.within("memory.route_speed"))?;
        }
        if let Some(r) = &m.reaction {
            r.validate().map_err(|e| e.within("memory.reaction"))?;
        }
        Ok(())
    }
}

impl Validate for CampaignMemory {
    fn validate(&self) -> Result<(), ValidationError> {
        if self.format != FORMAT {
            return Err(ValidationError::new(
                "format",
                format!("this build reads format {FORMAT}, got {}", self.format),
            ));
        }
        for (field, s) in [("vut", &self.vut), ("world", &self.world)] {
            if s.is_empty() || s.len() > 128 || s.chars().any(char::is_control) {
                return Err(ValidationError::new(field, "must be 1 to 128 printable characters"));
            }
        }
        if self.cases.len() > MAX_CASES {
            return Err(ValidationError::new("cases", format!("at most {MAX_CASES} tests, got {}", self.cases.len())));
        }
        for (i, c) in self.cases.iter().enumerate() {
            c.validate().map_err(|e| e.within(&format!("cases[{i}]")))?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests;
