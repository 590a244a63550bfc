//! Which PETs can any BV reach against a VUT? A grid of open-loop BV speed profiles — acceleration
//! `a1` for `t1` seconds, then `a2` until the BV has left its conflict zone, then its reference
//! speed — each run once against the VUT, with the scenario's sensor noise and delays. Runs where
//! the BV passed first without collision or zone overlap give the PETs a rushing BV can reach; runs
//! where the VUT passed first give those of a yielding one — at a crossing with a stop line, only
//! when the BV gave way as the regulator's BV must ([`YieldRule`]): behind its stop line until the
//! VUT was in its zone, and [`HOLD_CLEARANCE_M`] before its zone until the VUT had left it. A
//! profile that creeps into the junction while the VUT turns reaches yield PETs that no BV we put
//! on a track may aim at (a near miss, and a yield an ADS that judges gaps cannot read); the grid
//! counts those runs apart ([`Reach::unreadable_yields`]), and runs every profile once more
//! keeping the rule (its BV waits at its line until the VUT is in its zone, then drives its
//! profile on), so that what a BV that gives way properly can reach is measured, not assumed.
//!
//! It bounds what any regulator can achieve against that VUT: where no profile lands within ±10 %
//! of a target τ, a miss there is the VUT's rule, not the regulator's. It is an oracle for scoring
//! only; no regulator reads it. The same grid runs in every world (the builtin VUT models, SUMO's
//! drivers), through [`crate::vut::Vut::run`].

use serde::Serialize;
use v2t_game::qp::CAP_DECEL_SHARE;
use v2t_game::regulator::{HOLD_CLEARANCE_M, HOLD_CREEP_M, hold_station, stop_line_station};
use v2t_model::driving::{CurvePreview, curve_speed_ahead};
use v2t_model::metrics::ConflictKind;
use v2t_model::{Style, Target};
use v2t_sim::bv::BvController;
use v2t_sim::control::pure_pursuit;
use v2t_sim::observation::BvObservation;
use v2t_sim::plant::ActuationRequest;
use v2t_sim::runner::{FirstThrough, RunOutcome};
use v2t_sim::scenario::Scenario;

use crate::vut::Vut;

/// A BV keeping the yield rule that is this near its station and this slow stands until it may
/// go, m and m/s.
const KEEP_STAND_M: f64 = 3.0;
const KEEP_STAND_MPS: f64 = 0.5;

/// One open-loop speed profile of the grid.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Profile {
    /// First acceleration, m/s².
    pub a1_mps2: f64,
    /// How long the first acceleration lasts, s.
    pub t1_s: f64,
    /// Acceleration from `t1_s` until the BV has left its zone, m/s².
    pub a2_mps2: f64,
}

/// The grid: `a1`, `a2` ∈ {−3, −1.5, 0, 1.5, 3} m/s², `t1` ∈ {0, 1, …, 6, 8, 10, 12} s (250
/// profiles; the long `t1` let a BV that brakes to a stand wait long enough to pass second); each
/// acceleration is clipped to the BV's limits by its plant.
pub fn grid() -> Vec<Profile> {
    const ACCELS: [f64; 5] = [-3.0, -1.5, 0.0, 1.5, 3.0];
    const T1_S: [f64; 10] = [0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 8.0, 10.0, 12.0];
    let mut out = Vec::with_capacity(ACCELS.len() * ACCELS.len() * T1_S.len());
    for a1_mps2 in ACCELS {
        for t1_s in T1_S {
            for a2_mps2 in ACCELS {
                out.push(Profile { a1_mps2, t1_s, a2_mps2 });
            }
        }
    }
    out
}

/// A BV that drives one [`Profile`] and follows its route laterally, within its limits: never
/// faster than its path's curves allow at its lateral-acceleration limit (the curve speed ahead,
/// [`curve_speed_ahead`], braking for it at [`CAP_DECEL_SHARE`] of its largest deceleration, from
/// where its actuator's lag takes it, less the speed it may still gain meanwhile). Its plant
/// follows any speed on any curve (a kinematic bicycle does not skid): without this cap the grid
/// counted PETs that only a BV turning at half again its lateral limit reached (the BV-turning
/// left turn's rush at τ 1.5 s against SUMO's IDM, at 6.6 m/s² where 4.5 are allowed). With
/// `keep`, it gives way as [`YieldRule`] asks whatever its profile says: it never drives faster
/// than it can stop at (at [`CAP_DECEL_SHARE`] of its largest deceleration) before its hold
/// station until the VUT is in its zone, nor before the clearance station until the VUT has left
/// it; then its profile goes on.
#[derive(Debug, Clone, Copy)]
pub struct OpenLoop {
    /// The profile.
    pub profile: Profile,
    /// Give way as the rule asks.
    pub keep: Option<YieldRule>,
}

