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

/// A mock chat-completions server answering each request with `handler(request body)`; serves
/// until the test ends. Returns the base URL and every request body received.
fn serve_with(
    handler: impl Fn(&serde_json::Value) -> (u16, String) + Send + 'static,
) -> (String, std::sync::Arc<std::sync::Mutex<Vec<serde_json::Value>>>) {
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let url = format!("http://{}", listener.local_addr().unwrap());
    let seen = std::sync::Arc::new(std::sync::Mutex::new(Vec::new()));
    let log = seen.clone();
    std::thread::spawn(move || {
        for stream in listener.incoming() {
            let Ok(mut stream) = stream else { return };
            let mut reader = BufReader::new(stream.try_clone().unwrap());
            let mut len = 0;
            loop {
                let mut line = String::new();
                if reader.read_line(&mut line).unwrap_or(0) == 0 {
                    break;
                }
                if let Some(v) = line.to_ascii_lowercase().strip_prefix("content-length:") {
                    len = v.trim().parse().unwrap();
                }
                if line == "\r\n" {
                    break;
                }
            }
            let mut buf = vec![0; len];
            reader.read_exact(&mut buf).unwrap();
            let body: serde_json::Value = serde_json::from_slice(&buf).unwrap();
            let (status, reply) = handler(&body);
            log.lock().unwrap().push(body);
            let resp = format!("HTTP/1.1 {status} X\r\nContent-Type: application/json\r\nContent-Length: {}\r\nConnection: close\r\n\r\n{reply}", reply.len());
            let _ = stream.write_all(resp.as_bytes());
        }
    });
    (url, seen)
}

fn chat_reply(content: &str) -> String {
    serde_json::json!({"choices": [{"message": {"role": "assistant", "content": content}, "finish_reason": "stop"}]})
        .to_string()
}

/// What the real API answers a reasoning model (GPT-5 class) sent `max_tokens` or a temperature
/// other than 1: HTTP 400 with an OpenAI error object naming the parameter.
fn gpt5_rejection(body: &serde_json::Value) -> Option<String> {
    if body.get("max_tokens").is_some() {
        return Some(serde_json::json!({"error": {
            "message": "Unsupported parameter: 'max_tokens' is not supported with this model. Use 'max_completion_tokens' instead.",
            "type": "invalid_request_error", "param": "max_tokens", "code": "unsupported_parameter"}}).to_string());
    }
    if body.get("temperature").is_some_and(|t| t.as_f64() != Some(1.0)) {
        return Some(serde_json::json!({"error": {
            "message": format!("Unsupported value: 'temperature' does not support {} with this model. Only the default (1) value is supported.", body["temperature"]),
            "type": "invalid_request_error", "param": "temperature", "code": "unsupported_value"}}).to_string());
    }
    None
}

/// Numbers after `label` in `text`: "label (x, y)" -> (x, y).
fn pair_after(text: &str, label: &str) -> (f64, f64) {
    let rest = &text[text.find(label).unwrap() + label.len()..];
    let inner = &rest[rest.find('(').unwrap() + 1..rest.find(')').unwrap()];
    let mut it = inner.split(',').map(|s| s.trim().parse::<f64>().unwrap());
    (it.next().unwrap(), it.next().unwrap())
}

fn number_after(text: &str, label: &str) -> f64 {
    let rest = &text[text.find(label).unwrap() + label.len()..];
    rest.split(|c: char| !(c.is_ascii_digit() || c == '.' || c == '-'))
        .find(|s| !s.is_empty())
        .unwrap()
        .parse()
        .unwrap()
}

