//! Reading the server's answer: the chat-completion envelope, the JSON inside the message (bare or
//! in a ```json fence), and its check against the semantics rules once the pipeline's fields (the
//! operator's PET label, the provenance) are in.
//!
//! The check is [`v2t_model::semantics::parse_semantics_json`]: serde with `deny_unknown_fields`
//! gives the schema's shape (required fields, types, enum names, no unknown fields), and
//! `validate()` its ranges and lengths plus what a JSON Schema cannot say (BV count 1–2, unique
//! ids, interaction type consistent with the maneuvers and the road, finite numbers). The committed
//! JSON Schema is generated from the same types and drift-checked against them in `v2t-model`, so
//! this is at least as strict as a JSON Schema validator, without one in the dependency tree.

use serde_json::Value;
use v2t_model::semantics::{ScenarioSemantics, SemanticsError, SourceMetadata, parse_semantics_json};

/// The assistant message of a chat completion.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ChatReply {
    /// The message text.
    pub content: String,
    /// The model that answered, as the server names it.
    pub model: Option<String>,
    /// Why generation stopped (`stop`, `length`, …).
    pub finish_reason: Option<String>,
}

/// Why a 2xx response carries no usable message.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum ReplyError {
    /// Not a chat completion.
    #[error("not a chat completion: {0}")]
    Malformed(String),
    /// The model declined.
    #[error("the model refused: {0}")]
    Refused(String),
    /// The answer was cut off at the token limit.
    #[error("the answer was cut off at the token limit (finish_reason `length`); raise max_tokens")]
    Truncated,
}

/// Reads a chat-completion response body.
pub fn parse_reply(body: &str) -> Result<ChatReply, ReplyError> {
    let value: Value = serde_json::from_str(body).map_err(|e| ReplyError::Malformed(format!("{e}")))?;
    let choice = value
        .get("choices")
        .and_then(Value::as_array)
        .and_then(|c| c.first())
        .ok_or_else(|| ReplyError::Malformed("no `choices[0]`".into()))?;
    let message = choice.get("message").ok_or_else(|| ReplyError::Malformed("no `choices[0].message`".into()))?;
    if let Some(refusal) = message.get("refusal").and_then(Value::as_str).filter(|r| !r.trim().is_empty()) {
        return Err(ReplyError::Refused(refusal.to_owned()));
    }
    let finish_reason = choice.get("finish_reason").and_then(Value::as_str).map(str::to_owned);
    if finish_reason.as_deref() == Some("length") {
        return Err(ReplyError::Truncated);
    }
    let content = message
        .get("content")
        .and_then(Value::as_str)
        .ok_or_else(|| ReplyError::Malformed("no text in `choices[0].message.content`".into()))?
        .to_owned();
    let model = value.get("model").and_then(Value::as_str).map(str::to_owned);
    Ok(ChatReply { content, model, finish_reason })
}

/// What is wrong with an answer, in words the model is shown in the repair round.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum AnswerProblem {
    /// No JSON object in the text.
    #[error("the answer contains no JSON object")]
    NoJson,
    /// JSON syntax error.
    #[error("the answer is not valid JSON: {message} (line {line}, column {column} of the JSON)")]
    Syntax {
        /// 1-based line within the JSON text.
        line: usize,
        /// 1-based column.
        column: usize,
        /// serde_json's message.
        message: String,
    },
    /// JSON, but not an object.
    #[error("the answer must be one JSON object, got {0}")]
    NotAnObject(&'static str),
    /// An object that breaks the schema or the semantics rules.
    #[error("{0}")]
    Semantics(String),
}

/// The JSON text in an answer: the whole text if it is JSON, else the last ```json (or plain ```)
/// fence, else the span from the first `{` to the last `}` (or to the end).
pub fn extract_json(content: &str) -> Option<&str> {
    let trimmed = content.trim();
    if serde_json::from_str::<Value>(trimmed).is_ok() {
        return Some(trimmed);
    }
    if let Some(fenced) = last_fence(trimmed) {
        return Some(fenced);
    }
    // An object cut short still goes to the parser, whose error says where it ends.
    let start = trimmed.find('{')?;
    let end = trimmed.rfind('}').filter(|&e| e > start).map_or(trimmed.len(), |e| e + 1);
    trimmed.get(start..end)
}

/// The body of the last fenced block whose info string is empty or `json`.
fn last_fence(text: &str) -> Option<&str> {
    let mut found = None;
    let mut rest = text;
    let mut offset = 0;
    while let Some(open) = rest.find("```") {
        let after_ticks = rest.get(open + 3..)?;
        let line_end = after_ticks.find('\n')?;
        let info = after_ticks.get(..line_end)?.trim();
        let body_start = open + 3 + line_end + 1;
        let body_and_rest = rest.get(body_start..)?;
        let Some(close) = body_and_rest.find("```") else { break };
        if info.is_empty() || info.eq_ignore_ascii_case("json") {
            found = text.get(offset + body_start..offset + body_start + close).map(str::trim);
        }
        let consumed = body_start + close + 3;
        offset += consumed;
        rest = rest.get(consumed..)?;
    }
    found.filter(|f| !f.is_empty())
}

