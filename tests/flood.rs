//! The link under attack: anyone who can publish on the broker floods a BV's prior and command
//! topics with garbage (random bytes, and frames with a valid header and random contents) while
//! the supervisor aborts. Against Mosquitto and the embedded broker of `video2track serve`, the
//! BV's uplink node must keep its heartbeat (no minimal-risk stop of its own making) and its
//! telemetry, stay small, and let every abort through in time; a message far larger than a frame
//! must cost at most one reconnect. `send` must report the BV's real verdict meanwhile.
//!
//! The test floods for a few seconds (`V2T_FLOOD_S`, default 4) at a bounded rate
//! (`V2T_FLOOD_RATE`); the benchmark in `docs/BENCHMARKS.md` runs the same code for 15 s in release,
//! as fast as a local publisher writes.

#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)] // test code

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::{Duration, Instant};

use iceoryx2::prelude::ipc;
use v2t_edge::clock::now_ns;
use v2t_edge::ports::Bus;
use v2t_supervisor::link::RESEND_EVERY;
use v2t_tests::harness::{
    Broker, BrokerKind, Cloud, Flood, Proc, bin, edge_config, publish_packet, raw_mqtt, rss_mb, tempdir, uplink_node,
    uplink_node_on, write_keys,
};
use v2t_tests::repo_root;
use v2t_wire::link::{CloudBody, Command as CloudCommand, topics};
use v2t_wire::{Code, Heartbeat, NodeKind, SafetyAction, SafetyCommand, services};

fn flood_seconds() -> f64 {
    std::env::var("V2T_FLOOD_S").ok().and_then(|s| s.parse().ok()).filter(|s: &f64| *s > 0.0).unwrap_or(4.0)
}

/// Messages per second each of the two flooding connections writes at most (`V2T_FLOOD_RATE`,
/// 0: as fast as they can; default 20,000, which the debug builds of the tests keep up with on two
/// shared cores; the benchmark runs release builds unthrottled).
fn flood_rate() -> Option<f64> {
    match std::env::var("V2T_FLOOD_RATE").ok().and_then(|s| s.parse::<f64>().ok()) {
        Some(r) if r > 0.0 => Some(r),
        Some(_) => None,
        None => Some(20_000.0),
    }
}

