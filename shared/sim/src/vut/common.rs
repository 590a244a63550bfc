//! What the driver models share: input checks and the fallback, steering and speed caps, lead
//! detection, and (in tests) the scenarios and observations their tests use.

use v2t_model::driving::{CurvePreview, curve_speed_ahead};

use crate::control::pure_pursuit;
use crate::observation::{Perceived, VutObservation};
use crate::plant::ActuationRequest;
use crate::scenario::Scenario;

/// Never aim below this speed on a free road (keeps `v/v0` finite), m/s.
const MIN_DESIRED_MPS: f64 = v2t_model::driving::MIN_DESIRED_SPEED_MPS;
/// A BV whose centre is closer than this to the VUT's route is in the VUT's lane, m.
pub(crate) const LANE_HALF_WIDTH_M: f64 = 1.6;
/// Deceleration requested when an input is not finite, m/s².
pub(crate) const FALLBACK_DECEL_MPS2: f64 = 3.0;
/// The VUT stops this far before a zone it yields at, m.
pub(crate) const STOP_MARGIN_M: f64 = 1.0;
/// A BV slower than this is standing, m/s.
pub(crate) const STOPPED_MPS: f64 = 0.3;

/// Whether every number the drivers read is finite.
pub(crate) fn inputs_finite(obs: &VutObservation<'_>) -> bool {
    let ok = |p: &Perceived| p.state.is_finite() && p.s_m.is_finite() && p.l_m.is_finite() && p.age_s.is_finite();
    ok(&obs.own)
        && obs.bvs.iter().all(ok)
        && obs.t_s.is_finite()
        && obs.dt_s.is_finite()
        && obs.scenario.vut.desired_speed_mps.is_finite()
}

/// Pure-pursuit steering on the VUT's route; 0 when it cannot be computed.
pub(crate) fn steering(obs: &VutObservation<'_>) -> f64 {
    let agent = &obs.scenario.vut.agent;
    if !(obs.own.state.is_finite() && obs.own.s_m.is_finite()) {
        return 0.0;
    }
    let delta = pure_pursuit(&agent.route, &obs.own.state, obs.own.s_m, &agent.vehicle);
    if delta.is_finite() { delta } else { 0.0 }
}

/// Moderate braking with whatever steering can be computed: the answer to non-finite inputs.
pub(crate) fn fallback(obs: &VutObservation<'_>) -> ActuationRequest {
    ActuationRequest { accel_mps2: -FALLBACK_DECEL_MPS2, steer_rad: steering(obs) }
}

/// The request for `accel_mps2`, limited to `[-max_decel, min(max_accel_mps2, vehicle max)]`,
/// with pure-pursuit steering; the fallback if the acceleration is not finite.
pub(crate) fn finish(obs: &VutObservation<'_>, accel_mps2: f64, max_accel_mps2: f64) -> ActuationRequest {
    let lim = &obs.scenario.vut.agent.vehicle.limits;
    let accel = accel_mps2.min(max_accel_mps2).min(lim.max_accel_mps2).max(-lim.max_decel_mps2);
    if !accel.is_finite() {
        return fallback(obs);
    }
    ActuationRequest { accel_mps2: accel, steer_rad: steering(obs) }
}

/// Desired speed capped by the curvature ahead ([`curve_speed_ahead`] with the
/// [`CurvePreview::DRIVER`] preview, braking at `decel_mps2`) and by the vehicle's top speed.
pub(crate) fn speed_cap(obs: &VutObservation<'_>, decel_mps2: f64) -> f64 {
    let agent = &obs.scenario.vut.agent;
    let lim = &agent.vehicle.limits;
    let cap = curve_speed_ahead(
        &agent.route,
        obs.own.s_m,
        obs.own.state.speed_mps,
        lim.max_lat_accel_mps2,
        decel_mps2,
        &CurvePreview::DRIVER,
    );
    obs.scenario.vut.desired_speed_mps.min(cap).min(lim.max_speed_mps).max(MIN_DESIRED_MPS)
}

