//! A sampling-based speed planner.
//!
//! Every `replan_period_s` the planner rolls out each candidate constant acceleration over
//! `horizon_s` in steps of `step_s`, one-dimensionally along the VUT's route (speed clamped to
//! `[0, min(desired, curve speed limit)]`), and predicts every BV at constant speed along its own
//! route (footprint at `route.to_cartesian(s, l)`, advanced over the measurement's age). It scores
//! each candidate by
//!
//! - progress: `Σ (v_max − v)² dt`, the speed deficit against the allowed speed;
//! - comfort `a²` and change from the previous choice `(a − a_prev)²` (jerk);
//! - risk: footprint distance between the predicted VUT and BV footprints
//!   ([`OrientedBox::distance`]), a huge cost per step of overlap and a steep quadratic cost below
//!   `safety_distance_m`;
//! - zone co-occupancy at crossings: a cost per step during which the VUT is inside its zone
//!   interval while the BV is inside its own, widened by `zone_time_margin_s` at its speed;
//! - headway: a quadratic cost when a BV predicted in the VUT's lane ahead is closer than
//!   `min_gap_m + headway_s · v`,
//!
//! then holds the cheapest candidate (the first on ties: deterministic) until the next replan,
//! lowered each period where the speed cap from the curvature ahead requires it. Lateral control
//! is pure pursuit on the route.

use v2t_model::driving::{CURVE_HALF_WINDOW_M, curve_speed};
use v2t_model::geometry::OrientedBox;
use v2t_model::metrics::{ConflictKind, OccupancyInterval};

use super::VutDriver;
use super::common::{FALLBACK_DECEL_MPS2, LANE_HALF_WIDTH_M, fallback, finish, half_extent, inputs_finite, speed_cap};
use crate::observation::VutObservation;
use crate::plant::ActuationRequest;

/// Cost of one predicted step with overlapping footprints.
const COLLISION_COST: f64 = 1e6;
/// Smallest rollout step, s.
const MIN_STEP_S: f64 = 0.01;
/// Largest number of rollout steps.
const MAX_STEPS: usize = 200;
/// Deceleration behind the speed cap applied between replans, m/s².
const CAP_DECEL_MPS2: f64 = 2.0;
/// Time constant with which the held acceleration gives way to the speed cap, s.
const SPEED_TAU_S: f64 = 1.0;
/// Tolerance on replan times, s.
const TIME_EPS_S: f64 = 1e-6;

/// Sampling planner parameters.
#[derive(Debug, Clone, PartialEq)]
pub struct SamplingParams {
    /// Rollout horizon, s.
    pub horizon_s: f64,
    /// Rollout step, s.
    pub step_s: f64,
    /// Time between replans, s; the choice is held in between.
    pub replan_period_s: f64,
    /// Candidate constant accelerations, m/s² (clipped to the vehicle's limits).
    pub candidate_accels_mps2: Vec<f64>,
    /// Weight of the speed deficit, 1/m² s.
    pub progress_weight: f64,
    /// Weight of `a²`.
    pub comfort_weight: f64,
    /// Weight of `(a − a_prev)²`.
    pub change_weight: f64,
    /// Weight (per second) of the footprint distance falling below the safety distance.
    pub risk_weight: f64,
    /// Cost per second of predicted zone co-occupancy.
    pub zone_weight: f64,
    /// Weight (per second) of the headway to a BV in the lane falling below the desired one.
    pub headway_weight: f64,
    /// Footprint distance below which risk costs, m.
    pub safety_distance_m: f64,
    /// The BV's zone interval is widened by this much time on each side, s.
    pub zone_time_margin_s: f64,
    /// Desired time headway to a BV in the lane ahead, s.
    pub headway_s: f64,
    /// Desired standstill gap to a BV in the lane ahead, m.
    pub min_gap_m: f64,
}

impl Default for SamplingParams {
    /// `config/vut/builtin/sampling.toml`.
    fn default() -> Self {
        super::builtin::sampling()
    }
}

/// One BV at one predicted step.
#[derive(Debug, Clone, Copy)]
struct BvStep {
    footprint: OrientedBox,
    /// Inside its (widened) crossing-zone interval.
    in_zone: bool,
    /// Arc length on the VUT's route and half extent along it, when in the VUT's lane.
    in_lane: Option<(f64, f64)>,
}

/// The sampling planner (see the module documentation).
#[derive(Debug, Clone)]
pub struct SamplingPlanner {
    params: SamplingParams,
    /// The held choice, m/s².
    chosen_mps2: f64,
    next_replan_s: f64,
    last_t_s: f64,
    /// Predicted BV steps, BV-major: `bv * n_steps + (k − 1)`.
    predictions: Vec<BvStep>,
    /// The VUT's crossing interval with each BV (`None` for merges).
    vut_zones: Vec<Option<OccupancyInterval>>,
}

