//! Serving a host: the control loop, the API, event printing and shutdown, shared by
//! `kestrel sim` and `kestrel run`.

use crate::cli::flights::{self, Flights};
use anyhow::{Context, Result};
use kestrel::api::{self, ApiState};
use kestrel::config::ApiSection;
use kestrel::flightlog::writer::{self, LogFile};
use kestrel::flightlog::{files, LogFormat};
use kestrel::host::runtime::{self, HostHandle, Pace, RuntimeOptions};
use kestrel::host::status::{EventBody, HostEvent, SharedEvent};
use kestrel::host::{store, Host};
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};
use tokio::sync::watch;

pub struct ServeOptions {
    /// The API's socket (from [`bind`]); `None`: no API (`kestrel run --no-api`).
    pub listener: Option<std::net::TcpListener>,
    pub token: Option<String>,
    pub api: ApiSection,
    pub pace: Pace,
    pub log: Option<LogFile>,
    /// Missions flown at start (and the demo, once it starts).
    pub flights: Flights,
    /// Start the demo flight once drone 0 is ready, waiting at most this long.
    pub demo_within: Option<Duration>,
    /// Stop when every flight ended.
    pub exit_when_done: bool,
    /// Stop after this long in any case (host time); `None`: run until interrupted.
    pub max_time: Option<Duration>,
    /// Run by the control loop between ticks (the fleet bus).
    pub between_ticks: Option<kestrel::host::runtime::BetweenTicks>,
    /// `[ros2]` when enabled: the drones as ROS 2 topics (`kestrel::ros2`).
    pub ros2: Option<kestrel::config::ros2::Ros2Section>,
    /// Given every event the console printer receives, never waiting (texts for the ground
    /// station, `cli::announce`).
    pub on_event: Option<EventTap>,
    /// True while texts for the ground station have not left yet: waited for (at most
    /// [`TEXTS_FLUSH`]) before exiting, so the ground station sees the mission's last words.
    pub texts_pending: Option<Box<dyn Fn() -> bool + Send>>,
}

/// How long an exiting Kestrel waits for its last texts to the ground station (a few at the
/// session's pace; longer only when the link is down, and then they cannot go anyway).
pub const TEXTS_FLUSH: Duration = Duration::from_secs(3);
/// How long the end of a run waits for the flight log's writer to close the file.
const LOG_CLOSE: Duration = Duration::from_secs(10);

/// See [`ServeOptions::on_event`].
pub type EventTap = Box<dyn FnMut(&HostEvent) + Send>;

/// The API address (`--listen`, else the config's `[api] listen`) and token
/// (`KESTREL_API_TOKEN`, else the config).
pub fn listen_and_token(
    flag: Option<&str>,
    config: &kestrel::config::Config,
) -> Result<(SocketAddr, Option<String>)> {
    let listen: SocketAddr = flag
        .unwrap_or(&config.api.listen)
        .parse()
        .context("--listen takes ADDR:PORT, e.g. 127.0.0.1:8080")?;
    let token =
        kestrel::api::auth::resolve_token(std::env::var("KESTREL_API_TOKEN").ok(), &config.api)?;
    Ok((listen, token))
}

/// Prints how the flights ended; with `exit_when_done` a failure is an error (non-zero exit).
pub fn report(outcome: &Outcome, exit_when_done: bool) -> Result<()> {
    if outcome.results.is_empty() {
        return Ok(());
    }
    let failures: Vec<String> = outcome
        .results
        .iter()
        .filter_map(|(drone, r)| match r {
            Some(Ok(())) => None,
            Some(Err(e)) => Some(format!("{drone}: {e}")),
            None => Some(format!("{drone}: mission not finished")),
        })
        .collect();
    if failures.is_empty() {
        println!("flight succeeded");
        Ok(())
    } else if exit_when_done {
        anyhow::bail!("flight failed: {}", failures.join("; "))
    } else {
        println!("flight failed: {}", failures.join("; "));
        Ok(())
    }
}

/// A drone still landing after its flight ended (a failed mission lands, e.g. after a link loss
/// with `on_link_regained = "land"`): the flight is over once it is down.
fn landing(core: &kestrel::core::DroneCore) -> bool {
    core.platform_status().armed
        && core
            .server()
            .motion()
            .is_some_and(|(name, _)| name == "land")
}