/// Half the extent of a footprint along a direction at `rel_heading_rad` to its long axis:
/// the VUT's (`None`) or BV `bv_index`'s.
pub(crate) fn half_extent(scenario: &Scenario, bv_index: Option<usize>, rel_heading_rad: f64) -> f64 {
    let geo = match bv_index {
        None => Some(&scenario.vut.agent.vehicle.geometry),
        Some(i) => scenario.bvs.get(i).map(|b| &b.agent.vehicle.geometry),
    };
    geo.map_or(0.0, |g| 0.5 * (g.length_m * rel_heading_rad.cos().abs() + g.width_m * rel_heading_rad.sin().abs()))
}

/// The vehicle ahead in the VUT's lane.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Lead {
    /// Index of the BV.
    pub bv_index: usize,
    /// Bumper-to-bumper gap along the VUT's route, m.
    pub gap_m: f64,
    /// Its speed along the VUT's route, m/s (≥ 0).
    pub speed_mps: f64,
}

/// The nearest BV ahead whose position (advanced over its measurement's age) projects within
/// [`LANE_HALF_WIDTH_M`] of the VUT's route.
pub(crate) fn lead_vehicle(scenario: &Scenario, own: &Perceived, bvs: &[Perceived]) -> Option<Lead> {
    let route = &scenario.vut.agent.route;
    bvs.iter()
        .enumerate()
        .filter_map(|(i, bv)| {
            let f = route.project(bv.state.position())?;
            if f.l_m.abs() >= LANE_HALF_WIDTH_M || f.s_m <= own.s_m {
                return None;
            }
            let rel = bv.state.theta_rad - route.heading_at(f.s_m);
            let speed = (bv.state.speed_mps * rel.cos()).max(0.0);
            let own_half = half_extent(scenario, None, 0.0);
            let gap = f.s_m + speed * bv.age_s.max(0.0) - own.s_m - own_half - half_extent(scenario, Some(i), rel);
            Some(Lead { bv_index: i, gap_m: gap, speed_mps: speed })
        })
        .min_by(|a, b| a.gap_m.total_cmp(&b.gap_m))
}

/// Scenarios, observations and checks shared by the driver models' tests.
#[cfg(test)]
pub(crate) mod fixtures {
    use v2t_model::kinematics::State;
    use v2t_model::path::{PathSpec, SegmentSpec};
    use v2t_model::{Style, Target};

    use super::*;
    use crate::bv::{BvController, ReferenceFollower};
    use crate::config::{BvCard, ScenarioCard, SimSettings, VutCard};
    use crate::runner::{RunResult, run};
    use crate::vut::VutDriver;

    /// VUT speed of the crossing scenario, m/s.
    pub(crate) const VUT_SPEED: f64 = 10.0;
    /// BV speed at which it enters the crossing ≈ 0.35 s before a blind VUT, m/s.
    pub(crate) const BV_SLIGHTLY_FIRST: f64 = 8.5;

    fn scenario(vut: PathSpec, bv: PathSpec, bv_speed: f64) -> Scenario {
        let card = ScenarioCard {
            name: "test".into(),
            description: "test".into(),
            sim: "sim.toml".into(),
            duration_s: 20.0,
            target: Target::new(2.0, Style::Rush).unwrap(),
            vut: VutCard {
                vehicle: "vut.toml".into(),
                model: "idm-normal".into(),
                path: vut,
                initial_speed_mps: VUT_SPEED,
                desired_speed_mps: VUT_SPEED,
            },
            bvs: vec![BvCard {
                id: "bv1".into(),
                vehicle: "bv.toml".into(),
                path: bv,
                initial_speed_mps: bv_speed,
                speed_profile: vec![[0.0, bv_speed]],
                junction_entry_m: None,
            }],
        };
        let settings = SimSettings {
            plant_dt_s: 0.01,
            control_period_s: 0.1,
            record_period_s: 0.1,
            noise_enabled: true,
            v2x_delay_s: 0.1,
            perception_delay_s: 0.1,
        };
        let sedan = crate::plant::tests::sedan();
        Scenario::from_card(&card, settings, sedan.clone(), vec![sedan]).unwrap()
    }

    fn path(x: f64, y: f64, heading_deg: f64, segments: Vec<SegmentSpec>) -> PathSpec {
        PathSpec { start_x_m: x, start_y_m: y, start_heading_deg: heading_deg, segments }
    }

