//! The harness of the cloud–edge link tests: brokers (Mosquitto from the Debian package, or the
//! embedded broker of `video2track serve`), child processes of the workspace's binaries with their
//! output on a channel, edge configurations with an `[uplink]` section, and a test cloud client.

#![allow(
    clippy::panic,
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    missing_debug_implementations
)] // test code

use std::io::{BufRead, BufReader, Write as _};
use std::net::{TcpListener, TcpStream};
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdin, Command, Stdio};
use std::sync::mpsc::{Receiver, channel};
use std::time::{Duration, Instant};

use v2t_wire::link::{self, SigningKey, topics};

use crate::repo_root;

/// A binary of the workspace, built by `cargo test --workspace` next to the test executables.
pub fn bin(name: &str) -> PathBuf {
    let exe = std::env::current_exe().unwrap();
    let dir = exe.parent().and_then(Path::parent).unwrap();
    let p = dir.join(name);
    assert!(
        p.exists(),
        "{} is not built: run the workspace's tests (`cargo test --workspace`) or `cargo build --workspace` first",
        p.display()
    );
    p
}

/// Loads the project's iceoryx2 settings once per test process (every test of a file may ask).
pub fn iceoryx2_config() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| v2t_edge::ports::use_iceoryx2_config(&repo_root().join("config/iceoryx2.toml")).unwrap());
}

/// A fresh directory for one test, removed when dropped.
pub fn tempdir(name: &str) -> tempfile::TempDir {
    tempfile::Builder::new().prefix(&format!("v2t-link-{name}-")).tempdir().unwrap()
}

/// A free loopback port.
pub fn free_port() -> u16 {
    TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port()
}

/// Sends a signal by name (`INT`, `TERM`, `KILL`) to a child.
pub fn signal(child: &Child, name: &str) {
    let ok = Command::new("kill").arg(format!("-{name}")).arg(child.id().to_string()).status().unwrap().success();
    assert!(ok, "kill -{name} {}", child.id());
}

/// A child whose stdout and stderr lines arrive on one channel (echoed to the test's stderr),
/// killed when dropped.
pub struct Proc {
    /// The process.
    pub child: Child,
    stdin: Option<ChildStdin>,
    lines: Receiver<String>,
    tag: String,
}

impl Proc {
    /// Starts `exe args` in the repository root.
    pub fn start(exe: &Path, args: &[&str], tag: &str) -> Self {
        Self::start_env(exe, args, tag, &[])
    }

    /// [`Proc::start`] with extra environment variables.
    pub fn start_env(exe: &Path, args: &[&str], tag: &str, env: &[(&str, &str)]) -> Self {
        let mut child = Command::new(exe)
            .args(args)
            .envs(env.iter().copied())
            .current_dir(repo_root())
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap_or_else(|e| panic!("{}: {e}", exe.display()));
        let (tx, lines) = channel();
        let out = child.stdout.take().unwrap();
        let err = child.stderr.take().unwrap();
        for (stream, tx) in [(Box::new(out) as Box<dyn std::io::Read + Send>, tx.clone()), (Box::new(err), tx)] {
            let tag = tag.to_owned();
            std::thread::spawn(move || {
                for line in BufReader::new(stream).lines().map_while(Result::ok) {
                    eprintln!("  {tag} | {line}");
                    if tx.send(line).is_err() {
                        break;
                    }
                }
            });
        }
        let stdin = child.stdin.take();
        Self { child, stdin, lines, tag: tag.to_owned() }
    }

    /// Lines containing `needle` among those not yet read (reads them all).
    pub fn count_lines(&self, needle: &str) -> usize {
        let mut n = 0;
        while let Ok(line) = self.lines.try_recv() {
            n += usize::from(line.contains(needle));
        }
        n
    }

    /// The next line containing `needle`, within `timeout`.
    pub fn expect_line(&self, needle: &str, timeout: Duration) -> String {
        let deadline = Instant::now() + timeout;
        while let Some(left) = deadline.checked_duration_since(Instant::now()) {
            match self.lines.recv_timeout(left) {
                Ok(line) if line.contains(needle) => return line,
                Ok(_) => {}
                Err(_) => break,
            }
        }
        panic!("{}: no line containing {needle:?} within {timeout:?}", self.tag);
    }

