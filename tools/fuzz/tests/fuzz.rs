//! The mutation harness in CI: its budgeted share (every kind, 100 s of mutants, the regression
//! seeds first) under a 4 GiB address-space cap, and the harness's own self-tests: a panic, a hang
//! and an abort are each reported, with the input kept.
//!
//! The full run (≥ 10,000 mutants, release build) is a command in `docs/BENCHMARKS.md`.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)] // test code

use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::time::{Duration, Instant};

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// Runs `v2t-fuzz args` under `ulimit -v` (4 GiB), killed after `limit`.
fn fuzz(args: &[&str], work: &Path, limit: Duration) -> (Output, Duration) {
    let started = Instant::now();
    let mut child = Command::new("sh")
        .arg("-c")
        .arg("ulimit -v 4194304 && exec \"$0\" \"$@\"")
        .arg(env!("CARGO_BIN_EXE_v2t-fuzz"))
        .args(args)
        .arg("--repo")
        .arg(repo())
        .arg("--work")
        .arg(work.join("work"))
        .arg("--findings")
        .arg(work.join("findings"))
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    while child.try_wait().unwrap().is_none() {
        if started.elapsed() > limit {
            child.kill().unwrap();
            let progress = std::fs::read_to_string(work.join("work/progress")).unwrap_or_default();
            panic!("v2t-fuzz {args:?} still ran after {limit:?}; the mutant in flight: {progress}");
        }
        std::thread::sleep(Duration::from_millis(200));
    }
    (child.wait_with_output().unwrap(), started.elapsed())
}

fn text(o: &Output) -> String {
    format!("{}{}", String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr))
}

#[test]
fn every_input_kind_survives_its_budgeted_mutants() {
    let dir = tempfile::tempdir().unwrap();
    let (o, took) =
        fuzz(&["--budget-s", "100", "--mutants", "100000", "--timeout-s", "30"], dir.path(), Duration::from_secs(240));
    let out = text(&o);
    let progress = std::fs::read_to_string(dir.path().join("work/progress")).unwrap_or_default();
    assert!(
        o.status.success(),
        "v2t-fuzz found something ({:?}, mutant in flight: {progress}); the input is under {}:\n{out}",
        o.status,
        dir.path().join("findings").display()
    );
    assert!(out.contains("0 panics, 0 aborts, 0 hangs"), "{out}");
    // Every kind ran mutants, and the regression seeds were read.
    for kind in v2t_fuzz::targets::KINDS {
        let row = out.lines().find(|l| l.starts_with(&format!("| {} |", kind.name))).unwrap_or_else(|| panic!("{out}"));
        let mutants: u64 = row.split('|').nth(4).unwrap().trim().parse().unwrap();
        assert!(mutants >= 10, "{}: {mutants} mutants in its share: {row}", kind.name);
    }
    // Every regression seed was read first.
    for kind in ["opendrive", "card", "grounded", "prior", "run", "mcap"] {
        let files = std::fs::read_dir(repo().join("tests/fuzz/regressions").join(kind)).unwrap().count();
        let row = out.lines().find(|l| l.starts_with(&format!("| {kind} |"))).unwrap();
        let read: usize = row.split('|').nth(3).unwrap().trim().parse().unwrap();
        assert_eq!(read, files, "{kind}: {row}");
    }
    eprintln!("v2t-fuzz budgeted share took {took:?}");
}

#[test]
fn the_harness_reports_a_panic_a_hang_and_an_abort_with_the_input() {
    let dir = tempfile::tempdir().unwrap();
    let findings = dir.path().join("findings");
    let (o, _) = fuzz(&["--kinds", "selftest-panic", "--mutants", "5"], dir.path(), Duration::from_secs(60));
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    assert!(text(&o).contains("PANIC: selftest-panic-1-") && text(&o).contains("self-test panic"), "{}", text(&o));
    assert!(std::fs::read_dir(&findings).unwrap().count() >= 1, "the panicking inputs are kept");

    let (o, took) =
        fuzz(&["--kinds", "selftest-hang", "--mutants", "5", "--timeout-s", "1"], dir.path(), Duration::from_secs(60));
    assert_eq!(o.status.code(), Some(3), "{}", text(&o));
    assert!(text(&o).contains("HANG: selftest-hang-1-") && text(&o).contains("ran past 1 s"), "{}", text(&o));
    let kept = std::fs::read_dir(&findings).unwrap().filter_map(Result::ok);
    assert!(kept.into_iter().any(|e| e.file_name().to_string_lossy().starts_with("selftest-hang-1-")));
    assert!(took < Duration::from_secs(30), "the hang was cut at its timeout: {took:?}");

    let (o, _) = fuzz(&["--kinds", "selftest-abort", "--mutants", "5"], dir.path(), Duration::from_secs(60));
    assert!(o.status.code().is_none(), "an abort ends the process by a signal: {:?}", o.status);
    let progress = std::fs::read_to_string(dir.path().join("work/progress")).unwrap();
    assert!(progress.starts_with("selftest-abort-1-"), "progress names the mutant in flight: {progress}");
    assert!(dir.path().join("work/mutant-selftest-abort.txt").is_file(), "and it is still on disk");
}

#[test]
fn unknown_kinds_are_a_usage_error() {
    let dir = tempfile::tempdir().unwrap();
    let (o, _) = fuzz(&["--kinds", "opendrive,nonsense"], dir.path(), Duration::from_secs(30));
    assert_eq!(o.status.code(), Some(2));
    assert!(text(&o).contains("unknown kind `nonsense`") && text(&o).contains("opendrive"), "{}", text(&o));
}
