//! The cloud link node: signed priors and commands in from the MQTT broker, telemetry, heartbeats
//! and events out. The BV decides on its own — this node only hands accepted priors to the
//! regulator and accepted commands to the gateway over iceoryx2; losing the broker never stops the
//! onboard loop (the `on_link_loss` policy says whether the BV continues or makes its minimal-risk
//! stop).
//!
//! [`UplinkLogic`] is the pure part (frame in, actions out) and is tested without a broker;
//! [`MqttLink`] runs the `rumqttc` client on its own thread (persistent session, QoS 0
//! subscriptions — the cloud repeats a frame until it hears the BV's verdict —, QoS 1 events,
//! reconnect with backoff, TLS with rustls when the broker URL is `mqtts://`); [`run`] joins them.
//!
//! Under attack from anyone who can publish on the broker: commands wait in their own bounded
//! queue and are handled before priors; a message longer than a frame is dropped, never a reason to
//! lose the connection; garbage is refused by the cheapest check that catches it (header, body,
//! fleet, addressee, topic) before any signature is verified, and only counted, in one event per
//! second; the node spends at most `FRAME_BUDGET_NS` (2 ms of each 5 ms tick) on frames before
//! its telemetry, heartbeats and liveness, so a flood never stops the BV.

use std::path::{Path, PathBuf};
use std::time::{Duration, SystemTime, UNIX_EPOCH};

use iceoryx2::service::Service;
use serde::{Deserialize, Serialize};
use v2t_map::drivable::DrivableArea;
use v2t_model::validate::{Validate, ValidationError, in_range};
use v2t_wire::link::{self, Arrival, Receiver, Window, topics};
use v2t_wire::mqtt::{BrokerUrl, Lane, LinkEvent, MqttLink, MqttSettings, QueueLimits, Subscription};
use v2t_wire::{
    ActivePrior, BvState, Code, GateReport, Header, NodeKind, RegulatedPlan, SafetyAction, SafetyCommand, services,
};

use crate::clock::now_ns;
use crate::config::Loaded;
use crate::error::EdgeError;
use crate::heart::Heart;
use crate::ports::{Bus, latest, send};
use crate::prior::PriorChecks;

mod logic;

pub use logic::{Action, Outcome, RefusalTally, UplinkLogic, Verdict, reason_kind, with_campaign};

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

/// Most time the uplink spends on received frames before it turns to its periodic work
/// (telemetry, heartbeats, its own liveness), ns: a flood never starves them.
const FRAME_BUDGET_NS: u64 = 2_000_000;
/// Refusals that are only counted are reported this often, s.
const REFUSAL_REPORT_PERIOD_S: f64 = 1.0;
/// The node waits this long for the next cloud message when it has nothing to do.
const PERIOD: Duration = Duration::from_millis(5);

/// The onboard services the uplink talks to.
struct Ports<S: Service> {
    prior_out: iceoryx2::port::publisher::Publisher<S, ActivePrior, ()>,
    safety_out: iceoryx2::port::publisher::Publisher<S, SafetyCommand, ()>,
    wake: iceoryx2::port::notifier::Notifier<S>,
    states: iceoryx2::port::subscriber::Subscriber<S, BvState, ()>,
    plans: iceoryx2::port::subscriber::Subscriber<S, RegulatedPlan, ()>,
    gates: iceoryx2::port::subscriber::Subscriber<S, GateReport, ()>,
    lessons: iceoryx2::port::subscriber::Subscriber<S, v2t_wire::RunLearnedMsg, ()>,
}

/// The state of the link to the broker.
#[derive(Debug, Default)]
struct LinkState {
    /// Connected since (monotonic ns); `None` while the broker is away.
    connected_at: Option<u64>,
    /// Away since (monotonic ns).
    down_since: Option<u64>,
    /// The last reason a connection failed (each new one is logged once).
    last_failure: Option<String>,
    /// Whether the link-loss policy has run for this outage.
    loss_handled: bool,
}

/// The uplink node: the MQTT client, the logic, and what it reports.
struct Node<'a, S: Service> {
    cfg: &'a Loaded,
    u: &'a UplinkConfig,
    mqtt: MqttLink,
    logic: UplinkLogic,
    state_file: Option<PathBuf>,
    ports: Ports<S>,
    link: LinkState,
    tally: RefusalTally,
    last_report_ns: u64,
    seqs: (u64, u64, u64),
    last_tele_ns: u64,
    last_beat_ns: u64,
    gate: GateReport,
    plan: RegulatedPlan,
    state: BvState,
    /// What the last run taught the regulator, until it is sent (once, when connected).
    lesson: Option<link::RunLearned>,
}

