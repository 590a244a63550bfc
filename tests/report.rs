//! Opening the HTML reports in a real browser (headless Chromium): what every report must show
//! whatever its content, and a screenshot kept under `target/report-screenshots/` (CI's artifact).

#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used)] // test code

use std::path::{Path, PathBuf};

use v2t_test_support::browser::{self, Opened};

use crate::repo_root;

/// Where the screenshots go.
pub fn screenshot_dir() -> PathBuf {
    repo_root().join("target/report-screenshots")
}

/// Opens `html` headless: the page fetches nothing, logs nothing to the console, raises no error,
/// and its script ran to the end (`data-ready-ms`). Keeps a `width` × `height` screenshot as
/// `target/report-screenshots/<name>.png` and prints the size and the time the script took.
pub fn open_checked(html: &Path, name: &str, height: u32) -> Opened {
    let text = std::fs::read_to_string(html).unwrap();
    for fetch in ["src=\"http", "href=\"http", "src='http", "@import", "url(http"] {
        assert!(!text.contains(fetch), "{}: `{fetch}`: the report must be self-contained", html.display());
    }
    let opened = browser::open(html).unwrap_or_else(|e| panic!("{e}"));
    assert!(opened.console.is_empty(), "{}: the page logged:\n{}", html.display(), opened.console.join("\n"));
    assert!(
        !opened.dom.contains("data-errors="),
        "{}: the page raised errors: {}",
        html.display(),
        attr(&opened.dom, "data-errors").unwrap_or_default()
    );
    let ready = attr(&opened.dom, "data-ready-ms")
        .unwrap_or_else(|| panic!("{}: the page's script did not finish", html.display()));
    let png = screenshot_dir().join(format!("{name}.png"));
    browser::screenshot(html, &png, 1280, height).unwrap_or_else(|e| panic!("{e}"));
    println!(
        "{name}: {} bytes, script done {ready} ms after navigation, browser {:.2} s; screenshot {}",
        text.len(),
        opened.wall_s,
        png.display()
    );
    opened
}

/// The value of the first `name="…"` attribute in `dom`.
pub fn attr(dom: &str, name: &str) -> Option<String> {
    let start = dom.find(&format!("{name}=\""))? + name.len() + 2;
    let len = dom.get(start..)?.find('"')?;
    dom.get(start..start + len).map(str::to_owned)
}

/// Asserts that the DOM of a run's section shows every part a run's report has: the map with its
/// lanes and marks (when `on_map`), the conflict zone, routes and driven paths, fixed footprints
/// and the slider's footprints moved by the script, the plots with labelled axes, the τ line, the
/// zone-occupancy timeline with the PET gap, the regulator's status and the realism.
pub fn assert_run_parts(section: &str, on_map: bool, gate: bool) {
    let has = |part: &str| assert!(section.contains(part), "`{part}` missing from the run's section");
    if on_map {
        has("class=\"lane\"");
        has("class=\"mark\"");
    }
    for part in [
        "<svg class=\"map\"",
        "class=\"zone\"",
        "class=\"route\"",
        "class=\"driven\"",
        "class=\"ghost\"",
        "class=\"fp\"",
        "class=\"slider\"",
        "class=\"plot speed\"",
        "speed (m/s)",
        "class=\"plot accel\"",
        "acceleration (m/s²)",
        "class=\"plot pet\"",
        "τ = ",
        "time (s)",
        "class=\"plot timeline occupancy\"",
        "PET ",
        "class=\"plot timeline states\"",
        "regulator ",
        "class=\"realism\"",
        "button data-t=",
    ] {
        has(part);
    }
    if gate {
        has("actuation gate");
        has("Engaged");
    }
    // The script moved the footprints to the first key moment: a rotation only it writes.
    let fp = section.find("class=\"fp\"").unwrap();
    let tag_start = section[..fp].rfind('<').unwrap();
    let tag = &section[tag_start..tag_start + section[tag_start..].find('>').unwrap()];
    assert!(tag.contains("rotate("), "the slider's script did not place the footprints: {tag}");
}

/// The run sections of a report's DOM.
pub fn run_sections(dom: &str) -> Vec<&str> {
    dom.split("<section class=\"run\"").skip(1).map(|s| s.split("</section>").next().unwrap_or(s)).collect()
}
