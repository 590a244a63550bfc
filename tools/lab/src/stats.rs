//! Repeated runs of one case: the statistics every experiment reports, computed in one place.
//!
//! Per run the PET that counts is `PET_min`, the smallest PET over the run's conflicts. Over the
//! runs of a case: `meanPET^min` is the mean of the per-run values, `PET^min_track` the smallest,
//! and the steering error `|meanPET^min − τ| / τ`. A run that could not be built or did not finish
//! counts as a run without a measured PET (`unmeasured`) and as `failed`; it never disappears from
//! the denominators.

use serde::Serialize;
use v2t_model::realism::{ManoeuvreClass, MotionRealism};
use v2t_sim::realism::{RunRealism, VehicleRealism};
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
    bv_realism: RealismTally,
    vut_realism: RealismTally,
}

/// One vehicle role's realism over runs.
#[derive(Debug, Clone, Default)]
struct RealismTally {
    class: Option<ManoeuvreClass>,
    runs: usize,
    measured: Vec<MotionRealism>,
}

impl RealismTally {
    fn add(&mut self, v: Option<&VehicleRealism>) {
        let Some(v) = v else { return };
        self.runs += 1;
        // The class of the first run names the row; a run in another class is not averaged in.
        let class = *self.class.get_or_insert(v.class);
        if let Some(m) = v.realism.filter(|m| m.class == class) {
            self.measured.push(m);
        }
    }

    fn stats(&self) -> Option<RealismStats> {
        let class = self.class?;
        let n = self.measured.len();
        let mean = |f: &dyn Fn(&MotionRealism) -> f64| self.measured.iter().map(f).sum::<f64>() / n as f64;
        Some(RealismStats {
            class,
            runs: self.runs,
            measured: n,
            means: (n > 0).then(|| RealismMeans {
                w1_accel_mps2: mean(&|m| m.w1_accel_mps2),
                w1_jerk_mps3: mean(&|m| m.w1_jerk_mps3),
                w1_yaw_rate_radps: mean(&|m| m.w1_yaw_rate_radps),
                jerk_rms_mps3: mean(&|m| m.jerk_rms_mps3),
                speed_reversals: mean(&|m| m.speed_reversals as f64),
            }),
        })
    }
}

/// How human one vehicle's motion was over the runs of a case, against recorded human driving in
/// its manoeuvre class ([`v2t_sim::realism`]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct RealismStats {
    /// The class (of the first run's trajectory).
    pub class: ManoeuvreClass,
    /// Runs whose realism was asked for.
    pub runs: usize,
    /// Runs measured (0 when the reference has no human driving of this class).
    pub measured: usize,
    /// Means over the measured runs.
    pub means: Option<RealismMeans>,
}

/// Means over runs of [`MotionRealism`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct RealismMeans {
    /// W₁ of longitudinal acceleration, m/s².
    pub w1_accel_mps2: f64,
    /// W₁ of jerk, m/s³.
    pub w1_jerk_mps3: f64,
    /// W₁ of yaw rate, rad/s.
    pub w1_yaw_rate_radps: f64,
    /// Jerk RMS, m/s³.
    pub jerk_rms_mps3: f64,
    /// Speed reversals per run.
    pub speed_reversals: f64,
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

    /// The realism of one run that ran (the first BV's, and the VUT's).
    pub fn add_realism(&mut self, r: &RunRealism) {
        self.bv_realism.add(r.bv(0));
        self.vut_realism.add(r.vut());
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
            pets_s: self.pets.clone(),
            pet_min_track_s: self.pets.iter().copied().reduce(f64::min),
            collisions: self.collisions,
            zone_overlaps: self.zone_overlaps,
            order_ok_frac: if self.runs == 0 { 0.0 } else { self.order_ok as f64 / self.runs as f64 },
            unmeasured: self.unmeasured,
            failed: self.failed,
            bv_realism: self.bv_realism.stats(),
            vut_realism: self.vut_realism.stats(),
        }
    }
}

/// The largest lateral acceleration of trace agent `agent` (0: the VUT, 1: the first BV) in
/// `run`, m/s²: its speed times its yaw rate between trace samples; 0 without two samples.
pub fn peak_lateral_mps2(run: &v2t_sim::runner::RunOutcome, agent: usize) -> f64 {
    run.trace
        .windows(2)
        .filter_map(|w| {
            let (a, b) = (w.first()?, w.get(1)?);
            let (pa, pb) = (a.agents.get(agent)?.state, b.agents.get(agent)?.state);
            let dt = b.t_s - a.t_s;
            let turn = v2t_model::geometry::wrap_angle(pb.theta_rad - pa.theta_rad);
            (dt > 0.0).then(|| (pb.speed_mps * turn / dt).abs())
        })
        .filter(|x| x.is_finite())
        .fold(0.0, f64::max)
}

