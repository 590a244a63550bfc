//! The `video2track` binary end to end: real runs on the bundled cards, and bad input that must
//! give a message naming the file, the field and the problem, exit code 2 and no panic.

#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)] // test code

mod common;

use common::{ok, repo, s, tempdir, text, video2track};

use std::path::{Path, PathBuf};

#[test]
fn sim_runs_every_card_with_every_vut_model_and_writes_json() {
    let dir_scratch = tempdir("sim");
    let dir = dir_scratch.path();
    for card in ["left_turn_basic", "left_turn_vut", "cut_in_basic"] {
        for vut in ["idm-cautious", "idm-normal", "idm-aggressive", "reactive", "sampling"] {
            let json = dir.join(format!("{card}-{vut}.json"));
            let o = video2track(&[
                "sim",
                &format!("config/scenarios/{card}.toml"),
                "--vut",
                vut,
                "--seed",
                "3",
                "--json",
                json.to_str().unwrap(),
            ]);
            let (out, err) = text(&o);
            assert!(o.status.success(), "{card}/{vut}: {err}");
            assert!(out.contains("first through") && out.contains("PET") && out.contains("min distance"), "{out}");
            let v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
            assert_eq!(v["result"]["vut_model"], vut);
            assert_eq!(v["result"]["seed"], 3);
            assert!(v["result"]["min_distance_m"].as_f64().unwrap() > 0.0);
            assert!(v["trace"].as_array().unwrap().len() > 10);
        }
    }
}

/// Writes a copy of the left-turn card with `edit` applied to its text, next to copies of the
/// files it names, and returns its path with the scratch folder that holds it.
fn broken_card(
    name: &str,
    edit: impl Fn(&str) -> String,
    vehicle_edit: impl Fn(&str) -> String,
) -> (tempfile::TempDir, PathBuf) {
    let dir_scratch = tempdir(name);
    let dir = dir_scratch.path();
    std::fs::create_dir_all(dir.join("scenarios")).unwrap();
    std::fs::create_dir_all(dir.join("vehicles")).unwrap();
    std::fs::create_dir_all(dir.join("sim")).unwrap();
    let card = std::fs::read_to_string(repo().join("config/scenarios/left_turn_basic.toml")).unwrap();
    std::fs::write(dir.join("scenarios/card.toml"), edit(&card)).unwrap();
    for v in ["bv_sedan", "vut_sedan"] {
        let t = std::fs::read_to_string(repo().join(format!("config/vehicles/{v}.toml"))).unwrap();
        std::fs::write(dir.join(format!("vehicles/{v}.toml")), vehicle_edit(&t)).unwrap();
    }
    std::fs::copy(repo().join("config/sim/default.toml"), dir.join("sim/default.toml")).unwrap();
    let card = dir.join("scenarios/card.toml");
    (dir_scratch, card)
}

fn expect_input_error(card: &Path, needles: &[&str]) {
    let o = video2track(&["sim", card.to_str().unwrap()]);
    let (_, err) = text(&o);
    assert_eq!(o.status.code(), Some(2), "stderr: {err}");
    assert!(!err.contains("panicked"), "{err}");
    for n in needles {
        assert!(err.contains(n), "`{n}` missing from: {err}");
    }
}

#[test]
fn malformed_toml_names_the_file_and_line() {
    let (_dir, card) = broken_card("malformed", |t| t.replace("tau_s = 2.0", "tau_s = = 2.0"), str::to_owned);
    expect_input_error(&card, &["card.toml", "line"]);
}

#[test]
fn unknown_field_is_named() {
    let (_dir, card) =
        broken_card("unknown", |t| t.replace("tau_s = 2.0", "tau_s = 2.0\ncolour = \"red\""), str::to_owned);
    expect_input_error(&card, &["card.toml", "colour"]);
}

#[test]
fn nan_is_rejected_with_the_field() {
    let (_dir, card) =
        broken_card("nan", |t| t.replace("initial_speed_mps = 10.0", "initial_speed_mps = nan"), str::to_owned);
    expect_input_error(&card, &["card.toml", "bvs[0].initial_speed_mps", "NaN"]);
}

/// A segment of 1e308 m once panicked (capacity overflow) and 1e9 m aborted on a 32 GB allocation:
/// both are refused with the field and the bound before anything is sampled.
#[test]
fn an_absurd_segment_length_is_refused_with_its_bound() {
    for length in ["1e308", "1e9"] {
        let (_dir, card) = broken_card(
            "length",
            |t| {
                t.replacen(
                    "{ kind = \"line\", length_m = 150.0 }",
                    &format!("{{ kind = \"line\", length_m = {length} }}"),
                    1,
                )
            },
            str::to_owned,
        );
        expect_input_error(&card, &["card.toml", "length_m", "10000"]);
    }
}

/// Files larger than their kind allows are refused before they are parsed (a 122 MB card once
/// exhausted memory inside the TOML parser, exit 134): a card, a prior handed to `export xosc`, a
/// map handed to `map inspect`, each sparse (nothing on disk), each exit 2 naming the bound.
#[test]
fn files_over_their_size_bound_are_refused_unread() {
    let dir = tempdir("bounds");
    let big = |name: &str, bytes: u64| {
        let p = dir.path().join(name);
        std::fs::File::create(&p).unwrap().set_len(bytes).unwrap();
        p
    };
    let card = big("card.toml", 122_000_000);
    expect_input_error(&card, &["card.toml", "122000000 bytes", "4194304 bytes allowed for a TOML file"]);
    let map = big("huge.xodr", 1 << 30);
    let o = video2track(&["map", "inspect", map.to_str().unwrap()]);
    let (_, err) = text(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("huge.xodr") && err.contains("268435456 bytes allowed for an OpenDRIVE map"), "{err}");
    let prior = big("prior.json", 300_000_000);
    let out = dir.path().join("out.xosc");
    let o = video2track(&["export", "xosc", prior.to_str().unwrap(), "--out", out.to_str().unwrap()]);
    let (_, err) = text(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("prior.json") && err.contains("bytes allowed"), "{err}");
    assert!(!out.exists());
}

