//! The dependency rule of `docs/ARCHITECTURE.md` ("The crates and their dependency rule"), checked
//! on the workspace as `cargo metadata --no-deps` describes it: every crate's normal and build
//! dependencies on other workspace crates (dev-dependencies are test code and may reach anywhere).
//! A crate in a folder the table below does not know fails the test, so a new crate cannot slip in
//! without a layer; so does a known exception the tree no longer needs.

#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)] // test code

use std::collections::BTreeMap;
use std::process::Command;

use serde_json::Value;
use v2t_tests::repo_root;

/// What the crates in `crates` may depend on. `crates` and every entry of `may_use` and
/// `never_links` name folders: `shared/*` is every crate under `shared/`, `*` every crate,
/// anything else one crate's folder. The first row whose `crates` matches a crate is its rule.
struct Rule {
    crates: &'static str,
    /// The folders its normal and build dependencies may lie in.
    may_use: &'static [&'static str],
    /// Folders it never reaches through any chain of normal or build dependencies.
    never_links: &'static [&'static str],
    /// Third-party crates no workspace crate it reaches names as a normal or build dependency.
    never_links_external: &'static [&'static str],
    /// The rule, as ARCHITECTURE.md words it.
    says: &'static str,
}

const NOTHING: &[&str] = &[];

/// ARCHITECTURE.md's arrows, transcribed. Its layers: `shared/*`, the edge (`edge/*`), the cloud
/// (`cloud/*`), the lab (`tools/*`), the command line above them all (`app`); the tests' two
/// crates are not in its table (see their rows).
const RULES: &[Rule] = &[
    Rule {
        crates: "shared/model",
        may_use: NOTHING,
        never_links: NOTHING,
        never_links_external: NOTHING,
        says: "`shared/*` depends on nothing of ours but `shared/*` below it (`v2t-model` at the bottom)",
    },
    // "Below it" orders the shared crates only by "`v2t-model` at the bottom"; cargo refuses a
    // cycle, so any shared crate may use any other.
    Rule {
        crates: "shared/*",
        may_use: &["shared/*"],
        never_links: NOTHING,
        never_links_external: NOTHING,
        says: "`shared/*` depends on nothing of ours but `shared/*` below it",
    },
    Rule {
        crates: "edge/node",
        may_use: &["shared/*", "edge/game", "edge/track"],
        never_links: &["cloud/*", "tools/lab", "shared/sim"],
        // `--no-deps` shows only what workspace crates name: a third-party crate that pulled
        // `mcap` in would not show here (`cargo tree -p v2t-edge -e normal` would).
        never_links_external: &["mcap"],
        says: "the edge depends on `shared/*` and the pure edge crates; nothing on the edge depends \
               on `cloud/*` or on `tools/lab`, and `v2t-edge` does not link `v2t-sim` \
               (`cargo tree -p v2t-edge -e normal` shows neither `v2t-sim` nor `mcap`)",
    },
    // The pure edge crates: `v2t-game` and `v2t-track` (ARCHITECTURE.md's list of pure crates).
    Rule {
        crates: "edge/*",
        may_use: &["shared/*", "edge/game", "edge/track"],
        never_links: &["cloud/*", "tools/lab"],
        never_links_external: NOTHING,
        says: "the edge depends on `shared/*` and the pure edge crates; nothing on the edge depends \
               on `cloud/*` or on `tools/lab`",
    },
    Rule {
        crates: "app",
        may_use: &["shared/*", "edge/*", "cloud/*", "tools/*"],
        never_links: NOTHING,
        never_links_external: NOTHING,
        says: "the command line [depends] on everything it drives",
    },
    Rule {
        crates: "cloud/*",
        may_use: &["shared/*"],
        never_links: NOTHING,
        never_links_external: NOTHING,
        says: "the cloud crates depend on `shared/*`",
    },
    Rule {
        crates: "tools/*",
        may_use: &["shared/*", "edge/*", "cloud/*", "tools/*"],
        never_links: NOTHING,
        never_links_external: NOTHING,
        says: "the lab depends on whatever it measures, edge and cloud alike",
    },
    // Not in ARCHITECTURE.md's table: what every test suite shares (finding system tools, the
    // counting allocator) stands on nothing of ours, so any crate's tests can use it.
    Rule {
        crates: "tests/support",
        may_use: NOTHING,
        never_links: NOTHING,
        never_links_external: NOTHING,
        says: "`tests/support` depends on nothing of ours (not in ARCHITECTURE.md's table)",
    },
    // Not in ARCHITECTURE.md's table: the workspace-level integration tests drive every layer.
    Rule {
        crates: "tests",
        may_use: &["*"],
        never_links: NOTHING,
        never_links_external: NOTHING,
        says: "the workspace-level tests may depend on anything (not in ARCHITECTURE.md's table)",
    },
];

