//! The regulator in the cloud, for real: `video2track regulate` as its own process, a real
//! Mosquitto between it and the BV, the BV's connection behind a delaying proxy (`v2t-bench
//! netdelay`, 50 ms each way), the BV driven by `video2track sim --regulated --cloud-broker` in
//! real time. Its PET must land where the simulated network puts the same seed at the same setting
//! (50 ms each way, the default 2 ms of cloud processing), within the simulated runs' spread over
//! seeds 6–10.

#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)] // test code

use std::net::TcpStream;
use std::process::Command;
use std::time::{Duration, Instant};

use v2t_lab::controllers::{CloudRegulatedBv, RegulatedBv};
use v2t_sim::bv::BvController;
use v2t_sim::network::NetworkSettings;
use v2t_tests::harness::{Broker, Proc, bin, free_port, tempdir, write_keys};
use v2t_tests::repo_root;

const CARD: &str = "config/scenarios/left_turn_basic.toml";
const DELAY_MS: u64 = 50;
/// The least spread allowed, s (the real run's timing is the wall clock's: a few ms of scheduling on
/// each hop).
const MIN_SPREAD_S: f64 = 0.05;

/// The simulated network's PETs for seeds 6–10 at `DELAY_MS` each way.
fn simulated_pets() -> Vec<f64> {
    let sc = v2t_sim::files::load_scenario(&repo_root().join(CARD)).unwrap();
    let settings = v2t_files::load_toml(&repo_root().join(v2t_files::shipped::REGULATOR)).unwrap();
    let params = RegulatedBv::params_for(&settings, &sc, 0);
    let network = NetworkSettings::constant(DELAY_MS as f64, 0.0);
    (6..=10)
        .map(|seed| {
            let bv = CloudRegulatedBv::new(params, &sc, 0, &network, seed).unwrap();
            let mut bvs: Vec<Box<dyn BvController>> = vec![Box::new(bv)];
            let model = sc.vut.default_model;
            let out = v2t_sim::runner::run(&sc, &mut bvs, model.driver().as_mut(), seed).unwrap();
            assert!(out.result.collision.is_none());
            out.result.pet_min_s.unwrap()
        })
        .collect()
}

#[test]
fn the_cloud_regulator_through_mosquitto_lands_where_the_simulated_network_puts_it() {
    v2t_test_support::require!(v2t_test_support::BROKER_TOOLS);
    let dir = tempdir("cloud");
    let (_, secret, public) = write_keys(dir.path(), 23);
    let broker = Broker::mosquitto_with(dir.path(), "allow_anonymous true\nset_tcp_nodelay true\n");
    let proxy_port = free_port();
    let (listen, upstream) = (format!("127.0.0.1:{proxy_port}"), format!("127.0.0.1:{}", broker.port));
    let _proxy = Proc::start(
        &bin("v2t-bench"),
        &["netdelay", "--listen", &listen, "--upstream", &upstream, "--delay-ms", &DELAY_MS.to_string()],
        "netdelay",
    );
    let deadline = Instant::now() + Duration::from_secs(10);
    while TcpStream::connect(&listen).is_err() {
        assert!(Instant::now() < deadline, "the proxy did not listen");
        std::thread::sleep(Duration::from_millis(20));
    }
    let start = (v2t_lab::cloud_mqtt::unix_ms() + 3_000).to_string();
    let cloud = Proc::start(
        &bin("video2track"),
        &[
            "regulate",
            CARD,
            "--broker",
            &format!("mqtt://{upstream}"),
            "--key",
            secret.to_str().unwrap(),
            "--start-unix-ms",
            &start,
        ],
        "regulate",
    );
    let json = dir.path().join("run.json");
    let out = Command::new(bin("video2track"))
        .current_dir(repo_root())
        .args(["sim", CARD, "--regulated", "--cloud-broker", &format!("mqtt://{listen}"), "--cloud-key"])
        .arg(&public)
        .args(["--start-unix-ms", &start, "--seed", "6", "--json"])
        .arg(&json)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{stdout}\n{}", String::from_utf8_lossy(&out.stderr));
    let line = stdout.lines().find(|l| l.starts_with("link:")).unwrap();
    let accepted: u64 = line.split("plans accepted ").nth(1).unwrap().split(',').next().unwrap().parse().unwrap();
    assert!(accepted > 150, "plans crossed the broker both ways: {line}");
    let run: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert!(run["result"]["collision"].is_null(), "{}", run["result"]);
    let real = run["result"]["pet_min_s"].as_f64().unwrap();
    let heard = cloud.expect_line("published", Duration::from_secs(45));
    assert!(heard.contains("(0 on stale states)"), "{heard}");

    let sims = simulated_pets();
    let (lo, hi) = sims.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &p| (a.min(p), b.max(p)));
    let spread = (hi - lo).max(MIN_SPREAD_S);
    eprintln!("real {real:.3} s; simulated {DELAY_MS} ms, seeds 6–10: {sims:.3?}");
    assert!(
        (real - sims[0]).abs() <= spread,
        "through Mosquitto at {DELAY_MS} ms each way, seed 6: PET {real:.3} s; the simulated network: {:.3} s \
         (seeds 6–10 spread over {spread:.3} s)",
        sims[0]
    );
}
