//! The HTML reports in headless Chromium: an experiment's (a 10-run test campaign: tables per VUT,
//! every run's PET as strips, the steering error against τ, the campaign's learning, each case's
//! runs) and a single run's from `video2track sim --regulated` on a scenario card. The demo's
//! report is opened by the demo's own test.

#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)] // test code

use std::process::Command;

use v2t_tests::harness::{bin, tempdir};
use v2t_tests::repo_root;
use v2t_tests::report::{assert_run_parts, open_checked, run_sections};

#[test]
fn a_ten_run_campaign_report_shows_every_run_per_vut_and_stays_small() {
    let dir = tempdir("campaign-report");
    let html = dir.path().join("campaign.html");
    let o = Command::new(bin("video2track"))
        .args([
            "experiment",
            "campaign",
            "--runs",
            "10",
            "--repeats",
            "1",
            "--card",
            "config/scenarios/left_turn_basic.toml",
            "--vut",
            "idm-normal",
            "--vut",
            "idm-cautious",
            "--tau",
            "2",
            "--no-reach",
            "--report",
        ])
        .arg(&html)
        .current_dir(repo_root())
        .output()
        .unwrap();
    assert!(o.status.success(), "{}\n{}", String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr));
    let size = std::fs::metadata(&html).unwrap().len();
    assert!(size < 5_000_000, "a 10-run campaign's report is {size} bytes, over 5 MB");
    if !v2t_test_support::tools_or_not_run(v2t_test_support::BROWSER_TOOLS) {
        return;
    }
    let dom = open_checked(&html, "campaign", 3600).dom;
    for part in [
        "simulated proving ground",
        "Steering over a campaign, per VUT",
        "class=\"plot learning\"",
        "PET per run — VUT idm-normal",
        "PET per run — VUT idm-cautious",
        "Steering error — VUT idm-normal",
        "Steering error — VUT idm-cautious",
        "Runs, case by case",
    ] {
        assert!(dom.contains(part), "`{part}` missing from the campaign's report");
    }
    // The per-VUT table the experiment prints, one row per VUT.
    assert!(dom.contains("<td>idm-normal</td>") && dom.contains("<td>idm-cautious</td>"));
    // Two VUTs × two styles at one τ: four cases, each with its 10 runs of campaign 6.
    let cases: Vec<&str> = dom.split("<details").skip(1).collect();
    assert_eq!(cases.len(), 4, "one drill-down per case");
    for c in cases {
        assert!(c.contains("<th>run 10</th>") && !c.contains("<th>run 11</th>"), "10 runs per campaign");
        assert_eq!(c.matches("<tr><td>6 ").count(), 1, "campaign 6's row");
    }
    // 2 × 2 strips of 10 dots each.
    assert_eq!(dom.matches("r=\"2.4\"").count(), 40, "one dot per run");
}

#[test]
fn a_regulated_run_on_a_card_has_its_report() {
    let dir = tempdir("sim-report");
    let html = dir.path().join("run.html");
    let json = dir.path().join("run.json");
    let o = Command::new(bin("video2track"))
        .args(["sim", "config/scenarios/left_turn_basic.toml", "--regulated", "--report"])
        .arg(&html)
        .arg("--json")
        .arg(&json)
        .current_dir(repo_root())
        .output()
        .unwrap();
    assert!(o.status.success(), "{}\n{}", String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr));
    let text = std::fs::read_to_string(&html).unwrap();
    assert!(text.contains("href=\"run.json\""), "the run file is linked beside the report");
    assert!(text.contains("the map config/maps/proving_ground.xodr"), "a card's run is drawn on the map it runs on");
    assert!(text.contains("none in this world"), "no gate in the in-process world, and the report says so");
    if !v2t_test_support::tools_or_not_run(v2t_test_support::BROWSER_TOOLS) {
        return;
    }
    let dom = open_checked(&html, "sim", 2400).dom;
    let sections = run_sections(&dom);
    assert_eq!(sections.len(), 1);
    assert_run_parts(sections[0], true, false);
    assert!(sections[0].contains("Regulating"), "the regulator's status over the run");
}
