//! What crosses the cloud–edge link (MQTT): versioned `postcard` frames. The cloud signs what it
//! sends (priors and commands) with Ed25519; a BV accepts a frame only if the version is one it
//! speaks, the frame is for its fleet and addressed to it, it arrived on the topic its kind belongs
//! on, the signature checks out against the cloud key in its configuration, its sequence number is
//! newer than every one it accepted before, and its timestamp lies in the acceptance window. What the BV sends back (telemetry, heartbeats) is framed the same way,
//! unsigned.
//!
//! A frame is `b"V2T"`, the link version, the frame kind, the `postcard` body, and — for the
//! signed kinds — the 64-byte Ed25519 signature over everything before it. The header bytes are
//! signed too, so a body cannot be replayed as another kind or version.
//!
//! ```
//! use v2t_wire::link::{self, Arrival, CloudBody, CloudMessage, Command, Receiver, SigningKey};
//!
//! let key = SigningKey::from_bytes(&[7; 32]);
//! let mut rx = Receiver::new(key.verifying_key(), "pg", "bv1", link::Window::default());
//! let msg = CloudMessage { fleet: "pg".into(), bv_id: "bv1".into(), seq: 1, issued_ms: 1_000, body: CloudBody::Command(Command::Abort) };
//! let frame = link::seal(&msg, &key).unwrap();
//! assert_eq!(rx.open(&frame, Arrival::Command, 1_200).unwrap(), msg);
//! // The same frame again is a replay.
//! assert!(matches!(rx.open(&frame, Arrival::Command, 1_300).unwrap_err().reason, link::LinkError::Replay { .. }));
//! ```

use ed25519_dalek::Signer as _;
pub use ed25519_dalek::{SigningKey, VerifyingKey};
use serde::{Deserialize, Serialize};
use v2t_model::Target;
use v2t_model::prior::TrajectoryPrior;

/// The link version this build speaks (2: telemetry says how the VUT's reaction is identified,
/// campaign uploads and runs' reports exist; a BV and a cloud of another version refuse each
/// other's frames by name).
pub const LINK_VERSION: u8 = 2;
/// The first bytes of every frame.
pub const MAGIC: &[u8; 3] = b"V2T";
/// Header length: magic, version, kind.
pub const HEADER_LEN: usize = 5;
/// Ed25519 signature length.
pub const SIGNATURE_LEN: usize = 64;
/// Largest frame a receiver decodes, bytes (a prior of 3 agents × 30 s at 10 Hz is ~60 kB).
pub const MAX_FRAME_LEN: usize = 1 << 20;
/// A message addressed to every BV of the fleet.
pub const ALL_BVS: &str = "*";

/// MQTT topics: `v2t/<fleet>/bv/<bv>/<leaf>` for one BV, `v2t/<fleet>/all/cmd` for every BV.
pub mod topics {
    /// Cloud → BV: prior uploads (signed).
    pub const PRIOR: &str = "prior";
    /// Cloud → BV: commands (signed).
    pub const CMD: &str = "cmd";
    /// Cloud → BV: the cloud regulator's plans (signed), for a BV regulated in the cloud.
    pub const PLAN: &str = "plan";
    /// BV → cloud: telemetry at 10 Hz.
    pub const TELEMETRY: &str = "telemetry";
    /// BV → cloud: heartbeat at 5 Hz.
    pub const HEARTBEAT: &str = "heartbeat";
    /// BV → cloud: what the BV accepted, refused or did, as JSON text.
    pub const EVENT: &str = "event";
    /// BV → cloud: what a run taught the BV about the VUT ([`super::RunLearned`]), once per run.
    pub const LEARNED: &str = "learned";

    /// The topic `leaf` of BV `bv` in `fleet`.
    pub fn bv(fleet: &str, bv: &str, leaf: &str) -> String {
        format!("v2t/{fleet}/bv/{bv}/{leaf}")
    }

    /// Commands to every BV of `fleet`.
    pub fn all_cmd(fleet: &str) -> String {
        format!("v2t/{fleet}/all/{CMD}")
    }

    /// Whether a fleet or BV id can be part of a topic: ASCII letters, digits, `_`, `-`, 1–64 long
    /// (no MQTT wildcards or level separators).
    pub fn valid_id(id: &str) -> bool {
        (1..=64).contains(&id.len()) && id.chars().all(|c| c.is_ascii_alphanumeric() || matches!(c, '_' | '-'))
    }
}

/// What a frame carries.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u8)]
pub enum FrameKind {
    /// [`CloudMessage`], signed.
    Cloud = 1,
    /// [`Telemetry`], unsigned.
    Telemetry = 2,
    /// [`Heartbeat`], unsigned.
    Heartbeat = 3,
    /// [`RunLearned`], unsigned.
    Learned = 4,
}

impl FrameKind {
    fn from_u8(b: u8) -> Option<Self> {
        match b {
            1 => Some(Self::Cloud),
            2 => Some(Self::Telemetry),
            3 => Some(Self::Heartbeat),
            4 => Some(Self::Learned),
            _ => None,
        }
    }
}

/// A message from the cloud supervisor to one BV (or every BV: [`ALL_BVS`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CloudMessage {
    /// Fleet (test session) id.
    pub fleet: String,
    /// The BV it is for, or [`ALL_BVS`].
    pub bv_id: String,
    /// Strictly increasing per cloud key; a BV rejects any number it has seen or passed.
    pub seq: u64,
    /// When the cloud issued it, Unix time in ms.
    pub issued_ms: u64,
    /// What it says.
    pub body: CloudBody,
}

/// The content of a [`CloudMessage`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum CloudBody {
    /// A trajectory prior to regulate around.
    Prior(PriorUpload),
    /// A supervision command.
    Command(Command),
    /// A plan of the cloud regulator, for a BV regulated in the cloud (the onboard runtime
    /// regulates itself and never subscribes to plans).
    Plan(CloudPlan),
    /// What a test campaign has learned of the VUT, for the next run around the active prior.
    Campaign(CampaignUpload),
}

