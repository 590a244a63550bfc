//! Where the model is, how requests are shaped, and how hard to try.

use std::path::PathBuf;
use std::time::Duration;

use serde::{Deserialize, Serialize};

use crate::frames::FrameSettings;

/// Environment variable with the API's base URL, e.g. `https://api.openai.com/v1` or
/// `http://127.0.0.1:8000/v1` (vLLM); `/chat/completions` is appended.
pub const ENV_BASE_URL: &str = "V2T_VLM_BASE_URL";
/// Environment variable with the API key (optional: local servers often need none).
pub const ENV_API_KEY: &str = "V2T_VLM_API_KEY";
/// Environment variable with the model id.
pub const ENV_MODEL: &str = "V2T_VLM_MODEL";
/// Environment variable that overrides [`StructuredOutput`]: `auto`, `json_schema` or `in_prompt`.
pub const ENV_STRUCTURED_OUTPUT: &str = "V2T_VLM_STRUCTURED_OUTPUT";

/// Why a configuration is unusable.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ConfigError {
    /// A required environment variable is not set.
    #[error("environment variable {0} is not set (see cloud/vlm README: {ENV_BASE_URL}, {ENV_MODEL}, {ENV_API_KEY})")]
    MissingEnv(&'static str),
    /// A value is out of range or malformed.
    #[error("VLM config `{field}`: {problem}")]
    Invalid {
        /// The field.
        field: &'static str,
        /// What is wrong.
        problem: String,
    },
}

/// An API key. Its `Debug` and `Display` never show it; only the HTTP transport reads it.
#[derive(Clone, PartialEq, Eq)]
pub struct ApiKey(String);

impl ApiKey {
    /// Wraps a key.
    pub fn new(key: impl Into<String>) -> Self {
        Self(key.into())
    }

    /// The key itself, for the `Authorization` header.
    pub(crate) fn expose(&self) -> &str {
        &self.0
    }
}

impl std::fmt::Debug for ApiKey {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("ApiKey(<redacted>)")
    }
}

/// How the answer's form is requested.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum StructuredOutput {
    /// `response_format: json_schema` first; if the server answers 400 about `response_format`,
    /// the schema goes into the prompt instead.
    #[default]
    Auto,
    /// `response_format: json_schema` only.
    JsonSchema,
    /// The schema in the prompt, no `response_format`.
    InPrompt,
}

impl std::str::FromStr for StructuredOutput {
    type Err = ConfigError;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s.trim() {
            "auto" => Ok(Self::Auto),
            "json_schema" => Ok(Self::JsonSchema),
            "in_prompt" => Ok(Self::InPrompt),
            other => Err(ConfigError::Invalid {
                field: "structured_output",
                problem: format!("expected `auto`, `json_schema` or `in_prompt`, got `{other}`"),
            }),
        }
    }
}

/// Everything that shapes the request body besides the prompt and the frames. Recorded in
/// cassettes, so that a replay builds the same request.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RequestSettings {
    /// The model id sent as `model`.
    pub model: String,
    /// How the answer's form is requested.
    #[serde(default)]
    pub structured_output: StructuredOutput,
    /// `json_schema.strict`. Off by default: the semantics schema has optional fields and numeric
    /// ranges, which OpenAI's strict mode does not accept; the answer is validated here anyway.
    #[serde(default)]
    pub schema_strict: bool,
    /// `temperature`, if set (some reasoning models accept only their default).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub temperature: Option<f64>,
    /// `max_tokens`, if set.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_tokens: Option<u32>,
}

impl RequestSettings {
    /// Default settings for `model`.
    pub fn new(model: impl Into<String>) -> Self {
        Self {
            model: model.into(),
            structured_output: StructuredOutput::Auto,
            schema_strict: false,
            temperature: None,
            max_tokens: None,
        }
    }