/// The mock model: the zone reply names vehicle 1588 (side pass, left zone, 4 s); the trajectory
/// reply runs at constant speed from the vehicle to the collision target stated in the prompt.
fn mock_model(body: &serde_json::Value) -> String {
    let name = body["response_format"]["json_schema"]["name"].as_str().unwrap_or("");
    let user = body["messages"][1]["content"].as_str().unwrap();
    if name == "zone" {
        return r#"{"analysis":"1588 is behind-left","vehicle_id":"1588","zone":"left","behavior":"side_pass","ttc_s":4.0,"risk":"high","reasoning":"passes close"}"#.into();
    }
    let (x0, y0) = pair_after(user, "position");
    let (xt, yt) = pair_after(user, "Collision target (world):");
    let n = number_after(user, "write exactly") as usize;
    let t_start = number_after(user, "waypoints from t =");
    let w: Vec<String> = (0..n)
        .map(|k| {
            let s = k as f64 / (n - 1) as f64;
            format!(
                r#"{{"t":{:.3},"x":{:.4},"y":{:.4}}}"#,
                t_start + 0.1 * k as f64,
                x0 + (xt - x0) * s,
                y0 + (yt - y0) * s
            )
        })
        .collect();
    format!(r#"{{"waypoints":[{}]}}"#, w.join(","))
}

#[test]
fn gpt5_style_rejections_are_dropped_and_the_case_succeeds() {
    let Some(scene) =
        ingest::shared::womd_scenes().map(|v| v.into_iter().find(|s| s.name == "637f20cafde22ff8").unwrap())
    else {
        return;
    };
    std::env::set_var("CARLA_GS_TEST_KEY_4", "k");
    let (url, seen) = serve_with(|body| match gpt5_rejection(body) {
        Some(err) => (400, err),
        None => (200, chat_reply(&mock_model(body))),
    });
    let mut b = OpenAi::new(config(url, "CARLA_GS_TEST_KEY_4")).unwrap();
    let o = reason::ReasonOptions {
        t0: scene.frames[0].timestamp_s + 2.0,
        behavior: Some(scene::Behavior::SidePass),
        seed: 5,
        ..Default::default()
    };
    let out = reason::reason(&scene, &o, reason::Agent::Llm(&mut b)).unwrap();
    let reason::Outcome::Plan { plan, stats } = out else { panic!("expected a plan") };
    plan.validate().unwrap();
    let stats = stats.unwrap();
    assert_eq!(stats.zone, reason::Validity::RawValid);
    assert_eq!(stats.trajectory, reason::Validity::RawValid, "the model's own waypoints are used");
    assert_eq!(plan.adversary_track, "1588");
    assert_eq!(b.dropped_params(), vec!["temperature"]);
    let seen = seen.lock().unwrap();
    // Zone: rejected for temperature once, then accepted; trajectory: accepted first time.
    assert_eq!(seen.len(), 3, "{seen:?}");
    assert!(seen.iter().all(|r| r.get("max_tokens").is_none() && r["max_completion_tokens"].as_u64().is_some()));
    assert!(seen[0].get("temperature").is_some() && seen[1].get("temperature").is_none());
    assert!(seen[2].get("temperature").is_none(), "a dropped parameter stays dropped");
}

#[test]
fn older_servers_get_max_tokens_when_they_reject_max_completion_tokens() {
    std::env::set_var("CARLA_GS_TEST_KEY_5", "k");
    let (url, seen) = serve_with(|body| {
        if body.get("max_completion_tokens").is_some() {
            (400, r#"{"error":{"message":"Unrecognized request argument supplied: 'max_completion_tokens' is not supported","type":"invalid_request_error","param":null}}"#.into())
        } else {
            (200, chat_reply("{}"))
        }
    });
    let mut b = OpenAi::new(config(url, "CARLA_GS_TEST_KEY_5")).unwrap();
    assert_eq!(b.complete(&request()).unwrap(), "{}");
    let seen = seen.lock().unwrap();
    assert_eq!(seen[1]["max_tokens"], 100);
    // A 400 about anything else is an error, not a retry.
    drop(seen);
    let (url, seen) =
        serve_with(|_| (400, r#"{"error":{"message":"Invalid schema","param":"response_format.schema"}}"#.into()));
    let mut b = OpenAi::new(config(url, "CARLA_GS_TEST_KEY_5")).unwrap();
    let err = b.complete(&request()).unwrap_err().to_string();
    assert!(err.contains("HTTP 400") && err.contains("Invalid schema"), "{err}");
    assert_eq!(seen.lock().unwrap().len(), 1);
}

#[test]
fn null_content_is_asked_again_with_a_larger_budget() {
    std::env::set_var("CARLA_GS_TEST_KEY_6", "k");
    let calls = std::sync::atomic::AtomicUsize::new(0);
    let (url, seen) = serve_with(move |_| {
        if calls.fetch_add(1, std::sync::atomic::Ordering::SeqCst) == 0 {
            (200, r#"{"choices":[{"message":{"role":"assistant","content":null},"finish_reason":"length"}]}"#.into())
        } else {
            (200, chat_reply("{\"ok\":true}"))
        }
    });
    let mut b = OpenAi::new(config(url, "CARLA_GS_TEST_KEY_6")).unwrap();
    assert_eq!(b.complete(&request()).unwrap(), "{\"ok\":true}");
    let seen = seen.lock().unwrap();
    assert_eq!(seen.len(), 2);
    assert_eq!(seen[0]["max_completion_tokens"], 100);
    assert_eq!(seen[1]["max_completion_tokens"], 200, "a `length` finish doubles the budget");
    // Always null: a clear error after the retries.
    let (url, _) = serve_with(|_| {
        (200, r#"{"choices":[{"message":{"content":null,"refusal":"no"},"finish_reason":"stop"}]}"#.into())
    });
    let mut b = OpenAi::new(config(url, "CARLA_GS_TEST_KEY_6")).unwrap();
    let err = b.complete(&request()).unwrap_err().to_string();
    assert!(err.contains("no content in the reply after 3 tries") && err.contains("refusal `no`"), "{err}");
}

/// A writer collecting every log line (tracing output) of the test.
#[derive(Clone, Default)]
struct LogBuffer(std::sync::Arc<std::sync::Mutex<Vec<u8>>>);

impl Write for LogBuffer {
    fn write(&mut self, b: &[u8]) -> std::io::Result<usize> {
        self.0.lock().unwrap().extend_from_slice(b);
        Ok(b.len())
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

#[test]
fn the_api_key_never_reaches_logs_or_errors() {
    const SECRET: &str = "sk-proj-NEVER-LOG-THIS-0123456789";
    std::env::set_var("CARLA_GS_TEST_KEY_7", SECRET);
    let logs = LogBuffer::default();
    let sink = logs.clone();
    let subscriber = tracing_subscriber::fmt()
        .with_max_level(tracing::Level::TRACE)
        .with_writer(move || sink.clone())
        .with_ansi(false)
        .finish();
    let mut errors = Vec::new();
    tracing::subscriber::with_default(subscriber, || {
        // Every failure path: 5xx then give up, a 400, a rejected parameter, null content, no server.
        let replies: Vec<(u16, String)> = vec![
            (500, "{}".into()),
            (500, "{}".into()),
            (500, "{}".into()),
            (400, r#"{"error":{"message":"Unsupported value: 'temperature'","param":"temperature"}}"#.into()),
            (400, r#"{"error":{"message":"Incorrect API key provided","code":"invalid_api_key"}}"#.into()),
            (200, r#"{"choices":[{"message":{"content":null},"finish_reason":"length"}]}"#.into()),
        ];
        let replies = std::sync::Mutex::new(replies.into_iter());
        let (url, seen) = serve_with(move |_| replies.lock().unwrap().next().unwrap_or((401, "{}".into())));
        let mut b = OpenAi::new(config(url, "CARLA_GS_TEST_KEY_7")).unwrap();
        errors.push(b.complete(&request()).unwrap_err().to_string());
        errors.push(b.complete(&request()).unwrap_err().to_string());
        errors.push(b.complete(&request()).unwrap_err().to_string());
        let mut dead = OpenAi::new(config("http://127.0.0.1:9".into(), "CARLA_GS_TEST_KEY_7")).unwrap();
        errors.push(dead.complete(&request()).unwrap_err().to_string());
        // The key did go to the server, in the header only.
        assert!(seen.lock().unwrap().iter().all(|body| !body.to_string().contains(SECRET)));
    });
    let logs = String::from_utf8(logs.0.lock().unwrap().clone()).unwrap();
    assert!(logs.contains("attempt 1 failed"), "the failure paths were logged: {logs}");
    for e in &errors {
        assert!(!e.contains(SECRET), "the key leaked into an error: {e}");
    }
    assert!(!logs.contains(SECRET), "the key leaked into the logs");
}

#[test]
fn llama_cpp_python_rejection_of_json_schema_drops_response_format() {
    std::env::set_var("CARLA_GS_TEST_KEY_8", "k");
    // What llama-cpp-python 0.3.36's server answered (HTTP 500, pydantic validation error).
    let err = r#"{"error":{"message":"1 validation error:\n  {'type': 'literal_error', 'loc': ('body', 'response_format', 'type'), 'msg': \"Input should be 'text' or 'json_object'\", 'input': 'json_schema'}","type":"internal_server_error","param":null,"code":null}}"#;
    let (url, seen) = serve_with(move |body| {
        if body.get("response_format").is_some() {
            (500, err.to_string())
        } else {
            (200, chat_reply("{}"))
        }
    });
    let mut b = OpenAi::new(config(url, "CARLA_GS_TEST_KEY_8")).unwrap();
    assert_eq!(b.complete(&request()).unwrap(), "{}");
    assert_eq!(b.dropped_params(), vec!["response_format"]);
    assert_eq!(seen.lock().unwrap().len(), 2, "no backoff retries of the 500");
}