/// A BV placed where the VUT starts is a collision at t = 0, not a test (it ran, reported the
/// collision and exited 0).
#[test]
fn a_bv_that_starts_on_the_vut_is_refused() {
    let (_dir, card) = broken_card(
        "overlap",
        |t| {
            t.replacen(
                "start_x_m = -1.75, start_y_m = 47.85, start_heading_deg = -90.0",
                "start_x_m = 1.75, start_y_m = -70.51, start_heading_deg = 90.0",
                1,
            )
        },
        str::to_owned,
    );
    expect_input_error(&card, &["card.toml", "bvs[0].path", "`vut` and `bv1` overlap where they start"]);
}

/// The SUMO world converts the shipped map, found from the repository root: run elsewhere, it
/// is bad input naming the map and the folder (it was netconvert's "not accessible" and exit 1).
#[test]
fn the_sumo_world_outside_the_repository_names_the_missing_map() {
    let dir = tempdir("elsewhere");
    let card = repo().join("config/scenarios/left_turn_vut.toml");
    let driver = repo().join("config/vut/sumo/krauss.toml");
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_video2track"))
        .args(["sim", card.to_str().unwrap(), "--world", "sumo", "--sumo-driver", driver.to_str().unwrap()])
        .current_dir(dir.path())
        .output()
        .unwrap();
    let (_, err) = text(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("config/maps/proving_ground.xodr: not found in") && err.contains("repository root"), "{err}");
}

#[test]
fn negative_vehicle_dimension_names_the_vehicle_file() {
    let (_dir, card) = broken_card("negative", str::to_owned, |t| t.replace("width_m = 1.85", "width_m = -1.85"));
    expect_input_error(&card, &["sedan.toml", "geometry.width_m", "-1.85"]);
}

