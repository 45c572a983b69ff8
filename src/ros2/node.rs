//! Kestrel as a ROS 2 node over rmw_zenoh: a Zenoh session of its own (apart from the fleet
//! bus) that declares the node's and each endpoint's liveliness token, publishes the drones'
//! state at `[ros2] rate_hz`, each planned path when it changes, `/map` when it changed (at most
//! `map_rate_hz`, and to late joiners on request), and takes each drone's `goal_pose`.
//!
//! In: the `[ros2]` section and the host's handle (its snapshots, its map, its mission
//! commands). Out: Zenoh puts, replies and tokens; goals as missions the host validates (a
//! refused goal is logged with the reason and changes nothing).
//!
//! `/map` is transient local as rmw_zenoh makes it (Zenoh's advanced publisher): the latest map
//! is answered on `<key>/@adv/pub/<zid>/<eid>/_` (announced by a liveliness token there, so a
//! subscriber that comes later finds it), on `@adv/pub/<zid>/<eid>/_/@/<key>` and on the key
//! itself. The session is a Zenoh client of the router in `connect` (scouting off): the router
//! routes a client's samples, tokens and queries to the peers rmw_zenoh's nodes are. A peer
//! session that neither listens nor gossips exchanged nothing with such peers through a router
//! (Zenoh 1.10.2; `sitl/tests/test_ros2.py` checks the client). A client cannot open without a
//! router: the session is opened, and everything declared, in the background, trying again
//! until one answers.

use super::goal::{self, Aloft};
use super::keys::{self, Attachment, Endpoint, Entity, Owner, Qos};
use super::msgs::{self, MsgType, Stamp};
use super::outbox;
use crate::config::ros2::Ros2Section;
use crate::host::runtime::HostHandle;
use crate::host::Command;
use crate::mission::{Action, MissionUpdate};
use std::sync::{Arc, Mutex};
use std::time::Duration;
use tokio::sync::mpsc;
use zenoh::Wait;

/// Goals waiting for the host; more are dropped (and said).
const GOAL_QUEUE: usize = 16;

#[derive(Debug, thiserror::Error)]
pub enum Ros2Error {
    #[error("ROS 2 bridge: Zenoh configuration: {0}")]
    Config(String),
    #[error("ROS 2 bridge: cannot open the Zenoh session: {0}")]
    Open(String),
    #[error("ROS 2 bridge: cannot declare `{key}`: {why}")]
    Declare { key: String, why: String },
}

/// The session's configuration: a client of the routers, no scouting.
fn zenoh_config(section: &Ros2Section) -> Result<zenoh::Config, Ros2Error> {
    let json = serde_json::json!({
        "mode": "client",
        "connect": {
            "endpoints": section.connect,
            "retry": { "period_init_ms": 500, "period_max_ms": 4000, "period_increase_factor": 2 },
        },
        "scouting": { "multicast": { "enabled": false }, "gossip": { "enabled": false } },
    });
    zenoh::Config::from_json5(&json.to_string()).map_err(|e| Ros2Error::Config(e.to_string()))
}

/// Wall-clock nanoseconds since the Unix epoch: ROS stamps messages with the wall clock.
fn unix_ns() -> i64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| i64::try_from(d.as_nanos()).unwrap_or(i64::MAX))
        .unwrap_or(0)
}

/// One publisher: its key, its GID and its next sequence number.
struct Outlet {
    key: String,
    gid: [u8; 16],
    sequence: i64,
}

impl Outlet {
    fn attachment(&mut self, ts_ns: i64) -> Vec<u8> {
        self.sequence += 1;
        Attachment {
            sequence_number: self.sequence,
            source_timestamp_ns: ts_ns,
            source_gid: self.gid,
        }
        .encode()
    }
}

/// The names of this node: what its tokens and keys are made of.
struct Naming {
    domain: u32,
    zid: String,
    namespace: String,
    node: String,
    next_id: u32,
}

