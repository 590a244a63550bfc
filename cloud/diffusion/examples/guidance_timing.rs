//! Wall time of one guidance evaluation (energy and gradient) and of one guided correction, for a
//! three-agent, 8 s problem at 10 Hz with every term active. Prints figures; asserts nothing.
//!
//! ```text
//! nice -n 10 cargo run --release -p v2t-diffusion --example guidance_timing
//! ```

use std::time::Instant;

use v2t_diffusion::guidance::normalized::{ControlNormalization, GuidanceStep};
use v2t_diffusion::guidance::{Anchor, ConflictWindow, Guidance, GuidanceConfig, GuidanceContext, GuidanceWorkspace};
use v2t_model::geometry::Point2;
use v2t_model::kinematics::{Control, State};

fn main() -> anyhow::Result<()> {
    let (n, t) = (3usize, 80usize);
    let config = GuidanceConfig { agents: n, steps: t, clearance_radius_m: 8.0, ..GuidanceConfig::default() };
    // Two solid boundaries of 40 segments each, anchors at start, conflict and goal.
    let boundary =
        |y: f64| (0..=40).map(|k| Point2::new(-20.0 + 4.0 * k as f64, y + 0.2 * (k as f64 * 0.3).sin())).collect();
    let mut anchors = Vec::new();
    for i in 0..n {
        for (x, time_s) in [(40.0, 4.0), (75.0, 8.0)] {
            anchors.push(Anchor { agent: i, position: Point2::new(x, 3.5 * i as f64 - 3.5), time_s });
        }
    }
    let context = GuidanceContext {
        anchors,
        boundaries: vec![boundary(-5.5), boundary(5.5)],
        conflict_windows: vec![ConflictWindow { agent_a: 0, agent_b: 1, from_s: 3.0, to_s: 5.0 }],
        boundary_sides: Vec::new(),
        previous_accel_mps2: Vec::new(),
    };
    let g = Guidance::new(config, context)?;
    let mut ws = GuidanceWorkspace::new(&g);
    let x0s: Vec<State> =
        (0..n).map(|i| State { px: 0.0, py: 3.5 * i as f64 - 3.5, theta_rad: 0.0, speed_mps: 9.0 }).collect();
    let u: Vec<Control> = (0..n * t)
        .map(|k| Control {
            accel_mps2: 0.5 * ((k as f64) * 0.1).sin(),
            yaw_rate_radps: 0.05 * ((k as f64) * 0.07).cos(),
        })
        .collect();
    let mut grad = vec![Control::default(); n * t];
    let norm = ControlNormalization::default();
    let z0: Vec<f64> = u.iter().flat_map(|c| norm.normalize(*c)).collect();
    let mut z1 = vec![0.0; z0.len()];
    let step = GuidanceStep { scale: 0.01, max_step_norm: 1.0 };
    let reps = 20_000;
    for (name, run) in [("energy_and_grad", 0), ("guide_clean_sample", 1)] {
        let start = Instant::now();
        let mut total = 0.0;
        for _ in 0..reps {
            total += if run == 0 {
                g.energy_and_grad(&mut ws, &x0s, &u, &mut grad)?.total
            } else {
                g.guide_clean_sample(&mut ws, &norm, &step, &x0s, &z0, &mut z1)?.energy.total
            };
        }
        let us = start.elapsed().as_secs_f64() * 1e6 / reps as f64;
        println!("{name}: {us:.2} µs per call ({n} agents × {t} steps, E = {:.3})", total / reps as f64);
    }
    Ok(())
}
