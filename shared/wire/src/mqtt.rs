//! The MQTT side of the cloud–edge link (feature `mqtt`), shared by the BV's uplink node and the
//! cloud supervisor: broker URLs, and a `rumqttc` client on its own thread that connects with a
//! persistent session, resubscribes after every (re)connection, reconnects with backoff and turns
//! everything into [`LinkEvent`]s on a channel. TLS is rustls with the ring provider.

use std::sync::mpsc;
use std::time::Duration;

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
        /// Its payload.
        payload: Vec<u8>,
    },
}

/// Reconnect backoff: 100 ms doubling to 5 s.
pub const BACKOFF_MIN: Duration = Duration::from_millis(100);
/// The longest wait between two connection attempts.
pub const BACKOFF_MAX: Duration = Duration::from_secs(5);

/// The MQTT client on its own thread.
pub struct MqttLink {
    client: rumqttc::Client,
    events: mpsc::Receiver<LinkEvent>,
}

impl std::fmt::Debug for MqttLink {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("MqttLink").finish_non_exhaustive()
    }
}

impl MqttLink {
    /// Starts the client; `subscribe` (QoS 1) is renewed after every (re)connection.
    pub fn start(s: &MqttSettings, subscribe: Vec<String>) -> Result<Self, MqttError> {
        let mut opts = rumqttc::MqttOptions::new(&s.client_id, &s.broker.host, s.broker.port);
        opts.set_keep_alive(Duration::from_secs(5));
        opts.set_clean_session(!s.persistent);
        opts.set_max_packet_size(MAX_FRAME_LEN + 1024, MAX_FRAME_LEN + 1024);
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
        let (tx, events) = mpsc::channel();
        let sub_client = client.clone();
        std::thread::Builder::new()
            .name("mqtt".into())
            .spawn(move || {
                let mut backoff = BACKOFF_MIN;
                // Subscriptions still to be requested after the last connection, and the
                // acknowledgements still awaited: `Connected` is reported once every one is
                // acknowledged, so a frame sent after it cannot miss this client. A request that
                // does not fit the queue (full of publications from before the drop) is retried
                // after the next event.
                let mut to_request: Vec<String> = Vec::new();
                let mut awaiting = 0usize;
                for notification in connection.iter() {
                    let event = match notification {
                        Ok(rumqttc::Event::Incoming(rumqttc::Packet::ConnAck(_))) => {
                            backoff = BACKOFF_MIN;
                            to_request.clone_from(&subscribe);
                            awaiting = subscribe.len();
                            (awaiting == 0).then_some(LinkEvent::Connected)
                        }
                        Ok(rumqttc::Event::Incoming(rumqttc::Packet::SubAck(_))) => {
                            awaiting = awaiting.saturating_sub(1);
                            (awaiting == 0 && to_request.is_empty()).then_some(LinkEvent::Connected)
                        }
                        Ok(rumqttc::Event::Incoming(rumqttc::Packet::Publish(p))) => {
                            Some(LinkEvent::Frame { topic: p.topic, payload: p.payload.to_vec() })
                        }
                        Ok(_) => None,
                        Err(e) => {
                            to_request.clear();
                            if tx.send(LinkEvent::Down(e.to_string())).is_err() {
                                return;
                            }
                            std::thread::sleep(backoff);
                            backoff = (backoff * 2).min(BACKOFF_MAX);
                            continue;
                        }
                    };
                    to_request.retain(|t| sub_client.try_subscribe(t.as_str(), rumqttc::QoS::AtLeastOnce).is_err());
                    if let Some(event) = event
                        && tx.send(event).is_err()
                    {
                        return;
                    }
                }
            })
            .map_err(|e| MqttError::Thread(e.to_string()))?;
        Ok(Self { client, events })
    }

    /// The next event, if any.
    pub fn poll(&self) -> Option<LinkEvent> {
        self.events.try_recv().ok()
    }

    /// The next event, waiting up to `timeout` for one.
    pub fn wait(&self, timeout: Duration) -> Option<LinkEvent> {
        self.events.recv_timeout(timeout).ok()
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
}
