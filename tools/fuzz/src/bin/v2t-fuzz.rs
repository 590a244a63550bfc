//! `v2t-fuzz`: mutants of every input kind through its reader; see the crate's documentation.
//!
//! Exit codes: 0 no finding, 1 a panic (kept under `--findings`), 2 bad usage, 3 a hang (kept),
//! and the process dies by a signal when a mutant aborts it (the input is `WORK/mutant.*`, named in
//! `WORK/progress`).

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;

use clap::Parser;
use v2t_fuzz::harness::{Plan, run};
use v2t_fuzz::targets::{Context, KINDS, kind};

/// Mutation harness of every parser and decoder a user or a network peer can feed.
#[derive(Debug, Parser)]
#[command(name = "v2t-fuzz", version)]
struct Cli {
    /// The kinds to run, comma-separated (default: all; `--list` names them).
    #[arg(long, value_delimiter = ',')]
    kinds: Vec<String>,
    /// List the kinds and exit.
    #[arg(long)]
    list: bool,
    /// Mutants per kind at most (1 to 10,000,000).
    #[arg(long, default_value_t = 1000, value_parser = clap::value_parser!(u64).range(1..=10_000_000))]
    mutants: u64,
    /// Wall-clock budget of all the mutants, s (shared equally by the kinds; 1 to 86,400).
    #[arg(long, default_value_t = 600, value_parser = clap::value_parser!(u64).range(1..=86_400))]
    budget_s: u64,
    /// Mutation seed.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// A mutant running longer than this is a hang, s (1 to 3,600).
    #[arg(long, default_value_t = 10, value_parser = clap::value_parser!(u64).range(1..=3600))]
    timeout_s: u64,
    /// The repository root (seeds come from its `config/`).
    #[arg(long, default_value = ".")]
    repo: PathBuf,
    /// Regression seeds, `DIR/<kind>/<file>` (default: REPO/tests/fuzz/regressions).
    #[arg(long)]
    regressions: Option<PathBuf>,
    /// Scratch folder (mutants are written here before they are read).
    #[arg(long, default_value = "target/fuzz/work")]
    work: PathBuf,
    /// Where findings are kept.
    #[arg(long, default_value = "target/fuzz/findings")]
    findings: PathBuf,
    /// Write the report (JSON) here.
    #[arg(long)]
    json: Option<PathBuf>,
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    if cli.list {
        for k in KINDS {
            // A reader that went away (`| head`) has what it wanted.
            if v2t_files::outln!("{:16} {}", k.name, k.what).is_err() {
                break;
            }
        }
        return ExitCode::SUCCESS;
    }
    let mut kinds = Vec::new();
    for name in &cli.kinds {
        match kind(name) {
            Some(k) => kinds.push(k),
            None => {
                let names: Vec<&str> = KINDS.iter().map(|k| k.name).collect();
                eprintln!("v2t-fuzz: --kinds: unknown kind `{name}`; one of: {}", names.join(", "));
                return ExitCode::from(2);
            }
        }
    }
    if kinds.is_empty() {
        kinds = KINDS.iter().collect();
    }
    let plan = Plan {
        kinds,
        mutants_per_kind: cli.mutants,
        budget: Duration::from_secs(cli.budget_s),
        seed: cli.seed,
        timeout: Duration::from_secs(cli.timeout_s),
        regressions: Some(cli.regressions.unwrap_or_else(|| cli.repo.join("tests/fuzz/regressions"))),
        findings: cli.findings,
    };
    // Lines stdout cannot take (its reader went away: `| head`) are dropped, never a panic: the
    // run goes on to its verdict, the exit code.
    let result = Context::new(&cli.repo, &cli.work).and_then(|ctx| {
        run(&ctx, &plan, |line| {
            let _ = v2t_files::outln!("{line}");
        })
    });
    match result {
        Ok(report) => {
            let _ = v2t_files::out!("\n{}", report.table());
            if let Some(path) = &cli.json
                && let Err(e) = serde_json::to_string_pretty(&report)
                    .map_err(anyhow::Error::from)
                    .and_then(|t| Ok(std::fs::write(path, t)?))
            {
                eprintln!("v2t-fuzz: cannot write {}: {e}", path.display());
                return ExitCode::FAILURE;
            }
            if report.panics() > 0 { ExitCode::FAILURE } else { ExitCode::SUCCESS }
        }
        Err(e) => {
            eprintln!("v2t-fuzz: {}", v2t_files::error_chain(e.as_ref()));
            ExitCode::FAILURE
        }
    }
}
