//! `video2track demo` end to end: the three scenarios (cut-in, left turn with the BV turning, left
//! turn with the VUT turning) from their hand-written VLM exchanges through
//! grounding, the prior, the onboard processes and the simulated proving ground, to the report,
//! the summary, the OpenSCENARIO files and MCAP recordings that replay to the same metrics.

#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)] // test code

use v2t_tests::harness::{bin, tempdir};
use v2t_tests::repo_root;

#[test]
fn the_demo_runs_every_scenario_and_writes_what_it_promises() {
    let out_scratch = tempdir("demo");
    let out = out_scratch.path();
    let o = std::process::Command::new(bin("video2track"))
        .args(["demo", "--out", out.to_str().unwrap()])
        .current_dir(repo_root())
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{stdout}\n{}", String::from_utf8_lossy(&o.stderr));
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    let scenarios = summary["scenarios"].as_array().unwrap();
    let names: Vec<&str> = scenarios.iter().map(|s| s["name"].as_str().unwrap()).collect();
    assert_eq!(names, ["cut_in", "left_turn", "left_turn_vut"]);
    for s in scenarios {
        let name = s["name"].as_str().unwrap();
        assert_eq!(s["collision"], false, "{name}");
        assert_eq!(s["order_ok"], true, "{name}");
        let err = s["fidelity_error_rel"].as_f64().unwrap_or_else(|| {
            let log = std::fs::read_to_string(out.join(format!("{name}.run.log"))).unwrap_or_default();
            panic!("{name}: no PET measured\n{stdout}\n{name}.run.log:\n{log}")
        });
        println!(
            "{name}: PET video {} s, track {} s, error {:.1} %",
            s["pet_video_s"],
            s["pet_min_track_s"],
            100.0 * err
        );
        for suffix in ["semantics.json", "grounded.json", "prior.json", "xosc", "run.json", "mcap"] {
            assert!(out.join(format!("{name}.{suffix}")).is_file(), "{name}.{suffix}");
        }
        let xosc = std::fs::read_to_string(out.join(format!("{name}.xosc"))).unwrap();
        assert!(xosc.contains("<OpenSCENARIO") && xosc.contains("FollowTrajectoryAction"), "{name}");
        let r = std::process::Command::new(bin("video2track"))
            .arg("replay")
            .arg(out.join(format!("{name}.mcap")))
            .current_dir(repo_root())
            .output()
            .unwrap();
        let replay = String::from_utf8_lossy(&r.stdout);
        assert!(r.status.success(), "{name}: {replay}");
        assert!(replay.contains("/plans: ") && replay.contains("every metric identical"), "{name}: {replay}");
    }
    let report = std::fs::read_to_string(out.join("report.html")).unwrap();
    assert!(report.contains("<svg") && report.contains("cut_in") && report.contains("left_turn_vut"));
    let video = v2t_test_support::missing(v2t_test_support::VIDEO_TOOLS).is_empty();
    for name in ["cut_in", "left_turn", "left_turn_vut"] {
        for file in ["mcap", "xosc", "run.json"] {
            assert!(report.contains(&format!("href=\"{name}.{file}\"")), "{name}: no link to its {file}");
        }
        assert_eq!(report.contains(&format!("href=\"{name}.mp4\"")), video, "{name}: the video link follows ffmpeg");
    }
    // In a real browser.
    if !v2t_test_support::tools_or_not_run(v2t_test_support::BROWSER_TOOLS) {
        return;
    }
    let opened = v2t_tests::report::open_checked(&out.join("report.html"), "demo", 4200);
    let sections = v2t_tests::report::run_sections(&opened.dom);
    assert_eq!(sections.len(), 3, "one section per scenario");
    for s in sections {
        // Every demo run goes through the onboard gateway: the gate's state is on the CAN bus.
        v2t_tests::report::assert_run_parts(s, true, true);
    }
    assert!(opened.dom.contains("<table class=\"summary\""));
    // Printed, as an engineer hands it on: every page of it a PDF page, the slider left out.
    let pdf = v2t_tests::report::screenshot_dir().join("demo.pdf");
    v2t_test_support::browser::print_pdf(&out.join("report.html"), &pdf).unwrap();
    let bytes = std::fs::read(&pdf).unwrap();
    let count = |what: &[u8]| bytes.windows(what.len()).filter(|w| *w == what).count();
    let pages = count(b"/Type /Page") - count(b"/Type /Pages");
    assert!(pages >= 3, "the printed report has {pages} pages, one scenario needs about one");
}
