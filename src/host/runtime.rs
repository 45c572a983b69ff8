//! The host's control loop, on a thread of its own, and the handle the API talks to it with.
//!
//! In: commands (bounded `mpsc`, one-shot replies), a pace (real time, a speed-up factor, or as
//! fast as possible), a shutdown signal. Out: the latest [`HostSnapshot`] (`watch`, at most
//! every `publish_period` and on every mission change), events (`broadcast`: a slow reader
//! lags and skips, the loop never waits), and systemd READY / WATCHDOG notifications. What is
//! saved leaves through the host's store (`host::store`), written on a thread of its own.
//!
//! The loop runs in its own single-threaded tokio runtime on a dedicated thread, so WebSocket
//! clients and HTTP handlers on the main runtime cannot delay a control tick. Within the loop
//! the tick timer comes before commands, and between two ticks at most
//! [`MAX_COMMANDS_PER_TICK`] commands (or half a period of work) are carried out, so a stream
//! of commands cannot delay a tick either; the loop counts how regularly it ticked
//! ([`LoopStats`], `HostHandle::loop_stats`).

use super::engine::{Command, Host, HostError, Reply};
use super::status::{HostSnapshot, SharedEvent};
use super::store::Saved;
use crate::mission::methods::methods;
use crate::planning::worker::Delivery;
use serde::Serialize;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};
use tokio::sync::{broadcast, mpsc, oneshot, watch};

/// How simulated (or real) time advances against the wall clock.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Pace {
    /// A real vehicle: one tick per period, stamped with the wall-clock time since start.
    RealTime,
    /// The simulator at `factor` simulated seconds per wall-clock second.
    Factor(f64),
    /// The simulator as fast as the CPU allows.
    Max,
}

/// Checked after every step: true ends the loop.
pub type StopWhen = Box<dyn FnMut(&Host) -> bool + Send>;

pub struct RuntimeOptions {
    pub pace: Pace,
    pub command_capacity: usize,
    pub event_capacity: usize,
    /// Shortest wall-clock time between two published snapshots.
    pub publish_period: Duration,
    /// Checked after every step: true ends the loop (e.g. `--exit-when-done`).
    pub stop_when: Option<StopWhen>,
    /// Run after every tick (or batch), never waiting: the fleet bus's exchange.
    pub between_ticks: Option<BetweenTicks>,
    /// Plans and allocations answered in lock step at any pace, so a seeded run flies the same
    /// at every speed-up (`kestrel explore`); otherwise only at [`Pace::Max`], and paced to the
    /// wall clock a tick never waits for a plan.
    pub lock_step: bool,
}

/// Work the loop does between ticks, with the host.
pub type BetweenTicks = Box<dyn FnMut(&mut Host) + Send>;

impl RuntimeOptions {
    pub fn new(pace: Pace) -> Self {
        Self {
            pace,
            command_capacity: 64,
            event_capacity: 1024,
            publish_period: Duration::from_millis(20),
            stop_when: None,
            between_ticks: None,
            lock_step: false,
        }
    }
}

/// A behavior as `GET /api/behaviors` lists it.
#[derive(Debug, Clone, Serialize, utoipa::ToSchema)]
pub struct BehaviorInfo {
    pub name: String,
    pub description: String,
    pub resource: String,
    #[schema(value_type = Object)]
    pub args_schema: serde_json::Value,
    pub methods: Vec<String>,
}

/// What does not change while the host runs.
#[derive(Debug, Clone)]
pub struct HostInfo {
    pub drones: Vec<String>,
    pub simulated: bool,
    pub behaviors: Vec<BehaviorInfo>,
    /// The `[geofence]` section missions are checked against.
    pub geofence: crate::safety::GeofenceSection,
}

/// The API's way to the host. Cheap to clone.
#[derive(Clone)]
pub struct HostHandle {
    commands: mpsc::Sender<Command>,
    state: watch::Receiver<Arc<HostSnapshot>>,
    events: broadcast::Sender<SharedEvent>,
    stats: Arc<LoopStats>,
    pub info: Arc<HostInfo>,
}

/// How long a command may wait for room in the queue before the API answers "busy".
const QUEUE_WAIT: Duration = Duration::from_millis(500);
/// How long the API waits for the host's answer.
const REPLY_WAIT: Duration = Duration::from_secs(5);

