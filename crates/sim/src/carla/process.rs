//! The bridge as a child process: started with piped stdin/stdout/stderr, spoken to in JSON lines
//! (`protocol.rs`). Every wait has a deadline: stdout is read on a thread that forwards lines over
//! a channel, so a silent or stuck bridge (or server) ends in [`CarlaError::Silent`] and the child
//! is killed, never in a hang. The last lines of the bridge's stderr go into error messages.
//! Dropping a [`Bridge`] kills and reaps the child.

use super::protocol::{Reply, Request};
use super::CarlaError;
use std::collections::VecDeque;
use std::io::{BufRead, BufReader, Write};
use std::path::PathBuf;
use std::process::{Child, ChildStdin, Command, Stdio};
use std::sync::mpsc::{self, Receiver, RecvTimeoutError};
use std::sync::{Arc, Mutex};
use std::time::Duration;

/// How many stderr lines to keep for error messages.
const STDERR_LINES: usize = 20;

/// The program to run: `python -c <embedded script> [--fake]`, or `python <script> [--fake]`.
#[derive(Clone, Debug, PartialEq)]
pub struct BridgeCommand {
    pub python: PathBuf,
    /// A bridge script file; `None` runs the copy of `tools/carla_bridge.py` built into carla-gs.
    pub script: Option<PathBuf>,
    pub fake: bool,
}

impl BridgeCommand {
    fn command(&self) -> Command {
        let mut cmd = Command::new(&self.python);
        match &self.script {
            Some(path) => cmd.arg(path),
            None => cmd.arg("-c").arg(super::BRIDGE_SCRIPT),
        };
        if self.fake {
            cmd.arg("--fake");
        }
        cmd
    }

    /// For messages: `python3 tools/carla_bridge.py --fake`.
    pub fn describe(&self) -> String {
        let script = self.script.as_ref().map_or("<built-in carla_bridge.py>".to_string(), |p| p.display().to_string());
        format!("{} {script}{}", self.python.display(), if self.fake { " --fake" } else { "" })
    }
}

pub struct Bridge {
    child: Child,
    stdin: Option<ChildStdin>,
    lines: Receiver<std::io::Result<String>>,
    stderr: Arc<Mutex<VecDeque<String>>>,
}

impl Bridge {
    pub fn spawn(cmd: &BridgeCommand) -> Result<Self, CarlaError> {
        let mut child = cmd
            .command()
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .map_err(|e| CarlaError::Start { program: cmd.describe(), message: e.to_string() })?;
        let stdout = child.stdout.take().expect("piped stdout");
        let stderr_pipe = child.stderr.take().expect("piped stderr");
        let (tx, lines) = mpsc::channel();
        std::thread::spawn(move || {
            for line in BufReader::new(stdout).lines() {
                if tx.send(line).is_err() {
                    break;
                }
            }
        });
        let stderr = Arc::new(Mutex::new(VecDeque::new()));
        let keep = Arc::clone(&stderr);
        std::thread::spawn(move || {
            for line in BufReader::new(stderr_pipe).lines().map_while(Result::ok) {
                tracing::debug!("carla bridge: {line}");
                let mut q = keep.lock().unwrap_or_else(|e| e.into_inner());
                if q.len() == STDERR_LINES {
                    q.pop_front();
                }
                q.push_back(line);
            }
        });
        Ok(Bridge { stdin: child.stdin.take(), child, lines, stderr })
    }

    fn stderr_tail(&self) -> String {
        let q = self.stderr.lock().unwrap_or_else(|e| e.into_inner());
        if q.is_empty() {
            "(nothing on stderr)".into()
        } else {
            q.iter().cloned().collect::<Vec<_>>().join("\n")
        }
    }

    /// Sends one message as one line.
    pub fn send(&mut self, req: &Request) -> Result<(), CarlaError> {
        let mut line = serde_json::to_string(req).map_err(|e| CarlaError::Protocol(format!("encoding: {e}")))?;
        line.push('\n');
        let Some(stdin) = self.stdin.as_mut() else {
            return Err(CarlaError::Protocol("the bridge's stdin is closed".into()));
        };
        if let Err(e) = stdin.write_all(line.as_bytes()).and_then(|()| stdin.flush()) {
            // The bridge died; its stderr says why.
            std::thread::sleep(Duration::from_millis(100));
            return Err(CarlaError::Exited { waiting_for: format!("writing ({e})"), stderr: self.stderr_tail() });
        }
        Ok(())
    }

    /// The next reply, within `limit`. An `error` reply becomes [`CarlaError::Bridge`].
    pub fn recv(&mut self, limit: Duration, waiting_for: &str) -> Result<Reply, CarlaError> {
        let line = match self.lines.recv_timeout(limit) {
            Ok(Ok(line)) => line,
            Ok(Err(e)) => return Err(CarlaError::Protocol(format!("reading the bridge's output: {e}"))),
            Err(RecvTimeoutError::Timeout) => {
                self.kill();
                return Err(CarlaError::Silent {
                    waiting_for: waiting_for.into(),
                    seconds: limit.as_secs_f64(),
                    stderr: self.stderr_tail(),
                });
            }
            Err(RecvTimeoutError::Disconnected) => {
                let _ = self.child.wait();
                std::thread::sleep(Duration::from_millis(50));
                return Err(CarlaError::Exited { waiting_for: waiting_for.into(), stderr: self.stderr_tail() });
            }
        };
        let reply: Reply = serde_json::from_str(&line).map_err(|e| {
            CarlaError::Protocol(format!(
                "waiting for {waiting_for}: bad line `{}`: {e}",
                line.chars().take(200).collect::<String>()
            ))
        })?;
        match reply {
            Reply::Error { kind, message } => Err(CarlaError::Bridge { kind, message }),
            r => Ok(r),
        }
    }

    fn kill(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

impl Drop for Bridge {
    fn drop(&mut self) {
        drop(self.stdin.take());
        self.kill();
    }
}
