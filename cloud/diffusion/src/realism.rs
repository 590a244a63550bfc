//! Realism of the trained model: Wasserstein-1 distances between the controls it generates for
//! held-out windows (their conditions, their initial states) and the held-out windows' recorded
//! controls, for acceleration, jerk and yaw rate, with and without guidance. The distance between
//! training and held-out data is the floor that sampling noise alone gives.
//!
//! Guidance per held-out window: its conflict anchors (the recorded passage times), its agents'
//! recorded window-end positions, and for `full` also the solid boundaries of the corpus map
//! within 40 m, clearance outside the conflict and the kinematic limits.

use v2t_map::Map;
use v2t_map::boundaries::solid_boundaries;
use v2t_model::geometry::Point2;
use v2t_model::kinematics::{State, rollout_into};

use crate::guidance::{Anchor, ConflictWindow, Guidance, GuidanceConfig, GuidanceContext, GuidanceWeights};
use crate::sample::{Problem, SampleError, SamplerOptions, sample};
use crate::stats::{ControlDistances, ControlSamples};
use crate::train::Window;
use crate::weights::Model;

/// One row of the realism table.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct RealismRow {
    /// What was compared with the held-out controls.
    pub name: String,
    /// Windows compared.
    pub windows: usize,
    /// W₁ per quantity (none for the reference row).
    pub distances: ControlDistances,
    /// RMS per quantity of what was compared (the reference row: of the held-out data).
    pub rms: ControlDistances,
    /// Median distance to the window's anchors at their times (guided rows), m.
    pub median_anchor_error_m: Option<f64>,
    /// 5 % and 95 % quantiles of W₁ over [`BOOTSTRAP_DRAWS`] bootstrap draws of the held-out
    /// windows (generated and recorded controls of a window drawn together): how much of a
    /// difference between two rows the number of windows can tell.
    pub interval: Option<ControlIntervals>,
}

/// Bootstrap quantiles per quantity: `(5 %, 95 %)`.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ControlIntervals {
    /// Acceleration, m/s².
    pub accel_mps2: Option<(f64, f64)>,
    /// Jerk, m/s³.
    pub jerk_mps3: Option<(f64, f64)>,
    /// Yaw rate, rad/s.
    pub yaw_rate_radps: Option<(f64, f64)>,
}

/// Bootstrap draws of the realism intervals.
pub const BOOTSTRAP_DRAWS: usize = 200;

/// The bootstrap interval of W₁ between `generated[i]` and `reference[i]` over windows `i`.
fn bootstrap(generated: &[ControlSamples], reference: &[ControlSamples], seed: u64) -> Option<ControlIntervals> {
    use rand_chacha::ChaCha8Rng;
    use rand_chacha::rand_core::{Rng, SeedableRng};
    let n = generated.len().min(reference.len());
    if n < 2 {
        return None;
    }
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0xb007_57a9);
    let (mut a, mut j, mut y) = (Vec::new(), Vec::new(), Vec::new());
    for _ in 0..BOOTSTRAP_DRAWS {
        let (mut g, mut r) = (ControlSamples::default(), ControlSamples::default());
        for _ in 0..n {
            let i = (rng.next_u64() % n as u64) as usize;
            if let (Some(gi), Some(ri)) = (generated.get(i), reference.get(i)) {
                g.extend(gi);
                r.extend(ri);
            }
        }
        let d = g.distance(&r);
        a.extend(d.accel_mps2);
        j.extend(d.jerk_mps3);
        y.extend(d.yaw_rate_radps);
    }
    let q = |v: &mut Vec<f64>| -> Option<(f64, f64)> {
        v.sort_by(f64::total_cmp);
        let at = |f: f64| v.get(((v.len() - 1) as f64 * f).round() as usize).copied();
        at(0.05).zip(at(0.95))
    };
    Some(ControlIntervals { accel_mps2: q(&mut a), jerk_mps3: q(&mut j), yaw_rate_radps: q(&mut y) })
}

/// The guidance with `weights` for a recorded window (its conflict anchors and window-end
/// positions, and with a map the solid boundaries within 40 m), and its agents' initial states.
pub fn window_guidance(
    w: &Window,
    weights: GuidanceWeights,
    map: Option<&Map>,
    steps: usize,
) -> Result<(Guidance, Vec<State>), SampleError> {
    let used: Vec<_> = w.condition.slots.iter().flatten().collect();
    let x0s: Vec<State> = used.iter().map(|s| s.start).collect();
    let mut anchors: Vec<Anchor> = used
        .iter()
        .enumerate()
        .filter_map(|(agent, s)| s.anchor.map(|(position, time_s)| Anchor { agent, position, time_s }))
        .collect();
    let dt = crate::synth::DT_S;
    anchors.extend(w.end_positions.iter().enumerate().map(|(agent, p)| Anchor {
        agent,
        position: *p,
        time_s: w.data_steps.get(agent).copied().unwrap_or(steps) as f64 * dt,
    }));
    let times: Vec<f64> = used.iter().filter_map(|s| s.anchor.map(|(_, t)| t)).collect();
    let conflict_windows = if times.len() == 2 && used.len() >= 2 {
        let (lo, hi) = times.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), t| (a.min(*t), b.max(*t)));
        vec![ConflictWindow { agent_a: 0, agent_b: 1, from_s: lo - 1.5, to_s: hi + 1.5 }]
    } else {
        Vec::new()
    };
    let near: Vec<Point2> = x0s.iter().map(State::position).chain(w.end_positions.iter().copied()).collect();
    let boundaries = match map {
        Some(m) if weights.boundary > 0.0 => solid_boundaries(m, &near, 40.0, 0.05),
        _ => Vec::new(),
    };
    let context = GuidanceContext {
        anchors,
        boundaries,
        conflict_windows,
        boundary_sides: Vec::new(),
        previous_accel_mps2: Vec::new(),
    };
    let config = GuidanceConfig { agents: used.len(), steps, weights, ..GuidanceConfig::default() };
    Ok((Guidance::new(config, context)?, x0s))
}