impl HostHandle {
    /// Sends a command built around a reply channel and waits for the answer.
    pub async fn call<T>(&self, make: impl FnOnce(Reply<T>) -> Command) -> Result<T, HostError> {
        let (tx, rx) = oneshot::channel();
        self.commands
            .send_timeout(make(tx), QUEUE_WAIT)
            .await
            .map_err(|e| match e {
                mpsc::error::SendTimeoutError::Timeout(_) => {
                    HostError::Unavailable("the control loop is busy; try again".into())
                }
                mpsc::error::SendTimeoutError::Closed(_) => {
                    HostError::Unavailable("the control loop has stopped".into())
                }
            })?;
        match tokio::time::timeout(REPLY_WAIT, rx).await {
            Ok(Ok(result)) => result,
            Ok(Err(_)) => Err(HostError::Unavailable(
                "the control loop stopped before answering".into(),
            )),
            Err(_) => Err(HostError::Unavailable(
                "the control loop did not answer in time".into(),
            )),
        }
    }

    pub fn snapshot(&self) -> Arc<HostSnapshot> {
        self.state.borrow().clone()
    }

    pub fn watch_state(&self) -> watch::Receiver<Arc<HostSnapshot>> {
        self.state.clone()
    }

    /// How regularly the control loop has ticked so far.
    pub fn loop_stats(&self) -> LoopStatsView {
        self.stats.view()
    }

    pub fn subscribe_events(&self) -> broadcast::Receiver<SharedEvent> {
        self.events.subscribe()
    }
}

fn host_info(host: &Host) -> HostInfo {
    let behaviors = host
        .cores()
        .first()
        .map(|c| {
            c.server()
                .registry()
                .iter()
                .map(|s| BehaviorInfo {
                    name: s.name.to_string(),
                    description: s.description.to_string(),
                    resource: serde_json::to_value(s.resource)
                        .ok()
                        .and_then(|v| v.as_str().map(str::to_string))
                        .unwrap_or_default(),
                    args_schema: s.args_schema.clone(),
                    methods: methods(s.name),
                })
                .collect()
        })
        .unwrap_or_default();
    HostInfo {
        drones: host.drone_ids(),
        simulated: host.is_simulated(),
        behaviors,
        geofence: host.limits().geofence.clone(),
    }
}

/// A started control loop.
pub struct Spawned {
    pub handle: HostHandle,
    /// Subscribed before the first tick, so it sees every event.
    pub events: broadcast::Receiver<SharedEvent>,
    /// Ends (returning the host) when `shutdown` becomes true or `stop_when` says so.
    pub thread: std::thread::JoinHandle<Host>,
}

/// Starts the control loop on its own thread.
pub fn spawn(
    mut host: Host,
    options: RuntimeOptions,
    shutdown: watch::Receiver<bool>,
) -> std::io::Result<Spawned> {
    if options.pace != Pace::Max && !options.lock_step {
        // Paced to the wall clock, a tick never waits for a plan.
        host.set_plan_delivery(Delivery::RealTime {
            deadline: PLAN_DEADLINE,
        });
    }
    let (commands, rx) = mpsc::channel(options.command_capacity.max(1));
    let (state_tx, state) = watch::channel(Arc::new(host.snapshot()));
    let (events, first_events) = broadcast::channel(options.event_capacity.max(16));
    let stats = Arc::new(LoopStats::default());
    let handle = HostHandle {
        commands,
        state,
        events: events.clone(),
        stats: stats.clone(),
        info: Arc::new(host_info(&host)),
    };
    let thread = std::thread::Builder::new()
        .name("kestrel-control".into())
        .spawn(move || {
            let runtime = tokio::runtime::Builder::new_current_thread()
                .enable_all()
                .build();
            match runtime {
                Ok(rt) => rt.block_on(control_loop(
                    host, rx, state_tx, events, stats, options, shutdown,
                )),
                Err(e) => {
                    tracing::error!("cannot start the control loop: {e}");
                    host
                }
            }
        })?;
    Ok(Spawned {
        handle,
        events: first_events,
        thread,
    })
}

/// A plan not done within this wall-clock time fails (its behavior fails with a timeout).
const PLAN_DEADLINE: Duration = Duration::from_secs(2);

/// How long stopping waits for the last changes to reach the disk.
const SHUTDOWN_SAVE_WAIT: Duration = Duration::from_secs(5);

/// Most simulated ticks run in one wake-up when the loop is late.
const MAX_CATCH_UP: u32 = 50;
/// Ticks per batch at `Pace::Max` before other work (commands, publishing) gets a turn.
const MAX_BATCH: u32 = 100;
/// Most commands carried out between two ticks (or two batches at `Pace::Max`).
pub const MAX_COMMANDS_PER_TICK: u32 = 16;

