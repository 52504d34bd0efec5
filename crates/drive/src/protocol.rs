//! The policy protocol (`carla-gs-drive/1`): any stack can drive an episode as a subprocess
//! speaking JSON lines over stdin/stdout (stderr is its own, kept for error messages). One
//! message a line, UTF-8, at most [`MAX_LINE`] bytes:
//!
//! 1. carla-gs sends `{"type": "hello", ...EpisodeInfo}`; the policy answers
//!    `{"type": "ready", "name": "...", "ground_truth": false}` (`ground_truth: true` asks for
//!    the ground-truth objects each tick; they come flagged `"ground_truth": true`).
//! 2. Each tick carla-gs sends `{"type": "tick", ...Observation}` (images are PNG files whose
//!    absolute paths the message gives; they stay in the episode's `frames/`), and the policy
//!    answers `{"control": {"steer": s, "throttle": t, "brake": b}}` or
//!    `{"trajectory": [{"t": .., "x": .., "y": ..}, ...]}` (scene clock, world frame).
//! 3. At the end carla-gs sends `{"type": "end", "reason": "..."}` and closes stdin.
//!
//! Every answer must come within the time-out (per tick; the first, `ready`, gets
//! [`START_TIMEOUT_FACTOR`] times as long for the interpreter to start). A policy that exits, stops
//! answering, or answers anything but one of the two shapes (unknown fields included) ends the
//! episode with an error naming the tick and the line; its values are then checked
//! (`action::validate`). The child is killed when the episode ends, however it ends.

use crate::action::{Action, ControlMsg, Waypoint};
use crate::error::{DriveError, PolicyError};
use crate::policy::{EpisodeInfo, Observation, Policy, Ready};
use serde::{Deserialize, Serialize};
use std::collections::VecDeque;
use std::io::{BufRead, BufReader, Read, Write};
use std::process::{Child, ChildStdin, Command, Stdio};
use std::sync::mpsc::{channel, Receiver, RecvTimeoutError};
use std::sync::{Arc, Mutex};
use std::time::Duration;

pub const PROTOCOL: &str = "carla-gs-drive/1";
/// The longest line either side may send (bytes).
pub const MAX_LINE: usize = 1 << 20;
/// The `ready` answer may take this many time-outs (the interpreter starts).
pub const START_TIMEOUT_FACTOR: f64 = 5.0;
/// How much of the policy's stderr an error quotes (bytes).
const STDERR_TAIL: usize = 2000;

/// The policy's answer to a tick, as it must be written.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct Reply {
    #[serde(default)]
    control: Option<ControlMsg>,
    #[serde(default)]
    trajectory: Option<Vec<Waypoint>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ReadyMsg {
    #[serde(rename = "type")]
    kind: String,
    #[serde(default)]
    name: Option<String>,
    #[serde(default)]
    ground_truth: bool,
}

#[derive(Serialize)]
struct Tagged<'a, T: Serialize> {
    #[serde(rename = "type")]
    kind: &'a str,
    #[serde(flatten)]
    body: &'a T,
}

/// A policy in a child process.
pub struct Subprocess {
    command: String,
    child: Child,
    stdin: Option<ChildStdin>,
    lines: Receiver<Result<String, String>>,
    stderr: Arc<Mutex<VecDeque<u8>>>,
    timeout: Duration,
    name: String,
}

impl Subprocess {
    /// Starts `program args...` with a per-tick time-out of `timeout_s` seconds.
    pub fn spawn(program: &str, args: &[String], timeout_s: f64) -> Result<Self, DriveError> {
        let command = std::iter::once(program.to_string()).chain(args.iter().cloned()).collect::<Vec<_>>().join(" ");
        if !(timeout_s.is_finite() && timeout_s > 0.0 && timeout_s <= 3600.0) {
            return Err(DriveError::settings("--policy-timeout", format!("must be from 0 to 3600 s, got {timeout_s}")));
        }
        let mut child = Command::new(program)
            .args(args)
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .map_err(|e| PolicyError::Spawn { command: command.clone(), detail: e.to_string() })?;
        let stdout = child.stdout.take().expect("piped stdout");
        let stderr_pipe = child.stderr.take().expect("piped stderr");
        let (tx, lines) = channel();
        std::thread::spawn(move || {
            let mut r = BufReader::new(stdout);
            loop {
                let mut buf = Vec::new();
                match r.by_ref().take(MAX_LINE as u64 + 1).read_until(b'\n', &mut buf) {
                    Ok(0) => break,
                    Ok(_) if buf.len() > MAX_LINE => {
                        let _ = tx.send(Err(format!("a line longer than {MAX_LINE} bytes")));
                        break;
                    }
                    Ok(_) => {
                        let line = String::from_utf8_lossy(&buf).trim_end().to_string();
                        if tx.send(Ok(line)).is_err() {
                            break;
                        }
                    }
                    Err(e) => {
                        let _ = tx.send(Err(e.to_string()));
                        break;
                    }
                }
            }
        });
        let stderr = Arc::new(Mutex::new(VecDeque::new()));
        let keep = stderr.clone();
        std::thread::spawn(move || {
            let mut r = stderr_pipe;
            let mut buf = [0u8; 4096];
            while let Ok(n) = r.read(&mut buf) {
                if n == 0 {
                    break;
                }
                let mut q = keep.lock().unwrap_or_else(|p| p.into_inner());
                q.extend(&buf[..n]);
                while q.len() > STDERR_TAIL {
                    q.pop_front();
                }
            }
        });
        let stdin = child.stdin.take();
        Ok(Subprocess {
            command,
            child,
            stdin,
            lines,
            stderr,
            timeout: Duration::from_secs_f64(timeout_s),
            name: String::new(),
        })
    }

