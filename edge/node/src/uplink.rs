//! The cloud link node: signed priors and commands in from the MQTT broker, telemetry, heartbeats
//! and events out. The BV decides on its own — this node only hands accepted priors to the
//! regulator and accepted commands to the gateway over iceoryx2; losing the broker never stops the
//! onboard loop (the `on_link_loss` policy says whether the BV continues or makes its minimal-risk
//! stop).
//!
//! [`UplinkLogic`] is the pure part (frame in, actions out) and is tested without a broker;
//! [`MqttLink`] runs the `rumqttc` client on its own thread (QoS 1, persistent session, reconnect
//! with backoff, TLS with rustls when the broker URL is `mqtts://`); [`run`] joins them.

use std::path::{Path, PathBuf};
use std::time::{Duration, SystemTime, UNIX_EPOCH};

use iceoryx2::service::Service;
use serde::{Deserialize, Serialize};
use v2t_map::drivable::DrivableArea;
use v2t_model::validate::{Validate, ValidationError, in_range};
use v2t_wire::link::{self, CloudBody, Command, Receiver, Window, topics};
use v2t_wire::mqtt::{BrokerUrl, LinkEvent, MqttLink, MqttSettings};
use v2t_wire::{
    ActivePrior, BvState, Code, GateReport, Header, NodeKind, RegulatedPlan, SafetyAction, SafetyCommand, services,
};

use crate::clock::now_ns;
use crate::config::Loaded;
use crate::error::EdgeError;
use crate::heart::Heart;
use crate::ports::{Bus, latest, send};
use crate::prior::{PriorChecks, from_upload};

/// What the BV does when the broker has been unreachable for `link_loss_timeout_s`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum LinkLoss {
    /// Finish by its own rules (the regulator and the watchdogs keep running).
    Continue,
    /// Ask the gateway for the minimal-risk stop.
    MinimalRiskStop,
}

/// The `[uplink]` section of the edge configuration, as written.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct UplinkConfig {
    /// `mqtt://host:port` or `mqtts://host:port`.
    pub broker: String,
    /// Fleet (test session) id, part of every topic.
    pub fleet: String,
    /// This BV's id, part of its topics and its MQTT client id.
    pub bv_id: String,
    /// File holding the cloud's Ed25519 public key (64 hex digits), relative to this file.
    pub cloud_key: String,
    /// The track's OpenDRIVE map, relative to this file: every prior must stay on its drivable area.
    pub map: String,
    /// How far off the drivable area a prior's point may lie, m.
    pub geofence_margin_m: f64,
    /// A cloud message older than this is stale, s.
    pub max_age_s: f64,
    /// … or further ahead of the BV's clock than this, s.
    pub max_skew_s: f64,
    /// Telemetry period, s (10 Hz: 0.1).
    pub telemetry_period_s: f64,
    /// Heartbeat period to the cloud, s (5 Hz: 0.2).
    pub heartbeat_period_s: f64,
    /// What to do when the broker stays unreachable.
    pub on_link_loss: LinkLoss,
    /// … for this long, s.
    pub link_loss_timeout_s: f64,
    /// MQTT user name.
    #[serde(default)]
    pub username: Option<String>,
    /// Environment variable holding the MQTT password (never the password itself).
    #[serde(default)]
    pub password_env: Option<String>,
    /// CA certificate (PEM) for `mqtts://`, relative to this file.
    #[serde(default)]
    pub ca_file: Option<String>,
    /// Client certificate and key (PEM) for mutual TLS, relative to this file.
    #[serde(default)]
    pub client_cert: Option<String>,
    /// … and its key.
    #[serde(default)]
    pub client_key: Option<String>,
    /// File (relative to this file) where the last accepted sequence number is kept, so that a
    /// restarted uplink still refuses every frame it accepted or passed before (without it, frames
    /// younger than `max_age_s` could be replayed to a restarted node).
    #[serde(default)]
    pub state_file: Option<String>,
}