impl Naming {
    fn owner(&self) -> Owner<'_> {
        Owner {
            domain: self.domain,
            zid: &self.zid,
            node_id: 0,
            namespace: &self.namespace,
            node: &self.node,
        }
    }

    /// The next entity's token and the topic's key.
    fn endpoint(&mut self, kind: Entity, topic: &str, ty: &MsgType, qos: Qos) -> (u32, String) {
        self.next_id += 1;
        let e = Endpoint { topic, ty, qos };
        (
            self.next_id,
            keys::liveliness_token(&self.owner(), self.next_id, kind, Some(e)),
        )
    }
}

/// The session and what it declared; dropped, everything is undeclared.
struct Node {
    session: zenoh::Session,
    naming: Naming,
    tokens: Vec<zenoh::liveliness::LivelinessToken>,
}

impl Node {
    fn token(&mut self, key: String) -> Result<(), Ros2Error> {
        let token = self
            .session
            .liveliness()
            .declare_token(key.clone())
            .wait()
            .map_err(|e| Ros2Error::Declare {
                key,
                why: e.to_string(),
            })?;
        self.tokens.push(token);
        Ok(())
    }

    /// A publisher's token; its key, GID and sequence.
    fn publisher(&mut self, topic: &str, ty: &MsgType, qos: Qos) -> Result<Outlet, Ros2Error> {
        let (_, token) = self.naming.endpoint(Entity::Publisher, topic, ty, qos);
        let gid = keys::gid(&token);
        self.token(token)?;
        Ok(Outlet {
            key: keys::topic_key(self.naming.domain, topic, ty),
            gid,
            sequence: 0,
        })
    }

    fn put(&self, outlet: &mut Outlet, bytes: Vec<u8>, ts_ns: i64) {
        let attachment = outlet.attachment(ts_ns);
        let put = self
            .session
            .put(outlet.key.as_str(), bytes)
            .attachment(attachment)
            .congestion_control(zenoh::qos::CongestionControl::Drop)
            .wait();
        if let Err(e) = put {
            tracing::debug!("ROS 2 bridge: not sent on {}: {e}", outlet.key);
        }
    }
}

/// Per drone: its outlets.
struct DroneOutlets {
    drone: String,
    pose: Outlet,
    odom: Outlet,
    path: Outlet,
    /// The last path sent and when (unix ns), so an unchanged one is sent again only every
    /// [`PATH_REPEAT_NS`]: a subscriber that joined late, or a sample dropped on a congested
    /// link, gets it within that time.
    last_path: Option<(Vec<[f64; 3]>, i64)>,
}

/// An unchanged planned path is sent again this often (ns).
const PATH_REPEAT_NS: i64 = 1_000_000_000;

/// The latest `/map` and its attachment, for late joiners.
type Latest = Arc<Mutex<Option<(Vec<u8>, Vec<u8>)>>>;

/// Checks the configuration, then, in the background, opens the session once a router answers,
/// declares the node, its publishers and its `goal_pose` subscriptions, and starts publishing.
pub async fn start(section: Ros2Section, handle: HostHandle) -> Result<(), Ros2Error> {
    let config = zenoh_config(&section)?;
    tokio::spawn(async move {
        let session = open_when_reached(config, &section.connect).await;
        if let Err(e) = serve(session, section, handle).await {
            tracing::error!("{e}");
        }
    });
    Ok(())
}

/// Longest wait between two tries to reach a router.
const RETRY_MAX: Duration = Duration::from_secs(4);

