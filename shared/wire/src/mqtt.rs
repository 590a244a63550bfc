//! The MQTT side of the cloud–edge link (feature `mqtt`), shared by the BV's uplink node and the
//! cloud supervisor: broker URLs, and a `rumqttc` client on its own thread that connects with a
//! persistent session, resubscribes after every (re)connection, reconnects with backoff and turns
//! everything into [`LinkEvent`]s in a bounded inbox ([`QueueLimits`]): connection events first, then frames of
//! the urgent lane (commands), then the bulk lane (priors, telemetry). A message longer than a frame
//! is read and dropped (the connection stays up), and a screen may refuse garbage on the client's
//! thread before it is queued, so a flood costs bounded memory and never delays a command behind
//! priors. TLS is rustls with the ring provider.

use std::collections::VecDeque;
use std::sync::{Arc, Condvar, Mutex};
use std::time::{Duration, Instant};

use crate::link::MAX_FRAME_LEN;

/// A broker address that is not one, or a client that cannot start or send.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum MqttError {
    /// The broker URL does not parse.
    #[error("`{url}`: {problem}")]
    Url {
        /// The URL given.
        url: String,
        /// What is wrong with it.
        problem: String,
    },
    /// `mqtts://` without a CA certificate.
    #[error("mqtts:// needs a CA certificate")]
    NoCa,
    /// The client thread could not be started.
    #[error("cannot start the MQTT thread: {0}")]
    Thread(String),
    /// A publication could not be queued (the queue is full while the broker is away, or closed).
    #[error("not queued: {0}")]
    Publish(String),
}

/// A broker address: `mqtt://host[:port]` (1883) or `mqtts://host[:port]` (8883).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct BrokerUrl {
    /// Host name or address.
    pub host: String,
    /// TCP port.
    pub port: u16,
    /// Whether TLS is on.
    pub tls: bool,
}

impl BrokerUrl {
    /// Parses `url`.
    pub fn parse(url: &str) -> Result<Self, MqttError> {
        let bad = |problem: String| MqttError::Url { url: url.to_owned(), problem };
        let (tls, rest) = if let Some(r) = url.strip_prefix("mqtts://") {
            (true, r)
        } else if let Some(r) = url.strip_prefix("mqtt://") {
            (false, r)
        } else {
            return Err(bad("must start with mqtt:// or mqtts://".into()));
        };
        let rest = rest.trim_end_matches('/');
        let (host, port) = match rest.rsplit_once(':') {
            Some((h, p)) => (h, p.parse::<u16>().map_err(|_| bad(format!("bad port `{p}`")))?),
            None => (rest, if tls { 8883 } else { 1883 }),
        };
        if host.is_empty() || host.contains('/') {
            return Err(bad("no host".into()));
        }
        Ok(Self { host: host.to_owned(), port, tls })
    }
}

/// How to reach and log in to the broker.
#[derive(Clone)]
pub struct MqttSettings {
    /// The broker.
    pub broker: BrokerUrl,
    /// MQTT client id (a persistent session is keyed on it).
    pub client_id: String,
    /// User name and password.
    pub credentials: Option<(String, String)>,
    /// CA certificate (PEM), required for `mqtts://`.
    pub ca_pem: Option<Vec<u8>>,
    /// Client certificate and key (PEM) for mutual TLS.
    pub client_auth: Option<(Vec<u8>, Vec<u8>)>,
    /// Keep the session (subscriptions, queued QoS 1 messages) across reconnections.
    pub persistent: bool,
}

impl std::fmt::Debug for MqttSettings {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("MqttSettings")
            .field("broker", &self.broker)
            .field("client_id", &self.client_id)
            .field("user", &self.credentials.as_ref().map(|c| &c.0))
            .field("tls_ca", &self.ca_pem.is_some())
            .field("client_auth", &self.client_auth.is_some())
            .field("persistent", &self.persistent)
            .finish_non_exhaustive()
    }
}