#[test]
fn missing_file_and_unknown_model_are_input_errors() {
    let o = video2track(&["sim", "config/scenarios/no_such_card.toml"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(text(&o).1.contains("no_such_card.toml"));
    let (_dir, card) = broken_card("model", |t| t.replace("idm-normal", "idm-reckless"), str::to_owned);
    expect_input_error(&card, &["vut.model", "idm-reckless", "idm-normal"]);
    let o = video2track(&["sim", "config/scenarios/left_turn_basic.toml", "--vut", "nobody"]);
    assert_eq!(o.status.code(), Some(2), "clap rejects unknown values with its usage exit code");
}

#[test]
fn paths_that_never_meet_are_refused() {
    let (_dir, card) = broken_card(
        "apart",
        |t| t.replace("start_x_m = -1.75, start_y_m = 47.85", "start_x_m = -300.0, start_y_m = 47.85"),
        str::to_owned,
    );
    expect_input_error(&card, &["never comes into conflict"]);
}

/// Every command of `video2track`, in the order `--help` lists them.
const COMMANDS: [&str; 19] = [
    "demo",
    "sim",
    "replay",
    "render",
    "experiment",
    "campaign",
    "abstract",
    "generate",
    "realism",
    "corpus",
    "train",
    "ground",
    "export",
    "map",
    "keygen",
    "serve",
    "upload",
    "send",
    "regulate",
];

#[test]
fn help_lists_only_real_commands() {
    let o = video2track(&["--help"]);
    let (out, _) = text(&o);
    let commands: Vec<&str> = out
        .lines()
        .skip_while(|l| !l.starts_with("Commands:"))
        .skip(1)
        .take_while(|l| !l.trim().is_empty())
        .filter_map(|l| l.split_whitespace().next())
        .collect();
    let mut expected = COMMANDS.to_vec();
    expected.push("help");
    assert_eq!(commands, expected, "{out}");
}

#[test]
fn the_four_methods_run_on_every_paper_scenario() {
    let dir_scratch = tempdir("fidelity");
    let dir = dir_scratch.path();
    let json = dir.join("fidelity.json");
    let o = video2track(&[
        "experiment",
        "fidelity",
        "--repeats",
        "1",
        "--vut",
        "idm-normal",
        "--json",
        json.to_str().unwrap(),
    ]);
    let (out, err) = text(&o);
    assert!(o.status.success(), "{err}");
    for method in ["Predefined", "TroubleMaker-like", "Diffusion-only", "Video2Track"] {
        assert_eq!(out.matches(&format!("| {method} |")).count(), 3, "{out}");
    }
    let doc: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let cases = doc["cases"].as_array().unwrap();
    assert_eq!(cases.len(), 12, "3 scenarios × 4 methods × 1 VUT model");
    for c in cases {
        assert_eq!(c["collisions"], 0, "{c}");
        assert_eq!(c["repeats"], 1);
        assert!(c["mean_pet_min_s"].as_f64().unwrap() > 0.5, "{c}");
    }
    assert_eq!(doc["summary"].as_array().unwrap().len(), 12);
    // Every run's vehicles are measured against recorded human driving of their manoeuvre class:
    // lane changes, straight driving and (since 2026-11-27) left turns.
    assert!(out.contains("BV W₁ accel") && !out.contains("no human reference"), "{out}");
    for c in cases {
        let r = &c["bv_realism"];
        let scenario = c["scenario"].as_str().unwrap();
        let (bv, vut) = if scenario.starts_with("cut_in") {
            ("lane_change", "straight")
        } else if scenario.starts_with("left_turn_vut") {
            ("straight", "left_turn")
        } else {
            ("left_turn", "straight")
        };
        assert_eq!(r["class"], bv, "{c}");
        assert_eq!(r["measured"], 1, "{c}");
        assert!(r["means"]["w1_accel_mps2"].as_f64().unwrap() > 0.0, "{c}");
        assert_eq!(c["vut_realism"]["class"], vut, "{c}");
    }
    let taus: Vec<f64> = cases.iter().map(|c| c["tau_s"].as_f64().unwrap()).collect();
    assert!(taus.contains(&4.7) && taus.contains(&2.9), "the videos' PET labels are the targets: {taus:?}");
}

#[test]
fn steerability_compares_the_four_methods_on_request() {
    let dir_scratch = tempdir("steer-methods");
    let dir = dir_scratch.path();
    let json = dir.join("steer.json");
    let args = ["experiment", "steerability", "--methods", "--repeats", "1", "--tau", "3", "--vut", "idm-normal"];
    let o = video2track(&[&args[..], &["--json", json.to_str().unwrap()]].concat());
    let (out, err) = text(&o);
    assert!(o.status.success(), "{err}");
    assert!(out.contains("mean steering error"), "{out}");
    let doc: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert_eq!(doc["cases"].as_array().unwrap().len(), 24, "3 scenarios × 2 styles × 4 methods");
    let steering = doc["steering"].as_array().unwrap();
    assert_eq!(steering.len(), 4);
    for s in steering {
        assert_eq!(s["rows"], 6, "{s}");
        assert_eq!(s["vut"], "idm-normal", "per VUT model: {s}");
        assert!(s["mean_error_rel"].as_f64().unwrap().is_finite());
    }
}

#[test]
fn the_realism_tradeoff_sweeps_the_weight_and_draws_the_front() {
    let dir_scratch = tempdir("tradeoff");
    let dir = dir_scratch.path();
    let json = dir.join("tradeoff.json");
    let args = ["experiment", "tradeoff", "--repeats", "1", "--tau", "3", "--vut", "idm-normal", "--w-real", "0"];
    let o = video2track(
        &[&args[..], &["--w-real", "1", "--json", json.to_str().unwrap(), "--svg-dir", dir.to_str().unwrap()]].concat(),
    );
    let (out, err) = text(&o);
    assert!(o.status.success(), "{err}");
    assert!(out.contains("seeds 6–6") && out.contains("NGSIM"), "held-out seed and the reference named: {out}");
    let doc: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let points = doc["points"].as_array().unwrap();
    assert_eq!(points.len(), 5, "Diffusion-only, then 2 weights × the two regulated methods");
    assert_eq!(doc["cases"].as_array().unwrap().len(), 3 * 2 * 5, "3 scenarios × 2 styles × 5 points");
    for p in points {
        assert_eq!(p["errors"].as_array().unwrap().len(), 1, "one VUT model: {p}");
        assert_eq!(p["errors"][0]["rows"], 6, "3 scenarios × 2 styles: {p}");
        assert_eq!(p["collisions"], 0, "{p}");
    }
    // The cut-in's BV changes lanes, the left turn's turns left, the VUT-turning left turn's goes
    // straight: each has recorded human driving to be measured against, and a front.
    for name in ["cut_in", "left_turn", "left_turn_vut"] {
        let svg = std::fs::read_to_string(dir.join(format!("tradeoff_{name}.svg"))).unwrap();
        assert!(
            svg.starts_with("<svg") && svg.matches("class=\"series\"").count() == 6,
            "{name}: 2 panels × (2 methods and Diffusion-only)"
        );
    }
}

#[test]
fn experiment_options_an_experiment_would_ignore_are_refused() {
    for (args, needle) in [
        (&["experiment", "fidelity", "--tau", "3"][..], "unexpected argument '--tau' found"),
        (&["experiment", "fidelity", "--w-real", "1"][..], "unexpected argument '--w-real' found"),
        (&["experiment", "tradeoff", "--w-real", "-1"][..], "'--w-real <W_REAL>': must lie in [0, 1e6], got -1"),
        (&["experiment", "tradeoff", "--w-real", "NaN"][..], "'--w-real <W_REAL>': must lie in [0, 1e6], got NaN"),
        (
            &["experiment", "tradeoff", "--first-seed", "0"][..],
            "'--first-seed <FIRST_SEED>': 0 is not in 1..=9223372036854775807",
        ),
        (
            &["experiment", "adversariality", "--card", "config/scenarios/cut_in_basic.toml"][..],
            "unexpected argument '--card' found",
        ),
        (&["experiment", "steerability", "--tau", "0"][..], "τ must lie in [0.1, 30] s"),
        (&["experiment", "steerability", "--tau", "NaN"][..], "τ must lie in [0.1, 30] s"),
        (&["experiment", "steerability", "--repeats", "0"][..], "'--repeats <REPEATS>': 0 is not in 1..=1000000"),
        (
            &["experiment", "steerability", "--methods", "--card", "config/scenarios/cut_in_basic.toml"][..],
            "the argument '--methods' cannot be used with '--card <CARDS>'",
        ),
        (&["experiment", "adversariality", "--world", "sumo"][..], "unexpected argument '--world' found"),
        (&["experiment", "steerability", "--runs", "3"][..], "unexpected argument '--runs' found"),
        (&["experiment", "tradeoff", "--memory-dir", "x"][..], "unexpected argument '--memory-dir' found"),
        (&["experiment", "campaign", "--runs", "0"][..], "'--runs <RUNS>': 0 is not in 1..=1000"),
        (&["experiment", "campaign", "--methods"][..], "unexpected argument '--methods' found"),
        (&["experiment", "campaign", "--scenario", "cut_in"][..], "unexpected argument '--scenario' found"),
        (
            &["experiment", "steerability", "--world", "sumo", "--vut", "idm-normal"][..],
            "with --world sumo use --sumo-driver",
        ),
        (
            &["experiment", "steerability", "--scenario", "cut_in"][..],
            "required arguments were not provided:\n  --methods",
        ),
        (&["experiment", "fidelity", "--no-reach"][..], "unexpected argument '--no-reach' found"),
        (
            &["experiment", "steerability", "--sumo-driver", "config/vut/sumo/idm.toml"][..],
            "--sumo-driver applies with --world sumo",
        ),
        (
            &["sim", "config/scenarios/left_turn_vut.toml", "--sumo-driver", "config/vut/sumo/idm.toml"][..],
            "--sumo-driver applies with --world sumo",
        ),
        (&["experiment", "latency", "--tau", "3"][..], "unexpected argument '--tau' found"),
        (&["generate", "nothing.json", "--variants", "100000"][..], "--variants must lie in [1, 1000], got 100000"),
        (&["generate", "nothing.json", "--variants", "0"][..], "--variants must lie in [1, 1000], got 0"),
        (
            &["generate", "nothing.json", "--final-iterations", "4294967295"][..],
            "--final-iterations must lie in [0, 10000], got 4294967295",
        ),
        (&["generate", "nothing.json", "--guidance-scale", "NaN"][..], "--guidance-scale must lie in [0, 100]"),
        (
            &["experiment", "fidelity", "--network", "config/network/lte.toml"][..],
            "unexpected argument '--network' found",
        ),
        (
            &[
                "regulate",
                "config/scenarios/left_turn_basic.toml",
                "--broker",
                "mqtt://127.0.0.1:1",
                "--key",
                "config/keys/demo_cloud.key",
                "--start-unix-ms",
                "5",
            ][..],
            "--start-unix-ms 5 lies",
        ),
        (
            &[
                "regulate",
                "config/scenarios/left_turn_basic.toml",
                "--broker",
                "mqtt://127.0.0.1:1",
                "--key",
                "config/keys/demo_cloud.key",
                "--start-unix-ms",
                "5",
                "--bv-id",
                "a/#",
            ][..],
            "--bv-id \"a/#\"",
        ),
        (
            &["sim", "config/scenarios/left_turn_basic.toml", "--regulated", "--cloud-broker", "mqtt://127.0.0.1:1"][..],
            "--cloud-key",
        ),
    ] {
        let o = video2track(args);
        let (_, err) = text(&o);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(needle), "{args:?}: {err}");
    }
}

/// The regulator onboard against the same regulator in the cloud: per VUT model one onboard row and
/// one per network (the sweep, then the files asked for), the JSON's cases, and the plot.
#[test]
fn the_latency_experiment_compares_onboard_and_cloud_per_network() {
    let dir_scratch = tempdir("latency");
    let dir = dir_scratch.path();
    let (json, svg) = (dir.join("latency.json"), dir.join("latency.svg"));
    let o = video2track(&[
        "experiment",
        "latency",
        "--scenario",
        "left_turn",
        "--vut",
        "idm-normal",
        "--repeats",
        "1",
        "--network",
        "config/network/congested.toml",
        "--json",
        json.to_str().unwrap(),
        "--svg",
        svg.to_str().unwrap(),
    ]);
    let (out, err) = text(&o);
    assert!(o.status.success(), "{err}");
    assert!(out.contains("seeds 6–6: held out") && out.contains("networks simulated"), "{out}");
    assert!(out.contains("| onboard | every setting | 6 |"), "{out}");
    assert!(
        out.contains("| cloud | 300 ms, loss 5 % | 6 |") && out.contains("| cloud | congested cell | 6 |"),
        "{out}"
    );
    assert!(out.contains("- congested cell: preset") && out.contains("Collisions: "), "{out}");
    let doc: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert_eq!(doc["cases"].as_array().unwrap().len(), 6 * (1 + 12 + 1), "6 cases × (onboard + 13 networks)");
    assert_eq!(doc["summary"].as_array().unwrap().len(), 14);
    assert_eq!(doc["networks"].as_array().unwrap().len(), 13);
    let plot = std::fs::read_to_string(&svg).unwrap();
    assert_eq!(plot.matches("class=\"series\"").count(), 3, "onboard, cloud without and with loss: {plot}");
}

/// One run with the regulator in the cloud across a simulated network, and a network file out of
/// bounds refused with its field (exit 2).
#[test]
fn sim_regulates_in_the_cloud_across_a_network_file_and_refuses_a_bad_one() {
    let o = video2track(&[
        "sim",
        "config/scenarios/left_turn_basic.toml",
        "--regulated",
        "--network",
        "config/network/lte.toml",
        "--seed",
        "3",
    ]);
    let (out, err) = text(&o);
    assert!(o.status.success(), "{err}");
    assert!(out.contains("regulated in the cloud across the simulated network LTE"), "{out}");
    assert!(out.contains("BV cloud regulator") && out.contains("collision none"), "{out}");
    let link = out.lines().find(|l| l.starts_with("link:")).unwrap();
    assert!(link.contains("refused 0"), "{link}");
    let dir_scratch = tempdir("network");
    let bad = dir_scratch.path().join("bad.toml");
    let text_of = std::fs::read_to_string(repo().join("config/network/lte.toml")).unwrap();
    std::fs::write(&bad, text_of.replacen("loss = 0.0", "loss = 1.5", 1)).unwrap();
    let o = video2track(&[
        "sim",
        "config/scenarios/left_turn_basic.toml",
        "--regulated",
        "--network",
        bad.to_str().unwrap(),
    ]);
    let (_, err) = text(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("uplink.loss") && err.contains("0.99"), "{err}");
}

/// One test run three times as a campaign: the memory file is made on the first run and read on
/// the next, the aim moves, the file refuses another VUT, a broken file is bad input; `campaign`
/// gives the aim, records a track run and shows the memory.
#[test]
fn sim_runs_one_run_of_a_campaign_and_keeps_its_memory_in_a_file() {
    let scratch = tempdir("campaign");
    let memory = scratch.path().join("reactive.json");
    let card = "config/scenarios/left_turn_basic.toml";
    let run =
        |seed: &str| ok(&["sim", card, "--vut", "reactive", "--seed", seed, "--regulated", "--campaign", s(&memory)]);
    let first = run("1");
    assert!(first.contains("before the run: no earlier run: aims at τ"), "{first}");
    assert!(first.contains("after the run: 1 runs before"), "{first}");
    let file = std::fs::read_to_string(&memory).unwrap();
    assert!(file.contains("\"vut\": \"reactive\"") && file.contains("\"world\": \"builtin\""), "{file}");
    let second = run("2");
    assert!(second.contains("before the run: 1 runs before"), "{second}");
    // What run 1 showed of how the VUT drives its route is the second run's model of the VUT, so
    // it aims at τ again; the third aims where the second's miss says.
    assert!(second.contains("the VUT's speed along its route learned over 1 run(s)"), "{second}");
    let aimed = |text: &str| text.lines().find(|l| l.starts_with("BV 0 regulated, aiming at")).unwrap().to_owned();
    assert!(aimed(&second).contains("aiming at 2.00 s for τ 2.00 s"), "{second}");
    let third = run("3");
    assert!(third.contains("learned over 2 run(s)"), "{third}");

    // Another VUT's run is refused: nothing learned leaks.
    let o = video2track(&["sim", card, "--vut", "idm-cautious", "--regulated", "--campaign", s(&memory)]);
    let (_, err) = text(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("learned from VUT `reactive`") && err.contains("`idm-cautious`"), "{err}");
    // --campaign needs --regulated.
    let o = video2track(&["sim", card, "--campaign", s(&memory)]);
    assert_eq!(o.status.code(), Some(2));

    // The track's side: the aim, a measured run recorded, the memory shown.
    let aim = ok(&["campaign", "aim", s(&memory), "--scenario", "left_turn_basic", "--style", "rush", "--tau", "2"]);
    let aim: f64 = aim.trim().parse().unwrap();
    assert!((1.0..=3.0).contains(&aim), "{aim}");
    let recorded = ok(&[
        "campaign",
        "record",
        s(&memory),
        "--scenario",
        "left_turn_basic",
        "--style",
        "rush",
        "--tau",
        "2",
        "--vut",
        "reactive",
        "--world",
        "builtin",
        "--aim",
        &aim.to_string(),
        "--pet",
        "2.95",
    ]);
    assert!(recorded.contains("4 runs before"), "{recorded}");
    let shown = ok(&["campaign", "show", s(&memory)]);
    assert!(
        shown.contains("campaign memory of VUT `reactive`") && shown.contains("left_turn_basic BV 0 rush"),
        "{shown}"
    );
    let o = video2track(&[
        "campaign",
        "record",
        s(&memory),
        "--scenario",
        "x",
        "--style",
        "rush",
        "--tau",
        "2",
        "--vut",
        "reactive",
        "--world",
        "builtin",
        "--aim",
        "2",
        "--pet",
        "NaN",
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(text(&o).1.contains("--pet must lie in [0, 3600] s, got NaN"));

    // A memory that does not parse or validate: bad input naming the file.
    std::fs::write(&memory, "{\"format\": 1, \"vut\": \"reactive\", \"world\": \"builtin\", \"cases\": [{\"scenario\": \"s\", \"bv\": 0, \"style\": \"rush\", \"tau_s\": 1e300, \"memory\": {\"runs\": [], \"offset_s\": 0, \"gain\": 1, \"dropped\": false, \"learned_error_s\": 0, \"default_error_s\": 0, \"compared\": 0, \"below_reach\": null}}]}").unwrap();
    for args in [
        vec!["sim", card, "--vut", "reactive", "--regulated", "--campaign", s(&memory)],
        vec!["campaign", "show", s(&memory)],
    ] {
        let o = video2track(&args);
        let (_, err) = text(&o);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains("reactive.json") && err.contains("cases[0].tau_s"), "{err}");
    }
}

/// `campaign record --learned` reads what a BV reported from a session log; a log that is not
/// one, or holds no report of that run, is bad input (exit 2) and the memory is not written.
/// (The report crossing a broker from a running BV: `tests/fleet.rs`.)
#[test]
fn campaign_record_takes_what_the_bv_learned_only_from_a_report_of_that_run() {
    let scratch = tempdir("learned");
    let memory = scratch.path().join("ads.json");
    let log = scratch.path().join("session.jsonl");
    // Every call records in the test `left_turn` rush τ 2 s of VUT `ads` from the session log;
    // `run` adds what a run's record needs, `extra` the rest.
    let record_with = |run: &[&str], extra: &[&str]| {
        let mut args = vec!["campaign", "record", s(&memory), "--scenario", "left_turn", "--style", "rush", "--tau"];
        args.extend_from_slice(&["2", "--vut", "ads", "--learned", s(&log)]);
        args.extend_from_slice(run);
        args.extend_from_slice(extra);
        video2track(&args)
    };
    let record = |extra: &[&str]| record_with(&["--aim", "2", "--pet", "2.1"], extra);
    let telemetry = r#"{"received_ms":1,"topic":"v2t/pg/bv/bv1/telemetry","message":{"bv_id":"bv1"}}"#;
    for (content, says) in [
        ("not json\n", "session.jsonl line 1: not JSON"),
        (telemetry, "no report of what bv1 learned in the run of prior 41"),
        (
            r#"{"topic":"v2t/pg/bv/bv1/learned","message":{"bv_id":"bv1","prior_id":41,"stamp_ms":1,"aim":{"tau_s":99.0,"style":"rush"},"started_with_route":false,"started_with_reaction":false,"route":null,"reaction":null}}"#,
            "session.jsonl line 1: not a run's report",
        ),
    ] {
        std::fs::write(&log, content).unwrap();
        let o = record(&["--from-bv", "bv1", "--prior-id", "41"]);
        let (_, err) = text(&o);
        assert_eq!(o.status.code(), Some(2), "{err}");
        assert!(err.contains(says), "{says}: {err}");
        assert!(!memory.exists(), "nothing recorded from a bad log");
    }
    // --learned names a run: without the BV and the prior it is refused by the parser.
    let o = record(&[]);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o).1);

    // A report as `serve --log` keeps it: a free drive's (the BV parked, never started) teaches
    // the route alone; a regulated run's is a run of the test with what it learned.
    let report = |prior_id: u64, speed: f64| {
        let r = v2t_wire::link::RunLearned {
            bv_id: "bv1".into(),
            prior_id,
            stamp_ms: 1,
            aim: v2t_model::Target::new(2.0, v2t_model::Style::Rush).unwrap(),
            started_with_route: prior_id == 42,
            started_with_reaction: false,
            route: Some(v2t_wire::link::LearnedRoute { step_m: 2.0, runs: 1, speeds_mps: vec![speed; 30] }),
            reaction: None,
        };
        serde_json::json!({"received_ms": 2, "topic": "v2t/pg/bv/bv1/learned", "message": r}).to_string()
    };
    std::fs::write(&log, format!("{telemetry}\n{}\n{}\n", report(41, 7.0), report(42, 8.0))).unwrap();
    let free = |extra: &[&str]| record_with(&["--free-drive", "--from-bv", "bv1", "--prior-id", "41"], extra);
    let o = free(&["--aim", "2"]);
    assert_eq!(o.status.code(), Some(2), "a free drive has no aim: {}", text(&o).1);
    let o = free(&[]);
    let (out, err) = text(&o);
    assert!(o.status.success() && err.contains("free drive: the VUT's route learned to 58 m"), "{err}");
    assert!(out.contains("0 runs before") && out.contains("route learned over 1 run(s), to 58 m"), "{out}");
    let o = record(&["--from-bv", "bv1", "--prior-id", "42"]);
    let (out, err) = text(&o);
    assert!(o.status.success() && err.contains("from the BV's report: route over 1 run(s), 58 m"), "{err}");
    assert!(out.contains("1 runs before (1 with a PET in order)"), "{out}");
    assert!(out.contains("route learned over 2 run(s), to 58 m"), "the free drive's and the run's: {out}");
}

