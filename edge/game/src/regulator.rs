//! The leader: the BV's regulator.
//!
//! **Method.** Each cycle, from the measured states, the regulator solves a Stackelberg problem
//! whose leader decision is reduced to one number, the time `T` at which the BV reaches its key
//! point on its path — the zone exit when it rushes (it must be out before the VUT comes), the
//! zone entry when it yields (it goes in after the VUT has left):
//!
//! 1. **Follower best response.** The VUT is modelled as a QP-MPC (see [`crate::qp`]) that tracks
//!    its current speed with an effort penalty, speed ≥ 0 and its limits, and keeps the zone order
//!    the style fixes with one linear inequality at the BV's planned key time (slack reported).
//!    From its plan come the VUT's entry time (rush) or exit time (yield) `t_V`. When earlier runs
//!    of the test showed how this VUT drives its route ([`Regulator::set_route_speed`], kept by
//!    the campaign memory), it tracks that speed instead, its deviation from it now fading, and
//!    `t_V` is no earlier than that free motion gives (see [`crate::route_speed`]).
//!    At a crossing, when the VUT is identified to react to the BV ([`crate::reaction`]: a
//!    posterior over a grid of gap-accepting drivers, updated every decision from the VUT's
//!    measured acceleration, its prior carried from run to run by the campaign memory), the delay
//!    its most probable driver predicts for the BV's motion to each candidate key time is added
//!    to `t_V`, and the key time whose PET comes nearest τ is taken — counting on that predicted
//!    reaction for at most a fifth of τ of PET.
//! 2. **Leader choice.** PET is `t_V − T` (rush) or `T − t_V` (yield); the adversarial term
//!    `w_adv (PET − τ)²` plus the realism term `w_real (T − T_ref)²` is minimised in closed form,
//!    `T* = (w_adv (t_V ∓ τ) + w_real T_ref) / (w_adv + w_real)`. `T_ref` is the prior's own time
//!    from the BV's current arc length to the key point ([`Regulator::set_reference`]: the
//!    prior's timing along the path, measured on the prior itself), so the pull needs no clock
//!    shared with the prior. The follower is re-solved with `T*` (a fixed-point step: its response
//!    only moves when its order constraint becomes active).
//! 3. **Leader plan.** A QP-MPC for the BV with the event `s_BV(T*) = key station` (an equality,
//!    slack-penalized: when it cannot be met the plan comes as close as the limits allow and the
//!    status says `Degraded`), within the BV's limits, tracking a speed reference that blends the
//!    average speed to the key point with the prior's speed profile time-warped to arrive at `T*`
//!    (weights `w_adv : w_real`). `w_real = 0`, or no reference, is the regulator without the
//!    realism term.
//! 4. **Safety.** The follower is solved once more against the BV's *planned* key time plus a
//!    margin. If even the VUT's best response cannot keep the order (its slack is positive), the BV
//!    gives way: it plans to stay behind the zone entry until the VUT is predicted to have left
//!    (`SafetyYield`).
//!
//! 5. **A yield the VUT can read.** A BV that gives way at a crossing waits where a driver who
//!    gives way waits: before the junction's edge on its lane (its *stop line*, from the map:
//!    [`RegulatorInput::stop_line_s_m`]), never nearer the zone than [`HOLD_CLEARANCE_M`], so a VUT
//!    that judges the gap sees an oncoming car standing outside the junction, not one already in
//!    it. While the VUT is not yet in its zone (it has not committed), a plan that would pass the
//!    stop line before the VUT is predicted there is replaced by one that reaches the line no
//!    earlier, slowing from now on at the comfortable deceleration (`Waiting`); while the VUT is in
//!    its zone, the same keeps the BV [`HOLD_CLEARANCE_M`] before the zone until the VUT is
//!    predicted out of it; then the BV goes for its key time. It can cost reach: a BV that comes
//!    too fast to roll up to its line as the VUT commits must stop there first, and from a
//!    standstill 17 m before the zone (the VUT-turning card) no yield PET below about 3 s is reached.
//!
//! 6. **A rush the VUT can read.** A BV that goes first at a crossing does its slowing before
//!    it commits, where its front enters the junction (its stop line plus [`STOP_LINE_MARGIN_M`];
//!    without a stop line, its zone entry): when the average speed to its key point is below the
//!    speed it would cross at (its reference speed within the path's limits there), the plan goes
//!    to the commit station, due the crossing time before the key time, and speeds up from there
//!    — unless that means crawling to the junction at less than half the crossing speed: a BV
//!    that all but stops there while the VUT slows for it only waits for both to go at once.
//!    Inside the zone it never slows down for a VUT that comes later than predicted: a VUT that
//!    waits to turn, or one with priority that brakes for a car in its path, waits for as long as
//!    it sees the BV slowing in there, and a car that dawdles in another's path is not one to put
//!    on a track. It costs some reach against a VUT that slows down late (the PET comes out long).
//!
//! **Why it holds in closed loop.** The key time is a commitment in absolute time, recomputed from
//! measured states every cycle; the event may lie beyond the horizon (the QP extrapolates at the
//! terminal speed), so the plan never pushes its waiting past the horizon, and the target tracks the
//! VUT's actual progress (feedback on the predicted PET). When the VUT has already left the zone in
//! yield, the observed exit time is used instead of a prediction (back-dated to between cycles).
//!
//! **Cut-ins.** After a rushing merge the BV is the VUT's lead vehicle, and a VUT that closes in on
//! it brakes, which lengthens the PET. So a rushing cut-in arrives faster than the VUT, never slows
//! down inside the merge zone, and afterwards, while the VUT is predicted to reach the encroachment
//! point later than τ after the BV's observed exit, pulls away (see `docs/BENCHMARKS.md` for what
//! each step is worth).
//!
//! Every outcome is a [`RegulatorStatus`] with a defined plan; the acceleration returned is always
//! finite and within the BV's limits.

use v2t_model::metrics::{ConflictKind, OccupancyInterval};
use v2t_model::validate::{Validate, ValidationError, in_range};
use v2t_model::{Style, Target};

use crate::qp::{EventKind, LongitudinalQp, QpError, QpInput, QpShape, QpStatus};
use crate::reaction::{
    BvMotion, Constant, FreeSpeed, Identified, ReactionBelief, ReactionPosterior, Scene, Snapshot, rollout,
};
use crate::reference::{ReferenceSample, ReferenceTiming};
use crate::route_speed::{DEVIATION_FADE_S, RouteSpeed};

/// Longitudinal limits of one vehicle.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Limits {
    /// Top speed, m/s.
    pub max_speed_mps: f64,
    /// Largest acceleration, m/s².
    pub max_accel_mps2: f64,
    /// Largest deceleration (positive), m/s².
    pub max_decel_mps2: f64,
}

impl From<&v2t_model::vehicle::VehicleLimits> for Limits {
    /// The regulator's model of a vehicle: its longitudinal limits.
    fn from(l: &v2t_model::vehicle::VehicleLimits) -> Self {
        Self { max_speed_mps: l.max_speed_mps, max_accel_mps2: l.max_accel_mps2, max_decel_mps2: l.max_decel_mps2 }
    }
}

/// Regulator settings, as written in `config/regulator/*.toml`. The BV and VUT limits are not
/// part of the file: they come from the vehicle files (see [`RegulatorParams::with_limits`]).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RegulatorParams {
    /// MPC steps (30 or 50 are typical).
    pub horizon: usize,
    /// MPC step, s.
    pub dt_s: f64,
    /// Weight of the adversarial term `(PET − τ)²`.
    pub w_adv: f64,
    /// Weight of the realism term `(T − T_ref)²` on the key time.
    pub w_real: f64,
    /// The BV never plans to share the zone with the VUT closer than this, s.
    pub safety_margin_s: f64,
    /// Inputs older than this are stale, s.
    pub max_input_age_s: f64,
    /// Comfortable deceleration of the fallback profile, m/s².
    pub fallback_decel_mps2: f64,
    /// Time headway the VUT is assumed to keep behind a vehicle that cuts in ahead of it, s.
    pub vut_headway_s: f64,
    /// Weight of the jerk in the BV's plan, against its acceleration's 1 and its speed
    /// reference's 0.2: how smoothly it moves, traded against how fast it answers (3 when the
    /// file does not say; `docs/BENCHMARKS.md`, "What the plan's jerk weight buys").
    #[serde(default = "default_w_jerk")]
    pub w_jerk: f64,
    /// Whether the follower reacts to the BV as the VUT is identified to while the run goes on
    /// ([`crate::reaction`]; `true` when the file does not say). `false`: the follower drives its
    /// free motion and keeps the order only as far as it must (the paper's follower).
    #[serde(default = "default_reacting_follower")]
    pub reacting_follower: bool,
    /// Share of the prior's *acceleration shape* the BV's plan keeps, in [0, 1]: with the realism
    /// term (`w_real` > 0) the plan's jerk is counted beyond this share of the prior's own jerk,
    /// the prior time-warped to the key time the game chose, fading out over the last
    /// 1.5 s before the plan's event (the key point, or the commit station of a rushing
    /// BV that slows before it commits: there the plan is about landing on τ). The plan then
    /// eases off and presses on where the prior does, instead of smoothing the prior's motion away;
    /// the game still sets when it gets there. 0 (also when the file does not say): every bit of
    /// the plan's jerk counts, as before this setting existed.
    #[serde(default)]
    pub shape_share: f64,
    /// Time from an acceleration request until the BV's speed has followed it (transport delay
    /// and the actuator's lag; the tracker's `accel_latency_s`), s. A BV that speeds up keeps
    /// gaining speed for about this long after its plan stops asking, so its speed caps for a
    /// curve ahead are lowered by the speed its last request still adds:
    /// this times that request, when it accelerates (0.45 when the file does not say).
    #[serde(default = "default_accel_latency_s")]
    pub accel_latency_s: f64,
    /// BV limits (from the BV's vehicle file).
    #[serde(skip, default = "default_bv_limits")]
    pub bv: Limits,
    /// Assumed VUT limits for its best response (from the VUT's vehicle file).
    #[serde(skip, default = "default_vut_limits")]
    pub vut: Limits,
}

