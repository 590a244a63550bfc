//! Every file under `config/` parses and validates with the type its folder says it holds. A file
//! in a folder this test does not know fails the test, so new configuration cannot slip in unchecked.

#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)] // test code

use v2t_files::load_toml;
use v2t_game::regulator::RegulatorParams;
use v2t_model::semantics::{parse_semantics_json, scenario_semantics_schema};
use v2t_model::vehicle::VehicleConfig;
use v2t_sim::config::SimSettings;
use v2t_sim::files::load_scenario;
use v2t_tests::{files_under, repo_root};

#[test]
fn every_configuration_file_loads_and_validates() {
    let config = repo_root().join("config");
    let files = files_under(&config);
    assert!(files.len() >= 6, "expected the bundled configuration, found {files:?}");
    let mut checked = 0;
    for path in &files {
        let rel = path.strip_prefix(&config).unwrap().to_string_lossy().replace('\\', "/");
        let folder = rel.split('/').next().unwrap_or_default();
        match folder {
            "vehicles" => drop(load_toml::<VehicleConfig>(path).unwrap_or_else(|e| panic!("{e}"))),
            "sim" => drop(load_toml::<SimSettings>(path).unwrap_or_else(|e| panic!("{e}"))),
            "regulator" => drop(load_toml::<RegulatorParams>(path).unwrap_or_else(|e| panic!("{e}"))),
            "scenarios" => drop(load_scenario(path).unwrap_or_else(|e| panic!("{e}"))),
            "examples" if rel.contains("semantics_") => {
                let text = std::fs::read_to_string(path).unwrap();
                parse_semantics_json(&text).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
            }
            "schema" => {
                let text = std::fs::read_to_string(path).unwrap();
                let committed: serde_json::Value = serde_json::from_str(&text).unwrap();
                assert_eq!(committed, scenario_semantics_schema(), "{rel} drifted from the types");
            }
            "track" => drop(load_toml::<v2t_track::TrackerConfig>(path).unwrap_or_else(|e| panic!("{e}"))),
            "can" if rel.ends_with(".toml") => {
                let gate = load_toml::<v2t_can::gate::GateConfig>(path).unwrap_or_else(|e| panic!("{e}"));
                let bv = load_toml::<VehicleConfig>(&config.join("vehicles/bv_sedan.toml")).unwrap();
                gate.validate_for(&bv).unwrap_or_else(|e| panic!("{rel}: {e}"));
            }
            // The DBC is compiled into v2t-can (edge/can/build.rs): one that does not parse fails the
            // build. Here: every message the codec knows is in the file.
            "can" if rel.ends_with(".dbc") => {
                let text = std::fs::read_to_string(path).unwrap();
                for id in v2t_can::codec::MESSAGE_IDS {
                    assert!(text.contains(&format!("BO_ {id} ")), "{rel}: no message {id}");
                }
            }
            // The demo key pair: the public half is the key of the secret half.
            "keys" if rel.ends_with(".pub") => {
                let public = std::fs::read_to_string(path).unwrap();
                let secret = v2t_supervisor::link::load_signing_key(&path.with_extension("key"))
                    .unwrap_or_else(|e| panic!("{rel}: its secret half: {e}"));
                let bytes = v2t_wire::link::key_from_hex(&public).unwrap_or_else(|e| panic!("{rel}: {e}"));
                assert_eq!(bytes, secret.verifying_key().to_bytes(), "{rel} is not the key of its .key");
                assert!(v2t_supervisor::link::is_demo_key(&secret), "{rel}: not the demo key the tools warn about");
            }
            "keys" if rel.ends_with(".key") => assert!(path.with_extension("pub").exists(), "{rel} has no .pub"),
            "keys" if rel.ends_with("README.md") => {}
            "edge" => drop(v2t_edge::config::load(path).unwrap_or_else(|e| panic!("{e}"))),
            "iceoryx2.toml" => {
                let text = std::fs::read_to_string(path).unwrap();
                let parsed: Result<iceoryx2::config::Config, _> = toml::from_str(&text);
                parsed.unwrap_or_else(|e| panic!("{rel}: {e}"));
            }
            // Track maps: each parses without a warning; annotations name fragments of their map; the
            // generator is checked by CI (`proving_ground.py --check`) and the ASAM checker.
            "maps" if rel.ends_with(".xodr") => {
                let map = v2t_map::Map::load(path).unwrap_or_else(|e| panic!("{e}"));
                assert!(map.warnings.is_empty(), "{rel}: {:?}", map.warnings);
            }
            "maps" if rel.ends_with(".toml") => {
                let map =
                    v2t_map::Map::load(&path.with_extension("xodr")).unwrap_or_else(|e| panic!("{rel}: its map: {e}"));
                let text = std::fs::read_to_string(path).unwrap();
                let notes = v2t_map::annotate::Annotations::parse(&text, &rel).unwrap_or_else(|e| panic!("{e}"));
                v2t_map::library::TopologyLibrary::build(&map).annotate(&notes).unwrap_or_else(|e| panic!("{e}"));
            }
            "maps" if rel.ends_with(".py") => {
                assert!(path.with_extension("xodr").exists(), "{rel}: the map it generates is missing");
            }
            "maps" if rel.ends_with("README.md") => {}
            // The shipped denoiser weights: they load (format, version, architecture, every tensor's
            // shape, no NaN), say truthfully whether they saw recorded driving (the default weights
            // learnt from the shipped NGSIM recordings, the `_synthetic` ones from simulation only),
            // their metrics file ends with the held-out loss the weights record, and the README names
            // the command that made them.
            "diffusion" if rel.ends_with(".safetensors") => {
                let model = v2t_diffusion::weights::load(path).unwrap_or_else(|e| panic!("{e}"));
                let synthetic_only = rel.ends_with("_synthetic.safetensors");
                assert_eq!(model.meta.training.synthetic, synthetic_only, "{rel}: synthetic flag");
                if !synthetic_only {
                    assert!(model.meta.training.data.contains("NGSIM"), "{rel}: {}", model.meta.training.data);
                }
                let metrics = renamed(path, [("denoiser", "metrics"), (".safetensors", ".jsonl")]);
                let text =
                    std::fs::read_to_string(&metrics).unwrap_or_else(|e| panic!("{rel}: {}: {e}", metrics.display()));
                let lines: Vec<v2t_diffusion::train::TrainMetrics> =
                    text.lines().map(|l| serde_json::from_str(l).unwrap_or_else(|e| panic!("{rel}: {e}"))).collect();
                let last = lines.last().and_then(|m| m.heldout_loss).unwrap();
                assert_eq!(last, model.meta.training.heldout_loss, "{rel}: not the run of its metrics");
                assert_eq!(lines.last().unwrap().step, model.meta.training.steps);
                let readme = std::fs::read_to_string(path.with_file_name("README.md")).unwrap();
                let args = model.meta.training.command.split_once(" train ").map(|(_, a)| a.to_owned()).unwrap();
                assert!(
                    readme.contains(&format!("video2track train {args}")),
                    "README does not name {rel}'s command: {args}"
                );
            }
            "diffusion" if rel.ends_with(".jsonl") => {
                let weights = renamed(path, [("metrics", "denoiser"), (".jsonl", ".safetensors")]);
                assert!(weights.exists(), "{rel}: no weights {}", weights.display());
            }
            "diffusion" if rel.ends_with("README.md") => {}
            // The recordings: each reads (either CommonRoad format) with lanes and NGSIM tracks, the
            // data card lists it, and every licence text the card points to is there.
            "diffusion" if rel.starts_with("diffusion/recordings/ngsim/") => {
                let s = v2t_diffusion::import::commonroad::parse_scenario_file(path)
                    .unwrap_or_else(|e| panic!("{rel}: {e}"));
                assert!(s.source.contains("NGSIM") && !s.lanes.is_empty() && !s.episode.tracks.is_empty(), "{rel}");
                let card = std::fs::read_to_string(config.join("diffusion/DATA.md")).unwrap();
                let name = rel.trim_start_matches("diffusion/recordings/ngsim/");
                assert!(card.contains(&format!("`{name}`")), "DATA.md does not list {name}");
            }
            "diffusion" if rel.starts_with("diffusion/recordings/licences/") => {
                let text = std::fs::read_to_string(path).unwrap();
                assert!(
                    text.contains("Copyright") && text.contains("Permission") || text.contains("Redistribution"),
                    "{rel}"
                );
            }
            "diffusion" if rel.ends_with("DATA.md") => {}
            "diffusion" if rel.ends_with(".gitignore") => {
                assert!(std::fs::read_to_string(path).unwrap().contains("checkpoints/"));
            }
            // The human reference: it validates, names recorded data, and measures its own classes.
            "realism" if rel.ends_with(".json") => {
                let text = std::fs::read_to_string(path).unwrap();
                let r: v2t_model::realism::HumanReference =
                    serde_json::from_str(&text).unwrap_or_else(|e| panic!("{rel}: {e}"));
                r.validate().unwrap_or_else(|e| panic!("{rel}: {e}"));
                assert!(!r.classes.is_empty() && r.provenance.contains("NGSIM"), "{rel}");
                assert!(r.classes.iter().all(|c| c.vehicles >= v2t_model::realism::MIN_VEHICLES), "{rel}");
            }
            "realism" if rel.ends_with("README.md") => {}
            // This project's driver models: compiled into v2t-sim (a bad file fails the build); each
            // is a model the command line knows, with the description the code carries.
            "vut" if rel.starts_with("vut/builtin/") && rel.ends_with(".toml") => {
                let text = std::fs::read_to_string(path).unwrap();
                let name = text.lines().find_map(|l| l.strip_prefix("name = ")).unwrap().trim_matches('"');
                let model: v2t_sim::vut::VutModel = name.parse().unwrap_or_else(|e| panic!("{rel}: {e}"));
                assert!(text.contains(&format!("description = {:?}", model.description())), "{rel}");
                let readme = std::fs::read_to_string(path.with_file_name("README.md")).unwrap();
                assert!(readme.contains(&format!("`{name}.toml`")), "{rel}: its README does not list it");
            }
            // SUMO's drivers of the VUT (the held-out ones in `heldout/`): each validates, and the
            // README's table lists it by its path below `config/vut/sumo/`.
            "vut" if rel.ends_with(".toml") => {
                let driver = v2t_lab::sumo::SumoDriver::load(path).unwrap_or_else(|e| panic!("{e}"));
                let dir = path.ancestors().find(|a| a.ends_with("vut/sumo")).unwrap();
                let readme = std::fs::read_to_string(dir.join("README.md")).unwrap();
                let file = path.strip_prefix(dir).unwrap().to_string_lossy();
                assert!(readme.contains(&format!("`{file}`")), "{rel}: config/vut/sumo/README.md does not list it");
                assert!(driver.name.starts_with("sumo-"), "{rel}");
            }
            "vut" if rel.ends_with("README.md") => {}
            // Networks between track and cloud: each validates, names where its figures come from,
            // and the README's table lists it.
            "network" if rel.ends_with(".toml") => {
                let n = load_toml::<v2t_sim::network::NetworkSettings>(path).unwrap_or_else(|e| panic!("{e}"));
                assert!(!n.source.trim().is_empty(), "{rel}: no source");
                let readme = std::fs::read_to_string(path.with_file_name("README.md")).unwrap();
                let file = path.file_name().unwrap().to_string_lossy();
                assert!(readme.contains(&format!("`{file}`")), "{rel}: config/network/README.md does not list it");
            }
            "network" if rel.ends_with("README.md") => {}
            // The VLM prompt and the recorded exchanges: a cassette replays to its semantics.json.
            "vlm" => v2t_vlm::check_config_file(path).unwrap_or_else(|e| panic!("config/{rel}: {e}")),
            _ => panic!("config/{rel}: no validator knows this file; add one to tests/config_files.rs"),
        }
        checked += 1;
    }
    assert_eq!(checked, files.len());
}

