//! The `v2t-edge` binary as a technician runs it: bad configuration is exit 2 with the file, the
//! field and the bound named, a usage error is exit 2, and nothing starts.
//!
//! (This file also makes `cargo test --workspace` build the `v2t-edge` binary, which the lab's
//! and the workspace's multi-process tests start.)

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn edge(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_v2t-edge")).args(args).output().expect("v2t-edge runs")
}

fn config_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../config")
}

/// `config/edge/<name>` with its file references made absolute and each `(from, to)` replaced,
/// written into `dir`.
fn edge_config_with(dir: &Path, name: &str, replacements: &[(&str, &str)]) -> PathBuf {
    let text = std::fs::read_to_string(config_dir().join("edge").join(name)).unwrap();
    let absolute = format!("\"{}/", config_dir().display());
    let mut text = text.replace("\"../", &absolute);
    for (from, to) in replacements {
        assert!(text.contains(from), "{name} no longer has `{from}`");
        text = text.replace(from, to);
    }
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path
}

/// `config/edge/bv1.toml` with its file references made absolute and `from` replaced by `to`,
/// written into `dir`.
fn bv1_with(dir: &Path, from: &str, to: &str) -> PathBuf {
    edge_config_with(dir, "bv1.toml", &[(from, to)])
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// `v2t-edge check --config <config> <more>`: its exit code and its report.
fn check(config: &Path, more: &[&str]) -> (Option<i32>, String) {
    let mut args = vec!["check", "--config", config.to_str().unwrap()];
    args.extend_from_slice(more);
    let o = edge(&args);
    (o.status.code(), format!("{}{}", stdout(&o), stderr(&o)))
}

/// The line of `report` that starts with `prefix` (`"FAIL can nonexistent0:"`).
fn line<'a>(report: &'a str, prefix: &str) -> &'a str {
    report.lines().find(|l| l.starts_with(prefix)).unwrap_or_else(|| panic!("no `{prefix}` line:\n{report}"))
}

