//! Guidance energies: gradients against central finite differences, zero where constraints hold,
//! weights switching terms off, anchor reaching by gradient descent, NaN safety, and the guided
//! correction in normalized space.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic, clippy::indexing_slicing)]

use proptest::prelude::*;
use v2t_diffusion::guidance::normalized::{ControlNormalization, GuidanceStep, guided_posterior_mean};
use v2t_diffusion::guidance::{
    Anchor, ConflictWindow, Guidance, GuidanceConfig, GuidanceContext, GuidanceError, GuidanceWeights,
    GuidanceWorkspace, KinematicLimits,
};
use v2t_model::geometry::Point2;
use v2t_model::kinematics::{Control, State, rollout};

const OFF: GuidanceWeights = GuidanceWeights { anchor: 0.0, boundary: 0.0, clearance: 0.0, kinematic: 0.0 };

fn energy(g: &Guidance, x0s: &[State], u: &[Control]) -> f64 {
    let mut ws = GuidanceWorkspace::new(g);
    let mut grad = vec![Control::default(); u.len()];
    g.energy_and_grad(&mut ws, x0s, u, &mut grad).unwrap().total
}

/// Relative L2 error of the analytic gradient against central differences.
fn fd_error(g: &Guidance, x0s: &[State], u: &[Control]) -> (f64, f64) {
    let mut ws = GuidanceWorkspace::new(g);
    let mut grad = vec![Control::default(); u.len()];
    g.energy_and_grad(&mut ws, x0s, u, &mut grad).unwrap();
    let h = 1e-6;
    let (mut diff, mut norm) = (0.0, 0.0);
    for t in 0..u.len() {
        for ch in 0..2 {
            let mut up = u.to_vec();
            let mut dn = u.to_vec();
            if ch == 0 {
                up[t].accel_mps2 += h;
                dn[t].accel_mps2 -= h;
            } else {
                up[t].yaw_rate_radps += h;
                dn[t].yaw_rate_radps -= h;
            }
            let fd = (energy(g, x0s, &up) - energy(g, x0s, &dn)) / (2.0 * h);
            let an = if ch == 0 { grad[t].accel_mps2 } else { grad[t].yaw_rate_radps };
            diff += (an - fd).powi(2);
            norm += fd * fd;
        }
    }
    (diff.sqrt() / norm.sqrt().max(1e-3), norm.sqrt())
}

#[derive(Debug, Clone)]
struct Problem {
    x0s: Vec<State>,
    controls: Vec<Control>,
    steps: usize,
    anchors: Vec<(Point2, f64)>,
    boundary_y: f64,
}

fn problem() -> impl Strategy<Value = Problem> {
    (1usize..=3, 1usize..=20).prop_flat_map(|(n, steps)| {
        (
            prop::collection::vec((0.0f64..20.0, -4.0f64..4.0, -0.5f64..0.5, 0.0f64..14.0), n),
            prop::collection::vec((-3.0f64..3.0, -0.6f64..0.6), n * steps),
            prop::collection::vec((0.0f64..30.0, -4.0f64..4.0, 0.0f64..2.5), 2 * n),
            -2.0f64..2.0,
        )
            .prop_map(move |(x0s, u, anchors, boundary_y)| Problem {
                x0s: x0s
                    .into_iter()
                    .map(|(px, py, theta_rad, speed_mps)| State { px, py, theta_rad, speed_mps })
                    .collect(),
                controls: u.into_iter().map(|(a, w)| Control { accel_mps2: a, yaw_rate_radps: w }).collect(),
                steps,
                anchors: anchors.into_iter().map(|(x, y, t)| (Point2::new(x, y), t)).collect(),
                boundary_y,
            })
    })
}

