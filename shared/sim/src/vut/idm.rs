//! Intelligent Driver Model with gap acceptance at crossing conflicts.
//!
//! Longitudinal control is the IDM (Treiber, Hennecke & Helbing, 2000; [`v2t_model::driving::Idm`]):
//! `a = a_max [1 − (v/v0)^δ − (s*/s)²]` with `s* = s0 + max(0, v T + v Δv / (2 √(a_max b)))`,
//! where `v0` is the desired speed capped by the route's curvature ahead, taken against the most
//! restrictive of these obstacles (the smallest acceleration wins):
//!
//! - the **lead vehicle**: the nearest BV whose perceived position projects into the VUT's lane
//!   (`|l| < 1.6 m` on the VUT's route) ahead of it, at bumper-to-bumper gap. Against vehicles the
//!   IDM is blended with the constant-acceleration heuristic (the "enhanced IDM" of Kesting,
//!   Treiber & Helbing, 2010, coolness 0.99, [`v2t_model::driving::Idm::enhanced_accel`]) so that
//!   a close cut-in of a faster BV does not trigger the plain IDM's emergency braking;
//! - a BV **merging** ahead (merge zones): before it reaches the VUT's corridor the VUT eases off if
//!   it is alongside or closer than the safe gap; once it reaches the corridor it is followed;
//! - a **standing obstacle** just before each crossing zone at which the VUT yields.
//!
//! Gap acceptance at a crossing zone: the BV's entry and exit times come from its perceived arc
//! length and speed at constant velocity (compensated for the measurement's age), the VUT's from
//! accelerating at `a_max` toward `v0`. The VUT goes if it clears the zone at least
//! `critical_gap_s` before the BV enters, or if the BV clears it at least `commit_margin_s` before
//! the VUT enters (a BV standing before its zone counts as never coming); otherwise it yields.
//! Having chosen to go, it commits once it can no longer stop before the zone at the comfortable
//! deceleration, and then never yields there again; before that a hysteresis of 0.3 s keeps it from
//! flip-flopping. Lateral control is pure pursuit on the route.
//!

use v2t_model::driving::{Idm, Obstacle, travel_time};
use v2t_model::metrics::{ConflictKind, ConflictZone};

use super::VutDriver;
use super::common::{
    LANE_HALF_WIDTH_M, STOP_MARGIN_M, STOPPED_MPS, fallback, finish, half_extent, inputs_finite, lead_vehicle,
    speed_cap,
};
use crate::observation::{Perceived, VutObservation};
use crate::plant::ActuationRequest;

/// Gap relief granted to a decision to go that is already taken, s.
const GAP_HYSTERESIS_S: f64 = 0.3;
/// A merging BV is watched from this long before it reaches the VUT's corridor, s.
const MERGE_PREVIEW_S: f64 = 2.0;
/// Easing off for a merging BV decelerates at this fraction of the comfortable deceleration.
const EASE_OFF_FRACTION: f64 = 0.5;

/// IDM and gap-acceptance parameters.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IdmParams {
    /// Desired time headway `T`, s.
    pub desired_time_gap_s: f64,
    /// Standstill gap `s0`, m.
    pub min_gap_m: f64,
    /// Maximum acceleration `a_max`, m/s².
    pub max_accel_mps2: f64,
    /// Comfortable deceleration `b`, m/s².
    pub comfort_decel_mps2: f64,
    /// Free-road exponent `δ`.
    pub accel_exponent: f64,
    /// The VUT goes first only if it clears the zone at least this long before the BV enters, s.
    pub critical_gap_s: f64,
    /// The VUT goes after the BV only if the BV clears the zone at least this long before the VUT
    /// enters, s.
    pub commit_margin_s: f64,
}

impl IdmParams {
    /// Long headway, gentle acceleration, large accepted gaps (`config/vut/builtin/idm-cautious.toml`).
    pub fn cautious() -> Self {
        super::builtin::idm_cautious()
    }

    /// Typical human driver (`config/vut/builtin/idm-normal.toml`).
    pub fn normal() -> Self {
        super::builtin::idm_normal()
    }

    /// Short headway, brisk acceleration, small accepted gaps (`config/vut/builtin/idm-aggressive.toml`).
    pub fn aggressive() -> Self {
        super::builtin::idm_aggressive()
    }

    /// The car-following part: the IDM these parameters drive with.
    pub fn car_following(&self) -> Idm {
        Idm {
            time_gap_s: self.desired_time_gap_s,
            min_gap_m: self.min_gap_m,
            max_accel_mps2: self.max_accel_mps2,
            comfort_decel_mps2: self.comfort_decel_mps2,
            accel_exponent: self.accel_exponent,
        }
    }
}

