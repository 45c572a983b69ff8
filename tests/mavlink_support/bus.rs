//! `kestrel run` processes on one fleet bus (tests/fleet_bus_e2e.rs, benches/fleet_bus.rs):
//! the arenas (worlds of three bays), each node's config, TCP proxies in front of the bus ports
//! that a test can cut like a Wi-Fi drop, and waiting for the fleet to join and to finish an
//! exploration.

use super::{free_tcp_port, Api, Fake, Kestrel, LISTEN_ANY};
use serde_json::{json, Value};
use std::io::{Read, Write};
use std::net::{Shutdown, TcpListener, TcpStream};
use std::path::Path;
use std::process::Command;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// A world three vehicles explore, one per bay, and what every node's config needs of it.
#[derive(Debug, Clone, Copy)]
pub struct Arena {
    pub world: &'static str,
    /// Where the fake starts each vehicle: the world's `starts_xy_yaw` for three.
    pub starts_enu_m: [[f64; 3]; 3],
    /// The map grid every node shares (m, centred on the origin).
    pub map_size_m: [f64; 2],
    /// Longest one exploration may take, take-off to the last disarm (wall clock).
    pub exploration_timeout: Duration,
}

/// Three 6 x 6 m bays (tests/fleet_bus_e2e.rs).
pub const BAYS: Arena = Arena {
    world: "sitl/worlds/bays18_fleet.json",
    starts_enu_m: [[-6.0, -1.0, 0.0], [0.0, 1.0, 0.0], [6.0, -1.0, 0.0]],
    map_size_m: [20.0, 8.0],
    exploration_timeout: Duration::from_secs(240),
};

/// Three 10 x 10 m bays with three poles each (benches/fleet_bus.rs: an exploration long enough
/// that the climb, the first sweep and the landing are not most of it).
pub const BAYS30: Arena = Arena {
    world: "sitl/worlds/bays30_fleet.json",
    starts_enu_m: [[-10.0, -2.0, 0.0], [0.0, 2.0, 0.0], [10.0, -2.0, 0.0]],
    map_size_m: [32.0, 12.0],
    exploration_timeout: Duration::from_secs(900),
};
/// The explorer's arguments, as tests/run_fleet.rs.
pub const ARGS: &str = r#"{"height": 2.0, "spin_rate": 0.4, "safety_distance": 0.5}"#;

/// A TCP proxy in front of one Kestrel's bus port, which the test can cut.
pub struct BusProxy {
    port: u16,
    cut: Arc<AtomicBool>,
    open: Arc<Mutex<Vec<TcpStream>>>,
}

impl BusProxy {
    pub fn start(target: u16) -> Self {
        let listener = TcpListener::bind("127.0.0.1:0").unwrap();
        let port = listener.local_addr().unwrap().port();
        let cut = Arc::new(AtomicBool::new(false));
        let open = Arc::new(Mutex::new(Vec::new()));
        let (c, o) = (cut.clone(), open.clone());
        std::thread::spawn(move || {
            for inbound in listener.incoming() {
                let Ok(inbound) = inbound else { continue };
                if c.load(Ordering::SeqCst) {
                    drop(inbound);
                    continue;
                }
                let Ok(outbound) = TcpStream::connect(("127.0.0.1", target)) else {
                    continue;
                };
                let mut list = o.lock().unwrap();
                list.push(inbound.try_clone().unwrap());
                list.push(outbound.try_clone().unwrap());
                drop(list);
                pipe(inbound.try_clone().unwrap(), outbound.try_clone().unwrap());
                pipe(outbound, inbound);
            }
        });
        BusProxy { port, cut, open }
    }

    /// Closes every connection and refuses new ones until [`Self::restore`].
    pub fn cut(&self) {
        self.cut.store(true, Ordering::SeqCst);
        for s in self.open.lock().unwrap().drain(..) {
            let _ = s.shutdown(Shutdown::Both);
        }
    }

    pub fn restore(&self) {
        self.cut.store(false, Ordering::SeqCst);
    }

    pub fn endpoint(&self) -> String {
        format!("tcp/127.0.0.1:{}", self.port)
    }
}