/// Restores what the state directory `dir` keeps (created if missing) and keeps every change
/// there from now on. Files that cannot be read are quarantined with a warning and the rest
/// loads; only an unusable directory stops the start.
pub fn open_state(host: &mut Host, dir: &Path) -> Result<()> {
    let (state, report) = store::load(dir, &host.drone_ids())
        .with_context(|| format!("opening the state directory {}", dir.display()))?;
    for p in &report.problems {
        let moved = p.quarantined_as.as_deref().unwrap_or("could not be moved");
        tracing::warn!(
            "state file {} not loaded ({}); quarantined as {moved}",
            p.file,
            p.reason
        );
    }
    if let Some(old) = &report.migrated {
        println!("migrated the old state file to one file per mission (kept as {old})");
    }
    if report.missions > 0 {
        println!(
            "restored {} mission(s) from {} (not resumed)",
            report.missions,
            dir.display()
        );
    }
    host.restore(state);
    let sink = store::Sink::start(dir, report).context("starting the state writer")?;
    host.set_store(sink);
    Ok(())
}

/// Binds the API's port, before anything else starts (a flight log included). A taken port is
/// an error: a second instance must not quietly serve somewhere else while its operator talks
/// to the first one.
pub fn bind(listen: SocketAddr, token: Option<&str>) -> Result<std::net::TcpListener> {
    api::auth::check_listen(listen, token)?;
    let listener = match std::net::TcpListener::bind(listen) {
        Ok(l) => l,
        Err(e) if e.kind() == std::io::ErrorKind::AddrInUse => anyhow::bail!(
            "cannot serve the API on {listen}: the port is taken (another kestrel running?). \
             Stop it, or pass --listen {}:PORT for another port ({}:0 for any free one)",
            listen.ip(),
            listen.ip()
        ),
        Err(e) => return Err(e).with_context(|| format!("cannot listen on {listen}")),
    };
    listener
        .set_nonblocking(true)
        .with_context(|| format!("cannot listen on {listen}"))?;
    Ok(listener)
}

/// Where this run's flight log goes.
pub struct LogChoice {
    /// `--log FILE`: exactly there.
    pub explicit: Option<PathBuf>,
    /// `--log-overwrite`: an existing `--log FILE` is replaced.
    pub overwrite: bool,
    /// Otherwise a new file in this directory, named `<kind>-<start time>.<jsonl or mcap>`.
    pub dir: PathBuf,
    pub kind: String,
    /// Logs of this kind kept in `dir` (the oldest beyond are deleted).
    pub keep: usize,
    /// Wall-clock start of the run: the log's name and its header's `start_time`.
    pub start: std::time::SystemTime,
    /// JSON lines or MCAP.
    pub format: LogFormat,
}

/// What the flight log's header says about the run (see `kestrel::flightlog`).
pub struct RunInfo<'a> {
    /// `sim`, `run` or `explore`.
    pub command: &'a str,
    pub config: &'a kestrel::config::Config,
    pub seed: Option<u64>,
    pub world: Option<&'a Path>,
    pub scenario: Option<&'a Path>,
    pub mission: Option<&'a Path>,
    /// The ENU origin on Earth; `None` until the autopilot gives one.
    pub geo_origin: Option<kestrel::types::GeoPoint>,
    pub drones: Vec<String>,
    pub start: std::time::SystemTime,
}

/// The flight log's first record.
pub fn header(info: &RunInfo) -> serde_json::Value {
    serde_json::json!({
        "version": env!("CARGO_PKG_VERSION"),
        "command": info.command,
        "start_time": files::rfc3339(info.start),
        "drones": info.drones,
        "seed": info.seed,
        "world": info.world.map(|p| p.display().to_string()),
        "scenario": info.scenario.map(|p| p.display().to_string()),
        "mission": info.mission.map(|p| p.display().to_string()),
        "geo_origin": info.geo_origin,
        "config": info.config,
    })
}

/// Creates this run's flight log (never opening an existing file unless told to) and prunes
/// old logs of its kind.
pub fn open_log(choice: &LogChoice) -> Result<(writer::ChannelWriter, LogFile)> {
    let (file, path) = match &choice.explicit {
        Some(path) => {
            let file = files::create_at(path, choice.overwrite)
                .with_context(|| format!("creating flight log {}", path.display()))?;
            (file, path.clone())
        }
        None => {
            let ext = choice.format.extension();
            let (file, path) = files::create(&choice.dir, &choice.kind, ext, choice.start)
                .with_context(|| format!("creating a flight log in {}", choice.dir.display()))?;
            match files::prune(&choice.dir, &choice.kind, choice.keep, &path) {
                Ok(deleted) if !deleted.is_empty() => println!(
                    "deleted {} old flight log(s) (keeping {})",
                    deleted.len(),
                    choice.keep
                ),
                Ok(_) => {}
                Err(e) => tracing::warn!("pruning old flight logs: {e}"),
            }
            (file, path)
        }
    };
    writer::open(file, &path, choice.format)
        .with_context(|| format!("starting the writer of {}", path.display()))
}

