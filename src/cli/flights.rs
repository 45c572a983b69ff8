//! What the CLI follows while a host runs: the flights it started (missions given on the command
//! line, and the demo flight, started as a mission once the vehicle is ready), and one console
//! line per change of a drone's link, mode, arming, readiness or autopilot boot.
//!
//! In: the host's published state (a `watch`), and its handle to start the demo mission.
//! Out: the flights (drone index, mission id) whose outcome decides the exit status, and
//! console lines.

use kestrel::host::runtime::HostHandle;
use kestrel::host::status::{DroneStatus, HostSnapshot};
use kestrel::host::LoadOptions;
use kestrel::scenario::demo::{as_mission, demo_plan};
use kestrel::types::{LinkHealth, Vec3};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::Duration;
use tokio::sync::watch;

/// The flights whose end the CLI waits for; the demo joins once it has started.
#[derive(Clone, Default)]
pub struct Flights {
    inner: Arc<Mutex<FlightList>>,
}

#[derive(Default)]
struct FlightList {
    missions: Vec<(usize, u32)>,
    /// The demo has not started yet (waiting for the vehicle).
    demo_pending: bool,
    /// Why a flight could not even start.
    failed: Option<String>,
}

impl Flights {
    pub fn new(missions: Vec<(usize, u32)>, demo: bool) -> Self {
        Flights {
            inner: Arc::new(Mutex::new(FlightList {
                missions,
                demo_pending: demo,
                failed: None,
            })),
        }
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, FlightList> {
        self.inner.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// The flights started so far; `None` while one is still to start.
    pub fn started(&self) -> Option<Vec<(usize, u32)>> {
        let list = self.lock();
        (!list.demo_pending).then(|| list.missions.clone())
    }

    pub fn is_empty(&self) -> bool {
        let list = self.lock();
        list.missions.is_empty() && !list.demo_pending
    }

    /// A flight that could not start, and why.
    pub fn failure(&self) -> Option<String> {
        self.lock().failed.clone()
    }

    fn demo_started(&self, flight: (usize, u32)) {
        let mut list = self.lock();
        list.missions.push(flight);
        list.demo_pending = false;
    }

    fn demo_failed(&self, reason: String) {
        let mut list = self.lock();
        list.failed = Some(reason);
        list.demo_pending = false;
    }
}

/// Whether a drone can be given a flight: the link is up, the autopilot is ready and has given
/// a position (the demo starts from it).
fn ready(d: &DroneStatus) -> bool {
    d.link == LinkHealth::Ok && d.ready_to_fly && d.has_position
}

/// Waits for drone 0 to be ready, then starts the demo from where it stands; gives up after
/// `timeout` with the autopilot's last word.
pub async fn start_demo_when_ready(
    handle: HostHandle,
    mut state: watch::Receiver<Arc<HostSnapshot>>,
    flights: Flights,
    timeout: Duration,
) {
    let became_ready = tokio::time::timeout(
        timeout,
        state.wait_for(|s| s.drones.first().is_some_and(ready)),
    )
    .await
    .is_ok_and(|r| r.is_ok());
    let snapshot = state.borrow().clone();
    let Some(drone) = snapshot.drones.first() else {
        flights.demo_failed("no vehicle".into());
        return;
    };
    if !became_ready {
        let why = drone
            .last_error
            .clone()
            .unwrap_or_else(|| format!("link {}", kestrel::host::status::link_word(drone.link)));
        flights.demo_failed(format!("the autopilot never became ready: {why}"));
        return;
    }
    let (Some([x, y, z]), Some(yaw_rad)) = (drone.position_enu_m, drone.yaw_rad) else {
        flights.demo_failed("the autopilot is ready but has given no position".into());
        return;
    };
    let mission = as_mission(&drone.drone, demo_plan(Vec3::new(x, y, z), yaw_rad));
    match handle.load_mission(mission, LoadOptions::start()).await {
        Ok(up) => {
            println!("demo flight started as mission {}", up.mission_id);
            flights.demo_started((0, up.mission_id));
        }
        Err(e) => flights.demo_failed(format!("the demo mission was refused: {e}")),
    }
}

/// Prints a line whenever a drone's link, mode, arming, readiness or boot count changes.
pub async fn print_status_changes(mut state: watch::Receiver<Arc<HostSnapshot>>) {
    let mut last: Vec<DroneStatus> = Vec::new();
    loop {
        let snapshot = state.borrow_and_update().clone();
        for d in &snapshot.drones {
            let before = last.iter().find(|p| p.drone == d.drone);
            for line in changes(before, d) {
                println!("[{:8.2} s] {}: {line}", snapshot.t, d.drone);
            }
        }
        last.clone_from(&snapshot.drones);
        if state.changed().await.is_err() {
            return;
        }
    }
}

fn changes(before: Option<&DroneStatus>, now: &DroneStatus) -> Vec<String> {
    let mut out = Vec::new();
    if before.is_none_or(|b| b.link != now.link) {
        out.push(format!(
            "link: {}",
            kestrel::host::status::link_word(now.link)
        ));
    }
    let Some(b) = before else {
        return out;
    };
    if b.mode != now.mode {
        out.push(format!("mode: {}", now.mode));
    }
    if b.armed != now.armed {
        out.push(if now.armed { "armed" } else { "disarmed" }.to_string());
    }
    if b.ready_to_fly != now.ready_to_fly {
        out.push(format!("ready to fly: {}", now.ready_to_fly));
    }
    if b.boot_counter != now.boot_counter {
        out.push(format!("autopilot reboot #{}", now.boot_counter));
    }
    out
}