/// The commands one tick period may still take: a count and half the period's wall-clock time,
/// so a burst of expensive commands (large uploads) waits for the next period instead of
/// pushing the tick back.
struct CommandBudget {
    left: u32,
    since: Instant,
    time: Duration,
}

impl CommandBudget {
    fn new(wake: Duration) -> Self {
        Self {
            left: MAX_COMMANDS_PER_TICK,
            since: Instant::now(),
            time: wake / 2,
        }
    }

    fn open(&self) -> bool {
        self.left > 0 && self.since.elapsed() < self.time
    }

    fn spend(&mut self) {
        self.left = self.left.saturating_sub(1);
    }

    fn refill(&mut self) {
        self.left = MAX_COMMANDS_PER_TICK;
        self.since = Instant::now();
    }
}

/// The loop's own timing, counted as it runs: how regularly the tick timer woke it.
#[derive(Debug, Default)]
pub struct LoopStats {
    wakes: AtomicU64,
    late: AtomicU64,
    missed: AtomicU64,
    max_interval_us: AtomicU64,
    commands: AtomicU64,
    last: std::sync::Mutex<Option<Instant>>,
}

/// A copy of [`LoopStats`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize)]
pub struct LoopStatsView {
    /// Times the tick timer woke the loop (each runs one tick or a batch of ticks).
    pub wakes: u64,
    /// Wakes more than 1.5 periods after the previous one.
    pub late: u64,
    /// Periods that passed without a wake (an interval of n periods misses n - 1).
    pub missed: u64,
    /// Longest interval between two wakes (µs).
    pub max_interval_us: u64,
    /// Commands carried out.
    pub commands: u64,
}

impl LoopStats {
    fn woke(&self, now: Instant, period: Duration) {
        self.wakes.fetch_add(1, Ordering::Relaxed);
        let mut last = self.last.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(previous) = last.replace(now) {
            let interval = now.duration_since(previous);
            let us = u64::try_from(interval.as_micros()).unwrap_or(u64::MAX);
            self.max_interval_us.fetch_max(us, Ordering::Relaxed);
            let periods = interval.as_secs_f64() / period.as_secs_f64().max(1e-9);
            if periods > 1.5 {
                self.late.fetch_add(1, Ordering::Relaxed);
                self.missed
                    .fetch_add(periods.round() as u64 - 1, Ordering::Relaxed);
            }
        }
    }

    fn command(&self) {
        self.commands.fetch_add(1, Ordering::Relaxed);
    }

    pub fn view(&self) -> LoopStatsView {
        LoopStatsView {
            wakes: self.wakes.load(Ordering::Relaxed),
            late: self.late.load(Ordering::Relaxed),
            missed: self.missed.load(Ordering::Relaxed),
            max_interval_us: self.max_interval_us.load(Ordering::Relaxed),
            commands: self.commands.load(Ordering::Relaxed),
        }
    }
}

struct Publisher {
    state_tx: watch::Sender<Arc<HostSnapshot>>,
    events: broadcast::Sender<SharedEvent>,
    period: Duration,
    last: Option<Instant>,
    log_flushed: Instant,
    map_sent: Option<Instant>,
}

impl Publisher {
    fn publish(&mut self, host: &mut Host) {
        let events = host.drain_events();
        let due = self.last.is_none_or(|t| t.elapsed() >= self.period);
        if due || !events.is_empty() {
            self.state_tx.send_replace(Arc::new(host.snapshot()));
            self.last = Some(Instant::now());
        }
        let map_period = host.map().map(|m| m.update_period());
        let map_due = map_period.is_some_and(|p| self.map_sent.is_none_or(|t| t.elapsed() >= p));
        let map_updates = if map_due {
            self.map_sent = Some(Instant::now());
            host.take_map_updates()
        } else {
            Vec::new()
        };
        for e in events.into_iter().chain(map_updates) {
            // No subscriber is not an error: nobody is watching.
            let _ = self.events.send(Arc::new(e));
        }
        if self.log_flushed.elapsed() >= Duration::from_millis(200) {
            host.flush_log();
            self.log_flushed = Instant::now();
        }
    }
}

struct Watchdog {
    period: Option<Duration>,
    last: Instant,
}

impl Watchdog {
    fn new() -> Self {
        let mut usec = 0;
        let period =
            sd_notify::watchdog_enabled(false, &mut usec).then(|| Duration::from_micros(usec / 2));
        Self {
            period,
            last: Instant::now(),
        }
    }