fn default_w_jerk() -> f64 {
    3.0
}

fn default_reacting_follower() -> bool {
    true
}

fn default_accel_latency_s() -> f64 {
    0.45
}

fn default_bv_limits() -> Limits {
    Limits { max_speed_mps: 20.0, max_accel_mps2: 3.0, max_decel_mps2: 6.0 }
}

fn default_vut_limits() -> Limits {
    Limits { max_speed_mps: 25.0, max_accel_mps2: 3.0, max_decel_mps2: 6.0 }
}

impl RegulatorParams {
    /// These settings with the given vehicle limits.
    #[must_use]
    pub fn with_limits(mut self, bv: Limits, vut: Limits) -> Self {
        self.bv = bv;
        self.vut = vut;
        self
    }
}

impl Default for RegulatorParams {
    fn default() -> Self {
        Self {
            horizon: 50,
            dt_s: 0.1,
            w_adv: 1.0,
            w_real: 0.0,
            safety_margin_s: 0.5,
            max_input_age_s: 0.5,
            fallback_decel_mps2: 2.0,
            vut_headway_s: 1.5,
            w_jerk: default_w_jerk(),
            reacting_follower: default_reacting_follower(),
            shape_share: 0.0,
            accel_latency_s: default_accel_latency_s(),
            bv: default_bv_limits(),
            vut: default_vut_limits(),
        }
    }
}

impl Validate for Limits {
    fn validate(&self) -> Result<(), ValidationError> {
        in_range("max_speed_mps", self.max_speed_mps, 0.1, 70.0)?;
        in_range("max_accel_mps2", self.max_accel_mps2, 0.1, 10.0)?;
        in_range("max_decel_mps2", self.max_decel_mps2, 0.1, 12.0)
    }
}

impl Validate for RegulatorParams {
    fn validate(&self) -> Result<(), ValidationError> {
        if !(5..=200).contains(&self.horizon) {
            return Err(ValidationError::new("horizon", format!("must lie in [5, 200], got {}", self.horizon)));
        }
        in_range("dt_s", self.dt_s, 0.01, 0.5)?;
        // The weights stay within six decades of each other and of 1 (the QP's scaling); an input
        // older than 5 s is no measurement; the fallback brakes like a vehicle can.
        in_range("w_adv", self.w_adv, 1e-6, 1e6)?;
        in_range("w_real", self.w_real, 0.0, 1e6)?;
        in_range("safety_margin_s", self.safety_margin_s, 0.0, 5.0)?;
        in_range("max_input_age_s", self.max_input_age_s, 0.01, 5.0)?;
        in_range("fallback_decel_mps2", self.fallback_decel_mps2, 0.5, 12.0)?;
        in_range("vut_headway_s", self.vut_headway_s, 0.0, 5.0)?;
        in_range("w_jerk", self.w_jerk, 0.01, 1000.0)?;
        in_range("shape_share", self.shape_share, 0.0, 1.0)?;
        in_range("accel_latency_s", self.accel_latency_s, 0.0, 2.0)?;
        self.bv.validate().map_err(|e| e.within("bv"))?;
        self.vut.validate().map_err(|e| e.within("vut"))
    }
}

/// One vehicle along its own path.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PathState {
    /// Arc length, m.
    pub s_m: f64,
    /// Speed, m/s.
    pub v_mps: f64,
    /// Age of the measurement, s.
    pub age_s: f64,
}

/// Everything the regulator needs for one decision.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RegulatorInput {
    /// Time now, s (any fixed origin; used to remember the VUT's observed exit).
    pub t_s: f64,
    /// The BV along its reference path.
    pub bv: PathState,
    /// The VUT along its route.
    pub vut: PathState,
    /// Acceleration the BV applied last, m/s².
    pub bv_accel_mps2: f64,
    /// Zone occupancy along the BV's path.
    pub zone_bv: OccupancyInterval,
    /// Zone occupancy along the VUT's route.
    pub zone_vut: OccupancyInterval,
    /// Crossing or merge (after a rushing merge the BV is the VUT's lead vehicle).
    pub zone_kind: ConflictKind,
    /// Target PET τ and who passes first.
    pub target: Target,
    /// The BV's reference speed now, m/s.
    pub reference_speed_mps: f64,
    /// Where the BV stands when it gives way at a crossing, from the map (its centre's arc length,
    /// [`stop_line_station`]): its front just before the junction's edge on its lane, so it waits
    /// outside the junction as a driver who gives way does. `None` (no map) or a line nearer the
    /// zone than [`HOLD_CLEARANCE_M`]: that clearance before the zone instead.
    pub stop_line_s_m: Option<f64>,
}

/// The BV never stands closer to its zone than this when it gives way, m: its front stays this
/// far from the VUT's swept path (a VUT that passes a waiting car 0.5 m away is a near miss on a
/// track).
pub const HOLD_CLEARANCE_M: f64 = 2.5;
/// How far before a junction's edge on its lane the front of a BV that gives way stops, m.
pub const STOP_LINE_MARGIN_M: f64 = 2.0;

/// The arc length of the centre of a BV of `length_m` whose path enters the junction at
/// `junction_entry_m` when it stands [`STOP_LINE_MARGIN_M`] before the junction's edge: what
/// [`RegulatorInput::stop_line_s_m`] holds. `None` when that is not before the BV's zone, which
/// begins at `zone_enter_s_m` (a junction entered only after the zone gives no stop line).
#[must_use]
pub fn stop_line_station(junction_entry_m: f64, length_m: f64, zone_enter_s_m: f64) -> Option<f64> {
    let line = junction_entry_m - 0.5 * length_m - STOP_LINE_MARGIN_M;
    (line < zone_enter_s_m).then_some(line)
}

/// Where a BV that gives way at a crossing waits until the VUT is in its zone: its stop line
/// (`stop_line_s_m`, [`stop_line_station`]) when the map gives one, never nearer its zone (which
/// begins at `zone_enter_s_m`) than [`HOLD_CLEARANCE_M`].
#[must_use]
pub fn hold_station(stop_line_s_m: Option<f64>, zone_enter_s_m: f64) -> f64 {
    let clear = zone_enter_s_m - HOLD_CLEARANCE_M;
    stop_line_s_m.map_or(clear, |l| l.min(clear))
}

/// The inverse of [`stop_line_station`]: where the path enters the junction, for a BV of
/// `length_m` whose stop line is `stop_line_s_m`.
#[must_use]
pub fn junction_entry_of_stop_line(stop_line_s_m: f64, length_m: f64) -> f64 {
    stop_line_s_m + 0.5 * length_m + STOP_LINE_MARGIN_M
}

/// Share of the BV's lateral-acceleration limit its plans may use in curves (the rest is the
/// tracker's margin): the regulator's curve speed is [`v2t_model::driving::curve_speed`] over
/// ±[`v2t_model::driving::CURVE_HALF_WINDOW_M`] with this share of the limit
/// ([`crate::regulation::Regulation`] passes it to [`Regulator::decide_on_path`]). Chosen on
/// seeds 1–5 once the caps counted the speed the actuator still adds
/// ([`RegulatorParams::accel_latency_s`]): 0.8 gave up the PET a BV in a hurry had reached, 0.9
/// kept the limit with 0.02 m/s² to spare, 0.85 with a quarter of a m/s² (`docs/BENCHMARKS.md`).
pub const CURVE_LAT_SHARE: f64 = 0.85;

/// Farthest a speed cap is looked for ahead, m.
const CAP_SCAN_MAX_M: f64 = 400.0;
/// Share of the BV's largest deceleration its plans brake with for a curve ahead: the speed
/// caps of a plan are the braking envelope of the path's curve speeds at this deceleration.
pub const CURVE_BRAKE_SHARE: f64 = 0.35;
/// Points of the 1 m grid the caps ahead are read on.
const CAP_GRID: usize = CAP_SCAN_MAX_M as usize + 1;

/// What the regulator decided, and why.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum RegulatorStatus {
    /// The plan meets the target key time.
    Regulating,
    /// The target key time cannot be met within the limits; the plan comes as close as it can.
    Degraded,
    /// The VUT could not keep the order against the plan: the BV gives way and stays out of the zone.
    SafetyYield,
    /// Yield, and the VUT has not been predicted to leave the zone: the BV waits before it.
    Waiting,
    /// The BV has passed its key point (or the VUT has left in rush): it just follows its reference.
    Passed,
    /// Inputs are stale: minimal-risk deceleration.
    Stale,
    /// Inputs are not finite or a solver failed: minimal-risk deceleration.
    Fallback,
}

/// How the regulator knows that τ is out of this VUT's reach.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum BelowReachCause {
    /// In this run: yield, and the VUT has stood before its zone for [`WAIT_BELOW_REACH_S`] while the
    /// BV was before its own — it waits for the BV, so it will not pass first.
    VutWaits,
    /// Earlier runs of this test against this VUT (the campaign memory, [`crate::campaign`]): the
    /// PET did not follow the aim.
    Campaign,
    /// Earlier runs of this test against this VUT: two runs in a row without a PET in the asked
    /// order.
    OrderRefused,
}

/// τ is out of this VUT's reach: what the regulator reports with its status.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BelowReach {
    /// What shows it.
    pub cause: BelowReachCause,
    /// The PET this VUT allows, as far as it is known, s (`None`: not known, or no PET in the
    /// asked order at all).
    pub pet_bound_s: Option<f64>,
}

/// Yield: how long the VUT must stand before the zone while the BV holds back before the
/// regulator reports the target out of reach ([`BelowReachCause::VutWaits`]), s.
pub const WAIT_BELOW_REACH_S: f64 = 3.0;

