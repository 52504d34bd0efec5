//! The `openai` agent against a real OpenAI-compatible server: llama.cpp's own `llama-server`
//! (tools/build-llama-server.sh) serving the default GGUF (tools/setup-model.sh) on a free
//! loopback port. `carla-gs reason --agent openai` runs on the shared stationary-ego WOMD scene
//! under both protocols (exit 0 with a plan written, or 3 with none), then a tiny
//! `eval-cases --agents openai` writes `table_llm_validity.{md,csv}` whose counts add up.
//! The reply schema goes as `response_format: json_schema` (the backend's default).
//!
//! Skips with `SKIP: <reason>` when the server binary (`$CARLA_GS_LLAMA_SERVER`, else the
//! carla-gs cache), the model or the shared data is absent. The server is killed at the end, on a
//! panic too (`Server`'s `Drop`).

use std::io::{Read, Write};
use std::net::{TcpListener, TcpStream};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};
use std::time::{Duration, Instant};

fn carla_gs(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_carla-gs")).args(args).output().expect("run carla-gs")
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

fn cache_dir() -> PathBuf {
    std::env::var_os("XDG_CACHE_HOME")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(std::env::var_os("HOME").unwrap_or_default()).join(".cache"))
        .join("carla-gs")
}

fn server_binary() -> PathBuf {
    std::env::var_os("CARLA_GS_LLAMA_SERVER")
        .map(PathBuf::from)
        .unwrap_or_else(|| cache_dir().join("llama-server").join("bin").join("llama-server"))
}

/// A running llama-server, killed (and reaped) when dropped.
struct Server {
    child: Child,
    port: u16,
}

impl Drop for Server {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// `GET path` on the loopback port: the HTTP status, if the server answered.
fn http_status(port: u16, path: &str) -> Option<u16> {
    let mut stream = TcpStream::connect(("127.0.0.1", port)).ok()?;
    stream.set_read_timeout(Some(Duration::from_secs(5))).ok()?;
    write!(stream, "GET {path} HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\n\r\n").ok()?;
    let mut head = [0u8; 12];
    stream.read_exact(&mut head).ok()?;
    std::str::from_utf8(&head[9..12]).ok()?.parse().ok()
}

fn start_server(bin: &Path, model: &Path, log: &Path) -> Server {
    let port = TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port();
    let log = std::fs::File::create(log).unwrap();
    let child = Command::new(bin)
        .args(["-m", s(model), "--alias", "gemma-3-270m", "--host", "127.0.0.1", "--port", &port.to_string()])
        .args(["-c", "8192", "-np", "1", "-t", "1"])
        .stdout(log.try_clone().unwrap())
        .stderr(log)
        .stdin(Stdio::null())
        .spawn()
        .expect("start llama-server");
    let mut server = Server { child, port };
    let start = Instant::now();
    while http_status(port, "/health") != Some(200) {
        assert!(server.child.try_wait().unwrap().is_none(), "llama-server exited before /health answered");
        assert!(start.elapsed() < Duration::from_secs(120), "no /health from llama-server after 120 s");
        std::thread::sleep(Duration::from_millis(250));
    }
    server
}

/// The stationary-ego WOMD scenario ingested into `tmp`.
fn scene_dir(tmp: &Path) -> Option<PathBuf> {
    for name in ["motion_data_one_scenario.tfrecord", "womd_scenario_input.tfrecord"] {
        let input = ingest::shared::waymo_file(name)?;
        let dir = tmp.join(name);
        let out = carla_gs(&["ingest", s(&input), "--out", s(&dir)]);
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        if scene::load_scene(&dir).unwrap().name == "637f20cafde22ff8" {
            return Some(dir);
        }
    }
    panic!("the stationary-ego scenario is in neither shared file")
}

#[test]
fn reason_and_eval_cases_against_llama_server() {
    let bin = server_binary();
    if !bin.is_file() {
        eprintln!("SKIP: {} not found (tools/build-llama-server.sh builds it)", bin.display());
        return;
    }
    let model = reason::backend::default_model_path();
    if !model.is_file() {
        eprintln!("SKIP: {} not found (tools/setup-model.sh installs it)", model.display());
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let Some(dir) = scene_dir(tmp.path()) else { return };
    let log = tmp.path().join("server.log");
    let server = start_server(&bin, &model, &log);
    let url = format!("http://127.0.0.1:{}/v1", server.port);
    let openai =
        ["--openai-url", &url, "--openai-model", "gemma-3-270m", "--openai-key-env", "", "--openai-timeout-s", "300"];

    for protocol in ["ours", "paper"] {
        let plan = tmp.path().join(format!("plan_{protocol}.json"));
        // One re-prompt: Gemma 3 270M tends to repeat waypoints until the 1,500-token limit (about
        // 100 s on 2 busy cores), so each attempt is costly.
        let args = ["reason", s(&dir), "--t0", "2", "--behavior", "side_pass", "--agent", "openai", "--retries", "1"];
        let out = carla_gs(&[&args[..], &openai, &["--protocol", protocol, "--out", s(&plan)]].concat());
        let (stdout, stderr) = (String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
        eprintln!("reason --protocol {protocol}: exit {:?}\n{stdout}{stderr}", out.status.code());
        match out.status.code() {
            Some(0) => {
                let plan: scene::Plan = scene::format::read_json(&plan).unwrap();
                assert_eq!(plan.behavior, scene::Behavior::SidePass);
            }
            Some(3) => assert!(!plan.exists(), "exit 3 but a plan was written"),
            code => panic!(
                "reason --protocol {protocol} exited {code:?}:\n{stderr}\nserver log:\n{}",
                std::fs::read_to_string(&log).unwrap_or_default()
            ),
        }
    }

    let eval = tmp.path().join("eval");
    let args = ["eval-cases", s(&dir), "--agents", "openai", "--behaviors", "side_pass"];
    let small = ["--t0", "2", "--refine-rounds", "0", "--no-plots", "--protocol", "paper", "--out", s(&eval)];
    let out = carla_gs(&[&args[..], &openai, &small].concat());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "eval-cases: {stderr}");
    let md = std::fs::read_to_string(eval.join("table_llm_validity.md")).expect("table_llm_validity.md");
    eprintln!("{md}");
    let csv = std::fs::read_to_string(eval.join("table_llm_validity.csv")).unwrap();
    let rows: Vec<Vec<&str>> = csv.lines().skip(1).map(|l| l.split(',').collect()).collect();
    assert_eq!(rows.len(), 2, "{csv}");
    for r in &rows {
        let n: Vec<usize> = r[2..7].iter().map(|x| x.parse().unwrap()).collect();
        assert_eq!(r[0], "openai", "{csv}");
        assert_eq!(n[0], n[1] + n[2] + n[3] + n[4], "counts do not add up: {csv}");
    }
    // The Zone agent answered (side_pass at t0 = 2 s has a candidate, so the agent is asked).
    assert!(rows[0][2].parse::<usize>().unwrap() > 0, "no Zone agent reply counted: {csv}");
    drop(server);
}