/// How the flights at start ended; `None` for a drone still flying.
pub struct Outcome {
    pub results: Vec<(String, Option<Result<(), String>>)>,
    pub simulated_s: f64,
    pub wall_s: f64,
}

fn outcomes(host: &Host, flights: &Flights) -> Vec<(String, Option<Result<(), String>>)> {
    let first = host.drone_ids().into_iter().next().unwrap_or_default();
    if let Some(reason) = flights.failure() {
        return vec![(first, Some(Err(reason)))];
    }
    let Some(started) = flights.started() else {
        return vec![(first, None)];
    };
    started
        .iter()
        .filter_map(|&(i, id)| {
            let core = host.cores().get(i)?;
            let ex = host.executors().get(i)?;
            let outcome = ex.status(core).outcome(id);
            Some((
                core.drone_id().to_string(),
                outcome.map(|r| r.map_err(|e| e.to_string())),
            ))
        })
        .collect()
}

async fn shutdown_signal() {
    let ctrl_c = tokio::signal::ctrl_c();
    #[cfg(unix)]
    {
        let mut term =
            match tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate()) {
                Ok(t) => t,
                Err(_) => {
                    let _ = ctrl_c.await;
                    return;
                }
            };
        tokio::select! {
            _ = ctrl_c => {}
            _ = term.recv() => {}
        }
    }
    #[cfg(not(unix))]
    {
        let _ = ctrl_c.await;
    }
}

fn print_event(e: &HostEvent) {
    if let HostEvent::Event {
        drone,
        t,
        event: EventBody::Behavior(b),
    } = e
    {
        println!(
            "[{t:8.2} s] {drone}: {}",
            crate::cli::console::behavior_line(b)
        );
    }
}

/// Serves the API on `listener` until `stop`, and says where.
fn start_api(
    listener: tokio::net::TcpListener,
    handle: &HostHandle,
    options: &ServeOptions,
    store: Option<store::Sink>,
    stop: watch::Receiver<bool>,
) -> Result<tokio::task::JoinHandle<()>> {
    let address = listener.local_addr().context("reading the API address")?;
    let state = ApiState::new(
        handle.clone(),
        options.token.clone(),
        &options.api,
        options.log.clone(),
    )
    .with_store(store);
    let app = api::router(state, &options.api);
    let limits = api::serve::ConnLimits::from(&options.api);
    let server = tokio::spawn(api::serve::serve(listener, app, limits, stop));
    let auth = if options.token.is_some() {
        "bearer token required"
    } else {
        "no token: loopback only"
    };
    println!("API on http://{address} ({auth})");
    Ok(server)
}

/// Prints every host event (and hands it to `tap`) until the last sender is gone.
async fn print_events(
    mut events: tokio::sync::broadcast::Receiver<SharedEvent>,
    mut tap: Option<EventTap>,
) {
    loop {
        match events.recv().await {
            Ok(e) => {
                print_event(&e);
                if let Some(tap) = tap.as_mut() {
                    tap(&e);
                }
            }
            Err(tokio::sync::broadcast::error::RecvError::Lagged(n)) => {
                println!("({n} events not shown)")
            }
            Err(tokio::sync::broadcast::error::RecvError::Closed) => break,
        }
    }
}

/// Opens the ROS 2 bridge (its own Zenoh session): a bad configuration stops the start, the
/// router is reached in the background.
#[cfg(feature = "fleet-bus")]
async fn start_ros2(
    section: kestrel::config::ros2::Ros2Section,
    handle: &HostHandle,
) -> Result<()> {
    let (domain, connect) = (section.domain_id, section.connect.join(", "));
    kestrel::ros2::node::start(section, handle.clone()).await?;
    println!("ROS 2 (rmw_zenoh): domain {domain}, connecting to [{connect}]");
    Ok(())
}

#[cfg(not(feature = "fleet-bus"))]
async fn start_ros2(_: kestrel::config::ros2::Ros2Section, _: &HostHandle) -> Result<()> {
    anyhow::bail!("ros2.enabled: this kestrel was built without Zenoh (cargo feature `fleet-bus`)")
}

