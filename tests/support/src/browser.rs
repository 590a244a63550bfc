//! Headless Chromium (the Debian package `chromium`) for the tests of the HTML reports: the page as
//! the browser left it after its scripts ran, every console line it logged, and a screenshot.

use std::io::Read as _;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// What the browser made of a page.
#[derive(Debug, Clone)]
pub struct Opened {
    /// The DOM after the page's scripts ran (`--dump-dom`).
    pub dom: String,
    /// Every console message the page logged (errors, warnings, logs; uncaught exceptions too).
    pub console: Vec<String>,
    /// Wall time of the browser process, from start to exit, s.
    pub wall_s: f64,
}

/// A fresh profile folder, removed when dropped.
struct Profile(PathBuf);

impl Drop for Profile {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

fn profile() -> Profile {
    use std::sync::atomic::{AtomicU32, Ordering};
    static N: AtomicU32 = AtomicU32::new(0);
    let dir =
        std::env::temp_dir().join(format!("v2t-chromium-{}-{}", std::process::id(), N.fetch_add(1, Ordering::Relaxed)));
    let _ = std::fs::create_dir_all(&dir);
    Profile(dir)
}

/// Runs headless Chromium on `page` with `extra` options; its stdout, its console lines and its
/// wall time. Fails after `timeout`.
fn run(page: &Path, extra: &[String], timeout: Duration) -> Result<(String, Vec<String>, f64), String> {
    let exe = crate::find("chromium").ok_or("chromium is not installed")?;
    let page = std::path::absolute(page).map_err(|e| format!("{}: {e}", page.display()))?;
    let profile = profile();
    let mut cmd = Command::new(exe);
    cmd.args([
        "--headless",
        "--no-sandbox",
        "--disable-gpu",
        "--disable-dev-shm-usage",
        "--no-first-run",
        "--disable-extensions",
        "--disable-background-networking",
        "--disable-component-update",
        "--enable-logging=stderr",
        "--v=0",
    ])
    .arg(format!("--user-data-dir={}", profile.0.display()))
    .args(extra)
    .arg(format!("file://{}", page.display()))
    .stdin(Stdio::null())
    .stdout(Stdio::piped())
    .stderr(Stdio::piped());
    let started = Instant::now();
    let mut child = cmd.spawn().map_err(|e| format!("chromium: {e}"))?;
    let mut stdout = child.stdout.take().ok_or("no stdout")?;
    let mut stderr = child.stderr.take().ok_or("no stderr")?;
    let out = std::thread::spawn(move || {
        let mut s = String::new();
        let _ = stdout.read_to_string(&mut s);
        s
    });
    let err = std::thread::spawn(move || {
        let mut s = String::new();
        let _ = stderr.read_to_string(&mut s);
        s
    });
    loop {
        match child.try_wait() {
            Ok(Some(_)) => break,
            Ok(None) if started.elapsed() > timeout => {
                let _ = child.kill();
                let _ = child.wait();
                return Err(format!("chromium did not finish {} within {timeout:?}", page.display()));
            }
            Ok(None) => std::thread::sleep(Duration::from_millis(50)),
            Err(e) => return Err(format!("chromium: {e}")),
        }
    }
    let wall_s = started.elapsed().as_secs_f64();
    let out = out.join().unwrap_or_default();
    let err = err.join().unwrap_or_default();
    // Chromium logs every console message of the page as `…:CONSOLE(line)] "message", source: …`.
    let console = err.lines().filter(|l| l.contains(":CONSOLE")).map(str::to_owned).collect();
    Ok((out, console, wall_s))
}

/// Opens `page` (a local HTML file) and returns its DOM after the scripts ran, and the console.
pub fn open(page: &Path) -> Result<Opened, String> {
    let (dom, console, wall_s) = run(page, &["--dump-dom".to_owned()], Duration::from_secs(120))?;
    if dom.trim().is_empty() {
        return Err(format!("chromium returned no DOM for {}", page.display()));
    }
    Ok(Opened { dom, console, wall_s })
}

/// Runs the browser on `page` with `option=<out>` and `extra`, and checks that `out` starts with
/// `magic`.
fn to_file(page: &Path, option: &str, out: &Path, extra: &[String], magic: &[u8]) -> Result<(), String> {
    if let Some(dir) = out.parent() {
        std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    }
    let _ = std::fs::remove_file(out);
    let target = std::path::absolute(out).map_err(|e| format!("{}: {e}", out.display()))?;
    let mut options = vec![format!("{option}={}", target.display())];
    options.extend_from_slice(extra);
    run(page, &options, Duration::from_secs(120))?;
    let bytes = std::fs::read(out).map_err(|e| format!("nothing written to {}: {e}", out.display()))?;
    if !bytes.starts_with(magic) {
        return Err(format!("{} is not what {option} writes", out.display()));
    }
    Ok(())
}

/// A screenshot of `page`, `width` × `height` px, PNG at `png`.
pub fn screenshot(page: &Path, png: &Path, width: u32, height: u32) -> Result<(), String> {
    let extra = [format!("--window-size={width},{height}"), "--hide-scrollbars".to_owned()];
    to_file(page, "--screenshot", png, &extra, b"\x89PNG")
}

/// `page` printed to PDF at `pdf` (A4, the page's print styles), as a reader would print it.
pub fn print_pdf(page: &Path, pdf: &Path) -> Result<(), String> {
    to_file(page, "--print-to-pdf", pdf, &["--no-pdf-header-footer".to_owned()], b"%PDF")
}
