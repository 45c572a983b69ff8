//! Shared by the end-to-end tests: real processes (killed when dropped), free ports, a
//! `kestrel sim` serving its API on a free port, and a small async client of that API.
#![allow(dead_code, clippy::unwrap_used, clippy::expect_used)]

use serde_json::Value;
use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::{Duration, Instant};

/// A child process, killed and reaped when dropped.
pub struct Process(pub Child);

impl Drop for Process {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

pub fn free_tcp_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

pub fn free_udp_port() -> u16 {
    std::net::UdpSocket::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port()
}

/// Polls `GET {base}/api/health` until it answers 200 (30 s at most).
pub async fn wait_healthy(base: &str) {
    let deadline = Instant::now() + Duration::from_secs(30);
    while Instant::now() < deadline {
        if let Ok(r) = reqwest::get(format!("{base}/api/health")).await {
            if r.status().is_success() {
                return;
            }
        }
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    panic!("kestrel at {base} did not come up");
}

/// Spawns `command` (a Kestrel that serves its API) with `--listen 127.0.0.1:0` added, and
/// answers the process and the port the system gave it, read from Kestrel's own `API on` line.
/// A port picked free beforehand can be taken by a parallel test before Kestrel binds it; then
/// this test would talk to the other test's Kestrel.
pub fn spawn_api(mut command: Command) -> (Process, u16) {
    let mut child = command
        .args(["--listen", "127.0.0.1:0"])
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let stdout = child.stdout.take().unwrap();
    let process = Process(child);
    let (tx, rx) = std::sync::mpsc::sync_channel(1);
    // Reads every line to the end, so Kestrel never blocks on a full pipe.
    std::thread::spawn(move || {
        for line in BufReader::new(stdout).lines().map_while(Result::ok) {
            if let Some(port) = api_port(&line) {
                let _ = tx.try_send(port);
            }
        }
    });
    let port = rx
        .recv_timeout(Duration::from_secs(30))
        .expect("kestrel did not say where its API is");
    (process, port)
}

/// The port of Kestrel's `API on http://127.0.0.1:PORT (...)` line.
pub fn api_port(line: &str) -> Option<u16> {
    let rest = line.strip_prefix("API on http://")?;
    let address = rest.split_whitespace().next()?;
    address.rsplit_once(':')?.1.parse().ok()
}

/// A running `kestrel sim --no-demo --speedup 20` with its API on a free loopback port.
pub struct Kestrel {
    pub process: Process,
    pub base: String,
    pub port: u16,
    token: String,
}

impl Kestrel {
    /// Starts it with `token` (empty: none), its flight log in `dir` (one file per process),
    /// its state in `dir/state`, and `extra` arguments.
    pub async fn sim(dir: &Path, token: &str, extra: &[&str]) -> Self {
        static STARTED: AtomicUsize = AtomicUsize::new(0);
        let n = STARTED.fetch_add(1, Ordering::Relaxed);
        let mut command = Command::new(env!("CARGO_BIN_EXE_kestrel"));
        if token.is_empty() {
            command.env_remove("KESTREL_API_TOKEN");
        } else {
            command.env("KESTREL_API_TOKEN", token);
        }
        command
            .args(["sim", "--no-demo", "--speedup", "20", "--state-dir"])
            .arg(dir.join("state"))
            .arg("--log")
            .arg(dir.join(format!("flight-{}-{n}.jsonl", std::process::id())))
            .args(extra);
        let (process, port) = spawn_api(command);
        let k = Kestrel {
            process,
            base: format!("http://127.0.0.1:{port}"),
            port,
            token: token.to_string(),
        };
        wait_healthy(&k.base).await;
        k
    }

    /// One request with the bearer token; answers (status, JSON body or null).
    pub async fn call(&self, method: &str, path: &str, body: Option<&Value>) -> (u16, Value) {
        let client = reqwest::Client::new();
        let url = format!("{}{path}", self.base);
        let mut req = match method {
            "POST" => client.post(url),
            "DELETE" => client.delete(url),
            _ => client.get(url),
        };
        if !self.token.is_empty() {
            req = req.bearer_auth(&self.token);
        }
        if let Some(b) = body {
            req = req.json(b);
        }
        let r = req.send().await.unwrap();
        let status = r.status().as_u16();
        (status, r.json().await.unwrap_or(Value::Null))
    }

    /// `GET path` with the bearer token, the response as it came (headers, raw body).
    pub async fn get_raw(&self, path: &str) -> reqwest::Response {
        let mut req = reqwest::Client::new().get(format!("{}{path}", self.base));
        if !self.token.is_empty() {
            req = req.bearer_auth(&self.token);
        }
        req.send().await.unwrap()
    }

    pub async fn get(&self, path: &str) -> (u16, Value) {
        self.call("GET", path, None).await
    }

    pub async fn post(&self, path: &str, body: &Value) -> (u16, Value) {
        self.call("POST", path, Some(body)).await
    }

    /// Polls `GET path` until `done` holds; panics after `max_s`.
    pub async fn wait_for(&self, path: &str, max_s: f64, done: impl Fn(&Value) -> bool) -> Value {
        let deadline = Instant::now() + Duration::from_secs_f64(max_s);
        loop {
            let (_, v) = self.get(path).await;
            if done(&v) {
                return v;
            }
            assert!(Instant::now() < deadline, "timed out on {path}: {v}");
            tokio::time::sleep(Duration::from_millis(100)).await;
        }
    }
}