/// A free drive: the BVs parked, the VUT alone; what it showed is recorded for the test and the
/// first regulated run knows it without being a second run; the options that make no sense with
/// it are refused with exit 2.
#[test]
fn sim_drives_the_test_freely_and_the_first_regulated_run_knows_the_route() {
    let scratch = tempdir("free-drive");
    let memory = scratch.path().join("idm.json");
    let card = "config/scenarios/left_turn_vut.toml";
    let free = ok(&["sim", card, "--vut", "idm-normal", "--free-drive", "--campaign", s(&memory)]);
    assert!(free.contains("free drive: every BV parked where it starts"), "{free}");
    assert!(free.contains("BV 0: the VUT's route learned to 84 m"), "{free}");
    assert!(free.contains("BV parked"), "{free}");
    let first = ok(&["sim", card, "--vut", "idm-normal", "--regulated", "--campaign", s(&memory)]);
    assert!(first.contains("before the run: 0 runs before") && first.contains("learned over 1 run(s)"), "{first}");
    assert!(first.contains("aiming at 2.00 s for τ 2.00 s"), "{first}");
    for args in [
        vec!["sim", card, "--free-drive", "--regulated"],
        vec!["sim", card, "--campaign", s(&memory)],
        vec!["sim", card, "--vut", "reactive", "--free-drive", "--campaign", s(&memory)],
    ] {
        let o = video2track(&args);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {}", text(&o).1);
    }
    // What it learned goes to the BV with `campaign send` (crossing a broker: `tests/fleet.rs`);
    // for every BV at once, or from a file that is no memory, it does not go: exit 2, before any
    // connection (the broker here does not exist).
    let broken = scratch.path().join("broken.json");
    std::fs::write(&broken, "{").unwrap();
    let send = |memory: &str, to: &str| {
        video2track(&[
            "campaign",
            "send",
            memory,
            "--scenario",
            "left_turn_vut",
            "--style",
            "rush",
            "--tau",
            "2",
            "--to",
            to,
            "--prior-id",
            "1",
            "--broker",
            "mqtt://127.0.0.1:1",
        ])
    };
    for (memory, to, says) in [
        (s(&memory), "all", "--to must name one BV"),
        (s(&memory), "bv/1", "--to must name one BV"),
        (s(&broken), "bv1", "broken.json: not a campaign memory"),
    ] {
        let o = send(memory, to);
        let (_, err) = text(&o);
        assert_eq!(o.status.code(), Some(2), "{to}: {err}");
        assert!(err.contains(says), "{to}: {err}");
    }
}