impl Default for IdmParams {
    fn default() -> Self {
        Self::normal()
    }
}

/// Where the VUT stands with one conflict zone.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
enum Decision {
    /// Not evaluated yet.
    #[default]
    Undecided,
    /// Going, still able to stop comfortably.
    Go,
    /// Yielding: stopping before the zone.
    Yield,
    /// Going and unable to stop comfortably, or already inside: goes through whatever happens.
    Committed,
}

/// The IDM driver (see the module documentation).
#[derive(Debug, Clone)]
pub struct IdmDriver {
    params: IdmParams,
    name: &'static str,
    /// One decision per conflict of the scenario, in `scenario.conflicts` order.
    decisions: Vec<Decision>,
    /// Time of the last observation (time going backwards starts a new run), s.
    last_t_s: f64,
}

impl IdmDriver {
    /// A driver with these parameters; named after its preset when it is one.
    pub fn new(params: IdmParams) -> Self {
        let name = if params == IdmParams::cautious() {
            "idm-cautious"
        } else if params == IdmParams::normal() {
            "idm-normal"
        } else if params == IdmParams::aggressive() {
            "idm-aggressive"
        } else {
            "idm"
        };
        Self { params, name, decisions: Vec::new(), last_t_s: f64::NEG_INFINITY }
    }

    /// The parameters.
    pub fn params(&self) -> &IdmParams {
        &self.params
    }

    /// Updates the decision at crossing `index` and returns the gap to its stop point when yielding.
    fn crossing_gap(
        &mut self,
        index: usize,
        zone: &ConflictZone,
        bv: Option<&Perceived>,
        own: &Perceived,
        v0: f64,
    ) -> Option<f64> {
        let p = self.params;
        let decision = self.decisions.get_mut(index)?;
        let (s, v) = (own.s_m, own.state.speed_mps.max(0.0));
        if s >= zone.vut.enter_s_m || *decision == Decision::Committed {
            *decision = Decision::Committed;
            return None;
        }
        let go = bv.is_none_or(|bv| gap_accepted(&p, zone, bv, s, v, v0, *decision == Decision::Go));
        if go {
            let cannot_stop = v * v / (2.0 * p.comfort_decel_mps2.max(0.1)) > zone.vut.enter_s_m - s;
            *decision = if cannot_stop { Decision::Committed } else { Decision::Go };
            None
        } else {
            *decision = Decision::Yield;
            // The IDM keeps `s0` to a standing obstacle: place it `s0` beyond the stop point.
            Some(zone.vut.enter_s_m - STOP_MARGIN_M - s + p.min_gap_m)
        }
    }

    /// Most restrictive acceleration for BVs merging into the VUT's lane but not yet in it.
    fn merge_accel(&self, obs: &VutObservation<'_>, v: f64, v0: f64) -> f64 {
        let route = &obs.scenario.vut.agent.route;
        let p = &self.params;
        let idm = p.car_following();
        let mut accel = f64::INFINITY;
        for c in obs.scenario.conflicts.iter().filter(|c| c.zone.kind == ConflictKind::Merge) {
            let Some(bv) = obs.bvs.get(c.bv_index) else { continue };
            let v_b = bv.state.speed_mps.max(0.0);
            let b = &c.zone.bv;
            if bv.s_m < b.enter_s_m - v_b * MERGE_PREVIEW_S || bv.s_m > b.exit_s_m {
                continue;
            }
            let Some(f) = route.project(bv.state.position()) else { continue };
            if f.l_m.abs() < LANE_HALF_WIDTH_M {
                continue; // In the lane: the lead-vehicle logic follows it.
            }
            let rel = bv.state.theta_rad - route.heading_at(f.s_m);
            let gap = f.s_m
                - obs.own.s_m
                - half_extent(obs.scenario, None, rel)
                - half_extent(obs.scenario, Some(c.bv_index), rel);
            let ahead = f.s_m > obs.own.s_m;
            let safe_gap = p.min_gap_m + v * p.desired_time_gap_s;
            if bv.s_m >= b.enter_s_m && gap > 0.0 {
                let along = (v_b * rel.cos()).max(0.0);
                accel = accel.min(idm.enhanced_accel(v, v0, Obstacle { gap_m: gap, speed_mps: along }));
            } else if ahead && gap < safe_gap {
                accel = accel.min(-EASE_OFF_FRACTION * p.comfort_decel_mps2);
            }
        }
        accel
    }
}

