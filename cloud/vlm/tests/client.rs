//! The real client (ffmpeg frames, request building, ureq over HTTP, answer checking) against a
//! scripted local server: every case ends in valid semantics or a clear error, never a panic.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic, clippy::indexing_slicing)]

mod common;

use std::path::PathBuf;
use std::sync::OnceLock;
use std::time::{Duration, Instant};

use common::{Reply, Server, make_video, model_answer, temp_dir};
use v2t_model::semantics::InteractionType;
use v2t_vlm::cassette::semantics_text;
use v2t_vlm::{
    AnswerProblem, ApiKey, FrameError, Mode, RetryPolicy, StructuredOutput, Timeouts, VlmConfig, VlmError,
    abstract_video,
};

const KEY: &str = "sk-test-never-written-anywhere";

/// One short test video for the whole file: 2 s of `testsrc`, 320x240.
fn video() -> &'static PathBuf {
    // The folder lives as long as the test process (statics are not dropped): one per run.
    static VIDEO: OnceLock<PathBuf> = OnceLock::new();
    VIDEO.get_or_init(|| {
        let dir = temp_dir("client").keep();
        make_video(&dir, "clip.mp4", "testsrc=duration=2:size=320x240:rate=10")
    })
}

fn config(server: &Server) -> VlmConfig {
    let mut cfg = VlmConfig::new(&server.base_url, "vision-model-x");
    cfg.api_key = Some(ApiKey::new(KEY));
    cfg.frames.count = 3;
    cfg.retry = RetryPolicy {
        max_attempts: 3,
        initial_backoff: Duration::from_millis(10),
        max_backoff: Duration::from_millis(40),
        max_retry_after: Duration::from_millis(200),
    };
    cfg.timeouts = Timeouts { request: Duration::from_millis(1500), connect: Duration::from_millis(500) };
    cfg
}

fn cut_in() -> String {
    model_answer("semantics_cut_in.json")
}

fn run(script: Vec<Reply>) -> (Result<v2t_vlm::Abstraction, VlmError>, Vec<common::Received>) {
    run_with(script, |_| {})
}

fn run_with(
    script: Vec<Reply>,
    edit: impl FnOnce(&mut VlmConfig),
) -> (Result<v2t_vlm::Abstraction, VlmError>, Vec<common::Received>) {
    let server = Server::start(script);
    let mut cfg = config(&server);
    edit(&mut cfg);
    let result = abstract_video(video(), 4.7, &cfg, &Mode::Live);
    (result, server.received())
}

#[test]
fn a_valid_answer_gives_semantics_with_the_operators_pet_and_provenance() {
    v2t_test_support::require!(v2t_test_support::VIDEO_TOOLS);
    let (result, received) = run(vec![Reply::chat(&cut_in())]);
    let a = result.unwrap();
    assert_eq!((a.requests, a.repairs, a.schema_in_prompt), (1, 0, false));
    let s = &a.semantics;
    assert_eq!(s.interacting_bvs[0].interaction_type, InteractionType::CutIn);
    assert_eq!(s.pet_label_s, 4.7);
    assert_eq!(s.source.video, "clip.mp4");
    assert_eq!(s.source.frames_used, Some(3));
    assert_eq!(s.source.model.as_deref(), Some("test-model-2026"));
    assert_eq!(s.source.prompt_version.as_deref(), Some("semantics-v1"));
    assert!((s.source.duration_s.unwrap() - 2.0).abs() < 0.05);
    assert_eq!(a.frames.len(), 3);
    assert!(a.frames.windows(2).all(|w| w[0].timestamp_ms < w[1].timestamp_ms));

    // What the server saw.
    assert_eq!(received.len(), 1);
    let r = &received[0];
    assert_eq!((r.method.as_str(), r.path.as_str()), ("POST", "/v1/chat/completions"));
    assert_eq!(r.header("authorization"), Some(format!("Bearer {KEY}").as_str()));
    assert_eq!(r.body["model"], "vision-model-x");
    let images = r.images();
    assert_eq!(images.len(), 3);
    assert!(images.iter().all(|u| u.starts_with("data:image/jpeg;base64,/9j/")), "JPEG data URLs");
    let format = &r.body["response_format"];
    assert_eq!(format["type"], "json_schema");
    assert_eq!(format["json_schema"]["name"], "scenario_semantics");
    let schema = &format["json_schema"]["schema"];
    assert!(schema["properties"]["interacting_bvs"].is_object());
    assert!(schema["properties"].get("pet_label_s").is_none(), "the PET label is not asked from the model");
    let messages = r.body["messages"].as_array().unwrap();
    assert_eq!(messages[0]["role"], "system");
    let user = messages[1]["content"][0]["text"].as_str().unwrap();
    assert!(user.contains("3 images") && user.contains("Do not estimate the post-encroachment time"));
}

