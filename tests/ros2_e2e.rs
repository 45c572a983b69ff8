//! Kestrel's drones as ROS 2 topics over rmw_zenoh, end to end: a real `kestrel sim` with
//! `[ros2] enabled = true` connects to a plain Zenoh peer the test opens (standing in for the
//! `rmw_zenohd` router of a ROS 2 machine; no ROS installation here). The test checks the
//! liveliness tokens `ros2 topic list` is built from, decodes the `pose` samples against
//! `/api/status`, answers `/map` as a late joiner, and sends `goal_pose`s: malformed, in the
//! wrong frame and beyond the geofence ones change nothing; a good one is flown.
//!
//! Margins: the drone sits on the ground while poses are compared (the simulator's position
//! noise is centimetres); the goal is judged reached within 0.3 m of it on every axis, room for
//! the arrival and the hover's wander; the simulator runs at 20 times real time.
#![cfg(feature = "fleet-bus")]
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod support;

use kestrel::ros2::keys::Attachment;
use kestrel::ros2::msgs::{self, Pose, Stamp};
use serde_json::Value;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use support::{free_tcp_port, Kestrel};
use zenoh::Wait;

const POSE_HASH: &str = "RIHS01_10f3786d7d40fd2b54367835614bff85d4ad3b5dab62bf8bca0cc232d73b4cd8";

fn key(topic: &str, ty: &str, hash: &str) -> String {
    format!("0/{topic}/{ty}/{hash}")
}

/// A Zenoh peer listening on a free loopback port, as a ROS 2 machine's router would.
fn open_peer() -> (zenoh::Session, u16) {
    let port = free_tcp_port();
    let config = serde_json::json!({
        "mode": "peer",
        "listen": { "endpoints": [format!("tcp/127.0.0.1:{port}")] },
        "scouting": { "multicast": { "enabled": false }, "gossip": { "enabled": false } },
    });
    let config = zenoh::Config::from_json5(&config.to_string()).unwrap();
    (zenoh::open(config).wait().unwrap(), port)
}

