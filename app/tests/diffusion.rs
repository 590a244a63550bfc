//! `video2track generate`, `train` and `realism` end to end: the shipped weights give priors that
//! meet their grounded scenarios (anchors, solid boundaries, vehicle limits, passing order); a small
//! training run writes weights, metrics and checkpoints that `generate` and `realism` read; bad
//! input (no route, a number out of range, foreign or damaged weights) is a clear error.

#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)] // test code

mod common;

use std::path::Path;

use common::{ok, s, tempdir, video2track};
use v2t_model::prior::TrajectoryPrior;
use v2t_model::validate::Validate as _;

fn fails(args: &[&str]) -> String {
    let o = video2track(args);
    assert!(!o.status.success(), "{args:?} succeeded: {}", String::from_utf8_lossy(&o.stdout));
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn grounded(dir: &Path, which: &str) -> std::path::PathBuf {
    common::ground_example(dir, which)
}

#[test]
fn shipped_weights_generate_priors_that_meet_their_scenarios() {
    let dir_scratch = tempdir("generate");
    let dir = dir_scratch.path();
    for which in ["cut_in", "left_turn"] {
        let g = grounded(dir, which);
        let prior_path = dir.join(format!("{which}.prior.json"));
        let metrics_path = dir.join(format!("{which}.metrics.json"));
        let all = dir.join(format!("{which}-all"));
        let text = ok(&[
            "generate",
            s(&g),
            "--variants",
            "6",
            "--out",
            s(&prior_path),
            "--all",
            s(&all),
            "--json-metrics",
            s(&metrics_path),
        ]);
        assert!(text.contains("| full | 6 |"), "{text}");
        let prior: TrajectoryPrior = serde_json::from_str(&std::fs::read_to_string(&prior_path).unwrap()).unwrap();
        prior.validate().unwrap();
        assert!(prior.agents.iter().all(|a| a.rollout_gap_m(prior.dt_s) < 1e-6), "states are rollouts of the controls");
        assert_eq!(std::fs::read_dir(&all).unwrap().count(), 6);
        let m: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&metrics_path).unwrap()).unwrap();
        let summary = &m["summary"];
        assert!(summary["median_anchor_error_m"].as_f64().unwrap() <= 0.5, "{which}: {summary}");
        assert_eq!(summary["boundary_crossings"].as_u64(), Some(0), "{which}: {summary}");
        assert_eq!(summary["within_limits_frac"].as_f64(), Some(1.0), "{which}: {summary}");
        assert_eq!(summary["order_ok_frac"].as_f64(), Some(1.0), "{which}: {summary}");
        assert_eq!(m["variants"].as_array().unwrap().len(), 6);
        // The same seed gives the same priors.
        let again = dir.join(format!("{which}.again.json"));
        ok(&["generate", s(&g), "--variants", "6", "--out", s(&again)]);
        assert_eq!(std::fs::read_to_string(&again).unwrap(), std::fs::read_to_string(&prior_path).unwrap());
    }
}

#[test]
fn ablation_switches_change_the_result() {
    let dir_scratch = tempdir("ablation");
    let dir = dir_scratch.path();
    let g = grounded(dir, "cut_in");
    let metrics = |guidance: &str| -> serde_json::Value {
        let path = dir.join(format!("{guidance}.json"));
        ok(&["generate", s(&g), "--variants", "4", "--guidance", guidance, "--draws", "1", "--json-metrics", s(&path)]);
        serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap()
    };
    let none = metrics("none");
    let full = metrics("full");
    assert_eq!(none["guidance"], "no guidance");
    let err = |m: &serde_json::Value| m["summary"]["median_anchor_error_m"].as_f64().unwrap();
    assert!(err(&none) > 3.0 * err(&full), "guidance brings the anchors: none {} full {}", err(&none), err(&full));
}