impl<'a, S: Service> Node<'a, S> {
    fn topic(&self, leaf: &str) -> String {
        topics::bv(&self.u.fleet, &self.u.bv_id, leaf)
    }

    /// Where a message arrived, in the terms of the link's checks.
    fn arrival(&self, topic: &str) -> Option<Arrival> {
        if topic == self.topic(topics::PRIOR) {
            Some(Arrival::Prior)
        } else if topic == self.topic(topics::CMD) {
            Some(Arrival::Command)
        } else if topic == topics::all_cmd(&self.u.fleet) {
            Some(Arrival::AllCommand)
        } else {
            None
        }
    }

    /// Handles received events for at most [`FRAME_BUDGET_NS`], commands before priors.
    fn take_events(&mut self, first: Option<LinkEvent>) -> Result<(), EdgeError> {
        let started = now_ns();
        let mut next = first;
        while let Some(ev) = next.take().or_else(|| self.mqtt.poll()) {
            self.on_event(ev)?;
            if now_ns().saturating_sub(started) > FRAME_BUDGET_NS {
                break;
            }
        }
        Ok(())
    }

    fn on_event(&mut self, ev: LinkEvent) -> Result<(), EdgeError> {
        let now = now_ns();
        match ev {
            LinkEvent::Connected => {
                eprintln!("uplink: connected to {}", self.u.broker);
                self.link = LinkState { connected_at: Some(now), ..LinkState::default() };
            }
            LinkEvent::Down(why) => {
                if self.link.down_since.is_none() {
                    eprintln!("uplink: broker lost: {why}");
                    self.link.down_since = Some(now);
                } else if self.link.last_failure.as_deref() != Some(why.as_str()) {
                    // Each new reason once (a wrong password, a refused certificate), not every retry.
                    eprintln!("uplink: cannot reach the broker: {why}; retrying");
                }
                // Nothing is queued for the broker while it is away: telemetry would arrive late
                // and look current.
                self.link.connected_at = None;
                self.link.last_failure = Some(why);
            }
            LinkEvent::Frame { topic, payload, arrived_ms } => {
                let Some(arrival) = self.arrival(&topic) else {
                    self.tally.add("unexpected topic");
                    return Ok(());
                };
                match self.logic.on_frame(&payload, arrival, arrived_ms, unix_ms(), now_ns()) {
                    Outcome::Counted(reason) => self.tally.add(reason),
                    Outcome::Verdict(v) => self.on_verdict(&v)?,
                }
            }
        }
        Ok(())
    }

    /// Acts on a genuine frame's verdict and reports it.
    fn on_verdict(&mut self, v: &Verdict) -> Result<(), EdgeError> {
        eprintln!("uplink: {} {}", v.verdict, v.detail);
        if let (Some(path), "accepted") = (&self.state_file, v.verdict)
            && let Err(e) = save_seq(path, v.seq)
        {
            // The frame stands; only a later restart could accept a replay of it.
            eprintln!("uplink: cannot save the sequence number to {}: {e}", path.display());
        }
        for a in &v.actions {
            match a {
                Action::Prior(p) => {
                    self.ports
                        .prior_out
                        .send_copy((**p).clone())
                        .map_err(|e| EdgeError::ipc("send", services::PRIOR, e))?;
                }
                Action::Safety(action) => self.safety(*action, 0)?,
            }
        }
        let event = v.event_json(&self.u.bv_id, unix_ms());
        if let Err(e) = self.mqtt.publish(&self.topic(topics::EVENT), event.into_bytes(), true) {
            eprintln!("uplink: event not queued: {e}");
        }
        Ok(())
    }

    fn safety(&mut self, action: SafetyAction, culprit: u8) -> Result<(), EdgeError> {
        self.seqs.2 += 1;
        let cmd =
            SafetyCommand { header: Header { seq: self.seqs.2, stamp_ns: now_ns() }, action: action.code(), culprit };
        send(&self.ports.safety_out, Some(&self.ports.wake), cmd)
    }

    /// The link-loss policy, once per outage.
    fn link_loss(&mut self, now: u64) -> Result<(), EdgeError> {
        if let Some(since) = self.link.down_since
            && !self.link.loss_handled
            && now.saturating_sub(since) as f64 * 1e-9 > self.u.link_loss_timeout_s
        {
            self.link.loss_handled = true;
            eprintln!("uplink: broker unreachable for {} s: {:?}", self.u.link_loss_timeout_s, self.u.on_link_loss);
            if self.u.on_link_loss == LinkLoss::MinimalRiskStop {
                self.safety(SafetyAction::MinimalRiskStop, NodeKind::Uplink.code())?;
            }
        }
        Ok(())
    }

