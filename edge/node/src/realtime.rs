//! Opt-in real-time scheduling of the runtime's processes, `[launch.realtime]`: a `SCHED_FIFO`
//! priority and a CPU set for each node and for the launcher, and every page of each process
//! locked in memory (`mlockall`, current and future). Without the section nothing changes.
//!
//! Each process applies its own entry at start (the launcher before it starts the nodes, each node
//! before it opens its ports). A process that may not do what the section asks (no `rtprio` or
//! `memlock` allowance, no `CAP_SYS_NICE`/`CAP_IPC_LOCK`), or a CPU this machine does not have,
//! is a configuration that does not fit this machine: the process stops with
//! [`EdgeError::Config`] (exit code 2) and a message that says what failed and how to grant it,
//! and the launcher does not restart a node that exits so.
//!
//! ```toml
//! [launch.realtime]
//! lock_memory = true                   # mlockall(MCL_CURRENT | MCL_FUTURE) in every process
//! launcher = { priority = 10 }
//! gateway = { priority = 80, cpus = [1] }
//! ```
//!
//! The priority is set with `SCHED_RESET_ON_FORK`: what a process starts (the launcher's nodes,
//! a node's helper threads) begins under the normal scheduler and takes its own entry. A CPU set
//! is inherited like `taskset`'s: a node without `cpus` runs where the launcher may run.

use std::path::Path;

use serde::{Deserialize, Serialize};
use v2t_model::validate::{Validate, ValidationError};

use crate::NodeRole;
use crate::config::Loaded;
use crate::error::EdgeError;

/// CPU indices go up to this (exclusive): the size of the kernel interface's CPU set.
pub const MAX_CPUS: usize = 1024;

/// `[launch.realtime]`: real-time scheduling of the runtime's processes.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Realtime {
    /// Lock every page of each process in memory, current and future (`mlockall`): no page
    /// fault on the control path after start.
    pub lock_memory: bool,
    /// The launcher (supervision and restarts).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub launcher: Option<Scheduling>,
    /// The state node.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub state: Option<Scheduling>,
    /// The regulator.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub regulator: Option<Scheduling>,
    /// The tracker.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tracker: Option<Scheduling>,
    /// The CAN gateway.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gateway: Option<Scheduling>,
    /// The monitor.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub monitor: Option<Scheduling>,
    /// The uplink.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub uplink: Option<Scheduling>,
}

/// How one process is scheduled. A process without an entry, or an entry without `priority`,
/// stays under the normal scheduler.
#[derive(Debug, Clone, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scheduling {
    /// `SCHED_FIFO` priority, 1 (lowest) to 99.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub priority: Option<u32>,
    /// The CPUs the process may run on (indices from 0).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cpus: Option<Vec<usize>>,
}

/// A process of the runtime.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Process {
    /// `v2t-edge launch`.
    Launcher,
    /// `v2t-edge node <role>`.
    Node(NodeRole),
}

impl Process {
    /// Every process of the runtime.
    pub const ALL: [Self; 7] = [
        Self::Launcher,
        Self::Node(NodeRole::State),
        Self::Node(NodeRole::Regulator),
        Self::Node(NodeRole::Tracker),
        Self::Node(NodeRole::Gateway),
        Self::Node(NodeRole::Monitor),
        Self::Node(NodeRole::Uplink),
    ];

    /// Its name in `[launch.realtime]`.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Launcher => "launcher",
            Self::Node(role) => role.as_str(),
        }
    }
}

impl Realtime {
    /// The entry of `process`.
    pub fn scheduling(&self, process: Process) -> Option<&Scheduling> {
        match process {
            Process::Launcher => self.launcher.as_ref(),
            Process::Node(NodeRole::State) => self.state.as_ref(),
            Process::Node(NodeRole::Regulator) => self.regulator.as_ref(),
            Process::Node(NodeRole::Tracker) => self.tracker.as_ref(),
            Process::Node(NodeRole::Gateway) => self.gateway.as_ref(),
            Process::Node(NodeRole::Monitor) => self.monitor.as_ref(),
            Process::Node(NodeRole::Uplink) => self.uplink.as_ref(),
        }
    }
}

