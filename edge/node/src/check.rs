//! `v2t-edge check`: one BV's whole configuration checked before a test day, with every problem
//! named at once. Each check is one line of the [`Report`] — `ok`, `warn` (allowed, worth
//! knowing) or `FAIL` (the runtime would refuse to start, or start without what it needs), naming
//! the file, the field and the bound, and what to do.
//!
//! It reads what the runtime reads, with the runtime's own loaders: the edge configuration, each
//! file it names on its own (a broken vehicle file does not hide a broken gate file), the limits
//! that must agree (the gate narrows the vehicle's; the regulator takes both vehicles'), the cloud
//! link's key, map, broker and certificates, then [`crate::config::load`] as every process runs it.
//! Against this machine: the SocketCAN interface (present, a CAN interface, up) and
//! `[launch.realtime]` (its CPUs, and whether this process may take its priorities and lock its
//! memory). It starts no node, opens no iceoryx2 service and sends no CAN frame.
//!
//! ```
//! use std::path::Path;
//! use v2t_edge::check::{Machine, Status, run};
//!
//! let config = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config/edge/bv1.toml");
//! let report = run(&config, Default::default(), &Machine::this_one());
//! assert!(!report.failed(), "{report}");
//! assert!(report.count(Status::Ok) > 5);
//! ```

use std::fmt;
use std::path::{Path, PathBuf};

use serde::de::DeserializeOwned;
use v2t_files::{load_toml, read_text, relative_to};
use v2t_model::validate::Validate;
use v2t_model::vehicle::VehicleConfig;
use v2t_wire::link;

use crate::NodeRole;
use crate::config::{CanLink, EdgeConfig, Overrides};
use crate::realtime::{Process, Realtime, Step, check_cpus, failure_message, sys};
use crate::uplink::UplinkConfig;

/// How one check came out.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Status {
    /// As the runtime needs it.
    Ok,
    /// Allowed, but worth knowing (a bench transport, the demo key).
    Warn,
    /// The runtime would refuse to start, or start without what it needs.
    Fail,
}

impl fmt::Display for Status {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Self::Ok => "ok  ",
            Self::Warn => "warn",
            Self::Fail => "FAIL",
        })
    }
}

/// One line of the report.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Finding {
    /// How it came out.
    pub status: Status,
    /// What was checked: a file's field in the edge configuration, a relation, the CAN interface.
    pub subject: String,
    /// What was found, and for a `FAIL` what to do.
    pub detail: String,
}

impl fmt::Display for Finding {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} {}: {}", self.status, self.subject, self.detail)
    }
}

/// Every check, in order; printed one line each and a summary line.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Report {
    /// The checks.
    pub findings: Vec<Finding>,
}

impl Report {
    fn push(&mut self, status: Status, subject: impl Into<String>, detail: impl Into<String>) {
        self.findings.push(Finding { status, subject: subject.into(), detail: detail.into() });
    }

    fn ok(&mut self, subject: impl Into<String>, detail: impl Into<String>) {
        self.push(Status::Ok, subject, detail);
    }

    fn warn(&mut self, subject: impl Into<String>, detail: impl Into<String>) {
        self.push(Status::Warn, subject, detail);
    }

    fn fail(&mut self, subject: impl Into<String>, detail: impl Into<String>) {
        self.push(Status::Fail, subject, detail);
    }

    /// How many checks came out so.
    pub fn count(&self, status: Status) -> usize {
        self.findings.iter().filter(|f| f.status == status).count()
    }

    /// Whether any check failed (`v2t-edge check` then exits with code 2).
    pub fn failed(&self) -> bool {
        self.count(Status::Fail) > 0
    }
}

impl fmt::Display for Report {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for finding in &self.findings {
            writeln!(f, "{finding}")?;
        }
        let (ok, warn, fail) = (self.count(Status::Ok), self.count(Status::Warn), self.count(Status::Fail));
        let verdict = if fail > 0 {
            "do not start the runtime until every FAIL above is fixed"
        } else if warn > 0 {
            "the runtime can start; read the warn lines"
        } else {
            "the runtime can start"
        };
        writeln!(f, "summary: {ok} ok, {warn} warn, {fail} FAIL: {verdict}")
    }
}

pub use crate::realtime::Rlimit;

