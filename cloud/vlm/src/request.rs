//! The chat-completions request body (OpenAI-compatible), built from the prompt, the frames and the
//! conversation so far. Pure: the same inputs give the same JSON, which is what makes replays exact.

use serde_json::{Value, json};

use crate::config::RequestSettings;
use crate::frames::Frame;
use crate::prompt::{Prompt, SCHEMA_NAME, model_schema};

/// Path of the endpoint under the base URL.
pub const CHAT_COMPLETIONS_PATH: &str = "/chat/completions";

/// The opening messages: the system prompt, and the user message with the instructions and every
/// frame (a text label with its timestamp, then the image as a `data:` URL).
pub fn opening_messages(prompt: &Prompt, frames: &[Frame], duration_s: f64, schema_in_prompt: bool) -> Vec<Value> {
    let count = frames.len();
    let mut parts = vec![json!({"type": "text", "text": prompt.user_text(count, duration_s, schema_in_prompt)})];
    for (i, frame) in frames.iter().enumerate() {
        parts.push(json!({"type": "text", "text": prompt.frame_label(i + 1, count, frame.timestamp_ms)}));
        parts.push(json!({"type": "image_url", "image_url": {"url": frame.data_url()}}));
    }
    vec![json!({"role": "system", "content": prompt.system_text()}), json!({"role": "user", "content": parts})]
}

/// The messages that send a rejected answer back with what is wrong with it.
pub fn repair_messages(prompt: &Prompt, rejected_answer: &str, errors: &str) -> [Value; 2] {
    [
        json!({"role": "assistant", "content": rejected_answer}),
        json!({"role": "user", "content": prompt.repair_text(errors)}),
    ]
}

/// The request body. With `schema_in_prompt` false it carries
/// `response_format: {type: json_schema, json_schema: {name, schema, strict}}`.
pub fn chat_body(settings: &RequestSettings, messages: &[Value], schema_in_prompt: bool) -> Value {
    let mut body = json!({"model": settings.model, "messages": messages});
    if let Some(obj) = body.as_object_mut() {
        if !schema_in_prompt {
            obj.insert(
                "response_format".into(),
                json!({
                    "type": "json_schema",
                    "json_schema": {"name": SCHEMA_NAME, "schema": model_schema(), "strict": settings.schema_strict}
                }),
            );
        }
        if let Some(t) = settings.temperature {
            obj.insert("temperature".into(), json!(t));
        }
        if let Some(n) = settings.max_tokens {
            obj.insert("max_tokens".into(), json!(n));
        }
    }
    body
}

/// The frames' JPEG data, in order, from the `image_url` parts of a request body (used to replay a
/// cassette without the video).
pub fn images_in(body: &Value) -> Vec<&str> {
    let messages = body.get("messages").and_then(Value::as_array).map(Vec::as_slice).unwrap_or_default();
    messages
        .iter()
        .filter_map(|m| m.get("content").and_then(Value::as_array))
        .flatten()
        .filter(|part| part.get("type").and_then(Value::as_str) == Some("image_url"))
        .filter_map(|part| part.pointer("/image_url/url").and_then(Value::as_str))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frames() -> Vec<Frame> {
        (0..3)
            .map(|i| Frame { timestamp_ms: 500 + 1000 * i, width: 4, height: 2, jpeg: vec![0xFF, 0xD8, i as u8] })
            .collect()
    }

    #[test]
    fn body_carries_model_frames_and_schema() {
        let prompt = Prompt::builtin().unwrap();
        let mut settings = RequestSettings::new("m1");
        settings.temperature = Some(0.0);
        let messages = opening_messages(&prompt, &frames(), 3.0, false);
        let body = chat_body(&settings, &messages, false);
        assert_eq!(body["model"], "m1");
        assert_eq!(body["temperature"], 0.0);
        assert_eq!(body["response_format"]["json_schema"]["name"], SCHEMA_NAME);
        assert_eq!(body["response_format"]["json_schema"]["strict"], false);
        let images = images_in(&body);
        assert_eq!(images.len(), 3);
        assert_eq!(images[2], frames()[2].data_url());
        assert_eq!(body["messages"][1]["content"][3]["text"], "Frame 2 of 3, t = 1.500 s:");
        let in_prompt = chat_body(&settings, &opening_messages(&prompt, &frames(), 3.0, true), true);
        assert!(in_prompt.get("response_format").is_none());
        assert!(in_prompt["messages"][1]["content"][0]["text"].as_str().unwrap().contains("\"road_topology\""));
    }
}
