//! The builtin VUT driver models take their parameters from `config/vut/builtin/*.toml`: this
//! script reads those files and writes one Rust function per file (`$OUT_DIR/builtin_vut.rs`),
//! so the files are the parameters' only source and a bad file fails the build, naming the file,
//! the line and what is wrong (a field the model lacks or misses is a compile error naming it).
//!
//! The format is a small, checked subset of TOML: `name`, `description` and `model` as strings,
//! then a `[params]` table of numbers or arrays of numbers, one per line; `#` starts a comment.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// The models and the Rust type of their parameters.
const MODELS: [(&str, &str); 3] = [
    ("idm", "crate::vut::idm::IdmParams"),
    ("reactive", "crate::vut::reactive::ReactiveParams"),
    ("sampling", "crate::vut::sampling::SamplingParams"),
];

fn main() -> Result<(), String> {
    let manifest = std::env::var("CARGO_MANIFEST_DIR").map_err(|e| format!("CARGO_MANIFEST_DIR: {e}"))?;
    let dir = Path::new(&manifest).join("../../config/vut/builtin");
    println!("cargo::rerun-if-changed={}", dir.display());
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
        .map_err(|e| format!("{}: {e}", dir.display()))?
        .filter_map(Result::ok)
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|x| x == "toml"))
        .collect();
    files.sort();
    let mut out = String::new();
    for path in &files {
        println!("cargo::rerun-if-changed={}", path.display());
        let text = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
        let file = parse(&text).map_err(|e| format!("{}: {e}", path.display()))?;
        let ty = MODELS
            .iter()
            .find(|(m, _)| *m == file.model)
            .map(|(_, ty)| *ty)
            .ok_or_else(|| format!("{}: model `{}`: one of idm, reactive, sampling", path.display(), file.model))?;
        let stem = path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
        if stem != file.name {
            return Err(format!("{}: name `{}` must be the file's name `{stem}`", path.display(), file.name));
        }
        let func = file.name.replace('-', "_");
        let _ = writeln!(out, "/// `config/vut/builtin/{stem}.toml`: {}", file.description.replace('`', "'"));
        let _ = writeln!(out, "pub(crate) fn {func}() -> {ty} {{");
        let _ = writeln!(out, "    {ty} {{");
        for (key, value) in &file.params {
            let _ = match value {
                Value::Number(x) => writeln!(out, "        {key}: {x:?},"),
                Value::Array(xs) => {
                    writeln!(
                        out,
                        "        {key}: vec![{}],",
                        xs.iter().map(|x| format!("{x:?}")).collect::<Vec<_>>().join(", ")
                    )
                }
            };
        }
        let _ = writeln!(out, "    }}\n}}\n");
        let _ = writeln!(
            out,
            "/// `{}`'s description.\npub(crate) const {}_DESCRIPTION: &str = {:?};\n",
            file.name,
            func.to_uppercase(),
            file.description
        );
    }
    let dest = Path::new(&std::env::var("OUT_DIR").map_err(|e| format!("OUT_DIR: {e}"))?).join("builtin_vut.rs");
    std::fs::write(&dest, out).map_err(|e| format!("{}: {e}", dest.display()))
}

enum Value {
    Number(f64),
    Array(Vec<f64>),
}

struct File {
    name: String,
    description: String,
    model: String,
    params: Vec<(String, Value)>,
}

fn number(s: &str, line: usize) -> Result<f64, String> {
    let x: f64 = s.trim().parse().map_err(|_| format!("line {line}: `{}` is not a number", s.trim()))?;
    if x.is_finite() { Ok(x) } else { Err(format!("line {line}: {x} is not finite")) }
}

fn string(s: &str, line: usize) -> Result<String, String> {
    let s = s.trim();
    s.strip_prefix('"')
        .and_then(|s| s.strip_suffix('"'))
        .filter(|s| !s.contains(['"', '\\']))
        .map(str::to_owned)
        .ok_or_else(|| format!("line {line}: `{s}` is not a plain \"string\""))
}

fn parse(text: &str) -> Result<File, String> {
    let (mut name, mut description, mut model) = (None, None, None);
    let mut params: Vec<(String, Value)> = Vec::new();
    let mut in_params = false;
    for (i, raw) in text.lines().enumerate() {
        let line = i + 1;
        let l = raw.trim();
        if l.is_empty() || l.starts_with('#') {
            continue;
        }
        if l == "[params]" {
            in_params = true;
            continue;
        }
        let (key, value) = l.split_once('=').ok_or_else(|| format!("line {line}: expected `key = value`"))?;
        let key = key.trim();
        if !key.chars().all(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || c == '_') || key.is_empty() {
            return Err(format!("line {line}: `{key}` is not a plain key"));
        }
        if in_params {
            if params.iter().any(|(k, _)| k == key) {
                return Err(format!("line {line}: `{key}` given twice"));
            }
            let v = value.trim();
            let parsed = match v.strip_prefix('[').and_then(|v| v.strip_suffix(']')) {
                Some(items) => Value::Array(items.split(',').map(|x| number(x, line)).collect::<Result<_, _>>()?),
                None => Value::Number(number(v, line)?),
            };
            params.push((key.to_owned(), parsed));
        } else {
            let slot = match key {
                "name" => &mut name,
                "description" => &mut description,
                "model" => &mut model,
                _ => return Err(format!("line {line}: unknown key `{key}` (name, description, model, then [params])")),
            };
            *slot = Some(string(value, line)?);
        }
    }
    let need = |v: Option<String>, k: &str| v.ok_or_else(|| format!("`{k}` is missing"));
    Ok(File {
        name: need(name, "name")?,
        description: need(description, "description")?,
        model: need(model, "model")?,
        params,
    })
}