    /// One line containing each of `needles`, in any order, within `timeout`.
    pub fn expect_all(&self, needles: &[&str], timeout: Duration) {
        let mut left: Vec<&str> = needles.to_vec();
        let deadline = Instant::now() + timeout;
        while !left.is_empty() {
            let Some(wait) = deadline.checked_duration_since(Instant::now()) else { break };
            match self.lines.recv_timeout(wait) {
                Ok(line) => left.retain(|n| !line.contains(n)),
                Err(_) => break,
            }
        }
        assert!(left.is_empty(), "{}: no lines containing {left:?} within {timeout:?}", self.tag);
    }

    /// Types a console line.
    pub fn type_line(&mut self, line: &str) {
        let stdin = self.stdin.as_mut().unwrap();
        writeln!(stdin, "{line}").unwrap();
        stdin.flush().unwrap();
    }

    /// Waits for the process to end, up to `timeout`; its exit status.
    pub fn wait_exit(&mut self, timeout: Duration) -> std::process::ExitStatus {
        let deadline = Instant::now() + timeout;
        loop {
            if let Some(s) = self.child.try_wait().unwrap() {
                return s;
            }
            assert!(Instant::now() < deadline, "{} did not exit within {timeout:?}", self.tag);
            std::thread::sleep(Duration::from_millis(20));
        }
    }
}

impl Drop for Proc {
    fn drop(&mut self) {
        // SIGTERM first: a launcher stops its nodes on it.
        if matches!(self.child.try_wait(), Ok(None)) {
            let _ = Command::new("kill").arg("-TERM").arg(self.child.id().to_string()).status();
            let deadline = Instant::now() + Duration::from_secs(3);
            while Instant::now() < deadline && matches!(self.child.try_wait(), Ok(None)) {
                std::thread::sleep(Duration::from_millis(20));
            }
        }
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// `v2t-edge node uplink` with the configuration `cfg` in the iceoryx2 namespace `ns`, and extra
/// environment variables.
pub fn uplink_node(cfg: &Path, ns: &str, tag: &str, env: &[(&str, &str)]) -> Proc {
    uplink_node_on(None, cfg, ns, tag, env)
}

/// [`uplink_node`], pinned to `cpu` (a `taskset` CPU list) when one is given.
pub fn uplink_node_on(cpu: Option<&str>, cfg: &Path, ns: &str, tag: &str, env: &[(&str, &str)]) -> Proc {
    let edge = bin("v2t-edge");
    let args = [edge.to_str().unwrap(), "node", "uplink", "--config", cfg.to_str().unwrap(), "--namespace", ns];
    match cpu {
        Some(cpu) => Proc::start_env(Path::new("taskset"), &[&["-c", cpu][..], &args].concat(), tag, env),
        None => Proc::start_env(&edge, &args[1..], tag, env),
    }
}

/// Which broker a test runs against.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BrokerKind {
    /// Mosquitto, the Debian package (`.ci/run` installs it), with persistence.
    Mosquitto,
    /// The embedded broker of `video2track serve`.
    Embedded,
}

/// A broker on a loopback port, stopped when dropped.
pub struct Broker {
    /// Which.
    pub kind: BrokerKind,
    /// Its port.
    pub port: u16,
    dir: PathBuf,
    key: PathBuf,
    /// Mosquitto's settings after its `listener` line (default: anonymous, with persistence).
    mosquitto_conf: Option<String>,
    proc: Option<Proc>,
}

impl Broker {
    /// Starts a broker of `kind` keeping its files in `dir`; the embedded one signs with `key`.
    pub fn start(kind: BrokerKind, dir: &Path, key: &Path) -> Self {
        let mut b = Self {
            kind,
            port: free_port(),
            dir: dir.to_owned(),
            key: key.to_owned(),
            mosquitto_conf: None,
            proc: None,
        };
        b.restart();
        b
    }

    /// A Mosquitto with `conf` after its `listener` line (TLS, passwords, …).
    pub fn mosquitto_with(dir: &Path, conf: &str) -> Self {
        let mut b = Self {
            kind: BrokerKind::Mosquitto,
            port: free_port(),
            dir: dir.to_owned(),
            key: PathBuf::new(),
            mosquitto_conf: Some(conf.to_owned()),
            proc: None,
        };
        b.restart();
        b
    }