/// Opens the client session, trying again (500 ms, doubling up to [`RETRY_MAX`]) until a
/// router answers; says so once when none does at first.
async fn open_when_reached(config: zenoh::Config, routers: &[String]) -> zenoh::Session {
    let mut wait = Duration::from_millis(500);
    let mut said = false;
    loop {
        match zenoh::open(config.clone()).await {
            Ok(session) => {
                if said {
                    tracing::info!("ROS 2 bridge: router reached");
                }
                return session;
            }
            Err(e) if !said => {
                tracing::warn!(
                    "ROS 2 bridge: no Zenoh router answers at [{}] yet ({e}); trying again in the background",
                    routers.join(", ")
                );
                said = true;
            }
            Err(e) => tracing::debug!("ROS 2 bridge: {}", Ros2Error::Open(e.to_string())),
        }
        tokio::time::sleep(wait).await;
        wait = (wait * 2).min(RETRY_MAX);
    }
}

/// Declares everything on the open session and starts publishing.
async fn serve(
    session: zenoh::Session,
    section: Ros2Section,
    handle: HostHandle,
) -> Result<(), Ros2Error> {
    let naming = Naming {
        domain: section.domain_id,
        zid: session.zid().to_string(),
        namespace: section.namespace_path(),
        node: section.node.clone(),
        next_id: 0,
    };
    let mut node = Node {
        session,
        naming,
        tokens: Vec::new(),
    };
    let node_token = keys::liveliness_token(&node.naming.owner(), 0, Entity::Node, None);
    node.token(node_token)?;
    let ns = node.naming.namespace.clone();
    let mut drones = Vec::new();
    for drone in &handle.info.drones {
        let topic = |leaf| outbox::drone_topic(&ns, drone, leaf);
        drones.push(DroneOutlets {
            drone: drone.clone(),
            pose: node.publisher(&topic("pose"), &msgs::POSE_STAMPED, Qos::DEFAULT)?,
            odom: node.publisher(&topic("odom"), &msgs::ODOMETRY, Qos::DEFAULT)?,
            path: node.publisher(&topic("path"), &msgs::PATH, Qos::DEFAULT)?,
            last_path: None,
        });
    }
    let tf = node.publisher("/tf", &msgs::TF_MESSAGE, Qos::DEFAULT)?;
    let (map, latest, queryables) = declare_map(&mut node)?;
    let (goal_tx, goal_rx) = mpsc::channel(GOAL_QUEUE);
    let subscribers = declare_goals(&mut node, &handle.info.drones, goal_tx)?;
    tokio::spawn(fly_goals(handle.clone(), goal_rx, section.goal_speed_mps));
    tokio::spawn(async move {
        let _kept = (queryables, subscribers);
        let mut loop_state = Publishing {
            node,
            drones,
            tf,
            map,
            latest,
            last_map: None,
        };
        loop_state.run(&section, handle).await;
    });
    Ok(())
}

type Queryables = Vec<zenoh::query::Queryable<()>>;

/// `/map`'s token, its outlet, and the queryables that answer late joiners with the latest map.
fn declare_map(node: &mut Node) -> Result<(Outlet, Latest, Queryables), Ros2Error> {
    let map = node.publisher("/map", &msgs::OCCUPANCY_GRID, Qos::LATCHED)?;
    let eid = node.naming.next_id;
    let cache = format!("@adv/pub/{}/{eid}/_", node.naming.zid);
    let latest: Latest = Arc::new(Mutex::new(None));
    let mut queryables = Vec::new();
    for key in [
        map.key.clone(),
        format!("{}/{cache}", map.key),
        format!("{cache}/@/{}", map.key),
    ] {
        let latest = latest.clone();
        let reply_key = map.key.clone();
        let q = node
            .session
            .declare_queryable(key.clone())
            .callback(move |query| {
                let Ok(held) = latest.lock() else { return };
                if let Some((bytes, attachment)) = held.as_ref() {
                    let sent = query
                        .reply(reply_key.as_str(), bytes.clone())
                        .attachment(attachment.clone())
                        .wait();
                    if let Err(e) = sent {
                        tracing::debug!("ROS 2 bridge: /map not answered: {e}");
                    }
                }
            })
            .wait()
            .map_err(|e| Ros2Error::Declare {
                key,
                why: e.to_string(),
            })?;
        queryables.push(q);
    }
    node.token(format!("{}/{cache}", map.key))?;
    Ok((map, latest, queryables))
}

