//! Control-tick interval of the real-time host on a fleet bus while a peer floods it with valid
//! map messages, and the process's memory while made-up drones come and go (issue 29, item 4).
//!
//! One simulated drone flies one-second `go_to` items at 100 Hz on a 500 x 500 map (0.1 m
//! cells); the bus's control-loop end (`host::bus_link::BusLink`) is fed the way Zenoh's
//! subscriber feeds it: signed bytes handed to `fleet_bus::intake::Intake` (signature, counter,
//! decoding and checks off the loop, states queued, map regions coalesced in the map inbox), by
//! a thread standing for the peers. Three phases in one run: quiet; a flood of 100 full-grid
//! regions a second from a roster member (250 000 cells each, every cell changing every
//! message, its two drones); then 1 500 made-up drones, each announced by a made-up node and
//! mapped with a full grid once, 100 a second.
//!
//! Run: `cargo bench --bench bus_flood` (about 45 s). Prints p50, p99 and max per phase and the
//! resident memory at each phase's end; the results are in BENCHMARKS.md ("Control tick under a
//! flood of map messages").

use kestrel::config::Config;
use kestrel::fleet_bus::config::FleetSection;
use kestrel::fleet_bus::identity::Signer;
use kestrel::fleet_bus::inbox::MapInbox;
use kestrel::fleet_bus::intake::{Intake, Member};
use kestrel::fleet_bus::join::JoinWatch;
use kestrel::fleet_bus::node::{BusPort, BusStats};
use kestrel::fleet_bus::remote::SilencePolicy;
use kestrel::fleet_bus::wire::{DroneState, MapHeader, MapMsg, StateMsg, WIRE_VERSION};
use kestrel::host::bus_link::BusLink;
use kestrel::host::runtime::{self, Pace, RuntimeOptions};
use kestrel::mapping::grid::GridSpec;
use kestrel::mission::{Action, MissionUpdate};
use kestrel::scenario::sim_host::simulated_host;
use kestrel::sim::world::World;
use serde_json::{json, Value};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use tokio::sync::mpsc;

const HEIGHT_M: f64 = 1.5;
const QUIET_S: u64 = 10;
const FLOOD_S: u64 = 15;
/// Made-up drones announced and mapped in the last phase, 100 a second.
const MADE_UP: usize = 1500;
/// The target for the tick interval's p99 under the flood (ms).
const TARGET_P99_MS: f64 = 12.0;

fn flight(items: usize) -> Value {
    let mut plan = vec![json!({"behavior": "takeoff", "args": {"height": HEIGHT_M, "speed": 1.0}})];
    for k in 0..items {
        let x = if k % 2 == 0 { 0.5 } else { -0.5 };
        plan.push(json!({"behavior": "go_to",
            "args": {"x": x, "y": 0.0, "z": HEIGHT_M, "speed": 0.5, "run_for_s": 1.0}}));
    }
    plan.push(json!({"behavior": "land", "args": {"speed": 1.0}}));
    json!({"target": "drone_0", "plan": plan})
}

/// The last tick's time and every (phase, interval ms) recorded while the drone flies go_to.
type Intervals = (Option<Instant>, Vec<(usize, f64)>);

fn percentile(sorted: &[f64], q: f64) -> f64 {
    let k = ((sorted.len() as f64 - 1.0) * q).round() as usize;
    sorted.get(k).copied().unwrap_or(f64::NAN)
}

fn rss_mb() -> f64 {
    let status = std::fs::read_to_string("/proc/self/status").unwrap_or_default();
    status
        .lines()
        .find_map(|l| l.strip_prefix("VmRSS:"))
        .and_then(|v| v.trim().trim_end_matches("kB").trim().parse::<f64>().ok())
        .map_or(f64::NAN, |kb| kb / 1024.0)
}

fn drone(id: &str) -> DroneState {
    DroneState::at_rest(id, [20.0, 20.0, 0.0], false)
}

fn state(node: &str, drones: &[String], seq: u64) -> StateMsg {
    StateMsg {
        v: WIRE_VERSION,
        node: node.into(),
        seq,
        sent_unix_us: 0,
        drones: drones.iter().map(|d| drone(d)).collect(),
    }
}