/// Checks an answer: extracts the JSON object, inserts the operator's PET label and the provenance
/// (overwriting whatever the model put there), and parses it into checked semantics.
pub fn check_answer(
    content: &str,
    pet_label_s: f64,
    source: &SourceMetadata,
) -> Result<ScenarioSemantics, AnswerProblem> {
    let text = extract_json(content).ok_or(AnswerProblem::NoJson)?;
    let mut value: Value = serde_json::from_str(text).map_err(|e| AnswerProblem::Syntax {
        line: e.line(),
        column: e.column(),
        message: strip_position(&e),
    })?;
    let object = value.as_object_mut().ok_or(AnswerProblem::NotAnObject(kind_of(text)))?;
    let pet = serde_json::Number::from_f64(pet_label_s)
        .ok_or_else(|| AnswerProblem::Semantics(format!("PET label {pet_label_s} is not a finite number")))?;
    object.insert("pet_label_s".into(), Value::Number(pet));
    let source = serde_json::to_value(source).map_err(|e| AnswerProblem::Semantics(e.to_string()))?;
    object.insert("source".into(), source);
    let full = serde_json::to_string(&value).map_err(|e| AnswerProblem::Semantics(e.to_string()))?;
    parse_semantics_json(&full).map_err(|e| match e {
        // Positions refer to the re-serialized object, not to the model's text: leave them out.
        SemanticsError::Json { message, .. } => AnswerProblem::Semantics(format!("schema violation: {message}")),
        SemanticsError::Invalid(v) => AnswerProblem::Semantics(format!("rule violation: {v}")),
    })
}

fn strip_position(e: &serde_json::Error) -> String {
    let text = e.to_string();
    let suffix = format!(" at line {} column {}", e.line(), e.column());
    text.strip_suffix(&suffix).unwrap_or(&text).to_owned()
}

fn kind_of(text: &str) -> &'static str {
    match text.trim_start().chars().next() {
        Some('[') => "an array",
        Some('"') => "a string",
        Some('t' | 'f') => "a boolean",
        Some('n') => "null",
        _ => "a number",
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const ANSWER: &str = include_str!("../../../config/examples/semantics_cut_in.json");

    fn source() -> SourceMetadata {
        SourceMetadata {
            video: "v.mp4".into(),
            dataset: None,
            duration_s: Some(4.0),
            frames_used: Some(3),
            model: None,
            prompt_version: Some("semantics-v1".into()),
        }
    }

    #[test]
    fn json_is_found_bare_fenced_or_embedded() {
        assert_eq!(extract_json(" {\"a\": 1} "), Some("{\"a\": 1}"));
        assert_eq!(extract_json("Here:\n```json\n{\"a\": 1}\n```\n"), Some("{\"a\": 1}"));
        assert_eq!(extract_json("```\n{\"a\": 0}\n```\nthen\n```JSON\n{\"a\": 2}\n```"), Some("{\"a\": 2}"));
        assert_eq!(extract_json("```python\nx = 1\n```\nresult {\"a\": 3} done"), Some("{\"a\": 3}"));
        assert_eq!(extract_json("no json here"), None);
        assert_eq!(extract_json("so: {\"a\": "), Some("{\"a\":"));
    }

    #[test]
    fn pet_and_source_come_from_the_pipeline() {
        let s = check_answer(ANSWER, 1.25, &source()).unwrap();
        assert_eq!(s.pet_label_s, 1.25);
        assert_eq!(s.source, source());
    }

    #[test]
    fn problems_say_what_is_wrong() {
        let cut = ANSWER.get(..ANSWER.len() / 2).unwrap();
        assert!(matches!(check_answer(cut, 1.0, &source()), Err(AnswerProblem::Syntax { .. })));
        assert_eq!(check_answer("[1, 2]", 1.0, &source()), Err(AnswerProblem::NotAnObject("an array")));
        assert_eq!(check_answer("I cannot tell.", 1.0, &source()), Err(AnswerProblem::NoJson));
        let renamed = ANSWER.replace("\"road_type\"", "\"road_kind\"");
        let e = check_answer(&renamed, 1.0, &source()).unwrap_err().to_string();
        assert!(e.contains("schema violation") && e.contains("road_kind"), "{e}");
        let inconsistent = ANSWER.replace("\"lane_change_left\"", "\"left_turn\"");
        let e = check_answer(&inconsistent, 1.0, &source()).unwrap_err().to_string();
        assert!(e.contains("rule violation") && e.contains("interacting_bvs[0]"), "{e}");
    }

    #[test]
    fn replies_are_read_from_the_envelope() {
        let ok =
            r#"{"model":"m-2024","choices":[{"message":{"role":"assistant","content":"{}"},"finish_reason":"stop"}]}"#;
        assert_eq!(parse_reply(ok).unwrap().model.as_deref(), Some("m-2024"));
        let refused = r#"{"choices":[{"message":{"content":null,"refusal":"no"}}]}"#;
        assert_eq!(parse_reply(refused), Err(ReplyError::Refused("no".into())));
        let cut = r#"{"choices":[{"message":{"content":"{"},"finish_reason":"length"}]}"#;
        assert_eq!(parse_reply(cut), Err(ReplyError::Truncated));
        assert!(matches!(parse_reply("{}"), Err(ReplyError::Malformed(_))));
        assert!(matches!(parse_reply("<html>"), Err(ReplyError::Malformed(_))));
    }
}
