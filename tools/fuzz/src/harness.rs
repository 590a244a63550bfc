//! The loop: the regression seeds first, then mutants of every seed of every kind until the count
//! or the time budget is spent. Each mutant is written to disk before it is read (readers that
//! take paths read it there; a crash leaves it for the finding), a panic is caught and kept, a
//! mutant that runs past the timeout is kept and ends the process (exit 3), and one that aborts
//! the process (an allocation refused under the memory cap) is left on disk with `progress` naming
//! it, for the caller to keep.

use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use serde::Serialize;

use crate::mutate::{Rng, mutate};
use crate::targets::{Context, Kind};

/// What one run of the harness is asked to do.
#[derive(Debug, Clone)]
pub struct Plan {
    /// The kinds to run.
    pub kinds: Vec<&'static Kind>,
    /// Mutants per kind at most.
    pub mutants_per_kind: u64,
    /// Wall-clock budget of all the mutants (the regression seeds and the seeds' setup come on top).
    pub budget: Duration,
    /// Seed of the mutations (mutant `i` of a kind is the same for the same seed).
    pub seed: u64,
    /// A mutant running longer than this is a hang.
    pub timeout: Duration,
    /// Regression seeds: `<dir>/<kind>/<file>`, each read first.
    pub regressions: Option<PathBuf>,
    /// Where findings are kept: `<dir>/<kind>-<index>.<ext>`.
    pub findings: PathBuf,
}

/// What one kind gave.
#[derive(Debug, Clone, Default, Serialize)]
pub struct KindReport {
    /// The kind.
    pub kind: String,
    /// What it is.
    pub what: String,
    /// Seeds mutated.
    pub seeds: usize,
    /// Regression seeds read.
    pub regressions: usize,
    /// Mutants read.
    pub mutants: u64,
    /// Accepted (parsed and consumed).
    pub accepted: u64,
    /// Refused with an error.
    pub refused: u64,
    /// Panics (each kept under `findings`).
    pub panics: Vec<String>,
    /// Wall time of the mutants, s.
    pub seconds: f64,
}

/// The whole run.
#[derive(Debug, Clone, Default, Serialize)]
pub struct Report {
    /// Mutation seed.
    pub seed: u64,
    /// Per kind.
    pub kinds: Vec<KindReport>,
}

impl Report {
    /// Mutants over every kind.
    pub fn mutants(&self) -> u64 {
        self.kinds.iter().map(|k| k.mutants).sum()
    }

    /// Panics over every kind.
    pub fn panics(&self) -> usize {
        self.kinds.iter().map(|k| k.panics.len()).sum()
    }

    /// A markdown table.
    pub fn table(&self) -> String {
        let mut out = String::from(
            "| input | seeds | regression seeds | mutants | accepted | refused | panics | mutants/s |\n|---|---|---|---|---|---|---|---|\n",
        );
        for k in &self.kinds {
            let rate = if k.seconds > 0.0 { k.mutants as f64 / k.seconds } else { 0.0 };
            out.push_str(&format!(
                "| {} | {} | {} | {} | {} | {} | {} | {rate:.0} |\n",
                k.kind,
                k.seeds,
                k.regressions,
                k.mutants,
                k.accepted,
                k.refused,
                k.panics.len()
            ));
        }
        out.push_str(&format!(
            "\n{} mutants of {} kinds, seed {}: {} panics, 0 aborts, 0 hangs (either would have ended the run)\n",
            self.mutants(),
            self.kinds.len(),
            self.seed,
            self.panics()
        ));
        out
    }
}

/// The message of the last panic (the hook keeps it instead of printing it).
static LAST_PANIC: Mutex<String> = Mutex::new(String::new());

fn quiet_panics() {
    std::panic::set_hook(Box::new(|info| {
        let at = info.location().map(|l| format!(" at {}:{}", l.file(), l.line())).unwrap_or_default();
        let message = info
            .payload()
            .downcast_ref::<&str>()
            .map(|s| (*s).to_owned())
            .or_else(|| info.payload().downcast_ref::<String>().cloned())
            .unwrap_or_default();
        if let Ok(mut last) = LAST_PANIC.lock() {
            *last = format!("{message}{at}");
        }
    }));
}

/// Watches the mutant in flight: one that runs past `timeout` is copied to `findings` and the
/// process ends with exit code 3.
#[derive(Debug, Clone)]
struct Watchdog {
    started_ms: Arc<AtomicU64>,
    current: Arc<Mutex<(String, PathBuf)>>,
}

fn now_ms() -> u64 {
    std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map_or(0, |d| d.as_millis() as u64)
}

impl Watchdog {
    fn start(timeout: Duration, findings: PathBuf) -> Self {
        let dog = Self {
            started_ms: Arc::new(AtomicU64::new(0)),
            current: Arc::new(Mutex::new((String::new(), PathBuf::new()))),
        };
        let watched = dog.clone();
        std::thread::spawn(move || {
            loop {
                std::thread::sleep(Duration::from_millis(100));
                let started = watched.started_ms.load(Ordering::SeqCst);
                if started != 0 && now_ms().saturating_sub(started) > timeout.as_millis() as u64 {
                    let (label, path) = watched.current.lock().map(|c| c.clone()).unwrap_or_default();
                    let kept = keep(&findings, &label, &path);
                    // Dropped when stdout's reader went away: the exit code says it.
                    let _ = v2t_files::outln!(
                        "HANG: {label} ran past {} s; the input is kept as {}",
                        timeout.as_secs_f64(),
                        kept.display()
                    );
                    let _ = std::io::stdout().flush();
                    std::process::exit(3);
                }
            }
        });
        dog
    }