fn guidance_for(p: &Problem, weights: GuidanceWeights) -> Guidance {
    let n = p.x0s.len();
    let config = GuidanceConfig {
        agents: n,
        steps: p.steps,
        dt_s: 0.1,
        weights,
        boundary_margin_m: 1.5,
        clearance_radius_m: 6.0,
        limits: KinematicLimits {
            accel_min_mps2: -1.0,
            accel_max_mps2: 1.0,
            lat_accel_max_mps2: 1.0,
            jerk_max_mps3: 3.0,
            speed_max_mps: 12.0,
        },
    };
    let y = p.boundary_y;
    let context = GuidanceContext {
        anchors: p
            .anchors
            .iter()
            .enumerate()
            .map(|(k, (position, time_s))| Anchor { agent: k % n, position: *position, time_s: *time_s })
            .collect(),
        // A long boundary with a kink, a repeated point (zero-length segment) and a second one.
        boundaries: vec![
            vec![Point2::new(-500.0, y), Point2::new(10.0, y + 0.5), Point2::new(10.0, y + 0.5), Point2::new(500.0, y)],
            vec![Point2::new(-500.0, y + 5.0), Point2::new(500.0, y + 5.0)],
        ],
        conflict_windows: if n >= 2 {
            vec![ConflictWindow { agent_a: 0, agent_b: 1, from_s: 0.5, to_s: 1.0 }]
        } else {
            vec![]
        },
        // Agent 0 belongs below the first boundary, the others where they first come alongside.
        boundary_sides: (0..n).map(|i| if i == 0 { vec![-1, 0] } else { vec![] }).collect(),
        // The first step's jerk counts against a previous acceleration (a stitched prior).
        previous_accel_mps2: (0..n).map(|i| 0.8 - 0.7 * i as f64).collect(),
    };
    Guidance::new(config, context).unwrap()
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]
    #[test]
    fn every_term_gradient_matches_central_differences(p in problem()) {
        let ones = [
            GuidanceWeights { anchor: 1.0, ..OFF },
            GuidanceWeights { boundary: 1.0, ..OFF },
            GuidanceWeights { clearance: 1.0, ..OFF },
            GuidanceWeights { kinematic: 1.0, ..OFF },
            GuidanceWeights { anchor: 0.7, boundary: 2.0, clearance: 1.3, kinematic: 0.5 },
        ];
        for w in ones {
            let g = guidance_for(&p, w);
            let (rel, _) = fd_error(&g, &p.x0s, &p.controls);
            prop_assert!(rel < 1e-5, "weights {w:?}: relative error {rel}");
        }
    }
}

#[test]
fn finite_difference_test_exercises_every_term() {
    // One fixed problem where every term is active, so the property test is not vacuous.
    let p = Problem {
        x0s: vec![
            State { px: 0.0, py: 0.3, theta_rad: 0.2, speed_mps: 13.0 },
            State { px: 3.0, py: 1.0, theta_rad: -0.1, speed_mps: 1.0 },
        ],
        controls: (0..30)
            .map(|k| Control { accel_mps2: if k % 2 == 0 { 2.5 } else { -2.5 }, yaw_rate_radps: 0.4 })
            .collect(),
        steps: 15,
        anchors: vec![(Point2::new(20.0, 3.0), 1.23), (Point2::new(5.0, -1.0), 0.71)],
        boundary_y: 0.0,
    };
    let weights = [
        GuidanceWeights { anchor: 1.0, ..OFF },
        GuidanceWeights { boundary: 1.0, ..OFF },
        GuidanceWeights { clearance: 1.0, ..OFF },
        GuidanceWeights { kinematic: 1.0, ..OFF },
    ];
    for w in weights {
        let g = guidance_for(&p, w);
        let (rel, norm) = fd_error(&g, &p.x0s, &p.controls);
        assert!(norm > 1e-2, "weights {w:?}: gradient norm {norm} (term inactive)");
        assert!(rel < 1e-5, "weights {w:?}: relative error {rel}");
    }
}

/// A straight drive at 10 m/s along y = 0, with everything consistent with it.
fn satisfied() -> (Guidance, Vec<State>, Vec<Control>) {
    let x0s = vec![
        State { px: 0.0, py: 0.0, theta_rad: 0.0, speed_mps: 10.0 },
        State { px: 0.0, py: 20.0, theta_rad: 0.0, speed_mps: 10.0 },
    ];
    let u = vec![Control::default(); 40];
    let config = GuidanceConfig { agents: 2, steps: 20, ..GuidanceConfig::default() };
    let context = GuidanceContext {
        anchors: vec![
            Anchor { agent: 0, position: Point2::new(0.0, 0.0), time_s: 0.0 },
            Anchor { agent: 0, position: Point2::new(15.0, 0.0), time_s: 1.5 },
            Anchor { agent: 1, position: Point2::new(12.5, 20.0), time_s: 1.25 },
            Anchor { agent: 1, position: Point2::new(20.0, 20.0), time_s: 2.0 },
        ],
        boundaries: vec![
            vec![Point2::new(-10.0, 1.75), Point2::new(100.0, 1.75)],
            vec![Point2::new(-10.0, -1.75), Point2::new(100.0, -1.75)],
        ],
        conflict_windows: vec![],
        boundary_sides: Vec::new(),
        previous_accel_mps2: Vec::new(),
    };
    (Guidance::new(config, context).unwrap(), x0s, u)
}