impl Validate for Scheduling {
    fn validate(&self) -> Result<(), ValidationError> {
        if let Some(p) = self.priority
            && !(1..=99).contains(&p)
        {
            return Err(ValidationError::new("priority", format!("must be 1 to 99 (SCHED_FIFO), got {p}")));
        }
        if let Some(cpus) = &self.cpus {
            if cpus.is_empty() {
                return Err(ValidationError::new("cpus", "must name at least one CPU (leave it out to run anywhere)"));
            }
            for (i, c) in cpus.iter().enumerate() {
                if *c >= MAX_CPUS {
                    return Err(ValidationError::new(
                        format!("cpus[{i}]"),
                        format!("must be below {MAX_CPUS}, got {c}"),
                    ));
                }
                if cpus.iter().take(i).any(|d| d == c) {
                    return Err(ValidationError::new(format!("cpus[{i}]"), format!("CPU {c} is named twice")));
                }
            }
        }
        Ok(())
    }
}

impl Validate for Realtime {
    fn validate(&self) -> Result<(), ValidationError> {
        for p in Process::ALL {
            if let Some(s) = self.scheduling(p) {
                s.validate().map_err(|e| e.within(p.as_str()))?;
            }
        }
        Ok(())
    }
}

/// One step of putting a process under real-time scheduling.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Step<'a> {
    /// `sched_setaffinity` to these CPUs.
    Affinity(&'a [usize]),
    /// `mlockall(MCL_CURRENT | MCL_FUTURE)`.
    LockMemory,
    /// `sched_setscheduler(SCHED_FIFO)` at this priority.
    Priority(u32),
}

/// What to tell the operator when `step` failed with `errno`: what failed, and how to grant it.
pub fn failure_message(step: Step<'_>, errno: i32) -> String {
    let why = std::io::Error::from_raw_os_error(errno);
    let denied = errno == libc::EPERM;
    match step {
        Step::Priority(p) if denied => format!(
            "cannot run under SCHED_FIFO priority {p}: {why}. Allow it for the user that runs v2t-edge: \
             `<user> - rtprio 99` in /etc/security/limits.conf (check with `ulimit -r`), or the capability \
             CAP_SYS_NICE (`setcap cap_sys_nice,cap_ipc_lock=ep v2t-edge`), or in its systemd unit \
             `LimitRTPRIO=99` or `AmbientCapabilities=CAP_SYS_NICE CAP_IPC_LOCK` (in a container or a cgroup \
             without real-time runtime, root is refused too); or remove [launch.realtime]"
        ),
        Step::LockMemory if denied || errno == libc::ENOMEM || errno == libc::EAGAIN => format!(
            "cannot lock the process's memory (mlockall, current and future): {why}. Allow it for the user \
             that runs v2t-edge: `<user> - memlock unlimited` in /etc/security/limits.conf (check with \
             `ulimit -l`), or the capability CAP_IPC_LOCK, or in its systemd unit `LimitMEMLOCK=infinity` or \
             `AmbientCapabilities=CAP_IPC_LOCK`; or set lock_memory = false"
        ),
        Step::Affinity(cpus) if errno == libc::EINVAL => {
            format!("cannot run on CPUs {cpus:?}: {why}: none of them is allowed to this process (a cpuset or taskset)")
        }
        Step::Priority(p) => format!("cannot run under SCHED_FIFO priority {p}: {why}"),
        Step::LockMemory => format!("cannot lock the process's memory (mlockall): {why}"),
        Step::Affinity(cpus) => format!("cannot run on CPUs {cpus:?}: {why}"),
    }
}

/// Checks `cpus` against the `online` CPUs of this machine.
pub fn check_cpus(cpus: &[usize], online: usize) -> Result<(), String> {
    match cpus.iter().find(|c| **c >= online) {
        Some(c) => Err(format!(
            "CPU {c} does not exist on this machine: it has {online} CPU(s) online (0 to {})",
            online.saturating_sub(1)
        )),
        None => Ok(()),
    }
}

/// Applies the entry of `process` in `rt` to the calling process: CPU set, then memory lock,
/// then priority. Returns what it did, for the log.
pub fn apply(rt: &Realtime, process: Process, path: &Path) -> Result<String, EdgeError> {
    let fail = |what: &str, message: String| EdgeError::Config {
        path: path.to_owned(),
        message: format!("launch.realtime.{what}: {message}"),
    };
    let entry = rt.scheduling(process).cloned().unwrap_or_default();
    let name = process.as_str();
    let mut done = Vec::new();
    if let Some(cpus) = &entry.cpus {
        let field = format!("{name}.cpus");
        let online = sys::online_cpus().map_err(|e| fail(&field, failure_message(Step::Affinity(cpus), e)))?;
        check_cpus(cpus, online).map_err(|m| fail(&field, m))?;
        sys::set_affinity(cpus).map_err(|e| fail(&field, failure_message(Step::Affinity(cpus), e)))?;
        done.push(format!("CPUs {cpus:?}"));
    }
    if rt.lock_memory {
        sys::lock_memory().map_err(|e| fail("lock_memory", failure_message(Step::LockMemory, e)))?;
        done.push("memory locked".to_owned());
    }
    if let Some(p) = entry.priority {
        let field = format!("{name}.priority");
        sys::set_fifo(p).map_err(|e| fail(&field, failure_message(Step::Priority(p), e)))?;
        done.push(format!("SCHED_FIFO {p}"));
    }
    if done.is_empty() {
        done.push("normal scheduling".to_owned());
    }
    Ok(done.join(", "))
}