/// What the repeated runs of one case measured.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RunStats {
    /// Runs, failed ones included.
    pub repeats: usize,
    /// Mean over runs of PET_min, s (runs without a measured PET are left out and counted in
    /// `unmeasured`).
    pub mean_pet_min_s: Option<f64>,
    /// PET_min of every run with a measured PET, in the order the runs were added, s (the spread
    /// the reports plot).
    pub pets_s: Vec<f64>,
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
    /// How human the (first) BV's motion was; `None` when realism was not measured.
    pub bv_realism: Option<RealismStats>,
    /// How human the VUT's motion was, for reference.
    pub vut_realism: Option<RealismStats>,
}

impl RealismStats {
    /// The realism of several cases of one vehicle role pooled: runs add up, means weighted by the
    /// runs measured; `None` when no case has realism or their classes differ.
    pub fn pool<'a>(cases: impl IntoIterator<Item = &'a RealismStats>) -> Option<RealismStats> {
        let mut out: Option<RealismStats> = None;
        for c in cases {
            let Some(acc) = out.as_mut() else {
                out = Some(*c);
                continue;
            };
            if acc.class != c.class {
                return None;
            }
            let (n0, n1) = (acc.measured as f64, c.measured as f64);
            acc.means = match (acc.means, c.means) {
                (Some(a), Some(b)) => {
                    let w = |x: f64, y: f64| (x * n0 + y * n1) / (n0 + n1);
                    Some(RealismMeans {
                        w1_accel_mps2: w(a.w1_accel_mps2, b.w1_accel_mps2),
                        w1_jerk_mps3: w(a.w1_jerk_mps3, b.w1_jerk_mps3),
                        w1_yaw_rate_radps: w(a.w1_yaw_rate_radps, b.w1_yaw_rate_radps),
                        jerk_rms_mps3: w(a.jerk_rms_mps3, b.jerk_rms_mps3),
                        speed_reversals: w(a.speed_reversals, b.speed_reversals),
                    })
                }
                (a, b) => a.or(b),
            };
            acc.runs += c.runs;
            acc.measured += c.measured;
        }
        out
    }

    /// Markdown cells: class, W₁ of acceleration and of jerk, jerk RMS, speed reversals per run
    /// (`no human reference` where the class has none).
    pub fn cells(r: Option<&RealismStats>) -> String {
        match r {
            None => "– | – | – | – | –".into(),
            Some(r) => match r.means {
                Some(m) => format!(
                    "{} | {:.3} | {:.3} | {:.2} | {:.1}",
                    r.class.name(),
                    m.w1_accel_mps2,
                    m.w1_jerk_mps3,
                    m.jerk_rms_mps3,
                    m.speed_reversals
                ),
                None => format!("{} | no human reference | – | – | –", r.class.name()),
            },
        }
    }
}

impl RunStats {
    /// The steering error of the mean, `|meanPET^min − τ| / τ`; `None` without a measured PET.
    /// Overshoot and undershoot of single runs cancel in it: see [`Self::single_runs`].
    pub fn error_rel(&self, tau_s: f64) -> Option<f64> {
        self.mean_pet_min_s.map(|m| (m - tau_s).abs() / tau_s)
    }

    /// Every run scored on its own against τ: the mean of `|PET^min − τ| / τ` over the runs and
    /// the share of runs within ±10 % of τ (a run without a measured PET, or that failed, counts
    /// as error 1 and outside; a failed run counts among the unmeasured). `None` without a run.
    pub fn single_runs(&self, tau_s: f64) -> Option<SingleRuns> {
        let missing = self.repeats.saturating_sub(self.pets_s.len());
        SingleRuns::of(
            self.pets_s.iter().map(Some).chain(std::iter::repeat_n(None, missing)).map(|p| p.copied()),
            tau_s,
        )
    }
}

/// Runs scored one by one against τ.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct SingleRuns {
    /// Mean of the single runs' `|PET − τ| / τ` (no PET: 1).
    pub mean_error_rel: f64,
    /// Share of the runs within ±10 % of τ.
    pub within_10_frac: f64,
}