#[test]
fn a_campaign_experiment_reports_per_vut_and_writes_the_memories() {
    let scratch = tempdir("campaign-exp");
    let dir = scratch.path();
    let json = dir.join("campaign.json");
    let out = ok(&[
        "experiment",
        "campaign",
        "--card",
        "config/scenarios/cut_in_basic.toml",
        "--tau",
        "3",
        "--vut",
        "idm-normal",
        "--repeats",
        "1",
        "--runs",
        "3",
        "--no-reach",
        "--memory-dir",
        s(dir),
        "--json",
        s(&json),
    ]);
    assert!(out.contains("; campaigns: seeds 6–6: held out from the tuning seeds 1–5"), "{out}");
    assert!(out.contains("Campaigns of 3 runs") && out.contains("| idm-normal | cut_in_basic | rush | 3.0 |"), "{out}");
    let memory = std::fs::read_to_string(dir.join("idm-normal/campaign-6.json")).unwrap();
    assert!(
        memory.contains("\"cut_in_basic\"") && memory.matches("\"aim_s\"").count() == 6,
        "2 tests × 3 runs: {memory}"
    );
    let report: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert_eq!(report["cases"].as_array().unwrap().len(), 2);
    assert_eq!(report["cases"][0]["runs"].as_array().unwrap().len(), 3);
    assert_eq!(report["cases"][0]["runs"][0]["seed"], 6001);
    assert_eq!(report["per_vut"][0]["vut"], "idm-normal");
}