/// What the MQTT thread reports.
#[derive(Debug)]
pub enum LinkEvent {
    /// Connected (again) and every subscription acknowledged.
    Connected,
    /// The connection failed or dropped; the thread retries after a backoff.
    Down(String),
    /// A message on one of the subscribed topics.
    Frame {
        /// Its topic.
        topic: String,
        /// Its payload (never longer than [`MAX_FRAME_LEN`]).
        payload: Vec<u8>,
        /// When the MQTT thread received it, Unix time in ms.
        arrived_ms: u64,
    },
}

/// Reconnect backoff: 100 ms doubling to 5 s.
pub const BACKOFF_MIN: Duration = Duration::from_millis(100);
/// The longest wait between two connection attempts.
pub const BACKOFF_MAX: Duration = Duration::from_secs(5);

/// The largest MQTT packet the client reads (the protocol's own maximum). A message larger than a
/// frame is read and dropped rather than refused at the socket: refusing it would drop the
/// connection, and a persistent session would deliver it again on every reconnect.
pub const MAX_INCOMING_PACKET: usize = 268_435_455;

/// Which queue a received message waits in. Urgent messages (a BV's commands) are handed out
/// before bulk ones (priors, reports) however many bulk ones wait.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Lane {
    /// Handed out first; when full, new messages are dropped (and counted).
    Urgent,
    /// Handed out when no urgent message waits; when full, the oldest is dropped (and counted).
    Bulk,
}

/// One subscription of the client.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Subscription {
    /// The topic filter.
    pub topic: String,
    /// QoS 1: the broker keeps what the client has not acknowledged (also across a reconnect with a
    /// persistent session), in a queue of bounded length that a flood can fill, after which it
    /// drops new messages for this client, good ones among them. QoS 0: the broker hands every
    /// message over as it comes and queues nothing; the sender repeats what it needs answered.
    pub reliable: bool,
}

impl Subscription {
    /// A QoS 1 subscription.
    pub fn reliable(topic: String) -> Self {
        Self { topic, reliable: true }
    }

    /// A QoS 0 subscription.
    pub fn at_most_once(topic: String) -> Self {
        Self { topic, reliable: false }
    }

    fn qos(&self) -> rumqttc::QoS {
        if self.reliable { rumqttc::QoS::AtLeastOnce } else { rumqttc::QoS::AtMostOnce }
    }
}

/// How much each queue holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct QueueLimits {
    /// Messages in the urgent queue.
    pub urgent_messages: usize,
    /// Payload bytes in the urgent queue.
    pub urgent_bytes: usize,
    /// Messages in the bulk queue.
    pub bulk_messages: usize,
    /// Payload bytes in the bulk queue.
    pub bulk_bytes: usize,
}

impl Default for QueueLimits {
    /// 4,096 urgent messages in 4 MiB, 256 bulk messages in 8 MiB.
    fn default() -> Self {
        Self { urgent_messages: 4096, urgent_bytes: 4 << 20, bulk_messages: 256, bulk_bytes: 8 << 20 }
    }
}

/// Messages the MQTT thread did not queue, since the last [`MqttLink::take_dropped`].
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct Dropped {
    /// Longer than [`MAX_FRAME_LEN`].
    pub oversize: u64,
    /// The urgent queue was full.
    pub urgent_full: u64,
    /// The bulk queue was full (the oldest went).
    pub bulk_full: u64,
    /// Refused by the owner's screen, by reason.
    pub screened: std::collections::BTreeMap<&'static str, u64>,
}

impl Dropped {
    /// Whether nothing was dropped.
    pub fn is_empty(&self) -> bool {
        *self == Self::default()
    }
}

/// What the owner of a link does with a received message before it is queued: the lane it waits
/// in, or the reason it is dropped on the MQTT thread (cheap checks only: this runs for every
/// message a flood brings).
pub type Screen = dyn Fn(&str, &[u8]) -> Result<Lane, &'static str> + Send;

#[derive(Debug, Default)]
struct Queues {
    control: VecDeque<LinkEvent>,
    urgent: VecDeque<LinkEvent>,
    urgent_bytes: usize,
    bulk: VecDeque<LinkEvent>,
    bulk_bytes: usize,
    dropped: Dropped,
    closed: bool,
}

fn payload_len(e: &LinkEvent) -> usize {
    match e {
        LinkEvent::Frame { payload, .. } => payload.len(),
        _ => 0,
    }
}

