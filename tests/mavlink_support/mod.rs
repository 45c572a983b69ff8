//! Harness for the MAVLink end-to-end tests: the fake autopilot (`sitl/`) and the real
//! `kestrel` binary as processes on free ports, the fake's control channel, and a poller that
//! records the fake's true state.
#![allow(clippy::unwrap_used, clippy::expect_used, dead_code)]

pub mod bus;
pub mod room;
pub mod router;

use serde_json::{json, Value};
use std::io::{BufRead, BufReader, Write};
use std::net::TcpStream;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, RwLock, RwLockReadGuard, RwLockWriteGuard};
use std::time::{Duration, Instant};

/// E2E flights share two cores with everything else. A flight uses about 15 % of one core, so
/// two can fly at once (the test harness runs as many tests as there are cores); the flights
/// whose setpoint timing is measured fly alone.
static FLIGHTS: RwLock<()> = RwLock::new(());

/// For a test that measures timing: no other flight of this test binary runs meanwhile.
pub fn serial() -> RwLockWriteGuard<'static, ()> {
    FLIGHTS.write().unwrap_or_else(|e| e.into_inner())
}

/// For a test whose checks have wide time margins: it may fly beside another such test.
pub fn alongside() -> RwLockReadGuard<'static, ()> {
    FLIGHTS.read().unwrap_or_else(|e| e.into_inner())
}

pub fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn python() -> PathBuf {
    let p = repo().join("sitl/.venv/bin/python");
    assert!(
        p.exists(),
        "{} missing: run `bash sitl/setup.sh` first (the CI script does)",
        p.display()
    );
    p
}

pub use crate::support::{free_tcp_port, free_udp_port};

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Personality {
    Px4,
    Ardupilot,
}

impl Personality {
    pub fn profile(self) -> &'static str {
        match self {
            Self::Px4 => "platforms/px4.toml",
            Self::Ardupilot => "platforms/ardupilot-copter.toml",
        }
    }
}

/// The fake autopilot process.
pub struct Fake {
    child: Child,
    args: Vec<String>,
    pub control_port: u16,
    /// Kestrel's connection string for this fake.
    pub connection: String,
}

impl Fake {
    pub fn start(personality: Personality, extra: &[&str]) -> Self {
        let control_port = free_tcp_port();
        let mut args: Vec<String> = vec!["--control-port".into(), control_port.to_string()];
        let connection = match personality {
            Personality::Px4 => {
                let listen = free_udp_port();
                let remote = free_udp_port();
                args.extend(["--personality".into(), "px4".into()]);
                args.extend(["--px4-listen-base".into(), listen.to_string()]);
                args.extend(["--px4-remote-base".into(), remote.to_string()]);
                format!("udpin:127.0.0.1:{remote}")
            }
            Personality::Ardupilot => {
                let tcp = free_tcp_port();
                args.extend(["--personality".into(), "ardupilot".into()]);
                args.extend(["--ardupilot-tcp-base".into(), tcp.to_string()]);
                format!("tcpout:127.0.0.1:{tcp}")
            }
        };
        args.extend(extra.iter().map(|s| s.to_string()));
        Self {
            child: spawn_fake(&args),
            args,
            control_port,
            connection,
        }
    }

    /// `n` fake PX4 vehicles in one process (one world, one clock), each on its own UDP ports
    /// and system id `1 + i`; returns the fake and Kestrel's connection string for each.
    pub fn start_px4_fleet(n: u16, extra: &[&str]) -> (Self, Vec<String>) {
        let control_port = free_tcp_port();
        let listen = free_udp_ports(n);
        let remote = loop {
            let r = free_udp_ports(n);
            if r.abs_diff(listen) >= n {
                break r;
            }
        };
        let mut args: Vec<String> = vec!["--control-port".into(), control_port.to_string()];
        args.extend(["--personality".into(), "px4".into()]);
        args.extend(["--vehicles".into(), n.to_string()]);
        args.extend(["--px4-listen-base".into(), listen.to_string()]);
        args.extend(["--px4-remote-base".into(), remote.to_string()]);
        args.extend(extra.iter().map(|s| s.to_string()));
        let connections: Vec<String> = (0..n)
            .map(|i| format!("udpin:127.0.0.1:{}", remote + i))
            .collect();
        let fake = Self {
            child: spawn_fake(&args),
            args,
            control_port,
            connection: connections[0].clone(),
        };
        (fake, connections)
    }

    /// The true state of vehicle `index` of the process.
    pub fn state_of(&self, index: usize) -> Value {
        self.cmd(json!({"cmd": "state", "vehicle": index}))
    }