impl Validate for UplinkConfig {
    fn validate(&self) -> Result<(), ValidationError> {
        BrokerUrl::parse(&self.broker).map_err(|e| ValidationError::new("broker", e.to_string()))?;
        if !topics::valid_id(&self.fleet) {
            return Err(ValidationError::new("fleet", "must be 1–64 ASCII letters, digits, '_' or '-'"));
        }
        if !topics::valid_id(&self.bv_id) {
            return Err(ValidationError::new("bv_id", "must be 1–64 ASCII letters, digits, '_' or '-'"));
        }
        in_range("geofence_margin_m", self.geofence_margin_m, 0.0, 5.0)?;
        in_range("max_age_s", self.max_age_s, 0.1, 3600.0)?;
        in_range("max_skew_s", self.max_skew_s, 0.0, 60.0)?;
        in_range("telemetry_period_s", self.telemetry_period_s, 0.01, 10.0)?;
        in_range("heartbeat_period_s", self.heartbeat_period_s, 0.01, 10.0)?;
        in_range("link_loss_timeout_s", self.link_loss_timeout_s, 0.1, 600.0)?;
        if self.client_cert.is_some() != self.client_key.is_some() {
            return Err(ValidationError::new("client_cert", "client_cert and client_key go together"));
        }
        if (self.client_cert.is_some() || self.ca_file.is_some()) && !self.broker.starts_with("mqtts://") {
            return Err(ValidationError::new("broker", "certificates need an mqtts:// broker"));
        }
        Ok(())
    }
}

/// The uplink settings with the files they name loaded.
#[derive(Debug, Clone)]
pub struct UplinkSettings {
    /// As written.
    pub config: UplinkConfig,
    /// The cloud's public key.
    pub cloud_key: link::VerifyingKey,
    /// The drivable area of the track.
    pub area: DrivableArea,
    /// How to reach the broker (credentials and certificates loaded).
    pub mqtt: MqttSettings,
}

impl UplinkSettings {
    /// Loads what `config` (written in `file`) names.
    pub fn load(config: &UplinkConfig, file: &Path) -> Result<Self, EdgeError> {
        let bad = |m: String| EdgeError::Config { path: file.to_owned(), message: format!("uplink: {m}") };
        config.validate().map_err(|e| bad(e.to_string()))?;
        let rel = |w: &str| -> PathBuf { v2t_files::relative_to(file, w) };
        let read = |w: &str| std::fs::read(rel(w)).map_err(|e| bad(format!("{}: {e}", rel(w).display())));
        let key_text = String::from_utf8(read(&config.cloud_key)?).map_err(|_| bad("cloud_key is not text".into()))?;
        let key_bytes = link::key_from_hex(&key_text).map_err(|m| bad(format!("cloud_key: {m}")))?;
        let cloud_key = link::VerifyingKey::from_bytes(&key_bytes)
            .map_err(|e| bad(format!("cloud_key is not a public key: {e}")))?;
        let map = v2t_map::Map::load(&rel(&config.map)).map_err(|e| bad(format!("map: {e}")))?;
        let area = DrivableArea::from_map(&map);
        if area.is_empty() {
            return Err(bad(format!("map {} has no drivable lane", config.map)));
        }
        let ca_pem = config.ca_file.as_deref().map(read).transpose()?;
        let client_auth = match (&config.client_cert, &config.client_key) {
            (Some(c), Some(k)) => Some((read(c)?, read(k)?)),
            _ => None,
        };
        let credentials = match &config.username {
            Some(user) => {
                let password = match &config.password_env {
                    Some(var) => {
                        std::env::var(var).map_err(|_| bad(format!("the password variable {var} is not set")))?
                    }
                    None => String::new(),
                };
                Some((user.clone(), password))
            }
            None => None,
        };
        let broker = BrokerUrl::parse(&config.broker).map_err(|e| bad(e.to_string()))?;
        if broker.tls && ca_pem.is_none() {
            return Err(bad("an mqtts:// broker needs ca_file".into()));
        }
        let mqtt = MqttSettings {
            broker,
            client_id: format!("v2t-{}-{}", config.fleet, config.bv_id),
            credentials,
            ca_pem,
            client_auth,
            persistent: true,
        };
        Ok(Self { config: config.clone(), cloud_key, area, mqtt })
    }
}

/// Writes `seq` to `path` atomically (a temporary file renamed over it).
fn save_seq(path: &Path, seq: u64) -> std::io::Result<()> {
    let tmp = path.with_extension("tmp");
    std::fs::write(&tmp, format!("{seq}\n"))?;
    std::fs::rename(&tmp, path)
}

/// Unix time, ms.
pub fn unix_ms() -> u64 {
    SystemTime::now().duration_since(UNIX_EPOCH).map_or(0, |d| u64::try_from(d.as_millis()).unwrap_or(u64::MAX))
}