#[test]
fn zero_energy_and_gradient_where_constraints_hold() {
    let (g, x0s, u) = satisfied();
    let mut ws = GuidanceWorkspace::new(&g);
    let mut grad = vec![Control { accel_mps2: 7.0, yaw_rate_radps: 7.0 }; u.len()];
    let e = g.energy_and_grad(&mut ws, &x0s, &u, &mut grad).unwrap();
    assert!(e.anchor < 1e-20, "{e:?}");
    assert_eq!((e.boundary, e.clearance, e.kinematic), (0.0, 0.0, 0.0), "{e:?}");
    assert!(grad.iter().all(|c| c.accel_mps2.abs() < 1e-9 && c.yaw_rate_radps.abs() < 1e-9), "{grad:?}");
}

#[test]
fn zero_weights_switch_terms_off() {
    let (g0, x0s, _) = satisfied();
    // Violate everything: swerve across the boundary into the other agent, brake hard, jerk.
    let u: Vec<Control> =
        (0..40).map(|k| Control { accel_mps2: if k % 2 == 0 { 9.0 } else { -9.0 }, yaw_rate_radps: 1.0 }).collect();
    let context = g0.context().clone();
    let all_on = Guidance::new(GuidanceConfig { clearance_radius_m: 30.0, ..*g0.config() }, context.clone()).unwrap();
    let mut ws = GuidanceWorkspace::new(&all_on);
    let mut grad = vec![Control::default(); u.len()];
    let on = all_on.energy_and_grad(&mut ws, &x0s, &u, &mut grad).unwrap();
    assert!(on.anchor > 0.0 && on.boundary > 0.0 && on.clearance > 0.0 && on.kinematic > 0.0, "{on:?}");
    let off = Guidance::new(GuidanceConfig { weights: OFF, clearance_radius_m: 30.0, ..*g0.config() }, context.clone())
        .unwrap();
    let e = off.energy_and_grad(&mut ws, &x0s, &u, &mut grad).unwrap();
    assert_eq!(e.total, 0.0);
    assert_eq!((e.anchor, e.boundary, e.clearance, e.kinematic), (on.anchor, on.boundary, on.clearance, on.kinematic));
    assert!(grad.iter().all(|c| c.accel_mps2 == 0.0 && c.yaw_rate_radps == 0.0));
    // One term on at a time: the totals add up to the all-on total.
    let mut sum = 0.0;
    for w in [
        GuidanceWeights { anchor: 1.0, ..OFF },
        GuidanceWeights { boundary: 1.0, ..OFF },
        GuidanceWeights { clearance: 1.0, ..OFF },
        GuidanceWeights { kinematic: 1.0, ..OFF },
    ] {
        let gi =
            Guidance::new(GuidanceConfig { weights: w, clearance_radius_m: 30.0, ..*g0.config() }, context.clone())
                .unwrap();
        sum += gi.energy_and_grad(&mut ws, &x0s, &u, &mut grad).unwrap().total;
    }
    assert!((sum - on.total).abs() <= 1e-9 * on.total);
}

#[test]
fn conflict_window_switches_clearance_off_for_the_pair() {
    let x0s = vec![
        State { px: 0.0, py: 0.0, theta_rad: 0.0, speed_mps: 5.0 },
        State { px: 0.0, py: 1.0, theta_rad: 0.0, speed_mps: 5.0 },
    ];
    let u = vec![Control::default(); 20];
    let config = GuidanceConfig {
        agents: 2,
        steps: 10,
        weights: GuidanceWeights { clearance: 1.0, ..OFF },
        ..Default::default()
    };
    let mut grad = vec![Control::default(); 20];
    let open = Guidance::new(config, GuidanceContext::default()).unwrap();
    let mut ws = GuidanceWorkspace::new(&open);
    let e_open = open.energy_and_grad(&mut ws, &x0s, &u, &mut grad).unwrap().clearance;
    assert!((e_open - 10.0 * 9.0).abs() < 1e-9, "{e_open}"); // (4 − 1)² at 10 states
    let window = ConflictWindow { agent_a: 1, agent_b: 0, from_s: 0.25, to_s: 0.55 };
    let ctx = GuidanceContext { conflict_windows: vec![window], ..Default::default() };
    let closed = Guidance::new(config, ctx).unwrap();
    let e = closed.energy_and_grad(&mut ws, &x0s, &u, &mut grad).unwrap().clearance;
    assert!((e - 7.0 * 9.0).abs() < 1e-9, "{e}"); // t = 0.3, 0.4, 0.5 s off
}