impl SamplingPlanner {
    /// A planner with these parameters.
    pub fn new(params: SamplingParams) -> Self {
        Self {
            params,
            chosen_mps2: 0.0,
            next_replan_s: f64::NEG_INFINITY,
            last_t_s: f64::NEG_INFINITY,
            predictions: Vec::new(),
            vut_zones: Vec::new(),
        }
    }

    /// The parameters.
    pub fn params(&self) -> &SamplingParams {
        &self.params
    }

    /// Fills the BV predictions for `n` steps of `step` seconds.
    fn predict(&mut self, obs: &VutObservation<'_>, n: usize, step: f64) {
        self.predictions.clear();
        self.vut_zones.clear();
        let sc = obs.scenario;
        let route = &sc.vut.agent.route;
        for (i, (bv, setup)) in obs.bvs.iter().zip(&sc.bvs).enumerate() {
            let crossing = sc.conflict_of(i).filter(|c| c.zone.kind == ConflictKind::Crossing);
            self.vut_zones.push(crossing.map(|c| c.zone.vut));
            let v_b = bv.state.speed_mps.max(0.0);
            let margin = v_b * self.params.zone_time_margin_s;
            let geo = &setup.agent.vehicle.geometry;
            for k in 1..=n {
                let s_b = bv.s_m + v_b * (bv.age_s.max(0.0) + k as f64 * step);
                let center = setup.agent.route.to_cartesian(s_b, bv.l_m);
                let heading = setup.agent.route.heading_at(s_b);
                let footprint =
                    OrientedBox { center, heading_rad: heading, length_m: geo.length_m, width_m: geo.width_m };
                let in_zone =
                    crossing.is_some_and(|c| s_b >= c.zone.bv.enter_s_m - margin && s_b <= c.zone.bv.exit_s_m + margin);
                let in_lane = route
                    .project(center)
                    .filter(|f| f.l_m.abs() < LANE_HALF_WIDTH_M)
                    .map(|f| (f.s_m, half_extent(sc, Some(i), heading - route.heading_at(f.s_m))));
                self.predictions.push(BvStep { footprint, in_zone, in_lane });
            }
        }
    }

    /// Cost of holding acceleration `a` from the VUT's current state over `n` steps of `step` seconds.
    fn score(&self, obs: &VutObservation<'_>, a: f64, n: usize, step: f64) -> f64 {
        let p = &self.params;
        let agent = &obs.scenario.vut.agent;
        let geo = &agent.vehicle.geometry;
        let own_half = half_extent(obs.scenario, None, 0.0);
        let mut cost = p.comfort_weight * a * a + p.change_weight * (a - self.chosen_mps2).powi(2);
        let (mut s, mut v) = (obs.own.s_m, obs.own.state.speed_mps.max(0.0));
        for k in 1..=n {
            let curve = curve_speed(&agent.route, s, CURVE_HALF_WINDOW_M, agent.vehicle.limits.max_lat_accel_mps2);
            let v_max = obs.scenario.vut.desired_speed_mps.min(curve).min(agent.vehicle.limits.max_speed_mps).max(0.0);
            let v_next = (v + a * step).min(v_max).max(0.0);
            s += 0.5 * (v + v_next) * step;
            v = v_next;
            cost += p.progress_weight * (v_max - v).powi(2) * step;
            let footprint = OrientedBox {
                center: agent.route.point_at(s),
                heading_rad: agent.route.heading_at(s),
                length_m: geo.length_m,
                width_m: geo.width_m,
            };
            for (i, zone) in self.vut_zones.iter().enumerate() {
                let Some(bv) = self.predictions.get(i * n + k - 1) else { continue };
                let d = footprint.distance(&bv.footprint);
                if d <= 0.0 {
                    cost += COLLISION_COST;
                } else if d < p.safety_distance_m {
                    cost += p.risk_weight * ((p.safety_distance_m - d) / p.safety_distance_m).powi(2) * step;
                }
                if bv.in_zone && zone.is_some_and(|z| z.contains(s)) {
                    cost += p.zone_weight * step;
                }
                if let Some((s_bv, bv_half)) = bv.in_lane
                    && s_bv > s
                {
                    let gap = s_bv - s - own_half - bv_half;
                    let wanted = p.min_gap_m + p.headway_s * v;
                    if gap < wanted {
                        cost += p.headway_weight * ((wanted - gap) / wanted.max(1.0)).powi(2) * step;
                    }
                }
            }
        }
        cost
    }
}

impl VutDriver for SamplingPlanner {
    fn name(&self) -> &str {
        "sampling"
    }