/// Whether the gap at a crossing zone is acceptable (see the module documentation).
fn gap_accepted(p: &IdmParams, zone: &ConflictZone, bv: &Perceived, s: f64, v: f64, v0: f64, was_going: bool) -> bool {
    let v_b = bv.state.speed_mps.max(0.0);
    let s_b = bv.s_m + v_b * bv.age_s.max(0.0);
    if s_b >= zone.bv.exit_s_m {
        return true;
    }
    let (t_in_b, t_out_b) = if v_b < STOPPED_MPS {
        if s_b < zone.bv.enter_s_m {
            return true; // Standing before its zone.
        }
        (0.0, f64::INFINITY)
    } else {
        ((zone.bv.enter_s_m - s_b).max(0.0) / v_b, (zone.bv.exit_s_m - s_b) / v_b)
    };
    let t_in_v = travel_time(zone.vut.enter_s_m - s, v, p.max_accel_mps2, v0);
    let t_out_v = travel_time(zone.vut.exit_s_m - s, v, p.max_accel_mps2, v0);
    let relief = if was_going { GAP_HYSTERESIS_S } else { 0.0 };
    t_in_b - t_out_v >= p.critical_gap_s - relief || t_in_v - t_out_b >= p.commit_margin_s - relief
}

impl VutDriver for IdmDriver {
    fn name(&self) -> &str {
        self.name
    }

    fn control(&mut self, obs: &VutObservation<'_>) -> ActuationRequest {
        if !inputs_finite(obs) {
            return fallback(obs);
        }
        if self.decisions.len() != obs.scenario.conflicts.len() || obs.t_s < self.last_t_s {
            self.decisions = vec![Decision::Undecided; obs.scenario.conflicts.len()];
        }
        self.last_t_s = obs.t_s;
        let v = obs.own.state.speed_mps.max(0.0);
        let v0 = speed_cap(obs, self.params.comfort_decel_mps2);
        let idm = self.params.car_following();
        let mut accel = idm.accel(v, v0, None);
        if let Some(lead) = lead_vehicle(obs.scenario, &obs.own, obs.bvs) {
            accel = accel.min(idm.enhanced_accel(v, v0, Obstacle { gap_m: lead.gap_m, speed_mps: lead.speed_mps }));
        }
        accel = accel.min(self.merge_accel(obs, v, v0));
        for (i, c) in obs.scenario.conflicts.iter().enumerate() {
            if c.zone.kind != ConflictKind::Crossing || obs.own.s_m > c.zone.vut.exit_s_m {
                continue;
            }
            if let Some(gap) = self.crossing_gap(i, &c.zone, obs.bvs.get(c.bv_index), &obs.own, v0) {
                accel = accel.min(idm.accel(v, v0, Some(Obstacle { gap_m: gap, speed_mps: 0.0 })));
            }
        }
        finish(obs, accel, self.params.max_accel_mps2)
    }
}

#[cfg(test)]
mod tests {
    use v2t_model::kinematics::State;

    use super::*;
    use crate::scenario::Scenario;
    use crate::vut::common::fixtures::*;

    fn accel(driver: &mut IdmDriver, sc: &Scenario, own: Perceived, bvs: &[Perceived]) -> f64 {
        let r = driver.control(&observe(sc, 0.0, own, bvs));
        assert!(r.is_finite());
        r.accel_mps2
    }

    #[test]
    fn yields_to_a_bv_that_arrives_just_before() {
        let sc = crossing(BV_SLIGHTLY_FIRST);
        let mut d = IdmDriver::new(IdmParams::normal());
        let a = accel(&mut d, &sc, vut_at(0.0, VUT_SPEED), &[crossing_bv_at(0.0, BV_SLIGHTLY_FIRST)]);
        assert!(a < -0.3, "{a}");
        assert_eq!(d.decisions, vec![Decision::Yield]);
    }

    #[test]
    fn goes_when_the_bv_is_far_standing_or_gone() {
        let sc = crossing(BV_SLIGHTLY_FIRST);
        for bv in [crossing_bv_at(0.0, 2.0), crossing_bv_at(30.0, 0.0), crossing_bv_at(60.0, 10.0)] {
            let mut d = IdmDriver::new(IdmParams::normal());
            let a = accel(&mut d, &sc, vut_at(0.0, VUT_SPEED), &[bv]);
            assert!(a.abs() < 1e-6, "{bv:?}: {a}");
            assert_eq!(d.decisions, vec![Decision::Go]);
        }
        // No BV perceived at all.
        let mut d = IdmDriver::new(IdmParams::normal());
        assert!(accel(&mut d, &sc, vut_at(0.0, 8.0), &[]) > 0.5);
    }

