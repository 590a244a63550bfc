//! `video2track serve`: the cloud supervisor of a test session. It runs an embedded MQTT broker
//! (`rumqttd`, for a single machine) or joins an external one, follows every BV of the fleet from
//! its telemetry, heartbeats and events, takes operator commands on its console (upload a prior,
//! arm, start, abort, re-target), logs everything it receives as JSON lines, and aborts every BV on
//! Ctrl-C or `quit`. The BVs decide on their own: nothing here sits inside their control loop.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::io::Write as _;
use std::net::{SocketAddr, TcpStream};
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use v2t_model::{Style, Target, TargetError};
use v2t_wire::link::{self, ALL_BVS, CloudBody, Command, EdgeReport, Telemetry, topics};
use v2t_wire::mqtt::{Lane, LinkEvent, MqttLink, QueueLimits, Subscription};
use v2t_wire::{BelowReachCode, Code, GateReason, GateState, PlanStatus};

use crate::link::{BvEvent, Connection, LinkError, Signer, command, prior_from_file, unix_ms};

/// A BV whose last heartbeat is older than this is shown as offline.
pub const OFFLINE_AFTER: Duration = Duration::from_secs(1);

/// The embedded broker keeps at most this many bytes per segment of a topic's log …
pub const SEGMENT_BYTES: usize = 4 << 20;
/// … and this many segments: what a slow subscriber has not read yet is dropped beyond
/// 16 MiB per topic filter, so a flood cannot grow the supervisor's memory without bound.
pub const SEGMENTS: usize = 4;

/// Telemetry or a heartbeat older than this when it arrives is shown as late, not as current, ms.
pub const LATE_AFTER_MS: u64 = 1000;

/// The embedded broker hands its router at most this many messages per read from one connection.
/// Small batches make a flooding publisher wait its turn: its reads back up into TCP instead of
/// outpacing what the router forwards to the BVs (a flood at 590,000 messages per second still
/// lets aborts through in tens of milliseconds; `docs/BENCHMARKS.md`).
pub const INGRESS_BATCH: usize = 4;
/// … and forwards at most this many messages to a subscriber per turn, so a BV that reads fast
/// keeps up with a flood on its topics instead of falling behind and losing what the broker drops
/// beyond [`SEGMENTS`] × [`SEGMENT_BYTES`].
pub const EGRESS_BATCH: usize = 4096;

