//! Repeated runs of one case: the statistics every experiment reports, computed in one place.
//!
//! Per run the PET that counts is `PET_min`, the smallest PET over the run's conflicts. Over the
//! runs of a case: `meanPET^min` is the mean of the per-run values, `PET^min_track` the smallest,
//! and the steering error `|meanPET^min − τ| / τ`. A run that could not be built or did not finish
//! counts as a run without a measured PET (`unmeasured`) and as `failed`; it never disappears from
//! the denominators.

use serde::Serialize;
use v2t_sim::runner::RunResult;

/// Adds runs up.
#[derive(Debug, Clone, Default)]
pub struct Tally {
    pets: Vec<f64>,
    runs: usize,
    collisions: usize,
    zone_overlaps: usize,
    order_ok: usize,
    unmeasured: usize,
    failed: usize,
}

impl Tally {
    /// One run that ran.
    pub fn add(&mut self, r: &RunResult) {
        self.runs += 1;
        self.collisions += usize::from(r.collision.is_some());
        self.zone_overlaps += usize::from(r.zone_overlap);
        self.order_ok += usize::from(r.conflicts.iter().all(|c| c.order_matches_style == Some(true)));
        match r.pet_min_s {
            Some(p) => self.pets.push(p),
            None => self.unmeasured += 1,
        }
    }

    /// One run that could not be built or run.
    pub fn add_failed(&mut self) {
        self.runs += 1;
        self.failed += 1;
        self.unmeasured += 1;
    }

    /// What the runs so far measured.
    pub fn stats(&self) -> RunStats {
        let mean = (!self.pets.is_empty()).then(|| self.pets.iter().sum::<f64>() / self.pets.len() as f64);
        RunStats {
            repeats: self.runs,
            mean_pet_min_s: mean,
            pet_min_track_s: self.pets.iter().copied().reduce(f64::min),
            collisions: self.collisions,
            zone_overlaps: self.zone_overlaps,
            order_ok_frac: if self.runs == 0 { 0.0 } else { self.order_ok as f64 / self.runs as f64 },
            unmeasured: self.unmeasured,
            failed: self.failed,
        }
    }
}

/// What the repeated runs of one case measured.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct RunStats {
    /// Runs, failed ones included.
    pub repeats: usize,
    /// Mean over runs of PET_min, s (runs without a measured PET are left out and counted in
    /// `unmeasured`).
    pub mean_pet_min_s: Option<f64>,
    /// Smallest PET_min over the runs, s.
    pub pet_min_track_s: Option<f64>,
    /// Runs with a collision.
    pub collisions: usize,
    /// Runs in which both vehicles were in a conflict zone at once.
    pub zone_overlaps: usize,
    /// Share of all runs in which every conflict was passed in the style's order.
    pub order_ok_frac: f64,
    /// Runs without a measured PET (the second vehicle never came, or the run failed).
    pub unmeasured: usize,
    /// Runs that could not be built or did not finish.
    pub failed: usize,
}

impl RunStats {
    /// The steering error `|meanPET^min − τ| / τ`; `None` without a measured PET.
    pub fn error_rel(&self, tau_s: f64) -> Option<f64> {
        self.mean_pet_min_s.map(|m| (m - tau_s).abs() / tau_s)
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use v2t_model::Style;

    fn run(pet: Option<f64>, collision: bool, order_ok: bool) -> RunResult {
        RunResult {
            scenario: "s".into(),
            vut_model: "m".into(),
            bv_controller: "c".into(),
            seed: 1,
            style: Style::Rush,
            tau_s: 2.0,
            duration_s: 10.0,
            completed: true,
            conflicts: vec![v2t_sim::runner::ConflictResult {
                bv_id: "bv".into(),
                kind: v2t_model::metrics::ConflictKind::Crossing,
                pet: v2t_model::metrics::PetOutcome::NotReached,
                first: None,
                order_matches_style: Some(order_ok),
                vut_passage: None,
                bv_passage: None,
            }],
            pet_min_s: pet,
            min_distance_m: 3.0,
            min_distance_t_s: 1.0,
            min_ttc_s: None,
            collision: collision
                .then(|| v2t_sim::runner::CollisionEvent { t_s: 1.0, agents: ["vut".into(), "bv".into()] }),
            zone_overlap: false,
        }
    }

    #[test]
    fn known_runs_give_known_statistics() {
        let mut t = Tally::default();
        t.add(&run(Some(1.8), false, true));
        t.add(&run(Some(2.4), true, true));
        t.add(&run(None, false, false));
        t.add_failed();
        let s = t.stats();
        assert_eq!((s.repeats, s.collisions, s.unmeasured, s.failed), (4, 1, 2, 1));
        assert!((s.mean_pet_min_s.unwrap() - 2.1).abs() < 1e-12);
        assert_eq!(s.pet_min_track_s, Some(1.8));
        assert!((s.order_ok_frac - 0.5).abs() < 1e-12, "failed runs count in the denominator");
        assert!((s.error_rel(2.0).unwrap() - 0.05).abs() < 1e-12);
        let empty = Tally::default().stats();
        assert_eq!((empty.repeats, empty.mean_pet_min_s, empty.order_ok_frac), (0, None, 0.0));
        assert_eq!(empty.error_rel(2.0), None);
    }
}
