//! Which PETs can any BV reach against a VUT? A grid of open-loop BV speed profiles — acceleration
//! `a1` for `t1` seconds, then `a2` until the BV has left its conflict zone, then its reference
//! speed — each run once against the VUT, with the scenario's sensor noise and delays. Runs where
//! the BV passed first without collision or zone overlap give the PETs a rushing BV can reach; runs
//! where the VUT passed first give those of a yielding one.
//!
//! It bounds what any regulator can achieve against that VUT: where no profile lands within ±10 %
//! of a target τ, a miss there is the VUT's rule, not the regulator's. It is an oracle for scoring
//! only; no regulator reads it. The same grid runs in every world (the builtin VUT models, SUMO's
//! drivers), through [`crate::vut::Vut::run`].

use serde::Serialize;
use v2t_model::{Style, Target};
use v2t_sim::bv::BvController;
use v2t_sim::control::pure_pursuit;
use v2t_sim::observation::BvObservation;
use v2t_sim::plant::ActuationRequest;
use v2t_sim::runner::FirstThrough;
use v2t_sim::scenario::Scenario;

use crate::vut::Vut;

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

/// A BV that drives one [`Profile`] and follows its route laterally.
#[derive(Debug, Clone, Copy)]
pub struct OpenLoop {
    /// The profile.
    pub profile: Profile,
}

impl BvController for OpenLoop {
    fn name(&self) -> &str {
        "open-loop"
    }

    fn control(&mut self, obs: &BvObservation<'_>) -> ActuationRequest {
        let sc = obs.scenario;
        let Some(bv) = sc.bvs.get(obs.bv_index) else { return ActuationRequest::default() };
        let exit_s_m = sc.conflict_of(obs.bv_index).map_or(f64::INFINITY, |c| c.zone.bv.exit_s_m);
        let v = obs.own.state.speed_mps;
        let lim = &bv.agent.vehicle.limits;
        let wanted = if obs.own.s_m >= exit_s_m {
            0.5 * (bv.reference.speed_at(obs.t_s) - v)
        } else if obs.t_s < self.profile.t1_s {
            self.profile.a1_mps2
        } else {
            self.profile.a2_mps2
        };
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
    /// Profiles run.
    pub profiles: usize,
    /// PETs of the safe runs where the BV passed first, s (sorted).
    pub rush_pets_s: Vec<f64>,
    /// PETs of the safe runs where the VUT passed first, s (sorted).
    pub yield_pets_s: Vec<f64>,
    /// Runs that ended in a collision.
    pub collisions: usize,
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
        failed: 0,
    };
    for profile in profiles {
        let mut bvs: Vec<Box<dyn BvController>> =
            (0..scenario.bvs.len()).map(|_| Box::new(OpenLoop { profile }) as Box<dyn BvController>).collect();
        let Ok(run) = vut.run(scenario, &mut bvs, seed) else {
            out.failed += 1;
            continue;
        };
        let r = run.result;
        if r.collision.is_some() {
            out.collisions += 1;
            continue;
        }
        let Some(c) = r.conflicts.first() else { continue };
        match (c.first, c.pet.pet_s(), r.zone_overlap) {
            (Some(FirstThrough::Bv), Some(pet), false) => out.rush_pets_s.push(pet),
            (Some(FirstThrough::Vut), Some(pet), false) => out.yield_pets_s.push(pet),
            _ => {}
        }
    }
    out.rush_pets_s.sort_by(f64::total_cmp);
    out.yield_pets_s.sort_by(f64::total_cmp);
    out
}