    /// Checks the values (NaN fails).
    pub fn validate(&self) -> Result<(), ConfigError> {
        if self.model.trim().is_empty() {
            return Err(ConfigError::Invalid { field: "model", problem: format!("is empty (set {ENV_MODEL})") });
        }
        if let Some(t) = self.temperature
            && !(0.0..=2.0).contains(&t)
        {
            return Err(ConfigError::Invalid { field: "temperature", problem: format!("must lie in [0, 2], got {t}") });
        }
        if self.max_tokens == Some(0) {
            return Err(ConfigError::Invalid { field: "max_tokens", problem: "must be at least 1".into() });
        }
        Ok(())
    }
}

/// Retries on 408, 429, 5xx and transport errors: at most `max_attempts` requests per call, waiting
/// `initial_backoff · 2^k` (at most `max_backoff`) between them, or what `Retry-After` says (at most
/// `max_retry_after`).
#[derive(Debug, Clone, PartialEq)]
pub struct RetryPolicy {
    /// Requests per call, first one included, 1 to 10.
    pub max_attempts: u32,
    /// First wait.
    pub initial_backoff: Duration,
    /// Longest computed wait.
    pub max_backoff: Duration,
    /// Longest wait a `Retry-After` header may impose.
    pub max_retry_after: Duration,
}

impl Default for RetryPolicy {
    fn default() -> Self {
        Self {
            max_attempts: 4,
            initial_backoff: Duration::from_secs(1),
            max_backoff: Duration::from_secs(20),
            max_retry_after: Duration::from_secs(60),
        }
    }
}

impl RetryPolicy {
    /// The wait before attempt `failed + 1`, after `failed` failures (1-based), given the server's
    /// `Retry-After` value if any.
    pub fn wait_after(&self, failed: u32, retry_after: Option<&str>) -> Duration {
        if let Some(secs) = retry_after.and_then(|v| v.trim().parse::<f64>().ok())
            && secs.is_finite()
            && secs >= 0.0
        {
            return Duration::from_secs_f64(secs).min(self.max_retry_after);
        }
        let factor = 2u32.saturating_pow(failed.saturating_sub(1).min(20));
        self.initial_backoff.saturating_mul(factor).min(self.max_backoff)
    }
}

/// Time limits of one HTTP request.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Timeouts {
    /// Whole request, from connecting to the last byte of the answer.
    pub request: Duration,
    /// Connecting.
    pub connect: Duration,
}

impl Default for Timeouts {
    fn default() -> Self {
        Self { request: Duration::from_secs(180), connect: Duration::from_secs(10) }
    }
}

/// The whole configuration of scenario abstraction.
#[derive(Debug, Clone, PartialEq)]
pub struct VlmConfig {
    /// Base URL of the OpenAI-compatible API (`…/v1`).
    pub base_url: String,
    /// API key, if the server needs one.
    pub api_key: Option<ApiKey>,
    /// What shapes the request body.
    pub request: RequestSettings,
    /// Retries.
    pub retry: RetryPolicy,
    /// Time limits.
    pub timeouts: Timeouts,
    /// Frames.
    pub frames: FrameSettings,
    /// Prompt file; `None` = the built-in `config/vlm/prompt.md`.
    pub prompt_file: Option<PathBuf>,
}

impl VlmConfig {
    /// A configuration for `model` at `base_url`, defaults elsewhere.
    pub fn new(base_url: impl Into<String>, model: impl Into<String>) -> Self {
        Self {
            base_url: base_url.into(),
            api_key: None,
            request: RequestSettings::new(model),
            retry: RetryPolicy::default(),
            timeouts: Timeouts::default(),
            frames: FrameSettings::default(),
            prompt_file: None,
        }
    }

    /// Reads [`ENV_BASE_URL`], [`ENV_MODEL`], [`ENV_API_KEY`] and [`ENV_STRUCTURED_OUTPUT`].
    pub fn from_env() -> Result<Self, ConfigError> {
        Self::from_lookup(|name| std::env::var(name).ok())
    }

