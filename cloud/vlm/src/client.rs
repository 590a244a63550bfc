//! The conversation with the model: send the frames and the prompt, retry what can be retried,
//! fall back from `response_format` to the schema in the prompt when the server does not support
//! it, check the answer, and send it back once with its errors if it is wrong.

use serde_json::Value;
use v2t_model::semantics::{ScenarioSemantics, SourceMetadata};

use crate::answer::{AnswerProblem, ChatReply, check_answer, parse_reply};
use crate::config::{RequestSettings, RetryPolicy, StructuredOutput};
use crate::error::{VlmError, excerpt};
use crate::frames::Frame;
use crate::prompt::Prompt;
use crate::request::{CHAT_COMPLETIONS_PATH, chat_body, opening_messages, repair_messages};
use crate::transport::{HttpRequest, Transport, TransportErrorKind};

/// Characters of a body or answer kept in an error.
const EXCERPT_CHARS: usize = 400;

/// What one abstraction needs besides the transport.
#[derive(Debug, Clone, Copy)]
pub struct Conversation<'a> {
    /// The prompt.
    pub prompt: &'a Prompt,
    /// Model and request shape.
    pub settings: &'a RequestSettings,
    /// Retries.
    pub retry: &'a RetryPolicy,
    /// The frames, in time order.
    pub frames: &'a [Frame],
    /// The video's duration, s.
    pub duration_s: f64,
    /// The operator's PET label, s (already checked).
    pub pet_label_s: f64,
    /// Provenance; `model` is filled from the server's answer.
    pub source: &'a SourceMetadata,
}

/// What the conversation produced and how.
#[derive(Debug, Clone, PartialEq)]
pub struct Outcome {
    /// The checked semantics.
    pub semantics: ScenarioSemantics,
    /// HTTP requests sent (retries, the fallback and the repair included).
    pub requests: u32,
    /// Repair rounds (0 or 1).
    pub repairs: u32,
    /// Whether the schema went into the prompt instead of `response_format`.
    pub schema_in_prompt: bool,
    /// What the first answer's problem was, when a repair round was needed.
    pub repaired_problem: Option<AnswerProblem>,
}

/// Runs the conversation.
pub fn converse(transport: &mut dyn Transport, c: &Conversation<'_>) -> Result<Outcome, VlmError> {
    let mut requests = 0;
    let mut schema_in_prompt = c.settings.structured_output == StructuredOutput::InPrompt;
    let mut opening = opening_messages(c.prompt, c.frames, c.duration_s, schema_in_prompt);
    let reply = match chat(transport, c, &opening, schema_in_prompt, &mut requests) {
        Err(VlmError::ResponseFormatRejected { .. }) if c.settings.structured_output == StructuredOutput::Auto => {
            schema_in_prompt = true;
            opening = opening_messages(c.prompt, c.frames, c.duration_s, schema_in_prompt);
            chat(transport, c, &opening, schema_in_prompt, &mut requests)?
        }
        other => other?,
    };
    let source = |reply: &ChatReply| SourceMetadata { model: reply.model.clone(), ..c.source.clone() };
    let first = match check_answer(&reply.content, c.pet_label_s, &source(&reply)) {
        Ok(semantics) => {
            return Ok(Outcome { semantics, requests, repairs: 0, schema_in_prompt, repaired_problem: None });
        }
        Err(problem) => problem,
    };
    let mut messages = opening;
    messages.extend(repair_messages(c.prompt, &reply.content, &first.to_string()));
    let repaired = chat(transport, c, &messages, schema_in_prompt, &mut requests)?;
    match check_answer(&repaired.content, c.pet_label_s, &source(&repaired)) {
        Ok(semantics) => {
            Ok(Outcome { semantics, requests, repairs: 1, schema_in_prompt, repaired_problem: Some(first) })
        }
        Err(second) => {
            Err(VlmError::InvalidAnswer { first, second, answer: excerpt(&repaired.content, EXCERPT_CHARS) })
        }
    }
}

/// One chat completion, with retries. A 400 about `response_format` comes back as
/// [`VlmError::ResponseFormatRejected`] for the caller to decide.
fn chat(
    transport: &mut dyn Transport,
    c: &Conversation<'_>,
    messages: &[Value],
    schema_in_prompt: bool,
    requests: &mut u32,
) -> Result<ChatReply, VlmError> {
    let request =
        HttpRequest { path: CHAT_COMPLETIONS_PATH.into(), body: chat_body(c.settings, messages, schema_in_prompt) };
    let attempts = c.retry.max_attempts.max(1);
    let mut last = String::new();
    for attempt in 1..=attempts {
        *requests += 1;
        let retry_after = match transport.send(&request) {
            Ok(response) if (200..300).contains(&response.status) => return Ok(parse_reply(&response.body)?),
            Ok(response) if matches!(response.status, 408 | 429 | 500..=599) => {
                last = format!("HTTP {}: {}", response.status, excerpt(&response.body, EXCERPT_CHARS));
                response.retry_after
            }
            Ok(response) => {
                let body = excerpt(&response.body, EXCERPT_CHARS);
                let lower = response.body.to_ascii_lowercase();
                if response.status == 400
                    && !schema_in_prompt
                    && (lower.contains("response_format") || lower.contains("json_schema"))
                {
                    return Err(VlmError::ResponseFormatRejected { status: response.status, body });
                }
                return Err(VlmError::Http { status: response.status, body });
            }
            Err(e) if e.kind == TransportErrorKind::Replay => return Err(VlmError::Replay(e.message)),
            Err(e) if e.is_retryable() => {
                last = e.to_string();
                None
            }
            Err(e) => return Err(VlmError::Transport(e)),
        };
        if attempt < attempts {
            transport.pause(c.retry.wait_after(attempt, retry_after.as_deref()));
        }
    }
    Err(VlmError::RetriesExhausted { attempts, last })
}