/// Applies `cfg`'s `[launch.realtime]` for `process`, if the section is there, and says so on
/// stderr. Without the section it does nothing.
pub fn apply_configured(cfg: &Loaded, process: Process) -> Result<(), EdgeError> {
    if let Some(rt) = &cfg.edge.launch.realtime {
        let done = apply(rt, process, &cfg.path)?;
        eprintln!("{}: real-time: {done}", process.as_str());
    }
    Ok(())
}

/// A soft resource limit of this process.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Rlimit {
    /// `RLIM_INFINITY`.
    Unlimited,
    /// This much (a priority, or bytes).
    Of(u64),
}

/// The system calls, each returning the errno on failure (also what `v2t-edge check` reads).
#[allow(unsafe_code)]
pub(crate) mod sys {
    use super::Rlimit;

    fn errno() -> i32 {
        std::io::Error::last_os_error().raw_os_error().unwrap_or(libc::EINVAL)
    }

    /// How many CPUs are online.
    pub fn online_cpus() -> Result<usize, i32> {
        // SAFETY: sysconf takes a constant and touches no memory of ours.
        let n = unsafe { libc::sysconf(libc::_SC_NPROCESSORS_ONLN) };
        if n < 1 { Err(errno()) } else { usize::try_from(n).map_err(|_| libc::EINVAL) }
    }

    /// Restricts the calling process to `cpus` (each below the CPU set's size).
    pub fn set_affinity(cpus: &[usize]) -> Result<(), i32> {
        // SAFETY: cpu_set_t is a plain bit array: all zeroes is the empty set.
        let mut set: libc::cpu_set_t = unsafe { std::mem::zeroed() };
        let capacity = 8 * std::mem::size_of::<libc::cpu_set_t>();
        for &c in cpus {
            if c >= capacity {
                return Err(libc::EINVAL);
            }
            // SAFETY: `c` is below the set's size (checked above), so the bit lies inside `set`.
            unsafe { libc::CPU_SET(c, &mut set) };
        }
        // SAFETY: `set` is a valid cpu_set_t of the size passed; pid 0 is the calling thread, the
        // process's only one at this point (nodes and the launcher apply this first).
        let rc = unsafe { libc::sched_setaffinity(0, std::mem::size_of::<libc::cpu_set_t>(), &set) };
        if rc == 0 { Ok(()) } else { Err(errno()) }
    }

    /// Locks every current and future page of the process in memory.
    pub fn lock_memory() -> Result<(), i32> {
        // SAFETY: mlockall takes flags only and touches no memory of ours.
        let rc = unsafe { libc::mlockall(libc::MCL_CURRENT | libc::MCL_FUTURE) };
        if rc == 0 { Ok(()) } else { Err(errno()) }
    }

    /// The soft `RLIMIT_RTPRIO` and `RLIMIT_MEMLOCK` of this process (`None`: unreadable).
    pub fn limits() -> (Option<Rlimit>, Option<Rlimit>) {
        let soft = |rc: i32, l: libc::rlimit| {
            (rc == 0).then_some(if l.rlim_cur == libc::RLIM_INFINITY {
                Rlimit::Unlimited
            } else {
                Rlimit::Of(l.rlim_cur)
            })
        };
        let mut rtprio = libc::rlimit { rlim_cur: 0, rlim_max: 0 };
        let mut memlock = libc::rlimit { rlim_cur: 0, rlim_max: 0 };
        // SAFETY: each `rlimit` is valid and outlives its call, which only writes into it.
        let rc_rtprio = unsafe { libc::getrlimit(libc::RLIMIT_RTPRIO, &mut rtprio) };
        // SAFETY: as above.
        let rc_memlock = unsafe { libc::getrlimit(libc::RLIMIT_MEMLOCK, &mut memlock) };
        (soft(rc_rtprio, rtprio), soft(rc_memlock, memlock))
    }