fn pipe(mut from: TcpStream, mut to: TcpStream) {
    std::thread::spawn(move || {
        let mut buf = [0u8; 16 * 1024];
        while let Ok(n) = from.read(&mut buf) {
            if n == 0 || to.write_all(&buf[..n]).is_err() {
                break;
            }
        }
        let _ = to.shutdown(Shutdown::Both);
    });
}

/// The config every Kestrel of the arena shares (the map grid must be the same on every node),
/// with its own vehicle and, when on a fleet, its bus section.
pub fn config(arena: &Arena, id: usize, connection: &str, fleet: Option<&str>) -> String {
    let o = arena.starts_enu_m[id];
    let [w, h] = arena.map_size_m;
    let mut text = format!(
        "[map]\nsize_m = [{w:.1}, {h:.1}]\n\n\
         [mavlink]\nplatform = \"platforms/px4.toml\"\n\n\
         [[vehicle]]\nid = \"drone_{id}\"\nconnection = \"{connection}\"\n\
         target_system = {}\norigin_enu_m = [{:.1}, {:.1}, {:.1}]\n",
        // The fake numbers its vehicles from 1 in the order they were started.
        if fleet.is_some() { id + 1 } else { 1 },
        o[0],
        o[1],
        o[2]
    );
    if let Some(f) = fleet {
        text.push_str(f);
    }
    text
}

/// The fleet's identities: one key per node (`node_{i}`, flying `drone_{i}`) and the roster
/// every node's config lists.
pub struct Identities {
    dir: tempfile::TempDir,
    roster: String,
}

impl Identities {
    pub fn new(nodes: usize) -> Self {
        let dir = tempfile::tempdir().unwrap();
        let mut roster = String::new();
        for i in 0..nodes {
            let key = kestrel::fleet_bus::identity::Signer::generate(
                &dir.path().join(format!("node_{i}.key")),
            )
            .unwrap()
            .public()
            .to_base64();
            roster.push_str(&format!(
                "\n[fleet.roster.node_{i}]\nkeys = [\"{key}\"]\ndrones = [\"drone_{i}\"]\n"
            ));
        }
        Identities { dir, roster }
    }

    /// Node `id`'s key (what a member gone rogue, or its stolen key file, signs with).
    pub fn signer(&self, id: usize) -> kestrel::fleet_bus::identity::Signer {
        kestrel::fleet_bus::identity::Signer::read(&self.dir.path().join(format!("node_{id}.key")))
            .unwrap()
    }

    /// Node `id`'s key file and the roster: the end of its `[fleet]` section.
    pub fn section_end(&self, id: usize) -> String {
        let key = self.dir.path().join(format!("node_{id}.key"));
        format!("key_file = \"{}\"\n{}", key.to_str().unwrap(), self.roster)
    }
}

/// A credentials file the nodes of a fleet share (first line: this node's).
pub fn credentials(dir: &std::path::Path, name: &str, line: &str) -> String {
    let path = dir.join(name);
    std::fs::write(&path, format!("{line}\n")).unwrap();
    path.to_str().unwrap().to_string()
}

/// Kestrels on one bus, one per connection, each listening on its own port and reaching the
/// earlier ones through proxies: node 1 connects to node 0, node 2 to nodes 0 and 1.
pub struct Fleet {
    pub arena: Arena,
    pub nodes: Vec<Option<Kestrel>>,
    pub apis: Vec<Api>,
    pub proxies: Vec<BusProxy>,
    _creds: tempfile::TempDir,
    _ids: Option<Identities>,
}

