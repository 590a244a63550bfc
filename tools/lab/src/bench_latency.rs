//! `v2t-bench latency`: state-in → CAN-frame-out latency through the real processes.
//!
//! It starts the onboard runtime's launcher (`v2t-edge launch`, every node as its own process) and
//! the simulated ECU (`v2t-sim-ecu`) in a fresh namespace, runs the scenario, and reads every gateway report that carried a new tracker
//! command: latency = when the gateway finished writing the frames − when the state node received
//! the GNSS/INS fix the command was computed from. The regulator is not on that path (the tracker
//! follows its newest plan); its decision times are reported separately from the plans.
//!
//! The scenario is run again (a fresh launcher and ECU in a fresh namespace each time) until the
//! path has `min_samples` samples. `load` busy processes ([`Load`], pinned nowhere) spin beside the
//! runtime for the whole measurement; they are killed when the bench ends, on every path. With a
//! configuration that has `[launch.realtime]` the runtime's processes take their real-time
//! scheduling; the simulated ECU and the bench do not (neither is on the measured path).

use std::path::Path;
use std::process::{Child, Command, ExitStatus};
use std::time::{Duration, Instant};

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
    /// A run gave no sample: the runtime never commanded.
    #[error("run {run} gave no sample of the path (the ECU said: {ecu})")]
    NoSamples {
        /// Which run (from 1).
        run: usize,
        /// What the ECU printed.
        ecu: String,
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
    /// Busy processes that ran beside the runtime.
    pub load: usize,
    /// Whether the runtime ran with `[launch.realtime]`.
    pub realtime: bool,
    /// Scenario runs it took.
    pub runs: usize,
    /// State-in (fix received by the state node) → command frames written by the gateway.
    pub state_to_can: Percentiles,
    /// Regulator decision time (not on the path above).
    pub regulator_solve: Percentiles,
    /// The ECU's summary line of each run, one a line.
    pub ecu: String,
}