    /// Records the true state of all `n` vehicles every 50 ms (each sample an array of `n`).
    pub fn poll_fleet_states(&self, n: usize) -> Poller {
        let port = self.control_port;
        let stop = Arc::new(AtomicBool::new(false));
        let samples = Arc::new(Mutex::new(Vec::new()));
        let (s, out) = (stop.clone(), samples.clone());
        let handle = std::thread::spawn(move || {
            while !s.load(Ordering::Relaxed) {
                let states: Option<Vec<Value>> = (0..n)
                    .map(|i| try_control(port, &json!({"cmd": "state", "vehicle": i})))
                    .collect();
                if let Some(states) = states {
                    out.lock().unwrap().push(Value::Array(states));
                }
                std::thread::sleep(Duration::from_millis(50));
            }
        });
        Poller {
            stop,
            samples,
            handle: Some(handle),
        }
    }

    /// Kills the process and starts a new one on the same ports (an autopilot power cycle,
    /// or a serial cable pulled and plugged back).
    pub fn restart(&mut self, off_for: Duration) {
        let _ = self.child.kill();
        let _ = self.child.wait();
        std::thread::sleep(off_for);
        self.child = spawn_fake(&self.args);
    }

    /// One control-channel request; panics on `ok: false`.
    pub fn cmd(&self, request: Value) -> Value {
        control(self.control_port, &request)
    }

    pub fn state(&self) -> Value {
        self.cmd(json!({"cmd": "state"}))
    }

    /// The fake's state and last log entries, for failure messages.
    pub fn diagnostics(&self) -> String {
        let state = try_control(self.control_port, &json!({"cmd": "state"}));
        let log = try_control(self.control_port, &json!({"cmd": "log"}));
        let tail: Vec<String> = log
            .as_ref()
            .and_then(|l| l["entries"].as_array())
            .map(|e| {
                e.iter()
                    .rev()
                    .take(25)
                    .rev()
                    .map(|v| v.to_string())
                    .collect()
            })
            .unwrap_or_default();
        format!(
            "fake state: {}\nfake log tail:\n{}",
            state.map_or_else(|| "(no answer)".into(), |s| s.to_string()),
            tail.join("\n")
        )
    }

    /// Records the true state every 50 ms until the returned poller is stopped.
    pub fn poll_states(&self) -> Poller {
        let port = self.control_port;
        let stop = Arc::new(AtomicBool::new(false));
        let samples = Arc::new(Mutex::new(Vec::new()));
        let (s, out) = (stop.clone(), samples.clone());
        let handle = std::thread::spawn(move || {
            while !s.load(Ordering::Relaxed) {
                if let Some(v) = try_control(port, &json!({"cmd": "state"})) {
                    out.lock().unwrap().push(v);
                }
                std::thread::sleep(Duration::from_millis(50));
            }
        });
        Poller {
            stop,
            samples,
            handle: Some(handle),
        }
    }
}

/// The first of `n` consecutive UDP ports on loopback that are free now.
pub fn free_udp_ports(n: u16) -> u16 {
    for _ in 0..100 {
        let base = free_udp_port();
        if base.checked_add(n).is_none() {
            continue;
        }
        let all_free = (0..n)
            .map(|i| std::net::UdpSocket::bind(("127.0.0.1", base + i)))
            .collect::<Result<Vec<_>, _>>()
            .is_ok();
        if all_free {
            return base;
        }
    }
    panic!("no {n} consecutive free UDP ports");
}

fn spawn_fake(args: &[String]) -> Child {
    let mut child = Command::new(python())
        .arg(repo().join("sitl/fake_autopilot.py"))
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .expect("starting the fake autopilot");
    let mut ready = String::new();
    BufReader::new(child.stdout.take().unwrap())
        .read_line(&mut ready)
        .unwrap();
    assert!(
        ready.contains("\"ready\": true"),
        "fake did not start: {ready}"
    );
    child
}