/// `path` with its file name's parts swapped (`denoiser_x.safetensors` ↔ `metrics_x.jsonl`).
fn renamed(path: &std::path::Path, swaps: [(&str, &str); 2]) -> std::path::PathBuf {
    let mut name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    for (from, to) in swaps {
        name = name.replace(from, to);
    }
    path.with_file_name(name)
}

/// Every shipped scenario card is placed on the proving ground's map: its routes run along lane
/// centre lines (within 0.1 m, in the lane's driving direction) except for at most one stretch of
/// at most 50 m between two lanes (a lane change), and never leave the drivable area. A world that
/// drives the VUT on the map's lanes (SUMO) depends on it.
#[test]
fn every_shipped_card_drives_on_the_proving_grounds_lanes() {
    let root = repo_root();
    let map = v2t_map::Map::load(&root.join("config/maps/proving_ground.xodr")).unwrap();
    let area = v2t_map::drivable::DrivableArea::from_map(&map);
    let lanes: Vec<&v2t_map::graph::LaneInfo> = map.graph.lanes.iter().filter(|l| l.drivable).collect();
    // Distance from `p` to the nearest lane centre line whose direction there agrees with `heading`.
    let off_lane = |p: v2t_model::geometry::Point2, heading: f64| -> f64 {
        let mut best = f64::INFINITY;
        for lane in &lanes {
            for w in lane.samples.windows(2) {
                let (a, b) = (w[0].p, w[1].p);
                let ab = b.sub(a);
                let len2 = ab.dot(ab);
                let f = if len2 > 0.0 { (p.sub(a).dot(ab) / len2).clamp(0.0, 1.0) } else { 0.0 };
                let q = a.add(ab.scale(f));
                let d = p.sub(q).norm();
                if d < best && v2t_model::geometry::wrap_angle(w[0].heading - heading).abs() < 0.3 {
                    best = d;
                }
            }
        }
        best
    };
    for card in v2t_files::shipped::CARDS {
        let sc = load_scenario(&root.join(card)).unwrap();
        let agents = std::iter::once(&sc.vut.agent).chain(sc.bvs.iter().map(|b| &b.agent));
        for agent in agents {
            let route = &agent.route;
            let n = (route.length() / 0.5).ceil() as usize;
            let mut stretches: Vec<(f64, f64)> = Vec::new();
            let mut worst_on_lane = 0.0_f64;
            for k in 0..=n {
                let s = (k as f64 * 0.5).min(route.length());
                let p = route.point_at(s);
                assert!(area.contains(p, 0.0), "{card}: {} leaves the drivable area at s = {s} m ({p:?})", agent.id);
                let d = off_lane(p, route.heading_at(s));
                if d > 0.1 {
                    match stretches.last_mut() {
                        Some((_, end)) if s - *end <= 0.51 => *end = s,
                        _ => stretches.push((s, s)),
                    }
                } else {
                    worst_on_lane = worst_on_lane.max(d);
                }
            }
            assert!(
                stretches.len() <= 1 && stretches.iter().all(|(a, b)| b - a <= 50.0),
                "{card}: {} is off the lane centre lines over {stretches:?} (m of its route)",
                agent.id
            );
            eprintln!(
                "{card}: {}: on the lane centres within {worst_on_lane:.3} m, between lanes over {stretches:?}",
                agent.id
            );
        }
    }
}