/// A prior that meets none of its criteria is not written (exit 1, the reasons named) unless asked
/// for with `--write-failing`; the metrics are written either way.
#[test]
fn a_prior_that_meets_no_criterion_is_refused_unless_asked_for() {
    let dir_scratch = tempdir("refuse");
    let dir = dir_scratch.path();
    let g = grounded(dir, "cut_in");
    let (prior, metrics) = (dir.join("prior.json"), dir.join("metrics.json"));
    // The bare denoiser, no redraw: seed 1 crosses a solid boundary and misses its anchors by 15 m.
    let args =
        ["generate", s(&g), "--guidance", "none", "--draws", "1", "--out", s(&prior), "--json-metrics", s(&metrics)];
    let o = video2track(&args);
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(err.contains("no prior written") && err.contains("anchor error above 5 m"), "{err}");
    assert!(!prior.exists(), "a refused prior was written");
    assert!(metrics.exists(), "the metrics say why");
    let mut forced = args.to_vec();
    forced.push("--write-failing");
    let o = video2track(&forced);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(String::from_utf8_lossy(&o.stderr).contains("writing the best anyway"));
    assert!(prior.exists());
}

#[test]
fn bad_input_is_a_clear_error() {
    let dir_scratch = tempdir("bad");
    let dir = dir_scratch.path();
    let g = grounded(dir, "cut_in");
    let text = std::fs::read_to_string(&g).unwrap();
    let mut value: serde_json::Value = serde_json::from_str(&text).unwrap();
    value["agents"][0]["route"] = serde_json::json!([]);
    let no_route = dir.join("no_route.json");
    std::fs::write(&no_route, serde_json::to_string(&value).unwrap()).unwrap();
    let err = fails(&["generate", s(&no_route)]);
    assert!(err.contains("route"), "{err}");
    // A number out of range where an anchor's position belongs (JSON has no NaN).
    let out_of_range = text.replacen("\"x\":", "\"x\": 1e400, \"ignored\":", 1);
    let bad_anchor = dir.join("bad_anchor.json");
    std::fs::write(&bad_anchor, out_of_range).unwrap();
    let err = fails(&["generate", s(&bad_anchor)]);
    assert!(err.contains("not a grounded scenario"), "{err}");
    let garbage = dir.join("garbage.safetensors");
    std::fs::write(&garbage, b"\x08\x00\x00\x00\x00\x00\x00\x00{}garbage").unwrap();
    let err = fails(&["generate", s(&g), "--weights", s(&garbage)]);
    assert!(err.contains("garbage.safetensors") && err.contains("not a safetensors file"), "{err}");
    let err = fails(&["generate", s(&g), "--weights", s(&dir.join("missing.safetensors"))]);
    assert!(err.contains("missing.safetensors"), "{err}");
}

#[test]
fn a_small_training_run_writes_weights_that_generate_and_realism_read() {
    let dir_scratch = tempdir("train");
    let dir = dir_scratch.path();
    let out = dir.join("run");
    let text = ok(&[
        "train",
        "--episodes",
        "40",
        "--steps",
        "6",
        "--batch",
        "8",
        "--hidden",
        "8",
        "--blocks",
        "1",
        "--eval-every",
        "3",
        "--checkpoint-every",
        "3",
        "--out",
        s(&out),
    ]);
    assert!(text.contains("held-out loss"), "{text}");
    let metrics = std::fs::read_to_string(out.join("metrics.jsonl")).unwrap();
    let lines: Vec<serde_json::Value> = metrics.lines().map(|l| serde_json::from_str(l).unwrap()).collect();
    assert_eq!(lines.iter().map(|l| l["step"].as_u64().unwrap()).collect::<Vec<_>>(), vec![3, 6]);
    assert!(lines.iter().all(|l| l["heldout_loss"].as_f64().unwrap().is_finite()));
    for step in ["step-000003", "step-000006"] {
        assert!(out.join("checkpoints").join(format!("{step}.safetensors")).exists());
    }
    let weights = out.join("denoiser.safetensors");
    let g = grounded(dir, "cut_in");
    let prior = dir.join("prior.json");
    // Weights trained for seconds meet no criterion: written anyway, on request.
    ok(&["generate", s(&g), "--weights", s(&weights), "--out", s(&prior), "--write-failing"]);
    let p: TrajectoryPrior = serde_json::from_str(&std::fs::read_to_string(&prior).unwrap()).unwrap();
    p.validate().unwrap();
    let table = ok(&["realism", "--weights", s(&weights), "--episodes", "40", "--windows", "3"]);
    for row in ["training data (floor)", "no guidance", "anchor only", "full"] {
        assert!(table.contains(row), "{table}");
    }
}