/// What the check needs to know of the machine and of its own process; [`Machine::this_one`]
/// reads it, a test writes it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Machine {
    /// The network interfaces, `/sys/class/net`.
    pub net: PathBuf,
    /// CPUs online, counted as the runtime counts them (`sysconf(_SC_NPROCESSORS_ONLN)`).
    pub online_cpus: Option<usize>,
    /// `RLIMIT_RTPRIO`: the highest `SCHED_FIFO` priority allowed without `CAP_SYS_NICE`.
    pub rtprio: Option<Rlimit>,
    /// `RLIMIT_MEMLOCK`, bytes: what may be locked without `CAP_IPC_LOCK`.
    pub memlock: Option<Rlimit>,
    /// Effective user id.
    pub euid: Option<u32>,
    /// Effective capabilities (`CapEff` of `/proc/self/status`, one bit per capability).
    pub capabilities: Option<u64>,
    /// This process's address space, KiB (`VmSize`): `mlockall` needs all of it under the limit.
    pub vm_size_kib: Option<u64>,
}

/// `CAP_IPC_LOCK`: lock memory beyond `RLIMIT_MEMLOCK`.
const CAP_IPC_LOCK: u32 = 14;
/// `CAP_SYS_NICE`: real-time priorities beyond `RLIMIT_RTPRIO`.
const CAP_SYS_NICE: u32 = 23;
/// `ARPHRD_CAN`: the `type` of a CAN interface (`can0` and `vcan0` alike).
const ARPHRD_CAN: u32 = 280;
/// `IFF_UP` in an interface's `flags`: administratively up.
const IFF_UP: u32 = 0x1;

impl Machine {
    /// This machine and this process.
    pub fn this_one() -> Self {
        let status = std::fs::read_to_string("/proc/self/status").unwrap_or_default();
        let field = |name: &str| status.lines().find_map(|l| l.strip_prefix(name)).map(str::trim);
        let (rtprio, memlock) = sys::limits();
        Self {
            net: PathBuf::from("/sys/class/net"),
            online_cpus: sys::online_cpus().ok(),
            rtprio,
            memlock,
            euid: field("Uid:").and_then(|f| f.split_whitespace().nth(1)).and_then(|u| u.parse().ok()),
            capabilities: field("CapEff:").and_then(|c| u64::from_str_radix(c, 16).ok()),
            vm_size_kib: field("VmSize:").and_then(|v| v.trim_end_matches("kB").trim().parse().ok()),
        }
    }

    fn has(&self, capability: u32) -> Option<bool> {
        self.capabilities.map(|c| (c >> capability) & 1 == 1)
    }
}

/// Checks the configuration `path` as a process of the runtime started with `overrides` would
/// load it, and how it fits `machine`.
pub fn run(path: &Path, overrides: Overrides<'_>, machine: &Machine) -> Report {
    let mut r = Report::default();
    let Some(edge) = edge_config(&mut r, path, overrides) else {
        return r;
    };
    let bv = file::<VehicleConfig>(&mut r, path, "vehicle", &edge.vehicle, describe_vehicle);
    file::<VehicleConfig>(&mut r, path, "vut_vehicle", &edge.vut_vehicle, describe_vehicle);
    let regulator = file::<v2t_game::regulator::RegulatorParams>(&mut r, path, "regulator", &edge.regulator, |p| {
        format!("horizon {} steps of {} s", p.horizon, p.dt_s)
    });
    let tracker = file::<v2t_track::TrackerConfig>(&mut r, path, "tracker", &edge.tracker, |t| {
        format!("farthest off the path {} m, longest cycle {} s", t.max_cross_track_m, t.max_dt_s)
    });
    if let (Some(regulator), Some(tracker)) = (&regulator, &tracker) {
        latencies_agree(&mut r, regulator, tracker);
    }
    let gate = file::<v2t_can::gate::GateConfig>(&mut r, path, "gate", &edge.gate, |g| {
        format!("command timeout {} s, feedback timeout {} s", g.command_timeout_s, g.feedback_timeout_s)
    });
    iceoryx2_settings(&mut r, path, &edge.iceoryx2);
    if let (Some(bv), Some(gate)) = (&bv, &gate) {
        gate_fits_vehicle(&mut r, path, &edge.gate, gate, bv);
    }
    if let (Some(bv), Some(tracker)) = (&bv, tracker) {
        match v2t_track::Tracker::try_new(tracker, bv) {
            Ok(_) => r.ok(
                "tracker/vehicle",
                "the tracker takes its acceleration, jerk and steering limits from the vehicle file",
            ),
            Err(e) => r.fail("tracker/vehicle", format!("{e}: fix the tracker or the vehicle file")),
        }
    }
    match &edge.uplink {
        Some(u) => uplink(&mut r, path, u, &edge.launch.nodes),
        None => r.warn(
            "geofence",
            "no [uplink], so no map: priors reach the regulator over this BV's iceoryx2 services (on the bench \
             from the lab's v2t-sim-ecu) and no drivable area is checked on the BV; with a cloud link, \
             `uplink.map` is the track every uploaded prior must stay on",
        ),
    }
    // Every file read on its own above; now together, as every process of the runtime loads them.
    if !r.failed() {
        runtime_loader(&mut r, path);
    }
    can(&mut r, path, &edge.can, overrides.can_iface.is_some(), &machine.net);
    dbc(&mut r);
    match &edge.launch.realtime {
        Some(rt) => realtime(&mut r, rt, &edge.launch.nodes, machine),
        None => r.ok("launch.realtime", "off (no section): normal scheduling, memory not locked"),
    }
    r
}