#[test]
fn gradient_descent_reaches_an_early_anchor() {
    // Constant speed covers 30 m in 3 s; the anchor asks for 36 m.
    let x0s = [State { px: 0.0, py: 0.0, theta_rad: 0.0, speed_mps: 10.0 }];
    let config = GuidanceConfig { agents: 1, steps: 30, ..GuidanceConfig::default() };
    let context = GuidanceContext {
        anchors: vec![Anchor { agent: 0, position: Point2::new(36.0, 0.0), time_s: 3.0 }],
        ..Default::default()
    };
    let g = Guidance::new(config, context).unwrap();
    let mut ws = GuidanceWorkspace::new(&g);
    let mut u = vec![Control::default(); 30];
    let mut grad = vec![Control::default(); 30];
    let e0 = g.energy_and_grad(&mut ws, &x0s, &u, &mut grad).unwrap();
    assert!((e0.anchor - 36.0).abs() < 1e-9);
    for _ in 0..300 {
        g.energy_and_grad(&mut ws, &x0s, &u, &mut grad).unwrap();
        for (c, d) in u.iter_mut().zip(&grad) {
            c.accel_mps2 -= 0.3 * d.accel_mps2;
            c.yaw_rate_radps -= 0.3 * d.yaw_rate_radps;
        }
    }
    let e = g.energy_and_grad(&mut ws, &x0s, &u, &mut grad).unwrap();
    let end = rollout(x0s[0], &u, 0.1)[30];
    assert!(e.anchor.sqrt() < 0.03, "anchor error {} m", e.anchor.sqrt());
    assert!((end.px - 36.0).abs() < 0.03 && end.py.abs() < 1e-9, "{end:?}");
    assert!(u.iter().all(|c| c.accel_mps2 <= 3.05), "within the acceleration limit: {u:?}");
}

#[test]
fn degenerate_input_gives_finite_results() {
    // Zero speed, coincident agents, anchors at the start, a boundary through the start made of
    // zero-length segments only and one with a repeated point through the agents.
    let x0s = vec![State::default(); 3];
    let u = vec![Control::default(); 3 * 5];
    let config = GuidanceConfig { agents: 3, steps: 5, ..GuidanceConfig::default() };
    let context = GuidanceContext {
        anchors: vec![Anchor { agent: 1, position: Point2::new(0.0, 0.0), time_s: 0.2 }],
        boundaries: vec![
            vec![Point2::new(0.0, 0.0); 4],
            vec![Point2::new(-1.0, 0.0), Point2::new(0.0, 0.0), Point2::new(0.0, 0.0), Point2::new(1.0, 0.0)],
            vec![],
            vec![Point2::new(3.0, 3.0)],
        ],
        conflict_windows: vec![],
        boundary_sides: Vec::new(),
        previous_accel_mps2: Vec::new(),
    };
    let g = Guidance::new(config, context).unwrap();
    let mut ws = GuidanceWorkspace::new(&g);
    let mut grad = vec![Control::default(); u.len()];
    let e = g.energy_and_grad(&mut ws, &x0s, &u, &mut grad).unwrap();
    assert!(e.total.is_finite() && e.clearance > 0.0 && e.boundary > 0.0, "{e:?}");
    assert!(grad.iter().all(Control::is_finite));
}

#[test]
fn non_finite_and_misshapen_input_is_an_error() {
    let (g, x0s, u) = satisfied();
    let mut ws = GuidanceWorkspace::new(&g);
    let mut grad = vec![Control::default(); u.len()];
    let mut bad = u.clone();
    bad[7].yaw_rate_radps = f64::NAN;
    assert_eq!(
        g.energy_and_grad(&mut ws, &x0s, &bad, &mut grad),
        Err(GuidanceError::NonFiniteInput { what: "controls", index: 7 })
    );
    let mut bad_x = x0s.clone();
    bad_x[1].speed_mps = f64::INFINITY;
    assert!(matches!(g.energy_and_grad(&mut ws, &bad_x, &u, &mut grad), Err(GuidanceError::NonFiniteInput { .. })));
    assert!(matches!(g.energy_and_grad(&mut ws, &x0s, &u[1..], &mut grad), Err(GuidanceError::Shape { .. })));
    // Huge but finite controls overflow: an error, not NaN.
    let huge = vec![Control { accel_mps2: 1e300, yaw_rate_radps: 1e300 }; u.len()];
    match g.energy_and_grad(&mut ws, &x0s, &huge, &mut grad) {
        Ok(e) => assert!(e.total.is_finite() && grad.iter().all(Control::is_finite)),
        Err(e) => assert_eq!(e, GuidanceError::NonFiniteResult),
    }
    let bad_cfg = GuidanceConfig { dt_s: f64::NAN, ..GuidanceConfig::default() };
    assert!(Guidance::new(bad_cfg, GuidanceContext::default()).is_err());
    let bad_w = GuidanceConfig { weights: GuidanceWeights { anchor: f64::NAN, ..OFF }, ..GuidanceConfig::default() };
    assert!(Guidance::new(bad_w, GuidanceContext::default()).is_err());
}

