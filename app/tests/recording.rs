//! `video2track sim --mcap` and `video2track replay`: a recorded run measures again to exactly what
//! it reported; a recording whose truth differs does not; a file that is not a recording is an
//! input error.

#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)] // test code

mod common;

use common::{repo, tempdir, video2track};

#[test]
fn recorded_runs_replay_to_the_same_metrics_and_altered_ones_do_not() {
    let dir_scratch = tempdir("mcap");
    let dir = dir_scratch.path();
    for (card, vut) in
        [("config/scenarios/left_turn_basic.toml", "idm-normal"), ("config/scenarios/cut_in_basic.toml", "reactive")]
    {
        let mcap = dir.join("run.mcap");
        let json = dir.join("run.json");
        let o = video2track(&[
            "sim",
            card,
            "--vut",
            vut,
            "--mcap",
            mcap.to_str().unwrap(),
            "--json",
            json.to_str().unwrap(),
        ]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let replayed = dir.join("replayed.json");
        let o = video2track(&["replay", mcap.to_str().unwrap(), "--json", replayed.to_str().unwrap()]);
        let out = String::from_utf8_lossy(&o.stdout);
        assert!(o.status.success() && out.contains("every metric identical"), "{card}: {out}");
        for topic in ["/truth", "/scene", "/commands", "/pet"] {
            assert!(out.contains(&format!("{topic}: ")), "{card}: no {topic}: {out}");
        }
        // The recomputed result is the result the run wrote in its JSON.
        let run: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
        let again: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&replayed).unwrap()).unwrap();
        assert_eq!(run["result"], again, "{card}");
    }
    // The replay measures the recorded truth, it does not echo the recorded result: a run whose
    // truth is shifted (the VUT 2 m further along its route at every step) replays differently.
    let scenario = v2t_sim::files::load_scenario(&repo().join("config/scenarios/left_turn_basic.toml")).unwrap();
    let mut run =
        v2t_lab::sim::run_reference(&scenario, &v2t_lab::vut::Vut::Builtin(scenario.vut.default_model), 1).unwrap();
    for s in &mut run.truth.agents[0].s_m {
        *s += 2.0;
    }
    let shifted = dir.join("shifted.mcap");
    v2t_sim::recording::write(&run, &shifted).unwrap();
    let r = v2t_sim::recording::replay(&shifted).unwrap();
    assert!(!r.matches(), "a shifted truth replayed to the recorded result");
    assert_ne!(r.recorded["pet_min_s"], r.recomputed["pet_min_s"]);
    let o = video2track(&["replay", shifted.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(1), "{}", String::from_utf8_lossy(&o.stdout));

    // A recorded truth that is not motion (the VUT standing while its speed says it drives) is
    // refused, exit 2, naming the message and the vehicle, as a run file's trace would be.
    let mut still =
        v2t_lab::sim::run_reference(&scenario, &v2t_lab::vut::Vut::Builtin(scenario.vut.default_model), 1).unwrap();
    let first = still.truth.agents[0].states[0];
    for x in &mut still.truth.agents[0].states {
        *x = v2t_model::kinematics::State { speed_mps: 8.0, ..first };
    }
    let standing = dir.join("standing.mcap");
    v2t_sim::recording::write(&still, &standing).unwrap();
    let o = video2track(&["replay", standing.to_str().unwrap()]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("/truth #") && err.contains("(vehicle `vut`)") && err.contains("moved 0.00 m"), "{err}");

    // One byte of a message changed inside a chunk: the chunk's CRC no longer matches, and the
    // replay refuses the file (exit 2) naming the chunk, instead of measuring what the byte became.
    let good = dir.join("good.mcap");
    v2t_sim::recording::write(
        &v2t_lab::sim::run_reference(&scenario, &v2t_lab::vut::Vut::Builtin(scenario.vut.default_model), 1).unwrap(),
        &good,
    )
    .unwrap();
    let mut bytes = std::fs::read(&good).unwrap();
    let at = bytes.windows(7).position(|w| w == b"\"s_m\":1").expect("a truth message in the file") + 6;
    bytes[at] = if bytes[at] == b'1' { b'2' } else { b'1' };
    let corrupt = dir.join("corrupt.mcap");
    std::fs::write(&corrupt, &bytes).unwrap();
    let o = video2track(&["replay", corrupt.to_str().unwrap()]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("chunk ") && err.contains("is corrupt: CRC"), "{err}");

    let not_mcap = dir.join("not.mcap");
    std::fs::write(&not_mcap, b"hello").unwrap();
    let o = video2track(&["replay", not_mcap.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2), "{}", String::from_utf8_lossy(&o.stderr));
    let o = video2track(&["replay", dir.join("missing.mcap").to_str().unwrap()]);
    assert_ne!(o.status.code(), Some(0));
}
