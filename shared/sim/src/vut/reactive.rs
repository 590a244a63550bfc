//! A reactive driver: cruise control that reacts to predicted conflicts after a perception-reaction
//! delay.
//!
//! The driver keeps a buffer of what it perceived of the BVs and decides on the perception of
//! `reaction_time_s` ago (the oldest one until that much history exists), taken at face value,
//! together with its own current state. So it reacts late, and then sharply:
//!
//! - **Cruise**: P control toward the desired speed capped by the curvature ahead.
//! - **Crossing zones**: constant-velocity entry and exit times of both vehicles give a predicted
//!   PET. Below `pet_threshold_s`, with the BV arriving first or within `simultaneous_window_s` of
//!   the VUT, the driver yields: it aims to reach its stop point before the zone no earlier than the
//!   BV's predicted exit plus `yield_margin_s` (speed target = distance / time, capped by a braking
//!   profile to the stop point), with P control of gain `brake_gain` and braking up to
//!   `max_brake_mps2`. The decision stands until the (delayed) perception shows the BV out of the
//!   zone. A VUT clearly first, already in the zone or unable to stop before it keeps going.
//! - **Lead vehicle**: TTC on the bumper gap below `ttc_threshold_s` brakes in proportion to how far
//!   below it is (at least the deceleration that matches the lead's speed within the gap); inside
//!   the desired headway the speed target follows the lead's.
//!
//! Lateral control is pure pursuit on the route.

use std::collections::VecDeque;

use v2t_model::metrics::{ConflictKind, ConflictZone, ttc_1d};

use super::VutDriver;
use super::common::{STOP_MARGIN_M, STOPPED_MPS, fallback, finish, inputs_finite, lead_vehicle, speed_cap};
use crate::observation::{Perceived, VutObservation};
use crate::plant::ActuationRequest;

/// Tolerance on observation times, s.
const TIME_EPS_S: f64 = 1e-6;
/// Deceleration of the braking profile that caps the yield speed target, m/s².
const STOP_PROFILE_DECEL_MPS2: f64 = 3.0;
/// The VUT's own speed is at least this in its constant-velocity arrival estimate, m/s.
const MIN_PREDICTION_SPEED_MPS: f64 = 0.5;
/// Smallest gap used when computing the deceleration that matches a lead's speed, m.
const MIN_MATCH_GAP_M: f64 = 0.5;

/// Reactive driver parameters.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReactiveParams {
    /// Age of the BV perception the driver acts on, s.
    pub reaction_time_s: f64,
    /// A predicted PET below this is a threat, s.
    pub pet_threshold_s: f64,
    /// A lead-vehicle TTC below this is a threat, s.
    pub ttc_threshold_s: f64,
    /// Gain of the cruise speed controller, 1/s.
    pub cruise_gain: f64,
    /// Gain of the yield and follow speed controllers, 1/s.
    pub brake_gain: f64,
    /// Strongest braking the driver requests, m/s².
    pub max_brake_mps2: f64,
    /// Strongest acceleration the driver requests, m/s².
    pub max_accel_mps2: f64,
    /// The VUT aims to reach a zone this long after the BV's predicted exit, s.
    pub yield_margin_s: f64,
    /// Entries closer than this count as simultaneous even with the VUT first, s.
    pub simultaneous_window_s: f64,
    /// Desired time headway to a lead vehicle, s.
    pub time_gap_s: f64,
    /// Desired standstill gap to a lead vehicle, m.
    pub min_gap_m: f64,
}

impl Default for ReactiveParams {
    /// `config/vut/builtin/reactive.toml`.
    fn default() -> Self {
        super::builtin::reactive()
    }
}

/// The reactive driver (see the module documentation).
#[derive(Debug, Clone)]
pub struct ReactiveDriver {
    params: ReactiveParams,
    /// `(time, BVs as perceived then)`, oldest first; the front is the one acted upon.
    history: VecDeque<(f64, Vec<Perceived>)>,
    /// A buffer dropped from the history, reused for the next observation.
    spare: Vec<Perceived>,
    /// Per conflict (in `scenario.conflicts` order): yielding until the BV is seen out of the zone.
    yielding: Vec<bool>,
}

impl ReactiveDriver {
    /// A driver with these parameters.
    pub fn new(params: ReactiveParams) -> Self {
        Self { params, history: VecDeque::new(), spare: Vec::new(), yielding: Vec::new() }
    }

    /// The parameters.
    pub fn params(&self) -> &ReactiveParams {
        &self.params
    }

