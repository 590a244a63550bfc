//! The IPC payloads. All `#[repr(C)]`, fixed size, self-contained.

use iceoryx2::prelude::ZeroCopySend;
use iceoryx2_bb_container::vector::{StaticVec, Vector};

use crate::{Code as _, Header};

/// Most points of a path in an [`ActivePrior`].
pub const MAX_PATH_POINTS: usize = 512;
/// Most samples of a speed profile in an [`ActivePrior`].
pub const MAX_PROFILE_SAMPLES: usize = 512;

/// Most points of a learned route in a [`CampaignKnowledge`] (1,000 m every 2 m, the regulator's
/// longest record).
pub const MAX_ROUTE_POINTS: usize = 501;
/// Most hypotheses of a reaction posterior in a [`CampaignKnowledge`].
pub const MAX_REACTION_HYPOTHESES: usize = 64;

/// What a test campaign has learned of the VUT for the run around the active prior
/// ([`crate::link::CampaignUpload`] as the BV keeps it): fixed size, each part flagged.
#[derive(Debug, Clone, PartialEq, Default, ZeroCopySend)]
#[repr(C)]
pub struct CampaignKnowledge {
    /// The sequence of the cloud message that brought it; 0: none (the prior as uploaded).
    pub seq: u64,
    /// What earlier runs showed about reach: a [`crate::BelowReachCode`], 0 when nothing.
    pub below_reach: u8,
    /// 1 when `pet_bound_s` holds a value.
    pub has_pet_bound: u8,
    /// 1 when the `route_*` fields hold a learned route.
    pub has_route: u8,
    /// 1 when the `reaction_*` fields hold a posterior.
    pub has_reaction: u8,
    /// Valid runs the route rests on.
    pub route_runs: u32,
    /// Cycles that taught the posterior something.
    pub reaction_informative_cycles: u32,
    /// With `below_reach`: the PET the VUT allows as far as known, s.
    pub pet_bound_s: f64,
    /// Grid spacing of the route, m.
    pub route_step_m: f64,
    /// The VUT's speed at each grid point of its route, m/s.
    pub route_speeds_mps: StaticVec<f64, MAX_ROUTE_POINTS>,
    /// Probability of each hypothesis of the VUT's reaction.
    pub reaction_p: StaticVec<f64, MAX_REACTION_HYPOTHESES>,
}

impl CampaignKnowledge {
    /// What `up` says, as the BV keeps it, brought by the cloud message `seq`; `up` is checked
    /// first ([`crate::link::CampaignUpload::check`]).
    pub fn from_upload(up: &crate::link::CampaignUpload, seq: u64) -> Result<Self, crate::link::LinkError> {
        up.check()?;
        let mut k = Self { seq, ..Self::default() };
        if let Some(b) = &up.below_reach {
            k.below_reach = b.cause;
            k.has_pet_bound = u8::from(b.pet_bound_s.is_some());
            k.pet_bound_s = b.pet_bound_s.unwrap_or(0.0);
        }
        if let Some(r) = &up.route {
            k.has_route = 1;
            k.route_runs = r.runs;
            k.route_step_m = r.step_m;
            for &v in &r.speeds_mps {
                // `check` bounds the length by the capacity.
                let _ = k.route_speeds_mps.push(v);
            }
        }
        if let Some(r) = &up.reaction {
            k.has_reaction = 1;
            k.reaction_informative_cycles = r.informative_cycles;
            for &p in &r.probabilities {
                let _ = k.reaction_p.push(p);
            }
        }
        Ok(k)
    }

    /// The learned route: grid spacing, runs, speeds.
    pub fn route(&self) -> Option<(f64, u32, &[f64])> {
        (self.has_route == 1).then(|| (self.route_step_m, self.route_runs, self.route_speeds_mps.as_slice()))
    }

    /// The posterior of the VUT's reaction: probabilities, informative cycles.
    pub fn reaction(&self) -> Option<(&[f64], u32)> {
        (self.has_reaction == 1).then(|| (self.reaction_p.as_slice(), self.reaction_informative_cycles))
    }

