//! The onboard runtime's configuration, `config/edge/<bv>.toml`: which files hold the vehicle,
//! regulator, tracker and gate settings, the timing of every node, the CAN transport and what the
//! launcher starts.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};
use v2t_files::{load_toml, relative_to};
use v2t_model::validate::{Validate, ValidationError, in_range};
use v2t_model::vehicle::VehicleConfig;

use crate::error::EdgeError;

/// The runtime of one BV, as written.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EdgeConfig {
    /// Service namespace of this BV, e.g. `v2t/bv1`.
    pub namespace: String,
    /// The BV's vehicle file (limits, geometry), relative to this file.
    pub vehicle: String,
    /// The VUT's vehicle file (the regulator's model of its limits).
    pub vut_vehicle: String,
    /// Regulator settings (`config/regulator/*.toml`).
    pub regulator: String,
    /// Tracker settings (`config/track/*.toml`).
    pub tracker: String,
    /// Safety-gate settings (`config/can/*.toml`).
    pub gate: String,
    /// iceoryx2 settings shared by every process of the runtime (`config/iceoryx2.toml`).
    pub iceoryx2: String,
    /// Node timing and watchdogs.
    pub timing: Timing,
    /// The CAN link to the drive-by-wire system.
    pub can: CanLink,
    /// What the launcher starts and how it restarts.
    pub launch: Launch,
    /// The cloud link (needed when `launch.nodes` has `uplink`).
    #[serde(default)]
    pub uplink: Option<crate::uplink::UplinkConfig>,
}

/// Periods and timeouts, s.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Timing {
    /// The regulator decides this often.
    pub regulator_period_s: f64,
    /// A decision that takes longer than this overran its deadline: it is counted in the
    /// regulator's heartbeat (`deadline_misses`) and the monitor reports it. Default: the period.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub regulator_budget_s: Option<f64>,
    /// The gateway transmits commands this often (also when nothing new arrived).
    pub gateway_period_s: f64,
    /// The monitor checks this often.
    pub monitor_period_s: f64,
    /// Every node sends a heartbeat this often.
    pub heartbeat_period_s: f64,
    /// A node whose heartbeat is older than this is dead.
    pub heartbeat_timeout_s: f64,
    /// A BV state (localization) older than this is stale.
    pub state_timeout_s: f64,
    /// A VUT state older than this is stale.
    pub vut_timeout_s: f64,
    /// A plan older than this is stale.
    pub plan_timeout_s: f64,
}

/// Which CAN transport the gateway and the simulated ECU use.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, tag = "transport", rename_all = "snake_case")]
pub enum CanLink {
    /// A SocketCAN interface (`can0`, `vcan0`).
    Socketcan {
        /// Interface name.
        interface: String,
    },
    /// The iceoryx2 virtual bus (`<namespace>/can/tx`, `…/can/rx`) where the kernel has no CAN.
    Ipc,
}

/// The launcher's work.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Launch {
    /// Nodes to start, in order.
    pub nodes: Vec<crate::NodeRole>,
    /// Restarts allowed per node before the launcher gives up on the whole runtime.
    pub max_restarts: u32,
    /// Wait before a restart, s.
    pub restart_delay_s: f64,
    /// The monitor engages the gate once every node is healthy for the first time. After any
    /// stop, engaging again takes an explicit request (`v2t-edge engage`).
    pub auto_engage: bool,
    /// Real-time scheduling of the launcher and each node (off without the section).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub realtime: Option<crate::realtime::Realtime>,
}