#[test]
fn a_missing_or_malformed_configuration_is_exit_2_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("nowhere.toml");
    let o = edge(&["node", "state", "--config", missing.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("nowhere.toml") && stderr(&o).contains("cannot read"), "{}", stderr(&o));

    let broken = dir.path().join("broken.toml");
    std::fs::write(&broken, "namespace = [").unwrap();
    let o = edge(&["launch", "--config", broken.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("broken.toml") && stderr(&o).contains("line 1"), "{}", stderr(&o));
    // The file is named once, not once per layer of the error.
    assert_eq!(stderr(&o).matches("broken.toml").count(), 1, "{}", stderr(&o));
}

#[test]
fn out_of_range_and_non_finite_settings_are_exit_2_naming_the_field_and_the_bound() {
    let dir = tempfile::tempdir().unwrap();
    for (from, to, field, bound) in [
        ("regulator_period_s = 0.1", "regulator_period_s = -1", "timing.regulator_period_s", "[0.01, 1]"),
        ("heartbeat_timeout_s = 0.06", "heartbeat_timeout_s = nan", "timing.heartbeat_timeout_s", "NaN"),
        ("max_restarts = 5", "max_restarts = -5", "max_restarts", "max_restarts"),
    ] {
        let cfg = bv1_with(dir.path(), from, to);
        let o = edge(&["node", "regulator", "--config", cfg.to_str().unwrap()]);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{to}: {err}");
        assert!(err.contains(field) && err.contains(bound), "{to}: {err}");
    }
}

#[test]
fn a_usage_error_is_exit_2_and_help_names_every_command() {
    let o = edge(&["frobnicate"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("unrecognized subcommand"), "{}", stderr(&o));
    let o = edge(&["--help"]);
    assert!(o.status.success());
    let help = String::from_utf8_lossy(&o.stdout);
    for command in ["launch", "node", "engage", "reset", "stop", "disengage", "estop", "check"] {
        assert!(help.contains(command), "--help lacks `{command}`: {help}");
    }
}

#[test]
fn check_passes_the_shipped_configuration() {
    let (code, report) = check(&config_dir().join("edge/bv1.toml"), &[]);
    assert_eq!(code, Some(0), "{report}");
    for prefix in [
        "ok   config:",
        "ok   vehicle:",
        "ok   gate:",
        "ok   iceoryx2:",
        "ok   gate/vehicle:",
        "ok   regulator/vehicles:",
        "ok   regulator/tracker:",
    ] {
        line(&report, prefix);
    }
    // The bench's transport, and no map without a cloud link: allowed, worth knowing.
    assert!(line(&report, "warn can:").contains("ipc"), "{report}");
    line(&report, "warn geofence:");
    assert!(!report.contains("FAIL "), "{report}");
    assert!(report.lines().last().unwrap().starts_with("summary: ") && report.contains(" 0 FAIL"), "{report}");
}

#[test]
fn check_warns_about_the_demo_key_of_a_cloud_link() {
    let (code, report) = check(&config_dir().join("edge/bv1_link.toml"), &[]);
    assert_eq!(code, Some(0), "{report}");
    let demo = report.lines().find(|l| l.starts_with("warn uplink.cloud_key:") && l.contains("demo key"));
    assert!(demo.is_some_and(|l| l.contains("demo_cloud.pub") && l.contains("never on a vehicle")), "{report}");
    assert!(line(&report, "ok   uplink.map:").contains("proving_ground.xodr"), "{report}");
    line(&report, "ok   uplink.broker:");
}

#[test]
fn check_fails_on_a_can_interface_this_machine_lacks_and_says_how_to_bring_one_up() {
    let (code, report) = check(&config_dir().join("edge/bv1.toml"), &["--can-iface", "nonexistent0"]);
    assert_eq!(code, Some(2), "{report}");
    let fail = line(&report, "FAIL can nonexistent0:");
    for hint in
        ["--can-iface", "ip link set nonexistent0 up type can bitrate", "ip link add dev nonexistent0 type vcan"]
    {
        assert!(fail.contains(hint), "{hint}: {fail}");
    }
    assert!(report.lines().last().unwrap().contains("1 FAIL"), "{report}");
}

#[test]
fn check_names_every_broken_file_not_only_the_first() {
    let dir = tempfile::tempdir().unwrap();
    let gate = std::fs::read_to_string(config_dir().join("can/gate.toml")).unwrap();
    let gate_file = dir.path().join("gate.toml");
    std::fs::write(&gate_file, gate.replace("command_timeout_s = 0.25", "command_timeout_s = 50")).unwrap();
    let cfg = edge_config_with(
        dir.path(),
        "bv1.toml",
        &[
            ("vehicles/bv_sedan.toml", "vehicles/no_such_vehicle.toml"),
            (&format!("{}/can/gate.toml", config_dir().display()), gate_file.to_str().unwrap()),
        ],
    );
    let (code, report) = check(&cfg, &[]);
    assert_eq!(code, Some(2), "{report}");
    let vehicle = line(&report, "FAIL vehicle:");
    assert!(vehicle.contains("no_such_vehicle.toml") && vehicle.contains("cannot read"), "{report}");
    let gate = line(&report, "FAIL gate:");
    assert!(
        gate.contains("gate.toml") && gate.contains("command_timeout_s") && gate.contains("[0.001, 5]"),
        "{report}"
    );
    assert!(line(&report, "ok   tracker:").contains("track/default.toml"), "the others are still checked: {report}");
    assert!(report.lines().last().unwrap().contains("2 FAIL"), "{report}");
}

#[test]
fn check_fails_on_a_missing_configuration() {
    let dir = tempfile::tempdir().unwrap();
    let (code, report) = check(&dir.path().join("nowhere.toml"), &[]);
    assert_eq!(code, Some(2), "{report}");
    assert!(line(&report, "FAIL config:").contains("nowhere.toml: cannot read"), "{report}");
}

#[test]
fn the_uplink_does_not_start_without_a_valid_cloud_key() {
    let dir = tempfile::tempdir().unwrap();
    let key = dir.path().join("cloud.pub");
    let key_line = format!("\"{}/keys/demo_cloud.pub\"", config_dir().display());
    let cfg = edge_config_with(dir.path(), "bv1_link.toml", &[(&key_line, &format!("\"{}\"", key.display()))]);
    for (content, expected) in
        [(None, "cloud.pub: No such file"), (Some("not a key"), "cloud_key: expected 64 hex digits")]
    {
        if let Some(content) = content {
            std::fs::write(&key, content).unwrap();
        }
        let o = edge(&["node", "uplink", "--config", cfg.to_str().unwrap()]);
        assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
        assert!(stderr(&o).contains(expected), "{expected}: {}", stderr(&o));
        let (code, report) = check(&cfg, &[]);
        assert_eq!(code, Some(2), "{report}");
        assert!(line(&report, "FAIL uplink.cloud_key:").contains("the uplink does not start without it"), "{report}");
    }
}

/// `v2t-edge check … | head`: a reader that closes stdout early changes nothing but the report it
/// does not read: the exit code stays the check's (0 passed, 2 failed), never `println!`'s panic.
#[test]
fn check_on_a_closed_stdout_keeps_its_exit_code_without_a_panic() {
    use std::process::Stdio;
    let cfg = config_dir().join("edge/bv1.toml");
    for more in [&[][..], &["--can-iface", "nonexistent0"]] {
        let (code, report) = check(&cfg, more);
        let mut child = Command::new(env!("CARGO_BIN_EXE_v2t-edge"))
            .args(["check", "--config", cfg.to_str().unwrap()])
            .args(more)
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        // Closed before the report is written.
        drop(child.stdout.take());
        let o = child.wait_with_output().unwrap();
        assert!(!stderr(&o).contains("panicked"), "{more:?}: {}", stderr(&o));
        assert_eq!(o.status.code(), code, "{more:?}: {}\n(with stdout open: {report})", stderr(&o));
    }
}
