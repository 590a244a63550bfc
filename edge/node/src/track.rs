//! The tracker node: wakes on every new BV state, follows the newest regulated plan along the
//! prior's path with PID + Stanley (`v2t-track`), and hands the request to the gateway at once.

use std::time::Duration;

use iceoryx2::service::Service;
use v2t_model::kinematics::State;
use v2t_track::{PlanSample, TrackError, Tracker};
use v2t_wire::{ActivePrior, ActuationCommand, BvState, Header, NodeKind, RegulatedPlan, services};

use crate::clock::{now_ns, secs_between};
use crate::config::Loaded;
use crate::error::EdgeError;
use crate::heart::Heart;
use crate::ports::{Bus, latest, send, wait_wake};
use crate::prior::PriorContext;

/// Where the plan puts the BV at `stamp_ns`: the plan holds its acceleration from its own stamp
/// (speed never below zero).
pub fn plan_sample(plan: &RegulatedPlan, stamp_ns: u64) -> PlanSample {
    let dt = secs_between(plan.header.stamp_ns, stamp_ns).max(0.0);
    let (v0, a) = (plan.v0_mps.max(0.0), plan.accel_mps2);
    // Time until the plan's speed reaches zero (braking), after which it stands still.
    let t_move = if a < 0.0 { (v0 / -a).min(dt) } else { dt };
    let v = (v0 + a * t_move).max(0.0);
    let s = plan.s0_m + v0 * t_move + 0.5 * a * t_move * t_move;
    PlanSample { s_m: s, v_mps: v, a_mps2: if a < 0.0 && t_move < dt { 0.0 } else { a } }
}

/// The tracker with the path of the active prior. Pure: time comes in as arguments.
#[derive(Debug)]
pub struct Tracking {
    tracker: Tracker,
    prior: Option<PriorContext>,
    last_stamp_ns: Option<u64>,
    header: Header,
}

impl Tracking {
    /// A tracker for the BV of `cfg`.
    pub fn new(cfg: &Loaded) -> Self {
        Self {
            tracker: Tracker::new(cfg.tracker.clone(), &cfg.vehicle),
            prior: None,
            last_stamp_ns: None,
            header: Header::default(),
        }
    }

    /// Takes a new prior (a broken one is refused and the active one stays).
    pub fn set_prior(&mut self, prior: &ActivePrior) -> Result<(), EdgeError> {
        if self.prior.as_ref().is_some_and(|p| p.prior_id == prior.prior_id) {
            return Ok(());
        }
        self.prior = Some(PriorContext::new(prior)?);
        self.tracker.reset();
        self.last_stamp_ns = None;
        Ok(())
    }

    /// The command for BV state `bv` following `plan`, computed at `now_ns`. `Ok(None)` without a
    /// prior or a plan for it; an error when the tracker refuses the state or the plan (not
    /// finite, implausible, off the path). Either way no command goes out and the gateway's
    /// command timeout stops the BV.
    pub fn step(
        &mut self,
        bv: &BvState,
        plan: Option<&RegulatedPlan>,
        now_ns: u64,
    ) -> Result<Option<ActuationCommand>, TrackError> {
        let Some(ctx) = self.prior.as_ref() else { return Ok(None) };
        let Some(plan) = plan.filter(|p| p.prior_id == ctx.prior_id) else { return Ok(None) };
        if let Some((field, value)) = bv.non_finite() {
            return Err(TrackError::NotFinite { field, value });
        }
        let dt = self.last_stamp_ns.map_or(0.02, |t| secs_between(t, bv.header.stamp_ns)).clamp(1e-3, 0.2);
        self.last_stamp_ns = Some(bv.header.stamp_ns);
        let state = State { px: bv.px_m, py: bv.py_m, theta_rad: bv.theta_rad, speed_mps: bv.speed_mps };
        let sample = plan_sample(plan, bv.header.stamp_ns);
        let out = self.tracker.step(&state, &ctx.bv_path, &sample, dt)?;
        self.header.seq += 1;
        self.header.stamp_ns = now_ns;
        Ok(Some(ActuationCommand {
            header: self.header,
            plan_seq: plan.header.seq,
            state_seq: bv.header.seq,
            state_stamp_ns: bv.header.stamp_ns,
            state_received_ns: bv.received_ns,
            accel_mps2: out.accel_mps2,
            steer_rad: out.steer_rad,
            cross_track_m: out.cross_track_m,
            speed_error_mps: out.speed_error_mps,
        }))
    }
}