fn recordings(split: &str) -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../config/diffusion/recordings/ngsim").join(split)
}

#[test]
fn recorded_corpus_imports_counts_trains_and_measures_realism() {
    let dir_scratch = tempdir("corpus");
    let dir = dir_scratch.path();
    let licence = "NGSIM: US DOT public data; CommonRoad conversion BSD-3-Clause / MIT";
    let (train, heldout) = (dir.join("train.jsonl"), dir.join("heldout.jsonl"));
    let text = ok(&[
        "corpus",
        "import",
        s(&recordings("train")),
        "--dataset",
        "NGSIM train",
        "--licence",
        licence,
        "-o",
        s(&train),
    ]);
    assert!(text.contains("imported 7 files: 198 tracks"), "{text}");
    ok(&[
        "corpus",
        "import",
        s(&recordings("heldout")),
        "--dataset",
        "NGSIM held out",
        "--licence",
        licence,
        "-o",
        s(&heldout),
    ]);
    let stats = ok(&["corpus", "stats", s(&train), s(&heldout), "--json", s(&dir.join("stats.json"))]);
    assert!(
        stats.contains("| NGSIM train | NGSIM: US DOT public data") && stats.contains("total: 250 tracks"),
        "{stats}"
    );
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("stats.json")).unwrap()).unwrap();
    assert_eq!(json["tracks"], 250);
    // A few steps on the recordings from the shipped weights, held out by recording.
    let out = dir.join("run");
    let shipped = Path::new(env!("CARGO_MANIFEST_DIR")).join("../config/diffusion/denoiser.safetensors");
    let text = ok(&[
        "train",
        "--data",
        s(&train),
        "--heldout-data",
        s(&heldout),
        "--init",
        s(&shipped),
        "--steps",
        "2",
        "--batch",
        "4",
        "--eval-every",
        "2",
        "--checkpoint-every",
        "0",
        "--out",
        s(&out),
    ]);
    assert!(text.contains("held-out loss"), "{text}");
    let weights = out.join("denoiser.safetensors");
    let meta = v2t_diffusion::weights::load(&weights).unwrap().meta;
    assert!(!meta.training.synthetic && meta.training.data.contains("NGSIM held out"), "{:?}", meta.training);
    let table = ok(&[
        "realism",
        "--weights",
        s(&weights),
        "--data",
        s(&heldout),
        "--heldout-data",
        s(&train),
        "--windows",
        "3",
    ]);
    for row in ["training data (floor)", "no guidance", "anchor only", "full"] {
        assert!(table.contains(row), "{table}");
    }
}

#[test]
fn a_csv_recording_imports_with_its_driven_paths_as_routes() {
    let dir_scratch = tempdir("corpus-csv");
    let dir = dir_scratch.path();
    // INTERACTION-style: a follower at 10 m/s, a faster car cutting into its lane ahead of it.
    let mut csv = String::from("track_id,frame_id,timestamp_ms,x,y\n");
    for k in 0..100 {
        let t = 0.1 * f64::from(k);
        let f = ((t - 2.0) / 4.0).clamp(0.0, 1.0);
        let y = 3.5 * (1.0 - f * f * (3.0 - 2.0 * f));
        csv.push_str(&format!(
            "1,{k},{},{:.3},0\n2,{k},{},{:.3},{y:.3}\n",
            100 * k,
            10.0 * t,
            100 * k,
            12.0 + 11.0 * t
        ));
    }
    let file = dir.join("cut_in.csv");
    std::fs::write(&file, csv).unwrap();
    let out = dir.join("csv.jsonl");
    let text = ok(&["corpus", "import", s(&file), "--dataset", "made here", "--licence", "Apache-2.0", "-o", s(&out)]);
    assert!(text.contains("imported 1 files: 2 tracks"), "{text}");
    let corpus = v2t_diffusion::recorded::read_file(&out).unwrap();
    let cut_in =
        corpus.episodes.iter().find(|e| e.mined.kind == v2t_diffusion::mining::InteractionKind::CutIn).unwrap();
    assert_eq!(cut_in.mined.actor, "2");
    assert!(cut_in.file.ends_with("cut_in.csv") && cut_in.agents.iter().all(|a| a.route_from == "driven path"));
}