/// A dependency the rule as written does not allow, but the tree needs.
struct Exception {
    from: &'static str,
    to: &'static str,
    why: &'static str,
}

const EXCEPTIONS: &[Exception] = &[
    Exception {
        from: "edge/node",
        to: "edge/can",
        why: "`v2t-can` is not among ARCHITECTURE.md's pure crates (its transport is one of the \
              adapters), yet the onboard runtime's gateway process is `v2t-can`'s codec, gate and \
              SocketCAN transport (the pipeline's `gateway (v2t-can)`)",
    },
    Exception {
        from: "tools/lab",
        to: "tests/support",
        why: "the lab's `v2t-bench` binary counts allocations with `v2t_test_support::alloc`, the \
              one counting allocator of the allocation tests; the lab ships nothing",
    },
];

/// One workspace crate: its name, its folder relative to the workspace root, the workspace crates
/// and the third-party crates it names as normal or build dependencies.
#[derive(Debug, Clone)]
struct Crate {
    name: String,
    folder: String,
    uses: Vec<String>,
    uses_external: Vec<String>,
}

fn matches(pattern: &str, folder: &str) -> bool {
    match pattern.strip_suffix("/*") {
        _ if pattern == "*" => true,
        Some(layer) => folder.strip_prefix(layer).is_some_and(|rest| rest.starts_with('/')),
        None => pattern == folder,
    }
}

fn rule_of(folder: &str) -> Option<&'static Rule> {
    RULES.iter().find(|r| matches(r.crates, folder))
}

/// Every workspace crate with its normal and build dependencies, from `cargo metadata`'s JSON.
fn workspace(metadata: &Value) -> Vec<Crate> {
    let root = std::path::Path::new(metadata["workspace_root"].as_str().unwrap());
    let members: Vec<&str> =
        metadata["workspace_members"].as_array().unwrap().iter().map(|m| m.as_str().unwrap()).collect();
    let packages: Vec<&Value> = metadata["packages"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|p| members.contains(&p["id"].as_str().unwrap()))
        .collect();
    let names: Vec<&str> = packages.iter().map(|p| p["name"].as_str().unwrap()).collect();
    packages
        .iter()
        .map(|p| {
            let manifest = std::path::Path::new(p["manifest_path"].as_str().unwrap());
            let folder = manifest.parent().unwrap().strip_prefix(root).unwrap();
            let folder: Vec<String> =
                folder.components().map(|c| c.as_os_str().to_string_lossy().into_owned()).collect();
            let (mut uses, mut uses_external) = (Vec::new(), Vec::new());
            for d in p["dependencies"].as_array().unwrap() {
                // `kind` is null for a normal dependency, "build" or "dev" otherwise.
                if d["kind"].as_str() == Some("dev") {
                    continue;
                }
                let name = d["name"].as_str().unwrap().to_owned();
                if names.contains(&name.as_str()) {
                    uses.push(name);
                } else {
                    uses_external.push(name);
                }
            }
            Crate { name: p["name"].as_str().unwrap().to_owned(), folder: folder.join("/"), uses, uses_external }
        })
        .collect()
}