/// What the uplink does with an accepted frame.
#[derive(Debug, Clone, PartialEq)]
pub enum Action {
    /// Hand this prior to the regulator and the tracker.
    Prior(Box<ActivePrior>),
    /// Ask the gateway for this.
    Safety(SafetyAction),
}

/// What happened to a frame: the actions to take and the event to report (JSON text).
#[derive(Debug, Clone, PartialEq)]
pub struct Outcome {
    /// What to do.
    pub actions: Vec<Action>,
    /// `accepted` or `refused`.
    pub verdict: &'static str,
    /// The frame's sequence number, when it could be read.
    pub seq: Option<u64>,
    /// What, or why not.
    pub detail: String,
}

impl Outcome {
    /// The event as one JSON line.
    pub fn event_json(&self, bv_id: &str, stamp_ms: u64) -> String {
        serde_json::json!({
            "bv_id": bv_id, "stamp_ms": stamp_ms, "seq": self.seq, "verdict": self.verdict, "detail": self.detail
        })
        .to_string()
    }
}

/// The pure part of the uplink: checks every cloud frame and turns it into actions.
#[derive(Debug)]
pub struct UplinkLogic {
    rx: Receiver,
    checks: PriorChecks,
    active: Option<ActivePrior>,
}

impl UplinkLogic {
    /// The logic of BV `bv_id`, trusting `key`.
    pub fn new(key: link::VerifyingKey, bv_id: &str, window: Window, checks: PriorChecks) -> Self {
        Self { rx: Receiver::new(key, bv_id, window), checks, active: None }
    }

    /// Refuses every sequence number up to `seq` from now on (the state a previous run left).
    pub fn resume_after(&mut self, seq: u64) {
        self.rx.resume_after(seq);
    }

    /// The last accepted sequence number.
    pub fn last_seq(&self) -> Option<u64> {
        self.rx.last_seq()
    }

    /// The prior handed to the regulator last.
    pub fn active(&self) -> Option<&ActivePrior> {
        self.active.as_ref()
    }

    /// One frame at Unix time `now_ms` and monotonic `mono_ns`.
    pub fn on_frame(&mut self, frame: &[u8], now_ms: u64, mono_ns: u64) -> Outcome {
        let msg = match self.rx.open(frame, now_ms) {
            Ok(m) => m,
            Err(e) => {
                return Outcome { actions: Vec::new(), verdict: "refused", seq: None, detail: format!("frame: {e}") };
            }
        };
        let seq = Some(msg.seq);
        let refused = |detail: String| Outcome { actions: Vec::new(), verdict: "refused", seq, detail };
        let ok = |actions: Vec<Action>, detail: String| Outcome { actions, verdict: "accepted", seq, detail };
        match msg.body {
            CloudBody::Prior(up) => match from_upload(&up, now_ms, &self.checks, mono_ns) {
                Ok(prior) => {
                    self.active = Some(prior.clone());
                    ok(vec![Action::Prior(Box::new(prior))], format!("prior {} (seq {})", up.prior_id, msg.seq))
                }
                Err(e) => refused(e.to_string()),
            },
            CloudBody::Command(Command::Arm) => {
                ok(vec![Action::Safety(SafetyAction::Reset)], format!("arm (seq {}): gate reset", msg.seq))
            }
            CloudBody::Command(Command::Start) => {
                ok(vec![Action::Safety(SafetyAction::Engage)], format!("start (seq {}): engage", msg.seq))
            }
            CloudBody::Command(Command::Abort) => ok(
                vec![Action::Safety(SafetyAction::MinimalRiskStop)],
                format!("abort (seq {}): minimal-risk stop", msg.seq),
            ),
            CloudBody::Command(Command::SetTarget(target)) => {
                let Some(active) = self.active.as_mut() else {
                    return refused("set target: no active prior".into());
                };
                active.set_target(target);
                active.header = Header { seq: active.header.seq + 1, stamp_ns: mono_ns };
                let prior = active.clone();
                ok(vec![Action::Prior(Box::new(prior))], format!("set target (seq {}): {target}", msg.seq))
            }
        }
    }
}