    /// What earlier runs showed about reach: the cause's code and the bound.
    pub fn below_reach(&self) -> Option<(u8, Option<f64>)> {
        (self.below_reach != 0).then(|| (self.below_reach, (self.has_pet_bound == 1).then_some(self.pet_bound_s)))
    }
}

/// What one run taught the regulator about the VUT (its route and its reaction, in a
/// [`CampaignKnowledge`] block), published once per run when the VUT has left its zone.
#[derive(Debug, Clone, PartialEq, Default, ZeroCopySend)]
#[repr(C)]
pub struct RunLearnedMsg {
    /// Sequence and when.
    pub header: Header,
    /// The prior of the run.
    pub prior_id: u64,
    /// The τ the run aimed at, s.
    pub tau_s: f64,
    /// Its style ([`crate::StyleCode`] code).
    pub style: u8,
    /// 1 when the run started from a learned route.
    pub started_with_route: u8,
    /// 1 when it started from an earlier identification of the VUT's reaction.
    pub started_with_reaction: u8,
    /// The route as measured and the identification at the end (its `seq` unused).
    pub learned: CampaignKnowledge,
}

/// A point in the track frame, m.
#[derive(Debug, Clone, Copy, PartialEq, Default, ZeroCopySend)]
#[repr(C)]
pub struct Vec2 {
    /// East, m.
    pub x_m: f64,
    /// North, m.
    pub y_m: f64,
}

/// Pose and speed from the BV's GNSS/INS (in simulation: from the simulated ECU).
#[derive(Debug, Clone, Copy, PartialEq, Default, ZeroCopySend)]
#[repr(C)]
pub struct Localization {
    /// Sequence and time of the fix.
    pub header: Header,
    /// East, m.
    pub px_m: f64,
    /// North, m.
    pub py_m: f64,
    /// Heading, rad, counter-clockwise from east.
    pub theta_rad: f64,
    /// Speed over ground, m/s.
    pub speed_mps: f64,
    /// 1 when the fix is usable.
    pub valid: u8,
}

impl Localization {
    /// Every number finite.
    pub fn is_finite(&self) -> bool {
        [self.px_m, self.py_m, self.theta_rad, self.speed_mps].iter().all(|v| v.is_finite())
    }
}

/// What the drive-by-wire system reports over CAN, decoded by the gateway.
#[derive(Debug, Clone, Copy, PartialEq, Default, ZeroCopySend)]
#[repr(C)]
pub struct VehicleFeedback {
    /// Sequence and time the frame was received.
    pub header: Header,
    /// Wheel speed, m/s.
    pub wheel_speed_mps: f64,
    /// Yaw rate, rad/s.
    pub yaw_rate_radps: f64,
    /// Road-wheel angle, rad.
    pub steer_rad: f64,
    /// [`crate::DbwMode`] code.
    pub mode: u8,
}

/// The BV's own state, fused by the state node.
#[derive(Debug, Clone, Copy, PartialEq, Default, ZeroCopySend)]
#[repr(C)]
pub struct BvState {
    /// Sequence, and the time of the localization fix the state is built on.
    pub header: Header,
    /// East, m.
    pub px_m: f64,
    /// North, m.
    pub py_m: f64,
    /// Heading, rad.
    pub theta_rad: f64,
    /// Speed, m/s (wheel speed when fresh, else localization).
    pub speed_mps: f64,
    /// Yaw rate, rad/s.
    pub yaw_rate_radps: f64,
    /// Road-wheel angle, rad.
    pub steer_rad: f64,
    /// When the state node received the fix (start of the state-in → CAN-out latency).
    pub received_ns: u64,
    /// When the CAN feedback used was received (0: none).
    pub feedback_stamp_ns: u64,
    /// [`crate::DbwMode`] code of the feedback used.
    pub dbw_mode: u8,
}

impl BvState {
    /// Every number finite.
    pub fn is_finite(&self) -> bool {
        self.non_finite().is_none()
    }