async fn wait_until<T>(what: &str, max: Duration, mut f: impl FnMut() -> Option<T>) -> T {
    let deadline = Instant::now() + max;
    loop {
        if let Some(v) = f() {
            return v;
        }
        assert!(Instant::now() < deadline, "timed out waiting for {what}");
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
}

fn drone_0(status: &Value) -> &Value {
    &status["drones"][0]
}

fn position(status: &Value) -> [f64; 3] {
    let p = drone_0(status)["position_enu_m"].as_array().unwrap();
    [0, 1, 2].map(|i| p[i].as_f64().unwrap())
}

fn goal(frame: &str, p: [f64; 3]) -> Vec<u8> {
    msgs::pose_stamped(Stamp::default(), frame, &Pose::from_yaw(p, 0.0))
}

#[tokio::test(flavor = "multi_thread")]
async fn ros2_sees_the_drone_and_flies_its_goal() {
    let (peer, port) = open_peer();
    let tokens = Arc::new(Mutex::new(Vec::<String>::new()));
    let seen = tokens.clone();
    let _live = peer
        .liveliness()
        .declare_subscriber("@ros2_lv/0/**")
        .history(true)
        .callback(move |s| seen.lock().unwrap().push(s.key_expr().to_string()))
        .wait()
        .unwrap();
    let pose_key = key(
        "drone_0/pose",
        "geometry_msgs::msg::dds_::PoseStamped_",
        POSE_HASH,
    );
    let poses = Arc::new(Mutex::new(Vec::<(Vec<u8>, Option<Vec<u8>>)>::new()));
    let got = poses.clone();
    let _poses = peer
        .declare_subscriber(pose_key.clone())
        .callback(move |s| {
            let attachment = s.attachment().map(|a| a.to_bytes().to_vec());
            got.lock()
                .unwrap()
                .push((s.payload().to_bytes().to_vec(), attachment));
        })
        .wait()
        .unwrap();

    let dir = tempfile::tempdir().unwrap();
    let config = dir.path().join("kestrel.toml");
    std::fs::write(
        &config,
        format!("[ros2]\nenabled = true\nconnect = [\"tcp/127.0.0.1:{port}\"]\n"),
    )
    .unwrap();
    let k = Kestrel::sim(
        dir.path(),
        "",
        &["--config", config.to_str().unwrap(), "--sensor", "lidar"],
    )
    .await;

    // The graph: the node, a publisher per topic, the goal_pose subscription.
    let all = wait_until("the liveliness tokens", Duration::from_secs(20), || {
        let t = tokens.lock().unwrap().clone();
        (t.iter().any(|k| k.contains("/MS/"))
            && t.iter().filter(|k| k.contains("/MP/")).count() >= 5)
            .then_some(t)
    })
    .await;
    let node = all.iter().find(|k| k.contains("/NN/")).expect("node token");
    let parts: Vec<&str> = node.split('/').collect();
    assert_eq!(
        (
            parts.len(),
            parts[0],
            parts[1],
            parts[5],
            parts[6],
            parts[7],
            parts[8]
        ),
        (9, "@ros2_lv", "0", "NN", "%", "%", "kestrel"),
        "{node}"
    );
    let zid = parts[2];
    assert!(
        zid.len() >= 2 && zid.bytes().all(|b| b.is_ascii_hexdigit()),
        "{node}"
    );
    let has = |suffix: &str| {
        all.iter()
            .any(|k| k.starts_with(&format!("@ros2_lv/0/{zid}/0/")) && k.ends_with(suffix))
    };
    for suffix in [
        format!("/MP/%/%/kestrel/%drone_0%pose/geometry_msgs::msg::dds_::PoseStamped_/{POSE_HASH}/::,10:,:,:,,"),
        format!("/MS/%/%/kestrel/%drone_0%goal_pose/geometry_msgs::msg::dds_::PoseStamped_/{POSE_HASH}/::,10:,:,:,,"),
        format!("/MP/%/%/kestrel/%drone_0%odom/nav_msgs::msg::dds_::Odometry_/{}/::,10:,:,:,,", msgs::ODOMETRY.hash),
        format!("/MP/%/%/kestrel/%drone_0%path/nav_msgs::msg::dds_::Path_/{}/::,10:,:,:,,", msgs::PATH.hash),
        format!("/MP/%/%/kestrel/%tf/tf2_msgs::msg::dds_::TFMessage_/{}/::,10:,:,:,,", msgs::TF_MESSAGE.hash),
        format!("/MP/%/%/kestrel/%map/nav_msgs::msg::dds_::OccupancyGrid_/{}/:1:,1:,:,:,,", msgs::OCCUPANCY_GRID.hash),
    ] {
        assert!(has(&suffix), "no token ending {suffix} in {all:#?}");
    }

    // Poses arrive, decode, carry rmw_zenoh's attachment, and say where the drone is.
    let (_, status) = k.get("/api/status").await;
    let truth = position(&status);
    let samples = wait_until("pose samples", Duration::from_secs(10), || {
        let p = poses.lock().unwrap().clone();
        (p.len() >= 3).then_some(p)
    })
    .await;
    let mut last_seq = 0;
    for (payload, attachment) in &samples {
        let msg = msgs::decode_pose_stamped(payload).unwrap();
        assert_eq!(msg.frame_id, "world");
        for (a, b) in msg.pose.position_m.iter().zip(truth) {
            assert!(
                (a - b).abs() < 0.05,
                "pose {:?} vs status {truth:?}",
                msg.pose
            );
        }
        let a = Attachment::decode(attachment.as_deref().expect("an attachment")).unwrap();
        assert!(a.sequence_number > last_seq, "sequence numbers grow");
        last_seq = a.sequence_number;
        assert!(a.source_timestamp_ns > 1_600_000_000_000_000_000);
    }

    // /map to a late joiner: the latest map, on the topic's key and through the cache key.
    let map_key = key(
        "map",
        "nav_msgs::msg::dds_::OccupancyGrid_",
        msgs::OCCUPANCY_GRID.hash,
    );
    let map = wait_until("a /map reply", Duration::from_secs(10), || {
        let replies = peer
            .get(format!("{map_key}/@adv/pub/**?_anyke"))
            .wait()
            .unwrap();
        let reply = replies.recv_timeout(Duration::from_secs(2)).ok()??;
        let sample = reply.into_result().ok()?;
        assert_eq!(sample.key_expr().as_str(), map_key);
        Some(sample.payload().to_bytes().to_vec())
    })
    .await;
    assert_eq!(&map[..4], &[0, 1, 0, 0]);
    assert_eq!(&map[12..22], b"\x06\0\0\0world\0", "the map's frame");

    // Bad goals change nothing: garbage, another frame, beyond the 1000 m geofence.
    let goal_key = key(
        "drone_0/goal_pose",
        "geometry_msgs::msg::dds_::PoseStamped_",
        POSE_HASH,
    );
    for bad in [
        vec![0xde, 0xad, 0xbe, 0xef],
        vec![0; 4096],
        goal("base_link", [3.0, 2.0, 2.0]),
        goal("world", [5000.0, 0.0, 2.0]),
    ] {
        peer.put(goal_key.as_str(), bad).wait().unwrap();
    }
    tokio::time::sleep(Duration::from_secs(2)).await;
    let (_, missions) = k.get("/api/missions?drone=drone_0").await;
    assert_eq!(
        missions,
        serde_json::json!([]),
        "a refused goal left a mission"
    );
    let (_, status) = k.get("/api/status").await;
    let flight = drone_0(&status)["flight"].as_str().unwrap().to_string();
    assert!(
        ["disarmed", "landed"].contains(&flight.as_str()),
        "{status}"
    );
    for (a, b) in position(&status).iter().zip(truth) {
        assert!((a - b).abs() < 0.05, "the drone moved: {status}");
    }

    // A good goal is flown: takeoff, then navigate_to, to (3, 2, 2).
    let target = [3.0, 2.0, 2.0];
    peer.put(goal_key.as_str(), goal("world", target))
        .wait()
        .unwrap();
    k.wait_for("/api/status", 90.0, |s| {
        position(s)
            .iter()
            .zip(target)
            .all(|(a, b)| (a - b).abs() < 0.3)
    })
    .await;
}