/// The edge configuration with the command line's `overrides`; one that is out of range is still
/// returned, so that the files it names are checked too. `None`: it cannot be read or parsed.
fn edge_config(r: &mut Report, path: &Path, overrides: Overrides<'_>) -> Option<EdgeConfig> {
    let (mut edge, valid) = match load_toml::<EdgeConfig>(path) {
        Ok(edge) => (edge, true),
        Err(e) => {
            r.fail("config", format!("{e}: fix it, or name the right file with --config"));
            let raw = read_text(path).ok().and_then(|text| toml::from_str::<EdgeConfig>(&text).ok())?;
            (raw, false)
        }
    };
    if let Some(ns) = overrides.namespace {
        ns.clone_into(&mut edge.namespace);
    }
    if let Some(interface) = overrides.can_iface {
        edge.can = CanLink::Socketcan { interface: interface.to_owned() };
    }
    if valid {
        let nodes: Vec<&str> = edge.launch.nodes.iter().map(|n| n.as_str()).collect();
        match edge.validate() {
            Ok(()) => {
                r.ok("config", format!("{}: namespace {}, nodes {}", path.display(), edge.namespace, nodes.join(", ")))
            }
            Err(e) => r.fail("config", format!("{}: with the command line's options: {e}", path.display())),
        }
    }
    Some(edge)
}

fn describe_vehicle(v: &VehicleConfig) -> String {
    let l = &v.limits;
    format!(
        "{}: top speed {} m/s, acceleration {} m/s², deceleration {} m/s²",
        v.name, l.max_speed_mps, l.max_accel_mps2, l.max_decel_mps2
    )
}

/// Loads the file the edge configuration `config` names in `field` (`written`) as the runtime does.
fn file<T: DeserializeOwned + Validate>(
    r: &mut Report,
    config: &Path,
    field: &str,
    written: &str,
    describe: impl Fn(&T) -> String,
) -> Option<T> {
    let path = relative_to(config, written);
    match load_toml::<T>(&path) {
        Ok(value) => {
            r.ok(field, format!("{}: {}", path.display(), describe(&value)));
            Some(value)
        }
        Err(e) => {
            r.fail(field, format!("{e}: fix it, or point `{field} =` in {} at the right file", config.display()));
            None
        }
    }
}

/// The iceoryx2 settings: present (the runtime's loader) and parsed by iceoryx2 as each process
/// takes them (`ports::use_iceoryx2_config`, here without making them this process's settings).
fn iceoryx2_settings(r: &mut Report, config: &Path, written: &str) {
    let path = relative_to(config, written);
    let shown = path.display().to_string();
    let fix = format!("fix it, or point `iceoryx2 =` in {} at the right file", config.display());
    if !path.is_file() {
        r.fail("iceoryx2", format!("{shown} does not exist: {fix}"));
        return;
    }
    use iceoryx2::prelude::SemanticString as _;
    let parsed = iceoryx2::prelude::FilePath::new(shown.as_bytes())
        .map_err(|e| format!("{e:?}"))
        .and_then(|file| iceoryx2::config::Config::from_file(&file).map_err(|e| format!("{e:?}")));
    match parsed {
        Ok(_) => r.ok("iceoryx2", format!("{shown}: iceoryx2 settings of every process of the runtime")),
        Err(e) => r.fail("iceoryx2", format!("{shown}: iceoryx2 refuses it ({e}): {fix}")),
    }
}

/// Farthest apart the regulator's and the tracker's acceleration latencies may be, s.
const LATENCY_MISMATCH_S: f64 = 0.05;