    /// Stores this observation and drops the ones older than the one to act upon.
    fn remember(&mut self, obs: &VutObservation<'_>) {
        if self.history.back().is_some_and(|(t, _)| *t > obs.t_s) {
            // Time went backwards: a new run.
            self.history.clear();
            self.yielding.clear();
        }
        let mut bvs = std::mem::take(&mut self.spare);
        bvs.clear();
        bvs.extend_from_slice(obs.bvs);
        self.history.push_back((obs.t_s, bvs));
        let cutoff = obs.t_s - self.params.reaction_time_s.max(0.0) + TIME_EPS_S;
        while self.history.get(1).is_some_and(|(t, _)| *t <= cutoff) {
            if let Some((_, old)) = self.history.pop_front() {
                self.spare = old;
            }
        }
    }
}

/// The speed target that yields at `zone` to `bv` (perceived `reaction_time_s` ago), if the
/// situation calls for it; updates the latch `yielding`.
fn yield_target(
    p: &ReactiveParams,
    zone: &ConflictZone,
    bv: &Perceived,
    own: &Perceived,
    yielding: &mut bool,
) -> Option<f64> {
    let (s, v) = (own.s_m, own.state.speed_mps.max(0.0));
    let v_b = bv.state.speed_mps.max(0.0);
    let bv_gone = bv.s_m >= zone.bv.exit_s_m;
    let bv_stays_out = v_b < STOPPED_MPS && bv.s_m < zone.bv.enter_s_m;
    let cannot_stop = v * v / (2.0 * p.max_brake_mps2.max(0.1)) > zone.vut.enter_s_m - s;
    if bv_gone || bv_stays_out || s >= zone.vut.enter_s_m || (cannot_stop && !*yielding) {
        *yielding = false;
        return None;
    }
    let (t_in_b, t_out_b) = if v_b < STOPPED_MPS {
        (0.0, f64::INFINITY) // Standing inside the zone.
    } else {
        ((zone.bv.enter_s_m - bv.s_m).max(0.0) / v_b, (zone.bv.exit_s_m - bv.s_m) / v_b)
    };
    if !*yielding {
        let v_pred = v.max(MIN_PREDICTION_SPEED_MPS);
        let t_in_v = (zone.vut.enter_s_m - s) / v_pred;
        let t_out_v = (zone.vut.exit_s_m - s) / v_pred;
        let bv_first = t_in_b < t_in_v;
        let pet = if bv_first { t_in_v - t_out_b } else { t_in_b - t_out_v };
        *yielding = pet < p.pet_threshold_s && (bv_first || t_in_b - t_in_v < p.simultaneous_window_s);
    }
    if !*yielding {
        return None;
    }
    let d = (zone.vut.enter_s_m - STOP_MARGIN_M - s).max(0.0);
    let arrive_after = t_out_b + p.yield_margin_s;
    let target = if arrive_after.is_finite() { d / arrive_after.max(TIME_EPS_S) } else { 0.0 };
    Some(target.min((2.0 * STOP_PROFILE_DECEL_MPS2 * d).sqrt()))
}

impl VutDriver for ReactiveDriver {
    fn name(&self) -> &str {
        "reactive"
    }