impl Drop for Fake {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

fn try_control(port: u16, request: &Value) -> Option<Value> {
    let mut s = TcpStream::connect(("127.0.0.1", port)).ok()?;
    s.set_read_timeout(Some(Duration::from_secs(5))).ok()?;
    writeln!(s, "{request}").ok()?;
    let mut line = String::new();
    BufReader::new(s).read_line(&mut line).ok()?;
    serde_json::from_str(&line).ok()
}

pub fn control(port: u16, request: &Value) -> Value {
    let reply = try_control(port, request).expect("control channel");
    assert_eq!(reply["ok"], true, "{request} -> {reply}");
    reply
}

pub struct Poller {
    stop: Arc<AtomicBool>,
    samples: Arc<Mutex<Vec<Value>>>,
    handle: Option<std::thread::JoinHandle<()>>,
}

impl Poller {
    pub fn finish(mut self) -> Vec<Value> {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(h) = self.handle.take() {
            h.join().unwrap();
        }
        std::mem::take(&mut *self.samples.lock().unwrap())
    }
}

/// The `kestrel run` process, its stdout and stderr lines stamped on arrival.
/// `--listen` value for a test Kestrel: a port the system picks ([`Kestrel::api`] finds it). A
/// port picked free beforehand can be taken by a parallel test first.
pub const LISTEN_ANY: &str = "127.0.0.1:0";

pub struct Kestrel {
    child: Child,
    pub lines: Arc<Mutex<Vec<(Instant, String)>>>,
    pub log: PathBuf,
    _dir: tempfile::TempDir,
}

impl Kestrel {
    /// The process's id (to read its memory in /proc).
    pub fn pid(&self) -> u32 {
        self.child.id()
    }

    /// `kestrel run --platform P --connection C --log L <extra>`; `config` is written to a file.
    pub fn run(personality: Personality, connection: &str, config: &str, extra: &[&str]) -> Self {
        Self::run_with_platform(personality.profile(), connection, config, extra)
    }

    /// `kestrel run` with any platform file.
    pub fn run_with_platform(
        platform: &str,
        connection: &str,
        config: &str,
        extra: &[&str],
    ) -> Self {
        let mut args = vec!["--platform", platform, "--connection", connection];
        args.extend(extra);
        Self::run_config(config, &args)
    }

    /// `kestrel run --log L <extra>` where `config` (written to a file) says everything else.
    pub fn run_config(config: &str, extra: &[&str]) -> Self {
        let dir = tempfile::tempdir().unwrap();
        let config_path = dir.path().join("kestrel.toml");
        std::fs::write(&config_path, config).unwrap();
        let log = dir.path().join("flight.jsonl");
        let mut child = Command::new(env!("CARGO_BIN_EXE_kestrel"))
            .current_dir(repo())
            // KESTREL_TEST_RUST_LOG sets the children's log filter when a failure is studied.
            .env(
                "RUST_LOG",
                std::env::var("KESTREL_TEST_RUST_LOG").unwrap_or_else(|_| "warn".into()),
            )
            .env("RUST_BACKTRACE", "0")
            .arg("run")
            .args(["--config", config_path.to_str().unwrap()])
            .args(["--log", log.to_str().unwrap()])
            .args(["--state-dir", dir.path().join("state").to_str().unwrap()])
            .args(extra)
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .expect("starting kestrel");
        let lines = Arc::new(Mutex::new(Vec::new()));
        for stream in [
            Box::new(child.stdout.take().unwrap()) as Box<dyn std::io::Read + Send>,
            Box::new(child.stderr.take().unwrap()),
        ] {
            let out = lines.clone();
            std::thread::spawn(move || {
                for line in BufReader::new(stream).lines().map_while(Result::ok) {
                    out.lock().unwrap().push((Instant::now(), line));
                }
            });
        }
        Self {
            child,
            lines,
            log,
            _dir: dir,
        }
    }

    /// Waits for the exit; panics (with the output) after `timeout`.
    pub fn wait(&mut self, timeout: Duration) -> ExitStatus {
        let deadline = Instant::now() + timeout;
        loop {
            if let Some(status) = self.child.try_wait().unwrap() {
                std::thread::sleep(Duration::from_millis(100)); // let the readers drain
                return status;
            }
            if Instant::now() > deadline {
                let _ = self.child.kill();
                panic!(
                    "kestrel still running after {timeout:?}:\n{}",
                    self.output()
                );
            }
            std::thread::sleep(Duration::from_millis(100));
        }
    }

    pub fn output(&self) -> String {
        let lines = self.lines.lock().unwrap();
        lines
            .iter()
            .map(|(_, l)| l.as_str())
            .collect::<Vec<_>>()
            .join("\n")
    }

    /// When the first line containing `needle` arrived.
    pub fn line_at(&self, needle: &str) -> Option<Instant> {
        let lines = self.lines.lock().unwrap();
        lines
            .iter()
            .find(|(_, l)| l.contains(needle))
            .map(|(t, _)| *t)
    }

    /// When the first line containing `needle` arrived at or after `after`.
    pub fn line_after(&self, needle: &str, after: Instant) -> Option<Instant> {
        let lines = self.lines.lock().unwrap();
        lines
            .iter()
            .find(|(t, l)| *t >= after && l.contains(needle))
            .map(|(t, _)| *t)
    }