    /// Right-angle crossing: the VUT drives +x from (0, 0), the BV +y from (50, −40).
    pub(crate) fn crossing(bv_speed: f64) -> Scenario {
        let vut = path(0.0, 0.0, 0.0, vec![SegmentSpec::Line { length_m: 120.0 }]);
        let bv = path(50.0, -40.0, 90.0, vec![SegmentSpec::Line { length_m: 100.0 }]);
        scenario(vut, bv, bv_speed)
    }

    /// Cut-in: the VUT drives +x on y = 0, the BV from (10, 3.5) changes into its lane.
    pub(crate) fn cut_in() -> Scenario {
        let vut = path(0.0, 0.0, 0.0, vec![SegmentSpec::Line { length_m: 200.0 }]);
        let bv = path(
            10.0,
            3.5,
            0.0,
            vec![
                SegmentSpec::Line { length_m: 20.0 },
                SegmentSpec::LaneChange { length_m: 40.0, offset_m: -3.5 },
                SegmentSpec::Line { length_m: 150.0 },
            ],
        );
        scenario(vut, bv, 11.0)
    }

    /// The VUT at arc length `s` on the +x axis.
    pub(crate) fn vut_at(s: f64, v: f64) -> Perceived {
        Perceived { state: State { px: s, py: 0.0, theta_rad: 0.0, speed_mps: v }, s_m: s, l_m: 0.0, age_s: 0.0 }
    }

    /// The crossing BV at arc length `s` on its route.
    pub(crate) fn crossing_bv_at(s: f64, v: f64) -> Perceived {
        let state = State { px: 50.0, py: -40.0 + s, theta_rad: std::f64::consts::FRAC_PI_2, speed_mps: v };
        Perceived { state, s_m: s, l_m: 0.0, age_s: 0.0 }
    }

    /// An observation at `t_s` with the control period of the runner.
    pub(crate) fn observe<'a>(
        scenario: &'a Scenario,
        t_s: f64,
        own: Perceived,
        bvs: &'a [Perceived],
    ) -> VutObservation<'a> {
        VutObservation { t_s, dt_s: 0.1, own, bvs, scenario }
    }

    /// Closed loop on the crossing with a BV that arrives slightly before the VUT.
    pub(crate) fn closed_loop_crossing(driver: &mut dyn VutDriver) -> RunResult {
        let scenario = crossing(BV_SLIGHTLY_FIRST);
        let mut bvs: Vec<Box<dyn BvController>> = vec![Box::new(ReferenceFollower::default())];
        run(&scenario, &mut bvs, driver, 7).unwrap().result
    }

    /// Asserts that a driver survives the same non-finite inputs as every model must.
    pub(crate) fn assert_brakes_on_nan(driver: &mut dyn VutDriver) {
        let sc = crossing(BV_SLIGHTLY_FIRST);
        let bv = [crossing_bv_at(0.0, BV_SLIGHTLY_FIRST)];
        let mut own = vut_at(0.0, f64::NAN);
        let r = driver.control(&observe(&sc, 0.0, own, &bv));
        assert_eq!(r.accel_mps2, -FALLBACK_DECEL_MPS2);
        assert!(r.steer_rad.is_finite());
        own.state.speed_mps = VUT_SPEED;
        let bad_bv = [Perceived { s_m: f64::NAN, ..crossing_bv_at(0.0, 8.0) }];
        let r = driver.control(&observe(&sc, 0.1, own, &bad_bv));
        assert_eq!(r.accel_mps2, -FALLBACK_DECEL_MPS2);
        own.state.px = f64::INFINITY;
        let r = driver.control(&observe(&sc, 0.2, own, &bv));
        assert_eq!((r.accel_mps2, r.steer_rad), (-FALLBACK_DECEL_MPS2, 0.0));
        let r = driver.control(&observe(&sc, f64::NAN, vut_at(0.0, VUT_SPEED), &bv));
        assert!(r.is_finite() && r.accel_mps2 == -FALLBACK_DECEL_MPS2);
    }

    /// A VUT that holds its speed whatever happens and only steers along its route.
    pub(crate) struct Blind;

    impl VutDriver for Blind {
        fn name(&self) -> &str {
            "blind"
        }
        fn control(&mut self, obs: &VutObservation<'_>) -> ActuationRequest {
            ActuationRequest { accel_mps2: 0.0, steer_rad: steering(obs) }
        }
    }
}