impl BvController for OpenLoop {
    fn name(&self) -> &str {
        "open-loop"
    }

    fn control(&mut self, obs: &BvObservation<'_>) -> ActuationRequest {
        let sc = obs.scenario;
        let Some(bv) = sc.bvs.get(obs.bv_index) else { return ActuationRequest::default() };
        let conflict = sc.conflict_of(obs.bv_index);
        let exit_s_m = conflict.map_or(f64::INFINITY, |c| c.zone.bv.exit_s_m);
        let v = obs.own.state.speed_mps;
        let lim = &bv.agent.vehicle.limits;
        let mut wanted = if obs.own.s_m >= exit_s_m {
            0.5 * (bv.reference.speed_at(obs.t_s) - v)
        } else if obs.t_s < self.profile.t1_s {
            self.profile.a1_mps2
        } else {
            self.profile.a2_mps2
        };
        // The distance it covers before a request takes effect (its actuator's delay and lag, and
        // one control period): over that time it may still be speeding up at its largest
        // acceleration.
        let act = &bv.agent.vehicle.actuator;
        let lag_s = act.delay_s + act.accel_time_constant_s + obs.dt_s;
        let lag_m = v * lag_s + 0.5 * lim.max_accel_mps2 * lag_s * lag_s;
        // Within its lateral limit: no faster than the curves ahead allow from where the lag
        // takes it, less the speed it may still gain in that time.
        let curve = curve_speed_ahead(
            &bv.agent.route,
            obs.own.s_m + lag_m,
            v,
            lim.max_lat_accel_mps2,
            CAP_DECEL_SHARE * lim.max_decel_mps2,
            &CurvePreview::DRIVER,
        );
        if curve.is_finite() {
            wanted = wanted.min(((curve - lim.max_accel_mps2 * lag_s).max(0.0) - v) / obs.dt_s);
        }
        if let (Some(rule), Some(c)) = (self.keep, conflict) {
            let station = if obs.vut.s_m < c.zone.vut.enter_s_m {
                rule.hold_s_m
            } else if obs.vut.s_m < c.zone.vut.exit_s_m {
                rule.clear_s_m
            } else {
                f64::INFINITY
            };
            // The speed it can still stop from: the distance it covers before a request takes
            // effect comes off its room, and the speed it may still gain in that time off the
            // speed. Once it stands near the station it stays (no creeping up to it).
            let room = station - obs.own.s_m;
            if room < KEEP_STAND_M && v < KEEP_STAND_MPS {
                wanted = wanted.min(-v / obs.dt_s);
            } else {
                let stop = (2.0 * CAP_DECEL_SHARE * lim.max_decel_mps2 * (room - lag_m).max(0.0)).sqrt();
                let allowed = (stop - lim.max_accel_mps2 * lag_s).max(0.0);
                wanted = wanted.min((allowed - v) / obs.dt_s);
            }
        }
        // Neither below standstill nor above the top speed within one period.
        let accel = wanted.clamp(-v / obs.dt_s, (lim.max_speed_mps - v) / obs.dt_s);
        ActuationRequest {
            accel_mps2: accel.clamp(-lim.max_decel_mps2, lim.max_accel_mps2),
            steer_rad: pure_pursuit(&bv.agent.route, &obs.own.state, obs.own.s_m, &bv.agent.vehicle),
        }
    }
}

/// What the grid reached against one VUT on one scenario.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Reach {
    /// Scenario name.
    pub scenario: String,
    /// The VUT.
    pub vut: String,
    /// The seed of every run.
    pub seed: u64,
    /// Runs of the grid: its profiles, and where a yield must keep [`YieldRule`], each profile once
    /// more keeping it.
    pub profiles: usize,
    /// PETs of the safe runs where the BV passed first, s (sorted).
    pub rush_pets_s: Vec<f64>,
    /// PETs of the safe runs where the VUT passed first, s (sorted).
    pub yield_pets_s: Vec<f64>,
    /// Runs that ended in a collision.
    pub collisions: usize,
    /// Runs where the VUT passed first but the BV did not give way as [`YieldRule`] asks (left
    /// out of `yield_pets_s`).
    pub unreadable_yields: usize,
    /// Runs the world could not run (an external simulator's error).
    pub failed: usize,
}

