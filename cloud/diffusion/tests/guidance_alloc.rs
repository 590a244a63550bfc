//! The guidance hot path allocates nothing once its workspace is built (a counting global
//! allocator; its own test binary so that no other test allocates concurrently).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic, clippy::indexing_slicing)]

use v2t_diffusion::guidance::normalized::{ControlNormalization, GuidanceStep};
use v2t_diffusion::guidance::{Anchor, ConflictWindow, Guidance, GuidanceConfig, GuidanceContext, GuidanceWorkspace};
use v2t_model::geometry::Point2;
use v2t_model::kinematics::{Control, State};

#[global_allocator]
static GLOBAL: v2t_test_support::alloc::Counting = v2t_test_support::alloc::Counting;

#[test]
fn energy_and_grad_and_the_guided_correction_do_not_allocate() {
    let config = GuidanceConfig { agents: 3, steps: 40, ..GuidanceConfig::default() };
    let context = GuidanceContext {
        anchors: vec![
            Anchor { agent: 0, position: Point2::new(30.0, 0.0), time_s: 3.0 },
            Anchor { agent: 2, position: Point2::new(10.0, 4.0), time_s: 1.5 },
        ],
        boundaries: vec![vec![Point2::new(-50.0, 1.0), Point2::new(50.0, 1.5), Point2::new(90.0, 3.0)]],
        conflict_windows: vec![ConflictWindow { agent_a: 0, agent_b: 2, from_s: 1.0, to_s: 2.0 }],
        boundary_sides: vec![vec![1], vec![], vec![-1]],
        previous_accel_mps2: vec![0.0, 0.5, -1.0],
    };
    let g = Guidance::new(config, context).unwrap();
    let mut ws = GuidanceWorkspace::new(&g);
    let x0s = vec![
        State { px: 0.0, py: 0.0, theta_rad: 0.0, speed_mps: 10.0 },
        State { px: 5.0, py: 0.5, theta_rad: 0.1, speed_mps: 8.0 },
        State { px: 0.0, py: 4.0, theta_rad: -0.1, speed_mps: 0.0 },
    ];
    let u = vec![Control { accel_mps2: 4.0, yaw_rate_radps: 0.3 }; 120];
    let mut grad = vec![Control::default(); 120];
    let z0 = vec![0.3; 240];
    let mut z1 = vec![0.0; 240];
    let norm = ControlNormalization::default();
    let step = GuidanceStep { scale: 0.01, max_step_norm: 1.0 };
    // Warm up once, then count.
    g.energy_and_grad(&mut ws, &x0s, &u, &mut grad).unwrap();
    let before = v2t_test_support::alloc::total();
    assert!(before > 0, "the counting allocator is in use");
    for _ in 0..10 {
        let e = g.energy_and_grad(&mut ws, &x0s, &u, &mut grad).unwrap();
        std::hint::black_box(e);
        let c = g.guide_clean_sample(&mut ws, &norm, &step, &x0s, &z0, &mut z1).unwrap();
        std::hint::black_box(c);
    }
    let after = v2t_test_support::alloc::total();
    assert_eq!(after - before, 0, "allocations in the hot path");
}