/// Every shipped card's BV whose conflict lies in a junction of the proving ground says where its
/// path enters that junction (`junction_entry_m`, where a BV that gives way stops before), and
/// says it as the map does, within 5 cm; a BV whose conflict is in no junction says nothing.
#[test]
fn every_shipped_cards_junction_entry_is_the_maps() {
    let root = repo_root();
    let map = v2t_map::Map::load(&root.join("config/maps/proving_ground.xodr")).unwrap();
    let mut declared = 0;
    for card in v2t_files::shipped::CARDS {
        let sc = load_scenario(&root.join(card)).unwrap();
        for c in &sc.conflicts {
            let bv = &sc.bvs[c.bv_index];
            let mid = 0.5 * (c.zone.bv.enter_s_m + c.zone.bv.exit_s_m);
            let on_map = map.junction_entry(&bv.agent.route, mid);
            match (bv.junction_entry_m, on_map) {
                (Some(card_m), Some(map_m)) => {
                    assert!(
                        (card_m - map_m).abs() <= 0.05,
                        "{card}: {} says {card_m} m, the map {map_m:.3} m",
                        bv.agent.id
                    );
                    declared += 1;
                }
                (None, None) => {}
                (card_m, map_m) => panic!("{card}: {}: the card says {card_m:?}, the map {map_m:?}", bv.agent.id),
            }
        }
    }
    assert_eq!(declared, 2, "both left turns' BVs cross in junction 100");
}
