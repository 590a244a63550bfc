//! `video2track regulate` and `sim --regulated --network|--cloud-broker`: the BV's regulator in the
//! cloud — across a simulated network in the same process, or in its own process reached through
//! an MQTT broker in real time (the deployment the paper and TroubleMaker use; the comparison with
//! the onboard regulator is `experiment latency`).

use std::path::{Path, PathBuf};
use std::time::Duration;

use v2t_files::outln;
use v2t_game::regulator::RegulatorParams;
use v2t_lab::cloud_mqtt::{self, MqttCloudLink};
use v2t_lab::cloud_run::{CloudAt, cloud_regulated_run as cloud_regulated_run_in_lab};
use v2t_lab::controllers::{CloudRegulator, RegulatedBv};
use v2t_sim::scenario::Scenario;
use v2t_wire::link::{SigningKey, VerifyingKey, key_from_hex, topics};
use v2t_wire::mqtt::{BrokerUrl, MqttSettings};

use crate::Usage;

/// How far the agreed start may lie from now, ms (a start an hour off is a mistake, not a plan).
const MAX_START_OFFSET_MS: u64 = 3_600_000;

/// `regulate`'s arguments.
#[derive(Debug, clap::Args)]
pub struct RegulateArgs {
    /// The scenario card of the test (TOML): the BV's route, the VUT's, their conflict and τ.
    card: PathBuf,
    /// The MQTT broker (mqtt://host:port).
    #[arg(long)]
    broker: String,
    /// The cloud's secret key (64 hex digits; `video2track keygen`): every plan is signed with it.
    #[arg(long)]
    key: PathBuf,
    /// When the test starts, Unix ms (the BV's run is given the same).
    #[arg(long)]
    start_unix_ms: u64,
    /// The fleet (test session) id on the link.
    #[arg(long, default_value = "sim")]
    fleet: String,
    /// The BV regulated (the card's first BV), by its id on the link.
    #[arg(long, default_value = "bv1")]
    bv_id: String,
    /// Regulator settings (TOML).
    #[arg(long, default_value = v2t_files::shipped::REGULATOR)]
    regulator: PathBuf,
}

/// Where a cloud-regulated BV's regulator is, as `sim` was told.
#[derive(Debug, Clone)]
pub struct CloudSide {
    /// Regulator settings.
    pub regulator: PathBuf,
    /// A simulated network (TOML).
    pub network: Option<PathBuf>,
    /// Or a broker that reaches a `regulate` process.
    pub broker: Option<String>,
    /// The cloud's public key file.
    pub key: Option<PathBuf>,
    /// When the test starts, Unix ms.
    pub start_unix_ms: Option<u64>,
    /// Fleet id.
    pub fleet: String,
    /// BV id.
    pub bv_id: String,
}

fn check_ids(fleet: &str, bv: &str) -> Result<(), Usage> {
    for (what, id) in [("--fleet", fleet), ("--bv-id", bv)] {
        if !topics::valid_id(id) {
            return Err(Usage(format!("{what} {id:?}: ASCII letters, digits, '_' or '-', 1 to 64 long")));
        }
    }
    Ok(())
}

fn check_start(start_unix_ms: u64) -> Result<(), Usage> {
    let now = cloud_mqtt::unix_ms();
    if start_unix_ms.abs_diff(now) > MAX_START_OFFSET_MS {
        return Err(Usage(format!(
            "--start-unix-ms {start_unix_ms} lies {} s from now (at most {} s)",
            start_unix_ms.abs_diff(now) / 1000,
            MAX_START_OFFSET_MS / 1000
        )));
    }
    Ok(())
}

fn settings(broker: &str, client_id: String) -> anyhow::Result<MqttSettings> {
    let broker = BrokerUrl::parse(broker).map_err(|e| Usage(e.to_string()))?;
    Ok(MqttSettings { broker, client_id, credentials: None, ca_pem: None, client_auth: None, persistent: false })
}

fn one_bv(scenario: &Scenario) -> Result<(), Usage> {
    if scenario.bvs.len() == 1 {
        Ok(())
    } else {
        Err(Usage(format!("the cloud regulator drives one BV; the card {} has {}", scenario.name, scenario.bvs.len())))
    }
}

fn regulator_params(path: &Path, scenario: &Scenario) -> anyhow::Result<RegulatorParams> {
    let settings: RegulatorParams = v2t_files::load_toml(path)?;
    Ok(RegulatedBv::params_for(&settings, scenario, 0))
}