/// One decision.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Decision {
    /// What happened.
    pub status: RegulatorStatus,
    /// Acceleration to apply now, m/s² (finite, within the BV's limits).
    pub accel_mps2: f64,
    /// Speed the plan expects one step from now, m/s.
    pub next_speed_mps: f64,
    /// Planned key time, s from now.
    pub key_time_s: Option<f64>,
    /// Predicted PET if the plan is executed and the VUT responds as modelled, s.
    pub predicted_pet_s: Option<f64>,
    /// Slack of the leader's event, m.
    pub leader_slack_m: f64,
    /// Slack of the follower's order constraint in the safety check, m.
    pub follower_slack_m: f64,
    /// τ is out of this VUT's reach (with what shows it and the bound); `None`: nothing says so.
    /// It changes nothing in the plan: a report for the operator and the campaign.
    pub below_reach: Option<BelowReach>,
    /// How the VUT is identified to react to the BV so far this run (`None`: the follower does
    /// not react, [`RegulatorParams::reacting_follower`]).
    pub reaction: Option<Identified>,
}

/// The regulator of one BV: four QPs built once (follower with an upper or lower order
/// constraint, leader with an exact key time or a hold-back constraint).
#[derive(Debug)]
pub struct Regulator {
    params: RegulatorParams,
    follower_upper: LongitudinalQp,
    follower_lower: LongitudinalQp,
    leader_equal: LongitudinalQp,
    leader_upper: LongitudinalQp,
    /// Absolute time at which the VUT was seen leaving the zone.
    vut_exit_t_s: Option<f64>,
    /// Key time of the previous decision, absolute.
    last_key_t_s: Option<f64>,
    /// Absolute time at which the BV was seen leaving the zone.
    bv_exit_t_s: Option<f64>,
    /// The prior's timing along the BV's path (the realism term's reference).
    reference: ReferenceTiming,
    /// What earlier runs of this test showed ([`Regulator::set_known_below_reach`]).
    known_below_reach: Option<BelowReach>,
    /// Since when the regulator has been waiting for a VUT standing before the zone, absolute.
    waiting_since_t_s: Option<f64>,
    /// What this run has shown (kept until [`Regulator::reset`]).
    seen_below_reach: Option<BelowReach>,
    /// The lowest speed limit of the path between a rushing BV's commit station and its key
    /// point, this decision (infinite without limits), m/s.
    traverse_cap_mps: f64,
    /// How this VUT drove its route in earlier runs of the test ([`Regulator::set_route_speed`]).
    route_speed: Option<RouteSpeed>,
    /// How this VUT reacts to the BV, identified this run from the prior of earlier runs.
    belief: ReactionBelief,
}

/// What the realism term pulls toward in one decision: the reference's remaining time to the
/// BV's key point from where the BV is, and where the reference is in its own time now.
#[derive(Debug, Clone, Copy, PartialEq)]
struct RealismPull {
    /// The reference's time to the key point from the BV's current arc length, s.
    key_time_s: f64,
    /// The reference's own time at the BV's current arc length, s.
    now_ref_s: f64,
    /// Share of the realism term, `w_real / (w_adv + w_real)`.
    share: f64,
}

/// The leader's key time and the follower's predicted response to it.
#[derive(Debug, Clone, Copy)]
struct KeyTime {
    /// When the BV reaches its key point (the zone exit when it rushes, the entry when it yields),
    /// s from now.
    key_t: f64,
    /// When the VUT reaches the zone (rush) or leaves it (yield), s from now; `None`: never.
    t_vut: Option<f64>,
    /// Whether `t_vut` came from a follower solve whose order constraint did not bind (then the
    /// safety check need not solve again when its constraint cannot bind either).
    free_response: bool,
}

/// A rushing BV's plan to its commit station ([`Regulator::rush_commit`]).
#[derive(Debug, Clone, Copy)]
struct Commit {
    /// Where it commits, m.
    station_m: f64,
    /// How long it takes from there to its key point at the crossing speed, s.
    cross_s: f64,
    /// The crossing speed, m/s.
    speed_mps: f64,
}

/// The leader's objective `w_adv (PET − τ)² + w_real (T − T_ref)²` minimised over the key time T
/// in closed form: the adversarial key time `t_adv` pulled toward the reference's by its share.
fn pulled(realism: Option<RealismPull>, t_adv: f64) -> f64 {
    match realism {
        Some(r) => (1.0 - r.share) * t_adv + r.share * r.key_time_s,
        None => t_adv,
    }
}

/// When a plan (`s`, `v` every `dt`) reaches `station`: within the horizon as the plan says,
/// beyond it along the learned route speed from the plan's end ([`along_learned`]).
fn beyond_horizon(s: &[f64], v: &[f64], dt: f64, station: f64, learned: &RouteSpeed) -> Option<f64> {
    let (Some(&s_n), Some(&v_n)) = (s.last(), v.last()) else { return None };
    if s_n >= station {
        return crate::qp::time_at_station(s, v, dt, station);
    }
    along_learned(s.len().saturating_sub(1) as f64 * dt, s_n, v_n, station, learned)
}

/// When a VUT at `s0` driving the speeds `v_ref` (one per step of `dt`, from now) and then the
/// learned route speed reaches `station`: the follower's free motion itself, which its QP, with
/// its effort and jerk penalties, only smooths.
fn reference_time(s0: f64, v_ref: &[f64], dt: f64, station: f64, learned: &RouteSpeed) -> Option<f64> {
    let (mut at, mut last) = (s0, 0.0);
    if at >= station {
        return Some(0.0);
    }
    for (k, &v) in v_ref.iter().enumerate() {
        let next = at + v * dt;
        if next >= station {
            return Some((k as f64 + (station - at) / (v * dt)) * dt);
        }
        (at, last) = (next, v);
    }
    along_learned(v_ref.len() as f64 * dt, at, last, station, learned)
}

/// When a VUT at `from` at time `t0`, going on along the learned route speed, reaches `station`
/// (at `v_end` where nothing was learned; never if that is a standstill). Bounded by the grid.
fn along_learned(t0: f64, from: f64, v_end: f64, station: f64, learned: &RouteSpeed) -> Option<f64> {
    let (mut t, mut at) = (t0, from);
    while at < station {
        let next = ((at / learned.step_m).floor() + 1.0) * learned.step_m;
        let to = next.min(station);
        let speed = match (learned.speed_at(at), learned.speed_at(to)) {
            (Some(a), Some(b)) => 0.5 * (a + b),
            _ => return (v_end > 1e-3).then(|| t + (station - at) / v_end),
        };
        if speed <= 1e-3 {
            return None;
        }
        t += (to - at) / speed;
        at = to;
    }
    Some(t)
}

/// Whether every number of the input is finite.
fn inputs_finite(inp: &RegulatorInput) -> bool {
    [
        inp.t_s,
        inp.bv.s_m,
        inp.bv.v_mps,
        inp.bv.age_s,
        inp.vut.s_m,
        inp.vut.v_mps,
        inp.vut.age_s,
        inp.bv_accel_mps2,
        inp.zone_bv.enter_s_m,
        inp.zone_bv.exit_s_m,
        inp.zone_vut.enter_s_m,
        inp.zone_vut.exit_s_m,
        inp.reference_speed_mps,
    ]
    .iter()
    .all(|x| x.is_finite())
        && inp.stop_line_s_m.is_none_or(f64::is_finite)
}

const SLACK_TOL_M: f64 = 0.05;
/// A follower key time this far from its constraint's time means the constraint did not bind, s.
const BINDING_TOL_S: f64 = 0.05;
/// A rushing BV plans to its commit station only at an average speed of at least this share of
/// its crossing speed ([`Regulator::rush_commit`]).
const COMMIT_MIN_APPROACH_SHARE: f64 = 0.5;
/// The prior's acceleration shape ([`RegulatorParams::shape_share`]) fades out over this long
/// before the key time, s: without the fade, the cut-in's yield at τ 1.5 s landed 0.2 s short on
/// the tuning seeds (the last second of the plan is about the key time, not the prior's shape).
const SHAPE_FADE_S: f64 = 1.5;
/// A rushing BV inside a merge zone plans to leave it at no less than this speed, m/s.
const IN_ZONE_MIN_MPS: f64 = 2.0;
/// A rushing cut-in arrives at least this much faster than the VUT drives, m/s: a VUT that closes
/// in on the BV that just cut in brakes for it (car following), and the PET grows.
const MERGE_SPEED_MARGIN_MPS: f64 = 2.0;
/// How steeply the speed reference of a rushing cut-in ramps through its average, as a multiple
/// of the ramp that would end exactly at the arrival speed.
const MERGE_RAMP_GAIN: f64 = 2.5;
/// The key time the first decision of an interaction starts its fixed point from, s from now.
const FIRST_KEY_GUESS_S: f64 = 5.0;
/// A yielding BV this far past its zone's entry has only crept in (it still gives way to a VUT in
/// the zone); beyond it, it is committed and clears the zone, m.
const CREPT_IN_M: f64 = 1.0;
/// A VUT at or below this speed stands, m/s (the same threshold as "predicted never to leave").
const VUT_STANDING_MPS: f64 = 0.5;
/// How far behind the zone entry a BV already past its hold station stops when it must give way, m.
const HOLD_BACK_M: f64 = 0.5;
/// A BV this far past its hold station (a stop tracked late or noisily) still holds there, m.
pub const HOLD_CREEP_M: f64 = 1.0;
/// A plan that reaches the hold station this much before the VUT is predicted in its zone passes
/// it too early, s.
const HOLD_TOL_S: f64 = 0.05;
/// A reacting follower's predicted PET this near τ at the non-reacting key time changes nothing, s.
const REACT_TOL_S: f64 = 0.02;
/// Spacing of the key times a reacting follower is simulated against, s.
const REACT_SCAN_S: f64 = 0.25;
/// How many of them on each side of the non-reacting key time.
const REACT_SCAN_STEPS: usize = 8;
/// The most PET the leader counts on the VUT's predicted reaction for, as a share of τ.
const REACT_COUNT_SHARE: f64 = 0.2;
/// How much worse a key time 1 s farther from the non-reacting one counts, in s of PET error.
const REACT_SHIFT_COST: f64 = 0.05;
/// Bisection steps where the PET error changes sign.
const REACT_BISECT: usize = 5;