impl Reach {
    /// The PETs of `style`'s order.
    pub fn pets(&self, style: Style) -> &[f64] {
        match style {
            Style::Rush => &self.rush_pets_s,
            Style::Yield => &self.yield_pets_s,
        }
    }

    /// Whether some profile landed within ±10 % of the target in its order.
    pub fn reachable(&self, target: Target) -> bool {
        let tau = target.tau_s();
        self.pets(target.style()).iter().any(|p| (p - tau).abs() <= 0.1 * tau)
    }

    /// The smallest and largest PET reached in `style`'s order.
    pub fn range(&self, style: Style) -> Option<(f64, f64)> {
        let p = self.pets(style);
        Some((*p.first()?, *p.last()?))
    }
}

/// Runs the whole grid against `vut` on the scenario's first BV, seed `seed` (the scenario's target
/// style does not matter: the order of each run decides which list its PET joins).
pub fn reach(scenario: &Scenario, vut: &Vut<'_>, seed: u64) -> Reach {
    let profiles = grid();
    let mut out = Reach {
        scenario: scenario.name.clone(),
        vut: vut.name(),
        seed,
        profiles: profiles.len(),
        rush_pets_s: Vec::new(),
        yield_pets_s: Vec::new(),
        collisions: 0,
        unreadable_yields: 0,
        failed: 0,
    };
    let rule = YieldRule::of(scenario, 0);
    // Where a yield must keep the rule, every profile also runs once keeping it (those runs can
    // only give way: the BV waits behind its line until the VUT is in its zone).
    let keeps: &[Option<YieldRule>] = if rule.is_some() { &[None, rule] } else { &[None] };
    out.profiles = keeps.len() * profiles.len();
    for (keep, &profile) in keeps.iter().flat_map(|&k| profiles.iter().map(move |p| (k, p))) {
        let mut bvs: Vec<Box<dyn BvController>> =
            (0..scenario.bvs.len()).map(|_| Box::new(OpenLoop { profile, keep }) as Box<dyn BvController>).collect();
        let Ok(run) = vut.run(scenario, &mut bvs, seed) else {
            out.failed += 1;
            continue;
        };
        let r = &run.result;
        if r.collision.is_some() {
            out.collisions += 1;
            continue;
        }
        let Some(c) = r.conflicts.first() else { continue };
        match (c.first, c.pet.pet_s(), r.zone_overlap) {
            (Some(FirstThrough::Bv), Some(pet), false) => out.rush_pets_s.push(pet),
            (Some(FirstThrough::Vut), Some(pet), false) => match YieldRule::kept_in(scenario, 0, &run) {
                Some(false) => out.unreadable_yields += 1,
                _ => out.yield_pets_s.push(pet),
            },
            _ => {}
        }
    }
    out.rush_pets_s.sort_by(f64::total_cmp);
    out.yield_pets_s.sort_by(f64::total_cmp);
    out
}

/// How a BV gives way at a crossing with a stop line, as the regulator's BV does
/// (`v2t_game::regulator`, "A yield the VUT can read"): its centre no further than its hold
/// station (its stop line, never nearer the zone than [`HOLD_CLEARANCE_M`]) until the VUT enters
/// its zone, and no nearer than [`HOLD_CLEARANCE_M`] to its zone until the VUT has left it — each
/// with the regulator's own tolerance for a stop tracked late, [`HOLD_CREEP_M`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct YieldRule {
    /// Where the BV's centre waits until the VUT is in its zone, m along its path.
    pub hold_s_m: f64,
    /// Where it stays behind while the VUT is in the zone, m along its path.
    pub clear_s_m: f64,
}

impl YieldRule {
    /// The rule for BV `bv_index`: `None` unless its conflict is a crossing and its card (or
    /// grounding) gives its junction entry.
    pub fn of(scenario: &Scenario, bv_index: usize) -> Option<Self> {
        let conflict = scenario.conflict_of(bv_index)?;
        if conflict.zone.kind != ConflictKind::Crossing {
            return None;
        }
        let bv = scenario.bvs.get(bv_index)?;
        let enter = conflict.zone.bv.enter_s_m;
        let line = stop_line_station(bv.junction_entry_m?, bv.agent.vehicle.geometry.length_m, enter)?;
        Some(Self { hold_s_m: hold_station(Some(line), enter), clear_s_m: enter - HOLD_CLEARANCE_M })
    }