    /// As [`Self::from_env`], with the variables from `lookup`.
    pub fn from_lookup(lookup: impl Fn(&str) -> Option<String>) -> Result<Self, ConfigError> {
        let get = |name| lookup(name).filter(|v| !v.trim().is_empty());
        let base_url = get(ENV_BASE_URL).ok_or(ConfigError::MissingEnv(ENV_BASE_URL))?;
        let model = get(ENV_MODEL).ok_or(ConfigError::MissingEnv(ENV_MODEL))?;
        let mut cfg = Self::new(base_url.trim(), model.trim());
        cfg.api_key = get(ENV_API_KEY).map(|k| ApiKey::new(k.trim()));
        if let Some(mode) = get(ENV_STRUCTURED_OUTPUT) {
            cfg.request.structured_output = mode.parse()?;
        }
        cfg.validate()?;
        Ok(cfg)
    }

    /// Checks what a live request needs.
    pub fn validate(&self) -> Result<(), ConfigError> {
        let url = self.base_url.trim();
        if !(url.starts_with("http://") || url.starts_with("https://")) {
            return Err(ConfigError::Invalid {
                field: "base_url",
                problem: format!("must start with http:// or https://, got `{url}`"),
            });
        }
        self.request.validate()?;
        if !(1..=10).contains(&self.retry.max_attempts) {
            return Err(ConfigError::Invalid {
                field: "retry.max_attempts",
                problem: format!("must lie in 1..=10, got {}", self.retry.max_attempts),
            });
        }
        if self.timeouts.request.is_zero() || self.timeouts.connect.is_zero() {
            return Err(ConfigError::Invalid { field: "timeouts", problem: "must be longer than zero".into() });
        }
        Ok(())
    }
}

impl Default for VlmConfig {
    /// For replays, which take the request settings from the cassette: no endpoint, no model.
    fn default() -> Self {
        Self::new("", "")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn debug_never_shows_the_key() {
        let mut cfg = VlmConfig::new("http://127.0.0.1:1/v1", "m");
        cfg.api_key = Some(ApiKey::new("sk-very-secret"));
        let shown = format!("{cfg:?} {cfg:#?}");
        assert!(!shown.contains("sk-very-secret"), "{shown}");
        assert!(shown.contains("<redacted>"));
    }

    #[test]
    fn env_gives_endpoint_model_key_and_mode() {
        let env = |vars: &'static [(&'static str, &'static str)]| {
            move |name: &str| vars.iter().find(|(k, _)| *k == name).map(|(_, v)| (*v).to_owned())
        };
        let cfg = VlmConfig::from_lookup(env(&[
            (ENV_BASE_URL, "https://example.invalid/v1"),
            (ENV_MODEL, "gpt-x"),
            (ENV_API_KEY, "k"),
            (ENV_STRUCTURED_OUTPUT, "in_prompt"),
        ]))
        .unwrap();
        assert_eq!(cfg.request.model, "gpt-x");
        assert_eq!(cfg.api_key, Some(ApiKey::new("k")));
        assert_eq!(cfg.request.structured_output, StructuredOutput::InPrompt);
        assert_eq!(VlmConfig::from_lookup(env(&[(ENV_MODEL, "m")])), Err(ConfigError::MissingEnv(ENV_BASE_URL)));
        let bad = VlmConfig::from_lookup(env(&[(ENV_BASE_URL, "ftp://x"), (ENV_MODEL, "m")]));
        assert!(matches!(bad, Err(ConfigError::Invalid { field: "base_url", .. })));
    }

    #[test]
    fn backoff_doubles_up_to_its_cap_and_honours_retry_after() {
        let p = RetryPolicy {
            max_attempts: 5,
            initial_backoff: Duration::from_millis(100),
            max_backoff: Duration::from_millis(350),
            max_retry_after: Duration::from_secs(2),
        };
        let ms = |d: Duration| d.as_millis();
        assert_eq!([1, 2, 3, 4].map(|k| ms(p.wait_after(k, None))), [100, 200, 350, 350]);
        assert_eq!(ms(p.wait_after(1, Some("1.5"))), 1500);
        assert_eq!(ms(p.wait_after(1, Some("120"))), 2000);
        assert_eq!(ms(p.wait_after(2, Some("Wed, 21 Oct 2015 07:28:00 GMT"))), 200);
    }
}