/// Runs the host and the API until interrupted (or, with `exit_when_done`, until every
/// flight ended).
pub async fn serve(host: Host, mut options: ServeOptions) -> Result<Outcome> {
    let listener = match options.listener.take() {
        Some(l) => Some(tokio::net::TcpListener::from_std(l).context("serving the API")?),
        None => None,
    };
    let flights = options.flights.clone();
    let max_time = options.max_time;
    let store = host.store().cloned();
    let mut rt = RuntimeOptions::new(options.pace);
    rt.between_ticks = options.between_ticks.take();
    if options.exit_when_done || max_time.is_some() {
        let flights = flights.clone();
        let when_done = options.exit_when_done;
        rt.stop_when = Some(Box::new(move |host: &Host| {
            max_time.is_some_and(|m| host.now() > m)
                || (when_done
                    && outcomes(host, &flights).iter().all(|(_, o)| o.is_some())
                    && !host.cores().iter().any(landing))
        }));
    }
    let (shutdown_tx, shutdown_rx) = watch::channel(false);
    let wall = Instant::now();
    let spawned = runtime::spawn(host, rt, shutdown_rx).context("starting the control loop")?;
    let handle = spawned.handle;
    tokio::spawn(flights::print_status_changes(handle.watch_state()));
    if let Some(section) = options.ros2.take() {
        start_ros2(section, &handle).await?;
    }
    if let Some(timeout) = options.demo_within {
        tokio::spawn(flights::start_demo_when_ready(
            handle.clone(),
            handle.watch_state(),
            flights.clone(),
            timeout,
        ));
    }
    let server = match listener {
        Some(listener) => Some(start_api(
            listener,
            &handle,
            &options,
            store,
            shutdown_tx.subscribe(),
        )?),
        None => None,
    };
    let printer = tokio::spawn(print_events(spawned.events, options.on_event.take()));
    let thread = spawned.thread;
    let join = tokio::task::spawn_blocking(move || thread.join());
    tokio::pin!(join);
    let mut announced = false;
    let mut state_rx = handle.watch_state();
    // The control loop ends when every handle is gone: this one lives until shutdown, so a run
    // without the API keeps going after the demo task let go of its handle.
    let keep_alive = handle;
    let finished = loop {
        tokio::select! {
            _ = shutdown_signal() => break None,
            joined = &mut join => break Some(joined),
            changed = state_rx.changed(), if !announced && !flights.is_empty() => {
                if changed.is_err() {
                    continue;
                }
                let snap = state_rx.borrow_and_update().clone();
                let ended = flights.started().is_some_and(|started| {
                    started.iter().all(|&(i, id)| {
                        snap.drones
                            .get(i)
                            .and_then(|d| d.mission.as_ref())
                            .and_then(|m| m.outcome(id))
                            .is_some()
                    })
                });
                if ended && !options.exit_when_done {
                    announced = true;
                    println!("flights ended; still running (Ctrl-C to stop)");
                }
            }
        }
    };
    let _ = shutdown_tx.send(true);
    drop(keep_alive);
    let host = match finished {
        Some(joined) => joined,
        None => join.await,
    }
    .context("waiting for the control loop")?
    .map_err(|_| anyhow::anyhow!("the control loop panicked"))?;
    if let Some(server) = server {
        let _ = server.await;
    }
    drop(state_rx);
    // Every sender is gone once the server stopped: the printer ends after the last event.
    if tokio::time::timeout(Duration::from_secs(1), printer)
        .await
        .is_err()
    {
        tracing::warn!("some events were not printed");
    }
    if let Some(pending) = options.texts_pending.take() {
        let deadline = Instant::now() + TEXTS_FLUSH;
        while pending() && Instant::now() < deadline {
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
        if pending() {
            tracing::warn!("some texts for the ground station were not sent (is the link down?)");
        }
    }
    let outcome = Outcome {
        results: outcomes(&host, &flights),
        simulated_s: host.now().as_secs_f64(),
        wall_s: wall.elapsed().as_secs_f64(),
    };
    close_log(host, options.log.as_ref());
    Ok(outcome)
}

/// Drops the host, which owns the log's writer, so the writer thread finishes the file (an
/// MCAP log's summary) before the process ends; waits for it.
fn close_log(host: Host, log: Option<&LogFile>) {
    drop(host);
    if let Some(log) = log {
        if !log.wait_closed(LOG_CLOSE) {
            tracing::warn!(
                "the flight log {} was not closed in time",
                log.path.display()
            );
        }
    }
}