    /// (Re)starts it on the same port.
    pub fn restart(&mut self) {
        let port = self.port;
        let proc = match self.kind {
            BrokerKind::Mosquitto => {
                // Run as root, Mosquitto drops to its own user: let it save its sessions here.
                use std::os::unix::fs::PermissionsExt as _;
                std::fs::set_permissions(&self.dir, std::fs::Permissions::from_mode(0o777)).unwrap();
                let conf = self.dir.join("mosquitto.conf");
                let rest = self.mosquitto_conf.clone().unwrap_or_else(|| {
                    format!(
                        "allow_anonymous true\nset_tcp_nodelay true\npersistence true\npersistence_location {}/\n\
                         message_size_limit {}\n",
                        self.dir.display(),
                        link::MAX_FRAME_LEN
                    )
                });
                std::fs::write(&conf, format!("listener {port} 127.0.0.1\n{rest}")).unwrap();
                let exe = v2t_test_support::find("mosquitto")
                    .expect("mosquitto is not installed: `scripts/test` installs it (the Debian package mosquitto)");
                Proc::start(&exe, &["-c", conf.to_str().unwrap()], "mosquitto")
            }
            BrokerKind::Embedded => {
                let listen = format!("127.0.0.1:{port}");
                let args = [
                    "serve",
                    "--listen",
                    &listen,
                    "--fleet",
                    "pg",
                    "--key",
                    self.key.to_str().unwrap(),
                    "--status-period-s",
                    "0",
                ];
                Proc::start(&bin("video2track"), &args, "serve")
            }
        };
        self.proc = Some(proc);
        let deadline = Instant::now() + Duration::from_secs(10);
        while TcpStream::connect(("127.0.0.1", port)).is_err() {
            assert!(Instant::now() < deadline, "{:?} did not listen on {port}", self.kind);
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    /// The process id of the broker.
    pub fn pid(&self) -> Option<u32> {
        self.proc.as_ref().map(|p| p.child.id())
    }

    /// Stops it: Mosquitto with SIGTERM (it saves its sessions), the embedded one killed (a crash).
    pub fn stop(&mut self) {
        if let Some(mut p) = self.proc.take() {
            match self.kind {
                BrokerKind::Mosquitto => signal(&p.child, "TERM"),
                BrokerKind::Embedded => signal(&p.child, "KILL"),
            }
            p.wait_exit(Duration::from_secs(10));
        }
    }
}

/// Writes the supervisor's key pair into `dir` (`cloud.key`, `cloud.pub`) for `seed`.
pub fn write_keys(dir: &Path, seed: u8) -> (SigningKey, PathBuf, PathBuf) {
    let key = SigningKey::from_bytes(&[seed; 32]);
    let (secret, public) = (dir.join("cloud.key"), dir.join("cloud.pub"));
    std::fs::write(&secret, link::key_to_hex(&[seed; 32]) + "\n").unwrap();
    std::fs::write(&public, link::key_to_hex(&key.verifying_key().to_bytes()) + "\n").unwrap();
    (key, secret, public)
}

/// An edge configuration in `dir` for BV `bv_id` of fleet `pg` on the broker at `port`, trusting
/// the public key in `public`, with the proving ground as its geofence.
pub fn edge_config(dir: &Path, port: u16, public: &Path, bv_id: &str) -> PathBuf {
    edge_config_from(dir, port, public, bv_id, "config/edge/bv1.toml")
}

/// [`edge_config`] from another base configuration of `config/edge/` (its `[uplink]` section, if
/// any, replaced).
pub fn edge_config_from(dir: &Path, port: u16, public: &Path, bv_id: &str, base: &str) -> PathBuf {
    edge_config_with(dir, &format!("mqtt://127.0.0.1:{port}"), public, bv_id, base, "")
}

/// The most general form: any broker URL, and `extra` lines for the `[uplink]` section
/// (credentials, certificates).
pub fn edge_config_with(dir: &Path, broker: &str, public: &Path, bv_id: &str, base: &str, extra: &str) -> PathBuf {
    let base = std::fs::read_to_string(repo_root().join(base)).unwrap();
    let base = base.split("\n[uplink]").next().unwrap().to_owned();
    let edge_dir = repo_root().join("config/edge");
    let loss =
        if extra.contains("on_link_loss") { "" } else { "on_link_loss = \"continue\"\nlink_loss_timeout_s = 2.0\n" };
    let text = base.replace("\"../", &format!("\"{}/../", edge_dir.display()))
        + &format!(
            "\n[uplink]\nbroker = \"{broker}\"\nfleet = \"pg\"\nbv_id = \"{bv_id}\"\ncloud_key = \"{}\"\n\
             map = \"{}\"\ngeofence_margin_m = 0.5\nmax_age_s = 30.0\nmax_skew_s = 2.0\ntelemetry_period_s = 0.1\n\
             heartbeat_period_s = 0.2\n{loss}{extra}",
            public.display(),
            repo_root().join("config/maps/proving_ground.xodr").display()
        );
    let path = dir.join(format!("{bv_id}-uplink.toml"));
    std::fs::write(&path, text).unwrap();
    path
}

/// A test PKI made with the `openssl` command: a CA, a server certificate for 127.0.0.1 and
/// client certificates, every file PEM (keys PKCS#8) in `dir`.
pub fn make_pki(dir: &Path, clients: &[&str]) {
    let run = |args: &[&str]| {
        let out = Command::new("openssl")
            .args(args)
            .current_dir(dir)
            .output()
            .expect("openssl is not installed (.ci/run installs it)");
        assert!(out.status.success(), "openssl {args:?}: {}", String::from_utf8_lossy(&out.stderr));
    };
    let ec = ["-newkey", "ec", "-pkeyopt", "ec_paramgen_curve:prime256v1", "-nodes"];
    let mut ca = vec!["req", "-x509"];
    ca.extend(ec);
    ca.extend(["-keyout", "ca.key", "-out", "ca.pem", "-days", "2", "-subj", "/CN=v2t-test-ca"]);
    ca.extend(["-addext", "basicConstraints=critical,CA:TRUE", "-addext", "keyUsage=critical,keyCertSign,cRLSign"]);
    run(&ca);
    let leaf = |name: &str, usage: &str, san: &str| {
        let ext = format!("{name}.ext");
        std::fs::write(
            dir.join(&ext),
            format!("basicConstraints=CA:FALSE\nkeyUsage=critical,digitalSignature\nextendedKeyUsage={usage}\n{san}"),
        )
        .unwrap();
        let (key, csr, pem) = (format!("{name}.key"), format!("{name}.csr"), format!("{name}.pem"));
        let mut req = vec!["req"];
        req.extend(ec);
        let subj = format!("/CN={name}");
        req.extend(["-keyout", &key, "-out", &csr, "-subj", &subj]);
        run(&req);
        run(&[
            "x509",
            "-req",
            "-in",
            &csr,
            "-CA",
            "ca.pem",
            "-CAkey",
            "ca.key",
            "-CAcreateserial",
            "-out",
            &pem,
            "-days",
            "2",
            "-extfile",
            &ext,
        ]);
    };
    leaf("server", "serverAuth", "subjectAltName=IP:127.0.0.1\n");
    for c in clients {
        leaf(c, "clientAuth", "");
    }
    // The broker may drop root privileges before it reads its key: let any user read the test files.
    for e in std::fs::read_dir(dir).unwrap().flatten() {
        use std::os::unix::fs::PermissionsExt as _;
        std::fs::set_permissions(e.path(), std::fs::Permissions::from_mode(0o644)).unwrap();
    }
}

/// The grounded left turn on the proving ground, and a constant-speed prior along its routes
/// (25 s), valid for 10 minutes.
pub fn left_turn_upload(prior_id: u64) -> link::PriorUpload {
    let scenario = left_turn_grounded();
    let now = v2t_edge::uplink::unix_ms();
    let prior = v2t_model::prior::TrajectoryPrior::along_routes_at_start_speed(&scenario, 25.0).unwrap();
    let bv_agent = prior.bv_agent(None).unwrap().id.clone();
    link::PriorUpload { prior_id, bv_agent, valid_from_ms: now, valid_until_ms: now + 600_000, prior }
}

/// The example left-turn semantics grounded on the proving ground.
pub fn left_turn_grounded() -> v2t_model::grounded::GroundedScenario {
    let map = v2t_map::Map::load(&repo_root().join("config/maps/proving_ground.xodr")).unwrap();
    let lib = v2t_map::library::TopologyLibrary::build(&map);
    let sem = v2t_files::read_semantics(&repo_root().join("config/examples/semantics_left_turn.json")).unwrap();
    v2t_ground::ground(&map, &lib, &sem).unwrap().scenario
}

/// The cloud's side for a test: a client that publishes signed frames and collects what the BVs send.
pub struct Cloud {
    client: rumqttc::Client,
    inbox: Receiver<(String, Vec<u8>)>,
    key: SigningKey,
    seq: u64,
}

impl Cloud {
    /// Connects to the broker on `port` and follows every BV of fleet `pg`.
    pub fn connect(port: u16, key: SigningKey) -> Self {
        let mut opts = rumqttc::MqttOptions::new(format!("v2t-test-cloud-{}", std::process::id()), "127.0.0.1", port);
        opts.set_keep_alive(Duration::from_secs(5));
        opts.set_max_packet_size(2 << 20, 2 << 20);
        let (client, mut connection) = rumqttc::Client::new(opts, 64);
        let mut net = rumqttc::NetworkOptions::new();
        net.set_tcp_nodelay(true);
        connection.eventloop.set_network_options(net);
        let (tx, inbox) = channel();
        let sub = client.clone();
        std::thread::spawn(move || {
            for n in connection.iter() {
                match n {
                    Ok(rumqttc::Event::Incoming(rumqttc::Packet::ConnAck(_))) => {
                        // Telemetry and heartbeats are latest-wins (QoS 0); events are kept (QoS 1).
                        for (leaf, qos) in [
                            (topics::TELEMETRY, rumqttc::QoS::AtMostOnce),
                            (topics::HEARTBEAT, rumqttc::QoS::AtMostOnce),
                            (topics::EVENT, rumqttc::QoS::AtLeastOnce),
                        ] {
                            sub.try_subscribe(topics::bv("pg", "+", leaf), qos).unwrap();
                        }
                    }
                    Ok(rumqttc::Event::Incoming(rumqttc::Packet::Publish(p))) => {
                        if tx.send((p.topic.clone(), p.payload.to_vec())).is_err() {
                            return;
                        }
                    }
                    Ok(_) => {}
                    Err(_) => std::thread::sleep(Duration::from_millis(100)),
                }
            }
        });
        Self { client, inbox, key, seq: 0 }
    }

    /// A frame for `bv` signed with the test's key and the next sequence number (the clock in µs,
    /// as the supervisor's own tools number theirs, so the two can take turns).
    pub fn frame(&mut self, bv: &str, body: link::CloudBody) -> Vec<u8> {
        let now_us = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .map_or(0, |d| u64::try_from(d.as_micros()).unwrap_or(u64::MAX));
        self.seq = (self.seq + 1).max(now_us);
        let m = link::CloudMessage {
            fleet: "pg".into(),
            bv_id: bv.into(),
            seq: self.seq,
            issued_ms: v2t_edge::uplink::unix_ms(),
            body,
        };
        link::seal(&m, &self.key).unwrap()
    }

    /// Publishes `frame` on BV `bv`'s `leaf` topic (QoS 1).
    pub fn send(&self, bv: &str, leaf: &str, frame: Vec<u8>) {
        self.client.publish(topics::bv("pg", bv, leaf), rumqttc::QoS::AtLeastOnce, false, frame).unwrap();
    }

    /// The next verdict BV `bv` reports on a genuine frame (JSON with its `seq`), skipping
    /// everything else (the BV's summaries of refused garbage among it).
    pub fn event(&self, bv: &str, timeout: Duration) -> serde_json::Value {
        self.next_event(bv, timeout, false)
    }

    /// The next summary of refused frames BV `bv` reports (JSON without a `seq`).
    pub fn summary(&self, bv: &str, timeout: Duration) -> serde_json::Value {
        self.next_event(bv, timeout, true)
    }

    fn next_event(&self, bv: &str, timeout: Duration, summary: bool) -> serde_json::Value {
        let topic = topics::bv("pg", bv, topics::EVENT);
        let deadline = Instant::now() + timeout;
        while let Some(left) = deadline.checked_duration_since(Instant::now()) {
            match self.inbox.recv_timeout(left) {
                Ok((t, payload)) if t == topic => {
                    let e: serde_json::Value = serde_json::from_slice(&payload).unwrap();
                    if e["seq"].is_null() == summary {
                        return e;
                    }
                }
                Ok(_) => {}
                Err(_) => break,
            }
        }
        panic!("no {} from {bv} within {timeout:?}", if summary { "summary" } else { "event" });
    }

    /// Telemetry reports of BV `bv` stamped within `[from_ms, to_ms]`, among everything received
    /// so far (the rest is dropped).
    pub fn telemetry_between(&self, bv: &str, from_ms: u64, to_ms: u64) -> usize {
        let topic = topics::bv("pg", bv, topics::TELEMETRY);
        let mut n = 0;
        while let Ok((t, payload)) = self.inbox.try_recv() {
            if t == topic
                && let Ok(link::EdgeReport::Telemetry(r)) = link::read_report(&payload)
                && (from_ms..=to_ms).contains(&r.stamp_ms)
            {
                n += 1;
            }
        }
        n
    }

    /// Drops everything received so far.
    pub fn drain(&self) {
        while self.inbox.try_recv().is_ok() {}
    }

    /// Telemetry reports of BV `bv` that arrive within `window`.
    pub fn count_telemetry(&self, bv: &str, window: Duration) -> usize {
        let topic = topics::bv("pg", bv, topics::TELEMETRY);
        let deadline = Instant::now() + window;
        let mut n = 0;
        while let Some(left) = deadline.checked_duration_since(Instant::now()) {
            match self.inbox.recv_timeout(left) {
                Ok((t, _)) if t == topic => n += 1,
                Ok(_) => {}
                Err(_) => break,
            }
        }
        n
    }

    /// The next telemetry report of BV `bv`.
    pub fn telemetry(&self, bv: &str, timeout: Duration) -> link::Telemetry {
        let topic = topics::bv("pg", bv, topics::TELEMETRY);
        let deadline = Instant::now() + timeout;
        while let Some(left) = deadline.checked_duration_since(Instant::now()) {
            match self.inbox.recv_timeout(left) {
                Ok((t, payload)) if t == topic => match link::read_report(&payload).unwrap() {
                    link::EdgeReport::Telemetry(t) => return t,
                    other => panic!("{other:?} on the telemetry topic"),
                },
                Ok(_) => {}
                Err(_) => break,
            }
        }
        panic!("no telemetry from {bv} within {timeout:?}");
    }
}

/// A publisher that floods topics as fast as a raw MQTT 3.1.1 connection on loopback takes it:
/// random bytes and frames with a valid link header and random contents, alternately, at QoS 0 or
/// QoS 1 (its acknowledgements read and dropped). Stops when dropped.
pub struct Flood {
    stop: std::sync::Arc<std::sync::atomic::AtomicBool>,
    sent: std::sync::Arc<std::sync::atomic::AtomicU64>,
    thread: Option<std::thread::JoinHandle<()>>,
}

/// The bytes of an MQTT remaining length.
fn remaining_length(mut n: usize, out: &mut Vec<u8>) {
    loop {
        let mut b = (n % 128) as u8;
        n /= 128;
        if n > 0 {
            b |= 0x80;
        }
        out.push(b);
        if n == 0 {
            break;
        }
    }
}

/// An MQTT PUBLISH packet.
pub fn publish_packet(topic: &str, payload: &[u8], qos1: bool, packet_id: u16) -> Vec<u8> {
    let mut body = Vec::with_capacity(topic.len() + payload.len() + 4);
    body.extend((topic.len() as u16).to_be_bytes());
    body.extend(topic.as_bytes());
    if qos1 {
        body.extend(packet_id.max(1).to_be_bytes());
    }
    body.extend(payload);
    let mut p = vec![if qos1 { 0x32 } else { 0x30 }];
    remaining_length(body.len(), &mut p);
    p.extend(body);
    p
}

/// A raw MQTT 3.1.1 connection (clean session) to the broker on `port`.
pub fn raw_mqtt(port: u16, client_id: &str) -> TcpStream {
    use std::io::Read as _;
    let mut s = TcpStream::connect(("127.0.0.1", port)).unwrap();
    s.set_nodelay(true).unwrap();
    let mut body = vec![0, 4, b'M', b'Q', b'T', b'T', 4, 0x02, 0, 60];
    body.extend((client_id.len() as u16).to_be_bytes());
    body.extend(client_id.as_bytes());
    let mut p = vec![0x10];
    remaining_length(body.len(), &mut p);
    p.extend(body);
    s.write_all(&p).unwrap();
    let mut ack = [0u8; 4];
    s.read_exact(&mut ack).unwrap();
    assert_eq!((ack[0], ack[3]), (0x20, 0), "the broker refused the connection");
    s
}

impl Flood {
    /// Starts flooding `topics` on the broker on `port`, at most `rate` messages per second (`None`:
    /// as fast as the connection takes them).
    pub fn start(port: u16, topics: Vec<String>, qos1: bool, rate: Option<f64>) -> Self {
        use std::sync::Arc;
        use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
        let stop = Arc::new(AtomicBool::new(false));
        let sent = Arc::new(AtomicU64::new(0));
        let (s, n) = (Arc::clone(&stop), Arc::clone(&sent));
        let thread = std::thread::spawn(move || {
            static INSTANCE: AtomicU64 = AtomicU64::new(0);
            let id = INSTANCE.fetch_add(1, Ordering::Relaxed);
            let mut conn = raw_mqtt(port, &format!("v2t-flood-{}-{id}", std::process::id()));
            if qos1 {
                // Acknowledgements are read and dropped, so the broker never stalls on them.
                let mut reader = conn.try_clone().unwrap();
                std::thread::spawn(move || {
                    use std::io::Read as _;
                    let mut buf = [0u8; 65536];
                    while reader.read(&mut buf).is_ok_and(|k| k > 0) {}
                });
            }
            let mut rng = 0x9E37_79B9_7F4A_7C15u64;
            let mut next = move || {
                rng ^= rng << 13;
                rng ^= rng >> 7;
                rng ^= rng << 17;
                rng
            };
            let mut batch = Vec::with_capacity(1 << 16);
            let mut k: u64 = 0;
            let started = Instant::now();
            while !s.load(Ordering::Relaxed) {
                if let Some(rate) = rate {
                    let due = Duration::from_secs_f64(k as f64 / rate.max(1.0));
                    if let Some(wait) = due.checked_sub(started.elapsed()) {
                        std::thread::sleep(wait);
                    }
                }
                batch.clear();
                for _ in 0..200 {
                    let len = 16 + (next() % 200) as usize;
                    let mut payload: Vec<u8> = (0..len).map(|_| next() as u8).collect();
                    if k % 2 == 1 {
                        payload[..5].copy_from_slice(&[b'V', b'2', b'T', link::LINK_VERSION, 1]);
                    }
                    let topic = &topics[(k as usize) % topics.len()];
                    batch.extend(publish_packet(topic, &payload, qos1, (k % 65_000) as u16 + 1));
                    k += 1;
                }
                if conn.write_all(&batch).is_err() {
                    break;
                }
                n.fetch_add(200, Ordering::Relaxed);
            }
        });
        Self { stop, sent, thread: Some(thread) }
    }

    /// Messages written so far.
    pub fn sent(&self) -> u64 {
        self.sent.load(std::sync::atomic::Ordering::Relaxed)
    }
}

impl Drop for Flood {
    fn drop(&mut self) {
        self.stop.store(true, std::sync::atomic::Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// The resident memory of process `pid`, MB (`VmRSS`).
pub fn rss_mb(pid: u32) -> f64 {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).unwrap_or_default();
    status
        .lines()
        .find_map(|l| l.strip_prefix("VmRSS:"))
        .and_then(|v| v.split_whitespace().next())
        .and_then(|kb| kb.parse::<f64>().ok())
        .map_or(0.0, |kb| kb / 1024.0)
}