/// The regulator's plan counts the speed a BV speeding up still gains (`accel_latency_s`); the
/// tracker predicts the speed over its own `accel_latency_s`. Both describe one actuator.
fn latencies_agree(
    r: &mut Report,
    regulator: &v2t_game::regulator::RegulatorParams,
    tracker: &v2t_track::TrackerConfig,
) {
    let (plan, track) = (regulator.accel_latency_s, tracker.accel_latency_s);
    if (plan - track).abs() <= LATENCY_MISMATCH_S {
        r.ok("regulator/tracker", format!("both count the BV's acceleration latency as {track} s"));
    } else {
        r.warn(
            "regulator/tracker",
            format!(
                "the regulator's accel_latency_s is {plan} s, the tracker's {track} s: the plan's curve caps assume \
                 one actuator and the tracker another; set both to the BV's measured latency"
            ),
        );
    }
}

/// The gate may only narrow the vehicle's limits (the gateway's envelope is built from both).
fn gate_fits_vehicle(
    r: &mut Report,
    config: &Path,
    written: &str,
    gate: &v2t_can::gate::GateConfig,
    bv: &VehicleConfig,
) {
    let l = &bv.limits;
    match gate.validate_for(bv) {
        Ok(()) => r.ok(
            "gate/vehicle",
            format!(
                "stop at {} m/s² and {} m/s³, lateral acceleration up to {} m/s², within the BV's {}, {} and {}",
                gate.stop_decel_mps2,
                gate.stop_jerk_mps3,
                gate.max_lat_accel_mps2,
                l.max_decel_mps2,
                l.max_jerk_mps3,
                l.max_lat_accel_mps2
            ),
        ),
        Err(e) => r.fail(
            "gate/vehicle",
            format!(
                "{}: {e}: the gate may only narrow the vehicle's limits: lower it in the gate file (or fix the vehicle file)",
                relative_to(config, written).display()
            ),
        ),
    }
}

/// [`crate::config::load`] as every process runs it, then the regulator built on what it loaded
/// (the regulator node's start: its settings with both vehicles' limits, its QPs).
fn runtime_loader(r: &mut Report, path: &Path) {
    let cfg = match crate::config::load(path) {
        Ok(cfg) => cfg,
        Err(e) => {
            r.fail("runtime loader", format!("{e}"));
            return;
        }
    };
    let (bv, vut) = (cfg.regulator.bv, cfg.regulator.vut);
    match crate::regulate::Regulation::new(cfg.regulator, cfg.vehicle.limits.max_lat_accel_mps2) {
        Ok(_) => r.ok(
            "regulator/vehicles",
            format!(
                "the regulator builds with the BV's limits ({} m/s, +{}/-{} m/s²) and the VUT's ({} m/s, +{}/-{} m/s²)",
                bv.max_speed_mps,
                bv.max_accel_mps2,
                bv.max_decel_mps2,
                vut.max_speed_mps,
                vut.max_accel_mps2,
                vut.max_decel_mps2
            ),
        ),
        Err(e) => r.fail(
            "regulator/vehicles",
            format!(
                "{e}: the regulator takes both vehicles' speed and acceleration limits and would not start with \
                 these: fix the vehicle file (or the regulator file)"
            ),
        ),
    }
}

/// The `[uplink]` section's files and broker, each on its own (what `UplinkSettings::load` reads).
fn uplink(r: &mut Report, config: &Path, u: &UplinkConfig, nodes: &[NodeRole]) {
    if !nodes.contains(&NodeRole::Uplink) {
        r.warn(
            "uplink",
            "an [uplink] section, but launch.nodes does not start `uplink`: no cloud link will run (every node \
             still loads the section, so it is checked)",
        );
    }
    cloud_key(r, config, &u.cloud_key);
    geofence_map(r, config, u);
    match v2t_wire::mqtt::BrokerUrl::parse(&u.broker) {
        Ok(b) if b.tls => r.ok("uplink.broker", format!("{}: host {}, port {}, TLS", u.broker, b.host, b.port)),
        Ok(b) if matches!(b.host.as_str(), "127.0.0.1" | "localhost" | "::1") => {
            r.ok("uplink.broker", format!("{}: this machine's broker, port {}, no TLS", u.broker, b.port));
        }
        Ok(b) => r.warn(
            "uplink.broker",
            format!(
                "{}: host {}, port {}, without TLS: frames are signed, but telemetry and the MQTT password travel \
                 in clear; on a real track use mqtts:// with ca_file",
                u.broker, b.host, b.port
            ),
        ),
        Err(e) => r.fail("uplink.broker", format!("{e}: write mqtt://host:port or mqtts://host:port")),
    }
    for (field, written) in [("ca_file", &u.ca_file), ("client_cert", &u.client_cert), ("client_key", &u.client_key)] {
        if let Some(written) = written {
            let path = relative_to(config, written);
            match std::fs::read(&path) {
                Ok(_) => r.ok(format!("uplink.{field}"), format!("{}: readable", path.display())),
                Err(e) => r.fail(
                    format!("uplink.{field}"),
                    format!("{}: {e}: install it, or fix `{field}` in [uplink]", path.display()),
                ),
            }
        }
    }
}