#[test]
fn a_fenced_answer_is_accepted() {
    v2t_test_support::require!(v2t_test_support::VIDEO_TOOLS);
    let fenced = format!("Step by step: a three-lane road, …\n\n```json\n{}\n```\n", cut_in());
    let (result, received) = run(vec![Reply::chat(&fenced)]);
    let a = result.unwrap();
    assert_eq!((a.requests, a.repairs), (1, 0));
    assert_eq!(a.semantics.road_topology.lanes_per_direction, 3);
    assert_eq!(received.len(), 1);
}

#[test]
fn invalid_json_is_repaired_once() {
    v2t_test_support::require!(v2t_test_support::VIDEO_TOOLS);
    let broken = cut_in().replacen("\"road_topology\": {", "\"road_topology\": {{", 1);
    let (result, received) = run(vec![Reply::chat(&broken), Reply::chat(&cut_in())]);
    let a = result.unwrap();
    assert_eq!((a.requests, a.repairs), (2, 1));
    assert!(matches!(a.repaired_problem, Some(AnswerProblem::Syntax { .. })));
    // The repair request carries the conversation, the rejected answer and the reason.
    let repair = &received[1].body["messages"];
    assert_eq!(repair.as_array().unwrap().len(), 4);
    assert_eq!(repair[2]["role"], "assistant");
    assert_eq!(repair[2]["content"], broken.as_str());
    let text = received[1].last_message_text();
    assert!(text.contains("not valid JSON"), "{text}");
    assert_eq!(received[1].images().len(), 3, "the frames stay in the conversation");
}

#[test]
fn invalid_json_twice_is_a_clear_error() {
    v2t_test_support::require!(v2t_test_support::VIDEO_TOOLS);
    let (result, received) = run(vec![Reply::chat("{\"road_topology\": "), Reply::chat("I am not sure.")]);
    let e = result.unwrap_err();
    assert!(
        matches!(
            &e,
            VlmError::InvalidAnswer { first: AnswerProblem::Syntax { .. }, second: AnswerProblem::NoJson, .. }
        ),
        "{e:?}"
    );
    assert!(e.to_string().contains("repaired answer"), "{e}");
    assert_eq!(received.len(), 2, "one repair round only");
}

#[test]
fn a_schema_violation_is_sent_back_and_fixed() {
    v2t_test_support::require!(v2t_test_support::VIDEO_TOOLS);
    // A cut-in by a vehicle that turns left: the maneuver does not fit the interaction type.
    let inconsistent = cut_in().replace("\"lane_change_left\"", "\"left_turn\"");
    let (result, received) = run(vec![Reply::chat(&inconsistent), Reply::chat(&cut_in())]);
    let a = result.unwrap();
    assert_eq!((a.requests, a.repairs), (2, 1));
    let text = received[1].last_message_text();
    assert!(text.contains("rule violation") && text.contains("interacting_bvs[0]"), "{text}");
}

#[test]
fn schema_violations_twice_are_a_clear_error() {
    v2t_test_support::require!(v2t_test_support::VIDEO_TOOLS);
    let unknown_field =
        cut_in().replace("\"maneuver\": \"straight\"", "\"maneuver\": \"straight\", \"confidence\": 0.9");
    let three_bvs = {
        let mut v: serde_json::Value = serde_json::from_str(&cut_in()).unwrap();
        let bv = v["interacting_bvs"][0].clone();
        for id in ["bv2", "bv3"] {
            let mut b = bv.clone();
            b["id"] = id.into();
            v["interacting_bvs"].as_array_mut().unwrap().push(b);
        }
        v.to_string()
    };
    let (result, received) = run(vec![Reply::chat(&unknown_field), Reply::chat(&three_bvs)]);
    let e = result.unwrap_err();
    let VlmError::InvalidAnswer {
        first: AnswerProblem::Semantics(first),
        second: AnswerProblem::Semantics(second),
        ..
    } = &e
    else {
        panic!("{e:?}")
    };
    assert!(first.contains("unknown field `confidence`"), "{first}");
    assert!(second.contains("interacting_bvs") && second.contains("1 or 2"), "{second}");
    assert_eq!(received.len(), 2);
}

#[test]
fn rate_limits_are_retried_after_the_servers_wait() {
    v2t_test_support::require!(v2t_test_support::VIDEO_TOOLS);
    let started = Instant::now();
    let (result, received) = run(vec![
        Reply::status(429, "{\"error\":\"slow down\"}").with_header("Retry-After", "0.15"),
        Reply::chat(&cut_in()),
    ]);
    let a = result.unwrap();
    assert_eq!(a.requests, 2);
    assert_eq!(received.len(), 2);
    assert!(started.elapsed() >= Duration::from_millis(150), "Retry-After honoured");
}