/// What a test campaign has learned of the VUT in earlier runs of one test, for the BV that runs
/// the next one around the prior `prior_id`: the aim, what the runs showed about reach, how the
/// VUT drove its route and how it was identified to react (`v2t_game::campaign`'s memory of the
/// test). The BV takes it between the prior's upload and the start of the run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CampaignUpload {
    /// The prior it is for (the BV's active prior).
    pub prior_id: u64,
    /// The τ and style the BV aims at in the run (a τ out of range does not decode).
    pub aim: Target,
    /// What earlier runs showed about reach (`None`: nothing).
    pub below_reach: Option<KnownBelowReach>,
    /// How the VUT drove its route (`None`: not known).
    pub route: Option<LearnedRoute>,
    /// How the VUT was identified to react, the prior of the run's identification (`None`: the
    /// regulator's default prior).
    pub reaction: Option<LearnedReaction>,
}

/// What earlier runs showed about reach.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct KnownBelowReach {
    /// Why τ is out of the VUT's reach ([`crate::BelowReachCode`] code).
    pub cause: u8,
    /// The PET the VUT allows as far as known, s.
    pub pet_bound_s: Option<f64>,
}

/// The VUT's speed along its route, every `step_m` from the route's start (`v2t_game::route_speed`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LearnedRoute {
    /// Grid spacing, m.
    pub step_m: f64,
    /// Valid runs it rests on.
    pub runs: u32,
    /// Speed at each grid point, m/s.
    pub speeds_mps: Vec<f64>,
}

/// A posterior over the regulator's hypotheses of the VUT's reaction (`v2t_game::reaction`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LearnedReaction {
    /// Probability of each hypothesis, in the regulator's order.
    pub probabilities: Vec<f64>,
    /// Cycles that taught something, over every run it rests on.
    pub informative_cycles: u32,
}

impl CampaignUpload {
    /// Refuses what no campaign learns, each field against its bound and before anything is
    /// queued: a route of 2 to [`crate::MAX_ROUTE_POINTS`] speeds in [0, 70] m/s every (0, 10] m,
    /// 1 to [`crate::MAX_REACTION_HYPOTHESES`] probabilities in [0, 1], a cause that decodes, a
    /// bound in [0, 60] s, every number finite. (The regulator's own checks, the number of its
    /// hypotheses among them, come on the BV.)
    pub fn check(&self) -> Result<(), LinkError> {
        use crate::Code as _;
        let bad = |field: &str, bound: &str, v: f64| {
            Err(LinkError::Malformed(format!("campaign field {field} = {v}: must be finite and {bound}")))
        };
        if let Some(b) = &self.below_reach {
            if crate::BelowReachCode::from_code(b.cause).is_err() {
                return Err(LinkError::Malformed(format!(
                    "campaign field below_reach.cause = {}: unknown code",
                    b.cause
                )));
            }
            if let Some(v) = b.pet_bound_s
                && !(v.is_finite() && (0.0..=60.0).contains(&v))
            {
                return bad("below_reach.pet_bound_s", "within [0, 60] s", v);
            }
        }
        if let Some(r) = &self.route {
            r.check("campaign")?;
        }
        if let Some(r) = &self.reaction {
            r.check("campaign")?;
        }
        Ok(())
    }
}

/// `values` of the field `field` (under `what`): `count` of them (`noun` in the error), each
/// finite and within `bound` (`bound_text` says it with its unit); the error names the field and
/// the bound.
fn check_series(
    what: &str,
    (field, noun): (&str, &str),
    values: &[f64],
    count: std::ops::RangeInclusive<usize>,
    bound: std::ops::RangeInclusive<f64>,
    bound_text: &str,
) -> Result<(), LinkError> {
    if !count.contains(&values.len()) {
        return Err(LinkError::Malformed(format!(
            "{what} field {field}: {} {noun}, must be {} to {}",
            values.len(),
            count.start(),
            count.end()
        )));
    }
    match values.iter().enumerate().find(|(_, v)| !(v.is_finite() && bound.contains(*v))) {
        Some((i, v)) => Err(LinkError::Malformed(format!(
            "{what} field {field}[{i}] = {v}: must be finite and within {bound_text}"
        ))),
        None => Ok(()),
    }
}

impl LearnedRoute {
    /// 2 to [`crate::MAX_ROUTE_POINTS`] speeds in [0, 70] m/s every (0, 10] m; the error names
    /// the field under `what`.
    pub fn check(&self, what: &str) -> Result<(), LinkError> {
        if !(self.step_m.is_finite() && self.step_m > 0.0 && self.step_m <= 10.0) {
            return Err(LinkError::Malformed(format!(
                "{what} field route.step_m = {}: must be finite and within (0, 10] m",
                self.step_m
            )));
        }
        let (field, count) = (("route.speeds_mps", "points"), 2..=crate::MAX_ROUTE_POINTS);
        check_series(what, field, &self.speeds_mps, count, 0.0..=70.0, "[0, 70] m/s")
    }
}

impl LearnedReaction {
    /// 1 to [`crate::MAX_REACTION_HYPOTHESES`] probabilities in [0, 1]; the error names the field
    /// under `what`.
    pub fn check(&self, what: &str) -> Result<(), LinkError> {
        let count = 1..=crate::MAX_REACTION_HYPOTHESES;
        check_series(what, ("reaction.probabilities", "values"), &self.probabilities, count, 0.0..=1.0, "[0, 1]")
    }
}

/// What one run taught a BV about the VUT, reported once per run when the VUT has left its zone:
/// how the VUT drove its route up to there and how the regulator identified its reaction by then
/// (`campaign record --learned` adds it to the test's memory).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RunLearned {
    /// The BV.
    pub bv_id: String,
    /// The prior of the run.
    pub prior_id: u64,
    /// When, Unix ms.
    pub stamp_ms: u64,
    /// The τ and style the run aimed at.
    pub aim: Target,
    /// Whether the run started from a learned route (campaign knowledge), as its record must say.
    pub started_with_route: bool,
    /// Whether it started from an earlier identification of the VUT's reaction.
    pub started_with_reaction: bool,
    /// How the VUT drove its route up to its zone's exit, as the BV measured it (`None`: too
    /// little of it seen).
    pub route: Option<LearnedRoute>,
    /// The identification of the VUT's reaction at that moment (`None`: the BV's regulator does
    /// not identify it).
    pub reaction: Option<LearnedReaction>,
}

