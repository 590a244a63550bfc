//! The scenario prompt: the versioned file `config/vlm/prompt.md`, its parts, and how they are
//! filled. The schema the model fills is the committed semantics schema without the fields the
//! pipeline supplies (`pet_label_s`, `source`).

use std::path::Path;

use serde_json::Value;

/// The built-in prompt, `config/vlm/prompt.md`.
pub const BUILTIN_PROMPT: &str = include_str!("../../../config/vlm/prompt.md");
/// Name of the schema in `response_format.json_schema.name`.
pub const SCHEMA_NAME: &str = "scenario_semantics";
/// Fields of the semantics that the model is not asked for: the operator's PET label and the
/// provenance, both added by the pipeline.
pub const FIELDS_NOT_ASKED: [&str; 2] = ["pet_label_s", "source"];

/// Why a prompt file is unusable.
#[derive(Debug, thiserror::Error)]
pub enum PromptError {
    /// It could not be read.
    #[error("prompt file {path}: {source}")]
    Read {
        /// The file.
        path: std::path::PathBuf,
        /// What the file system said.
        source: std::io::Error,
    },
    /// Its structure is wrong.
    #[error("prompt: {0}")]
    Malformed(String),
}

/// A parsed prompt.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Prompt {
    version: String,
    system: String,
    user: String,
    frame: String,
    output_json_schema: String,
    output_in_prompt: String,
    repair: String,
}

/// Parts of the file, their heading and the placeholders each may use.
const PARTS: [(&str, &[&str]); 6] = [
    ("System", &[]),
    ("User", &["frame_count", "duration_s", "output_format"]),
    ("Frame", &["frame_index", "frame_count", "timestamp_s"]),
    ("Output json_schema", &["schema_name"]),
    ("Output in_prompt", &["schema"]),
    ("Repair", &["errors"]),
];

impl Prompt {
    /// The built-in prompt.
    pub fn builtin() -> Result<Self, PromptError> {
        Self::parse(BUILTIN_PROMPT)
    }

    /// Reads and parses a prompt file.
    pub fn load(path: &Path) -> Result<Self, PromptError> {
        let text = v2t_files::bounds::read_text_within(path, v2t_files::bounds::VLM_FILE)
            .map_err(|source| PromptError::Read { path: path.into(), source })?;
        Self::parse(&text)
    }

    /// Parses a prompt: a `<!-- prompt-version: … -->` line, then the parts, each under a `# Name`
    /// heading.
    pub fn parse(text: &str) -> Result<Self, PromptError> {
        let malformed = |m: String| PromptError::Malformed(m);
        let version = text
            .lines()
            .find_map(|l| l.trim().strip_prefix("<!-- prompt-version:").and_then(|r| r.strip_suffix("-->")))
            .map(|v| v.trim().to_owned())
            .filter(|v| !v.is_empty())
            .ok_or_else(|| malformed("no `<!-- prompt-version: … -->` line".into()))?;
        let mut parts: Vec<(String, String)> = Vec::new();
        let mut in_comment = false;
        for line in text.lines() {
            if parts.is_empty() {
                // Before the first part: only the version and comments.
                if line.contains("<!--") && !line.contains("-->") {
                    in_comment = true;
                }
                if in_comment {
                    in_comment = !line.contains("-->");
                    continue;
                }
            }
            if let Some(name) = line.strip_prefix("# ") {
                parts.push((name.trim().to_owned(), String::new()));
            } else if let Some((_, body)) = parts.last_mut() {
                body.push_str(line);
                body.push('\n');
            }
        }
        let mut take = |name: &str, allowed: &[&str]| -> Result<String, PromptError> {
            let i =
                parts.iter().position(|(n, _)| n == name).ok_or_else(|| malformed(format!("no `# {name}` part")))?;
            let (_, body) = parts.remove(i);
            let body = body.trim().to_owned();
            for used in placeholders(&body) {
                if !allowed.contains(&used) {
                    return Err(malformed(format!("part `{name}` uses unknown placeholder {{{{{used}}}}}")));
                }
            }
            Ok(body)
        };
        let mut bodies = Vec::with_capacity(PARTS.len());
        for (name, allowed) in PARTS {
            bodies.push(take(name, allowed)?);
        }
        if let Some((extra, _)) = parts.first() {
            return Err(malformed(format!("unknown part `# {extra}`")));
        }
        let [system, user, frame, output_json_schema, output_in_prompt, repair]: [String; 6] =
            bodies.try_into().map_err(|_| malformed("wrong number of parts".into()))?;
        Ok(Self { version, system, user, frame, output_json_schema, output_in_prompt, repair })
    }

    /// The version recorded in requests and semantics.
    pub fn version(&self) -> &str {
        &self.version
    }

    /// The system message.
    pub fn system_text(&self) -> String {
        self.system.clone()
    }

    /// The user message's text. `schema_in_prompt`: whether the schema goes into the text (no
    /// `response_format`).
    pub fn user_text(&self, frame_count: usize, duration_s: f64, schema_in_prompt: bool) -> String {
        let output = if schema_in_prompt {
            let schema = serde_json::to_string_pretty(&model_schema()).unwrap_or_default();
            fill(&self.output_in_prompt, &[("schema", &schema)])
        } else {
            fill(&self.output_json_schema, &[("schema_name", SCHEMA_NAME)])
        };
        let count = frame_count.to_string();
        let duration = format!("{duration_s:.2}");
        fill(&self.user, &[("frame_count", &count), ("duration_s", &duration), ("output_format", &output)])
    }