/// Runs the uplink node until termination.
pub fn run<S: Service>(cfg: &Loaded) -> Result<(), EdgeError> {
    let settings = cfg
        .uplink
        .as_ref()
        .ok_or_else(|| EdgeError::Config { path: cfg.path.clone(), message: "no [uplink] section".into() })?;
    let u = &settings.config;
    let bus = Bus::<S>::new("uplink", &cfg.edge.namespace)?;
    let prior_out = bus.publisher::<ActivePrior>(services::PRIOR)?;
    let safety_out = bus.publisher::<SafetyCommand>(services::SAFETY)?;
    let wake = bus.notifier(services::WAKE_GATEWAY)?;
    let states = bus.subscriber::<BvState>(services::STATE)?;
    let plans = bus.subscriber::<RegulatedPlan>(services::PLAN)?;
    let gates = bus.subscriber::<GateReport>(services::GATE)?;
    let t = cfg.edge.timing;
    let mut heart = Heart::new(&bus, NodeKind::Uplink, t.heartbeat_period_s)?;
    let checks =
        PriorChecks::for_vehicles(&cfg.vehicle, &cfg.vut_vehicle, Some(settings.area.clone()), u.geofence_margin_m);
    let window = Window { max_age_ms: (u.max_age_s * 1e3) as u64, max_skew_ms: (u.max_skew_s * 1e3) as u64 };
    let mut logic = UplinkLogic::new(settings.cloud_key, &u.bv_id, window, checks);
    let state_file = u.state_file.as_deref().map(|w| v2t_files::relative_to(&cfg.path, w));
    if let Some(path) = &state_file {
        match std::fs::read_to_string(path) {
            Ok(text) => {
                let seq: u64 = text.trim().parse().map_err(|_| EdgeError::Config {
                    path: path.clone(),
                    message: format!("uplink state: `{}` is not a sequence number", text.trim()),
                })?;
                logic.resume_after(seq);
                eprintln!("uplink: resuming after sequence number {seq}");
            }
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
            Err(e) => return Err(EdgeError::Config { path: path.clone(), message: format!("uplink state: {e}") }),
        }
    }
    let topic = |leaf: &str| topics::bv(&u.fleet, &u.bv_id, leaf);
    let subscribe = vec![topic(topics::PRIOR), topic(topics::CMD), topics::all_cmd(&u.fleet)];
    let mqtt = MqttLink::start(&settings.mqtt, subscribe).map_err(EdgeError::Mqtt)?;
    let period = Duration::from_millis(5);
    let (mut tele_seq, mut beat_seq, mut safety_seq) = (0u64, 0u64, 0u64);
    let (mut last_tele, mut last_beat) = (0u64, 0u64);
    let start = now_ns();
    let mut connected_at: Option<u64> = None;
    let mut down_since = Some(start);
    let mut last_failure: Option<String> = None;
    let mut loss_handled = false;
    let mut gate = GateReport::default();
    let mut plan = RegulatedPlan::default();
    let mut state = BvState::default();
    let mut unsent = 0u64;
    let mut first = None;
    loop {
        let now = now_ns();
        while let Some(ev) = first.take().or_else(|| mqtt.poll()) {
            match ev {
                LinkEvent::Connected => {
                    eprintln!("uplink: connected to {}", u.broker);
                    last_failure = None;
                    if unsent > 0 {
                        eprintln!(
                            "uplink: {unsent} telemetry and heartbeat frames could not be queued while the broker was away"
                        );
                        unsent = 0;
                    }
                    connected_at = Some(now);
                    down_since = None;
                    loss_handled = false;
                }
                LinkEvent::Down(why) => {
                    if down_since.is_none() {
                        eprintln!("uplink: broker lost: {why}");
                        down_since = Some(now);
                    } else if last_failure.as_deref() != Some(why.as_str()) {
                        // Each new reason once (a wrong password, a refused certificate), not every retry.
                        eprintln!("uplink: cannot reach the broker: {why}; retrying");
                    }
                    last_failure = Some(why);
                }
                LinkEvent::Frame { payload: bytes, .. } => {
                    let outcome = logic.on_frame(&bytes, unix_ms(), now_ns());
                    eprintln!("uplink: {} {}", outcome.verdict, outcome.detail);
                    if let (Some(path), Some(seq), "accepted") = (&state_file, outcome.seq, outcome.verdict)
                        && let Err(e) = save_seq(path, seq)
                    {
                        // The frame stands; only a later restart could accept a replay of it.
                        eprintln!("uplink: cannot save the sequence number to {}: {e}", path.display());
                    }
                    for a in &outcome.actions {
                        match a {
                            Action::Prior(p) => {
                                prior_out
                                    .send_copy((**p).clone())
                                    .map_err(|e| EdgeError::ipc("send", services::PRIOR, e))?;
                            }
                            Action::Safety(action) => {
                                safety_seq += 1;
                                let cmd = SafetyCommand {
                                    header: Header { seq: safety_seq, stamp_ns: now_ns() },
                                    action: action.code(),
                                    culprit: 0,
                                };
                                send(&safety_out, Some(&wake), cmd)?;
                            }
                        }
                    }
                    let event = outcome.event_json(&u.bv_id, unix_ms());
                    if let Err(e) = mqtt.publish(&topic(topics::EVENT), event.into_bytes(), true) {
                        eprintln!("uplink: event not queued: {e}");
                    }
                }
            }
        }
        if let Some(since) = down_since
            && !loss_handled
            && now.saturating_sub(since) as f64 * 1e-9 > u.link_loss_timeout_s
        {
            loss_handled = true;
            eprintln!("uplink: broker unreachable for {} s: {:?}", u.link_loss_timeout_s, u.on_link_loss);
            if u.on_link_loss == LinkLoss::MinimalRiskStop {
                safety_seq += 1;
                let cmd = SafetyCommand {
                    header: Header { seq: safety_seq, stamp_ns: now },
                    action: SafetyAction::MinimalRiskStop.code(),
                    culprit: NodeKind::Uplink.code(),
                };
                send(&safety_out, Some(&wake), cmd)?;
            }
        }
        if let Some(s) = latest(&states)? {
            state = s;
        }
        if let Some(p) = latest(&plans)? {
            plan = p;
        }
        if let Some(g) = latest(&gates)? {
            gate = g;
        }
        if now.saturating_sub(last_tele) as f64 * 1e-9 >= u.telemetry_period_s && connected_at.is_some() {
            last_tele = now;
            tele_seq += 1;
            let tele = link::Telemetry {
                bv_id: u.bv_id.clone(),
                seq: tele_seq,
                stamp_ms: unix_ms(),
                prior_id: logic.active().map_or(0, |p| p.prior_id),
                px_m: state.px_m,
                py_m: state.py_m,
                theta_rad: state.theta_rad,
                speed_mps: state.speed_mps,
                plan_status: plan.status,
                predicted_pet_s: (plan.has_predicted_pet == 1 && plan.predicted_pet_s.is_finite())
                    .then_some(plan.predicted_pet_s),
                gate_state: gate.state,
                gate_reason: gate.reason,
            };
            match link::telemetry_frame(&tele) {
                Ok(frame) => {
                    if mqtt.publish(&topic(topics::TELEMETRY), frame, false).is_err() {
                        unsent += 1;
                    }
                }
                Err(e) => eprintln!("uplink: telemetry not encoded: {e}"),
            }
        }
        if now.saturating_sub(last_beat) as f64 * 1e-9 >= u.heartbeat_period_s && connected_at.is_some() {
            last_beat = now;
            beat_seq += 1;
            // Healthy: the onboard loop is alive (a fresh BV state) and the gate is not stopping.
            let fresh = now.saturating_sub(state.header.stamp_ns) as f64 * 1e-9 <= t.state_timeout_s;
            let stopping = gate.state == v2t_wire::GateState::MinimalRiskStop.code();
            let beat = link::Heartbeat {
                bv_id: u.bv_id.clone(),
                seq: beat_seq,
                stamp_ms: unix_ms(),
                healthy: fresh && !stopping,
            };
            match link::heartbeat_frame(&beat) {
                Ok(frame) => {
                    if mqtt.publish(&topic(topics::HEARTBEAT), frame, false).is_err() {
                        unsent += 1;
                    }
                }
                Err(e) => eprintln!("uplink: heartbeat not encoded: {e}"),
            }
        }
        heart.cycle(now_ns() - now, period.as_nanos() as u64);
        heart.tick(now_ns(), down_since.is_none())?;
        // Sleep until the next cloud message or the period, whichever comes first: a command is
        // handled the moment it arrives.
        first = mqtt.wait(period);
        if !bus.wait(Duration::ZERO) {
            return Ok(());
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use link::{CloudMessage, SigningKey};
    use v2t_wire::StyleCode;

    fn setup() -> (UplinkLogic, SigningKey, link::PriorUpload) {
        let (up, checks) = crate::prior::fixtures::upload("semantics_cut_in.json", 5, (0, 100_000));
        let key = SigningKey::from_bytes(&[3; 32]);
        let logic = UplinkLogic::new(key.verifying_key(), "bv1", Window::default(), checks);
        (logic, key, up)
    }

    fn yield_3s() -> v2t_model::Target {
        v2t_model::Target::new(3.0, v2t_model::Style::Yield).unwrap()
    }

    fn frame(key: &SigningKey, seq: u64, body: CloudBody) -> Vec<u8> {
        let m = CloudMessage { fleet: "pg".into(), bv_id: "bv1".into(), seq, issued_ms: 50_000, body };
        link::seal(&m, key).unwrap()
    }

    #[test]
    fn priors_and_commands_become_actions_and_refusals_say_why() {
        let (mut logic, key, up) = setup();
        let o = logic.on_frame(&frame(&key, 1, CloudBody::Command(Command::SetTarget(yield_3s()))), 50_000, 1);
        assert_eq!((o.verdict, o.actions.len()), ("refused", 0));
        assert!(o.detail.contains("no active prior"), "{}", o.detail);

        let o = logic.on_frame(&frame(&key, 2, CloudBody::Prior(up.clone())), 50_000, 7);
        assert_eq!(o.verdict, "accepted", "{}", o.detail);
        let Some(Action::Prior(p)) = o.actions.first() else { panic!("{o:?}") };
        assert_eq!((p.prior_id, p.header.stamp_ns, p.tau_s), (5, 7, up.prior.tau_s));
        assert!(o.event_json("bv1", 9).contains("\"verdict\":\"accepted\""));

        let o = logic.on_frame(&frame(&key, 3, CloudBody::Command(Command::SetTarget(yield_3s()))), 50_000, 8);
        let Some(Action::Prior(q)) = o.actions.first() else { panic!("{o:?}") };
        assert_eq!((q.tau_s, q.style, q.header.seq), (3.0, StyleCode::Yield.code(), p.header.seq + 1));
        assert_eq!(q.bv_path, p.bv_path, "only the target changes");

        for (seq, cmd, action) in [
            (5, Command::Arm, SafetyAction::Reset),
            (6, Command::Start, SafetyAction::Engage),
            (7, Command::Abort, SafetyAction::MinimalRiskStop),
        ] {
            let o = logic.on_frame(&frame(&key, seq, CloudBody::Command(cmd)), 50_000, 9);
            assert_eq!(o.actions, vec![Action::Safety(action)]);
        }
        let o = logic.on_frame(&frame(&key, 7, CloudBody::Command(Command::Start)), 50_000, 9);
        assert!(o.detail.contains("replay") && o.actions.is_empty(), "{}", o.detail);
        let other = SigningKey::from_bytes(&[4; 32]);
        let o = logic.on_frame(&frame(&other, 8, CloudBody::Command(Command::Start)), 50_000, 9);
        assert!(o.detail.contains("signature"), "{}", o.detail);
        let mut off = up;
        for x in &mut off.prior.agents[1].states {
            x.py += 300.0;
        }
        let o = logic.on_frame(&frame(&key, 9, CloudBody::Prior(off)), 50_000, 9);
        assert!(o.detail.contains("drivable area") && o.actions.is_empty(), "{}", o.detail);
        assert_eq!(logic.active().map(|p| p.tau_s), Some(3.0), "a refused prior leaves the active one");
    }

    #[test]
    fn uplink_configs_are_checked() {
        let mut c = UplinkConfig {
            broker: "mqtt://127.0.0.1:1883".into(),
            fleet: "pg".into(),
            bv_id: "bv1".into(),
            cloud_key: "cloud.pub".into(),
            map: "map.xodr".into(),
            geofence_margin_m: 0.5,
            max_age_s: 30.0,
            max_skew_s: 2.0,
            telemetry_period_s: 0.1,
            heartbeat_period_s: 0.2,
            on_link_loss: LinkLoss::Continue,
            link_loss_timeout_s: 2.0,
            username: None,
            password_env: None,
            ca_file: None,
            client_cert: None,
            client_key: None,
            state_file: None,
        };
        assert_eq!(c.validate(), Ok(()));
        c.bv_id = "bv/#".into();
        assert_eq!(c.validate().unwrap_err().field, "bv_id");
        c.bv_id = "bv1".into();
        c.ca_file = Some("ca.pem".into());
        assert_eq!(c.validate().unwrap_err().field, "broker");
        c.broker = "mqtts://host".into();
        c.client_cert = Some("c.pem".into());
        assert_eq!(c.validate().unwrap_err().field, "client_cert");
    }
}