    fn control(&mut self, obs: &VutObservation<'_>) -> ActuationRequest {
        if !inputs_finite(obs) {
            return fallback(obs);
        }
        self.remember(obs);
        if self.yielding.len() != obs.scenario.conflicts.len() {
            self.yielding = vec![false; obs.scenario.conflicts.len()];
        }
        let p = self.params;
        let bvs: &[Perceived] = self.history.front().map_or(&[], |(_, b)| b.as_slice());
        let v = obs.own.state.speed_mps.max(0.0);
        let brake_limit = |a: f64| a.max(-p.max_brake_mps2);

        let cruise = speed_cap(obs, STOP_PROFILE_DECEL_MPS2);
        let mut accel = brake_limit(p.cruise_gain * (cruise - v));
        for (c, yielding) in obs.scenario.conflicts.iter().zip(self.yielding.iter_mut()) {
            // At a merge the BV ends up in the VUT's lane: the lead-vehicle rule below handles it;
            // yielding to it at the merge point as if it crossed would stall the VUT behind a BV
            // that is waiting for it.
            if c.zone.kind != ConflictKind::Crossing {
                continue;
            }
            let Some(bv) = bvs.get(c.bv_index) else { continue };
            if let Some(target) = yield_target(&p, &c.zone, bv, &obs.own, yielding) {
                accel = accel.min(brake_limit(p.brake_gain * (target - v)));
            }
        }
        if let Some(lead) = lead_vehicle(obs.scenario, &obs.own, bvs) {
            let closing = v - lead.speed_mps;
            if let Some(ttc) = ttc_1d(lead.gap_m, closing, 0.0).filter(|t| *t < p.ttc_threshold_s) {
                let proportional = p.max_brake_mps2 * (1.0 - ttc / p.ttc_threshold_s.max(TIME_EPS_S));
                let matching = closing * closing / (2.0 * lead.gap_m.max(MIN_MATCH_GAP_M));
                accel = accel.min(-proportional.max(matching));
            }
            let desired_gap = p.min_gap_m + p.time_gap_s * v;
            if lead.gap_m < desired_gap {
                let target = (lead.speed_mps + (lead.gap_m - desired_gap) / p.time_gap_s.max(TIME_EPS_S)).max(0.0);
                accel = accel.min(p.brake_gain * (target - v));
            }
            accel = brake_limit(accel);
        }
        finish(obs, accel, p.max_accel_mps2)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::vut::common::fixtures::{
        BV_SLIGHTLY_FIRST, VUT_SPEED, assert_brakes_on_nan, closed_loop_crossing, crossing, crossing_bv_at, cut_in,
        observe, vut_at,
    };
    use v2t_model::kinematics::State;

    #[test]
    fn reacts_only_after_its_reaction_time() {
        let sc = crossing(BV_SLIGHTLY_FIRST);
        let mut d = ReactiveDriver::new(ReactiveParams::default());
        // Standing at the start of its route until t = 1 s, then (teleported) arriving just before the VUT.
        let parked = [crossing_bv_at(0.0, 0.0)];
        let mut first_reaction = None;
        for k in 0..30 {
            let t = k as f64 * 0.1;
            let s_vut = VUT_SPEED * t;
            let threat = [crossing_bv_at(BV_SLIGHTLY_FIRST * t, BV_SLIGHTLY_FIRST)];
            let bvs: &[Perceived] = if t < 1.0 - 1e-9 { &parked } else { &threat };
            let r = d.control(&observe(&sc, t, vut_at(s_vut, VUT_SPEED), bvs));
            assert!(r.is_finite());
            if r.accel_mps2 < -1.0 && first_reaction.is_none() {
                first_reaction = Some(t);
            }
            if first_reaction.is_none() {
                assert!(r.accel_mps2.abs() < 1e-9, "t = {t}: {r:?}");
            }
        }
        let t = first_reaction.unwrap();
        assert!((t - 1.8).abs() < 1e-6, "reacted at {t}");
        // Once it reacts, it reacts hard.
        let late = d.control(&observe(&sc, 3.0, vut_at(30.0, VUT_SPEED), &[crossing_bv_at(25.5, BV_SLIGHTLY_FIRST)]));
        assert!(late.accel_mps2 < -3.0, "{late:?}");
    }

    #[test]
    fn keeps_going_when_clearly_first_or_the_road_is_empty() {
        let sc = crossing(BV_SLIGHTLY_FIRST);
        let zone = sc.conflicts[0].zone;
        let mut d = ReactiveDriver::new(ReactiveParams { reaction_time_s: 0.0, ..ReactiveParams::default() });
        // The VUT clears the zone 1 s before the BV enters: PET 1 s, but the VUT is clearly first.
        let t_out = zone.vut.exit_s_m / VUT_SPEED;
        let t_in_v = zone.vut.enter_s_m / VUT_SPEED;
        let t_in_b = t_out + 1.0;
        assert!(t_in_b - t_in_v > 1.0);
        let bv = [crossing_bv_at(zone.bv.enter_s_m - 8.0 * t_in_b, 8.0)];
        assert!(d.control(&observe(&sc, 0.0, vut_at(0.0, VUT_SPEED), &bv)).accel_mps2.abs() < 1e-9);
        assert!(d.control(&observe(&sc, 0.1, vut_at(0.0, 6.0), &[])).accel_mps2 > 1.0);
    }

    #[test]
    fn brakes_for_a_close_slow_lead() {
        let sc = cut_in();
        let mut d = ReactiveDriver::new(ReactiveParams { reaction_time_s: 0.0, ..ReactiveParams::default() });
        let far = Perceived {
            state: State { px: 80.0, py: 0.0, theta_rad: 0.0, speed_mps: 5.0 },
            s_m: 80.0,
            l_m: 0.0,
            age_s: 0.0,
        };
        let near = Perceived { state: State { px: 15.0, ..far.state }, ..far };
        let a_far = d.control(&observe(&sc, 0.0, vut_at(0.0, VUT_SPEED), &[far])).accel_mps2;
        let a_near = d.control(&observe(&sc, 0.1, vut_at(0.0, VUT_SPEED), &[near])).accel_mps2;
        assert!(a_far.abs() < 1e-9, "{a_far}");
        assert!(a_near <= -3.0, "{a_near}");
    }

    #[test]
    fn non_finite_inputs_brake_moderately() {
        assert_brakes_on_nan(&mut ReactiveDriver::new(ReactiveParams::default()));
    }

    #[test]
    fn closed_loop_crossing_has_no_collision() {
        let r = closed_loop_crossing(&mut ReactiveDriver::new(ReactiveParams::default()));
        assert!(r.collision.is_none(), "{r:?}");
        assert!(r.pet_min_s.is_some_and(|p| p > 0.3), "{r:?}");
    }
}