/// What a refusal of the tracker is, without its values (which change every cycle): its variant
/// and the input it names.
fn refusal_kind(e: &TrackError) -> (std::mem::Discriminant<TrackError>, &'static str) {
    let field = match e {
        TrackError::NotFinite { field, .. } | TrackError::Implausible { field, .. } => field,
        _ => "",
    };
    (std::mem::discriminant(e), field)
}

/// Runs the tracker node until termination.
pub fn run<S: Service>(cfg: &Loaded) -> Result<(), EdgeError> {
    let bus = Bus::<S>::new("tracker", &cfg.edge.namespace)?;
    let states = bus.subscriber::<BvState>(services::STATE)?;
    let state_wake = bus.listener(services::WAKE_TRACKER)?;
    let plans = bus.subscriber::<RegulatedPlan>(services::PLAN)?;
    let priors = bus.subscriber::<ActivePrior>(services::PRIOR)?;
    let out = bus.publisher::<ActuationCommand>(services::ACTUATION)?;
    let out_wake = bus.notifier(services::WAKE_GATEWAY)?;
    let t = cfg.edge.timing;
    let mut heart = Heart::new(&bus, NodeKind::Tracker, t.heartbeat_period_s)?;
    let mut tracking = Tracking::new(cfg);
    let mut plan: Option<RegulatedPlan> = None;
    let timeout = Duration::from_secs_f64(t.heartbeat_period_s / 2.0);
    let mut last_cmd_ns = 0;
    // The kind of refusal last reported: each new kind is logged once, and so is the recovery.
    let mut refusing = None;
    loop {
        wait_wake(&state_wake, timeout)?;
        if bus.terminating() {
            return Ok(());
        }
        let start = now_ns();
        while let Some(p) = priors.receive().map_err(|e| EdgeError::ipc("receive", services::PRIOR, e))? {
            if let Err(e) = tracking.set_prior(&p) {
                eprintln!("tracker: prior {} refused: {e}", p.prior_id);
            }
        }
        plan = latest(&plans)?.or(plan);
        let fresh_plan = plan.filter(|p| secs_between(p.header.stamp_ns, start) <= t.plan_timeout_s);
        if let Some(state) = latest(&states)? {
            match tracking.step(&state, fresh_plan.as_ref(), start) {
                Ok(Some(cmd)) => {
                    send(&out, Some(&out_wake), cmd)?;
                    last_cmd_ns = start;
                    heart.cycle(now_ns() - start, (t.heartbeat_period_s * 1e9) as u64);
                    if refusing.take().is_some() {
                        eprintln!("tracker: commanding again");
                    }
                }
                Ok(None) => {}
                Err(e) => {
                    let kind = refusal_kind(&e);
                    if refusing != Some(kind) {
                        eprintln!("tracker: no command ({e}); the gateway's command timeout stops the BV");
                        refusing = Some(kind);
                    }
                }
            }
        }
        let now = now_ns();
        heart.tick(now, secs_between(last_cmd_ns, now) <= t.state_timeout_s)?;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_plan_sample_integrates_the_held_acceleration_and_stops_at_zero_speed() {
        let plan = RegulatedPlan {
            header: Header { seq: 1, stamp_ns: 1_000_000_000 },
            s0_m: 10.0,
            v0_mps: 4.0,
            accel_mps2: 1.0,
            ..RegulatedPlan::default()
        };
        let p = plan_sample(&plan, 1_500_000_000);
        assert!((p.s_m - (10.0 + 2.0 + 0.125)).abs() < 1e-9 && (p.v_mps - 4.5).abs() < 1e-9);
        let braking = RegulatedPlan { accel_mps2: -2.0, ..plan };
        let p = plan_sample(&braking, 4_000_000_000);
        assert!((p.s_m - 14.0).abs() < 1e-9, "stops after 2 s and 4 m: {p:?}");
        assert_eq!((p.v_mps, p.a_mps2), (0.0, 0.0));
        // A state older than the plan reads the plan's start.
        let p = plan_sample(&plan, 900_000_000);
        assert_eq!((p.s_m, p.v_mps), (10.0, 4.0));
    }
}

#[cfg(test)]
mod step_tests {
    use super::*;
    use v2t_wire::{Code as _, PlanStatus};

    fn setup() -> (Tracking, ActivePrior) {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config");
        let cfg = crate::config::load(&dir.join("edge/bv1.toml")).unwrap();
        (Tracking::new(&cfg), crate::prior::fixtures::left_turn(1))
    }

    fn on_path(prior: &ActivePrior, speed_mps: f64, stamp_ns: u64) -> BvState {
        let p = prior.bv_path[0];
        let q = prior.bv_path[1];
        BvState {
            header: Header { seq: 1, stamp_ns },
            px_m: p.x_m,
            py_m: p.y_m,
            theta_rad: (q.y_m - p.y_m).atan2(q.x_m - p.x_m),
            speed_mps,
            ..BvState::default()
        }
    }

    fn plan(prior: &ActivePrior, stamp_ns: u64) -> RegulatedPlan {
        RegulatedPlan {
            header: Header { seq: 1, stamp_ns },
            prior_id: prior.prior_id,
            status: PlanStatus::Regulating.code(),
            v0_mps: 8.0,
            ..RegulatedPlan::default()
        }
    }

    #[test]
    fn refused_states_are_errors_that_name_the_input_and_send_nothing() {
        let (mut tracking, prior) = setup();
        let t = 1_000_000_000;
        // No prior yet: nothing to do, no error.
        assert_eq!(tracking.step(&on_path(&prior, 8.0, t), Some(&plan(&prior, t)), t), Ok(None));
        tracking.set_prior(&prior).unwrap();
        // No plan for this prior: nothing to do.
        assert_eq!(tracking.step(&on_path(&prior, 8.0, t), None, t), Ok(None));
        let ok = tracking.step(&on_path(&prior, 8.0, t), Some(&plan(&prior, t)), t).unwrap().unwrap();
        assert!(ok.accel_mps2.is_finite() && ok.steer_rad.is_finite());

        let t = t + 20_000_000;
        let e = tracking.step(&on_path(&prior, 1.0e9, t), Some(&plan(&prior, t)), t).unwrap_err();
        assert!(matches!(e, TrackError::Implausible { field: "state.speed_mps", .. }), "{e}");
        let e = tracking.step(&on_path(&prior, f64::NAN, t), Some(&plan(&prior, t)), t).unwrap_err();
        assert!(matches!(e, TrackError::NotFinite { field: "bv.speed_mps", .. }), "{e}");
        let steer_nan = BvState { steer_rad: f64::NAN, ..on_path(&prior, 8.0, t) };
        let e = tracking.step(&steer_nan, Some(&plan(&prior, t)), t).unwrap_err();
        assert!(matches!(e, TrackError::NotFinite { field: "bv.steer_rad", .. }), "{e}");
        let far = BvState { px_m: 1.0e5, ..on_path(&prior, 8.0, t) };
        let e = tracking.step(&far, Some(&plan(&prior, t)), t).unwrap_err();
        assert!(matches!(e, TrackError::OffPath { .. } | TrackError::FarFromPath { .. }), "{e}");
        // 3 m to the side of the path: located, but farther than the tracker accepts.
        let here = on_path(&prior, 8.0, t);
        let aside = BvState {
            px_m: here.px_m - 3.0 * here.theta_rad.sin(),
            py_m: here.py_m + 3.0 * here.theta_rad.cos(),
            ..here
        };
        let e = tracking.step(&aside, Some(&plan(&prior, t)), t).unwrap_err();
        assert!(matches!(e, TrackError::FarFromPath { .. }), "{e}");
        // The same kind of refusal with other values is one kind (logged once by the node).
        let a = TrackError::Implausible { field: "state.speed_mps", value: 1e9, bound: 150.0 };
        let b = TrackError::Implausible { field: "state.speed_mps", value: -1e9, bound: 150.0 };
        assert_eq!(refusal_kind(&a), refusal_kind(&b));
        assert_ne!(refusal_kind(&a), refusal_kind(&e));
        // And it recovers with a good state.
        let t = t + 20_000_000;
        assert!(tracking.step(&on_path(&prior, 8.0, t), Some(&plan(&prior, t)), t).unwrap().is_some());
    }
}