/// The longest gap between two heartbeats of the uplink node, watched on iceoryx2 in a thread.
struct HeartbeatWatch {
    stop: Arc<AtomicBool>,
    max_gap_ns: Arc<AtomicU64>,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl HeartbeatWatch {
    fn start(ns: &str) -> Self {
        let (stop, max_gap_ns) = (Arc::new(AtomicBool::new(false)), Arc::new(AtomicU64::new(0)));
        let (s, m, ns) = (Arc::clone(&stop), Arc::clone(&max_gap_ns), ns.to_owned());
        let thread = std::thread::spawn(move || {
            let bus = Bus::<ipc::Service>::new("test-heartbeats", &ns).unwrap();
            let beats = bus.subscriber::<Heartbeat>(services::HEARTBEAT).unwrap();
            let mut last: Option<u64> = None;
            while !s.load(Ordering::Relaxed) {
                while let Some(b) = beats.receive().unwrap() {
                    if b.node == NodeKind::Uplink.code() {
                        if let Some(l) = last {
                            m.fetch_max(b.header.stamp_ns.saturating_sub(l), Ordering::Relaxed);
                        }
                        last = Some(b.header.stamp_ns);
                    }
                }
                std::thread::sleep(Duration::from_millis(1));
            }
        });
        Self { stop, max_gap_ns, thread: Some(thread) }
    }

    fn reset(&self) {
        self.max_gap_ns.store(0, Ordering::Relaxed);
    }

    fn max_gap_ms(&self) -> f64 {
        self.max_gap_ns.load(Ordering::Relaxed) as f64 * 1e-6
    }
}

impl Drop for HeartbeatWatch {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// The BV's uplink runs on the BV's own onboard computer, not on the broker's host. When this
/// machine has two CPUs or more, the uplink gets the last one, and this process — the flooders, the
/// cloud's client and the broker or `serve` it starts — the others; `V2T_FLOOD_SHARED_CPUS=1` lets
/// everything share every CPU (what the benchmark also reports). Returns the uplink's CPU.
/// Decided once per test process: after the first call this process is pinned, and
/// `available_parallelism` (which follows the affinity) would see one CPU.
fn split_cpus() -> Option<String> {
    static SPLIT: std::sync::OnceLock<Option<String>> = std::sync::OnceLock::new();
    SPLIT.get_or_init(pin_away_from_last_cpu).clone()
}

fn pin_away_from_last_cpu() -> Option<String> {
    let n = std::thread::available_parallelism().map_or(1, usize::from);
    if n < 2 || std::env::var("V2T_FLOOD_SHARED_CPUS").is_ok_and(|v| v == "1") {
        return None;
    }
    let rest = if n == 2 { "0".to_owned() } else { format!("0-{}", n - 2) };
    let ok = std::process::Command::new("taskset")
        .args(["-a", "-p", "-c", &rest, &std::process::id().to_string()])
        .stdout(std::process::Stdio::null())
        .status()
        .is_ok_and(|s| s.success());
    assert!(ok, "taskset (util-linux) could not pin the test process to CPUs {rest}");
    Some((n - 1).to_string())
}

fn percentile(sorted: &[f64], q: f64) -> f64 {
    sorted[((sorted.len() - 1) as f64 * q).round() as usize]
}

/// The gateway's side of bv1's uplink `node` (its safety requests on iceoryx2, kept with the bus
/// they come from) and the supervisor's, once the node is connected and bv1's telemetry arrives.
fn attach(node: &Proc, ns: &str, port: u16, key: v2t_wire::link::SigningKey) -> (Bus<ipc::Service>, Safety, Cloud) {
    v2t_tests::harness::iceoryx2_config();
    let bus = Bus::<ipc::Service>::new("test-cloud", ns).unwrap();
    let safety = bus.subscriber::<SafetyCommand>(services::SAFETY).unwrap();
    node.expect_line("connected", Duration::from_secs(10));
    let cloud = Cloud::connect(port, key);
    cloud.telemetry("bv1", Duration::from_secs(5));
    (bus, safety, cloud)
}

type Safety = iceoryx2::port::subscriber::Subscriber<ipc::Service, SafetyCommand, ()>;

/// One abort as the supervisor sends it: a signed abort, and a fresh copy (its own sequence
/// number) every [`RESEND_EVERY`] until the minimal-risk stop request appears on iceoryx2 — frames
/// to a BV travel at QoS 0, and a broker may drop one for a subscriber that a flood has put behind.
#[derive(Debug, Clone, Copy)]
struct Abort {
    /// From the first copy handed to the MQTT client to the stop request, ms.
    latency_ms: f64,
    /// Copies sent (1 when the first got through).
    copies: u32,
}

fn abort(cloud: &mut Cloud, safety: &Safety) -> Abort {
    while safety.receive().unwrap().is_some() {}
    let t0 = now_ns();
    let start = Instant::now();
    let deadline = start + Duration::from_secs(5);
    let mut copies = 0u32;
    let mut next_copy = start;
    loop {
        if Instant::now() >= next_copy {
            let frame = cloud.frame("bv1", CloudBody::Command(CloudCommand::Abort));
            cloud.send("bv1", topics::CMD, frame);
            copies += 1;
            next_copy += RESEND_EVERY;
        }
        if let Some(c) = safety.receive().unwrap() {
            assert_eq!(c.action, SafetyAction::MinimalRiskStop.code());
            assert_eq!(c.culprit, 0, "a stop of the uplink's own making (link loss), not the abort");
            return Abort { latency_ms: (now_ns() - t0) as f64 * 1e-6, copies };
        }
        assert!(Instant::now() < deadline, "an abort did not get through the flood within 5 s ({copies} copies)");
        std::thread::sleep(Duration::from_micros(200));
    }
}

fn flood(kind: BrokerKind) {
    let dir_scratch = tempdir(&format!("flood-{kind:?}").to_lowercase());
    let dir = dir_scratch.path();
    let (key, secret, public) = write_keys(dir, 21);
    let uplink_cpu = split_cpus();
    let broker = Broker::start(kind, dir, &secret);
    let cfg = edge_config(dir, broker.port, &public, "bv1");
    let ns = format!("v2t/test/flood{kind:?}{}", std::process::id());
    let node = uplink_node_on(uplink_cpu.as_deref(), &cfg, &ns, "uplink", &[]);
    let (_bus, safety, mut cloud) = attach(&node, &ns, broker.port, key);
    let watch = HeartbeatWatch::start(&ns);
    let targets = vec![topics::bv("pg", "bv1", topics::PRIOR), topics::bv("pg", "bv1", topics::CMD)];
    let secs = flood_seconds();
    for qos1 in [false, true] {
        let rate = flood_rate();
        let floods = [
            Flood::start(broker.port, targets.clone(), qos1, rate),
            Flood::start(broker.port, targets.clone(), qos1, rate),
        ];
        std::thread::sleep(Duration::from_millis(300));
        watch.reset();
        cloud.drain();
        let started = Instant::now();
        let sent0: u64 = floods.iter().map(Flood::sent).sum();
        let from_ms = v2t_edge::uplink::unix_ms();
        let mut latencies = Vec::new();
        let mut resent = 0;
        let mut send_checked = false;
        while started.elapsed().as_secs_f64() < secs {
            let a = abort(&mut cloud, &safety);
            latencies.push(a.latency_ms);
            resent += usize::from(a.copies > 1);
            if !send_checked && started.elapsed().as_secs_f64() > secs / 2.0 {
                // The supervisor's tool gets the BV's verdict on its own frame, not a summary.
                let o = std::process::Command::new(bin("video2track"))
                    .args(["send", "abort", "--bv", "bv1", "--fleet", "pg", "--wait-s", "5"])
                    .arg("--key")
                    .arg(&secret)
                    .args(["--broker", &format!("mqtt://127.0.0.1:{}", broker.port)])
                    .current_dir(repo_root())
                    .output()
                    .unwrap();
                let out = String::from_utf8_lossy(&o.stdout);
                assert!(
                    o.status.success() && out.contains("bv1: accepted abort"),
                    "{out}{}",
                    String::from_utf8_lossy(&o.stderr)
                );
                send_checked = true;
            }
            std::thread::sleep(Duration::from_millis(150));
        }
        let elapsed = started.elapsed().as_secs_f64();
        let rate = (floods.iter().map(Flood::sent).sum::<u64>() - sent0) as f64 / elapsed;
        let to_ms = v2t_edge::uplink::unix_ms();
        drop(floods);
        let uplink_mb = rss_mb(node.child.id());
        let serve_mb = broker.pid().map(rss_mb);
        let tele = cloud.telemetry_between("bv1", from_ms, to_ms);
        let tele_hz = tele as f64 / ((to_ms - from_ms) as f64 * 1e-3);
        latencies.sort_by(f64::total_cmp);
        let gap = watch.max_gap_ms();
        println!(
            "{kind:?} QoS {} ({}): flood {:.0} msg/s written for {elapsed:.1} s; {} aborts ({resent} needed a second copy): median {:.1} ms, p99 {:.1} ms, \
             max {:.1} ms; uplink heartbeat gap max {gap:.1} ms; telemetry {tele_hz:.1} Hz; RSS uplink {uplink_mb:.1} MB{}",
            u8::from(qos1),
            uplink_cpu
                .as_ref()
                .map_or_else(|| "all processes on all CPUs".to_owned(), |c| format!("uplink alone on CPU {c}")),
            rate,
            latencies.len(),
            percentile(&latencies, 0.5),
            percentile(&latencies, 0.99),
            percentile(&latencies, 1.0),
            serve_mb.map_or_else(String::new, |m| format!(", broker process {m:.1} MB")),
        );
        assert!(send_checked, "the flood ended before `send` ran");
        assert!(gap < 60.0, "{kind:?}: the uplink's heartbeat paused {gap:.1} ms (the monitor's timeout is 60 ms)");
        assert!(tele_hz >= 8.0, "{kind:?}: telemetry fell to {tele_hz:.1} Hz under the flood");
        assert!(uplink_mb <= 64.0, "{kind:?}: the uplink grew to {uplink_mb:.1} MB");
        assert!(serve_mb.is_none_or(|m| m <= 256.0), "{kind:?}: serve grew to {serve_mb:?} MB");
        assert!(percentile(&latencies, 1.0) < 1000.0, "{kind:?}: an abort took {:.0} ms", percentile(&latencies, 1.0));
    }
    // The node is still there, and summarized what it refused.
    let summary = cloud.summary("bv1", Duration::from_secs(5));
    assert!(summary["detail"].as_str().unwrap().contains("frames refused"), "{summary}");
    drop(watch);
}

#[test]
fn a_garbage_flood_on_mosquitto_never_stops_the_bv_or_its_aborts() {
    v2t_test_support::require!(v2t_test_support::BROKER_TOOLS);
    flood(BrokerKind::Mosquitto);
}

#[test]
fn a_garbage_flood_on_the_embedded_broker_never_stops_the_bv_or_its_aborts() {
    flood(BrokerKind::Embedded);
}

/// One message of 10 MiB and one of 100 MiB on the BV's topics at every QoS. With the documented
/// broker limits the broker drops it; without them (a Mosquitto with no `message_size_limit`) the
/// BV reads it and drops it itself. Either way the BV stays connected (at most one reconnect) and
/// an abort right after it takes effect.
fn oversize(broker: &Broker, key: v2t_wire::link::SigningKey, cfg: &std::path::Path, label: &str) {
    let tag: String = label.chars().filter(char::is_ascii_alphanumeric).collect();
    let ns = format!("v2t/test/oversize{tag}{}", std::process::id());
    let node = uplink_node(cfg, &ns, "uplink", &[]);
    let (_bus, safety, mut cloud) = attach(&node, &ns, broker.port, key);
    let mut latencies = Vec::new();
    for (size, qos) in
        [(10usize << 20, 0u8), (10 << 20, 1), (10 << 20, 2), (100 << 20, 0), (100 << 20, 1), (100 << 20, 2)]
    {
        for leaf in [topics::PRIOR, topics::CMD] {
            let topic = topics::bv("pg", "bv1", leaf);
            let mut conn = raw_mqtt(broker.port, &format!("v2t-big-{size}-{qos}-{leaf}"));
            let mut packet = publish_packet(&topic, &vec![0x56; size], qos > 0, 7);
            packet[0] = 0x30 | (qos << 1);
            use std::io::Write as _;
            let _ = conn.write_all(&packet);
            std::thread::sleep(Duration::from_millis(200));
            latencies.push(abort(&mut cloud, &safety).latency_ms);
        }
    }
    std::thread::sleep(Duration::from_millis(300));
    let reconnects = node.count_lines("connected to");
    latencies.sort_by(f64::total_cmp);
    println!(
        "{label}: 10 and 100 MiB messages at QoS 0/1/2 on the prior and command topics: {reconnects} reconnects, \
         aborts right after: median {:.1} ms, max {:.1} ms",
        percentile(&latencies, 0.5),
        percentile(&latencies, 1.0)
    );
    assert!(reconnects <= 1, "{label}: {reconnects} reconnects");
    assert!(percentile(&latencies, 1.0) < 1000.0, "{label}");
    cloud.telemetry("bv1", Duration::from_secs(2));
}

#[test]
fn messages_far_larger_than_a_frame_cost_at_most_one_reconnect() {
    v2t_test_support::require!(v2t_test_support::BROKER_TOOLS);
    let dir_scratch = tempdir("oversize");
    let dir = dir_scratch.path();
    let (key, secret, public) = write_keys(dir, 22);
    for kind in [BrokerKind::Mosquitto, BrokerKind::Embedded] {
        let broker = Broker::start(kind, dir, &secret);
        let cfg = edge_config(dir, broker.port, &public, "bv1");
        oversize(&broker, key.clone(), &cfg, &format!("{kind:?} (documented limits)"));
    }
    // A Mosquitto without the documented limit: the BV's own defence.
    let sub = tempdir("oversize-nolimit");
    let open = Broker::mosquitto_with(sub.path(), "allow_anonymous true\nset_tcp_nodelay true\n");
    let cfg = edge_config(sub.path(), open.port, &public, "bv1");
    oversize(&open, key, &cfg, "Mosquitto without message_size_limit");
}