    /// Pings systemd from the loop, so a stuck loop gets the service restarted.
    fn ping(&mut self) {
        if let Some(p) = self.period {
            if self.last.elapsed() >= p {
                let _ = sd_notify::notify(false, &[sd_notify::NotifyState::Watchdog]);
                self.last = Instant::now();
            }
        }
    }
}

async fn control_loop(
    mut host: Host,
    mut rx: mpsc::Receiver<Command>,
    state_tx: watch::Sender<Arc<HostSnapshot>>,
    events: broadcast::Sender<SharedEvent>,
    stats: Arc<LoopStats>,
    mut options: RuntimeOptions,
    mut shutdown: watch::Receiver<bool>,
) -> Host {
    let tick = host.tick_period();
    let wake = match options.pace {
        Pace::RealTime | Pace::Max => tick,
        Pace::Factor(f) => tick.div_f64(f.max(1e-3)),
    }
    .max(Duration::from_millis(1));
    let mut ticker = tokio::time::interval(wake);
    ticker.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Skip);
    let mut publisher = Publisher {
        state_tx,
        events,
        period: options.publish_period,
        last: None,
        log_flushed: Instant::now(),
        map_sent: None,
    };
    let mut watchdog = Watchdog::new();
    let _ = sd_notify::notify(false, &[sd_notify::NotifyState::Ready]);
    let mut wall_start = Instant::now();
    let mut sim_start = host.now();
    if options.pace == Pace::RealTime {
        host.log_wall_clock(std::time::SystemTime::now());
    }
    let mut budget = CommandBudget::new(wake);
    loop {
        // As fast as possible only while something flies: once every flight is over, simulated
        // time goes on at the wall clock's pace (an idle `--speedup max` would fill the disk
        // with flight log at thousands of seconds a second).
        let fast = options.pace == Pace::Max && !host.is_idle();
        // The tick timer comes first: a stream of commands cannot hold back a tick, and
        // between two ticks at most `MAX_COMMANDS_PER_TICK` commands (or half a period of
        // work) are taken; the rest wait in the bounded queue for the next tick.
        tokio::select! {
            biased;
            changed = shutdown.changed() => {
                if changed.is_err() || *shutdown.borrow() {
                    break;
                }
                continue;
            }
            _ = ticker.tick(), if !fast => {}
            command = rx.recv(), if budget.open() => {
                match command {
                    Some(c) => host.handle(c),
                    None => break,
                }
                budget.spend();
                stats.command();
                publisher.publish(&mut host);
                continue;
            }
            _ = tokio::task::yield_now(), if fast => {}
        }
        stats.woke(Instant::now(), wake);
        budget.refill();
        let stop = match options.pace {
            Pace::RealTime => {
                host.step_at(sim_start + wall_start.elapsed());
                check_stop(&mut options, &host)
            }
            Pace::Factor(f) => {
                let target = sim_start + wall_start.elapsed().mul_f64(f);
                let mut steps = 0;
                let mut stop = false;
                while host.now() + tick <= target && steps < MAX_CATCH_UP && !stop {
                    host.step();
                    steps += 1;
                    stop = check_stop(&mut options, &host);
                }
                if steps == MAX_CATCH_UP {
                    // Too slow for this factor: run slower than asked rather than in bursts.
                    wall_start = Instant::now();
                    sim_start = host.now();
                }
                stop
            }
            Pace::Max => {
                let mut stop = false;
                let batch = if fast { MAX_BATCH } else { 1 };
                for _ in 0..batch {
                    host.step();
                    stop = check_stop(&mut options, &host);
                    if stop {
                        break;
                    }
                }
                stop
            }
        };
        if let Some(f) = options.between_ticks.as_mut() {
            f(&mut host);
        }
        publisher.publish(&mut host);
        watchdog.ping();
        if stop {
            break;
        }
    }
    let _ = sd_notify::notify(false, &[sd_notify::NotifyState::Stopping]);
    publisher.publish(&mut host);
    host.flush_log();
    host.commit();
    if let Some(store) = host.store() {
        match store.saved(SHUTDOWN_SAVE_WAIT).await {
            Saved::Durable => {}
            Saved::Failed(e) => tracing::error!("stopping with the state not saved: {e}"),
            Saved::Pending => tracing::error!("stopping with the state not saved yet"),
        }
    }
    host
}

fn check_stop(options: &mut RuntimeOptions, host: &Host) -> bool {
    options.stop_when.as_mut().is_some_and(|f| f(host))
}