    fn control(&mut self, obs: &VutObservation<'_>) -> ActuationRequest {
        if !inputs_finite(obs) {
            return fallback(obs);
        }
        if obs.t_s < self.last_t_s {
            // Time went backwards: a new run.
            self.chosen_mps2 = 0.0;
            self.next_replan_s = f64::NEG_INFINITY;
        }
        self.last_t_s = obs.t_s;
        if obs.t_s >= self.next_replan_s - TIME_EPS_S {
            let step = self.params.step_s.max(MIN_STEP_S);
            let n = ((self.params.horizon_s / step).ceil() as usize).clamp(1, MAX_STEPS);
            self.predict(obs, n, step);
            let lim = &obs.scenario.vut.agent.vehicle.limits;
            let mut best: Option<(f64, f64)> = None;
            for a in &self.params.candidate_accels_mps2 {
                let a = a.min(lim.max_accel_mps2).max(-lim.max_decel_mps2);
                let cost = self.score(obs, a, n, step);
                if cost.is_finite() && best.is_none_or(|(_, c)| cost < c) {
                    best = Some((a, cost));
                }
            }
            self.chosen_mps2 = best.map_or(-FALLBACK_DECEL_MPS2, |(a, _)| a);
            self.next_replan_s = obs.t_s + self.params.replan_period_s.max(0.0);
        }
        let v = obs.own.state.speed_mps.max(0.0);
        let cap = speed_cap(obs, CAP_DECEL_MPS2);
        finish(obs, self.chosen_mps2.min((cap - v) / SPEED_TAU_S), f64::INFINITY)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::observation::Perceived;
    use crate::vut::common::fixtures::{
        BV_SLIGHTLY_FIRST, VUT_SPEED, assert_brakes_on_nan, closed_loop_crossing, crossing, crossing_bv_at, cut_in,
        observe, vut_at,
    };
    use v2t_model::kinematics::State;

    fn accel(
        planner: &mut SamplingPlanner,
        t: f64,
        own: Perceived,
        bvs: &[Perceived],
        sc: &crate::scenario::Scenario,
    ) -> f64 {
        let r = planner.control(&observe(sc, t, own, bvs));
        assert!(r.is_finite());
        r.accel_mps2
    }

    #[test]
    fn keeps_speed_on_an_empty_road() {
        let sc = crossing(BV_SLIGHTLY_FIRST);
        for bvs in [vec![], vec![crossing_bv_at(0.0, 0.0)], vec![crossing_bv_at(70.0, 8.0)]] {
            let mut planner = SamplingPlanner::new(SamplingParams::default());
            assert_eq!(accel(&mut planner, 0.0, vut_at(0.0, VUT_SPEED), &bvs, &sc), 0.0, "{bvs:?}");
        }
        let mut planner = SamplingPlanner::new(SamplingParams::default());
        assert!(accel(&mut planner, 0.0, vut_at(0.0, 6.0), &[], &sc) > 0.0);
    }

    #[test]
    fn brakes_when_a_bv_will_occupy_the_zone_at_arrival_and_holds_the_choice() {
        let sc = crossing(BV_SLIGHTLY_FIRST);
        let mut planner = SamplingPlanner::new(SamplingParams::default());
        let threat = [crossing_bv_at(0.0, BV_SLIGHTLY_FIRST)];
        let a = accel(&mut planner, 0.0, vut_at(0.0, VUT_SPEED), &threat, &sc);
        assert!(a < 0.0, "{a}");
        // Held until the next replan even though the road is now empty, then released.
        assert_eq!(accel(&mut planner, 0.1, vut_at(1.0, VUT_SPEED), &[], &sc), a);
        assert!(accel(&mut planner, 0.2, vut_at(2.0, VUT_SPEED), &[], &sc) > a);
        // Deterministic.
        let mut again = SamplingPlanner::new(SamplingParams::default());
        assert_eq!(accel(&mut again, 0.0, vut_at(0.0, VUT_SPEED), &threat, &sc), a);
    }

    #[test]
    fn brakes_for_a_slow_cut_in() {
        let sc = cut_in();
        let mut planner = SamplingPlanner::new(SamplingParams::default());
        // The BV starts its lane change 10 m ahead at 6 m/s.
        let bv = Perceived {
            state: State { px: 30.0, py: 3.5, theta_rad: 0.0, speed_mps: 6.0 },
            s_m: 20.0,
            l_m: 0.0,
            age_s: 0.0,
        };
        let a = accel(&mut planner, 0.0, vut_at(10.0, VUT_SPEED), &[bv], &sc);
        assert!(a <= -1.0, "{a}");
    }

    #[test]
    fn non_finite_inputs_brake_moderately() {
        assert_brakes_on_nan(&mut SamplingPlanner::new(SamplingParams::default()));
    }

    #[test]
    fn closed_loop_crossing_has_no_collision() {
        let r = closed_loop_crossing(&mut SamplingPlanner::new(SamplingParams::default()));
        assert!(r.collision.is_none(), "{r:?}");
        assert!(r.pet_min_s.is_some_and(|p| p > 0.3), "{r:?}");
    }
}