impl Regulator {
    /// Builds the solvers.
    pub fn new(params: RegulatorParams) -> Result<Self, QpError> {
        params.validate().map_err(|e| QpError::Shape(e.to_string()))?;
        let base = QpShape {
            horizon: params.horizon,
            dt_s: params.dt_s,
            w_speed: 1.0,
            w_accel: 1.0,
            w_jerk: 2.0,
            w_slack: 1e4,
            event: EventKind::Upper,
        };
        let leader = QpShape { w_speed: 0.2, w_accel: 1.0, w_jerk: params.w_jerk, ..base };
        Ok(Self {
            params,
            follower_upper: LongitudinalQp::new(base)?,
            follower_lower: LongitudinalQp::new(QpShape { event: EventKind::Lower, ..base })?,
            leader_equal: LongitudinalQp::new(QpShape { event: EventKind::Equal, ..leader })?,
            leader_upper: LongitudinalQp::new(QpShape { event: EventKind::Upper, ..leader })?,
            vut_exit_t_s: None,
            last_key_t_s: None,
            bv_exit_t_s: None,
            reference: ReferenceTiming::default(),
            known_below_reach: None,
            waiting_since_t_s: None,
            seen_below_reach: None,
            traverse_cap_mps: f64::INFINITY,
            route_speed: None,
            belief: ReactionBelief::default(),
        })
    }

    /// How this VUT drove its route in earlier runs of this test (the campaign memory's
    /// [`crate::campaign::CaseMemory::route_speed`]): the follower's free motion from then on (see
    /// [`crate::route_speed`]). `None`: the follower keeps the VUT's current speed. Like what
    /// earlier runs showed about reach, it outlives [`Self::reset`]. A refused record leaves the
    /// one before in place.
    pub fn set_route_speed(&mut self, learned: Option<RouteSpeed>) -> Result<(), ValidationError> {
        if let Some(r) = &learned {
            r.validate().map_err(|e| e.within("route_speed"))?;
        }
        self.route_speed = learned;
        Ok(())
    }

    /// The learned route speed in use.
    pub fn route_speed(&self) -> Option<&RouteSpeed> {
        self.route_speed.as_ref()
    }

    /// Sets the prior's timing along the BV's path (time since its start, arc length, speed), the
    /// reference of the realism term (`w_real`). Called once per prior, not per decision; a refused
    /// reference leaves the one before in place. Without one, the regulator decides as with
    /// `w_real = 0`.
    pub fn set_reference<I>(&mut self, samples: I) -> Result<(), ValidationError>
    where
        I: IntoIterator<Item = ReferenceSample>,
        I::IntoIter: Clone,
    {
        self.reference.set(samples)
    }

    /// The realism pull toward the reference for a BV at `s_m` whose key point is at `key_s_m`
    /// (`None` when `w_real = 0`, without a reference, or when the reference never gets there).
    fn realism_pull(&self, s_m: f64, key_s_m: f64) -> Option<RealismPull> {
        let w = self.params.w_real;
        if w <= 0.0 || !self.reference.is_set() {
            return None;
        }
        let now_ref_s = self.reference.time_at_station(s_m)?;
        let key_ref_s = self.reference.time_at_station(key_s_m)?;
        let key_time_s = (key_ref_s - now_ref_s).max(0.0);
        key_time_s.is_finite().then(|| RealismPull { key_time_s, now_ref_s, share: w / (self.params.w_adv + w) })
    }

    /// The settings.
    pub fn params(&self) -> &RegulatorParams {
        &self.params
    }

    /// Forgets what it remembered of the current interaction (call between runs). What earlier
    /// runs showed ([`Self::set_known_below_reach`]) stays.
    pub fn reset(&mut self) {
        self.vut_exit_t_s = None;
        self.last_key_t_s = None;
        self.bv_exit_t_s = None;
        self.waiting_since_t_s = None;
        self.seen_below_reach = None;
        self.belief.reset();
    }

    /// How earlier runs of this test identified this VUT's reaction (the campaign memory's
    /// [`crate::campaign::CaseMemory::reaction`]): the prior of this run's identification from now
    /// on (`None`: [`crate::reaction::DEFAULT_NONE_PRIOR`] on a VUT that does not react, the rest
    /// even). It starts the run's belief over. A refused posterior leaves the one before.
    pub fn set_reaction_prior(&mut self, prior: Option<&ReactionPosterior>) -> Result<(), ValidationError> {
        self.belief.set_prior(prior).map_err(|e| e.within("reaction"))
    }

    /// How this VUT is identified to react so far this run.
    pub fn reaction_belief(&self) -> &ReactionBelief {
        &self.belief
    }

    /// What earlier runs of this test against this VUT showed about reach (the campaign memory's
    /// verdict, [`crate::campaign::CaseMemory::below_reach`]): reported with every decision of the
    /// run until this run shows its own. It changes no plan.
    pub fn set_known_below_reach(&mut self, known: Option<BelowReach>) {
        self.known_below_reach = known;
    }

    /// Updates what this run shows about reach from one decision, and returns the report.
    fn watch_reach(&mut self, inp: &RegulatorInput) -> Option<BelowReach> {
        // Yield, both before their zones, the VUT standing: it waits for the BV (whatever the
        // status says: a measured speed that flickers just above zero gives a very late key time
        // rather than `Waiting`).
        let standing = inp.vut.v_mps.is_finite() && inp.vut.v_mps <= VUT_STANDING_MPS;
        let both_before = inp.vut.s_m < inp.zone_vut.enter_s_m && inp.bv.s_m < inp.zone_bv.enter_s_m;
        if inp.target.style() == Style::Yield && standing && both_before && inp.t_s.is_finite() {
            let since = *self.waiting_since_t_s.get_or_insert(inp.t_s);
            if inp.t_s - since >= WAIT_BELOW_REACH_S && self.seen_below_reach.is_none() {
                self.seen_below_reach = Some(BelowReach { cause: BelowReachCause::VutWaits, pet_bound_s: None });
            }
        } else {
            self.waiting_since_t_s = None;
        }
        self.seen_below_reach.or(self.known_below_reach)
    }

    fn fallback(&self, status: RegulatorStatus, v: f64) -> Decision {
        let v = if v.is_finite() { v.max(0.0) } else { 0.0 };
        let decel = self.params.fallback_decel_mps2.min(v / self.params.dt_s);
        Decision {
            status,
            accel_mps2: -decel,
            next_speed_mps: (v - decel * self.params.dt_s).max(0.0),
            key_time_s: None,
            predicted_pet_s: None,
            leader_slack_m: 0.0,
            follower_slack_m: 0.0,
            below_reach: None,
            reaction: None,
        }
    }

    fn qp_input(&self, inp: &RegulatorInput, lim: &Limits, event: Option<(f64, f64)>) -> QpInput {
        let (s, v, a_prev) = (inp.bv.s_m, inp.bv.v_mps, inp.bv_accel_mps2);
        QpInput {
            s0_m: s,
            v0_mps: v.clamp(0.0, lim.max_speed_mps),
            a_prev_mps2: a_prev.clamp(-lim.max_decel_mps2, lim.max_accel_mps2),
            v_max_mps: lim.max_speed_mps,
            a_max_mps2: lim.max_accel_mps2,
            d_max_mps2: lim.max_decel_mps2,
            event_t_s: event.map(|e| e.0),
            event_station_m: event.map_or(0.0, |e| e.1),
        }
    }

    /// Solves the follower against the BV key time `key_t` (relative; `None`: unconstrained) and
    /// returns its own key time and the slack of its order constraint.
    fn follower(&mut self, inp: &RegulatorInput, key_t: Option<f64>) -> Option<(Option<f64>, f64)> {
        let vut = inp.vut;
        let lim = self.params.vut;
        let (qp, station, probe) = match inp.target.style() {
            // Not in the zone before the BV is out: s_V(T) ≤ entry.
            Style::Rush => (&mut self.follower_upper, inp.zone_vut.enter_s_m, inp.zone_vut.enter_s_m),
            // Out of the zone before the BV comes: s_V(T) ≥ exit.
            Style::Yield => (&mut self.follower_lower, inp.zone_vut.exit_s_m, inp.zone_vut.exit_s_m),
        };
        let v_track = vut.v_mps.clamp(0.0, lim.max_speed_mps);
        // With a learned route speed, the VUT is predicted to drive its route as it did before,
        // its deviation from that now fading; a standing VUT keeps standing.
        let learned = self.route_speed.as_ref().filter(|_| v_track > VUT_STANDING_MPS);
        match learned.and_then(|r| Some((r, r.speed_at(vut.s_m)?))) {
            Some((r, here)) => {
                let (dt, deviation) = (self.params.dt_s, v_track - here);
                let mut s = vut.s_m;
                let mut last = here;
                for (k, v) in qp.v_ref_mut().iter_mut().enumerate() {
                    last = r.speed_at(s).unwrap_or(last);
                    let fade = (-((k + 1) as f64) * dt / DEVIATION_FADE_S).exp();
                    *v = (last + deviation * fade).clamp(0.0, lim.max_speed_mps);
                    s += *v * dt;
                }
            }
            None => qp.v_ref_mut().iter_mut().for_each(|v| *v = v_track),
        }
        let input = QpInput {
            s0_m: vut.s_m,
            v0_mps: v_track,
            a_prev_mps2: 0.0,
            v_max_mps: lim.max_speed_mps,
            a_max_mps2: lim.max_accel_mps2,
            d_max_mps2: lim.max_decel_mps2,
            event_t_s: key_t.map(|t| t.max(0.0)),
            event_station_m: station,
        };
        if qp.solve(&input) == QpStatus::Failed {
            return None;
        }
        let t = match learned {
            // Beyond the horizon the VUT drives on as learned, not at its terminal speed; and it
            // comes no sooner than its free motion says (the plan smooths its slowdown).
            Some(r) => {
                let dt = self.params.dt_s;
                let planned = beyond_horizon(qp.station(), qp.speed(), dt, probe, r);
                let free = reference_time(vut.s_m, qp.v_ref(), dt, probe, r);
                match (planned, free) {
                    (Some(p), Some(f)) => Some(p.max(f)),
                    _ => None,
                }
            }
            None => qp.time_at_station(probe),
        };
        Some((t, qp.slack_m()))
    }