#[test]
fn guided_correction_lowers_the_energy_and_respects_the_clip() {
    let x0s = [State { px: 0.0, py: 0.0, theta_rad: 0.0, speed_mps: 10.0 }];
    let config = GuidanceConfig { agents: 1, steps: 30, ..GuidanceConfig::default() };
    let context = GuidanceContext {
        anchors: vec![Anchor { agent: 0, position: Point2::new(33.0, 1.0), time_s: 3.0 }],
        ..Default::default()
    };
    let g = Guidance::new(config, context).unwrap();
    let mut ws = GuidanceWorkspace::new(&g);
    let norm = ControlNormalization::default();
    let z0 = vec![0.1; 60];
    let mut z1 = vec![0.0; 60];
    let step = GuidanceStep { scale: 0.01, max_step_norm: f64::INFINITY };
    let c = g.guide_clean_sample(&mut ws, &norm, &step, &x0s, &z0, &mut z1).unwrap();
    assert!((c.step_norm - 0.01 * c.grad_norm).abs() < 1e-12);
    let mut z2 = vec![0.0; 60];
    let after = g.guide_clean_sample(&mut ws, &norm, &step, &x0s, &z1, &mut z2).unwrap();
    assert!(after.energy.total < c.energy.total, "{} → {}", c.energy.total, after.energy.total);
    // The chain rule through the normalization: the correction equals η σ ∇_U E.
    let u: Vec<Control> = z0.chunks(2).map(|z| norm.denormalize([z[0], z[1]])).collect();
    let mut grad = vec![Control::default(); 30];
    g.energy_and_grad(&mut ws, &x0s, &u, &mut grad).unwrap();
    for (t, d) in grad.iter().enumerate() {
        assert!((z0[2 * t] - z1[2 * t] - 0.01 * 1.5 * d.accel_mps2).abs() < 1e-12);
        assert!((z0[2 * t + 1] - z1[2 * t + 1] - 0.01 * 0.15 * d.yaw_rate_radps).abs() < 1e-12);
    }
    // Clipping keeps the direction and caps the norm.
    let clipped = GuidanceStep { scale: 1e3, max_step_norm: 0.5 };
    let c = g.guide_clean_sample(&mut ws, &norm, &clipped, &x0s, &z0, &mut z1).unwrap();
    assert!((c.step_norm - 0.5).abs() < 1e-12);
    let moved: f64 = z0.iter().zip(&z1).map(|(a, b)| (a - b) * (a - b)).sum::<f64>().sqrt();
    assert!((moved - 0.5).abs() < 1e-9);
    let mut nan = z0.clone();
    nan[3] = f64::NAN;
    assert!(g.guide_clean_sample(&mut ws, &norm, &step, &x0s, &nan, &mut z1).is_err());
}

#[test]
fn guided_posterior_mean_matches_the_formula() {
    let (ab_k, ab_prev, beta) = (0.5f64, 0.6f64, 1.0 - 0.5 / 0.6);
    let u0 = [1.0, -2.0];
    let uk = [0.5, 0.25];
    let mut out = [0.0; 2];
    guided_posterior_mean(ab_k, ab_prev, beta, &u0, &uk, &mut out).unwrap();
    for i in 0..2 {
        let want =
            ab_prev.sqrt() * beta / (1.0 - ab_k) * u0[i] + (1.0 - beta).sqrt() * (1.0 - ab_prev) / (1.0 - ab_k) * uk[i];
        assert!((out[i] - want).abs() < 1e-15);
    }
    assert!(guided_posterior_mean(1.0, ab_prev, beta, &u0, &uk, &mut out).is_err());
    assert!(guided_posterior_mean(ab_k, ab_prev, beta, &u0, &uk[..1], &mut out).is_err());
}

