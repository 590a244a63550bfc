//! `video2track sim`: one scenario in the simulated proving ground with BVs that follow their
//! references, and a plain-text report of what happened.

use std::fmt::Write as _;

use v2t_model::metrics::{ConflictKind, PetOutcome};
use v2t_sim::bv::{BvController, ReferenceFollower};
use v2t_sim::runner::{FirstThrough, RunError, RunOutcome};
use v2t_sim::scenario::Scenario;

use crate::vut::{Vut, World};

/// Runs `scenario` with reference-following BVs against `vut`.
pub fn run_reference(scenario: &Scenario, vut: &Vut<'_>, seed: u64) -> Result<RunOutcome, RunError> {
    let mut bvs: Vec<Box<dyn BvController>> =
        scenario.bvs.iter().map(|_| Box::new(ReferenceFollower::default()) as Box<dyn BvController>).collect();
    vut.run(scenario, &mut bvs, seed)
}

fn who(f: Option<FirstThrough>) -> &'static str {
    match f {
        Some(FirstThrough::Bv) => "BV",
        Some(FirstThrough::Vut) => "VUT",
        None => "nobody",
    }
}

/// A short human-readable report of a run in `world`.
pub fn report(outcome: &RunOutcome, world: World) -> String {
    let r = &outcome.result;
    let mut out = String::new();
    let place = world.place();
    let _ = writeln!(
        out,
        "scenario {}  |  VUT {}  |  BV {}  |  seed {}  |  style {} (target PET {:.2} s)  |  {place}",
        r.scenario,
        r.vut_model,
        r.bv_controller,
        r.seed,
        r.target.style(),
        r.target.tau_s()
    );
    for c in &r.conflicts {
        let pet = match c.pet {
            PetOutcome::Measured { pet_s, overlap: false, .. } => format!("PET {pet_s:.2} s"),
            PetOutcome::Measured { pet_s, overlap: true, .. } => {
                format!("PET {pet_s:.2} s (both vehicles in the zone at once)")
            }
            PetOutcome::Censored { pet_lower_bound_s, .. } => {
                format!("PET > {pet_lower_bound_s:.2} s (the second vehicle never entered)")
            }
            PetOutcome::NotReached => "PET undefined (nobody reached the zone)".to_owned(),
        };
        let order = match c.order_matches_style {
            Some(true) => "order as the style asks",
            Some(false) => "order OPPOSITE to the style",
            None => "no order",
        };
        let _ = writeln!(
            out,
            "  conflict with {} ({}): {} first through, {}, {}",
            c.bv_id,
            match c.kind {
                ConflictKind::Crossing => "crossing",
                ConflictKind::Merge => "merge",
            },
            who(c.first),
            pet,
            order
        );
    }
    let fmt_opt = |v: Option<f64>| v.map_or_else(|| "n/a".to_owned(), |x| format!("{x:.2} s"));
    let _ = writeln!(
        out,
        "  PET_min {}  |  min distance {:.2} m at {:.1} s  |  min TTC {}  |  collision {}  |  {} after {:.1} s",
        fmt_opt(r.pet_min_s),
        r.min_distance_m,
        r.min_distance_t_s,
        fmt_opt(r.min_ttc_s),
        r.collision
            .as_ref()
            .map_or_else(|| "none".to_owned(), |c| format!("{} and {} at {:.2} s", c.agents[0], c.agents[1], c.t_s)),
        if r.completed { "completed" } else { "stopped" },
        r.duration_s
    );
    out
}

/// The realism lines of a run: per vehicle its manoeuvre class and how far its motion is from the
/// recorded human driving of that class (`reference` names where that driving came from).
pub fn realism_report(r: &v2t_sim::realism::RunRealism, reference: &v2t_model::realism::HumanReference) -> String {
    let mut out = String::new();
    let source = reference.provenance.split("; made by").next().unwrap_or_default();
    let _ = writeln!(out, "  realism against {source}:");
    for v in &r.vehicles {
        let _ = match &v.realism {
            Some(m) => writeln!(
                out,
                "    {} ({}): W₁ accel {:.3} m/s², W₁ jerk {:.3} m/s³, W₁ yaw rate {:.4} rad/s, jerk RMS {:.2} m/s³, {} speed reversals",
                v.id,
                v.class.name(),
                m.w1_accel_mps2,
                m.w1_jerk_mps3,
                m.w1_yaw_rate_radps,
                m.jerk_rms_mps3,
                m.speed_reversals
            ),
            None => writeln!(out, "    {} ({}): no human reference for this class", v.id, v.class.name()),
        };
    }
    out
}