    /// The first number that is NaN or infinite, with its name.
    pub fn non_finite(&self) -> Option<(&'static str, f64)> {
        [
            ("bv.px_m", self.px_m),
            ("bv.py_m", self.py_m),
            ("bv.theta_rad", self.theta_rad),
            ("bv.speed_mps", self.speed_mps),
            ("bv.yaw_rate_radps", self.yaw_rate_radps),
            ("bv.steer_rad", self.steer_rad),
        ]
        .into_iter()
        .find(|(_, v)| !v.is_finite())
    }
}

/// The VUT as the BV learns it (V2X, the cloud, or onboard perception).
#[derive(Debug, Clone, Copy, PartialEq, Default, ZeroCopySend)]
#[repr(C)]
pub struct VutState {
    /// Sequence and the time the VUT was at this state.
    pub header: Header,
    /// East, m.
    pub px_m: f64,
    /// North, m.
    pub py_m: f64,
    /// Heading, rad.
    pub theta_rad: f64,
    /// Speed, m/s.
    pub speed_mps: f64,
}

impl VutState {
    /// Every number finite.
    pub fn is_finite(&self) -> bool {
        [self.px_m, self.py_m, self.theta_rad, self.speed_mps].iter().all(|v| v.is_finite())
    }
}

/// One sample of the BV's reference timing along its path.
#[derive(Debug, Clone, Copy, PartialEq, Default, ZeroCopySend)]
#[repr(C)]
pub struct ProfileSample {
    /// Time since the start of the prior, s.
    pub t_s: f64,
    /// Arc length along the BV's path, m.
    pub s_m: f64,
    /// Speed, m/s.
    pub v_mps: f64,
}

/// The prior the BV regulates around: both paths, the conflict zone on each, the BV's reference
/// timing, the target PET and the style.
#[derive(Debug, Clone, PartialEq, Default, ZeroCopySend)]
#[repr(C)]
pub struct ActivePrior {
    /// Sequence and the time the prior was issued.
    pub header: Header,
    /// Identifies the prior (changes whenever its content does).
    pub prior_id: u64,
    /// Target PET τ, s.
    pub tau_s: f64,
    /// [`crate::StyleCode`] code.
    pub style: u8,
    /// [`crate::ZoneKind`] code.
    pub zone_kind: u8,
    /// The BV's footprint is in the zone between these arc lengths of its path, m.
    pub bv_zone_enter_s_m: f64,
    /// See `bv_zone_enter_s_m`.
    pub bv_zone_exit_s_m: f64,
    /// The VUT's footprint is in the zone between these arc lengths of its path, m.
    pub vut_zone_enter_s_m: f64,
    /// See `vut_zone_enter_s_m`.
    pub vut_zone_exit_s_m: f64,
    /// The BV's reference path.
    pub bv_path: StaticVec<Vec2, MAX_PATH_POINTS>,
    /// The VUT's expected route.
    pub vut_path: StaticVec<Vec2, MAX_PATH_POINTS>,
    /// The VUT's speed at the start of `vut_path` in the prior, m/s (the simulated proving ground
    /// starts its VUT with it).
    pub vut_speed_mps: f64,
    /// The BV's reference timing along `bv_path`.
    pub bv_profile: StaticVec<ProfileSample, MAX_PROFILE_SAMPLES>,
    /// 1 when `bv_stop_line_s_m` holds a value (the map gave the junction's edge on the BV's lane).
    pub has_bv_stop_line: u8,
    /// Where the BV's centre stands when it gives way at this crossing: its front just before the
    /// junction's edge on its lane, m along `bv_path`.
    pub bv_stop_line_s_m: f64,
    /// What a test campaign has learned of the VUT for this run (`seq` 0: nothing; the uplink
    /// sets it, a prior is uploaded without).
    pub campaign: CampaignKnowledge,
    /// Which run of this prior it stands for: 0 as uploaded, one more each time the BV is armed
    /// with the prior active (the uplink counts). A new run starts from what the prior and its
    /// campaign block say, nothing of the run before.
    pub run: u64,
}

impl ActivePrior {
    /// τ and the style, decoded and range-checked.
    pub fn target(&self) -> Result<v2t_model::Target, PriorCodeError> {
        let style = crate::StyleCode::from_code(self.style)?;
        Ok(v2t_model::Target::new(self.tau_s, style.into())?)
    }

