//! The supervisor's Ed25519 key pair, signing with sequence numbers that keep increasing across
//! processes and restarts, priors read from files, and one-shot publication (`video2track upload`,
//! `video2track send`) that waits for the BV's verdict.

use std::io::Read as _;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use v2t_files::InputError;
use v2t_model::{Style, Target, TargetError};
use v2t_wire::link::{
    self, ALL_BVS, CloudBody, CloudMessage, Command, PriorUpload, SigningKey, VerifyingKey, key_from_hex, key_to_hex,
    topics,
};
use v2t_wire::mqtt::{BrokerUrl, LinkEvent, MqttLink, MqttSettings};

/// A failure of the link's cloud side.
#[derive(Debug, thiserror::Error)]
pub enum LinkError {
    /// A key file could not be read, written or understood.
    #[error("{path}: {message}")]
    Key {
        /// The file.
        path: PathBuf,
        /// Why.
        message: String,
    },
    /// A prior file could not be read or used.
    #[error(transparent)]
    Prior(#[from] InputError),
    /// The prior file has no such BV agent.
    #[error("{path}: {source}")]
    Agent {
        /// The file.
        path: PathBuf,
        /// Why.
        source: v2t_model::validate::ValidationError,
    },
    /// τ or the style given is not a target.
    #[error(transparent)]
    Target(#[from] TargetError),
    /// A bad argument (broker URL, id, τ).
    #[error("{0}")]
    Usage(String),
    /// The broker URL is not one.
    #[error(transparent)]
    Url(v2t_wire::mqtt::MqttError),
    /// The broker could not be reached, or the frame not sent.
    #[error("broker: {0}")]
    Broker(String),
    /// A frame could not be made.
    #[error("frame: {0}")]
    Frame(#[from] link::LinkError),
    /// The BV refused it, or did not answer.
    #[error("{0}")]
    Refused(String),
}

impl From<v2t_wire::mqtt::MqttError> for LinkError {
    fn from(e: v2t_wire::mqtt::MqttError) -> Self {
        match e {
            v2t_wire::mqtt::MqttError::Url { .. } => Self::Url(e),
            other => Self::Broker(other.to_string()),
        }
    }
}

/// Unix time, µs.
fn unix_us() -> u64 {
    SystemTime::now().duration_since(UNIX_EPOCH).map_or(0, |d| u64::try_from(d.as_micros()).unwrap_or(u64::MAX))
}

/// Unix time, ms.
pub fn unix_ms() -> u64 {
    unix_us() / 1000
}

/// Writes a new key pair as `dir/cloud.key` (the secret seed, mode 0600) and `dir/cloud.pub` (the
/// public key every BV's edge config names); refuses to overwrite either. Returns the public key.
pub fn keygen(dir: &Path) -> Result<VerifyingKey, LinkError> {
    let bad = |path: &Path, message: String| LinkError::Key { path: path.to_owned(), message };
    std::fs::create_dir_all(dir).map_err(|e| bad(dir, e.to_string()))?;
    let (secret, public) = (dir.join("cloud.key"), dir.join("cloud.pub"));
    for p in [&secret, &public] {
        if p.exists() {
            return Err(bad(p, "exists already; remove it first to replace the key pair".into()));
        }
    }
    let mut seed = [0u8; 32];
    std::fs::File::open("/dev/urandom")
        .and_then(|mut f| f.read_exact(&mut seed))
        .map_err(|e| bad(Path::new("/dev/urandom"), e.to_string()))?;
    let key = SigningKey::from_bytes(&seed);
    write_private(&secret, &format!("{}\n", key_to_hex(&seed))).map_err(|e| bad(&secret, e.to_string()))?;
    let vk = key.verifying_key();
    std::fs::write(&public, format!("{}\n", key_to_hex(vk.as_bytes()))).map_err(|e| bad(&public, e.to_string()))?;
    Ok(vk)
}

fn write_private(path: &Path, text: &str) -> std::io::Result<()> {
    use std::io::Write as _;
    use std::os::unix::fs::OpenOptionsExt as _;
    let mut f = std::fs::OpenOptions::new().write(true).create_new(true).mode(0o600).open(path)?;
    f.write_all(text.as_bytes())
}

/// Reads the supervisor's secret key (64 hex digits).
pub fn load_signing_key(path: &Path) -> Result<SigningKey, LinkError> {
    let bad = |message: String| LinkError::Key { path: path.to_owned(), message };
    let text = std::fs::read_to_string(path).map_err(|e| bad(e.to_string()))?;
    key_from_hex(&text).map(|seed| SigningKey::from_bytes(&seed)).map_err(bad)
}

pub use v2t_wire::link::DEMO_PUBLIC_KEY;

/// Whether `key` is the committed demo key, which must never sign for a real vehicle.
pub fn is_demo_key(key: &SigningKey) -> bool {
    key_to_hex(key.verifying_key().as_bytes()) == DEMO_PUBLIC_KEY
}

/// Signs cloud messages for one fleet. Sequence numbers are the Unix time in µs, or one more than
/// the last when the clock has not moved on: they keep increasing across `upload`, `command` and a
/// restarted `serve` signing with the same key, which is what a BV's replay check needs.
#[derive(Debug)]
pub struct Signer {
    key: SigningKey,
    fleet: String,
    last_seq: u64,
}

impl Signer {
    /// A signer for `fleet`.
    pub fn new(key: SigningKey, fleet: &str) -> Result<Self, LinkError> {
        if !topics::valid_id(fleet) {
            return Err(LinkError::Usage(format!("fleet `{fleet}`: use 1–64 ASCII letters, digits, '_' or '-'")));
        }
        Ok(Self { key, fleet: fleet.to_owned(), last_seq: 0 })
    }

    /// The fleet.
    pub fn fleet(&self) -> &str {
        &self.fleet
    }

    /// Seals `body` for `bv_id` (or [`ALL_BVS`]); returns the topic, the frame and its sequence number.
    pub fn seal(&mut self, bv_id: &str, body: CloudBody) -> Result<(String, Vec<u8>, u64), LinkError> {
        let topic = if bv_id == ALL_BVS {
            topics::all_cmd(&self.fleet)
        } else if topics::valid_id(bv_id) {
            // What belongs to one BV's run travels with its priors; commands on their own topic.
            let leaf =
                if matches!(body, CloudBody::Prior(_) | CloudBody::Campaign(_)) { topics::PRIOR } else { topics::CMD };
            topics::bv(&self.fleet, bv_id, leaf)
        } else {
            return Err(LinkError::Usage(format!("BV id `{bv_id}`: use 1–64 ASCII letters, digits, '_' or '-'")));
        };
        if bv_id == ALL_BVS && matches!(body, CloudBody::Prior(_)) {
            return Err(LinkError::Usage("a prior goes to one BV, not to all".into()));
        }
        if bv_id == ALL_BVS && matches!(body, CloudBody::Campaign(_)) {
            return Err(LinkError::Usage("what a test learned goes to the BV that runs it, not to all".into()));
        }
        let seq = unix_us().max(self.last_seq + 1);
        self.last_seq = seq;
        let msg = CloudMessage { fleet: self.fleet.clone(), bv_id: bv_id.to_owned(), seq, issued_ms: unix_ms(), body };
        Ok((topic, link::seal(&msg, &self.key)?, seq))
    }
}

/// Turns a priors file into the upload for one BV: a `TrajectoryPrior` (the generator's output) or
/// a `GroundedScenario` (then its constant-speed stand-in prior along the grounded routes).
/// `agent` picks the BV agent it drives (default: the first BV); `tau_s` and `style` override the
/// file's target.
pub fn prior_from_file(
    path: &Path,
    agent: Option<&str>,
    target: (Option<f64>, Option<Style>),
    valid_s: f64,
    prior_id: u64,
) -> Result<PriorUpload, LinkError> {
    let mut prior = v2t_files::read_prior_or_grounded(path)?.into_prior();
    let bv_agent =
        prior.bv_agent(agent).map_err(|source| LinkError::Agent { path: path.to_owned(), source })?.id.clone();
    let mut t = prior.target;
    if let Some(tau) = target.0 {
        t = t.with_tau(tau)?;
    }
    if let Some(style) = target.1 {
        t = t.with_style(style);
    }
    prior.target = t;
    if !(valid_s > 0.0 && valid_s <= 86_400.0) {
        return Err(LinkError::Usage(format!("--valid-s must lie in (0, 86400] s, got {valid_s}")));
    }
    let now = unix_ms();
    Ok(PriorUpload { prior_id, bv_agent, valid_from_ms: now, valid_until_ms: now + (valid_s * 1e3) as u64, prior })
}

/// Where the cloud's client connects and how it logs in.
#[derive(Debug, Clone)]
pub struct Connection {
    /// `mqtt://…` or `mqtts://…`.
    pub broker: BrokerUrl,
    /// User name and password.
    pub credentials: Option<(String, String)>,
    /// CA certificate (PEM) for `mqtts://`.
    pub ca_pem: Option<Vec<u8>>,
    /// Client certificate and key (PEM) for mutual TLS.
    pub client_auth: Option<(Vec<u8>, Vec<u8>)>,
}

/// Where the supervisor's TLS files are: CA, and the client certificate and key for mutual TLS.
#[derive(Debug, Clone, Copy, Default)]
pub struct TlsFiles<'a> {
    /// CA certificate (PEM).
    pub ca: Option<&'a Path>,
    /// Client certificate (PEM).
    pub client_cert: Option<&'a Path>,
    /// Client key (PEM).
    pub client_key: Option<&'a Path>,
}

impl Connection {
    /// From the command line's `--broker`, `--username`, `--password-env` and TLS files.
    pub fn new(
        broker: &str,
        username: Option<&str>,
        password_env: Option<&str>,
        tls: TlsFiles<'_>,
    ) -> Result<Self, LinkError> {
        let broker = BrokerUrl::parse(broker).map_err(LinkError::Url)?;
        let credentials = match username {
            Some(u) => {
                let password = match password_env {
                    Some(var) => std::env::var(var)
                        .map_err(|_| LinkError::Usage(format!("the password variable {var} is not set")))?,
                    None => String::new(),
                };
                Some((u.to_owned(), password))
            }
            None => None,
        };
        let read = |p: &Path| std::fs::read(p).map_err(|e| LinkError::Usage(format!("{}: {e}", p.display())));
        let ca_pem = tls.ca.map(read).transpose()?;
        let client_auth = match (tls.client_cert, tls.client_key) {
            (Some(c), Some(k)) => Some((read(c)?, read(k)?)),
            (None, None) => None,
            _ => return Err(LinkError::Usage("--client-cert and --client-key go together".into())),
        };
        if broker.tls && ca_pem.is_none() {
            return Err(LinkError::Usage("an mqtts:// broker needs --ca-file".into()));
        }
        if !broker.tls && (ca_pem.is_some() || client_auth.is_some()) {
            return Err(LinkError::Usage("certificates need an mqtts:// broker".into()));
        }
        Ok(Self { broker, credentials, ca_pem, client_auth })
    }

    /// The client settings for `client_id`.
    pub fn settings(&self, client_id: &str, persistent: bool) -> MqttSettings {
        MqttSettings {
            broker: self.broker.clone(),
            client_id: client_id.to_owned(),
            credentials: self.credentials.clone(),
            ca_pem: self.ca_pem.clone(),
            client_auth: self.client_auth.clone(),
            persistent,
        }
    }
}

/// What a BV said about one frame (its `event` message).
#[derive(Debug, Clone, PartialEq, serde::Deserialize, serde::Serialize)]
pub struct BvEvent {
    /// The BV.
    pub bv_id: String,
    /// When, Unix ms.
    pub stamp_ms: u64,
    /// The frame's sequence number, for a genuine frame of the cloud (signature checked); `None` in
    /// the BV's summary of the frames it refused without one (garbage, other keys, other fleets).
    pub seq: Option<u64>,
    /// `accepted` or `refused`.
    pub verdict: String,
    /// What, or why not.
    pub detail: String,
    /// In a summary: refused frames per reason.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub counts: Option<std::collections::BTreeMap<String, u64>>,
}

/// A frame is sent again this often until the BV's verdict on one of its copies arrives: the BV
/// takes cloud frames at QoS 0 (a flood cannot then push them out of a broker queue), so a copy can
/// be lost on the way; each copy is sealed anew, with its own sequence number.
pub const RESEND_EVERY: Duration = Duration::from_millis(250);
/// Copies of a frame to every BV, which no single verdict answers.
pub const ALL_BVS_COPIES: usize = 3;

/// Publishes one sealed frame and, unless `wait` is zero, waits for the BV's verdict on it, sending
/// a new copy every [`RESEND_EVERY`] until one arrives. A frame to [`ALL_BVS`] is sent
/// [`ALL_BVS_COPIES`] times and nothing is awaited.
pub fn send_once(
    conn: &Connection,
    signer: &mut Signer,
    bv_id: &str,
    body: CloudBody,
    wait: Duration,
) -> Result<Option<BvEvent>, LinkError> {
    let fleet = signer.fleet().to_owned();
    let event_topic = topics::bv(&fleet, bv_id, topics::EVENT);
    let awaits = bv_id != ALL_BVS && !wait.is_zero();
    let subscribe = if awaits { vec![event_topic] } else { Vec::new() };
    let client_id = format!("v2t-{fleet}-cli-{}", std::process::id());
    let mqtt = MqttLink::start(&conn.settings(&client_id, false), subscribe).map_err(LinkError::from)?;
    let deadline = Instant::now() + Duration::from_secs(5);
    loop {
        match mqtt.wait(deadline.saturating_duration_since(Instant::now())) {
            Some(LinkEvent::Connected) => break,
            Some(LinkEvent::Down(why)) => return Err(LinkError::Broker(why)),
            Some(LinkEvent::Frame { .. }) => {}
            None => return Err(LinkError::Broker("no connection within 5 s".into())),
        }
    }
    // `Connected` comes once the event subscription is acknowledged: the BV's answer cannot miss it.
    let mut sent = Vec::new();
    let send_copy = |signer: &mut Signer, sent: &mut Vec<u64>| -> Result<(), LinkError> {
        let (topic, frame, seq) = signer.seal(bv_id, body.clone())?;
        mqtt.publish(&topic, frame, true)?;
        sent.push(seq);
        Ok(())
    };
    send_copy(signer, &mut sent)?;
    let answer = if awaits {
        let deadline = Instant::now() + wait;
        let mut next_copy = Instant::now() + RESEND_EVERY;
        // The BV's summaries of frames it refused without a verdict (another key, another fleet):
        // what to say when no verdict comes.
        let mut summary: Option<BvEvent> = None;
        loop {
            if Instant::now() >= next_copy {
                send_copy(signer, &mut sent)?;
                next_copy += RESEND_EVERY;
            }
            let until = deadline.min(next_copy).saturating_duration_since(Instant::now());
            match mqtt.wait(until) {
                Some(LinkEvent::Frame { payload, .. }) => {
                    // Only a verdict on one of these copies: the BV reports every genuine frame with
                    // its sequence number, and summarizes everything else without one.
                    let Ok(ev) = serde_json::from_slice::<BvEvent>(&payload) else { continue };
                    if ev.seq.is_some_and(|s| sent.contains(&s)) {
                        break Some(ev);
                    }
                    if ev.seq.is_none() {
                        summary = Some(ev);
                    }
                }
                Some(_) => {}
                None if Instant::now() < deadline => {}
                None => {
                    mqtt.disconnect();
                    let why = match summary {
                        Some(s) => format!(
                            "; it refused frames it could not verify meanwhile ({}): is the key the one it trusts, \
                             the fleet its own?",
                            s.detail
                        ),
                        None => format!(
                            " (is its uplink node running and connected to {}:{}?)",
                            conn.broker.host, conn.broker.port
                        ),
                    };
                    return Err(LinkError::Refused(format!(
                        "{bv_id} gave no verdict on {} copies within {:.1} s{why}",
                        sent.len(),
                        wait.as_secs_f64()
                    )));
                }
            }
        }
    } else {
        for _ in 1..ALL_BVS_COPIES {
            std::thread::sleep(Duration::from_millis(100));
            send_copy(signer, &mut sent)?;
        }
        // Let the QoS 1 publication leave before the client goes.
        std::thread::sleep(Duration::from_millis(200));
        None
    };
    mqtt.disconnect();
    std::thread::sleep(Duration::from_millis(20));
    Ok(answer)
}

/// A supervision command from its words: `arm`, `start`, `abort`, or `target` with τ and style.
pub fn command(action: &str, tau_s: Option<f64>, style: Option<Style>) -> Result<Command, LinkError> {
    match action {
        "arm" => Ok(Command::Arm),
        "start" => Ok(Command::Start),
        "abort" => Ok(Command::Abort),
        "target" => {
            let tau_s = tau_s.ok_or_else(|| LinkError::Usage("target needs --tau".into()))?;
            let style = style.ok_or_else(|| LinkError::Usage("target needs --style rush|yield".into()))?;
            Ok(Command::SetTarget(Target::new(tau_s, style)?))
        }
        other => Err(LinkError::Usage(format!("unknown command `{other}`: arm, start, abort or target"))),
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing)]
    use super::*;
    use v2t_wire::link::{Receiver, Window};

    /// A path that does not exist yet, in a scratch folder removed when the guard drops.
    fn tempdir(name: &str) -> (tempfile::TempDir, PathBuf) {
        let scratch = tempfile::Builder::new().prefix(&format!("v2t-cli-link-{name}-")).tempdir().unwrap();
        let d = scratch.path().join("keys");
        (scratch, d)
    }

    #[test]
    fn keygen_writes_a_pair_the_edge_reads_and_refuses_to_overwrite() {
        let (_scratch, dir) = tempdir("keygen");
        let vk = keygen(&dir).unwrap();
        let sk = load_signing_key(&dir.join("cloud.key")).unwrap();
        assert_eq!(sk.verifying_key(), vk);
        let public = std::fs::read_to_string(dir.join("cloud.pub")).unwrap();
        assert_eq!(key_from_hex(&public).unwrap(), *vk.as_bytes());
        use std::os::unix::fs::PermissionsExt as _;
        let mode = std::fs::metadata(dir.join("cloud.key")).unwrap().permissions().mode();
        assert_eq!(mode & 0o077, 0, "the secret key is readable by others: {mode:o}");
        assert!(matches!(keygen(&dir), Err(LinkError::Key { .. })));
        assert!(!is_demo_key(&sk));
        std::fs::write(dir.join("bad.key"), "not hex").unwrap();
        assert!(load_signing_key(&dir.join("bad.key")).is_err());
    }

    #[test]
    fn sequence_numbers_keep_increasing_across_signers_and_bvs_accept_them() {
        let key = SigningKey::from_bytes(&[9; 32]);
        let mut rx = Receiver::new(key.verifying_key(), "pg", "bv1", Window { max_age_ms: 10_000, max_skew_ms: 1_000 });
        let mut last = 0;
        for round in 0..3 {
            // A new signer per round, as a new `upload` process or a restarted `serve` would be.
            let mut s = Signer::new(key.clone(), "pg").unwrap();
            for _ in 0..50 {
                let (topic, frame, seq) = s.seal("bv1", CloudBody::Command(Command::Arm)).unwrap();
                assert_eq!(topic, "v2t/pg/bv/bv1/cmd");
                assert!(seq > last, "round {round}: {seq} after {last}");
                last = seq;
                rx.open(&frame, v2t_wire::link::Arrival::Command, unix_ms()).unwrap();
            }
        }
        let mut s = Signer::new(key, "pg").unwrap();
        assert_eq!(s.seal(ALL_BVS, CloudBody::Command(Command::Abort)).unwrap().0, "v2t/pg/all/cmd");
        assert!(s.seal("bv/1", CloudBody::Command(Command::Abort)).is_err());
        // Campaign knowledge travels with the BV's priors, to one BV.
        let campaign = || {
            CloudBody::Campaign(v2t_wire::link::CampaignUpload {
                prior_id: 3,
                aim: v2t_model::Target::new(2.0, Style::Rush).unwrap(),
                below_reach: None,
                route: None,
                reaction: None,
            })
        };
        let (topic, frame, _) = s.seal("bv1", campaign()).unwrap();
        assert_eq!(topic, "v2t/pg/bv/bv1/prior");
        rx.open(&frame, v2t_wire::link::Arrival::Prior, unix_ms()).unwrap();
        assert!(s.seal(ALL_BVS, campaign()).is_err());
        assert!(Signer::new(SigningKey::from_bytes(&[1; 32]), "a+b").is_err());
    }

    #[test]
    fn commands_and_styles_parse_or_say_why_not() {
        assert_eq!(command("abort", None, None).unwrap(), Command::Abort);
        assert_eq!(
            command("target", Some(3.5), Some(Style::Yield)).unwrap(),
            Command::SetTarget(Target::new(3.5, Style::Yield).unwrap())
        );
        for (a, t, s) in [
            ("target", None, Some(Style::Rush)),
            ("target", Some(f64::NAN), Some(Style::Rush)),
            ("target", Some(31.0), Some(Style::Rush)),
            ("go", None, None),
        ] {
            assert!(command(a, t, s).is_err(), "{a} {t:?}");
        }
    }
}