/// The queues between the MQTT thread and its owner: bounded, with priority.
#[derive(Debug, Default)]
struct Inbox {
    queues: Mutex<Queues>,
    ready: Condvar,
    limits: QueueLimits,
}

impl Inbox {
    fn lock(&self) -> std::sync::MutexGuard<'_, Queues> {
        self.queues.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
    }

    fn control(&self, e: LinkEvent) {
        self.lock().control.push_back(e);
        self.ready.notify_one();
    }

    fn frame(&self, screen: &Screen, topic: String, payload: Vec<u8>) {
        if payload.len() > MAX_FRAME_LEN {
            self.lock().dropped.oversize += 1;
            return;
        }
        let lane = match screen(&topic, &payload) {
            Ok(lane) => lane,
            Err(reason) => {
                *self.lock().dropped.screened.entry(reason).or_default() += 1;
                return;
            }
        };
        let mut q = self.lock();
        let n = payload.len();
        let e = LinkEvent::Frame { topic, payload, arrived_ms: unix_ms() };
        match lane {
            Lane::Urgent => {
                if q.urgent.len() >= self.limits.urgent_messages || q.urgent_bytes + n > self.limits.urgent_bytes {
                    q.dropped.urgent_full += 1;
                    return;
                }
                q.urgent_bytes += n;
                q.urgent.push_back(e);
            }
            Lane::Bulk => {
                while !q.bulk.is_empty()
                    && (q.bulk.len() >= self.limits.bulk_messages || q.bulk_bytes + n > self.limits.bulk_bytes)
                {
                    if let Some(old) = q.bulk.pop_front() {
                        q.bulk_bytes -= payload_len(&old);
                        q.dropped.bulk_full += 1;
                    }
                }
                q.bulk_bytes += n;
                q.bulk.push_back(e);
            }
        }
        drop(q);
        self.ready.notify_one();
    }

    fn next(q: &mut Queues) -> Option<LinkEvent> {
        if let Some(e) = q.control.pop_front() {
            return Some(e);
        }
        if let Some(e) = q.urgent.pop_front() {
            q.urgent_bytes -= payload_len(&e);
            return Some(e);
        }
        let e = q.bulk.pop_front()?;
        q.bulk_bytes -= payload_len(&e);
        Some(e)
    }

    fn wait(&self, timeout: Duration) -> Option<LinkEvent> {
        let deadline = Instant::now() + timeout;
        let mut q = self.lock();
        loop {
            if let Some(e) = Self::next(&mut q) {
                return Some(e);
            }
            let left = deadline.checked_duration_since(Instant::now()).filter(|d| !d.is_zero())?;
            if q.closed {
                return None;
            }
            q = self.ready.wait_timeout(q, left).map_or_else(|p| p.into_inner().0, |(g, _)| g);
        }
    }
}

/// Unix time, ms.
fn unix_ms() -> u64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| u64::try_from(d.as_millis()).unwrap_or(u64::MAX))
}

/// The MQTT client on its own thread. What it receives waits in bounded queues: control events
/// first, then urgent messages, then bulk ones ([`Lane`]); a message longer than a frame is
/// dropped unread by anyone and counted, never a reason to drop the connection.
pub struct MqttLink {
    client: rumqttc::Client,
    inbox: Arc<Inbox>,
}

impl std::fmt::Debug for MqttLink {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("MqttLink").finish_non_exhaustive()
    }
}

impl MqttLink {
    /// Starts the client; `subscribe` (QoS 1) is renewed after every (re)connection; every
    /// received message is bulk.
    pub fn start(s: &MqttSettings, subscribe: Vec<String>) -> Result<Self, MqttError> {
        let subscribe = subscribe.into_iter().map(Subscription::reliable).collect();
        Self::start_screened(s, subscribe, Box::new(|_, _| Ok(Lane::Bulk)), QueueLimits::default())
    }