    /// Plans the BV to be at `station` exactly at `key_t` (relative); returns the status of the solve.
    ///
    /// With a key time the speed reference is the average speed that gets there on time: tracking
    /// the prior's speed as it is would make the plan hurry to the station within the horizon and
    /// stop there, pushing the waiting past the horizon (the time inconsistency of the literal
    /// formulation). With the realism term, that average is blended (by the term's share) with the
    /// prior's own speed profile from where the BV is, *time-warped* so that it too reaches the
    /// station exactly at `key_t`: the prior's shape (where it accelerates, where it eases off) at
    /// the timing the game chose. Without a key time it is the prior's reference speed.
    fn lead(
        &mut self,
        inp: &RegulatorInput,
        key_t: Option<f64>,
        station: f64,
        realism: Option<RealismPull>,
        then_mps: Option<f64>,
    ) -> QpStatus {
        let qin = self.qp_input(inp, &self.params.bv, key_t.map(|t| (t, station)));
        let v_max = self.params.bv.max_speed_mps;
        let (dt, v_ref) = (self.params.dt_s, inp.reference_speed_mps.clamp(0.0, v_max));
        match key_t {
            Some(t) if t > dt => {
                let v_avg = ((station - inp.bv.s_m) / t).clamp(0.0, v_max);
                // A rushing cut-in must arrive fast enough that the VUT, keeping its headway behind
                // it, does not brake before reaching the encroachment point: the BV's rear must be
                // `h · v_VUT` ahead within τ, so its speed there should reach `h · v_VUT / τ`, and
                // never below the VUT's own speed plus a margin (a VUT closing in brakes too). The
                // reference ramps through the average so the key time stays the same; it overshoots
                // the arrival speed by `MERGE_RAMP_GAIN`, because the plan follows its reference
                // loosely (speed weight 0.2 against effort and jerk) and would arrive well below it.
                let v_arrive = if inp.target.style() == Style::Rush && inp.zone_kind == ConflictKind::Merge {
                    (self.params.vut_headway_s * inp.vut.v_mps / inp.target.tau_s())
                        .max(inp.vut.v_mps + MERGE_SPEED_MARGIN_MPS)
                        .clamp(v_avg, v_max)
                } else {
                    v_avg
                };
                let ramp = if v_arrive > v_avg { MERGE_RAMP_GAIN * (v_arrive - v_avg) } else { 0.0 };
                // The prior's time per plan second: it reaches the station in `key_time_s` of its
                // own time, the plan in `t`; its speeds scale by the same ratio.
                let warp = realism.filter(|r| r.key_time_s > 0.0).map(|r| (r, r.key_time_s / t));
                let reference = &self.reference;
                // The prior's acceleration at the same warp, step by step (its speeds scale by the
                // ratio, its time by the inverse: its accelerations by the ratio squared), as the
                // shape the plan's jerk is counted against; it fades out before the key time.
                let shape = self.params.shape_share;
                let warped = |t_k: f64| {
                    warp.map_or(0.0, |(r, ratio)| ratio * reference.speed_at_time(r.now_ref_s + t_k * ratio))
                };
                for (k, a) in self.leader_equal.a_ref_mut().iter_mut().enumerate() {
                    let t_k = k as f64 * dt;
                    let fade = ((t - t_k) / SHAPE_FADE_S).clamp(0.0, 1.0);
                    *a = if shape > 0.0 && warp.is_some() {
                        shape * fade * (warped(t_k + dt) - warped(t_k)) / dt
                    } else {
                        0.0
                    };
                }
                for (k, v) in self.leader_equal.v_ref_mut().iter_mut().enumerate() {
                    let t_k = (k + 1) as f64 * dt;
                    let frac = (t_k / t).min(1.0);
                    let adversarial = match then_mps {
                        Some(v_then) if t_k > t => v_then,
                        _ => v_avg + ramp * (2.0 * frac - 1.0),
                    };
                    let blended = match warp {
                        Some((r, ratio)) => {
                            let prior = ratio * reference.speed_at_time(r.now_ref_s + t_k * ratio);
                            (1.0 - r.share) * adversarial + r.share * prior
                        }
                        None => adversarial,
                    };
                    *v = blended.clamp(0.0, v_max);
                }
            }
            _ => {
                self.leader_equal.v_ref_mut().iter_mut().for_each(|v| *v = v_ref);
                self.leader_equal.a_ref_mut().iter_mut().for_each(|a| *a = 0.0);
            }
        }
        self.leader_equal.solve(&qin)
    }

    /// Rushing across a crossing with time to spare: the BV slows *before* it commits and
    /// crosses at the speed it would drive there, so it is not seen creeping through the junction
    /// (a VUT that sees a car slow in the junction waits for it). With the key point `bv_key` at
    /// `key_t` (s from now), the plan goes to the commit station instead, reaching it
    /// [`Commit::cross_s`] before the key time, and then tracks the crossing speed (the reference
    /// speed within the path's limits between the two). `None` when the average speed to the key
    /// point is not below that speed (no time to spare), when the approach would be slower than
    /// [`COMMIT_MIN_APPROACH_SHARE`] of the crossing speed, past the commit station, or not a
    /// rushing BV at a crossing.
    fn rush_commit(&self, inp: &RegulatorInput, bv_key: f64, key_t: f64) -> Option<Commit> {
        if inp.target.style() != Style::Rush || inp.zone_kind != ConflictKind::Crossing {
            return None;
        }
        let station_m = Self::rush_commit_station(inp);
        let speed_mps = inp.reference_speed_mps.min(self.traverse_cap_mps).min(self.params.bv.max_speed_mps);
        let (approach, cross) = (station_m - inp.bv.s_m, bv_key - station_m);
        if approach <= 0.0
            || cross <= 0.0
            || speed_mps <= 0.0
            || key_t <= 0.0
            || (bv_key - inp.bv.s_m) / key_t >= speed_mps
        {
            return None;
        }
        let cross_s = cross / speed_mps;
        let t_commit = key_t - cross_s;
        // Not to a crawl: a BV that would have to all but stop before the junction to let the
        // time pass (a VUT that slows down for it) keeps rolling on instead.
        let slow = approach < COMMIT_MIN_APPROACH_SHARE * speed_mps * t_commit;
        (t_commit > self.params.dt_s && !slow).then_some(Commit { station_m, cross_s, speed_mps })
    }

    /// Where the BV stands when it gives way: [`hold_station`], when it is
    /// [`Self::within_reach`].
    fn hold_station(&self, inp: &RegulatorInput) -> f64 {
        self.within_reach(inp, hold_station(inp.stop_line_s_m, inp.zone_bv.enter_s_m))
    }

    /// `station`, when the BV can still stop there at the share [`crate::qp::CAP_DECEL_SHARE`]
    /// of its deceleration (or has crept past it by at most [`HOLD_CREEP_M`]); else
    /// [`HOLD_BACK_M`] before the zone.
    fn within_reach(&self, inp: &RegulatorInput, station: f64) -> f64 {
        let v = inp.bv.v_mps.max(0.0);
        let stopping = v * v / (2.0 * crate::qp::CAP_DECEL_SHARE * self.params.bv.max_decel_mps2);
        if inp.bv.s_m + stopping <= station + HOLD_CREEP_M { station } else { inp.zone_bv.enter_s_m - HOLD_BACK_M }
    }

    /// Plans the BV to stay behind `station` until `until_t` (relative), tracking its reference
    /// speed — or, with `arrive = Some(v)`, a reference that slows from the BV's speed now at the
    /// comfortable deceleration (`fallback_decel_mps2`) to the speed at most `v` that then reaches
    /// the station just at `until_t`, or, when even a stop at that deceleration would pass it,
    /// evenly to a stop there: a driver who gives way slows early and visibly, not at the last
    /// moment.
    fn hold_back(&mut self, inp: &RegulatorInput, station: f64, until_t: f64, arrive: Option<f64>) -> QpStatus {
        let qin = self.qp_input(inp, &self.params.bv, Some((until_t, station)));
        let (v_max, dt) = (self.params.bv.max_speed_mps, self.params.dt_s);
        let v_ref = inp.reference_speed_mps.clamp(0.0, v_max);
        let (v0, gap, t) = (qin.v0_mps, (station - inp.bv.s_m).max(0.0), until_t.max(dt));
        // Slowing at b from v0 to v_end, then keeping v_end, covers the gap in t when
        // (v0 − v_end)² / 2b + v_end t = gap.
        let b = self.params.fallback_decel_mps2;
        let disc = b * b * t * t - 2.0 * b * t * v0 + 2.0 * b * gap;
        let cruise = (disc >= 0.0).then(|| v0 - b * t + disc.sqrt()).filter(|v| (0.0..=v0).contains(v));
        let (decel, floor) = match (arrive, cruise) {
            (Some(v), Some(c)) => (b, c.min(v).max(0.0)),
            _ => (if gap > 0.0 { (v0 * v0 / (2.0 * gap)).max(b) } else { self.params.bv.max_decel_mps2 }, 0.0),
        };
        for (k, v) in self.leader_upper.v_ref_mut().iter_mut().enumerate() {
            *v = match arrive {
                Some(_) => (v0 - decel * (k + 1) as f64 * dt).max(floor).clamp(0.0, v_max),
                None => v_ref,
            };
        }
        self.leader_upper.solve(&qin)
    }