#[test]
fn steerability_writes_the_documented_json() {
    let dir_scratch = tempdir("steer");
    let dir = dir_scratch.path();
    let json = dir.join("steer.json");
    let o = video2track(&[
        "experiment",
        "steerability",
        "--repeats",
        "1",
        "--tau",
        "3",
        "--vut",
        "sampling",
        "--card",
        "config/scenarios/left_turn_basic.toml",
        "--json",
        json.to_str().unwrap(),
    ]);
    let (out, err) = text(&o);
    assert!(o.status.success(), "{err}");
    assert!(out.contains("| left_turn_basic | rush | sampling | 3.0 |"), "{out}");
    let v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let cases = v["cases"].as_array().unwrap();
    assert_eq!(cases.len(), 2, "rush and yield");
    for key in [
        "scenario",
        "style",
        "vut",
        "tau_s",
        "repeats",
        "mean_pet_min_s",
        "pet_min_track_s",
        "error_rel",
        "collisions",
        "zone_overlaps",
        "order_ok_frac",
        "world",
        "reachable",
    ] {
        assert!(cases[0].get(key).is_some(), "missing {key}");
    }
    assert!(v["mean_error_rel"].is_number() && v["max_error_rel"].is_number());
    // The open-loop grid ran against the VUT on the card and marked each case: at this crossing
    // with a stop line, its 250 profiles twice (once keeping the yield rule).
    let reach = v["reach"].as_array().unwrap();
    assert_eq!(reach.len(), 1);
    assert_eq!((reach[0]["profiles"].as_u64(), reach[0]["vut"].as_str()), (Some(500), Some("sampling")));
    assert!(reach[0]["unreadable_yields"].is_u64(), "{:?}", reach[0]);
    assert!(cases.iter().all(|c| c["reachable"].is_boolean() && c["world"] == "builtin"), "{cases:?}");
    assert!(v["reachable_errors"].is_array() && out.contains("τ reachable"), "{out}");
}