    /// [`MqttLink::start`] with a QoS per subscription, every message screened by `screen` on the
    /// MQTT thread (its lane, or dropped and counted), and these queue limits.
    pub fn start_screened(
        s: &MqttSettings,
        subscribe: Vec<Subscription>,
        screen: Box<Screen>,
        limits: QueueLimits,
    ) -> Result<Self, MqttError> {
        let mut opts = rumqttc::MqttOptions::new(&s.client_id, &s.broker.host, s.broker.port);
        opts.set_keep_alive(Duration::from_secs(5));
        opts.set_clean_session(!s.persistent);
        opts.set_max_packet_size(MAX_INCOMING_PACKET, MAX_FRAME_LEN + 1024);
        if let Some((user, password)) = &s.credentials {
            opts.set_credentials(user, password);
        }
        if s.broker.tls {
            // The process-wide rustls provider (ring); a second install in one process is harmless.
            let _ = rustls::crypto::ring::default_provider().install_default();
            let ca = s.ca_pem.clone().ok_or(MqttError::NoCa)?;
            opts.set_transport(rumqttc::Transport::Tls(rumqttc::TlsConfiguration::Simple {
                ca,
                alpn: None,
                client_auth: s.client_auth.clone(),
            }));
        }
        let (client, mut connection) = rumqttc::Client::new(opts, 256);
        // No Nagle: a command must not wait for the acknowledgement of the last small packet.
        let mut net = rumqttc::NetworkOptions::new();
        net.set_tcp_nodelay(true);
        connection.eventloop.set_network_options(net);
        let inbox = Arc::new(Inbox { limits, ..Inbox::default() });
        let sub_client = client.clone();
        let thread_inbox = Arc::clone(&inbox);
        std::thread::Builder::new()
            .name("mqtt".into())
            .spawn(move || {
                let inbox = thread_inbox;
                let mut backoff = BACKOFF_MIN;
                // Subscriptions still to be requested after the last connection, and the
                // acknowledgements still awaited: `Connected` is reported once every one is
                // acknowledged, so a frame sent after it cannot miss this client. A request that
                // does not fit the queue (full of publications from before the drop) is retried
                // after the next event.
                let mut to_request: Vec<Subscription> = Vec::new();
                let mut awaiting = 0usize;
                for notification in connection.iter() {
                    if Arc::strong_count(&inbox) == 1 {
                        return;
                    }
                    match notification {
                        Ok(rumqttc::Event::Incoming(rumqttc::Packet::ConnAck(_))) => {
                            backoff = BACKOFF_MIN;
                            to_request.clone_from(&subscribe);
                            awaiting = subscribe.len();
                            if awaiting == 0 {
                                inbox.control(LinkEvent::Connected);
                            }
                        }
                        Ok(rumqttc::Event::Incoming(rumqttc::Packet::SubAck(_))) => {
                            awaiting = awaiting.saturating_sub(1);
                            if awaiting == 0 && to_request.is_empty() {
                                inbox.control(LinkEvent::Connected);
                            }
                        }
                        Ok(rumqttc::Event::Incoming(rumqttc::Packet::Publish(p))) => {
                            inbox.frame(&*screen, p.topic, p.payload.to_vec());
                        }
                        Ok(_) => {}
                        Err(e) => {
                            to_request.clear();
                            inbox.control(LinkEvent::Down(e.to_string()));
                            std::thread::sleep(backoff);
                            backoff = (backoff * 2).min(BACKOFF_MAX);
                            continue;
                        }
                    }
                    to_request.retain(|t| sub_client.try_subscribe(t.topic.as_str(), t.qos()).is_err());
                }
                inbox.lock().closed = true;
            })
            .map_err(|e| MqttError::Thread(e.to_string()))?;
        Ok(Self { client, inbox })
    }

    /// The next event, if any (control events, then urgent messages, then bulk ones).
    pub fn poll(&self) -> Option<LinkEvent> {
        Inbox::next(&mut self.inbox.lock())
    }

    /// The next event, waiting up to `timeout` for one.
    pub fn wait(&self, timeout: Duration) -> Option<LinkEvent> {
        self.inbox.wait(timeout)
    }

    /// Messages dropped since the last call (oversize, queues full), and resets the counts.
    pub fn take_dropped(&self) -> Dropped {
        std::mem::take(&mut self.inbox.lock().dropped)
    }

