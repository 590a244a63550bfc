//! The one adapter between a BV's prior and measurements and the [`Regulator`]: "prior context +
//! measurements → regulator input → decision".
//!
//! The onboard regulator node (`v2t-edge`), the lab's in-process regulated BV and the lab's cloud
//! regulator all wrap this type and differ only in where their measurements come from (iceoryx2,
//! the simulator, the link) and where the decision goes (a plan on the bus, the simulated
//! actuators, a signed frame). So every figure measured in the lab is made by the code the vehicle
//! runs, down to how a position becomes an arc length and which reference speed the leader tracks.
//!
//! Pure: time and measurement ages come in as arguments; no allocation per decision (the context's
//! buffers are made once per prior).

use v2t_model::Target;
use v2t_model::driving::{CURVE_HALF_WINDOW_M, curve_speed};
use v2t_model::geometry::Point2;
use v2t_model::metrics::{ConflictKind, OccupancyInterval};
use v2t_model::path::ReferencePath;
use v2t_model::validate::ValidationError;

use crate::qp::QpError;
use crate::reaction::{ReactionBelief, ReactionPosterior};
use crate::reference::ReferenceSample;
use crate::regulator::{
    BelowReach, CURVE_LAT_SHARE, Decision, PathState, Regulator, RegulatorInput, RegulatorParams, RegulatorStatus,
};
use crate::route_speed::RouteSpeed;

/// How far from the last projection a vehicle is looked for along its path, m: the projection
/// never jumps to another branch of a path that passes near itself.
pub const PROJECTION_WINDOW_M: f64 = 15.0;

/// What a prior gives the regulator: the BV's path with the prior's timing along it, the VUT's
/// route, their conflict zone and the target.
#[derive(Debug, Clone)]
pub struct Context {
    /// The BV's reference path.
    pub bv_path: ReferencePath,
    /// The VUT's route.
    pub vut_path: ReferencePath,
    /// Zone along the BV's path.
    pub zone_bv: OccupancyInterval,
    /// Zone along the VUT's route.
    pub zone_vut: OccupancyInterval,
    /// Crossing or merge.
    pub zone_kind: ConflictKind,
    /// Where the BV stands when it gives way, from the map (see
    /// [`RegulatorInput::stop_line_s_m`]); `None` without one.
    pub stop_line_s_m: Option<f64>,
    /// Target PET and who passes first.
    pub target: Target,
    /// The prior's timing along the BV's path, as received (the realism term's reference).
    timing: Vec<ReferenceSample>,
    /// Reference speed over arc length: (s, v), s strictly increasing.
    profile: Vec<(f64, f64)>,
}

/// The zone of a [`Context`]: along the BV's path, along the VUT's route, and its kind.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Zone {
    /// Along the BV's path.
    pub bv: OccupancyInterval,
    /// Along the VUT's route.
    pub vut: OccupancyInterval,
    /// Crossing or merge.
    pub kind: ConflictKind,
    /// Where the BV stands when it gives way, from the map (see
    /// [`RegulatorInput::stop_line_s_m`]); `None` without one.
    pub stop_line_s_m: Option<f64>,
}

impl Context {
    /// The context of a prior: paths, zone, target and the BV's timing along its path (time since
    /// the prior's start, arc length, speed; allocates once per prior, not per decision).
    pub fn new(
        bv_path: ReferencePath,
        vut_path: ReferencePath,
        zone: Zone,
        target: Target,
        timing: impl IntoIterator<Item = ReferenceSample>,
    ) -> Self {
        let timing: Vec<ReferenceSample> = timing.into_iter().collect();
        let mut profile: Vec<(f64, f64)> = Vec::with_capacity(timing.len());
        for q in &timing {
            // Keep s strictly increasing (a standstill in the reference repeats s).
            if profile.last().is_none_or(|(s, _)| q.s_m > *s) {
                profile.push((q.s_m, q.v_mps.max(0.0)));
            }
        }
        Self {
            bv_path,
            vut_path,
            zone_bv: zone.bv,
            zone_vut: zone.vut,
            zone_kind: zone.kind,
            stop_line_s_m: zone.stop_line_s_m,
            target,
            timing,
            profile,
        }
    }