impl SingleRuns {
    /// The runs' PETs (`None`: no PET) scored against `tau_s`: error 1 and outside for a run without
    /// a PET. `None` without a run.
    pub fn of(pets_s: impl Iterator<Item = Option<f64>>, tau_s: f64) -> Option<Self> {
        let (mut runs, mut sum, mut within) = (0_usize, 0.0, 0_usize);
        for p in pets_s {
            let e = p.map_or(1.0, |p| (p - tau_s).abs() / tau_s);
            runs += 1;
            sum += e;
            within += usize::from(e <= 0.10);
        }
        (runs > 0).then(|| Self { mean_error_rel: sum / runs as f64, within_10_frac: within as f64 / runs as f64 })
    }
    /// Cases' single runs pooled, each weighted by its number of runs (zero without a run).
    pub fn pool(cases: impl Iterator<Item = (Self, usize)>) -> Self {
        let (mut runs, mut err, mut within) = (0.0, 0.0, 0.0);
        for (s, n) in cases {
            let n = n as f64;
            runs += n;
            err += s.mean_error_rel * n;
            within += s.within_10_frac * n;
        }
        if runs > 0.0 {
            Self { mean_error_rel: err / runs, within_10_frac: within / runs }
        } else {
            Self { mean_error_rel: 0.0, within_10_frac: 0.0 }
        }
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use v2t_model::Style;

    #[test]
    fn single_runs_are_scored_one_by_one_and_do_not_cancel() {
        let mut t = Tally::default();
        for pet in [1.6, 2.4, 2.1] {
            t.add(&run(Some(pet), false, true));
        }
        t.add(&run(None, false, true));
        t.add_failed();
        let s = t.stats();
        // The mean of the three PETs is τ within 1.7 %: overshoot and undershoot cancel.
        assert!(s.error_rel(2.0).unwrap() < 0.02);
        let single = s.single_runs(2.0).unwrap();
        assert!((single.mean_error_rel - (0.2 + 0.2 + 0.05 + 1.0 + 1.0) / 5.0).abs() < 1e-12);
        assert!((single.within_10_frac - 0.2).abs() < 1e-12);
        assert!(Tally::default().stats().single_runs(2.0).is_none());
    }

    fn run(pet: Option<f64>, collision: bool, order_ok: bool) -> RunResult {
        RunResult {
            scenario: "s".into(),
            vut_model: "m".into(),
            bv_controller: "c".into(),
            seed: 1,
            target: v2t_model::Target::new(2.0, Style::Rush).unwrap(),
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

    fn realism(class: ManoeuvreClass, w1_accel: Option<f64>) -> RunRealism {
        let m = |w: f64| MotionRealism {
            class,
            w1_accel_mps2: w,
            w1_jerk_mps3: 2.0 * w,
            w1_yaw_rate_radps: 0.01,
            jerk_rms_mps3: 1.0,
            speed_reversals: 1,
        };
        let v = |id: &str, c, r| VehicleRealism { id: id.into(), class: c, realism: r };
        RunRealism {
            vehicles: vec![
                v("vut", ManoeuvreClass::Straight, Some(m(0.1))),
                v("bv1", class, w1_accel.map(|w| MotionRealism { class, ..m(w) })),
            ],
        }
    }

    #[test]
    fn realism_is_averaged_over_measured_runs_and_pooled_by_runs() {
        let mut t = Tally::default();
        t.add_realism(&realism(ManoeuvreClass::LaneChange, Some(0.2)));
        t.add_realism(&realism(ManoeuvreClass::LaneChange, Some(0.4)));
        let a = t.stats().bv_realism.unwrap();
        assert_eq!((a.class, a.runs, a.measured), (ManoeuvreClass::LaneChange, 2, 2));
        let m = a.means.unwrap();
        assert!((m.w1_accel_mps2 - 0.3).abs() < 1e-12 && (m.w1_jerk_mps3 - 0.6).abs() < 1e-12);
        // A second case with one run at 0.9: pooled by runs measured, (0.2 + 0.4 + 0.9) / 3.
        let mut u = Tally::default();
        u.add_realism(&realism(ManoeuvreClass::LaneChange, Some(0.9)));
        let b = u.stats().bv_realism.unwrap();
        let pooled = RealismStats::pool([&a, &b]).unwrap();
        assert_eq!((pooled.runs, pooled.measured), (3, 3));
        assert!((pooled.means.unwrap().w1_accel_mps2 - 0.5).abs() < 1e-12);
        // A class without a human reference is counted and says so; classes never mix.
        let mut l = Tally::default();
        l.add_realism(&realism(ManoeuvreClass::LeftTurn, None));
        let c = l.stats().bv_realism.unwrap();
        assert_eq!((c.runs, c.measured, c.means), (1, 0, None));
        assert!(RealismStats::cells(Some(&c)).contains("no human reference"));
        assert_eq!(RealismStats::pool([&a, &c]), None);
        assert_eq!(t.stats().vut_realism.unwrap().class, ManoeuvreClass::Straight);
        assert_eq!(Tally::default().stats().bv_realism, None, "not measured: no realism at all");
    }
}