fn full_grid(signer: &mut Signer, node: &str, drone: &str, grid: GridSpec, value: i8) -> Vec<u8> {
    let bytes = MapMsg {
        header: MapHeader {
            v: WIRE_VERSION,
            node: node.into(),
            drone: drone.into(),
            seq: 0,
            keyframe: true,
            grid,
            region: grid.full_box(),
        },
        cells: vec![value; grid.cell_count()],
    }
    .encode();
    signer.seal("bench", node, "map", &bytes)
}

/// The peers: what Zenoh's subscriber would hand the bus, at 100 messages a second.
fn peers(intake: Intake, mut member: Signer, grid: GridSpec, phase: Arc<AtomicUsize>) {
    let mut stranger = Signer::from_seed(&[9; 32]).unwrap_or_else(|e| panic!("{e}"));
    let example = full_grid(&mut member, "peer", "peer_a", grid, 0);
    println!("a full-grid region, signed: {} bytes", example.len());
    let ours = ["peer_a".to_string(), "peer_b".to_string()];
    let mut k = 0usize;
    let mut made_up = 0usize;
    let tick = Duration::from_millis(10);
    let mut next = Instant::now();
    loop {
        match phase.load(Ordering::Relaxed) {
            0 => {}
            1 => {
                if k.is_multiple_of(10) {
                    let bytes = member.seal(
                        "bench",
                        "peer",
                        "state",
                        &state("peer", &ours, k as u64).encode(),
                    );
                    let _ = intake.take("kestrel/bench/peer/state", &bytes);
                }
                // Two drones, every cell changing every message.
                let value = [0i8, 100][(k / 2) % 2];
                let drone = &ours[k % 2];
                let msg = full_grid(&mut member, "peer", drone, grid, value);
                if let Err(e) = intake.take("kestrel/bench/peer/map", &msg) {
                    panic!("{e}");
                }
            }
            2 if made_up < MADE_UP => {
                let node = format!("made-up-{}", made_up % 100);
                let id = format!("x{made_up}");
                let s = state(&node, std::slice::from_ref(&id), k as u64).encode();
                let s = stranger.seal("bench", &node, "state", &s);
                let _ = intake.take(&format!("kestrel/bench/{node}/state"), &s);
                let m = full_grid(&mut stranger, &node, &id, grid, 100);
                let _ = intake.take(&format!("kestrel/bench/{node}/map"), &m);
                made_up += 1;
            }
            2 => {}
            _ => return,
        }
        k += 1;
        next += tick;
        std::thread::sleep(next.saturating_duration_since(Instant::now()));
    }
}