    /// The prior's timing along the BV's path.
    pub fn timing(&self) -> &[ReferenceSample] {
        &self.timing
    }

    /// The reference speed where the BV is, m/s (linear in arc length; the ends hold).
    pub fn reference_speed_at(&self, s_m: f64) -> f64 {
        let (Some(first), Some(last)) = (self.profile.first(), self.profile.last()) else { return 0.0 };
        if s_m <= first.0 {
            return first.1;
        }
        if s_m >= last.0 {
            return last.1;
        }
        let i = self.profile.partition_point(|(s, _)| *s <= s_m);
        match (self.profile.get(i.saturating_sub(1)), self.profile.get(i)) {
            (Some(a), Some(b)) => a.1 + (b.1 - a.1) * (s_m - a.0) / (b.0 - a.0),
            _ => last.1,
        }
    }
}

/// One vehicle as measured, in the track frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Measurement {
    /// Position, m.
    pub x_m: f64,
    /// Position, m.
    pub y_m: f64,
    /// Speed, m/s (a negative reading counts as standing).
    pub speed_mps: f64,
    /// Age of the measurement when the decision is made, s (negative counts as 0).
    pub age_s: f64,
}

impl Measurement {
    fn is_finite(&self) -> bool {
        self.x_m.is_finite() && self.y_m.is_finite() && self.speed_mps.is_finite() && self.age_s.is_finite()
    }
}

/// Where a vehicle is along a path, remembered between decisions.
#[derive(Debug, Clone, Copy, Default)]
struct Tracked {
    s_m: Option<f64>,
}

impl Tracked {
    fn project(&mut self, path: &ReferencePath, m: &Measurement) -> Option<f64> {
        let q = Point2 { x: m.x_m, y: m.y_m };
        let f = match self.s_m {
            Some(hint) => path.project_near(q, hint, PROJECTION_WINDOW_M),
            None => path.project(q),
        }?;
        self.s_m = Some(f.s_m);
        Some(f.s_m)
    }
}

/// One decision and what it was made from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Step {
    /// The BV's arc length as measured (before it is brought to now), m; `None` when the BV could
    /// not be placed on its path (then the decision is the minimal-risk deceleration, `Fallback`).
    pub bv_s_m: Option<f64>,
    /// What the regulator was given; `None` when it was not asked (the BV off its path, or no VUT
    /// to regulate against: `Stale`).
    pub input: Option<RegulatorInput>,
    /// The decision.
    pub decision: Decision,
}

/// Most VUT samples a run keeps for what it learns of the VUT's route (10 min of decisions at
/// 10 Hz; reserved once).
pub const RUN_SAMPLES: usize = 6000;

/// What one run taught the regulator about the VUT ([`Regulation::lesson`]).
#[derive(Debug, Clone, PartialEq)]
pub struct Lesson {
    /// How the VUT drove its route up to its zone's exit, as the regulator measured it (every
    /// decision's VUT arc length and speed, both at the instant they were measured;
    /// [`RouteSpeed::from_samples`]). `None`: too little of it seen.
    pub route: Option<RouteSpeed>,
    /// With the reacting follower: how it identified the VUT's reaction by then.
    pub reaction: Option<ReactionPosterior>,
}

/// The regulator of one BV with the prior it regulates around.
#[derive(Debug)]
pub struct Regulation {
    regulator: Regulator,
    context: Option<Context>,
    bv: Tracked,
    vut: Tracked,
    last_accel: f64,
    lat_accel_mps2: f64,
    /// The VUT's arc length and speed as measured at every decision of the run (capacity
    /// [`RUN_SAMPLES`]).
    vut_samples: Vec<(f64, f64)>,
    /// Whether the run's [`Lesson`] was given.
    lesson_given: bool,
}

impl Regulation {
    /// A regulator with `params` and no prior yet, for a BV whose lateral acceleration is limited
    /// to `lat_accel_mps2` (its plans slow down for the curves of its path).
    pub fn new(params: RegulatorParams, lat_accel_mps2: f64) -> Result<Self, QpError> {
        Ok(Self {
            regulator: Regulator::new(params)?,
            context: None,
            bv: Tracked::default(),
            vut: Tracked::default(),
            last_accel: 0.0,
            lat_accel_mps2,
            vut_samples: Vec::with_capacity(RUN_SAMPLES),
            lesson_given: false,
        })
    }