#[test]
fn a_bad_recording_is_named_and_nothing_is_written() {
    let dir_scratch = tempdir("corpus-bad");
    let dir = dir_scratch.path();
    let good = recordings("heldout").join("USA_Peach-4_8_T-1.xml");
    let text = std::fs::read_to_string(&good).unwrap();
    let bad = dir.join("bad.xml");
    std::fs::write(&bad, text.replacen("<exact>0</exact>", "<exact>zero</exact>", 1)).unwrap();
    let out = dir.join("out.jsonl");
    let o = video2track(&["corpus", "import", s(&good), s(&bad), "--dataset", "d", "--licence", "l", "-o", s(&out)]);
    assert_eq!(o.status.code(), Some(2));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("bad.xml: line ") && err.contains("`zero`"), "{err}");
    assert!(!out.exists(), "nothing half-written");
    let err = fails(&["corpus", "import", s(&good), "--dataset", "d", "--licence", " ", "-o", s(&out)]);
    assert!(err.contains("--licence"), "{err}");
    let far = dir.join("far.csv");
    std::fs::write(&far, "track_id,frame_id,timestamp_ms,x,y\n1,0,0,0,0\n1,1,100,1e12,0\n1,2,200,2e12,0\n").unwrap();
    let o = video2track(&["corpus", "import", s(&far), "--dataset", "d", "--licence", "l", "-o", s(&out)]);
    assert_eq!(o.status.code(), Some(2));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("far.csv: track 1 at 0.1 s") && err.contains("outside ±1e6 m"), "{err}");
    let err = fails(&["corpus", "stats", s(&good)]);
    assert!(err.contains("USA_Peach-4_8_T-1.xml") && err.contains("line 1"), "{err}");
}

#[test]
fn with_dedup_a_vehicle_in_two_files_is_counted_once_and_its_interactions_too() {
    let dir_scratch = tempdir("dedup");
    let dir = dir_scratch.path();
    let file = recordings("train").join("USA_US101-3_1_T-1.xml");
    for name in ["a.xml", "b.xml"] {
        std::fs::copy(&file, dir.join(name)).unwrap();
    }
    let args = |out: &Path, dedup: bool| {
        let mut a = vec!["corpus", "import", s(dir), "--dataset", "d", "--licence", "l", "-o", s(out)];
        if dedup {
            a.push("--dedup");
        }
        a.into_iter().map(str::to_owned).collect::<Vec<_>>()
    };
    let (plain, dedup) = (dir.join("plain.jsonl"), dir.join("dedup.jsonl"));
    let once = ok(&args(&plain, false).iter().map(String::as_str).collect::<Vec<_>>());
    assert!(once.contains("imported 2 files: 70 tracks (70 vehicles, 0 of them already in an earlier file)"), "{once}");
    let text = ok(&args(&dedup, true).iter().map(String::as_str).collect::<Vec<_>>());
    assert!(
        text.contains("imported 2 files: 70 tracks (70 vehicles, 35 of them already in an earlier file)"),
        "{text}"
    );
    let count = |p: &Path| v2t_diffusion::recorded::read_file(p).unwrap().episodes.len();
    assert!(count(&plain) > 0 && count(&dedup) * 2 == count(&plain), "{} {}", count(&plain), count(&dedup));
    let stats = ok(&["corpus", "stats", s(&dedup)]);
    assert!(stats.contains("total: 70 tracks (70 vehicles, 35 distinct)"), "{stats}");
    // Each agent carries its vehicle's number with --dedup (none without); and recordings imported
    // twice under other names add no vehicle to the human reference.
    let agents = |p: &Path| v2t_diffusion::recorded::read_file(p).unwrap().episodes.into_iter().flat_map(|e| e.agents);
    assert!(agents(&dedup).all(|a| a.vehicle.is_some()) && agents(&plain).all(|a| a.vehicle.is_none()));
    // Every training recording, then each again under another name (7 recordings: enough vehicles
    // for the classes).
    let train = recordings("train");
    let copies = dir.join("copies");
    std::fs::create_dir(&copies).unwrap();
    for entry in std::fs::read_dir(&train).unwrap() {
        let path = entry.unwrap().path();
        std::fs::copy(&path, copies.join(format!("again_{}", path.file_name().unwrap().to_string_lossy()))).unwrap();
    }
    let (single, doubled) = (dir.join("single.jsonl"), dir.join("doubled.jsonl"));
    ok(&["corpus", "import", s(&train), "--dataset", "d", "--licence", "l", "--dedup", "-o", s(&single)]);
    ok(&["corpus", "import", s(&train), s(&copies), "--dataset", "d", "--licence", "l", "--dedup", "-o", s(&doubled)]);
    let classes = |corpus: &Path| {
        let text = ok(&["corpus", "reference", s(corpus), "-o", s(&dir.join("reference.json"))]);
        text.lines().filter(|l| l.contains(" vehicles, ")).map(str::to_owned).collect::<Vec<_>>()
    };
    let (twice, once) = (classes(&doubled), classes(&single));
    assert!(!once.is_empty() && twice == once, "{twice:?} vs {once:?}");
}