#[test]
fn context_from_a_grounded_scenario() {
    use v2t_diffusion::guidance::ConflictTiming;
    use v2t_model::grounded::{AgentRole, AnchorState, GroundedAgent, GroundedConflict, GroundedScenario};
    use v2t_model::metrics::{ConflictKind, OccupancyInterval};
    use v2t_model::semantics::InteractionType;
    use v2t_model::{Style, Target};
    let anchor = |id: &str, x: f64, y: f64, t: Option<f64>| AnchorState {
        anchor_id: id.into(),
        position: Point2::new(x, y),
        heading_rad: 0.0,
        speed_mps: 10.0,
        time_s: t,
    };
    let agent = |id: &str, role, y: f64, t_goal| GroundedAgent {
        id: id.into(),
        role,
        route: vec![Point2::new(0.0, y), Point2::new(100.0, y)],
        start: anchor("s", 0.0, y, Some(0.0)),
        goal: anchor("g", 100.0, y, t_goal),
    };
    let conflict = |bv: &str| GroundedConflict {
        bv_id: bv.into(),
        kind: ConflictKind::Crossing,
        anchor_id: "c".into(),
        point: Point2::new(50.0, 0.0),
        vut_interval: OccupancyInterval { enter_s_m: 48.0, exit_s_m: 52.0 },
        bv_interval: OccupancyInterval { enter_s_m: 48.0, exit_s_m: 52.0 },
        bv_junction_entry: None,
    };
    let scenario = GroundedScenario {
        fragment_id: "f".into(),
        interaction_type: InteractionType::Crossing,
        agents: vec![
            agent("bv1", AgentRole::Bv, 3.0, None),
            agent("vut", AgentRole::Vut, 0.0, Some(10.0)),
            agent("bv2", AgentRole::Bv, -3.0, None),
        ],
        conflicts: vec![conflict("bv1"), conflict("bv2")],
        target: Target::new(1.5, Style::Rush).unwrap(),
    };
    let timing = ConflictTiming { bv_id: "bv1".into(), vut_time_s: 5.0, bv_time_s: 3.5 };
    let ctx = GuidanceContext::from_grounded(&scenario, &[timing], 0.5, vec![]).unwrap();
    // Three start anchors, the VUT's timed goal, and the conflict point for the VUT and bv1.
    assert_eq!(ctx.anchors.len(), 6);
    assert!(ctx.anchors.contains(&Anchor { agent: 1, position: Point2::new(100.0, 0.0), time_s: 10.0 }));
    assert!(ctx.anchors.contains(&Anchor { agent: 1, position: Point2::new(50.0, 0.0), time_s: 5.0 }));
    assert!(ctx.anchors.contains(&Anchor { agent: 0, position: Point2::new(50.0, 0.0), time_s: 3.5 }));
    let w = ctx.conflict_windows[0];
    assert!(w.covers(0, 1, 3.0) && w.covers(1, 0, 5.5) && !w.covers(0, 1, 5.6) && !w.covers(1, 2, 4.0));
    // bv2 has no timing: its pair with the VUT is off over the whole horizon.
    assert!(ctx.conflict_windows[1].covers(2, 1, 0.0) && ctx.conflict_windows[1].covers(1, 2, 1e6));
    let config = GuidanceConfig { agents: 3, steps: 100, ..GuidanceConfig::default() };
    assert!(Guidance::new(config, ctx).is_ok());
    let unknown = GroundedScenario { conflicts: vec![conflict("bv9")], ..scenario };
    assert_eq!(
        GuidanceContext::from_grounded(&unknown, &[], 0.5, vec![]),
        Err(GuidanceError::UnknownAgent("bv9".into()))
    );
}

/// Guidance of one agent over 20 steps by the boundary term alone, against one solid line.
fn one_agent_boundary_only(line: Vec<Point2>) -> Guidance {
    let config = GuidanceConfig {
        agents: 1,
        steps: 20,
        weights: GuidanceWeights { boundary: 1.0, ..OFF },
        ..Default::default()
    };
    Guidance::new(config, GuidanceContext { boundaries: vec![line], ..Default::default() }).unwrap()
}