/// The crates `start` reaches through its dependencies, itself excluded.
fn reached<'a>(start: &'a Crate, by_name: &BTreeMap<&str, &'a Crate>) -> Vec<&'a Crate> {
    let mut seen: Vec<&Crate> = Vec::new();
    let mut stack: Vec<&str> = start.uses.iter().map(String::as_str).collect();
    while let Some(name) = stack.pop() {
        let Some(c) = by_name.get(name) else { continue };
        if c.name == start.name || seen.iter().any(|s| s.name == c.name) {
            continue;
        }
        seen.push(c);
        stack.extend(c.uses.iter().map(String::as_str));
    }
    seen
}

/// Every breach of [`RULES`] in `crates`, and every exception `crates` no longer needs, as
/// sentences that name the crate, the dependency and the rule.
fn breaches(crates: &[Crate]) -> Vec<String> {
    let by_name: BTreeMap<&str, &Crate> = crates.iter().map(|c| (c.name.as_str(), c)).collect();
    let mut out = Vec::new();
    let mut used_exceptions = vec![false; EXCEPTIONS.len()];
    for c in crates {
        let Some(rule) = rule_of(&c.folder) else {
            out.push(format!(
                "{} ({}) lies in no layer of docs/ARCHITECTURE.md: add its folder to the rule's table \
                 and to tests/dependency_rule.rs",
                c.name, c.folder
            ));
            continue;
        };
        let mut refused: Vec<&str> = Vec::new();
        for dep in &c.uses {
            let Some(d) = by_name.get(dep.as_str()) else { continue };
            if rule.may_use.iter().any(|p| matches(p, &d.folder)) {
                continue;
            }
            if let Some(k) = EXCEPTIONS.iter().position(|e| e.from == c.folder && e.to == d.folder) {
                used_exceptions[k] = true;
                continue;
            }
            refused.push(&d.name);
            out.push(format!(
                "{} ({}) depends on {} ({}), which the rule for {} does not allow: {}",
                c.name, c.folder, d.name, d.folder, rule.crates, rule.says
            ));
        }
        // What it reaches, directly (when `may_use` allows it) or through other crates.
        for d in reached(c, &by_name).into_iter().filter(|d| !refused.contains(&d.name.as_str())) {
            if let Some(p) = rule.never_links.iter().find(|p| matches(p, &d.folder)) {
                out.push(format!(
                    "{} ({}) links {} ({}) through its dependencies, which the rule for {} forbids ({p}): {}",
                    c.name, c.folder, d.name, d.folder, rule.crates, rule.says
                ));
            }
        }
        for d in std::iter::once(c).chain(reached(c, &by_name)) {
            for ext in d.uses_external.iter().filter(|e| rule.never_links_external.contains(&e.as_str())) {
                out.push(format!(
                    "{} ({}) links {ext} through {} ({}), which the rule for {} forbids: {}",
                    c.name, c.folder, d.name, d.folder, rule.crates, rule.says
                ));
            }
        }
    }
    for (e, used) in EXCEPTIONS.iter().zip(used_exceptions) {
        if !used {
            out.push(format!(
                "the exception {} -> {} is no longer needed (no such dependency): remove it from \
                 tests/dependency_rule.rs and docs/ARCHITECTURE.md ({})",
                e.from, e.to, e.why
            ));
        }
    }
    out
}

/// This workspace, as `cargo metadata --format-version 1 --no-deps` describes it.
fn this_workspace() -> Vec<Crate> {
    let cargo = std::env::var_os("CARGO").unwrap_or_else(|| "cargo".into());
    let out = Command::new(&cargo)
        .args(["metadata", "--format-version", "1", "--no-deps", "--manifest-path"])
        .arg(repo_root().join("Cargo.toml"))
        .output()
        .unwrap_or_else(|e| panic!("running {} metadata: {e}", cargo.to_string_lossy()));
    assert!(out.status.success(), "cargo metadata failed: {}", String::from_utf8_lossy(&out.stderr));
    let crates = workspace(&serde_json::from_slice(&out.stdout).unwrap());
    assert!(crates.len() >= 20, "expected the workspace's crates, found {crates:?}");
    crates
}

