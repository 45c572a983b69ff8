//! Shared by the end-to-end tests: real processes (killed when dropped), free ports, a
//! `kestrel sim` serving its API on a free port, and a small async client of that API.
#![allow(dead_code, clippy::unwrap_used, clippy::expect_used)]

use serde_json::Value;
use std::path::Path;
use std::process::{Child, Command, Stdio};
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

/// A running `kestrel sim --no-demo --speedup 20` with its API on a free loopback port.
pub struct Kestrel {
    pub process: Process,
    pub base: String,
    pub port: u16,
    token: String,
}

impl Kestrel {
    /// Starts it with `token` (empty: none), its flight log in `dir` (one file per port), its state in
    /// `dir/state`, and `extra` arguments.
    pub async fn sim(dir: &Path, token: &str, extra: &[&str]) -> Self {
        let port = free_tcp_port();
        let mut command = Command::new(env!("CARGO_BIN_EXE_kestrel"));
        if token.is_empty() {
            command.env_remove("KESTREL_API_TOKEN");
        } else {
            command.env("KESTREL_API_TOKEN", token);
        }
        let child = command
            .args(["sim", "--no-demo", "--speedup", "20", "--listen"])
            .arg(format!("127.0.0.1:{port}"))
            .arg("--state-dir")
            .arg(dir.join("state"))
            .arg("--log")
            .arg(dir.join(format!("flight-{port}.jsonl")))
            .args(extra)
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .unwrap();
        let k = Kestrel {
            process: Process(child),
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