impl LatencyReport {
    /// A markdown table.
    pub fn table(&self) -> String {
        let row = |name: &str, p: &Percentiles| {
            format!("| {name} | {} | {:.0} µs | {:.0} µs | {:.0} µs |", p.n, p.p50_us, p.p99_us, p.max_us)
        };
        let rt = if self.realtime { "on ([launch.realtime])" } else { "off" };
        format!(
            "load: {} busy process(es), realtime: {rt}, {} run(s)\n\n| path | samples | p50 | p99 | max |\n|---|---|---|---|---|\n{}\n{}\n\n{}",
            self.load,
            self.runs,
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

/// A process of the bench, ended when dropped: the launcher with SIGTERM (its nodes stop with
/// it), anything else killed.
#[derive(Debug)]
struct Running {
    child: Child,
    terminate: bool,
}

impl Drop for Running {
    fn drop(&mut self) {
        if self.terminate && matches!(self.child.try_wait(), Ok(None)) {
            send_signal(&self.child, iceoryx2_bb_posix::signal::Signal::Terminate);
            let deadline = Instant::now() + Duration::from_secs(15);
            while Instant::now() < deadline && matches!(self.child.try_wait(), Ok(None)) {
                std::thread::sleep(Duration::from_millis(10));
            }
        }
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// `n` busy processes (`program args…`, each spinning on one CPU, pinned nowhere), killed when
/// dropped.
#[derive(Debug)]
pub struct Load {
    children: Vec<Child>,
}

impl Load {
    /// Starts `n` copies of `program args…`.
    pub fn start(n: usize, program: &Path, args: &[&str]) -> Result<Self, BenchError> {
        let mut load = Self { children: Vec::with_capacity(n) };
        for _ in 0..n {
            // A failed start drops `load`: the ones already started are killed.
            let child = Command::new(program)
                .args(args)
                .spawn()
                .map_err(|source| BenchError::Spawn { exe: program.display().to_string(), source })?;
            load.children.push(child);
        }
        Ok(load)
    }

    /// How many processes it runs.
    pub fn len(&self) -> usize {
        self.children.len()
    }

    /// Whether it runs none.
    pub fn is_empty(&self) -> bool {
        self.children.is_empty()
    }
}

impl Drop for Load {
    fn drop(&mut self) {
        for c in &mut self.children {
            let _ = c.kill();
        }
        for c in &mut self.children {
            let _ = c.wait();
        }
    }
}

/// Spins on one CPU until the process `parent` is gone (the body of a [`Load`] process started by
/// the bench itself): it cannot outlive a bench that was killed before it could kill it.
pub fn spin(parent: u32) {
    let mut x = 0_u64;
    loop {
        for _ in 0..1_000_000 {
            x = std::hint::black_box(x.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1));
        }
        if std::os::unix::process::parent_id() != parent {
            return;
        }
    }
}

/// The two programs the bench starts.
#[derive(Debug, Clone, Copy)]
pub struct Programs<'a> {
    /// `v2t-edge`, the onboard runtime.
    pub edge: &'a Path,
    /// `v2t-sim-ecu`, the simulated drive-by-wire ECU.
    pub ecu: &'a Path,
}

/// How the bench runs.
#[derive(Debug, Clone, Copy)]
pub struct LatencyOptions<'a> {
    /// The scenario to drive.
    pub scenario: &'a Path,
    /// Run the scenario again until the path has this many samples.
    pub min_samples: usize,
    /// The busy processes beside the runtime (their count goes into the report).
    pub load: &'a Load,
}

/// At most this many runs, whatever `min_samples` asks.
const MAX_RUNS: usize = 100;

/// Samples of one run.
struct Run {
    path_ns: Vec<u64>,
    solve_ns: Vec<u64>,
    ecu: String,
}

/// Runs the bench with `cfg` (its namespace gets a unique suffix per run).
pub fn latency(cfg: &Loaded, programs: Programs<'_>, opts: &LatencyOptions<'_>) -> Result<LatencyReport, BenchError> {
    let (mut path_ns, mut solve_ns, mut ecu) = (Vec::new(), Vec::new(), String::new());
    let mut runs = 0;
    while runs == 0 || (path_ns.len() < opts.min_samples && runs < MAX_RUNS) {
        runs += 1;
        let run = run_once(cfg, programs, opts.scenario, runs)?;
        if run.path_ns.is_empty() {
            return Err(BenchError::NoSamples { run: runs, ecu: run.ecu });
        }
        eprintln!("run {runs}: {} samples", run.path_ns.len());
        path_ns.extend(run.path_ns);
        solve_ns.extend(run.solve_ns);
        // The summary line of each run (the realism report after it is the same every run).
        ecu.push_str(run.ecu.lines().next().unwrap_or_default());
        ecu.push('\n');
        if v2t_edge::ports::terminating() {
            break;
        }
    }
    Ok(LatencyReport {
        load: opts.load.len(),
        realtime: cfg.edge.launch.realtime.is_some(),
        runs,
        state_to_can: Percentiles::of(&mut path_ns),
        regulator_solve: Percentiles::of(&mut solve_ns),
        ecu,
    })
}

/// One run of `scenario`: a launcher and an ECU in namespace `…/bench<pid>_<run>`.
fn run_once(cfg: &Loaded, programs: Programs<'_>, scenario: &Path, run: usize) -> Result<Run, BenchError> {
    let ns = format!("{}/bench{}_{run}", cfg.edge.namespace, std::process::id());
    let config = cfg.path.display().to_string();
    let bus = Bus::<ipc::Service>::new("bench", &ns)?;
    let reports = bus.subscriber::<GateReport>(services::GATE)?;
    let plans = bus.subscriber::<RegulatedPlan>(services::PLAN)?;
    let launcher =
        Running { child: spawn(programs.edge, &["launch", "--config", &config, "--namespace", &ns])?, terminate: true };
    let scenario = scenario.display().to_string();
    let args = ["--config", config.as_str(), "--namespace", &ns, "--scenario", &scenario];
    let mut ecu = Running { child: spawn(programs.ecu, &args)?, terminate: false };
    let (mut path_ns, mut solve_ns) = (Vec::new(), Vec::new());
    let wait_ecu = |c: &mut Child| {
        c.wait().map_err(|source| BenchError::Spawn { exe: programs.ecu.display().to_string(), source })
    };
    let status: ExitStatus = loop {
        while let Ok(Some(r)) = reports.receive() {
            if r.fresh_command == 1 && r.state_received_ns > 0 {
                path_ns.push(r.header.stamp_ns.saturating_sub(r.state_received_ns));
            }
        }
        while let Ok(Some(p)) = plans.receive() {
            solve_ns.push(p.solve_ns);
        }
        if let Ok(Some(status)) = ecu.child.try_wait() {
            break status;
        }
        if !bus.wait(Duration::from_millis(5)) {
            let _ = ecu.child.kill();
            break wait_ecu(&mut ecu.child)?;
        }
    };
    drop(launcher);
    let mut ecu_line = String::new();
    if let Some(mut out) = ecu.child.stdout.take() {
        use std::io::Read;
        let _ = out.read_to_string(&mut ecu_line);
    }
    if !status.success() {
        return Err(BenchError::Ecu { status: status.to_string(), output: ecu_line });
    }
    Ok(Run { path_ns, solve_ns, ecu: ecu_line })
}