    #[test]
    fn cautious_waits_where_aggressive_goes() {
        let sc = crossing(BV_SLIGHTLY_FIRST);
        let zone = sc.conflicts[0].zone;
        // The VUT at desired speed clears the zone 2 s before the BV enters.
        let s = 10.0;
        let t_out = (zone.vut.exit_s_m - s) / VUT_SPEED;
        let v_b = 5.0;
        let bv = [crossing_bv_at(zone.bv.enter_s_m - v_b * (t_out + 2.0), v_b)];
        let mut aggressive = IdmDriver::new(IdmParams::aggressive());
        let mut cautious = IdmDriver::new(IdmParams::cautious());
        let a_aggr = accel(&mut aggressive, &sc, vut_at(s, VUT_SPEED), &bv);
        let a_caut = accel(&mut cautious, &sc, vut_at(s, VUT_SPEED), &bv);
        assert!(a_aggr.abs() < 1e-6, "{a_aggr}");
        assert!(a_caut < -1.0, "{a_caut}");
        assert_eq!((aggressive.name(), cautious.name()), ("idm-aggressive", "idm-cautious"));
    }

    #[test]
    fn commits_once_it_cannot_stop_comfortably() {
        let sc = crossing(BV_SLIGHTLY_FIRST);
        let zone = sc.conflicts[0].zone;
        let s = zone.vut.enter_s_m - 12.0; // Comfortable stop from 10 m/s takes 25 m.
        let far = [crossing_bv_at(0.0, 1.0)];
        let mut d = IdmDriver::new(IdmParams::normal());
        assert!(accel(&mut d, &sc, vut_at(s, VUT_SPEED), &far).abs() < 1e-6);
        assert_eq!(d.decisions, vec![Decision::Committed]);
        // The BV speeds up and now arrives with the VUT: a committed VUT goes on, a fresh one brakes.
        let rushing = [crossing_bv_at(zone.bv.enter_s_m - 12.0, VUT_SPEED)];
        assert!(accel(&mut d, &sc, vut_at(s + 1.0, VUT_SPEED), &rushing).abs() < 1e-6);
        let mut fresh = IdmDriver::new(IdmParams::normal());
        assert!(accel(&mut fresh, &sc, vut_at(s + 1.0, VUT_SPEED), &rushing) < -3.0);
        // Reused for a new run (time goes back), the driver forgets its commitment.
        d.control(&observe(&sc, 5.0, vut_at(s + 2.0, VUT_SPEED), &rushing));
        assert!(accel(&mut d, &sc, vut_at(s + 1.0, VUT_SPEED), &rushing) < -3.0);
    }

    #[test]
    fn follows_a_slower_lead_and_ignores_the_next_lane() {
        let sc = cut_in();
        let mut d = IdmDriver::new(IdmParams::normal());
        let lead = Perceived {
            state: State { px: 25.0, py: 0.2, theta_rad: 0.0, speed_mps: 5.0 },
            s_m: 80.0,
            l_m: 0.0,
            age_s: 0.0,
        };
        assert!(accel(&mut d, &sc, vut_at(0.0, VUT_SPEED), &[lead]) < -2.0);
        // Still in its own lane, well before its lane change: not the VUT's business.
        let beside = Perceived {
            state: State { px: 12.0, py: 3.5, theta_rad: 0.0, speed_mps: VUT_SPEED },
            s_m: 2.0,
            l_m: 0.0,
            age_s: 0.0,
        };
        assert!(accel(&mut d, &sc, vut_at(0.0, VUT_SPEED), &[beside]).abs() < 1e-6);
        // About to change lanes just ahead: ease off.
        let merging = Perceived { s_m: 18.0, ..beside };
        let a = accel(&mut d, &sc, vut_at(0.0, VUT_SPEED), &[merging]);
        assert!(a < -0.5 && a > -2.0, "{a}");
    }

    #[test]
    fn non_finite_inputs_brake_moderately() {
        assert_brakes_on_nan(&mut IdmDriver::new(IdmParams::normal()));
    }

    #[test]
    fn closed_loop_crossing_has_no_collision() {
        // Sanity: a VUT that ignores the BV collides.
        assert!(closed_loop_crossing(&mut Blind).collision.is_some());
        for params in [IdmParams::cautious(), IdmParams::normal(), IdmParams::aggressive()] {
            let r = closed_loop_crossing(&mut IdmDriver::new(params));
            assert!(r.collision.is_none(), "{params:?}: {r:?}");
            assert!(r.pet_min_s.is_some_and(|p| p > 0.3), "{params:?}: {r:?}");
        }
    }
}
