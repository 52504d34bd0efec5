//! The OpenAI-compatible backend against a mock chat-completions server on 127.0.0.1: the
//! request carries the model, messages, temperature, seed and the JSON schema as structured
//! output, the key from the named environment variable; HTTP 500 is retried with backoff; a
//! 400 is not retried; a server that never answers times out with a clear error.

use reason::backend::openai::{OpenAi, OpenAiConfig};
use reason::backend::{Backend, ChatRequest, Message, Role};
use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpListener;
use std::sync::mpsc;
use std::time::Duration;

/// Serves the given (status, body) replies in order, sending each request (head and body) back.
fn serve(replies: Vec<(u16, String)>) -> (String, mpsc::Receiver<String>) {
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let url = format!("http://{}", listener.local_addr().unwrap());
    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        for (status, body) in replies {
            let (mut stream, _) = listener.accept().unwrap();
            let mut reader = BufReader::new(stream.try_clone().unwrap());
            let mut head = String::new();
            let mut len = 0;
            loop {
                let mut line = String::new();
                reader.read_line(&mut line).unwrap();
                if let Some(v) = line.to_ascii_lowercase().strip_prefix("content-length:") {
                    len = v.trim().parse().unwrap();
                }
                head.push_str(&line);
                if line == "\r\n" {
                    break;
                }
            }
            let mut buf = vec![0; len];
            reader.read_exact(&mut buf).unwrap();
            tx.send(head + &String::from_utf8(buf).unwrap()).unwrap();
            let resp = format!("HTTP/1.1 {status} X\r\nContent-Type: application/json\r\nContent-Length: {}\r\nConnection: close\r\n\r\n{body}", body.len());
            stream.write_all(resp.as_bytes()).unwrap();
        }
    });
    (url, rx)
}

fn request() -> ChatRequest {
    ChatRequest {
        messages: vec![
            Message { role: Role::System, content: "sys".into() },
            Message { role: Role::User, content: "hello".into() },
        ],
        schema: serde_json::json!({"type": "object"}),
        schema_name: "zone".into(),
        temperature: 0.3,
        seed: 42,
        max_tokens: 100,
    }
}

fn config(url: String, key_env: &str) -> OpenAiConfig {
    OpenAiConfig {
        base_url: url,
        model: "test-model".into(),
        api_key_env: Some(key_env.into()),
        timeout: Duration::from_secs(5),
        retries: 2,
        backoff: Duration::from_millis(10),
        json_schema: true,
    }
}

#[test]
fn retries_server_errors_and_sends_everything() {
    std::env::set_var("CARLA_GS_TEST_KEY_1", "sk-test");
    let ok = r#"{"choices":[{"message":{"role":"assistant","content":"{\"a\":1}"}}]}"#.to_string();
    let (url, rx) = serve(vec![(500, "{}".into()), (200, ok)]);
    let mut b = OpenAi::new(config(url, "CARLA_GS_TEST_KEY_1")).unwrap();
    assert_eq!(b.complete(&request()).unwrap(), r#"{"a":1}"#);
    let first = rx.recv().unwrap();
    let second = rx.recv().unwrap();
    assert!(first.starts_with("POST /chat/completions"), "{first}");
    assert!(second.to_ascii_lowercase().contains("authorization: bearer sk-test"));
    let body: serde_json::Value = serde_json::from_str(&second[second.find("\r\n\r\n").unwrap() + 4..]).unwrap();
    assert_eq!(body["model"], "test-model");
    assert_eq!(body["seed"], 42);
    assert_eq!(body["temperature"], 0.3);
    assert_eq!(body["messages"][1]["content"], "hello");
    assert_eq!(body["response_format"]["type"], "json_schema");
    assert_eq!(body["response_format"]["json_schema"]["name"], "zone");
}

#[test]
fn client_errors_are_not_retried() {
    std::env::set_var("CARLA_GS_TEST_KEY_2", "k");
    let (url, rx) = serve(vec![(400, r#"{"error":"bad schema"}"#.into())]);
    let mut b = OpenAi::new(config(url, "CARLA_GS_TEST_KEY_2")).unwrap();
    let err = b.complete(&request()).unwrap_err().to_string();
    assert!(err.contains("HTTP 400") && err.contains("bad schema"), "{err}");
    assert_eq!(rx.try_iter().count(), 1);
}

#[test]
fn missing_key_and_dead_server_are_clear_errors() {
    let err = OpenAi::new(config("http://127.0.0.1:9".into(), "CARLA_GS_TEST_KEY_UNSET")).err().unwrap().to_string();
    assert!(err.contains("CARLA_GS_TEST_KEY_UNSET"), "{err}");
    std::env::set_var("CARLA_GS_TEST_KEY_3", "k");
    // Nothing listens on port 9 (discard): connection refused on every attempt.
    let mut b = OpenAi::new(config("http://127.0.0.1:9".into(), "CARLA_GS_TEST_KEY_3")).unwrap();
    let err = b.complete(&request()).unwrap_err().to_string();
    assert!(err.contains("gave up after 3 attempts"), "{err}");
}