    fn decision_from(
        &self,
        qp: &LongitudinalQp,
        status: RegulatorStatus,
        key: Option<f64>,
        pet: Option<f64>,
        fslack: f64,
    ) -> Decision {
        let lim = &self.params.bv;
        let a = qp.accel().first().copied().unwrap_or(0.0);
        let v1 = qp.speed().get(1).copied().unwrap_or(0.0);
        Decision {
            status,
            accel_mps2: if a.is_finite() {
                a.clamp(-lim.max_decel_mps2, lim.max_accel_mps2)
            } else {
                -self.params.fallback_decel_mps2
            },
            next_speed_mps: if v1.is_finite() { v1.max(0.0) } else { 0.0 },
            key_time_s: key,
            predicted_pet_s: pet,
            leader_slack_m: qp.slack_m(),
            follower_slack_m: fslack,
            below_reach: None,
            reaction: None,
        }
    }

    /// One decision.
    pub fn decide(&mut self, inp: &RegulatorInput) -> Decision {
        self.set_caps(inp, None);
        self.observe(inp);
        let mut d = self.decide_capped(inp);
        d.below_reach = self.watch_reach(inp);
        d.reaction = self.params.reacting_follower.then(|| self.belief.identified());
        d
    }

    /// [`Self::decide`] for a BV whose path limits its speed: `speed_limit_at(s)` is the highest
    /// speed at arc length `s` (curves, [`v2t_model::driving::curve_speed`]). Step `k` of the plan is capped by
    /// the lowest limit the BV could reach by then (from its speed at full acceleration):
    /// conservative, and never infeasible (the cap is approached at a bounded deceleration).
    pub fn decide_on_path(&mut self, inp: &RegulatorInput, speed_limit_at: &dyn Fn(f64) -> f64) -> Decision {
        self.set_caps(inp, Some(speed_limit_at));
        self.observe(inp);
        let mut d = self.decide_capped(inp);
        d.below_reach = self.watch_reach(inp);
        d.reaction = self.params.reacting_follower.then(|| self.belief.identified());
        d
    }

    /// What the VUT knows of the scene, for its reaction model.
    fn scene(&self, inp: &RegulatorInput) -> Scene {
        Scene {
            zone_bv: inp.zone_bv,
            zone_vut: inp.zone_vut,
            vut_accel_mps2: self.params.vut.max_accel_mps2,
            vut_decel_mps2: self.params.vut.max_decel_mps2,
        }
    }

    /// Identification: one measurement into the belief of how the VUT reacts (fresh inputs only).
    fn observe(&mut self, inp: &RegulatorInput) {
        let fresh = inp.bv.age_s <= self.params.max_input_age_s && inp.vut.age_s <= self.params.max_input_age_s;
        if !self.params.reacting_follower || !fresh || inp.zone_kind != ConflictKind::Crossing {
            return;
        }
        let snap =
            Snapshot { bv_s_m: inp.bv.s_m, bv_v_mps: inp.bv.v_mps, vut_s_m: inp.vut.s_m, vut_v_mps: inp.vut.v_mps };
        let scene = self.scene(inp);
        let free = self.route_speed.as_ref().map(|r| r as &dyn FreeSpeed);
        self.belief.observe(inp.t_s, snap, &scene, free);
    }

    /// The accelerations decision `d` (the last one this regulator made) plans, one per step of
    /// [`RegulatorParams::dt_s`] over the horizon: what a regulator in the cloud sends a BV to
    /// track. `None` for a stale or fallback decision (the minimal-risk deceleration).
    pub fn planned_accels(&self, d: &Decision) -> Option<&[f64]> {
        match d.status {
            RegulatorStatus::Regulating | RegulatorStatus::Degraded | RegulatorStatus::Passed => {
                Some(self.leader_equal.accel())
            }
            RegulatorStatus::SafetyYield | RegulatorStatus::Waiting => Some(self.leader_upper.accel()),
            RegulatorStatus::Stale | RegulatorStatus::Fallback => None,
        }
    }

    /// Writes the leader plans' per-step speed caps (no allocation).
    fn set_caps(&mut self, inp: &RegulatorInput, speed_limit_at: Option<&dyn Fn(f64) -> f64>) {
        self.traverse_cap_mps = f64::INFINITY;
        if let Some(limit) = speed_limit_at
            && inp.target.style() == Style::Rush
            && inp.zone_kind == ConflictKind::Crossing
        {
            let (from, to) = (Self::rush_commit_station(inp).max(inp.bv.s_m), inp.zone_bv.exit_s_m);
            if from.is_finite() && to.is_finite() {
                let mut s = from;
                while s <= to.min(from + CAP_SCAN_MAX_M) {
                    let v = limit(s);
                    if v >= 0.0 && v < self.traverse_cap_mps {
                        self.traverse_cap_mps = v;
                    }
                    s += 1.0;
                }
            }
        }
        let (dt, a_max) = (self.params.dt_s, self.params.bv.max_accel_mps2);
        let brake = CURVE_BRAKE_SHARE * self.params.bv.max_decel_mps2;
        let (s0, v0) = (inp.bv.s_m, inp.bv.v_mps.max(0.0));
        let upper = self.leader_upper.v_cap_mut();
        let caps = self.leader_equal.v_cap_mut().iter_mut().zip(upper.iter_mut());
        let Some(limit) = speed_limit_at.filter(|_| s0.is_finite()) else {
            caps.for_each(|(c, u)| (*c, *u) = (f64::INFINITY, f64::INFINITY));
            return;
        };
        // The limits every metre ahead, as far as the BV can get within the horizon and then brake
        // from its top speed, and their braking envelope (the fastest the BV may be at each metre
        // and still slow down to every limit after it at `brake`).
        let horizon_t = self.params.horizon as f64 * dt;
        let stop_m = self.params.bv.max_speed_mps.powi(2) / (2.0 * brake);
        let far = (v0 * horizon_t + 0.5 * a_max * horizon_t * horizon_t + stop_m).min(CAP_SCAN_MAX_M);
        let n = (far.ceil() as usize + 1).min(CAP_GRID);
        let mut envelope = [f64::INFINITY; CAP_GRID];
        for (i, e) in envelope.iter_mut().enumerate().take(n) {
            let v = limit(s0 + i as f64);
            *e = if v >= 0.0 { v } else { f64::INFINITY };
        }
        if let Some(ahead) = envelope.get_mut(..n) {
            v2t_model::driving::braking_envelope(ahead, 1.0, brake);
        }
        // At step k the BV is at most `reach` ahead: no faster than the envelope anywhere up to
        // there (every limit it may have reached, and a curve beyond still to be braked for),
        // less the speed its last request still adds when it is speeding up (the actuator
        // follows `accel_latency_s` late: a plan that stops accelerating at the cap overshoots it).
        let gaining = self.params.accel_latency_s * inp.bv_accel_mps2.max(0.0);
        let (mut cap, mut scanned) = (f64::INFINITY, 0usize);
        for (k, (c, u)) in caps.enumerate() {
            let t = (k + 1) as f64 * dt;
            let reach = (v0 * t + 0.5 * a_max * t * t).min(CAP_SCAN_MAX_M);
            let at = (reach.ceil() as usize).min(n.saturating_sub(1));
            while scanned <= at {
                cap = cap.min(envelope.get(scanned).copied().unwrap_or(f64::INFINITY));
                scanned += 1;
            }
            *c = (cap - gaining).max(0.0);
            *u = *c;
        }
    }

    fn decide_capped(&mut self, inp: &RegulatorInput) -> Decision {
        if !inputs_finite(inp) {
            return self.fallback(RegulatorStatus::Fallback, inp.bv.v_mps);
        }
        if inp.bv.age_s > self.params.max_input_age_s || inp.vut.age_s > self.params.max_input_age_s {
            return self.fallback(RegulatorStatus::Stale, inp.bv.v_mps);
        }
        self.note_exits(inp);
        let bv_key = match inp.target.style() {
            Style::Rush => inp.zone_bv.exit_s_m,
            Style::Yield => inp.zone_bv.enter_s_m,
        };
        if let Some(d) = self.outside_interaction(inp, bv_key) {
            return d;
        }
        self.regulate(inp, bv_key)
    }

    /// Remembers when each vehicle was first seen out of its zone.
    fn note_exits(&mut self, inp: &RegulatorInput) {
        if inp.vut.s_m >= inp.zone_vut.exit_s_m && self.vut_exit_t_s.is_none() {
            // Seen out at this cycle: it left between cycles. Back-date the exit by the distance
            // beyond it at the measured speed (at most one step), so the yield target carries no
            // bias of half a control period.
            let beyond_s = (inp.vut.s_m - inp.zone_vut.exit_s_m) / inp.vut.v_mps.max(0.1);
            self.vut_exit_t_s = Some(inp.t_s - beyond_s.min(self.params.dt_s));
        }
        if inp.bv.s_m >= inp.zone_bv.exit_s_m && self.bv_exit_t_s.is_none() {
            let beyond_s = (inp.bv.s_m - inp.zone_bv.exit_s_m) / inp.bv.v_mps.max(0.1);
            self.bv_exit_t_s = Some(inp.t_s - beyond_s.min(self.params.dt_s));
        }
    }