impl Validate for Timing {
    fn validate(&self) -> Result<(), ValidationError> {
        in_range("regulator_period_s", self.regulator_period_s, 0.01, 1.0)?;
        if let Some(budget) = self.regulator_budget_s {
            in_range("regulator_budget_s", budget, 0.001, self.regulator_period_s)?;
        }
        in_range("gateway_period_s", self.gateway_period_s, 0.001, 0.1)?;
        in_range("monitor_period_s", self.monitor_period_s, 0.001, 0.1)?;
        in_range("heartbeat_period_s", self.heartbeat_period_s, 0.001, 0.5)?;
        in_range("heartbeat_timeout_s", self.heartbeat_timeout_s, 0.005, 2.0)?;
        if self.heartbeat_timeout_s < 2.0 * self.heartbeat_period_s {
            return Err(ValidationError::new("heartbeat_timeout_s", "must be at least twice heartbeat_period_s"));
        }
        in_range("state_timeout_s", self.state_timeout_s, 0.01, 2.0)?;
        in_range("vut_timeout_s", self.vut_timeout_s, 0.01, 5.0)?;
        in_range("plan_timeout_s", self.plan_timeout_s, 0.01, 5.0)
    }
}

impl Timing {
    /// The regulator's budget for one decision, ns: `regulator_budget_s`, or the period.
    pub fn regulator_budget_ns(&self) -> u64 {
        (self.regulator_budget_s.unwrap_or(self.regulator_period_s) * 1e9) as u64
    }
}

impl Validate for EdgeConfig {
    fn validate(&self) -> Result<(), ValidationError> {
        let ns_ok = !self.namespace.is_empty()
            && self.namespace.chars().all(|c| c.is_ascii_alphanumeric() || matches!(c, '/' | '_' | '-'));
        if !ns_ok {
            return Err(ValidationError::new("namespace", "must be non-empty ASCII letters, digits, '/', '_', '-'"));
        }
        self.timing.validate().map_err(|e| e.within("timing"))?;
        if let CanLink::Socketcan { interface } = &self.can
            && (interface.is_empty() || interface.len() > 15)
        {
            return Err(ValidationError::new("can.interface", "must have 1 to 15 characters"));
        }
        in_range("launch.restart_delay_s", self.launch.restart_delay_s, 0.0, 60.0)?;
        if self.launch.nodes.is_empty() {
            return Err(ValidationError::new("launch.nodes", "must name at least one node"));
        }
        if let Some(rt) = &self.launch.realtime {
            rt.validate().map_err(|e| e.within("launch.realtime"))?;
        }
        if let Some(u) = &self.uplink {
            u.validate().map_err(|e| e.within("uplink"))?;
        } else if self.launch.nodes.contains(&crate::NodeRole::Uplink) {
            return Err(ValidationError::new("uplink", "launch.nodes has `uplink`: an [uplink] section is needed"));
        }
        Ok(())
    }
}

/// Everything one BV's runtime needs, loaded and validated.
#[derive(Debug, Clone)]
pub struct Loaded {
    /// The file it came from.
    pub path: PathBuf,
    /// The runtime settings.
    pub edge: EdgeConfig,
    /// The BV.
    pub vehicle: VehicleConfig,
    /// The VUT as the regulator models it.
    pub vut_vehicle: VehicleConfig,
    /// Regulator settings with both vehicles' limits.
    pub regulator: v2t_game::regulator::RegulatorParams,
    /// Tracker settings.
    pub tracker: v2t_track::TrackerConfig,
    /// Safety-gate settings.
    pub gate: v2t_can::gate::GateConfig,
    /// The iceoryx2 configuration file.
    pub iceoryx2: PathBuf,
    /// The cloud link with its key and the track's drivable area, when configured.
    pub uplink: Option<crate::uplink::UplinkSettings>,
}

fn input(path: &Path, e: impl std::fmt::Display) -> EdgeError {
    EdgeError::Config { path: path.to_owned(), message: e.to_string() }
}