    /// Puts the calling thread under SCHED_FIFO at `priority`; what it starts later begins under
    /// the normal scheduler (SCHED_RESET_ON_FORK).
    pub fn set_fifo(priority: u32) -> Result<(), i32> {
        let param = libc::sched_param { sched_priority: i32::try_from(priority).map_err(|_| libc::EINVAL)? };
        // SAFETY: `param` is a valid sched_param that outlives the call; pid 0 is the calling thread.
        let rc = unsafe { libc::sched_setscheduler(0, libc::SCHED_FIFO | libc::SCHED_RESET_ON_FORK, &param) };
        if rc == 0 { Ok(()) } else { Err(errno()) }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<Realtime, String> {
        let rt: Realtime = toml::from_str(text).map_err(|e| e.to_string())?;
        rt.validate().map_err(|e| e.within("launch.realtime").to_string())?;
        Ok(rt)
    }

    #[test]
    fn an_entry_per_process_with_priorities_and_cpus() {
        let rt = parse("lock_memory = true\nlauncher = { priority = 10 }\ngateway = { priority = 80, cpus = [1, 0] }")
            .unwrap();
        assert_eq!(rt.scheduling(Process::Launcher).and_then(|s| s.priority), Some(10));
        let gw = rt.scheduling(Process::Node(NodeRole::Gateway)).unwrap();
        assert_eq!((gw.priority, gw.cpus.as_deref()), (Some(80), Some(&[1, 0][..])));
        assert_eq!(rt.scheduling(Process::Node(NodeRole::Regulator)), None);
    }

    #[test]
    fn priorities_outside_1_to_99_and_bad_cpu_lists_are_refused_by_name() {
        for (text, field, bound) in [
            ("gateway = { priority = 0 }", "launch.realtime.gateway.priority", "1 to 99"),
            ("state = { priority = 100 }", "launch.realtime.state.priority", "got 100"),
            ("launcher = { priority = 99, cpus = [] }", "launch.realtime.launcher.cpus", "at least one"),
            ("tracker = { cpus = [0, 1024] }", "launch.realtime.tracker.cpus[1]", "below 1024"),
            ("monitor = { cpus = [1, 1] }", "launch.realtime.monitor.cpus[1]", "twice"),
        ] {
            let e = parse(&format!("lock_memory = false\n{text}")).unwrap_err();
            assert!(e.contains(field) && e.contains(bound), "{text}: {e}");
        }
        assert!(parse("lock_memory = false\ngateway = { prio = 1 }").unwrap_err().contains("prio"));
        assert!(parse("lock_memory = false\nplanner = { priority = 1 }").is_err(), "unknown process");
        assert!(parse("gateway = { priority = 1 }").is_err(), "lock_memory is written out");
        assert!(parse("lock_memory = true\nuplink = { priority = 1, cpus = [1023] }").is_ok());
    }

    #[test]
    fn a_cpu_beyond_the_machine_is_named_with_the_machine_s_count() {
        assert_eq!(check_cpus(&[0, 1], 2), Ok(()));
        let e = check_cpus(&[0, 3], 2).unwrap_err();
        assert!(e.contains("CPU 3") && e.contains("2 CPU(s) online (0 to 1)"), "{e}");
    }

    #[test]
    fn a_refusal_says_what_failed_and_how_to_grant_it() {
        let e = failure_message(Step::Priority(80), libc::EPERM);
        for hint in ["SCHED_FIFO priority 80", "rtprio", "ulimit -r", "limits.conf", "CAP_SYS_NICE", "LimitRTPRIO="] {
            assert!(e.contains(hint), "{hint}: {e}");
        }
        for errno in [libc::EPERM, libc::ENOMEM] {
            let e = failure_message(Step::LockMemory, errno);
            for hint in ["mlockall", "memlock", "ulimit -l", "CAP_IPC_LOCK", "LimitMEMLOCK=", "lock_memory = false"] {
                assert!(e.contains(hint), "{hint}: {e}");
            }
        }
        let e = failure_message(Step::Affinity(&[3]), libc::EINVAL);
        assert!(e.contains("[3]") && e.contains("allowed to this process"), "{e}");
        assert!(!failure_message(Step::Priority(5), libc::EINVAL).contains("rtprio"), "only a refusal gets the hint");
    }

    #[test]
    fn without_an_entry_the_process_keeps_normal_scheduling() {
        let rt = parse("lock_memory = false").unwrap();
        let done = apply(&rt, Process::Node(NodeRole::Uplink), Path::new("x.toml")).unwrap();
        assert_eq!(done, "normal scheduling");
    }
}