    /// Waits until a line contains `needle`.
    pub fn wait_line(&self, needle: &str, timeout: Duration) -> Instant {
        let deadline = Instant::now() + timeout;
        while Instant::now() < deadline {
            if let Some(t) = self.line_at(needle) {
                return t;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        panic!("no `{needle}` within {timeout:?}:\n{}", self.output());
    }

    /// The API of a Kestrel started with `--listen 127.0.0.1:0` ([`LISTEN_ANY`]): the port the
    /// system gave it, read from its `API on http://...` line (waits up to 60 s), then health.
    pub fn api(&self) -> Api {
        self.wait_line("API on http://", Duration::from_secs(60));
        let port = {
            let lines = self.lines.lock().unwrap();
            lines
                .iter()
                .find_map(|(_, l)| crate::support::api_port(l))
                .expect("the API line names a port")
        };
        Api::connect(port)
    }

    pub fn flight_log(&self) -> Vec<Value> {
        let text = std::fs::read_to_string(&self.log).unwrap_or_default();
        text.lines()
            .filter_map(|l| serde_json::from_str(l).ok())
            .collect()
    }
}

impl Drop for Kestrel {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
        // KESTREL_KEEP_LOGS=DIR keeps every flight log and the process's output there, to read
        // after a run (the temporary directory goes with the process).
        if let Some(dir) = std::env::var_os("KESTREL_KEEP_LOGS") {
            let dir = PathBuf::from(dir);
            let _ = std::fs::create_dir_all(&dir);
            let name = format!("kestrel-{}", self.child.id());
            let _ = std::fs::copy(&self.log, dir.join(format!("{name}.jsonl")));
            let _ = std::fs::write(dir.join(format!("{name}.out")), self.output());
        }
    }
}

/// The demo plan's targets in the autopilot's local ENU frame, in order, for a vehicle that
/// starts at the origin facing east (the fake's default): the takeoff point, every go_to and
/// follow_path point, and the touchdown below the last one.
/// `kestrel run` flags that fly the demo mission without the API and exit when it ends.
pub const DEMO: &[&str] = &[
    "--mission-demo",
    "--no-api",
    "--exit-when-done",
    "--max-time-s",
    "110",
];

pub fn demo_targets() -> Vec<[f64; 3]> {
    let mut targets = Vec::new();
    let mut last = [0.0, 0.0, 0.0];
    for (behavior, goal) in kestrel::scenario::demo::demo_plan(kestrel::types::Vec3::zeros(), 0.0) {
        let point = |v: &Value| {
            [
                v[0].as_f64().unwrap(),
                v[1].as_f64().unwrap(),
                v[2].as_f64().unwrap(),
            ]
        };
        let new: Vec<[f64; 3]> = match behavior.as_str() {
            "takeoff" => vec![[last[0], last[1], last[2] + goal["height"].as_f64().unwrap()]],
            "go_to" => vec![[
                goal["x"].as_f64().unwrap(),
                goal["y"].as_f64().unwrap(),
                goal["z"].as_f64().unwrap(),
            ]],
            "follow_path" => goal["path"].as_array().unwrap().iter().map(point).collect(),
            "land" => vec![[last[0], last[1], 0.0]],
            other => panic!("demo item {other} has no target here"),
        };
        if let Some(p) = new.last() {
            last = *p;
        }
        targets.extend(new);
    }
    targets
}

fn vec3(v: &Value) -> [f64; 3] {
    let a = |i: usize| v[i].as_f64().unwrap();
    [a(0), a(1), a(2)]
}

/// For each target in order, the closest the true trajectory came (metres), searching each
/// target only after the previous one was passed.
pub fn closest_approaches(samples: &[Value], targets: &[[f64; 3]]) -> Vec<f64> {
    let points: Vec<[f64; 3]> = samples
        .iter()
        .map(|s| {
            let p = vec3(&s["position_enu_m"]);
            let o = vec3(&s["local_origin_enu_m"]);
            [p[0] - o[0], p[1] - o[1], p[2] - o[2]]
        })
        .collect();
    let mut from = 0;
    targets
        .iter()
        .map(|t| {
            let dist = |p: &[f64; 3]| {
                ((p[0] - t[0]).powi(2) + (p[1] - t[1]).powi(2) + (p[2] - t[2]).powi(2)).sqrt()
            };
            let best = points
                .iter()
                .enumerate()
                .skip(from)
                .min_by(|a, b| dist(a.1).total_cmp(&dist(b.1)));
            match best {
                Some((i, p)) => {
                    from = i;
                    dist(p)
                }
                None => f64::INFINITY,
            }
        })
        .collect()
}

pub fn profile_path(p: Personality) -> &'static Path {
    Path::new(p.profile())
}

/// A blocking client of a Kestrel's HTTP API (the tests here are synchronous).
pub struct Api {
    base: String,
    rt: tokio::runtime::Runtime,
}

impl Api {
    /// Waits up to 30 s for `GET /api/health` on `port`.
    pub fn connect(port: u16) -> Self {
        let api = Api {
            base: format!("http://127.0.0.1:{port}"),
            rt: tokio::runtime::Builder::new_current_thread()
                .enable_all()
                .build()
                .unwrap(),
        };
        let deadline = Instant::now() + Duration::from_secs(30);
        while Instant::now() < deadline {
            if api.try_get("/api/health").is_some() {
                return api;
            }
            std::thread::sleep(Duration::from_millis(100));
        }
        panic!("the API on {port} never answered");
    }