/// Loads `path` and every file it names.
pub fn load(path: &Path) -> Result<Loaded, EdgeError> {
    let edge: EdgeConfig = load_toml(path)?;
    let file = |written: &str| relative_to(path, written);
    let vehicle: VehicleConfig = load_toml(&file(&edge.vehicle)).map_err(|e| input(path, e))?;
    let vut_vehicle: VehicleConfig = load_toml(&file(&edge.vut_vehicle)).map_err(|e| input(path, e))?;
    let regulator: v2t_game::regulator::RegulatorParams =
        load_toml(&file(&edge.regulator)).map_err(|e| input(path, e))?;
    let regulator = regulator.with_limits((&vehicle.limits).into(), (&vut_vehicle.limits).into());
    let tracker: v2t_track::TrackerConfig = load_toml(&file(&edge.tracker)).map_err(|e| input(path, e))?;
    let gate: v2t_can::gate::GateConfig = load_toml(&file(&edge.gate)).map_err(|e| input(path, e))?;
    let gate_for_vehicle = gate.validate_for(&vehicle);
    gate_for_vehicle.map_err(|e| input(path, format!("{}: {e}", edge.gate)))?;
    let iceoryx2 = file(&edge.iceoryx2);
    if !iceoryx2.is_file() {
        return Err(input(path, format!("iceoryx2 configuration {} does not exist", iceoryx2.display())));
    }
    let uplink = edge.uplink.as_ref().map(|u| crate::uplink::UplinkSettings::load(u, path)).transpose()?;
    Ok(Loaded { path: path.to_owned(), edge, vehicle, vut_vehicle, regulator, tracker, gate, iceoryx2, uplink })
}

/// What a process's command line may change in a configuration.
#[derive(Debug, Clone, Copy, Default)]
pub struct Overrides<'a> {
    /// Another service namespace.
    pub namespace: Option<&'a str>,
    /// A SocketCAN interface (`can0`, `vcan0`) instead of the configured CAN transport.
    pub can_iface: Option<&'a str>,
}

/// Loads `path` for one process of the runtime: [`load`], the command line's `overrides` (checked
/// like the file), and the iceoryx2 settings of the configuration installed for this process.
pub fn load_for_process(path: &Path, overrides: Overrides<'_>) -> Result<Loaded, EdgeError> {
    let mut cfg = load(path)?;
    if let Some(ns) = overrides.namespace {
        ns.clone_into(&mut cfg.edge.namespace);
    }
    if let Some(interface) = overrides.can_iface {
        cfg.edge.can = CanLink::Socketcan { interface: interface.to_owned() };
    }
    cfg.edge.validate().map_err(|e| input(path, format!("with the command line's options: {e}")))?;
    crate::ports::use_iceoryx2_config(&cfg.iceoryx2)?;
    Ok(cfg)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn bv1() -> EdgeConfig {
        load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config/edge/bv1.toml")).unwrap().edge
    }

    #[test]
    fn the_regulator_budget_lies_within_its_period() {
        let mut cfg = bv1();
        assert_eq!(cfg.timing.regulator_budget_s, None);
        cfg.timing.regulator_budget_s = Some(0.05);
        assert!(cfg.validate().is_ok());
        for bad in [0.2, 0.0, f64::NAN] {
            cfg.timing.regulator_budget_s = Some(bad);
            let e = cfg.validate().unwrap_err().to_string();
            assert!(e.contains("timing.regulator_budget_s") && e.contains("[0.001, 0.1]"), "{e}");
        }
    }

    #[test]
    fn a_realtime_section_is_checked_with_the_rest_of_the_launch() {
        let text =
            std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config/edge/bv1.toml")).unwrap();
        let with = |section: &str| toml::from_str::<EdgeConfig>(&format!("{text}\n[launch.realtime]\n{section}"));
        let cfg = with("lock_memory = true\ngateway = { priority = 80 }").unwrap();
        assert!(cfg.validate().is_ok());
        assert_eq!(bv1().launch.realtime, None, "off without the section");
        let e = with("lock_memory = true\nregulator = { priority = 120 }").unwrap().validate().unwrap_err();
        assert_eq!(e.field, "launch.realtime.regulator.priority");
        assert!(with("lock_memory = true\nswap = false").is_err(), "unknown fields are refused");
    }
}