    fn stderr_tail(&self) -> String {
        let q = self.stderr.lock().unwrap_or_else(|p| p.into_inner());
        let text = String::from_utf8_lossy(&q.iter().copied().collect::<Vec<_>>()).trim().to_string();
        if text.is_empty() {
            String::new()
        } else {
            format!("; its stderr ended with:\n{text}")
        }
    }

    fn send<T: Serialize>(&mut self, tick: &str, kind: &str, body: &T) -> Result<(), PolicyError> {
        let mut line = serde_json::to_string(&Tagged { kind, body })
            .map_err(|e| PolicyError::Pipe { tick: tick.into(), detail: e.to_string() })?;
        line.push('\n');
        let Some(stdin) = self.stdin.as_mut() else {
            return Err(PolicyError::Pipe { tick: tick.into(), detail: "stdin already closed".into() });
        };
        if let Err(e) = stdin.write_all(line.as_bytes()).and_then(|_| stdin.flush()) {
            // A closed pipe means the policy is gone: say how it ended if it has.
            std::thread::sleep(Duration::from_millis(50));
            if let Ok(Some(status)) = self.child.try_wait() {
                return Err(PolicyError::Died {
                    tick: tick.into(),
                    status: status.to_string(),
                    stderr: self.stderr_tail(),
                });
            }
            return Err(PolicyError::Pipe { tick: tick.into(), detail: e.to_string() });
        }
        Ok(())
    }

    fn receive(&mut self, tick: &str, timeout: Duration) -> Result<String, PolicyError> {
        match self.lines.recv_timeout(timeout) {
            Ok(Ok(line)) => Ok(line),
            Ok(Err(detail)) => Err(PolicyError::Garbage { tick: tick.into(), detail, line: "(not read)".into() }),
            Err(RecvTimeoutError::Timeout) => {
                let _ = self.child.kill();
                let _ = self.child.wait();
                Err(PolicyError::TimedOut {
                    tick: tick.into(),
                    timeout_s: timeout.as_secs_f64(),
                    stderr: self.stderr_tail(),
                })
            }
            Err(RecvTimeoutError::Disconnected) => {
                let status = self.child.wait().map_or_else(|e| e.to_string(), |s| s.to_string());
                // Give the stderr reader a moment to drain what the policy said on its way out.
                std::thread::sleep(Duration::from_millis(50));
                Err(PolicyError::Died { tick: tick.into(), status, stderr: self.stderr_tail() })
            }
        }
    }
}

/// At most this many characters of a policy's line in an error.
fn excerpt(line: &str) -> String {
    let mut s: String = line.chars().take(200).collect();
    if s.len() < line.len() {
        s.push('…');
    }
    s
}

impl Policy for Subprocess {
    fn name(&self) -> String {
        if self.name.is_empty() {
            self.command.clone()
        } else {
            self.name.clone()
        }
    }

    fn needs_images(&self) -> bool {
        true
    }

    fn start(&mut self, info: &EpisodeInfo) -> Result<Ready, DriveError> {
        let tick = "the hello";
        self.send(tick, "hello", info)?;
        let line = self.receive(tick, self.timeout.mul_f64(START_TIMEOUT_FACTOR))?;
        let garbage = |detail: String| PolicyError::Garbage { tick: tick.into(), detail, line: excerpt(&line) };
        let msg: ReadyMsg =
            serde_json::from_str(&line).map_err(|e| garbage(format!("expected {{\"type\": \"ready\", ...}}: {e}")))?;
        if msg.kind != "ready" {
            return Err(garbage(format!("expected type \"ready\", got \"{}\"", msg.kind)).into());
        }
        self.name = msg.name.filter(|n| !n.trim().is_empty()).map_or_else(|| self.command.clone(), |n| excerpt(&n));
        Ok(Ready { name: self.name.clone(), ground_truth: msg.ground_truth })
    }

    fn act(&mut self, obs: &Observation) -> Result<Action, DriveError> {
        let tick = format!("tick {}", obs.tick);
        self.send(&tick, "tick", obs)?;
        let line = self.receive(&tick, self.timeout)?;
        let garbage = |detail: String| PolicyError::Garbage { tick: tick.clone(), detail, line: excerpt(&line) };
        let reply: Reply = serde_json::from_str(&line)
            .map_err(|e| garbage(format!("expected {{\"control\": {{...}}}} or {{\"trajectory\": [...]}}: {e}")))?;
        match (reply.control, reply.trajectory) {
            (Some(c), None) => Ok(Action::Control(c)),
            (None, Some(t)) => Ok(Action::Trajectory(t)),
            _ => Err(garbage("expected exactly one of `control` and `trajectory`".into()).into()),
        }
    }

    fn finish(&mut self, reason: &str) {
        #[derive(Serialize)]
        struct End<'a> {
            reason: &'a str,
        }
        let _ = self.send("end", "end", &End { reason });
        self.stdin = None;
        // A second to leave on its own, then it is stopped.
        for _ in 0..20 {
            if let Ok(Some(_)) = self.child.try_wait() {
                return;
            }
            std::thread::sleep(Duration::from_millis(50));
        }
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

impl Drop for Subprocess {
    fn drop(&mut self) {
        if let Ok(None) = self.child.try_wait() {
            let _ = self.child.kill();
            let _ = self.child.wait();
        }
    }
}
