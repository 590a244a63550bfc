//! The launcher: starts every configured node as its own process (`v2t-edge node <role>`),
//! restarts one that exits or dies, and shuts them all down cleanly on SIGINT/SIGTERM. A node that
//! exits with code 2 (a configuration that does not fit this machine, e.g. real-time scheduling it
//! may not use) is not restarted: the launcher stops the others and fails with code 2.

use std::path::Path;
use std::process::{Child, Command};
use std::time::{Duration, Instant};

use iceoryx2::service::Service;
use iceoryx2_bb_posix::process::{Process, ProcessId};
use iceoryx2_bb_posix::signal::Signal;

use crate::NodeRole;
use crate::config::{CanLink, Loaded};
use crate::error::EdgeError;
use crate::ports::{Bus, clean_dead_nodes};

/// How long a node gets to exit after SIGTERM before it is killed.
const STOP_GRACE: Duration = Duration::from_secs(2);

#[derive(Debug)]
struct Supervised {
    role: NodeRole,
    child: Option<Child>,
    restarts: u32,
    restart_at: Option<Instant>,
}

/// Starts `role` with the launcher's configuration, including what its command line overrode
/// (namespace, CAN interface).
fn spawn(exe: &Path, cfg: &Loaded, role: NodeRole) -> Result<Child, EdgeError> {
    let mut cmd = Command::new(exe);
    cmd.arg("node").arg(role.as_str()).arg("--config").arg(&cfg.path).arg("--namespace").arg(&cfg.edge.namespace);
    if let CanLink::Socketcan { interface } = &cfg.edge.can {
        cmd.arg("--can-iface").arg(interface);
    }
    cmd.env(crate::ports::PARENT_ENV, std::process::id().to_string()).spawn().map_err(|e| EdgeError::Config {
        path: cfg.path.clone(),
        message: format!("cannot start {}: {e}", role.as_str()),
    })
}

/// Sends `signal` to `child` (a child that is gone already needs none).
pub fn send_signal(child: &Child, signal: Signal) {
    signal_pid(child.id(), signal);
}

/// Sends `signal` to process `pid` (one that is gone already needs none).
pub fn signal_pid(pid: u32, signal: Signal) {
    let pid = ProcessId::new(i32::try_from(pid).unwrap_or(i32::MAX));
    if let Err(e) = Process::from_pid(pid).send_signal(signal) {
        eprintln!("launcher: cannot signal {pid:?}: {e:?}");
    }
}

/// Sends SIGTERM to `child` (iceoryx2 nodes leave their loop on it), waits up to the grace
/// period, then kills it.
fn stop(child: &mut Child) {
    send_signal(child, Signal::Terminate);
    let start = Instant::now();
    let deadline = start + STOP_GRACE;
    while Instant::now() < deadline {
        if matches!(child.try_wait(), Ok(Some(_))) {
            eprintln!("launcher: pid {} stopped after {:?}", child.id(), start.elapsed());
            return;
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    let _ = child.kill();
    let _ = child.wait();
}

/// Exit code of a node whose configuration does not fit (restarting it cannot help).
const BAD_CONFIGURATION: i32 = 2;

/// Supervises the nodes of `cfg` until SIGINT/SIGTERM, or until a node used up its restarts or
/// exited for a bad configuration. The launcher takes its own `[launch.realtime]` entry first.
pub fn run<S: Service>(cfg: &Loaded, exe: &Path) -> Result<(), EdgeError> {
    crate::realtime::apply_configured(cfg, crate::realtime::Process::Launcher)?;
    let bus = Bus::<S>::new("launcher", &cfg.edge.namespace)?;
    let cleaned = clean_dead_nodes::<S>();
    if cleaned > 0 {
        eprintln!("launcher: removed what {cleaned} dead node(s) left behind");
    }
    let mut nodes = Vec::with_capacity(cfg.edge.launch.nodes.len());
    for role in &cfg.edge.launch.nodes {
        let child = spawn(exe, cfg, *role)?;
        eprintln!("launcher: started {} (pid {})", role.as_str(), child.id());
        nodes.push(Supervised { role: *role, child: Some(child), restarts: 0, restart_at: None });
    }
    let delay = Duration::from_secs_f64(cfg.edge.launch.restart_delay_s);
    let mut failure = None;
    while bus.wait(Duration::from_millis(20)) {
        for n in &mut nodes {
            if let Some(child) = n.child.as_mut()
                && let Ok(Some(status)) = child.try_wait()
            {
                eprintln!("launcher: {} exited ({status})", n.role.as_str());
                n.child = None;
                if status.code() == Some(BAD_CONFIGURATION) {
                    failure = Some(format!(
                        "{} exited with code 2: its configuration does not fit this machine (its message is above); not restarted",
                        n.role.as_str()
                    ));
                } else if n.restarts >= cfg.edge.launch.max_restarts {
                    failure = Some(format!("{} exited {} times", n.role.as_str(), n.restarts + 1));
                } else {
                    n.restart_at = Some(Instant::now() + delay);
                }
            }
            if n.child.is_none() && n.restart_at.is_some_and(|t| Instant::now() >= t) {
                clean_dead_nodes::<S>();
                n.restarts += 1;
                n.restart_at = None;
                let child = spawn(exe, cfg, n.role)?;
                eprintln!("launcher: restarted {} (pid {}, restart {})", n.role.as_str(), child.id(), n.restarts);
                n.child = Some(child);
            }
        }
        if failure.is_some() {
            break;
        }
    }
    eprintln!("launcher: stopping");
    // The gateway last: it keeps commanding the stop profile while the others go.
    nodes.sort_by_key(|n| n.role == NodeRole::Gateway);
    for n in &mut nodes {
        if let Some(child) = n.child.as_mut() {
            stop(child);
        }
    }
    match failure {
        Some(f) => Err(EdgeError::Config { path: cfg.path.clone(), message: f }),
        None => Ok(()),
    }
}