/// Starts the embedded broker on `listen` and returns once it accepts connections.
pub fn start_embedded_broker(listen: SocketAddr) -> Result<(), LinkError> {
    let server = serde_json::json!({
        "name": "v2t",
        "listen": listen.to_string(),
        "next_connection_delay_ms": 1,
        "connections": {
            "connection_timeout_ms": 5000,
            "max_payload_size": link::MAX_FRAME_LEN + 1024,
            "max_inflight_count": INGRESS_BATCH,
            "dynamic_filters": true
        }
    });
    let config = serde_json::json!({
        "id": 0,
        "router": {
            "max_connections": 1000,
            "max_outgoing_packet_count": EGRESS_BATCH,
            "max_segment_size": SEGMENT_BYTES,
            "max_segment_count": SEGMENTS
        },
        "v4": { "1": server }
    });
    let config: rumqttd::Config =
        serde_json::from_value(config).map_err(|e| LinkError::Broker(format!("embedded broker settings: {e}")))?;
    let (tx, rx) = mpsc::channel();
    std::thread::Builder::new()
        .name("broker".into())
        .spawn(move || {
            let mut broker = rumqttd::Broker::new(config);
            let result = broker.start();
            let _ = tx.send(result.map_err(|e| e.to_string()));
        })
        .map_err(|e| LinkError::Broker(format!("cannot start the embedded broker: {e}")))?;
    let deadline = Instant::now() + Duration::from_secs(5);
    loop {
        match rx.try_recv() {
            Ok(Err(e)) => return Err(LinkError::Broker(format!("embedded broker on {listen}: {e}"))),
            Ok(Ok(())) => return Err(LinkError::Broker(format!("embedded broker on {listen} stopped"))),
            Err(_) => {}
        }
        if TcpStream::connect_timeout(&listen, Duration::from_millis(100)).is_ok() {
            return Ok(());
        }
        if Instant::now() > deadline {
            return Err(LinkError::Broker(format!("embedded broker on {listen}: not listening after 5 s")));
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// What the supervisor knows of one BV.
#[derive(Debug, Clone, Default)]
pub struct BvStatus {
    /// Last telemetry.
    pub telemetry: Option<Telemetry>,
    /// How old that telemetry was when it arrived, ms (a backlog after an outage arrives late).
    pub telemetry_age_ms: u64,
    /// When the last heartbeat arrived.
    pub heartbeat_at: Option<Instant>,
    /// Whether every onboard node was alive at the last heartbeat.
    pub healthy: bool,
    /// The last accepted or refused frame.
    pub event: Option<BvEvent>,
}

/// The fleet as seen from the supervisor. Pure: messages and the time come in from outside.
#[derive(Debug, Default)]
pub struct Fleet {
    /// By BV id.
    pub bvs: BTreeMap<String, BvStatus>,
}

/// A message from the broker that the supervisor cannot use (reported, never acted on).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MessageError {
    /// Not a topic of a BV of this fleet.
    #[error("unexpected topic {0}")]
    Topic(String),
    /// A report that does not decode.
    #[error("{topic}: {source}")]
    Frame {
        /// The topic.
        topic: String,
        /// Why.
        source: link::LinkError,
    },
    /// A report that names another BV than its topic.
    #[error("{0}: the report names another BV")]
    OtherBv(String),
    /// An event that is not the JSON a BV sends.
    #[error("{topic}: {message}")]
    Event {
        /// The topic.
        topic: String,
        /// The parser's message.
        message: String,
    },
}

/// A console line that is not a command, and what to type instead.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{0}")]
pub struct ConsoleError(pub String);

/// What a message changed, for the console.
#[derive(Debug, Clone, PartialEq)]
pub enum Change {
    /// A BV was heard from for the first time, or again after being offline.
    Online(String),
    /// A BV said what it did with a frame.
    Event(BvEvent),
    /// A BV reported what a run taught it about the VUT (the session log keeps it whole).
    Learned(link::RunLearned),
    /// Nothing worth a line.
    Quiet,
}

impl Fleet {
    /// One message on `topic` received at `now` (Unix time `arrived_ms`). A message that does not
    /// decode is an error the caller reports; it changes nothing.
    pub fn on_message(
        &mut self,
        topic: &str,
        payload: &[u8],
        now: Instant,
        arrived_ms: u64,
    ) -> Result<Change, MessageError> {
        let mut parts = topic.split('/');
        let (Some("v2t"), Some(_fleet), Some("bv"), Some(bv), Some(leaf), None) =
            (parts.next(), parts.next(), parts.next(), parts.next(), parts.next(), parts.next())
        else {
            return Err(MessageError::Topic(topic.to_owned()));
        };
        let was_online = self.bvs.get(bv).is_some_and(|s| s.online(now));
        match leaf {
            topics::TELEMETRY | topics::HEARTBEAT => {
                let report = link::read_report(payload)
                    .map_err(|source| MessageError::Frame { topic: topic.to_owned(), source })?;
                let status = self.bvs.entry(bv.to_owned()).or_default();
                match report {
                    EdgeReport::Telemetry(t) if t.bv_id == bv => {
                        // Only newer telemetry replaces what is shown: a report held back in a queue
                        // never overwrites a newer one.
                        if status.telemetry.as_ref().is_none_or(|old| t.stamp_ms >= old.stamp_ms) {
                            status.telemetry_age_ms = arrived_ms.saturating_sub(t.stamp_ms);
                            status.telemetry = Some(t);
                        }
                    }
                    EdgeReport::Heartbeat(h) if h.bv_id == bv => {
                        // A heartbeat that arrives late says nothing about the BV now.
                        if arrived_ms.saturating_sub(h.stamp_ms) <= LATE_AFTER_MS {
                            status.heartbeat_at = Some(now);
                            status.healthy = h.healthy;
                        }
                    }
                    _ => return Err(MessageError::OtherBv(topic.to_owned())),
                }
                if !was_online && status.online(now) {
                    return Ok(Change::Online(bv.to_owned()));
                }
                Ok(Change::Quiet)
            }
            topics::LEARNED => match link::read_report(payload) {
                Ok(EdgeReport::Learned(r)) if r.bv_id == bv => Ok(Change::Learned(r)),
                Ok(_) => Err(MessageError::OtherBv(topic.to_owned())),
                Err(source) => Err(MessageError::Frame { topic: topic.to_owned(), source }),
            },
            topics::EVENT => {
                let ev: BvEvent = serde_json::from_slice(payload)
                    .map_err(|e| MessageError::Event { topic: topic.to_owned(), message: e.to_string() })?;
                self.bvs.entry(bv.to_owned()).or_default().event = Some(ev.clone());
                Ok(Change::Event(ev))
            }
            _ => Err(MessageError::Topic(topic.to_owned())),
        }
    }

    /// A table of every BV at `now`.
    pub fn table(&self, now: Instant) -> String {
        let mut s = String::from(
            "BV        link     health   prior  speed   plan              PET pred  τ reach           VUT reacts        gate  (telemetry age)\n",
        );
        for (id, b) in &self.bvs {
            let link = if b.online(now) { "online" } else { "OFFLINE" };
            let health = if b.healthy { "ok" } else { "DEGRADED" };
            let (prior, speed, plan, pet, reach, reacts, gate) = match &b.telemetry {
                Some(t) => (
                    if t.prior_id == 0 { "-".to_owned() } else { t.prior_id.to_string() },
                    format!("{:.1}", t.speed_mps),
                    PlanStatus::from_code(t.plan_status)
                        .map_or_else(|_| format!("?{}", t.plan_status), |p| format!("{p:?}")),
                    t.predicted_pet_s.map_or_else(|| "-".to_owned(), |p| format!("{p:.2} s")),
                    reach_text(t.below_reach, t.pet_bound_s),
                    t.vut_reaction.map_or_else(
                        || "-".to_owned(),
                        |r| format!("p {:.2}, {:.1}±{:.1} s", r.reacts_p, r.gap_s, r.gap_sd_s),
                    ),
                    gate_text(t.gate_state, t.gate_reason),
                ),
                None => ("-".into(), "-".into(), "-".into(), "-".into(), "-".into(), "-".into(), "-".into()),
            };
            let late = if b.telemetry_age_ms > LATE_AFTER_MS {
                format!("  LATE: {:.1} s old on arrival", b.telemetry_age_ms as f64 * 1e-3)
            } else {
                String::new()
            };
            let _ = writeln!(
                s,
                "{id:<9} {link:<8} {health:<8} {prior:<6} {speed:<7} {plan:<17} {pet:<9} {reach:<17} {reacts:<17} {gate}{late}"
            );
        }
        s
    }
}

/// The regulator's word on reach: `-` when nothing says τ is out of reach, else why, with the
/// bound when one is known (`BELOW: campaign ≥ 2.04 s`).
fn reach_text(code: u8, bound_s: Option<f64>) -> String {
    if code == 0 {
        return "-".to_owned();
    }
    let cause = match BelowReachCode::from_code(code) {
        Ok(BelowReachCode::VutWaits) => "VUT waits".to_owned(),
        Ok(BelowReachCode::Campaign) => "campaign".to_owned(),
        Ok(BelowReachCode::OrderRefused) => "order refused".to_owned(),
        Err(_) => format!("?{code}"),
    };
    match bound_s {
        Some(b) => format!("BELOW: {cause} {b:.2} s"),
        None => format!("BELOW: {cause}"),
    }
}

fn gate_text(state: u8, reason: u8) -> String {
    let state = GateState::from_code(state).map_or_else(|_| format!("?{state}"), |g| format!("{g:?}"));
    match GateReason::from_code(reason) {
        Ok(GateReason::Init) => state,
        Ok(r) => format!("{state} ({r:?})"),
        Err(_) => format!("{state} (?{reason})"),
    }
}

impl BvStatus {
    /// Whether a heartbeat came within [`OFFLINE_AFTER`].
    pub fn online(&self, now: Instant) -> bool {
        self.heartbeat_at.is_some_and(|t| now.saturating_duration_since(t) < OFFLINE_AFTER)
    }
}

/// An operator command typed on the console.
#[derive(Debug, Clone, PartialEq)]
pub enum ConsoleCommand {
    /// `upload FILE BV [tau S] [style rush|yield] [agent A]`.
    Upload {
        /// Priors file.
        file: PathBuf,
        /// The BV.
        bv: String,
        /// Target override.
        tau_s: Option<f64>,
        /// Style override.
        style: Option<Style>,
        /// The prior's agent the BV drives.
        agent: Option<String>,
    },
    /// `arm|start|abort [BV|all]`, `target BV|all TAU rush|yield`.
    Send {
        /// BV id or [`ALL_BVS`].
        bv: String,
        /// What.
        command: Command,
    },
    /// `status`.
    Status,
    /// `quit`: abort every BV, then stop.
    Quit,
    /// `help`.
    Help,
}

/// The console's help text.
pub const HELP: &str = "commands:
  upload FILE BV [tau S] [style rush|yield] [agent ID]   sign and send a prior (TrajectoryPrior or GroundedScenario JSON)
  arm [BV|all]                                           reset the BV's gate, ready to start
  start [BV|all]                                         engage
  abort [BV|all]                                         minimal-risk stop
  target BV|all TAU rush|yield                           re-target the running interaction
  status                                                 the fleet table
  quit                                                   abort every BV and stop (Ctrl-C does the same)";

/// Parses one console line.
pub fn parse_console(line: &str) -> Result<Option<ConsoleCommand>, ConsoleError> {
    let bad = |e: String| ConsoleError(e);
    let words: Vec<&str> = line.split_whitespace().collect();
    let bv = |w: Option<&&str>| match w {
        None | Some(&"all") => ALL_BVS.to_owned(),
        Some(b) => (*b).to_owned(),
    };
    match words.as_slice() {
        [] => Ok(None),
        ["status"] => Ok(Some(ConsoleCommand::Status)),
        ["quit" | "exit"] => Ok(Some(ConsoleCommand::Quit)),
        ["help" | "?"] => Ok(Some(ConsoleCommand::Help)),
        [action @ ("arm" | "start" | "abort"), rest @ ..] if rest.len() <= 1 => Ok(Some(ConsoleCommand::Send {
            bv: bv(rest.first()),
            command: command(action, None, None).map_err(|e| bad(e.to_string()))?,
        })),
        ["target", who, tau, style] => {
            let tau = Target::parse_tau(tau).map_err(|e| bad(e.to_string()))?;
            let style: Style = style.parse().map_err(|e: TargetError| bad(e.to_string()))?;
            let command = command("target", Some(tau), Some(style)).map_err(|e| bad(e.to_string()))?;
            Ok(Some(ConsoleCommand::Send { bv: bv(Some(who)), command }))
        }
        ["upload", file, who, rest @ ..] => {
            if *who == "all" {
                return Err(bad("a prior goes to one BV".into()));
            }
            let (mut tau_s, mut style, mut agent) = (None, None, None);
            for pair in rest.chunks(2) {
                match pair {
                    ["tau", v] => tau_s = Some(Target::parse_tau(v).map_err(|e| bad(e.to_string()))?),
                    ["style", v] => style = Some(v.parse().map_err(|e: TargetError| bad(e.to_string()))?),
                    ["agent", v] => agent = Some((*v).to_owned()),
                    other => return Err(bad(format!("upload: unexpected `{}`", other.join(" ")))),
                }
            }
            Ok(Some(ConsoleCommand::Upload { file: PathBuf::from(file), bv: (*who).to_owned(), tau_s, style, agent }))
        }
        _ => Err(bad(format!("cannot read `{line}`; `help` lists the commands"))),
    }
}

/// How `serve` runs.
#[derive(Debug)]
pub struct ServeOptions {
    /// Where to connect.
    pub connection: Connection,
    /// Start the embedded broker on this address first.
    pub embedded: Option<SocketAddr>,
    /// Signs every frame.
    pub signer: Signer,
    /// JSON-lines log of everything received and sent.
    pub log: Option<PathBuf>,
    /// Print the fleet table this often (zero: only on `status`).
    pub status_period: Duration,
    /// How long a prior stays valid after its upload.
    pub prior_valid_s: f64,
}

/// A console line on stdout, dropped when it cannot be written: a reader that went away (`| head`,
/// a `tee` that died) must neither panic nor stop the supervisor the BVs rely on; `quit` and Ctrl-C
/// still abort every BV.
macro_rules! say {
    ($($arg:tt)*) => {{
        let _ = v2t_files::outln!($($arg)*);
    }};
}

/// Runs the supervisor until `quit`, Ctrl-C (`stop` set) or an error.
pub fn serve(mut opts: ServeOptions, stop: &Arc<AtomicBool>) -> Result<(), LinkError> {
    if let Some(addr) = opts.embedded {
        start_embedded_broker(addr)?;
        say!("serve: embedded broker listening on mqtt://{addr}");
    }
    let fleet_id = opts.signer.fleet().to_owned();
    let subscribe = [topics::TELEMETRY, topics::HEARTBEAT, topics::EVENT, topics::LEARNED]
        .iter()
        .map(|leaf| Subscription::reliable(format!("v2t/{fleet_id}/bv/+/{leaf}")))
        .collect();
    let client_id = format!("v2t-{fleet_id}-supervisor");
    let route = |t: &str, _: &[u8]| Ok(if t.ends_with(topics::EVENT) { Lane::Urgent } else { Lane::Bulk });
    let mqtt = MqttLink::start_screened(
        &opts.connection.settings(&client_id, true),
        subscribe,
        Box::new(route),
        QueueLimits::default(),
    )?;
    let mut log = match &opts.log {
        Some(p) => Some(std::io::BufWriter::new(
            std::fs::File::create(p).map_err(|e| LinkError::Usage(format!("{}: {e}", p.display())))?,
        )),
        None => None,
    };
    let console = spawn_console();
    let mut fleet = Fleet::default();
    let mut next_table = Instant::now() + opts.status_period;
    let mut next_prior_id = (unix_ms() % 1_000_000_000).max(1);
    let mut connected = false;
    say!(
        "serve: fleet `{fleet_id}`, broker {}:{}; `help` lists the commands",
        opts.connection.broker.host,
        opts.connection.broker.port
    );
    loop {
        if stop.load(Ordering::SeqCst) {
            say!("serve: interrupted: aborting every BV");
            return abort_all_and_wait(&mqtt, &mut opts.signer, &mut fleet, &mut log);
        }
        if let Some(ev) = mqtt.wait(Duration::from_millis(20)) {
            let now = Instant::now();
            match ev {
                LinkEvent::Connected => {
                    connected = true;
                    say!("serve: connected to the broker");
                }
                LinkEvent::Down(why) => {
                    if connected {
                        say!("serve: broker lost: {why}; reconnecting");
                    }
                    connected = false;
                }
                LinkEvent::Frame { topic, payload, arrived_ms } => {
                    match fleet.on_message(&topic, &payload, now, arrived_ms) {
                        Ok(Change::Online(bv)) => say!("serve: {bv} online"),
                        // A summary of refused garbage says so itself ("N frames refused in 1.0 s: …").
                        Ok(Change::Event(e)) if e.seq.is_none() => say!("serve: {}: {}", e.bv_id, e.detail),
                        Ok(Change::Event(e)) => say!("serve: {} {} {}", e.bv_id, e.verdict, e.detail),
                        Ok(Change::Learned(r)) => say!(
                            "serve: {} learned in the run of prior {}: {}",
                            r.bv_id,
                            r.prior_id,
                            learned_summary(&r)
                        ),
                        Ok(Change::Quiet) => {}
                        Err(why) => say!("serve: ignored a message: {why}"),
                    }
                    if let Some(w) = log.as_mut() {
                        let _ = writeln!(w, "{}", log_line(&topic, &payload, arrived_ms));
                    }
                }
            }
        }
        while let Ok(line) = console.try_recv() {
            match parse_console(&line) {
                Ok(None) => {}
                Ok(Some(ConsoleCommand::Quit)) => {
                    say!("serve: quit: aborting every BV");
                    return abort_all_and_wait(&mqtt, &mut opts.signer, &mut fleet, &mut log);
                }
                Ok(Some(ConsoleCommand::Help)) => say!("{HELP}"),
                Ok(Some(ConsoleCommand::Status)) => {
                    let _ = v2t_files::out!("{}", fleet.table(Instant::now()));
                }
                Ok(Some(ConsoleCommand::Send { bv, command })) => {
                    match send(&mqtt, &mut opts.signer, &bv, CloudBody::Command(command)) {
                        Ok(seq) => say!("serve: sent {command:?} to {bv} (seq {seq})"),
                        Err(e) => say!("serve: {e}"),
                    }
                }
                Ok(Some(ConsoleCommand::Upload { file, bv, tau_s, style, agent })) => {
                    let id = next_prior_id;
                    next_prior_id += 1;
                    let sent = prior_from_file(&file, agent.as_deref(), (tau_s, style), opts.prior_valid_s, id)
                        .and_then(|up| {
                            let text = format!(
                                "prior {id} ({}, τ {} s, {:?})",
                                file.display(),
                                up.prior.target.tau_s(),
                                up.prior.target.style()
                            );
                            send(&mqtt, &mut opts.signer, &bv, CloudBody::Prior(up)).map(|seq| (text, seq))
                        });
                    match sent {
                        Ok((text, seq)) => say!("serve: sent {text} to {bv} (seq {seq})"),
                        Err(e) => say!("serve: upload refused here: {e}"),
                    }
                }
                Err(why) => say!("serve: {why}"),
            }
        }
        if !opts.status_period.is_zero() && Instant::now() >= next_table {
            next_table += opts.status_period;
            if !fleet.bvs.is_empty() {
                let _ = v2t_files::out!("{}", fleet.table(Instant::now()));
            }
        }
        let _ = std::io::stdout().flush();
    }
}

fn send(mqtt: &MqttLink, signer: &mut Signer, bv: &str, body: CloudBody) -> Result<u64, LinkError> {
    let (topic, frame, seq) = signer.seal(bv, body)?;
    mqtt.publish(&topic, frame, true)?;
    Ok(seq)
}

/// Sends abort to every BV, again every [`crate::link::RESEND_EVERY`], until each BV known to be
/// online has confirmed one of the copies, for up to 2 s.
fn abort_all_and_wait(
    mqtt: &MqttLink,
    signer: &mut Signer,
    fleet: &mut Fleet,
    log: &mut Option<std::io::BufWriter<std::fs::File>>,
) -> Result<(), LinkError> {
    let mut seqs = vec![send(mqtt, signer, ALL_BVS, CloudBody::Command(Command::Abort))?];
    let mut waiting: Vec<String> =
        fleet.bvs.iter().filter(|(_, s)| s.online(Instant::now())).map(|(id, _)| id.clone()).collect();
    let deadline = Instant::now() + Duration::from_secs(2);
    let mut next_copy = Instant::now() + crate::link::RESEND_EVERY;
    while !waiting.is_empty() && Instant::now() < deadline {
        if Instant::now() >= next_copy {
            seqs.push(send(mqtt, signer, ALL_BVS, CloudBody::Command(Command::Abort))?);
            next_copy += crate::link::RESEND_EVERY;
        }
        let Some(LinkEvent::Frame { topic, payload, arrived_ms }) = mqtt.wait(Duration::from_millis(20)) else {
            continue;
        };
        if let Some(w) = log.as_mut() {
            let _ = writeln!(w, "{}", log_line(&topic, &payload, arrived_ms));
        }
        if let Ok(Change::Event(e)) = fleet.on_message(&topic, &payload, Instant::now(), arrived_ms)
            && e.seq.is_some_and(|s| seqs.contains(&s))
        {
            say!("serve: {} {} {}", e.bv_id, e.verdict, e.detail);
            waiting.retain(|b| *b != e.bv_id);
        }
    }
    if let Some(w) = log.as_mut() {
        let _ = w.flush();
    }
    mqtt.disconnect();
    std::thread::sleep(Duration::from_millis(50));
    if waiting.is_empty() {
        say!("serve: every BV confirmed the abort");
        Ok(())
    } else {
        Err(LinkError::Refused(format!("no abort confirmation from {} within 2 s", waiting.join(", "))))
    }
}

/// What a run's report says it learned, in words.
fn learned_summary(r: &link::RunLearned) -> String {
    let route = match &r.route {
        Some(route) => {
            format!("the VUT's route to {:.0} m", (route.speeds_mps.len().saturating_sub(1)) as f64 * route.step_m)
        }
        None => "no route".to_owned(),
    };
    let reaction = if r.reaction.is_some() { "its reaction identified" } else { "no identification" };
    format!("{route}, {reaction} (aim {}; `campaign record --learned` takes it from the session log)", r.aim)
}

/// One line of the session log: when it arrived, the topic, the message, and for a report how old
/// it was on arrival (`age_ms`: a backlog after an outage arrives late, not current).
fn log_line(topic: &str, payload: &[u8], arrived_ms: u64) -> String {
    let (body, stamp) = match link::read_report(payload) {
        Ok(EdgeReport::Telemetry(t)) => (serde_json::to_value(&t).unwrap_or_default(), Some(t.stamp_ms)),
        Ok(EdgeReport::Heartbeat(h)) => (serde_json::to_value(&h).unwrap_or_default(), Some(h.stamp_ms)),
        Ok(EdgeReport::Learned(r)) => (serde_json::to_value(&r).unwrap_or_default(), Some(r.stamp_ms)),
        Err(_) => (serde_json::from_slice(payload).unwrap_or(serde_json::Value::Null), None),
    };
    let mut line = serde_json::json!({"received_ms": arrived_ms, "topic": topic, "message": body});
    if let (Some(stamp), Some(obj)) = (stamp, line.as_object_mut()) {
        obj.insert("age_ms".into(), arrived_ms.saturating_sub(stamp).into());
    }
    line.to_string()
}

/// Console lines on a channel; the reader ends with stdin.
fn spawn_console() -> mpsc::Receiver<String> {
    let (tx, rx) = mpsc::channel();
    let _ = std::thread::Builder::new().name("console".into()).spawn(move || {
        for line in std::io::stdin().lines().map_while(Result::ok) {
            if tx.send(line).is_err() {
                return;
            }
        }
    });
    rx
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing)]
    use super::*;
    use v2t_wire::link::{Heartbeat, heartbeat_frame, telemetry_frame};

    fn telemetry(bv: &str, prior_id: u64) -> Telemetry {
        Telemetry {
            bv_id: bv.into(),
            seq: 1,
            stamp_ms: 1,
            prior_id,
            px_m: 0.0,
            py_m: 0.0,
            theta_rad: 0.0,
            speed_mps: 8.25,
            plan_status: PlanStatus::Regulating.code(),
            predicted_pet_s: Some(2.5),
            below_reach: 0,
            pet_bound_s: None,
            gate_state: GateState::Engaged.code(),
            gate_reason: GateReason::EngageRequest.code(),
            vut_reaction: None,
        }
    }

    #[test]
    fn a_runs_lesson_is_shown_and_logged_whole_and_a_bad_one_is_ignored() {
        use v2t_wire::link::{LearnedReaction, LearnedRoute, RunLearned, learned_frame};
        let lesson = RunLearned {
            bv_id: "bv1".into(),
            prior_id: 41,
            stamp_ms: 5,
            aim: Target::new(2.0, Style::Rush).unwrap(),
            started_with_route: true,
            started_with_reaction: false,
            route: Some(LearnedRoute { step_m: 2.0, runs: 1, speeds_mps: vec![8.0, 7.0, 4.5] }),
            reaction: Some(LearnedReaction { probabilities: vec![0.25; 4], informative_cycles: 30 }),
        };
        let frame = learned_frame(&lesson).unwrap();
        let mut f = Fleet::default();
        let t0 = Instant::now();
        let change = f.on_message("v2t/pg/bv/bv1/learned", &frame, t0, 10).unwrap();
        assert_eq!(change, Change::Learned(lesson.clone()));
        assert!(learned_summary(&lesson).contains("the VUT's route to 4 m, its reaction identified"));
        // Under another BV's topic, or with a number out of bounds: not taken.
        assert!(f.on_message("v2t/pg/bv/bv2/learned", &frame, t0, 10).is_err());
        let mut bad = lesson.clone();
        bad.route.as_mut().unwrap().speeds_mps[1] = f64::NAN;
        let e = f.on_message("v2t/pg/bv/bv1/learned", &learned_frame(&bad).unwrap(), t0, 10).unwrap_err();
        assert!(e.to_string().contains("route.speeds_mps[1]"), "{e}");
        // The session log keeps it whole, as `campaign record --learned` reads it back.
        let line: serde_json::Value = serde_json::from_str(&log_line("v2t/pg/bv/bv1/learned", &frame, 12)).unwrap();
        let back: RunLearned = serde_json::from_value(line["message"].clone()).unwrap();
        assert_eq!((back, line["age_ms"].as_u64()), (lesson, Some(7)));
    }

    #[test]
    fn the_fleet_follows_heartbeats_telemetry_and_events() {
        let mut f = Fleet::default();
        let t0 = Instant::now();
        let beat = heartbeat_frame(&Heartbeat { bv_id: "bv1".into(), seq: 1, stamp_ms: 1, healthy: true }).unwrap();
        assert_eq!(f.on_message("v2t/pg/bv/bv1/heartbeat", &beat, t0, 10).unwrap(), Change::Online("bv1".into()));
        assert_eq!(f.on_message("v2t/pg/bv/bv1/heartbeat", &beat, t0, 10).unwrap(), Change::Quiet);
        let tel = telemetry_frame(&telemetry("bv1", 42)).unwrap();
        f.on_message("v2t/pg/bv/bv1/telemetry", &tel, t0, 10).unwrap();
        let table = f.table(t0);
        assert!(
            table.contains("bv1") && table.contains("online") && table.contains("42") && table.contains("2.50 s"),
            "{table}"
        );
        assert!(f.table(t0 + OFFLINE_AFTER).contains("OFFLINE"));
        assert_eq!(
            f.on_message("v2t/pg/bv/bv1/heartbeat", &beat, t0 + 2 * OFFLINE_AFTER, 10).unwrap(),
            Change::Online("bv1".into()),
            "back online after a silence"
        );
        let ev = br#"{"bv_id":"bv1","stamp_ms":5,"seq":7,"verdict":"refused","detail":"off the drivable area"}"#;
        match f.on_message("v2t/pg/bv/bv1/event", ev, t0, 10).unwrap() {
            Change::Event(e) => assert_eq!((e.seq, e.verdict.as_str()), (Some(7), "refused")),
            other => panic!("{other:?}"),
        }
        // Garbage, a report naming another BV and unknown topics are errors that change nothing.
        assert!(f.on_message("v2t/pg/bv/bv1/telemetry", b"garbage", t0, 10).is_err());
        let other = telemetry_frame(&telemetry("bv2", 1)).unwrap();
        assert!(f.on_message("v2t/pg/bv/bv1/telemetry", &other, t0, 10).is_err());
        assert!(f.on_message("v2t/pg/bv/bv1/secret", &beat, t0, 10).is_err());
        assert!(f.on_message("v2t/pg/bv1/heartbeat", &beat, t0, 10).is_err());
        assert_eq!(f.bvs.len(), 1);
        assert!(!f.table(t0).contains("LATE"));
    }

    /// bv1's telemetry `t` arriving at `at` (10 ms old), taken by the fleet.
    fn report(f: &mut Fleet, t: &Telemetry, at: Instant) {
        f.on_message("v2t/pg/bv/bv1/telemetry", &telemetry_frame(t).unwrap(), at, 10).unwrap();
    }

    #[test]
    fn the_fleet_table_says_when_tau_is_out_of_the_vuts_reach() {
        let mut f = Fleet::default();
        let t0 = Instant::now();
        report(&mut f, &telemetry("bv1", 42), t0);
        assert!(!f.table(t0).contains("BELOW"), "{}", f.table(t0));
        let below = Telemetry {
            seq: 2,
            below_reach: BelowReachCode::Campaign.code(),
            pet_bound_s: Some(2.04),
            ..telemetry("bv1", 42)
        };
        report(&mut f, &below, t0);
        assert!(f.table(t0).contains("BELOW: campaign 2.04 s"), "{}", f.table(t0));
        let waits = Telemetry { seq: 3, below_reach: BelowReachCode::VutWaits.code(), ..telemetry("bv1", 42) };
        report(&mut f, &waits, t0);
        assert!(f.table(t0).contains("BELOW: VUT waits"), "{}", f.table(t0));
        // An unknown code is shown as such, never as "nothing".
        let odd = Telemetry { seq: 4, below_reach: 77, ..telemetry("bv1", 42) };
        report(&mut f, &odd, t0);
        assert!(f.table(t0).contains("BELOW: ?77"), "{}", f.table(t0));
    }

    #[test]
    fn the_fleet_table_says_how_the_vuts_reaction_is_identified() {
        let mut f = Fleet::default();
        let t0 = Instant::now();
        report(&mut f, &telemetry("bv1", 42), t0);
        assert!(!f.table(t0).contains("±"), "{}", f.table(t0));
        let reaction = link::VutReaction { reacts_p: 0.93, gap_s: 2.1, gap_sd_s: 0.4 };
        let t = Telemetry { seq: 2, vut_reaction: Some(reaction), ..telemetry("bv1", 42) };
        report(&mut f, &t, t0);
        assert!(f.table(t0).contains("p 0.93, 2.1±0.4 s"), "{}", f.table(t0));
    }

    #[test]
    fn late_reports_are_marked_not_shown_as_current() {
        let mut f = Fleet::default();
        let t0 = Instant::now();
        let fresh = Telemetry { seq: 2, stamp_ms: 10_000, ..telemetry("bv1", 42) };
        f.on_message("v2t/pg/bv/bv1/telemetry", &telemetry_frame(&fresh).unwrap(), t0, 10_050).unwrap();
        assert!(!f.table(t0).contains("LATE"));
        // A burst of reports held back during an outage: older ones never replace newer ones, and
        // a late one is marked with its age.
        let older = Telemetry { seq: 1, stamp_ms: 9_000, speed_mps: 1.0, ..telemetry("bv1", 41) };
        f.on_message("v2t/pg/bv/bv1/telemetry", &telemetry_frame(&older).unwrap(), t0, 16_300).unwrap();
        assert_eq!(f.bvs["bv1"].telemetry.as_ref().unwrap().prior_id, 42);
        let late = Telemetry { seq: 3, stamp_ms: 10_100, ..telemetry("bv1", 43) };
        f.on_message("v2t/pg/bv/bv1/telemetry", &telemetry_frame(&late).unwrap(), t0, 16_400).unwrap();
        let table = f.table(t0);
        assert!(table.contains("LATE: 6.3 s old on arrival"), "{table}");
        // A late heartbeat does not bring a BV online.
        let beat = heartbeat_frame(&Heartbeat { bv_id: "bv1".into(), seq: 1, stamp_ms: 1_000, healthy: true }).unwrap();
        assert_eq!(f.on_message("v2t/pg/bv/bv1/heartbeat", &beat, t0, 16_400).unwrap(), Change::Quiet);
        assert!(f.table(t0).contains("OFFLINE"));
        assert!(
            log_line("v2t/pg/bv/bv1/telemetry", &telemetry_frame(&late).unwrap(), 16_400).contains("\"age_ms\":6300")
        );
    }

    #[test]
    fn console_lines_parse_or_say_why_not() {
        assert_eq!(parse_console("  ").unwrap(), None);
        assert_eq!(
            parse_console("abort").unwrap(),
            Some(ConsoleCommand::Send { bv: ALL_BVS.into(), command: Command::Abort })
        );
        assert_eq!(
            parse_console("start bv2").unwrap(),
            Some(ConsoleCommand::Send { bv: "bv2".into(), command: Command::Start })
        );
        assert_eq!(
            parse_console("target bv1 3.5 yield").unwrap(),
            Some(ConsoleCommand::Send {
                bv: "bv1".into(),
                command: Command::SetTarget(Target::new(3.5, Style::Yield).unwrap())
            })
        );
        assert_eq!(
            parse_console("upload p.json bv1 tau 2 style rush").unwrap(),
            Some(ConsoleCommand::Upload {
                file: "p.json".into(),
                bv: "bv1".into(),
                tau_s: Some(2.0),
                style: Some(Style::Rush),
                agent: None
            })
        );
        for bad in [
            "target bv1 x rush",
            "target bv1 3 fast",
            "target bv1 -1 rush",
            "upload p.json all",
            "upload p.json bv1 tau",
            "launch",
            "abort bv1 bv2",
        ] {
            assert!(parse_console(bad).is_err(), "{bad}");
        }
    }
}