/// A CommonRoad 2020a file made here: one lanelet and `cars` cars, each driving a quarter circle
/// to the left (radius 40 m) at its own speed from 6 m/s up, sampled every `dt` s.
fn left_turners_xml(cars: usize, dt: f64) -> String {
    let mut xml = format!(
        "<commonRoad commonRoadVersion=\"2020a\" benchmarkID=\"ZAM_V2T-9_1_T-1\" source=\"made by this test\" timeStepSize=\"{dt}\">\
         <lanelet id=\"1\"><leftBound><point><x>0</x><y>2</y></point><point><x>100</x><y>2</y></point></leftBound>\
         <rightBound><point><x>0</x><y>-2</y></point><point><x>100</x><y>-2</y></point></rightBound></lanelet>"
    );
    let r = 40.0;
    for car in 0..cars {
        let v = 6.0 + car as f64;
        let steps = (r * std::f64::consts::FRAC_PI_2 / v / dt) as usize;
        xml.push_str(&format!(
            "<dynamicObstacle id=\"{}\"><type>car</type><shape><rectangle><length>{}</length><width>1.8</width></rectangle></shape>",
            10 + car,
            4.0 + 0.1 * car as f64
        ));
        for k in 0..=steps {
            let a = v * dt * k as f64 / r;
            let (x, y) = (100.0 * car as f64 + r * a.sin(), r * (1.0 - a.cos()));
            let tag = if k == 0 { "initialState" } else { "state" };
            if k == 1 {
                xml.push_str("<trajectory>");
            }
            xml.push_str(&format!(
                "<{tag}><position><point><x>{x}</x><y>{y}</y></point></position><orientation><exact>{a}</exact></orientation>\
                 <time><exact>{k}</exact></time><velocity><exact>{v}</exact></velocity></{tag}>"
            ));
        }
        xml.push_str("</trajectory></dynamicObstacle>");
    }
    xml + "</commonRoad>"
}