/// `n` fake ArduPilot vehicles in one process, each on its own TCP port (the fake's base + 10
/// per vehicle) and system id `1 + i`; returns the fake and Kestrel's connection for each.
pub fn start_ardupilot_fleet(n: u16, extra: &[&str]) -> (Fake, Vec<String>) {
    let control_port = free_tcp_port();
    let base = loop {
        let b = free_tcp_port();
        let free = (0..n).all(|i| TcpListener::bind(("127.0.0.1", b + 10 * i)).is_ok());
        if free {
            break b;
        }
    };
    let mut args: Vec<String> = vec!["--control-port".into(), control_port.to_string()];
    args.extend(["--personality".into(), "ardupilot".into()]);
    args.extend(["--vehicles".into(), n.to_string()]);
    args.extend(["--ardupilot-tcp-base".into(), base.to_string()]);
    args.extend(extra.iter().map(|s| s.to_string()));
    let connections: Vec<String> = (0..n)
        .map(|i| format!("tcpout:127.0.0.1:{}", base + 10 * i))
        .collect();
    let fake = Fake {
        child: super::spawn_fake(&args),
        args,
        control_port,
        connection: connections[0].clone(),
    };
    (fake, connections)
}

impl Fleet {
    pub fn start(arena: &Arena, connections: &[String]) -> Self {
        Self::start_on(arena, connections, "platforms/px4.toml")
    }

    /// As [`Self::start`], every vehicle flown with the profile `platform`.
    pub fn start_on(arena: &Arena, connections: &[String], platform: &str) -> Self {
        let creds = tempfile::tempdir().unwrap();
        let file = credentials(creds.path(), "fleet-credentials", "bays:s3cret-shared");
        let name = format!("bays-{}", std::process::id());
        let n = connections.len();
        let ids = Identities::new(n);
        let bus_ports: Vec<u16> = (0..n).map(|_| free_tcp_port()).collect();
        let proxies: Vec<BusProxy> = bus_ports[..n - 1]
            .iter()
            .map(|&p| BusProxy::start(p))
            .collect();
        let mut nodes = Vec::new();
        let mut apis = Vec::new();
        for id in 0..n {
            let connect: Vec<String> = proxies[..id].iter().map(|p| p.endpoint()).collect();
            let fleet = format!(
                "\n[fleet]\nenabled = true\nname = \"{name}\"\nnode = \"node_{id}\"\n\
                 listen = [\"tcp/127.0.0.1:{}\"]\nconnect = {}\ncredentials_file = \"{file}\"\n{}",
                bus_ports[id],
                serde_json::to_string(&connect).unwrap(),
                ids.section_end(id)
            );
            let text = config(arena, id, &connections[id], Some(&fleet))
                .replace("platforms/px4.toml", platform);
            nodes.push(Some(Kestrel::run_config(&text, &["--listen", LISTEN_ANY])));
            apis.push(nodes.last().unwrap().as_ref().unwrap().api());
        }
        Fleet {
            arena: *arena,
            nodes,
            apis,
            proxies,
            _creds: creds,
            _ids: Some(ids),
        }
    }

    /// One Kestrel alone in the arena with vehicle 0 (the fake's first), no bus: what three nodes
    /// are measured against.
    pub fn start_alone(arena: &Arena, connection: &str) -> Self {
        let node = Kestrel::run_config(
            &config(arena, 0, connection, None),
            &["--listen", LISTEN_ANY],
        );
        let api = node.api();
        Fleet {
            arena: *arena,
            nodes: vec![Some(node)],
            apis: vec![api],
            proxies: Vec::new(),
            _creds: tempfile::tempdir().unwrap(),
            _ids: None,
        }
    }

    /// `kestrel evaluate` over the listed nodes' flight logs, as one flight in `world`: its
    /// metrics (`exploration::offline::evaluate::ExplorationMetrics`), the area curve every 0.5 s.
    pub fn evaluate(&self, live: &[usize], world: &Path) -> Value {
        let out = tempfile::NamedTempFile::new().unwrap();
        let mut cmd = Command::new(env!("CARGO_BIN_EXE_kestrel"));
        cmd.args(["evaluate", "--world", world.to_str().unwrap()])
            .args(["--curve-step-s", "0.5"])
            .args(["--out", out.path().to_str().unwrap()]);
        for &i in live {
            let node = self.nodes[i].as_ref().expect("a live node");
            cmd.args(["--log", node.log.to_str().unwrap()]);
        }
        let run = cmd.output().unwrap();
        assert!(
            run.status.success(),
            "kestrel evaluate: {}",
            String::from_utf8_lossy(&run.stderr)
        );
        serde_json::from_str(&std::fs::read_to_string(out.path()).unwrap()).unwrap()
    }