/// The realism rows: training vs held-out (the floor, when `train` is given), then one per
/// guidance mode in `modes` (`None` weights: no guidance), over at most `max_windows` held-out
/// windows: one per episode, or with `spacing_steps` every window that starts at least that many
/// steps after the last one taken of its episode (recorded episodes are few and their windows
/// start at every step). Where a recorded window holds fewer steps than the horizon, only those
/// steps of the generated controls are compared.
#[allow(clippy::too_many_arguments)] // each is a separate choice of the caller
pub fn realism(
    model: &Model,
    heldout: &[Window],
    train: Option<&[Window]>,
    spacing_steps: Option<usize>,
    map: Option<&Map>,
    modes: &[(&str, Option<GuidanceWeights>)],
    max_windows: usize,
    seed: u64,
    options: &SamplerOptions,
) -> Result<Vec<RealismRow>, SampleError> {
    let cfg = *model.denoiser.config();
    let dt = crate::synth::DT_S;
    let chosen_windows = |ws: &[Window]| -> Vec<Window> {
        let mut last: std::collections::HashMap<usize, usize> = std::collections::HashMap::new();
        ws.iter()
            .filter(|w| {
                let take = match (last.get(&w.episode), spacing_steps) {
                    (None, _) => true,
                    (Some(_), None) => false,
                    (Some(&l), Some(gap)) => w.start_step >= l + gap,
                };
                if take {
                    last.insert(w.episode, w.start_step);
                }
                take
            })
            .take(max_windows)
            .cloned()
            .collect()
    };
    let heldout = chosen_windows(heldout);
    let samples_of = |ws: &[Window]| {
        let mut s = ControlSamples::default();
        for w in ws {
            for c in &w.controls {
                s.add_sequence(c, dt);
            }
        }
        s
    };
    let per_window: Vec<ControlSamples> = heldout.iter().map(|w| samples_of(std::slice::from_ref(w))).collect();
    let reference = samples_of(&heldout);
    let none = ControlDistances { accel_mps2: None, jerk_mps3: None, yaw_rate_radps: None };
    let mut rows = vec![RealismRow {
        name: "held-out data (reference)".into(),
        windows: heldout.len(),
        distances: none,
        rms: reference.rms(),
        median_anchor_error_m: None,
        interval: None,
    }];
    if let Some(train) = train {
        let train = chosen_windows(train);
        let samples = samples_of(&train);
        rows.push(RealismRow {
            name: "training data (floor)".into(),
            windows: train.len(),
            distances: samples.distance(&reference),
            rms: samples.rms(),
            median_anchor_error_m: None,
            interval: None,
        });
    }
    for (name, weights) in modes {
        let mut generated = ControlSamples::default();
        let mut generated_per_window = Vec::with_capacity(heldout.len());
        let mut errors = Vec::new();
        for (k, w) in heldout.iter().enumerate() {
            let mut this_window = ControlSamples::default();
            let guided = match weights {
                Some(wt) => Some(window_guidance(w, *wt, map, cfg.steps)?),
                None => None,
            };
            let x0s: Vec<State> = w.condition.slots.iter().flatten().map(|s| s.start).collect();
            let problem = Problem { condition: &w.condition, guidance: guided.as_ref().map(|(g, _)| g), x0s: &x0s };
            let variants = sample(model, &problem, 1, seed.wrapping_add(k as u64), options)?;
            for v in &variants {
                for (agent, c) in v.controls.iter().enumerate() {
                    let n = w.data_steps.get(agent).copied().unwrap_or(c.len()).min(c.len());
                    let c = c.get(..n).unwrap_or(c);
                    generated.add_sequence(c, dt);
                    this_window.add_sequence(c, dt);
                    let Some(x0) = x0s.get(agent) else { continue };
                    let mut states = vec![State::default(); c.len() + 1];
                    rollout_into(*x0, c, dt, &mut states);
                    let anchor = w.condition.slots.iter().flatten().nth(agent).and_then(|s| s.anchor);
                    let targets = anchor.into_iter().chain(w.end_positions.get(agent).map(|p| (*p, n as f64 * dt)));
                    for (p, t) in targets {
                        let i = ((t / dt).round() as usize).min(states.len() - 1);
                        if let Some(x) = states.get(i) {
                            errors.push(x.position().dist(p));
                        }
                    }
                }
            }
            generated_per_window.push(this_window);
        }
        rows.push(RealismRow {
            name: (*name).to_owned(),
            windows: heldout.len(),
            distances: generated.distance(&reference),
            rms: generated.rms(),
            median_anchor_error_m: crate::stats::median(&mut errors),
            interval: bootstrap(&generated_per_window, &per_window, seed),
        });
    }
    Ok(rows)
}