/// One run of `scenario` with its BV regulated in the cloud (simulated network, or a cloud
/// process through a broker), against `vut`: the options read here, the run in the lab
/// ([`v2t_lab::cloud_run::cloud_regulated_run`]).
pub fn cloud_regulated_run(
    c: &CloudSide,
    scenario: &Scenario,
    vut: &v2t_lab::vut::Vut<'_>,
    seed: u64,
) -> anyhow::Result<v2t_sim::runner::RunOutcome> {
    one_bv(scenario)?;
    let regulator: RegulatorParams = v2t_files::load_toml(&c.regulator)?;
    let network: Option<v2t_sim::network::NetworkSettings> =
        c.network.as_deref().map(v2t_files::load_toml).transpose()?;
    let at = match (&network, &c.broker) {
        (Some(network), _) => {
            outln!("BV 0 regulated in the cloud across the simulated network {} ({})", network.name, network.source)?;
            CloudAt::Network(network)
        }
        (None, Some(broker)) => {
            check_ids(&c.fleet, &c.bv_id)?;
            let start = c.start_unix_ms.ok_or_else(|| Usage("--cloud-broker needs --start-unix-ms".into()))?;
            check_start(start)?;
            let key_path = c.key.as_deref().ok_or_else(|| Usage("--cloud-broker needs --cloud-key".into()))?;
            let text = v2t_files::read_text(key_path)?;
            let key = key_from_hex(&text)
                .ok()
                .and_then(|k| VerifyingKey::from_bytes(&k).ok())
                .ok_or_else(|| Usage(format!("{}: not a public key (64 hex digits)", key_path.display())))?;
            let s = settings(broker, format!("v2t-sim-{}-{}", c.bv_id, std::process::id()))?;
            let mqtt = cloud_mqtt::connect(&s, topics::bv(&c.fleet, &c.bv_id, topics::PLAN), Duration::from_secs(10))?;
            outln!(
                "BV 0 ({}) regulated by the cloud process through {broker}, in real time from Unix ms {start}",
                c.bv_id
            )?;
            let link = MqttCloudLink::new(mqtt, &c.fleet, &c.bv_id, start);
            CloudAt::Link { link: Box::new(link), key: Box::new(key), fleet: &c.fleet, bv_id: &c.bv_id }
        }
        (None, None) => return Err(Usage("a cloud regulator needs --network or --cloud-broker".into()).into()),
    };
    let (outcome, r) = cloud_regulated_run_in_lab(&regulator, scenario, vut, seed, at)?;
    outln!(
        "link: {} cycles, {} on the minimal-risk fallback; plans accepted {}, refused {}; lost up {}, down {}",
        r.cycles,
        r.fallback_cycles,
        r.plans_accepted,
        r.plans_refused,
        r.up_lost,
        r.down_lost
    )?;
    Ok(outcome)
}

/// The cloud process of one BV: regulates on what it hears until the scenario's end.
pub fn run(a: RegulateArgs) -> anyhow::Result<()> {
    check_ids(&a.fleet, &a.bv_id)?;
    check_start(a.start_unix_ms)?;
    let scenario = v2t_sim::files::load_scenario(&a.card)?;
    one_bv(&scenario)?;
    let params = regulator_params(&a.regulator, &scenario)?;
    let key: SigningKey = v2t_supervisor::link::load_signing_key(&a.key).map_err(crate::BadFile::of)?;
    let mut cloud = CloudRegulator::new(params, &scenario, 0, key, &a.fleet, &a.bv_id)?;
    let s = settings(&a.broker, format!("v2t-regulate-{}-{}", a.bv_id, std::process::id()))?;
    let mqtt = cloud_mqtt::connect(&s, topics::bv(&a.fleet, &a.bv_id, topics::TELEMETRY), Duration::from_secs(10))?;
    outln!(
        "regulating {} of fleet {} ({}, {}) through {} from Unix ms {}",
        a.bv_id,
        a.fleet,
        scenario.name,
        scenario.target,
        a.broker,
        a.start_unix_ms
    )?;
    let stats = cloud_mqtt::serve_regulator(&mut cloud, &scenario, &mqtt, &a.fleet, &a.bv_id, a.start_unix_ms);
    mqtt.disconnect();
    outln!("heard {} BV states, published {} plans ({} on stale states)", stats.states, stats.plans, stats.stale)?;
    Ok(())
}
