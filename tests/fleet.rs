//! Two simulated BVs in one session, supervised by one `video2track serve` with its embedded
//! broker: each BV's uplink node runs as its own process with its own iceoryx2 namespace; each gets
//! its own prior and τ (one from the console, one from `video2track upload`), one is re-targeted
//! and given what a campaign learned (`video2track campaign send`), a prior signed with the wrong
//! key is refused, and Ctrl-C on `serve` brings both to the
//! minimal-risk stop.

#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)] // test code

use std::time::{Duration, Instant};

use iceoryx2::port::subscriber::Subscriber;
use iceoryx2::prelude::ipc;
use v2t_edge::ports::Bus;
use v2t_tests::harness::{
    Proc, bin, edge_config, free_port, left_turn_grounded, signal, tempdir, uplink_node, write_keys,
};
use v2t_tests::repo_root;
use v2t_wire::{ActivePrior, Code, SafetyAction, SafetyCommand, StyleCode, services};

struct Bv {
    _node: Proc,
    bus: Bus<ipc::Service>,
    priors: Subscriber<ipc::Service, ActivePrior, ()>,
    safety: Subscriber<ipc::Service, SafetyCommand, ()>,
}

impl Bv {
    fn start(dir: &std::path::Path, port: u16, public: &std::path::Path, id: &str) -> Self {
        let cfg = edge_config(dir, port, public, id);
        let ns = format!("v2t/test/fleet{}/{id}", std::process::id());
        let node = uplink_node(&cfg, &ns, id, &[]);
        let bus = Bus::<ipc::Service>::new("test-fleet", &ns).unwrap();
        let priors = bus.subscriber::<ActivePrior>(services::PRIOR).unwrap();
        let safety = bus.subscriber::<SafetyCommand>(services::SAFETY).unwrap();
        Self { _node: node, bus, priors, safety }
    }

    fn prior(&self) -> ActivePrior {
        let deadline = Instant::now() + Duration::from_secs(5);
        loop {
            if let Some(p) = self.priors.receive().unwrap() {
                return p.clone();
            }
            assert!(Instant::now() < deadline, "no prior on iceoryx2");
            self.bus.wait(Duration::from_millis(5));
        }
    }

    fn safety(&self) -> SafetyCommand {
        let deadline = Instant::now() + Duration::from_secs(5);
        loop {
            if let Some(c) = self.safety.receive().unwrap() {
                return *c;
            }
            assert!(Instant::now() < deadline, "no safety command on iceoryx2");
            self.bus.wait(Duration::from_millis(5));
        }
    }
}

/// `video2track serve` of fleet `pg` with its embedded broker on `listen`, signing with `key`,
/// logging the session to `log`, no periodic table; returned once its broker listens.
fn serve(listen: &str, key: &str, log: &std::path::Path) -> Proc {
    let log = log.to_str().unwrap();
    let args = ["serve", "--listen", listen, "--fleet", "pg", "--key", key, "--log", log, "--status-period-s", "0"];
    let serve = Proc::start(&bin("video2track"), &args, "serve");
    serve.expect_line("embedded broker listening", Duration::from_secs(10));
    serve
}