#[test]
fn persistent_server_errors_stop_after_the_bounded_retries() {
    v2t_test_support::require!(v2t_test_support::VIDEO_TOOLS);
    let script = vec![Reply::status(500, "{\"error\":\"boom\"}"); 5];
    let (result, received) = run(script);
    let e = result.unwrap_err();
    assert!(matches!(&e, VlmError::RetriesExhausted { attempts: 3, last } if last.contains("HTTP 500")), "{e:?}");
    std::thread::sleep(Duration::from_millis(100));
    assert_eq!(received.len(), 3, "max_attempts requests, no more");
}

#[test]
fn a_hanging_server_times_out() {
    v2t_test_support::require!(v2t_test_support::VIDEO_TOOLS);
    let hang = Duration::from_secs(3);
    let started = Instant::now();
    let (result, received) = run_with(vec![Reply::chat(&cut_in()).after(hang); 2], |cfg| {
        cfg.retry.max_attempts = 2;
        cfg.timeouts.request = Duration::from_millis(300);
    });
    let e = result.unwrap_err();
    assert!(
        matches!(&e, VlmError::RetriesExhausted { attempts: 2, last } if last.to_lowercase().contains("timeout")),
        "{e:?}"
    );
    assert!(started.elapsed() < hang, "gave up at the timeout, not when the server answered");
    assert_eq!(received.len(), 2);
}

#[test]
fn without_response_format_support_the_schema_goes_into_the_prompt() {
    v2t_test_support::require!(v2t_test_support::VIDEO_TOOLS);
    let unsupported =
        Reply::status(400, "{\"error\":{\"message\":\"Unknown parameter: 'response_format.json_schema'\"}}");
    let (result, received) = run(vec![unsupported.clone(), Reply::chat(&cut_in())]);
    let a = result.unwrap();
    assert!(a.schema_in_prompt);
    assert_eq!(a.requests, 2);
    assert!(received[1].body.get("response_format").is_none());
    let user = received[1].body["messages"][1]["content"][0]["text"].as_str().unwrap();
    assert!(user.contains("conforms to this JSON Schema") && user.contains("\"interaction_type\""), "{user}");

    // Where json_schema is required, the same answer is an error.
    let (result, received) =
        run_with(vec![unsupported], |cfg| cfg.request.structured_output = StructuredOutput::JsonSchema);
    assert!(matches!(result, Err(VlmError::ResponseFormatRejected { status: 400, .. })), "{result:?}");
    assert_eq!(received.len(), 1);
}

#[test]
fn in_prompt_mode_never_sends_response_format() {
    v2t_test_support::require!(v2t_test_support::VIDEO_TOOLS);
    let (result, received) =
        run_with(vec![Reply::chat(&cut_in())], |cfg| cfg.request.structured_output = StructuredOutput::InPrompt);
    assert!(result.unwrap().schema_in_prompt);
    assert!(received[0].body.get("response_format").is_none());
}

#[test]
fn client_errors_and_refusals_are_not_retried() {
    v2t_test_support::require!(v2t_test_support::VIDEO_TOOLS);
    let (result, received) = run(vec![Reply::status(401, "{\"error\":\"bad key\"}"); 2]);
    assert!(matches!(result, Err(VlmError::Http { status: 401, .. })), "{result:?}");
    assert_eq!(received.len(), 1);
    let refusal = serde_json::json!({"choices": [{"message": {"role": "assistant", "content": null, "refusal": "I can't help"}}]});
    let (result, _) = run(vec![Reply::status(200, &refusal.to_string())]);
    let e = result.unwrap_err();
    assert!(e.to_string().contains("refused") && e.to_string().contains("I can't help"), "{e}");
}

#[test]
fn a_bad_pet_label_or_config_fails_before_any_request() {
    v2t_test_support::require!(v2t_test_support::VIDEO_TOOLS);
    let server = Server::start(vec![Reply::chat(&cut_in())]);
    let cfg = config(&server);
    for pet in [0.0, -1.0, 31.0, f64::NAN] {
        assert!(matches!(abstract_video(video(), pet, &cfg, &Mode::Live), Err(VlmError::PetLabel(_))));
    }
    let mut no_model = cfg.clone();
    no_model.request.model = " ".into();
    assert!(matches!(abstract_video(video(), 1.0, &no_model, &Mode::Live), Err(VlmError::Config(_))));
    assert!(server.received().is_empty());
}

