//! What the test suites share that is not about the project: the system tools some tests run
//! (`mosquitto`, `openssl`, `ffmpeg`, …), found on the machine or, when the suite runs without them
//! on purpose, reported as *not run* by the test's name — never passed in silence.
//!
//! `scripts/test` installs the Debian packages these tools come from and runs the suite. Run with
//! `scripts/test --no-install` (or set [`ALLOW_MISSING`] yourself), a test whose tool is missing
//! prints `NOT RUN <test>: needs <tool> (Debian package <package>)`, appends the same line to the
//! file named by [`NOT_RUN_LOG`] when that is set (the script lists them in its summary), and
//! returns before doing anything. Without [`ALLOW_MISSING`], a missing tool fails the test with
//! the command that installs it.
//!
//! It also holds the counting global allocator ([`alloc`]) of the tests that a control cycle
//! allocates nothing, and of `v2t-bench game`.

#![allow(clippy::panic)] // test support: a missing tool fails the calling test

pub mod alloc;

use std::io::Write as _;
use std::path::{Path, PathBuf};

/// Set to `1`, tests whose tool is missing report themselves as not run instead of failing.
pub const ALLOW_MISSING: &str = "V2T_ALLOW_MISSING_TOOLS";
/// A file that collects the `NOT RUN` lines of every test process (appended, one line each).
pub const NOT_RUN_LOG: &str = "V2T_NOT_RUN_LOG";

/// A system tool a test runs, and the Debian package it comes from.
#[derive(Debug, Clone, Copy)]
pub struct Tool {
    /// The executable's name, looked up in `PATH` and the system directories.
    pub name: &'static str,
    /// The Debian package that ships it.
    pub package: &'static str,
}

/// The MQTT broker the link tests start on loopback.
pub const MOSQUITTO: Tool = Tool { name: "mosquitto", package: "mosquitto" };
/// Writes Mosquitto's password files.
pub const MOSQUITTO_PASSWD: Tool = Tool { name: "mosquitto_passwd", package: "mosquitto" };
/// Makes the TLS certificates of the link tests.
pub const OPENSSL: Tool = Tool { name: "openssl", package: "openssl" };
/// Makes test videos, takes frames, encodes renders.
pub const FFMPEG: Tool = Tool { name: "ffmpeg", package: "ffmpeg" };
/// Probes videos.
pub const FFPROBE: Tool = Tool { name: "ffprobe", package: "ffmpeg" };

/// Opens the HTML reports headless.
pub const CHROMIUM: Tool = Tool { name: "chromium", package: "chromium" };

/// What the MQTT tests need: the broker.
pub const BROKER_TOOLS: &[Tool] = &[MOSQUITTO];
/// What the TLS and password tests need besides the broker.
pub const TLS_TOOLS: &[Tool] = &[MOSQUITTO, MOSQUITTO_PASSWD, OPENSSL];
/// What the video tests need.
pub const VIDEO_TOOLS: &[Tool] = &[FFMPEG, FFPROBE];
/// What the report tests need: a real browser.
pub const BROWSER_TOOLS: &[Tool] = &[CHROMIUM];

pub mod browser;

/// `require!(TOOLS)` at the top of a test: returns from the test, reported as not run, when a tool
/// of `TOOLS` (a `&[Tool]`) is missing and [`ALLOW_MISSING`] is set; fails it when not set.
#[macro_export]
macro_rules! require {
    ($tools:expr) => {
        if !$crate::tools_or_not_run($tools) {
            return;
        }
    };
}

/// Where `name` is installed: the first match in `PATH`, then `/usr/sbin`, `/usr/bin`, `/sbin`
/// (Mosquitto installs into `/usr/sbin`, which a user's `PATH` often lacks).
pub fn find(name: &str) -> Option<PathBuf> {
    let path = std::env::var_os("PATH").unwrap_or_default();
    std::env::split_paths(&path)
        .chain(["/usr/sbin", "/usr/bin", "/sbin"].into_iter().map(PathBuf::from))
        .map(|dir| dir.join(name))
        .find(|p| is_executable(p))
}

fn is_executable(p: &Path) -> bool {
    use std::os::unix::fs::PermissionsExt as _;
    p.metadata().is_ok_and(|m| m.is_file() && m.permissions().mode() & 0o111 != 0)
}

/// The tools of `tools` that are not installed.
pub fn missing(tools: &[Tool]) -> Vec<Tool> {
    tools.iter().copied().filter(|t| find(t.name).is_none()).collect()
}

/// `true` when every tool of `tools` is installed. Otherwise: with [`ALLOW_MISSING`] set, reports
/// the calling test as not run (by its name) and returns `false`, so the test returns at once;
/// without it, fails the test naming the packages to install.
///
/// ```no_run
/// # fn start_mosquitto() {}
/// if !v2t_test_support::tools_or_not_run(&[v2t_test_support::MOSQUITTO]) {
///     return;
/// }
/// start_mosquitto();
/// ```
pub fn tools_or_not_run(tools: &[Tool]) -> bool {
    let allow = std::env::var(ALLOW_MISSING).is_ok_and(|v| v == "1");
    let log = std::env::var_os(NOT_RUN_LOG).map(PathBuf::from);
    let test = std::thread::current().name().unwrap_or("<unnamed test>").to_owned();
    // The test binary's name is its target's (`link`, `client`) plus a hash: `link-0123abcd`.
    let exe = std::env::current_exe().ok();
    let stem = exe.as_deref().and_then(Path::file_stem).and_then(|s| s.to_str()).unwrap_or("test");
    let target = stem.rsplit_once('-').map_or(stem, |(name, _hash)| name);
    verdict(&format!("{target}::{test}"), &missing(tools), allow, log.as_deref())
}