    /// The decision when there is nothing to regulate (the BV is past the interaction) or the BV
    /// must give way whatever the target (the VUT is in the zone before it); `None` otherwise.
    fn outside_interaction(&mut self, inp: &RegulatorInput, bv_key: f64) -> Option<Decision> {
        let vut_gone = inp.vut.s_m >= inp.zone_vut.exit_s_m;
        // Yielding at a crossing, the BV has crept over its entry (a plan that holds it just
        // before the zone, tracked late or noisily) while the VUT has yet to leave the zone: it is
        // not past anything — give way until the VUT has left, never drive on across its path.
        if inp.target.style() == Style::Yield
            && inp.zone_kind == ConflictKind::Crossing
            && inp.bv.s_m >= inp.zone_bv.enter_s_m
            && inp.bv.s_m < inp.zone_bv.enter_s_m + CREPT_IN_M
            && !vut_gone
        {
            return Some(self.give_way(inp));
        }
        // Past the interaction: follow the reference.
        if inp.bv.s_m >= bv_key
            || (inp.target.style() == Style::Rush && vut_gone)
            || (inp.target.style() == Style::Yield && inp.bv.s_m >= inp.zone_bv.enter_s_m)
        {
            let after = self.after_merge(inp);
            return Some(match self.lead(&after, None, 0.0, None, None) {
                QpStatus::Failed => self.fallback(RegulatorStatus::Fallback, inp.bv.v_mps),
                _ => self.decision_from(&self.leader_equal, RegulatorStatus::Passed, None, None, 0.0),
            });
        }
        // Rush, but the VUT is already in the zone: give way until it has left.
        if inp.target.style() == Style::Rush && inp.vut.s_m >= inp.zone_vut.enter_s_m {
            return Some(self.give_way(inp));
        }
        None
    }

    /// The regulated decision before the zone: the leader's key time against the follower's
    /// response (steps 1–2), the plan that meets it (3) and the safety check of that plan (4).
    fn regulate(&mut self, inp: &RegulatorInput, bv_key: f64) -> Decision {
        let tau = inp.target.tau_s();
        let realism = self.realism_pull(inp.bv.s_m, bv_key);
        let Some(KeyTime { mut key_t, t_vut, free_response }) = self.key_time(inp, realism) else {
            return self.fallback(RegulatorStatus::Fallback, inp.bv.v_mps);
        };
        let Some(t_v) = t_vut else {
            // The VUT is predicted never to reach (rush) or leave (yield) the zone.
            return match inp.target.style() {
                // Rush with a VUT that stays away: nothing to regulate against; go at the reference.
                Style::Rush => match self.lead(inp, None, 0.0, None, None) {
                    QpStatus::Failed => self.fallback(RegulatorStatus::Fallback, inp.bv.v_mps),
                    _ => self.decision_from(&self.leader_equal, RegulatorStatus::Regulating, None, None, 0.0),
                },
                Style::Yield => self.wait(inp),
            };
        };
        // Yield at a crossing, until the VUT has left the zone: the BV waits before its stop line
        // until the VUT is predicted in the zone (it has committed), then at least the clearance
        // before the zone until the VUT is predicted out of it.
        let mut hold_until: Option<(f64, f64)> = None;
        if inp.target.style() == Style::Yield {
            key_t = pulled(realism, t_v + tau).max(t_v + self.params.safety_margin_s).max(0.0);
            if inp.zone_kind == ConflictKind::Crossing && self.vut_exit_t_s.is_none() {
                hold_until = if inp.vut.s_m < inp.zone_vut.enter_s_m {
                    let t_in = self.follower_lower.time_at_station(inp.zone_vut.enter_s_m);
                    t_in.map(|t| (self.hold_station(inp), t))
                } else {
                    Some((self.within_reach(inp, inp.zone_bv.enter_s_m - HOLD_CLEARANCE_M), t_v))
                };
            }
        }

        // Rushing and inside the zone: clear it, never slow down in it for a VUT that comes later
        // than predicted. In a merge the VUT follows the BV from here on: a BV that slows in front
        // of it brakes it more, which only makes the PET longer still. At a crossing, a VUT that
        // waits to turn (or brakes for a car in its path) waits for as long as it sees the BV
        // slowing in there; and a car that dawdles in another's path is not one to put on a track.
        if inp.target.style() == Style::Rush && inp.bv.s_m >= inp.zone_bv.enter_s_m {
            key_t = key_t.min((bv_key - inp.bv.s_m) / inp.bv.v_mps.max(IN_ZONE_MIN_MPS));
        }
        let d = self.checked_plan(inp, bv_key, realism, key_t, t_v, free_response);
        match (d.status, hold_until) {
            (RegulatorStatus::Regulating | RegulatorStatus::Degraded, Some((station, until))) => {
                let early = inp.bv.s_m <= station + HOLD_CREEP_M
                    && self.leader_equal.time_at_station(station).is_some_and(|t| t < until - HOLD_TOL_S);
                if early { self.hold_until(inp, station, until, d) } else { d }
            }
            _ => d,
        }
    }

    /// Where a rushing BV commits at a crossing ([`Self::rush_commit`]): where its front enters
    /// the junction (its stop line plus [`STOP_LINE_MARGIN_M`]); without a stop line, or in a
    /// merge, its zone entry.
    fn rush_commit_station(inp: &RegulatorInput) -> f64 {
        let enter = inp.zone_bv.enter_s_m;
        match (inp.zone_kind, inp.stop_line_s_m) {
            (ConflictKind::Crossing, Some(line)) => (line + STOP_LINE_MARGIN_M).min(enter),
            _ => enter,
        }
    }

    /// Yield at a crossing: the plan `planned` would pass `station` before `until` (s from now):
    /// the stop line before the VUT is in its zone, or the clearance before the zone before the
    /// VUT has left it. A driver who gives way waits before the junction until the other has
    /// committed, and keeps clear of its path while it passes: the BV holds there until then
    /// (`Waiting`, with the key time it aims at kept for the next decision).
    fn hold_until(&mut self, inp: &RegulatorInput, station: f64, until: f64, planned: Decision) -> Decision {
        // It reaches the station just then, at the average speed that then takes it to its zone
        // at the key time it aims at.
        let arrive = planned
            .key_time_s
            .filter(|k| *k > until + self.params.dt_s)
            .map_or(0.0, |k| (inp.zone_bv.enter_s_m - station) / (k - until))
            .min(inp.reference_speed_mps);
        match self.hold_back(inp, station, until, Some(arrive)) {
            QpStatus::Failed => self.fallback(RegulatorStatus::Fallback, inp.bv.v_mps),
            _ => Decision {
                key_time_s: planned.key_time_s,
                ..self.decision_from(&self.leader_upper, RegulatorStatus::Waiting, None, None, 0.0)
            },
        }
    }

    /// Steps 1–2: the follower's response and the leader's key time (a fixed-point step); `None`
    /// when a follower solve fails.
    fn key_time(&mut self, inp: &RegulatorInput, realism: Option<RealismPull>) -> Option<KeyTime> {
        let tau = inp.target.tau_s();
        let mut key_t = self.last_key_t_s.map_or(FIRST_KEY_GUESS_S, |t| t - inp.t_s).max(0.0);
        if inp.target.style() == Style::Yield
            && let Some(t_exit) = self.vut_exit_t_s
        {
            return Some(KeyTime { key_t, t_vut: Some(t_exit - inp.t_s), free_response: true });
        }
        let mut t_vut: Option<f64> = None;
        let mut free_response = false;
        // Rush: the VUT's best response to the BV's key time (it may have to wait for the BV).
        // Yield: the BV is the one that gives way, so the VUT is predicted unconstrained.
        for _ in 0..2 {
            let order = (inp.target.style() == Style::Rush).then_some(key_t);
            let (t_v, _) = self.follower(inp, order)?;
            t_vut = t_v;
            let Some(tv) = t_v else { break };
            if inp.target.style() == Style::Yield {
                free_response = true;
                break;
            }
            free_response = tv > key_t + BINDING_TOL_S;
            let next = pulled(realism, tv - tau).max(0.0);
            // The response only moves when the order constraint binds; if the VUT's entry is
            // after the new key time too, the fixed point is reached.
            let settled = tv >= next.max(key_t);
            key_t = next;
            if settled {
                break;
            }
        }
        Some(self.reacted(inp, realism, KeyTime { key_t, t_vut, free_response }))
    }