impl RunLearned {
    /// Each field against its bound (as [`CampaignUpload::check`]).
    pub fn check(&self) -> Result<(), LinkError> {
        if let Some(r) = &self.route {
            r.check("learned")?;
        }
        if let Some(r) = &self.reaction {
            r.check("learned")?;
        }
        Ok(())
    }
}

/// The frame of a run's report of what it learned.
pub fn learned_frame(r: &RunLearned) -> Result<Vec<u8>, LinkError> {
    encode(FrameKind::Learned, r)
}

/// Most steps a cloud plan carries (the regulator's longest horizon).
pub const MAX_PLAN_STEPS: usize = 200;

/// The cloud regulator's plan for one BV: from the BV's arc length and speed at `t0_ms`, one
/// acceleration per step of `dt_s`. The BV tracks it against its own clock (synchronised to the
/// cloud's, GNSS time on a track), so a plan that arrives late is still read at the right instant.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CloudPlan {
    /// Sequence of the BV state the plan was computed from.
    pub state_seq: u64,
    /// The instant the plan starts, Unix ms.
    pub t0_ms: u64,
    /// The BV's arc length along its path at `t0_ms`, as the cloud predicted it, m.
    pub s0_m: f64,
    /// Speed at `t0_ms`, m/s.
    pub v0_mps: f64,
    /// Step, s.
    pub dt_s: f64,
    /// Acceleration per step, m/s² (empty: brake at `fallback_decel_mps2`).
    pub accel_mps2: Vec<f64>,
    /// The regulator's status (`v2t_wire::PlanStatus` code).
    pub status: u8,
    /// Predicted PET, s.
    pub predicted_pet_s: Option<f64>,
}

impl CloudPlan {
    /// Refuses numbers no regulator plans: each field against its bound.
    pub fn check(&self) -> Result<(), LinkError> {
        let bad = |field: &str, bound: &str, v: f64| {
            Err(LinkError::Malformed(format!("plan field {field} = {v}: must be finite and {bound}")))
        };
        if !(self.s0_m.is_finite() && self.s0_m.abs() <= 1.0e6) {
            return bad("s0_m", "within ±1e6 m", self.s0_m);
        }
        if !(self.v0_mps.is_finite() && (0.0..=150.0).contains(&self.v0_mps)) {
            return bad("v0_mps", "within [0, 150] m/s", self.v0_mps);
        }
        if !(self.dt_s.is_finite() && (0.01..=1.0).contains(&self.dt_s)) {
            return bad("dt_s", "within [0.01, 1] s", self.dt_s);
        }
        if self.accel_mps2.len() > MAX_PLAN_STEPS {
            return Err(LinkError::Malformed(format!(
                "plan field accel_mps2: {} steps, at most {MAX_PLAN_STEPS}",
                self.accel_mps2.len()
            )));
        }
        if let Some(&a) = self.accel_mps2.iter().find(|a| !(a.is_finite() && a.abs() <= 50.0)) {
            return bad("accel_mps2", "within ±50 m/s²", a);
        }
        Ok(())
    }
}

/// A prior for one BV: the generated trajectories of the scenario, which of them this BV drives,
/// and when it may be used.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PriorUpload {
    /// Identifier the BV reports back in its telemetry.
    pub prior_id: u64,
    /// The agent of `prior` this BV drives.
    pub bv_agent: String,
    /// Not to be used before, Unix ms.
    pub valid_from_ms: u64,
    /// Not to be used after, Unix ms.
    pub valid_until_ms: u64,
    /// The trajectories (VUT and BVs), conflicts, τ and style.
    pub prior: TrajectoryPrior,
}

/// A supervision command.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub enum Command {
    /// Prepare: the accepted prior becomes active, the BV waits at its start.
    Arm,
    /// Go: engage and drive the active prior.
    Start,
    /// Stop now: the minimal-risk stop.
    Abort,
    /// Re-target the running interaction (a τ out of range does not decode).
    SetTarget(Target),
}

/// What a BV reports at 10 Hz.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Telemetry {
    /// The BV.
    pub bv_id: String,
    /// Per-BV sequence number.
    pub seq: u64,
    /// When, Unix ms.
    pub stamp_ms: u64,
    /// The active prior, 0 when none.
    pub prior_id: u64,
    /// Position x, m (map frame).
    pub px_m: f64,
    /// Position y, m.
    pub py_m: f64,
    /// Heading, rad.
    pub theta_rad: f64,
    /// Speed, m/s.
    pub speed_mps: f64,
    /// The regulator's last plan status (`v2t_wire::PlanStatus` code).
    pub plan_status: u8,
    /// The regulator's predicted PET, s (NaN-free: `None` when it has none).
    pub predicted_pet_s: Option<f64>,
    /// τ out of the VUT's reach (`v2t_wire::BelowReachCode` code, 0 when nothing says so).
    pub below_reach: u8,
    /// With `below_reach`: the PET the VUT allows as far as known, s.
    pub pet_bound_s: Option<f64>,
    /// The actuation gate's state (`v2t_wire::GateState` code).
    pub gate_state: u8,
    /// Why the gate is in that state (`v2t_wire::GateReason` code).
    pub gate_reason: u8,
    /// How the regulator identifies the VUT's reaction to the BV so far this run (`None`: it does
    /// not identify it, or has no decision yet).
    pub vut_reaction: Option<VutReaction>,
}

/// How the regulator identifies the VUT's reaction to the BV (its plan's `vut_*` fields).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct VutReaction {
    /// Probability that the VUT reacts to the BV at all.
    pub reacts_p: f64,
    /// The gap it is identified to accept (expected over the reacting hypotheses), s.
    pub gap_s: f64,
    /// Its standard deviation, s.
    pub gap_sd_s: f64,
}

/// A BV's sign of life at 5 Hz.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Heartbeat {
    /// The BV.
    pub bv_id: String,
    /// Per-BV sequence number.
    pub seq: u64,
    /// When, Unix ms.
    pub stamp_ms: u64,
    /// Whether every onboard node is alive.
    pub healthy: bool,
}