#[test]
fn a_bad_regulator_file_is_an_input_error() {
    let dir_scratch = tempdir("regulator");
    let dir = dir_scratch.path();
    let path = dir.join("regulator.toml");
    let original = std::fs::read_to_string(repo().join("config/regulator/default.toml")).unwrap();
    std::fs::write(&path, original.replace("horizon = 50", "horizon = 1")).unwrap();
    let o = video2track(&["experiment", "steerability", "--repeats", "1", "--regulator", path.to_str().unwrap()]);
    let (_, err) = text(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("regulator.toml") && err.contains("horizon"), "{err}");
}

#[test]
fn map_inspect_and_ground_work_on_the_proving_ground() {
    let dir_scratch = tempdir("ground");
    let dir = dir_scratch.path();
    let lib = dir.join("library.json");
    let svg = dir.join("pg.svg");
    let o = video2track(&[
        "map",
        "inspect",
        "config/maps/proving_ground.xodr",
        "--json",
        lib.to_str().unwrap(),
        "--svg",
        svg.to_str().unwrap(),
    ]);
    let (out, err) = text(&o);
    assert!(o.status.success(), "{err}");
    assert!(out.contains("fragments:") && out.contains("annotations"), "{out}");
    let v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&lib).unwrap()).unwrap();
    assert!(!v["library"]["fragments"].as_array().unwrap().is_empty());
    assert!(std::fs::read_to_string(&svg).unwrap().starts_with("<svg"));

    for (example, anchor) in [("semantics_cut_in", "/cutin/"), ("semantics_left_turn", "/x/")] {
        let scenario = dir.join(format!("{example}.grounded.json"));
        let full = dir.join(format!("{example}.grounding.json"));
        let o = video2track(&[
            "ground",
            &format!("config/examples/{example}.json"),
            "--top",
            "2",
            "--out",
            scenario.to_str().unwrap(),
            "--json",
            full.to_str().unwrap(),
        ]);
        let (out, err) = text(&o);
        assert!(o.status.success(), "{example}: {err}");
        assert!(out.contains("ranking:") && out.contains("#2 ") && !out.contains("#3 "), "{out}");
        assert!(out.contains("grounded on") && out.contains("planned PET"), "{out}");
        let s: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&scenario).unwrap()).unwrap();
        assert_eq!(s["agents"][0]["role"], "vut", "{s}");
        let anchor_id = s["conflicts"][0]["anchor_id"].as_str().unwrap();
        assert!(anchor_id.contains(anchor), "{anchor_id}");
        let g: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&full).unwrap()).unwrap();
        assert_eq!(g["scenario"], s);
        assert!(g["ranking"].as_array().unwrap().len() >= 2 && g["timing"].as_array().unwrap().len() == 1);
    }
}

#[test]
fn ground_refuses_bad_semantics_and_explains_a_misfit() {
    let dir_scratch = tempdir("ground-bad");
    let dir = dir_scratch.path();
    let bad = dir.join("bad.json");
    std::fs::write(&bad, "{ \"road_topology\": 3 }").unwrap();
    let o = video2track(&["ground", bad.to_str().unwrap()]);
    let (_, err) = text(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("bad.json") && err.contains("line 1"), "{err}");

    let missing_map = video2track(&["ground", "config/examples/semantics_cut_in.json", "--map", "no/such.xodr"]);
    assert_eq!(missing_map.status.code(), Some(2), "{}", text(&missing_map).1);

    // A roundabout: the proving ground has none, and every fragment says why not.
    let o = video2track(&["ground", "cloud/ground/tests/data/roundabout.json"]);
    let (out, err) = text(&o);
    assert_eq!(o.status.code(), Some(1), "{out}\n{err}");
    assert!(
        out.contains("ranking:") && err.contains("no fragment of the library fits") && err.contains("J100"),
        "{err}"
    );
}

#[test]
fn a_bad_sumo_driver_file_is_refused_before_sumo_starts() {
    let dir_scratch = tempdir("sumo-driver");
    let path = dir_scratch.path().join("driver.toml");
    std::fs::write(&path, "name = \"sumo-x\"\ndescription = \"x\"\n[vtype]\nlength = 9.0\n").unwrap();
    let o = video2track(&[
        "sim",
        "config/scenarios/left_turn_vut.toml",
        "--world",
        "sumo",
        "--sumo-driver",
        path.to_str().unwrap(),
    ]);
    let (_, err) = text(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("driver.toml") && err.contains("vtype.length") && err.contains("vehicle file"), "{err}");
}