/// What [`tools_or_not_run`] decides for `test` lacking `lacking`.
fn verdict(test: &str, lacking: &[Tool], allow: bool, log: Option<&Path>) -> bool {
    if lacking.is_empty() {
        return true;
    }
    let names = lacking.iter().map(|t| t.name).collect::<std::collections::BTreeSet<_>>();
    let names = names.into_iter().collect::<Vec<_>>().join(", ");
    let packages = lacking.iter().map(|t| t.package).collect::<std::collections::BTreeSet<_>>();
    let packages = packages.into_iter().collect::<Vec<_>>().join(" ");
    if !allow {
        panic!(
            "{names} is not installed: run `scripts/test`, which installs what the suite needs, or \
             `sudo apt-get install {packages}`; `scripts/test --no-install` runs the suite without it \
             and lists the tests that need it as not run"
        );
    }
    let line = format!("NOT RUN {test}: needs {names} (Debian package {packages})");
    eprintln!("{line}");
    if let Some(log) = log {
        // One write per line with O_APPEND: lines of parallel test processes do not interleave.
        let written = std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .open(log)
            .and_then(|mut f| f.write_all(format!("{line}\n").as_bytes()));
        if let Err(e) = written {
            panic!("could not record a test that did not run in {}: {e}", log.display());
        }
    }
    false
}

/// `true` when `found`. Otherwise, like [`tools_or_not_run`] for what is not a Debian package
/// (SUMO, found by its own crate): with [`ALLOW_MISSING`] set, prints
/// `NOT RUN <target>::<test>: needs <what> (<install>)`, appends that line to [`NOT_RUN_LOG`] when
/// set, and returns `false`, so the test returns at once; without it, fails the test with
/// `install`.
///
/// ```no_run
/// # let sumo_found = true;
/// if !v2t_test_support::found_or_not_run(sumo_found, "SUMO", "run `scripts/install-sumo`") {
///     return;
/// }
/// ```
pub fn found_or_not_run(found: bool, what: &str, install: &str) -> bool {
    if found {
        return true;
    }
    if !std::env::var(ALLOW_MISSING).is_ok_and(|v| v == "1") {
        panic!(
            "{what} is not installed: {install}; `scripts/test --no-install` runs the suite without \
             it and lists the tests that need it as not run"
        );
    }
    let test = std::thread::current().name().unwrap_or("<unnamed test>").to_owned();
    let exe = std::env::current_exe().ok();
    let stem = exe.as_deref().and_then(Path::file_stem).and_then(|s| s.to_str()).unwrap_or("test");
    let target = stem.rsplit_once('-').map_or(stem, |(name, _hash)| name);
    let line = format!("NOT RUN {target}::{test}: needs {what} ({install})");
    eprintln!("{line}");
    if let Some(log) = std::env::var_os(NOT_RUN_LOG).map(PathBuf::from) {
        // One write per line with O_APPEND: lines of parallel test processes do not interleave.
        let written = std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .open(&log)
            .and_then(|mut f| f.write_all(format!("{line}\n").as_bytes()));
        if let Err(e) = written {
            panic!("could not record a test that did not run in {}: {e}", log.display());
        }
    }
    false
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_shell_is_found_and_a_made_up_tool_is_missing() {
        assert!(find("sh").is_some());
        let ghost = Tool { name: "v2t-no-such-tool-here", package: "v2t-ghost" };
        assert_eq!(missing(&[ghost]).len(), 1);
        assert!(missing(&[Tool { name: "sh", package: "dash" }]).is_empty());
    }

    const GHOST: Tool = Tool { name: "v2t-ghost", package: "v2t-ghost-pkg" };

    #[test]
    fn a_missing_tool_is_reported_by_the_tests_name_when_allowed() {
        let dir = std::env::temp_dir().join(format!("v2t-support-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap_or_else(|e| panic!("{e}"));
        let log = dir.join("not-run.txt");
        assert!(verdict("x::present", &[], true, Some(&log)));
        assert!(!log.exists(), "a test with its tools logs nothing");
        assert!(!verdict("x::first", &[GHOST], true, Some(&log)));
        assert!(!verdict("x::second", &[GHOST, GHOST], true, Some(&log)));
        let text = std::fs::read_to_string(&log).unwrap_or_else(|e| panic!("{e}"));
        std::fs::remove_dir_all(&dir).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(
            text,
            "NOT RUN x::first: needs v2t-ghost (Debian package v2t-ghost-pkg)\n\
             NOT RUN x::second: needs v2t-ghost (Debian package v2t-ghost-pkg)\n"
        );
    }

    /// `scripts/test` installs what these lists name: its own table (tool:package, in bash) must
    /// hold every tool a test can require, with the same package.
    #[test]
    fn the_test_script_installs_every_tool_a_test_requires() {
        let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scripts/test");
        let text = std::fs::read_to_string(&script).unwrap_or_else(|e| panic!("{}: {e}", script.display()));
        let table = text
            .lines()
            .find_map(|l| l.strip_prefix("TOOLS=(").and_then(|rest| rest.strip_suffix(')')))
            .unwrap_or_else(|| panic!("{}: no `TOOLS=(…)` line", script.display()));
        let entries: Vec<&str> = table.split_whitespace().collect();
        for tool in BROKER_TOOLS.iter().chain(TLS_TOOLS).chain(VIDEO_TOOLS) {
            let entry = format!("{}:{}", tool.name, tool.package);
            assert!(entries.contains(&entry.as_str()), "scripts/test's TOOLS lacks {entry}: {table}");
        }
    }

    #[test]
    #[should_panic(expected = "v2t-ghost is not installed: run `scripts/test`")]
    fn a_missing_tool_fails_the_test_unless_allowed() {
        verdict("x::y", &[GHOST], false, None);
    }
}