    fn read_onboard(&mut self) -> Result<(), EdgeError> {
        if let Some(s) = latest(&self.ports.states)? {
            self.state = s;
        }
        if let Some(p) = latest(&self.ports.plans)? {
            self.plan = p;
        }
        if let Some(g) = latest(&self.ports.gates)? {
            self.gate = g;
        }
        while let Some(m) = self.ports.lessons.receive().map_err(|e| EdgeError::ipc("receive", services::LEARNED, e))? {
            match logic::run_learned(&m, &self.u.bv_id, unix_ms()) {
                Ok(r) => self.lesson = Some(r),
                Err(e) => eprintln!("uplink: what the run learned is not sent: {e}"),
            }
        }
        Ok(())
    }

    /// Telemetry, heartbeat and the refusal summary when they are due (only while connected).
    fn report(&mut self, now: u64) {
        if self.link.connected_at.is_none() {
            return;
        }
        let due = |last: u64, period_s: f64| now.saturating_sub(last) as f64 * 1e-9 >= period_s;
        if let Some(r) = self.lesson.take() {
            // Once per run, at QoS 1: the campaign's memory needs it.
            match link::learned_frame(&r) {
                Ok(frame) => {
                    if let Err(e) = self.mqtt.publish(&self.topic(topics::LEARNED), frame, true) {
                        eprintln!("uplink: learned not queued: {e}");
                    }
                }
                Err(e) => eprintln!("uplink: learned not encoded: {e}"),
            }
        }
        if due(self.last_tele_ns, self.u.telemetry_period_s) {
            self.last_tele_ns = now;
            self.seqs.0 += 1;
            let (s, p, g) = (&self.state, &self.plan, &self.gate);
            let tele = link::Telemetry {
                bv_id: self.u.bv_id.clone(),
                seq: self.seqs.0,
                stamp_ms: unix_ms(),
                prior_id: self.logic.active().map_or(0, |p| p.prior_id),
                px_m: s.px_m,
                py_m: s.py_m,
                theta_rad: s.theta_rad,
                speed_mps: s.speed_mps,
                plan_status: p.status,
                predicted_pet_s: (p.has_predicted_pet == 1 && p.predicted_pet_s.is_finite())
                    .then_some(p.predicted_pet_s),
                below_reach: p.below_reach,
                pet_bound_s: (p.below_reach != 0 && p.has_pet_bound == 1 && p.pet_bound_s.is_finite())
                    .then_some(p.pet_bound_s),
                gate_state: g.state,
                gate_reason: g.reason,
                vut_reaction: (p.has_reaction == 1
                    && [p.vut_reacts_p, p.vut_gap_s, p.vut_gap_sd_s].iter().all(|v| v.is_finite()))
                .then_some(link::VutReaction {
                    reacts_p: p.vut_reacts_p,
                    gap_s: p.vut_gap_s,
                    gap_sd_s: p.vut_gap_sd_s,
                }),
            };
            self.send_report(topics::TELEMETRY, link::telemetry_frame(&tele));
        }
        if due(self.last_beat_ns, self.u.heartbeat_period_s) {
            self.last_beat_ns = now;
            self.seqs.1 += 1;
            // Healthy: the onboard loop is alive (a fresh BV state) and the gate is not stopping.
            let fresh =
                now.saturating_sub(self.state.header.stamp_ns) as f64 * 1e-9 <= self.cfg.edge.timing.state_timeout_s;
            let stopping = self.gate.state == v2t_wire::GateState::MinimalRiskStop.code();
            let beat = link::Heartbeat {
                bv_id: self.u.bv_id.clone(),
                seq: self.seqs.1,
                stamp_ms: unix_ms(),
                healthy: fresh && !stopping,
            };
            self.send_report(topics::HEARTBEAT, link::heartbeat_frame(&beat));
        }
        self.tally.add_dropped(&self.mqtt.take_dropped());
        if due(self.last_report_ns, REFUSAL_REPORT_PERIOD_S) {
            let period_s = now.saturating_sub(self.last_report_ns) as f64 * 1e-9;
            self.last_report_ns = now;
            if !self.tally.is_empty() {
                let event = self.tally.take_event(&self.u.bv_id, unix_ms(), period_s.min(3600.0));
                eprintln!("uplink: {event}");
                if let Err(e) = self.mqtt.publish(&self.topic(topics::EVENT), event.into_bytes(), true) {
                    eprintln!("uplink: refusal summary not queued: {e}");
                }
            }
        }
    }

    fn send_report(&self, leaf: &str, frame: Result<Vec<u8>, link::LinkError>) {
        match frame {
            Ok(frame) => {
                if let Err(e) = self.mqtt.publish(&self.topic(leaf), frame, false) {
                    eprintln!("uplink: {leaf} not queued: {e}");
                }
            }
            Err(e) => eprintln!("uplink: {leaf} not encoded: {e}"),
        }
    }
}