    /// Queues a publication: QoS 1 when `reliable`, else QoS 0. A full queue while the broker is
    /// away is reported, not fatal.
    pub fn publish(&self, topic: &str, payload: Vec<u8>, reliable: bool) -> Result<(), MqttError> {
        let qos = if reliable { rumqttc::QoS::AtLeastOnce } else { rumqttc::QoS::AtMostOnce };
        self.client.try_publish(topic, qos, false, payload).map_err(|e| MqttError::Publish(e.to_string()))
    }

    /// Asks the broker for a clean disconnect (after what is queued).
    pub fn disconnect(&self) {
        let _ = self.client.try_disconnect();
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    #[test]
    fn broker_urls_name_scheme_host_and_port() {
        assert_eq!(
            BrokerUrl::parse("mqtt://127.0.0.1:1884").unwrap(),
            BrokerUrl { host: "127.0.0.1".into(), port: 1884, tls: false }
        );
        assert_eq!(BrokerUrl::parse("mqtts://broker.track").unwrap().port, 8883);
        assert_eq!(BrokerUrl::parse("mqtt://broker/").unwrap().port, 1883);
        for bad in ["tcp://x:1", "mqtt://", "mqtt://:1883", "mqtt://h:99999", "mqtt://h:x", "mqtt://a/b:1"] {
            assert!(BrokerUrl::parse(bad).is_err(), "{bad}");
        }
    }

    fn inbox(limits: QueueLimits) -> Inbox {
        Inbox { limits, ..Inbox::default() }
    }

    fn topic_of(e: Option<LinkEvent>) -> String {
        match e {
            Some(LinkEvent::Frame { topic, .. }) => topic,
            Some(LinkEvent::Connected) => "connected".into(),
            other => format!("{other:?}"),
        }
    }

    #[test]
    fn control_then_urgent_then_bulk_and_every_queue_is_bounded() {
        let limits = QueueLimits { urgent_messages: 2, urgent_bytes: 100, bulk_messages: 2, bulk_bytes: 100 };
        let i = inbox(limits);
        let screen = |t: &str, p: &[u8]| match (t.starts_with("cmd"), p.first()) {
            (_, Some(0xff)) => Err("garbage"),
            (true, _) => Ok(Lane::Urgent),
            (false, _) => Ok(Lane::Bulk),
        };
        for k in 0..4 {
            i.frame(&screen, format!("bulk{k}"), vec![0; 10]);
        }
        for k in 0..3 {
            i.frame(&screen, format!("cmd{k}"), vec![0; 10]);
        }
        i.frame(&screen, "cmd-garbage".into(), vec![0xff; 10]);
        i.control(LinkEvent::Connected);
        i.frame(&screen, "cmd-big".into(), vec![0; MAX_FRAME_LEN + 1]);
        let order: Vec<String> = (0..5).map(|_| topic_of(i.wait(Duration::ZERO))).collect();
        assert_eq!(order, ["connected", "cmd0", "cmd1", "bulk2", "bulk3"]);
        assert!(i.wait(Duration::from_millis(1)).is_none());
        let d = std::mem::take(&mut i.lock().dropped);
        let screened = [("garbage", 1)].into_iter().collect();
        assert_eq!(d, Dropped { oversize: 1, urgent_full: 1, bulk_full: 2, screened }, "new commands and old bulk go");
        // Bytes bound the queues too.
        i.frame(&screen, "a".into(), vec![0; 60]);
        i.frame(&screen, "b".into(), vec![0; 60]);
        assert_eq!(topic_of(i.wait(Duration::ZERO)), "b");
        assert_eq!(i.lock().bulk_bytes, 0);
    }

    #[test]
    fn a_waiter_wakes_when_a_message_arrives() {
        let i = Arc::new(inbox(QueueLimits::default()));
        let sender = Arc::clone(&i);
        let t = std::thread::spawn(move || {
            std::thread::sleep(Duration::from_millis(30));
            sender.frame(&|_: &str, _: &[u8]| Ok(Lane::Urgent), "cmd".into(), vec![1]);
        });
        let started = Instant::now();
        assert_eq!(topic_of(i.wait(Duration::from_secs(5))), "cmd");
        assert!(started.elapsed() < Duration::from_secs(2));
        t.join().unwrap();
    }
}
