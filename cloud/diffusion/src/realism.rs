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
use crate::train::{Dataset, Window};
use crate::weights::Model;

/// One row of the realism table.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct RealismRow {
    /// What was compared with the held-out controls.
    pub name: String,
    /// Windows compared.
    pub windows: usize,
    /// W₁ per quantity.
    pub distances: ControlDistances,
    /// Median distance to the window's anchors at their times (guided rows), m.
    pub median_anchor_error_m: Option<f64>,
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
    let horizon = steps as f64 * crate::synth::DT_S;
    anchors.extend(w.end_positions.iter().enumerate().map(|(agent, p)| Anchor {
        agent,
        position: *p,
        time_s: horizon,
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

/// The realism rows: training vs held-out (the floor), then one per guidance mode in `modes`
/// (`None` weights: no guidance), over at most `max_windows` held-out windows (one per episode).
pub fn realism(
    model: &Model,
    data: &Dataset,
    map: Option<&Map>,
    modes: &[(&str, Option<GuidanceWeights>)],
    max_windows: usize,
    seed: u64,
    options: &SamplerOptions,
) -> Result<Vec<RealismRow>, SampleError> {
    let cfg = *model.denoiser.config();
    let dt = crate::synth::DT_S;
    let first_per_episode = |ws: &[Window]| -> Vec<Window> {
        let mut seen = std::collections::HashSet::new();
        ws.iter().filter(|w| seen.insert(w.episode)).take(max_windows).cloned().collect()
    };
    let heldout = first_per_episode(&data.heldout);
    let train = first_per_episode(&data.train);
    let samples_of = |ws: &[Window]| {
        let mut s = ControlSamples::default();
        for w in ws {
            for c in &w.controls {
                s.add_sequence(c, dt);
            }
        }
        s
    };
    let reference = samples_of(&heldout);
    let mut rows = vec![RealismRow {
        name: "training data (floor)".into(),
        windows: train.len(),
        distances: samples_of(&train).distance(&reference),
        median_anchor_error_m: None,
    }];
    for (name, weights) in modes {
        let mut generated = ControlSamples::default();
        let mut errors = Vec::new();
        for (k, w) in heldout.iter().enumerate() {
            let guided = match weights {
                Some(wt) => Some(window_guidance(w, *wt, map, cfg.steps)?),
                None => None,
            };
            let x0s: Vec<State> = w.condition.slots.iter().flatten().map(|s| s.start).collect();
            let problem = Problem { condition: &w.condition, guidance: guided.as_ref().map(|(g, _)| g), x0s: &x0s };
            let variants = sample(model, &problem, 1, seed.wrapping_add(k as u64), options)?;
            for v in &variants {
                for (agent, c) in v.controls.iter().enumerate() {
                    generated.add_sequence(c, dt);
                    let Some(x0) = x0s.get(agent) else { continue };
                    let mut states = vec![State::default(); c.len() + 1];
                    rollout_into(*x0, c, dt, &mut states);
                    let anchor = w.condition.slots.iter().flatten().nth(agent).and_then(|s| s.anchor);
                    let targets =
                        anchor.into_iter().chain(w.end_positions.get(agent).map(|p| (*p, cfg.steps as f64 * dt)));
                    for (p, t) in targets {
                        let i = ((t / dt).round() as usize).min(states.len() - 1);
                        if let Some(x) = states.get(i) {
                            errors.push(x.position().dist(p));
                        }
                    }
                }
            }
        }
        rows.push(RealismRow {
            name: (*name).to_owned(),
            windows: heldout.len(),
            distances: generated.distance(&reference),
            median_anchor_error_m: crate::stats::median(&mut errors),
        });
    }
    Ok(rows)
}