    /// Step 1 with a reacting follower: when the belief's most probable VUT reacts to the BV
    /// ([`crate::reaction`]), the key time whose predicted PET is nearest τ once that reaction is
    /// added to the follower's response. The reaction is simulated against the BV's motion to
    /// each candidate key time ([`BvMotion`], through its commit station when it rushes there),
    /// and the delay it predicts over the same free motion without reaction is added to the
    /// follower's time. Candidates every [`REACT_SCAN_S`] within [`REACT_SCAN_STEPS`] of the
    /// non-reacting answer (on the side that leaves the VUT less room, within
    /// [`REACT_COUNT_SHARE`] of τ), then bisection where the error changes sign nearest to it.
    fn reacted(&self, inp: &RegulatorInput, realism: Option<RealismPull>, kt: KeyTime) -> KeyTime {
        if !self.params.reacting_follower
            || inp.zone_kind != ConflictKind::Crossing
            || inp.vut.s_m >= inp.zone_vut.enter_s_m
        {
            return kt;
        }
        let Some(t_f) = kt.t_vut else { return kt };
        let Some(reaction) = self.belief.identified().reaction else { return kt };
        let rush = inp.target.style() == Style::Rush;
        let tau = inp.target.tau_s();
        let (bv_key, probe) = if rush {
            (inp.zone_bv.exit_s_m, inp.zone_vut.enter_s_m)
        } else {
            (inp.zone_bv.enter_s_m, inp.zone_vut.exit_s_m)
        };
        let scene = self.scene(inp);
        let constant = Constant(inp.vut.v_mps.max(self.belief.top_speed_mps()));
        let free: &dyn FreeSpeed = match &self.route_speed {
            Some(r) => r,
            None => &constant,
        };
        let vut = (inp.vut.s_m, inp.vut.v_mps);
        let d_bv = bv_key - inp.bv.s_m;
        let motion = |t: f64| match self.rush_commit(inp, bv_key, t) {
            Some(c) => BvMotion::new(inp.bv.s_m, inp.bv.v_mps, t - c.cross_s, c.station_m, c.speed_mps),
            None => {
                let v_end = (2.0 * d_bv / t - inp.bv.v_mps).max(d_bv / t);
                BvMotion::new(inp.bv.s_m, inp.bv.v_mps, t, bv_key, v_end)
            }
        };
        let Some(free_t) = rollout(None, &scene, &motion(1.0), vut, free, constant.0, probe) else { return kt };
        let base = if kt.free_response { t_f } else { free_t };
        let t_min = (d_bv / self.params.bv.max_speed_mps).max(self.params.dt_s);
        // The VUT's time for key time `t`, and the PET error.
        let response = |t: f64| -> Option<(f64, f64)> {
            let t_h = rollout(Some(&reaction), &scene, &motion(t), vut, free, constant.0, probe)?;
            let t_v = t_f.max(base + (t_h - free_t).max(0.0));
            let pet = if rush { t_v - t } else { t - t_v };
            Some((t_v, pet - tau))
        };
        let t0 = if rush { t_f - tau } else { t_f + tau }.max(t_min);
        let Some((tv0, e0)) = response(t0) else { return kt };
        if e0.abs() <= REACT_TOL_S {
            return kt;
        }
        // Scan outward from t0; keep the nearest sign change, else the smallest error, counting a
        // key time farther from t0 as worse by `REACT_SHIFT_COST` per second (where the error is
        // flat, the BV does not move its key time for nothing).
        let cost = |t: f64, e: f64| e.abs() + REACT_SHIFT_COST * (t - t0).abs();
        let mut best = (t0, tv0, e0);
        let mut bracket: Option<(f64, f64, f64)> = None;
        // The last candidate on each side: below t0, above t0 (`None` once a side is out of range).
        // On the side that leaves the VUT less room (a rushing BV later, a yielding one earlier)
        // the leader counts on the VUT's predicted reaction to make the PET: a VUT that does not
        // react after all meets a PET shorter than τ by as much. It counts on it for at most
        // `REACT_COUNT_SHARE` of τ.
        let count_s = REACT_COUNT_SHARE * tau;
        let mut sides = [Some((t0, e0)), Some((t0, e0))];
        'scan: for j in 1..=REACT_SCAN_STEPS {
            for (side, dir) in sides.iter_mut().zip([-1.0, 1.0]) {
                let Some((t_in, e_in)) = *side else { continue };
                let t_out = t0 + dir * j as f64 * REACT_SCAN_S;
                let counts_on_it = if rush { t_out - t0 } else { t0 - t_out };
                let t_out = if counts_on_it > count_s { t0 + dir * count_s } else { t_out };
                let last = counts_on_it >= count_s;
                let Some((tv, e)) = (t_out >= t_min).then(|| response(t_out)).flatten() else {
                    *side = None;
                    continue;
                };
                if cost(t_out, e) < cost(best.0, best.2) {
                    best = (t_out, tv, e);
                }
                if e_in.signum() != e.signum() {
                    bracket = Some((t_in, e_in, t_out));
                    break 'scan;
                }
                *side = (!last).then_some((t_out, e));
            }
        }
        if let Some((mut a, ea, mut b)) = bracket {
            for _ in 0..REACT_BISECT {
                let m = 0.5 * (a + b);
                let Some((tv, e)) = response(m) else { break };
                if cost(m, e) < cost(best.0, best.2) {
                    best = (m, tv, e);
                }
                if e.signum() == ea.signum() { a = m } else { b = m }
            }
        }
        let (t_adv, t_v, _) = best;
        if rush {
            KeyTime { key_t: pulled(realism, t_adv).max(0.0), t_vut: Some(t_v), free_response: kt.free_response }
        } else {
            KeyTime { t_vut: Some(t_v), ..kt }
        }
    }

    /// Steps 3–4: the leader's plan for key time `key_t`, checked against the follower's best
    /// response to it (`t_v`, the VUT's time at the zone, came from a free response when
    /// `free_response`); the BV gives way when the order could not be kept.
    fn checked_plan(
        &mut self,
        inp: &RegulatorInput,
        bv_key: f64,
        realism: Option<RealismPull>,
        key_t: f64,
        t_v: f64,
        free_response: bool,
    ) -> Decision {
        // 3: the leader's plan: to the key point at the key time, or, for a rushing BV that
        // slows before it commits, to its commit station that much earlier than the key time as
        // it takes to cross from there at the speed it crosses at.
        let commit = self.rush_commit(inp, bv_key, key_t);
        let (event_t, event_station, then, realism) = match commit {
            Some(c) => (key_t - c.cross_s, c.station_m, Some(c.speed_mps), self.realism_pull(inp.bv.s_m, c.station_m)),
            None => (key_t, bv_key, None, realism),
        };
        if self.lead(inp, Some(event_t), event_station, realism, then) == QpStatus::Failed {
            return self.fallback(RegulatorStatus::Fallback, inp.bv.v_mps);
        }
        let lslack = self.leader_equal.slack_m();
        // Met exactly: the key time is the event's (the plan may stand at the station just before
        // it); missed: when the plan actually gets there.
        let planned_key = match commit {
            _ if lslack <= SLACK_TOL_M => Some(key_t),
            None => self.leader_equal.time_at_station(bv_key),
            Some(c) => self.leader_equal.time_at_station(c.station_m).map(|t| t + c.cross_s),
        };

        // 4: safety against the follower's best response to the planned key time.
        let margin = self.params.safety_margin_s;
        let probe_t = match (inp.target.style(), planned_key) {
            (Style::Rush, Some(tb)) => tb + margin,
            (Style::Yield, Some(tb)) => (tb - margin).max(0.0),
            (_, None) => key_t,
        };
        let cannot_bind = free_response
            && match inp.target.style() {
                Style::Rush => t_v > probe_t + BINDING_TOL_S,
                Style::Yield => t_v < probe_t - BINDING_TOL_S,
            };
        let (t_v_check, fslack) = if cannot_bind {
            (Some(t_v), 0.0)
        } else {
            let Some(check) = self.follower(inp, Some(probe_t)) else {
                return self.fallback(RegulatorStatus::Fallback, inp.bv.v_mps);
            };
            check
        };
        let pet = match (inp.target.style(), planned_key, t_v_check.or(Some(t_v))) {
            (Style::Rush, Some(tb), Some(tv)) => Some(tv - tb),
            (Style::Yield, Some(tb), _) => Some(tb - t_v),
            _ => None,
        };
        let unsafe_order = fslack > SLACK_TOL_M || planned_key.is_none() || pet.is_some_and(|p| p < margin);
        if unsafe_order {
            return self.give_way(inp);
        }
        self.last_key_t_s = planned_key.map(|t| t + inp.t_s);
        let status = if lslack > SLACK_TOL_M { RegulatorStatus::Degraded } else { RegulatorStatus::Regulating };
        self.decision_from(&self.leader_equal, status, planned_key, pet, fslack)
    }

    /// The input of the plan after a rushing cut-in: the BV is now the VUT's lead vehicle, and
    /// the VUT has yet to reach the encroachment point. If it is predicted (at its measured speed)
    /// to get there later than τ after the BV's observed exit — it eases off behind the BV — the
    /// BV pulls away at its top speed (within its caps), so the VUT brakes less: feedback on the
    /// PET that is still to be measured. Anything else: the input as it is.
    fn after_merge(&self, inp: &RegulatorInput) -> RegulatorInput {
        let mut after = *inp;
        if inp.target.style() != Style::Rush
            || inp.zone_kind != ConflictKind::Merge
            || inp.vut.s_m >= inp.zone_vut.enter_s_m
        {
            return after;
        }
        let Some(bv_exit) = self.bv_exit_t_s else { return after };
        let vut_in = inp.t_s + (inp.zone_vut.enter_s_m - inp.vut.s_m) / inp.vut.v_mps.max(0.1);
        if vut_in - bv_exit > inp.target.tau_s() {
            after.reference_speed_mps = after.reference_speed_mps.max(self.params.bv.max_speed_mps);
        }
        after
    }

    /// The BV stays behind its zone entry until the VUT is predicted out of the zone plus the margin.
    fn give_way(&mut self, inp: &RegulatorInput) -> Decision {
        let until = self
            .predicted_vut_exit(inp)
            .map_or(self.params.horizon as f64 * self.params.dt_s * 2.0, |t| t + self.params.safety_margin_s);
        match self.hold_back(inp, self.hold_station(inp), until, None) {
            QpStatus::Failed => self.fallback(RegulatorStatus::Fallback, inp.bv.v_mps),
            _ => self.decision_from(&self.leader_upper, RegulatorStatus::SafetyYield, None, None, 0.0),
        }
    }

    /// Yield with a VUT that does not come through: hold before the zone.
    fn wait(&mut self, inp: &RegulatorInput) -> Decision {
        let until = self.params.horizon as f64 * self.params.dt_s * 2.0;
        match self.hold_back(inp, self.hold_station(inp), until, None) {
            QpStatus::Failed => self.fallback(RegulatorStatus::Fallback, inp.bv.v_mps),
            _ => self.decision_from(&self.leader_upper, RegulatorStatus::Waiting, None, None, 0.0),
        }
    }

    /// When the VUT will have left the zone, s from now, by constant speed (no BV influence).
    fn predicted_vut_exit(&self, inp: &RegulatorInput) -> Option<f64> {
        let d = inp.zone_vut.exit_s_m - inp.vut.s_m;
        if d <= 0.0 {
            return Some(0.0);
        }
        (inp.vut.v_mps > VUT_STANDING_MPS).then(|| d / inp.vut.v_mps)
    }
}

#[cfg(test)]
mod tests;