/// A frame that cannot be made or accepted.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum LinkError {
    /// Too short, too long, wrong magic or unknown kind.
    #[error("malformed frame: {0}")]
    Malformed(String),
    /// Another link version.
    #[error("link version {got}, this build speaks {LINK_VERSION}")]
    Version {
        /// The frame's version.
        got: u8,
    },
    /// Not signed by the configured cloud key, or altered.
    #[error("bad signature: not from the configured cloud key, or altered")]
    Signature,
    /// The body does not decode.
    #[error("undecodable body: {0}")]
    Decode(String),
    /// Signed for another fleet (test session).
    #[error("for fleet {fleet}, this BV is in fleet {mine}")]
    OtherFleet {
        /// The frame's fleet.
        fleet: String,
        /// This BV's.
        mine: String,
    },
    /// A frame that does not belong on the topic it arrived on (a prior on a command topic, a frame
    /// for every BV on one BV's topic, …).
    #[error("a {kind} arrived on the {topic} topic")]
    WrongTopic {
        /// What the frame is.
        kind: &'static str,
        /// Where it arrived.
        topic: &'static str,
    },
    /// Addressed to another BV.
    #[error("addressed to {to}, this is {me}")]
    NotForMe {
        /// The addressee.
        to: String,
        /// This BV.
        me: String,
    },
    /// A sequence number already seen or passed.
    #[error("replay: sequence {seq} ≤ last accepted {last}")]
    Replay {
        /// The frame's.
        seq: u64,
        /// The last accepted.
        last: u64,
    },
    /// Issued too long ago.
    #[error("stale: issued {age_ms} ms ago (window {max_ms} ms)")]
    Stale {
        /// Age.
        age_ms: u64,
        /// Window.
        max_ms: u64,
    },
    /// Issued in the future beyond the allowed clock skew.
    #[error("issued {ahead_ms} ms in the future (allowed skew {max_ms} ms)")]
    Future {
        /// How far ahead.
        ahead_ms: u64,
        /// Allowed skew.
        max_ms: u64,
    },
    /// The body does not encode.
    #[error("cannot encode: {0}")]
    Encode(String),
}

fn header(kind: FrameKind) -> [u8; HEADER_LEN] {
    [MAGIC[0], MAGIC[1], MAGIC[2], LINK_VERSION, kind as u8]
}

fn encode<T: Serialize>(kind: FrameKind, body: &T) -> Result<Vec<u8>, LinkError> {
    let mut out = header(kind).to_vec();
    out.extend(postcard::to_allocvec(body).map_err(|e| LinkError::Encode(e.to_string()))?);
    Ok(out)
}

/// Splits a frame into kind and the bytes after the header, checking magic, version and length.
pub fn parse_header(frame: &[u8]) -> Result<(FrameKind, &[u8]), LinkError> {
    if frame.len() > MAX_FRAME_LEN {
        return Err(LinkError::Malformed(format!("{} bytes, at most {MAX_FRAME_LEN}", frame.len())));
    }
    let (Some(head), Some(rest)) = (frame.get(..HEADER_LEN), frame.get(HEADER_LEN..)) else {
        return Err(LinkError::Malformed(format!("{} bytes, shorter than the header", frame.len())));
    };
    if head.get(..3) != Some(MAGIC.as_slice()) {
        return Err(LinkError::Malformed("not a Video2Track frame (magic)".into()));
    }
    let version = head.get(3).copied().unwrap_or(0);
    if version != LINK_VERSION {
        return Err(LinkError::Version { got: version });
    }
    let kind_byte = head.get(4).copied().unwrap_or(0);
    let kind =
        FrameKind::from_u8(kind_byte).ok_or_else(|| LinkError::Malformed(format!("unknown kind {kind_byte}")))?;
    Ok((kind, rest))
}

/// The signed frame of `msg`.
pub fn seal(msg: &CloudMessage, key: &SigningKey) -> Result<Vec<u8>, LinkError> {
    let mut frame = encode(FrameKind::Cloud, msg)?;
    let sig = key.sign(&frame);
    frame.extend(sig.to_bytes());
    Ok(frame)
}

/// The frame of a telemetry report.
pub fn telemetry_frame(t: &Telemetry) -> Result<Vec<u8>, LinkError> {
    encode(FrameKind::Telemetry, t)
}

/// The frame of a heartbeat.
pub fn heartbeat_frame(h: &Heartbeat) -> Result<Vec<u8>, LinkError> {
    encode(FrameKind::Heartbeat, h)
}

/// What the cloud reads from a BV.
#[derive(Debug, Clone, PartialEq)]
pub enum EdgeReport {
    /// Telemetry.
    Telemetry(Telemetry),
    /// Heartbeat.
    Heartbeat(Heartbeat),
    /// What a run taught the BV.
    Learned(RunLearned),
}

/// Decodes a telemetry, heartbeat or run-learned frame (the last one checked against its bounds).
pub fn read_report(frame: &[u8]) -> Result<EdgeReport, LinkError> {
    let decode = |e: postcard::Error| LinkError::Decode(e.to_string());
    match parse_header(frame)? {
        (FrameKind::Telemetry, body) => Ok(EdgeReport::Telemetry(postcard::from_bytes(body).map_err(decode)?)),
        (FrameKind::Heartbeat, body) => Ok(EdgeReport::Heartbeat(postcard::from_bytes(body).map_err(decode)?)),
        (FrameKind::Learned, body) => {
            let r: RunLearned = postcard::from_bytes(body).map_err(decode)?;
            r.check()?;
            Ok(EdgeReport::Learned(r))
        }
        (FrameKind::Cloud, _) => Err(LinkError::Malformed("a cloud frame where a BV report was expected".into())),
    }
}

/// How far a cloud message's timestamp may lie from the BV's clock.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Window {
    /// Older than this is stale, ms.
    pub max_age_ms: u64,
    /// Further ahead than this is refused, ms (clock skew between cloud and BV).
    pub max_skew_ms: u64,
}

impl Default for Window {
    /// 30 s of age (a broker that held a QoS 1 message through a short outage), 2 s of skew.
    fn default() -> Self {
        Self { max_age_ms: 30_000, max_skew_ms: 2_000 }
    }
}

