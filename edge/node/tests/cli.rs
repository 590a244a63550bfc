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

/// `config/edge/bv1.toml` with its file references made absolute and `from` replaced by `to`,
/// written into `dir`.
fn bv1_with(dir: &Path, from: &str, to: &str) -> PathBuf {
    let text = std::fs::read_to_string(config_dir().join("edge/bv1.toml")).unwrap();
    assert!(text.contains(from), "bv1.toml no longer has `{from}`");
    let absolute = format!("\"{}/", config_dir().display());
    let text = text.replace("\"../", &absolute).replace(from, to);
    let path = dir.join("bv1.toml");
    std::fs::write(&path, text).unwrap();
    path
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
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
    for command in ["launch", "node", "engage", "reset", "stop", "disengage", "estop"] {
        assert!(help.contains(command), "--help lacks `{command}`: {help}");
    }
}