    /// What this run taught the regulator about the VUT, once per run (per context), as soon as
    /// the VUT has left its zone: how it drove its route up to there and how its reaction was
    /// identified by then. The onboard node reports it to the cloud; the lab's campaigns learn it
    /// as the campaign memory on the track does. `None` before, and after it was given; a run in
    /// which the VUT never leaves its zone teaches nothing. Allocates when it gives it (once).
    pub fn lesson(&mut self) -> Option<Lesson> {
        let ctx = self.context.as_ref().filter(|_| !self.lesson_given)?;
        let exit = ctx.zone_vut.exit_s_m;
        if self.vut_samples.last().is_none_or(|&(s, _)| s < exit) {
            return None;
        }
        self.lesson_given = true;
        Some(Lesson {
            route: RouteSpeed::from_samples(self.vut_samples.iter().copied(), exit),
            reaction: self.regulator.params().reacting_follower.then(|| self.regulator.reaction_belief().posterior()),
        })
    }

    /// Regulates around `context` from now on, as a new interaction. Its timing is checked first:
    /// a refused timing is the error and leaves the active context whole.
    pub fn set_context(&mut self, context: Context) -> Result<(), ValidationError> {
        self.regulator.set_reference(context.timing.iter().copied())?;
        self.context = Some(context);
        self.regulator.reset();
        self.bv = Tracked::default();
        self.vut = Tracked::default();
        self.last_accel = 0.0;
        self.vut_samples.clear();
        self.lesson_given = false;
        Ok(())
    }

    /// The active context.
    pub fn context(&self) -> Option<&Context> {
        self.context.as_ref()
    }

    /// Aims at `target` instead of the prior's (a campaign's learned aim, [`crate::campaign`]),
    /// told what earlier runs showed about reach. Without a context only the reach is kept.
    pub fn aim(&mut self, target: Target, known: Option<BelowReach>) {
        if let Some(c) = self.context.as_mut() {
            c.target = target;
        }
        self.regulator.set_known_below_reach(known);
    }

    /// How this VUT drove its route in earlier runs of the test (see
    /// [`Regulator::set_route_speed`]); it stays across contexts. A refused record is the error
    /// and leaves the one before.
    pub fn set_route_speed(&mut self, learned: Option<RouteSpeed>) -> Result<(), ValidationError> {
        self.regulator.set_route_speed(learned)
    }

    /// The prior of the VUT's reaction from earlier runs of the test (see
    /// [`Regulator::set_reaction_prior`]); it stays across contexts. A refused posterior is the
    /// error and leaves the one before.
    pub fn set_reaction_prior(&mut self, prior: Option<&ReactionPosterior>) -> Result<(), ValidationError> {
        self.regulator.set_reaction_prior(prior)
    }

    /// How the VUT is identified to react so far this run.
    pub fn reaction_belief(&self) -> &ReactionBelief {
        self.regulator.reaction_belief()
    }

    /// The learned route speed in use.
    pub fn route_speed(&self) -> Option<&RouteSpeed> {
        self.regulator.route_speed()
    }

    /// The regulator's settings.
    pub fn params(&self) -> &RegulatorParams {
        self.regulator.params()
    }

    /// The accelerations the last decision `d` plans over the horizon (see
    /// [`Regulator::planned_accels`]).
    pub fn planned_accels(&self, d: &Decision) -> Option<&[f64]> {
        self.regulator.planned_accels(d)
    }

    /// The minimal-risk deceleration with `status`, for a BV at `v_mps`.
    fn minimal_risk(&self, status: RegulatorStatus, v_mps: f64) -> Decision {
        let p = self.regulator.params();
        let v = if v_mps.is_finite() { v_mps.max(0.0) } else { 0.0 };
        Decision {
            status,
            accel_mps2: -p.fallback_decel_mps2,
            next_speed_mps: (v - p.fallback_decel_mps2 * p.dt_s).max(0.0),
            key_time_s: None,
            predicted_pet_s: None,
            leader_slack_m: 0.0,
            follower_slack_m: 0.0,
            below_reach: None,
            reaction: None,
        }
    }