#[test]
fn sim_runs_a_card_with_sumo_driving_the_vut() {
    let found = v2t_sumo::SumoBinaries::find().is_ok();
    if !v2t_test_support::found_or_not_run(found, "SUMO (sumo, netconvert)", v2t_sumo::INSTALL_HINT) {
        return;
    }
    let dir_scratch = tempdir("sim-sumo");
    let json = dir_scratch.path().join("run.json");
    let o = video2track(&[
        "sim",
        "config/scenarios/left_turn_vut.toml",
        "--world",
        "sumo",
        "--sumo-driver",
        "config/vut/sumo/impatient.toml",
        "--json",
        json.to_str().unwrap(),
    ]);
    let (out, err) = text(&o);
    assert!(o.status.success(), "{err}");
    assert!(
        out.contains("VUT sumo-impatient") && out.contains("VUT driven by SUMO") && out.contains("first through"),
        "{out}"
    );
    let v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert_eq!(v["result"]["vut_model"], "sumo-impatient");
    assert!(v["result"]["collision"].is_null(), "{}", v["result"]);
}

/// One exit-code rule for every command (README, "Exit codes"): 0 done, 1 the work failed, 2 bad
/// input or usage. Every command that reads a file the user names answers a missing one with 2 and
/// the file's name, before it starts anything; every command answers an unknown option with 2.
#[test]
fn every_command_follows_one_exit_code_rule() {
    let scratch = tempdir("exit-codes");
    let dir = scratch.path();
    let missing = dir.join("missing.file");
    let m = s(&missing);
    let out = |name: &str| dir.join(name).to_str().unwrap().to_owned();
    let (mp4, xosc, jsonl) = (out("x.mp4"), out("x.xosc"), out("x.jsonl"));
    let key = "config/keys/demo_cloud.key";
    let commands: Vec<Vec<&str>> = vec![
        vec!["sim", m],
        vec!["replay", m],
        vec!["render", m, "--out", &mp4],
        vec!["experiment", "steerability", "--card", m],
        vec!["experiment", "latency", "--network", m],
        vec!["campaign", "show", m],
        vec!["generate", m],
        vec!["realism", "--weights", m],
        vec!["corpus", "import", m, "--dataset", "d", "--licence", "l", "-o", &jsonl],
        vec!["corpus", "stats", m],
        vec!["train", "--data", m],
        vec!["ground", m],
        vec!["export", "xosc", m, "-o", &xosc],
        vec!["map", "inspect", m],
        vec!["serve", "--key", m],
        vec!["upload", m, "--bv", "bv1"],
        vec!["send", "abort", "--key", m],
        vec!["regulate", m, "--broker", "mqtt://127.0.0.1:1", "--key", key, "--start-unix-ms", "1"],
    ];
    for args in &commands {
        let o = video2track(args);
        let (_, err) = text(&o);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
        // `regulate` checks its start time first: a usage error, also 2.
        assert!(err.contains("missing.file") || args[0] == "regulate", "{args:?} does not name the file: {err}");
    }
    for command in COMMANDS {
        let o = video2track(&[command, "--no-such-option"]);
        assert_eq!(o.status.code(), Some(2), "{command}: {}", text(&o).1);
    }
    // A failure of the work is 1: a key pair that exists already is not overwritten.
    let keys = out("keys");
    ok(&["keygen", "--out", &keys]);
    let o = video2track(&["keygen", "--out", &keys]);
    assert_eq!(o.status.code(), Some(1), "{}", text(&o).1);
    assert!(text(&o).1.contains("exists already"), "{}", text(&o).1);
}

/// `video2track … | head`: a reader that closes stdout before the command is done ends the command
/// quietly with 0 (nothing failed and the input was fine), never with `println!`'s panic (101).
#[test]
fn a_closed_stdout_ends_a_command_quietly() {
    use std::io::BufRead as _;
    use std::process::{Command, Stdio};
    let spawn = |args: &[&str]| {
        Command::new(env!("CARGO_BIN_EXE_video2track"))
            .args(args)
            .current_dir(repo())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap()
    };
    let quiet = |args: &[&str], o: std::process::Output| {
        let (_, err) = text(&o);
        assert!(!err.contains("panicked") && !err.contains("Broken pipe"), "{args:?}: {err}");
        assert_eq!(o.status.code(), Some(0), "{args:?}: {err}");
    };
    // Closed before the command has written anything: its first line meets the closed pipe.
    let commands: [&[&str]; 4] = [
        &["sim", "config/scenarios/cut_in_basic.toml"],
        &["map", "inspect", "config/maps/proving_ground.xodr"],
        &["ground", "config/examples/semantics_cut_in.json"],
        &["--help"],
    ];
    for args in commands {
        let mut child = spawn(args);
        drop(child.stdout.take());
        quiet(args, child.wait_with_output().unwrap());
    }
    // `| head -1`: one line read, then the reader goes; the run goes on writing its JSON and says
    // so on the closed pipe.
    let scratch = tempdir("closed-stdout");
    let json = scratch.path().join("run.json");
    let args = ["sim", "config/scenarios/cut_in_basic.toml", "--json", s(&json)];
    let mut child = spawn(&args);
    let mut first = String::new();
    std::io::BufReader::new(child.stdout.take().unwrap()).read_line(&mut first).unwrap();
    assert!(!first.trim().is_empty(), "no first line");
    quiet(&args, child.wait_with_output().unwrap());
}

/// `map inspect` on an OpenDRIVE file whose every road is refused names the file (exit 2).
#[test]
fn map_inspect_names_a_file_without_a_usable_road() {
    let scratch = tempdir("no-road");
    let map = scratch.path().join("every_road_refused.xodr");
    std::fs::write(
        &map,
        r#"<?xml version="1.0"?><OpenDRIVE><header revMajor="1" revMinor="4" name="t"/>
<road id="1" length="50" junction="-1">
  <planView><geometry s="0" x="0" y="0" hdg="0" length="50"><spiral/></geometry></planView>
  <lanes><laneSection s="0">
    <center><lane id="0" type="none"/></center>
    <right><lane id="-1" type="driving"><width sOffset="0" a="3.5" b="0" c="0" d="0"/></lane></right>
  </laneSection></lanes>
</road></OpenDRIVE>"#,
    )
    .unwrap();
    let o = video2track(&["map", "inspect", s(&map)]);
    let (_, err) = text(&o);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains(s(&map)) && err.contains("no usable road"), "{err}");
    assert!(!err.contains("panicked"), "{err}");
}
