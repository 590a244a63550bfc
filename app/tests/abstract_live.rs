//! `video2track abstract` live, against a scripted OpenAI-compatible server on 127.0.0.1, on a video
//! `video2track render` made of a simulated left turn: frames from the video, the request with its
//! images and key, the report, `--record`, and a replay of that recording that writes the same
//! semantics byte for byte with the key in none of its files.

#![allow(clippy::panic, clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)] // test code

use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpListener;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::sync::mpsc;

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn video2track(args: &[&str], env: &[(&str, &str)]) -> Output {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_video2track"));
    for (name, _) in std::env::vars_os() {
        if name.to_string_lossy().starts_with("V2T_VLM_") {
            cmd.env_remove(name);
        }
    }
    cmd.envs(env.iter().copied()).args(args).current_dir(repo()).output().unwrap()
}

fn text(o: &Output) -> (String, String) {
    (String::from_utf8_lossy(&o.stdout).into_owned(), String::from_utf8_lossy(&o.stderr).into_owned())
}

/// Answers one chat-completions request with `content`; sends the request's headers and body.
fn serve_once(content: String) -> (String, mpsc::Receiver<(String, serde_json::Value)>) {
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let base_url = format!("http://{}/v1", listener.local_addr().unwrap());
    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        let (stream, _) = listener.accept().unwrap();
        let mut reader = BufReader::new(stream.try_clone().unwrap());
        let mut head = String::new();
        loop {
            let mut line = String::new();
            reader.read_line(&mut line).unwrap();
            if line == "\r\n" || line.is_empty() {
                break;
            }
            head.push_str(&line);
        }
        let length: usize = head
            .lines()
            .find_map(|l| l.to_ascii_lowercase().strip_prefix("content-length:").map(|v| v.trim().parse().unwrap()))
            .unwrap();
        let mut body = vec![0; length];
        reader.read_exact(&mut body).unwrap();
        tx.send((head, serde_json::from_slice(&body).unwrap())).unwrap();
        let answer = serde_json::json!({
            "id": "chatcmpl-test",
            "object": "chat.completion",
            "choices": [{"index": 0, "message": {"role": "assistant", "content": content}, "finish_reason": "stop"}]
        })
        .to_string();
        let mut out = stream;
        write!(
            out,
            "HTTP/1.1 200 OK\r\nContent-Type: application/json\r\nContent-Length: {}\r\nConnection: close\r\n\r\n{answer}",
            answer.len()
        )
        .unwrap();
    });
    (base_url, rx)
}

#[test]
fn a_rendered_run_is_abstracted_live_recorded_and_replayed() {
    v2t_test_support::require!(v2t_test_support::VIDEO_TOOLS);
    let scratch = tempfile::Builder::new().prefix("v2t-cli-abstract-live-").tempdir().unwrap();
    let dir = scratch.path();
    let run = dir.join("left_turn.json");
    let video = dir.join("left_turn.mp4");
    let o = video2track(&["sim", "config/scenarios/left_turn_basic.toml", "--json", run.to_str().unwrap()], &[]);
    assert!(o.status.success(), "{}", text(&o).1);
    let o = video2track(&["render", run.to_str().unwrap(), "-o", video.to_str().unwrap(), "--width", "640"], &[]);
    assert!(o.status.success(), "{}", text(&o).1);

    // The model's answer: the one of the hand-written left-turn cassette.
    let exchange: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(repo().join("config/vlm/cassettes/left_turn/exchange_01.json")).unwrap(),
    )
    .unwrap();
    let content = exchange["response"]["body_json"]["choices"][0]["message"]["content"].as_str().unwrap().to_owned();
    let (base_url, requests) = serve_once(content);

    let cassette = dir.join("cassette");
    let live = dir.join("live.json");
    let env =
        [("V2T_VLM_BASE_URL", base_url.as_str()), ("V2T_VLM_MODEL", "test-vlm"), ("V2T_VLM_API_KEY", "sk-test-secret")];
    let o = video2track(
        &[
            "abstract",
            video.to_str().unwrap(),
            "--pet-label",
            "2.9",
            "--frames",
            "6",
            "--sampling",
            "motion",
            "--record",
            cassette.to_str().unwrap(),
            "--out",
            live.to_str().unwrap(),
        ],
        &env,
    );
    let (out, err) = text(&o);
    assert!(o.status.success(), "{err}\n{out}");
    assert!(out.contains("video left_turn.mp4") && out.contains("640x360, 10 fps"), "{out}");
    assert!(out.contains("frames 6, 640x360 at ") && out.contains("model test-vlm"), "{out}");
    assert!(out.contains("1 request(s), 0 repair(s)") && out.contains("bv1: unprotected_left_turn"), "{out}");

    let (head, body) = requests.recv().unwrap();
    assert!(head.starts_with("POST /v1/chat/completions"), "{head}");
    assert!(head.to_ascii_lowercase().contains("authorization: bearer sk-test-secret"), "{head}");
    assert_eq!(body["model"], "test-vlm");
    let images: usize = body["messages"]
        .as_array()
        .unwrap()
        .iter()
        .filter_map(|m| m["content"].as_array())
        .flatten()
        .filter(|p| p["type"] == "image_url")
        .count();
    assert_eq!(images, 6);

    let semantics: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&live).unwrap()).unwrap();
    assert_eq!(semantics["pet_label_s"], 2.9);
    assert_eq!(semantics["source"]["video"], "left_turn.mp4");
    assert_eq!(semantics["source"]["frames_used"], 6);

    // The recording holds no key, and replays offline to the same document.
    for entry in std::fs::read_dir(&cassette).unwrap() {
        let text = std::fs::read_to_string(entry.unwrap().path()).unwrap();
        assert!(!text.contains("sk-test-secret"));
    }
    let replayed = dir.join("replayed.json");
    let o = video2track(
        &[
            "abstract",
            "left_turn.mp4",
            "--pet-label",
            "2.9",
            "--replay",
            cassette.to_str().unwrap(),
            "--out",
            replayed.to_str().unwrap(),
        ],
        &[],
    );
    assert!(o.status.success(), "{}", text(&o).1);
    assert_eq!(std::fs::read(&replayed).unwrap(), std::fs::read(&live).unwrap());
}