    /// One decision at time `t_s` (any fixed origin) from the BV's measurement and the VUT's, if
    /// any: both placed on their paths, brought to `t_s` at constant speed, the BV's curves capping
    /// its plan, the reference speed the prior's at the BV's arc length. `None` without a context
    /// (no prior: the caller brakes). A BV that cannot be placed on its path is `Fallback`, a
    /// missing VUT `Stale`: both the minimal-risk deceleration.
    pub fn decide(&mut self, t_s: f64, bv: &Measurement, vut: Option<&Measurement>) -> Option<Step> {
        let ctx = self.context.as_ref()?;
        let bv_s = if bv.is_finite() { self.bv.project(&ctx.bv_path, bv) } else { None };
        let Some(bv_s) = bv_s else {
            return Some(Step {
                bv_s_m: None,
                input: None,
                decision: self.minimal_risk(RegulatorStatus::Fallback, 0.0),
            });
        };
        let vut_seen = vut.filter(|v| v.is_finite()).and_then(|v| Some((self.vut.project(&ctx.vut_path, v)?, v)));
        let Some((vut_s, vut)) = vut_seen else {
            // Without the VUT there is nothing to regulate against.
            let decision = self.minimal_risk(RegulatorStatus::Stale, bv.speed_mps);
            return Some(Step { bv_s_m: Some(bv_s), input: None, decision });
        };
        let now = |s_m: f64, m: &Measurement| {
            let (v, age) = (m.speed_mps.max(0.0), m.age_s.max(0.0));
            PathState { s_m: s_m + v * age, v_mps: v, age_s: age }
        };
        let input = RegulatorInput {
            t_s,
            bv: now(bv_s, bv),
            vut: now(vut_s, vut),
            bv_accel_mps2: self.last_accel,
            zone_bv: ctx.zone_bv,
            zone_vut: ctx.zone_vut,
            zone_kind: ctx.zone_kind,
            target: ctx.target,
            reference_speed_mps: ctx.reference_speed_at(bv_s),
            stop_line_s_m: ctx.stop_line_s_m,
        };
        let lat = CURVE_LAT_SHARE * self.lat_accel_mps2;
        let path = &ctx.bv_path;
        let decision = self.regulator.decide_on_path(&input, &|s| curve_speed(path, s, CURVE_HALF_WINDOW_M, lat));
        self.last_accel = decision.accel_mps2;
        if self.vut_samples.len() < RUN_SAMPLES {
            // Where the VUT was and how fast, at the one instant it was measured: brought to the
            // decision's time, a VUT that slows would be recorded ahead of where it had that speed.
            self.vut_samples.push((vut_s, vut.speed_mps.max(0.0)));
        }
        Some(Step { bv_s_m: Some(bv_s), input: Some(input), decision })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use v2t_model::Style;
    use v2t_model::path::PathBuilder;

    /// A BV going east on y = 0 and a VUT going north on x = 50: they cross at (50, 0).
    fn context(timing: Vec<ReferenceSample>) -> Context {
        let bv_path = PathBuilder::new(0.0, 0.0, 0.0).line(100.0).build(1.0).unwrap();
        let vut_path = PathBuilder::new(50.0, -60.0, std::f64::consts::FRAC_PI_2).line(120.0).build(1.0).unwrap();
        let zone = Zone {
            bv: OccupancyInterval { enter_s_m: 46.0, exit_s_m: 54.0 },
            vut: OccupancyInterval { enter_s_m: 56.0, exit_s_m: 64.0 },
            kind: ConflictKind::Crossing,
            stop_line_s_m: None,
        };
        Context::new(bv_path, vut_path, zone, Target::new(2.0, Style::Rush).unwrap(), timing)
    }

    fn steady(v: f64) -> Vec<ReferenceSample> {
        (0..=20).map(|k| ReferenceSample { t_s: k as f64, s_m: v * k as f64, v_mps: v }).collect()
    }

    fn at(x_m: f64, y_m: f64, speed_mps: f64) -> Measurement {
        Measurement { x_m, y_m, speed_mps, age_s: 0.05 }
    }

    #[test]
    fn without_a_context_nothing_is_decided() {
        let mut r = Regulation::new(RegulatorParams::default(), 4.0).unwrap();
        assert!(r.decide(0.0, &at(0.0, 0.0, 8.0), None).is_none());
    }

    #[test]
    fn a_refused_timing_is_an_error_and_leaves_the_context_in_place() {
        let mut r = Regulation::new(RegulatorParams::default(), 4.0).unwrap();
        r.set_context(context(steady(8.0))).unwrap();
        let mut bad = steady(8.0);
        bad[3].v_mps = f64::NAN;
        let err = r.set_context(context(bad)).unwrap_err();
        assert!(err.to_string().contains("reference[3].v_mps"), "{err}");
        assert_eq!(r.context().unwrap().timing(), steady(8.0).as_slice(), "the active context is whole");
        let mut one = steady(8.0);
        one.truncate(1);
        assert!(r.set_context(context(one)).is_err(), "a timing of one sample is refused, not ignored");
    }

    #[test]
    fn measurements_are_placed_on_their_paths_and_brought_to_now() {
        let mut r = Regulation::new(RegulatorParams::default(), 4.0).unwrap();
        r.set_context(context(steady(8.0))).unwrap();
        let step = r.decide(3.0, &at(10.0, 0.3, 8.0), Some(&at(50.0, -40.0, 10.0))).unwrap();
        assert_eq!(step.bv_s_m, Some(10.0));
        let input = step.input.unwrap();
        assert!((input.bv.s_m - (10.0 + 8.0 * 0.05)).abs() < 1e-9);
        assert!((input.vut.s_m - (20.0 + 10.0 * 0.05)).abs() < 1e-9);
        assert_eq!(input.reference_speed_mps, 8.0);
        assert!(matches!(step.decision.status, RegulatorStatus::Regulating | RegulatorStatus::Degraded));
        // The next decision starts from the acceleration this one applied.
        let next = r.decide(3.1, &at(10.8, 0.3, 8.0), Some(&at(50.0, -39.0, 10.0))).unwrap();
        assert_eq!(next.input.unwrap().bv_accel_mps2, step.decision.accel_mps2);
    }

    #[test]
    fn a_bv_off_its_path_falls_back_and_a_missing_vut_is_stale() {
        let mut r = Regulation::new(RegulatorParams::default(), 4.0).unwrap();
        r.set_context(context(steady(8.0))).unwrap();
        let fallback = r.decide(0.0, &at(f64::NAN, 0.0, 8.0), None).unwrap();
        assert_eq!((fallback.decision.status, fallback.bv_s_m), (RegulatorStatus::Fallback, None));
        assert!(fallback.decision.accel_mps2 < 0.0);
        let stale = r.decide(0.0, &at(5.0, 0.0, 8.0), Some(&at(f64::INFINITY, 0.0, 1.0))).unwrap();
        assert_eq!(stale.decision.status, RegulatorStatus::Stale);
        assert_eq!(stale.decision.accel_mps2, -r.params().fallback_decel_mps2);
        assert!(stale.input.is_none());
    }

    #[test]
    fn the_reference_speed_is_the_priors_at_the_bvs_arc_length() {
        let timing = vec![
            ReferenceSample { t_s: 0.0, s_m: 0.0, v_mps: 4.0 },
            ReferenceSample { t_s: 1.0, s_m: 0.0, v_mps: 4.0 },
            ReferenceSample { t_s: 5.0, s_m: 40.0, v_mps: 12.0 },
        ];
        let c = context(timing);
        assert_eq!(c.reference_speed_at(-5.0), 4.0);
        assert!((c.reference_speed_at(20.0) - 8.0).abs() < 1e-12);
        assert_eq!(c.reference_speed_at(90.0), 12.0);
    }

    #[test]
    fn aiming_changes_the_target_of_the_decisions() {
        let mut r = Regulation::new(RegulatorParams::default(), 4.0).unwrap();
        r.set_context(context(steady(8.0))).unwrap();
        let aim = Target::new(3.5, Style::Yield).unwrap();
        r.aim(aim, None);
        let step = r.decide(0.0, &at(5.0, 0.0, 8.0), Some(&at(50.0, -40.0, 10.0))).unwrap();
        assert_eq!(step.input.unwrap().target, aim);
    }
}
