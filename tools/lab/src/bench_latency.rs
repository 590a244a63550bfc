//! `v2t-bench latency`: state-in → CAN-frame-out latency through the real processes.
//!
//! It starts the onboard runtime's launcher (`v2t-edge launch`, every node as its own process) and
//! the simulated ECU (`v2t-sim-ecu`) in a fresh namespace, runs the scenario, and reads every gateway report that carried a new tracker
//! command: latency = when the gateway finished writing the frames − when the state node received
//! the GNSS/INS fix the command was computed from. The regulator is not on that path (the tracker
//! follows its newest plan); its decision times are reported separately from the plans.

use std::path::Path;
use std::process::{Child, Command};
use std::time::Duration;

use iceoryx2::prelude::ipc;
use v2t_wire::{GateReport, RegulatedPlan, services};

use v2t_edge::config::Loaded;
use v2t_edge::error::EdgeError;
use v2t_edge::launch::send_signal;
use v2t_edge::ports::Bus;

/// Why the bench could not run.
#[derive(Debug, thiserror::Error)]
pub enum BenchError {
    /// iceoryx2 or the configuration failed.
    #[error(transparent)]
    Edge(#[from] EdgeError),
    /// A process could not be started or waited for.
    #[error("{exe}: {source}")]
    Spawn {
        /// The program.
        exe: String,
        /// Why.
        source: std::io::Error,
    },
    /// The simulated ECU failed.
    #[error("the simulated ECU failed ({status}): {output}")]
    Ecu {
        /// Its exit status.
        status: String,
        /// What it printed.
        output: String,
    },
}

/// Percentiles of a set of durations, µs.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize)]
pub struct Percentiles {
    /// Samples.
    pub n: usize,
    /// Median, µs.
    pub p50_us: f64,
    /// 99th percentile, µs.
    pub p99_us: f64,
    /// Largest, µs.
    pub max_us: f64,
}

impl Percentiles {
    /// Of `ns` (sorted in place).
    pub fn of(ns: &mut [u64]) -> Self {
        ns.sort_unstable();
        let at = |q: f64| {
            let i = ((ns.len() as f64 - 1.0) * q).round() as usize;
            ns.get(i).map_or(0.0, |v| *v as f64 / 1e3)
        };
        Self { n: ns.len(), p50_us: at(0.5), p99_us: at(0.99), max_us: at(1.0) }
    }
}

/// What the bench measured.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct LatencyReport {
    /// State-in (fix received by the state node) → command frames written by the gateway.
    pub state_to_can: Percentiles,
    /// Regulator decision time (not on the path above).
    pub regulator_solve: Percentiles,
    /// The ECU's summary line.
    pub ecu: String,
}

impl LatencyReport {
    /// A markdown table.
    pub fn table(&self) -> String {
        let row = |name: &str, p: &Percentiles| {
            format!("| {name} | {} | {:.0} µs | {:.0} µs | {:.0} µs |", p.n, p.p50_us, p.p99_us, p.max_us)
        };
        format!(
            "| path | samples | p50 | p99 | max |\n|---|---|---|---|---|\n{}\n{}\n\n{}",
            row("state in → CAN frames out", &self.state_to_can),
            row("regulator decision (separate)", &self.regulator_solve),
            self.ecu.trim()
        )
    }
}

fn spawn(exe: &Path, args: &[&str]) -> Result<Child, BenchError> {
    Command::new(exe)
        .args(args)
        .stdout(std::process::Stdio::piped())
        .spawn()
        .map_err(|source| BenchError::Spawn { exe: exe.display().to_string(), source })
}

/// The two programs the bench starts.
#[derive(Debug, Clone, Copy)]
pub struct Programs<'a> {
    /// `v2t-edge`, the onboard runtime.
    pub edge: &'a Path,
    /// `v2t-sim-ecu`, the simulated drive-by-wire ECU.
    pub ecu: &'a Path,
}

/// Runs the bench with `cfg` (its namespace gets a unique suffix) on `scenario`.
pub fn latency(cfg: &Loaded, programs: Programs<'_>, scenario: &Path) -> Result<LatencyReport, BenchError> {
    let ns = format!("{}/bench{}", cfg.edge.namespace, std::process::id());
    let config = cfg.path.display().to_string();
    let bus = Bus::<ipc::Service>::new("bench", &ns)?;
    let reports = bus.subscriber::<GateReport>(services::GATE)?;
    let plans = bus.subscriber::<RegulatedPlan>(services::PLAN)?;
    let mut launcher = spawn(programs.edge, &["launch", "--config", &config, "--namespace", &ns])?;
    let scenario = scenario.display().to_string();
    let mut ecu = spawn(programs.ecu, &["--config", &config, "--namespace", &ns, "--scenario", &scenario])?;
    let (mut path_ns, mut solve_ns) = (Vec::new(), Vec::new());
    let status = loop {
        while let Ok(Some(r)) = reports.receive() {
            if r.fresh_command == 1 && r.state_received_ns > 0 {
                path_ns.push(r.header.stamp_ns.saturating_sub(r.state_received_ns));
            }
        }
        while let Ok(Some(p)) = plans.receive() {
            solve_ns.push(p.solve_ns);
        }
        if let Ok(Some(status)) = ecu.try_wait() {
            break status;
        }
        if !bus.wait(Duration::from_millis(5)) {
            let _ = ecu.kill();
            break ecu
                .wait()
                .map_err(|source| BenchError::Spawn { exe: programs.ecu.display().to_string(), source })?;
        }
    };
    send_signal(&launcher, iceoryx2_bb_posix::signal::Signal::Terminate);
    let _ = launcher.wait();
    let mut ecu_line = String::new();
    if let Some(mut out) = ecu.stdout.take() {
        use std::io::Read;
        let _ = out.read_to_string(&mut ecu_line);
    }
    if !status.success() {
        return Err(BenchError::Ecu { status: status.to_string(), output: ecu_line });
    }
    Ok(LatencyReport {
        state_to_can: Percentiles::of(&mut path_ns),
        regulator_solve: Percentiles::of(&mut solve_ns),
        ecu: ecu_line,
    })
}