/// `crates` with a made-up dependency of the crate in `from` on the crate in `to`.
fn with_edge(mut crates: Vec<Crate>, from: &str, to: &str) -> Vec<Crate> {
    let to_name = crates.iter().find(|c| c.folder == to).unwrap().name.clone();
    crates.iter_mut().find(|c| c.folder == from).unwrap().uses.push(to_name);
    crates
}

#[test]
fn every_crate_depends_only_on_what_the_architecture_allows() {
    let found = breaches(&this_workspace());
    assert!(found.is_empty(), "the dependency rule of docs/ARCHITECTURE.md is broken:\n{}", found.join("\n"));
}

#[test]
fn the_checker_refuses_an_edge_crate_on_the_cloud() {
    let found = breaches(&with_edge(this_workspace(), "edge/game", "cloud/ground"));
    // The direct edge, and v2t-edge that now reaches the cloud through v2t-game.
    assert_eq!(found.len(), 2, "{found:?}");
    assert!(
        found.iter().any(|f| f.starts_with("v2t-game (edge/game) depends on v2t-ground (cloud/ground), which the rule for edge/* does not allow: the edge depends on `shared/*` and the pure edge crates")),
        "{found:?}"
    );
    assert!(found.iter().any(|f| f.starts_with("v2t-edge (edge/node) links v2t-ground (cloud/ground)")), "{found:?}");
}

#[test]
fn the_checker_refuses_a_shared_crate_on_the_edge() {
    let found = breaches(&with_edge(this_workspace(), "shared/map", "edge/game"));
    assert_eq!(
        found,
        ["v2t-map (shared/map) depends on v2t-game (edge/game), which the rule for shared/* does not allow: \
          `shared/*` depends on nothing of ours but `shared/*` below it"]
    );
}

#[test]
fn the_checker_refuses_the_onboard_runtime_linking_the_simulator_through_another_crate() {
    // An edge crate may use `shared/*`, but `v2t-edge` then links `v2t-sim` (and `mcap`).
    let found = breaches(&with_edge(this_workspace(), "edge/track", "shared/sim"));
    assert!(found.iter().any(|f| f.starts_with("v2t-edge (edge/node) links v2t-sim (shared/sim)")), "{found:?}");
    assert!(found.iter().any(|f| f.starts_with("v2t-edge (edge/node) links mcap through v2t-sim")), "{found:?}");
}

#[test]
fn the_checker_refuses_a_crate_outside_every_layer_and_a_stale_exception() {
    let mut crates = this_workspace();
    crates.push(Crate {
        name: "v2t-new".into(),
        folder: "plugins/new".into(),
        uses: Vec::new(),
        uses_external: Vec::new(),
    });
    for c in &mut crates {
        if c.folder == "tools/lab" {
            c.uses.retain(|d| d != "v2t-test-support");
        }
    }
    let found = breaches(&crates);
    assert_eq!(found.len(), 2, "{found:?}");
    assert!(found[0].starts_with("v2t-new (plugins/new) lies in no layer"), "{found:?}");
    assert!(found[1].starts_with("the exception tools/lab -> tests/support is no longer needed"), "{found:?}");
}

#[test]
fn folder_patterns_match_whole_folders() {
    assert!(matches("shared/*", "shared/model"));
    assert!(!matches("shared/*", "shared"));
    assert!(!matches("shared/*", "sharedx/model"));
    assert!(matches("edge/game", "edge/game"));
    assert!(!matches("edge/game", "edge/gamepad"));
    assert!(matches("*", "anything/at/all"));
    assert_eq!(rule_of("edge/node").map(|r| r.crates), Some("edge/node"));
    assert_eq!(rule_of("edge/can").map(|r| r.crates), Some("edge/*"));
    assert_eq!(rule_of("tests").map(|r| r.crates), Some("tests"));
    assert!(rule_of("docs").is_none());
}