#[test]
fn missing_ffmpeg_names_the_debian_package() {
    v2t_test_support::require!(v2t_test_support::VIDEO_TOOLS);
    let server = Server::start(vec![]);
    let mut cfg = config(&server);
    cfg.frames.tools.ffprobe = "/nonexistent/ffprobe".into();
    let e = abstract_video(video(), 1.0, &cfg, &Mode::Live).unwrap_err();
    assert!(matches!(e, VlmError::Frames(FrameError::ToolMissing { .. })), "{e:?}");
    assert!(e.to_string().contains("Debian package `ffmpeg`"), "{e}");
}

#[test]
fn a_recorded_run_replays_offline_byte_for_byte_and_keeps_the_key_out() {
    v2t_test_support::require!(v2t_test_support::VIDEO_TOOLS);
    let dir_scratch = temp_dir("record");
    let dir = dir_scratch.path();
    let server = Server::start(vec![
        Reply::status(503, "overloaded").with_header("Retry-After", "0"),
        Reply::chat(&cut_in().replace("\"lane_change_left\"", "\"left_turn\"")),
        Reply::chat(&cut_in()),
    ]);
    let cfg = config(&server);
    let recorded = abstract_video(video(), 4.7, &cfg, &Mode::Record(dir.to_path_buf())).unwrap();
    assert_eq!((recorded.requests, recorded.repairs), (3, 1));

    // Nothing in the cassette carries the key.
    for entry in std::fs::read_dir(dir).unwrap() {
        let text = std::fs::read_to_string(entry.unwrap().path()).unwrap();
        assert!(!text.contains(KEY));
    }
    let exchange: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("exchange_01.json")).unwrap()).unwrap();
    assert_eq!(exchange["request"]["headers"]["authorization"], "Bearer <redacted>");
    assert_eq!(exchange["response"]["body_text"], "overloaded");

    // Offline: no server, no video file, no endpoint in the config.
    let offline = Mode::Replay(dir.to_path_buf());
    let replayed = abstract_video(std::path::Path::new("clip.mp4"), 4.7, &VlmConfig::default(), &offline).unwrap();
    assert!(recorded.provenance.starts_with("live exchange with vision-model-x"), "{}", recorded.provenance);
    assert!(replayed.provenance.ends_with(": recorded"), "a replay says it replays: {}", replayed.provenance);
    assert_eq!(v2t_vlm::Abstraction { provenance: recorded.provenance.clone(), ..replayed.clone() }, recorded);
    let written = std::fs::read_to_string(dir.join("semantics.json")).unwrap();
    assert_eq!(semantics_text(&replayed.semantics).unwrap(), written);

    // A replay that would send a different request fails and says where.
    let dir_scratch = temp_dir("prompt");
    let dir = dir_scratch.path();
    let prompt = dir.join("prompt.md");
    let builtin = v2t_vlm::prompt::BUILTIN_PROMPT;
    std::fs::write(&prompt, builtin.replace("traffic-scenario analyst", "traffic analyst")).unwrap();
    let changed = VlmConfig { prompt_file: Some(prompt), ..VlmConfig::default() };
    let e = abstract_video(std::path::Path::new("clip.mp4"), 4.7, &changed, &offline).unwrap_err();
    assert!(matches!(&e, VlmError::Replay(m) if m.contains("/messages/0/content")), "{e:?}");
    let e = abstract_video(std::path::Path::new("other.mp4"), 4.7, &VlmConfig::default(), &offline).unwrap_err();
    assert!(matches!(&e, VlmError::Replay(m) if m.contains("clip.mp4")), "{e:?}");
}

#[test]
fn a_recorded_timeout_replays_as_a_timeout() {
    v2t_test_support::require!(v2t_test_support::VIDEO_TOOLS);
    let dir_scratch = temp_dir("record-timeout");
    let dir = dir_scratch.path();
    let server = Server::start(vec![Reply::chat(&cut_in()).after(Duration::from_secs(2)), Reply::chat(&cut_in())]);
    let mut cfg = config(&server);
    cfg.timeouts.request = Duration::from_millis(300);
    let recorded = abstract_video(video(), 2.0, &cfg, &Mode::Record(dir.to_path_buf())).unwrap();
    assert_eq!(recorded.requests, 2);
    let first: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("exchange_01.json")).unwrap()).unwrap();
    assert_eq!(first["error"]["kind"], "timeout");

    let started = Instant::now();
    let replayed = abstract_video(video(), 2.0, &VlmConfig::default(), &Mode::Replay(dir.to_path_buf())).unwrap();
    assert_eq!(v2t_vlm::Abstraction { provenance: recorded.provenance.clone(), ..replayed }, recorded);
    assert!(started.elapsed() < Duration::from_millis(300), "a replay does not wait");
}
