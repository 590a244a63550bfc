//! What the command-line tests share: running `video2track` from the repository root, scratch
//! folders, grounding the example semantics.

#![allow(dead_code, clippy::unwrap_used, clippy::panic)] // test code; not every test file uses every helper

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use tempfile::TempDir;

/// The repository root (commands run there, so `config/…` defaults resolve).
pub fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// Runs `video2track args` in the repository root.
pub fn video2track(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_video2track")).args(args).current_dir(repo()).output().unwrap()
}

/// Its stdout and stderr as text.
pub fn text(o: &Output) -> (String, String) {
    (String::from_utf8_lossy(&o.stdout).into_owned(), String::from_utf8_lossy(&o.stderr).into_owned())
}

/// Runs it and asserts success; returns stdout.
pub fn ok(args: &[&str]) -> String {
    let o = video2track(args);
    assert!(o.status.success(), "{args:?}: {}", String::from_utf8_lossy(&o.stderr));
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// A fresh scratch folder `v2t-cli-<name>-…`, removed when dropped.
pub fn tempdir(name: &str) -> TempDir {
    tempfile::Builder::new().prefix(&format!("v2t-cli-{name}-")).tempdir().unwrap()
}

/// A path as `&str`.
pub fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// Grounds `config/examples/semantics_<which>.json` into `dir/<which>.json`.
pub fn ground_example(dir: &Path, which: &str) -> PathBuf {
    let out = dir.join(format!("{which}.json"));
    ok(&["ground", &format!("config/examples/semantics_{which}.json"), "--out", s(&out)]);
    out
}