type Subscribers = Vec<zenoh::pubsub::Subscriber<()>>;

/// Each drone's `goal_pose` subscription; goals that pass `goal::read_goal` go to `tx`.
fn declare_goals(
    node: &mut Node,
    drones: &[String],
    tx: mpsc::Sender<(String, goal::Goal)>,
) -> Result<Subscribers, Ros2Error> {
    let mut subscribers = Vec::new();
    for drone in drones {
        let topic = outbox::drone_topic(&node.naming.namespace, drone, "goal_pose");
        let (_, token) = node.naming.endpoint(
            Entity::Subscription,
            &topic,
            &msgs::POSE_STAMPED,
            Qos::DEFAULT,
        );
        node.token(token)?;
        let key = keys::topic_key(node.naming.domain, &topic, &msgs::POSE_STAMPED);
        let tx = tx.clone();
        let drone = drone.clone();
        let sub = node
            .session
            .declare_subscriber(key.clone())
            .callback(move |sample| {
                let size = sample.payload().len();
                // Bounded before the payload is copied out of Zenoh's buffers.
                let read = if size > goal::MAX_GOAL_BYTES {
                    Err(goal::GoalError::TooLarge(size))
                } else {
                    goal::read_goal(&sample.payload().to_bytes())
                };
                match read {
                    Ok(g) => {
                        if tx.try_send((drone.clone(), g)).is_err() {
                            tracing::warn!("ROS 2 goal_pose for {drone} dropped: goals are coming faster than the host takes them");
                        }
                    }
                    Err(e) => tracing::warn!("ROS 2 goal_pose for {drone} refused: {e}"),
                }
            })
            .wait()
            .map_err(|e| Ros2Error::Declare {
                key,
                why: e.to_string(),
            })?;
        subscribers.push(sub);
    }
    Ok(subscribers)
}

/// Hands each goal to the host as a mission; a refusal is logged with the host's reason. A
/// drone's goals reuse one mission id (the last goal's), so they do not pile up in its store.
async fn fly_goals(
    handle: HostHandle,
    mut goals: mpsc::Receiver<(String, goal::Goal)>,
    speed_mps: f64,
) {
    let mut mission_ids: std::collections::HashMap<String, u32> = Default::default();
    while let Some((drone, g)) = goals.recv().await {
        let snapshot = handle.snapshot();
        let aloft = snapshot
            .drones
            .iter()
            .find(|d| d.drone == drone)
            .and_then(|d| {
                d.flight
                    .is_airborne()
                    .then(|| Aloft::AtHeight(d.position_enu_m.map_or(0.0, |p| p[2])))
            })
            .unwrap_or(Aloft::Grounded);
        let update = MissionUpdate {
            drone_id: Some(drone.clone()),
            mission_id: mission_ids.get(&drone).map(|&id| i64::from(id)),
            item_id: None,
            action: Action::Execute,
            mission: Some(goal::mission(&drone, &g, aloft, speed_mps)),
        };
        match handle.call(|reply| Command::Update { update, reply }).await {
            Ok(updated) => {
                if let Some(id) = updated.status.mission_id {
                    mission_ids.insert(drone.clone(), id);
                }
                tracing::info!(
                    "ROS 2 goal_pose: {drone} flies to ({:.2}, {:.2}, {:.2}) m",
                    g.position_m[0],
                    g.position_m[1],
                    g.position_m[2]
                );
            }
            Err(e) => tracing::warn!("ROS 2 goal_pose for {drone} refused: {e}"),
        }
    }
}

/// The publishing loop's state.
struct Publishing {
    node: Node,
    drones: Vec<DroneOutlets>,
    tf: Outlet,
    map: Outlet,
    latest: Latest,
    /// What the last `/map` was made of (spec and cells), so an unchanged map is not resent.
    last_map: Option<u64>,
}