    /// The label before frame `index` (1-based).
    pub fn frame_label(&self, index: usize, count: usize, timestamp_ms: u64) -> String {
        let t = format!("{}.{:03}", timestamp_ms / 1000, timestamp_ms % 1000);
        fill(
            &self.frame,
            &[("frame_index", &index.to_string()), ("frame_count", &count.to_string()), ("timestamp_s", &t)],
        )
    }

    /// The repair message that sends `errors` back.
    pub fn repair_text(&self, errors: &str) -> String {
        fill(&self.repair, &[("errors", errors)])
    }
}

/// The `{{name}}` placeholders in `text`.
fn placeholders(text: &str) -> Vec<&str> {
    let mut found = Vec::new();
    let mut rest = text;
    while let Some(start) = rest.find("{{") {
        let after = rest.get(start + 2..).unwrap_or("");
        let Some(end) = after.find("}}") else { break };
        found.push(after.get(..end).unwrap_or(""));
        rest = after.get(end + 2..).unwrap_or("");
    }
    found
}

/// Replaces each `{{name}}` once, left to right; inserted values are not scanned again.
fn fill(template: &str, values: &[(&str, &str)]) -> String {
    let mut out = String::with_capacity(template.len());
    let mut rest = template;
    while let Some(start) = rest.find("{{") {
        out.push_str(rest.get(..start).unwrap_or(""));
        let after = rest.get(start + 2..).unwrap_or("");
        let Some(end) = after.find("}}") else {
            out.push_str(rest.get(start..).unwrap_or(""));
            return out;
        };
        let name = after.get(..end).unwrap_or("");
        match values.iter().find(|(n, _)| *n == name) {
            Some((_, value)) => out.push_str(value),
            None => {
                out.push_str("{{");
                out.push_str(name);
                out.push_str("}}");
            }
        }
        rest = after.get(end + 2..).unwrap_or("");
    }
    out.push_str(rest);
    out
}

/// The schema the model fills: [`v2t_model::semantics::scenario_semantics_schema`] without
/// [`FIELDS_NOT_ASKED`] (and without their definitions).
pub fn model_schema() -> Value {
    let mut schema = v2t_model::semantics::scenario_semantics_schema();
    if let Some(props) = schema.get_mut("properties").and_then(Value::as_object_mut) {
        for field in FIELDS_NOT_ASKED {
            props.remove(field);
        }
    }
    if let Some(required) = schema.get_mut("required").and_then(Value::as_array_mut) {
        required.retain(|f| f.as_str().is_none_or(|f| !FIELDS_NOT_ASKED.contains(&f)));
    }
    if let Some(defs) = schema.get_mut("$defs").and_then(Value::as_object_mut) {
        defs.remove("SourceMetadata");
    }
    schema
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn builtin_prompt_parses_and_follows_the_chain_of_thought() {
        let p = Prompt::builtin().unwrap();
        assert_eq!(p.version(), "semantics-v1");
        let user = p.user_text(16, 10.0, false);
        let order =
            ["Road topology", "Ego vehicle", "Interacting background vehicles", "type and style", "Event description"];
        let at: Vec<usize> = order.iter().map(|s| user.find(s).unwrap_or_else(|| panic!("no {s}"))).collect();
        assert!(at.windows(2).all(|w| w[0] < w[1]), "{at:?}");
        assert!(user.contains("16 images") && user.contains("10.00 s") && user.contains(SCHEMA_NAME));
        assert!(!user.contains("{{"));
        let with_schema = p.user_text(4, 2.5, true);
        assert!(with_schema.contains("\"interacting_bvs\"") && !with_schema.contains("\"pet_label_s\""));
        assert_eq!(p.frame_label(3, 16, 1875), "Frame 3 of 16, t = 1.875 s:");
        assert!(p.repair_text("field `x`: bad").contains("field `x`: bad"));
    }

    #[test]
    fn model_schema_leaves_out_pet_and_source_only() {
        let full = v2t_model::semantics::scenario_semantics_schema();
        let asked = model_schema();
        let keys = |s: &Value| s["properties"].as_object().unwrap().keys().cloned().collect::<Vec<_>>();
        let mut expected = keys(&full);
        expected.retain(|k| !FIELDS_NOT_ASKED.contains(&k.as_str()));
        assert_eq!(keys(&asked), expected);
        assert!(!asked.to_string().contains("pet_label_s") && !asked.to_string().contains("SourceMetadata"));
        assert_eq!(asked["$defs"]["InteractingBv"], full["$defs"]["InteractingBv"]);
    }

    #[test]
    fn malformed_prompts_are_rejected_with_the_reason() {
        let no_version = BUILTIN_PROMPT.replace("prompt-version:", "version:");
        assert!(Prompt::parse(&no_version).unwrap_err().to_string().contains("prompt-version"));
        let unknown = BUILTIN_PROMPT.replace("{{errors}}", "{{errrors}}");
        assert!(Prompt::parse(&unknown).unwrap_err().to_string().contains("errrors"));
        let missing = BUILTIN_PROMPT.replace("# Repair", "# Repairs");
        assert!(Prompt::parse(&missing).unwrap_err().to_string().contains("Repair"));
    }

    #[test]
    fn fill_does_not_rescan_values() {
        assert_eq!(fill("a {{x}} b {{y}}", &[("x", "{{y}}"), ("y", "2")]), "a {{y}} b 2");
        assert_eq!(placeholders("{{a}} {{b}} {{c"), vec!["a", "b"]);
    }
}