#[test]
fn one_serve_supervises_two_bvs_each_with_its_own_prior_and_target() {
    let dir_scratch = tempdir("fleet");
    let dir = dir_scratch.path();
    let (_key, secret, public) = write_keys(dir, 23);
    let port = free_port();
    let listen = format!("127.0.0.1:{port}");
    let log = dir.join("session.jsonl");
    let key_arg = secret.to_str().unwrap().to_owned();
    let mut serve = serve(&listen, &key_arg, &log);
    v2t_tests::harness::iceoryx2_config();
    let bv1 = Bv::start(dir, port, &public, "bv1");
    let bv2 = Bv::start(dir, port, &public, "bv2");
    let mut online =
        [serve.expect_line(" online", Duration::from_secs(10)), serve.expect_line(" online", Duration::from_secs(10))];
    online.sort();
    assert!(online[0].contains("bv1") && online[1].contains("bv2"), "{online:?}");

    let grounded = dir.join("left_turn.grounded.json");
    std::fs::write(&grounded, serde_json::to_string_pretty(&left_turn_grounded()).unwrap()).unwrap();
    let file = grounded.to_str().unwrap();

    // bv1: from the console, rush at 2.5 s.
    serve.type_line(&format!("upload {file} bv1 tau 2.5 style rush"));
    serve.expect_line("bv1 accepted prior", Duration::from_secs(5));
    let p1 = bv1.prior();
    assert_eq!((p1.tau_s, StyleCode::from_code(p1.style).unwrap()), (2.5, StyleCode::Rush));

    // bv2: from another terminal with `video2track upload`, yield at 4 s.
    let broker = format!("mqtt://{listen}");
    let upload = |key: &str, tau: &str| {
        std::process::Command::new(bin("video2track"))
            .args([
                "upload", file, "--bv", "bv2", "--tau", tau, "--style", "yield", "--fleet", "pg", "--key", key,
                "--broker", &broker,
            ])
            .current_dir(repo_root())
            .output()
            .unwrap()
    };
    let out = upload(&key_arg, "4");
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success() && stdout.contains("bv2: accepted"),
        "{stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let p2 = bv2.prior();
    assert_eq!((p2.tau_s, StyleCode::from_code(p2.style).unwrap()), (4.0, StyleCode::Yield));
    assert_ne!(p1.prior_id, p2.prior_id);
    assert!(bv1.priors.receive().unwrap().is_none(), "bv1 got bv2's prior");

    // A prior signed with another key: bv2 refuses it and says why; `upload` fails with the reason.
    let wrong_dir = tempdir("fleet-wrong-key");
    let (_, wrong, _) = write_keys(wrong_dir.path(), 24);
    let out = upload(wrong.to_str().unwrap(), "3");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && stderr.contains("refused") && stderr.contains("signature"), "{stderr}");
    // Not signed with the cloud's key: counted in bv2's summary of refused frames, which serve prints.
    let summary = serve.expect_line("bv2: ", Duration::from_secs(5));
    assert!(summary.contains("frames refused") && summary.contains("bad signature"), "{summary}");
    assert!(bv2.priors.receive().unwrap().is_none(), "a refused prior reached bv2's regulator");

    // Re-target bv2 live; the status table shows both BVs with their priors.
    serve.type_line("target bv2 3 rush");
    serve.expect_line("bv2 accepted set target", Duration::from_secs(5));
    let p2b = bv2.prior();
    assert_eq!(
        (p2b.prior_id, p2b.tau_s, StyleCode::from_code(p2b.style).unwrap()),
        (p2.prior_id, 3.0, StyleCode::Rush)
    );
    // What earlier runs of this test learned of the VUT (a campaign memory as `campaign record`
    // or `sim --campaign` keep it), sent with `video2track campaign send` for the prior bv2 holds.
    let rush_3 = v2t_model::Target::new(3.0, v2t_model::Style::Rush).unwrap();
    let mut memory = v2t_game::campaign::CampaignMemory::new("their-ads", "track");
    let case = memory.case_mut("left_turn", 0, rush_3);
    let speeds = (0..40).map(|i| if i < 20 { 8.0 } else { 4.5 }).collect();
    case.learn_free_drive(rush_3, &v2t_game::route_speed::RouteSpeed { step_m: 2.0, speeds_mps: speeds, runs: 1 });
    let learned = v2t_lab::campaign::learned_of(case);
    let mem = dir.join("their-ads.json");
    std::fs::write(&mem, v2t_lab::campaign::memory_json(&memory).unwrap()).unwrap();
    let campaign_send = |prior_id: u64| {
        std::process::Command::new(bin("video2track"))
            .args(["campaign", "send", mem.to_str().unwrap(), "--scenario", "left_turn", "--style", "rush"])
            .args(["--tau", "3", "--to", "bv2", "--prior-id", &prior_id.to_string(), "--fleet", "pg"])
            .args(["--key", &key_arg, "--broker", &broker])
            .current_dir(repo_root())
            .output()
            .unwrap()
    };
    let out = campaign_send(p2.prior_id);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success()
            && stdout.contains("bv2: accepted campaign")
            && stdout.contains("route over 1 run(s), 78 m"),
        "{stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let p2c = bv2.prior();
    assert_eq!((p2c.prior_id, p2c.header.seq), (p2.prior_id, p2b.header.seq + 1));
    assert_eq!(p2c.target().unwrap(), rush_3, "the aim: no run yet, τ");
    assert_eq!(v2t_edge::campaign::Learned::from_knowledge(&p2c.campaign).unwrap(), learned);
    // For a prior bv2 does not hold: refused, and `campaign send` fails saying why.
    let out = campaign_send(p2.prior_id + 1);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && stderr.contains("the active prior is"), "{stderr}");

    std::thread::sleep(Duration::from_millis(300));
    serve.type_line("status");
    let r1 = serve.expect_line("bv1 ", Duration::from_secs(5));
    let r2 = serve.expect_line("bv2 ", Duration::from_secs(5));
    assert!(r1.contains("online") && r1.contains(&p1.prior_id.to_string()), "{r1}");
    assert!(r2.contains("online") && r2.contains(&p2.prior_id.to_string()), "{r2}");

    // Ctrl-C: serve aborts every BV, waits for both confirmations and exits cleanly.
    while bv1.safety.receive().unwrap().is_some() {}
    while bv2.safety.receive().unwrap().is_some() {}
    signal(&serve.child, "INT");
    assert_eq!(bv1.safety().action, SafetyAction::MinimalRiskStop.code());
    assert_eq!(bv2.safety().action, SafetyAction::MinimalRiskStop.code());
    serve.expect_line("every BV confirmed the abort", Duration::from_secs(5));
    assert!(serve.wait_exit(Duration::from_secs(5)).success());

    // The session log holds both BVs' telemetry and events as JSON lines.
    let text = std::fs::read_to_string(&log).unwrap();
    let lines: Vec<serde_json::Value> = text.lines().map(|l| serde_json::from_str(l).unwrap()).collect();
    for bv in ["bv1", "bv2"] {
        let tele = lines.iter().filter(|l| l["topic"] == format!("v2t/pg/bv/{bv}/telemetry")).count();
        assert!(tele >= 5, "{bv}: {tele} telemetry lines");
        assert!(
            lines
                .iter()
                .any(|l| l["topic"] == format!("v2t/pg/bv/{bv}/event") && l["message"]["verdict"] == "accepted")
        );
    }
}