#[test]
fn signed_distance_conventions_and_a_crossing_is_pushed_back() {
    use v2t_diffusion::guidance::terms::signed_distance;
    let line = [Point2::new(0.0, 0.0), Point2::new(10.0, 0.0)];
    let d = signed_distance(&line, Point2::new(5.0, 2.0)).unwrap();
    assert_eq!((d.signed_m, d.gradient, d.alongside), (2.0, Point2::new(0.0, 1.0), true)); // left is positive
    let d = signed_distance(&line, Point2::new(5.0, -2.0)).unwrap();
    assert_eq!((d.signed_m, d.alongside), (-2.0, true));
    // Beyond the last point there is no side: the distance to the end point, positive.
    let d = signed_distance(&line, Point2::new(13.0, -4.0)).unwrap();
    assert!(!d.alongside);
    assert!(
        (d.signed_m - 5.0).abs() < 1e-12 && (d.gradient.x - 0.6).abs() < 1e-12 && (d.gradient.y + 0.8).abs() < 1e-12
    );
    // At a joint between two segments the side is kept (the outside of a corner).
    let corner = [Point2::new(0.0, 0.0), Point2::new(10.0, 0.0), Point2::new(10.0, 10.0)];
    let d = signed_distance(&corner, Point2::new(12.0, -2.0)).unwrap();
    assert!(d.alongside && d.signed_m < 0.0, "{d:?}");
    assert!(signed_distance(&[Point2::new(1.0, 1.0); 3], Point2::new(0.0, 0.0)).is_none());
    // An agent starting below y = 1 that turns left across it: the boundary gradient steers right.
    let x0s = [State { px: 0.0, py: 0.0, theta_rad: 0.0, speed_mps: 10.0 }];
    let u = vec![Control { accel_mps2: 0.0, yaw_rate_radps: 0.3 }; 20];
    let g = one_agent_boundary_only(vec![Point2::new(-10.0, 1.0), Point2::new(100.0, 1.0)]);
    let mut ws = GuidanceWorkspace::new(&g);
    let mut grad = vec![Control::default(); 20];
    let e = g.energy_and_grad(&mut ws, &x0s, &u, &mut grad).unwrap();
    assert!(e.boundary > 1.0);
    assert!(grad[0].yaw_rate_radps > 0.0, "descending lowers the yaw rate: {:?}", grad[0]);
}

#[test]
fn a_boundary_ending_at_a_junction_does_not_reach_across_it() {
    // A road edge along y = 1 ending at x = 0; an agent crosses the line's extension (x < 0) far
    // from its end: no energy. One that drives alongside and crosses it: energy.
    let g = one_agent_boundary_only(vec![Point2::new(0.0, 1.0), Point2::new(100.0, 1.0)]);
    let mut ws = GuidanceWorkspace::new(&g);
    let mut grad = vec![Control::default(); 20];
    let north = [State { px: -20.0, py: -10.0, theta_rad: std::f64::consts::FRAC_PI_2, speed_mps: 10.0 }];
    let straight = vec![Control::default(); 20];
    let e = g.energy_and_grad(&mut ws, &north, &straight, &mut grad).unwrap();
    assert_eq!(e.boundary, 0.0, "{e:?}");
    let along = [State { px: 10.0, py: -3.0, theta_rad: 0.3, speed_mps: 10.0 }];
    let e = g.energy_and_grad(&mut ws, &along, &straight, &mut grad).unwrap();
    assert!(e.boundary > 1.0, "{e:?}");
}

fn wild() -> impl Strategy<Value = f64> {
    prop_oneof![Just(0.0), Just(-0.0), Just(1e-300), -1e6f64..1e6, Just(1e200), Just(-1e300), -1.0f64..1.0]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]
    /// Whatever finite input, the result is finite or an error, never NaN.
    #[test]
    fn never_nan_out(
        xs in prop::collection::vec(prop::array::uniform4(wild()), 2),
        us in prop::collection::vec(prop::array::uniform2(wild()), 2 * 6),
        pts in prop::collection::vec(prop::array::uniform2(wild()), 0..4),
    ) {
        let x0s: Vec<State> = xs.iter().map(|x| State { px: x[0], py: x[1], theta_rad: x[2], speed_mps: x[3] }).collect();
        let u: Vec<Control> = us.iter().map(|c| Control { accel_mps2: c[0], yaw_rate_radps: c[1] }).collect();
        let boundary: Vec<Point2> = pts.iter().map(|p| Point2::new(p[0], p[1])).collect();
        let config = GuidanceConfig { agents: 2, steps: 6, ..GuidanceConfig::default() };
        let ctx = GuidanceContext {
            anchors: vec![Anchor { agent: 1, position: boundary.first().copied().unwrap_or_default(), time_s: 0.33 }],
            boundaries: vec![boundary],
            conflict_windows: vec![], boundary_sides: Vec::new(), previous_accel_mps2: Vec::new() };
        let g = Guidance::new(config, ctx).unwrap();
        let mut ws = GuidanceWorkspace::new(&g);
        let mut grad = vec![Control::default(); u.len()];
        match g.energy_and_grad(&mut ws, &x0s, &u, &mut grad) {
            Ok(e) => {
                prop_assert!(e.total.is_finite() && e.total >= 0.0, "{e:?}");
                prop_assert!(grad.iter().all(Control::is_finite));
            }
            Err(e) => prop_assert_eq!(e, GuidanceError::NonFiniteResult),
        }
    }
}