    fn try_get(&self, path: &str) -> Option<Value> {
        let url = format!("{}{path}", self.base);
        self.rt.block_on(async {
            let r = reqwest::get(url).await.ok()?;
            r.status().is_success().then_some(())?;
            r.json().await.ok()
        })
    }

    pub fn get(&self, path: &str) -> Value {
        self.try_get(path)
            .unwrap_or_else(|| panic!("GET {path} failed"))
    }

    /// POSTs JSON; returns (status, body).
    pub fn post(&self, path: &str, body: &Value) -> (u16, Value) {
        let url = format!("{}{path}", self.base);
        self.rt.block_on(async {
            let r = reqwest::Client::new()
                .post(url)
                .json(body)
                .send()
                .await
                .unwrap();
            let status = r.status().as_u16();
            (status, r.json().await.unwrap_or(Value::Null))
        })
    }

    /// Uploads and starts `mission`; returns its id.
    pub fn fly(&self, mission: &Value) -> u64 {
        let (status, uploaded) = self.post("/api/missions", mission);
        assert_eq!(status, 201, "{uploaded}");
        let id = uploaded["mission_id"].as_u64().unwrap();
        let start = json!({"drone_id": "drone_0", "mission_id": id, "action": "START"});
        let (status, started) = self.post("/api/mission_update", &start);
        assert_eq!(status, 200, "{started}");
        id
    }

    /// The mission status of drone 0, once its mission has ended (waits up to `timeout`).
    pub fn wait_mission_end(&self, timeout: Duration) -> Value {
        let deadline = Instant::now() + timeout;
        while Instant::now() < deadline {
            let status = self.get("/api/status");
            let mission = &status["drones"][0]["mission"];
            if mission["state"] == 0 && mission["mission_id"].is_u64() {
                return mission.clone();
            }
            std::thread::sleep(Duration::from_millis(200));
        }
        panic!("the mission did not end within {timeout:?}");
    }
}

/// The demo flight from the origin, as mission JSON for drone 0.
pub fn demo_mission() -> Value {
    kestrel::scenario::demo::as_mission(
        "drone_0",
        kestrel::scenario::demo::demo_plan(kestrel::types::Vec3::zeros(), 0.0),
    )
}

/// One `[[vehicle]]` entry of a `kestrel run` config: id, connection, the autopilot's system id
/// and where its local frame starts in the shared frame (m, ENU).
pub fn vehicle_section(id: &str, connection: &str, system: usize, origin: [f64; 3]) -> String {
    format!(
        "\n[[vehicle]]\nid = \"{id}\"\nconnection = \"{connection}\"\ntarget_system = {system}\n\
         origin_enu_m = [{:.1}, {:.1}, {:.1}]\n",
        origin[0], origin[1], origin[2]
    )
}

/// Waits up to 40 s until `GET /api/status` lists `n` drones, each linked and ready to fly;
/// returns that status.
pub fn wait_fleet_ready(api: &Api, kestrel: &Kestrel, n: usize) -> Value {
    let deadline = Instant::now() + Duration::from_secs(40);
    loop {
        let status = api.get("/api/status");
        let ready = status["drones"].as_array().map_or(0, |d| {
            d.iter()
                .filter(|d| d["link"] == "ok" && d["ready_to_fly"] == true)
                .count()
        });
        if ready == n {
            return status;
        }
        assert!(
            Instant::now() < deadline,
            "autopilots not ready: {status}\n{}",
            kestrel.output()
        );
        std::thread::sleep(Duration::from_millis(200));
    }
}
