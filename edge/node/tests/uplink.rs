//! The uplink node against a real Mosquitto broker (the Debian package; `.ci/run` installs it):
//! the test starts the broker on a free loopback port, runs `v2t-edge node uplink` as its own
//! process, plays the cloud with a `rumqttc` client and signs with a key made for the test, and
//! watches what reaches the onboard iceoryx2 services.

#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)] // test code

use std::io::{BufRead, BufReader};
use std::net::{TcpListener, TcpStream};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::mpsc::{Receiver, channel};
use std::time::{Duration, Instant};

use iceoryx2::prelude::ipc;
use v2t_edge::clock::now_ns;
use v2t_edge::ports::Bus;
use v2t_edge::uplink::unix_ms;
use v2t_wire::link::{self, CloudBody, CloudMessage, Command as CloudCommand, SigningKey, topics};
use v2t_wire::{ActivePrior, Code, SafetyAction, SafetyCommand, services};

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn tempdir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("v2t-uplink-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// A Mosquitto broker on loopback with persistence, killed when dropped.
struct Broker {
    child: Option<Child>,
    conf: PathBuf,
    port: u16,
}

impl Broker {
    fn start(dir: &Path) -> Self {
        let port = TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port();
        let conf = dir.join("mosquitto.conf");
        std::fs::write(
            &conf,
            format!(
                "listener {port} 127.0.0.1\nallow_anonymous true\nset_tcp_nodelay true\npersistence true\npersistence_location {}/\n",
                dir.display()
            ),
        )
        .unwrap();
        let mut b = Self { child: None, conf, port };
        b.restart();
        b
    }

    fn restart(&mut self) {
        let exe = ["/usr/sbin/mosquitto", "/usr/bin/mosquitto"]
            .into_iter()
            .find(|p| Path::new(p).exists())
            .expect("mosquitto is not installed: `apt-get install mosquitto` (.ci/run does)");
        let child = Command::new(exe).arg("-c").arg(&self.conf).stderr(Stdio::null()).spawn().unwrap();
        self.child = Some(child);
        let deadline = Instant::now() + Duration::from_secs(10);
        while TcpStream::connect(("127.0.0.1", self.port)).is_err() {
            assert!(Instant::now() < deadline, "mosquitto did not listen on {}", self.port);
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    fn stop(&mut self) {
        if let Some(mut c) = self.child.take() {
            // SIGTERM: mosquitto saves its persistent sessions on the way out.
            v2t_edge::launch::send_signal(&c, iceoryx2_bb_posix::signal::Signal::Terminate);
            let _ = c.wait();
        }
    }
}

impl Drop for Broker {
    fn drop(&mut self) {
        if let Some(mut c) = self.child.take() {
            let _ = c.kill();
            let _ = c.wait();
        }
    }
}

/// A child whose stderr lines arrive on a channel, killed when dropped.
struct Proc {
    child: Child,
    lines: Receiver<String>,
}

impl Proc {
    fn start(args: &[&str]) -> Self {
        let mut child = Command::new(env!("CARGO_BIN_EXE_v2t-edge"))
            .args(args)
            .current_dir(root())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let stderr = child.stderr.take().unwrap();
        let (tx, lines) = channel();
        std::thread::spawn(move || {
            for line in BufReader::new(stderr).lines().map_while(Result::ok) {
                eprintln!("  | {line}");
                if tx.send(line).is_err() {
                    break;
                }
            }
        });
        Self { child, lines }
    }

    fn expect_line(&self, needle: &str, timeout: Duration) -> String {
        let deadline = Instant::now() + timeout;
        while let Some(left) = deadline.checked_duration_since(Instant::now()) {
            match self.lines.recv_timeout(left) {
                Ok(line) if line.contains(needle) => return line,
                Ok(_) => {}
                Err(_) => break,
            }
        }
        panic!("no line containing {needle:?} within {timeout:?}");
    }
}

impl Drop for Proc {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// The cloud's side: a client that publishes signed frames and collects what the BV sends.
struct Cloud {
    client: rumqttc::Client,
    inbox: Receiver<(String, Vec<u8>)>,
    key: SigningKey,
    seq: u64,
}

impl Cloud {
    fn connect(port: u16, key: SigningKey) -> Self {
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
                            sub.try_subscribe(topics::bv("pg", "bv1", leaf), qos).unwrap();
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

    fn frame(&mut self, body: CloudBody) -> Vec<u8> {
        self.seq += 1;
        let m = CloudMessage { fleet: "pg".into(), bv_id: "bv1".into(), seq: self.seq, issued_ms: unix_ms(), body };
        link::seal(&m, &self.key).unwrap()
    }

    fn send(&self, leaf: &str, frame: Vec<u8>) {
        self.client.publish(topics::bv("pg", "bv1", leaf), rumqttc::QoS::AtLeastOnce, false, frame).unwrap();
    }

    /// The next event the BV reports (JSON), skipping telemetry and heartbeats.
    fn event(&self, timeout: Duration) -> serde_json::Value {
        let deadline = Instant::now() + timeout;
        while let Some(left) = deadline.checked_duration_since(Instant::now()) {
            match self.inbox.recv_timeout(left) {
                Ok((topic, payload)) if topic.ends_with("/event") => return serde_json::from_slice(&payload).unwrap(),
                Ok(_) => {}
                Err(_) => break,
            }
        }
        panic!("no event within {timeout:?}");
    }

    /// The next telemetry report.
    fn telemetry(&self, timeout: Duration) -> link::Telemetry {
        let deadline = Instant::now() + timeout;
        while let Some(left) = deadline.checked_duration_since(Instant::now()) {
            match self.inbox.recv_timeout(left) {
                Ok((topic, payload)) if topic.ends_with("/telemetry") => match link::read_report(&payload).unwrap() {
                    link::EdgeReport::Telemetry(t) => return t,
                    other => panic!("{other:?} on the telemetry topic"),
                },
                Ok(_) => {}
                Err(_) => break,
            }
        }
        panic!("no telemetry within {timeout:?}");
    }
}

fn upload(prior_id: u64) -> link::PriorUpload {
    let map = v2t_map::Map::load(&root().join("config/maps/proving_ground.xodr")).unwrap();
    let lib = v2t_map::library::TopologyLibrary::build(&map);
    let text = std::fs::read_to_string(root().join("config/examples/semantics_left_turn.json")).unwrap();
    let sem = v2t_model::semantics::parse_semantics_json(&text).unwrap();
    let sc = v2t_ground::ground(&map, &lib, &sem).unwrap().scenario;
    let now = unix_ms();
    v2t_edge::prior::upload_along_routes(&sc, prior_id, 12.0, (now, now + 600_000)).unwrap()
}

/// An edge configuration for `port` in `dir`, trusting `key`.
fn edge_config(dir: &Path, port: u16, key: &SigningKey) -> PathBuf {
    let pubkey = dir.join("cloud.pub");
    std::fs::write(&pubkey, link::key_to_hex(&key.verifying_key().to_bytes()) + "\n").unwrap();
    let base = std::fs::read_to_string(root().join("config/edge/bv1.toml")).unwrap();
    let edge_dir = root().join("config/edge");
    let text = base.replace("\"../", &format!("\"{}/../", edge_dir.display()))
        + &format!(
            "\n[uplink]\nbroker = \"mqtt://127.0.0.1:{port}\"\nfleet = \"pg\"\nbv_id = \"bv1\"\ncloud_key = \"{}\"\n\
             map = \"{}\"\ngeofence_margin_m = 0.5\nmax_age_s = 30.0\nmax_skew_s = 2.0\ntelemetry_period_s = 0.1\n\
             heartbeat_period_s = 0.2\non_link_loss = \"continue\"\nlink_loss_timeout_s = 2.0\n",
            pubkey.display(),
            root().join("config/maps/proving_ground.xodr").display()
        );
    let path = dir.join("bv1-uplink.toml");
    std::fs::write(&path, text).unwrap();
    path
}

#[test]
fn priors_and_commands_cross_mosquitto_bad_ones_are_refused_and_a_broker_restart_loses_nothing() {
    let dir = tempdir("mqtt");
    let mut broker = Broker::start(&dir);
    let key = SigningKey::from_bytes(&[11; 32]);
    let cfg = edge_config(&dir, broker.port, &key);
    let ns = format!("v2t/test/uplink{}", std::process::id());
    let node = Proc::start(&["node", "uplink", "--config", cfg.to_str().unwrap(), "--namespace", &ns]);
    v2t_edge::ports::use_iceoryx2_config(&root().join("config/iceoryx2.toml")).unwrap();
    let bus = Bus::<ipc::Service>::new("test-cloud", &ns).unwrap();
    let priors = bus.subscriber::<ActivePrior>(services::PRIOR).unwrap();
    let safety = bus.subscriber::<SafetyCommand>(services::SAFETY).unwrap();
    node.expect_line("connected", Duration::from_secs(10));
    let mut cloud = Cloud::connect(broker.port, key);
    cloud.telemetry(Duration::from_secs(5));

    // A good prior reaches the regulator's service.
    let good = cloud.frame(CloudBody::Prior(upload(41)));
    cloud.send(topics::PRIOR, good.clone());
    let e = cloud.event(Duration::from_secs(5));
    assert_eq!(e["verdict"], "accepted", "{e}");
    let deadline = Instant::now() + Duration::from_secs(2);
    let prior = loop {
        if let Some(p) = priors.receive().unwrap() {
            break p.clone();
        }
        assert!(Instant::now() < deadline, "no prior on iceoryx2");
        bus.wait(Duration::from_millis(2));
    };
    assert_eq!(prior.prior_id, 41);

    // Tampered, replayed, off-road and garbage frames are refused with the reason; nothing reaches iceoryx2.
    let mut tampered = cloud.frame(CloudBody::Prior(upload(42)));
    let mid = tampered.len() / 2;
    tampered[mid] ^= 0x40;
    cloud.send(topics::PRIOR, tampered);
    assert!(cloud.event(Duration::from_secs(5))["detail"].as_str().unwrap().contains("signature"));
    cloud.send(topics::PRIOR, good);
    assert!(cloud.event(Duration::from_secs(5))["detail"].as_str().unwrap().contains("replay"));
    let mut off = upload(43);
    for x in &mut off.prior.agents[1].states[50..] {
        x.px += 60.0;
    }
    let off = cloud.frame(CloudBody::Prior(off));
    cloud.send(topics::PRIOR, off);
    let e = cloud.event(Duration::from_secs(5));
    assert!(e["detail"].as_str().unwrap().contains("drivable area"), "{e}");
    cloud.send(topics::CMD, b"hello".to_vec());
    assert_eq!(cloud.event(Duration::from_secs(5))["verdict"], "refused");
    assert!(priors.receive().unwrap().is_none(), "a refused prior never reaches the regulator");
    assert_eq!(cloud.telemetry(Duration::from_secs(2)).prior_id, 41, "the node keeps running on the accepted prior");

    // Abort: publish → the minimal-risk stop request on the gateway's service.
    let mut latencies = Vec::new();
    for _ in 0..20 {
        while safety.receive().unwrap().is_some() {}
        let abort = cloud.frame(CloudBody::Command(CloudCommand::Abort));
        let t0 = now_ns();
        cloud.send(topics::CMD, abort);
        let deadline = Instant::now() + Duration::from_secs(2);
        let cmd = loop {
            if let Some(c) = safety.receive().unwrap() {
                break *c;
            }
            assert!(Instant::now() < deadline, "no safety command on iceoryx2");
            std::thread::sleep(Duration::from_micros(200));
        };
        latencies.push((now_ns() - t0) as f64 * 1e-6);
        assert_eq!(cmd.action, SafetyAction::MinimalRiskStop.code());
        cloud.event(Duration::from_secs(2));
    }
    latencies.sort_by(f64::total_cmp);
    let pct = |q: f64| latencies[((latencies.len() - 1) as f64 * q).round() as usize];
    println!(
        "abort publish -> minimal-risk stop request on iceoryx2, {} aborts: min {:.1} ms, median {:.1} ms, p90 {:.1} ms, max {:.1} ms",
        latencies.len(),
        pct(0.0),
        pct(0.5),
        pct(0.9),
        pct(1.0)
    );

    // The broker restarts: the node reconnects, telemetry resumes, the accepted prior stays.
    broker.stop();
    std::thread::sleep(Duration::from_millis(500));
    broker.restart();
    node.expect_line("connected", Duration::from_secs(15));
    let t = cloud.telemetry(Duration::from_secs(10));
    assert_eq!(t.prior_id, 41, "the accepted prior survives the broker restart");
    let retarget =
        cloud.frame(CloudBody::Command(CloudCommand::SetTarget { tau_s: 3.5, style: v2t_model::Style::Yield }));
    cloud.send(topics::CMD, retarget);
    assert_eq!(cloud.event(Duration::from_secs(5))["verdict"], "accepted");
    let deadline = Instant::now() + Duration::from_secs(2);
    let retargeted = loop {
        if let Some(p) = priors.receive().unwrap() {
            break p.clone();
        }
        assert!(Instant::now() < deadline, "no re-targeted prior on iceoryx2");
        bus.wait(Duration::from_millis(2));
    };
    assert_eq!((retargeted.prior_id, retargeted.tau_s), (41, 3.5));
}