/// The cloud's public key: present, a valid Ed25519 key, not the demo key, and no secret key
/// beside it that every user can read.
fn cloud_key(r: &mut Report, config: &Path, written: &str) {
    let path = relative_to(config, written);
    let install = "install the cloud's public key (made with `video2track keygen` on the supervisor's machine; \
                   copy only its .pub to the BV): the uplink does not start without it";
    let key = std::fs::read(&path)
        .map_err(|e| e.to_string())
        .and_then(|bytes| String::from_utf8(bytes).map_err(|_| "not text".to_owned()))
        .and_then(|text| link::key_from_hex(&text))
        .and_then(|bytes| {
            link::VerifyingKey::from_bytes(&bytes).map(|_| bytes).map_err(|e| format!("not a public key: {e}"))
        });
    match key {
        Err(e) => r.fail("uplink.cloud_key", format!("{}: {e}: {install}", path.display())),
        Ok(bytes) if link::key_to_hex(&bytes) == link::DEMO_PUBLIC_KEY => r.warn(
            "uplink.cloud_key",
            format!(
                "{}: the committed demo key, whose secret half is public: anyone can sign priors and commands for \
                 this BV; simulated sessions only, never on a vehicle (make a pair with `video2track keygen`)",
                path.display()
            ),
        ),
        Ok(bytes) => r.ok(
            "uplink.cloud_key",
            format!(
                "{}: an Ed25519 public key ({}…)",
                path.display(),
                link::key_to_hex(&bytes).get(..16).unwrap_or("")
            ),
        ),
    }
    let secret = path.with_extension("key");
    if let Ok(meta) = std::fs::metadata(&secret) {
        use std::os::unix::fs::PermissionsExt as _;
        if meta.permissions().mode() & 0o004 != 0 {
            r.warn(
                "uplink.cloud_key",
                format!(
                    "a secret key {} lies beside it, readable by every user: the BV needs only the public half; \
                     remove it from the vehicle (at least `chmod 600` it)",
                    secret.display()
                ),
            );
        }
    }
}

/// The track map whose drivable area every uploaded prior must stay on (the prior check's geofence).
fn geofence_map(r: &mut Report, config: &Path, u: &UplinkConfig) {
    let path = relative_to(config, &u.map);
    let shown = path.display().to_string();
    let map = match v2t_map::Map::load(&path) {
        Ok(map) => map,
        Err(e) => {
            let e = e.to_string();
            let what = if e.contains(&shown) { e } else { format!("{shown}: {e}") };
            r.fail(
                "uplink.map",
                format!(
                    "{what}: every uploaded prior is checked against this track's drivable area, the uplink does \
                     not start without it: fix `map` in [uplink] or the map"
                ),
            );
            return;
        }
    };
    let area = v2t_map::drivable::DrivableArea::from_map(&map);
    if area.is_empty() {
        r.fail("uplink.map", format!("{shown} has no drivable lane: name the track's map in `map`"));
        return;
    }
    r.ok(
        "uplink.map",
        format!(
            "{shown}: {}, whose drivable area is the geofence of every uploaded prior, within {} m",
            map.name, u.geofence_margin_m
        ),
    );
    if let Some(first) = map.warnings.first() {
        r.warn(
            "uplink.map",
            format!(
                "{} warning(s) while reading it, the first: {first}: its drivable area may lack lanes",
                map.warnings.len()
            ),
        );
    }
}