/// The whole session in closed loop: two BVs, each its full onboard runtime (`v2t-edge launch` with
/// the uplink node) and a simulated proving ground (`v2t-sim-ecu --from-uplink`) that builds
/// the world from the prior the BV accepted; one `serve` uploads a different τ to each, arms and
/// starts them, and each BV regulates its own interaction to its own target.
#[test]
fn two_simulated_bvs_regulate_their_own_priors_in_closed_loop_under_one_serve() {
    let dir_scratch = tempdir("fleet-closed");
    let dir = dir_scratch.path();
    let (_key, secret, public) = write_keys(dir, 31);
    let log = dir.join("session.jsonl");
    let port = free_port();
    let listen = format!("127.0.0.1:{port}");
    let key_arg = secret.to_str().unwrap().to_owned();
    let mut serve = serve(&listen, &key_arg, &log);
    let mut launchers = Vec::new();
    let mut ecus = Vec::new();
    for (i, bv) in ["bv1", "bv2"].into_iter().enumerate() {
        let cfg = v2t_tests::harness::edge_config_from(dir, port, &public, bv, &format!("config/edge/{bv}_link.toml"));
        let ns = format!("v2t/test/closed{}/{bv}", std::process::id());
        let cfg_arg = cfg.to_str().unwrap().to_owned();
        launchers.push(Proc::start(&bin("v2t-edge"), &["launch", "--config", &cfg_arg, "--namespace", &ns], bv));
        let out = dir.join(format!("{bv}.run.json"));
        let seed = (i + 1).to_string();
        let args =
            ["--config", &cfg_arg, "--namespace", &ns, "--from-uplink", "--seed", &seed, "--engage-timeout-s", "60"];
        let mut cmd = std::process::Command::new(bin("v2t-sim-ecu"));
        cmd.args(args).arg("--out").arg(&out).current_dir(repo_root());
        ecus.push((bv, out, std::thread::spawn(move || cmd.output().unwrap())));
    }
    let mut online =
        [serve.expect_line(" online", Duration::from_secs(15)), serve.expect_line(" online", Duration::from_secs(15))];
    online.sort();
    assert!(online[0].contains("bv1") && online[1].contains("bv2"), "{online:?}");

    let grounded = dir.join("left_turn.grounded.json");
    std::fs::write(&grounded, serde_json::to_string_pretty(&left_turn_grounded()).unwrap()).unwrap();
    let file = grounded.to_str().unwrap();
    let targets = [("bv1", 3.0, "yield"), ("bv2", 4.0, "yield")];
    let mut prior_ids = Vec::new();
    for (bv, tau, style) in targets {
        serve.type_line(&format!("upload {file} {bv} tau {tau} style {style}"));
        let line = serve.expect_line(&format!("{bv} accepted prior"), Duration::from_secs(5));
        let id = line.split("accepted prior ").nth(1).and_then(|r| r.split_whitespace().next()).unwrap();
        prior_ids.push(id.parse::<u64>().unwrap());
    }
    // The simulated worlds start from the priors; then the supervisor arms and starts both.
    std::thread::sleep(Duration::from_millis(500));
    serve.type_line("arm");
    serve.expect_all(&["bv1 accepted arm", "bv2 accepted arm"], Duration::from_secs(5));
    std::thread::sleep(Duration::from_millis(300));
    serve.type_line("start");
    serve.expect_all(&["bv1 accepted start", "bv2 accepted start"], Duration::from_secs(5));
    let mut pets = Vec::new();
    for ((bv, out, ecu), (_, tau, _)) in ecus.into_iter().zip(targets) {
        let output = ecu.join().unwrap();
        eprintln!(
            "{bv} sim-ecu:\n{}{}",
            String::from_utf8_lossy(&output.stdout),
            String::from_utf8_lossy(&output.stderr)
        );
        assert!(output.status.success(), "{bv}: sim-ecu failed");
        let run: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&out).unwrap()).unwrap();
        let r = &run["result"];
        assert_eq!(r["tau_s"].as_f64(), Some(tau), "{bv} ran its own prior's target");
        assert_eq!(r["collision"], serde_json::Value::Null, "{bv}");
        assert_eq!(r["zone_overlap"], false, "{bv}");
        assert_eq!(r["conflicts"][0]["order_matches_style"], true, "{bv}");
        let pet = r["pet_min_s"].as_f64().unwrap();
        println!("{bv}: τ {tau:.2} s (yield), PET {pet:.2} s, error {:.1} %", 100.0 * (pet - tau).abs() / tau);
        assert!((pet - tau).abs() / tau <= 0.15, "{bv}: PET {pet:.2} s vs τ {tau:.2} s");
        pets.push(pet);
    }
    // Each BV reported what its run taught it about the VUT once the VUT had left its zone.
    let lessons = [
        serve.expect_line("learned in the run of prior", Duration::from_secs(10)),
        serve.expect_line("learned in the run of prior", Duration::from_secs(10)),
    ];
    for (bv, id) in ["bv1", "bv2"].into_iter().zip(&prior_ids) {
        let line = lessons.iter().find(|l| l.contains(&format!("{bv} learned in the run of prior {id}")));
        assert!(
            line.is_some_and(|l| l.contains("the VUT's route to") && l.contains("its reaction identified")),
            "{lessons:?}"
        );
    }
    // Ctrl-C: the session log is complete; the test's memory learns bv1's run from it.
    signal(&serve.child, "INT");
    serve.expect_line("every BV confirmed the abort", Duration::from_secs(5));
    assert!(serve.wait_exit(Duration::from_secs(5)).success());
    // The telemetry said, while the runs went on, how each BV's regulator identified the VUT.
    let session = std::fs::read_to_string(&log).unwrap();
    for bv in ["bv1", "bv2"] {
        let identified = session
            .lines()
            .filter(|l| l.contains(&format!("/bv/{bv}/telemetry")))
            .filter_map(|l| serde_json::from_str::<serde_json::Value>(l).ok())
            .filter_map(|v| v["message"]["vut_reaction"]["reacts_p"].as_f64())
            .count();
        assert!(identified > 10, "{bv}: {identified} telemetry reports with the VUT's identification");
    }
    let memory = dir.join("sim-vut.json");
    let record = |aim: &str| {
        std::process::Command::new(bin("video2track"))
            .args(["campaign", "record", memory.to_str().unwrap(), "--scenario", "left_turn", "--style", "yield"])
            .args(["--tau", "3", "--vut", "sim-vut", "--aim", aim, "--pet", &pets[0].to_string()])
            .args(["--learned", log.to_str().unwrap(), "--from-bv", "bv1", "--prior-id", &prior_ids[0].to_string()])
            .current_dir(repo_root())
            .output()
            .unwrap()
    };
    let out = record("2.5");
    assert_eq!(out.status.code(), Some(2), "the run aimed at 3 s: {}", String::from_utf8_lossy(&out.stderr));
    let out = record("3");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success() && stderr.contains("from the BV's report: route over 1 run(s)"), "{stderr}");
    let text = std::fs::read_to_string(&memory).unwrap();
    let m = v2t_lab::campaign::memory_from_json(&text).unwrap();
    let case = m.case("left_turn", 0, v2t_model::Target::new(3.0, v2t_model::Style::Yield).unwrap()).unwrap();
    assert!(case.route_speed.is_some() && case.reaction.is_some(), "{text}");
    drop(launchers);
}