    /// Sets τ and the style.
    pub fn set_target(&mut self, target: v2t_model::Target) {
        self.tau_s = target.tau_s();
        self.style = crate::StyleCode::from(target.style()).code();
    }

    /// The stop line of a BV that gives way, when the prior has one.
    pub fn bv_stop_line(&self) -> Option<f64> {
        (self.has_bv_stop_line == 1).then_some(self.bv_stop_line_s_m)
    }

    /// Sets (or clears) the stop line of a BV that gives way.
    pub fn set_bv_stop_line(&mut self, s_m: Option<f64>) {
        self.has_bv_stop_line = u8::from(s_m.is_some());
        self.bv_stop_line_s_m = s_m.unwrap_or(0.0);
    }

    /// Every number finite, both paths with at least two points, intervals ordered, τ in range,
    /// a stop line (when there is one) before the BV's zone.
    pub fn check(&self) -> Result<(), &'static str> {
        let numbers = [
            self.tau_s,
            self.bv_zone_enter_s_m,
            self.bv_zone_exit_s_m,
            self.vut_zone_enter_s_m,
            self.vut_zone_exit_s_m,
            self.vut_speed_mps,
        ];
        if !numbers.iter().all(|v| v.is_finite()) {
            return Err("non-finite target or zone interval");
        }
        if self.vut_speed_mps < 0.0 {
            return Err("negative VUT speed");
        }
        if v2t_model::Target::check_tau("tau_s", self.tau_s).is_err() {
            return Err("target PET out of range");
        }
        if !(self.bv_zone_enter_s_m < self.bv_zone_exit_s_m && self.vut_zone_enter_s_m < self.vut_zone_exit_s_m) {
            return Err("zone interval with enter >= exit");
        }
        if self.has_bv_stop_line > 1 {
            return Err("stop-line flag neither 0 nor 1");
        }
        if let Some(line) = self.bv_stop_line()
            && !(line.is_finite() && line < self.bv_zone_enter_s_m)
        {
            return Err("stop line not finite or not before the BV's zone");
        }
        if self.bv_path.len() < 2 || self.vut_path.len() < 2 {
            return Err("path with fewer than two points");
        }
        let finite_path = |p: &[Vec2]| p.iter().all(|q| q.x_m.is_finite() && q.y_m.is_finite());
        if !finite_path(self.bv_path.as_slice()) || !finite_path(self.vut_path.as_slice()) {
            return Err("non-finite path point");
        }
        let finite_profile =
            self.bv_profile.as_slice().iter().all(|q| q.t_s.is_finite() && q.s_m.is_finite() && q.v_mps.is_finite());
        if !finite_profile {
            return Err("non-finite profile sample");
        }
        if self.bv_profile.as_slice().windows(2).any(|w| matches!(w, [a, b] if b.t_s <= a.t_s)) {
            return Err("profile times not increasing");
        }
        Ok(())
    }
}