    /// Whether BV `bv_index` of `scenario` kept its rule in `run` (a run of that scenario), where
    /// the VUT went through that BV's zone first; `None` where there is no rule (no crossing with
    /// a stop line), the BV went first, or no one went through. The grid's runs and the
    /// experiments' regulated runs are read by this one check: a yield that broke the rule is no
    /// yield a BV may aim at.
    pub fn kept_in(scenario: &Scenario, bv_index: usize, run: &RunOutcome) -> Option<bool> {
        let rule = Self::of(scenario, bv_index)?;
        let id = &scenario.bvs.get(bv_index)?.agent.id;
        let c = run.result.conflicts.iter().find(|c| &c.bv_id == id)?;
        let vut = c.vut_passage.filter(|_| c.first == Some(FirstThrough::Vut))?;
        // Agent 0 is the VUT, the BVs follow in the scenario's order.
        let bv_s = run.trace.iter().filter_map(|x| x.agents.get(bv_index + 1).map(|a| (x.t_s, a.s_m)));
        Some(rule.kept(bv_s, vut.enter_t_s, vut.exit_t_s.unwrap_or(f64::INFINITY)))
    }

    /// Whether the BV's arc lengths `bv_s` (time, m) kept the rule against a VUT that was in its
    /// zone from `vut_enter_t_s` to `vut_exit_t_s`.
    pub fn kept(&self, mut bv_s: impl Iterator<Item = (f64, f64)>, vut_enter_t_s: f64, vut_exit_t_s: f64) -> bool {
        bv_s.all(|(t, s)| {
            if t < vut_enter_t_s {
                s <= self.hold_s_m + HOLD_CREEP_M
            } else if t <= vut_exit_t_s {
                s <= self.clear_s_m + HOLD_CREEP_M
            } else {
                true
            }
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use v2t_sim::vut::VutModel;

    #[test]
    fn a_yield_counts_only_when_the_bv_waited_behind_its_line_and_kept_clear_while_the_vut_passed() {
        let rule = YieldRule { hold_s_m: 29.0, clear_s_m: 44.0 };
        // Stands at its line, goes once the VUT is in its zone, keeps back until it has left.
        let waited = [(0.0, 0.0), (5.0, 29.4), (9.9, 29.9), (10.5, 38.0), (11.4, 44.8), (12.0, 47.0)];
        assert!(rule.kept(waited.into_iter(), 10.0, 11.5));
        // Rolls past its line before the VUT has committed.
        let early = [(0.0, 0.0), (9.0, 31.0), (10.5, 38.0)];
        assert!(!rule.kept(early.into_iter(), 10.0, 11.5));
        // Creeps up to the zone while the VUT is in it.
        let crept = [(0.0, 0.0), (9.9, 29.0), (11.0, 45.5)];
        assert!(!rule.kept(crept.into_iter(), 10.0, 11.5));
        // The regulator's own tolerance for a stop tracked late holds here too.
        assert!(rule.kept([(9.0, 29.0 + HOLD_CREEP_M)].into_iter(), 10.0, 11.5));
    }

    #[test]
    fn a_profile_run_keeping_the_rule_waits_at_its_line_and_gives_way() {
        let root = concat!(env!("CARGO_MANIFEST_DIR"), "/../../config/scenarios/left_turn_vut.toml");
        let scenario = v2t_sim::files::load_scenario(std::path::Path::new(root)).unwrap();
        let rule = YieldRule::of(&scenario, 0).unwrap();
        // Full throttle from the start: without the rule it runs through the junction first.
        let profile = Profile { a1_mps2: 3.0, t1_s: 0.0, a2_mps2: 3.0 };
        let vut = Vut::Builtin(VutModel::IdmNormal);
        for (keep, bv_first) in [(None, true), (Some(rule), false)] {
            let mut bvs: Vec<Box<dyn BvController>> = vec![Box::new(OpenLoop { profile, keep })];
            let run = vut.run(&scenario, &mut bvs, 1).unwrap();
            let c = &run.result.conflicts[0];
            assert!(run.result.collision.is_none());
            assert_eq!(c.first == Some(FirstThrough::Bv), bv_first, "{keep:?}: {:?}", c.first);
            assert_eq!(
                YieldRule::kept_in(&scenario, 0, &run),
                keep.map(|_| true),
                "{keep:?}: a BV that went first gave no yield"
            );
            if keep.is_some() {
                let p = c.vut_passage.unwrap();
                let bv_s = run.trace.iter().map(|x| (x.t_s, x.agents[1].s_m));
                assert!(rule.kept(bv_s, p.enter_t_s, p.exit_t_s.unwrap()), "{p:?}");
                // It stood at its line: within the 3 m it stands in, not further back.
                let waited = run.trace.iter().filter(|x| x.t_s < p.enter_t_s).map(|x| x.agents[1].s_m);
                assert!(waited.fold(0.0, f64::max) > rule.hold_s_m - KEEP_STAND_M);
            }
        }
    }

    /// A BV that brakes hard, then rolls on into the junction while the VUT turns, gives way to
    /// the VUT, but not from behind its line: the rule read from its run says so, and the same
    /// profile keeping the rule gives way from behind it.
    #[test]
    fn a_yield_rolled_into_the_junction_is_read_from_the_run_as_not_kept() {
        let root = concat!(env!("CARGO_MANIFEST_DIR"), "/../../config/scenarios/left_turn_vut.toml");
        let scenario = v2t_sim::files::load_scenario(std::path::Path::new(root)).unwrap();
        let rule = YieldRule::of(&scenario, 0).unwrap();
        let vut = Vut::Builtin(VutModel::IdmNormal);
        let profile = Profile { a1_mps2: -3.0, t1_s: 5.0, a2_mps2: 1.5 };
        for (keep, kept) in [(None, false), (Some(rule), true)] {
            let mut bvs: Vec<Box<dyn BvController>> = vec![Box::new(OpenLoop { profile, keep })];
            let run = vut.run(&scenario, &mut bvs, 1).unwrap();
            assert!(run.result.collision.is_none() && !run.result.zone_overlap, "{keep:?}");
            assert_eq!(run.result.conflicts[0].first, Some(FirstThrough::Vut), "{keep:?}");
            assert_eq!(YieldRule::kept_in(&scenario, 0, &run), Some(kept), "{keep:?}");
        }
    }

    /// Stop, then full throttle into the left turn: the plant would follow it at 6.6 m/s² of
    /// lateral acceleration (the grid's profile that reached 1.58 s against SUMO's IDM). The
    /// grid's BV keeps its limit, and slows for the turn before it, not in it.
    #[test]
    fn a_profile_run_turns_within_the_bvs_lateral_limit() {
        let root = concat!(env!("CARGO_MANIFEST_DIR"), "/../../config/scenarios/left_turn_basic.toml");
        let scenario = v2t_sim::files::load_scenario(std::path::Path::new(root)).unwrap();
        let limit = scenario.bvs[0].agent.vehicle.limits.max_lat_accel_mps2;
        let vut = Vut::Builtin(VutModel::IdmNormal);
        for profile in
            [Profile { a1_mps2: -3.0, t1_s: 4.0, a2_mps2: 3.0 }, Profile { a1_mps2: 3.0, t1_s: 12.0, a2_mps2: 3.0 }]
        {
            let mut bvs: Vec<Box<dyn BvController>> = vec![Box::new(OpenLoop { profile, keep: None })];
            let run = vut.run(&scenario, &mut bvs, 1).unwrap();
            let peak = crate::stats::peak_lateral_mps2(&run, 1);
            assert!(peak <= 1.05 * limit, "{profile:?}: {peak:.2} m/s² against a limit of {limit} m/s²");
            // Where the path is straight it still drives its profile's first acceleration.
            let first = run.trace.iter().find(|x| x.t_s >= 1.0).unwrap().agents[1].state.speed_mps;
            assert!(
                if profile.a1_mps2 > 0.0 { first > 11.0 } else { first < 9.0 },
                "{profile:?}: {first:.2} m/s at 1 s"
            );
        }
    }

    #[test]
    fn the_rule_is_the_cards_stop_line_and_only_at_a_crossing() {
        let root = concat!(env!("CARGO_MANIFEST_DIR"), "/../../config/scenarios/");
        let card = |name: &str| v2t_sim::files::load_scenario(std::path::Path::new(&format!("{root}{name}"))).unwrap();
        let vut_turning = card("left_turn_vut.toml");
        let rule = YieldRule::of(&vut_turning, 0).expect("a crossing with its junction entry");
        let bv = &vut_turning.bvs[0];
        let enter = vut_turning.conflict_of(0).unwrap().zone.bv.enter_s_m;
        let line = bv.junction_entry_m.unwrap() - 0.5 * bv.agent.vehicle.geometry.length_m - 2.0;
        assert!((rule.hold_s_m - line).abs() < 1e-9 && line < enter - HOLD_CLEARANCE_M, "{rule:?}");
        assert!((rule.clear_s_m - (enter - HOLD_CLEARANCE_M)).abs() < 1e-9);
        assert_eq!(YieldRule::of(&card("cut_in_basic.toml"), 0), None, "a merge has no stop line");
    }
}