/// Reads the sequence number a previous run left in `path` (none when the file does not exist).
fn resume_state(path: &Path) -> Result<Option<u64>, EdgeError> {
    match std::fs::read_to_string(path) {
        Ok(text) => text.trim().parse().map(Some).map_err(|_| EdgeError::Config {
            path: path.to_owned(),
            message: format!("uplink state: `{}` is not a sequence number", text.trim()),
        }),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(None),
        Err(e) => Err(EdgeError::Config { path: path.to_owned(), message: format!("uplink state: {e}") }),
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
    let ports = Ports {
        prior_out: bus.publisher::<ActivePrior>(services::PRIOR)?,
        safety_out: bus.publisher::<SafetyCommand>(services::SAFETY)?,
        wake: bus.notifier(services::WAKE_GATEWAY)?,
        states: bus.subscriber::<BvState>(services::STATE)?,
        plans: bus.subscriber::<RegulatedPlan>(services::PLAN)?,
        gates: bus.subscriber::<GateReport>(services::GATE)?,
        lessons: bus.subscriber::<v2t_wire::RunLearnedMsg>(services::LEARNED)?,
    };
    let mut heart = Heart::new(&bus, NodeKind::Uplink, cfg.edge.timing.heartbeat_period_s)?;
    let checks =
        PriorChecks::for_vehicles(&cfg.vehicle, &cfg.vut_vehicle, Some(settings.area.clone()), u.geofence_margin_m);
    let window = Window { max_age_ms: (u.max_age_s * 1e3) as u64, max_skew_ms: (u.max_skew_s * 1e3) as u64 };
    let mut logic = UplinkLogic::new(settings.cloud_key, &u.fleet, &u.bv_id, window, checks);
    let state_file = u.state_file.as_deref().map(|w| v2t_files::relative_to(&cfg.path, w));
    if let Some(seq) = state_file.as_deref().map(resume_state).transpose()?.flatten() {
        logic.resume_after(seq);
        eprintln!("uplink: resuming after sequence number {seq}");
    }
    let topic = |leaf: &str| topics::bv(&u.fleet, &u.bv_id, leaf);
    // QoS 0: the broker queues nothing for this BV, so a flood cannot fill a queue of the BV's at the
    // broker and push a good command out of it; the cloud repeats a frame until the BV's verdict on it
    // arrives (a duplicate is harmless: each copy carries its own sequence number).
    let subscribe = [topic(topics::PRIOR), topic(topics::CMD), topics::all_cmd(&u.fleet)]
        .into_iter()
        .map(Subscription::at_most_once)
        .collect();
    // Garbage is refused on the MQTT thread by the cheap checks (header, body, fleet, addressee,
    // topic) before it is queued: the queues hold only frames that may be genuine, commands apart.
    let screener = Receiver::new(settings.cloud_key, &u.fleet, &u.bv_id, window);
    let arrivals = [
        (topic(topics::PRIOR), Arrival::Prior, Lane::Bulk),
        (topic(topics::CMD), Arrival::Command, Lane::Urgent),
        (topics::all_cmd(&u.fleet), Arrival::AllCommand, Lane::Urgent),
    ];
    let screen = move |t: &str, frame: &[u8]| {
        let (_, arrival, lane) = arrivals.iter().find(|(a, _, _)| a == t).ok_or("unexpected topic")?;
        screener.screen(frame, *arrival).map(|_| *lane).map_err(|e| reason_kind(&e))
    };
    let mqtt = MqttLink::start_screened(&settings.mqtt, subscribe, Box::new(screen), QueueLimits::default())?;
    let start = now_ns();
    let mut node = Node {
        cfg,
        u,
        mqtt,
        logic,
        state_file,
        ports,
        link: LinkState { down_since: Some(start), ..LinkState::default() },
        tally: RefusalTally::default(),
        last_report_ns: start,
        seqs: (0, 0, 0),
        last_tele_ns: 0,
        last_beat_ns: 0,
        gate: GateReport::default(),
        plan: RegulatedPlan::default(),
        state: BvState::default(),
        lesson: None,
    };
    let mut first = None;
    loop {
        let now = now_ns();
        node.take_events(first.take())?;
        node.link_loss(now)?;
        node.read_onboard()?;
        node.report(now);
        heart.cycle(now_ns() - now, PERIOD.as_nanos() as u64);
        heart.tick(now_ns(), node.link.down_since.is_none())?;
        // Sleep until the next cloud message or the period, whichever comes first: a command is
        // handled the moment it arrives.
        first = node.mqtt.wait(PERIOD);
        if !bus.wait(Duration::ZERO) {
            return Ok(());
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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