/// A prior whose target or zone kind does not decode.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PriorCodeError {
    /// An unknown style or zone-kind code.
    #[error(transparent)]
    Code(#[from] crate::CodeError),
    /// τ out of range.
    #[error(transparent)]
    Target(#[from] v2t_model::TargetError),
}

/// What the regulator decided from one BV state.
#[derive(Debug, Clone, Copy, PartialEq, Default, ZeroCopySend)]
#[repr(C)]
pub struct RegulatedPlan {
    /// Sequence; stamp = the stamp of the BV state the plan starts from.
    pub header: Header,
    /// Sequence of that BV state.
    pub state_seq: u64,
    /// The prior regulated around (0: none).
    pub prior_id: u64,
    /// [`crate::PlanStatus`] code.
    pub status: u8,
    /// 1 when `predicted_pet_s` holds a value.
    pub has_predicted_pet: u8,
    /// τ out of the VUT's reach: a [`crate::BelowReachCode`], 0 when nothing says so.
    pub below_reach: u8,
    /// 1 when `pet_bound_s` holds a value.
    pub has_pet_bound: u8,
    /// 1 when the `vut_*` fields hold how the VUT is identified to react to the BV this run.
    pub has_reaction: u8,
    /// The BV's arc length along its path at the stamp, m.
    pub s0_m: f64,
    /// Speed at the stamp, m/s.
    pub v0_mps: f64,
    /// Acceleration to hold from the stamp on, m/s².
    pub accel_mps2: f64,
    /// Predicted PET, s.
    pub predicted_pet_s: f64,
    /// With `below_reach`: the PET this VUT allows as far as known, s.
    pub pet_bound_s: f64,
    /// With `has_reaction`: probability that the VUT reacts to the BV at all.
    pub vut_reacts_p: f64,
    /// With `has_reaction`: the gap the VUT is identified to accept (expected over the reacting
    /// hypotheses), s.
    pub vut_gap_s: f64,
    /// With `has_reaction`: its standard deviation, s.
    pub vut_gap_sd_s: f64,
    /// CPU time of the decision, ns.
    pub solve_ns: u64,
}

/// The tracker's request to the gateway.
#[derive(Debug, Clone, Copy, PartialEq, Default, ZeroCopySend)]
#[repr(C)]
pub struct ActuationCommand {
    /// Sequence and the time it was computed.
    pub header: Header,
    /// Sequence of the plan followed.
    pub plan_seq: u64,
    /// Sequence of the BV state it was computed from.
    pub state_seq: u64,
    /// Stamp of that BV state (the start of the state-in → CAN-out latency).
    pub state_stamp_ns: u64,
    /// When the state node received the fix behind that BV state.
    pub state_received_ns: u64,
    /// Requested acceleration, m/s².
    pub accel_mps2: f64,
    /// Requested road-wheel angle, rad.
    pub steer_rad: f64,
    /// Cross-track error, m (positive: left of the path).
    pub cross_track_m: f64,
    /// Speed error (reference − measured), m/s.
    pub speed_error_mps: f64,
}

/// A request to the gateway from the monitor or the operator.
#[derive(Debug, Clone, Copy, PartialEq, Default, ZeroCopySend)]
#[repr(C)]
pub struct SafetyCommand {
    /// Sequence and time of the request.
    pub header: Header,
    /// [`crate::SafetyAction`] code.
    pub action: u8,
    /// [`crate::NodeKind`] code of the node whose failure caused it (0: none).
    pub culprit: u8,
}

/// What the gateway sent and why.
#[derive(Debug, Clone, Copy, PartialEq, Default, ZeroCopySend)]
#[repr(C)]
pub struct GateReport {
    /// Sequence and time of the last transmission.
    pub header: Header,
    /// [`crate::GateState`] code.
    pub state: u8,
    /// [`crate::GateReason`] code.
    pub reason: u8,
    /// Acceleration sent, m/s².
    pub accel_sent_mps2: f64,
    /// Road-wheel angle sent, rad.
    pub steer_sent_rad: f64,
    /// Command frames written to the bus.
    pub frames_tx: u64,
    /// Frames received and accepted.
    pub frames_rx: u64,
    /// Frames received and rejected (checksum, counter, range, unknown id).
    pub frames_rejected: u64,
    /// Bus errors seen.
    pub bus_errors: u64,
    /// 1 when this transmission carried a new tracker command (0: a repeat or the gate's own profile).
    pub fresh_command: u8,
    /// `state_received_ns` of the command sent (latency: `header.stamp_ns − state_received_ns`).
    pub state_received_ns: u64,
}

/// A node's liveness and timing.
#[derive(Debug, Clone, Copy, PartialEq, Default, ZeroCopySend)]
#[repr(C)]
pub struct Heartbeat {
    /// Sequence and time.
    pub header: Header,
    /// [`crate::NodeKind`] code.
    pub node: u8,
    /// 1 when the node's inputs are healthy.
    pub inputs_ok: u8,
    /// Cycles completed.
    pub cycles: u64,
    /// Cycles that overran their period.
    pub deadline_misses: u64,
    /// Longest cycle so far, ns.
    pub max_cycle_ns: u64,
}

/// A raw classic CAN frame on the virtual bus that stands in for SocketCAN where the kernel has none.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, ZeroCopySend)]
#[repr(C)]
pub struct CanFrameMsg {
    /// Sequence and the time the frame was put on the bus.
    pub header: Header,
    /// 11-bit identifier.
    pub id: u32,
    /// Data length, 0–8.
    pub len: u8,
    /// Data bytes.
    pub data: [u8; 8],
}

#[cfg(test)]
mod tests {
    use super::*;

    fn prior() -> ActivePrior {
        let mut p = ActivePrior {
            tau_s: 2.0,
            bv_zone_enter_s_m: 10.0,
            bv_zone_exit_s_m: 15.0,
            vut_zone_enter_s_m: 30.0,
            vut_zone_exit_s_m: 36.0,
            ..ActivePrior::default()
        };
        for i in 0..3 {
            let q = Vec2 { x_m: i as f64, y_m: 0.0 };
            p.bv_path.push(q).unwrap();
            p.vut_path.push(q).unwrap();
            p.bv_profile.push(ProfileSample { t_s: i as f64, s_m: i as f64, v_mps: 1.0 }).unwrap();
        }
        p
    }

    #[test]
    fn a_well_formed_prior_passes_its_check() {
        assert_eq!(prior().check(), Ok(()));
    }

    #[test]
    fn malformed_priors_are_rejected_with_a_reason() {
        let mut p = prior();
        p.tau_s = f64::NAN;
        assert_eq!(p.check(), Err("non-finite target or zone interval"));
        let mut p = prior();
        p.tau_s = 0.0;
        assert_eq!(p.check(), Err("target PET out of range"));
        assert!(p.target().is_err());
        let mut p = prior();
        p.style = 9;
        assert_eq!(p.target().unwrap_err().to_string(), "unknown style code 9");
        p.set_target(v2t_model::Target::new(3.5, v2t_model::Style::Yield).unwrap());
        assert_eq!(p.target().unwrap(), v2t_model::Target::new(3.5, v2t_model::Style::Yield).unwrap());
        let mut p = prior();
        p.vut_zone_exit_s_m = 20.0;
        assert_eq!(p.check(), Err("zone interval with enter >= exit"));
        // A stop line is optional, and when there is one it lies before the BV's zone.
        let mut p = prior();
        p.set_bv_stop_line(Some(4.0));
        assert_eq!((p.check(), p.bv_stop_line()), (Ok(()), Some(4.0)));
        p.set_bv_stop_line(None);
        assert_eq!((p.check(), p.bv_stop_line(), p.has_bv_stop_line), (Ok(()), None, 0));
        for bad in [10.0, 12.0, f64::NAN, f64::NEG_INFINITY] {
            p.set_bv_stop_line(Some(bad));
            assert_eq!(p.check(), Err("stop line not finite or not before the BV's zone"), "{bad}");
        }
        p.has_bv_stop_line = 2;
        assert_eq!(p.check(), Err("stop-line flag neither 0 nor 1"));
        let mut p = prior();
        p.bv_path.clear();
        assert_eq!(p.check(), Err("path with fewer than two points"));
        let mut p = prior();
        p.vut_path.push(Vec2 { x_m: f64::INFINITY, y_m: 0.0 }).unwrap();
        assert_eq!(p.check(), Err("non-finite path point"));
        let mut p = prior();
        p.bv_profile.push(ProfileSample { t_s: 1.0, s_m: 3.0, v_mps: 1.0 }).unwrap();
        assert_eq!(p.check(), Err("profile times not increasing"));
    }

    #[test]
    fn a_full_path_refuses_more_points() {
        let mut p = ActivePrior::default();
        for i in 0..MAX_PATH_POINTS {
            p.bv_path.push(Vec2 { x_m: i as f64, y_m: 0.0 }).unwrap();
        }
        assert!(p.bv_path.push(Vec2::default()).is_err());
    }

    #[test]
    fn header_age_never_goes_negative() {
        let h = Header { seq: 1, stamp_ns: 2_000_000_000 };
        assert!((h.age_s(2_500_000_000) - 0.5).abs() < 1e-12);
        assert_eq!(h.age_s(1_000_000_000), 0.0);
    }
}