/// `corpus reference --left-turns`: every vehicle turning left in the recordings makes the
/// left-turn class, each once although two files hold it; without the option the corpora's mined
/// left turns alone (too few in the shipped recordings for a class).
#[test]
fn the_human_reference_takes_every_left_turner_once_from_recordings() {
    let dir_scratch = tempdir("reference");
    let dir = dir_scratch.path();
    let corpus = dir.join("heldout.jsonl");
    let licence = "NGSIM: US DOT public data; CommonRoad conversion BSD-3-Clause / MIT";
    ok(&["corpus", "import", s(&recordings("heldout")), "--dataset", "NGSIM", "--licence", licence, "-o", s(&corpus)]);
    let (a, b) = (dir.join("turns_a.xml"), dir.join("turns_b.xml"));
    std::fs::write(&a, left_turners_xml(6, 0.1)).unwrap();
    std::fs::copy(&a, &b).unwrap();
    let out = dir.join("reference.json");
    let args = |extra: &[&str]| {
        let mut v = vec!["corpus", "reference", s(&corpus)];
        v.extend_from_slice(extra);
        v.extend_from_slice(&["-o", s(&out)]);
        v.into_iter().map(str::to_owned).collect::<Vec<_>>()
    };
    let run = |extra: &[&str]| ok(&args(extra).iter().map(String::as_str).collect::<Vec<_>>());
    let text = run(&[]);
    assert!(!text.contains("LeftTurn"), "{text}");
    let text =
        run(&["--left-turns", s(&a), s(&b), "--left-turns-dataset", "made here", "--left-turns-licence", "Apache-2.0"]);
    assert!(text.contains("LeftTurn: 6 vehicles"), "{text}");
    let r: v2t_model::realism::HumanReference = serde_json::from_str(&std::fs::read_to_string(&out).unwrap()).unwrap();
    r.validate().unwrap();
    assert!(
        r.provenance.contains("the 6 vehicles turning left by at least 60° in 2 recordings of made here [Apache-2.0]")
    );
    let turn = r.classes.iter().find(|c| c.class == v2t_model::realism::ManoeuvreClass::LeftTurn).unwrap();
    // Each car turns at v / r, 0.15 to 0.28 rad/s, at constant speed (the smoother's ends aside).
    let (yaw, acc) = (&turn.yaw_rate_radps, &turn.accel_mps2);
    assert!(yaw[20] > 0.14 && yaw[80] < 0.29 && acc[20].abs() < 0.1 && acc[80].abs() < 0.1, "{yaw:?} {acc:?}");
    // Bad input: no licence, a recording at another period.
    let err = fails(
        &args(&["--left-turns", s(&a), "--left-turns-dataset", "d"]).iter().map(String::as_str).collect::<Vec<_>>(),
    );
    assert!(err.contains("--left-turns-licence"), "{err}");
    let slow = dir.join("slow.xml");
    std::fs::write(&slow, left_turners_xml(6, 0.2)).unwrap();
    let err = fails(
        &args(&["--left-turns", s(&slow), "--left-turns-dataset", "d", "--left-turns-licence", "l"])
            .iter()
            .map(String::as_str)
            .collect::<Vec<_>>(),
    );
    assert!(err.contains("slow.xml: sampled at 0.2 s, the corpora at 0.1 s"), "{err}");
}

/// The shipped human reference is exactly what `scripts/human-reference` makes of the fetched
/// recordings (its classes to the last bit, its provenance up to the command). The recordings are
/// fetch only (`scripts/fetch-ngsim`, GPL-3.0 conversions): where they are absent this test says
/// so and checks nothing more than `tests/config_files.rs` does.
#[test]
fn the_shipped_human_reference_is_what_its_script_makes() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let data = std::env::var_os("V2T_NGSIM_DIR")
        .map(std::path::PathBuf::from)
        .unwrap_or_else(|| root.join("target/recordings-ngsim"));
    if !data.join("commonroad-search").is_dir() {
        eprintln!("the fetched NGSIM recordings are not in {}: nothing to rebuild", data.display());
        return;
    }
    let dir_scratch = tempdir("human-reference");
    let out = dir_scratch.path().join("reference.json");
    let o = std::process::Command::new(root.join("scripts/human-reference"))
        .args(["-o", s(&out)])
        .env("V2T_BIN", env!("CARGO_BIN_EXE_video2track"))
        .env("V2T_NGSIM_DIR", &data)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let read = |p: &Path| -> v2t_model::realism::HumanReference {
        serde_json::from_str(&std::fs::read_to_string(p).unwrap()).unwrap()
    };
    let (made, shipped) = (read(&out), read(&root.join("config/realism/human_reference.json")));
    let source = |r: &v2t_model::realism::HumanReference| r.provenance.split("; made by").next().unwrap().to_owned();
    assert_eq!(source(&made), source(&shipped));
    assert_eq!((made.dt_s, &made.classes), (shipped.dt_s, &shipped.classes));
}