/// The CAN transport: a SocketCAN interface must exist, be a CAN interface and be up.
fn can(r: &mut Report, config: &Path, link: &CanLink, from_command_line: bool, net: &Path) {
    let iface = match link {
        CanLink::Ipc => {
            r.warn(
                "can",
                "transport ipc: the bench's iceoryx2 virtual bus (the lab's v2t-sim-ecu at the other end), no \
                 vehicle bus; on the vehicle write [can] transport = \"socketcan\", interface = \"can0\" (or pass \
                 --can-iface can0)",
            );
            return;
        }
        CanLink::Socketcan { interface } => interface,
    };
    let origin =
        if from_command_line { "--can-iface".to_owned() } else { format!("[can] interface in {}", config.display()) };
    let subject = format!("can {iface}");
    let dir = net.join(iface);
    if !dir.is_dir() {
        r.fail(
            subject,
            format!(
                "no network interface `{iface}` ({origin}; {} is missing): on the vehicle plug in the CAN adapter, \
                 then `sudo ip link set {iface} up type can bitrate 500000` (the vehicle's bitrate); on a bench \
                 `sudo modprobe vcan && sudo ip link add dev {iface} type vcan && sudo ip link set {iface} up`; or \
                 name another interface",
                dir.display()
            ),
        );
        return;
    }
    let read = |leaf: &str| std::fs::read_to_string(dir.join(leaf)).map(|s| s.trim().to_owned()).unwrap_or_default();
    let kind = read("type");
    if kind.parse::<u32>().ok() != Some(ARPHRD_CAN) {
        r.fail(
            subject,
            format!(
                "`{iface}` ({origin}) is not a CAN interface (type {kind}, CAN is {ARPHRD_CAN}): name the CAN \
                 adapter's interface (`ip -brief link show type can`, or `type vcan`)"
            ),
        );
        return;
    }
    let flags = u32::from_str_radix(read("flags").trim_start_matches("0x"), 16).unwrap_or(0);
    let operstate = read("operstate");
    if flags & IFF_UP == 0 {
        r.fail(
            subject,
            format!(
                "`{iface}` is down: bring it up, on the vehicle `sudo ip link set {iface} up type can bitrate 500000` \
                 (the vehicle's bitrate), a vcan with `sudo ip link set {iface} up`"
            ),
        );
    } else if operstate == "down" {
        r.fail(
            subject,
            format!(
                "`{iface}` is up but its link is down (bus-off, or no transceiver or cable): check the wiring and \
                 `ip -details -statistics link show {iface}`, then `sudo ip link set {iface} down` and up again"
            ),
        );
    } else {
        r.ok(subject, format!("a CAN interface, up (operstate {operstate}), from {origin}"));
    }
}

/// What the binary's CAN codec carries (generated from `config/can/bv.dbc` at build time).
fn dbc(r: &mut Report) {
    let ids: Vec<String> = v2t_can::codec::MESSAGE_IDS.iter().map(|id| format!("{id:#05x}")).collect();
    r.ok(
        "dbc",
        format!(
            "this binary's codec is config/can/bv.dbc as built, messages {} (it records no DBC version: compare \
             the ids with the vehicle's drive-by-wire DBC)",
            ids.join(", ")
        ),
    );
}