impl Publishing {
    async fn run(&mut self, section: &Ros2Section, handle: HostHandle) {
        let mut every = tokio::time::interval(Duration::from_secs_f64(1.0 / section.rate_hz));
        every.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Skip);
        let mut map_every =
            tokio::time::interval(Duration::from_secs_f64(1.0 / section.map_rate_hz));
        map_every.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Skip);
        let mut state = handle.watch_state();
        loop {
            tokio::select! {
                _ = every.tick() => self.state(&handle),
                _ = map_every.tick() => self.map(&handle).await,
                changed = state.changed() => {
                    if changed.is_err() {
                        break;
                    }
                    self.paths(&handle);
                }
            }
        }
    }

    fn state(&mut self, handle: &HostHandle) {
        let snapshot = handle.snapshot();
        let ts = unix_ns();
        let stamp = Stamp::from_unix_ns(ts);
        for out in &mut self.drones {
            let Some(d) = snapshot.drones.iter().find(|d| d.drone == out.drone) else {
                continue;
            };
            if let Some((pose, odom)) = outbox::pose_and_odometry(d, stamp) {
                self.node.put(&mut out.pose, pose, ts);
                self.node.put(&mut out.odom, odom, ts);
            }
        }
        if let Some(tf) = outbox::transforms(&snapshot.drones, stamp) {
            self.node.put(&mut self.tf, tf, ts);
        }
    }

    /// Each drone's planned path, on every snapshot the host publishes (on every mission change
    /// and at least every 20 ms): a plan that lives shorter than one `rate_hz` period (a short
    /// hop, a simulator run faster than real time) is still sent. Unchanged, it is sent again
    /// every [`PATH_REPEAT_NS`].
    fn paths(&mut self, handle: &HostHandle) {
        let snapshot = handle.snapshot();
        let ts = unix_ns();
        for out in &mut self.drones {
            let Some(d) = snapshot.drones.iter().find(|d| d.drone == out.drone) else {
                continue;
            };
            let points = outbox::planned_path(d);
            let due = out.last_path.as_ref().is_none_or(|(last, at)| {
                *last != points || ts.saturating_sub(*at) >= PATH_REPEAT_NS
            });
            if due {
                let path = outbox::path(&points, Stamp::from_unix_ns(ts));
                self.node.put(&mut out.path, path, ts);
                out.last_path = Some((points, ts));
            }
        }
    }

    async fn map(&mut self, handle: &HostHandle) {
        let view = match handle
            .call(|reply| Command::Map { drone: None, reply })
            .await
        {
            Ok(v) => v,
            Err(e) => {
                tracing::debug!("ROS 2 bridge: no map: {e}");
                return;
            }
        };
        let digest = {
            use std::hash::{Hash, Hasher};
            let mut h = std::collections::hash_map::DefaultHasher::new();
            view.grid.data().hash(&mut h);
            let spec = view.grid.spec();
            (spec.width_cells, spec.height_cells).hash(&mut h);
            spec.resolution_m.to_bits().hash(&mut h);
            spec.origin_enu_m.x.to_bits().hash(&mut h);
            spec.origin_enu_m.y.to_bits().hash(&mut h);
            h.finish()
        };
        if self.last_map == Some(digest) {
            return;
        }
        self.last_map = Some(digest);
        let ts = unix_ns();
        let bytes = outbox::map(&view, Stamp::from_unix_ns(ts));
        let attachment = self.map.attachment(ts);
        if let Ok(mut held) = self.latest.lock() {
            *held = Some((bytes.clone(), attachment.clone()));
        }
        let put = self
            .node
            .session
            .put(self.map.key.as_str(), bytes)
            .attachment(attachment)
            .wait();
        if let Err(e) = put {
            tracing::debug!("ROS 2 bridge: /map not sent: {e}");
        }
    }
}