/// The topic a cloud frame arrived on, as the BV subscribes them.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Arrival {
    /// `v2t/<fleet>/bv/<me>/prior`: priors and campaign knowledge addressed to this BV.
    Prior,
    /// `v2t/<fleet>/bv/<me>/cmd`: commands addressed to this BV.
    Command,
    /// `v2t/<fleet>/all/cmd`: commands addressed to every BV ([`ALL_BVS`]).
    AllCommand,
    /// `v2t/<fleet>/bv/<me>/plan`: the cloud regulator's plans for this BV.
    Plan,
}

impl Arrival {
    fn name(self) -> &'static str {
        match self {
            Self::Prior => "prior",
            Self::Command => "command",
            Self::AllCommand => "every-BV command",
            Self::Plan => "plan",
        }
    }
}

/// A refused cloud frame: why, and its sequence number when its signature checked out (a genuine
/// frame of the cloud, whose sender waits for the verdict; anything else may be an attacker's).
#[derive(Debug, Clone, PartialEq)]
pub struct Refusal {
    /// Why.
    pub reason: LinkError,
    /// The frame's sequence number, when it was signed with the cloud's key.
    pub genuine_seq: Option<u64>,
}

impl From<LinkError> for Refusal {
    fn from(reason: LinkError) -> Self {
        Self { reason, genuine_seq: None }
    }
}

/// A stale abort is still accepted up to this many acceptance windows old: a stop is always safe,
/// and this bound keeps a captured abort from being replayed into a nuisance after a restart that
/// lost the last sequence number.
pub const ABORT_STALE_WINDOWS: u64 = 20;

/// A BV's side of the link: checks every cloud frame and remembers the last sequence accepted.
///
/// The checks run cheapest first, so that garbage costs little: header, body, fleet, addressee and
/// topic, and only then the Ed25519 signature; the sequence number and the time window of a frame
/// whose signature checked out come last. Only an accepted frame advances the sequence.
#[derive(Debug, Clone)]
pub struct Receiver {
    key: VerifyingKey,
    fleet: String,
    bv_id: String,
    window: Window,
    last_seq: Option<u64>,
}

impl Receiver {
    /// A receiver for BV `bv_id` of `fleet` that trusts `key`.
    pub fn new(key: VerifyingKey, fleet: &str, bv_id: &str, window: Window) -> Self {
        Self { key, fleet: fleet.to_owned(), bv_id: bv_id.to_owned(), window, last_seq: None }
    }

    /// The last sequence number accepted.
    pub fn last_seq(&self) -> Option<u64> {
        self.last_seq
    }

    /// Starts after `seq` (a sequence persisted across restarts).
    pub fn resume_after(&mut self, seq: u64) {
        self.last_seq = Some(self.last_seq.map_or(seq, |s| s.max(seq)));
    }

    /// The checks of [`Receiver::open`] that need no key and no state (header, body, fleet,
    /// addressee, topic): cheap enough to run for every message a flood brings, before anything is
    /// queued. Returns the message and the part the signature covers.
    pub fn screen<'f>(
        &self,
        frame: &'f [u8],
        arrival: Arrival,
    ) -> Result<(CloudMessage, &'f [u8], &'f [u8]), LinkError> {
        let (kind, _) = parse_header(frame)?;
        if kind != FrameKind::Cloud {
            return Err(LinkError::Malformed(format!("{kind:?} frame where a cloud frame was expected")));
        }
        let Some(split) = frame.len().checked_sub(SIGNATURE_LEN).filter(|&n| n >= HEADER_LEN) else {
            return Err(LinkError::Malformed("shorter than header and signature".into()));
        };
        let (signed, sig) = frame.split_at(split);
        let body = signed.get(HEADER_LEN..).unwrap_or_default();
        let msg: CloudMessage = postcard::from_bytes(body).map_err(|e| LinkError::Decode(e.to_string()))?;
        if msg.fleet != self.fleet {
            return Err(LinkError::OtherFleet { fleet: msg.fleet, mine: self.fleet.clone() });
        }
        if msg.bv_id != self.bv_id && msg.bv_id != ALL_BVS {
            return Err(LinkError::NotForMe { to: msg.bv_id, me: self.bv_id.clone() });
        }
        let (kind, fits) = match (&msg.body, msg.bv_id == ALL_BVS) {
            (CloudBody::Prior(_), false) => ("prior", arrival == Arrival::Prior),
            (CloudBody::Prior(_), true) => ("prior for every BV", false),
            (CloudBody::Command(_), false) => ("command", arrival == Arrival::Command),
            (CloudBody::Command(_), true) => ("command for every BV", arrival == Arrival::AllCommand),
            (CloudBody::Plan(_), false) => ("plan", arrival == Arrival::Plan),
            (CloudBody::Plan(_), true) => ("plan for every BV", false),
            (CloudBody::Campaign(_), false) => ("campaign knowledge", arrival == Arrival::Prior),
            (CloudBody::Campaign(_), true) => ("campaign knowledge for every BV", false),
        };
        if !fits {
            return Err(LinkError::WrongTopic { kind, topic: arrival.name() });
        }
        match &msg.body {
            CloudBody::Plan(plan) => plan.check()?,
            CloudBody::Campaign(c) => c.check()?,
            CloudBody::Prior(_) | CloudBody::Command(_) => {}
        }
        Ok((msg, signed, sig))
    }

    /// Checks `frame`, which arrived on `arrival` at Unix time `arrived_ms` (the time window counts
    /// from its arrival, so that a backlog of this BV's own does not age it), and returns the message.
    pub fn open(&mut self, frame: &[u8], arrival: Arrival, arrived_ms: u64) -> Result<CloudMessage, Refusal> {
        let (msg, signed, sig) = self.screen(frame, arrival)?;
        let sig: [u8; SIGNATURE_LEN] = sig.try_into().map_err(|_| LinkError::Signature)?;
        self.key
            .verify_strict(signed, &ed25519_dalek::Signature::from_bytes(&sig))
            .map_err(|_| LinkError::Signature)?;
        let genuine = |reason| Refusal { reason, genuine_seq: Some(msg.seq) };
        if let Some(last) = self.last_seq
            && msg.seq <= last
        {
            return Err(genuine(LinkError::Replay { seq: msg.seq, last }));
        }
        let age = arrived_ms.saturating_sub(msg.issued_ms);
        let abort = matches!(msg.body, CloudBody::Command(Command::Abort));
        let max_age = self.window.max_age_ms.saturating_mul(if abort { ABORT_STALE_WINDOWS } else { 1 });
        if age > max_age {
            return Err(genuine(LinkError::Stale { age_ms: age, max_ms: max_age }));
        }
        let ahead = msg.issued_ms.saturating_sub(arrived_ms);
        if ahead > self.window.max_skew_ms {
            return Err(genuine(LinkError::Future { ahead_ms: ahead, max_ms: self.window.max_skew_ms }));
        }
        self.last_seq = Some(msg.seq);
        Ok(msg)
    }
}