/// `[launch.realtime]` against this machine and this process's allowances.
fn realtime(r: &mut Report, rt: &Realtime, nodes: &[NodeRole], m: &Machine) {
    let processes: Vec<Process> =
        std::iter::once(Process::Launcher).chain(nodes.iter().map(|n| Process::Node(*n))).collect();
    let before = r.findings.len();
    for p in &processes {
        let Some(cpus) = rt.scheduling(*p).and_then(|s| s.cpus.as_deref()) else {
            continue;
        };
        let subject = format!("launch.realtime.{}.cpus", p.as_str());
        match m.online_cpus.map(|n| (n, check_cpus(cpus, n))) {
            Some((n, Ok(()))) => r.ok(subject, format!("{cpus:?}: this machine has {n} CPU(s) online")),
            Some((_, Err(e))) => r.fail(subject, format!("{e}: name CPUs this machine has, or leave `cpus` out")),
            None => r.warn(subject, "cannot count this machine's CPUs: the process checks them at start"),
        }
    }
    let who = format!(
        "this process (uid {}) — check runs with its own limits, so run it as the runtime runs, as the service's \
         ExecStartPre does",
        m.euid.map_or_else(|| "?".to_owned(), |u| u.to_string())
    );
    let highest = processes
        .iter()
        .filter_map(|p| rt.scheduling(*p).and_then(|s| s.priority).map(|pr| (pr, *p)))
        .max_by_key(|(pr, _)| *pr);
    if let Some((priority, process)) = highest {
        let subject = "launch.realtime priority";
        let cgroup =
            "a cgroup or container without real-time runtime can still refuse it: each process checks at start";
        let allowed =
            |by: String| format!("SCHED_FIFO up to {priority} ({}) allowed by {by}; {cgroup}", process.as_str());
        match (m.has(CAP_SYS_NICE), m.rtprio) {
            (Some(true), _) => r.ok(subject, allowed("CAP_SYS_NICE".to_owned())),
            (_, Some(Rlimit::Unlimited)) => r.ok(subject, allowed("RLIMIT_RTPRIO unlimited".to_owned())),
            (_, Some(Rlimit::Of(n))) if n >= u64::from(priority) => {
                r.ok(subject, allowed(format!("RLIMIT_RTPRIO {n}")))
            }
            (Some(false), Some(Rlimit::Of(n))) => r.fail(
                subject,
                format!(
                    "{} would stop with exit code 2 at start: {} (RLIMIT_RTPRIO {n}, no CAP_SYS_NICE for {who})",
                    process.as_str(),
                    failure_message(Step::Priority(priority), libc::EPERM)
                ),
            ),
            _ => r.warn(subject, format!("cannot read the limits of {who}: each process checks at start")),
        }
    }
    if rt.lock_memory {
        let subject = "launch.realtime.lock_memory";
        let hint = failure_message(Step::LockMemory, libc::ENOMEM);
        match (m.has(CAP_IPC_LOCK), m.memlock, m.vm_size_kib) {
            (Some(true), _, _) => r.ok(subject, "mlockall allowed by CAP_IPC_LOCK"),
            (_, Some(Rlimit::Unlimited), _) => r.ok(subject, "mlockall allowed by RLIMIT_MEMLOCK unlimited"),
            (_, Some(Rlimit::Of(bytes)), Some(vm)) if bytes / 1024 < vm => r.fail(
                subject,
                format!(
                    "RLIMIT_MEMLOCK {} KiB is less than even this check's address space ({vm} KiB), and mlockall \
                     needs all of it under the limit: every process would stop with exit code 2 at start: {hint} \
                     ({who})",
                    bytes / 1024
                ),
            ),
            (_, Some(Rlimit::Of(bytes)), _) => r.warn(
                subject,
                format!(
                    "RLIMIT_MEMLOCK {} KiB and no CAP_IPC_LOCK: a process whose address space outgrows it stops with \
                     exit code 2 at start: {hint}",
                    bytes / 1024
                ),
            ),
            _ => r.warn(subject, format!("cannot read the limits of {who}: each process checks at start")),
        }
    }
    if r.findings.len() == before {
        r.ok("launch.realtime", "no entry for the processes launched: normal scheduling");
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn machine(net: &Path) -> Machine {
        Machine {
            net: net.to_owned(),
            online_cpus: Some(2),
            rtprio: Some(Rlimit::Of(0)),
            memlock: Some(Rlimit::Of(8 << 20)),
            euid: Some(1000),
            capabilities: Some(0),
            vm_size_kib: Some(64 << 10),
        }
    }

    /// A fake `/sys/class/net/<iface>`.
    fn interface(net: &Path, iface: &str, kind: u32, flags: u32, operstate: &str) {
        let dir = net.join(iface);
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(dir.join("type"), format!("{kind}\n")).unwrap();
        std::fs::write(dir.join("flags"), format!("{flags:#x}\n")).unwrap();
        std::fs::write(dir.join("operstate"), format!("{operstate}\n")).unwrap();
    }

    fn can_line(net: &Path, iface: &str) -> Finding {
        let mut r = Report::default();
        let link = CanLink::Socketcan { interface: iface.to_owned() };
        can(&mut r, Path::new("bv1.toml"), &link, true, net);
        assert_eq!(r.findings.len(), 1, "{r}");
        r.findings.remove(0)
    }

    #[test]
    fn the_regulator_and_the_tracker_count_one_acceleration_latency() {
        let (regulator, tracker) =
            (v2t_game::regulator::RegulatorParams::default(), v2t_track::TrackerConfig::default());
        let mut r = Report::default();
        latencies_agree(&mut r, &regulator, &tracker);
        assert_eq!(r.findings.first().map(|f| f.status), Some(Status::Ok), "{r}");
        let slow = v2t_track::TrackerConfig { accel_latency_s: 0.8, ..tracker };
        let mut r = Report::default();
        latencies_agree(&mut r, &regulator, &slow);
        let f = r.findings.first().unwrap();
        assert_eq!(f.status, Status::Warn, "{r}");
        assert!(f.detail.contains("0.45 s") && f.detail.contains("0.8 s"), "{r}");
    }

    #[test]
    fn the_demo_key_is_the_committed_one() {
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config/keys/demo_cloud.pub");
        assert_eq!(std::fs::read_to_string(root).unwrap().trim(), link::DEMO_PUBLIC_KEY);
    }

    #[test]
    fn a_socketcan_interface_must_exist_be_can_and_be_up() {
        let dir = tempfile::tempdir().unwrap();
        let net = dir.path();
        interface(net, "eth0", 1, 0x1003, "up");
        interface(net, "can0", ARPHRD_CAN, 0x0, "down");
        interface(net, "can1", ARPHRD_CAN, 0x1, "down");
        interface(net, "vcan0", ARPHRD_CAN, 0xc1, "unknown");
        let missing = can_line(net, "nonexistent0");
        assert_eq!(missing.status, Status::Fail);
        for hint in ["nonexistent0", "--can-iface", "ip link set nonexistent0 up type can bitrate", "type vcan"] {
            assert!(missing.detail.contains(hint), "{hint}: {missing}");
        }
        let eth = can_line(net, "eth0");
        assert!(eth.status == Status::Fail && eth.detail.contains("not a CAN interface (type 1"), "{eth}");
        let down = can_line(net, "can0");
        assert!(
            down.status == Status::Fail
                && down.detail.contains("is down")
                && down.detail.contains("ip link set can0 up"),
            "{down}"
        );
        let no_link = can_line(net, "can1");
        assert!(no_link.status == Status::Fail && no_link.detail.contains("bus-off"), "{no_link}");
        // A vcan reports operstate `unknown` when up: it has no carrier.
        assert_eq!(can_line(net, "vcan0").status, Status::Ok);
    }

    #[test]
    fn the_ipc_transport_is_a_warning() {
        let mut r = Report::default();
        can(&mut r, Path::new("bv1.toml"), &CanLink::Ipc, false, Path::new("/nowhere"));
        assert_eq!(r.count(Status::Warn), 1, "{r}");
        assert!(!r.failed());
    }

    fn realtime_report(text: &str, m: &Machine) -> Report {
        let rt: Realtime = toml::from_str(text).unwrap();
        let mut r = Report::default();
        realtime(&mut r, &rt, &[NodeRole::Gateway, NodeRole::Regulator], m);
        r
    }

    #[test]
    fn real_time_settings_are_checked_against_this_process_s_allowances() {
        let dir = tempfile::tempdir().unwrap();
        let m = machine(dir.path());
        let text = "lock_memory = true\nlauncher = { priority = 10 }\ngateway = { priority = 80, cpus = [1] }";
        let r = realtime_report(text, &m);
        let line = |subject: &str| r.findings.iter().find(|f| f.subject == subject).unwrap().clone();
        assert_eq!(line("launch.realtime.gateway.cpus").status, Status::Ok, "{r}");
        let prio = line("launch.realtime priority");
        assert_eq!(prio.status, Status::Fail, "{r}");
        for hint in ["gateway", "SCHED_FIFO priority 80", "rtprio", "RLIMIT_RTPRIO 0", "CAP_SYS_NICE", "uid 1000"] {
            assert!(prio.detail.contains(hint), "{hint}: {prio}");
        }
        let lock = line("launch.realtime.lock_memory");
        assert!(lock.status == Status::Fail && lock.detail.contains("memlock unlimited"), "{lock}");

        let privileged = Machine { capabilities: Some((1 << CAP_SYS_NICE) | (1 << CAP_IPC_LOCK)), ..m.clone() };
        assert!(!realtime_report(text, &privileged).failed(), "{}", realtime_report(text, &privileged));
        let limits = Machine { rtprio: Some(Rlimit::Of(99)), memlock: Some(Rlimit::Unlimited), ..m.clone() };
        assert!(!realtime_report(text, &limits).failed());
        let unknown = Machine { rtprio: None, memlock: None, capabilities: None, ..m.clone() };
        assert_eq!(realtime_report(text, &unknown).count(Status::Warn), 2);

        let r = realtime_report("lock_memory = false\nregulator = { cpus = [0, 3] }\nuplink = { cpus = [9] }", &m);
        assert_eq!(r.count(Status::Fail), 1, "the uplink is not launched: {r}");
        assert!(r.findings.iter().any(|f| f.subject == "launch.realtime.regulator.cpus" && f.detail.contains("CPU 3")));
    }

    #[test]
    fn the_report_ends_with_a_summary() {
        let mut r = Report::default();
        r.ok("a", "fine");
        r.warn("b", "worth knowing");
        assert!(r.to_string().ends_with("summary: 1 ok, 1 warn, 0 FAIL: the runtime can start; read the warn lines\n"));
        r.fail("c", "broken");
        assert!(r.failed());
        assert!(r.to_string().starts_with("ok   a: fine\nwarn b: worth knowing\nFAIL c: broken\n"), "{r}");
    }
}