#[test]
fn algorithm_1_with_an_oracle_denoiser() {
    use v2t_diffusion::guidance::normalized::predicted_clean_sample;
    // Lines 1–10 with a stand-in ε_θ that always points at the constant-speed prior Z0* = 0:
    // ε̂ = (U_k − √ᾱ_k Z0*) / √(1 − ᾱ_k). It ignores the corrections carried in U_k, so what is left
    // at k = 1 is one guided step from the prior; a trained denoiser keeps them. Guided, the sample
    // ends nearer the early anchor.
    let x0s = [State { px: 0.0, py: 0.0, theta_rad: 0.0, speed_mps: 10.0 }];
    let config = GuidanceConfig { agents: 1, steps: 30, ..GuidanceConfig::default() };
    let context = GuidanceContext {
        anchors: vec![Anchor { agent: 0, position: Point2::new(33.0, 0.5), time_s: 3.0 }],
        ..Default::default()
    };
    let g = Guidance::new(config, context).unwrap();
    let mut ws = GuidanceWorkspace::new(&g);
    let norm = ControlNormalization::default();
    let k_max = 50;
    let betas: Vec<f64> = (0..k_max).map(|k| 1e-3 + (0.2 - 1e-3) * k as f64 / (k_max - 1) as f64).collect();
    let alpha_bars: Vec<f64> = betas
        .iter()
        .scan(1.0, |a, b| {
            *a *= 1.0 - b;
            Some(*a)
        })
        .collect();
    let run = |eta: f64, ws: &mut GuidanceWorkspace| {
        // A fixed "noise" start.
        let mut u_k: Vec<f64> = (0..60).map(|i| ((i * 37 % 11) as f64 - 5.0) / 5.0).collect();
        let (mut eps, mut z0, mut z0t, mut next) = (vec![0.0; 60], vec![0.0; 60], vec![0.0; 60], vec![0.0; 60]);
        for k in (1..=k_max).rev() {
            let (ab, beta) = (alpha_bars[k - 1], betas[k - 1]);
            let ab_prev = if k >= 2 { alpha_bars[k - 2] } else { 1.0 };
            for (e, u) in eps.iter_mut().zip(&u_k) {
                *e = u / (1.0 - ab).sqrt();
            }
            predicted_clean_sample(ab, &u_k, &eps, &mut z0).unwrap();
            let step = GuidanceStep { scale: eta, max_step_norm: 5.0 };
            g.guide_clean_sample(ws, &norm, &step, &x0s, &z0, &mut z0t).unwrap();
            if k == 1 {
                return z0t.clone();
            }
            guided_posterior_mean(ab, ab_prev, beta, &z0t, &u_k, &mut next).unwrap();
            std::mem::swap(&mut u_k, &mut next);
        }
        unreachable!()
    };
    let anchor_error = |z: &[f64], ws: &mut GuidanceWorkspace| {
        let u: Vec<Control> = z.chunks(2).map(|p| norm.denormalize([p[0], p[1]])).collect();
        let mut grad = vec![Control::default(); 30];
        g.energy_and_grad(ws, &x0s, &u, &mut grad).unwrap().anchor.sqrt()
    };
    let unguided = run(0.0, &mut ws);
    let guided = run(0.2, &mut ws);
    let (e0, e1) = (anchor_error(&unguided, &mut ws), anchor_error(&guided, &mut ws));
    assert!(unguided.iter().all(|z| z.abs() < 1e-9), "the oracle alone returns its prior");
    assert!((e0 - (3.0f64 * 3.0 + 0.25).sqrt()).abs() < 1e-9, "{e0}");
    assert!(e1 < 0.25 * e0, "guided anchor error {e1} m, unguided {e0} m");
}

#[test]
fn invalid_context_is_rejected() {
    let config = GuidanceConfig { agents: 2, steps: 5, ..GuidanceConfig::default() };
    let bad_boundary = GuidanceContext {
        boundaries: vec![vec![Point2::new(0.0, 0.0), Point2::new(f64::NAN, 1.0)]],
        ..Default::default()
    };
    assert!(matches!(
        Guidance::new(config, bad_boundary),
        Err(GuidanceError::InvalidConfig { field: "boundaries", .. })
    ));
    let bad_anchor = GuidanceContext {
        anchors: vec![Anchor { agent: 2, position: Point2::new(0.0, 0.0), time_s: 1.0 }],
        ..Default::default()
    };
    assert!(Guidance::new(config, bad_anchor).is_err());
    let bad_window = GuidanceContext {
        conflict_windows: vec![ConflictWindow { agent_a: 0, agent_b: 1, from_s: f64::NAN, to_s: 1.0 }],
        ..Default::default()
    };
    assert!(Guidance::new(config, bad_window).is_err());
    assert!(Guidance::new(GuidanceConfig { steps: 0, ..config }, GuidanceContext::default()).is_err());
}