/// Reads a 32-byte Ed25519 key seed written as 64 hex digits (whitespace around it allowed).
pub fn key_from_hex(text: &str) -> Result<[u8; 32], String> {
    let t = text.trim();
    if t.len() != 64 {
        return Err(format!("expected 64 hex digits, got {} characters", t.len()));
    }
    let mut out = [0u8; 32];
    for (i, byte) in out.iter_mut().enumerate() {
        let pair = t.get(2 * i..2 * i + 2).ok_or("not ASCII hex")?;
        *byte = u8::from_str_radix(pair, 16).map_err(|_| format!("not hex: {pair:?}"))?;
    }
    Ok(out)
}

/// The public half of the committed demo key pair, `config/keys/demo_cloud.pub`. Its secret half
/// is public on purpose: a BV that trusts it accepts priors and commands from anyone, so it is for
/// simulated sessions only (the supervisor refuses to sign for a real vehicle with it, `v2t-edge
/// check` warns about it).
pub const DEMO_PUBLIC_KEY: &str = "2e99bfa75838d24cc111c8688e17019fd96f84f169011257821a70a0a2af7e1e";

/// A key as 64 hex digits.
pub fn key_to_hex(key: &[u8; 32]) -> String {
    key.iter().map(|b| format!("{b:02x}")).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use v2t_model::grounded::AgentRole;
    use v2t_model::kinematics::{Control, State, rollout};
    use v2t_model::prior::AgentTrajectory;
    use v2t_model::{Style, Target};

    fn key() -> SigningKey {
        SigningKey::from_bytes(&[42; 32])
    }

    fn msg(seq: u64, issued_ms: u64, body: CloudBody) -> CloudMessage {
        CloudMessage { fleet: "pg".into(), bv_id: "bv1".into(), seq, issued_ms, body }
    }

    fn prior() -> PriorUpload {
        let controls = vec![Control { accel_mps2: 0.2, yaw_rate_radps: 0.0 }; 30];
        let states = rollout(State { px: 0.0, py: 0.0, theta_rad: 0.0, speed_mps: 8.0 }, &controls, 0.1);
        PriorUpload {
            prior_id: 9,
            bv_agent: "bv1".into(),
            valid_from_ms: 0,
            valid_until_ms: 60_000,
            prior: TrajectoryPrior {
                fragment_id: "J100".into(),
                dt_s: 0.1,
                agents: vec![AgentTrajectory { id: "bv1".into(), role: AgentRole::Bv, states, controls }],
                conflicts: vec![],
                target: Target::new(2.0, Style::Yield).unwrap(),
            },
        }
    }

    fn rx() -> Receiver {
        Receiver::new(key().verifying_key(), "pg", "bv1", Window::default())
    }

    /// Opens a command frame as it arrives on this BV's command topic; the refusal's reason.
    fn cmd(r: &mut Receiver, frame: &[u8], now_ms: u64) -> Result<CloudMessage, LinkError> {
        r.open(frame, Arrival::Command, now_ms).map_err(|e| e.reason)
    }

    fn plan(accel: Vec<f64>) -> CloudPlan {
        CloudPlan {
            state_seq: 3,
            t0_ms: 10_000,
            s0_m: 20.0,
            v0_mps: 4.0,
            dt_s: 0.1,
            accel_mps2: accel,
            status: 1,
            predicted_pet_s: Some(2.0),
        }
    }

    #[test]
    fn a_plan_arrives_on_its_own_topic_and_its_numbers_are_checked_before_anything_else() {
        let frame = seal(&msg(1, 1_000, CloudBody::Plan(plan(vec![0.5; 50]))), &key()).unwrap();
        assert!(matches!(rx().open(&frame, Arrival::Command, 1_000).unwrap_err().reason, LinkError::WrongTopic { .. }));
        assert!(rx().open(&frame, Arrival::Plan, 1_000).is_ok());
        for (bad, field) in [
            (CloudPlan { v0_mps: f64::NAN, ..plan(vec![]) }, "v0_mps"),
            (plan(vec![0.0, f64::INFINITY]), "accel_mps2"),
            (plan(vec![0.0; MAX_PLAN_STEPS + 1]), "201 steps"),
            (CloudPlan { dt_s: 0.0, ..plan(vec![]) }, "dt_s"),
        ] {
            let frame = seal(&msg(2, 1_000, CloudBody::Plan(bad)), &key()).unwrap();
            let e = rx().open(&frame, Arrival::Plan, 1_000).unwrap_err();
            assert!(e.genuine_seq.is_none() && e.reason.to_string().contains(field), "{}", e.reason);
        }
    }

    fn campaign(speeds: Vec<f64>) -> CampaignUpload {
        CampaignUpload {
            prior_id: 9,
            aim: Target::new(2.0, Style::Rush).unwrap(),
            below_reach: Some(KnownBelowReach { cause: 2, pet_bound_s: Some(2.4) }),
            route: Some(LearnedRoute { step_m: 2.0, runs: 2, speeds_mps: speeds }),
            reaction: Some(LearnedReaction { probabilities: vec![0.5, 0.5], informative_cycles: 40 }),
        }
    }

    #[test]
    fn campaign_knowledge_goes_to_one_bv_on_its_prior_topic_and_its_numbers_are_checked_first() {
        let frame = seal(&msg(1, 1_000, CloudBody::Campaign(campaign(vec![8.0; 40]))), &key()).unwrap();
        assert!(matches!(rx().open(&frame, Arrival::Command, 1_000).unwrap_err().reason, LinkError::WrongTopic { .. }));
        let m = rx().open(&frame, Arrival::Prior, 1_000).unwrap();
        let CloudBody::Campaign(c) = &m.body else { panic!("{m:?}") };
        let k = crate::CampaignKnowledge::from_upload(c, 1).unwrap();
        assert_eq!(k.route(), Some((2.0, 2, &[8.0; 40][..])));
        assert_eq!((k.below_reach(), k.reaction()), (Some((2, Some(2.4))), Some((&[0.5, 0.5][..], 40))));
        let every =
            CloudMessage { bv_id: ALL_BVS.into(), ..msg(2, 1_000, CloudBody::Campaign(campaign(vec![8.0; 4]))) };
        let e = rx().open(&seal(&every, &key()).unwrap(), Arrival::Prior, 1_000).unwrap_err();
        assert!(matches!(e.reason, LinkError::WrongTopic { .. }), "{}", e.reason);
        let mut bound = campaign(vec![8.0; 4]);
        bound.below_reach = Some(KnownBelowReach { cause: 2, pet_bound_s: Some(f64::INFINITY) });
        let mut cause = campaign(vec![8.0; 4]);
        cause.below_reach = Some(KnownBelowReach { cause: 0, pet_bound_s: None });
        let mut p = campaign(vec![8.0; 4]);
        p.reaction = Some(LearnedReaction { probabilities: vec![0.5, -0.1], informative_cycles: 1 });
        let mut many = campaign(vec![8.0; 4]);
        many.reaction = Some(LearnedReaction { probabilities: vec![0.0; 65], informative_cycles: 1 });
        let mut step = campaign(vec![8.0; 4]);
        step.route.as_mut().unwrap().step_m = f64::NAN;
        for (bad, field) in [
            (campaign(vec![8.0, 80.0]), "route.speeds_mps[1]"),
            (campaign(vec![8.0; crate::MAX_ROUTE_POINTS + 1]), "502 points"),
            (campaign(vec![8.0]), "1 points"),
            (step, "route.step_m"),
            (bound, "below_reach.pet_bound_s"),
            (cause, "below_reach.cause = 0"),
            (p, "reaction.probabilities[1]"),
            (many, "65 values"),
        ] {
            let frame = seal(&msg(3, 1_000, CloudBody::Campaign(bad)), &key()).unwrap();
            let e = rx().open(&frame, Arrival::Prior, 1_000).unwrap_err();
            assert!(e.genuine_seq.is_none() && e.reason.to_string().contains(field), "{field}: {}", e.reason);
        }
    }

    #[test]
    fn a_signed_prior_round_trips() {
        let m = msg(1, 10_000, CloudBody::Prior(prior()));
        let frame = seal(&m, &key()).unwrap();
        assert_eq!(rx().open(&frame, Arrival::Prior, 10_050).unwrap(), m);
    }

    #[test]
    fn tampering_anywhere_never_passes_and_only_a_genuine_frame_carries_its_sequence() {
        let frame = seal(&msg(1, 10_000, CloudBody::Prior(prior())), &key()).unwrap();
        for i in 0..frame.len() {
            let mut bad = frame.clone();
            bad[i] ^= 0x01;
            let e = rx().open(&bad, Arrival::Prior, 10_000).unwrap_err();
            assert_eq!(e.genuine_seq, None, "byte {i}: {}", e.reason);
        }
    }

    #[test]
    fn another_key_unsigned_and_truncated_frames_are_refused() {
        let m = msg(1, 10_000, CloudBody::Command(Command::Start));
        let other = SigningKey::from_bytes(&[1; 32]);
        assert_eq!(cmd(&mut rx(), &seal(&m, &other).unwrap(), 10_000), Err(LinkError::Signature));
        let unsigned = encode(FrameKind::Cloud, &m).unwrap();
        assert!(cmd(&mut rx(), &unsigned, 10_000).is_err());
        assert!(matches!(cmd(&mut rx(), b"V2", 0), Err(LinkError::Malformed(_))));
        assert!(matches!(cmd(&mut rx(), b"XYZ\x01\x01", 0), Err(LinkError::Malformed(_))));
        let mut other_version = seal(&m, &key()).unwrap();
        other_version[3] = LINK_VERSION - 1;
        assert_eq!(cmd(&mut rx(), &other_version, 10_000), Err(LinkError::Version { got: LINK_VERSION - 1 }));
        let tele = telemetry_frame(&Telemetry {
            bv_id: "bv1".into(),
            seq: 1,
            stamp_ms: 0,
            prior_id: 0,
            px_m: 0.0,
            py_m: 0.0,
            theta_rad: 0.0,
            speed_mps: 0.0,
            plan_status: 0,
            predicted_pet_s: None,
            below_reach: 0,
            pet_bound_s: None,
            gate_state: 0,
            gate_reason: 0,
            vut_reaction: None,
        })
        .unwrap();
        assert!(matches!(cmd(&mut rx(), &tele, 0), Err(LinkError::Malformed(_))));
        assert!(matches!(read_report(&tele), Ok(EdgeReport::Telemetry(_))));
    }

    #[test]
    fn replays_old_sequences_stale_and_future_frames_are_refused_and_do_not_advance() {
        let mut r = rx();
        let f5 = seal(&msg(5, 10_000, CloudBody::Command(Command::Arm)), &key()).unwrap();
        assert!(cmd(&mut r, &f5, 10_000).is_ok());
        assert_eq!(cmd(&mut r, &f5, 10_001), Err(LinkError::Replay { seq: 5, last: 5 }));
        assert_eq!(r.open(&f5, Arrival::Command, 10_001).unwrap_err().genuine_seq, Some(5), "a genuine replay");
        let f4 = seal(&msg(4, 10_000, CloudBody::Command(Command::Arm)), &key()).unwrap();
        assert_eq!(cmd(&mut r, &f4, 10_001), Err(LinkError::Replay { seq: 4, last: 5 }));
        let stale = seal(&msg(6, 10_000, CloudBody::Command(Command::Start)), &key()).unwrap();
        assert!(matches!(cmd(&mut r, &stale, 50_001), Err(LinkError::Stale { .. })));
        let future = seal(&msg(7, 20_000, CloudBody::Command(Command::Start)), &key()).unwrap();
        assert!(matches!(cmd(&mut r, &future, 10_000), Err(LinkError::Future { .. })));
        assert_eq!(r.last_seq(), Some(5), "refused frames leave the sequence where it was");
        // The stale one is still acceptable in its window (nothing consumed its number).
        assert!(cmd(&mut r, &stale, 10_100).is_ok());
        let mut other = msg(8, 10_100, CloudBody::Command(Command::Abort));
        other.bv_id = "bv2".into();
        assert!(matches!(cmd(&mut r, &seal(&other, &key()).unwrap(), 10_100), Err(LinkError::NotForMe { .. })));
        other.bv_id = ALL_BVS.into();
        let all = seal(&other, &key()).unwrap();
        assert!(matches!(cmd(&mut r, &all, 10_100), Err(LinkError::WrongTopic { .. })), "an abort-all on my topic");
        assert!(r.open(&all, Arrival::AllCommand, 10_100).is_ok());
    }

    #[test]
    fn fleet_addressee_and_topic_scope_every_frame() {
        let mut foreign = msg(1, 10_000, CloudBody::Command(Command::Arm));
        foreign.fleet = "capture".into();
        let e = cmd(&mut rx(), &seal(&foreign, &key()).unwrap(), 10_000).unwrap_err();
        assert_eq!(e, LinkError::OtherFleet { fleet: "capture".into(), mine: "pg".into() });
        assert_eq!(e.to_string(), "for fleet capture, this BV is in fleet pg");
        let prior_frame = seal(&msg(2, 10_000, CloudBody::Prior(prior())), &key()).unwrap();
        assert!(matches!(cmd(&mut rx(), &prior_frame, 10_000), Err(LinkError::WrongTopic { kind: "prior", .. })));
        let arm = seal(&msg(3, 10_000, CloudBody::Command(Command::Arm)), &key()).unwrap();
        for wrong in [Arrival::Prior, Arrival::AllCommand] {
            let e = rx().open(&arm, wrong, 10_000).unwrap_err();
            assert!(matches!(e.reason, LinkError::WrongTopic { kind: "command", .. }), "{wrong:?}");
        }
        let mut prior_all = msg(4, 10_000, CloudBody::Prior(prior()));
        prior_all.bv_id = ALL_BVS.into();
        let e = rx().open(&seal(&prior_all, &key()).unwrap(), Arrival::AllCommand, 10_000).unwrap_err();
        assert!(matches!(e.reason, LinkError::WrongTopic { kind: "prior for every BV", .. }));
    }

    #[test]
    fn an_abort_aged_by_a_backlog_still_stops_but_only_so_far_back() {
        let window = Window::default();
        let mut r = rx();
        let late = window.max_age_ms * 5;
        let abort = seal(&msg(9, 10_000, CloudBody::Command(Command::Abort)), &key()).unwrap();
        let start = seal(&msg(8, 10_000, CloudBody::Command(Command::Start)), &key()).unwrap();
        assert!(matches!(cmd(&mut r, &start, 10_000 + late), Err(LinkError::Stale { .. })), "only a stop");
        assert!(cmd(&mut r, &abort, 10_000 + late).is_ok());
        let ancient = seal(&msg(10, 10_000, CloudBody::Command(Command::Abort)), &key()).unwrap();
        let too_late = window.max_age_ms * ABORT_STALE_WINDOWS + 1;
        assert!(matches!(cmd(&mut r, &ancient, 10_000 + too_late), Err(LinkError::Stale { .. })));
    }

    #[test]
    fn keys_read_from_hex_and_refuse_garbage() {
        let k = [0xabu8; 32];
        assert_eq!(key_from_hex(&format!(" {}\n", key_to_hex(&k))).unwrap(), k);
        assert!(key_from_hex("abc").is_err());
        assert!(key_from_hex(&"zz".repeat(32)).is_err());
    }

    #[test]
    fn a_signed_target_out_of_range_does_not_decode() {
        let m = msg(3, 5_000, CloudBody::Command(Command::SetTarget(Target::new(3.0, Style::Rush).unwrap())));
        let mut frame = encode(FrameKind::Cloud, &m).unwrap();
        let three = 3.0f64.to_le_bytes();
        let at = frame.windows(8).position(|w| w == three).unwrap();
        for bad in [f64::NAN, 0.0, 1e9] {
            frame.splice(at..at + 8, bad.to_le_bytes());
            let mut signed = frame.clone();
            signed.extend(key().sign(&frame).to_bytes());
            assert!(matches!(cmd(&mut rx(), &signed, 5_000), Err(LinkError::Decode(_))), "{bad}");
        }
    }

    #[test]
    fn a_signed_prior_with_tau_out_of_range_does_not_decode() {
        let mut frame = encode(FrameKind::Cloud, &msg(3, 5_000, CloudBody::Prior(prior()))).unwrap();
        let two = 2.0f64.to_le_bytes();
        let at = frame.windows(8).rposition(|w| w == two).unwrap();
        assert_eq!(at + 8 + 1, frame.len(), "τ is the prior's last number, its style the last byte");
        for bad in [f64::NAN, 0.0, 45.0] {
            frame.splice(at..at + 8, bad.to_le_bytes());
            let mut signed = frame.clone();
            signed.extend(key().sign(&frame).to_bytes());
            let e = rx().open(&signed, Arrival::Prior, 5_000).unwrap_err();
            assert!(matches!(e.reason, LinkError::Decode(_)), "{bad}: {}", e.reason);
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(300))]

        #[test]
        fn random_bytes_never_panic_and_never_pass(bytes in proptest::collection::vec(any::<u8>(), 0..400), prefix in any::<bool>()) {
            let mut frame = bytes;
            if prefix {
                let mut f = header(FrameKind::Cloud).to_vec();
                f.extend(frame);
                frame = f;
            }
            for arrival in [Arrival::Prior, Arrival::Command, Arrival::AllCommand] {
                prop_assert!(rx().open(&frame, arrival, 0).is_err());
            }
            let _ = read_report(&frame);
        }

        #[test]
        fn set_target_round_trips(tau in 0.5f64..10.0, rush in any::<bool>(), seq in 1u64..u64::MAX) {
            let style = if rush { Style::Rush } else { Style::Yield };
            let m = msg(seq, 5_000, CloudBody::Command(Command::SetTarget(Target::new(tau, style).unwrap())));
            prop_assert_eq!(cmd(&mut rx(), &seal(&m, &key()).unwrap(), 5_000).unwrap(), m);
        }
    }
}