    pub fn output(&self) -> String {
        self.nodes
            .iter()
            .enumerate()
            .map(|(i, k)| match k {
                Some(k) => format!("--- node_{i} ---\n{}", k.output()),
                None => format!("--- node_{i}: killed ---"),
            })
            .collect::<Vec<_>>()
            .join("\n")
    }

    /// Waits until every live node has its drone ready and hears every other live node's.
    pub fn wait_joined(&self, live: &[usize]) {
        let deadline = Instant::now() + Duration::from_secs(60);
        loop {
            let joined = live.iter().all(|&i| {
                let s = self.apis[i].get("/api/status");
                let own = &s["drones"][0];
                let heard: Vec<&str> = s["remote"]
                    .as_array()
                    .map(|r| {
                        r.iter()
                            .filter(|d| d["silent"] == false)
                            .filter_map(|d| d["id"].as_str())
                            .collect()
                    })
                    .unwrap_or_default();
                own["link"] == "ok"
                    && own["ready_to_fly"] == true
                    && live
                        .iter()
                        .filter(|&&j| j != i)
                        .all(|j| heard.contains(&format!("drone_{j}").as_str()))
            });
            if joined {
                return;
            }
            assert!(
                Instant::now() < deadline,
                "the fleet did not join: {:?}\n{}",
                live.iter()
                    .map(|&i| self.apis[i].get("/api/status"))
                    .collect::<Vec<_>>(),
                self.output()
            );
            std::thread::sleep(Duration::from_millis(250));
        }
    }

    pub fn explore(&self, i: usize) {
        let args: Value = serde_json::from_str(ARGS).unwrap();
        let (code, body) = self.apis[i].post(
            "/api/exploration/start",
            &json!({"drones": [format!("drone_{i}")], "args": args}),
        );
        assert_eq!(code, 200, "node_{i}: {body}");
    }

    /// Waits until every listed node's exploration has finished; returns their views.
    pub fn wait_explored(&self, live: &[usize], fake: &Fake) -> Vec<Value> {
        let timeout = self.arena.exploration_timeout;
        let deadline = Instant::now() + timeout;
        loop {
            let views: Vec<Value> = live
                .iter()
                .map(|&i| self.apis[i].get("/api/exploration"))
                .collect();
            if views.iter().all(|v| v["progress"]["finished"] == true) {
                return views;
            }
            assert!(
                Instant::now() < deadline,
                "not explored within {timeout:?}: {views:?}\n{}\n{}",
                fake.diagnostics(),
                self.output()
            );
            std::thread::sleep(Duration::from_millis(500));
        }
    }
}

/// A Kestrel on a bus without an autopilot (its drone `drone_{id}` waits on a UDP port where
/// nothing answers): node `node_{id}` of `ids` listening on `listen`, connecting to `connect`.
pub fn bus_only_node(
    id: usize,
    fleet: &str,
    listen: u16,
    connect: &[u16],
    creds: &str,
    ids: &Identities,
) -> String {
    let connect: Vec<String> = connect
        .iter()
        .map(|p| format!("tcp/127.0.0.1:{p}"))
        .collect();
    format!(
        "[[vehicle]]\nid = \"drone_{id}\"\nconnection = \"udpin:127.0.0.1:{}\"\n\n\
         [fleet]\nenabled = true\nname = \"{fleet}\"\nnode = \"node_{id}\"\n\
         listen = [\"tcp/127.0.0.1:{listen}\"]\nconnect = {}\ncredentials_file = \"{creds}\"\n{}",
        super::free_udp_port(),
        serde_json::to_string(&connect).unwrap(),
        ids.section_end(id)
    )
}

/// `kestrel run` of that config, its API on a free port.
pub fn start_bus_only(config: &str) -> (Kestrel, Api) {
    let node = Kestrel::run_config(config, &["--listen", LISTEN_ANY]);
    let api = node.api();
    (node, api)
}