fn main() {
    // `cargo test --all-targets` runs bench binaries too: only `cargo bench` measures.
    if !std::env::args().any(|a| a == "--bench") {
        println!("bus_flood: run it with `cargo bench --bench bus_flood`");
        return;
    }
    let mut config = Config::default();
    config.map.size_m = Some([50.0, 50.0]);
    let mut host = simulated_host(World::empty(), 1, 1, &config);
    let section = FleetSection {
        enabled: true,
        name: "bench".into(),
        listen: vec!["tcp/127.0.0.1:7447".into()],
        ..FleetSection::default()
    };
    let drones = vec!["peer_a".to_string(), "peer_b".to_string()];
    host.enable_fleet_bus(
        SilencePolicy {
            peer_timeout: Duration::from_secs_f64(section.peer_timeout_s),
            lost_after: Duration::from_secs_f64(section.lost_after_s),
            keepout_m: section.silent_keepout_m,
        },
        [("peer".to_string(), drones.clone())].into(),
    );
    let Some(grid) = host.map().map(|m| *m.merged().spec()) else {
        panic!("the simulated host has no map");
    };
    println!(
        "map grid {} x {} cells",
        grid.width_cells, grid.height_cells
    );
    host.step();
    host.update(&MissionUpdate {
        drone_id: Some("drone_0".into()),
        mission_id: None,
        item_id: None,
        action: Action::Execute,
        mission: Some(flight((QUIET_S + 2 * FLOOD_S + 30) as usize)),
    })
    .unwrap_or_else(|e| panic!("flight: {e}"));

    let (state_tx, inbound) = mpsc::channel(256);
    let (outbound, mut sent) = mpsc::channel(256);
    let maps = Arc::new(MapInbox::default());
    let stats = Arc::new(BusStats::default());
    let port = BusPort {
        inbound,
        maps: maps.clone(),
        outbound,
        stats: stats.clone(),
        join: JoinWatch::global(),
    };
    let mut link = BusLink::new(port, &section, "bench".into());
    std::thread::spawn(move || while sent.blocking_recv().is_some() {});

    let phase = Arc::new(AtomicUsize::new(0));
    let intervals: Arc<Mutex<Intervals>> = Arc::default();
    let (p, rec) = (phase.clone(), intervals.clone());
    let mut options = RuntimeOptions::new(Pace::RealTime);
    options.between_ticks = Some(Box::new(move |h| link.exchange(h)));
    options.stop_when = Some(Box::new(move |host| {
        let now = Instant::now();
        let flying = host
            .cores()
            .first()
            .and_then(|c| c.server().motion())
            .is_some_and(|(name, _)| name == "go_to");
        let mut r = rec.lock().unwrap_or_else(|e| e.into_inner());
        if let (true, Some(last)) = (flying, r.0) {
            let ms = now.duration_since(last).as_secs_f64() * 1000.0;
            r.1.push((p.load(Ordering::Relaxed), ms));
        }
        r.0 = Some(now);
        p.load(Ordering::Relaxed) == 3
    }));
    let member = Signer::from_seed(&[7; 32]).unwrap_or_else(|e| panic!("{e}"));
    let members = [(
        "peer".to_string(),
        Member {
            keys: vec![member.public()],
            drones,
        },
    )]
    .into();
    let intake = Intake::new(
        "bench",
        "bench",
        members,
        grid.cell_count(),
        stats.clone(),
        state_tx,
        maps.clone(),
    );
    let feeder = {
        let phase = phase.clone();
        std::thread::spawn(move || peers(intake, member, grid, phase))
    };

    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(1)
        .enable_all()
        .build()
        .unwrap_or_else(|e| panic!("{e}"));
    let mut memory = Vec::new();
    let host = rt.block_on(async {
        let (_stop, stop_rx) = tokio::sync::watch::channel(false);
        let spawned = runtime::spawn(host, options, stop_rx).unwrap_or_else(|e| panic!("{e}"));
        tokio::time::sleep(Duration::from_secs(QUIET_S)).await;
        memory.push(rss_mb());
        phase.store(1, Ordering::Relaxed);
        tokio::time::sleep(Duration::from_secs(FLOOD_S)).await;
        memory.push(rss_mb());
        phase.store(2, Ordering::Relaxed);
        tokio::time::sleep(Duration::from_millis(10 * MADE_UP as u64 + 1000)).await;
        memory.push(rss_mb());
        phase.store(3, Ordering::Relaxed);
        let joined = tokio::task::spawn_blocking(move || spawned.thread.join()).await;
        joined
            .unwrap_or_else(|e| panic!("{e}"))
            .unwrap_or_else(|_| panic!("control loop panicked"))
    });
    let _ = feeder.join();
    let r = intervals.lock().unwrap_or_else(|e| e.into_inner());
    println!("| phase | ticks | p50 ms | p99 ms | max ms | resident memory at its end |");
    println!("|---|---|---|---|---|---|");
    let names = [
        "flight, quiet".to_string(),
        "flight, 100 full-grid regions/s".to_string(),
        format!("flight, {MADE_UP} made-up drones mapped"),
    ];
    let mut flood_p99 = f64::NAN;
    for (ph, name) in names.iter().enumerate() {
        let mut v: Vec<f64> =
            r.1.iter()
                .filter(|(p, _)| *p == ph)
                .map(|(_, ms)| *ms)
                .collect();
        v.sort_by(f64::total_cmp);
        let p99 = percentile(&v, 0.99);
        if ph == 1 {
            flood_p99 = p99;
        }
        println!(
            "| {name} | {} | {:.2} | {p99:.2} | {:.2} | {:.0} MB |",
            v.len(),
            percentile(&v, 0.5),
            v.last().copied().unwrap_or(f64::NAN),
            memory.get(ph).copied().unwrap_or(f64::NAN)
        );
    }
    let s = stats.view();
    println!(
        "map layers at the end {}; bus: received {}, refused {}, dropped {}; flood p99 \
         {flood_p99:.2} ms (target < {TARGET_P99_MS} ms)",
        host.map_layers(),
        s.received,
        s.refused,
        s.dropped
    );
}