    fn begin(&self, label: &str, path: &Path) {
        if let Ok(mut c) = self.current.lock() {
            *c = (label.to_owned(), path.to_owned());
        }
        self.started_ms.store(now_ms().max(1), Ordering::SeqCst);
    }

    fn end(&self) {
        self.started_ms.store(0, Ordering::SeqCst);
    }
}

/// Copies the input at `path` into `findings` under a name made from `label`; returns where.
fn keep(findings: &Path, label: &str, path: &Path) -> PathBuf {
    let ext = path.extension().map(|e| e.to_string_lossy().into_owned()).unwrap_or_default();
    let name: String = label.chars().map(|c| if c.is_ascii_alphanumeric() || c == '-' { c } else { '_' }).collect();
    let to = findings.join(format!("{name}.{ext}"));
    let _ = std::fs::create_dir_all(findings);
    let _ = std::fs::copy(path, &to);
    to
}

/// Writes `label` into `work/progress` (what the caller reads when the process died).
fn progress(work: &Path, label: &str) {
    let _ = std::fs::write(work.join("progress"), label);
}

/// Runs the plan; a panic is recorded and kept, a hang ends the process (exit 3).
pub fn run(ctx: &Context, plan: &Plan, mut log: impl FnMut(&str)) -> anyhow::Result<Report> {
    quiet_panics();
    let dog = Watchdog::start(plan.timeout, plan.findings.clone());
    let mut report = Report { seed: plan.seed, kinds: Vec::new() };
    let per_kind = plan.budget.div_f64(plan.kinds.len().max(1) as f64);
    for (k, kind) in plan.kinds.iter().enumerate() {
        let seeds = ctx.seeds(kind)?;
        let path = ctx.mutant_path(kind);
        // A seed the reader refuses would make every mutant stop at the first check: the
        // harness itself would be broken.
        for (name, bytes) in &seeds {
            std::fs::write(&path, bytes)?;
            ctx.check(kind, &path, bytes)
                .map_err(|e| anyhow::anyhow!("{}: seed `{name}` is refused: {e}", kind.name))?;
        }
        let mut r =
            KindReport { kind: kind.name.into(), what: kind.what.into(), seeds: seeds.len(), ..KindReport::default() };
        let mut one = |label: String, bytes: &[u8], r: &mut KindReport| -> anyhow::Result<()> {
            std::fs::write(&path, bytes)?;
            progress(&ctx.work, &label);
            dog.begin(&label, &path);
            let outcome = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| ctx.check(kind, &path, bytes)));
            dog.end();
            match outcome {
                Ok(Ok(())) => r.accepted += 1,
                Ok(Err(_)) => r.refused += 1,
                Err(_) => {
                    let message = LAST_PANIC.lock().map(|m| m.clone()).unwrap_or_default();
                    let kept = keep(&plan.findings, &label, &path);
                    log(&format!("PANIC: {label}: {message}; the input is kept as {}", kept.display()));
                    r.panics.push(format!("{label}: {message}"));
                }
            }
            Ok(())
        };
        if let Some(dir) = &plan.regressions {
            let dir = dir.join(kind.name);
            if dir.is_dir() {
                let mut files: Vec<PathBuf> =
                    std::fs::read_dir(&dir)?.filter_map(Result::ok).map(|e| e.path()).collect();
                files.sort();
                for f in files.iter().filter(|f| f.is_file() && f.extension().is_some_and(|e| e == kind.ext)) {
                    let bytes = std::fs::read(f)?;
                    let name = f.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
                    one(format!("{}-regression-{name}", kind.name), &bytes, &mut r)?;
                    r.regressions += 1;
                }
            }
        }
        // Regression seeds are counted apart from the mutants (their panics stay in the report).
        r.accepted = 0;
        r.refused = 0;
        let started = Instant::now();
        let mut rng = Rng::new(plan.seed.wrapping_mul(0x100).wrapping_add(k as u64));
        let mut i = 0u64;
        while i < plan.mutants_per_kind && started.elapsed() < per_kind && !seeds.is_empty() {
            let Some((_, seed)) = seeds.get((i as usize) % seeds.len()) else { break };
            let bytes = mutate(&mut rng, seed, kind.form);
            one(format!("{}-{}-{i}", kind.name, plan.seed), &bytes, &mut r)?;
            i += 1;
        }
        r.mutants = i;
        r.seconds = started.elapsed().as_secs_f64();
        log(&format!(
            "{}: {} mutants in {:.1} s ({} accepted, {} refused, {} panics), {} regression seeds",
            kind.name,
            r.mutants,
            r.seconds,
            r.accepted,
            r.refused,
            r.panics.len(),
            r.regressions
        ));
        report.kinds.push(r);
    }
    progress(&ctx.work, "done");
    Ok(report)
}
